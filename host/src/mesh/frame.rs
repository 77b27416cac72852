//! The frame a mesh is built and traced in: centred on its bounds and scaled by a power of two
//! to unit size, whatever the units of the file.
//!
//! A scan in micrometres or a CAD part in millimetres a thousand kilometres from the origin
//! holds coordinates whose magnitude says nothing about the size of its details. Built as
//! given, every `f32` quantity downstream (sheared vertices, sphere tests, products of edge
//! functions, offsets along rays) would carry the offset's rounding or over- and underflow
//! at the extremes of the range. Moved to this frame once, in `f64`, the whole pipeline works
//! on numbers of the same size for every input: the subtraction of the centre is exact to
//! the input's own precision (the file's vertices are `f32`), and a power-of-two scale
//! changes no rounding at all, so what is rendered is the input, up to that scale, exactly.

use gridrt_shared::glam::{DVec3, Vec3};

use super::Mesh;

/// Maps world coordinates (as in the file) to the local frame: `local = (world - centre) * scale`.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct LocalFrame {
    pub centre: DVec3,
    /// A power of two.
    pub scale: f64,
}

impl LocalFrame {
    /// The identity: local coordinates are world coordinates.
    pub const IDENTITY: LocalFrame = LocalFrame {
        centre: DVec3::ZERO,
        scale: 1.0,
    };

    /// The frame centred on the box `lo..hi` whose largest side becomes a length in `[1, 2)`.
    pub fn of_bounds(lo: DVec3, hi: DVec3) -> LocalFrame {
        let centre = (lo + hi) * 0.5;
        let extent = (hi - lo).max_element();
        let scale = if extent.is_normal() {
            // `extent * 2^-floor(log2 extent)` lies in [1, 2).
            (-extent.log2().floor()).exp2()
        } else {
            1.0
        };
        LocalFrame { centre, scale }
    }

    pub fn to_local(&self, world: DVec3) -> Vec3 {
        ((world - self.centre) * self.scale).as_vec3()
    }

    pub fn to_world(&self, local: Vec3) -> DVec3 {
        local.as_dvec3() / self.scale + self.centre
    }
}

impl Mesh {
    /// Moves the mesh into its [`LocalFrame`] and returns that frame.
    pub fn into_local_frame(&mut self) -> LocalFrame {
        if self.positions.is_empty() {
            return LocalFrame::IDENTITY;
        }
        // Minimum and maximum round nothing: the f32 bounds are exact in f64.
        let (lo, hi) = self.bounds();
        let frame = LocalFrame::of_bounds(lo.as_dvec3(), hi.as_dvec3());
        for p in &mut self.positions {
            *p = frame.to_local(p.as_dvec3());
        }
        frame
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mesh(points: &[[f32; 3]]) -> Mesh {
        Mesh {
            positions: points.iter().map(|&p| Vec3::from(p)).collect(),
            triangles: vec![[0, 1, 2]],
        }
    }

    #[test]
    fn centred_and_scaled_by_a_power_of_two() {
        let mut m = mesh(&[
            [1.0e6, 1.0e6, 1.0e6],
            [1.0e6 + 3.0, 1.0e6, 1.0e6],
            [1.0e6, 1.0e6 + 1.0, 1.0e6],
        ]);
        let frame = m.into_local_frame();
        assert_eq!(frame.scale, 0.5);
        assert_eq!(frame.centre, DVec3::new(1.0e6 + 1.5, 1.0e6 + 0.5, 1.0e6));
        assert_eq!(m.positions[0], Vec3::new(-0.75, -0.25, 0.0));
        assert_eq!(m.positions[1], Vec3::new(0.75, -0.25, 0.0));
        for (p, q) in m
            .positions
            .iter()
            .zip([[1.0e6, 1.0e6, 1.0e6], [1.0e6 + 3.0, 1.0e6, 1.0e6]])
        {
            assert_eq!(frame.to_world(*p), DVec3::from(q.map(f64::from)));
        }
    }

    #[test]
    fn any_scale_lands_in_one_to_two() {
        for extent in [1.0e-30f32, 3.0e-10, 1.0, 1.5, 2.0, 7.0e8, 3.0e38] {
            let mut m = mesh(&[[0.0; 3], [extent, 0.0, 0.0], [0.0, extent * 0.5, 0.0]]);
            let frame = m.into_local_frame();
            let (lo, hi) = m.bounds();
            let size = (hi - lo).max_element();
            assert!((1.0..2.0).contains(&size), "extent {extent}: local size {size}");
            assert_eq!(frame.scale.log2().fract(), 0.0);
        }
    }

    #[test]
    fn a_point_mesh_keeps_unit_scale() {
        let mut m = mesh(&[[5.0; 3], [5.0; 3], [5.0; 3]]);
        let frame = m.into_local_frame();
        assert_eq!(frame.scale, 1.0);
        assert!(m.positions.iter().all(|&p| p == Vec3::ZERO));
    }
}
