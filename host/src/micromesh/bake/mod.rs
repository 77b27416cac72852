//! Baking a detailed mesh into a displaced micro-mesh: a coarse base mesh whose every triangle
//! carries one 11-bit displacement per micro-vertex of its level-`L` lattice, so that
//! `p = lerp(P) + lerp(D) * d` lies on the detailed (reference) surface.
//!
//! The steps, as in the "Micro-Mesh Construction" paper (Maggiordomo et al. 2023,
//! <https://doi.org/10.1145/3592440>) and NVIDIA's displacement micro-map tools:
//!
//! 1. **Base mesh**: the reference decimated ([`decimate`]), or a base the caller made.
//! 2. **Directions**: a unit vector per base vertex ([`directions`]).
//! 3. **First pass**: each micro-vertex's line, `lerp(P) + t * lerp(D)`, meets the reference
//!    where rays both ways from the base surface first hit it ([`cast`]), through gridrt's
//!    own triangle BVH and traversal; lines that meet nothing within reach (or only another
//!    sheet, far beyond the closest point of the surface) take the closest point's
//!    projection, and are counted.
//! 4. **Fit**: each base vertex's range of displacements is folded into its position and
//!    direction ([`fit`]), so the stored values span `[0, 1]`.
//! 5. **Second pass**: the lines of the folded mesh (which, where directions differ, are not
//!    quite the first pass's) meet the reference again, from the first pass's crossing.
//! 6. **Least-squares fit**: the values move along their lines so the micro-mesh fits points
//!    sampled on the reference rather than passing through the crossings ([`refine`]); the
//!    result is quantized to 11 bits.
//!
//! Optionally, each base triangle then takes a level of its own ([`levels`]).
//!
//! Every micro-vertex on a shared base edge or corner is computed by the shared decoder's
//! interpolation, which gives both triangles the same bits, so the same ray is cast for it
//! from both sides and it gets one value: the baked surface is watertight wherever the base
//! mesh is.
//!
//! ```no_run
//! # fn main() -> gridrt::error::Result<()> {
//! let input = gridrt::input::open(Some("scan.ply".as_ref()))?;
//! let options = gridrt::micromesh::bake::BakeOptions::for_reference(&input.mesh, 3);
//! let baked = gridrt::micromesh::bake::bake(&input.mesh, &options)?;
//! gridrt::micromesh::gltf::write("scan.gltf".as_ref(), &baked.mesh, &input.frame)?;
//! # Ok(()) }
//! ```

pub mod cast;
pub mod decimate;
pub mod directions;
pub mod fit;
pub mod levels;
pub mod refine;
pub mod request;

use gridrt_shared::displacement::{interpolated, u_major_index, DisplacedTriangle};
use gridrt_shared::glam::Vec3;
use gridrt_shared::grid_index::{grid_size, lattice_points, triangle_count};
use rayon::prelude::*;

use crate::error::{fail, Result};
use crate::mesh::Mesh;
use crate::micromesh::bary::{values_per_triangle, Micromap};
use crate::micromesh::{self, DisplacedMesh};
use cast::{Crossing, Reference};
use refine::{MicroLines, Refinement};

/// Where the base mesh comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum Base {
    /// The reference decimated to about this many triangles.
    Decimated { triangles: usize },
    /// A mesh the caller made, in the reference's frame.
    Given(Mesh),
}

/// What to bake.
#[derive(Clone, Debug, PartialEq)]
pub struct BakeOptions {
    pub base: Base,
    /// Subdivision level `L`: each base triangle gets `4^L` micro-triangles.
    pub levels: u32,
    /// How far the first pass looks for the reference on each side of the base surface, in
    /// mean base edge lengths.
    pub reach: f32,
    /// How the values are fitted to the reference after the rays have found it.
    pub refinement: Refinement,
}

/// The share of a bake's own RMS distance from its reference that compressing its values may
/// add by default. Independent errors add in squares, so the compressed mesh stays within
/// `sqrt(1 + 0.5^2)`, about 1.12 times the uncompressed one's distance.
pub const COMPRESSION_ERROR_SHARE: f32 = 0.5;

/// The share of an error bound on the compressed micro-mesh that its levels may take when
/// they are chosen per triangle, leaving the rest to the default compression:
/// `1 / sqrt(1 + COMPRESSION_ERROR_SHARE^2)`, so both together stay about within the bound.
pub fn levels_error_share() -> f32 {
    1.0 / (1.0 + COMPRESSION_ERROR_SHARE * COMPRESSION_ERROR_SHARE).sqrt()
}

/// Bytes per micro-triangle that everything the GPU gets keeps within by default, by level:
/// the sizes of the fixed-function hardware's compressed displacement blocks (64 micro-triangles
/// in 64 bytes at level 3, 256 in 128 at level 4, 1024 in 128 from level 5 on), here for the
/// values with the hierarchy that hardware keeps to itself; none below level 3, where its
/// blocks hold values uncompressed.
pub fn default_byte_budget(levels: u32) -> Option<f64> {
    match levels {
        0..=2 => None,
        3 => Some(1.0),
        4 => Some(0.5),
        _ => Some(0.2),
    }
}

/// How many micro-triangles each base triangle stands for by default: with [`BakeOptions::for_reference`]
/// at level 3, about as many micro-triangles as the reference has triangles.
pub const REDUCTION: usize = 64;

/// The fewest base triangles a default bake decimates to: a base of fewer keeps too little
/// of any shape for the values to make up (a square of two triangles decimated to one
/// loses half of itself), so a small reference is decimated less, or not at all.
pub const MIN_BASE_TRIANGLES: usize = 128;

/// The base triangles a reference of `triangles` is decimated to by default: 1/[`REDUCTION`]
/// of them, or [`MIN_BASE_TRIANGLES`] (all of them where it has fewer).
pub fn default_base_triangles(triangles: usize) -> usize {
    (triangles / REDUCTION).max(triangles.min(MIN_BASE_TRIANGLES)).max(1)
}

impl BakeOptions {
    /// A base of [`default_base_triangles`] of `reference`'s, at `levels`.
    pub fn for_reference(reference: &Mesh, levels: u32) -> BakeOptions {
        BakeOptions {
            base: Base::Decimated {
                triangles: default_base_triangles(reference.triangles.len()),
            },
            levels,
            reach: 2.0,
            refinement: Refinement::default(),
        }
    }
}

/// A share of a bake's values whose lines met no reference surface beyond which the base
/// does not follow the reference (see [`shortfalls`]).
pub const MISSES_WARNING: f64 = 0.10;

/// A distance, as a fraction of the reference's bounding-box diagonal, beyond which one
/// percent of the reference lying from the bake means part of it is lost (see [`shortfalls`]).
pub const LOSS_WARNING: f64 = 0.05;

/// How close a bake came to what was asked: its report, where its base came from, its
/// distances from the reference (fractions of the reference's diagonal), and the symmetric RMS
/// bound asked for, if any (`--max-error`).
pub struct Outcome<'a> {
    pub report: &'a BakeReport,
    pub base: &'a Base,
    pub reference_to_baked: &'a crate::surface_distance::DistanceSummary,
    pub symmetric: &'a crate::surface_distance::DistanceSummary,
    pub max_error: Option<f32>,
}

/// Where a bake falls short of what the reference and the options ask, one line each with
/// the figure and what to do: values that met no surface (a base that does not follow the
/// reference: too coarse, or another mesh or units), part of the reference lost (a base too
/// coarse for its shape), an error bound not met. Empty for a bake that did what was asked.
pub fn shortfalls(o: &Outcome) -> Vec<String> {
    let mut lines = Vec::new();
    let advice = match o.base {
        Base::Decimated { .. } => format!(
            "a base of {} triangle(s) is too coarse for it; give more --base-triangles",
            o.report.base_triangles
        ),
        Base::Given(_) => "the base mesh does not follow it (another mesh, or other units?)".to_string(),
    };
    let missed = o.report.misses as f64 / o.report.values.max(1) as f64;
    if missed > MISSES_WARNING {
        lines.push(format!(
            "{:.1}% of the values met no surface of the reference within reach: {advice}",
            100.0 * missed
        ));
    }
    if o.reference_to_baked.p99 > LOSS_WARNING {
        lines.push(format!(
            "part of the reference is lost: 1% of its surface lies more than {:.1}% of its diagonal from the \
             bake (at most {:.1}%): {advice}",
            100.0 * o.reference_to_baked.p99,
            100.0 * o.reference_to_baked.max
        ));
    }
    if let Some(bound) = o.max_error.filter(|&b| o.symmetric.rms > b as f64 * MAX_ERROR_SLACK) {
        lines.push(format!(
            "--max-error {bound} is not met: the bake's symmetric RMS distance is {:.3e} of the diagonal, as close \
             as level {} comes; give more --levels or a finer base",
            o.symmetric.rms, o.report.levels
        ));
    }
    lines
}

/// How far over `--max-error` a bake may land and still count as within it: the bound is
/// one the levels aim at ("about"), met on a measure taken by sampling.
const MAX_ERROR_SLACK: f64 = 1.1;

/// A baked micro-mesh and what happened on the way.
#[derive(Clone, Debug)]
pub struct Baked {
    pub mesh: DisplacedMesh,
    pub report: BakeReport,
}

/// Counts a caller shows the user.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct BakeReport {
    pub base_vertices: usize,
    pub base_triangles: usize,
    pub levels: u32,
    pub micro_triangles: u64,
    /// Values baked: micro-vertices per base triangle (those on shared edges once per side).
    pub values: u64,
    /// Values whose line met no reference surface within reach (or only another sheet far
    /// beyond the closest point): they took the projection of the reference's closest point.
    pub misses: u64,
    /// Values whose second-pass crossing fell outside the fitted range by more than rounding
    /// would hide, and were clamped.
    pub clamped: u64,
}

/// Bakes `reference` (a mesh in its local frame) as `options` say.
pub fn bake(reference: &Mesh, options: &BakeOptions) -> Result<Baked> {
    let crossed = cross(reference, options)?;
    let fitted = match options.refinement.rounds {
        0 => (crossed.second.iter())
            .map(|c| c.iter().map(|x| x.t).collect())
            .collect(),
        _ => {
            let (lines, values) = crossed.fitted(reference, options.levels, &options.refinement);
            lines.per_triangle(&values)
        }
    };
    let values: Vec<(u32, Vec<u16>)> = fitted
        .iter()
        .map(|c| (options.levels, c.iter().map(|&u| fit::quantize(u)).collect()))
        .collect();
    let mesh = DisplacedMesh {
        positions: crossed.positions,
        directions: crossed.directions,
        triangles: crossed.triangles,
        micromap: Micromap::from_triangles(0.0, 1.0, &values),
        decimated_edges: Vec::new(),
    };
    mesh.check()?;
    Ok(Baked {
        mesh,
        report: crossed.report,
    })
}

/// A base mesh with its ranges folded in, and where its level-`L` lines meet the reference
/// (steps 1 to 5 of the module docs).
struct Crossed {
    triangles: Vec<[u32; 3]>,
    positions: Vec<Vec3>,
    directions: Vec<Vec3>,
    /// The second pass's crossings, per triangle in u-major order.
    second: Vec<Vec<Crossing>>,
    report: BakeReport,
}

impl Crossed {
    fn folded(&self) -> FoldedBase<'_> {
        (&self.positions, &self.directions, &self.triangles)
    }

    /// The lines of the base's level-`level` lattice (at most the crossings' level), and
    /// their values: the crossings at the lattice's points, refined as `refinement` says.
    fn fitted(&self, reference: &Mesh, level: u32, refinement: &Refinement) -> (MicroLines, Vec<f32>) {
        let (positions, directions, triangles) = self.folded();
        let lines = MicroLines::new(positions, directions, triangles, level);
        let (n, big) = (grid_size(level), grid_size(self.report.levels));
        let step = 1 << (self.report.levels - level);
        let mut values = vec![0.0f32; lines.origins.len()];
        for (of_triangle, crossings) in lines.of_triangle.iter().zip(&self.second) {
            for p in lattice_points(n) {
                let line = of_triangle[u_major_index(p, n) as usize] as usize;
                let at = u_major_index([p[0] * step, p[1] * step], big) as usize;
                values[line] = crossings[at].t.clamp(0.0, 1.0);
            }
        }
        refine::refine(reference, &lines, &mut values, refinement);
        (lines, values)
    }
}

/// Refuses, before the rays are cast, a bake of `base_triangles` at `levels` that would not
/// fit in memory (see [`crate::limits`]).
fn check_memory(base_triangles: usize, levels: u32) -> Result<()> {
    let micro = crate::limits::micro_triangles(base_triangles, levels);
    crate::limits::check_memory(
        micro.saturating_mul(crate::limits::BAKE_BYTES_PER_MICRO_TRIANGLE),
        crate::limits::available_memory()?,
        &format!("baking {base_triangles} base triangles at level {levels} ({micro} micro-triangles)"),
        "use fewer --levels or --base-triangles",
    )
}

/// A folded base mesh's positions, directions and triangles.
type FoldedBase<'a> = (&'a [Vec3], &'a [Vec3], &'a [[u32; 3]]);

/// Steps 1 to 5 of the module docs: the base mesh, its directions, both passes and the fit
/// of the ranges between them.
fn cross(reference: &Mesh, options: &BakeOptions) -> Result<Crossed> {
    if options.levels > micromesh::MAX_LEVEL {
        fail!(
            Options,
            "level {} is past the deepest gridrt decodes ({})",
            options.levels,
            micromesh::MAX_LEVEL
        );
    }
    let base = match &options.base {
        Base::Decimated { triangles } => decimate::decimate(reference, *triangles),
        Base::Given(mesh) => mesh.clone(),
    };
    if base.triangles.is_empty() {
        match &options.base {
            Base::Decimated { triangles } => fail!(
                Options,
                "decimated to {triangles} triangles (--base-triangles), none is left: the simplifier cannot \
                 collapse this mesh that far; ask for more"
            ),
            Base::Given(_) => fail!(Input, "the base mesh has no triangles"),
        }
    }
    check_memory(base.triangles.len(), options.levels)?;
    let directions = directions::area_weighted_normals(&base);
    let surface = Reference::new(reference);
    let lines = Lines {
        triangles: &base.triangles,
        level: options.levels,
    };

    // First pass: along the unit directions, as far as `reach` edge lengths either way.
    let reach = options.reach * mean_edge_length(&base);
    let first = lines.cross(&base.positions, &directions, |origin, direction, _| {
        surface.crossing_near_surface(origin, direction, reach)
    });
    let displacements: Vec<Vec<f32>> = first.iter().map(|c| c.iter().map(|x| x.t).collect()).collect();

    // Fit, then the second pass along the folded lines, from the first pass's crossings.
    let ranges = fit::vertex_ranges(&base.triangles, &displacements, base.positions.len());
    let least_span = 1e-6 * diagonal(&base);
    let (positions, folded) = fit::fold_ranges(&base.positions, &directions, &ranges, least_span);
    let crossings = lines.points(&base.positions, &directions, &first);
    let second = lines.cross(&positions, &folded, |origin, direction, k| {
        let (t, k) = (k.0, k.1);
        let found = crossings[t][k];
        let u0 = projection(found.point, origin, direction).clamp(0.0, 1.0);
        if !found.hit {
            return Crossing { t: u0, hit: false };
        }
        let again = surface.crossing(origin + direction * u0, direction, 1.0);
        Crossing {
            t: if again.hit { u0 + again.t } else { u0 },
            hit: true,
        }
    });

    let report = BakeReport {
        base_vertices: base.positions.len(),
        base_triangles: base.triangles.len(),
        levels: options.levels,
        micro_triangles: base.triangles.len() as u64 * triangle_count(options.levels) as u64,
        values: second.iter().map(|c| c.len() as u64).sum(),
        misses: first.iter().flatten().filter(|c| !c.hit).count() as u64,
        clamped: second.iter().flatten().filter(|c| fit::clipped(c.t)).count() as u64,
    };
    Ok(Crossed {
        triangles: base.triangles,
        positions,
        directions: folded,
        second,
        report,
    })
}

/// The micro-vertex lines of every base triangle at one level, in u-major order.
struct Lines<'a> {
    triangles: &'a [[u32; 3]],
    level: u32,
}

/// A first-pass crossing as a point.
#[derive(Clone, Copy)]
struct Found {
    point: Vec3,
    hit: bool,
}

impl Lines<'_> {
    /// `find(origin, direction, (triangle, value))` for every micro-vertex's line of the
    /// mesh `positions` + `directions`, per triangle in u-major order, on all cores.
    fn cross(
        &self,
        positions: &[Vec3],
        directions: &[Vec3],
        find: impl Fn(Vec3, Vec3, (usize, usize)) -> Crossing + Sync,
    ) -> Vec<Vec<Crossing>> {
        let n = grid_size(self.level);
        (0..self.triangles.len())
            .into_par_iter()
            .map(|t| {
                let triangle = self.triangle(positions, directions, t);
                let mut found = vec![Crossing { t: 0.0, hit: false }; values_per_triangle(self.level)];
                for p in lattice_points(n) {
                    let k = u_major_index(p, n) as usize;
                    let (origin, direction) = interpolated(&triangle, p, n);
                    found[k] = find(origin, direction, (t, k));
                }
                found
            })
            .collect()
    }

    /// The points the crossings stand for on the mesh they were found on.
    fn points(&self, positions: &[Vec3], directions: &[Vec3], crossings: &[Vec<Crossing>]) -> Vec<Vec<Found>> {
        let n = grid_size(self.level);
        (0..self.triangles.len())
            .into_par_iter()
            .map(|t| {
                let triangle = self.triangle(positions, directions, t);
                let mut points = vec![
                    Found {
                        point: Vec3::ZERO,
                        hit: false
                    };
                    crossings[t].len()
                ];
                for p in lattice_points(n) {
                    let k = u_major_index(p, n) as usize;
                    let (origin, direction) = interpolated(&triangle, p, n);
                    let c = crossings[t][k];
                    points[k] = Found {
                        point: origin + direction * c.t,
                        hit: c.hit,
                    };
                }
                points
            })
            .collect()
    }

    fn triangle(&self, positions: &[Vec3], directions: &[Vec3], t: usize) -> DisplacedTriangle {
        let ids = self.triangles[t];
        DisplacedTriangle {
            positions: ids.map(|i| positions[i as usize]),
            directions: ids.map(|i| directions[i as usize]),
            ids,
        }
    }
}

/// The `u` of the point of `origin + u * direction` nearest `point`.
fn projection(point: Vec3, origin: Vec3, direction: Vec3) -> f32 {
    let length2 = direction.length_squared();
    if length2 > 0.0 {
        (point - origin).dot(direction) / length2
    } else {
        0.0
    }
}

fn mean_edge_length(mesh: &Mesh) -> f32 {
    let total: f64 = (mesh.triangles.iter())
        .map(|t| {
            let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
            (a.distance(b) + b.distance(c) + c.distance(a)) as f64
        })
        .sum();
    (total / (3 * mesh.triangles.len()).max(1) as f64) as f32
}

fn diagonal(mesh: &Mesh) -> f32 {
    let (lo, hi) = mesh.bounds();
    lo.distance(hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::WorldMesh;
    use crate::subdiv::{subdivide, Scheme};
    use crate::surface_distance::{measure, Sampling};

    /// A unit sphere of `8 * 4^levels` triangles: the octahedron subdivided flat, its
    /// vertices pushed onto the sphere.
    pub(super) fn sphere(levels: u32) -> Mesh {
        let octahedron = crate::mesh::scene::octahedron();
        let sub = subdivide(&octahedron, levels, Scheme::Flat);
        let mesh = Mesh {
            positions: sub.positions.iter().map(|p| p.normalize()).collect(),
            triangles: sub.micro_triangles(levels),
        };
        // Welded: the flat subdivision shares its lattice points already.
        let (world, _) = WorldMesh::from(mesh).validate("sphere").unwrap();
        world.to_f32()
    }

    pub(super) fn border_edges(triangles: &[[u32; 3]]) -> usize {
        let mut edges = std::collections::HashMap::new();
        for t in triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        edges.values().filter(|&&c| c == 1).count()
    }

    pub(super) fn symmetric_rms(reference: &Mesh, baked: &DisplacedMesh) -> f64 {
        let sampling = Sampling {
            samples: 20_000,
            ..Sampling::default()
        };
        let d = measure(reference, &baked.decoded(), &sampling);
        d.symmetric.relative_to(d.a_diagonal).rms
    }

    /// A closed sphere bakes closed (every shared edge decodes alike from both sides, so
    /// welding leaves no border), every line meets it, and the micro-mesh lies far closer to
    /// it than its base does.
    #[test]
    fn a_sphere_bakes_watertight_and_close() {
        let reference = sphere(5);
        let options = BakeOptions {
            base: Base::Decimated { triangles: 128 },
            ..BakeOptions::for_reference(&reference, 3)
        };
        let baked = bake(&reference, &options).unwrap();
        let r = baked.report;
        assert!(r.base_triangles <= 128 && r.base_triangles >= 100, "{r:?}");
        assert_eq!(r.micro_triangles, 64 * r.base_triangles as u64);
        assert_eq!((r.misses, r.clamped), (0, 0), "{r:?}");
        let (welded, _) = WorldMesh::from(baked.mesh.decoded()).validate("baked").unwrap();
        assert_eq!(border_edges(&welded.triangles), 0);
        let base_only = BakeOptions { levels: 0, ..options };
        let base_error = symmetric_rms(&reference, &bake(&reference, &base_only).unwrap().mesh);
        let baked_error = symmetric_rms(&reference, &baked.mesh);
        assert!(baked_error < base_error / 10.0, "{baked_error} vs {base_error}");
        assert!(baked_error < 3e-4, "{baked_error}");
    }

    /// Fitting the values in the least-squares sense brings the micro-mesh closer to a curved
    /// surface than micro-vertices on it (whose flat micro-triangles all cut inside).
    #[test]
    fn the_least_squares_fit_is_closer_than_the_crossings() {
        let reference = sphere(5);
        let fitted = BakeOptions {
            base: Base::Decimated { triangles: 32 },
            ..BakeOptions::for_reference(&reference, 2)
        };
        let crossings = BakeOptions {
            refinement: Refinement {
                rounds: 0,
                ..fitted.refinement
            },
            ..fitted.clone()
        };
        let error = |options: &BakeOptions| symmetric_rms(&reference, &bake(&reference, options).unwrap().mesh);
        let (fitted, crossings) = (error(&fitted), error(&crossings));
        assert!(fitted < 0.5 * crossings, "{fitted} vs {crossings}");
    }

    /// What raw scans bring: repeated and reversed triangles, a fin, a hole and a second
    /// part. The bake still reaches its budget, keeps the second part, and stays close to
    /// the surface.
    #[test]
    fn raw_scan_defects_do_not_stop_the_bake() {
        let mut reference = sphere(5);
        let count = reference.triangles.len();
        for t in (0..count).step_by(7) {
            reference.triangles[t].swap(1, 2);
        }
        for t in (3..count).step_by(11) {
            let repeated = reference.triangles[t];
            reference.triangles.push(repeated);
        }
        let [a, b, _] = reference.triangles[5];
        reference.positions.push(Vec3::new(0.0, 0.0, 1.5));
        reference.triangles.push([a, b, reference.positions.len() as u32 - 1]);
        reference.triangles.drain(40..52);
        let part = sphere(3);
        let offset = reference.positions.len() as u32;
        reference
            .positions
            .extend(part.positions.iter().map(|p| *p * 0.3 + Vec3::new(3.0, 0.0, 0.0)));
        reference
            .triangles
            .extend(part.triangles.iter().map(|t| t.map(|i| i + offset)));

        let options = BakeOptions::for_reference(&reference, 3);
        let Base::Decimated { triangles: budget } = options.base else {
            unreachable!()
        };
        let baked = bake(&reference, &options).unwrap();
        let on_part = (baked.mesh.triangles.iter())
            .filter(|t| t.iter().all(|&i| baked.mesh.positions[i as usize].x > 2.0))
            .count();
        assert!(on_part >= 8, "{on_part} base triangles on the second part");
        assert!(
            baked.report.base_triangles <= budget + budget / 10,
            "{:?}",
            baked.report
        );
        // The fin stands out of the surface: no displacement of the sphere can hold it.
        let error = symmetric_rms(&reference, &baked.mesh);
        assert!(error < 2e-3, "{error}");
    }

    #[test]
    fn a_level_past_the_decoder_is_refused() {
        let reference = sphere(1);
        let options = BakeOptions::for_reference(&reference, 7);
        let e = bake(&reference, &options).unwrap_err();
        assert!(e.to_string().contains("level 7 is past the deepest"), "{e}");
    }
}
