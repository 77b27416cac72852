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
//! A micro-mesh whose values carry a compressed code ([`crate::micromesh::bary::Micromap::value_code`]) is laid
//! out with blocks for values: a table of the grids' blocks and the blocks, each of its own
//! length (written in leaf order by the build), then the base edges' blocks end to end and the
//! corners' 11-bit values (see [`super::compressed`]).
//!
//! A value on a shared base edge or corner is taken from the first grid that uses it; in a
//! consistent micromap (gridrt's, or any tool's that keeps edges watertight) every grid holds
//! the same value there.
//!
//! Triangles of mixed levels are laid out at the deepest level `L` (`grid::expanded`): a
//! level-`l` grid holds its values at the multiples of `2^(L - l)` of the level-`L` lattice,
//! which decode to the same bits as its own lattice, and its own level and decimated edges
//! sit in a byte per grid after the headers (`GridParams::level_element`). The traversal
//! renders such a grid at most `l` deep and snaps the odd points of its decimated edges as
//! the decoded triangles do; its spheres and leaf thicknesses are found over the points it
//! renders (`spheres::rendered_points`). The buffer holds only the points some grid renders
//! (see `gridrt_shared::value_tables`): each grid's block its own level's inner points,
//! plain ([`LeveledValues`]) or compressed, after a table of where each block begins, and
//! each base edge's block the points of the level it is rendered at, the edges numbered
//! coarse to fine after a table of where each level's begin.

use crate::bit_writer::BitWriter;
use gridrt_shared::displacement::{displaced_point, u_major_index, unorm11_displacement, DisplacedTriangle};
use gridrt_shared::glam::Vec3;
use gridrt_shared::grid_index::{
    corner_point, edge_vertex_count, grid_size, inner_index, inner_points, inner_vertex_count, Lattice,
};
use gridrt_shared::grid_traverse::DISPLACEMENT_BITS;

use super::expanded::expanded_mesh;
use super::{
    check_counts, compressed, edge_points, value_tables, BaseEdges, GridBuild, GridLayout, GridOptions, GridScene,
    GridShape,
};
use crate::error::{fail, Result};
use crate::limits::BufferSize;
use crate::mesh::Mesh;
use crate::micromesh::DisplacedMesh;

/// Lays out `mesh` as displaced grids. Triangles of mixed levels share the deepest one's
/// lattice: a coarser grid holds its own level's points of it, and the points between them
/// (which it never renders) are the means of their parents, as compressed values predict them
/// (see `grid::expanded`).
pub fn layout(mesh: &DisplacedMesh, options: &GridOptions) -> Result<GridLayout> {
    let Some(levels) = mesh.deepest_level() else {
        fail!(Input, "it has no base triangles");
    };
    let mesh = mesh.with_ranges_folded();
    let own_levels = mesh.own_levels();
    let (edges, rendered) = value_tables::level_sorted_edges(&mesh);
    let mesh = match own_levels.is_empty() {
        true => mesh,
        false => expanded_mesh(&mesh),
    };
    let base = Mesh {
        positions: mesh.positions.clone(),
        triangles: mesh.triangles.clone(),
    };
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

    let (values, vertices) = values_by_slot(&mesh, &base, &edges, &shape);

    let (inner_by_grid, shared, value_blocks) = match mesh.micromap.value_code {
        None if !own_levels.is_empty() => {
            let leveled = LeveledValues::new(&mesh, (&edges, &rendered), &own_levels, &values);
            shape.inner_words = 0;
            shape.block_offset_bits = leveled.blocks.offset_bits;
            let edge_word = leveled.blocks.words;
            let base_word = edge_word + leveled.shared.len() as u64;
            check_addressable(base_word, &format!("{grids} grids of levels up to {levels}"))?;
            shape.edge_word = edge_word as u32;
            shape.corner_bit = (32 * edge_word + leveled.edge_area_bits) as u32;
            shape.base_word = base_word as u32;
            (Vec::new(), leveled.shared, Some(leveled.blocks))
        }
        None => {
            let inner = grids * inner_count;
            let inner_by_grid = (0..grids)
                .flat_map(|g| pack(&values[g * inner_count..(g + 1) * inner_count]))
                .collect();
            (inner_by_grid, pack(&values[inner..]), None)
        }
        Some(code) => {
            let Some(encoded) = compressed::encode_exact(&mesh, (&edges, &rendered), code) else {
                fail!(
                    Input,
                    "its values are not those of their compressed code: compress the micro-mesh again"
                );
            };
            let blocks = value_tables::GridBlocks::new(encoded.grid_blocks);
            shape.inner_words = 0;
            shape.value_code = Some(code);
            shape.block_offset_bits = blocks.offset_bits;
            let edge_word = blocks.words;
            let corner_bit = 32 * edge_word + encoded.edge_area_bits;
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
    let buffer = value_buffer(&shape, &shared, &mesh);
    Ok(GridLayout {
        shape,
        ids: edges.ids(&base),
        vertices,
        inner_by_grid,
        value_blocks,
        buffer,
        own_levels,
    })
}

/// Each vertex slot's value and decoded position, slot by slot: the inner areas grid by
/// grid, each base edge's points from the grid that stores it, then the corners (a base
/// vertex no triangle uses decodes to its own position, value 0).
fn values_by_slot(mesh: &DisplacedMesh, base: &Mesh, edges: &BaseEdges, shape: &GridShape) -> (Vec<u16>, Vec<Vec3>) {
    let n = grid_size(shape.levels);
    let value = |g: usize, p: Lattice| mesh.micromap.triangle_values(g)[u_major_index(p, n) as usize];
    let triangle = |g: usize| DisplacedTriangle {
        positions: mesh.triangles[g].map(|v| mesh.positions[v as usize]),
        directions: mesh.triangles[g].map(|v| mesh.directions[v as usize]),
        ids: mesh.triangles[g],
    };
    let decode =
        |g: usize, p: Lattice| displaced_point(&triangle(g), p, n, unorm11_displacement(value(g, p) as u32, 1.0, 0.0));
    let mut values: Vec<u16> = Vec::with_capacity(shape.corner_offset as usize + base.positions.len());
    let mut vertices: Vec<Vec3> = Vec::with_capacity(values.capacity());
    for g in 0..base.triangles.len() {
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
            let lattice = corner_point(c as u32, n);
            corner_of[v as usize].get_or_insert((g, lattice));
        }
    }
    for &corner in &corner_of {
        let (q, p) = corner.map_or((0, None), |(g, lattice)| (value(g, lattice), Some(decode(g, lattice))));
        values.push(q);
        vertices.push(p.unwrap_or(Vec3::ZERO));
    }
    (values, vertices)
}

/// The vertex buffer of displaced grids: their values' `shared` words at the shape's edge
/// word, then each base vertex's position and direction as six `f32` words.
fn value_buffer(shape: &GridShape, shared: &[u32], mesh: &DisplacedMesh) -> Vec<u32> {
    let edge_word = shape.edge_word as usize;
    let mut buffer = vec![0u32; shape.base_word as usize + 6 * mesh.positions.len()];
    buffer[edge_word..edge_word + shared.len()].copy_from_slice(shared);
    for (record, (p, d)) in buffer[shape.base_word as usize..]
        .chunks_mut(6)
        .zip(mesh.positions.iter().zip(&mesh.directions))
    {
        record[..3].copy_from_slice(&p.to_array().map(f32::to_bits));
        record[3..].copy_from_slice(&d.to_array().map(f32::to_bits));
    }
    buffer
}

/// Plain values of grids of mixed levels, each block at its own level (see
/// `gridrt_shared::value_tables`): each grid's inner points of its own level, and each base
/// edge's points of the level it is rendered at, edges numbered coarse to fine after their
/// table of levels, then the corners.
struct LeveledValues {
    blocks: value_tables::GridBlocks,
    /// The edges' table and values, then the corners' values.
    shared: Vec<u32>,
    /// Bits of `shared` before the corners' values.
    edge_area_bits: u64,
}

impl LeveledValues {
    /// From `mesh` (expanded to the deepest level, see `grid::expanded`) and its values
    /// `values` as the scene-level layout holds them: inner areas, edge areas (by the ids
    /// of `edges`), corners.
    fn new(
        mesh: &DisplacedMesh,
        (edges, rendered): (&BaseEdges, &value_tables::Rendered),
        own_levels: &[u8],
        values: &[u16],
    ) -> LeveledValues {
        let levels = mesh.deepest_level().unwrap_or(0);
        let n = grid_size(levels);
        let inner_count = inner_vertex_count(levels) as usize;
        let blocks = own_levels
            .iter()
            .enumerate()
            .map(|(g, &own)| {
                let shift = levels - (own as u32 >> 3);
                let grid_values = &values[g * inner_count..(g + 1) * inner_count];
                let own_values: Vec<u16> = inner_points(n >> shift)
                    .map(|[i, j]| grid_values[inner_index(i << shift, j << shift, n) as usize])
                    .collect();
                (pack(&own_values), own_values.len() as u32 * DISPLACEMENT_BITS)
            })
            .collect();
        let mut out = BitWriter::default();
        let edge_bits = |level: u32| edge_vertex_count(level) * DISPLACEMENT_BITS;
        value_tables::write_edge_levels(&rendered.edge_levels, edge_bits, &mut out);
        let edge_area = own_levels.len() * inner_count;
        for (id, edge_values) in values[edge_area..]
            .chunks(n as usize - 1)
            .take(edges.owner.len())
            .enumerate()
        {
            let step = 1 << (levels - rendered.edge_levels[id]);
            for &q in edge_values.iter().skip(step - 1).step_by(step) {
                out.push(q as u32, DISPLACEMENT_BITS);
            }
        }
        let edge_area_bits = out.bits as u64;
        let corners = &values[edge_area + edges.owner.len() * (n as usize - 1)..];
        for &q in corners {
            out.push(q as u32, DISPLACEMENT_BITS);
        }
        out.words.push(0);
        LeveledValues {
            blocks: value_tables::GridBlocks::new(blocks),
            shared: out.words,
            edge_area_bits,
        }
    }
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
    let Some(levels) = mesh.deepest_level() else {
        fail!(Input, "it has no base triangles");
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
    let mixed = mesh.uniform_level().is_none();
    let value_words = match mixed {
        true => leveled_value_words(mesh, &base),
        false => {
            let inner_words = packed_words(inner_vertex_count(levels) as u64);
            let shared = edges as u64 * edge_vertex_count(levels) as u64 + base.positions.len() as u64;
            grids * inner_words + packed_words(shared)
        }
    };
    let words = value_words + 6 * base.positions.len() as u64;
    for size in &mut sizes {
        match size.name {
            "grid vertex" => size.bytes = 4 * words,
            // A byte per grid of its own level (see `GridParams::level_element`).
            "grid header" if mixed => size.bytes += 16 * grids.div_ceil(16),
            _ => {}
        }
    }
    Ok(sizes)
}

/// Words of plain values of grids of mixed levels, each at its own level (see
/// [`LeveledValues`]), their tables at their narrowest.
fn leveled_value_words(mesh: &DisplacedMesh, base: &Mesh) -> u64 {
    let edges = BaseEdges::new(base);
    let rendered = value_tables::Rendered::new(mesh, &edges);
    let inner_bits: u64 = (rendered.own.iter())
        .map(|&own| 1 + inner_vertex_count(own as u32 >> 3) as u64 * DISPLACEMENT_BITS as u64)
        .sum();
    let edge_points: u64 = rendered.edge_levels.iter().map(|&l| edge_vertex_count(l) as u64).sum();
    let shared_bits = (edge_points + base.positions.len() as u64) * DISPLACEMENT_BITS as u64;
    inner_bits.div_ceil(32) + gridrt_shared::value_tables::EDGE_LEVEL_WORDS as u64 + shared_bits.div_ceil(32)
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
