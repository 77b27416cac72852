use crate::glam::Vec3;
use crate::ray::{component, Ray};
// On the GPU, float methods come from a trait (GLSL.std.450 underneath); natively from core.
#[cfg(target_arch = "spirv")]
use spirv_std::num_traits::Float;

/// A vertex moved into the ray's sheared frame: the ray runs from the origin along +z, and
/// `z` is already scaled by the shear. Splitting this from [`intersect_sheared`] lets a grid
/// leaf transform each of its vertices once for all the triangles that share it.
#[inline]
pub fn shear(v: Vec3, ray: &Ray) -> Vec3 {
    let a = v - ray.origin;
    let z = component(a, ray.axis(2));
    Vec3::new(
        component(a, ray.axis(0)) - ray.shear.x * z,
        component(a, ray.axis(1)) - ray.shear.y * z,
        ray.shear.z * z,
    )
}

/// Watertight ray/triangle intersection (Woop, Benthin and Wald, JCGT 2013).
///
/// The ray is sheared so it runs along +z; the three 2D edge functions are then evaluated
/// in a way that gives the same result for a shared edge from both of its triangles, so a ray
/// through an edge or a vertex of a closed mesh always hits at least one of them. A zero edge
/// function counts as inside.
///
/// Returns `(t, b1, b2)` (barycentrics of `v1` and `v2`) with `t` in `(0, t_max)`, or `None`.
#[inline]
pub fn intersect_triangle(v0: Vec3, v1: Vec3, v2: Vec3, ray: &Ray, t_max: f32) -> Option<(f32, f32, f32)> {
    intersect_sheared(shear(v0, ray), shear(v1, ray), shear(v2, ray), t_max)
}

/// [`intersect_triangle`] on vertices already passed through [`shear`].
#[inline]
pub fn intersect_sheared(a: Vec3, b: Vec3, c: Vec3, t_max: f32) -> Option<(f32, f32, f32)> {
    let mut u = c.x * b.y - c.y * b.x;
    let mut v = a.x * c.y - a.y * c.x;
    let mut w = b.x * a.y - b.y * a.x;
    // An edge function that rounds to exactly zero says the ray grazes that edge's line,
    // which counts as inside. For a triangle far smaller than its distance from the ray the
    // two products cancel to zero by rounding alone, and a ray nowhere near it would hit it.
    // As Woop et al. do, such a zero is recomputed more precisely (here exactly in sign,
    // see `edge_function_exact`). Only the zero ones: each edge's value still depends on
    // that edge alone, so the two triangles sharing it still see it alike (watertight).
    if u == 0.0 || v == 0.0 || w == 0.0 {
        u = if u == 0.0 { edge_function_exact(c, b) } else { u };
        v = if v == 0.0 { edge_function_exact(a, c) } else { v };
        w = if w == 0.0 { edge_function_exact(b, a) } else { w };
    }
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 {
        return None;
    }
    let t_scaled = u * a.z + v * b.z + w * c.z;
    // Compare before dividing: t = t_scaled / det must lie in (0, t_max).
    if det > 0.0 {
        if t_scaled <= 0.0 || t_scaled >= t_max * det {
            return None;
        }
    } else if t_scaled >= 0.0 || t_scaled <= t_max * det {
        return None;
    }
    let inv_det = 1.0 / det;
    Some((t_scaled * inv_det, v * inv_det, w * inv_det))
}

/// `p.x q.y - p.y q.x` with the sign of the exact value (zero only when that is zero):
/// Kahan's difference of products, whose fused multiply-adds recover the rounding error of
/// one product exactly (relative error at most two units in the last place).
#[inline]
fn edge_function_exact(p: Vec3, q: Vec3) -> f32 {
    let w = p.y * q.x;
    let error = (-p.y).mul_add(q.x, w);
    p.x.mul_add(q.y, -w) + error
}

/// Unnormalised geometric normal, `(v1 - v0) x (v2 - v0)`.
#[inline]
pub fn triangle_normal(v0: Vec3, v1: Vec3, v2: Vec3) -> Vec3 {
    (v1 - v0).cross(v2 - v0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ray::T_FAR;

    fn ray(o: [f32; 3], d: [f32; 3]) -> Ray {
        Ray::new(Vec3::from(o), Vec3::from(d))
    }

    const A: Vec3 = Vec3::new(0.0, 0.0, 0.0);
    const B: Vec3 = Vec3::new(1.0, 0.0, 0.0);
    const C: Vec3 = Vec3::new(0.0, 1.0, 0.0);
    const D: Vec3 = Vec3::new(1.0, 1.0, 0.0);

    #[test]
    fn hits_inside_with_barycentrics() {
        let (t, u, v) = intersect_triangle(A, B, C, &ray([0.25, 0.5, 2.0], [0.0, 0.0, -1.0]), T_FAR).unwrap();
        assert!((t - 2.0).abs() < 1e-6);
        assert!((u - 0.25).abs() < 1e-6 && (v - 0.5).abs() < 1e-6);
    }

    #[test]
    fn both_sides_hit_and_outside_misses() {
        assert!(intersect_triangle(A, B, C, &ray([0.2, 0.2, -1.0], [0.0, 0.0, 1.0]), T_FAR).is_some());
        assert!(intersect_triangle(A, B, C, &ray([0.8, 0.8, 1.0], [0.0, 0.0, -1.0]), T_FAR).is_none());
        assert!(intersect_triangle(A, B, C, &ray([-0.1, 0.5, 1.0], [0.0, 0.0, -1.0]), T_FAR).is_none());
    }

    #[test]
    fn respects_the_interval() {
        let r = ray([0.2, 0.2, 1.0], [0.0, 0.0, -1.0]);
        assert!(intersect_triangle(A, B, C, &r, 0.5).is_none());
        assert!(intersect_triangle(A, B, C, &ray([0.2, 0.2, -1.0], [0.0, 0.0, -1.0]), T_FAR).is_none());
    }

    #[test]
    fn parallel_ray_misses() {
        assert!(intersect_triangle(A, B, C, &ray([-1.0, 0.2, 0.0], [1.0, 0.0, 0.0]), T_FAR).is_none());
        assert!(intersect_triangle(A, B, C, &ray([-1.0, 0.2, 0.5], [1.0, 0.0, 0.0]), T_FAR).is_none());
    }

    #[test]
    fn shared_edges_and_vertices_are_never_missed() {
        // Quad A B D C split along B-C; rays through points on the diagonal, on the outer
        // edges and at the vertices, from oblique directions.
        let dirs = [
            [0.0, 0.0, -1.0],
            [0.3, -0.2, -1.0],
            [-0.7, 0.4, -0.5],
            [0.01, 0.02, -1.0],
        ];
        let mut targets = [[0.0f32; 3]; 13];
        for (k, t) in targets.iter_mut().enumerate().take(9) {
            let s = k as f32 / 8.0;
            *t = [1.0 - s, s, 0.0];
        }
        targets[9] = [0.0, 0.0, 0.0];
        targets[10] = [1.0, 1.0, 0.0];
        targets[11] = [1.0 / 3.0, 2.0 / 3.0, 0.0];
        targets[12] = [0.1, 0.9, 0.0];
        for d in dirs {
            for p in targets {
                let dir = Vec3::from(d);
                let r = Ray::new(Vec3::from(p) - dir * 3.0, dir);
                let first = intersect_triangle(A, B, C, &r, T_FAR);
                let second = intersect_triangle(B, D, C, &r, T_FAR);
                let inside_quad = p[0] > 0.0 && p[1] > 0.0 && p[0] < 1.0 && p[1] < 1.0;
                if inside_quad {
                    assert!(
                        first.is_some() || second.is_some(),
                        "ray {d:?} through {p:?} slipped through"
                    );
                }
                for (t, _, _) in first.into_iter().chain(second) {
                    assert!((t - 3.0).abs() < 1e-5);
                }
            }
        }
    }

    #[test]
    fn hits_exactly_at_a_vertex() {
        let r = ray([1.0, 0.0, 1.0], [0.0, 0.0, -1.0]);
        let (t, u, v) = intersect_triangle(A, B, C, &r, T_FAR).unwrap();
        assert!((t - 1.0).abs() < 1e-6 && (u - 1.0).abs() < 1e-6 && v.abs() < 1e-6);
    }

    /// A triangle a million times smaller than its distance from the ray: its edge
    /// functions cancel to zero in plain `f32`, yet the ray passes far from it.
    #[test]
    fn a_tiny_far_triangle_is_not_hit_by_rounding() {
        let (a, b, c) = (
            Vec3::new(0.0, -1.8179996e-7, -0.767864),
            Vec3::new(0.0, -1.2119997e-7, -0.7678629),
            Vec3::new(0.0, -1.2119997e-7, -0.7678641),
        );
        let o = Vec3::new(-0.6224639, 0.8039437, 1.8971152);
        let r = Ray::new(o, (Vec3::new(0.7985193, -0.50139976, 0.0) - o).normalize());
        assert_eq!(intersect_triangle(a, b, c, &r, T_FAR), None);
        // The same triangle is still hit by a ray through it from close by (from 3.8 units
        // away its 6e-8 width is below the resolution of the ray's coordinates).
        let centre = (a + b + c) / 3.0;
        let through = Ray::new(centre - r.dir * 1e-6, r.dir);
        assert!(intersect_triangle(a, b, c, &through, T_FAR).is_some());
    }

    #[test]
    fn exact_edge_functions_have_the_true_sign() {
        // 1 + 2^-23 squared: the products differ from their roundings in the last bits.
        let e = f32::EPSILON;
        let p = Vec3::new(1.0 + e, 1.0, 0.0);
        let q = Vec3::new(1.0, 1.0 + e, 0.0);
        assert_eq!(p.x * q.y - p.y * q.x, (1.0 + e) * (1.0 + e) - 1.0);
        assert!(edge_function_exact(p, q) > 0.0);
        assert!(edge_function_exact(q, p) < 0.0);
        assert_eq!(edge_function_exact(p, p), 0.0);
        let big = Vec3::new(3.0e7, 3.0e7 + 2.0, 0.0);
        let near = Vec3::new(3.0e7 + 2.0, 3.0e7 + 4.0, 0.0);
        // Exactly 3e7 * (3e7 + 4) - (3e7 + 2)^2 = -4, lost entirely in plain products.
        assert_eq!(big.x * near.y - big.y * near.x, 0.0);
        assert!(edge_function_exact(big, near) < 0.0);
    }

    #[test]
    fn degenerate_triangle_misses() {
        assert!(intersect_triangle(A, B, B * 2.0, &ray([0.5, 0.0, 1.0], [0.0, 0.0, -1.0]), T_FAR).is_none());
    }
}
