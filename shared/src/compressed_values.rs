//! Compressed displacement values: each lattice point of a displaced grid below its corners
//! stored as a correction to a prediction, the mean of the two points of the next coarser
//! lattice it halves, as the subdivision makes it. Smooth surfaces need small corrections,
//! and finer levels smaller ones, so each level's corrections take fewer bits than a value.
//!
//! The format, for grids of depth `L` (lattice size `n = 2^L`):
//! - A point is new at level `l` when it is on the level-`l` lattice and not on the level
//!   `l - 1` one; its parents are the ends of the coarser edge it halves. Its value is
//!   `clamp(mean + correction << shift, 0, 2047)`, `mean = (a + b + 1) >> 1` of its parents'
//!   values: whole numbers, so every decoder computes the same bits.
//! - Corrections are signed, `width(l)` bits each (0 to 11), one set of widths for a whole
//!   scene. Each block (a grid's inner points, or a base edge's points) begins with its own
//!   shift per level, [`SHIFT_BITS`] each, chosen by the encoder, then its corrections level by
//!   level, coarse to fine.
//! - A base edge's points form a block of their own, stored once from the edge's lower base
//!   vertex id, and are predicted from points of that edge alone: both grids that share the
//!   edge decode the same values, so the surface stays watertight. Corners are plain 11-bit
//!   values, one per base vertex.
//!
//! Inside a grid, the new points of level `l` are taken row by row (`i`, then `j`, on the
//! level-`l` lattice), so a point's place among them is a closed form of its coordinates.
//!
//! [`CodedGrid::value`] decodes any one point by walking down from the grid's corners,
//! deriving the three midpoints of the sub-triangle that holds the point at each level.

use crate::buffer::Buffer;
use crate::grid_index::Lattice;
use crate::layout::GridIds;

/// Bits of one block's shift for one level.
pub const SHIFT_BITS: u32 = 4;
/// Bits of a correction's width for one level, in [`ValueCode::widths`].
pub const WIDTH_BITS: u32 = 4;
/// Bits of a plain value (a corner).
pub const VALUE_BITS: u32 = 11;
/// The largest value.
pub const VALUE_MAX: u32 = (1 << VALUE_BITS) - 1;

/// The widths of a scene's corrections: level `l`'s (1 to `levels`) in bits `4 (l - 1)`.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct ValueCode {
    pub levels: u32,
    pub widths: u32,
}

/// Points new at level `l` strictly inside a grid.
#[inline]
pub const fn inner_new_count(l: u32) -> u32 {
    inner_count(1 << l) - inner_count(1 << l >> 1)
}

/// Points strictly inside a lattice of size `m`.
#[inline]
const fn inner_count(m: u32) -> u32 {
    if m < 3 {
        0
    } else {
        (m - 1) * (m - 2) / 2
    }
}

/// Points new at level `l` strictly inside a base edge.
#[inline]
pub const fn edge_new_count(l: u32) -> u32 {
    1 << l >> 1
}

/// Place of inner point `(a, b)` among the points new at its level, `m` the level's lattice
/// size and `(a, b)` on that lattice, not both even.
#[inline]
pub fn inner_rank(a: u32, b: u32, m: u32) -> u32 {
    // Rows below `a`: the odd ones hold every `b` in `1 ..= m - 1 - r`, the even ones only
    // the odd `b` (the even ones are older).
    let odd_rows = a / 2;
    let even_rows = (a - 1) / 2;
    let below = odd_rows * (m - 1) - odd_rows * odd_rows + (even_rows * m - even_rows * (even_rows + 1)) / 2;
    below + if a & 1 == 1 { b - 1 } else { (b - 1) / 2 }
}

impl ValueCode {
    /// Bits of one correction at level `l`.
    #[inline]
    pub fn width(&self, l: u32) -> u32 {
        (self.widths >> (WIDTH_BITS * (l - 1))) & ((1 << WIDTH_BITS) - 1)
    }

    /// Bits of the shifts at the start of every block.
    #[inline]
    pub fn shift_bits(&self) -> u32 {
        SHIFT_BITS * self.levels
    }

    /// Bit, within a grid's block, where level `l`'s corrections begin.
    #[inline]
    pub fn inner_level_bit(&self, l: u32) -> u32 {
        let mut bit = self.shift_bits();
        let mut k = 1;
        while k < l {
            bit += inner_new_count(k) * self.width(k);
            k += 1;
        }
        bit
    }

    /// Bit, within a base edge's block, where level `l`'s corrections begin.
    #[inline]
    pub fn edge_level_bit(&self, l: u32) -> u32 {
        let mut bit = self.shift_bits();
        let mut k = 1;
        while k < l {
            bit += edge_new_count(k) * self.width(k);
            k += 1;
        }
        bit
    }

    /// Bits of a grid's block.
    #[inline]
    pub fn inner_block_bits(&self) -> u32 {
        self.inner_level_bit(self.levels + 1)
    }

    /// Bits of a base edge's block.
    #[inline]
    pub fn edge_block_bits(&self) -> u32 {
        self.edge_level_bit(self.levels + 1)
    }
}

/// `width` bits of `buffer` from bit `bit` (`width <= 25`: they span at most two words; the
/// word after them must exist).
#[inline]
pub fn read_bits<B: Buffer<u32>>(buffer: B, bit: u32, width: u32) -> u32 {
    let (word, shift) = (bit >> 5, bit & 31);
    // Shifted in two steps, so a field that starts a word shifts the next one out entirely
    // rather than by 32, which shifts by nothing on some targets.
    let low = buffer.load(word) >> shift;
    let high = (buffer.load(word + 1) << 1) << (31 - shift);
    (low | high) & ((1 << width) - 1)
}

/// The value predicted from parents `a` and `b`, moved by a `width`-bit two's-complement
/// `field` shifted left by `shift`, and clamped to the values' range.
#[inline]
pub fn corrected(a: u32, b: u32, field: u32, width: u32, shift: u32) -> u32 {
    let mean = ((a + b + 1) >> 1) as i32;
    // Sign-extend the field; a zero width stands for a zero correction.
    let correction = if width == 0 {
        0
    } else {
        ((field << (32 - width)) as i32) >> (32 - width)
    };
    let value = mean + (correction << shift);
    value.clamp(0, VALUE_MAX as i32) as u32
}

/// A grid of compressed values, resolved for reading: where its blocks are and its corners'
/// values.
#[derive(Copy, Clone, Default)]
pub struct CodedGrid {
    pub code_levels: u32,
    pub widths: u32,
    /// Bit where the grid's own block begins, and its shifts.
    pub inner_bit: u32,
    pub inner_shifts: u32,
    /// Bit where each base edge's block begins, their shifts, and which run against the
    /// stored direction (bit `e`).
    pub edge_bit: [u32; 3],
    pub edge_shifts: [u32; 3],
    pub edge_reversed: u32,
    pub corner_values: [u32; 3],
}

/// Where a scene's compressed values lie in its buffer.
#[derive(Copy, Clone)]
pub struct CodedScene {
    pub code: ValueCode,
    /// Bit of base edge 0's block (edge `e`'s at `edge_bit + e * edge_block_bits`).
    pub edge_bit: u32,
    pub edge_block_bits: u32,
    /// Bit of base vertex 0's corner value (11 bits each).
    pub corner_bit: u32,
}

impl CodedScene {
    /// Grid `ids` whose block begins at bit `inner_bit`, resolved.
    #[inline]
    pub fn open<B: Buffer<u32>>(&self, buffer: B, ids: &GridIds, inner_bit: u32) -> CodedGrid {
        let shift_bits = self.code.shift_bits();
        let edge = |e: u32| self.edge_bit + ids.edge(e) * self.edge_block_bits;
        let edge_bit = [edge(0), edge(1), edge(2)];
        let corner = |c: u32| read_bits(buffer, self.corner_bit + ids.corner(c) * VALUE_BITS, VALUE_BITS);
        CodedGrid {
            code_levels: self.code.levels,
            widths: self.code.widths,
            inner_bit,
            inner_shifts: read_bits(buffer, inner_bit, shift_bits),
            edge_bit,
            edge_shifts: [
                read_bits(buffer, edge_bit[0], shift_bits),
                read_bits(buffer, edge_bit[1], shift_bits),
                read_bits(buffer, edge_bit[2], shift_bits),
            ],
            edge_reversed: ids.edge_reversed(0) as u32
                | (ids.edge_reversed(1) as u32) << 1
                | (ids.edge_reversed(2) as u32) << 2,
            corner_values: [corner(0), corner(1), corner(2)],
        }
    }
}

impl CodedGrid {
    fn code(&self) -> ValueCode {
        ValueCode {
            levels: self.code_levels,
            widths: self.widths,
        }
    }

    /// The value of point `p`, a point of the grid's lattice that is not a corner, whose
    /// parents hold `a` and `b`.
    #[inline]
    pub fn midpoint<B: Buffer<u32>>(&self, buffer: B, p: Lattice, a: u32, b: u32) -> u32 {
        let code = self.code();
        let n = 1u32 << code.levels;
        let [i, j] = p;
        let k = n - i - j;
        // The base edge the point lies on (3: none) and its step along it from the edge's
        // first corner.
        let (edge, s) = if j == 0 {
            (0, i)
        } else if k == 0 {
            (1, j)
        } else if i == 0 {
            (2, k)
        } else {
            (3, 0)
        };
        let (bit, shifts, level, place) = if edge < 3 {
            let t = if (self.edge_reversed >> edge) & 1 != 0 {
                n - s
            } else {
                s
            };
            let tz = t.trailing_zeros();
            let level = code.levels - tz;
            let place = code.edge_level_bit(level) + (t >> (tz + 1)) * code.width(level);
            (
                self.edge_bit[edge as usize],
                self.edge_shifts[edge as usize],
                level,
                place,
            )
        } else {
            let tz = (i | j).trailing_zeros();
            let level = code.levels - tz;
            let rank = inner_rank(i >> tz, j >> tz, 1 << level);
            (
                self.inner_bit,
                self.inner_shifts,
                level,
                code.inner_level_bit(level) + rank * code.width(level),
            )
        };
        let width = code.width(level);
        let shift = (shifts >> (SHIFT_BITS * (level - 1))) & ((1 << SHIFT_BITS) - 1);
        corrected(a, b, read_bits(buffer, bit + place, width), width, shift)
    }

    /// The value of lattice point `p`: its corner's, or derived level by level from the
    /// corners down the sub-triangles that hold it.
    pub fn value<B: Buffer<u32>>(&self, buffer: B, p: Lattice) -> u32 {
        let n = 1i32 << self.code_levels;
        let (pi, pj) = (p[0] as i32, p[1] as i32);
        // The sub-triangle: first corner `a`, edge length `h`, orientation `d` (the corners
        // are `a`, `a + d (h, 0)`, `a + d (0, h)`), and the corners' values.
        let mut a = [0i32, 0];
        let mut h = n;
        let mut d = 1i32;
        let [mut qa, mut qb, mut qc] = self.corner_values;
        loop {
            let (u, v) = (d * (pi - a[0]), d * (pj - a[1]));
            if u == 0 && v == 0 {
                return qa;
            }
            if u == h {
                return qb;
            }
            if v == h {
                return qc;
            }
            let g = h / 2;
            let at = |x: i32, y: i32| [(a[0] + d * x) as u32, (a[1] + d * y) as u32];
            let qab = self.midpoint(buffer, at(g, 0), qa, qb);
            let qbc = self.midpoint(buffer, at(g, g), qb, qc);
            let qca = self.midpoint(buffer, at(0, g), qc, qa);
            // The child that holds the point: corner children at a, b, c, else the
            // inverted middle one, whose first corner is the midpoint of b and c.
            let corner = |x: i32, y: i32| [a[0] + d * x, a[1] + d * y];
            if u + v <= g {
                (qb, qc) = (qab, qca);
            } else if u >= g {
                a = corner(g, 0);
                (qa, qc) = (qab, qbc);
            } else if v >= g {
                a = corner(0, g);
                (qa, qb) = (qca, qbc);
            } else {
                a = corner(g, g);
                d = -d;
                (qa, qb, qc) = (qbc, qca, qab);
            }
            h = g;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The closed-form ranks number the new inner points of each level once each, in order.
    #[test]
    fn inner_ranks_enumerate_each_level() {
        for l in 1..=6u32 {
            let m = 1u32 << l;
            let mut next = 0;
            for a in 1..m {
                for b in 1..m - a {
                    if a % 2 == 0 && b % 2 == 0 {
                        continue;
                    }
                    assert_eq!(inner_rank(a, b, m), next, "level {l}, ({a}, {b})");
                    next += 1;
                }
            }
            assert_eq!(next, inner_new_count(l), "level {l}");
        }
    }

    #[test]
    fn corrections_sign_extend_shift_and_clamp() {
        assert_eq!(corrected(10, 20, 0b111, 3, 0), 14);
        assert_eq!(corrected(10, 20, 0b011, 3, 2), 27);
        assert_eq!(corrected(0, 1, 0b100, 3, 4), 0);
        assert_eq!(corrected(2047, 2047, 0b011, 3, 4), 2047);
        assert_eq!(corrected(3, 4, 0, 0, 7), 4);
    }

    #[test]
    fn bits_read_across_words() {
        let words = [0xdead_beefu32, 0x1234_5678, 0];
        assert_eq!(read_bits(&words[..], 0, 8), 0xef);
        assert_eq!(read_bits(&words[..], 28, 8), 0x8d);
        assert_eq!(read_bits(&words[..], 32, 24), 0x34_5678);
    }
}
