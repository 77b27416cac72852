//! Refining baked values so the micro-mesh fits the reference in the least-squares sense,
//! rather than passing through points of it.
//!
//! The two passes put every micro-vertex *on* the reference. The flat micro-triangles between
//! those points then cut inside convex parts and stand outside concave ones, and a scan's
//! noise is kept wherever a lattice point happens to fall and lost elsewhere. Each round
//! here samples the reference by area, finds each sample's closest point on the micro-mesh,
//! and moves every micro-vertex along its line by the mean of the normal offsets of the
//! samples it carries, weighted by its barycentric share of each: a Jacobi step towards the
//! least-squares fit. Where all offsets near a vertex agree, the surface moves by exactly
//! that offset; where they differ, it settles between them.
//!
//! Only the reference's samples pull. Samples of the micro-mesh would pull too where it
//! spans a hole of the scan or a part too thin for the base to follow, towards a rim or the
//! other side, and make the fit worse there.
//!
//! Guarantees: each line (a lattice point's interpolated position and direction, equal bits
//! on every base triangle that shares it) keeps one value, so shared edges and corners stay
//! shared and the surface stays watertight; values stay within `[0, 1]`, the range fitted to
//! them; the result does not depend on the number of threads (samples are found in parallel
//! and summed in order); a round never reads a value it has already changed; a step is kept
//! only while it brings the reference's samples closer to the surface (their mean squared
//! offset), and the rounds end once a step no longer does, so more rounds never fit worse by
//! that measure.

use std::collections::HashMap;

use gridrt_shared::displacement::{decimated_point, interpolated, u_major_index, DisplacedTriangle};
use gridrt_shared::glam::{DVec3, Vec3};
use gridrt_shared::grid_index::{grid_size, lattice_points, sub_triangle, triangle_count};
use rayon::prelude::*;

use crate::mesh::Mesh;
use crate::micromesh::bary::values_per_triangle;
use crate::surface_distance::{area_samples, NearestTriangles, Sampling};

/// How far refinement goes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Refinement {
    /// Rounds of moving every micro-vertex (0 leaves the values where the rays put them).
    pub rounds: u32,
    /// Reference samples per micro-triangle, each round.
    pub samples: u32,
}

impl Default for Refinement {
    fn default() -> Self {
        Refinement { rounds: 2, samples: 3 }
    }
}

/// The most rounds a refinement takes: each costs a search of every sample, and a fit
/// settles in a few.
pub const MAX_ROUNDS: u32 = 100;

/// A lattice point's line lying this close to the tangent plane does not move the surface
/// enough, along its normal, to be moved by it: `(D . n)^2 < TANGENT * |D|^2`.
const TANGENT: f64 = 0.01;

/// How many samples are found at once before they are summed (bounds the memory they take).
const CHUNK: usize = 1 << 18;

/// The micro-vertex lines of a base mesh's lattices, each line once.
pub struct MicroLines {
    pub origins: Vec<Vec3>,
    pub directions: Vec<Vec3>,
    /// Per base triangle, the line of each of its values, in u-major order (a point of a
    /// decimated edge that the decoder moves takes the line of the point it moves to).
    pub of_triangle: Vec<Vec<u32>>,
    /// The micro-triangles, as lines (those a decimated edge collapses left out).
    pub micro_triangles: Vec<[u32; 3]>,
    /// The base triangle of each micro-triangle.
    pub owners: Vec<u32>,
}

impl MicroLines {
    /// The lines of `triangles` over `positions` and `directions` at `level`. Lattice points
    /// whose interpolated position and direction have the same bits are one line (a shared
    /// edge's or corner's points, seen from each side).
    pub fn new(positions: &[Vec3], directions: &[Vec3], triangles: &[[u32; 3]], level: u32) -> MicroLines {
        let levels = vec![level; triangles.len()];
        MicroLines::with_levels(positions, directions, triangles, (&levels, &[]))
    }

    /// The lines of `triangles`, triangle `t` at `levels.0[t]` with the edges of
    /// `levels.1[t]` decimated (as `DisplacedMesh::decimated_edges`; empty for none). Points
    /// are one line where their positions and directions at the finest level's lattice have
    /// the same bits, so a coarse triangle's points are the lines its finer neighbours see.
    pub fn with_levels(
        positions: &[Vec3],
        directions: &[Vec3],
        triangles: &[[u32; 3]],
        (levels, decimated): (&[u32], &[u8]),
    ) -> MicroLines {
        let finest = levels.iter().copied().max().unwrap_or(0);
        let big = grid_size(finest);
        let per_triangle: Vec<Vec<(Vec3, Vec3)>> = (triangles.par_iter().enumerate())
            .map(|(t, &ids)| {
                let triangle = DisplacedTriangle {
                    positions: ids.map(|i| positions[i as usize]),
                    directions: ids.map(|i| directions[i as usize]),
                    ids,
                };
                let (n, step) = (grid_size(levels[t]), 1 << (finest - levels[t]));
                let flags = decimated.get(t).copied().unwrap_or(0) as u32;
                let mut lines = vec![(Vec3::ZERO, Vec3::ZERO); values_per_triangle(levels[t])];
                for p in lattice_points(n) {
                    let [i, j] = decimated_point(p, n, flags);
                    lines[u_major_index(p, n) as usize] = interpolated(&triangle, [i * step, j * step], big);
                }
                lines
            })
            .collect();
        let mut ids = HashMap::with_capacity(per_triangle.iter().map(Vec::len).sum::<usize>() / 2);
        let (mut origins, mut line_directions) = (Vec::new(), Vec::new());
        let of_triangle: Vec<Vec<u32>> = (per_triangle.iter())
            .map(|lines| {
                (lines.iter())
                    .map(|&(o, d)| {
                        let key = (o.to_array().map(f32::to_bits), d.to_array().map(f32::to_bits));
                        *ids.entry(key).or_insert_with(|| {
                            origins.push(o);
                            line_directions.push(d);
                            origins.len() as u32 - 1
                        })
                    })
                    .collect()
            })
            .collect();
        let (mut micro_triangles, mut owners) = (Vec::new(), Vec::new());
        for (t, lines) in of_triangle.iter().enumerate() {
            let (l, n) = (levels[t], grid_size(levels[t]));
            for k in 0..triangle_count(l) {
                let [a, b, c] = sub_triangle(n, l, k).map(|p| lines[u_major_index(p, n) as usize]);
                if a != b && b != c && c != a {
                    micro_triangles.push([a, b, c]);
                    owners.push(t as u32);
                }
            }
        }
        MicroLines {
            origins,
            directions: line_directions,
            of_triangle,
            micro_triangles,
            owners,
        }
    }

    /// The micro-mesh that `values` (one per line) decode to.
    pub fn mesh(&self, values: &[f32]) -> Mesh {
        Mesh {
            positions: self.positions(values),
            triangles: self.micro_triangles.clone(),
        }
    }

    /// `values` (one per line) per base triangle, each triangle's in u-major order.
    pub fn per_triangle(&self, values: &[f32]) -> Vec<Vec<f32>> {
        (self.of_triangle.iter())
            .map(|of_triangle| of_triangle.iter().map(|&line| values[line as usize]).collect())
            .collect()
    }

    /// The points that `values` (one per line) decode to.
    fn positions(&self, values: &[f32]) -> Vec<Vec3> {
        (self.origins.iter().zip(&self.directions).zip(values))
            .map(|((&o, &d), &u)| o + d * u)
            .collect()
    }
}

/// Moves `values` (one per line of `lines`) for `refinement.rounds` rounds, so the micro-mesh
/// fits `reference`.
pub fn refine(reference: &Mesh, lines: &MicroLines, values: &mut [f32], refinement: &Refinement) {
    if refinement.rounds == 0 || lines.micro_triangles.is_empty() {
        return;
    }
    let rounds = refinement.rounds.min(MAX_ROUNDS);
    let sampling = Sampling {
        samples: refinement.samples as usize * lines.micro_triangles.len(),
        seed: 0x0ff5e7,
    };
    let samples = area_samples(reference, &sampling);
    let mut micro = lines.mesh(values);
    // The mean squared offset the values had before the last step, and those values.
    let mut before: Option<(f64, Vec<f32>)> = None;
    for round in 0..rounds {
        if round > 0 {
            micro.positions = lines.positions(values);
        }
        let nearest = NearestTriangles::new(&micro);
        let mut sums = Sums::new(values.len());
        for chunk in samples.chunks(CHUNK) {
            let found: Vec<Offset> = (chunk.par_iter())
                .filter_map(|&r| {
                    let c = nearest.closest(r)?;
                    Offset::new(&micro, c.triangle, c.point, r)
                })
                .collect();
            sums.add(lines, &micro, &found);
        }
        // A Jacobi step can overshoot where neighbouring lines pull on the same samples:
        // once a step no longer brings the surface closer by a share worth a round, the
        // values before it stay.
        let residual = sums.mean_squared_offset();
        if let Some((last, kept)) = &before {
            if residual > (1.0 - SETTLED) * last {
                values.copy_from_slice(kept);
                return;
            }
        }
        before = Some((residual, values.to_vec()));
        sums.apply(values);
    }
}

/// A step that brings the mean squared offset down by less than this share of it is undone
/// and ends the refinement: the fit has settled.
const SETTLED: f64 = 1e-3;

/// A sample's point on a micro-triangle, and how far along the triangle's normal the surface
/// should move there.
struct Offset {
    triangle: u32,
    weights: [f64; 3],
    normal: DVec3,
    along: f64,
}

impl Offset {
    /// The offset at `point` (on micro-triangle `t` of `micro`) towards `target`; `None` on a
    /// degenerate triangle.
    fn new(micro: &Mesh, t: usize, point: DVec3, target: DVec3) -> Option<Offset> {
        let [a, b, c] = micro.triangles[t].map(|i| micro.positions[i as usize].as_dvec3());
        let cross = (b - a).cross(c - a);
        let area2 = cross.length_squared();
        if area2.is_nan() || area2 <= 0.0 {
            return None;
        }
        let normal = cross / area2.sqrt();
        // Barycentrics by sub-triangle areas, clamped against rounding past the edges.
        let wb = (point - a).cross(c - a).dot(cross) / area2;
        let wc = (b - a).cross(point - a).dot(cross) / area2;
        let weights = [1.0 - wb - wc, wb, wc].map(|w| w.clamp(0.0, 1.0));
        Some(Offset {
            triangle: t as u32,
            weights,
            normal,
            along: (target - point).dot(normal),
        })
    }
}

/// Per line, the weighted sums whose ratio is its move.
struct Sums {
    moved: Vec<f64>,
    weight: Vec<f64>,
    /// The offsets' squares summed, and how many there were.
    squared: f64,
    offsets: usize,
}

impl Sums {
    fn new(lines: usize) -> Sums {
        Sums {
            moved: vec![0.0; lines],
            weight: vec![0.0; lines],
            squared: 0.0,
            offsets: 0,
        }
    }

    /// How far, squared and on average, the samples lay from the surface the sums were taken on.
    fn mean_squared_offset(&self) -> f64 {
        self.squared / self.offsets.max(1) as f64
    }

    /// Each offset's share, for each corner of its micro-triangle: the value change that
    /// moves the surface by the offset there, weighted by the corner's barycentric and by how
    /// squarely its line crosses the triangle.
    fn add(&mut self, lines: &MicroLines, micro: &Mesh, offsets: &[Offset]) {
        self.offsets += offsets.len();
        for o in offsets {
            self.squared += o.along * o.along;
            for (&line, &w) in micro.triangles[o.triangle as usize].iter().zip(&o.weights) {
                let d = lines.directions[line as usize].as_dvec3();
                let dn = d.dot(o.normal);
                if dn * dn < TANGENT * d.length_squared() {
                    continue;
                }
                self.moved[line as usize] += w * o.along * dn;
                self.weight[line as usize] += w * dn * dn;
            }
        }
    }

    fn apply(&self, values: &mut [f32]) {
        for ((u, &moved), &weight) in values.iter_mut().zip(&self.moved).zip(&self.weight) {
            if weight > 0.0 {
                *u = (*u as f64 + moved / weight).clamp(0.0, 1.0) as f32;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles sharing the edge between vertices 1 and 2, in opposite orientations.
    fn two_triangles() -> (Vec<Vec3>, Vec<Vec3>, Vec<[u32; 3]>) {
        let positions = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.3),
        ];
        let directions = vec![Vec3::Z, Vec3::new(0.1, 0.0, 1.0), Vec3::new(0.0, -0.2, 1.0), Vec3::Z];
        (positions, directions, vec![[0, 1, 2], [3, 2, 1]])
    }

    #[test]
    fn shared_edge_points_are_one_line() {
        let (positions, directions, triangles) = two_triangles();
        let lines = MicroLines::new(&positions, &directions, &triangles, 2);
        // Two lattices of 15 points share the 5 of their common edge.
        assert_eq!(lines.origins.len(), 25);
        assert_eq!(lines.micro_triangles.len(), 32);
        let shared = |t: usize| {
            lines.of_triangle[t]
                .iter()
                .copied()
                .collect::<std::collections::HashSet<_>>()
        };
        assert_eq!(shared(0).intersection(&shared(1)).count(), 5);
    }

    /// A flat reference above flat micro-triangles pulls every line up by the same offset,
    /// along directions that are not its normal.
    #[test]
    fn a_uniform_offset_is_met_in_one_round() {
        let (positions, directions, triangles) = two_triangles();
        let flat = |z: f32| -> Vec<Vec3> { positions.iter().map(|p| Vec3::new(p.x, p.y, z)).collect() };
        let base = flat(0.0);
        let lines = MicroLines::new(&base, &directions, &triangles[..1], 2);
        let reference = Mesh {
            positions: vec![
                Vec3::new(-1.0, -1.0, 0.25),
                Vec3::new(3.0, -1.0, 0.25),
                Vec3::new(-1.0, 3.0, 0.25),
            ],
            triangles: vec![[0, 1, 2]],
        };
        let mut values = vec![0.0; lines.origins.len()];
        let once = Refinement { rounds: 1, samples: 64 };
        refine(&reference, &lines, &mut values, &once);
        for (p, line) in lines.mesh(&values).positions.iter().zip(0..) {
            assert!((p.z - 0.25).abs() < 1e-5, "line {line} at {p}");
        }
    }
}
