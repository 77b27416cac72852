//! A level per base triangle: each base triangle of a bake takes its own level up to `L`,
//! flat regions coarse and detailed ones fine, as NVIDIA's displacement micro-map tools do,
//! so that a micro-mesh spends its bytes where the reference needs them.
//!
//! Every level `0 ..= L` is fitted to the reference on its own, on the one base mesh, folded
//! ranges and crossings of the level-`L` bake ([`fit_levels`]): a coarse triangle's values are
//! its own least-squares fit, not the level-`L` values subsampled, which keep the fine
//! surface's wiggles at the coarse points. Each fit's squared distances to the reference are
//! summed per base triangle, both ways (the reference's samples to the micro-mesh, the
//! micro-mesh's to the reference: a coarse triangle over a hole of a scan has few of the
//! first and far ones of the second). The levels then follow one trade of error against
//! bytes for the whole mesh (Lagrangian allocation: every triangle takes the level where a
//! byte saved would cost more squared error than one rate they all share), the rate found by
//! bisection for an error bound or a byte budget ([`choose_levels`]). Last, the micro-mesh of
//! the chosen levels is fitted once more as a whole, so that every point shared by triangles
//! of different levels has one value.
//!
//! Guarantees:
//! - Across every base edge the levels differ by at most one (coarse triangles are raised
//!   where a neighbour needs it, non-manifold edges included). The finer triangles of a level
//!   change decimate that edge (`DisplacedMesh::decimated_edges`, glTF's `primitiveFlags`):
//!   their odd points there move onto the coarser side's points, and the final fit gives
//!   each such point one value, so the surface stays watertight. The odd points store 0, as
//!   other tools' files do.
//! - The bound and the budget hold for the per-level fits (the symmetric RMS distance, and
//!   the packed values' bytes); the final fit moves the error a little, the bytes not at all.

use std::collections::HashMap;

use gridrt_shared::displacement::{decimated_point, u_major_index};
use gridrt_shared::glam::DVec3;
use gridrt_shared::grid_index::{grid_size, lattice_points, triangle_count};
use rayon::prelude::*;

use super::refine::{self, MicroLines};
use super::{fit, BakeOptions, Baked, Crossed};
use crate::error::Result;
use crate::mesh::Mesh;
use crate::micromesh::bary::{packed_bytes, Micromap};
use crate::micromesh::DisplacedMesh;
use crate::surface_distance::{area_samples, area_samples_on_triangles, NearestTriangles, Sampling};

/// What decides the levels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LevelTarget {
    /// The symmetric RMS distance between the reference and the micro-mesh (samples of each
    /// surface to the other), in the reference's units, in the fewest bytes.
    MaxError(f32),
    /// The packed values' bytes, at the least distance.
    MaxBytes(u64),
}

/// Bakes `reference` as `options` say, then gives each base triangle a level up to
/// `options.levels` for `target` (see the module docs).
pub fn bake_levels(reference: &Mesh, options: &BakeOptions, target: LevelTarget) -> Result<Baked> {
    LevelFitting::new(reference, options)?.bake(target)
}

/// A reference crossed and fitted at every level once, for levels chosen for as many
/// targets as a caller tries (as a byte budget of everything the GPU gets needs, whose bytes
/// are known only once the values are compressed).
pub struct LevelFitting<'a> {
    reference: &'a Mesh,
    options: &'a BakeOptions,
    crossed: Crossed,
    fits: LevelFits,
}

impl<'a> LevelFitting<'a> {
    pub fn new(reference: &'a Mesh, options: &'a BakeOptions) -> Result<Self> {
        let crossed = super::cross(reference, options)?;
        let fits = fit_levels(reference, &crossed, options);
        Ok(LevelFitting {
            reference,
            options,
            crossed,
            fits,
        })
    }

    /// Each base triangle at its level for `target`, fitted as a whole.
    pub fn bake(&self, target: LevelTarget) -> Result<Baked> {
        let levels = choose_levels(&self.crossed.triangles, &self.fits, target);
        let mesh = fitted_together(self.reference, &self.crossed, &self.fits, &levels, self.options);
        mesh.check()?;
        let mut report = self.crossed.report;
        report.micro_triangles = mesh.micro_triangles_at(crate::micromesh::MAX_LEVEL);
        Ok(Baked { mesh, report })
    }
}

/// The fits of every level, level 0 first, and how many samples (of both surfaces) measured
/// each.
pub struct LevelFits {
    pub levels: Vec<LevelFit>,
    pub samples: usize,
}

/// One level's fit: per base triangle, its values (u-major, in `[0, 1]`) and the sum of the
/// squared distances between it and the reference (see [`squared_error_by_triangle`]).
pub struct LevelFit {
    pub values: Vec<Vec<f32>>,
    pub squared_error: Vec<f64>,
}

/// The fits of every level `0 ..= options.levels`, measured with as many reference samples
/// per finest micro-triangle as refinement takes.
fn fit_levels(reference: &Mesh, crossed: &Crossed, options: &BakeOptions) -> LevelFits {
    let finest = options.levels;
    let per_micro = options.refinement.samples.max(1) as usize;
    let sampling = Sampling {
        samples: per_micro * crossed.triangles.len() * triangle_count(finest) as usize,
        seed: 0x1e7e15,
    };
    let samples = area_samples(reference, &sampling);
    let surface = NearestTriangles::new(reference);
    let levels = (0..=finest)
        .map(|level| {
            // As many samples as the finest level's fit, however few the micro-triangles.
            let refinement = refine::Refinement {
                samples: options.refinement.samples << (2 * (finest - level)),
                ..options.refinement
            };
            let (lines, values) = crossed.fitted(reference, level, &refinement);
            LevelFit {
                squared_error: squared_error_by_triangle(&lines, &values, (&samples, &surface)),
                values: lines.per_triangle(&values),
            }
        })
        .collect();
    LevelFits {
        levels,
        samples: 2 * samples.len(),
    }
}

/// Per base triangle, the summed squared distances between the micro-mesh of `values` on
/// `lines` and the reference, both ways: each of `samples` (on the reference) counted on the
/// micro-triangle closest to it, and as many samples of the micro-mesh, each counted on its
/// own, to the reference (`reference`).
fn squared_error_by_triangle(
    lines: &MicroLines,
    values: &[f32],
    (samples, reference): (&[DVec3], &NearestTriangles),
) -> Vec<f64> {
    let micro = lines.mesh(values);
    let nearest = NearestTriangles::new(&micro);
    let to_micro = (samples.par_iter()).filter_map(|&r| {
        let c = nearest.closest(r)?;
        Some((lines.owners[c.triangle], (c.point - r).length_squared()))
    });
    let sampling = Sampling {
        samples: samples.len(),
        seed: 0x0b5e55ed,
    };
    let on_micro = area_samples_on_triangles(&micro, &sampling);
    let to_reference = (on_micro.par_iter()).filter_map(|&(p, t)| {
        let q = reference.closest_point(p)?;
        Some((lines.owners[t as usize], (q - p).length_squared()))
    });
    let found: Vec<(u32, f64)> = to_micro.chain(to_reference).collect();
    let mut sums = vec![0.0; lines.of_triangle.len()];
    for (t, d2) in found {
        sums[t as usize] += d2;
    }
    sums
}

/// Each triangle's level for `target` (see the module docs), levels across every edge at
/// most one apart.
pub fn choose_levels(triangles: &[[u32; 3]], fits: &LevelFits, target: LevelTarget) -> Vec<u32> {
    let edges: Vec<Vec<usize>> = edge_triangles(triangles).into_values().collect();
    let pick = |rate: f64| -> (Vec<u32>, f64, u64) {
        let levels: Vec<u32> = (0..triangles.len())
            .map(|t| {
                (0..fits.levels.len() as u32)
                    .min_by(|&a, &b| {
                        let price = |l: u32| fits.levels[l as usize].squared_error[t] + rate * packed_bytes(l) as f64;
                        price(a).total_cmp(&price(b))
                    })
                    .unwrap_or(0)
            })
            .collect();
        let levels = balanced(&edges, levels);
        let error = (levels.iter().enumerate())
            .map(|(t, &l)| fits.levels[l as usize].squared_error[t])
            .sum();
        let bytes = levels.iter().map(|&l| packed_bytes(l) as u64).sum();
        (levels, error, bytes)
    };
    // A larger rate trades more error for fewer bytes: the largest rate within the bound, or
    // the smallest within the budget.
    let fits_target = |(_, error, bytes): &(Vec<u32>, f64, u64)| match target {
        LevelTarget::MaxError(e) => *error <= (e as f64).powi(2) * fits.samples as f64,
        LevelTarget::MaxBytes(b) => *bytes <= b,
    };
    let low_fits = matches!(target, LevelTarget::MaxError(_));
    let rate = crate::lagrangian::bisect_rate(low_fits, |rate| fits_target(&pick(rate)));
    pick(rate).0
}

/// Levels raised until those across every edge (`edges`: the triangles around each) differ
/// by at most one. Raising only ever increases levels, up to the finest given: this ends.
fn balanced(edges: &[Vec<usize>], mut levels: Vec<u32>) -> Vec<u32> {
    loop {
        let mut changed = false;
        for around in edges {
            let finest = around.iter().map(|&t| levels[t]).max().unwrap_or(0);
            for &t in around {
                if levels[t] + 1 < finest {
                    levels[t] = finest - 1;
                    changed = true;
                }
            }
        }
        if !changed {
            return levels;
        }
    }
}

/// The triangles around each edge (a pair of vertex ids, smaller first).
fn edge_triangles(triangles: &[[u32; 3]]) -> HashMap<(u32, u32), Vec<usize>> {
    let mut edges: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for (t, v) in triangles.iter().enumerate() {
        for e in 0..3 {
            let (a, b) = (v[e], v[(e + 1) % 3]);
            edges.entry((a.min(b), a.max(b))).or_default().push(t);
        }
    }
    edges
}

/// Each triangle's edges towards a neighbour one level coarser (see
/// `DisplacedMesh::decimated_edges`).
pub fn decimated_edges(triangles: &[[u32; 3]], levels: &[u32]) -> Vec<u8> {
    let edges = edge_triangles(triangles);
    (triangles.iter().enumerate())
        .map(|(t, v)| {
            (0..3).fold(0u8, |flags, e| {
                let (a, b) = (v[e], v[(e + 1) % 3]);
                let coarser = edges[&(a.min(b), a.max(b))].iter().any(|&o| levels[o] + 1 == levels[t]);
                flags | (coarser as u8) << e
            })
        })
        .collect()
}

/// The micro-mesh of `levels`, its edges towards coarser neighbours decimated, its values
/// those of each triangle's level fit, fitted once more as a whole.
fn fitted_together(
    reference: &Mesh,
    crossed: &Crossed,
    fits: &LevelFits,
    levels: &[u32],
    options: &BakeOptions,
) -> DisplacedMesh {
    let flags = decimated_edges(&crossed.triangles, levels);
    let (positions, directions, triangles) = crossed.folded();
    let lines = MicroLines::with_levels(positions, directions, triangles, (levels, &flags));
    // A point the decoder moves takes the value of the point it moves to, from that point's
    // own triangle.
    let moved = |t: usize, p| decimated_point(p, grid_size(levels[t]), flags[t] as u32) != p;
    let mut values = vec![0.0f32; lines.origins.len()];
    for (t, of_triangle) in lines.of_triangle.iter().enumerate() {
        let (own, n) = (&fits.levels[levels[t] as usize].values[t], grid_size(levels[t]));
        for p in lattice_points(n).filter(|&p| !moved(t, p)) {
            let k = u_major_index(p, n) as usize;
            values[of_triangle[k] as usize] = own[k];
        }
    }
    refine::refine(reference, &lines, &mut values, &options.refinement);
    let stored: Vec<(u32, Vec<u16>)> = (lines.of_triangle.iter().enumerate())
        .map(|(t, of_triangle)| {
            let n = grid_size(levels[t]);
            let mut own = vec![0u16; of_triangle.len()];
            for p in lattice_points(n).filter(|&p| !moved(t, p)) {
                let k = u_major_index(p, n) as usize;
                own[k] = fit::quantize(values[of_triangle[k] as usize]);
            }
            (levels[t], own)
        })
        .collect();
    let decimated = flags.iter().any(|&f| f != 0);
    DisplacedMesh {
        positions: crossed.positions.clone(),
        directions: crossed.directions.clone(),
        triangles: crossed.triangles.clone(),
        micromap: Micromap::from_triangles(0.0, 1.0, &stored),
        decimated_edges: if decimated { flags } else { Vec::new() },
    }
}

/// Micro-triangles of each level `0 ..= 6` in `mesh`, as rendered (less those that decimated
/// edges collapse).
pub fn level_counts(mesh: &DisplacedMesh) -> Vec<u64> {
    let deepest = crate::micromesh::MAX_LEVEL;
    let mut counts = vec![0u64; deepest as usize + 1];
    for (t, triangle) in mesh.micromap.triangles.iter().enumerate() {
        counts[triangle.level as usize] += mesh.rendered_micro_triangles(t, deepest);
    }
    counts
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::WorldMesh;
    use crate::micromesh::bake::tests::{border_edges, sphere, symmetric_rms};
    use crate::micromesh::bake::Base;

    /// Fits of a strip of four triangles (0-1-2-3 in a row) at levels 0 to 3: the first two
    /// flat (level 0 as good as any), the third gaining little past level 1, the last
    /// everything up to level 3.
    fn strip_fits() -> ([[u32; 3]; 4], LevelFits) {
        let triangles = [[0, 2, 1], [1, 2, 3], [2, 4, 3], [3, 4, 5]];
        let errors = [
            [0.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 0.0],
            [8.0, 1.0, 0.9, 0.85],
            [900.0, 400.0, 100.0, 1.0],
        ];
        let levels = (0..4)
            .map(|l| LevelFit {
                values: vec![vec![0.0; crate::micromesh::bary::values_per_triangle(l as u32)]; 4],
                squared_error: errors.iter().map(|e| e[l]).collect(),
            })
            .collect();
        (triangles, LevelFits { levels, samples: 100 })
    }

    /// Flat triangles go as coarse as their neighbours allow, the detailed one as fine as the
    /// budget allows; levels step by one across edges, and the finer side of each step
    /// decimates it.
    #[test]
    fn levels_follow_the_error_and_step_by_one() {
        let (triangles, fits) = strip_fits();
        let bytes = |levels: &[u32]| levels.iter().map(|&l| packed_bytes(l) as u64).sum::<u64>();
        // A sum of squares of 2.05 over 100 samples: the last triangle at level 3, the third
        // at level 1, raised to 2 beside it, and so on down the strip.
        let fine = choose_levels(
            &triangles,
            &fits,
            LevelTarget::MaxError(0.2050f32.sqrt() / 10f32.sqrt()),
        );
        assert_eq!(fine, vec![0, 1, 2, 3]);
        assert_eq!(decimated_edges(&triangles, &fine), vec![0, 0b001, 0b100, 0b001]);
        // A byte less takes the detailed triangle down a level, and its neighbours with it.
        let budget = bytes(&fine) - 1;
        let fewer = choose_levels(&triangles, &fits, LevelTarget::MaxBytes(budget));
        assert!(bytes(&fewer) <= budget, "{fewer:?}");
        assert_eq!(fewer, vec![0, 0, 1, 2]);
        // A loose bound leaves everything at level 0.
        let coarse = choose_levels(&triangles, &fits, LevelTarget::MaxError(10.0));
        assert_eq!(coarse, vec![0, 0, 0, 0]);
    }

    /// A unit hemisphere, bumpy, on a flat disc.
    fn bumpy_dome() -> Mesh {
        let mut mesh = sphere(5);
        for p in &mut mesh.positions {
            if p.z > 0.0 {
                let bump = 0.03 * (14.0 * p.x).sin() * (14.0 * p.y).sin() * p.z;
                *p *= 1.0 + bump;
            } else {
                p.z = 0.0;
            }
        }
        mesh
    }

    /// At the bytes of a uniform bake, levels per triangle come closer to a surface of
    /// uneven detail, and stay watertight.
    #[test]
    fn at_equal_bytes_levels_per_triangle_beat_one_level() {
        let reference = bumpy_dome();
        let options = BakeOptions {
            base: Base::Decimated { triangles: 128 },
            ..BakeOptions::for_reference(&reference, 2)
        };
        let uniform = crate::micromesh::bake::bake(&reference, &options).unwrap().mesh;
        let budget = (uniform.triangles.len() * packed_bytes(2)) as u64;
        let finer = BakeOptions { levels: 3, ..options };
        let mixed = bake_levels(&reference, &finer, LevelTarget::MaxBytes(budget)).unwrap();
        let stored: u64 = (mixed.mesh.micromap.triangles.iter())
            .map(|t| packed_bytes(t.level) as u64)
            .sum();
        assert!(stored <= budget, "{stored} > {budget}");
        let (mixed_error, uniform_error) = (
            symmetric_rms(&reference, &mixed.mesh),
            symmetric_rms(&reference, &uniform),
        );
        assert!(mixed_error < 0.9 * uniform_error, "{mixed_error} vs {uniform_error}");

        // It spends bytes saved on some triangles on others.
        let levels: Vec<u32> = mixed.mesh.micromap.triangles.iter().map(|t| t.level).collect();
        assert!(levels.contains(&3) && levels.iter().any(|&l| l < 2), "{levels:?}");
        assert!(!mixed.mesh.decimated_edges.is_empty());
        let (welded, _) = WorldMesh::from(mixed.mesh.decoded()).validate("mixed").unwrap();
        assert_eq!(border_edges(&welded.triangles), 0);
        assert_eq!(mixed.mesh.open_seams(), 0);
    }

    /// Seams whose sides render different levels are counted: none in a bake, one for each
    /// edge whose flag is cleared, and the flagged edges of a triangle raised a level above
    /// its coarser neighbours.
    #[test]
    fn open_seams_are_counted() {
        let [(_, mixed), _] = mixed_domes();
        assert_eq!(mixed.open_seams(), 0);
        let flags = |t: usize| mixed.decimated(t).count_ones() as usize;
        let flagged: usize = (0..mixed.triangles.len()).map(flags).sum();
        assert!(flagged > 0);
        let mut unflagged = mixed.clone();
        unflagged.decimated_edges.iter_mut().for_each(|f| *f = 0);
        assert_eq!(unflagged.open_seams(), flagged);
        let t = (0..mixed.triangles.len()).find(|&t| flags(t) > 0).unwrap();
        let mut raised = mixed.clone();
        raised.micromap.triangles[t].level += 1;
        assert!(raised.open_seams() >= flags(t), "{}", raised.open_seams());
    }

    /// The dome baked up to level 3 within the bytes of level 2 (triangles of levels 0 to 3,
    /// with decimated edges): its values plain, and compressed.
    fn mixed_domes() -> [(&'static str, DisplacedMesh); 2] {
        mixed_domes_up_to(3)
    }

    /// The dome baked up to level `levels` within the bytes of the level above.
    fn mixed_domes_up_to(levels: u32) -> [(&'static str, DisplacedMesh); 2] {
        let reference = bumpy_dome();
        let options = BakeOptions {
            base: Base::Decimated { triangles: 128 },
            ..BakeOptions::for_reference(&reference, levels)
        };
        let budget = (128 * packed_bytes(levels - 1)) as u64;
        let plain = bake_levels(&reference, &options, LevelTarget::MaxBytes(budget))
            .unwrap()
            .mesh;
        let compression = crate::grid::compressed::ValueCompression::bounded(2e-4);
        let compressed = crate::grid::compressed::compress(&plain, &compression).unwrap().mesh;
        [("plain", plain), ("compressed", compressed)]
    }

    /// Displaced grids of mixed levels read back each triangle's own decoded points, at the
    /// scene's lattice points of its own level, moved as its decimated edges move them.
    #[test]
    fn grids_of_mixed_levels_read_back_their_points() {
        use gridrt_shared::grid_index::{grid_size, lattice_points};
        for (variant, mixed) in mixed_domes() {
            let levels: Vec<u32> = mixed.micromap.triangles.iter().map(|t| t.level).collect();
            assert!(levels.contains(&3) && levels.iter().any(|&l| l < 2), "{levels:?}");
            let grids = crate::grid::displaced::build(&mixed, &crate::grid::GridOptions::for_displaced()).unwrap();
            assert_ne!(grids.params.level_element, 0);
            assert_eq!(grids.params.displaced == 2, variant == "compressed");
            let folded = mixed.with_ranges_folded();
            let rendered = mixed.decoded_welded().triangles.len() as u64;
            assert_eq!(
                mixed.micro_triangles_at(3),
                rendered,
                "{variant}: the count less the collapsed"
            );
            // Their headers widened too, which keeps their level bytes.
            for grids in [grids.clone(), grids.with_wide_headers()] {
                let view = grids.view();
                for (slot, &t) in grids.base_triangle.iter().enumerate() {
                    let open = view.open(slot as u32);
                    let shift = 3 - levels[t as usize];
                    let expected = folded.micro_vertices(t as usize);
                    for (q, want) in lattice_points(grid_size(levels[t as usize])).zip(expected) {
                        let got = view.vertex(&open, [q[0] << shift, q[1] << shift]);
                        assert_eq!(got, want, "{variant}: triangle {t} at {q:?}");
                    }
                }
            }
        }
    }

    /// Plain values of mixed levels take their own levels' bits: each grid's block its own
    /// level's inner points, each base edge's block the points of the finest level it is
    /// rendered at, after their tables; the sizes checked before a build bound them below.
    #[test]
    fn plain_grids_of_mixed_levels_store_their_own_levels() {
        use gridrt_shared::grid_index::inner_vertex_count;
        use gridrt_shared::grid_traverse::DISPLACEMENT_BITS;
        use gridrt_shared::value_tables::EDGE_LEVEL_WORDS;
        let [(_, plain), _] = mixed_domes();
        let options = crate::grid::GridOptions::for_displaced();
        let grids = crate::grid::displaced::build(&plain, &options).unwrap();
        let p = grids.params;
        let bits = DISPLACEMENT_BITS as u64;
        let inner: u64 = (plain.micromap.triangles.iter())
            .map(|t| inner_vertex_count(t.level) as u64 * bits)
            .sum();
        let table = (plain.triangles.len() as u64 * p.block_offset_bits as u64).div_ceil(32);
        assert_eq!(p.edge_word as u64, table + inner.div_ceil(32));
        let mut edges = std::collections::HashMap::new();
        for (t, corners) in plain.triangles.iter().enumerate() {
            for e in 0..3 {
                let (a, b) = (corners[e], corners[(e + 1) % 3]);
                let level = edges.entry((a.min(b), a.max(b))).or_insert(0);
                *level = plain.rendered_edge_level(t, e).max(*level);
            }
        }
        let edge_bits: u64 = edges.values().map(|&l| ((1u64 << l) - 1) * bits).sum();
        assert_eq!(
            (p.corner_bit - 32 * p.edge_word) as u64,
            32 * EDGE_LEVEL_WORDS as u64 + edge_bits
        );
        let sizes = crate::grid::displaced::least_buffer_sizes(&plain, &options).unwrap();
        let vertex = sizes.iter().find(|s| s.name == "grid vertex").unwrap();
        assert!(
            vertex.bytes <= 4 * grids.vertices.len() as u64,
            "{} bytes",
            vertex.bytes
        );
    }

    /// Grids of mixed levels in rooms of their own levels (`GridParams::own_rooms`), and in the
    /// scene's room when asked: either way, every sphere down to the grid's leaves holds the
    /// points the grid renders below it, and each leaf's thickness bounds how far those points
    /// lie from the leaf's flat triangle. Own rooms are taken where they take fewer words than
    /// the scene's room: at level 4 they do.
    #[test]
    fn grids_of_mixed_levels_keep_conservative_spheres() {
        use crate::grid::GridOptions;
        use gridrt_shared::grid_index::{grid_size, level_start, sub_triangle, triangle_count};
        use gridrt_shared::grid_traverse::sphere_center;
        for deepest in [3, 4] {
            for (variant, mixed) in mixed_domes_up_to(deepest) {
                let levels: Vec<u32> = mixed.micromap.triangles.iter().map(|t| t.level).collect();
                let coarse_level = levels.iter().any(|&l| l + 1 < deepest);
                assert!(levels.contains(&deepest) && coarse_level, "{variant}: {levels:?}");
                let build = |own_rooms| {
                    let options = GridOptions {
                        own_rooms,
                        ..GridOptions::for_displaced()
                    };
                    crate::grid::displaced::build(&mixed, &options).unwrap()
                };
                let (own, shared) = (build(true), build(false));
                assert_eq!(shared.params.own_rooms, 0, "{variant}");
                assert!(own.params.own_rooms != 0 || deepest < 4, "{variant}");
                for grids in [&own, &shared] {
                    let thick = check_spheres(grids);
                    assert!(thick > 0, "{variant}: every leaf was flat");
                }
                assert!(
                    own.radii.len() < shared.radii.len() || own.params.own_rooms == 0,
                    "{variant}: {} words, {} in the scene's room",
                    own.radii.len(),
                    shared.radii.len()
                );
            }
        }

        /// Checks every grid's spheres and leaf thicknesses; the number of leaves not flat.
        fn check_spheres(grids: &crate::grid::GridScene) -> usize {
            let params = grids.params;
            let n = grid_size(params.levels);
            let view = grids.view();
            let mut thick = 0;
            for slot in 0..grids.grid_count() as u32 {
                let open = view.open(slot);
                let own = view.own_level(&open);
                let leaf_level = open.spheres.leaf_level;
                match params.own_rooms {
                    0 => assert_eq!(leaf_level, params.leaf_level),
                    _ => assert_eq!(leaf_level, (own + params.leaf_level).saturating_sub(params.levels)),
                }
                let at = |p: [u32; 2]| view.vertex(&open, p);
                for level in 0..=leaf_level.min(own) {
                    for index in 0..triangle_count(level) {
                        let c = sub_triangle(n, level, index);
                        let center = sphere_center(at(c[0]), at(c[1]), at(c[2]));
                        let r = view.radius(&open, level_start(level) + index);
                        let below = own - level;
                        for t in 0..triangle_count(below) {
                            for p in sub_triangle(n, own, index * triangle_count(below) + t) {
                                let d = at(p).distance(center);
                                assert!(d <= r, "grid {slot}, level {level}: {d} outside {r}");
                            }
                        }
                    }
                }
                // Leaves deeper than the grid are never reached: its walk stops at its level.
                if params.leaf_footprint == 0 || own < leaf_level {
                    continue;
                }
                let m = 1i32 << (own - leaf_level);
                for leaf in 0..triangle_count(leaf_level) {
                    let lattice = sub_triangle(n, leaf_level, leaf).map(|p| [p[0] as i32, p[1] as i32]);
                    let d = view.thickness(&open, leaf, view.radius(&open, level_start(leaf_level) + leaf));
                    let moved = crate::grid::tests::farthest_from_flat(lattice, m, at);
                    assert!(moved <= d, "grid {slot}: moved {moved}, thickness {d}");
                    thick += (moved > 0.0) as usize;
                }
            }
            thick
        }
    }
}
