//! Displaced grids: the grid layout of a displaced micro-mesh, one 11-bit value per lattice
//! point instead of a position, stored once like every grid vertex (inner points per grid,
//! edge points per base edge, corners per base vertex), and the base mesh's positions and
//! directions to decode them with.
//!
//! The vertex buffer: each grid's inner values (11 bits each, end to end, in whole words per
//! grid, so the build can reorder grids as records), then the edge and corner values as one
//! run of 11-bit values, then six `f32` per base vertex (position, direction). Values are
//! addressed in bits, so the values take at most 512 MiB. The traversal decodes a lattice point
//! with `gridrt_shared::displacement`, as the host does here for the bounds and radii: the
//! spheres enclose exactly the points the traversal computes. The micromap's ranges are
//! folded into the base mesh first (see [`DisplacedMesh::with_ranges_folded`]).
//!
//! A micro-mesh whose values carry a compressed code ([`crate::bary::Micromap::value_code`]) is laid
//! out with blocks for values: a table of the grids' blocks and the blocks, each of its own
//! length (written in leaf order by the build), then the base edges' blocks end to end and the
//! corners' 11-bit values (see [`super::compressed`]).
//!
//! A value on a shared base edge or corner is taken from the first grid that uses it; in a
//! consistent micromap (gridrt's, or any tool's that keeps edges watertight) every grid holds
//! the same value there.

use crate::bit_writer::BitWriter;
use gridrt_shared::displacement::{displaced_point, u_major_index, unorm11_displacement, DisplacedTriangle};
use gridrt_shared::glam::Vec3;
use gridrt_shared::grid_index::{edge_vertex_count, grid_size, inner_points, inner_vertex_count, Lattice};
use gridrt_shared::grid_traverse::DISPLACEMENT_BITS;

use super::{
    check_counts, compressed, corner_point, edge_points, BaseEdges, GridBuild, GridLayout, GridOptions, GridScene,
    GridShape,
};
use crate::displaced::DisplacedMesh;
use crate::error::{fail, Result};
use crate::limits::BufferSize;
use crate::mesh::Mesh;

/// Lays out `mesh` (every triangle at one level) as displaced grids.
pub fn layout(mesh: &DisplacedMesh, options: &GridOptions) -> Result<GridLayout> {
    let Some(levels) = mesh.uniform_level() else {
        fail!(
            Input,
            "its base triangles are subdivided to different levels, which displaced grids do not hold yet"
        );
    };
    let mesh = mesh.with_ranges_folded();
    let base = Mesh {
        positions: mesh.positions.clone(),
        triangles: mesh.triangles.clone(),
    };
    let n = grid_size(levels);
    let edges = BaseEdges::new(&base);
    check_counts(&base, edges.owner.len() as u64, levels, options, false)?;
    let mut shape = GridShape::new(&base, edges.owner.len(), levels, options, false);
    let inner_count = inner_vertex_count(levels) as usize;
    shape.inner_words = packed_words(inner_count as u64) as u32;
    let grids = base.triangles.len();
    let edge_word = grids * shape.inner_words as usize;
    shape.edge_word = edge_word as u32;
    let shared_values = (shape.corner_offset - shape.edge_offset) as usize + base.positions.len();
    let base_word = edge_word as u64 + packed_words(shared_values as u64);
    check_addressable(base_word, &format!("{grids} grids at level {levels}"))?;
    shape.base_word = base_word as u32;

    let value = |g: usize, p: Lattice| mesh.micromap.triangle_values(g)[u_major_index(p, n) as usize];
    let triangle = |g: usize| DisplacedTriangle {
        positions: mesh.triangles[g].map(|v| mesh.positions[v as usize]),
        directions: mesh.triangles[g].map(|v| mesh.directions[v as usize]),
        ids: mesh.triangles[g],
    };
    let decode =
        |g: usize, p: Lattice| displaced_point(&triangle(g), p, n, unorm11_displacement(value(g, p) as u32, 1.0, 0.0));

    // Values and decoded positions, slot by slot: inner, edge, corner areas.
    let mut values: Vec<u16> = Vec::with_capacity(shape.corner_offset as usize + base.positions.len());
    let mut vertices: Vec<Vec3> = Vec::with_capacity(values.capacity());
    for g in 0..grids {
        values.extend(inner_points(n).map(|p| value(g, p)));
        vertices.extend(inner_points(n).map(|p| decode(g, p)));
    }
    for &(g, e) in &edges.owner {
        values.extend(edge_points(&base.triangles[g], e, n).map(|p| value(g, p)));
        vertices.extend(edge_points(&base.triangles[g], e, n).map(|p| decode(g, p)));
    }
    let mut corner_of = vec![None; base.positions.len()];
    for (g, t) in base.triangles.iter().enumerate() {
        for (c, &v) in t.iter().enumerate() {
            let lattice = corner_point(c, n);
            corner_of[v as usize].get_or_insert((g, lattice));
        }
    }
    for &corner in &corner_of {
        // A base vertex no triangle uses decodes to its own position (value 0).
        let (q, p) = corner.map_or((0, None), |(g, lattice)| (value(g, lattice), Some(decode(g, lattice))));
        values.push(q);
        vertices.push(p.unwrap_or(Vec3::ZERO));
    }

    let (inner_by_grid, shared, value_blocks) = match mesh.micromap.value_code {
        None => {
            let inner = grids * inner_count;
            let inner_by_grid = (0..grids)
                .flat_map(|g| pack(&values[g * inner_count..(g + 1) * inner_count]))
                .collect();
            (inner_by_grid, pack(&values[inner..]), None)
        }
        Some(code) => {
            let Some(encoded) = compressed::encode_exact(&mesh, &edges, code) else {
                fail!(
                    Input,
                    "its values are not those of their compressed code: compress the micro-mesh again"
                );
            };
            let blocks = compressed::GridBlocks::new(encoded.grid_blocks);
            shape.inner_words = 0;
            shape.value_code = Some(code);
            shape.block_offset_bits = blocks.offset_bits;
            let edge_word = blocks.words;
            let corner_bit = 32 * edge_word + edges.owner.len() as u64 * code.edge_block_bits() as u64;
            let base_word = edge_word + encoded.shared.len() as u64;
            check_addressable(
                base_word,
                &format!("{grids} grids of compressed values at level {levels}"),
            )?;
            shape.edge_word = edge_word as u32;
            shape.corner_bit = corner_bit as u32;
            shape.base_word = base_word as u32;
            (Vec::new(), encoded.shared, Some(blocks))
        }
    };
    let edge_word = shape.edge_word as usize;
    let mut buffer = vec![0u32; shape.base_word as usize + 6 * base.positions.len()];
    buffer[edge_word..edge_word + shared.len()].copy_from_slice(&shared);
    for (record, (p, d)) in buffer[shape.base_word as usize..]
        .chunks_mut(6)
        .zip(mesh.positions.iter().zip(&mesh.directions))
    {
        record[..3].copy_from_slice(&p.to_array().map(f32::to_bits));
        record[3..].copy_from_slice(&d.to_array().map(f32::to_bits));
    }
    Ok(GridLayout {
        shape,
        ids: edges.ids(&base),
        vertices,
        inner_by_grid,
        value_blocks,
        buffer,
    })
}

/// Refuses values that end past what bit addresses reach (`whose` says whose they are):
/// everything before the base vertices, `base_word` words, within 2^32 bits.
fn check_addressable(base_word: u64, whose: &str) -> Result<()> {
    if 32 * base_word >= 1 << 32 {
        fail!(
            Limits,
            "{whose} need {} of displacement values, more than displaced grids address (512 MiB)",
            crate::limits::human(4 * base_word)
        );
    }
    Ok(())
}

/// Words that hold `values` 11-bit values end to end.
fn packed_words(values: u64) -> u64 {
    (values * DISPLACEMENT_BITS as u64).div_ceil(32)
}

/// `values` (each below `2^11`) as 11-bit fields end to end, the first in the lowest bits.
fn pack(values: &[u16]) -> Vec<u32> {
    let mut words = BitWriter::packed(values.iter().map(|&q| q as u32), DISPLACEMENT_BITS);
    words.resize(packed_words(values.len() as u64) as usize, 0);
    words
}

/// The sizes of `mesh`'s displaced-grid buffers, from counts alone (the top-level BVH's
/// bounded below), after checking the layout can address them; in the order of
/// `crate::split::scene_buffers`.
pub fn least_buffer_sizes(mesh: &DisplacedMesh, options: &GridOptions) -> Result<Vec<BufferSize>> {
    let Some(levels) = mesh.uniform_level() else {
        fail!(Input, "its base triangles are subdivided to different levels");
    };
    let base = Mesh {
        positions: mesh.positions.clone(),
        triangles: mesh.triangles.clone(),
    };
    let edges = BaseEdges::new(&base).owner.len();
    check_counts(&base, edges as u64, levels, options, false)?;
    let build = GridBuild {
        options: *options,
        quantized: false,
        ..GridBuild::new(levels)
    };
    let mut sizes = super::least_buffer_sizes(&base, edges as u64, &build);
    let grids = base.triangles.len() as u64;
    let inner_words = packed_words(inner_vertex_count(levels) as u64);
    let shared = edges as u64 * edge_vertex_count(levels) as u64 + base.positions.len() as u64;
    let words = grids * inner_words + packed_words(shared) + 6 * base.positions.len() as u64;
    for size in &mut sizes {
        if size.name == "grid vertex" {
            size.bytes = 4 * words;
        }
    }
    Ok(sizes)
}

/// Lays out and builds displaced grids in one go.
pub fn build(mesh: &DisplacedMesh, options: &GridOptions) -> Result<GridScene> {
    Ok(super::build_from_layout(&mut layout(mesh, options)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Packed values read back as the traversal reads them, across word boundaries.
    #[test]
    fn packed_values_read_back() {
        let values: Vec<u16> = (0..100).map(|k| ((k * 1237 + 5) % 2048) as u16).collect();
        let mut words = pack(&values);
        words.push(0);
        for (k, &q) in values.iter().enumerate() {
            let bit = k as u32 * DISPLACEMENT_BITS;
            let (word, shift) = ((bit >> 5) as usize, bit & 31);
            let low = words[word] >> shift;
            let high = (words[word + 1] << 1) << (31 - shift);
            assert_eq!((low | high) & 0x7ff, q as u32, "value {k}");
        }
        assert_eq!(pack(&[0x7ff; 32]).len(), 11);
    }
}
