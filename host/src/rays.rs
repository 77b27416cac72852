//! Ray sets for benchmarks: primary rays from fixed views, ambient-occlusion rays from their
//! hits. Both representations trace the very same list.

use gridrt_shared::camera::primary_ray;
use gridrt_shared::glam::Vec3;
use gridrt_shared::layout::{HitRecord, RayRecord};
use gridrt_shared::ray::T_FAR;

use crate::bvh::Aabb;
use crate::camera;
use crate::scene::Scene;

/// AO rays look this far, as a fraction of the scene's bounding-box diagonal.
pub const AO_RADIUS: f32 = 0.1;
/// Seed of the AO directions, so every run traces the same rays.
pub const AO_SEED: u32 = 0x9e37_79b9;

fn record(origin: Vec3, dir: Vec3, t_max: f32) -> RayRecord {
    RayRecord {
        origin: origin.to_array(),
        t_max,
        dir: dir.to_array(),
        _pad: 0,
    }
}

/// `views` auto-framed orbit views of `bounds`, `width x height` pixels each, row by row.
pub fn primary_rays(bounds: &Aabb, views: u32, width: u32, height: u32) -> Vec<RayRecord> {
    let mut rays = Vec::with_capacity((views * width * height) as usize);
    for v in 0..views {
        let cam = camera::orbit(bounds, v, views, width, height);
        for y in 0..height {
            for x in 0..width {
                let r = primary_ray(&cam, x, y);
                rays.push(record(r.origin, r.dir, T_FAR));
            }
        }
    }
    rays
}

/// A 32-bit integer hash (lowbias32), the source of the AO directions.
fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^ (x >> 16)
}

fn unit_float(x: u32) -> f32 {
    (x >> 8) as f32 / (1u32 << 24) as f32
}

/// `samples` cosine-distributed rays over the hemisphere of each primary hit, on the side the
/// primary ray came from, starting a hair off the surface. `normal_of` gives the geometric
/// normal of a hit.
pub fn ao_rays(
    primary: &[RayRecord],
    hits: &[HitRecord],
    samples: u32,
    bounds: &Aabb,
    normal_of: impl Fn(u32) -> Vec3,
) -> Vec<RayRecord> {
    let diagonal = (bounds.max - bounds.min).length();
    let offset = diagonal * 1e-5;
    let mut rays = Vec::new();
    for (k, (ray, hit)) in primary.iter().zip(hits).enumerate() {
        if hit.prim == gridrt_shared::layout::NO_HIT {
            continue;
        }
        let dir = Vec3::from(ray.dir);
        let mut n = normal_of(hit.prim).normalize_or_zero();
        if n == Vec3::ZERO {
            continue;
        }
        if n.dot(dir) > 0.0 {
            n = -n;
        }
        let p = Vec3::from(ray.origin) + dir * hit.t + n * offset;
        let (t1, t2) = n.any_orthonormal_pair();
        for s in 0..samples {
            let h = hash(AO_SEED ^ hash(k as u32 * samples + s));
            let (u1, u2) = (unit_float(h), unit_float(hash(h)));
            let r = u1.sqrt();
            let phi = std::f32::consts::TAU * u2;
            let d = t1 * (r * phi.cos()) + t2 * (r * phi.sin()) + n * (1.0 - u1).max(0.0).sqrt();
            rays.push(record(p, d.normalize(), diagonal * AO_RADIUS));
        }
    }
    rays
}

/// Traces a ray list on the CPU, in parallel: the closest hit of each.
pub fn trace_cpu(scene: &Scene, rays: &[RayRecord]) -> Vec<HitRecord> {
    use rayon::prelude::*;
    rays.par_iter()
        .with_min_len(256)
        .map(|r| {
            let ray = gridrt_shared::ray::Ray::new(Vec3::from(r.origin), Vec3::from(r.dir));
            let hit = scene.trace(&ray, r.t_max);
            HitRecord {
                t: hit.t,
                prim: hit.prim,
            }
        })
        .collect()
}
