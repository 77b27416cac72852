//! Camera set-up on the host: framing a scene's bounds automatically.

use gridrt_shared::glam::Vec3;
use gridrt_shared::layout::Camera;

use crate::bvh::Aabb;

/// Vertical field of view of every auto-framed view, in degrees.
pub const FOV_DEGREES: f32 = 40.0;

/// A pinhole camera at `eye` looking at `target`, `+y` up.
pub fn look_at(eye: Vec3, target: Vec3, fov_degrees: f32, width: u32, height: u32) -> Camera {
    let forward = (target - eye).normalize();
    let up_hint = if forward.cross(Vec3::Y).length_squared() < 1e-8 {
        Vec3::Z
    } else {
        Vec3::Y
    };
    let right = forward.cross(up_hint).normalize();
    let up = right.cross(forward);
    let half_h = (fov_degrees.to_radians() * 0.5).tan();
    let half_w = half_h * width as f32 / height as f32;
    Camera {
        origin: eye.to_array(),
        width,
        to_top_left: (forward - right * half_w + up * half_h).to_array(),
        height,
        horizontal: (right * (2.0 * half_w)).to_array(),
        vertical: (up * (-2.0 * half_h)).to_array(),
        ..Default::default()
    }
}

/// View `k` of `views` on an orbit around the scene: azimuths evenly spaced, starting at the
/// front-right, all from 25 degrees above the horizon, at a distance where the bounding
/// sphere fills the frame.
pub fn orbit(bounds: &Aabb, k: u32, views: u32, width: u32, height: u32) -> Camera {
    let center = bounds.center();
    let radius = (bounds.max - bounds.min).length() * 0.5;
    let fov = FOV_DEGREES.to_radians();
    let fit = fov.min(fov * width as f32 / height as f32);
    let distance = radius / (fit * 0.5).sin() * 1.02;
    let azimuth = 35f32.to_radians() + std::f32::consts::TAU * k as f32 / views.max(1) as f32;
    let elevation = 25f32.to_radians();
    let dir = Vec3::new(
        elevation.cos() * azimuth.sin(),
        elevation.sin(),
        elevation.cos() * azimuth.cos(),
    );
    look_at(center + dir * distance, center, FOV_DEGREES, width, height)
}

/// The default auto-framed view.
pub fn frame(bounds: &Aabb, width: u32, height: u32) -> Camera {
    orbit(bounds, 0, 1, width, height)
}
