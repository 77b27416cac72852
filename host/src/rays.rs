//! Ray sets for benchmarks: primary rays from fixed views, ambient-occlusion rays from their
//! hits. Both representations trace the very same list.

use gridrt_shared::camera::primary_ray;
use gridrt_shared::glam::Vec3;
use gridrt_shared::layout::{Camera, HitRecord, RayRecord};
use gridrt_shared::ray::T_FAR;
use gridrt_shared::sample::{cosine_direction, hash, unit_float};

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
        rays.extend(view_rays(&camera::orbit(bounds, v, views, width, height)));
    }
    rays
}

/// The primary ray of every pixel `camera` renders, row-major, top row first: the rays a
/// render traces first, for [`crate::backend::Backend::trace`].
pub fn view_rays(camera: &Camera) -> Vec<RayRecord> {
    let (width, height) = (camera.width, camera.height);
    let pixels = (0..height).flat_map(|y| (0..width).map(move |x| (x, y)));
    pixels
        .map(|(x, y)| {
            let r = primary_ray(camera, x, y);
            record(r.origin, r.dir, T_FAR)
        })
        .collect()
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
            let d = cosine_direction(n, t1, t2, unit_float(h), unit_float(hash(h)));
            rays.push(record(p, d.normalize(), diagonal * AO_RADIUS));
        }
    }
    rays
}

/// The order a benchmark traces its rays in. Both representations always trace the same list.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum RayOrder {
    /// Primary rays row by row, view by view; AO rays hit by hit in that order, each hit's
    /// samples together.
    #[default]
    Scanline,
    /// Primary rays in 8x8 pixel tiles, Z order inside each, so eight consecutive rays (one
    /// SIMD group on lavapipe, a quarter warp) cover a 4x2 block; AO rays sorted by the octant
    /// of their direction, then along a Morton curve through their origins.
    Coherent,
}

/// Puts `primary` (made by [`primary_rays`]) and `ao` in `order`: the same rays, permuted.
pub fn reorder(
    order: RayOrder,
    primary: &mut Vec<RayRecord>,
    ao: &mut [RayRecord],
    views: u32,
    width: u32,
    height: u32,
    bounds: &Aabb,
) {
    if order == RayOrder::Scanline {
        return;
    }
    let mut tiled = Vec::with_capacity(primary.len());
    for v in 0..views {
        let view = &primary[(v * width * height) as usize..((v + 1) * width * height) as usize];
        for ty in (0..height).step_by(8) {
            for tx in (0..width).step_by(8) {
                for z in 0..64u32 {
                    let (x, y) = (tx + compact_bits(z), ty + compact_bits(z >> 1));
                    if x < width && y < height {
                        tiled.push(view[(y * width + x) as usize]);
                    }
                }
            }
        }
    }
    *primary = tiled;
    let extent = (bounds.max - bounds.min).max(Vec3::splat(f32::MIN_POSITIVE));
    let key = |r: &RayRecord| {
        let octant = (r.dir[0] < 0.0) as u64 | ((r.dir[1] < 0.0) as u64) << 1 | ((r.dir[2] < 0.0) as u64) << 2;
        let cell = ((Vec3::from(r.origin) - bounds.min) / extent * 1024.0).clamp(Vec3::ZERO, Vec3::splat(1023.0));
        let morton = spread_bits(cell.x as u32) | spread_bits(cell.y as u32) << 1 | spread_bits(cell.z as u32) << 2;
        octant << 30 | morton
    };
    ao.sort_by_cached_key(key);
}

/// The even bits of `z` packed together: the x coordinate of a 2D Morton index.
fn compact_bits(z: u32) -> u32 {
    (z & 1) | (z >> 1 & 2) | (z >> 2 & 4)
}

/// The 10 low bits of `x` spread to every third bit, for a 3D Morton code.
fn spread_bits(x: u32) -> u64 {
    let mut v = x as u64 & 0x3ff;
    v = (v | v << 16) & 0x0300_00ff;
    v = (v | v << 8) & 0x0300_f00f;
    v = (v | v << 4) & 0x030c_30c3;
    (v | v << 2) & 0x0924_9249
}

/// Which of `scenes` scenes takes turn `turn` of repetition `repetition` when several are timed
/// on one ray list: in order, then in reverse, so that the first of one repetition is the last
/// of the next and a change in the machine's speed meets every scene alike.
pub fn in_turn(repetition: usize, turn: usize, scenes: usize) -> usize {
    match repetition % 2 {
        0 => turn,
        _ => scenes - 1 - turn,
    }
}

/// A ray's closest hit as a caller outside the kernels reads it: where it lies on which
/// micro-triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceHit {
    /// Distance along the ray in units of its direction's length; infinite on a miss.
    pub t: f32,
    /// The micro-triangle, numbered as [`Scene::original_triangle`] numbers it; `NO_HIT` on a
    /// miss.
    pub triangle: u32,
    /// Barycentric coordinates of the hit point: `(1 - u - v) a + u b + v c` for the
    /// micro-triangle's corners `a, b, c` ([`Scene::triangle`]); zero on a miss.
    pub u: f32,
    pub v: f32,
    /// The micro-triangle's unit geometric normal, `(b - a) x (c - a)` normalised; zero on a
    /// miss.
    pub normal: [f32; 3],
}

/// What each of `hits` (the closest hits of `rays` in `scene`, from any backend) lies on:
/// the barycentrics and normal are those of the hit micro-triangle, worked out again in double
/// precision from its corners, so both backends describe a hit alike.
pub fn surface_hits(scene: &Scene, rays: &[RayRecord], hits: &[HitRecord]) -> Vec<SurfaceHit> {
    use rayon::prelude::*;
    rays.par_iter()
        .zip(hits)
        .with_min_len(256)
        .map(|(ray, hit)| surface_hit(scene, ray, hit))
        .collect()
}

fn surface_hit(scene: &Scene, ray: &RayRecord, hit: &HitRecord) -> SurfaceHit {
    if hit.prim == gridrt_shared::layout::NO_HIT {
        return SurfaceHit {
            t: f32::INFINITY,
            triangle: hit.prim,
            u: 0.0,
            v: 0.0,
            normal: [0.0; 3],
        };
    }
    let [a, b, c] = scene.triangle(hit.prim).map(|p| p.as_dvec3());
    let point = Vec3::from(ray.origin).as_dvec3() + Vec3::from(ray.dir).as_dvec3() * hit.t as f64;
    // The barycentrics of the point's projection on the triangle's plane.
    let (e1, e2, p) = (b - a, c - a, point - a);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (p1, p2) = (p.dot(e1), p.dot(e2));
    let det = d11 * d22 - d12 * d12;
    let (u, v) = match det > 0.0 {
        true => ((d22 * p1 - d12 * p2) / det, (d11 * p2 - d12 * p1) / det),
        false => (0.0, 0.0),
    };
    SurfaceHit {
        t: hit.t,
        triangle: scene.original_triangle(hit.prim),
        u: u as f32,
        v: v as f32,
        normal: e1.cross(e2).normalize_or_zero().as_vec3().to_array(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(r: &RayRecord) -> [u32; 6] {
        let [o, d] = [r.origin, r.dir].map(|v| v.map(f32::to_bits));
        [o[0], o[1], o[2], d[0], d[1], d[2]]
    }

    #[test]
    fn coherent_order_is_a_permutation_in_tiles() {
        let bounds = Aabb {
            min: Vec3::ZERO,
            max: Vec3::ONE,
        };
        let (views, w, h) = (2, 20, 11);
        let scanline = primary_rays(&bounds, views, w, h);
        let ao: Vec<RayRecord> = scanline
            .iter()
            .map(|r| record(Vec3::from(r.dir).fract(), Vec3::from(r.dir), 1.0))
            .collect();
        let (mut primary, mut sorted) = (scanline.clone(), ao.clone());
        reorder(RayOrder::Coherent, &mut primary, &mut sorted, views, w, h, &bounds);
        // The first eight rays are the 4x2 block at the corner of the first view.
        let block: Vec<_> = [0, 1, w, w + 1, 2, 3, w + 2, w + 3]
            .iter()
            .map(|&i| key(&scanline[i as usize]))
            .collect();
        assert_eq!(primary[..8].iter().map(key).collect::<Vec<_>>(), block);
        for (a, b) in [(scanline, primary), (ao, sorted)] {
            let (mut a, mut b): (Vec<_>, Vec<_>) = (a.iter().map(key).collect(), b.iter().map(key).collect());
            assert_ne!(a, b);
            a.sort();
            b.sort();
            assert_eq!(a, b);
        }
    }
}
