//! Every type that crosses the host/GPU boundary, defined once.
//!
//! All fields are 4-byte scalars or arrays of them, so `#[repr(C)]` gives the same offsets in
//! Rust, in the SPIR-V that rust-gpu emits and in std430 storage buffers.

use crate::grid_index::{sphere_count, triangle_count};
#[cfg(not(target_arch = "spirv"))]
use bytemuck::{Pod, Zeroable};

/// Words of one grid's radii stored relative to its root ([`RADII_RELATIVE`]): the
/// root's `f32`, then a byte per other sphere, four to a word.
#[inline]
pub fn relative_radius_words(sphere_count: u32) -> u32 {
    1 + (sphere_count - 1).div_ceil(4)
}

/// One node of a binary BVH (32 bytes). `count == 0`: interior node whose children are
/// `first` and `first + 1`. `count > 0`: leaf over primitives `first .. first + count` of the
/// primitive buffer, which the builder reorders so every leaf is a contiguous range.
#[repr(C)]
#[derive(Copy, Clone, Default)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable, Debug, PartialEq))]
pub struct BvhNode {
    pub min: [f32; 3],
    pub first: u32,
    pub max: [f32; 3],
    pub count: u32,
}

impl BvhNode {
    #[inline]
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }
}

/// Where a grid finds the vertices it shares with its neighbours, as stored (16 bytes).
///
/// Its inner vertices and sphere radii need no pointer: they sit at `grid * inner_count` and
/// `grid * sphere_count` in their areas. What remains are the [`GridIds`] of its three base
/// edges and three corners. Packed, they take 21 bits each, three to a 64-bit pair: one
/// header per grid. A mesh with more than `2^21` base edges or vertices stores them *wide*
/// instead (see `GridParams::wide_headers`): two headers per grid holding the six ids as
/// plain words, `edges[0], edges[1], corners[0]`... in id order (edges, then corners), the
/// last two words unused. Both are whole 16-byte elements, so a split header buffer never
/// cuts a grid's ids in two.
#[repr(C)]
#[derive(Copy, Clone, Default)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable, Debug, PartialEq))]
pub struct GridHeader {
    pub edges: [u32; 2],
    pub corners: [u32; 2],
}

/// Largest base edge or vertex id a packed header can hold, `2^21 - 1`.
pub const MAX_HEADER_ID: u32 = (1 << 21) - 1;

#[inline]
fn unpack21(pair: [u32; 2], i: u32) -> u32 {
    if i == 0 {
        pair[0] & MAX_HEADER_ID
    } else if i == 1 {
        (pair[0] >> 21) | ((pair[1] & 0x3ff) << 11)
    } else {
        (pair[1] >> 10) & MAX_HEADER_ID
    }
}

#[cfg(not(target_arch = "spirv"))]
fn pack21(v: [u32; 3]) -> [u32; 2] {
    assert!(v.iter().all(|&x| x <= MAX_HEADER_ID), "header id beyond 21 bits");
    [v[0] | (v[1] << 21), (v[1] >> 11) | (v[2] << 10)]
}

impl GridHeader {
    /// The ids of a packed header.
    #[inline]
    pub fn ids(&self) -> GridIds {
        GridIds {
            edges: [
                unpack21(self.edges, 0),
                unpack21(self.edges, 1),
                unpack21(self.edges, 2),
            ],
            corners: [
                unpack21(self.corners, 0),
                unpack21(self.corners, 1),
                unpack21(self.corners, 2),
            ],
        }
    }
}

/// A grid's three base edges (ids into the edge area, which holds the `2^L - 1` vertices of
/// each base edge once, from its lower to its higher base vertex id) and three corners (base
/// vertex ids, into the corner area). Edge `e` runs from corner `e` to corner `(e + 1) % 3`;
/// whether the grid walks it backwards follows from the corner ids, so no flag is stored.
#[derive(Copy, Clone, Default)]
#[cfg_attr(not(target_arch = "spirv"), derive(Debug, PartialEq, Eq))]
pub struct GridIds {
    pub edges: [u32; 3],
    pub corners: [u32; 3],
}

impl GridIds {
    /// The ids of a wide header, its two elements in order.
    #[inline]
    pub fn from_wide(first: GridHeader, second: GridHeader) -> Self {
        GridIds {
            edges: [first.edges[0], first.edges[1], first.corners[0]],
            corners: [first.corners[1], second.edges[0], second.edges[1]],
        }
    }

    /// One packed header; every id must fit in 21 bits.
    #[cfg(not(target_arch = "spirv"))]
    pub fn pack(&self) -> GridHeader {
        GridHeader {
            edges: pack21(self.edges),
            corners: pack21(self.corners),
        }
    }

    /// The two elements of a wide header.
    #[cfg(not(target_arch = "spirv"))]
    pub fn pack_wide(&self) -> [GridHeader; 2] {
        let [e0, e1, e2] = self.edges;
        let [c0, c1, c2] = self.corners;
        [
            GridHeader {
                edges: [e0, e1],
                corners: [e2, c0],
            },
            GridHeader {
                edges: [c1, c2],
                corners: [0, 0],
            },
        ]
    }

    /// Base vertex id of corner `c`.
    #[inline]
    pub fn corner(&self, c: u32) -> u32 {
        self.corners[c as usize]
    }

    /// Id of base edge `e`.
    #[inline]
    pub fn edge(&self, e: u32) -> u32 {
        self.edges[e as usize]
    }

    /// Whether edge `e` runs against its stored direction (from its higher vertex id).
    #[inline]
    pub fn edge_reversed(&self, e: u32) -> bool {
        let next = if e == 2 { 0 } else { e + 1 };
        self.corner(e) > self.corner(next)
    }
}

/// Pinhole camera: the ray through pixel centre `(x + 0.5, y + 0.5)` leaves `origin` along
/// `to_top_left + (x + 0.5) / width * horizontal + (y + 0.5) / height * vertical`.
///
/// Every vector but `origin` is relative to the eye, with the image plane one unit away:
/// a pixel's direction is then exact to `f32` rounding of unit-sized numbers wherever the eye
/// is. (A point on the image plane minus the eye would lose the per-pixel offsets once the
/// eye's coordinates are large next to one unit.)
#[repr(C)]
#[derive(Copy, Clone, Default)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable, Debug, PartialEq))]
pub struct Camera {
    pub origin: [f32; 3],
    pub width: u32,
    pub to_top_left: [f32; 3],
    pub height: u32,
    pub horizontal: [f32; 3],
    pub _pad0: u32,
    pub vertical: [f32; 3],
    pub _pad1: u32,
}

/// Shading modes understood by [`crate::shade::shade`].
pub const SHADE_EYE_LIGHT: u32 = 0;
pub const SHADE_NORMAL: u32 = 1;
pub const SHADE_PRIMITIVE: u32 = 2;
pub const SHADE_AMBIENT_OCCLUSION: u32 = 3;
pub const SHADE_DEPTH: u32 = 4;
/// Not a colour: each pixel is the packed [`crate::cost::Costs`] of its primary ray, which the
/// host maps to colours (the cost heat map).
pub const SHADE_COST: u32 = 5;
/// Each grid coloured by the depth it was rendered at (level of detail).
pub const SHADE_LEVEL: u32 = 6;
/// A key light and a sky, both dimmed by ambient occlusion (see [`crate::shade::ao_pixel`]).
pub const SHADE_LIT: u32 = 7;

/// How the grid buffers are to be read; all zero for a triangle scene.
#[repr(C)]
#[derive(Copy, Clone, Default)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable, Debug, PartialEq))]
pub struct GridParams {
    /// Subdivision depth `L` the grids were built at.
    pub levels: u32,
    /// Depth `D <= L` rendered (level of detail); with `lod_auto`, the deepest any grid is
    /// rendered at.
    pub lod: u32,
    /// Deepest level of the sphere hierarchy, `max(L - excluded, 0)`: its sub-triangles are
    /// the leaves whose micro-triangles are tested directly.
    pub leaf_level: u32,
    /// Spheres per grid, `(4^(leaf_level + 1) - 1) / 3`.
    pub sphere_count: u32,
    /// Inner vertices per grid, `(2^L - 1)(2^L - 2) / 2`.
    pub inner_count: u32,
    /// First vertex slot of the edge area (inner slots start at 0).
    pub edge_offset: u32,
    /// First vertex slot of the corner area.
    pub corner_offset: u32,
    /// Inner vertices as 16-bit codes (see [`crate::quantize`]) rather than `f32` triples.
    pub quantized_inner: u32,
    /// Words of each grid's inner area in the vertex buffer.
    pub inner_words: u32,
    /// Word where the edge area (then the corner area, `f32` triples) begins.
    pub edge_word: u32,
    /// How the sphere radii are stored: [`RADII_F32`], [`RADII_HALF`] (in units of
    /// `radius_scale`, a power of two) or [`RADII_RELATIVE`].
    pub radius_format: u32,
    pub radius_scale: f32,
    /// Word of the radius buffer where the leaves' bytes begin, `4^leaf_level` bytes per grid
    /// in whole words, grids in order. Each byte holds the leaf's thickness (see
    /// `crate::footprint`): in `2 / 255`ths of the leaf's radius; or, with relative radii
    /// ([`GridParams::leaf_pairs`]), the leaf's radius in its low four bits (see
    /// `crate::sphere::leaf_radius`) and its thickness in its high four (see
    /// `crate::sphere::leaf_thickness`), and the radius area then holds no leaf radii.
    pub thickness_word: u32,
    /// Whether leaf thicknesses are stored and leaves culled by their footprint.
    pub leaf_footprint: u32,
    /// Whether each grid's ids take two wide headers rather than one packed header (see
    /// [`GridHeader`]).
    pub wide_headers: u32,
    /// Nonzero for tight headers: each grid's six ids in as many bits as the counts need,
    /// `edge_bits | corner_bits << 8`, grids end to end in the header buffer's words (its
    /// elements' four words in order): grid `g`'s three edge ids, then its three corner ids,
    /// from bit `3 g (edge_bits + corner_bits)`, each field least significant bit first.
    pub header_bits: u32,
    /// Whether each grid chooses its own depth from its size on screen (see
    /// [`crate::lod::grid_level`]) rather than every grid rendering depth `lod`.
    pub lod_auto: u32,
    /// The eye that `lod_auto` measures distances from.
    pub lod_eye: [f32; 3],
    /// Pixels per unit of length one unit away from the eye, over the target micro-triangle
    /// size in pixels (`lod_auto`).
    pub lod_scale: f32,
    /// Whether the vertex areas hold 11-bit displacement values (packed end to end, addressed
    /// in bits) rather than positions: each lattice point is then decoded from its base
    /// triangle's corners and directions (see [`crate::displacement`]).
    pub displaced: u32,
    /// Word of the vertex buffer where the base vertices of a displaced scene begin: a
    /// position and a direction, six `f32`, per base vertex.
    pub base_word: u32,
    /// For displaced grids of compressed values ([`DISPLACED_COMPRESSED`]): each level's
    /// correction width on the base edges (see `crate::compressed_values::ValueCode`), the
    /// bits of one base edge's block, the bit where the corner values begin, and the bits of
    /// each entry of the grid blocks' table (see `crate::compressed_values::CodedScene`).
    pub value_widths: u32,
    pub edge_block_bits: u32,
    pub corner_bit: u32,
    pub block_offset_bits: u32,
    /// For displaced grids of mixed levels: the element of the header buffer where a byte per
    /// grid begins, grids in order, four to a word, four words to an element. Its low three
    /// bits are the grid's decimated edges (see `crate::displacement::DECIMATED_EDGES`), the
    /// rest its own level, at most `levels`: the grid holds that level's points of the scene's
    /// lattice, and is rendered at most that deep. Zero when every grid is at `levels` and no
    /// edge is decimated (element 0 is always a header).
    pub level_element: u32,
    /// Nonzero when each grid of mixed levels holds the spheres and leaf bytes of its own
    /// level rather than the scene's (relative radii only, see [`GridParams::own_room`]); then
    /// the word of the radius buffer where the grids' record offsets begin. The buffer opens
    /// with a word per sixteen grids, the word where the first of their records begins, then
    /// holds a 16-bit offset per grid from that word to its own record, two to a word, low half
    /// first, then the records, grids in order. A record is the grid's relative radii (as
    /// [`RADII_RELATIVE`] lays out a grid's) followed by its leaves' bytes (as
    /// [`GridParams::thickness_word`] lays out a grid's), both at its own leaf level.
    /// `thickness_word` is then unused.
    pub own_rooms: u32,
}

/// A grid's record in a room of its own level (see [`GridParams::own_room`]): the deepest
/// level of its sphere hierarchy, and the words of its relative radii and of its leaves' bytes.
#[derive(Copy, Clone)]
pub struct OwnRoom {
    pub leaf_level: u32,
    pub radius_words: u32,
    pub leaf_words: u32,
}

/// [`GridParams::radius_format`]: one `f32` per radius.
pub const RADII_F32: u32 = 0;
/// [`GridParams::radius_format`]: half floats, two to a word, rounded up.
pub const RADII_HALF: u32 = 1;
/// [`GridParams::radius_format`]: per grid, the root's radius as an `f32` word, then a byte
/// per sphere below it, in 255ths of the root's radius, rounded up. A sphere's four children
/// are one word, so a visit reads their radii in one load, and every radius decodes from its
/// own byte and the root's (no chain through the parents). With leaf footprints and at least
/// two sphere levels above the leaves, the leaves' radii are not here but beside their
/// thicknesses, relative to their parents' (see [`GridParams::thickness_word`]): the leaves
/// are most of the spheres, and half a byte each holds them within a sixteenth of their
/// parent's radius.
pub const RADII_RELATIVE: u32 = 2;

/// [`GridParams::displaced`] for grids of plain 11-bit values.
pub const DISPLACED_PLAIN: u32 = 1;
/// [`GridParams::displaced`] for grids of compressed values (see `crate::compressed_values`).
pub const DISPLACED_COMPRESSED: u32 = 2;

impl GridParams {
    /// Whether each leaf's byte holds its radius and its thickness (see
    /// [`Self::thickness_word`]): with relative radii and leaf footprints, from two sphere
    /// levels above the leaves on. (Leaves that are the root's children keep a byte of the
    /// root's radius each: their half-byte radii would test more leaves for four bytes a
    /// grid.)
    #[inline]
    pub fn leaf_pairs(&self) -> bool {
        self.radius_format == RADII_RELATIVE && self.leaf_footprint != 0 && self.leaf_level >= 2
    }

    /// Spheres per grid in the radius area: all of them, or all but the leaves when the
    /// leaves' radii are in their bytes.
    #[inline]
    pub fn stored_spheres(&self) -> u32 {
        self.spheres_in_radius_area(self.leaf_pairs())
    }

    /// Whether leaves at `leaf_level` hold their radii in their bytes: as
    /// [`Self::leaf_pairs`] for a hierarchy that deep.
    #[inline]
    pub fn leaf_pairs_at(&self, leaf_level: u32) -> bool {
        self.radius_format == RADII_RELATIVE && self.leaf_footprint != 0 && leaf_level >= 2
    }

    /// The hierarchy of a grid of level `own` in a room of its own level (see
    /// [`Self::own_rooms`]): its leaf level, the scene's as many levels above `own` as
    /// `leaf_level` is above `levels`, and the words of its record's relative radii and of its
    /// leaves' bytes.
    #[inline]
    pub fn own_room(&self, own: u32) -> OwnRoom {
        // Not `saturating_sub`, which rust-gpu does not compile.
        #[allow(clippy::implicit_saturating_sub)]
        let leaf_level = if own + self.leaf_level > self.levels {
            own + self.leaf_level - self.levels
        } else {
            0
        };
        let spheres = if self.leaf_pairs_at(leaf_level) {
            sphere_count(leaf_level - 1)
        } else {
            sphere_count(leaf_level)
        };
        let leaf_words = if self.leaf_footprint != 0 {
            triangle_count(leaf_level).div_ceil(4)
        } else {
            0
        };
        OwnRoom {
            leaf_level,
            radius_words: relative_radius_words(spheres),
            leaf_words,
        }
    }

    /// Spheres per grid in the radius area of a buffer whose leaves do (`leaf_pairs`) or do
    /// not hold their radii in their bytes.
    #[inline]
    pub fn spheres_in_radius_area(&self, leaf_pairs: bool) -> u32 {
        if leaf_pairs {
            sphere_count(self.leaf_level - 1)
        } else {
            self.sphere_count
        }
    }

    /// Whether the grids use a format made for displaced grids: displacement values, tight
    /// headers or radii relative to each grid's root. (The wide top level is the other one;
    /// the nodes say whether they are wide.) Only kernels that carry these formats read such
    /// scenes (see `crate::buffer::carries::DISPLACED_FORMATS`).
    #[inline]
    pub fn uses_displaced_formats(&self) -> bool {
        self.displaced != 0 || self.header_bits != 0 || self.radius_format == RADII_RELATIVE
    }

    /// Whether every grid's hierarchy is walked by its root's visit alone: its stored leaves
    /// are the root's children or the root itself, as at the default depth `L = 3`. Such
    /// scenes are walked without a stack (see `GridScene::intersect_grid`).
    pub fn one_visit(&self) -> bool {
        self.leaf_level <= 1
    }
}

/// Where a split scene's buffers lie among its chunks (see [`crate::buffer`]): buffer `b`
/// starts at chunk `first_chunk[b]` and holds `len[b]` elements; every chunk but a buffer's
/// last holds `2^chunk_shift` words. Buffers of a grid scene: [`GRID_NODES`],
/// [`GRID_HEADERS`], [`GRID_VERTICES`], [`GRID_RADII`]; of a triangle scene: [`TRIANGLE_NODES`],
/// [`TRIANGLE_POSITIONS`], [`TRIANGLE_INDICES`]. Unused (all zero) when the scene is not split.
#[repr(C)]
#[derive(Copy, Clone, Default)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable, Debug, PartialEq))]
pub struct SplitParams {
    pub chunk_shift: u32,
    pub first_chunk: [u32; 4],
    pub len: [u32; 4],
    pub _pad: [u32; 3],
}

pub const GRID_NODES: usize = 0;
pub const GRID_HEADERS: usize = 1;
pub const GRID_VERTICES: usize = 2;
pub const GRID_RADII: usize = 3;
pub const TRIANGLE_NODES: usize = 0;
pub const TRIANGLE_POSITIONS: usize = 1;
pub const TRIANGLE_INDICES: usize = 2;

/// Everything one dispatch needs besides geometry. A frame is rendered in tiles (each within
/// the GPU's limits on one dispatch and one output buffer): this dispatch renders the
/// `tile_width x tile_height` pixels from `(tile_x, tile_y)` into a buffer of its own.
#[repr(C)]
#[derive(Copy, Clone, Default)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable, Debug, PartialEq))]
pub struct FrameParams {
    pub camera: Camera,
    pub grid: GridParams,
    pub split: SplitParams,
    pub shading: u32,
    pub tile_x: u32,
    pub tile_y: u32,
    pub tile_width: u32,
    pub tile_height: u32,
    /// Ambient occlusion ([`SHADE_AMBIENT_OCCLUSION`]): rays per pixel, how far they look,
    /// and how far off the surface they start.
    pub ao_samples: u32,
    pub ao_distance: f32,
    pub ao_offset: f32,
    /// Depth ([`SHADE_DEPTH`]): the distances from the eye shaded brightest and darkest.
    pub depth_near: f32,
    pub depth_far: f32,
    /// Whether hits are lit with smooth normals (grids: see [`crate::smooth_normal`]) rather
    /// than their micro-triangle's.
    pub smooth_normals: u32,
    /// Progressive ambient occlusion: this pass casts samples `ao_first_sample ..
    /// ao_first_sample + ao_samples` of each pixel, and the pixel is the count of them that
    /// meet nothing (see [`crate::shade::render_pixel`]), or [`AO_MISS`] where the primary ray
    /// misses.
    pub ao_first_sample: u32,
}

/// The pixel of a progressive ambient-occlusion pass whose primary ray hit nothing.
pub const AO_MISS: u32 = u32::MAX;

/// The most ambient-occlusion rays per pixel: their open count fits in [`AO_OPEN_MASK`].
pub const MAX_AO_SAMPLES: u32 = 4096;

/// The bits of an ambient-occlusion pixel that count its open rays; under [`SHADE_LIT`] the
/// bits above hold the lights' cosines at the hit (see [`crate::shade::render_pixel`]).
pub const AO_OPEN_MASK: u32 = (1 << 13) - 1;

/// Primitive id of a miss.
pub const NO_HIT: u32 = u32::MAX;

/// Closest hit found so far. `prim` is the index of the triangle in the (reordered) triangle
/// buffer, or for grids `grid_slot * 4^lod + t * 4^(lod - level)`, `t` the micro-triangle's
/// index (recursion order) among the grid's `4^level`: numbered as at depth `lod` whatever
/// depth the grid was rendered at.
#[repr(C)]
#[derive(Copy, Clone)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable, Debug, PartialEq))]
pub struct Hit {
    pub t: f32,
    pub u: f32,
    pub v: f32,
    pub prim: u32,
    /// Unnormalised geometric normal of the hit triangle.
    pub normal: [f32; 3],
    /// Depth of the grid's micro-triangles the hit is on (0 for the baseline).
    pub level: u32,
}

impl Hit {
    #[inline]
    pub fn miss(t_max: f32) -> Self {
        Hit {
            t: t_max,
            u: 0.0,
            v: 0.0,
            prim: NO_HIT,
            normal: [0.0; 3],
            level: 0,
        }
    }

    #[inline]
    pub fn is_hit(&self) -> bool {
        self.prim != NO_HIT
    }
}

/// Threads per workgroup of the render kernels, in x and y: 32, one wave or warp. A driver may
/// run a larger workgroup of these kernels in 64-wide waves, whose masks and registers take
/// twice the room (RADV does).
pub const RENDER_WORKGROUP: [u32; 2] = [8, 4];

/// One ray to trace (32 bytes): the benchmark traces the same list through both
/// representations.
#[repr(C)]
#[derive(Copy, Clone, Default)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable, Debug, PartialEq))]
pub struct RayRecord {
    pub origin: [f32; 3],
    pub t_max: f32,
    pub dir: [f32; 3],
    pub _pad: u32,
}

/// The closest hit of a [`RayRecord`]: distance and primitive (`NO_HIT` for a miss).
#[repr(C)]
#[derive(Copy, Clone, Default)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable, Debug, PartialEq))]
pub struct HitRecord {
    pub t: f32,
    pub prim: u32,
}

/// Parameters of a ray-list dispatch. Rays are numbered `x + y * threads_per_row` over a 2D
/// grid of workgroups, because one dimension holds at most 65535 of them.
#[repr(C)]
#[derive(Copy, Clone, Default)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable, Debug, PartialEq))]
pub struct TraceParams {
    pub grid: GridParams,
    pub split: SplitParams,
    pub ray_count: u32,
    pub threads_per_row: u32,
    pub _pad: [u32; 2],
}

/// Threads per workgroup of the ray-list kernels: one wave or warp, as [`RENDER_WORKGROUP`].
pub const TRACE_WORKGROUP_SIZE: u32 = 32;
