use crate::buffer::Buffer;
use crate::glam::{Vec3, Vec4};
use crate::min_max::max_of;
use crate::ray::{Ray, T_FAR};
// On the GPU, float methods come from a trait (GLSL.std.450 underneath); natively from core.
#[cfg(target_arch = "spirv")]
use spirv_std::num_traits::Float;

/// Radii are stored as IEEE half floats (rounded up on the host, so spheres only grow), in
/// units of a power-of-two `scale` chosen per scene so the largest radius fits.
#[inline]
pub fn decode_radius(half: u32, scale: f32) -> f32 {
    let exponent = (half >> 10) & 0x1f;
    let mantissa = half & 0x3ff;
    let value = if exponent == 0 {
        mantissa as f32 * (1.0 / 16_777_216.0)
    } else {
        f32::from_bits(((exponent + 112) << 23) | (mantissa << 13))
    };
    value * scale
}

/// The thickness a leaf's 8-bit code `code` stands for, its radius being `radius` (without
/// leaf pairs): up to twice the radius, for the same reason as [`leaf_thickness`].
#[inline]
pub fn byte_thickness(radius: f32, code: u32) -> f32 {
    radius * ((code & 0xff) as f32 * (2.0 / 255.0))
}

/// The radius that byte `k` of `word` codes, in 255ths of the root's radius `root`.
#[inline]
pub fn relative_radius(root: f32, word: u32, k: u32) -> f32 {
    let code = (word >> (8 * k)) & 0xff;
    root * (code as f32 * (1.0 / 255.0))
}

/// The radius a leaf's 4-bit code `code` stands for, its parent's radius being `parent`
/// (leaf pairs: see `layout::GridParams::thickness_word`): `(code + 1) / 16` of it, or twice it
/// for code 15. A leaf's points lie in its parent's sphere, and so does its centre (their
/// mean), so its radius never exceeds twice its parent's.
#[inline]
pub fn leaf_radius(parent: f32, code: u32) -> f32 {
    let k = code & 0xf;
    let fraction = if k == 15 { 2.0 } else { (k + 1) as f32 * (1.0 / 16.0) };
    parent * fraction
}

/// The thickness a leaf's 4-bit code `code` stands for, its radius being `radius` (leaf
/// pairs): `code / 32` of it below 8, where thin leaves want fine steps, then `(code - 6) / 4`,
/// up to 2.25 times it. A point lies within the radius of the leaf's centre, and so does its
/// flat place, so a thickness never exceeds twice the radius.
#[inline]
pub fn leaf_thickness(radius: f32, code: u32) -> f32 {
    let k = code & 0xf;
    let fraction = if k < 8 {
        k as f32 * (1.0 / 32.0)
    } else {
        (k - 6) as f32 * 0.25
    };
    radius * fraction
}

/// Radius of sphere `node` (breadth-first id) of the grid whose relative radius words start
/// at word `first` of `radii`.
#[inline]
pub fn relative_radius_at<B: Buffer<u32>>(radii: B, first: u32, node: u32) -> f32 {
    let root = f32::from_bits(radii.load(first));
    if node == 0 {
        return root;
    }
    relative_radius(root, radii.load(first + 1 + (node - 1) / 4), (node - 1) & 3)
}

/// Ray against a bounding sphere. Returns the entry distance (clamped to 0 when the origin is
/// inside) when the sphere overlaps `[0, t_max]` along the ray, otherwise `T_FAR`.
///
/// Written relative to the projection of the centre on the ray: the discriminant
/// `r^2 - |oc - b d|^2` loses far less precision than `b^2 - c` when the sphere is small and far
/// away, which is exactly the case of the deep levels of a grid's hierarchy.
#[inline]
pub fn intersect_sphere(center: Vec3, radius: f32, ray: &Ray, t_max: f32) -> f32 {
    intersect_sphere_scaled(center, radius, ray, 1.0 / ray.dir.dot(ray.dir), t_max)
}

/// [`intersect_sphere`] given `inv_dir_len2 = 1 / |dir|^2`, which a grid visit computes once
/// for all its spheres (a field of the ray would slow down every other ray test).
#[inline]
pub fn intersect_sphere_scaled(center: Vec3, radius: f32, ray: &Ray, inv_dir_len2: f32, t_max: f32) -> f32 {
    let oc = center - ray.origin;
    let b = oc.dot(ray.dir) * inv_dir_len2;
    let closest = oc - ray.dir * b;
    let h = radius * radius - closest.dot(closest);
    if h < 0.0 {
        return T_FAR;
    }
    let s = (h * inv_dir_len2).sqrt();
    let t_enter = b - s;
    let t_exit = b + s;
    if t_exit >= 0.0 && t_enter <= t_max {
        max_of(t_enter, 0.0)
    } else {
        T_FAR
    }
}

/// [`intersect_sphere_scaled`] of four spheres at once, sphere `k` in lane `k`: the same
/// operations in the same order, lane by lane, so each lane is the distance
/// `intersect_sphere_scaled` gives its sphere. Natively in SIMD lanes, four square roots at
/// once.
#[cfg(not(target_arch = "spirv"))]
#[inline(always)]
pub fn intersect_spheres(centers: [Vec3; 4], radii: Vec4, ray: &Ray, inv_dir_len2: f32, t_max: f32) -> Vec4 {
    let [c0, c1, c2, c3] = centers;
    let (o, d) = (ray.origin, ray.dir);
    let oc = [
        Vec4::new(c0.x, c1.x, c2.x, c3.x) - o.x,
        Vec4::new(c0.y, c1.y, c2.y, c3.y) - o.y,
        Vec4::new(c0.z, c1.z, c2.z, c3.z) - o.z,
    ];
    let b = (oc[0] * d.x + oc[1] * d.y + oc[2] * d.z) * inv_dir_len2;
    let closest = [oc[0] - d.x * b, oc[1] - d.y * b, oc[2] - d.z * b];
    let h = radii * radii - (closest[0] * closest[0] + closest[1] * closest[1] + closest[2] * closest[2]);
    // A negative `h` (a miss) makes a NaN here, which no comparison below lets through.
    let s = (h * inv_dir_len2).sqrt();
    let t_enter = b - s;
    let t_exit = b + s;
    let crossed = h.cmpge(Vec4::ZERO) & t_exit.cmpge(Vec4::ZERO) & t_enter.cmple(Vec4::splat(t_max));
    Vec4::select(crossed, t_enter.max(Vec4::ZERO), Vec4::splat(T_FAR))
}

/// [`intersect_spheres`] in a shader: the four tests one after the other. A GPU's lanes are
/// its threads, not vector registers, and four tests side by side hold more values at once:
/// a grid's render kernel needs more registers with them, for no gain.
#[cfg(target_arch = "spirv")]
#[inline(always)]
pub fn intersect_spheres(centers: [Vec3; 4], radii: Vec4, ray: &Ray, inv_dir_len2: f32, t_max: f32) -> Vec4 {
    Vec4::new(
        intersect_sphere_scaled(centers[0], radii.x, ray, inv_dir_len2, t_max),
        intersect_sphere_scaled(centers[1], radii.y, ray, inv_dir_len2, t_max),
        intersect_sphere_scaled(centers[2], radii.z, ray, inv_dir_len2, t_max),
        intersect_sphere_scaled(centers[3], radii.w, ray, inv_dir_len2, t_max),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_radii_decode() {
        assert_eq!(decode_radius(0x3c00, 1.0), 1.0);
        assert_eq!(decode_radius(0x3c00, 0.25), 0.25);
        assert_eq!(decode_radius(0x7bff, 1.0), 65504.0);
        assert_eq!(decode_radius(0x0001, 1.0), 2f32.powi(-24));
        assert_eq!(decode_radius(0x0400, 1.0), 2f32.powi(-14));
        assert_eq!(decode_radius(0x3555, 1.0), 0.33325195);
    }

    #[test]
    fn enter_inside_and_miss() {
        let r = Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::new(0.0, 0.0, 2.0));
        // Unnormalised direction: t is in units of `dir`.
        assert!((intersect_sphere(Vec3::ZERO, 1.0, &r, T_FAR) - 2.0).abs() < 1e-6);
        assert_eq!(intersect_sphere(Vec3::ZERO, 1.0, &r, 1.0), T_FAR);
        assert_eq!(intersect_sphere(Vec3::new(0.0, 1.5, 0.0), 1.0, &r, T_FAR), T_FAR);
        let inside = Ray::new(Vec3::ZERO, Vec3::X);
        assert_eq!(intersect_sphere(Vec3::ZERO, 1.0, &inside, T_FAR), 0.0);
        let behind = Ray::new(Vec3::new(0.0, 0.0, 5.0), Vec3::Z);
        assert_eq!(intersect_sphere(Vec3::ZERO, 1.0, &behind, T_FAR), T_FAR);
    }

    #[test]
    fn small_far_sphere_is_found() {
        let r = Ray::new(Vec3::new(0.0, 0.0, -1.0e4), Vec3::Z);
        let t = intersect_sphere(Vec3::new(1.0e-3, 0.0, 0.0), 2.0e-3, &r, T_FAR);
        assert!(t < T_FAR && (t - 1.0e4).abs() < 1.0);
    }

    #[test]
    fn four_lanes_match_the_scalar_test() {
        let mut state = 0x9e37_79b9_u32;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            (state >> 8) as f32 / (1 << 24) as f32 * 4.0 - 2.0
        };
        let mut entered = 0;
        for round in 0..4000 {
            let mut v = || Vec3::new(next(), next(), next());
            let centers = [v(), v(), v(), v()];
            let radii = Vec4::new(v().x, v().x, v().x, v().x).abs();
            let origin = v();
            // Every other ray aimed at a sphere, so that many cross theirs.
            let dir = if round % 2 == 0 {
                v()
            } else {
                centers[round % 4] - origin
            };
            let ray = Ray::new(origin, dir);
            let inv_dir_len2 = 1.0 / ray.dir.dot(ray.dir);
            let t_max = if round % 3 == 0 { T_FAR } else { 1.0 };
            let four = intersect_spheres(centers, radii, &ray, inv_dir_len2, t_max).to_array();
            for k in 0..4 {
                let one = intersect_sphere_scaled(centers[k], radii[k], &ray, inv_dir_len2, t_max);
                assert_eq!(four[k], one, "round {round}, sphere {k}");
                entered += (one < T_FAR) as u32;
            }
        }
        assert!(entered > 4000, "{entered} entered");
    }
}
