//! A leaf's footprint: where its micro-triangles can lie, seen along the ray, known before
//! any of its vertices is loaded.
//!
//! The host stores for every leaf its thickness `d`: how far any of its micro-vertices lies
//! from its flat place, the same lattice point of the flat triangle of the leaf's three
//! corners. Every micro-vertex is then a point of that triangle moved by at most `d`. In the
//! ray's sheared frame (the ray is the z axis, see [`crate::triangle::shear`]), a move by
//! `delta` shifts `x` by `delta[kx] - sx delta[kz]`, at most `d sqrt(1 + sx^2)`, and `y`
//! likewise; so the leaf lies inside the 2D box of its three sheared corners grown by those
//! margins, and a ray outside that box cannot hit it. Unlike the leaf's sphere, the box follows
//! a flat leaf's true shape: the sphere around a long thin or tilted triangle is mostly empty.

use crate::glam::Vec3;
use crate::min_max::{max_of, min_of};
use crate::ray::Ray;
// On the GPU, float methods come from a trait (GLSL.std.450 underneath); natively from core.
#[cfg(target_arch = "spirv")]
use spirv_std::num_traits::Float;

/// The per-ray part of the footprint test: how much a leaf's box grows per unit of thickness
/// along sheared x and y.
#[derive(Copy, Clone)]
pub struct FootprintFrame {
    grow_x: f32,
    grow_y: f32,
}

impl FootprintFrame {
    #[inline]
    pub fn new(ray: &Ray) -> Self {
        FootprintFrame {
            grow_x: (1.0 + ray.shear.x * ray.shear.x).sqrt(),
            grow_y: (1.0 + ray.shear.y * ray.shear.y).sqrt(),
        }
    }

    /// Room for rounding around vertices no farther than `reach` from the ray's origin along
    /// any axis: their sheared coordinates are exact to a few units of `2^-24` of twice that;
    /// this allows about ten times as much.
    #[inline]
    pub fn slack(reach: f32) -> f32 {
        reach * (1.0 / 262_144.0)
    }

    /// Whether the ray (the sheared frame's z axis) can cross a leaf with sheared corners `a`,
    /// `b`, `c` and thickness `thickness`.
    #[inline]
    pub fn overlaps(&self, a: Vec3, b: Vec3, c: Vec3, thickness: f32, slack: f32) -> bool {
        let mx = thickness * self.grow_x + slack;
        let my = thickness * self.grow_y + slack;
        let lo_x = min3(a.x, b.x, c.x) - mx;
        let hi_x = max3(a.x, b.x, c.x) + mx;
        let lo_y = min3(a.y, b.y, c.y) - my;
        let hi_y = max3(a.y, b.y, c.y) + my;
        lo_x <= 0.0 && hi_x >= 0.0 && lo_y <= 0.0 && hi_y >= 0.0
    }

    /// Which lattice points of a leaf can belong to a micro-triangle the ray crosses: the box
    /// `[la_lo, la_hi, lb_lo, lb_hi]` of lattice coordinates (empty when a `lo` exceeds its
    /// `hi`). The leaf has `m` steps a side (a power of two), thickness `thickness` and sheared corners `a`,
    /// `b`, `c` at lattice points `(0, 0)`, `(m, 0)`, `(0, m)`.
    ///
    /// The leaf's flat lattice in the sheared plane is `F(la, lb) = a + la u + lb v`. A
    /// micro-triangle the ray crosses has a flat version that meets the margin box around the
    /// ray (the margins of [`Self::overlaps`]), so its cell meets the preimage of that box under
    /// `F`: a parallelogram around the ray's own lattice coordinates. Its bounding box, widened
    /// for rounding and by one step (a cell touching it keeps all three vertices), is returned.
    /// A leaf seen nearly edge-on makes `F` ill-conditioned: then the whole leaf is returned.
    #[inline]
    pub fn leaf_window(&self, a: Vec3, b: Vec3, c: Vec3, m: u32, thickness: f32, slack: f32) -> [u32; 4] {
        let whole = [0, m, 0, m];
        let steps = m as f32;
        // `m` is a power of two: its reciprocal is exact, and so is every product by it.
        let per_step = 1.0 / steps;
        let (ux, uy) = ((b.x - a.x) * per_step, (b.y - a.y) * per_step);
        let (vx, vy) = ((c.x - a.x) * per_step, (c.y - a.y) * per_step);
        let det = ux * vy - uy * vx;
        // The sine of the angle between u and v at least 1/16 (and no underflow); a NaN from
        // overflow shows up in `margin` below.
        if det * det * 256.0 <= (ux * ux + uy * uy) * (vx * vx + vy * vy) {
            return whole;
        }
        let inv = 1.0 / det;
        let mx = thickness * self.grow_x + slack;
        let my = thickness * self.grow_y + slack;
        // Lattice coordinates of the ray (F(alpha, beta) = 0) and the half extents of the
        // margin box's preimage.
        let alpha = (a.y * vx - a.x * vy) * inv;
        let beta = (a.x * uy - a.y * ux) * inv;
        let half_a = (vy.abs() * mx + vx.abs() * my) * inv.abs();
        let half_b = (uy.abs() * mx + ux.abs() * my) * inv.abs();
        // The solve's rounding is a few units of 2^-24 times the condition number (below 16)
        // and the sizes involved; this allows some hundred times as much.
        let margin = (1.0 + alpha.abs() + beta.abs() + half_a + half_b) * (1.0 / 1024.0);
        if margin.is_nan() || margin >= 64.0 * steps {
            return whole;
        }
        let (lo_a, hi_a) = (
            first_point(alpha - half_a - margin, m),
            last_point(alpha + half_a + margin, m),
        );
        let (lo_b, hi_b) = (
            first_point(beta - half_b - margin, m),
            last_point(beta + half_b + margin, m),
        );
        if lo_a > hi_a || lo_b > hi_b || lo_a + lo_b > m as i32 {
            return [1, 0, 1, 0];
        }
        [lo_a as u32, hi_a as u32, lo_b as u32, hi_b as u32]
    }
}

/// `max(0, ceil(x) - 1)`, or more than `m` when that is, for `x` not NaN: the first lattice
/// point of a cell reaching `x`. Floors by truncating a non-negative number, which every target
/// does in one instruction (`ceil` and `floor` are library calls on baseline x86-64).
#[inline]
fn first_point(x: f32, m: u32) -> i32 {
    let top = m as f32 + 2.0;
    // ceil(x) - 1 = top - 1 - floor(top - x), with top - x >= 0 once x <= top.
    let x = min_of(max_of(x, 0.0), top);
    let first = (top - 1.0) as i32 - (top - x) as i32;
    if first < 0 {
        0
    } else {
        first
    }
}

/// `min(m, floor(x) + 1)`, or negative when that is, for `x` not NaN: the last lattice point of
/// a cell reaching `x`.
#[inline]
fn last_point(x: f32, m: u32) -> i32 {
    let x = min_of(max_of(x, -2.0), m as f32 - 1.0);
    (x + 2.0) as i32 - 1
}

#[inline]
fn min3(a: f32, b: f32, c: f32) -> f32 {
    min_of(min_of(a, b), c)
}

#[inline]
fn max3(a: f32, b: f32, c: f32) -> f32 {
    max_of(max_of(a, b), c)
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::triangle::shear;

    /// A thick leaf around the triangle (0,0,0) (1,0,0) (0,1,0): rays through any point within
    /// its thickness overlap the footprint, from steep and from grazing directions; rays clear
    /// of the grown triangle's box do not.
    #[test]
    fn footprint_holds_every_point_within_the_thickness() {
        let corners = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let thickness = 0.05;
        let dirs = [
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::new(0.3, -0.2, -1.0),
            Vec3::new(1.0, 0.4, -0.2),
            Vec3::new(-0.2, 1.0, 0.3),
        ];
        for dir in dirs {
            for k in 0..200 {
                // A point of the triangle, moved by up to the thickness in some direction.
                let (u, v) = ((k % 13) as f32 / 13.0, (k % 7) as f32 / 7.0);
                let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
                let offset = Vec3::new((k as f32 * 0.7).sin(), (k as f32 * 1.3).cos(), (k as f32 * 0.4).sin());
                let p = corners[0]
                    + (corners[1] - corners[0]) * u
                    + (corners[2] - corners[0]) * v
                    + offset.normalize() * thickness * (k % 5) as f32 / 4.0;
                let ray = Ray::new(p - dir * 3.0, dir);
                let frame = FootprintFrame::new(&ray);
                let [a, b, c] = corners.map(|q| shear(q, &ray));
                let slack = FootprintFrame::slack(4.0);
                assert!(frame.overlaps(a, b, c, thickness, slack), "{p} along {dir}");
            }
        }
        let miss = Ray::new(Vec3::new(-0.3, 0.3, 1.0), Vec3::new(0.0, 0.0, -1.0));
        let frame = FootprintFrame::new(&miss);
        let [a, b, c] = corners.map(|q| shear(q, &miss));
        assert!(!frame.overlaps(a, b, c, thickness, FootprintFrame::slack(2.0)));
        // ...which a sphere around the same leaf would not have culled.
        assert!(
            crate::sphere::intersect_sphere(Vec3::splat(1.0 / 3.0), 0.75, &miss, crate::ray::T_FAR) < crate::ray::T_FAR
        );
    }

    #[test]
    fn window_ends_match_ceil_and_floor() {
        let m = 4;
        for k in -800..=800 {
            let x = k as f32 / 100.0 + 0.001 * (k % 3) as f32;
            let first = ((x.ceil() - 1.0).max(0.0) as i32).min(m as i32 + 1);
            assert_eq!(first_point(x, m).min(m as i32 + 1), first, "first point at {x}");
            let last = ((x.floor() + 1.0).min(m as f32) as i32).max(-1);
            assert_eq!(last_point(x, m).max(-1), last, "last point at {x}");
        }
    }

    /// A fixed stream of numbers in `[0, 1)`.
    struct Numbers(u64);

    impl Numbers {
        fn next(&mut self) -> f32 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 40) as f32 / (1u64 << 24) as f32
        }

        fn vec(&mut self) -> Vec3 {
            Vec3::new(self.next(), self.next(), self.next()) * 2.0 - Vec3::ONE
        }
    }

    /// Leaves of 16 micro-triangles whose points are moved off their flat places by up to the
    /// thickness: every micro-triangle a ray crosses (rays at random points of them, at their
    /// vertices, from steep to grazing directions) keeps its three lattice points inside the
    /// window, and the window is mostly much smaller than the leaf.
    #[test]
    fn leaf_window_keeps_every_crossed_triangle() {
        let m = 4u32;
        let mut numbers = Numbers(7);
        let (mut crossed, mut points_in_windows, mut windows) = (0, 0, 0);
        for _ in 0..300 {
            let corners = [numbers.vec(), numbers.vec(), numbers.vec()];
            let thickness = 0.1 * numbers.next() * numbers.next();
            let mut points = [Vec3::ZERO; 15];
            for lb in 0..=m {
                for la in 0..=m - lb {
                    let flat = corners[0]
                        + (corners[1] - corners[0]) * (la as f32 / m as f32)
                        + (corners[2] - corners[0]) * (lb as f32 / m as f32);
                    // The corners are vertices of their own: they are their flat places.
                    let corner = (la == 0 || la == m) && (lb == 0 || lb == m);
                    let moved = numbers.vec().clamp_length_max(1.0) * thickness * !corner as u32 as f32;
                    points[crate::grid_index::lattice_index(la, lb, m) as usize] = flat + moved;
                }
            }
            for k in 0..40 {
                let dir = numbers.vec();
                // Half the rays through a micro-triangle's point, some exactly at its vertex.
                let (la, lb) = ((numbers.next() * 3.0) as u32, (numbers.next() * 2.0) as u32);
                let [a, b, c] = [(la, lb), (la + 1, lb), (la, lb + 1)]
                    .map(|(i, j)| points[crate::grid_index::lattice_index(i, j, m) as usize]);
                let (u, v) = (numbers.next() * 0.5, numbers.next() * 0.5);
                let target = if k % 8 == 0 { a } else { a + (b - a) * u + (c - a) * v };
                let ray = Ray::new(target - dir * 3.0, dir);
                let frame = FootprintFrame::new(&ray);
                let [sa, sb, sc] = [points[0], points[4], points[14]].map(|q| shear(q, &ray));
                let slack = FootprintFrame::slack((target - ray.origin).abs().max_element() + 4.0);
                let window = frame.leaf_window(sa, sb, sc, m, thickness, slack);
                let inside = |i: u32, j: u32| i >= window[0] && i <= window[1] && j >= window[2] && j <= window[3];
                windows += 1;
                for lb in 0..=m {
                    for la in 0..=m - lb {
                        points_in_windows += inside(la, lb) as u32;
                    }
                }
                // Every micro-triangle: upright cells, then inverted ones.
                for lb in 0..m {
                    for la in 0..m - lb {
                        let mut cells = std::vec![[(la, lb), (la + 1, lb), (la, lb + 1)]];
                        if la + lb + 2 <= m {
                            cells.push([(la + 1, lb), (la, lb + 1), (la + 1, lb + 1)]);
                        }
                        for cell in cells {
                            let [p0, p1, p2] =
                                cell.map(|(i, j)| points[crate::grid_index::lattice_index(i, j, m) as usize]);
                            if crate::triangle::intersect_triangle(p0, p1, p2, &ray, crate::ray::T_FAR).is_some() {
                                crossed += 1;
                                assert!(
                                    cell.iter().all(|&(i, j)| inside(i, j)),
                                    "cell {cell:?} crossed outside window {window:?}"
                                );
                            }
                        }
                    }
                }
            }
        }
        assert!(crossed > 1000, "only {crossed} crossings");
        let mean = points_in_windows as f32 / windows as f32;
        assert!(mean < 9.0, "windows hold {mean} of 15 points on average");
    }
}
