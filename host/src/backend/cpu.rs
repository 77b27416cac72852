//! The CPU backend: every pixel and every ray of a list through the same `gridrt_shared`
//! functions the kernels call, in parallel over rayon's threads. Its images and hits are the
//! reference the GPU's are tested against. Grids are read by the code of their format alone,
//! as a GPU pipeline reads them (see [`crate::grid::format`]).

use std::time::Instant;

use gridrt_shared::cost::Uncounted;
use gridrt_shared::glam::Vec3;
use gridrt_shared::layout::{FrameParams, HitRecord, RayRecord, SHADE_COST};
use gridrt_shared::ray::Ray;
use gridrt_shared::shade::{cost_pixel, render_pixel};
use gridrt_shared::traverse::{closest_hit, Hierarchy, LeafPrimitives};
use rayon::prelude::*;

use super::TimedTrace;
use crate::grid::format::read_as_format;
use crate::rays::in_turn;
use crate::scene::Scene;

/// Renders on the CPU, rows in parallel: packed RGBA8, row-major, top row first.
pub fn render_cpu(scene: &Scene, frame: &FrameParams) -> Vec<u32> {
    match scene {
        Scene::Triangles(s) => render_pixels(frame, s.nodes.as_slice(), &s.view()),
        // Read as the frame says (its level of detail), as the kernels do.
        Scene::Grids(s) => read_as_format!(s, frame.grid, |view| render_pixels(frame, s.top(), &view)),
    }
}

/// Every pixel of the frame as the kernels make it: coloured, or its ray's packed costs for
/// the heat map.
pub(crate) fn render_pixels<N: Hierarchy + Sync, P: LeafPrimitives + Sync>(
    frame: &FrameParams,
    nodes: N,
    prims: &P,
) -> Vec<u32> {
    if frame.shading == SHADE_COST {
        render_rows(frame, |x, y| cost_pixel(frame, nodes, prims, x, y))
    } else {
        render_rows(frame, |x, y| render_pixel(frame, nodes, prims, x, y))
    }
}

/// Every pixel of the frame by `pixel(x, y)`, rows in parallel.
fn render_rows(frame: &FrameParams, pixel: impl Fn(u32, u32) -> u32 + Sync) -> Vec<u32> {
    let (w, h) = (frame.camera.width, frame.camera.height);
    let mut image = vec![0u32; w as usize * h as usize];
    image.par_chunks_mut(w as usize).enumerate().for_each(|(y, row)| {
        for (x, px) in row.iter_mut().enumerate() {
            *px = pixel(x as u32, y as u32);
        }
    });
    image
}

/// Traces a ray list on the CPU, in parallel: the closest hit of each.
pub fn trace_cpu(scene: &Scene, rays: &[RayRecord]) -> Vec<HitRecord> {
    match scene {
        Scene::Triangles(s) => trace_rays(rays, s.nodes.as_slice(), &s.view()),
        Scene::Grids(s) => read_as_format!(s, s.params, |view| trace_rays(rays, s.top(), &view)),
    }
}

/// The closest hit of each ray, without its normal, as the GPU's ray lists trace it: all a
/// ray list asks for (a grid's normal decodes its triangle's corners again).
fn trace_rays<N: Hierarchy + Sync, P: LeafPrimitives + Sync>(
    rays: &[RayRecord],
    nodes: N,
    prims: &P,
) -> Vec<HitRecord> {
    rays.par_iter()
        .with_min_len(256)
        .map(|r| {
            let ray = Ray::new(Vec3::from(r.origin), Vec3::from(r.dir));
            let hit = closest_hit(nodes, prims, &ray, r.t_max, &mut Uncounted);
            HitRecord {
                t: hit.t,
                prim: hit.prim,
            }
        })
        .collect()
}

/// [`Backend::time_traces`] on the CPU.
pub(super) fn time_traces_cpu(scenes: &[&Scene], rays: &[RayRecord], warmup: usize, repeats: usize) -> Vec<TimedTrace> {
    let mut timed: Vec<TimedTrace> = (scenes.iter())
        .map(|_| TimedTrace {
            hits: Vec::new(),
            seconds: Vec::new(),
        })
        .collect();
    for k in 0..warmup + repeats {
        for turn in 0..scenes.len() {
            let s = in_turn(k, turn, scenes.len());
            let start = Instant::now();
            timed[s].hits = trace_cpu(scenes[s], rays);
            if k >= warmup {
                timed[s].seconds.push(start.elapsed().as_secs_f64());
            }
        }
    }
    timed
}
