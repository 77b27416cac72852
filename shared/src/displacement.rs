//! Displaced micro-vertices: a point of a base triangle's level-`L` lattice moved along the
//! interpolated direction by its displacement, `p = lerp(P) + lerp(D) * d`, as NVIDIA's
//! displacement micro-maps define them (`P` the base corners, `D` their direction vectors,
//! neither normalised; `d` the stored value mapped by the micromap's bias and scale).
//!
//! Watertight by construction: a point on a base edge is interpolated from the two corners of
//! that edge alone, always from the corner with the smaller vertex id towards the other, so
//! the two triangles that share the edge (whatever their orientation and corner order)
//! compute the same bits for it from the same value; a corner is its own position and
//! direction. Points inside a triangle belong to it alone.
//!
//! Lattice point `(i, j)` of a triangle with lattice size `n = 2^L` has barycentrics
//! `(n - i - j, i, j) / n` on corners `(0, 1, 2)`, as in [`crate::grid_index`], and is
//! value `i * (n + 1) - i * (i - 1) / 2 + j` of the triangle's values in u-major order.

use crate::glam::Vec3;
use crate::grid_index::Lattice;
use crate::min_max::{max_of, min_of};
use crate::ray::Ray;
use crate::triangle::shear;

/// The largest 11-bit unorm value.
pub const UNORM11_MAX: u32 = 2047;

/// A base triangle as displacement needs it: its corners' positions, directions and vertex
/// ids (which order the interpolation along its edges).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DisplacedTriangle {
    pub positions: [Vec3; 3],
    pub directions: [Vec3; 3],
    pub ids: [u32; 3],
}

impl DisplacedTriangle {
    /// Whether `ray`'s line may cross the triangle's shell, the points it can be displaced to
    /// whatever its values: false only where it crosses none of them. Only the base triangle
    /// is read, no value: a grid can be left before any of it is decoded.
    ///
    /// A point is `sum w_i (P_i + d D_i)` (barycentrics `w_i >= 0` summing to one, `d` in
    /// `[0, 1]`: every value decodes into the unit range), a convex combination of the six
    /// points `P_i` and `P_i + D_i`. Seen along the ray (in its sheared frame the ray is the
    /// z axis) the shell lies within the 2D hull of those six, and the ray misses the hull
    /// where a line separates the two. The lines tried are parallel to the sheared base
    /// triangle's edges, which a thin shell follows. Each side is allowed for rounding, of
    /// the decoded points and of the shears: a few units of `2^-24` of the largest coordinate
    /// involved, of which `2^-16` is ample.
    #[inline(always)]
    pub fn shell_may_cross(&self, ray: &Ray) -> bool {
        let [p0, p1, p2] = self.positions;
        let [d0, d1, d2] = self.directions;
        let six = [
            shear(p0, ray),
            shear(p1, ray),
            shear(p2, ray),
            shear(p0 + d0, ray),
            shear(p1 + d1, ray),
            shear(p2 + d2, ray),
        ];
        let extent = |p: Vec3, d: Vec3| p.abs().max_element() + d.abs().max_element();
        let reach = max_of(max_of(extent(p0, d0), extent(p1, d1)), extent(p2, d2)) + ray.origin.abs().max_element();
        let margin = reach * (1.0 / 65_536.0);
        let [a, b, c, ..] = six;
        let ab = || separates(six, a, b, margin);
        let bc = || separates(six, b, c, margin);
        let ca = || separates(six, c, a, margin);
        // A shader tests all three without branching; the CPU stops at the first that separates.
        if cfg!(target_arch = "spirv") {
            !(ab() | bc() | ca())
        } else {
            !(ab() || bc() || ca())
        }
    }
}

/// Whether a line parallel to `p`-`q` (in the sheared frame's xy plane) has all of `points`
/// on one side and the origin on the other, with room for each coordinate being `margin`
/// off, twice over.
#[inline(always)]
fn separates(points: [Vec3; 6], p: Vec3, q: Vec3, margin: f32) -> bool {
    let (nx, ny) = (q.y - p.y, p.x - q.x);
    let at = |v: Vec3| v.x * nx + v.y * ny;
    let [a, b, c, d, e, f] = points;
    let lo = min_of(min_of(min_of(at(a), at(b)), min_of(at(c), at(d))), min_of(at(e), at(f)));
    let hi = max_of(max_of(max_of(at(a), at(b)), max_of(at(c), at(d))), max_of(at(e), at(f)));
    let room = 2.0 * margin * (nx.abs() + ny.abs());
    lo > room || hi < -room
}

/// The displacement a stored 11-bit value stands for: `q / 2047 * scale + bias`.
#[inline]
pub fn unorm11_displacement(q: u32, scale: f32, bias: f32) -> f32 {
    q as f32 / UNORM11_MAX as f32 * scale + bias
}

/// Where lattice point `(i, j)`'s value sits among a triangle's u-major values.
#[inline]
pub const fn u_major_index(p: Lattice, n: u32) -> u32 {
    let [i, j] = p;
    i * (n + 1) - (i * i - i) / 2 + j
}

/// Edge flags of a base triangle whose neighbour across an edge is one level coarser (bit `e`
/// for the edge from corner `e` to corner `e + 1 mod 3`, as glTF's `primitiveFlags` hold
/// them): such an edge keeps only its even lattice points, the ones its coarser neighbour
/// has, so the two sides meet watertight.
pub const DECIMATED_EDGES: u32 = 0b111;

/// Where lattice point `p` of a size-`n` lattice lies once the edges `decimated` flags (see
/// [`DECIMATED_EDGES`]) are decimated: an odd point of such an edge moves onto its even
/// neighbour towards the nearer end of the edge (towards the edge's first corner from the
/// midpoint), as NVIDIA's displacement micro-maps snap it; any other point stays. The
/// micro-triangles keep their lattice corners, so those along a decimated edge may become
/// degenerate, and the rest close the gap.
#[inline]
pub fn decimated_point(p: Lattice, n: u32, decimated: u32) -> Lattice {
    let [i, j] = p;
    // `s` steps from the edge's first corner: odd ones move to an even neighbour (corners
    // stay, also at level 0, where `n = 1`).
    let snap = |s: u32| {
        if s & 1 == 0 || s == n {
            s
        } else if 2 * s <= n {
            s - 1
        } else {
            s + 1
        }
    };
    if decimated & 1 != 0 && j == 0 {
        [snap(i), 0]
    } else if decimated & 2 != 0 && i + j == n {
        let j = snap(j);
        [n - j, j]
    } else if decimated & 4 != 0 && i == 0 {
        [0, n - snap(n - j)]
    } else {
        p
    }
}

/// [`decimated_point`] for a grid of its own level within a scene's finer lattice: the scene's
/// lattice has size `n`, and the grid's own is `2^shift` times coarser (its points are the
/// multiples of `2^shift`), so its decimated edges snap odd points of its own lattice. Any
/// other point of the scene's lattice is returned as it is.
#[inline]
pub fn decimated_grid_point(p: Lattice, n: u32, shift: u32, decimated: u32) -> Lattice {
    let mask = (1u32 << shift) - 1;
    if decimated == 0 || (p[0] | p[1]) & mask != 0 {
        return p;
    }
    let [i, j] = decimated_point([p[0] >> shift, p[1] >> shift], n >> shift, decimated);
    [i << shift, j << shift]
}

/// Lattice point `p` of `triangle`'s size-`n` lattice, displaced by `d`.
#[inline]
pub fn displaced_point(triangle: &DisplacedTriangle, p: Lattice, n: u32, d: f32) -> Vec3 {
    let (position, direction) = interpolated(triangle, p, n);
    position + direction * d
}

/// The position and direction interpolated at lattice point `p` (see the module docs for the
/// order of operations on edges).
///
/// Corners and weights are chosen by comparisons, not array indices computed at run time (a
/// GPU keeps an array indexed so in slow private memory), and the barycentrics are steps
/// times `1 / n`, which for the power-of-two lattices of grids is exactly the quotient, at no
/// division per point. Always inlined: a CPU call returns the pair through memory, and the
/// caller's wide reads of it wait on the callee's narrow writes.
#[inline(always)]
pub fn interpolated(triangle: &DisplacedTriangle, p: Lattice, n: u32) -> (Vec3, Vec3) {
    let [i, j] = p;
    let k = n - i - j;
    let [p0, p1, p2] = triangle.positions;
    let [d0, d1, d2] = triangle.directions;
    let [id0, id1, id2] = triangle.ids;
    // A corner is its own position and direction, exactly.
    if k == n {
        return (p0, d0);
    } else if i == n {
        return (p1, d1);
    } else if j == n {
        return (p2, d2);
    }
    let inv_n = 1.0 / n as f32;
    if i != 0 && j != 0 && k != 0 {
        let (u, v) = (i as f32 * inv_n, j as f32 * inv_n);
        return (p0 + (p1 - p0) * u + (p2 - p0) * v, d0 + (d1 - d0) * u + (d2 - d0) * v);
    }
    // On an edge exactly one weight is zero: the edge joins the other two corners, each
    // given with its id and weight (`k`, `i`, `j` for corners 0, 1, 2).
    let ((pa, da, ida, wa), (pb, db, idb, wb)) = if k == 0 {
        ((p1, d1, id1, i), (p2, d2, id2, j))
    } else if i == 0 {
        ((p2, d2, id2, j), (p0, d0, id0, k))
    } else {
        ((p0, d0, id0, k), (p1, d1, id1, i))
    };
    // From the corner with the smaller id towards the other, by the other's weight.
    let ((from_p, from_d), (to_p, to_d), s) = if ida <= idb {
        ((pa, da), (pb, db), wb)
    } else {
        ((pb, db), (pa, da), wa)
    };
    let s = s as f32 * inv_n;
    (from_p + (to_p - from_p) * s, from_d + (to_d - from_d) * s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid_index::lattice_points;

    fn triangle(ids: [u32; 3]) -> DisplacedTriangle {
        DisplacedTriangle {
            positions: [
                Vec3::new(0.1, 0.2, 0.3),
                Vec3::new(1.7, -0.2, 0.1),
                Vec3::new(0.3, 1.9, -0.7),
            ],
            directions: [
                Vec3::new(0.0, 0.3, 1.0),
                Vec3::new(0.2, 0.1, 0.9),
                Vec3::new(-0.1, 0.0, 1.1),
            ],
            ids,
        }
    }

    /// The u-major order counts every lattice point once, in order.
    #[test]
    fn u_major_indices_enumerate_the_lattice() {
        let n = 8;
        let mut seen = [false; 45];
        for u in 0..=n {
            for v in 0..=n - u {
                let k = u_major_index([u, v], n) as usize;
                assert!(!seen[k]);
                seen[k] = true;
            }
        }
        assert!(seen.iter().all(|&s| s));
        assert_eq!(u_major_index([0, 1], 8), 1);
        assert_eq!(u_major_index([1, 0], 8), 9);
    }

    /// Corners are exact, and the same edge read from either side gives the same bits.
    #[test]
    fn shared_edges_decode_alike_from_both_sides() {
        let n = 16;
        let t = triangle([40, 7, 12]);
        for (c, p) in [[0, 0], [n, 0], [0, n]].into_iter().enumerate() {
            assert_eq!(displaced_point(&t, p, n, 0.5), t.positions[c] + t.directions[c] * 0.5);
        }
        // The edge from corner 1 to corner 2, seen by a neighbour whose corners 0 and 2 are
        // this triangle's 2 and 1 (the opposite orientation).
        let other = DisplacedTriangle {
            positions: [t.positions[2], Vec3::new(2.0, 2.0, 2.0), t.positions[1]],
            directions: [t.directions[2], Vec3::Z, t.directions[1]],
            ids: [12, 99, 7],
        };
        for k in 0..=n {
            // (n - k, k) on this triangle is k steps from corner 1 towards corner 2; on the
            // other, the same point is (0, n - k): n - k steps from its corner 0 (id 12).
            let here = displaced_point(&t, [n - k, k], n, 0.25);
            let there = displaced_point(&other, [0, n - k], n, 0.25);
            assert_eq!(
                here.to_array().map(f32::to_bits),
                there.to_array().map(f32::to_bits),
                "k = {k}"
            );
        }
    }

    /// Interpolation reproduces the base triangle when nothing is displaced.
    #[test]
    fn without_displacement_points_lie_on_the_base_triangle() {
        let n = 8;
        let t = triangle([0, 1, 2]);
        for p in lattice_points(n) {
            let [i, j] = p;
            let w = [(n - i - j) as f32, i as f32, j as f32].map(|w| w / n as f32);
            let expected = t.positions[0] * w[0] + t.positions[1] * w[1] + t.positions[2] * w[2];
            assert!((displaced_point(&t, p, n, 0.0) - expected).length() < 1e-6, "{p:?}");
        }
    }

    /// Every point a triangle can be displaced to lies in its shell: rays through displaced
    /// lattice points, from many origins, some far from the scene's origin, some along the
    /// triangle's plane, all cross it; rays that pass the shell by well over its rounding
    /// room do not.
    #[test]
    fn shells_hold_every_displaced_point() {
        let n = 8;
        let mut seed = 7u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1u32 << 24) as f32 - 0.5
        };
        for offset in [Vec3::ZERO, Vec3::new(3.0e4, -2.0e4, 1.0e4)] {
            for scale in [1.0e-3, 1.0, 250.0] {
                let mut t = triangle([3, 9, 4]);
                t.positions = t.positions.map(|p| p * scale + offset);
                t.directions = t.directions.map(|d| d * scale);
                let normal = (t.positions[1] - t.positions[0]).cross(t.positions[2] - t.positions[0]);
                for p in lattice_points(n) {
                    for q in [0, 1, 1023, 2046, UNORM11_MAX] {
                        let point = displaced_point(&t, p, n, unorm11_displacement(q, 1.0, 0.0));
                        let from = Vec3::new(next(), next(), next()) * 40.0 * scale;
                        // Along the triangle's plane too: the shell seen edge on.
                        let along = from - normal * (from.dot(normal) / normal.length_squared());
                        for origin in [point + from, point + along, point + from * 1.0e3] {
                            let ray = Ray::new(origin, point - origin);
                            assert!(t.shell_may_cross(&ray), "{p:?} {q} scale {scale} offset {offset}");
                        }
                    }
                }
                // Beside the shell: aimed past each corner, as far beyond it as it lies from
                // the triangle's centre, more than the directions lean.
                let centre = (t.positions[0] + t.positions[1] + t.positions[2]) / 3.0;
                let mut missed = 0;
                for c in 0..3 {
                    let outside = t.positions[c] * 2.0 - centre;
                    let origin = outside + normal.normalize() * 5.0 * scale;
                    missed += !t.shell_may_cross(&Ray::new(origin, outside - origin)) as u32;
                }
                // Far from the scene's origin, the rounding room of a small triangle may
                // exceed its size: it then culls nothing, which is safe.
                if offset == Vec3::ZERO {
                    assert_eq!(missed, 3, "scale {scale}");
                }
            }
        }
    }

    /// A decimated edge keeps its even points, each odd one moved to the even neighbour nearer
    /// the edge's end (the first end from the midpoint); nothing off the flagged edges moves.
    #[test]
    fn decimated_edges_keep_their_even_points() {
        let n = 8;
        // Edge 0 runs (0, 0) -> (n, 0), edge 1 (n, 0) -> (0, n), edge 2 (0, n) -> (0, 0).
        assert_eq!(decimated_point([1, 0], n, 1), [0, 0]);
        assert_eq!(decimated_point([3, 0], n, 1), [2, 0]);
        assert_eq!(decimated_point([5, 0], n, 1), [6, 0]);
        assert_eq!(decimated_point([7, 0], n, 1), [8, 0]);
        assert_eq!(decimated_point([7, 1], n, 2), [8, 0]);
        assert_eq!(decimated_point([3, 5], n, 2), [2, 6]);
        assert_eq!(decimated_point([5, 3], n, 2), [6, 2]);
        assert_eq!(decimated_point([0, 7], n, 4), [0, 8]);
        assert_eq!(decimated_point([0, 1], n, 4), [0, 0]);
        assert_eq!(decimated_point([0, 5], n, 4), [0, 6]);
        // Level 0 has corners alone.
        for p in lattice_points(1) {
            assert_eq!(decimated_point(p, 1, DECIMATED_EDGES), p);
        }
        // The midpoint of a level-1 edge goes to the edge's first corner.
        assert_eq!(decimated_point([1, 0], 2, 1), [0, 0]);
        assert_eq!(decimated_point([1, 1], 2, 2), [2, 0]);
        assert_eq!(decimated_point([0, 1], 2, 4), [0, 2]);
        for p in lattice_points(n) {
            let [i, j] = p;
            let on_edge = [j == 0, i + j == n, i == 0];
            for flags in 0..8u32 {
                let moved = decimated_point(p, n, flags);
                let flagged = (0..3).any(|e| flags >> e & 1 != 0 && on_edge[e]);
                if !flagged || (i % 2 == 0 && j % 2 == 0) {
                    assert_eq!(moved, p, "{p:?} flags {flags}");
                } else {
                    // One step along the same edge, onto an even point.
                    assert_eq!(moved[0] % 2 + moved[1] % 2, 0, "{p:?} flags {flags}");
                    assert!(moved[0].abs_diff(i) + moved[1].abs_diff(j) <= 2, "{p:?} flags {flags}");
                }
            }
        }
    }

    /// Within a finer scene lattice, a coarser grid snaps its own odd points, at its own
    /// spacing, and leaves the points it does not have alone.
    #[test]
    fn coarser_grids_snap_their_own_points() {
        let (n, shift) = (16, 2);
        for p in lattice_points(n) {
            let moved = decimated_grid_point(p, n, shift, 1);
            if p[0] % 4 != 0 || p[1] % 4 != 0 {
                assert_eq!(moved, p);
            } else {
                let own = decimated_point([p[0] / 4, p[1] / 4], 4, 1);
                assert_eq!(moved, [own[0] * 4, own[1] * 4]);
            }
        }
        assert_eq!(decimated_grid_point([4, 0], n, shift, 1), [0, 0]);
        assert_eq!(decimated_grid_point([12, 0], n, shift, 1), [16, 0]);
        assert_eq!(decimated_grid_point([12, 0], n, shift, 0), [12, 0]);
    }

    #[test]
    fn unorm_values_span_bias_to_bias_plus_scale() {
        assert_eq!(unorm11_displacement(0, 2.0, -0.5), -0.5);
        assert_eq!(unorm11_displacement(UNORM11_MAX, 2.0, -0.5), 1.5);
    }
}
