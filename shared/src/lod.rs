//! Level of detail per grid: every grid holds all depths `0 ..= L` of its subdivision, so a
//! grid far from the eye can be rendered coarser from the same data, without a rebuild.
//!
//! The depth is chosen per grid, not per ray: every ray that meets a grid (primary or
//! secondary) sees the same micro-triangles, so a grid stays watertight inside. Where two
//! neighbouring grids choose different depths their shared edge is cut at different points
//! and a crack (a T-junction) can open between them; the host measures it per frame.

use crate::glam::Vec3;
use crate::layout::GridParams;

/// The depth the grid whose root sphere is `center`, `radius` is rendered at.
///
/// Without `params.lod_auto`, `params.lod`. With it, the shallowest depth `D <= params.lod` at
/// which the sphere's diameter over `2^D` (a bound on the size of the grid's micro-triangles
/// at depth `D`) seen from the sphere's nearest point to the eye spans at most the target
/// number of pixels: `2 r lod_scale / 2^D <= |c - eye| - r`. Squared, so that only products
/// and sums decide (no square root, whose rounding a GPU may do differently), and a grid
/// around the eye gets the full depth.
#[inline]
pub fn grid_level(params: &GridParams, center: Vec3, radius: f32) -> u32 {
    if params.lod_auto == 0 {
        return params.lod;
    }
    let to_eye = center - Vec3::from(params.lod_eye);
    let distance2 = to_eye.dot(to_eye);
    let mut size = 2.0 * radius * params.lod_scale;
    let mut level = 0;
    while level < params.lod {
        let reach = size + radius;
        if reach * reach <= distance2 {
            break;
        }
        size *= 0.5;
        level += 1;
    }
    level
}

#[cfg(test)]
mod tests {
    use super::*;

    fn auto(lod: u32, eye: Vec3, scale: f32) -> GridParams {
        GridParams {
            levels: lod,
            lod,
            lod_auto: 1,
            lod_eye: eye.to_array(),
            lod_scale: scale,
            ..Default::default()
        }
    }

    #[test]
    fn a_fixed_level_of_detail_ignores_the_eye() {
        let params = GridParams {
            levels: 4,
            lod: 2,
            ..Default::default()
        };
        assert_eq!(grid_level(&params, Vec3::ZERO, 1.0), 2);
        assert_eq!(grid_level(&params, Vec3::splat(1e9), 1.0), 2);
    }

    #[test]
    fn farther_grids_are_never_finer() {
        let params = auto(5, Vec3::new(0.0, 0.0, 3.0), 400.0);
        let mut previous = u32::MAX;
        for step in 0..200 {
            let distance = 1.0 + step as f32 * 10.0;
            let level = grid_level(&params, Vec3::new(0.0, 0.0, 3.0 - distance), 0.5);
            assert!(
                level <= previous,
                "level {level} at distance {distance} after {previous}"
            );
            previous = level;
        }
        assert_eq!(previous, 0, "far enough, one triangle per grid");
    }

    /// Each level is the shallowest that keeps the sphere's diameter over `2^D` within the
    /// target, checked in `f64` against the definition, at any scale and offset.
    #[test]
    fn the_chosen_level_meets_the_target_and_one_less_would_not() {
        for (offset, scale) in [(0.0, 1.0), (3.0e4, 1.0e3), (-7.0, 1.0e-3)] {
            let eye = Vec3::new(offset, offset * 0.5, -offset);
            let params = auto(6, eye, 250.0);
            for k in 1..400 {
                let radius = 0.01 * scale;
                let distance = k as f64 * 0.37 * scale as f64;
                let center = eye + Vec3::new(0.6, 0.0, 0.8) * distance as f32;
                let level = grid_level(&params, center, radius);
                let near = (center - eye).as_dvec3().length() - radius as f64;
                let projected = |d: u32| 2.0 * radius as f64 * 250.0 / (1u64 << d) as f64 / near;
                let margin = 1e-4;
                if level < 6 {
                    assert!(
                        projected(level) <= 1.0 + margin,
                        "level {level} too coarse at {distance}"
                    );
                }
                if level > 0 {
                    assert!(
                        projected(level - 1) > 1.0 - margin,
                        "level {level} finer than needed at {distance}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_grid_around_the_eye_gets_the_full_depth() {
        let params = auto(4, Vec3::ZERO, 1.0e-6);
        assert_eq!(grid_level(&params, Vec3::new(0.1, 0.0, 0.0), 0.5), 4);
    }
}
