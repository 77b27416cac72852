//! Inner grid vertices as 16-bit integers.
//!
//! A grid's inner vertices belong to it alone, so they can be stored relative to the grid
//! itself: as signed 16-bit offsets from the mean of its three corners (the root sphere's
//! centre, which the traversal computes anyway), in units of one power of two per grid. Edge
//! and corner vertices stay 32-bit floats: they are shared with the neighbouring grids and must
//! read back bit-identical from either side, which keeps the surface watertight.
//!
//! Because the unit is a power of two, `code * unit` is exact, so `origin + code * unit` rounds
//! once whether or not a GPU compiler fuses it into one multiply-add: the host and every
//! backend decode the same bits. The host snaps the subdivided positions to these values
//! before anything is built, so both representations hold the same micro-triangles.
//!
//! Storage, per grid, in 16-bit halves packed two to a little-endian word: half 0 is the biased
//! exponent of the unit (as in an `f32`), then x, y, z of each inner vertex in
//! [`crate::grid_index::inner_index`] order.

use crate::buffer::Buffer;
use crate::glam::Vec3;

/// Largest magnitude of a code.
pub const CODE_MAX: i32 = 32767;

/// Words per grid of the quantized inner area.
#[inline]
pub const fn inner_words(inner_count: u32) -> u32 {
    if inner_count == 0 {
        0
    } else {
        (3 * inner_count + 2) / 2
    }
}

/// Signed 16-bit half `h` of a packed word array.
#[inline]
pub fn read_half<W: Buffer<u32>>(words: W, h: u32) -> i32 {
    let w = words.load(h / 2) >> (16 * (h & 1));
    ((w << 16) as i32) >> 16
}

/// The three signed 16-bit halves that start at the low (`odd == 0`) or high (`odd == 1`) half
/// of `w0`, from `w0` and the word after it.
#[inline]
pub fn halves_from_words(w0: u32, w1: u32, odd: u32) -> [i32; 3] {
    let s = 16 * odd;
    let sext = |w: u32| ((w << 16) as i32) >> 16;
    [sext(w0 >> s), sext(if odd != 0 { w1 } else { w0 >> 16 }), sext(w1 >> s)]
}

/// The unit `2^(biased - 127)` from its biased exponent.
#[inline]
pub fn unit_from_exponent(biased: u32) -> f32 {
    f32::from_bits(biased << 23)
}

/// A position from its code.
#[inline]
pub fn dequantize(origin: Vec3, code: [i32; 3], unit: f32) -> Vec3 {
    origin + Vec3::new(code[0] as f32, code[1] as f32, code[2] as f32) * unit
}
