//! The GPU entry points, each a thin wrapper around `gridrt_shared`: one thread per pixel of a
//! tile, or per ray of a list.
//!
//! Every kernel exists twice: reading each scene buffer from one binding, and reading a scene
//! split into chunks (descriptor set 1, see `gridrt_shared::buffer`) when a buffer is larger
//! than one binding may be. Both run the same traversal. Grids in the formats made for
//! displaced grids have whole-buffer kernels of their own, the only ones that carry those
//! formats, and grids of compressed values others again, the only ones that carry their
//! decoder (see `Buffer::DISPLACED_FORMATS`); split scenes of either have one kernel per job
//! for both.
#![cfg_attr(target_arch = "spirv", no_std)]

use gridrt_shared::buffer::{AnyDisplacedWords, Buffer, Chunks, CompressedWords, DisplacedWords, Split};
use gridrt_shared::cost::Uncounted;
use gridrt_shared::glam::{UVec3, Vec3};
use gridrt_shared::grid_traverse::{GridScene, OneVisitGrids};
use gridrt_shared::layout::{
    BvhNode, FrameParams, GridHeader, GridParams, Hit, HitRecord, RayRecord, SplitParams, TraceParams, GRID_HEADERS,
    GRID_NODES, GRID_RADII, GRID_VERTICES, TRACE_WORKGROUP_SIZE, TRIANGLE_NODES, WORKGROUP_SIZE,
};
use gridrt_shared::ray::Ray;
use gridrt_shared::shade::render_pixel;
use gridrt_shared::top_nodes::TopNodes;
use gridrt_shared::traverse::{closest_hit, Hierarchy, LeafPrimitives, TriangleMesh};
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

// Pictures. (The cost heat map's counts are the traversal's, the same on every device: the
// host counts them on the CPU.) Grids whose hierarchies one visit walks
// (`GridParams::one_visit`) have kernels of their own, without the stack.
triangle_image_kernels!(render_pixel: render_triangles, render_triangles_split);
grid_image_kernels!(render_pixel, stacked: render_grids, render_grids_split);
grid_image_kernels!(render_pixel, OneVisitGrids: render_grids_one_visit, render_grids_one_visit_split);
grid_image_kernel!(render_pixel, stacked, DisplacedWords: render_grids_displaced);
grid_image_kernel!(render_pixel, OneVisitGrids, DisplacedWords: render_grids_one_visit_displaced);
grid_image_kernel!(render_pixel, stacked, CompressedWords: render_grids_compressed);
grid_image_kernel!(render_pixel, OneVisitGrids, CompressedWords: render_grids_one_visit_compressed);
// Split scenes of displaced grids: one kernel per job for every format, walked with the stack
// (which finds what the root's visit alone does), in the first `FEW_CHUNKS` chunks: each split
// kernel takes lavapipe minutes to compile.
grid_image_split_kernel!(render_pixel, stacked, AnyDisplacedWords, true, few: render_grids_displaced_split);

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

// The workgroup sizes are literals because attribute arguments cannot name constants.
const _: () = assert!(WORKGROUP_SIZE == 8 && TRACE_WORKGROUP_SIZE == 64);
