use crate::camera::{primary_direction, primary_ray};
use crate::cost::{Costs, Uncounted};
use crate::glam::Vec3;
use crate::layout::{
    Camera, FrameParams, Hit, AO_MISS, AO_OPEN_MASK, SHADE_AMBIENT_OCCLUSION, SHADE_DEPTH, SHADE_LEVEL, SHADE_LIT,
    SHADE_NORMAL, SHADE_PRIMITIVE,
};
use crate::ray::{Ray, T_FAR};
use crate::sample::{cosine_direction, hash, orthonormal_basis, unit_float};
use crate::traverse::{closest_hit, trace_tallied, with_normal, Hierarchy, LeafPrimitives};
// On the GPU, float methods come from a trait (GLSL.std.450 underneath); natively from core.
#[cfg(target_arch = "spirv")]
use spirv_std::num_traits::Float;

/// The plain material ambient occlusion darkens.
const AO_MATERIAL: Vec3 = Vec3::new(0.85, 0.78, 0.62);

/// The clay [`SHADE_LIT`] lights: darker and warmer than [`AO_MATERIAL`], so that light and
/// occlusion both show on it.
const LIT_MATERIAL: Vec3 = Vec3::new(0.62, 0.52, 0.40);

/// The key light's strength and the sky's (linear).
const KEY_LIGHT: f32 = 0.95;
const SKY_LIGHT: f32 = 0.55;

/// How much of the key light ambient occlusion dims: occlusion stands in for the key light's
/// shadows, which would take one more ray per pixel.
const KEY_OCCLUDED: f32 = 0.6;

/// Bits of a [`SHADE_LIT`] pixel above [`AO_OPEN_MASK`]: the key light's cosine, then the
/// sky's (`0.5 + 0.5 n.up`), each in fixed point.
const KEY_SHIFT: u32 = 13;
const KEY_BITS: u32 = 10;
const SKY_SHIFT: u32 = KEY_SHIFT + KEY_BITS;
const SKY_BITS: u32 = 32 - SKY_SHIFT;

/// Colour of a pixel from its closest hit.
///
/// - eye light: a two-sided headlight, so the shape reads without any light set-up;
/// - normal: the unit geometric normal mapped to RGB;
/// - primitive: a colour hashed from the primitive id, to see the micro-triangles;
/// - ambient occlusion and lit: the plain material, which [`ao_pixel`] darkens by occlusion
///   or lights (the kernels return ray counts and light cosines for these instead);
/// - depth: white at `frame.depth_near` from the eye to black at `frame.depth_far`;
/// - level: a colour per depth of the micro-triangles hit (see [`level_color`]), lit by the
///   headlight.
pub fn shade(hit: &Hit, ray: &Ray, frame: &FrameParams) -> Vec3 {
    let mode = frame.shading;
    if !hit.is_hit() {
        // A quiet vertical gradient, so silhouettes stand out.
        let up = 0.5 * (1.0 - ray.dir.normalize().y);
        return Vec3::new(0.12, 0.13, 0.16).lerp(Vec3::new(0.32, 0.34, 0.40), up);
    }
    // Not `normalize_or_zero`: its finiteness check compares with an infinite constant, which
    // shader translators reject.
    let n = Vec3::from(hit.normal);
    let len2 = n.dot(n);
    let n = if len2 > 0.0 { n / len2.sqrt() } else { Vec3::ZERO };
    if mode == SHADE_NORMAL {
        return n * 0.5 + Vec3::splat(0.5);
    }
    if mode == SHADE_AMBIENT_OCCLUSION {
        return AO_MATERIAL;
    }
    if mode == SHADE_DEPTH {
        let span = frame.depth_far - frame.depth_near;
        let d = if span > 0.0 {
            (hit.t - frame.depth_near) / span
        } else {
            0.0
        };
        return Vec3::splat(1.0 - d.clamp(0.0, 1.0));
    }
    let facing = n.dot(ray.dir.normalize()).abs();
    let base = if mode == SHADE_PRIMITIVE {
        hash_color(hit.prim)
    } else if mode == SHADE_LEVEL {
        level_color(hit.level)
    } else {
        Vec3::new(0.85, 0.78, 0.62)
    };
    base * (0.15 + 0.85 * facing)
}

/// Colour of a level of detail: from blue (depth 0, one triangle per grid) through green to
/// red (depth 6), so coarser reads cooler.
pub fn level_color(level: u32) -> Vec3 {
    match level {
        0 => Vec3::new(0.25, 0.2, 0.9),
        1 => Vec3::new(0.15, 0.5, 0.95),
        2 => Vec3::new(0.1, 0.8, 0.8),
        3 => Vec3::new(0.3, 0.85, 0.25),
        4 => Vec3::new(0.95, 0.85, 0.15),
        5 => Vec3::new(0.98, 0.5, 0.1),
        _ => Vec3::new(0.9, 0.15, 0.15),
    }
}

fn hash_color(id: u32) -> Vec3 {
    // Wang-style integer hash; three bytes become the colour.
    let mut h = id ^ 61 ^ (id >> 16);
    h = h.wrapping_mul(9);
    h ^= h >> 4;
    h = h.wrapping_mul(0x27d4_eb2d);
    h ^= h >> 15;
    Vec3::new(
        (h & 0xff) as f32 / 255.0,
        ((h >> 8) & 0xff) as f32 / 255.0,
        ((h >> 16) & 0xff) as f32 / 255.0,
    ) * 0.7
        + Vec3::splat(0.3)
}

/// Linear colour in `[0, 1]` to packed RGBA8 (red in the low byte), with a 2.2 gamma.
pub fn pack_rgba8(color: Vec3) -> u32 {
    let c = color.clamp(Vec3::ZERO, Vec3::ONE);
    let r = (c.x.powf(1.0 / 2.2) * 255.0 + 0.5) as u32;
    let g = (c.y.powf(1.0 / 2.2) * 255.0 + 0.5) as u32;
    let b = (c.z.powf(1.0 / 2.2) * 255.0 + 0.5) as u32;
    r | (g << 8) | (b << 16) | (255 << 24)
}

/// One pixel of a frame, packed RGBA8: its primary ray, the closest hit under `nodes` among
/// `prims`, shaded (lit by its smooth normal if `frame.smooth_normals`). The render kernels and
/// the CPU backend both run exactly this.
///
/// Ambient occlusion is progressive: each pass casts some of a pixel's samples (see
/// `FrameParams::ao_first_sample`), and its pixel is the count of them that meet nothing, or
/// [`AO_MISS`] where the primary ray misses; [`ao_pixel`] makes the colour from the counts of
/// every pass.
///
/// Every ray, primary or not, goes through one call of the traversal: a shader inlines each
/// call whole, and two copies of it make a kernel that lavapipe takes minutes to compile when
/// the scene is split over bindings.
#[inline]
pub fn render_pixel<N: Hierarchy, P: LeafPrimitives>(frame: &FrameParams, nodes: N, prims: &P, x: u32, y: u32) -> u32 {
    // What one ray leaves the next: the primary hit's distance and the normal on the side the
    // primary came from, and the pixel's value so far (the lights, and the open rays counted
    // below them). Each ray is made at the top of the loop from these, so that no ray, point
    // or basis is held across the traversal, where every register counts.
    let (mut t_primary, mut n) = (0.0, Vec3::ZERO);
    let mut value = 0u32;
    // Ray 0 is the primary; under ambient occlusion ray `k > 0` is sample
    // `ao_first_sample + k - 1` (see [`ao_ray`]).
    let mut k = 0u32;
    loop {
        let (ray, t_max) = if k == 0 {
            (primary_ray(&frame.camera, x, y), T_FAR)
        } else {
            let eye = Vec3::from(frame.camera.origin);
            let origin = eye + primary_direction(&frame.camera, x, y) * t_primary + n * frame.ao_offset;
            (
                ao_ray(frame, origin, n, y * frame.camera.width + x, k - 1),
                frame.ao_distance,
            )
        };
        // Occlusion rays ask only whether they hit: no normal.
        let mut hit = closest_hit(nodes, prims, &ray, t_max, &mut Uncounted);
        if k == 0 {
            let primary = ray;
            hit = with_normal(prims, hit);
            // One call site of the smooth normal, whatever the mode: a shader inlines each.
            let mut lit = hit;
            if frame.smooth_normals != 0 && hit.is_hit() {
                lit.normal = prims.smooth_normal(&hit).to_array();
            }
            if frame.shading != SHADE_AMBIENT_OCCLUSION && frame.shading != SHADE_LIT {
                return pack_rgba8(shade(&lit, &primary, frame));
            }
            if !hit.is_hit() {
                return AO_MISS;
            }
            if frame.shading == SHADE_LIT {
                value = light_bits(Vec3::from(lit.normal), primary.dir, &frame.camera);
            }
            let normal = Vec3::from(hit.normal);
            let len2 = normal.dot(normal);
            if len2 == 0.0 {
                // No side to cast from: counted open.
                return value | frame.ao_samples;
            }
            n = normal / len2.sqrt();
            if n.dot(primary.dir) > 0.0 {
                n = -n;
            }
            t_primary = hit.t;
        } else if !hit.is_hit() {
            // Below the lights: at most `ao_samples` (within `AO_OPEN_MASK`) are counted.
            value += 1;
        }
        if k == frame.ao_samples {
            return value;
        }
        k += 1;
    }
}

/// Ambient-occlusion sample `ao_first_sample + i` of pixel `pixel` (its index in the image),
/// from `origin` on the surface of unit normal `n`: cosine-distributed about `n`, its
/// direction a hash of the pixel and the sample, so every run, every split into passes and
/// both backends draw the same ones.
#[inline(always)]
fn ao_ray(frame: &FrameParams, origin: Vec3, n: Vec3, pixel: u32, i: u32) -> Ray {
    let sample = frame.ao_first_sample + i;
    let h = hash(hash(pixel) ^ sample.wrapping_mul(0x9e37_79b9));
    let (t1, t2) = orthonormal_basis(n);
    Ray::new(origin, cosine_direction(n, t1, t2, unit_float(h), unit_float(hash(h))))
}

/// Pixel `sum` of the passes so far with pixel `pass` of one more pass added: their open rays
/// added up, the lights (the same in every pass) kept, a miss kept a miss.
pub fn ao_accumulate(sum: u32, pass: u32) -> u32 {
    if pass == AO_MISS {
        return AO_MISS;
    }
    (pass & !AO_OPEN_MASK) | ((sum & AO_OPEN_MASK) + (pass & AO_OPEN_MASK))
}

/// The packed colour of pixel `(x, y)` under ambient occlusion from the passes' pixels added
/// up by [`ao_accumulate`]: `pixel` counts which of its `samples` rays met nothing (and under
/// [`SHADE_LIT`] holds the lights' cosines), or is [`AO_MISS`] (the background).
///
/// Plain occlusion darkens the plain material. Lit, the clay takes a key light from the
/// upper left of the view, partly dimmed by occlusion, plus a sky brighter above than
/// below, dimmed by occlusion in full; both in linear light, gamma applied once at the end.
pub fn ao_pixel(frame: &FrameParams, x: u32, y: u32, pixel: u32, samples: u32) -> u32 {
    let ray = primary_ray(&frame.camera, x, y);
    if pixel == AO_MISS {
        return pack_rgba8(shade(&Hit::miss(T_FAR), &ray, frame));
    }
    let open = pixel & AO_OPEN_MASK;
    let visible = if samples > 0 { open as f32 / samples as f32 } else { 1.0 };
    if frame.shading != SHADE_LIT {
        return pack_rgba8(AO_MATERIAL * (0.1 + 0.9 * visible));
    }
    let key = unpack_unorm(pixel >> KEY_SHIFT, KEY_BITS);
    let sky = unpack_unorm(pixel >> SKY_SHIFT, SKY_BITS);
    let key_light = KEY_LIGHT * key * (1.0 - KEY_OCCLUDED + KEY_OCCLUDED * visible);
    pack_rgba8(LIT_MATERIAL * (key_light + SKY_LIGHT * sky * visible))
}

/// The key light's and the sky's cosines at a hit with normal `normal` (any length; turned
/// to face the eye) seen along `view`, packed above [`AO_OPEN_MASK`]. The lights follow the
/// camera (the key from its upper left and a little behind it, the sky from its up), so every
/// view of any mesh, whatever its up axis, is lit alike.
fn light_bits(normal: Vec3, view: Vec3, camera: &Camera) -> u32 {
    let len2 = normal.dot(normal);
    if len2 == 0.0 {
        return 0;
    }
    let mut n = normal / len2.sqrt();
    if n.dot(view) > 0.0 {
        n = -n;
    }
    let (right, up, forward) = camera_axes(camera);
    let key = (up * 0.65 - right * 0.45 - forward * 0.6).normalize();
    let key_cos = n.dot(key).max(0.0);
    let sky_cos = 0.5 + 0.5 * n.dot(up);
    (pack_unorm(key_cos, KEY_BITS) << KEY_SHIFT) | (pack_unorm(sky_cos, SKY_BITS) << SKY_SHIFT)
}

/// The picture's right, up and forward directions (unit).
fn camera_axes(camera: &Camera) -> (Vec3, Vec3, Vec3) {
    let (h, v) = (Vec3::from(camera.horizontal), Vec3::from(camera.vertical));
    let forward = Vec3::from(camera.to_top_left) + h * 0.5 + v * 0.5;
    (h.normalize(), -v.normalize(), forward.normalize())
}

/// `x` in `[0, 1]` as a `bits`-bit unsigned fixed-point number, rounded.
fn pack_unorm(x: f32, bits: u32) -> u32 {
    let top = ((1u32 << bits) - 1) as f32;
    (x.clamp(0.0, 1.0) * top + 0.5) as u32
}

/// The low `bits` of `packed` as a fraction of their largest value.
fn unpack_unorm(packed: u32, bits: u32) -> f32 {
    let top = (1u32 << bits) - 1;
    (packed & top) as f32 / top as f32
}

/// The tests pixel `(x, y)`'s primary ray makes, packed (see [`Costs::pack`]): what the cost
/// heat map runs (on the CPU) instead of [`render_pixel`].
#[inline]
pub fn cost_pixel<N: Hierarchy, P: LeafPrimitives>(frame: &FrameParams, nodes: N, prims: &P, x: u32, y: u32) -> u32 {
    let ray = primary_ray(&frame.camera, x, y);
    let mut costs = Costs::default();
    trace_tallied(nodes, prims, &ray, T_FAR, &mut costs);
    costs.pack()
}
