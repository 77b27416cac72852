//! The GPU entry points, each a thin wrapper around `gridrt_shared`: one thread per pixel of a
//! tile, or per ray of a list.
//!
//! Every job has a kernel reading each scene buffer from one binding, and kernels reading a
//! scene split into chunks (descriptor set 1, see `gridrt_shared::buffer`) when a buffer is
//! larger than one binding may be (plain grids and the baseline: displaced grids' formats are
//! read from whole buffers alone). All run the same traversal. A grid kernel's module carries
//! the formats and walks of its family, and each pipeline made from it keeps those its
//! specialisation constant 0 names (`gridrt_shared::buffer::carries`): the driver folds the
//! others away, so a scene pays for its own format and walk alone.
#![cfg_attr(target_arch = "spirv", no_std)]

use gridrt_shared::buffer::{carries, Chunks, KernelWords, Split};
use gridrt_shared::cost::Uncounted;
use gridrt_shared::glam::{UVec3, Vec3};
use gridrt_shared::grid_traverse::GridScene;
use gridrt_shared::layout::{
    BvhNode, FrameParams, GridHeader, GridParams, Hit, HitRecord, RayRecord, SplitParams, TraceParams, GRID_NODES,
    RENDER_WORKGROUP, TRACE_WORKGROUP_SIZE, TRIANGLE_NODES,
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
/// binding per chunk in set 1, gathered into `Chunks` named `$chunks` for the body.
macro_rules! split_kernel {
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
        ) {
            let $chunks = Chunks {
                c0, c1, c2, c3, c4, c5, c6, c7,
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
        #[spirv(compute(threads(8, 4, 1)))]
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
            #[spirv(compute(threads(8, 4, 1)))]
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

triangle_image_kernels!(render_pixel: render_triangles, render_triangles_split);

/// What each family of grid kernels carries in its module (see
/// `gridrt_shared::buffer::carries`), of which a pipeline keeps what its specialisation
/// constant 0 says: on whole buffers, everything (a pipeline per format and walk, and renders
/// with or without smooth normals); over split scenes, the formats plain grids may ask for,
/// both walks, smooth normals. Displaced grids' values, wide top levels and leaf radius
/// pairs are read from whole buffers alone: every read of a split scene branches to its
/// chunk, and their decoders read at so many places that such a kernel was the largest of
/// the module.
const WHOLE: u32 = carries::ALL | carries::ONLY_COMPRESSED;
const SPLIT_PLAIN: u32 = carries::DISPLACED_FORMATS | carries::STACK | carries::ONE_VISIT | carries::SMOOTH_NORMALS;

/// The grids of a scene bound whole, their words carrying `WHOLE & carried`.
fn whole_grids<'a>(
    headers: &'a [GridHeader],
    vertices: &'a [u32],
    radii: &'a [u32],
    micro_triangles: &'a [u32],
    params: GridParams,
    carried: u32,
) -> GridScene<'a, &'a [GridHeader], KernelWords<&'a [u32], WHOLE>> {
    let scene = GridScene {
        headers,
        vertices,
        radii,
        micro_triangles,
        params,
    };
    scene.carrying(carried)
}

/// The grids of a split scene, their words carrying `SPLIT_PLAIN & carried`.
fn split_grids<'a>(
    chunks: &Chunks<'a>,
    split: &SplitParams,
    micro_triangles: &'a [u32],
    params: GridParams,
    carried: u32,
) -> GridScene<'a, Split<'a, GridHeader>, KernelWords<Split<'a, u32>, SPLIT_PLAIN>> {
    GridScene::split(chunks, split, micro_triangles, params).carrying(carried)
}

/// Grid primitives on whole buffers: top-level BVH over grids, sphere hierarchy inside each;
/// any format and walk, as the pipeline's specialisation constant says.
#[allow(clippy::too_many_arguments)] // one per binding
#[spirv(compute(threads(8, 4, 1)))]
pub fn render_grids(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(spec_constant(id = 0, default = 0))] carried: u32,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] frame: &FrameParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] image: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] micro_triangles: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] nodes: &[BvhNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] headers: &[GridHeader],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] vertices: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] radii: &[u32],
) {
    if let Some(i) = tile_index(id, frame) {
        let scene = whole_grids(headers, vertices, radii, micro_triangles, frame.grid, carried);
        image[i] = render_pixel(
            frame,
            TopNodes::new(nodes),
            &scene,
            frame.tile_x + id.x,
            frame.tile_y + id.y,
        );
    }
}

split_kernel! {
    /// Grid primitives over a split scene.
    #[spirv(compute(threads(8, 4, 1)))]
    fn render_grids_split(
        #[spirv(global_invocation_id)] id: UVec3,
        #[spirv(spec_constant(id = 0, default = 0))] carried: u32,
        #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] frame: &FrameParams,
        #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] image: &mut [u32],
        #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] micro_triangles: &[u32],
    ) |chunks| {
        if let Some(i) = tile_index(id, frame) {
            let nodes = TopNodes::new(Split::<BvhNode>::new(&chunks, &frame.split, GRID_NODES));
            let scene = split_grids(&chunks, &frame.split, micro_triangles, frame.grid, carried);
            image[i] = render_pixel(frame, nodes, &scene, frame.tile_x + id.x, frame.tile_y + id.y);
        }
    }
}

/// A list of rays against the baseline (benchmarks, and anything that brings its own rays).
#[spirv(compute(threads(32, 1, 1)))]
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
    #[spirv(compute(threads(32, 1, 1)))]
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

/// A list of rays against grid primitives on whole buffers, any format and walk (see
/// [`render_grids`]).
#[allow(clippy::too_many_arguments)] // one per binding
#[spirv(compute(threads(32, 1, 1)))]
pub fn trace_grids_rays(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(spec_constant(id = 0, default = 0))] carried: u32,
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
        let scene = whole_grids(headers, vertices, radii, micro_triangles, params.grid, carried);
        hits[i] = trace_record(TopNodes::new(nodes), &scene, &rays[i]);
    }
}

split_kernel! {
    /// A list of rays against grid primitives over a split scene.
    #[spirv(compute(threads(32, 1, 1)))]
    fn trace_grids_rays_split(
        #[spirv(global_invocation_id)] id: UVec3,
        #[spirv(spec_constant(id = 0, default = 0))] carried: u32,
        #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &TraceParams,
        #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[RayRecord],
        #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] hits: &mut [HitRecord],
        #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] micro_triangles: &[u32],
    ) |chunks| {
        if let Some(i) = ray_index(id, params) {
            let nodes = TopNodes::new(Split::<BvhNode>::new(&chunks, &params.split, GRID_NODES));
            let scene = split_grids(&chunks, &params.split, micro_triangles, params.grid, carried);
            hits[i] = trace_record(nodes, &scene, &rays[i]);
        }
    }
}

// The workgroup sizes are literals because attribute arguments cannot name constants.
const _: () = assert!(RENDER_WORKGROUP[0] == 8 && RENDER_WORKGROUP[1] == 4 && TRACE_WORKGROUP_SIZE == 32);
