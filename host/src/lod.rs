//! What a level of detail per grid ([`crate::pipeline::RenderOptions::lod_pixels`]) makes of a
//! frame: how many grids render at each depth, and the cracks it opens.
//!
//! Neighbouring grids read the same edge vertices, but a grid rendered at depth `D` joins
//! only every `2^(L - D)`-th of them by straight segments. Where the grid across the edge is
//! rendered deeper, its extra edge vertices lie off those segments (the surface is curved)
//! and a gap opens between the two: a T-junction crack, at most as wide as the farthest such
//! vertex is from the coarser grid's segment. [`LodReport::measure`] finds that distance for
//! every edge whose grids differ in depth and states the widest on screen, in pixels.

use std::collections::HashMap;

use gridrt_shared::glam::{DVec3, Vec3};
use gridrt_shared::grid_index::{edge_point, Lattice};
use gridrt_shared::layout::FrameParams;
use gridrt_shared::lod::grid_level;

use crate::grid::GridScene;
use crate::pipeline::pixels_per_unit;

/// The depths a frame renders its grids at, and the cracks between them.
#[derive(Clone, Debug, PartialEq)]
pub struct LodReport {
    /// `grids_per_level[d]`: how many grids are rendered at depth `d`.
    pub grids_per_level: Vec<usize>,
    /// Base edges whose two grids are rendered at different depths.
    pub mismatched_edges: usize,
    /// The widest gap any of them can open in front of the eye, in pixels (0 when none
    /// can: every grid at one depth, or every mismatched edge straight).
    pub widest_crack_pixels: f64,
}

impl LodReport {
    /// The depth each grid of `scene` is rendered at under `frame` (the choice the traversal
    /// makes, by the same function), and the cracks between grids that differ.
    pub fn measure(scene: &GridScene, frame: &FrameParams) -> LodReport {
        let view = scene.view();
        let params = frame.grid;
        // A grid of mixed levels renders at most its own level, and at that level its decimated
        // edges only at the level below, as its coarser neighbour does.
        let opened: Vec<_> = (0..scene.grid_count() as u32).map(|g| view.open(g)).collect();
        let levels: Vec<u32> = (opened.iter())
            .map(|open| grid_level(&params, open.origin, view.radius(open, 0)).min(view.own_level(open)))
            .collect();
        let edge_level = |g: u32, e: usize| {
            let (level, open) = (levels[g as usize], &opened[g as usize]);
            level - (level > 0 && level == view.own_level(open) && open.decimated >> e & 1 != 0) as u32
        };
        let mut grids_per_level = vec![0; params.lod as usize + 1];
        for &level in &levels {
            grids_per_level[level as usize] += 1;
        }
        let screen = Screen::new(frame);
        let mut first_grid_of_edge: HashMap<u32, (u32, usize)> = HashMap::new();
        let mut mismatched_edges = 0;
        let mut widest_crack_pixels: f64 = 0.0;
        for g in 0..scene.grid_count() as u32 {
            let ids = view.ids(g);
            for (e, &edge) in ids.edges.iter().enumerate() {
                let Some(&(other, other_e)) = first_grid_of_edge.get(&edge) else {
                    first_grid_of_edge.insert(edge, (g, e));
                    continue;
                };
                let (here, there) = (edge_level(g, e), edge_level(other, other_e));
                let (coarse, fine) = (here.min(there), here.max(there));
                if coarse == fine {
                    continue;
                }
                mismatched_edges += 1;
                // Both grids read the same edge vertices: walk them along this grid's edge.
                let open = view.open(g);
                let points: Vec<Vec3> = edge_points(params.levels, e).map(|p| view.vertex(&open, p)).collect();
                widest_crack_pixels =
                    widest_crack_pixels.max(crack_pixels(&points, params.levels, coarse, fine, &screen));
            }
        }
        LodReport {
            grids_per_level,
            mismatched_edges,
            widest_crack_pixels,
        }
    }
}

/// The lattice points of a grid's edge `e` (from corner `e` to corner `e + 1`), in order.
fn edge_points(levels: u32, e: usize) -> impl Iterator<Item = Lattice> {
    let n = 1u32 << levels;
    (0..=n).map(move |s| edge_point(e as u32, s, n))
}

/// The camera's image plane (one unit in front of the eye, see
/// [`gridrt_shared::layout::Camera`]) and how lengths on it map to pixels.
struct Screen {
    eye: DVec3,
    to_top_left: DVec3,
    horizontal: DVec3,
    vertical: DVec3,
    /// Unit direction the camera looks along.
    forward: DVec3,
    pixels_per_unit: f64,
}

impl Screen {
    fn new(frame: &FrameParams) -> Screen {
        let c = &frame.camera;
        let [to_top_left, horizontal, vertical] =
            [c.to_top_left, c.horizontal, c.vertical].map(|v| Vec3::from(v).as_dvec3());
        Screen {
            eye: Vec3::from(c.origin).as_dvec3(),
            to_top_left,
            horizontal,
            vertical,
            forward: (to_top_left + 0.5 * (horizontal + vertical)).normalize(),
            pixels_per_unit: pixels_per_unit(c) as f64,
        }
    }

    /// Pixels that a gap of `length` at `point` spans, or `None` where the frame does not show
    /// `point` (behind the eye or outside the picture).
    fn pixels(&self, length: f64, point: DVec3) -> Option<f64> {
        let relative = point - self.eye;
        let depth = relative.dot(self.forward);
        if depth <= 0.0 {
            return None;
        }
        // Where the line from the eye through `point` meets the image plane, as fractions of
        // the picture's width and height.
        let on_plane = relative * (self.to_top_left.dot(self.forward) / depth) - self.to_top_left;
        let x = on_plane.dot(self.horizontal) / self.horizontal.length_squared();
        let y = on_plane.dot(self.vertical) / self.vertical.length_squared();
        let in_picture = (0.0..=1.0).contains(&x) && (0.0..=1.0).contains(&y);
        in_picture.then(|| length * self.pixels_per_unit / depth)
    }
}

/// The widest gap, in pixels, between an edge drawn through every `2^(L - fine)`-th of its
/// `points` and through every `2^(L - coarse)`-th: the farthest a fine vertex lies from the
/// coarse segment under it.
fn crack_pixels(points: &[Vec3], levels: u32, coarse: u32, fine: u32, screen: &Screen) -> f64 {
    let (coarse_step, fine_step) = (1usize << (levels - coarse), 1usize << (levels - fine));
    let mut widest: f64 = 0.0;
    for s in (0..points.len()).step_by(fine_step) {
        if s % coarse_step == 0 {
            continue;
        }
        let start = s - s % coarse_step;
        let (a, b, p) = (
            points[start].as_dvec3(),
            points[start + coarse_step].as_dvec3(),
            points[s].as_dvec3(),
        );
        if let Some(pixels) = screen.pixels(distance_to_segment(p, a, b), p) {
            widest = widest.max(pixels);
        }
    }
    widest
}

fn distance_to_segment(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let len2 = ab.length_squared();
    let t = if len2 > 0.0 {
        ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + ab * t)).length()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_straight_edge_opens_no_crack_and_a_bent_one_does() {
        // Looking down -z from z = 10 at the square -10..10 around the origin.
        let screen = Screen {
            eye: DVec3::new(0.0, 0.0, 10.0),
            to_top_left: DVec3::new(-1.0, 1.0, -1.0),
            horizontal: DVec3::new(2.0, 0.0, 0.0),
            vertical: DVec3::new(0.0, -2.0, 0.0),
            forward: DVec3::new(0.0, 0.0, -1.0),
            pixels_per_unit: 100.0,
        };
        let straight: Vec<Vec3> = (0..=8).map(|i| Vec3::new(i as f32, 0.0, 0.0)).collect();
        assert_eq!(crack_pixels(&straight, 3, 1, 3, &screen), 0.0);
        let mut bent = straight.clone();
        bent[3].y = 0.5;
        // Depth 1 joins points 0, 4, 8; depth 3 has point 3 half a unit off, ten units away.
        assert!((crack_pixels(&bent, 3, 1, 3, &screen) - 5.0).abs() < 1e-9);
        // Depth 2 (points 0, 2, 4, ...) does not have point 3.
        assert_eq!(crack_pixels(&bent, 3, 1, 2, &screen), 0.0);
        // Outside the picture, nothing is seen.
        let beside: Vec<Vec3> = bent.iter().map(|p| *p + Vec3::new(20.0, 0.0, 0.0)).collect();
        assert_eq!(crack_pixels(&beside, 3, 1, 3, &screen), 0.0);
        let behind: Vec<Vec3> = bent.iter().map(|p| *p + Vec3::new(0.0, 0.0, 20.0)).collect();
        assert_eq!(crack_pixels(&behind, 3, 1, 3, &screen), 0.0);
    }

    #[test]
    fn edge_points_run_from_corner_to_corner() {
        for e in 0..3 {
            let points: Vec<Lattice> = edge_points(2, e).collect();
            let corners = [[0, 0], [4, 0], [0, 4]];
            assert_eq!(points[0], corners[e]);
            assert_eq!(points[4], corners[(e + 1) % 3]);
            assert!(points
                .iter()
                .all(|p| p[0] + p[1] <= 4 && (p[0] == 0 || p[1] == 0 || p[0] + p[1] == 4)));
        }
    }
}
