//! Builds the grid representation from a subdivided mesh: the three vertex areas (inner per
//! grid, edge per base edge, corner per base vertex), the per-grid headers, the sphere radii
//! and the top-level BVH over grids.

use std::collections::HashMap;

use crate::bit_writer::BitWriter;
use crate::error::{fail, Result};
use gridrt_shared::buffer::Buffer;
use gridrt_shared::compressed_values::ValueCode;
use gridrt_shared::glam::Vec3;
use gridrt_shared::grid_index::{
    edge_point, edge_vertex_count, grid_size, inner_points, inner_vertex_count, sphere_count, triangle_count, Lattice,
};
use gridrt_shared::grid_slots::GridSlots;
use gridrt_shared::grid_traverse::MAX_SPHERE_LEVEL;
use gridrt_shared::layout::relative_radius_words;
use gridrt_shared::layout::{
    BvhNode, GridHeader, GridIds, GridParams, OwnRoom, DISPLACED_COMPRESSED, DISPLACED_PLAIN, MAX_HEADER_ID,
};
use gridrt_shared::quantize;
use gridrt_shared::top_nodes::{TopNodes, COMPACT};
use gridrt_shared::traverse::BINARY_TOP_STACK;
use gridrt_shared::wide_nodes::{WIDE, WIDTH};
use rayon::prelude::*;

use crate::bvh::{self, Aabb, BuildParams, Bvh};
use crate::limits::BufferSize;

pub mod compact_top;
pub mod compressed;
pub mod displaced;
mod expanded;
pub mod format;
mod lean;
mod spheres;
#[cfg(test)]
pub(crate) mod tests;
pub mod value_tables;
pub mod wide_top;
use crate::mesh::Mesh;
use crate::subdiv::Subdivided;
pub use lean::{build_lean, build_lean_reporting, lean_build_applies, GridBuild};
pub use spheres::encode_radius;
pub use spheres::RadiusFormat;
use spheres::{
    encode_leaf_pairs, encode_relative_radii, grid_bounds_and_radii, radius_scale, rescale_thickness, SphereTable,
};

/// Sphere levels left out at the bottom by default: leaves of 16 micro-triangles.
pub const DEFAULT_EXCLUDED_LEVELS: u32 = 2;

/// How the grids' top-level BVH is stored. Every form is built from the same binary
/// hierarchy, and a form that cannot hold it (codes, links or stack out of range) falls back to
/// the next larger one, so the traversal finds the same hits in each.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum TopFormat {
    /// Binary, 32-byte nodes with `f32` boxes.
    Full,
    /// Binary, 16-byte nodes, boxes as codes of the scene's box (see [`compact_top`]).
    Compact,
    /// Up to seven children to a 64-byte node, each child's box as 8-bit codes in its node's
    /// frame (see [`wide_top`]).
    Wide,
}

/// Choices of the grid representation.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct GridOptions {
    /// Levels at the bottom of the sphere hierarchy that get no spheres.
    pub excluded_levels: u32,
    /// How sphere radii are stored (every format rounds up, so spheres only grow).
    pub radii: RadiusFormat,
    /// Store each leaf's thickness, so the traversal can cull leaves by their footprint
    /// (see `gridrt_shared::footprint`) before loading their vertices.
    pub leaf_footprint: bool,
    /// How the top-level BVH is stored.
    pub top: TopFormat,
    /// Store each grid's ids in as many bits as the mesh's counts need (see
    /// `GridParams::header_bits`) rather than in a 16-byte header.
    pub tight_headers: bool,
    /// Give grids of mixed levels rooms of their own levels for their spheres where that
    /// takes fewer bytes than the scene's room for every grid (see `GridParams::own_rooms`).
    pub own_rooms: bool,
}

impl Default for GridOptions {
    fn default() -> Self {
        GridOptions {
            excluded_levels: DEFAULT_EXCLUDED_LEVELS,
            radii: RadiusFormat::F32,
            leaf_footprint: true,
            top: TopFormat::Full,
            tight_headers: false,
            own_rooms: true,
        }
    }
}

impl GridOptions {
    /// The defaults for displaced grids: radii relative to their grid's root, a wide
    /// top-level BVH and tight headers. Their values already hold 11 bits, so `f32` radii buy
    /// them no speed; and the top level is the largest part left (docs/RESULTS.md,
    /// "Displaced micro-meshes", measures each).
    pub fn for_displaced() -> GridOptions {
        GridOptions {
            radii: RadiusFormat::Relative,
            top: TopFormat::Wide,
            tight_headers: true,
            ..GridOptions::default()
        }
    }
}

/// Everything the grid traversal reads, as uploaded.
#[derive(Clone, Debug, PartialEq)]
pub struct GridScene {
    pub nodes: Vec<BvhNode>,
    /// One packed header per grid, or two wide ones (see `GridParams::wide_headers`).
    pub headers: Vec<GridHeader>,
    /// Words: each grid's inner area (`f32` triples or 16-bit codes), then the edge and corner
    /// areas as `f32` triples (see `gridrt_shared::grid_traverse::GridScene`).
    pub vertices: Vec<u32>,
    /// Sphere radii (see `GridParams::radius_format`); then the leaves' thickness codes (see
    /// `GridParams::thickness_word`).
    pub radii: Vec<u32>,
    pub params: GridParams,
    /// `base_triangle[slot]`: which base triangle the grid stored at `slot` is.
    pub base_triangle: Vec<u32>,
}

impl GridScene {
    /// The top-level BVH as the traversal searches it, full, compact or wide (binary nodes are
    /// also read one by one through it; wide ones only by its search).
    pub fn top(&self) -> TopNodes<&[BvhNode]> {
        TopNodes::new(self.nodes.as_slice())
    }

    /// Nodes of the top-level BVH (not elements of its buffer, which hold two compact ones, or
    /// half a wide one).
    pub fn top_node_count(&self) -> u32 {
        match self.nodes.first() {
            Some(header) if header.count == COMPACT || header.count == WIDE => header.first,
            _ => self.nodes.len() as u32,
        }
    }

    /// Whether the top-level BVH is wide (see [`wide_top`]).
    pub fn has_wide_top(&self) -> bool {
        self.nodes.first().is_some_and(|header| header.count == WIDE)
    }

    /// The box around every grid, as the top level's root holds it.
    pub fn bounds(&self) -> Aabb {
        if self.has_wide_top() {
            return wide_top::bounds(&self.nodes);
        }
        let root = self.top().load(0);
        Aabb {
            min: root.min.into(),
            max: root.max.into(),
        }
    }

    /// The most grids any leaf of the top-level BVH holds (at least 1).
    pub fn leaf_size(&self) -> u32 {
        if self.has_wide_top() {
            return wide_top::leaf_size(&self.nodes);
        }
        let top = self.top();
        (0..self.top_node_count())
            .map(|i| top.load(i).count)
            .max()
            .unwrap_or(0)
            .max(1)
    }

    /// The scene as the traversal reads it.
    pub fn view(&self) -> gridrt_shared::grid_traverse::GridScene<'_, &[GridHeader], &[u32]> {
        gridrt_shared::grid_traverse::GridScene {
            headers: self.headers.as_slice(),
            vertices: self.vertices.as_slice(),
            radii: self.radii.as_slice(),
            micro_triangles: &gridrt_shared::grid_index::MICRO_TRIANGLES,
            params: self.params,
        }
    }

    /// The scene as the traversal reads it under `params` (this scene's, with a frame's level
    /// of detail).
    pub fn view_as(&self, params: GridParams) -> gridrt_shared::grid_traverse::GridScene<'_, &[GridHeader], &[u32]> {
        gridrt_shared::grid_traverse::GridScene { params, ..self.view() }
    }

    /// Number of grids (base triangles).
    pub fn grid_count(&self) -> usize {
        self.base_triangle.len()
    }

    /// The same scene with every grid's ids in a wide header, the form a mesh with more than
    /// `2^21` base edges or vertices gets: for trying that form on small meshes.
    pub fn with_wide_headers(mut self) -> GridScene {
        if self.params.wide_headers == 0 {
            let view = self.view();
            let mut headers: Vec<GridHeader> = (0..self.grid_count() as u32)
                .flat_map(|g| view.ids(g).pack_wide())
                .collect();
            // Grids of mixed levels keep their level bytes, after the new headers.
            if self.params.level_element != 0 {
                let levels = &self.headers[self.params.level_element as usize..];
                self.params.level_element = headers.len() as u32;
                headers.extend_from_slice(levels);
            }
            self.headers = headers;
            self.params.wide_headers = 1;
            self.params.header_bits = 0;
        }
        self
    }

    /// Renders depth `lod` instead of the full depth (no rebuild).
    pub fn set_lod(&mut self, lod: u32) -> Result<()> {
        if lod > self.params.levels {
            fail!(
                Options,
                "level of detail {lod} is deeper than the {} levels built",
                self.params.levels
            );
        }
        self.params.lod = lod;
        Ok(())
    }

    /// Maps a hit's primitive id to `base triangle * 4^lod + micro-triangle`, the numbering of
    /// [`Subdivided::micro_triangles`].
    pub fn micro_triangle_id(&self, prim: u32) -> u32 {
        let per_grid = triangle_count(self.params.lod);
        self.base_triangle[(prim / per_grid) as usize] * per_grid + prim % per_grid
    }

    /// Bytes of each uploaded part.
    pub fn memory(&self) -> Vec<(&'static str, usize)> {
        let mut parts = self.vertex_memory();
        parts.insert(0, ("headers", std::mem::size_of_val(self.headers.as_slice())));
        parts.insert(0, ("top_bvh", std::mem::size_of_val(self.nodes.as_slice())));
        let leaf_words = match self.params.own_rooms {
            0 => self.radii.len() - self.params.thickness_word as usize,
            _ => self
                .own_levels()
                .map(|own| self.params.own_room(own).leaf_words as usize)
                .sum(),
        };
        parts.extend([
            ("sphere_radii", (self.radii.len() - leaf_words) * 4),
            (
                match self.params.leaf_pairs() {
                    true => "leaf_radii_and_thickness",
                    false => "leaf_thickness",
                },
                leaf_words * 4,
            ),
        ]);
        parts
    }

    /// Each grid's own level, in leaf order, where the grids are of mixed levels (see
    /// `GridParams::level_element`).
    fn own_levels(&self) -> impl Iterator<Item = u32> + '_ {
        let element = (self.params.level_element as usize).min(self.headers.len());
        let bytes: &[u8] = bytemuck::cast_slice(&self.headers[element..]);
        bytes.iter().take(self.grid_count()).map(|&b| b as u32 >> 3)
    }

    /// Bytes of the vertex buffer's areas.
    fn vertex_memory(&self) -> Vec<(&'static str, usize)> {
        let inner = self.params.edge_word as usize;
        if self.params.displaced != 0 {
            let base = self.params.base_word as usize;
            let table = (self.grid_count() * self.params.block_offset_bits as usize).div_ceil(32);
            let mut parts = vec![
                ("inner_values", (inner - table) * 4),
                ("edge_and_corner_values", (base - inner) * 4),
                ("base_vertices", (self.vertices.len() - base) * 4),
            ];
            if table > 0 {
                parts.insert(1, ("value_block_table", table * 4));
            }
            return parts;
        }
        let edge = ((self.params.corner_offset - self.params.edge_offset) * 3) as usize;
        let corner = self.vertices.len() - inner - edge;
        vec![
            ("inner_vertices", inner * 4),
            ("edge_vertices", edge * 4),
            ("corner_vertices", corner * 4),
        ]
    }
}

/// Top-level builder settings: opening a grid and testing its first spheres costs about four
/// node visits, so the SAH weighs grids as such; a leaf may still hold a few grids where that
/// pays. (Against weighing them as one node visit: 3 to 4% fewer traversal instructions for
/// 0.3 to 0.4 B per micro-triangle; see docs/RESULTS.md.) Kept within the binary top-level
/// walk's stack, which a wide top level's collapse starts from.
pub fn top_level_params() -> BuildParams {
    BuildParams {
        max_leaf_size: 4,
        max_depth: BINARY_TOP_STACK - 2,
        traversal_cost: 1.0,
        intersection_cost: 4.0,
    }
}

/// What both builds settle before any vertex is computed: depths, vertex areas and formats.
#[derive(Copy, Clone, Debug)]
pub struct GridShape {
    pub levels: u32,
    pub leaf_level: u32,
    pub radii: RadiusFormat,
    pub top: TopFormat,
    pub leaf_footprint: bool,
    pub own_rooms: bool,
    pub edge_offset: u32,
    pub corner_offset: u32,
    /// Inner vertices as 16-bit codes (`gridrt_shared::quantize`) rather than `f32` triples.
    pub quantized_inner: bool,
    /// Words of one grid's inner area (none for compressed values, whose grid blocks differ
    /// in length: see `block_offset_bits`).
    pub inner_words: u32,
    /// Word of the vertex buffer where the inner areas end.
    pub edge_word: u32,
    /// Ids stored as plain words, two headers per grid (more than `2^21` base edges or
    /// vertices), rather than packed in one.
    pub wide_headers: bool,
    /// `GridParams::header_bits`: nonzero for tight headers.
    pub header_bits: u32,
    /// Word of the base vertex records of displaced grids (see [`displaced`]); 0 otherwise.
    pub base_word: u32,
    /// For displaced grids of compressed values: their base edges' code, the bit where the
    /// corner values begin and the bits of each entry of the grid blocks' table (see
    /// [`compressed`]).
    pub value_code: Option<ValueCode>,
    pub corner_bit: u32,
    pub block_offset_bits: u32,
}

impl GridShape {
    fn new(base: &Mesh, edges: usize, levels: u32, options: &GridOptions, quantized: bool) -> GridShape {
        let grids = base.triangles.len();
        let inner_count = inner_vertex_count(levels);
        let edge_offset = grids as u32 * inner_count;
        let wide_headers = needs_wide_headers(edges as u64, base.positions.len() as u64);
        let inner_words = match quantized {
            true => quantize::inner_words(inner_count),
            false => 3 * inner_count,
        };
        GridShape {
            levels,
            leaf_level: levels.saturating_sub(options.excluded_levels),
            radii: options.radii,
            top: options.top,
            leaf_footprint: options.leaf_footprint,
            own_rooms: options.own_rooms,
            edge_offset,
            corner_offset: edge_offset + edges as u32 * edge_vertex_count(levels),
            quantized_inner: quantized,
            inner_words,
            edge_word: grids as u32 * inner_words,
            wide_headers,
            header_bits: match options.tight_headers && !wide_headers {
                true => id_bits(edges as u64) | id_bits(base.positions.len() as u64) << 8,
                false => 0,
            },
            base_word: 0,
            value_code: None,
            corner_bit: 0,
            block_offset_bits: 0,
        }
    }

    /// The parameters that decide how the radii are laid out, as the traversal reads them:
    /// the rule is `GridParams`' alone.
    fn radius_params(&self) -> GridParams {
        GridParams {
            levels: self.levels,
            radius_format: self.radii.code(),
            leaf_footprint: self.leaf_footprint as u32,
            leaf_level: self.leaf_level,
            sphere_count: sphere_count(self.leaf_level),
            ..Default::default()
        }
    }

    /// Whether each leaf's byte holds its radius and its thickness (see
    /// `GridParams::leaf_pairs`).
    fn leaf_pairs(&self) -> bool {
        self.radius_params().leaf_pairs()
    }

    /// Spheres per grid in the radius area (see `GridParams::stored_spheres`).
    fn stored_spheres(&self) -> u32 {
        self.radius_params().stored_spheres()
    }

    /// Words of the vertex buffer as uploaded, for `corners` base vertices: the inner areas,
    /// then the edge and corner areas as `f32` triples.
    fn buffer_words(&self, grids: usize, corners: usize) -> usize {
        grids * self.inner_words as usize + 3 * (self.corner_offset - self.edge_offset) as usize + 3 * corners
    }

    /// Where grid `g` with ids `ids` finds its vertices, as the GPU resolves it.
    #[inline]
    fn slots(&self, ids: &GridIds, g: usize) -> GridSlots {
        GridSlots::new(
            ids,
            g as u32,
            grid_size(self.levels),
            inner_vertex_count(self.levels),
            self.edge_offset,
            self.corner_offset,
        )
    }
}

/// The grids as subdivision hands them over, in base-triangle order: their ids and the three
/// vertex areas, but no acceleration structure yet.
#[derive(Clone, Debug)]
pub struct GridLayout {
    pub shape: GridShape,
    pub ids: Vec<GridIds>,
    /// Inner area (grid after grid), edge area, corner area: every position, decoded.
    pub vertices: Vec<Vec3>,
    /// Each grid's inner area as stored, grid after grid in base-triangle order.
    pub inner_by_grid: Vec<u32>,
    /// For compressed values, the grids' blocks instead (`inner_by_grid` is then empty).
    pub value_blocks: Option<value_tables::GridBlocks>,
    /// The vertex buffer as uploaded: room for the inner areas (filled in leaf order by the
    /// build), then the edge and corner areas, which never move.
    pub buffer: Vec<u32>,
    /// For displaced grids of mixed levels, each grid's own level and decimated edges (see
    /// `GridParams::level_element`); empty otherwise.
    pub own_levels: Vec<u8>,
}

impl GridLayout {
    /// Where grid `g` finds its vertices, resolved from its ids as the GPU resolves them.
    #[inline]
    fn slots(&self, g: usize) -> GridSlots {
        self.shape.slots(&self.ids[g], g)
    }
}

/// The base mesh's edges as the grids share them: each undirected edge gets an id (in the
/// order the triangles first use them), and the first grid to use it owns it, which is the
/// grid that stores its vertices.
struct BaseEdges {
    /// Each grid's three edge ids, edge `e` running from corner `e` to corner `e + 1`.
    of_grid: Vec<[u32; 3]>,
    /// `(grid, edge within grid)` of each edge's owner, by edge id; owners never decrease.
    owner: Vec<(usize, usize)>,
}

impl BaseEdges {
    fn new(base: &Mesh) -> BaseEdges {
        let mut ids: HashMap<(u32, u32), u32> = HashMap::with_capacity(base.triangles.len() * 3 / 2 + 16);
        let mut owner = Vec::new();
        let of_grid = base
            .triangles
            .iter()
            .enumerate()
            .map(|(g, t)| {
                std::array::from_fn(|e| {
                    *ids.entry(base_edge(t, e)).or_insert_with(|| {
                        owner.push((g, e));
                        owner.len() as u32 - 1
                    })
                })
            })
            .collect();
        BaseEdges { of_grid, owner }
    }

    fn ids(&self, base: &Mesh) -> Vec<GridIds> {
        self.of_grid
            .iter()
            .zip(&base.triangles)
            .map(|(&edges, &corners)| GridIds { edges, corners })
            .collect()
    }
}

/// Bits an id below `count` needs (at least one).
fn id_bits(count: u64) -> u32 {
    u64::BITS - (count.max(2) - 1).leading_zeros()
}

/// Header elements of `grids` tight headers of `header_bits` (see `GridParams::header_bits`),
/// including the element after the last grid's first, which its read also loads.
fn tight_header_elements(grids: u64, header_bits: u32) -> u64 {
    let bits = grids * 3 * ((header_bits & 0xff) + (header_bits >> 8)) as u64;
    bits.div_ceil(128) + 1
}

/// The ids of the grids `order` names, in that order, as tight headers.
fn tight_headers(ids: &[GridIds], order: &[u32], header_bits: u32) -> Vec<GridHeader> {
    let (edge_bits, corner_bits) = (header_bits & 0xff, header_bits >> 8);
    let mut out = BitWriter::default();
    for &g in order {
        let grid = &ids[g as usize];
        grid.edges.iter().for_each(|&e| out.push(e, edge_bits));
        grid.corners.iter().for_each(|&c| out.push(c, corner_bits));
    }
    let mut words = out.words;
    words.resize(4 * tight_header_elements(order.len() as u64, header_bits) as usize, 0);
    words
        .chunks(4)
        .map(|w| GridHeader {
            edges: [w[0], w[1]],
            corners: [w[2], w[3]],
        })
        .collect()
}

/// Whether a mesh's grid ids need wide headers: packed ones hold `2^21` edges and vertices.
pub fn needs_wide_headers(edges: u64, vertices: u64) -> bool {
    let packed = MAX_HEADER_ID as u64 + 1;
    edges > packed || vertices > packed
}

/// Refuses, with the reason, a mesh whose grids the layout cannot address: sphere and leaf
/// depths, 32-bit primitive and header ids, and vertex words below 2^31. From counts alone,
/// so it runs before the long subdivision; returns the scene's buffer sizes: exact, but for
/// the top-level BVH's, bounded below by its leaves of at most four grids.
pub fn check_limits(base: &Mesh, build: &GridBuild) -> Result<Vec<BufferSize>> {
    let edges = base_edge_count(base);
    check_counts(base, edges, build.levels, &build.options, build.quantized)?;
    Ok(least_buffer_sizes(base, edges, build))
}

/// The sizes of a grid scene's buffers from counts alone, in the order of
/// `crate::split::scene_buffers`: exact but for the top-level BVH's, whose node count is only
/// bounded below until it is built. `edges` base edges; the counts are within
/// [`check_limits`].
fn least_buffer_sizes(base: &Mesh, edges: u64, build: &GridBuild) -> Vec<BufferSize> {
    let shape = GridShape::new(base, edges as usize, build.levels, &build.options, build.quantized);
    let grids = base.triangles.len() as u64;
    let spheres = sphere_count(shape.leaf_level) as u64;
    let leaves = if shape.leaf_footprint {
        triangle_count(shape.leaf_level) as u64
    } else {
        0
    };
    let radius_words = match shape.radii {
        RadiusFormat::F32 => grids * spheres,
        RadiusFormat::Half => (grids * spheres).div_ceil(2),
        RadiusFormat::Relative => grids * relative_radius_words(shape.stored_spheres()) as u64,
    };
    let size = |name, bytes| BufferSize {
        name,
        bytes,
        at_least: false,
    };
    vec![
        BufferSize {
            at_least: true,
            ..size(
                "top-level BVH",
                top_level_bytes(bvh::least_node_count(grids, &top_level_params()), &shape),
            )
        },
        size(
            "grid header",
            match (shape.header_bits, shape.wide_headers) {
                (0, wide) => grids * if wide { 32 } else { 16 },
                (bits, _) => 16 * tight_header_elements(grids, bits),
            },
        ),
        size(
            "grid vertex",
            4 * shape.buffer_words(grids as usize, base.positions.len()) as u64,
        ),
        size("sphere radius", 4 * (radius_words + grids * leaves.div_ceil(4))),
    ]
}

/// [`check_limits`] with the number of base edges known.
fn check_counts(base: &Mesh, edges: u64, levels: u32, options: &GridOptions, quantized: bool) -> Result<()> {
    let leaf_level = levels.saturating_sub(options.excluded_levels);
    if leaf_level > MAX_SPHERE_LEVEL {
        fail!(
            Limits,
            "a sphere hierarchy of {} levels is deeper than the traversal supports ({})",
            leaf_level + 1,
            MAX_SPHERE_LEVEL + 1
        );
    }
    // Leaves under a sphere level are tested with their siblings, as one leaf of their parent
    // a level deeper (see `GridScene::intersect_grid`).
    let deepest_test = levels - leaf_level + (leaf_level > 0) as u32;
    if deepest_test > gridrt_shared::grid_index::MAX_LEAF_DEPTH {
        fail!(
            Limits,
            "leaves of {} micro-triangles{} are more than the static index list holds ({}); leave out \
             at most {} sphere levels, or all of them",
            triangle_count(levels - leaf_level),
            if leaf_level > 0 { ", tested four at a time," } else { "" },
            triangle_count(gridrt_shared::grid_index::MAX_LEAF_DEPTH),
            gridrt_shared::grid_index::MAX_LEAF_DEPTH - 1
        );
    }
    let grids = base.triangles.len() as u64;
    if grids * triangle_count(levels) as u64 >= u32::MAX as u64 {
        fail!(
            Limits,
            "{grids} grids of {} micro-triangles overflow 32-bit primitive ids; use fewer --levels",
            triangle_count(levels)
        );
    }
    let vertices = base.positions.len() as u64;
    if vertices.max(edges) > u32::MAX as u64 {
        fail!(
            Limits,
            "{vertices} base vertices and {edges} base edges overflow 32-bit grid header ids"
        );
    }
    let inner_count = inner_vertex_count(levels) as u64;
    let inner_words = if quantized {
        quantize::inner_words(inner_count as u32) as u64
    } else {
        3 * inner_count
    };
    // The vertex buffer: the inner areas, then the base vertices and those inside base edges
    // as `f32` triples. Its word addresses sit below a flag bit (2^31), which marks the half
    // addresses of 16-bit inner codes.
    let inner_area = grids * inner_words;
    let words = inner_area + 3 * (vertices + edges * edge_vertex_count(levels) as u64);
    if words >= 1 << 31 || (quantized && 2 * inner_area >= 1 << 31) {
        fail!(
            Limits,
            "{grids} grids of {} micro-triangles need {} of vertices, more than a grid scene can \
             address (8 GiB, of which 4 GiB of 16-bit inner codes); use fewer --levels",
            triangle_count(levels),
            crate::limits::human(4 * words)
        );
    }
    Ok(())
}

/// Edge `e` of triangle `t`, undirected: from its lower to its higher vertex id.
fn base_edge(t: &[u32; 3], e: usize) -> (u32, u32) {
    let (a, b) = (t[e], t[(e + 1) % 3]);
    (a.min(b), a.max(b))
}

/// Undirected edges of a triangle mesh.
fn base_edge_count(base: &Mesh) -> u64 {
    let mut edges = std::collections::HashSet::with_capacity(base.triangles.len() * 3 / 2 + 16);
    for t in &base.triangles {
        edges.extend((0..3).map(|e| base_edge(t, e)));
    }
    edges.len() as u64
}

/// Lays out the grids of `sub` (subdivided from `base`): shared edge and corner vertices
/// stored once.
pub fn layout(base: &Mesh, sub: &Subdivided, options: &GridOptions) -> Result<GridLayout> {
    let levels = sub.levels;
    let grids = base.triangles.len();
    let n = grid_size(levels);
    let edges = BaseEdges::new(base);
    let quantized = sub.inner_codes.is_some();
    check_counts(base, edges.owner.len() as u64, levels, options, quantized)?;
    let shape = GridShape::new(base, edges.owner.len(), levels, options, quantized);

    let mut vertices: Vec<Vec3> = Vec::with_capacity(shape.corner_offset as usize + base.positions.len());
    for g in 0..grids {
        vertices.extend(inner_points(n).map(|p| sub.positions[sub.vertex(g, p) as usize]));
    }
    for &(g, e) in &edges.owner {
        let t = base.triangles[g];
        vertices.extend(edge_points(&t, e, n).map(|p| sub.positions[sub.vertex(g, p) as usize]));
    }
    // Base vertex v stays vertex v through subdivision (at its moved position).
    vertices.extend_from_slice(&sub.positions[..base.positions.len()]);
    let inner_by_grid = match &sub.inner_codes {
        Some(codes) => codes.clone(),
        None => vertices[..shape.edge_offset as usize]
            .iter()
            .flat_map(|v| v.to_array().map(f32::to_bits))
            .collect(),
    };
    let inner_end = grids * shape.inner_words as usize;
    let mut buffer = vec![0u32; shape.buffer_words(grids, base.positions.len())];
    for (d, v) in buffer[inner_end..]
        .chunks_mut(3)
        .zip(&vertices[shape.edge_offset as usize..])
    {
        d.copy_from_slice(&v.to_array().map(f32::to_bits));
    }
    Ok(GridLayout {
        shape,
        ids: edges.ids(base),
        vertices,
        inner_by_grid,
        value_blocks: None,
        buffer,
        own_levels: Vec::new(),
    })
}

/// Lays out and builds in one go.
pub fn build(base: &Mesh, sub: &Subdivided, options: &GridOptions) -> Result<GridScene> {
    Ok(build_from_layout(&mut layout(base, sub, options)?))
}

/// Grids one parallel task handles at least: below that, handing work to another thread
/// costs more than it saves.
const GRIDS_PER_TASK: usize = 128;

/// The grid representation's build proper, what `stats` and `bench` time: grid bounds and
/// sphere radii, the top-level BVH, and the grids' inner areas, headers and radii in its leaf
/// order. The edge and corner areas stay where the layout put them.
///
/// The layout's vertex buffer moves into the result (its edge and corner areas are final);
/// the rest of it is left to the caller, so freeing it is not part of the build.
pub fn build_from_layout(layout: &mut GridLayout) -> GridScene {
    let grids = layout.ids.len();
    let mut vertices = std::mem::take(&mut layout.buffer);
    let layout = &*layout;
    let shape = &layout.shape;
    // Grids of mixed levels each get a hierarchy of their own level, where the radii's
    // layout allows records of different lengths.
    let own_rooms = own_rooms(shape, &layout.own_levels);
    let leaf_level_of = |g: usize| own_rooms.as_ref().map_or(shape.leaf_level, |rooms| rooms[g].leaf_level);
    let tables: Vec<Option<SphereTable>> = (0..=shape.leaf_level)
        .map(|l| (own_rooms.is_some() || l == shape.leaf_level).then(|| SphereTable::new(shape.levels, l)))
        .collect();
    // One pass over each grid's vertices gives its box, its radii and its leaves' thicknesses.
    let mut per_grid = PerGrid::new(grids, shape);
    per_grid
        .tasks()
        .into_par_iter()
        .for_each_init(Vec::new, |points, mut task| {
            for (i, g) in task.grids.clone().enumerate() {
                let leaf_level = leaf_level_of(g);
                let table = tables[leaf_level as usize]
                    .as_ref()
                    .expect("a table for every leaf level used");
                let (bounds, radii, thickness) = task.grid(i);
                let radii = &mut radii[..sphere_count(leaf_level) as usize];
                let thickness = &mut thickness[..leaves_with_bytes(shape, leaf_level)];
                *bounds = grid_bounds_and_radii(layout, table, g, radii, thickness, points);
            }
        });
    vertices[..layout.inner_by_grid.len()].copy_from_slice(&layout.inner_by_grid);
    let mut scene = assemble(shape, &layout.ids, &per_grid, vertices);
    append_own_levels(&mut scene, &layout.own_levels);
    if let Some(rooms) = &own_rooms {
        lay_out_own_rooms(&mut scene, shape, &per_grid, rooms);
    }
    if let Some(blocks) = &layout.value_blocks {
        blocks.write(&scene.base_triangle, &mut scene.vertices);
    }
    scene
}

/// Per grid, in base-triangle order: its box, its spheres' radii and its leaves' thickness
/// codes, as the pass over its vertices finds them.
struct PerGrid {
    boxes: Vec<Aabb>,
    radii: Vec<f32>,
    thickness: Vec<u8>,
    spheres: usize,
    /// Leaves with a thickness code (none without footprints).
    leaves: usize,
    /// Bytes of thickness codes per grid: whole words, and at least one byte, since chunks
    /// cannot be empty.
    leaf_bytes: usize,
}

/// `GRIDS_PER_TASK` grids' part of a [`PerGrid`], for one parallel task.
struct PerGridTask<'a> {
    grids: std::ops::Range<usize>,
    boxes: &'a mut [Aabb],
    radii: &'a mut [f32],
    thickness: &'a mut [u8],
    spheres: usize,
    leaves: usize,
    leaf_bytes: usize,
}

/// Leaves with a thickness code in a hierarchy whose leaves are at `leaf_level` (none
/// without footprints).
fn leaves_with_bytes(shape: &GridShape, leaf_level: u32) -> usize {
    match shape.leaf_footprint {
        true => triangle_count(leaf_level) as usize,
        false => 0,
    }
}

impl PerGrid {
    fn new(grids: usize, shape: &GridShape) -> PerGrid {
        let spheres = sphere_count(shape.leaf_level) as usize;
        let leaves = leaves_with_bytes(shape, shape.leaf_level);
        let leaf_bytes = (leaves.div_ceil(4) * 4).max(1);
        PerGrid {
            boxes: vec![Aabb::EMPTY; grids],
            radii: vec![0f32; grids * spheres],
            thickness: vec![0u8; grids * leaf_bytes],
            spheres,
            leaves,
            leaf_bytes,
        }
    }

    fn tasks(&mut self) -> Vec<PerGridTask<'_>> {
        let (spheres, leaves, leaf_bytes) = (self.spheres, self.leaves, self.leaf_bytes);
        self.boxes
            .chunks_mut(GRIDS_PER_TASK)
            .zip(self.radii.chunks_mut(GRIDS_PER_TASK * spheres))
            .zip(self.thickness.chunks_mut(GRIDS_PER_TASK * leaf_bytes))
            .enumerate()
            .map(|(k, ((boxes, radii), thickness))| PerGridTask {
                grids: k * GRIDS_PER_TASK..k * GRIDS_PER_TASK + boxes.len(),
                boxes,
                radii,
                thickness,
                spheres,
                leaves,
                leaf_bytes,
            })
            .collect()
    }
}

impl PerGridTask<'_> {
    /// The box, radii and thickness codes of the task's `i`-th grid.
    fn grid(&mut self, i: usize) -> (&mut Aabb, &mut [f32], &mut [u8]) {
        (
            &mut self.boxes[i],
            &mut self.radii[i * self.spheres..][..self.spheres],
            &mut self.thickness[i * self.leaf_bytes..][..self.leaves],
        )
    }
}

/// What both builds end with: the top-level BVH over the grids' boxes, then every per-grid
/// part in its leaf order, so leaves name contiguous ranges and need no indirection.
/// `vertices` holds the inner areas in base-triangle order, reordered where they lie.
fn assemble(shape: &GridShape, ids: &[GridIds], per_grid: &PerGrid, mut vertices: Vec<u32>) -> GridScene {
    let grids = ids.len();
    let top = top_level(shape, &per_grid.boxes);
    let words = shape.inner_words as usize;
    reorder_records(&mut vertices[..grids * words], words, &top.order);

    let spheres = per_grid.spheres;
    let leaf_words = per_grid.leaves.div_ceil(4);
    let sphere_words = match shape.radii {
        RadiusFormat::F32 => spheres,
        RadiusFormat::Half => 0,
        RadiusFormat::Relative => relative_radius_words(shape.stored_spheres()) as usize,
    };
    let header_stride = if shape.wide_headers { 2 } else { 1 };
    let mut leaf_headers = vec![GridHeader::default(); grids * header_stride];
    let mut radii = vec![0u32; grids * (sphere_words + leaf_words)];
    let (radius_area, thickness_area) = radii.split_at_mut(grids * sphere_words);
    let tasks: Vec<_> = top
        .order
        .chunks(GRIDS_PER_TASK)
        .zip(leaf_headers.chunks_mut(GRIDS_PER_TASK * header_stride))
        .zip(chunks_or_empty(radius_area, sphere_words))
        .zip(chunks_or_empty(thickness_area, leaf_words))
        .collect();
    tasks.into_par_iter().for_each(|(((order, into), radii), thickness)| {
        for (i, &g) in order.iter().enumerate() {
            let g = g as usize;
            // Tight headers are packed after, end to end across grids.
            match (shape.header_bits, shape.wide_headers) {
                (0, true) => into[2 * i..][..2].copy_from_slice(&ids[g].pack_wide()),
                (0, false) => into[i] = ids[g].pack(),
                _ => {}
            }
            let grid_spheres = GridSpheres {
                radii: &per_grid.radii[g * spheres..][..spheres],
                leaves: per_grid.leaves,
                bytes: &per_grid.thickness[g * per_grid.leaf_bytes..][..leaf_words * 4],
            };
            let into = &mut radii[i * sphere_words..][..sphere_words];
            let leaf_bytes = &mut thickness[i * leaf_words..][..leaf_words];
            grid_spheres.encode(shape.radii, shape.leaf_pairs(), into, leaf_bytes);
        }
    });
    let radius_scale = radius_scale(per_grid.radii.iter().fold(0f32, |m, &r| m.max(r)));
    if shape.radii == RadiusFormat::Half {
        // Two radii to a word, across grid boundaries: packed in one go, in leaf order.
        let half: Vec<u32> = top
            .order
            .iter()
            .flat_map(|&g| &per_grid.radii[g as usize * spheres..][..spheres])
            .collect::<Vec<_>>()
            .chunks(2)
            .map(|pair| {
                let lo = encode_radius(*pair[0], radius_scale) as u32;
                let hi = pair.get(1).map_or(0, |&&r| encode_radius(r, radius_scale) as u32);
                lo | (hi << 16)
            })
            .collect();
        radii.splice(0..0, half);
    }
    let thickness_word = (radii.len() - grids * leaf_words) as u32;
    if shape.header_bits != 0 {
        leaf_headers = tight_headers(ids, &top.order, shape.header_bits);
    }
    GridScene {
        nodes: top.nodes,
        headers: leaf_headers,
        vertices,
        radii,
        params: grid_params(shape, spheres, radius_scale, thickness_word),
        base_triangle: top.order,
    }
}

/// The grids' top level over their boxes, in the shape's format: its nodes, and the order the
/// grids are stored in.
fn top_level(shape: &GridShape, boxes: &[Aabb]) -> Bvh {
    let mut top = bvh::build(boxes, &top_level_params());
    let wide = match shape.top {
        TopFormat::Wide => wide_top::pack(&top),
        _ => None,
    };
    if let Some(wide) = &wide {
        top.order = wide.order.iter().map(|&k| top.order[k as usize]).collect();
    }
    let nodes = match (wide, shape.top) {
        (Some(wide), _) => wide.nodes,
        (None, TopFormat::Full) => top.nodes,
        (None, _) => compact_top::pack(&top.nodes).unwrap_or(top.nodes),
    };
    Bvh {
        nodes,
        order: top.order,
    }
}

/// The parameters the traversal reads grids of `shape` with.
fn grid_params(shape: &GridShape, spheres: usize, radius_scale: f32, thickness_word: u32) -> GridParams {
    GridParams {
        levels: shape.levels,
        lod: shape.levels,
        leaf_level: shape.leaf_level,
        sphere_count: spheres as u32,
        inner_count: inner_vertex_count(shape.levels),
        edge_offset: shape.edge_offset,
        corner_offset: shape.corner_offset,
        quantized_inner: shape.quantized_inner as u32,
        inner_words: shape.inner_words,
        edge_word: shape.edge_word,
        radius_format: shape.radii.code(),
        leaf_footprint: shape.leaf_footprint as u32,
        radius_scale,
        thickness_word,
        wide_headers: shape.wide_headers as u32,
        header_bits: shape.header_bits,
        displaced: match (shape.base_word, shape.value_code) {
            (0, _) => 0,
            (_, None) => DISPLACED_PLAIN,
            (_, Some(_)) => DISPLACED_COMPRESSED,
        },
        base_word: shape.base_word,
        value_widths: shape.value_code.map_or(0, |c| c.widths),
        edge_block_bits: shape.value_code.map_or(0, |c| c.edge_block_bits()),
        corner_bit: shape.corner_bit,
        block_offset_bits: shape.block_offset_bits,
        ..Default::default()
    }
}

/// One grid's spheres as the pass over its vertices found them: radii in breadth-first
/// order, and the thickness codes of its `leaves` leaves (`bytes`, in whole words).
struct GridSpheres<'a> {
    radii: &'a [f32],
    leaves: usize,
    bytes: &'a [u8],
}

impl GridSpheres<'_> {
    /// Encoded into the grid's radius words `into` (none for half radii, packed across grids)
    /// and leaf words `leaf_words`, in `format`, the leaves holding their radii in their bytes
    /// where `leaf_pairs` says.
    fn encode(&self, format: RadiusFormat, leaf_pairs: bool, into: &mut [u32], leaf_words: &mut [u32]) {
        for (w, b) in leaf_words.iter_mut().zip(self.bytes.chunks(4)) {
            *w = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        }
        match format {
            RadiusFormat::F32 => into.iter_mut().zip(self.radii).for_each(|(r, &f)| *r = f.to_bits()),
            RadiusFormat::Half => {}
            RadiusFormat::Relative if leaf_pairs => encode_leaf_pairs(self.radii, self.leaves, into, leaf_words),
            RadiusFormat::Relative => {
                encode_relative_radii(self.radii, into);
                rescale_thickness(into, self.radii, self.leaves, leaf_words);
            }
        }
    }
}

/// Each grid's room of its own level (see `GridParams::own_rooms`), in base-triangle order,
/// for grids of mixed levels (`own_levels`, see `GridParams::level_element`) whose rooms and
/// their table take fewer radius words than the scene's room for every grid; `None` where
/// they do not (as when most grids are at the deepest level, 3) or cannot (only relative radii
/// have such rooms).
fn own_rooms(shape: &GridShape, own_levels: &[u8]) -> Option<Vec<OwnRoom>> {
    if !shape.own_rooms || own_levels.is_empty() || shape.radii != RadiusFormat::Relative {
        return None;
    }
    let params = shape.radius_params();
    let words = |room: &OwnRoom| (room.radius_words + room.leaf_words) as usize;
    // The scene's room is a room of the deepest level.
    let scene_room = words(&params.own_room(shape.levels));
    let rooms: Vec<OwnRoom> = own_levels.iter().map(|&own| params.own_room(own as u32 >> 3)).collect();
    let records: usize = rooms.iter().map(words).sum();
    (own_room_table_words(rooms.len()) + records < rooms.len() * scene_room).then_some(rooms)
}

/// Words of the table of `grids` grids' records (see `GridParams::own_rooms`): a word per
/// sixteen grids, and half a word per grid.
fn own_room_table_words(grids: usize) -> usize {
    grids.div_ceil(16) + grids.div_ceil(2)
}

/// Lays the radius buffer out anew for grids of mixed levels, each grid's spheres and leaf
/// bytes at its own level (see `GridParams::own_rooms`; `rooms` in base-triangle order): the
/// table that says where each grid's record begins, then the records, grids in leaf order. A
/// grid coarser than the scene then takes its own level's bytes, and its walk stops at its
/// own leaves, with their thicknesses.
fn lay_out_own_rooms(scene: &mut GridScene, shape: &GridShape, per_grid: &PerGrid, rooms: &[OwnRoom]) {
    let params = shape.radius_params();
    let rooms: Vec<OwnRoom> = scene.base_triangle.iter().map(|&g| rooms[g as usize]).collect();
    let offsets_word = rooms.len().div_ceil(16);
    let table = own_room_table_words(rooms.len());
    let mut radii = vec![0u32; table];
    let mut next = table as u32;
    for (g, room) in rooms.iter().enumerate() {
        if g % 16 == 0 {
            radii[g / 16] = next;
        }
        // Sixteen records of the deepest level decoded take far fewer than 2^16 words.
        let offset = u16::try_from(next - radii[g / 16]).expect("a record offset of 16 bits");
        radii[offsets_word + g / 2] |= (offset as u32) << (16 * (g % 2));
        next += room.radius_words + room.leaf_words;
    }
    radii.resize(next as usize, 0);
    let mut records = &mut radii[table..];
    for (&g, room) in scene.base_triangle.iter().zip(&rooms) {
        let g = g as usize;
        let (record, rest) = records.split_at_mut((room.radius_words + room.leaf_words) as usize);
        records = rest;
        let leaves = leaves_with_bytes(shape, room.leaf_level);
        let spheres = GridSpheres {
            radii: &per_grid.radii[g * per_grid.spheres..][..sphere_count(room.leaf_level) as usize],
            leaves,
            bytes: &per_grid.thickness[g * per_grid.leaf_bytes..][..4 * room.leaf_words as usize],
        };
        let (into, leaf_words) = record.split_at_mut(room.radius_words as usize);
        spheres.encode(shape.radii, params.leaf_pairs_at(room.leaf_level), into, leaf_words);
    }
    scene.radii = radii;
    scene.params.own_rooms = offsets_word as u32;
}

/// Appends to the header buffer a byte per grid of its own level and decimated edges, in leaf
/// order, sixteen to an element, when the grids are of mixed levels (see
/// `GridParams::level_element`).
fn append_own_levels(scene: &mut GridScene, own_levels: &[u8]) {
    if own_levels.is_empty() {
        return;
    }
    scene.params.level_element = scene.headers.len() as u32;
    let bytes: Vec<u8> = scene.base_triangle.iter().map(|&g| own_levels[g as usize]).collect();
    for chunk in bytes.chunks(16) {
        let mut element = [0u8; 16];
        element[..chunk.len()].copy_from_slice(chunk);
        let word = |k: usize| {
            u32::from_le_bytes([
                element[4 * k],
                element[4 * k + 1],
                element[4 * k + 2],
                element[4 * k + 3],
            ])
        };
        scene.headers.push(GridHeader {
            edges: [word(0), word(1)],
            corners: [word(2), word(3)],
        });
    }
}

/// Bytes of a top-level BVH of `nodes` binary nodes in the form `shape` asks for (compact: a
/// header, then two nodes to 32 bytes; wide: a header, then 64 bytes for each node, which
/// holds at least two of the binary nodes' children).
fn top_level_bytes(nodes: u64, shape: &GridShape) -> u64 {
    match shape.top {
        TopFormat::Full => 32 * nodes,
        TopFormat::Compact => 32 * (1 + nodes.div_ceil(2)),
        TopFormat::Wide => 32 + 64 * nodes.div_ceil(2 * WIDTH as u64),
    }
}

/// Puts record `order[i]` at place `i`, records being `words` long, in place: each cycle of
/// the permutation is walked once, holding one record aside. No second copy of the area.
fn reorder_records(data: &mut [u32], words: usize, order: &[u32]) {
    if words == 0 {
        return;
    }
    let mut done = vec![false; order.len()];
    let mut held = vec![0u32; words];
    for start in 0..order.len() {
        if done[start] {
            continue;
        }
        held.copy_from_slice(&data[start * words..][..words]);
        let mut i = start;
        loop {
            done[i] = true;
            let from = order[i] as usize;
            if from == start {
                data[i * words..][..words].copy_from_slice(&held);
                break;
            }
            data.copy_within(from * words..(from + 1) * words, i * words);
            i = from;
        }
    }
}

/// `GRIDS_PER_TASK` grids' worth of `per_grid` items at a time, or endless empty slices when
/// there are none per grid.
fn chunks_or_empty<T>(items: &mut [T], per_grid: usize) -> Box<dyn Iterator<Item = &mut [T]> + '_> {
    if per_grid == 0 {
        Box::new(std::iter::repeat_with(|| &mut [][..]))
    } else {
        Box::new(items.chunks_mut(GRIDS_PER_TASK * per_grid))
    }
}

/// The inner lattice points of edge `e` of a grid over base triangle `t`, in the order the
/// edge area stores them: from the lower base vertex id towards the higher.
fn edge_points(t: &[u32; 3], e: usize, n: u32) -> impl Iterator<Item = Lattice> {
    let t = *t;
    (1..n).map(move |s| stored_edge_point(&t, e, s, n))
}

/// The lattice point `s` steps along edge `e` of a grid over base triangle `t` (of lattice
/// size `n`), counted as a shared edge is stored: from its lower base vertex id, so both
/// grids on the edge name its points alike.
pub(crate) fn stored_edge_point(t: &[u32; 3], e: usize, s: u32, n: u32) -> Lattice {
    let reversed = t[e] > t[(e + 1) % 3];
    edge_point(e as u32, if reversed { n - s } else { s }, n)
}
