//! The cost heat map: how many tests each pixel's primary ray makes (top-level or baseline
//! BVH nodes, grid spheres and micro-triangles, counted by `gridrt_shared::cost`), as colours.
//!
//! The kernels and the CPU loop only count; colours are chosen here, after the frame is
//! done, because the scale (the count shown white) is a property of the whole frame.

use gridrt_shared::cost::Costs;

use crate::pipeline::Image;

/// Every pixel's costs, row-major, top row first.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CostImage {
    pub width: u32,
    pub height: u32,
    pub costs: Vec<Costs>,
}

/// A frame's costs in figures: the means over its pixels, and the totals its heat map's scale
/// is chosen from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CostSummary {
    pub mean_nodes: f64,
    pub mean_spheres: f64,
    pub mean_triangles: f64,
    /// Tests of the pixel at the 99th percentile, and of the costliest pixel.
    pub p99_total: u32,
    pub max_total: u32,
}

impl CostSummary {
    /// Tests shown white: `heat_white` when given, else the 99th percentile.
    pub fn white(&self, heat_white: Option<u32>) -> u32 {
        heat_white.unwrap_or(self.p99_total)
    }
}

impl CostImage {
    /// The image of packed costs the kernels write.
    pub fn from_packed(width: u32, height: u32, packed: &[u32]) -> CostImage {
        CostImage {
            width,
            height,
            costs: packed.iter().map(|&w| Costs::unpack(w)).collect(),
        }
    }

    pub fn summary(&self) -> CostSummary {
        let n = self.costs.len().max(1) as f64;
        let mean = |f: fn(&Costs) -> u32| self.costs.iter().map(|c| f(c) as f64).sum::<f64>() / n;
        let mut totals: Vec<u32> = self.costs.iter().map(Costs::total).collect();
        totals.sort_unstable();
        let at = |q: f64| {
            totals
                .get(((totals.len() as f64 - 1.0) * q).round() as usize)
                .copied()
                .unwrap_or(0)
        };
        CostSummary {
            mean_nodes: mean(|c| c.nodes),
            mean_spheres: mean(|c| c.spheres),
            mean_triangles: mean(|c| c.triangles),
            p99_total: at(0.99),
            max_total: at(1.0),
        }
    }

    /// Each pixel's total tests on a black-red-yellow-white scale reaching white at `white`
    /// tests (at least 1); more saturate.
    pub fn heat_map(&self, white: u32) -> Image {
        let white = white.max(1) as f32;
        Image {
            width: self.width,
            height: self.height,
            pixels: self
                .costs
                .iter()
                .map(|c| heat_colour(c.total() as f32 / white))
                .collect(),
        }
    }
}

/// Packed RGBA8 of `fraction` (0 to 1) on the heat scale: black, purple, red, orange, yellow,
/// white, evenly spaced, so equal steps in tests look like equal steps in colour.
pub fn heat_colour(fraction: f32) -> u32 {
    const STOPS: [[f32; 3]; 6] = [
        [0.0, 0.0, 0.0],
        [0.33, 0.06, 0.43],
        [0.73, 0.13, 0.33],
        [0.96, 0.45, 0.08],
        [0.98, 0.85, 0.2],
        [1.0, 1.0, 1.0],
    ];
    let x = fraction.clamp(0.0, 1.0) * (STOPS.len() - 1) as f32;
    let i = (x as usize).min(STOPS.len() - 2);
    let f = x - i as f32;
    let channel = |c: usize| {
        let v = STOPS[i][c] + (STOPS[i + 1][c] - STOPS[i][c]) * f;
        (v * 255.0 + 0.5) as u32
    };
    channel(0) | (channel(1) << 8) | (channel(2) << 16) | (255 << 24)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scale_runs_from_black_to_white_and_saturates() {
        assert_eq!(heat_colour(0.0), 0xff00_0000);
        assert_eq!(heat_colour(1.0), 0xffff_ffff);
        assert_eq!(heat_colour(7.0), 0xffff_ffff);
        // Brighter with every step.
        let luma = |c: u32| (c & 0xff) + ((c >> 8) & 0xff) + ((c >> 16) & 0xff);
        let steps: Vec<u32> = (0..=20).map(|k| luma(heat_colour(k as f32 / 20.0))).collect();
        assert!(steps.windows(2).all(|w| w[0] < w[1]), "{steps:?}");
    }

    #[test]
    fn summary_means_and_percentiles() {
        let costs = (0..100)
            .map(|k| Costs {
                nodes: k,
                spheres: 2 * k,
                triangles: 0,
            })
            .collect();
        let image = CostImage {
            width: 10,
            height: 10,
            costs,
        };
        let s = image.summary();
        assert_eq!((s.mean_nodes, s.mean_spheres, s.mean_triangles), (49.5, 99.0, 0.0));
        assert_eq!((s.p99_total, s.max_total), (3 * 98, 3 * 99));
        let map = image.heat_map(3 * 99);
        assert_eq!(map.pixels[0], heat_colour(0.0));
        assert_eq!(map.pixels[99], heat_colour(1.0));
    }
}
