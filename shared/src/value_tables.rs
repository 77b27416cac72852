//! Where the values of displaced grids of mixed levels lie, plain or compressed: each grid's
//! block through a table of first bits, and each base edge's through a table of levels.
//!
//! A grid of mixed levels stores its values at its own level only, so grids' blocks differ
//! in length: a table at the start of the buffer gives each block's first bit, a fixed
//! number of bits per grid ([`block_bit`]).
//!
//! A base edge stores its points at the level it is rendered at, the finest of its grids'
//! levels there, so edges' blocks differ in length too. Rather than a table entry per edge,
//! the edges are numbered coarse to fine: all edges of one level are one run of blocks of
//! one length. A table of [`EDGE_LEVEL_WORDS`] words before the blocks gives, for each level
//! `1 ..= EDGE_TABLE_LEVELS`, its first edge id and the bit where its blocks begin, from the
//! table's first bit ([`leveled_edge`]). An edge's level is then how many levels' first ids
//! its own id has reached.

use crate::bit_fields::read_long_bits;
use crate::buffer::Buffer;

/// The deepest level the table of edge levels describes.
pub const EDGE_TABLE_LEVELS: u32 = 6;
/// Words of the table of edge levels: per level, its first edge id and its first bit.
pub const EDGE_LEVEL_WORDS: u32 = 2 * EDGE_TABLE_LEVELS;

/// The first bit of grid `grid`'s block: entry `grid` of the table at the start of the
/// buffer, `offset_bits` bits each, end to end.
#[inline]
pub fn block_bit<B: Buffer<u32>>(buffer: B, grid: u32, offset_bits: u32) -> u32 {
    read_long_bits(buffer, grid * offset_bits, offset_bits)
}

/// A base edge found in the table of edge levels.
#[derive(Copy, Clone)]
pub struct LeveledEdge {
    /// The level its block holds (0: no points between its corners).
    pub level: u32,
    /// Where its level's blocks begin, in bits from the table's first bit.
    pub start: u32,
    /// Its place among its level's edges.
    pub index: u32,
}

impl LeveledEdge {
    /// Its block's first bit, for the table at `table_bit` and blocks of `block_bits` bits.
    #[inline]
    pub fn bit(&self, table_bit: u32, block_bits: u32) -> u32 {
        table_bit + self.start + self.index * block_bits
    }
}

/// Base edge `id` in the table of edge levels at bit `table_bit` (a word's first bit).
#[inline]
pub fn leveled_edge<B: Buffer<u32>>(buffer: B, table_bit: u32, id: u32) -> LeveledEdge {
    // Levels' first ids never decrease, and a level past the scene's begins past the last
    // edge. Unrolled rather than a loop: lavapipe ends a kernel's loops once all of them
    // together have run 65535 times in one invocation.
    let table = table_bit >> 5;
    let reached = |k: u32| (id >= buffer.load(table + 2 * (k - 1))) as u32;
    let level = reached(1) + reached(2) + reached(3) + reached(4) + reached(5) + reached(6);
    if level == 0 {
        return LeveledEdge {
            level: 0,
            start: 0,
            index: 0,
        };
    }
    let first = buffer.load(table + 2 * (level - 1));
    LeveledEdge {
        level,
        start: buffer.load(table + 2 * (level - 1) + 1),
        index: id - first,
    }
}
