//! The GPU entry points: one thread per pixel, each a thin wrapper around `gridrt_shared`.
#![cfg_attr(target_arch = "spirv", no_std)]

use gridrt_shared::camera::primary_ray;
use gridrt_shared::glam::UVec3;
use gridrt_shared::glam::Vec3;
use gridrt_shared::grid_traverse::{trace_grids, GridScene};
use gridrt_shared::layout::Hit;
use gridrt_shared::layout::{
    BvhNode, FrameParams, GridHeader, HitRecord, RayRecord, TraceParams, TRACE_WORKGROUP_SIZE, WORKGROUP_SIZE,
};
use gridrt_shared::ray::Ray;
use gridrt_shared::ray::T_FAR;
use gridrt_shared::shade::{pack_rgba8, shade};
use gridrt_shared::traverse::{trace_triangles, TriangleMesh};
use spirv_std::spirv;

/// The baseline: a triangle BVH over an indexed triangle list.
#[spirv(compute(threads(8, 8, 1)))]
pub fn render_triangles(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &FrameParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] nodes: &[BvhNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] positions: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] indices: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] image: &mut [u32],
) {
    let cam = &params.camera;
    if id.x >= cam.width || id.y >= cam.height {
        return;
    }
    let ray = primary_ray(cam, id.x, id.y);
    let mesh = TriangleMesh { positions, indices };
    let hit = trace_triangles(nodes, &mesh, &ray, T_FAR);
    image[(id.y * cam.width + id.x) as usize] = pack_rgba8(shade(&hit, &ray, params.shading));
}

/// Grid primitives: top-level BVH over grids, sphere hierarchy inside each.
#[allow(clippy::too_many_arguments)] // one per binding
#[spirv(compute(threads(8, 8, 1)))]
pub fn render_grids(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &FrameParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] nodes: &[BvhNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] headers: &[GridHeader],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] vertices: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] radii: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] micro_triangles: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] image: &mut [u32],
) {
    let cam = &params.camera;
    if id.x >= cam.width || id.y >= cam.height {
        return;
    }
    let ray = primary_ray(cam, id.x, id.y);
    let scene = GridScene {
        headers,
        vertices,
        radii,
        micro_triangles,
        params: params.grid,
    };
    let hit = trace_grids(nodes, &scene, &ray, T_FAR);
    image[(id.y * cam.width + id.x) as usize] = pack_rgba8(shade(&hit, &ray, params.shading));
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

/// A list of rays against the baseline (benchmarks, and anything that brings its own rays).
#[spirv(compute(threads(64, 1, 1)))]
pub fn trace_triangles_rays(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &TraceParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] nodes: &[BvhNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] positions: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] indices: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] rays: &[RayRecord],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] hits: &mut [HitRecord],
) {
    if let Some(index) = ray_index(id, params) {
        let mesh = TriangleMesh { positions, indices };
        hits[index] = record(&trace_triangles(nodes, &mesh, &ray_of(&rays[index]), rays[index].t_max));
    }
}

/// A list of rays against grid primitives.
#[allow(clippy::too_many_arguments)] // one per binding
#[spirv(compute(threads(64, 1, 1)))]
pub fn trace_grids_rays(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &TraceParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] nodes: &[BvhNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] headers: &[GridHeader],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] vertices: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] radii: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] micro_triangles: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] rays: &[RayRecord],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] hits: &mut [HitRecord],
) {
    if let Some(index) = ray_index(id, params) {
        let scene = GridScene {
            headers,
            vertices,
            radii,
            micro_triangles,
            params: params.grid,
        };
        hits[index] = record(&trace_grids(nodes, &scene, &ray_of(&rays[index]), rays[index].t_max));
    }
}

// The workgroup sizes above is a literal because attribute arguments cannot name constants.
const _: () = assert!(WORKGROUP_SIZE == 8 && TRACE_WORKGROUP_SIZE == 64);
