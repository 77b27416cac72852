use crate::glam::Vec3;
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
}
