//! Where the values of displaced grids of mixed levels go, plain or compressed (see
//! `gridrt_shared::value_tables`): each grid's block through a table of first bits
//! ([`GridBlocks`]), and the base edges numbered coarse to fine by the level they are
//! rendered at ([`level_sorted_edges`]), after a table of where each level's blocks begin
//! ([`write_edge_levels`]).

use gridrt_shared::grid_index::Lattice;
use gridrt_shared::value_tables::{EDGE_LEVEL_WORDS, EDGE_TABLE_LEVELS};

use super::BaseEdges;
use crate::bit_writer::BitWriter;
use crate::micromesh::DisplacedMesh;

/// Which points some grid renders, where triangles of mixed levels are laid out at the
/// deepest level (see [`super::expanded::expanded_mesh`]): a grid renders its own level's
/// points, but not those its decimated edges move, and a base edge is rendered at the finest
/// level any of its grids renders it at. Every point is rendered where levels are one.
#[derive(Clone, Debug, Default)]
pub(super) struct Rendered {
    /// Each grid's own level and decimated edges (see [`DisplacedMesh::own_levels`]); empty
    /// where levels are one.
    pub(super) own: Vec<u8>,
    /// Each base edge's finest rendered level, by edge id.
    pub(super) edge_levels: Vec<u32>,
    pub(super) levels: u32,
}

impl Rendered {
    pub(super) fn new(mesh: &DisplacedMesh, edges: &BaseEdges) -> Rendered {
        let own = mesh.own_levels();
        if own.is_empty() {
            return Rendered::default();
        }
        let mut edge_levels = vec![0; edges.owner.len()];
        for (g, ids) in edges.of_grid.iter().enumerate() {
            for (e, &id) in ids.iter().enumerate() {
                let level = &mut edge_levels[id as usize];
                *level = (*level).max(mesh.rendered_edge_level(g, e));
            }
        }
        Rendered {
            own,
            edge_levels,
            levels: mesh.deepest_level().unwrap_or(0),
        }
    }

    /// Grid `g`'s own level, in a scene of `levels`.
    pub(super) fn own_level(&self, g: usize, levels: u32) -> u32 {
        self.own.get(g).map_or(levels, |&b| b as u32 >> 3)
    }

    /// Each grid's decimated edges, as [`DisplacedMesh::decimated_edges`] holds them.
    pub(super) fn decimated_edges(&self) -> Vec<u8> {
        self.own.iter().map(|&b| b & 7).collect()
    }

    /// Whether grid `g` renders its inner point `p`.
    pub(super) fn inner_point(&self, g: usize, p: Lattice) -> bool {
        let Some(&own) = self.own.get(g) else { return true };
        let mask = (1u32 << (self.levels - (own as u32 >> 3))) - 1;
        (p[0] | p[1]) & mask == 0
    }

    /// The levels base edge `id`'s block holds, in a scene of `levels`: the finest it is
    /// rendered at.
    pub(super) fn edge_level(&self, id: usize, levels: u32) -> u32 {
        self.edge_levels.get(id).map_or(levels, |&l| l)
    }

    /// Whether base edge `id`'s point `s` steps from its first corner is rendered.
    pub(super) fn edge_point(&self, id: usize, s: u32) -> bool {
        s & ((1u32 << (self.levels - self.edge_level(id, self.levels))) - 1) == 0
    }
}

/// The grids' blocks as the vertex buffer holds them, from its first word: a table of each
/// block's first bit (`offset_bits` each, end to end, in whole words), then the blocks end to
/// end in bits, grid by grid in the order the grids are stored.
#[derive(Clone, Debug, Default)]
pub struct GridBlocks {
    /// Each grid's block and its length in bits, in base-triangle order.
    pub blocks: Vec<(Vec<u32>, u32)>,
    pub offset_bits: u32,
    pub table_words: u64,
    /// Words of the table and the blocks together.
    pub words: u64,
}

impl GridBlocks {
    pub fn new(blocks: Vec<(Vec<u32>, u32)>) -> GridBlocks {
        let grids = blocks.len() as u64;
        let block_bits: u64 = blocks.iter().map(|b| b.1 as u64).sum();
        // The table's entries must hold the bits before the last block, which grow with the
        // table: widen them until they do.
        let mut offset_bits = 1;
        loop {
            let table_words = (grids * offset_bits as u64).div_ceil(32);
            let end = 32 * table_words + block_bits;
            let needed = (u64::BITS - end.leading_zeros()).max(1);
            if needed <= offset_bits || offset_bits >= 32 {
                return GridBlocks {
                    blocks,
                    offset_bits,
                    table_words,
                    words: end.div_ceil(32),
                };
            }
            offset_bits = needed;
        }
    }

    /// The table and the blocks into `out` (`words` words), the grid of base triangle
    /// `order[slot]` stored at `slot`.
    pub fn write(&self, order: &[u32], out: &mut [u32]) {
        let mut table = BitWriter::default();
        let mut area = BitWriter::default();
        let start = 32 * self.table_words;
        for &g in order {
            table.push((start + area.bits as u64) as u32, self.offset_bits);
            let (words, bits) = &self.blocks[g as usize];
            for (k, &w) in words.iter().enumerate() {
                area.push(w, (bits - 32 * k as u32).min(32));
            }
        }
        out[..table.words.len()].copy_from_slice(&table.words);
        let area_start = self.table_words as usize;
        out[area_start..area_start + area.words.len()].copy_from_slice(&area.words);
    }
}

/// The table of levels before the base edges' blocks in grids of mixed levels (see
/// `gridrt_shared::value_tables::leveled_edge`): per level, its first edge
/// id and the bit its blocks begin at, from the table's first bit. `levels`, each edge's by
/// id, never decrease (see [`level_sorted_edges`]).
pub(super) fn write_edge_levels(levels: &[u32], block_bits: impl Fn(u32) -> u32, out: &mut BitWriter) {
    debug_assert!(levels.is_sorted(), "edges are numbered coarse to fine");
    let mut bit = 32 * EDGE_LEVEL_WORDS as u64;
    let mut id = 0;
    for level in 1..=EDGE_TABLE_LEVELS {
        // Edges of coarser levels come first; past the scene's levels, past the last edge.
        while id < levels.len() && levels[id] < level {
            bit += block_bits(levels[id]) as u64;
            id += 1;
        }
        out.push(id as u32, 32);
        out.push(bit as u32, 32);
    }
}

/// The base edges of `mesh` (ranges folded, of its own levels) numbered coarse to fine by
/// the levels they are rendered at (in the order the triangles first use them within a
/// level), as grids of mixed levels store them, plain or compressed, and which points are
/// rendered.
/// Where levels are one, the edges as [`BaseEdges::new`] numbers them.
pub(super) fn level_sorted_edges(mesh: &DisplacedMesh) -> (BaseEdges, Rendered) {
    let mut edges = BaseEdges::new(&mesh.base_mesh());
    let mut rendered = Rendered::new(mesh, &edges);
    if rendered.own.is_empty() {
        return (edges, rendered);
    }
    let mut order: Vec<u32> = (0..edges.owner.len() as u32).collect();
    order.sort_by_key(|&id| rendered.edge_levels[id as usize]);
    let mut new_id = vec![0u32; order.len()];
    for (new, &old) in order.iter().enumerate() {
        new_id[old as usize] = new as u32;
    }
    edges.owner = order.iter().map(|&old| edges.owner[old as usize]).collect();
    rendered.edge_levels = order.iter().map(|&old| rendered.edge_levels[old as usize]).collect();
    for ids in &mut edges.of_grid {
        *ids = ids.map(|id| new_id[id as usize]);
    }
    (edges, rendered)
}
