//! Deterministic random samples: an integer hash and cosine-distributed directions, so that
//! the CPU and the GPU draw the same ambient-occlusion rays for the same pixel.

use crate::glam::Vec3;
#[cfg(target_arch = "spirv")]
use spirv_std::num_traits::Float;

/// A 32-bit integer hash (lowbias32).
#[inline]
pub fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^ (x >> 16)
}

/// The top 24 bits of `x` as a float in `[0, 1)`.
#[inline]
pub fn unit_float(x: u32) -> f32 {
    (x >> 8) as f32 / (1u32 << 24) as f32
}

/// A direction in the hemisphere around unit `n`, with density proportional to its cosine
/// with `n`, from two uniform numbers in `[0, 1)`; `t1`, `t2` complete `n` to an orthonormal
/// basis. Not normalised (its length is one up to rounding).
#[inline]
pub fn cosine_direction(n: Vec3, t1: Vec3, t2: Vec3, u1: f32, u2: f32) -> Vec3 {
    let r = u1.sqrt();
    let phi = core::f32::consts::TAU * u2;
    t1 * (r * phi.cos()) + t2 * (r * phi.sin()) + n * (1.0 - u1).max(0.0).sqrt()
}

/// Two unit vectors completing unit `n` to an orthonormal basis, branching only on the sign
/// of `n.z` (Duff et al., "Building an orthonormal basis, revisited", JCGT 2017).
#[inline]
pub fn orthonormal_basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = if n.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bases_are_orthonormal_and_samples_face_the_normal() {
        for k in 0..1000u32 {
            let h = hash(k);
            let n = Vec3::new(
                unit_float(h) - 0.5,
                unit_float(hash(h)) - 0.5,
                unit_float(hash(h ^ 7)) - 0.5,
            );
            let n = if k == 0 { -Vec3::Z } else { n.normalize() };
            let (t1, t2) = orthonormal_basis(n);
            for (a, b) in [(t1, t2), (t1, n), (t2, n)] {
                assert!(a.dot(b).abs() < 1e-5, "{n}");
            }
            assert!((t1.length() - 1.0).abs() < 1e-5 && (t2.length() - 1.0).abs() < 1e-5);
            let d = cosine_direction(n, t1, t2, unit_float(hash(h ^ 1)), unit_float(hash(h ^ 2)));
            assert!(d.dot(n) >= -1e-6 && (d.length() - 1.0).abs() < 1e-5);
        }
    }
}
