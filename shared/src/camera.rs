use crate::glam::Vec3;
use crate::layout::Camera;
use crate::ray::Ray;

/// The primary ray through the centre of pixel `(x, y)`, `y` growing downwards.
#[inline]
pub fn primary_ray(camera: &Camera, x: u32, y: u32) -> Ray {
    Ray::new(Vec3::from(camera.origin), primary_direction(camera, x, y))
}

/// The unit direction of [`primary_ray`]`(camera, x, y)`.
#[inline]
pub fn primary_direction(camera: &Camera, x: u32, y: u32) -> Vec3 {
    let fx = (x as f32 + 0.5) / camera.width as f32;
    let fy = (y as f32 + 0.5) / camera.height as f32;
    let dir = Vec3::from(camera.to_top_left) + Vec3::from(camera.horizontal) * fx + Vec3::from(camera.vertical) * fy;
    dir.normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pixel's direction does not depend on where the eye is: the same camera moved far from
    /// the origin gives every pixel the same direction as at the origin, so neighbouring
    /// pixels stay apart.
    #[test]
    fn directions_do_not_depend_on_the_eye_position() {
        let at = |origin: [f32; 3]| Camera {
            origin,
            width: 64,
            to_top_left: [-0.4, 0.3, -1.0],
            height: 48,
            horizontal: [0.8, 0.0, 0.0],
            vertical: [0.0, -0.6, 0.0],
            ..Default::default()
        };
        let near = at([0.0; 3]);
        for origin in [[1.0e7, -3.0e6, 2.0e7], [1.0e-30, 0.0, 0.0], [-3.0e30, 1.0e30, 0.0]] {
            let far = at(origin);
            for (x, y) in [(0, 0), (1, 0), (31, 24), (63, 47)] {
                assert_eq!(primary_ray(&near, x, y).dir, primary_ray(&far, x, y).dir);
            }
            assert_ne!(primary_ray(&far, 31, 24).dir, primary_ray(&far, 32, 24).dir);
        }
    }
}
