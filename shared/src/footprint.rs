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
}

#[inline]
fn min3(a: f32, b: f32, c: f32) -> f32 {
    a.min(b).min(c)
}

#[inline]
fn max3(a: f32, b: f32, c: f32) -> f32 {
    a.max(b).max(c)
}

#[cfg(test)]
mod tests {
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
}
