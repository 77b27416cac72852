//! Fitting the stored range to the displacements found, and quantizing into it.
//!
//! Each base vertex gets the range `[lo, hi]` of the displacements its triangles'
//! micro-vertices need (every micro-vertex of every triangle around it, so any point that
//! interpolates it lies within the range of each of its corners), and the range is folded
//! into the base mesh: the vertex moves to `P + lo * D` and its direction becomes
//! `(hi - lo) * D`. A stored value `u` in `[0, 1]` then spans exactly the range the vertex
//! needs, and the 11 bits are spent on it alone rather than on the mesh's largest offset.

use gridrt_shared::displacement::UNORM11_MAX;
use gridrt_shared::glam::Vec3;

/// Per vertex, the least and greatest displacement of the micro-vertices of its triangles.
/// `displacements[t]` holds triangle `t`'s; a vertex of no triangle gets `(0, 0)`.
pub fn vertex_ranges(triangles: &[[u32; 3]], displacements: &[Vec<f32>], vertices: usize) -> Vec<(f32, f32)> {
    let mut ranges = vec![(f32::INFINITY, f32::NEG_INFINITY); vertices];
    for (t, values) in triangles.iter().zip(displacements) {
        let (lo, hi) = values.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &d| {
            (lo.min(d), hi.max(d))
        });
        for &i in t {
            let r = &mut ranges[i as usize];
            *r = (r.0.min(lo), r.1.max(hi));
        }
    }
    for r in &mut ranges {
        if r.0 > r.1 {
            *r = (0.0, 0.0);
        }
    }
    ranges
}

/// Positions and directions with each vertex's range folded in; a range narrower than
/// `least_span` is widened to it around its middle (a direction of zero length would leave
/// nothing for the values to say, and other tools may normalise it).
pub fn fold_ranges(
    positions: &[Vec3],
    directions: &[Vec3],
    ranges: &[(f32, f32)],
    least_span: f32,
) -> (Vec<Vec3>, Vec<Vec3>) {
    (positions.iter().zip(directions).zip(ranges))
        .map(|((&p, &d), &(lo, hi))| {
            let (lo, span) = if hi - lo >= least_span {
                (lo, hi - lo)
            } else {
                (0.5 * (lo + hi) - 0.5 * least_span, least_span)
            };
            (p + d * lo, d * span)
        })
        .unzip()
}

/// The 11-bit value nearest `u`, clamped to `[0, 1]`.
pub fn quantize(u: f32) -> u16 {
    (u.clamp(0.0, 1.0) * UNORM11_MAX as f32).round() as u16
}

/// Whether `u` lies outside `[0, 1]` by more than half a quantization step (so that
/// clamping it changes its value).
pub fn clipped(u: f32) -> bool {
    let half_step = 0.5 / UNORM11_MAX as f32;
    !(-half_step..=1.0 + half_step).contains(&u)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_cover_every_triangle_around_a_vertex() {
        let triangles = [[0, 1, 2], [2, 1, 3]];
        let displacements = vec![vec![0.5, -0.25, 0.0], vec![1.0, 0.75]];
        let ranges = vertex_ranges(&triangles, &displacements, 5);
        assert_eq!(ranges[0], (-0.25, 0.5));
        assert_eq!(ranges[1], (-0.25, 1.0));
        assert_eq!(ranges[3], (0.75, 1.0));
        assert_eq!(ranges[4], (0.0, 0.0));
    }

    #[test]
    fn folded_ranges_map_zero_and_one_to_their_ends() {
        let (p, d) = fold_ranges(&[Vec3::ONE], &[Vec3::Z], &[(-0.5, 1.5)], 1e-3);
        assert_eq!(p[0] + d[0] * 0.0, Vec3::new(1.0, 1.0, 0.5));
        assert_eq!(p[0] + d[0] * 1.0, Vec3::new(1.0, 1.0, 2.5));
        let (p, d) = fold_ranges(&[Vec3::ZERO], &[Vec3::Z], &[(2.0, 2.0)], 0.5);
        assert_eq!((p[0], d[0]), (Vec3::new(0.0, 0.0, 1.75), Vec3::new(0.0, 0.0, 0.5)));
    }

    #[test]
    fn quantization_rounds_and_clamps() {
        assert_eq!(quantize(0.0), 0);
        assert_eq!(quantize(1.0), 2047);
        assert_eq!(quantize(0.5), 1024);
        assert_eq!(quantize(-0.1), 0);
        assert_eq!(quantize(7.0), 2047);
    }
}
