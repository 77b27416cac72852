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
//! - Corrections are signed, `width(l)` bits each (0 to 11). Each block (a grid's inner
//!   points, or a base edge's points) holds its own shift per level, [`SHIFT_BITS`] each,
//!   chosen by the encoder, then its corrections level by level, coarse to fine.
//! - The base edges share one set of widths, the scene's. Each grid's block begins with its
//!   own widths, [`WIDTH_BITS`] per level, before its shifts: a smooth grid spends few bits
//!   and a detailed one many, where one set for the whole scene would spend the detailed
//!   grids' widths everywhere. Grid blocks are therefore of different lengths; a table at
//!   the start of the buffer gives each one's first bit (see [`CodedScene::block_bit`]).
//! - A base edge's points form a block of their own, stored once from the edge's lower base
//!   vertex id, and are predicted from points of that edge alone: both grids that share the
//!   edge decode the same values, so the surface stays watertight. Corners are plain 11-bit
//!   values, one per base vertex.
//! - In grids of mixed levels every block holds the levels it renders and no more: a grid's
//!   block its own level's widths, shifts and corrections, a base edge's block those of the
//!   level the edge is rendered at (the finest of its grids' levels there). A point of a
//!   finer level than its block holds is its parents' mean. The base edges are numbered
//!   coarse to fine, and a table before their blocks gives, for each level, its first edge
//!   and the bit where its blocks begin (see [`CodedScene::edge_block`]).
//!
//! Inside a grid, the new points of level `l` are taken row by row (`i`, then `j`, on the
//! level-`l` lattice), so a point's place among them is a closed form of its coordinates.
//!
//! [`CodedGrid::value`] decodes any one point by walking down from the grid's corners,
//! deriving the three midpoints of the sub-triangle that holds the point at each level; the
//! traversal walks to a sub-triangle's corners once ([`CodedGrid::sub_triangle_values`]) and
//! decodes from them the part of a leaf's lattice its test reads ([`CodedGrid::decode_lattice`]).

use crate::bit_fields::read_bits;
use crate::buffer::Buffer;
use crate::grid_index::{lattice_index, parents, Lattice};
use crate::layout::GridIds;
use crate::value_tables::{block_bit, leveled_edge, EDGE_TABLE_LEVELS};

const _: () = assert!(
    MAX_LEVELS == EDGE_TABLE_LEVELS,
    "the table of edge levels covers every level"
);

/// Bits of one block's shift for one level.
pub const SHIFT_BITS: u32 = 4;
/// Bits of a correction's width for one level, in [`ValueCode::widths`].
pub const WIDTH_BITS: u32 = 4;
/// The deepest level a code describes.
pub const MAX_LEVELS: u32 = 6;
/// Where [`CodedGrid::edge_code`] keeps the levels, above the widths of [`MAX_LEVELS`] levels.
const LEVELS_SHIFT: u32 = WIDTH_BITS * MAX_LEVELS;
/// Where [`CodedGrid::block_levels`] keeps the grid's own level, and then its edges' (four bits
/// each), above the edges' directions.
const OWN_LEVEL_SHIFT: u32 = 4;
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

    /// Bits of the widths at the start of every grid's block.
    #[inline]
    pub fn width_bits(&self) -> u32 {
        WIDTH_BITS * self.levels
    }

    /// Bit, within a grid's block, where level `l`'s corrections begin.
    #[inline]
    pub fn inner_level_bit(&self, l: u32) -> u32 {
        self.level_bit(l, false)
    }

    /// Bit, within a base edge's block, where level `l`'s corrections begin.
    #[inline]
    pub fn edge_level_bit(&self, l: u32) -> u32 {
        self.level_bit(l, true)
    }

    /// Bit, within a base edge's block (`edge`) or a grid's, where level `l`'s corrections
    /// begin: after the shifts and the coarser levels.
    #[inline]
    fn level_bit(&self, l: u32, edge: bool) -> u32 {
        // Unrolled over the [`MAX_LEVELS`] levels a code may have, rather than a loop up to `l`: every decoded
        // value asks for it, and lavapipe ends a kernel's loops once all of them together
        // have run 65535 times in one invocation, which a loop here used up on deep grids.
        let term = |k: u32| {
            let count = if edge { edge_new_count(k) } else { inner_new_count(k) };
            if k < l {
                count * self.width(k)
            } else {
                0
            }
        };
        self.shift_bits() + term(1) + term(2) + term(3) + term(4) + term(5) + term(6)
    }

    /// Bits of a grid's block whose own widths are this code's, its widths included.
    #[inline]
    pub fn inner_block_bits(&self) -> u32 {
        self.width_bits() + self.inner_level_bit(self.levels + 1)
    }

    /// Bits of a base edge's block.
    #[inline]
    pub fn edge_block_bits(&self) -> u32 {
        self.edge_level_bit(self.levels + 1)
    }

    /// This code's widths for a block of `levels` levels: those of levels `1 ..= levels`.
    #[inline]
    pub fn at_levels(&self, levels: u32) -> ValueCode {
        let bits = WIDTH_BITS * levels;
        ValueCode {
            levels,
            widths: if bits >= 32 {
                self.widths
            } else {
                self.widths & ((1 << bits) - 1)
            },
        }
    }
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
    /// The code's levels (bits 24 and up) and the base edges' widths (the scene's) below
    /// them, in one word, and the grid's own widths. (One word for both keeps the struct the
    /// size it had before grids had widths of their own: the GPU's shader validator reads its
    /// members at the offsets Rust lays out, and a larger struct moved them.)
    pub edge_code: u32,
    pub inner_widths: u32,
    /// Bit where the grid's own block begins after its widths, and its shifts.
    pub inner_bit: u32,
    pub inner_shifts: u32,
    /// Bit where each base edge's block begins, their shifts, and in `block_levels` which run
    /// against the stored direction (bit `e`), and above them (from [`OWN_LEVEL_SHIFT`], four
    /// bits each) the levels the grid's own block holds and then each edge's block.
    pub edge_bit: [u32; 3],
    pub edge_shifts: [u32; 3],
    pub block_levels: u32,
    pub corner_values: [u32; 3],
}

/// What decoding a point new at one level takes from its grid that no point changes: found
/// once for the points of a level (a sub-triangle's three midpoints, a leaf's points of one
/// spacing) rather than once a point.
#[derive(Copy, Clone)]
pub struct LevelCode {
    level: u32,
    /// Bit where the level's corrections begin in a base edge's block holding every level,
    /// and their width (the scene's).
    edge_bit: u32,
    edge_width: u32,
    /// The same in the grid's own block (its own widths).
    inner_bit: u32,
    inner_width: u32,
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
    /// Bits of each entry of the block table (see [`Self::block_bit`]).
    pub offset_bits: u32,
    /// Whether the grids are of mixed levels, each block holding its own (see the module
    /// docs): the base edges' blocks then follow a table of levels at `edge_bit`.
    pub mixed: bool,
}

impl CodedScene {
    /// The first bit of grid `grid`'s block (see `crate::value_tables`).
    #[inline]
    pub fn block_bit<B: Buffer<u32>>(&self, buffer: B, grid: u32) -> u32 {
        block_bit(buffer, grid, self.offset_bits)
    }

    /// Where base edge `id`'s block begins, and the levels it holds.
    #[inline]
    pub fn edge_block<B: Buffer<u32>>(&self, buffer: B, id: u32) -> (u32, u32) {
        if !self.mixed {
            return (self.edge_bit + id * self.edge_block_bits, self.code.levels);
        }
        let edge = leveled_edge(buffer, self.edge_bit, id);
        let bits = self.code.at_levels(edge.level).edge_block_bits();
        (edge.bit(self.edge_bit, bits), edge.level)
    }

    /// Grid `grid` with ids `ids`, of level `own` (the scene's where levels are one),
    /// resolved.
    #[inline]
    pub fn open<B: Buffer<u32>>(&self, buffer: B, ids: &GridIds, grid: u32, own: u32) -> CodedGrid {
        let block_bit = self.block_bit(buffer, grid);
        let width_bits = WIDTH_BITS * own;
        let inner_bit = block_bit + width_bits;
        let (bit0, level0) = self.edge_block(buffer, ids.edge(0));
        let (bit1, level1) = self.edge_block(buffer, ids.edge(1));
        let (bit2, level2) = self.edge_block(buffer, ids.edge(2));
        let corner = |c: u32| read_bits(buffer, self.corner_bit + ids.corner(c) * VALUE_BITS, VALUE_BITS);
        CodedGrid {
            edge_code: (self.code.levels << LEVELS_SHIFT) | self.code.widths,
            inner_widths: read_bits(buffer, block_bit, width_bits),
            inner_bit,
            inner_shifts: read_bits(buffer, inner_bit, SHIFT_BITS * own),
            edge_bit: [bit0, bit1, bit2],
            edge_shifts: [
                read_bits(buffer, bit0, SHIFT_BITS * level0),
                read_bits(buffer, bit1, SHIFT_BITS * level1),
                read_bits(buffer, bit2, SHIFT_BITS * level2),
            ],
            block_levels: ids.edge_reversed(0) as u32
                | (ids.edge_reversed(1) as u32) << 1
                | (ids.edge_reversed(2) as u32) << 2
                | own << OWN_LEVEL_SHIFT
                | level0 << (OWN_LEVEL_SHIFT + 4)
                | level1 << (OWN_LEVEL_SHIFT + 8)
                | level2 << (OWN_LEVEL_SHIFT + 12),
            corner_values: [corner(0), corner(1), corner(2)],
        }
    }
}

impl CodedGrid {
    /// The code's levels.
    #[inline]
    fn levels(&self) -> u32 {
        self.edge_code >> LEVELS_SHIFT
    }

    /// The base edges' code.
    fn code(&self) -> ValueCode {
        ValueCode {
            levels: self.levels(),
            widths: self.edge_code & ((1 << LEVELS_SHIFT) - 1),
        }
    }

    /// The grid's own code, for its inner points: its own levels.
    fn inner_code(&self) -> ValueCode {
        ValueCode {
            levels: (self.block_levels >> OWN_LEVEL_SHIFT) & 15,
            widths: self.inner_widths,
        }
    }

    /// The levels base edge `e`'s block holds.
    #[inline]
    fn edge_levels(&self, e: u32) -> u32 {
        (self.block_levels >> (OWN_LEVEL_SHIFT + 4 + 4 * e)) & 15
    }

    /// What decoding any point new at `level` takes from this grid, whatever the point.
    #[inline]
    pub fn level_code(&self, level: u32) -> LevelCode {
        let (code, inner) = (self.code(), self.inner_code());
        LevelCode {
            level,
            edge_bit: code.edge_level_bit(level),
            edge_width: code.width(level),
            inner_bit: inner.inner_level_bit(level),
            inner_width: inner.width(level),
        }
    }

    /// The value of point `p`, a point of the grid's lattice new at `at.level` (so not a
    /// corner), whose parents hold `a` and `b`.
    #[inline]
    pub fn midpoint<B: Buffer<u32>>(&self, buffer: B, p: Lattice, a: u32, b: u32, at: &LevelCode) -> u32 {
        let levels = self.levels();
        let n = 1u32 << levels;
        let [i, j] = p;
        let k = n - i - j;
        // A point new at `level` lies an odd multiple of `2^tz` grid steps from every corner.
        let level = at.level;
        let tz = levels - level;
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
        let (bit, shifts, place, width) = if edge < 3 {
            let t = if (self.block_levels >> edge) & 1 != 0 { n - s } else { s };
            // A point finer than the edge's block holds is its parents' mean. The block's
            // shifts are of its own levels, fewer than the scene's shifts by `missing`.
            let held = self.edge_levels(edge);
            let missing = SHIFT_BITS * (levels - held);
            let (place, width) = if level > held {
                (0, 0)
            } else {
                (at.edge_bit - missing + (t >> (tz + 1)) * at.edge_width, at.edge_width)
            };
            // Chosen by comparisons: an array indexed at run time stays in a GPU's slow
            // private memory.
            let pick = |v: [u32; 3]| {
                if edge == 0 {
                    v[0]
                } else if edge == 1 {
                    v[1]
                } else {
                    v[2]
                }
            };
            (pick(self.edge_bit), pick(self.edge_shifts), place, width)
        } else {
            let rank = inner_rank(i >> tz, j >> tz, 1 << level);
            (
                self.inner_bit,
                self.inner_shifts,
                at.inner_bit + rank * at.inner_width,
                at.inner_width,
            )
        };
        let shift = (shifts >> (SHIFT_BITS * (level - 1))) & ((1 << SHIFT_BITS) - 1);
        corrected(a, b, read_bits(buffer, bit + place, width), width, shift)
    }

    /// The grid itself, as the start of a walk down its hierarchy.
    #[inline]
    fn root(&self) -> Walk {
        Walk {
            a: [0, 0],
            h: 1 << self.levels(),
            d: 1,
            q: self.corner_values,
        }
    }

    /// The value of lattice point `p`: its corner's, or derived level by level from the
    /// corners down the sub-triangles that hold it.
    pub fn value<B: Buffer<u32>>(&self, buffer: B, p: Lattice) -> u32 {
        let (pi, pj) = (p[0] as i32, p[1] as i32);
        let mut walk = self.root();
        loop {
            let (u, v) = (walk.d * (pi - walk.a[0]), walk.d * (pj - walk.a[1]));
            if u == 0 && v == 0 {
                return walk.q[0];
            }
            if u == walk.h {
                return walk.q[1];
            }
            if v == walk.h {
                return walk.q[2];
            }
            let g = walk.h / 2;
            let child = if u + v <= g {
                0
            } else if u >= g {
                1
            } else if v >= g {
                2
            } else {
                3
            };
            walk.descend(self, buffer, child);
        }
    }

    /// The values at the corners of sub-triangle `index` at depth `level`, whose base-4
    /// digits, most significant first, name the child taken at each level.
    pub fn sub_triangle_values<B: Buffer<u32>>(&self, buffer: B, level: u32, index: u32) -> [u32; 3] {
        let mut walk = self.root();
        let mut k = level;
        while k > 0 {
            k -= 1;
            walk.descend(self, buffer, (index >> (2 * k)) & 3);
        }
        walk.q
    }

    /// The values of sub-triangle lattice `lattice`, coarse to fine from its corners' values
    /// `corners`, into `out` at [`lattice_index`]`(la, lb, 2^k)`. Only the points of `window`
    /// (`[la_lo, la_hi, lb_lo, lb_hi]`, as a leaf test reads them) are decoded, with the
    /// coarser points they are predicted from; `out` holds what it held before elsewhere.
    pub fn decode_lattice<B: Buffer<u32>, const WORDS: usize>(
        &self,
        buffer: B,
        lattice: SubLattice,
        corners: [u32; 3],
        window: [u32; 4],
        out: &mut PackedValues<WORDS>,
    ) {
        let SubLattice { first, step, k } = lattice;
        let m = 1u32 << k;
        out.set(lattice_index(0, 0, m), corners[0]);
        out.set(lattice_index(m, 0, m), corners[1]);
        out.set(lattice_index(0, m, m), corners[2]);
        let mut s = m;
        while s > 1 {
            let h = s / 2;
            // Every point new at spacing `h` is new at the same level of the grid.
            let at = self.level_code(self.levels() - (h * step.unsigned_abs()).trailing_zeros());
            // The window rounded outwards to spacing `h`: a point's parents lie within `h` of
            // it on the coarser spacing, so the window rounded to each spacing holds the
            // parents of the points decoded in it at the next finer one.
            let down = |x: u32| x & !(h - 1);
            let up = |x: u32| (x + h - 1) & !(h - 1);
            let (la_hi, lb_lo, lb_hi) = (up(window[1]), down(window[2]), up(window[3]));
            // The points new at spacing `h`: multiples of `h`, not both multiples of `s`.
            let mut la = down(window[0]);
            while la <= la_hi {
                let mut lb = lb_lo;
                while lb <= lb_hi && la + lb <= m {
                    if (la | lb) & h != 0 {
                        let [a, b] = parents([la, lb], h);
                        let p = [
                            (first[0] + la as i32 * step) as u32,
                            (first[1] + lb as i32 * step) as u32,
                        ];
                        let qa = out.get(lattice_index(a[0], a[1], m));
                        let qb = out.get(lattice_index(b[0], b[1], m));
                        out.set(lattice_index(la, lb, m), self.midpoint(buffer, p, qa, qb, &at));
                    }
                    lb += h;
                }
                la += h;
            }
            s = h;
        }
    }
}

/// Decoded values of a lattice, two to a word in 16-bit halves (values are at most 16 bits
/// wide): a GPU keeps an array it indexes at run time in registers only while it is small,
/// and this one is read at every point of a leaf.
#[derive(Copy, Clone)]
pub struct PackedValues<const WORDS: usize>([u32; WORDS]);

impl<const WORDS: usize> PackedValues<WORDS> {
    /// Every value `value`.
    #[inline(always)]
    pub fn filled(value: u32) -> Self {
        PackedValues([value | value << 16; WORDS])
    }

    /// Value `i`.
    #[inline(always)]
    pub fn get(&self, i: u32) -> u32 {
        (self.0[(i >> 1) as usize] >> (16 * (i & 1))) & 0xffff
    }

    /// Sets value `i` to `value` (below `2^16`).
    #[inline(always)]
    pub fn set(&mut self, i: u32, value: u32) {
        let shift = 16 * (i & 1);
        let word = &mut self.0[(i >> 1) as usize];
        *word = (*word & !(0xffff << shift)) | value << shift;
    }
}

/// A sub-triangle's lattice `k` levels deep: lattice point `(la, lb)` is grid point
/// `first + (la, lb) * step` (`step` negative for an inverted sub-triangle).
#[derive(Copy, Clone)]
pub struct SubLattice {
    pub first: [i32; 2],
    pub step: i32,
    pub k: u32,
}

/// A sub-triangle on the way down a grid's hierarchy: first corner `a`, edge length `h`,
/// orientation `d` (its corners are `a`, `a + d (h, 0)`, `a + d (0, h)`) and their values.
#[derive(Copy, Clone)]
struct Walk {
    a: [i32; 2],
    h: i32,
    d: i32,
    q: [u32; 3],
}

impl Walk {
    /// Lattice point `(x, y)` of the sub-triangle's frame.
    #[inline]
    fn at(&self, x: i32, y: i32) -> Lattice {
        [(self.a[0] + self.d * x) as u32, (self.a[1] + self.d * y) as u32]
    }

    /// One level down, into child `child`: 0, 1, 2 at corners a, b, c, 3 the inverted middle
    /// one, whose first corner is the midpoint of b and c (as `crate::grid_traverse` numbers
    /// them); its three midpoints decoded on the way.
    #[inline]
    fn descend<B: Buffer<u32>>(&mut self, grid: &CodedGrid, buffer: B, child: u32) {
        let g = self.h / 2;
        let [qa, qb, qc] = self.q;
        let at = grid.level_code(grid.levels() - (g as u32).trailing_zeros());
        let qab = grid.midpoint(buffer, self.at(g, 0), qa, qb, &at);
        let qbc = grid.midpoint(buffer, self.at(g, g), qb, qc, &at);
        let qca = grid.midpoint(buffer, self.at(0, g), qc, qa, &at);
        let (a, d) = (self.a, self.d);
        let corner = |x: i32, y: i32| [a[0] + d * x, a[1] + d * y];
        if child == 0 {
            self.q = [qa, qab, qca];
        } else if child == 1 {
            self.a = corner(g, 0);
            self.q = [qab, qb, qbc];
        } else if child == 2 {
            self.a = corner(0, g);
            self.q = [qca, qbc, qc];
        } else {
            self.a = corner(g, g);
            self.d = -d;
            self.q = [qbc, qca, qab];
        }
        self.h = g;
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
}
