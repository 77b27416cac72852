//! The GPU entry points, each a thin wrapper around `gridrt_shared`: one thread per pixel of a
//! tile, or per ray of a list.
//!
//! Every kernel exists twice: reading each scene buffer from one binding, and reading a scene
//! split into chunks (descriptor set 1, see `gridrt_shared::buffer`) when a buffer is larger
//! than one binding may be. Both run the same traversal. Grids in the formats made for
//! displaced grids have whole-buffer kernels of their own, the only ones that carry those
//! formats, and grids of compressed values others again, the only ones that carry their
//! decoder (see `Buffer::DISPLACED_FORMATS`); split scenes of either have one kernel per job
//! for both. The two-phase schedule's grid kernels come in the same three kinds.
#![cfg_attr(target_arch = "spirv", no_std)]

use gridrt_shared::buffer::{AnyDisplacedWords, Buffer, Chunks, CompressedWords, DisplacedWords, Split};
use gridrt_shared::cost::Uncounted;
use gridrt_shared::glam::{UVec3, Vec3};
use gridrt_shared::grid_traverse::{leaf_test_class, GridScene, OneVisitGrids};
use gridrt_shared::layout::{
    BvhNode, FrameParams, GridHeader, GridParams, Hit, HitRecord, LeafEntry, QueueEntry, RayRecord, SplitParams,
    TraceParams, WalkState, FINISH_RAYS_PER_THREAD, FINISH_RAYS_PER_THREAD_COMPRESSED, GRID_HEADERS, GRID_NODES,
    GRID_RADII, GRID_VERTICES, LEAF_TEST_CLASSES, NO_HIT, TRACE_WORKGROUP_SIZE, TRIANGLE_NODES, WORKGROUP_SIZE,
};
use gridrt_shared::ray::Ray;
use gridrt_shared::shade::{cost_pixel, render_pixel};
use gridrt_shared::top_nodes::TopNodes;
use gridrt_shared::traverse::{closest_hit, BufferStack, Hierarchy, LeafPrimitives, TriangleMesh};
use spirv_std::spirv;

/// Where this thread's pixel goes in the tile's image buffer, or `None` outside the tile.
fn tile_index(id: UVec3, frame: &FrameParams) -> Option<usize> {
    if id.x < frame.tile_width && id.y < frame.tile_height {
        Some((id.y * frame.tile_width + id.x) as usize)
    } else {
        None
    }
}

/// The index of the ray this thread traces, or `None` past the end of the list. (No tuples or
/// other reordered Rust layouts cross function boundaries here: shader translators reject
/// struct members out of offset order.)
fn ray_index(id: UVec3, params: &TraceParams) -> Option<usize> {
    let index = id.x + id.y * params.threads_per_row;
    if index < params.ray_count {
        Some(index as usize)
    } else {
        None
    }
}

fn ray_of(r: &RayRecord) -> Ray {
    Ray::new(Vec3::from(r.origin), Vec3::from(r.dir))
}

fn record(hit: &Hit) -> HitRecord {
    HitRecord {
        t: hit.t,
        prim: hit.prim,
    }
}

/// The closest hit of ray `r` as the ray-list kernels record it: distance and triangle, so the
/// walk stops there (no normal, see `closest_hit`).
fn trace_record<N: Hierarchy, P: LeafPrimitives>(nodes: N, prims: &P, r: &RayRecord) -> HitRecord {
    record(&closest_hit(nodes, prims, &ray_of(r), r.t_max, &mut Uncounted))
}

/// Declares a kernel whose scene is split into chunks: its own bindings in set 0, then one
/// binding per chunk in set 1, gathered into `Chunks` named `$chunks` for the body. With
/// `few`, the first `FEW_CHUNKS` chunks alone (the body reads them as `Split<_, true>`); the
/// other fields of `Chunks` repeat the last, never read.
macro_rules! split_kernel {
    (
        few
        $(#[$attr:meta])*
        fn $name:ident($($arg:tt)*) |$chunks:ident| $body:block
    ) => {
        $(#[$attr])*
        #[allow(clippy::too_many_arguments)] // one per binding
        pub fn $name(
            $($arg)*
            #[spirv(storage_buffer, descriptor_set = 1, binding = 0)] c0: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 1)] c1: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 2)] c2: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 3)] c3: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 4)] c4: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 5)] c5: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 6)] c6: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 7)] c7: &[u32],
        ) {
            let $chunks = Chunks {
                c0, c1, c2, c3, c4, c5, c6, c7, c8: c7, c9: c7, c10: c7, c11: c7, c12: c7, c13: c7, c14: c7,
                c15: c7, c16: c7, c17: c7, c18: c7, c19: c7, c20: c7, c21: c7, c22: c7, c23: c7, c24: c7,
                c25: c7, c26: c7, c27: c7,
            };
            $body
        }
    };
    (
        $(#[$attr:meta])*
        fn $name:ident($($arg:tt)*) |$chunks:ident| $body:block
    ) => {
        $(#[$attr])*
        #[allow(clippy::too_many_arguments)] // one per binding
        pub fn $name(
            $($arg)*
            #[spirv(storage_buffer, descriptor_set = 1, binding = 0)] c0: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 1)] c1: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 2)] c2: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 3)] c3: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 4)] c4: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 5)] c5: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 6)] c6: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 7)] c7: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 8)] c8: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 9)] c9: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 10)] c10: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 11)] c11: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 12)] c12: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 13)] c13: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 14)] c14: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 15)] c15: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 16)] c16: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 17)] c17: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 18)] c18: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 19)] c19: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 20)] c20: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 21)] c21: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 22)] c22: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 23)] c23: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 24)] c24: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 25)] c25: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 26)] c26: &[u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 27)] c27: &[u32],
        ) {
            let $chunks = Chunks {
                c0, c1, c2, c3, c4, c5, c6, c7, c8, c9, c10, c11, c12, c13, c14, c15, c16, c17, c18, c19, c20,
                c21, c22, c23, c24, c25, c26, c27,
            };
            $body
        }
    };
}

/// Declares the two kernels that colour a frame's pixels of the baseline by `$pixel` (a
/// `gridrt_shared::shade` function of the frame, the BVH, the primitives and the pixel): a
/// triangle BVH over an indexed triangle list, reading whole buffers and a split scene.
macro_rules! triangle_image_kernels {
    ($pixel:path: $name:ident, $split:ident) => {
        /// The baseline: a triangle BVH over an indexed triangle list.
        #[spirv(compute(threads(8, 8, 1)))]
        pub fn $name(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] frame: &FrameParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] image: &mut [u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] nodes: &[BvhNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] positions: &[f32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] indices: &[u32],
        ) {
            if let Some(i) = tile_index(id, frame) {
                let mesh = TriangleMesh { positions, indices };
                image[i] = $pixel(frame, nodes, &mesh, frame.tile_x + id.x, frame.tile_y + id.y);
            }
        }

        split_kernel! {
            /// The baseline over a split scene.
            #[spirv(compute(threads(8, 8, 1)))]
            fn $split(
                #[spirv(global_invocation_id)] id: UVec3,
                #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] frame: &FrameParams,
                #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] image: &mut [u32],
            ) |chunks| {
                if let Some(i) = tile_index(id, frame) {
                    let nodes = Split::<BvhNode>::new(&chunks, &frame.split, TRIANGLE_NODES);
                    let mesh = TriangleMesh::split(&chunks, &frame.split);
                    image[i] = $pixel(frame, nodes, &mesh, frame.tile_x + id.x, frame.tile_y + id.y);
                }
            }
        }
    };
}

/// Declares a kernel that colours a frame's pixels of grid primitives by `$pixel`, each grid
/// walked as `$walk` wraps the scene (see [`stacked`]), its words read as `$words` wraps them
/// (see [`whole`]), each buffer from one binding.
macro_rules! grid_image_kernel {
    ($pixel:path, $walk:path, $words:path: $name:ident) => {
        /// Grid primitives: top-level BVH over grids, sphere hierarchy inside each.
        #[allow(clippy::too_many_arguments)] // one per binding
        #[spirv(compute(threads(8, 8, 1)))]
        pub fn $name(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] frame: &FrameParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] image: &mut [u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] micro_triangles: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] nodes: &[BvhNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] headers: &[GridHeader],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] vertices: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] radii: &[u32],
        ) {
            if let Some(i) = tile_index(id, frame) {
                let scene = GridScene {
                    headers,
                    vertices: $words(vertices),
                    radii: $words(radii),
                    micro_triangles,
                    params: frame.grid,
                };
                image[i] = $pixel(
                    frame,
                    TopNodes::new(nodes),
                    &$walk(scene),
                    frame.tile_x + id.x,
                    frame.tile_y + id.y,
                );
            }
        }
    };
}

/// Declares a kernel that colours a frame's pixels of grid primitives by `$pixel` over a split
/// scene, each grid walked as `$walk` wraps the scene, its words read as `$words` wraps them.
macro_rules! grid_image_split_kernel {
    ($pixel:path, $walk:path, $words:path, $few:literal $(, $kind:ident)?: $split:ident) => {
        split_kernel! {
            $($kind)?
            /// Grid primitives over a split scene.
            #[spirv(compute(threads(8, 8, 1)))]
            fn $split(
                #[spirv(global_invocation_id)] id: UVec3,
                #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] frame: &FrameParams,
                #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] image: &mut [u32],
                #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] micro_triangles: &[u32],
            ) |chunks| {
                if let Some(i) = tile_index(id, frame) {
                    let nodes = TopNodes::new(Split::<BvhNode, $few>::new(&chunks, &frame.split, GRID_NODES));
                    let scene = split_grids::<_, $few>(&chunks, &frame.split, micro_triangles, frame.grid, $words);
                    image[i] = $pixel(frame, nodes, &$walk(scene), frame.tile_x + id.x, frame.tile_y + id.y);
                }
            }
        }
    };
}

/// Declares the two kernels that colour a frame's pixels of grid primitives by `$pixel`, each
/// grid walked as `$walk` wraps the scene, reading whole buffers and a split scene.
macro_rules! grid_image_kernels {
    ($pixel:path, $walk:path: $name:ident, $split:ident) => {
        grid_image_kernel!($pixel, $walk, whole: $name);
        grid_image_split_kernel!($pixel, $walk, whole, false: $split);
    };
}

/// Grids walked with a stack of sub-triangles: any hierarchy depth.
fn stacked<S>(scene: S) -> S {
    scene
}

/// A scene's words read as they are: plain grids' formats only. Kernels for the formats of
/// displaced grids read them as [`DisplacedWords`], those for compressed values as
/// [`CompressedWords`], and split kernels for either as [`AnyDisplacedWords`].
fn whole<W>(words: W) -> W {
    words
}

/// The grids of a split scene, their words read as `words` wraps them; `FEW` as for `Split`.
fn split_grids<'a, W: Buffer<u32>, const FEW: bool>(
    chunks: &Chunks<'a>,
    split: &SplitParams,
    micro_triangles: &'a [u32],
    params: GridParams,
    words: impl Fn(Split<'a, u32, FEW>) -> W,
) -> GridScene<'a, Split<'a, GridHeader, FEW>, W> {
    GridScene {
        headers: Split::new(chunks, split, GRID_HEADERS),
        vertices: words(Split::new(chunks, split, GRID_VERTICES)),
        radii: words(Split::new(chunks, split, GRID_RADII)),
        micro_triangles,
        params,
    }
}

// Pictures, and the cost heat map's counts (packed `Costs` per pixel, coloured on the host).
// Grids whose hierarchies one visit walks (`GridParams::one_visit`) have kernels of their
// own, without the stack; the heat map's counts are the same either way.
triangle_image_kernels!(render_pixel: render_triangles, render_triangles_split);
grid_image_kernels!(render_pixel, stacked: render_grids, render_grids_split);
grid_image_kernels!(render_pixel, OneVisitGrids: render_grids_one_visit, render_grids_one_visit_split);
triangle_image_kernels!(cost_pixel: cost_triangles, cost_triangles_split);
grid_image_kernels!(cost_pixel, stacked: cost_grids, cost_grids_split);
grid_image_kernel!(render_pixel, stacked, DisplacedWords: render_grids_displaced);
grid_image_kernel!(render_pixel, OneVisitGrids, DisplacedWords: render_grids_one_visit_displaced);
grid_image_kernel!(cost_pixel, stacked, DisplacedWords: cost_grids_displaced);
grid_image_kernel!(render_pixel, stacked, CompressedWords: render_grids_compressed);
grid_image_kernel!(render_pixel, OneVisitGrids, CompressedWords: render_grids_one_visit_compressed);
grid_image_kernel!(cost_pixel, stacked, CompressedWords: cost_grids_compressed);
// Split scenes of displaced grids: one kernel per job for every format, walked with the stack
// (which finds what the root's visit alone does), in the first `FEW_CHUNKS` chunks: each split
// kernel takes lavapipe minutes to compile.
grid_image_split_kernel!(render_pixel, stacked, AnyDisplacedWords, true, few: render_grids_displaced_split);
grid_image_split_kernel!(cost_pixel, stacked, AnyDisplacedWords, true, few: cost_grids_displaced_split);

/// A list of rays against the baseline (benchmarks, and anything that brings its own rays).
#[spirv(compute(threads(64, 1, 1)))]
pub fn trace_triangles_rays(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &TraceParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[RayRecord],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] hits: &mut [HitRecord],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] nodes: &[BvhNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] positions: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] indices: &[u32],
) {
    if let Some(i) = ray_index(id, params) {
        let mesh = TriangleMesh { positions, indices };
        hits[i] = trace_record(nodes, &mesh, &rays[i]);
    }
}

split_kernel! {
    /// [`trace_triangles_rays`] over a split scene.
    #[spirv(compute(threads(64, 1, 1)))]
    fn trace_triangles_rays_split(
        #[spirv(global_invocation_id)] id: UVec3,
        #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &TraceParams,
        #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[RayRecord],
        #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] hits: &mut [HitRecord],
    ) |chunks| {
        if let Some(i) = ray_index(id, params) {
            let nodes = Split::<BvhNode>::new(&chunks, &params.split, TRIANGLE_NODES);
            let mesh = TriangleMesh::split(&chunks, &params.split);
            hits[i] = trace_record(nodes, &mesh, &rays[i]);
        }
    }
}

/// Declares a kernel that traces a list of rays against grid primitives, each grid walked as
/// `$walk` wraps the scene, its words read as `$words` wraps them, each buffer from one binding.
macro_rules! grid_ray_kernel {
    ($walk:path, $words:path: $name:ident) => {
        /// A list of rays against grid primitives.
        #[allow(clippy::too_many_arguments)] // one per binding
        #[spirv(compute(threads(64, 1, 1)))]
        pub fn $name(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &TraceParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[RayRecord],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] hits: &mut [HitRecord],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] micro_triangles: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] nodes: &[BvhNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] headers: &[GridHeader],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] vertices: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] radii: &[u32],
        ) {
            if let Some(i) = ray_index(id, params) {
                let scene = GridScene {
                    headers,
                    vertices: $words(vertices),
                    radii: $words(radii),
                    micro_triangles,
                    params: params.grid,
                };
                hits[i] = trace_record(TopNodes::new(nodes), &$walk(scene), &rays[i]);
            }
        }
    };
}

/// Declares a kernel that traces a list of rays against grid primitives over a split scene,
/// each grid walked as `$walk` wraps the scene, its words read as `$words` wraps them.
macro_rules! grid_ray_split_kernel {
    ($walk:path, $words:path, $few:literal $(, $kind:ident)?: $split:ident) => {
        split_kernel! {
            $($kind)?
            /// A list of rays against grid primitives over a split scene.
            #[spirv(compute(threads(64, 1, 1)))]
            fn $split(
                #[spirv(global_invocation_id)] id: UVec3,
                #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &TraceParams,
                #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[RayRecord],
                #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] hits: &mut [HitRecord],
                #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] micro_triangles: &[u32],
            ) |chunks| {
                if let Some(i) = ray_index(id, params) {
                    let nodes = TopNodes::new(Split::<BvhNode, $few>::new(&chunks, &params.split, GRID_NODES));
                    let scene = split_grids::<_, $few>(&chunks, &params.split, micro_triangles, params.grid, $words);
                    hits[i] = trace_record(nodes, &$walk(scene), &rays[i]);
                }
            }
        }
    };
}

/// Declares the two kernels that trace a list of rays against grid primitives, each grid
/// walked as `$walk` wraps the scene, reading whole buffers and a split scene.
macro_rules! grid_ray_kernels {
    ($walk:path: $name:ident, $split:ident) => {
        grid_ray_kernel!($walk, whole: $name);
        grid_ray_split_kernel!($walk, whole, false: $split);
    };
}

grid_ray_kernels!(stacked: trace_grids_rays, trace_grids_rays_split);
grid_ray_kernels!(OneVisitGrids: trace_grids_rays_one_visit, trace_grids_rays_one_visit_split);
grid_ray_kernel!(stacked, DisplacedWords: trace_grids_rays_displaced);
grid_ray_kernel!(OneVisitGrids, DisplacedWords: trace_grids_rays_one_visit_displaced);
grid_ray_kernel!(stacked, CompressedWords: trace_grids_rays_compressed);
grid_ray_kernel!(OneVisitGrids, CompressedWords: trace_grids_rays_one_visit_compressed);
grid_ray_split_kernel!(stacked, AnyDisplacedWords, true, few: trace_grids_rays_displaced_split);

// The workgroup sizes are literals because attribute arguments cannot name constants; one
// group of `order_leaf_classes` covers every class.
const _: () = assert!(WORKGROUP_SIZE == 8 && TRACE_WORKGROUP_SIZE == 64 && LEAF_TEST_CLASSES <= 64);

/// Slots of a two-phase counter block: an indirect dispatch's three group counts, then the
/// number of items.
const GROUPS_X: usize = 0;
const ITEMS: usize = 3;

const DEVICE: u32 = spirv_std::memory::Scope::QueueFamily as u32;
const RELAXED: u32 = spirv_std::memory::Semantics::NONE.bits();

/// Adds `n` to `counter` atomically among all the dispatch's threads; returns the value before.
fn atomic_add(counter: &mut u32, n: u32) -> u32 {
    unsafe { spirv_std::arch::atomic_i_add::<u32, DEVICE, RELAXED>(counter, n) }
}

/// The index in its list of the next item for a thread that takes items in turn, its first
/// being its thread index: past the dispatch's threads, those already taken, counted in `next`
/// (cleared before the dispatch).
fn take_next(next: &mut [u32], groups: UVec3) -> u32 {
    groups.x * TRACE_WORKGROUP_SIZE + atomic_add(&mut next[0], 1)
}

/// Appends `n` items to the list counted by `counter`; returns the first's index. The block's
/// group counts grow to cover the list.
fn append(counter: &mut [u32], n: u32) -> u32 {
    let first = atomic_add(&mut counter[ITEMS], n);
    // Only an append that opens a new workgroup's worth raises the group count (fewer
    // contended writes to one counter).
    let groups = (first + n).div_ceil(TRACE_WORKGROUP_SIZE);
    if groups > first.div_ceil(TRACE_WORKGROUP_SIZE) {
        unsafe { spirv_std::arch::atomic_u_max::<u32, DEVICE, RELAXED>(&mut counter[GROUPS_X], groups) };
    }
    if first == 0 {
        counter[1] = 1;
        counter[2] = 1;
    }
    first
}

/// The grids of a two-phase kernel's bindings, walked by their root's visit alone, their
/// words read as `W`.
fn one_visit_grids<'a, W: Buffer<u32>>(
    params: &TraceParams,
    headers: &'a [GridHeader],
    vertices: W,
    radii: W,
    micro_triangles: &'a [u32],
) -> OneVisitGrids<'a, &'a [GridHeader], W> {
    OneVisitGrids(GridScene {
        headers,
        vertices,
        radii,
        micro_triangles,
        params: params.grid,
    })
}

/// Where a two-phase walk round leaves its rays: the hits of those done, the queue entries and
/// walk states of the others, and the list of rays walking in the next round.
struct WalkOutput<'a> {
    hits: &'a mut [HitRecord],
    states: &'a mut [WalkState],
    active_out: &'a mut [u32],
    count_out: &'a mut [u32],
    queue: &'a mut [QueueEntry],
    queue_count: &'a mut [u32],
}

impl WalkOutput<'_> {
    /// Ray `r`'s round ended at `leaf`: nothing left to walk (its hit written), or the leaf's
    /// grids queued and the ray listed for the next round.
    fn leave(&mut self, r: u32, leaf: BvhNode, mut state: WalkState) {
        if leaf.count == 0 {
            self.hits[r as usize] = HitRecord {
                t: state.t,
                prim: state.prim,
            };
            return;
        }
        let first = append(self.queue_count, leaf.count);
        let mut g = 0;
        loop {
            self.queue[(first + g) as usize] = QueueEntry {
                ray: r,
                grid: leaf.first + g,
                t: state.t,
                _pad: 0,
            };
            g += 1;
            if g >= leaf.count {
                break;
            }
        }
        state.first_entry = first;
        state.entries = leaf.count;
        let slot = append(self.count_out, 1);
        self.active_out[slot as usize] = r;
        self.states[r as usize] = state;
    }
}

/// Declares the two-phase schedule's top-level walk kernels; `$wide`: whether they carry the
/// wide top level's walk (the kernels of displaced grids' formats).
macro_rules! two_phase_walk_kernels {
    ($wide:literal: $first:ident, $rounds:ident) => {
        /// The two-phase schedule's first phase, first round: every ray of the batch (ray `i` is
        /// thread `i`) from the root down to its first leaf, queueing that leaf's grids. Its walk
        /// state is written, not read: nothing needs clearing before.
        #[allow(clippy::too_many_arguments)] // one per binding
        #[spirv(compute(threads(64, 1, 1)))]
        pub fn $first(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] rays: &[RayRecord],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] hits: &mut [HitRecord],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] nodes: &[BvhNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] states: &mut [WalkState],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] stacks: &mut [u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] active_out: &mut [u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] queue: &mut [QueueEntry],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] count_in: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] count_out: &mut [u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 9)] queue_count: &mut [u32],
        ) {
            let r = id.x;
            if r >= count_in[ITEMS] {
                return;
            }
            let record = &rays[r as usize];
            let mut state = WalkState::default();
            let mut stack = BufferStack {
                words: stacks,
                ray: r as usize,
                rays: rays.len(),
            };
            let leaf =
                TopNodes::new(nodes).first_round::<{ $wide }, _>(&ray_of(record), record.t_max, &mut state, &mut stack);
            let mut out = WalkOutput {
                hits,
                states,
                active_out,
                count_out,
                queue,
                queue_count,
            };
            out.leave(r, leaf, state);
        }

        /// The two-phase schedule's first phase, every later round: one round of the top-level walk
        /// for each ray still walking, queueing the grids of the leaf it reaches.
        #[allow(clippy::too_many_arguments)] // one per binding
        #[spirv(compute(threads(64, 1, 1)))]
        pub fn $rounds(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] rays: &[RayRecord],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] hits: &mut [HitRecord],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] nodes: &[BvhNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] states: &mut [WalkState],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] stacks: &mut [u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] active_in: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] active_out: &mut [u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] queue: &mut [QueueEntry],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] results: &[HitRecord],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 9)] count_in: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 10)] count_out: &mut [u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 11)] queue_count: &mut [u32],
        ) {
            let i = id.x;
            if i >= count_in[ITEMS] {
                return;
            }
            let r = active_in[i as usize];
            let mut state = states[r as usize];
            let mut stack = BufferStack {
                words: stacks,
                ray: r as usize,
                rays: rays.len(),
            };
            let leaf = TopNodes::new(nodes).next_round::<{ $wide }, _, _>(
                results,
                &ray_of(&rays[r as usize]),
                &mut state,
                &mut stack,
            );
            let mut out = WalkOutput {
                hits,
                states,
                active_out,
                count_out,
                queue,
                queue_count,
            };
            out.leave(r, leaf, state);
        }
    };
}

two_phase_walk_kernels!(false: walk_first_rounds, walk_rounds);
two_phase_walk_kernels!(true: walk_first_rounds_displaced, walk_rounds_displaced);

/// Where each size class of the queued leaf tests begins once they are sorted by class: the
/// counts of the classes before it. One thread per class.
#[spirv(compute(threads(64, 1, 1)))]
pub fn order_leaf_classes(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] class_counts: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] class_starts: &mut [u32],
) {
    let class = id.x as usize;
    if class >= LEAF_TEST_CLASSES as usize {
        return;
    }
    let mut start = 0;
    let mut k = 0;
    while k < class {
        start += class_counts[k];
        k += 1;
    }
    class_starts[class] = start;
}

/// The queued leaf tests sorted by size class, each moved to its class's start plus its rank.
#[spirv(compute(threads(64, 1, 1)))]
pub fn sort_queued_leaves(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &TraceParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] leaves: &[LeafEntry],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] leaf_count: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] class_starts: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] sorted: &mut [LeafEntry],
) {
    let i = id.x as usize;
    if i >= leaf_count[ITEMS] as usize {
        return;
    }
    let leaf = leaves[i];
    let class = leaf_test_class(&params.grid, leaf.window());
    sorted[(class_starts[class as usize] + leaf.rank) as usize] = leaf;
}

/// Declares the two-phase schedule's grid kernels, their scene's words read as `$words` wraps
/// them (see [`whole`]); `$wide` as for [`two_phase_walk_kernels`].
macro_rules! two_phase_grid_kernels {
    ($words:path, $wide:literal, $rays_per_thread:expr, $visit:ident, $test:ident, $finish:ident) => {
        /// The two-phase schedule's second phase, first half: one queued grid per thread, its spheres
        /// and footprints; the visits that need a leaf test are queued again, counted by size class
        /// (`leaf_test_class`), the others answer a miss.
        #[allow(clippy::too_many_arguments)] // one per binding
        #[spirv(compute(threads(64, 1, 1)))]
        pub fn $visit(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &TraceParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[RayRecord],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] queue: &[QueueEntry],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] results: &mut [HitRecord],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] queue_count: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] headers: &[GridHeader],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] vertices: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] radii: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] leaves: &mut [LeafEntry],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 9)] leaf_count: &mut [u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 10)] class_counts: &mut [u32],
        ) {
            let i = id.x as usize;
            if i >= queue_count[ITEMS] as usize {
                return;
            }
            let entry = queue[i];
            let ray = ray_of(&rays[entry.ray as usize]);
            // The first half reads no cell table.
            let grids = one_visit_grids(params, headers, $words(vertices), $words(radii), vertices);
            let mut scratch = grids.scratch(&ray);
            let window = grids.leaf_window(entry.grid, &ray, entry.t, &mut scratch, &mut Uncounted);
            results[i] = HitRecord {
                t: entry.t,
                prim: NO_HIT,
            };
            if window[0] <= window[1] {
                let class = leaf_test_class(&params.grid, window);
                let rank = atomic_add(&mut class_counts[class as usize], 1);
                let slot = append(leaf_count, 1);
                leaves[slot as usize] = LeafEntry::new(i as u32, window, rank);
            }
        }

        /// The two-phase schedule's second phase, second half: one queued leaf test per thread, in the
        /// order of their size classes (`sort_queued_leaves`).
        #[allow(clippy::too_many_arguments)] // one per binding
        #[spirv(compute(threads(64, 1, 1)))]
        pub fn $test(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &TraceParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[RayRecord],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] queue: &[QueueEntry],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] results: &mut [HitRecord],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] leaves: &[LeafEntry],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] leaf_count: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] micro_triangles: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] headers: &[GridHeader],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] vertices: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 9)] radii: &[u32],
        ) {
            let i = id.x as usize;
            if i >= leaf_count[ITEMS] as usize {
                return;
            }
            let leaf = leaves[i];
            let entry = queue[leaf.slot as usize];
            let ray = ray_of(&rays[entry.ray as usize]);
            let grids = one_visit_grids(params, headers, $words(vertices), $words(radii), micro_triangles);
            let mut hit = Hit::miss(entry.t);
            let mut scratch = grids.scratch(&ray);
            grids.test_leaf_window(
                entry.grid,
                leaf.window(),
                &ray,
                &mut hit,
                &mut scratch,
                &mut Uncounted,
            );
            results[leaf.slot as usize] = record(&hit);
        }

        /// The two-phase schedule's tail: the rays still walking finish in one pass, their grids
        /// visited in place, once too few are left to fill the queue's dispatches. A thread takes the
        /// next ray of the list (`take_next`) as soon as its ray is done, one leaf a pass: in a SIMD
        /// group no lane waits idle for the group's longest walk while rays are left. It takes at most
        /// `FINISH_RAYS_PER_THREAD` rays (`FINISH_RAYS_PER_THREAD_COMPRESSED` for compressed values),
        /// so that its SIMD group's loops stay within a driver's limit.
        #[allow(clippy::too_many_arguments)] // one per binding
        #[spirv(compute(threads(64, 1, 1)))]
        pub fn $finish(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(num_workgroups)] groups: UVec3,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &TraceParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[RayRecord],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] hits: &mut [HitRecord],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] nodes: &[BvhNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] states: &[WalkState],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] stacks: &mut [u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] active_in: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] results: &[HitRecord],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] count_in: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 9)] micro_triangles: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 10)] headers: &[GridHeader],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 11)] vertices: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 12)] radii: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 13)] next: &mut [u32],
        ) {
            let count = count_in[ITEMS];
            if id.x >= count {
                return;
            }
            let grids = one_visit_grids(params, headers, $words(vertices), $words(radii), micro_triangles);
            let top = TopNodes::new(nodes);
            let mut r = active_in[id.x as usize] as usize;
            let mut ray = ray_of(&rays[r]);
            let mut state = states[r];
            let mut scratch = grids.scratch(&ray);
            let mut taken = 1;
            loop {
                let mut stack = BufferStack {
                    words: stacks,
                    ray: r,
                    rays: rays.len(),
                };
                let leaf = top.next_round::<{ $wide }, _, _>(results, &ray, &mut state, &mut stack);
                if leaf.count == 0 {
                    hits[r] = HitRecord {
                        t: state.t,
                        prim: state.prim,
                    };
                    if taken == $rays_per_thread {
                        break;
                    }
                    taken += 1;
                    let i = take_next(next, groups);
                    if i >= count {
                        break;
                    }
                    r = active_in[i as usize] as usize;
                    ray = ray_of(&rays[r]);
                    state = states[r];
                    scratch.aim(&ray);
                } else {
                    let mut hit = Hit::miss(state.t);
                    grids.intersect_leaf(
                        leaf.first,
                        leaf.count,
                        &ray,
                        &mut hit,
                        &mut scratch,
                        &mut Uncounted,
                    );
                    if hit.t < state.t {
                        state.t = hit.t;
                        state.prim = hit.prim;
                    }
                    state.entries = 0;
                }
            }
        }
    };
}

two_phase_grid_kernels!(
    whole,
    false,
    FINISH_RAYS_PER_THREAD,
    visit_queued,
    test_queued_leaves,
    finish_walks
);
two_phase_grid_kernels!(
    DisplacedWords,
    true,
    FINISH_RAYS_PER_THREAD,
    visit_queued_displaced,
    test_queued_leaves_displaced,
    finish_walks_displaced
);
// Compressed values walk their top level with the displaced grids' walk kernels.
two_phase_grid_kernels!(
    CompressedWords,
    true,
    FINISH_RAYS_PER_THREAD_COMPRESSED,
    visit_queued_compressed,
    test_queued_leaves_compressed,
    finish_walks_compressed
);
