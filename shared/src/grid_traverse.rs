//! The bottom level: grid primitives searched through their 4-ary sphere hierarchies, nearest
//! sphere first, down to leaves whose micro-triangles the static index list names; under the
//! top-level BVH of [`crate::traverse`].

use crate::bit_fields::read_bits;
use crate::buffer::{carries, element, Buffer, Chunks, KernelWords, Split};
use crate::compressed_values::{CodedGrid, CodedScene, PackedValues, SubLattice, ValueCode};
use crate::cost::Tally;
use crate::displacement::{decimated_grid_point, displaced_point, unorm11_displacement, DisplacedTriangle};
use crate::footprint::FootprintFrame;
use crate::glam::{Vec3, Vec4};
use crate::grid_index::{
    edge_vertex_count, lattice_index, level_start, micro_cell_offset, sub_triangle, triangle_count, vertex_count,
    Lattice, MAX_LEAF_DEPTH,
};
use crate::grid_slots::{GridSlots, LeveledAreas};
use crate::layout::{
    relative_radius_words, GridHeader, GridIds, GridParams, Hit, SplitParams, DISPLACED_COMPRESSED, GRID_HEADERS,
    GRID_RADII, GRID_VERTICES, RADII_HALF, RADII_RELATIVE,
};
use crate::lod::grid_level;
use crate::quantize::{dequantize, halves_from_words, read_half, unit_from_exponent};
use crate::ray::{Ray, T_FAR};
use crate::sphere::{
    byte_thickness, decode_radius, intersect_sphere_scaled, intersect_spheres, leaf_radius, leaf_thickness,
    relative_radius, relative_radius_at,
};
use crate::traverse::{load_vec3_bits, record_hit, LeafPrimitives, TopStack};
use crate::triangle::{intersect_sheared, shear};
use crate::value_tables::{block_bit, leveled_edge, LeveledEdge};

/// Most spheres a grid hierarchy may be deep: levels `0 ..= MAX_SPHERE_LEVEL`.
pub const MAX_SPHERE_LEVEL: u32 = 6;

/// Grid primitives: headers, the three vertex areas in one buffer, and the sphere radii;
/// plain slices, or split buffers (see [`crate::buffer`]).
#[derive(Copy, Clone)]
pub struct GridScene<'a, H, W> {
    pub headers: H,
    /// Each grid's inner area (`GridParams::inner_words` words: `f32` triples or 16-bit
    /// codes), then the edge and corner areas as `f32` triples.
    pub vertices: W,
    /// Sphere radii in breadth-first order per grid (see `GridParams::radius_format`), then
    /// the leaves' thicknesses.
    pub radii: W,
    /// The static index list, [`crate::grid_index::MICRO_TRIANGLES`]: read where it lives
    /// (a storage buffer on the GPU) rather than copied per ray, which costs a GPU thread 85
    /// private words.
    pub micro_triangles: &'a [u32],
    pub params: GridParams,
}

/// A grid resolved for reading by [`GridScene::open`].
///
/// Laid out in order, the base triangle last: SPIR-V validators size a struct that holds a
/// `Vec3` as a multiple of 16 bytes, more than Rust does, so a field after the base triangle
/// at Rust's offset would overlap it.
#[repr(C)]
#[derive(Copy, Clone)]
pub struct OpenGrid {
    slots: GridSlots,
    /// Where a grid of compressed values finds them (unused otherwise).
    coded: CodedGrid,
    /// For displaced grids of mixed levels: how many levels coarser than the scene the grid is
    /// (its points are the multiples of `2^shift` of the scene's lattice), and its decimated
    /// edges (see `GridParams::level_element`). Zero otherwise.
    pub shift: u32,
    pub decimated: u32,
    /// Where its spheres and leaf bytes lie.
    pub spheres: SphereRoom,
    /// Length of one code step (zero for `f32` inner vertices).
    unit: f32,
    /// The grid's corners: lattice points `(0, 0)`, `(n, 0)`, `(0, n)`.
    pub corners: [Vec3; 3],
    /// Mean of the corners: the root sphere's centre and the origin of the inner codes.
    pub origin: Vec3,
    /// The base triangle a displaced grid decodes its lattice points from (unused otherwise).
    base: DisplacedTriangle,
}

/// Where a grid's spheres and leaf bytes lie in the radius buffer, and how deep its hierarchy
/// is: the scene's layout, or a room of the grid's own level (see `GridParams::own_rooms`).
#[repr(C)]
#[derive(Copy, Clone)]
pub struct SphereRoom {
    /// The grid's first radius: a word of the buffer for relative radii, else the index of the
    /// grid's first radius among all radii (`f32` words or halves).
    first_radius: u32,
    /// The word where its leaves' bytes begin.
    first_leaf_word: u32,
    /// The deepest level of its sphere hierarchy.
    pub leaf_level: u32,
}

/// Bits of one stored displacement value.
pub const DISPLACEMENT_BITS: u32 = 11;

/// Flag bit of an address in 16-bit halves of the inner codes (buffers stay far below 2^31
/// words).
const INNER_CODES: u32 = 1 << 31;

/// Working memory of the grid traversal, one per ray.
pub struct GridScratch {
    /// A compressed leaf's values, decoded at their lattice slots (see
    /// [`GridScene::decode_leaf`]); never read by kernels without the decoder.
    values: PackedValues<LEAF_WORDS>,
    /// `1 / |dir|^2`, for the sphere tests.
    inv_dir_len2: f32,
    frame: FootprintFrame,
}

/// Most vertices a leaf can hold: a sub-triangle subdivided `MAX_LEAF_DEPTH` times.
const LEAF_VERTICES: usize = vertex_count(MAX_LEAF_DEPTH) as usize;

/// Words of a leaf's decoded values, two to a word.
const LEAF_WORDS: usize = LEAF_VERTICES.div_ceil(2);

/// Slot in a leaf's vertex list of corner `v` of a packed static-list entry.
#[inline]
fn corner_slot(packed: u32, v: u32) -> usize {
    ((packed >> (8 * v)) & 0xff) as usize
}

/// Mean of three corners, summed in corner order: the host computes the radii around exactly
/// this point.
#[inline]
pub fn sphere_center(a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    (a + b + c) * (1.0 / 3.0)
}

impl<'a> GridScene<'a, Split<'a, GridHeader>, Split<'a, u32>> {
    /// The grid buffers of a split scene (its BVH is `Split::new(chunks, split, GRID_NODES)`).
    #[inline(always)]
    pub fn split(chunks: &Chunks<'a>, split: &SplitParams, micro_triangles: &'a [u32], params: GridParams) -> Self {
        GridScene {
            headers: Split::new(chunks, split, GRID_HEADERS),
            vertices: Split::new(chunks, split, GRID_VERTICES),
            radii: Split::new(chunks, split, GRID_RADII),
            micro_triangles,
            params,
        }
    }
}

impl<'a, H, W> GridScene<'a, H, W> {
    /// The same scene read by code that carries `MOST & carries` (see [`KernelWords`]): a
    /// kernel's pipeline, or the CPU's code for one grid format.
    #[inline(always)]
    pub fn carrying<const MOST: u32>(self, carries: u32) -> GridScene<'a, H, KernelWords<W, MOST>> {
        let words = |words| KernelWords { words, carries };
        GridScene {
            headers: self.headers,
            vertices: words(self.vertices),
            radii: words(self.radii),
            micro_triangles: self.micro_triangles,
            params: self.params,
        }
    }
}

impl<H: Buffer<GridHeader>, W: Buffer<u32>> GridScene<'_, H, W> {
    /// Whether the code reading this scene carries `PART` (bits of [`carries`]): always
    /// natively, as the kernel's words say on the GPU. A part outside the words' `MOST` is a
    /// constant `false`, so its code never reaches the module.
    #[inline(always)]
    pub fn carries<const PART: u32>(&self) -> bool {
        if const { W::MOST & PART != 0 } {
            self.vertices.carries() & PART != 0
        } else {
            false
        }
    }

    /// Whether a grid is walked with the stack of sub-triangles, rather than by the root's
    /// visit alone: where only the stack's walk is carried, or the grids' stored leaves lie
    /// deeper than the root's children (see [`GridParams::one_visit`]).
    #[inline(always)]
    fn walks_with_stack(&self) -> bool {
        self.carries::<{ carries::STACK }>() && !(self.carries::<{ carries::ONE_VISIT }>() && self.params.one_visit())
    }

    /// The base edge and corner ids of grid `grid`, from its packed or wide header.
    #[inline]
    pub fn ids(&self, grid: u32) -> GridIds {
        if self.carries::<{ carries::DISPLACED_FORMATS }>() && self.params.header_bits != 0 {
            return self.tight_ids(grid);
        }
        // The same two reads either way (the second is the first again for packed headers):
        // SIMD hardware that runs both sides of a branch would otherwise pay three.
        let wide = (self.params.wide_headers != 0) as u32;
        let first = self.headers.load(grid << wide);
        let second = self.headers.load((grid << wide) + wide);
        if wide != 0 {
            GridIds::from_wide(first, second)
        } else {
            first.ids()
        }
    }

    /// The ids of a tight header (see `GridParams::header_bits`). A grid's six fields span
    /// at most 126 bits, so they lie in the element holding their first bit and the next
    /// one: two loads, then the five words from the one holding the first bit, taken in
    /// order (see [`BitQueue`]).
    #[inline]
    fn tight_ids(&self, grid: u32) -> GridIds {
        let (edge_bits, corner_bits) = (self.params.header_bits & 0xff, self.params.header_bits >> 8);
        let first = 3 * grid * (edge_bits + corner_bits);
        let (a, b) = (self.headers.load(first >> 7), self.headers.load((first >> 7) + 1));
        let w = [
            a.edges[0],
            a.edges[1],
            a.corners[0],
            a.corners[1],
            b.edges[0],
            b.edges[1],
            b.corners[0],
            b.corners[1],
        ];
        let bit = first & 127;
        // Fields of at most 126 bits from bit 31 of the first word at most: five words.
        let q = bit >> 5;
        let mut bits = BitQueue(if q == 0 {
            [w[0], w[1], w[2], w[3], w[4]]
        } else if q == 1 {
            [w[1], w[2], w[3], w[4], w[5]]
        } else if q == 2 {
            [w[2], w[3], w[4], w[5], w[6]]
        } else {
            [w[3], w[4], w[5], w[6], w[7]]
        });
        bits.drop(bit & 31);
        let edges = [bits.take(edge_bits), bits.take(edge_bits), bits.take(edge_bits)];
        let corners = [bits.take(corner_bits), bits.take(corner_bits), bits.take(corner_bits)];
        GridIds { edges, corners }
    }

    /// Grid `grid` resolved for reading, once per visit: where its vertices live, and the
    /// frame its inner vertices are decoded in.
    #[inline]
    pub fn open(&self, grid: u32) -> OpenGrid {
        if self.displaced() {
            let ids = self.ids(grid);
            let base = self.base_triangle(&ids);
            return self.open_displaced(grid, &ids, base);
        }
        self.open_stored(grid)
    }

    /// [`Self::open`] for a grid that stores its vertices (not displaced).
    #[inline(always)]
    fn open_stored(&self, grid: u32) -> OpenGrid {
        let g = &self.params;
        let n = 1u32 << g.levels;
        let quantized = g.quantized_inner != 0;
        // Addresses are buffer words, or halves for 16-bit inner codes (marked by a flag bit);
        // either way three units per vertex.
        let inner_word = grid * g.inner_words;
        let inner_first = if quantized {
            (2 * inner_word + 1) | INNER_CODES
        } else {
            inner_word
        };
        let corner_word = g.edge_word + 3 * (g.corner_offset - g.edge_offset);
        let slots = GridSlots::addressed(&self.ids(grid), n, inner_first, g.edge_word, corner_word, 3);
        let corners = [
            load_vec3_bits(self.vertices, slots.slot([0, 0])),
            load_vec3_bits(self.vertices, slots.slot([n, 0])),
            load_vec3_bits(self.vertices, slots.slot([0, n])),
        ];
        let origin = sphere_center(corners[0], corners[1], corners[2]);
        let unit = if quantized && g.inner_count > 0 {
            unit_from_exponent(read_half(self.vertices, 2 * inner_word) as u32)
        } else {
            0.0
        };
        OpenGrid {
            slots,
            corners,
            origin,
            unit,
            base: DisplacedTriangle {
                positions: [Vec3::ZERO; 3],
                directions: [Vec3::ZERO; 3],
                ids: [0; 3],
            },
            coded: CodedGrid::default(),
            shift: 0,
            decimated: 0,
            spheres: self.sphere_room(grid, g.levels),
        }
    }

    /// The base triangle of a displaced grid with ids `ids`: its corners' positions and
    /// directions, which decode its values.
    #[inline(always)]
    fn base_triangle(&self, ids: &GridIds) -> DisplacedTriangle {
        let g = &self.params;
        let corner_ids = [ids.corner(0), ids.corner(1), ids.corner(2)];
        let at = |c: usize, k: u32| load_vec3_bits(self.vertices, g.base_word + 6 * corner_ids[c] + k);
        DisplacedTriangle {
            positions: [at(0, 0), at(1, 0), at(2, 0)],
            directions: [at(0, 3), at(1, 3), at(2, 3)],
            ids: corner_ids,
        }
    }

    /// [`Self::open`] for a displaced grid with ids `ids` and base triangle `base`: one
    /// 11-bit value per lattice point, addressed in bits, or compressed values.
    fn open_displaced(&self, grid: u32, ids: &GridIds, base: DisplacedTriangle) -> OpenGrid {
        let g = &self.params;
        let n = 1u32 << g.levels;
        let edge_bit = 32 * g.edge_word;
        let corner_bit = edge_bit + DISPLACEMENT_BITS * (g.corner_offset - g.edge_offset);
        let inner_bit = 32 * grid * g.inner_words;
        let own = self.level_byte(grid);
        let slots = if g.level_element != 0 && !self.compressed() {
            self.leveled_slots(grid, ids, own >> 3)
        } else {
            GridSlots::addressed(ids, n, inner_bit, edge_bit, corner_bit, DISPLACEMENT_BITS)
        };
        let coded = if self.compressed() {
            let scene = CodedScene {
                code: ValueCode {
                    levels: g.levels,
                    widths: g.value_widths,
                },
                edge_bit,
                edge_block_bits: g.edge_block_bits,
                corner_bit: g.corner_bit,
                offset_bits: g.block_offset_bits,
                mixed: g.level_element != 0,
            };
            scene.open(self.vertices, ids, grid, own >> 3)
        } else {
            CodedGrid::default()
        };
        let mut open = OpenGrid {
            slots,
            corners: [Vec3::ZERO; 3],
            origin: Vec3::ZERO,
            unit: 0.0,
            base,
            coded,
            shift: g.levels - (own >> 3),
            decimated: own & 7,
            spheres: self.sphere_room(grid, own >> 3),
        };
        // A corner's compressed value is stored plain: read as it is, not walked down to (a
        // shader inlines each walk).
        open.corners = if self.compressed() {
            let q = open.coded.corner_values;
            [
                self.displaced_at(&open, [0, 0], q[0]),
                self.displaced_at(&open, [n, 0], q[1]),
                self.displaced_at(&open, [0, n], q[2]),
            ]
        } else {
            [
                self.stored_vertex(&open, [0, 0]),
                self.stored_vertex(&open, [n, 0]),
                self.stored_vertex(&open, [0, n]),
            ]
        };
        open.origin = sphere_center(open.corners[0], open.corners[1], open.corners[2]);
        open
    }

    /// Where a displaced grid of plain values and mixed levels, grid `grid` with ids `ids` of
    /// level `own`, finds them (see `crate::value_tables`): its own level's inner points in
    /// its block, each base edge's points at the level the edge holds.
    fn leveled_slots(&self, grid: u32, ids: &GridIds, own: u32) -> GridSlots {
        let g = &self.params;
        let table_bit = 32 * g.edge_word;
        let edge = |e: u32| leveled_edge(self.vertices, table_bit, ids.edge(e));
        let first = |edge: LeveledEdge| edge.bit(table_bit, edge_vertex_count(edge.level) * DISPLACEMENT_BITS);
        let (e0, e1, e2) = (edge(0), edge(1), edge(2));
        let areas = LeveledAreas {
            inner_first: block_bit(self.vertices, grid, g.block_offset_bits),
            inner_shift: g.levels - own,
            edge_first: [first(e0), first(e1), first(e2)],
            edge_shifts: [g.levels - e0.level, g.levels - e1.level, g.levels - e2.level],
            corner_first: g.corner_bit,
            stride: DISPLACEMENT_BITS,
        };
        GridSlots::leveled(ids, 1 << g.levels, areas)
    }

    /// Displaced grid `grid`'s byte of its own level and decimated edges (see
    /// `GridParams::level_element`): the scene's level and none when the grids are of one.
    #[inline]
    fn level_byte(&self, grid: u32) -> u32 {
        if self.params.level_element == 0 {
            return self.params.levels << 3;
        }
        let element = self.headers.load(self.params.level_element + (grid >> 4));
        let pick = (grid >> 2) & 3;
        let word = if pick == 0 {
            element.edges[0]
        } else if pick == 1 {
            element.edges[1]
        } else if pick == 2 {
            element.corners[0]
        } else {
            element.corners[1]
        };
        (word >> (8 * (grid & 3))) & 0xff
    }

    /// Where lattice point `p` of an opened displaced grid lies on its surface: moved along a
    /// decimated edge (see [`decimated_grid_point`]), or where it is.
    #[inline(always)]
    fn snapped(&self, grid: &OpenGrid, p: Lattice) -> Lattice {
        if grid.decimated == 0 {
            return p;
        }
        decimated_grid_point(p, 1 << self.params.levels, grid.shift, grid.decimated)
    }

    /// The deepest level grid `open` is rendered at: its own (see
    /// `GridParams::level_element`).
    #[inline(always)]
    pub fn own_level(&self, open: &OpenGrid) -> u32 {
        self.params.levels - open.shift
    }

    /// Position of lattice point `p` of an opened grid, read on its own: a compressed value
    /// is decoded by walking down from the grid's corners.
    #[inline(always)]
    pub fn vertex(&self, grid: &OpenGrid, p: Lattice) -> Vec3 {
        if self.compressed() {
            let p = self.snapped(grid, p);
            return self.displaced_at(grid, p, grid.coded.value(self.vertices, p));
        }
        self.stored_vertex(grid, p)
    }

    /// Whether the grids hold displacement values, plain or compressed. Never in kernels that
    /// leave displaced grids out (see [`carries::DISPLACED_GRIDS`]).
    #[inline(always)]
    fn displaced(&self) -> bool {
        self.carries::<{ carries::DISPLACED_GRIDS }>()
            && (self.carries::<{ carries::ONLY_COMPRESSED }>() || self.params.displaced != 0)
    }

    /// Whether the grids hold compressed values, which the traversal decodes a sub-triangle
    /// at a time rather than a point at a time. Only kernels that carry the decoder read them
    /// (see [`carries::DECODER`]): a decoder no ray runs still costs a kernel its registers.
    #[inline(always)]
    fn compressed(&self) -> bool {
        self.displaced()
            && self.carries::<{ carries::DECODER }>()
            && (self.carries::<{ carries::ONLY_COMPRESSED }>() || self.params.displaced == DISPLACED_COMPRESSED)
    }

    /// Position of lattice point `p` of an opened grid whose vertices or values are stored
    /// as they are read (not compressed). (Always inlined: the traversal reads vertices in its
    /// innermost loops, where a call per vertex shows in the CPU backend's speed.)
    #[inline(always)]
    fn stored_vertex(&self, grid: &OpenGrid, p: Lattice) -> Vec3 {
        if self.displaced() {
            // A value may run on into the next word, always there: the base vertices follow
            // the values.
            let p = self.snapped(grid, p);
            return self.displaced_at(grid, p, read_bits(self.vertices, grid.slots.slot(p), DISPLACEMENT_BITS));
        }
        let at = grid.slots.slot(p);
        let codes = at & INNER_CODES != 0;
        let h = at & !INNER_CODES;
        // One read of three words either way: an `f32` triple, or the two words that hold a
        // code triple (the third is never past the buffer's end: the corner area comes after
        // every inner area). On SIMD hardware that runs both sides of a branch, two separate
        // reads cost every vertex both.
        let [x, y, z] = self.vertices.load3(if codes { h / 2 } else { at });
        if !codes {
            return Vec3::new(f32::from_bits(x), f32::from_bits(y), f32::from_bits(z));
        }
        dequantize(grid.origin, halves_from_words(x, y, h & 1), grid.unit)
    }

    /// Lattice point `p` of a displaced grid whose 11-bit value is `q` (a unorm whose range
    /// the base vertices' positions and directions hold), decoded along its interpolated
    /// direction by the one decoder the host's triangles are made with.
    #[inline(always)]
    fn displaced_at(&self, grid: &OpenGrid, p: Lattice, q: u32) -> Vec3 {
        displaced_point(
            &grid.base,
            p,
            1 << self.params.levels,
            unorm11_displacement(q, 1.0, 0.0),
        )
    }

    /// The corners of sub-triangle `index` at depth `level` (lattice points `corners`) and
    /// its edges' midpoints (ab, bc, ca) from compressed values: the corners' from one walk
    /// down the hierarchy, then the midpoints'. Kept out of line on the CPU, so grids of other
    /// formats trace the same code as before.
    #[cfg_attr(not(target_arch = "spirv"), inline(never))]
    fn compressed_points(&self, open: &OpenGrid, level: u32, index: u32, corners: [Lattice; 3]) -> [Vec3; 6] {
        let coded = &open.coded;
        let [qa, qb, qc] = coded.sub_triangle_values(self.vertices, level, index);
        let [a, b, c] = corners;
        let mid = |p: Lattice, q: Lattice| [(p[0] + q[0]) / 2, (p[1] + q[1]) / 2];
        // The three midpoints are new one level below the sub-triangle.
        let at = coded.level_code(level + 1);
        // A midpoint that a decimated edge moves lands on one of that edge's ends (corners of
        // sub-triangles above the grid's own level never move).
        let midpoint = |p0: Lattice, p1: Lattice, q0: u32, q1: u32| {
            let p = mid(p0, p1);
            let on = self.snapped(open, p);
            let q = if on[0] == p[0] && on[1] == p[1] {
                coded.midpoint(self.vertices, p, q0, q1, &at)
            } else if on[0] == p0[0] && on[1] == p0[1] {
                q0
            } else {
                q1
            };
            self.displaced_at(open, on, q)
        };
        [
            self.displaced_at(open, a, qa),
            self.displaced_at(open, b, qb),
            self.displaced_at(open, c, qc),
            midpoint(a, b, qa, qb),
            midpoint(b, c, qb, qc),
            midpoint(c, a, qc, qa),
        ]
    }

    /// Whether the leaves of `room` hold their radii in their bytes
    /// ([`GridParams::leaf_pairs_at`]). Never in kernels that leave displaced grids out (see
    /// [`carries::DISPLACED_GRIDS`]).
    #[inline(always)]
    fn leaf_pairs(&self, room: &SphereRoom) -> bool {
        self.carries::<{ carries::DISPLACED_GRIDS }>() && self.params.leaf_pairs_at(room.leaf_level)
    }

    /// Whether the radii are bytes relative to each grid's root ([`RADII_RELATIVE`]), a
    /// format made for displaced grids (see [`carries::DISPLACED_FORMATS`]).
    #[inline(always)]
    fn relative_radii(&self) -> bool {
        self.carries::<{ carries::DISPLACED_FORMATS }>() && self.params.radius_format == RADII_RELATIVE
    }

    /// Whether each grid's spheres are at its own level (see `GridParams::own_rooms`): only
    /// for displaced grids.
    #[inline(always)]
    fn own_rooms(&self) -> bool {
        self.carries::<{ carries::DISPLACED_GRIDS }>() && self.params.own_rooms != 0
    }

    /// Where the spheres of `grid`, whose own level is `own`, lie in the radius buffer.
    #[inline]
    fn sphere_room(&self, grid: u32, own: u32) -> SphereRoom {
        let g = &self.params;
        if self.own_rooms() {
            let room = g.own_room(own);
            let offsets = self.radii.load(g.own_rooms + (grid >> 1));
            let first_radius = self.radii.load(grid >> 4) + ((offsets >> (16 * (grid & 1))) & 0xffff);
            return SphereRoom {
                first_radius,
                first_leaf_word: first_radius + room.radius_words,
                leaf_level: room.leaf_level,
            };
        }
        let first_radius = if self.relative_radii() {
            let stored = g.spheres_in_radius_area(self.carries::<{ carries::DISPLACED_GRIDS }>() && g.leaf_pairs());
            grid * relative_radius_words(stored)
        } else {
            grid * g.sphere_count
        };
        SphereRoom {
            first_radius,
            first_leaf_word: g.thickness_word + grid * triangle_count(g.leaf_level).div_ceil(4),
            leaf_level: g.leaf_level,
        }
    }

    /// Radius of sphere `node` (breadth-first id) of grid `open`.
    #[inline]
    pub fn radius(&self, open: &OpenGrid, node: u32) -> f32 {
        let room = &open.spheres;
        if self.relative_radii() {
            let first_leaf = level_start(room.leaf_level);
            if self.leaf_pairs(room) && node >= first_leaf {
                let parent = relative_radius_at(self.radii, room.first_radius, (node - 1) / 4);
                return leaf_radius(parent, self.leaf_byte(open, node - first_leaf));
            }
            return relative_radius_at(self.radii, room.first_radius, node);
        }
        let k = room.first_radius + node;
        // One read either way (see `ids`).
        let half_radii = self.params.radius_format == RADII_HALF;
        let word = self.radii.load(if half_radii { k / 2 } else { k });
        if !half_radii {
            return f32::from_bits(word);
        }
        decode_radius((word >> (16 * (k & 1))) & 0xffff, self.params.radius_scale)
    }

    /// Radii of the four children of a sphere of grid `open` whose first child is
    /// `first_child` at level `level`, whose own radius is `parent_radius`, in a grid whose
    /// root has radius `root_radius`.
    #[inline]
    fn child_radii(
        &self,
        open: &OpenGrid,
        first_child: u32,
        level: u32,
        parent_radius: f32,
        root_radius: f32,
    ) -> [f32; 4] {
        let room = &open.spheres;
        if self.leaf_pairs(room) && level == room.leaf_level {
            // The leaves' own bytes, four to a word.
            let word = self.leaf_word(open, first_child - level_start(level));
            return [
                leaf_radius(parent_radius, word),
                leaf_radius(parent_radius, word >> 8),
                leaf_radius(parent_radius, word >> 16),
                leaf_radius(parent_radius, word >> 24),
            ];
        }
        if self.relative_radii() {
            // The four bytes of one word.
            let word = self.radii.load(room.first_radius + 1 + (first_child - 1) / 4);
            return [
                relative_radius(root_radius, word, 0),
                relative_radius(root_radius, word, 1),
                relative_radius(root_radius, word, 2),
                relative_radius(root_radius, word, 3),
            ];
        }
        [
            self.radius(open, first_child),
            self.radius(open, first_child + 1),
            self.radius(open, first_child + 2),
            self.radius(open, first_child + 3),
        ]
    }

    /// Thickness of leaf `leaf` (its index at its grid's stored leaf level) of grid `open`,
    /// whose sphere has radius `radius`.
    #[inline]
    pub fn thickness(&self, open: &OpenGrid, leaf: u32, radius: f32) -> f32 {
        let byte = self.leaf_byte(open, leaf);
        if self.leaf_pairs(&open.spheres) {
            return leaf_thickness(radius, byte >> 4);
        }
        byte_thickness(radius, byte)
    }

    /// The word of grid `open`'s leaf bytes that holds leaf `leaf`'s, in its lowest byte when
    /// `leaf` is a multiple of 4.
    #[inline]
    fn leaf_word(&self, open: &OpenGrid, leaf: u32) -> u32 {
        self.radii.load(open.spheres.first_leaf_word + leaf / 4)
    }

    /// Leaf `leaf`'s byte (see `GridParams::thickness_word`).
    #[inline]
    fn leaf_byte(&self, open: &OpenGrid, leaf: u32) -> u32 {
        (self.leaf_word(open, leaf) >> (8 * (leaf & 3))) & 0xff
    }

    /// Tests the `4^k` micro-triangles of a leaf sub-triangle: its first corner is `corner`,
    /// and one step of its own lattice (`2^k` a side) is `step` grid-lattice units along both
    /// axes (negative for an inverted sub-triangle). Only the cells whose points lie inside
    /// `window` (`[la_lo, la_hi, lb_lo, lb_hi]`, see [`FootprintFrame::leaf_window`]) are
    /// tested, the static list's cell table naming each cell's triangle and the order of its
    /// corners. A hit is numbered by `ids`.
    ///
    /// The cells are walked two lattice rows at a time, column by column: each step reads one
    /// point (alternately of the lower and the upper row) into four named registers, the last
    /// two columns of both rows, and tests the one cell that point completes (the upright cell
    /// after a lower point, the inverted one after an upper point). No array is indexed at run
    /// time, so a GPU keeps the leaf's points in registers; the price is that a point inside
    /// the window is read once for each of the two row pairs it belongs to. The cells come in
    /// the order of the rows, and in each row upright before inverted, as the static list
    /// numbers them: ties between cells resolve alike on every backend.
    #[allow(clippy::too_many_arguments)]
    fn intersect_leaf_triangles<T: Tally>(
        &self,
        open: &OpenGrid,
        corner: [i32; 2],
        step: i32,
        k: u32,
        window: [u32; 4],
        ids: LeafIds,
        ray: &Ray,
        hit: &mut Hit,
        scratch: &GridScratch,
        tally: &mut T,
    ) {
        let m = 1u32 << k;
        let (la_lo, la_hi, lb_lo, lb_hi) = (window[0], window[1], window[2], window[3]);
        let row_end = |lb: u32| window_row_end(la_hi, lb, m);
        // A row pair has cells where its lower row holds two points of the window; rows end
        // sooner the higher they lie, so the first pair without any ends the walk.
        let has_cells = |lb: u32| lb < lb_hi && la_lo < row_end(lb);
        if !has_cells(lb_lo) {
            return;
        }
        let cells = micro_cell_offset(k);
        // The closest hit so far in plain locals, written to `hit` once after the walk (found
        // when its distance is below `hit.t`): on lavapipe a store into the ray's memory under
        // a branch costs at every cell.
        let mut closest = (hit.t, 0.0, 0.0);
        let mut closest_entry = 0;
        // Columns `la - 1` and `la` of rows `lb` (lower) and `lb + 1` (upper), sheared, with
        // their side bits (see `LeafPoint`).
        let mut lower = [LeafPoint::NONE; 2];
        let mut upper = [LeafPoint::NONE; 2];
        let (mut la, mut lb, mut up) = (la_lo, lb_lo, false);
        // Tested at the bottom, behind the test above that there is a first pass (see
        // `traverse_bvh`); one flat loop rather than a loop per row (see `snap_leaf_values`).
        loop {
            let point = self.leaf_point(open, corner, step, k, [la, lb + up as u32], ray, scratch);
            if up {
                upper = [upper[1], point];
            } else {
                lower = [lower[1], point];
            }
            if la > la_lo {
                // The cell anchored at `(la - 1, lb)` this point completes: upright after a
                // lower point, `(la - 1, lb), (la, lb), (la - 1, lb + 1)`; inverted after an
                // upper one, `(la, lb), (la - 1, lb + 1), (la, lb + 1)`.
                // The row above starts `m + 1 - lb` points further on: its point over this one.
                let first_lower = lattice_index(la - 1, lb, m);
                let first_upper = first_lower + m + 1 - lb;
                let (cell, slots) = if up {
                    ([lower[1], upper[0], upper[1]], [first_lower + 1, first_upper])
                } else {
                    ([lower[0], lower[1], upper[1]], [first_lower, first_lower + 1])
                };
                // In the sheared frame the ray is the z axis; a triangle whose vertices all
                // lie strictly on one side of it cannot be crossed: many fail this, at no
                // edge function and no read of the cell table.
                if cell[0].sides & cell[1].sides & cell[2].sides == 0 {
                    tally.triangles(1);
                    // The corners in the order the static list gives them, which the
                    // barycentrics follow.
                    let entry = element(self.micro_triangles, (cells + 2 * first_lower + up as u32) as usize);
                    let pick = |v: u32| {
                        let slot = corner_slot(entry, v) as u32;
                        if slot == slots[0] {
                            cell[0].at
                        } else if slot == slots[1] {
                            cell[1].at
                        } else {
                            cell[2].at
                        }
                    };
                    if let Some(found) = intersect_sheared(pick(0), pick(1), pick(2), closest.0) {
                        closest = found;
                        closest_entry = entry;
                    }
                }
            }
            // Next: the upper point of this column where the upper row reaches it, else the
            // lower point of the next column, else the next row pair's first column.
            if !up && la + lb < m {
                up = true;
            } else {
                up = false;
                la += 1;
                if la > row_end(lb) {
                    la = la_lo;
                    lb += 1;
                    if !has_cells(lb) {
                        break;
                    }
                }
            }
        }
        if closest.0 < hit.t {
            record_hit(hit, closest, ids.first + ((closest_entry >> 24) << ids.shift));
            hit.level = ids.level;
        }
    }

    /// Point `(la, lb)` of a leaf's lattice `k` deep (first corner `corner`, one step `step`
    /// grid units), sheared into `ray`'s frame. Compressed values come decoded in
    /// `scratch.values` (see [`Self::test_window`]).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn leaf_point(
        &self,
        open: &OpenGrid,
        corner: [i32; 2],
        step: i32,
        k: u32,
        l: Lattice,
        ray: &Ray,
        scratch: &GridScratch,
    ) -> LeafPoint {
        let p = [
            (corner[0] + l[0] as i32 * step) as u32,
            (corner[1] + l[1] as i32 * step) as u32,
        ];
        let v = if self.compressed() {
            let q = scratch.values.get(lattice_index(l[0], l[1], 1 << k));
            self.displaced_at(open, self.snapped(open, p), q)
        } else {
            self.stored_vertex(open, p)
        };
        LeafPoint::new(shear(v, ray))
    }

    /// Corners of the micro-triangle a hit at depth `level` names `prim` (see [`Hit`]): its
    /// grid, and its index at that depth in recursion order, whose digits walk down to its
    /// corners.
    pub fn micro_triangle(&self, prim: u32, level: u32) -> [Vec3; 3] {
        let (open, points) = self.locate(prim, level);
        // One vertex read in a loop a shader keeps: each read inlines a decoder, or a split
        // scene's branches to its chunk.
        let mut corners = [Vec3::ZERO; 3];
        let mut k = 0;
        while k < 3 + self.opaque_zero() as usize {
            corners[k] = self.vertex(&open, points[k]);
            k += 1;
        }
        corners
    }

    /// Zero, read from the scene's parameters (no depth reaches 256), so that a loop bounded
    /// by a constant plus this keeps one copy of its body in a shader: compilers unroll loops
    /// of a known trip count.
    #[inline]
    pub(crate) fn opaque_zero(&self) -> u32 {
        self.params.levels >> 8
    }

    /// The grid of the micro-triangle a hit at depth `level` names `prim`, opened, and the
    /// triangle's lattice corners.
    pub fn locate(&self, prim: u32, level: u32) -> (OpenGrid, [Lattice; 3]) {
        let per_grid = triangle_count(self.params.lod);
        let open = self.open(prim / per_grid);
        let t = (prim % per_grid) >> (2 * (self.params.lod - level));
        (open, sub_triangle(1 << self.params.levels, level, t))
    }

    /// Whether `ray` crosses the root sphere of the grid `visit` opened, closer than `t`.
    #[inline(always)]
    fn crosses_root<T: Tally>(
        &self,
        visit: &GridVisit,
        ray: &Ray,
        t: f32,
        scratch: &GridScratch,
        tally: &mut T,
    ) -> bool {
        tally.spheres(1);
        intersect_sphere_scaled(visit.open.origin, visit.root_radius, ray, scratch.inv_dir_len2, t) < T_FAR
    }

    /// Grid `grid`, opened as `open`, set up for a visit along `ray`.
    #[inline(always)]
    fn visit_of(&self, grid: u32, open: OpenGrid, ray: &Ray) -> GridVisit {
        let root_radius = self.radius(&open, 0);
        let lod = grid_level(&self.params, open.origin, root_radius);
        // A grid of mixed levels has no points deeper than its own level.
        let own = self.own_level(&open);
        let lod = if lod < own { lod } else { own };
        // At a coarse level of detail the hierarchy is cut where the rendered triangles are.
        let stored = open.spheres.leaf_level;
        let leaf_level = if stored < lod { stored } else { lod };
        GridVisit {
            grid,
            open,
            root_radius,
            lod,
            leaf_level,
            // Every vertex of the grid lies within the root sphere.
            slack: FootprintFrame::slack((open.origin - ray.origin).abs().max_element() + root_radius),
        }
    }

    /// The bottom level: depth-first, nearest sphere first, over the grid's 4-ary hierarchy.
    ///
    /// With a stack of pending sub-triangles, which takes any depth; or, for hierarchies whose
    /// stored leaves are the root's children or the root itself ([`GridParams::one_visit`]),
    /// by the root's visit alone, which tests its children as one leaf and so never pushes
    /// (see [`Self::walks_with_stack`]). One visit call site serves both: a shader inlines
    /// each, and a kernel specialised to the root's visit leaves the stack out.
    pub fn intersect_grid<T: Tally>(
        &self,
        grid: u32,
        ray: &Ray,
        hit: &mut Hit,
        scratch: &mut GridScratch,
        tally: &mut T,
    ) {
        // A displaced grid lies within its base triangle's shell, which the ray can miss
        // where it enters the grid's box: tested before any value is read.
        let open = if self.displaced() {
            let ids = self.ids(grid);
            let base = self.base_triangle(&ids);
            if !base.shell_may_cross(ray) {
                return;
            }
            self.open_displaced(grid, &ids, base)
        } else {
            self.open_stored(grid)
        };
        // The ray entered the grid's box closer than the closest hit to get here, and a sphere
        // around the box's grid rarely culls what the box let through: the root's sphere is
        // tested only where the root is itself the leaf, whose micro-triangles come next;
        // otherwise its children's spheres are.
        let visit = self.visit_of(grid, open, ray);
        if visit.leaf_level == 0 && !self.crosses_root(&visit, ray, hit.t, scratch, tally) {
            return;
        }
        let stack = self.walks_with_stack();
        let n = 1u32 << self.params.levels;
        let mut sub = SubTriangle::ROOT;
        let mut pending = PendingChildren::NONE;
        // Tested at the bottom (see `traverse_bvh`): the root is always visited, and a pass
        // more would cost every group a sub-triangle's whole work.
        loop {
            self.visit_sub_triangle(stack, &visit, &sub, &mut pending, ray, hit, scratch, tally);
            if !stack || pending.is_empty() {
                break;
            }
            // The nearest child waiting at the deepest level: a child of `sub`'s ancestor one
            // level up, since everything below that ancestor's other children waits above it.
            let (level, child) = pending.pop();
            let parent = sub.index >> (2 * (sub.level + 1 - level));
            sub = SubTriangle::at(n, level, 4 * parent + child);
        }
    }

    /// Sub-triangle `sub`, the root or a child just taken from `pending` (whose sphere is
    /// tested again first: a closer hit may have been found since it was put there): its
    /// children's spheres are tested and, with the `stack`, the hit ones put in `pending`,
    /// nearest on top; or, when they are leaves, tested here as one leaf of `sub`, over the
    /// lattice points the ray may touch in any of them; or `sub` is tested, when it is a leaf.
    #[allow(clippy::too_many_arguments)]
    fn visit_sub_triangle<T: Tally>(
        &self,
        stack: bool,
        visit: &GridVisit,
        sub: &SubTriangle,
        pending: &mut PendingChildren,
        ray: &Ray,
        hit: &mut Hit,
        scratch: &mut GridScratch,
        tally: &mut T,
    ) {
        let (open, leaf_level) = (visit.open, visit.leaf_level);
        let inv_dir_len2 = scratch.inv_dir_len2;
        let (level, index) = (sub.level, sub.index);
        // The one leaf test of this visit, through one call site below (rust-gpu inlines
        // every call: each copy of the leaf test costs the GPU kernel, and lavapipe runs the
        // code of a branch even when none of its rays takes it): the popped sub-triangle
        // itself when it is a leaf, or, when its children are leaves, the part of it that
        // holds the parts of them the ray can cross.
        // It is `sub`'s lattice, `k` steps deep, within `window` (all of it for a leaf).
        let k = visit.lod - level;
        let mut window = [0, 1 << k, 0, 1 << k];
        let mut tested = level == leaf_level;
        if level != leaf_level {
            let points = self.sub_triangle_points(&open, *sub);
            let [pa, pb, pc, pab, pbc, pca] = points;
            // A waiting child (never a leaf: leaves are tested with their parent) is visited only
            // if its sphere is still entered before the closest hit: the test its parent made,
            // made again on the same corners and radius.
            let radius = if level == 0 || !stack {
                visit.root_radius
            } else {
                self.radius(&open, level_start(level) + index)
            };
            if stack && level > 0 {
                tally.spheres(1);
                if intersect_sphere_scaled(sphere_center(pa, pb, pc), radius, ray, inv_dir_len2, hit.t) >= hit.t {
                    return;
                }
            }
            // Children 0, 1, 2 at corners a, b, c, and the inverted middle child 3; their radii
            // are adjacent in BFS order.
            let first_child = level_start(level + 1) + 4 * index;
            let r = self.child_radii(&open, first_child, level + 1, radius, visit.root_radius);
            let centers = [
                sphere_center(pa, pab, pca),
                sphere_center(pab, pb, pbc),
                sphere_center(pca, pbc, pc),
                sphere_center(pbc, pca, pab),
            ];
            tally.spheres(4);
            let t = intersect_spheres(centers, Vec4::from_array(r), ray, inv_dir_len2, hit.t).to_array();
            let mut e0 = Entry::new(t[0], 0);
            let mut e1 = Entry::new(t[1], 1);
            let mut e2 = Entry::new(t[2], 2);
            let mut e3 = Entry::new(t[3], 3);
            if level + 1 == leaf_level {
                window = self.leaf_children_window(visit, index, k, (points, r, t), ray, scratch.frame);
                tested = window[0] <= window[1];
            } else if stack {
                push_nearest_last(pending, level + 1, &mut e0, &mut e1, &mut e2, &mut e3);
            }
        }
        if tested {
            self.test_window(visit, sub, window, ray, hit, scratch, tally);
        }
    }

    /// The six points sub-triangle `sub` shares with its four children: its three corners and
    /// its edges' three midpoints, `[a, b, c, ab, bc, ca]`.
    #[inline(always)]
    fn sub_triangle_points(&self, open: &OpenGrid, sub: SubTriangle) -> [Vec3; 6] {
        let (level, a) = (sub.level, sub.corner);
        // A sub-triangle is its first corner `a`, its edge length and its orientation:
        // `b = a + d (s, 0)`, `c = a + d (0, s)`, `d = -1` for the inverted ones.
        let d = if sub.inverted { -1 } else { 1 };
        let s = d * ((1u32 << self.params.levels) >> level) as i32;
        let h = s / 2;
        let at = |x: i32, y: i32| [(a[0] + x) as u32, (a[1] + y) as u32];
        if self.compressed() {
            self.compressed_points(open, level, sub.index, [at(0, 0), at(s, 0), at(0, s)])
        } else {
            // The root's corners are the grid's, already loaded.
            let corner = |c: usize, p: Lattice| {
                if level == 0 {
                    open.corners[c]
                } else {
                    self.stored_vertex(open, p)
                }
            };
            [
                corner(0, at(0, 0)),
                corner(1, at(s, 0)),
                corner(2, at(0, s)),
                self.stored_vertex(open, at(h, 0)),
                self.stored_vertex(open, at(h, h)),
                self.stored_vertex(open, at(0, h)),
            ]
        }
    }

    /// The window of sub-triangle `index`'s lattice, `k` steps deep, that one leaf test covers
    /// when its children are leaves: each child the ray may cross (its sphere entered at
    /// `t < T_FAR`) gives the box of its lattice points that may belong to a crossed
    /// micro-triangle (all of them without footprints), and the window is the box around
    /// those boxes, a step finer. One test instead of a test per child: in lockstep each is
    /// as long as the group's longest. Empty (`window[0] > window[1]`) when the ray crosses
    /// none.
    #[inline(always)]
    fn leaf_children_window(
        &self,
        visit: &GridVisit,
        index: u32,
        k: u32,
        (points, r, t): ([Vec3; 6], [f32; 4], [f32; 4]),
        ray: &Ray,
        frame: FootprintFrame,
    ) -> [u32; 4] {
        let (open, slack) = (&visit.open, visit.slack);
        let footprint = self.params.leaf_footprint != 0 && visit.leaf_level == open.spheres.leaf_level;
        let m = 1u32 << (k - 1);
        let whole = [0, m, 0, m];
        let [mut w0, mut w1, mut w2, mut w3] = [whole; 4];
        if footprint {
            let [pa, pb, pc, pab, pbc, pca] = points;
            let [sa, sb, sc, sab, sbc, sca] = [
                shear(pa, ray),
                shear(pb, ray),
                shear(pc, ray),
                shear(pab, ray),
                shear(pbc, ray),
                shear(pca, ray),
            ];
            let child_window = |t: f32, leaf: u32, radius: f32, ca: Vec3, cb: Vec3, cc: Vec3| {
                let thickness = self.thickness(open, leaf, radius);
                if t < T_FAR && frame.overlaps(ca, cb, cc, thickness, slack) {
                    frame.leaf_window(ca, cb, cc, m, thickness, slack)
                } else {
                    EMPTY_WINDOW
                }
            };
            let first_leaf = 4 * index;
            w0 = child_window(t[0], first_leaf, r[0], sa, sab, sca);
            w1 = child_window(t[1], first_leaf + 1, r[1], sab, sb, sbc);
            w2 = child_window(t[2], first_leaf + 2, r[2], sca, sbc, sc);
            w3 = child_window(t[3], first_leaf + 3, r[3], sbc, sca, sab);
        }
        // Grown from empty.
        let mut window = [1 << k, 0, 1 << k, 0];
        window = add_child_window(window, t[0], 0, w0, m);
        window = add_child_window(window, t[1], 1, w1, m);
        window = add_child_window(window, t[2], 2, w2, m);
        add_child_window(window, t[3], 3, w3, m)
    }

    /// The leaf test of sub-triangle `sub`'s visit, over `window` of its lattice.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn test_window<T: Tally>(
        &self,
        visit: &GridVisit,
        sub: &SubTriangle,
        window: [u32; 4],
        ray: &Ray,
        hit: &mut Hit,
        scratch: &mut GridScratch,
        tally: &mut T,
    ) {
        let (grid, lod) = (visit.grid, visit.lod);
        let k = lod - sub.level;
        let size = ((1u32 << self.params.levels) >> sub.level) as i32;
        let d = if sub.inverted { -1 } else { 1 };
        // Numbered as at depth `params.lod`: each of this depth's triangles by the first of
        // the `4^(params.lod - lod)` it would split into.
        let shift = 2 * (self.params.lod - lod);
        let ids = LeafIds {
            first: grid * triangle_count(self.params.lod) + ((sub.index * triangle_count(k)) << shift),
            shift,
            level: lod,
        };
        let step = d * (size >> k);
        if self.compressed() {
            self.decode_leaf(&visit.open, sub, step, k, window, &mut scratch.values);
        }
        self.intersect_leaf_triangles(&visit.open, sub.corner, step, k, window, ids, ray, hit, scratch, tally);
    }

    /// The compressed values of sub-triangle `sub`'s lattice `k` levels deep (one step
    /// `step` grid units), those of the points of `window` at least, decoded into `values` as
    /// the leaf test indexes its points. Kept out of line on the CPU, so grids of other
    /// formats trace the same code as before.
    #[cfg_attr(not(target_arch = "spirv"), inline(never))]
    fn decode_leaf<const WORDS: usize>(
        &self,
        open: &OpenGrid,
        sub: &SubTriangle,
        step: i32,
        k: u32,
        window: [u32; 4],
        values: &mut PackedValues<WORDS>,
    ) {
        let corners = open.coded.sub_triangle_values(self.vertices, sub.level, sub.index);
        let lattice = SubLattice {
            first: sub.corner,
            step,
            k,
        };
        open.coded
            .decode_lattice(self.vertices, lattice, corners, window, values);
        if open.decimated != 0 {
            self.snap_leaf_values(open, lattice, window, values);
        }
    }

    /// Gives each point of `window` of a leaf's decoded lattice (see [`Self::decode_leaf`])
    /// that a decimated edge moves the value of the point it moves to: one step along the
    /// edge, an even point, which stays, lies in the same leaf (whose corners are even), and
    /// was decoded with the window (which the decoder rounds outward to each spacing).
    fn snap_leaf_values<const WORDS: usize>(
        &self,
        open: &OpenGrid,
        lattice: SubLattice,
        window: [u32; 4],
        values: &mut PackedValues<WORDS>,
    ) {
        let SubLattice { first, step, k } = lattice;
        let m = 1u32 << k;
        // A step is a power of two, either way: a point's steps from `first` are an exact
        // shift and a sign, not a division per point.
        let (shift, sign) = (step.unsigned_abs().trailing_zeros(), if step < 0 { -1 } else { 1 });
        let mut lb = window[2];
        while lb <= window[3] && lb <= m {
            let row_end = window_row_end(window[1], lb, m);
            let mut la = window[0];
            while la <= row_end {
                let p = [
                    (first[0] + la as i32 * step) as u32,
                    (first[1] + lb as i32 * step) as u32,
                ];
                let on = self.snapped(open, p);
                if on[0] != p[0] || on[1] != p[1] {
                    let to_a = sign * ((on[0] as i32 - first[0]) >> shift);
                    let to_b = sign * ((on[1] as i32 - first[1]) >> shift);
                    values.set(
                        lattice_index(la, lb, m),
                        values.get(lattice_index(to_a as u32, to_b as u32, m)),
                    );
                }
                la += 1;
            }
            lb += 1;
        }
    }
}

/// Bit fields read in order from five words in registers, least significant bit first: each
/// read takes the lowest bits and shifts the rest down, so no word is picked by an index
/// computed at run time (which a GPU keeps in slow private memory).
#[derive(Copy, Clone)]
struct BitQueue([u32; 5]);

impl BitQueue {
    /// Drops the lowest `n` bits (`n < 32`).
    #[inline(always)]
    fn drop(&mut self, n: u32) {
        let w = &mut self.0;
        // The bits moved down from the next word, shifted in two steps so that `n = 0`
        // moves none rather than shifting by 32.
        let next = |x: u32| (x << 1) << (31 - n);
        w[0] = (w[0] >> n) | next(w[1]);
        w[1] = (w[1] >> n) | next(w[2]);
        w[2] = (w[2] >> n) | next(w[3]);
        w[3] = (w[3] >> n) | next(w[4]);
        w[4] >>= n;
    }

    /// The lowest `width` bits (`width < 32`), taken off.
    #[inline(always)]
    fn take(&mut self, width: u32) -> u32 {
        let field = self.0[0] & ((1 << width) - 1);
        self.drop(width);
        field
    }
}

/// A leaf's lattice point in the ray's sheared frame, and which sides of the ray it lies
/// strictly on: bits for `x > 0`, `x < 0`, `y > 0`, `y < 0`.
#[derive(Copy, Clone)]
struct LeafPoint {
    at: Vec3,
    sides: u32,
}

impl LeafPoint {
    /// A register not yet holding a point: never one of a tested cell's corners.
    const NONE: LeafPoint = LeafPoint {
        at: Vec3::ZERO,
        sides: 0,
    };

    #[inline(always)]
    fn new(at: Vec3) -> LeafPoint {
        let sides =
            (at.x > 0.0) as u32 | ((at.x < 0.0) as u32) << 1 | ((at.y > 0.0) as u32) << 2 | ((at.y < 0.0) as u32) << 3;
        LeafPoint { at, sides }
    }
}

/// A window that holds no lattice point: `lo > hi` on both axes.
pub const EMPTY_WINDOW: [u32; 4] = [1, 0, 1, 0];

/// The last `la` of row `lb` of a window reaching `la_hi`, in a sub-triangle `m` steps a side
/// (whose row `lb` ends at `m - lb`).
#[inline]
fn window_row_end(la_hi: u32, lb: u32, m: u32) -> u32 {
    if la_hi < m - lb {
        la_hi
    } else {
        m - lb
    }
}

/// `window` (in a sub-triangle's lattice, `2m` steps a side) grown to hold the window `w` of
/// its child `child` (in the child's lattice, `m` steps a side) when the ray may cross the
/// child (entered at `t`) and `w` is not empty. Children 1 and 2 are offset by `m` along `la`
/// and `lb`; the inverted middle child's point `(la, lb)` is the parent's `(m - la, m - lb)`.
#[inline]
fn add_child_window(window: [u32; 4], t: f32, child: u32, w: [u32; 4], m: u32) -> [u32; 4] {
    if t >= T_FAR || w[0] > w[1] || w[2] > w[3] {
        return window;
    }
    let (oa, ob) = ((child == 1) as u32 * m, (child == 2) as u32 * m);
    let w = if child == 3 {
        [m - w[1], m - w[0], m - w[3], m - w[2]]
    } else {
        [w[0] + oa, w[1] + oa, w[2] + ob, w[3] + ob]
    };
    [
        window[0].min(w[0]),
        window[1].max(w[1]),
        window[2].min(w[2]),
        window[3].max(w[3]),
    ]
}

/// First corner `a` of child `child` of a sub-triangle with first corner `a` and signed half
/// edge `h`: a, ab, ca, and bc for the inverted middle child.
#[inline]
fn child_first_corner(a: [i32; 2], h: i32, child: u32) -> [i32; 2] {
    if child == 0 {
        a
    } else if child == 1 {
        [a[0] + h, a[1]]
    } else if child == 2 {
        [a[0], a[1] + h]
    } else {
        [a[0] + h, a[1] + h]
    }
}

/// How a leaf's hits are numbered (see [`Hit`]): the id of its first triangle, the shift of
/// each triangle's index within the leaf, and the depth to record.
#[repr(C)]
#[derive(Copy, Clone)]
struct LeafIds {
    first: u32,
    shift: u32,
    level: u32,
}

/// What every sub-triangle of one grid visit shares: the grid, opened, the depth it is
/// rendered at, where its hierarchy is cut, and the rounding room of its footprint tests.
#[derive(Copy, Clone)]
struct GridVisit {
    grid: u32,
    open: OpenGrid,
    root_radius: f32,
    lod: u32,
    leaf_level: u32,
    slack: f32,
}

/// A sub-triangle of a grid's hierarchy to visit: its depth, its index at that depth, and its
/// first corner and orientation (see [`GridScene::visit_sub_triangle`]).
#[derive(Copy, Clone)]
struct SubTriangle {
    level: u32,
    index: u32,
    corner: [i32; 2],
    inverted: bool,
}

impl SubTriangle {
    const ROOT: SubTriangle = SubTriangle {
        level: 0,
        index: 0,
        corner: [0, 0],
        inverted: false,
    };

    /// Sub-triangle `index` at depth `level` of a grid `n` steps a side: its first corner and
    /// orientation followed down its index's digits, two bits per level, the root's first.
    #[inline]
    fn at(n: u32, level: u32, index: u32) -> SubTriangle {
        let mut sub = SubTriangle { level, ..Self::ROOT };
        let mut l = 0;
        while l < level {
            let child = (index >> (2 * (level - 1 - l))) & 3;
            let d = if sub.inverted { -1 } else { 1 };
            let h = d * ((n >> l) as i32) / 2;
            sub.corner = child_first_corner(sub.corner, h, child);
            sub.inverted = sub.inverted != (child == 3);
            l += 1;
        }
        sub.index = index;
        sub
    }
}

/// The children a grid's depth-first walk has yet to visit, as a stack of their child numbers
/// (two bits each, the top in the lowest bits) and a count per level (three bits each): a
/// visit puts a sub-triangle's hit children on top, farthest first, and the walk takes the
/// nearest next, then its siblings once everything below it is done. Two words in place of
/// an array indexed at run time, which a GPU keeps in its slow private memory.
///
/// A visit that puts children there takes one off at once, so at most three wait at each
/// level; they wait at levels `1 ..= MAX_SPHERE_LEVEL - 1` (children at the leaf level are
/// tested with their parent): fifteen, thirty bits.
#[derive(Copy, Clone)]
struct PendingChildren {
    children: u32,
    counts: u32,
}

impl PendingChildren {
    const NONE: PendingChildren = PendingChildren { children: 0, counts: 0 };

    #[inline]
    fn is_empty(&self) -> bool {
        self.counts == 0
    }

    /// Child `child` of a sub-triangle one level above `level`, put on top.
    #[inline]
    fn push(&mut self, level: u32, child: u32) {
        self.children = (self.children << 2) | child;
        self.counts += 1 << (3 * level);
    }

    /// The top child taken off, and its level: the deepest with a child waiting.
    #[inline]
    fn pop(&mut self) -> (u32, u32) {
        // Each level's count folded into its lowest bit.
        let c = self.counts;
        let any = (c | (c >> 1) | (c >> 2)) & LOWEST_COUNT_BITS;
        let level = (31 - any.leading_zeros()) / 3;
        let child = self.children & 3;
        self.children >>= 2;
        self.counts -= 1 << (3 * level);
        (level, child)
    }
}

/// The lowest bit of each level's count in [`PendingChildren::counts`].
const LOWEST_COUNT_BITS: u32 = 0o1111111111;

/// A child sphere's entry distance, which child it is, and its radius.
#[repr(C)]
#[derive(Copy, Clone)]
struct Entry {
    t: f32,
    child: u32,
}

impl Entry {
    #[inline]
    fn new(t: f32, child: u32) -> Entry {
        Entry { t, child }
    }
}

/// The children hit (entered before `T_FAR`) pushed on `pending` at `level`, farthest first
/// so the nearest is popped next, sorted with a fixed network (no dynamically indexed arrays:
/// those are slow on GPUs).
#[inline(always)]
fn push_nearest_last(
    pending: &mut PendingChildren,
    level: u32,
    e0: &mut Entry,
    e1: &mut Entry,
    e2: &mut Entry,
    e3: &mut Entry,
) {
    sort_descending(e0, e1);
    sort_descending(e2, e3);
    sort_descending(e0, e2);
    sort_descending(e1, e3);
    sort_descending(e1, e2);
    let mut push = |e: &Entry| {
        if e.t < T_FAR {
            pending.push(level, e.child);
        }
    };
    push(e0);
    push(e1);
    push(e2);
    push(e3);
}

/// Orders two children so the farther comes first.
#[inline]
fn sort_descending(x: &mut Entry, y: &mut Entry) {
    if x.t < y.t {
        core::mem::swap(x, y);
    }
}

impl<H: Buffer<GridHeader>, W: Buffer<u32>> GridScene<'_, H, W> {
    /// Working memory of one ray's grid visits.
    fn new_scratch(ray: &Ray) -> GridScratch {
        GridScratch {
            values: PackedValues::filled(0),
            inv_dir_len2: 1.0 / ray.dir.dot(ray.dir),
            frame: FootprintFrame::new(ray),
        }
    }

    /// Grids `first .. first + count`.
    fn intersect_grids<T: Tally>(
        &self,
        first: u32,
        count: u32,
        ray: &Ray,
        hit: &mut Hit,
        scratch: &mut GridScratch,
        tally: &mut T,
    ) {
        let mut grid = first;
        // Tested at the bottom (see `traverse_bvh`): a pass more would be a whole grid visit.
        // The builder makes no empty leaves.
        loop {
            self.intersect_grid(grid, ray, hit, scratch, tally);
            grid += 1;
            if grid >= first + count {
                break;
            }
        }
    }
}

/// Grid primitives: each grid walked down its sphere hierarchy (see
/// [`GridScene::intersect_grid`]).
impl<H: Buffer<GridHeader>, W: Buffer<u32>> LeafPrimitives for GridScene<'_, H, W> {
    const WIDE_WALK: bool = W::MOST & carries::DISPLACED_GRIDS != 0;
    type Stack = TopStack;
    type Scratch = GridScratch;

    #[inline(always)]
    fn displaced_grids(&self) -> bool {
        self.carries::<{ carries::DISPLACED_GRIDS }>()
    }

    fn scratch(&self, ray: &Ray) -> GridScratch {
        Self::new_scratch(ray)
    }

    fn intersect_leaf<T: Tally>(
        &self,
        first: u32,
        count: u32,
        ray: &Ray,
        hit: &mut Hit,
        scratch: &mut GridScratch,
        tally: &mut T,
    ) {
        self.intersect_grids(first, count, ray, hit, scratch, tally);
    }

    #[inline]
    fn triangle(&self, prim: u32, level: u32) -> [Vec3; 3] {
        self.micro_triangle(prim, level)
    }

    fn smooth_normal(&self, hit: &Hit) -> Vec3 {
        if self.carries::<{ carries::SMOOTH_NORMALS }>() {
            GridScene::smooth_normal(self, hit)
        } else {
            Vec3::from(hit.normal)
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    /// A sub-triangle found from its index has the corners the hierarchy gives it: `a`, then
    /// `b` and `c` one edge along each axis, backwards when inverted.
    #[test]
    fn sub_triangles_follow_their_index() {
        let n = 1 << MAX_SPHERE_LEVEL;
        for level in 0..=MAX_SPHERE_LEVEL {
            for index in 0..triangle_count(level) {
                let sub = SubTriangle::at(n, level, index);
                let s = (n >> level) as i32 * if sub.inverted { -1 } else { 1 };
                let a = sub.corner;
                let at = |x: i32, y: i32| [(a[0] + x) as u32, (a[1] + y) as u32];
                assert_eq!(
                    [at(0, 0), at(s, 0), at(0, s)],
                    sub_triangle(n, level, index),
                    "{level} {index}"
                );
            }
        }
    }

    /// The pending children come off as a stack of (level, child) pairs would give them, over
    /// every walk a grid can take: each visit puts up to four children one level down and the
    /// nearest is taken at once.
    #[test]
    fn pending_children_are_a_stack() {
        // A small generator, so each case is the same on every run.
        let mut state = 0x2545_f491u32;
        let mut next = move |bound: u32| {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state % bound
        };
        for _ in 0..2000 {
            let mut pending = PendingChildren::NONE;
            let mut expected: Vec<(u32, u32)> = Vec::new();
            let mut level = 0;
            loop {
                // Children are put only above the leaf level's parent.
                if level + 1 < MAX_SPHERE_LEVEL {
                    for _ in 0..next(5) {
                        let child = next(4);
                        pending.push(level + 1, child);
                        expected.push((level + 1, child));
                    }
                }
                assert_eq!(pending.is_empty(), expected.is_empty());
                let Some((l, child)) = expected.pop() else {
                    break;
                };
                assert_eq!(pending.pop(), (l, child));
                level = l;
            }
        }
    }
}
