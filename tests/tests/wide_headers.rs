//! Wide grid headers: a mesh with more than 2^21 base edges or vertices stores each grid's ids
//! as plain words, two headers per grid (see `gridrt_shared::layout::GridHeader`). Such meshes
//! are large, so the form is tried here on a small scene converted to it: the same scene must
//! give the same pictures and hits, whole and split, on the CPU and on the GPU.

use gridrt::backend::cpu::{render_cpu, trace_cpu};
use gridrt::camera;
use gridrt::grid::{GridOptions, TopFormat};
use gridrt::mesh::scene::default_scene;
use gridrt::rays::primary_rays;
use gridrt::scene::Scene;
use gridrt::split::{render_cpu_split, split};
use gridrt::subdiv::Scheme;
use gridrt_shared::layout::{FrameParams, SHADE_PRIMITIVE};
use gridrt_tests::{build_pair_with, gpu_or_skip, Pair};

/// The default scene's grids, packed and wide, and a frame of each. One level and compact top
/// nodes, so that the headers are among the largest buffers and a split scene's few chunks
/// cut them.
fn packed_and_wide() -> (Pair, Scene, [FrameParams; 2]) {
    let options = GridOptions {
        top: TopFormat::Compact,
        ..GridOptions::default()
    };
    let pair = build_pair_with(&default_scene(), 1, 1, Scheme::Loop, &options);
    let Scene::Grids(grids) = &pair.grids else {
        unreachable!()
    };
    let wide = Scene::Grids(grids.clone().with_wide_headers());
    let Scene::Grids(w) = &wide else { unreachable!() };
    assert_eq!(w.params.wide_headers, 1);
    assert_eq!(w.headers.len(), 2 * grids.headers.len());
    let camera = camera::frame(&pair.bounds, 96, 72);
    let frames = [&pair.grids, &wide].map(|s| s.frame(camera, SHADE_PRIMITIVE));
    (pair, wide, frames)
}

/// Smallest power-of-two chunk, from 1 KiB, that holds `scene` in a split scene's chunks.
fn smallest_chunk_words(scene: &Scene) -> u32 {
    let mut words = 256;
    while split(scene, words, "test").is_err() {
        words *= 2;
    }
    words
}

#[test]
fn wide_headers_read_as_packed_ones_on_the_cpu() {
    let (pair, wide, [packed_frame, wide_frame]) = packed_and_wide();
    let image = render_cpu(&pair.grids, &packed_frame);
    assert!(render_cpu(&wide, &wide_frame) == image, "whole");
    let words = smallest_chunk_words(&wide);
    let Scene::Grids(w) = &wide else { unreachable!() };
    assert!(w.headers.len() * 4 > words as usize, "the headers are not cut");
    let cut = split(&wide, words, "test").unwrap();
    assert!(render_cpu_split(&wide, &cut, &wide_frame) == image, "split");
    let rays = primary_rays(&pair.bounds, 1, 64, 48);
    assert!(trace_cpu(&wide, &rays) == trace_cpu(&pair.grids, &rays), "hits");
}

#[test]
fn wide_headers_read_as_packed_ones_on_the_gpu() {
    let Some(gpu) = gpu_or_skip("wide_headers_read_as_packed_ones_on_the_gpu") else {
        return;
    };
    let (pair, wide, [packed_frame, wide_frame]) = packed_and_wide();
    let image = gpu.render(&pair.grids, &packed_frame).unwrap();
    assert!(gpu.render(&wide, &wide_frame).unwrap() == image, "whole");
    let rays = primary_rays(&pair.bounds, 1, 64, 48);
    let hits = gpu.trace(&gpu.upload(&pair.grids).unwrap(), &rays).unwrap();
    assert!(gpu.trace(&gpu.upload(&wide).unwrap(), &rays).unwrap() == hits, "hits");
    // Split, through the render kernel that tests/split.rs compiles too (each split kernel
    // takes lavapipe minutes to compile; the split reads of both jobs are one code, which
    // the CPU test above checks with wide headers).
    let mut small = gpu_or_skip("wide_headers_read_as_packed_ones_on_the_gpu").unwrap();
    small.limit_bindings(4 * smallest_chunk_words(&wide) as u64).unwrap();
    let uploaded = small.upload(&wide).unwrap();
    assert!(uploaded.is_split());
    assert!(small.render_uploaded(&uploaded, &wide_frame).unwrap() == image, "split");
}
