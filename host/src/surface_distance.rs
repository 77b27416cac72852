//! The distance between two triangle surfaces, as mesh simplification and baking papers report
//! it: points sampled uniformly by area on each surface, each point's exact distance to the
//! closest point of the other surface (through a BVH over its triangles), and the root mean
//! square, 99th percentile and maximum of those distances, each way and both ways together.
//!
//! Guarantees: every distance is the exact point-to-triangle distance (closest point by the
//! Voronoi regions of the triangle, computed in `f64`), found by a nearest-point walk that
//! prunes only boxes farther than the best distance so far, so the result is the brute-force
//! one. Sampling is stratified by area (sample `k` of `n` falls at `(k + u) / n` of the
//! surface's cumulative area) and seeded, so a measurement is repeatable and its samples cover
//! every large triangle; zero-area triangles get none. The maximum over samples is a lower
//! bound of the Hausdorff distance, approaching it as samples grow.

use rayon::prelude::*;

use crate::bvh::{self, Aabb, BuildParams};
use crate::error::Result;
use crate::mesh::Mesh;
use gridrt_shared::glam::{DVec3, Vec3};
use gridrt_shared::layout::BvhNode;

/// How many points to sample on each surface, and the seed they are drawn from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sampling {
    pub samples: usize,
    pub seed: u64,
}

impl Default for Sampling {
    fn default() -> Self {
        Sampling {
            samples: 1_000_000,
            seed: 0x5eed,
        }
    }
}

/// Peak host bytes per sample of [`measure`], both surfaces' samples together: a side's
/// points (24 B each) and distances (8 B) alive with the other side's distances (8 B), and
/// rounded up for the threads' collection.
pub const BYTES_PER_SAMPLE: u64 = 48;

/// Refuses, before any work, `samples` per surface whose [`measure`] would not fit in
/// memory (see [`crate::limits`]); `option` names the option that set them.
pub fn check_samples(samples: usize, option: &str) -> Result<()> {
    crate::limits::check_memory(
        (samples as u64).saturating_mul(BYTES_PER_SAMPLE),
        crate::limits::available_memory()?,
        &format!("measuring {samples} samples per surface ({option})"),
        &format!("give fewer {option}"),
    )
}

/// The area of `mesh`'s triangles, in its units squared.
pub fn area(mesh: &Mesh) -> f64 {
    mesh.triangles.iter().map(|t| triangle_area(mesh, t)).sum()
}

/// The area of triangle `t` of `mesh`, in `f64`.
fn triangle_area(mesh: &Mesh, t: &[u32; 3]) -> f64 {
    let [a, b, c] = t.map(|i| mesh.positions[i as usize].as_dvec3());
    (b - a).cross(c - a).length() * 0.5
}

/// Refuses a surface without area (every triangle's corners on one line): no point can be
/// sampled on it, and a distance from it would be no measure. `name` is its file.
pub fn check_area(mesh: &Mesh, name: &str) -> Result<()> {
    let area = area(mesh);
    if area.is_nan() || area <= 0.0 {
        crate::error::fail!(
            Input,
            "{name}: the surface has no area: every triangle's corners lie on one line, so no distance can be measured from it"
        );
    }
    Ok(())
}

/// Distances from points on one surface to the other surface, in the meshes' units.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct DistanceSummary {
    pub rms: f64,
    pub p99: f64,
    pub max: f64,
    pub samples: usize,
}

impl DistanceSummary {
    /// The summary of `distances` (which it sorts).
    pub fn of(distances: &mut [f64]) -> DistanceSummary {
        if distances.is_empty() {
            return DistanceSummary::default();
        }
        distances.sort_unstable_by(f64::total_cmp);
        let n = distances.len();
        let squares: f64 = distances.iter().map(|d| d * d).sum();
        // The nearest-rank percentile: the smallest distance at or above 99% of the samples.
        let rank = (0.99 * n as f64).ceil() as usize;
        DistanceSummary {
            rms: (squares / n as f64).sqrt(),
            p99: distances[rank.clamp(1, n) - 1],
            max: distances[n - 1],
            samples: n,
        }
    }

    /// Every figure divided by `length` (a bounding-box diagonal, say).
    pub fn relative_to(&self, length: f64) -> DistanceSummary {
        DistanceSummary {
            rms: self.rms / length,
            p99: self.p99 / length,
            max: self.max / length,
            samples: self.samples,
        }
    }
}

/// The distance between surfaces A and B, each way and both ways together (the samples of
/// both directions pooled: the symmetric figures).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct SurfaceDistance {
    pub a_to_b: DistanceSummary,
    pub b_to_a: DistanceSummary,
    pub symmetric: DistanceSummary,
    /// A's bounding-box diagonal, the length the figures are usually given as fractions of.
    pub a_diagonal: f64,
}

/// Measures the distance between surfaces `a` and `b` (in the same frame and units).
pub fn measure(a: &Mesh, b: &Mesh, sampling: &Sampling) -> SurfaceDistance {
    let (to_a, to_b) = rayon::join(|| NearestTriangles::new(a), || NearestTriangles::new(b));
    let mut a_b = distances(&area_samples(a, sampling), &to_b);
    let mut b_a = distances(
        &area_samples(
            b,
            &Sampling {
                seed: sampling.seed ^ 0x9e37_79b9_7f4a_7c15,
                ..*sampling
            },
        ),
        &to_a,
    );
    let mut both: Vec<f64> = a_b.iter().chain(&b_a).copied().collect();
    let (lo, hi) = a.bounds();
    SurfaceDistance {
        a_to_b: DistanceSummary::of(&mut a_b),
        b_to_a: DistanceSummary::of(&mut b_a),
        symmetric: DistanceSummary::of(&mut both),
        a_diagonal: (hi - lo).as_dvec3().length(),
    }
}

/// Each point's distance to the surface, on all cores.
fn distances(points: &[DVec3], surface: &NearestTriangles) -> Vec<f64> {
    points.par_iter().map(|&p| surface.distance(p)).collect()
}

/// `sampling.samples` points on the surface, stratified by area (see the module docs).
pub fn area_samples(mesh: &Mesh, sampling: &Sampling) -> Vec<DVec3> {
    samples_as(mesh, sampling, |point, _| point)
}

/// [`area_samples`], each with the index of the triangle it lies on.
pub fn area_samples_on_triangles(mesh: &Mesh, sampling: &Sampling) -> Vec<(DVec3, u32)> {
    samples_as(mesh, sampling, |point, t| (point, t))
}

/// The samples of [`area_samples`], each `sample(point, triangle)`.
fn samples_as<T: Send>(mesh: &Mesh, sampling: &Sampling, sample: impl Fn(DVec3, u32) -> T + Sync) -> Vec<T> {
    let corners = |t: &[u32; 3]| t.map(|i| mesh.positions[i as usize].as_dvec3());
    let mut cumulative = Vec::with_capacity(mesh.triangles.len());
    let mut total = 0.0f64;
    for t in &mesh.triangles {
        total += triangle_area(mesh, t);
        cumulative.push(total);
    }
    if total.is_nan() || total <= 0.0 || sampling.samples == 0 {
        return Vec::new();
    }
    let n = sampling.samples;
    (0..n)
        .into_par_iter()
        .map(|k| {
            let mut rng = SplitMix(sampling.seed.wrapping_add(k as u64).wrapping_mul(0xbf58_476d_1ce4_e5b9));
            let at = (k as f64 + rng.unit()) / n as f64 * total;
            let t = cumulative.partition_point(|&c| c <= at).min(cumulative.len() - 1);
            let [a, b, c] = corners(&mesh.triangles[t]);
            // Uniform on the triangle: the square root folds the unit square onto it evenly.
            let (r1, r2) = (rng.unit().sqrt(), rng.unit());
            sample(a * (1.0 - r1) + b * (r1 * (1.0 - r2)) + c * (r1 * r2), t as u32)
        })
        .collect()
}

/// A small seeded generator (SplitMix64): repeatable samples without a dependency.
struct SplitMix(u64);

impl SplitMix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`.
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// A surface's triangles under a BVH, for closest-point queries.
pub struct NearestTriangles {
    nodes: Vec<BvhNode>,
    /// The triangles' corners, in the hierarchy's leaf order.
    triangles: Vec<[DVec3; 3]>,
    /// Each leaf-order triangle's index in the mesh.
    order: Vec<u32>,
}

/// The point of a surface closest to a query point, and the triangle it lies on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosestPoint {
    pub point: DVec3,
    /// The triangle's index in the mesh the query was built from.
    pub triangle: usize,
}

impl NearestTriangles {
    pub fn new(mesh: &Mesh) -> NearestTriangles {
        let corners = |t: &[u32; 3]| t.map(|i| mesh.positions[i as usize]);
        let boxes: Vec<Aabb> = (mesh.triangles.par_iter())
            .map(|t| Aabb::from_points(corners(t)))
            .collect();
        let bvh = bvh::build(&boxes, &BuildParams::default());
        let triangles = (bvh.order.iter())
            .map(|&k| corners(&mesh.triangles[k as usize]).map(Vec3::as_dvec3))
            .collect();
        NearestTriangles {
            nodes: bvh.nodes,
            triangles,
            order: bvh.order,
        }
    }

    /// The distance from `p` to the closest point of the surface (infinite when it has no
    /// triangles).
    pub fn distance(&self, p: DVec3) -> f64 {
        self.closest_point(p).map_or(f64::INFINITY, |q| p.distance(q))
    }

    /// The point of the surface closest to `p` (`None` when it has no triangles).
    pub fn closest_point(&self, p: DVec3) -> Option<DVec3> {
        self.closest(p).map(|c| c.point)
    }

    /// The point of the surface closest to `p` and its triangle (`None` when it has no
    /// triangles).
    pub fn closest(&self, p: DVec3) -> Option<ClosestPoint> {
        let mut best = (f64::INFINITY, None);
        if self.nodes.is_empty() {
            return None;
        }
        let mut stack = vec![(0usize, box_distance_squared(&self.nodes[0], p))];
        while let Some((i, d2)) = stack.pop() {
            if d2 >= best.0 {
                continue;
            }
            let node = &self.nodes[i];
            if node.is_leaf() {
                let range = node.first as usize..(node.first + node.count) as usize;
                for k in range {
                    let q = closest_point_on_triangle(p, &self.triangles[k]);
                    let d2 = p.distance_squared(q);
                    if d2 < best.0 {
                        let triangle = self.order[k] as usize;
                        best = (d2, Some(ClosestPoint { point: q, triangle }));
                    }
                }
                continue;
            }
            // The nearer child is popped first, so its leaves shrink `best` before the other.
            let children = [node.first as usize, node.first as usize + 1];
            let [near, far] = children.map(|c| (c, box_distance_squared(&self.nodes[c], p)));
            let (near, far) = if near.1 <= far.1 { (near, far) } else { (far, near) };
            stack.push(far);
            stack.push(near);
        }
        best.1
    }
}

fn box_distance_squared(node: &BvhNode, p: DVec3) -> f64 {
    let (lo, hi) = (Vec3::from(node.min).as_dvec3(), Vec3::from(node.max).as_dvec3());
    let outside = (lo - p).max(p - hi).max(DVec3::ZERO);
    outside.length_squared()
}

/// The point of triangle `t` closest to `p`: found by which Voronoi region of the triangle
/// (a corner's, an edge's or the face's) `p` lies in, from dot products of `p`'s offsets with
/// the edges.
pub fn closest_point_on_triangle(p: DVec3, t: &[DVec3; 3]) -> DVec3 {
    let [a, b, c] = *t;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let sum = va + vb + vc;
    if sum.is_nan() || sum <= 0.0 {
        // A degenerate triangle: its closest point is on one of its edges.
        return [(a, b), (b, c), (c, a)]
            .map(|(s, e)| closest_point_on_segment(p, s, e))
            .into_iter()
            .min_by(|x, y| p.distance_squared(*x).total_cmp(&p.distance_squared(*y)))
            .unwrap_or(a);
    }
    a + ab * (vb / sum) + ac * (vc / sum)
}

fn closest_point_on_segment(p: DVec3, s: DVec3, e: DVec3) -> DVec3 {
    let d = e - s;
    let length2 = d.length_squared();
    if length2 == 0.0 {
        return s;
    }
    s + d * ((p - s).dot(d) / length2).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(z: f32) -> Mesh {
        Mesh {
            positions: vec![
                Vec3::new(0.0, 0.0, z),
                Vec3::new(1.0, 0.0, z),
                Vec3::new(1.0, 1.0, z),
                Vec3::new(0.0, 1.0, z),
            ],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        }
    }

    fn few() -> Sampling {
        Sampling {
            samples: 20_000,
            seed: 7,
        }
    }

    #[test]
    fn a_surface_is_at_no_distance_from_itself() {
        let d = measure(&square(0.0), &square(0.0), &few());
        // Zero up to the rounding of the closest point's barycentric arithmetic.
        assert!(d.symmetric.max < 1e-15, "{:?}", d.symmetric);
        assert_eq!(d.symmetric.samples, 40_000);
    }

    /// Two parallel squares 0.25 apart: every point is 0.25 from the other.
    #[test]
    fn parallel_squares_are_their_gap_apart() {
        let d = measure(&square(0.0), &square(0.25), &few());
        for s in [d.a_to_b, d.b_to_a, d.symmetric] {
            assert!((s.rms - 0.25).abs() < 1e-6 && (s.max - 0.25).abs() < 1e-6, "{s:?}");
        }
        assert!((d.a_diagonal - 2f64.sqrt()).abs() < 1e-12);
        let relative = d.symmetric.relative_to(d.a_diagonal);
        assert!((relative.rms - 0.25 / 2f64.sqrt()).abs() < 1e-6);
    }

    /// A square against a half of it: from the half, no distance; from the other half, up to
    /// the diagonal's distance to the cut (the far corner, sqrt(2)/2 away).
    #[test]
    fn the_directions_differ_where_one_surface_covers_less() {
        let half = Mesh {
            triangles: vec![[0, 1, 2]],
            ..square(0.0)
        };
        let d = measure(&square(0.0), &half, &few());
        assert!(d.b_to_a.max < 1e-15, "{:?}", d.b_to_a);
        let corner = 0.5f64.sqrt();
        assert!(
            d.a_to_b.max <= corner + 1e-9 && d.a_to_b.max > 0.95 * corner,
            "{:?}",
            d.a_to_b
        );
        // Half the square's samples are on the half itself.
        assert!(d.a_to_b.p99 > 0.5 * corner);
    }

    /// The BVH walk finds what testing every triangle finds.
    #[test]
    fn the_nearest_walk_is_the_brute_force_minimum() {
        let mut rng = SplitMix(3);
        let mut point = || DVec3::new(rng.unit(), rng.unit(), rng.unit()) * 4.0 - DVec3::splat(2.0);
        let positions: Vec<Vec3> = (0..60).map(|_| point().as_vec3()).collect();
        let triangles: Vec<[u32; 3]> = (0..40).map(|k| [k, (k * 7 + 3) % 60, (k * 13 + 11) % 60]).collect();
        let mesh = Mesh { positions, triangles };
        let surface = NearestTriangles::new(&mesh);
        for _ in 0..500 {
            let p = point() * 1.5;
            let brute = (mesh.triangles.iter())
                .map(|t| {
                    let c = t.map(|i| mesh.positions[i as usize].as_dvec3());
                    p.distance(closest_point_on_triangle(p, &c))
                })
                .fold(f64::INFINITY, f64::min);
            assert_eq!(surface.distance(p), brute);
        }
    }

    /// Closest points by region: the face, an edge, a corner, and a degenerate triangle.
    #[test]
    fn closest_points_by_region() {
        let t = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let at = |x, y, z| closest_point_on_triangle(DVec3::new(x, y, z), &t);
        assert_eq!(at(0.25, 0.25, 3.0), DVec3::new(0.25, 0.25, 0.0));
        assert_eq!(at(0.5, -1.0, 0.0), DVec3::new(0.5, 0.0, 0.0));
        assert_eq!(at(-1.0, -1.0, 1.0), DVec3::ZERO);
        assert_eq!(at(2.0, 2.0, 0.0), DVec3::new(0.5, 0.5, 0.0));
        let line = [DVec3::ZERO, DVec3::X, DVec3::X * 2.0];
        assert_eq!(
            closest_point_on_triangle(DVec3::new(1.5, 1.0, 0.0), &line),
            DVec3::new(1.5, 0.0, 0.0)
        );
    }

    #[test]
    fn percentiles_are_nearest_rank() {
        let mut d: Vec<f64> = (1..=100).map(f64::from).collect();
        let s = DistanceSummary::of(&mut d);
        assert_eq!((s.p99, s.max, s.samples), (99.0, 100.0, 100));
        assert!((s.rms - (338350.0f64 / 100.0).sqrt()).abs() < 1e-9);
    }
}
