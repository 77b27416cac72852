use crate::glam::{Vec3, Vec4};
use crate::min_max::{max_of, min_of};
use crate::ray::{Ray, T_FAR};

/// Makes the exit distance conservative against the rounding of the six slab distances
/// (Ize, "Robust BVH ray traversal", JCGT 2013): without it a flat box, or a ray through a
/// box's edge, can come out empty and hide a triangle that the watertight test would hit.
const EXIT_SCALE: f32 = 1.0 + 4.0 * f32::EPSILON;

/// Slab test. Returns the entry distance when the box overlaps `[0, t_max]` along the ray,
/// otherwise `T_FAR`.
#[inline]
pub fn intersect_aabb(min: Vec3, max: Vec3, ray: &Ray, t_max: f32) -> f32 {
    let t0 = (min - ray.origin) * ray.inv_dir;
    let t1 = (max - ray.origin) * ray.inv_dir;
    let near = t0.min(t1);
    let far = t0.max(t1);
    let t_enter = max_of(max_of(max_of(near.x, near.y), near.z), 0.0);
    // A zero direction component has the reciprocal `1 / tiny` (see `Ray::inv_dir`); with
    // the origin exactly on one of that axis's faces the face's distance is `0 * 1 / tiny`,
    // an exit at 0 from a slab the ray never leaves, and a ray through a vertex on such a
    // face would slip past every triangle around it. A slab exit of exactly 0 is therefore
    // read as no exit: conservative, since a box merely touching the origin is then entered.
    // Looked at only where the nearest exit is 0 (were another exit negative, it would be
    // nearer than any replaced one), which is rare: the common case costs one comparison.
    let mut exit = min_of(min_of(far.x, far.y), far.z);
    if exit == 0.0 {
        exit = min_of(
            min_of(no_exit_at_zero(far.x), no_exit_at_zero(far.y)),
            no_exit_at_zero(far.z),
        );
    }
    let t_exit = min_of(exit * EXIT_SCALE, t_max);
    if t_enter <= t_exit {
        t_enter
    } else {
        T_FAR
    }
}

/// [`intersect_aabb`] of four boxes at once, lane `k` of `min` and `max` holding box `k`'s
/// bounds on each axis: the same operations in the same order, lane by lane, so each lane is
/// bit for bit the distance `intersect_aabb` gives its box (a CPU makes the four in SIMD
/// lanes; a GPU runs them as it would four scalar tests).
#[inline(always)]
pub fn intersect_aabbs(min: [Vec4; 3], max: [Vec4; 3], ray: &Ray, t_max: f32) -> Vec4 {
    let origin = [ray.origin.x, ray.origin.y, ray.origin.z];
    let inv_dir = [ray.inv_dir.x, ray.inv_dir.y, ray.inv_dir.z];
    let slab = |a: usize| {
        let t0 = (min[a] - Vec4::splat(origin[a])) * inv_dir[a];
        let t1 = (max[a] - Vec4::splat(origin[a])) * inv_dir[a];
        (t0.min(t1), t0.max(t1))
    };
    let (near_x, far_x) = slab(0);
    let (near_y, far_y) = slab(1);
    let (near_z, far_z) = slab(2);
    let t_enter = near_x.max(near_y).max(near_z).max(Vec4::ZERO);
    let mut exit = far_x.min(far_y).min(far_z);
    let zero = exit.cmpeq(Vec4::ZERO);
    if zero.any() {
        let open = |far: Vec4| Vec4::select(far.cmpeq(Vec4::ZERO), Vec4::splat(T_FAR), far);
        exit = Vec4::select(zero, open(far_x).min(open(far_y)).min(open(far_z)), exit);
    }
    let t_exit = (exit * EXIT_SCALE).min(Vec4::splat(t_max));
    Vec4::select(t_enter.cmple(t_exit), t_enter, Vec4::splat(T_FAR))
}

#[inline]
fn no_exit_at_zero(t: f32) -> f32 {
    if t == 0.0 {
        T_FAR
    } else {
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn test(o: [f32; 3], d: [f32; 3], t_max: f32) -> f32 {
        intersect_aabb(Vec3::ZERO, Vec3::ONE, &Ray::new(Vec3::from(o), Vec3::from(d)), t_max)
    }

    #[test]
    fn entry_distance_and_misses() {
        assert_eq!(test([0.5, 0.5, -1.0], [0.0, 0.0, 1.0], T_FAR), 1.0);
        assert_eq!(test([0.5, 0.5, -1.0], [0.0, 0.0, -1.0], T_FAR), T_FAR);
        assert_eq!(test([1.5, 0.5, -1.0], [0.0, 0.0, 1.0], T_FAR), T_FAR);
        assert_eq!(test([0.5, 0.5, -1.0], [0.0, 0.0, 1.0], 0.5), T_FAR);
    }

    #[test]
    fn origin_inside_enters_at_zero() {
        assert_eq!(test([0.5, 0.5, 0.5], [0.3, -0.2, 1.0], T_FAR), 0.0);
    }

    #[test]
    fn axis_parallel_rays_on_a_face_plane() {
        // Zero direction components give infinite reciprocals; a ray lying in the plane of a
        // face must not turn into NaNs that accept or reject everything.
        assert_eq!(test([0.0, 0.5, -1.0], [0.0, 0.0, 1.0], T_FAR), 1.0);
        assert_eq!(test([-0.1, 0.5, -1.0], [0.0, 0.0, 1.0], T_FAR), T_FAR);
        // The far faces too, with either sign of the zero component.
        assert_eq!(test([1.0, 0.5, -1.0], [0.0, 0.0, 1.0], T_FAR), 1.0);
        assert_eq!(test([1.0, 1.0, -1.0], [-0.0, 0.0, 1.0], T_FAR), 1.0);
        assert_eq!(test([0.5, 1.0, 2.0], [0.0, -0.0, -1.0], T_FAR), 1.0);
        assert_eq!(test([1.1, 0.5, -1.0], [0.0, 0.0, 1.0], T_FAR), T_FAR);
        // A flat box seen along its own plane, from outside it and from a corner.
        let flat = |o: [f32; 3], d: [f32; 3]| {
            intersect_aabb(
                Vec3::new(0.0, 0.0, 0.5),
                Vec3::new(1.0, 1.0, 0.5),
                &Ray::new(Vec3::from(o), Vec3::from(d)),
                T_FAR,
            )
        };
        assert_eq!(flat([-1.0, 0.5, 0.5], [1.0, 0.0, 0.0]), 1.0);
        assert_eq!(flat([2.0, 1.0, 0.5], [-1.0, 0.0, 0.0]), 1.0);
        assert_eq!(flat([2.0, 1.0, 0.6], [-1.0, 0.0, 0.0]), T_FAR);
    }

    #[test]
    fn flat_box_is_hit() {
        let b = intersect_aabb(
            Vec3::new(0.0, 0.0, 0.5),
            Vec3::new(1.0, 1.0, 0.5),
            &Ray::new(Vec3::new(0.5, 0.5, 0.0), Vec3::Z),
            T_FAR,
        );
        assert_eq!(b, 0.5);
    }

    #[test]
    fn four_lanes_match_the_scalar_test() {
        // Boxes and rays from a fixed sequence, many of them with coordinates on a coarse
        // grid, so that origins on faces, flat boxes and zero direction components come up.
        let mut state = 0x2545_f491_u32;
        let mut next = |coarse: bool| {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            let unit = (state >> 8) as f32 / (1 << 24) as f32;
            if coarse {
                ((unit * 5.0) as i32 - 2) as f32 * 0.5
            } else {
                unit * 4.0 - 2.0
            }
        };
        let mut compared = 0;
        for round in 0..4000 {
            let coarse = round % 2 == 0;
            let mut v = || Vec3::new(next(coarse), next(coarse), next(coarse));
            let boxes: [(Vec3, Vec3); 4] = core::array::from_fn(|k| {
                let (a, b) = (v(), v());
                let (lo, mut hi) = (a.min(b), a.max(b));
                // Flat boxes, whose entry and exit coincide but for rounding.
                if k == 3 {
                    hi[round % 3] = lo[round % 3];
                }
                (lo, hi)
            });
            // Some rays aimed at a box's centre, so that many enter their boxes, and some
            // through one of its edges, where an entry and an exit coincide but for rounding.
            let origin = v();
            let (lo, hi) = boxes[round % 4];
            let dir = match round % 4 {
                0 | 1 => v(),
                2 => (lo + hi) * 0.5 - origin,
                _ => Vec3::new(lo.x, hi.y, (lo.z + hi.z) * 0.5) - origin,
            };
            let ray = Ray::new(origin, dir);
            let t_max = if round % 3 == 0 { T_FAR } else { 1.5 };
            let lanes = |f: fn(Vec3) -> f32| {
                (
                    Vec4::new(f(boxes[0].0), f(boxes[1].0), f(boxes[2].0), f(boxes[3].0)),
                    Vec4::new(f(boxes[0].1), f(boxes[1].1), f(boxes[2].1), f(boxes[3].1)),
                )
            };
            let (x, y, z) = (lanes(|p| p.x), lanes(|p| p.y), lanes(|p| p.z));
            let four = intersect_aabbs([x.0, y.0, z.0], [x.1, y.1, z.1], &ray, t_max).to_array();
            for (k, (lo, hi)) in boxes.iter().enumerate() {
                assert_eq!(four[k], intersect_aabb(*lo, *hi, &ray, t_max), "round {round}, box {k}");
                compared += (four[k] < T_FAR) as u32;
            }
        }
        // Enough of them hit for the comparison to mean something.
        assert!(compared > 2000, "{compared} hits");
    }
}
