//! Snaps each grid's inner vertices to 16-bit codes (the format is `gridrt_shared::quantize`)
//! before anything is built: the grid then stores them in 6 bytes instead of 12, and the
//! baseline, built from the same snapped positions, holds exactly the same micro-triangles.
//!
//! A vertex moves by at most half a code step, and a step is at most `2^-14` of the largest
//! offset of an inner vertex from the mean of its grid's corners (the grid's reach): far below
//! the size of a micro-triangle (a grid is `2^L` of them across). Edge and corner vertices do
//! not move.

use gridrt_shared::glam::Vec3;
use gridrt_shared::grid_index::{grid_size, inner_points, inner_vertex_count};
use gridrt_shared::grid_traverse::sphere_center;
use gridrt_shared::quantize::{dequantize, inner_words, unit_from_exponent, CODE_MAX};
use rayon::prelude::*;

use crate::subdiv::Subdivided;

impl Subdivided {
    /// Replaces every inner vertex by its 16-bit code, decoded, and keeps the codes in
    /// `inner_codes`. Running it twice changes nothing.
    pub fn quantize_inner(&mut self) {
        if self.inner_codes.is_some() {
            return;
        }
        let n = grid_size(self.levels);
        let inner_count = inner_vertex_count(self.levels) as usize;
        let words = inner_words(inner_count as u32) as usize;
        let grids = self.grid_count();
        let mut codes = vec![0u32; grids * words];
        let mut snapped = vec![Vec3::ZERO; grids * inner_count];
        if inner_count > 0 {
            let this = &*self;
            codes
                .par_chunks_mut(words)
                .zip(snapped.par_chunks_mut(inner_count))
                .enumerate()
                .for_each_init(Vec::new, |inner, (g, (codes, snapped))| {
                    let corner = |p| this.positions[this.vertex(g, p) as usize];
                    let origin = sphere_center(corner([0, 0]), corner([n, 0]), corner([0, n]));
                    inner.clear();
                    inner.extend(inner_points(n).map(|p| this.positions[this.vertex(g, p) as usize]));
                    quantize_grid(origin, inner, codes, snapped);
                });
        }
        // Each inner vertex belongs to one grid, so these writes never collide.
        for g in 0..grids {
            for (p, &v) in inner_points(n).zip(&snapped[g * inner_count..]) {
                let id = self.vertex(g, p) as usize;
                self.positions[id] = v;
            }
        }
        self.inner_codes = Some(codes);
    }
}

/// Codes one grid's inner vertices around `origin` into `words` (the exponent first), and
/// their decoded positions into `snapped`.
pub(crate) fn quantize_grid(origin: Vec3, inner: &[Vec3], words: &mut [u32], snapped: &mut [Vec3]) {
    let reach = inner
        .iter()
        .map(|&p| (p - origin).abs().max_element())
        .fold(0f32, f32::max);
    let biased = unit_exponent(reach);
    let unit = unit_from_exponent(biased);
    write_half(words, 0, biased as i32);
    for (k, (&p, out)) in inner.iter().zip(snapped).enumerate() {
        let code = ((p - origin) / unit)
            .to_array()
            .map(|c| (c.round() as i32).clamp(-CODE_MAX, CODE_MAX));
        for (axis, &c) in code.iter().enumerate() {
            write_half(words, 1 + 3 * k + axis, c);
        }
        *out = dequantize(origin, code, unit);
    }
}

/// Biased exponent of the smallest power-of-two unit that spans `reach` in `CODE_MAX` steps,
/// kept in the normal range with room for the codes.
fn unit_exponent(reach: f32) -> u32 {
    const LOWEST: u32 = 1;
    const HIGHEST: u32 = 254 - 16;
    let fits = |biased: u32| unit_from_exponent(biased) * CODE_MAX as f32 >= reach;
    if !reach.is_finite() {
        return HIGHEST;
    }
    let guess = ((reach / CODE_MAX as f32).log2().ceil() as i32 + 127).clamp(LOWEST as i32, HIGHEST as i32) as u32;
    let mut biased = guess;
    while biased < HIGHEST && !fits(biased) {
        biased += 1;
    }
    while biased > LOWEST && fits(biased - 1) {
        biased -= 1;
    }
    biased
}

fn write_half(words: &mut [u32], h: usize, value: i32) {
    let shift = 16 * (h & 1);
    let w = &mut words[h / 2];
    *w = (*w & !(0xffff << shift)) | (((value as u32) & 0xffff) << shift);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::scene::default_scene;
    use crate::subdiv::{subdivide, Scheme};
    use gridrt_shared::quantize::{halves_from_words, read_half};

    #[test]
    fn halves_round_trip() {
        let mut words = vec![0u32; 3];
        let values = [-32767, 32767, 0, -1, 12345];
        for (h, &v) in values.iter().enumerate() {
            write_half(&mut words, h, v);
        }
        for (h, &v) in values.iter().enumerate() {
            assert_eq!(read_half(words.as_slice(), h as u32), v);
        }
        // Triples starting on either half of a word, the last one ending the array.
        for h in 0..values.len() as u32 - 2 {
            let want = [0, 1, 2].map(|d| read_half(words.as_slice(), h + d));
            let (w0, w1) = (words[h as usize / 2], words[h as usize / 2 + 1]);
            assert_eq!(halves_from_words(w0, w1, h & 1), want, "triple at half {h}");
        }
    }

    #[test]
    fn unit_is_the_smallest_that_fits() {
        for reach in [1e-30f32, 1e-6, 0.37, 1.0, 32767.0, 32768.0, 5e7] {
            let unit = unit_from_exponent(unit_exponent(reach));
            assert!(unit * CODE_MAX as f32 >= reach, "{reach}");
            assert!(unit / 2.0 * (CODE_MAX as f32) < reach, "{reach}");
        }
        assert_eq!(unit_exponent(0.0), 1);
    }

    /// Inner vertices move by at most half a step (a step being at most `2^-14` of the grid's
    /// reach), and nothing else moves.
    #[test]
    fn only_inner_vertices_move_and_only_a_little() {
        for levels in 0..=4 {
            let mesh = default_scene();
            let exact = subdivide(&mesh, levels, Scheme::Loop);
            let mut snapped = exact.clone();
            snapped.quantize_inner();
            let n = grid_size(levels);
            let mut moved = 0;
            for g in 0..exact.grid_count() {
                let corner = |p| exact.positions[exact.vertex(g, p) as usize];
                let origin = sphere_center(corner([0, 0]), corner([n, 0]), corner([0, n]));
                let reach = inner_points(n)
                    .map(|p| {
                        (exact.positions[exact.vertex(g, p) as usize] - origin)
                            .abs()
                            .max_element()
                    })
                    .fold(0f32, f32::max);
                for j in 0..=n {
                    for i in 0..=n - j {
                        let id = exact.vertex(g, [i, j]) as usize;
                        let (before, after) = (exact.positions[id], snapped.positions[id]);
                        if i == 0 || j == 0 || i + j == n {
                            assert_eq!(before, after, "boundary vertex moved");
                        } else {
                            let bound = reach / CODE_MAX as f32 + before.abs().max_element() * f32::EPSILON;
                            assert!((before - after).abs().max_element() <= bound, "L={levels}");
                            moved += (before != after) as usize;
                        }
                    }
                }
            }
            if levels >= 2 {
                assert!(moved > 0, "L={levels}: quantization changed nothing");
            }
            let again = {
                let mut s = snapped.clone();
                s.quantize_inner();
                s
            };
            assert_eq!(again.positions, snapped.positions);
        }
    }
}
