use crate::glam::Vec3;
use crate::layout::Camera;
use crate::ray::Ray;

/// The primary ray through the centre of pixel `(x, y)`, `y` growing downwards.
#[inline]
pub fn primary_ray(camera: &Camera, x: u32, y: u32) -> Ray {
    let fx = (x as f32 + 0.5) / camera.width as f32;
    let fy = (y as f32 + 0.5) / camera.height as f32;
    let target = Vec3::from(camera.top_left) + Vec3::from(camera.horizontal) * fx + Vec3::from(camera.vertical) * fy;
    let origin = Vec3::from(camera.origin);
    Ray::new(origin, (target - origin).normalize())
}
