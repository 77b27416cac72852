//! Camera set-up on the host: framing a scene's bounds automatically, or from a
//! [`Viewpoint`] given in part or in full.

use crate::error::{fail, Result};
use gridrt_shared::glam::{DVec3, Vec3};
use gridrt_shared::layout::Camera;

use crate::bvh::Aabb;
use crate::mesh::frame::LocalFrame;

/// Vertical field of view of every auto-framed view, in degrees.
pub const FOV_DEGREES: f32 = 40.0;

/// A pinhole camera at `eye` looking at `target`, `+y` up (`+z` when looking along `y`).
pub fn look_at(eye: Vec3, target: Vec3, fov_degrees: f32, width: u32, height: u32) -> Camera {
    let forward = (target - eye).normalize();
    let up_hint = if forward.cross(Vec3::Y).length_squared() < 1e-8 {
        Vec3::Z
    } else {
        Vec3::Y
    };
    look_at_up(eye, forward, up_hint, fov_degrees, width, height)
}

/// A pinhole camera at `eye` looking along unit `forward`, `up_hint` (not parallel to it)
/// pointing up in the picture.
fn look_at_up(eye: Vec3, forward: Vec3, up_hint: Vec3, fov_degrees: f32, width: u32, height: u32) -> Camera {
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

/// The default auto-framed view: [`view`] from the default [`Viewpoint`], the box filling
/// the frame ([`orbit`]'s first view where that fails, as for a box that is not finite).
pub fn frame(bounds: &Aabb, width: u32, height: u32) -> Camera {
    view(bounds, &Viewpoint::default(), width, height).unwrap_or_else(|_| orbit(bounds, 0, 1, width, height))
}

/// Where a camera stands and looks, in the scene's coordinates. Every part left out is chosen
/// from the scene's bounds as [`frame`] chooses it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Viewpoint {
    /// The eye; `None`: on the orbit `azimuth`, `elevation`, `distance` around the target.
    pub eye: Option<Vec3>,
    /// The point looked at; `None`: the centre of the bounds.
    pub target: Option<Vec3>,
    /// Up in the picture (any length, not along the view).
    pub up: Vec3,
    /// Vertical field of view.
    pub fov_degrees: f32,
    /// Around `up`, from the front (`+z` when `up` is `+y`) towards `+x`.
    pub azimuth_degrees: f32,
    /// Above the plane across `up`.
    pub elevation_degrees: f32,
    /// From the target; `None`: as close as the bounds fit in the frame (see [`view`]).
    pub distance: Option<f32>,
}

impl Default for Viewpoint {
    fn default() -> Self {
        Viewpoint {
            eye: None,
            target: None,
            up: Vec3::Y,
            fov_degrees: FOV_DEGREES,
            azimuth_degrees: 35.0,
            elevation_degrees: 25.0,
            distance: None,
        }
    }
}

/// A [`Viewpoint`] in a mesh file's units (double precision, far from the origin as the file
/// may be): what a user gives, before it is moved into the mesh's local frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FileViewpoint {
    pub eye: Option<DVec3>,
    pub target: Option<DVec3>,
    pub up: Vec3,
    pub fov_degrees: f32,
    pub azimuth_degrees: f32,
    pub elevation_degrees: f32,
    pub distance: Option<f64>,
}

impl Default for FileViewpoint {
    fn default() -> Self {
        let v = Viewpoint::default();
        FileViewpoint {
            eye: None,
            target: None,
            up: v.up,
            fov_degrees: v.fov_degrees,
            azimuth_degrees: v.azimuth_degrees,
            elevation_degrees: v.elevation_degrees,
            distance: None,
        }
    }
}

impl FileViewpoint {
    /// The same viewpoint in the local frame `frame` maps the file's units to.
    pub fn local(&self, frame: &LocalFrame) -> Viewpoint {
        Viewpoint {
            eye: self.eye.map(|p| frame.to_local(p)),
            target: self.target.map(|p| frame.to_local(p)),
            up: self.up,
            fov_degrees: self.fov_degrees,
            azimuth_degrees: self.azimuth_degrees,
            elevation_degrees: self.elevation_degrees,
            distance: self.distance.map(|d| (d * frame.scale) as f32),
        }
    }
}

/// Refuses fields of view and numbers no camera can be made of.
fn check(v: &Viewpoint, height: u32) -> Result<()> {
    if !(v.fov_degrees > 0.0 && v.fov_degrees < 180.0) {
        fail!(
            Options,
            "a field of view of {} degrees is not between 0 and 180",
            v.fov_degrees
        );
    }
    let narrowest = narrowest_fov_degrees(height);
    if v.fov_degrees < narrowest {
        fail!(
            Options,
            "a field of view of {} degrees is too narrow for a picture {height} pixels high: 32-bit \
             rays cannot tell its pixels apart; use at least {:.4} degrees",
            v.fov_degrees,
            (narrowest * 1e4).ceil() / 1e4
        );
    }
    let angles = [v.azimuth_degrees, v.elevation_degrees];
    let points_finite = [v.eye, v.target, Some(v.up)]
        .into_iter()
        .flatten()
        .all(|p| p.is_finite());
    if !angles.iter().all(|a| a.is_finite()) || !points_finite {
        fail!(Options, "a camera position, direction or angle is not a finite number");
    }
    if v.distance.is_some_and(|d| !(d.is_finite() && d > 0.0)) {
        fail!(
            Options,
            "a camera distance of {:?} is not a finite length above zero",
            v.distance
        );
    }
    Ok(())
}

/// The camera `viewpoint` describes for a scene within `bounds`: [`view_of`] the box's
/// corners.
pub fn view(bounds: &Aabb, viewpoint: &Viewpoint, width: u32, height: u32) -> Result<Camera> {
    view_of(&bounds.corners(), viewpoint, width, height)
}

/// The camera `viewpoint` describes for a scene drawn within the convex hull of `points` (a
/// mesh's vertices hold its flat, Loop-subdivided and displaced micro-triangles alike). Without
/// an eye or a distance, the closest view along the viewpoint's direction in which every point
/// falls inside [`FILL`] of the frame; without a target either, that view is also centred
/// on the points' picture rather than on their box. Refuses a view with no direction (the eye
/// on the target) or no up (up along the view, or zero).
pub fn view_of(points: &[Vec3], viewpoint: &Viewpoint, width: u32, height: u32) -> Result<Camera> {
    let placed = placement(points, viewpoint, width, height)?;
    Ok(look_at_up(
        placed.eye,
        placed.forward,
        placed.up,
        viewpoint.fov_degrees,
        width,
        height,
    ))
}

/// Where [`view_of`] puts the eye, and what it looks at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    pub eye: Vec3,
    pub target: Vec3,
    /// Unit direction from the eye to the target.
    pub forward: Vec3,
    /// Unit up, as asked.
    pub up: Vec3,
}

/// The eye and target of [`view_of`], checked as it checks them.
pub fn placement(points: &[Vec3], viewpoint: &Viewpoint, width: u32, height: u32) -> Result<Placement> {
    let v = viewpoint;
    check(v, height)?;
    let empty = points.is_empty();
    let points = if empty { &[Vec3::ZERO][..] } else { points };
    let up = v.up.normalize_or_zero();
    if up == Vec3::ZERO {
        fail!(Options, "the up direction {} has no length", v.up);
    }
    let bounds = Aabb::from_points(points.iter().copied());
    let extent = (bounds.max - bounds.min).max_element();
    if !empty && (extent.is_nan() || extent <= 0.0) {
        fail!(
            Input,
            "the scene has no size: all its points are at {}, so there is nothing to look at",
            bounds.min
        );
    }
    let back = orbit_direction(up, v.azimuth_degrees, v.elevation_degrees);
    let lens = Lens::new(back, up, v.fov_degrees, width as f32 / height as f32);
    let centre = bounds.center();
    let (eye, target) = match (v.eye, v.target, v.distance) {
        (Some(eye), target, _) => (eye, target.unwrap_or(centre)),
        (None, target, Some(distance)) => {
            let target = target.unwrap_or(centre);
            (target + back * distance, target)
        }
        (None, Some(target), None) => (target + back * lens.fitting_distance(points, target), target),
        (None, None, None) => lens.tightest(points, centre),
    };
    // A flat, tiny or empty subject still leaves the eye off the target.
    let least = (bounds.max - bounds.min).length() * 0.5;
    let fitted = v.eye.is_none() && v.distance.is_none();
    let away = (eye - target).length();
    let eye = if fitted && (away.is_nan() || away < least) {
        target + back * least.max(f32::MIN_POSITIVE)
    } else {
        eye
    };
    let size = (bounds.max - bounds.min).length().max(f32::MIN_POSITIVE) as f64;
    let far = (target.as_dvec3() - eye.as_dvec3()).length() / size;
    if far > FARTHEST {
        fail!(
            Options,
            "the eye is {far:.1e} times the scene's size from the target: at most {FARTHEST:.0e}, \
             beyond which 32-bit rays lose the scene"
        );
    }
    let forward = (target - eye).normalize_or_zero();
    if forward == Vec3::ZERO {
        fail!(Options, "the eye is on the target: no direction to look in");
    }
    if forward.cross(up).length_squared() < 1e-8 {
        fail!(
            Options,
            "the up direction {} is along the view: no way to tell up in the picture",
            v.up
        );
    }
    Ok(Placement {
        eye,
        target,
        forward,
        up,
    })
}

/// The farthest an eye may stand from its target, in sizes of the scene (its bounding box's
/// diagonal).
pub const FARTHEST: f64 = 1e6;

/// The angle between neighbouring pixels' rays below which 32-bit directions (unit length,
/// their parts rounded to 2^-24) no longer step evenly from pixel to pixel: 2^-18 radians
/// leaves 64 steps of rounding between them.
const NARROWEST_PIXEL_RADIANS: f32 = 1.0 / 262_144.0;

/// The narrowest vertical field of view a picture `height` pixels high can be rendered at.
pub fn narrowest_fov_degrees(height: u32) -> f32 {
    (NARROWEST_PIXEL_RADIANS * height as f32).to_degrees()
}

/// Share of the frame the auto-framed box's picture may fill, each way.
pub const FILL: f32 = 0.95;

/// The view's frame as auto-framing sees it: its axes, and the tangents of the half angles
/// that [`FILL`] of it spans.
struct Lens {
    back: Vec3,
    right: Vec3,
    up: Vec3,
    tan_v: f32,
    tan_h: f32,
}

impl Lens {
    /// The frame looking along `-back` (unit) with `up` (unit, not along it) up.
    fn new(back: Vec3, up: Vec3, fov_degrees: f32, aspect: f32) -> Lens {
        let right = up.cross(back).normalize();
        let tan_v = (fov_degrees.to_radians() * 0.5).tan() * FILL;
        Lens {
            back,
            right,
            up: back.cross(right),
            tan_v,
            tan_h: tan_v * aspect,
        }
    }

    /// How far back from `target` the eye must stand for every point to fall inside the
    /// frame: each point's offset across the view, over the tangent of the half field of
    /// view, plus its depth towards the eye.
    fn fitting_distance(&self, points: &[Vec3], target: Vec3) -> f32 {
        (points.iter())
            .map(|&p| {
                let r = p - target;
                r.dot(self.back) + (r.dot(self.right).abs() / self.tan_h).max(r.dot(self.up).abs() / self.tan_v)
            })
            .fold(0.0, f32::max)
    }

    /// The closest eye from which every point falls inside the frame, and the target it looks
    /// at (on its view axis, as deep as `centre`).
    ///
    /// In the view's axes, a point `(x, y, z)` (`z` along the view) is inside when
    /// `|x - ex| <= tan_h (z - ez)` and `|y - ey| <= tan_v (z - ez)`. The right and left
    /// sides are tightest through the points of greatest `x - tan_h z` and `-x - tan_h z`;
    /// both through the eye fixes `ex` and the depth the width needs. The top and bottom fix
    /// `ey` and the depth the height needs, and the eye takes the farther of the two depths
    /// (moving back along the view keeps every point inside).
    fn tightest(&self, points: &[Vec3], centre: Vec3) -> (Vec3, Vec3) {
        let forward = -self.back;
        let reach = |axis: Vec3, tan: f32| {
            let (mut plus, mut minus) = (f32::NEG_INFINITY, f32::NEG_INFINITY);
            for &p in points {
                let (a, z) = (p.dot(axis), p.dot(forward));
                plus = plus.max(a - tan * z);
                minus = minus.max(-a - tan * z);
            }
            // The eye's offset along the axis, and its depth.
            (0.5 * (plus - minus), -0.5 * (plus + minus) / tan)
        };
        let (ex, depth_x) = reach(self.right, self.tan_h);
        let (ey, depth_y) = reach(self.up, self.tan_v);
        let eye = self.right * ex + self.up * ey + forward * depth_x.min(depth_y);
        let target = eye + forward * (centre - eye).dot(forward);
        (eye, target)
    }
}

/// Unit direction from a target to an eye at `azimuth` and `elevation` (degrees) about `up`
/// (unit): the front is the part of `+z` across `up` (of `+x` when `up` is along `z`).
fn orbit_direction(up: Vec3, azimuth: f32, elevation: f32) -> Vec3 {
    let across = |axis: Vec3| axis - up * up.dot(axis);
    let front = match across(Vec3::Z) {
        f if f.length_squared() > 1e-8 => f.normalize(),
        _ => across(Vec3::X).normalize(),
    };
    let side = up.cross(front);
    let (a, e) = (azimuth.to_radians(), elevation.to_radians());
    side * (e.cos() * a.sin()) + up * e.sin() + front * (e.cos() * a.cos())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bounds() -> Aabb {
        Aabb {
            min: Vec3::new(-1.0, -0.5, -0.25),
            max: Vec3::new(1.0, 0.5, 0.25),
        }
    }

    /// The auto-framed box fills the frame: every corner inside it, and one near its edge.
    #[test]
    fn the_box_fills_the_frame() {
        let b = bounds();
        for (azimuth, elevation) in [(35.0, 25.0), (0.0, 0.0), (90.0, 80.0), (200.0, -30.0)] {
            let v = Viewpoint {
                azimuth_degrees: azimuth,
                elevation_degrees: elevation,
                ..Viewpoint::default()
            };
            let c = view(&b, &v, 64, 48).unwrap();
            let (eye, h, vv) = (Vec3::from(c.origin), Vec3::from(c.horizontal), Vec3::from(c.vertical));
            let normal = h.cross(vv).normalize();
            let mut widest = 0f32;
            for (k, p) in b.corners().into_iter().enumerate() {
                // The corner on the image plane, one unit along the view from the eye.
                let d = p - eye;
                let on_plane = d / d.dot(normal).abs() * (Vec3::from(c.to_top_left).dot(normal).abs());
                let rel = on_plane - Vec3::from(c.to_top_left);
                let (u, w) = (rel.dot(h) / h.length_squared(), rel.dot(vv) / vv.length_squared());
                assert!(
                    (0.0..=1.0).contains(&u) && (0.0..=1.0).contains(&w),
                    "corner {k} at {u}, {w}"
                );
                widest = widest.max((u - 0.5).abs()).max((w - 0.5).abs());
            }
            assert!(widest > 0.4, "the box fills too little: {widest}");
        }
    }

    /// Where `p` falls in the picture of camera `c`: `(0, 0)` the top left corner, `(1, 1)`
    /// the bottom right.
    fn in_picture(c: &Camera, p: Vec3) -> (f32, f32) {
        let (eye, h, v) = (Vec3::from(c.origin), Vec3::from(c.horizontal), Vec3::from(c.vertical));
        let corner = Vec3::from(c.to_top_left);
        let normal = h.cross(v).normalize();
        let d = p - eye;
        let rel = d * (corner.dot(normal) / d.dot(normal)) - corner;
        (rel.dot(h) / h.length_squared(), rel.dot(v) / v.length_squared())
    }

    /// An uneven cloud: a long arm off a ball, most points on one side of the box.
    fn arm_and_ball() -> Vec<Vec3> {
        let mut points = Vec::new();
        for k in 0..400 {
            let (a, b) = (k as f32 * 0.7, k as f32 * 1.3);
            points.push(Vec3::new(a.cos() * b.sin(), a.sin() * b.sin(), b.cos()) * 0.5);
        }
        points.extend((0..50).map(|k| Vec3::new(0.5 + k as f32 * 0.05, 0.1 * (k as f32 * 0.4).sin(), 0.2)));
        points
    }

    /// The tight view keeps every point inside the frame's margin, touches it on two opposite
    /// sides, and comes closer than the box's view.
    #[test]
    fn every_point_falls_inside_the_tight_frame() {
        let points = arm_and_ball();
        let bounds = Aabb::from_points(points.iter().copied());
        for (azimuth, elevation) in [(35.0, 25.0), (0.0, 0.0), (90.0, 80.0), (200.0, -30.0), (300.0, 10.0)] {
            let v = Viewpoint {
                azimuth_degrees: azimuth,
                elevation_degrees: elevation,
                ..Viewpoint::default()
            };
            let tight = view_of(&points, &v, 64, 48).unwrap();
            let placed: Vec<(f32, f32)> = points.iter().map(|&p| in_picture(&tight, p)).collect();
            let margin = 0.5 * (1.0 - FILL) - 1e-4;
            for (k, &(x, y)) in placed.iter().enumerate() {
                let inside = |t: f32| (margin..=1.0 - margin).contains(&t);
                assert!(
                    inside(x) && inside(y),
                    "point {k} at {x}, {y} from {azimuth}, {elevation}"
                );
            }
            let extent = |pick: fn(&(f32, f32)) -> f32| {
                let lo = placed.iter().map(pick).fold(f32::INFINITY, f32::min);
                let hi = placed.iter().map(pick).fold(f32::NEG_INFINITY, f32::max);
                (lo, hi)
            };
            let ((x0, x1), (y0, y1)) = (extent(|p| p.0), extent(|p| p.1));
            let touches = |lo: f32, hi: f32| lo < margin + 1e-3 && hi > 1.0 - margin - 1e-3;
            assert!(touches(x0, x1) || touches(y0, y1), "{x0}..{x1}, {y0}..{y1}");
            let boxed = view(&bounds, &v, 64, 48).unwrap();
            let centre = bounds.center();
            let distance = |c: &Camera| Vec3::from(c.origin).distance(centre);
            assert!(distance(&tight) < distance(&boxed), "{azimuth}, {elevation}");
        }
    }

    /// A given target stays in the middle of the picture; the eye still keeps every point
    /// inside.
    #[test]
    fn a_given_target_is_looked_at() {
        let points = arm_and_ball();
        let v = Viewpoint {
            target: Some(Vec3::ZERO),
            ..Viewpoint::default()
        };
        let c = view_of(&points, &v, 64, 48).unwrap();
        let (x, y) = in_picture(&c, Vec3::ZERO);
        assert!((x - 0.5).abs() < 1e-5 && (y - 0.5).abs() < 1e-5, "{x}, {y}");
        for p in points {
            let (x, y) = in_picture(&c, p);
            assert!((0.0..=1.0).contains(&x) && (0.0..=1.0).contains(&y), "{p} at {x}, {y}");
        }
    }

    #[test]
    fn an_eye_and_a_target_are_kept() {
        let v = Viewpoint {
            eye: Some(Vec3::new(0.0, 0.0, 5.0)),
            target: Some(Vec3::ZERO),
            ..Viewpoint::default()
        };
        let c = view(&bounds(), &v, 64, 48).unwrap();
        assert_eq!(c.origin, [0.0, 0.0, 5.0]);
        // The centre pixel looks straight at the target, up is up.
        let centre = Vec3::from(c.to_top_left) + Vec3::from(c.horizontal) * 0.5 + Vec3::from(c.vertical) * 0.5;
        assert!(centre.normalize().distance(-Vec3::Z) < 1e-6, "{centre}");
        assert!(Vec3::from(c.vertical).y < 0.0);
        // From behind, around +y: the eye at -z.
        let behind = Viewpoint {
            azimuth_degrees: 180.0,
            elevation_degrees: 0.0,
            distance: Some(3.0),
            ..Viewpoint::default()
        };
        let c = view(&bounds(), &behind, 64, 48).unwrap();
        assert!(Vec3::from(c.origin).distance(Vec3::new(0.0, 0.0, -3.0)) < 1e-5);
        // Up along z: the front is +x.
        let z_up = Viewpoint {
            up: Vec3::Z,
            azimuth_degrees: 0.0,
            elevation_degrees: 0.0,
            distance: Some(2.0),
            ..Viewpoint::default()
        };
        let c = view(&bounds(), &z_up, 64, 48).unwrap();
        assert!(Vec3::from(c.origin).distance(Vec3::new(2.0, 0.0, 0.0)) < 1e-5);
    }

    #[test]
    fn views_without_a_direction_or_an_up_are_refused() {
        let on_target = Viewpoint {
            eye: Some(Vec3::ONE),
            target: Some(Vec3::ONE),
            ..Viewpoint::default()
        };
        let up_along = Viewpoint {
            eye: Some(Vec3::new(0.0, 3.0, 0.0)),
            target: Some(Vec3::ZERO),
            ..Viewpoint::default()
        };
        let no_up = Viewpoint {
            up: Vec3::ZERO,
            ..Viewpoint::default()
        };
        let wide = Viewpoint {
            fov_degrees: 180.0,
            ..Viewpoint::default()
        };
        let spun = Viewpoint {
            azimuth_degrees: f32::INFINITY,
            ..Viewpoint::default()
        };
        let far = Viewpoint {
            distance: Some(f32::INFINITY),
            ..Viewpoint::default()
        };
        for (v, needle) in [
            (on_target, "on the target"),
            (up_along, "along the view"),
            (no_up, "no length"),
            (wide, "field of view"),
            (spun, "not a finite number"),
            (far, "finite length"),
        ] {
            let e = view(&bounds(), &v, 64, 48).unwrap_err().to_string();
            assert!(e.contains(needle), "{e}");
        }
    }
}
