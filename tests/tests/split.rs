//! Scenes larger than one GPU binding: their buffers are cut into chunks and read through the
//! same shared traversal (see `gridrt_shared::buffer`). Forced here by a small binding limit,
//! so the scenes stay small: the split reads must give exactly what the whole reads give, on
//! the CPU and on the GPU, and what cannot be bound (too many chunks, or displaced grids,
//! which are bound whole) must be refused with its sizes.

use gridrt::backend::cpu::{render_cpu, trace_cpu};
use gridrt::bvh::Aabb;
use gridrt::camera;
use gridrt::grid::{GridOptions, TopFormat};
use gridrt::image_io::fraction_within;
use gridrt::mesh::scene::default_scene;
use gridrt::rays::primary_rays;
use gridrt::scene::Scene;
use gridrt::split::{render_cpu_split, scene_buffers, split};
use gridrt::subdiv::Scheme;
use gridrt_shared::buffer::SPLIT_CHUNKS;
use gridrt_shared::layout::SHADE_NORMAL;
use gridrt_tests::{baked_ball, build_pair, build_pair_with, displaced_grids, gpu_or_skip, Pair};

/// The smallest power-of-two chunk (at least 1 KiB) that holds `scene` in at most
/// [`SPLIT_CHUNKS`] chunks; the tests check that it still cuts every buffer larger than 1 KiB.
fn smallest_chunk_bytes(scene: &Scene) -> u64 {
    let mut bytes = 1024;
    while split(scene, (bytes / 4) as u32, "test").is_err() {
        bytes *= 2;
    }
    bytes
}

fn pair() -> Pair {
    build_pair(&default_scene(), 2, 2, Scheme::Loop)
}

/// Grids whose hierarchies take the stack (every level with spheres: deeper than one visit
/// walks, see `GridParams::one_visit`).
fn stacked_grids() -> Scene {
    let options = GridOptions {
        excluded_levels: 0,
        top: TopFormat::Compact,
        tight_headers: true,
        ..GridOptions::default()
    };
    build_pair_with(&default_scene(), 2, 2, Scheme::Loop, &options).grids
}

/// The scenes each split test runs: both walks of grids, and the baseline.
fn named_scenes<'a>(pair: &'a Pair, stacked: &'a Scene) -> [(&'static str, &'a Scene); 3] {
    [
        ("grids", &pair.grids),
        ("grids, stacked walk", stacked),
        ("triangles", &pair.triangles),
    ]
}

#[test]
fn cpu_reads_split_scenes_as_whole_ones() {
    let pair = pair();
    let stacked = stacked_grids();
    for (name, scene) in named_scenes(&pair, &stacked) {
        let bytes = smallest_chunk_bytes(scene);
        let cut = split(scene, (bytes / 4) as u32, "test").unwrap();
        let buffers = scene_buffers(scene);
        eprintln!(
            "{name}: {} chunks of {bytes} bytes for {:?}",
            cut.chunks.len(),
            buffers.iter().map(|b| b.words.len() * 4).collect::<Vec<_>>()
        );
        // Every buffer larger than a chunk is cut, so each is read across chunk boundaries.
        let cut_buffers = buffers.iter().filter(|b| b.words.len() * 4 > bytes as usize).count();
        assert!(cut_buffers >= 2, "{name}");
        let frame = scene.frame(camera::frame(&scene.bounds(), 96, 72), SHADE_NORMAL);
        assert_eq!(
            render_cpu(scene, &frame),
            render_cpu_split(scene, &cut, &frame),
            "{name}"
        );
    }
}

#[test]
fn too_many_chunks_are_refused_with_the_sizes() {
    let pair = pair();
    let err = split(&pair.grids, 8, "a small GPU").err().expect("refused").to_string();
    for part in [
        "grid vertex",
        "bytes",
        &format!("{SPLIT_CHUNKS}"),
        "a small GPU",
        "--backend cpu",
    ] {
        assert!(err.contains(part), "{err:?} lacks {part:?}");
    }
    assert!(!err.contains('\n'), "{err:?} is not one line");
}

/// What the GPU gives for `scene` with a binding limit small enough to split it: its own
/// whole-scene results exactly, and the CPU's within the usual tolerance; rendered in tiles
/// (`render`), and traced as batched ray lists (`trace`).
fn split_on_the_gpu_equals_whole(name: &str, scene: &Scene, bounds: &Aabb, render: bool, trace: bool) {
    let Some(whole_gpu) = gpu_or_skip(name) else {
        return;
    };
    let mut gpu = gpu_or_skip(name).unwrap();
    gpu.limit_bindings(smallest_chunk_bytes(scene)).unwrap();
    let uploaded = gpu.upload(scene).unwrap();
    assert!(uploaded.is_split(), "{name}: not split");
    if render {
        let frame = scene.frame(camera::frame(bounds, 96, 72), SHADE_NORMAL);
        let image = gpu.render_uploaded(&uploaded, &frame).unwrap();
        assert_eq!(image, whole_gpu.render(scene, &frame).unwrap(), "{name}: split image");
        let within = fraction_within(&image, &render_cpu(scene, &frame), 2);
        assert!(
            within >= 0.995,
            "{name}: {:.3}% of pixels agree with the CPU",
            100.0 * within
        );
    }
    if trace {
        let rays = primary_rays(bounds, 1, 64, 48);
        let hits = gpu.trace(&uploaded, &rays).unwrap();
        let whole_hits = whole_gpu.trace(&whole_gpu.upload(scene).unwrap(), &rays).unwrap();
        assert_eq!(hits, whole_hits, "{name}: split hits");
        let cpu = trace_cpu(scene, &rays);
        let same = cpu.iter().zip(&hits).filter(|(a, b)| a.prim == b.prim).count();
        assert!(
            same as f64 >= 0.999 * cpu.len() as f64,
            "{name}: {same} of {} hits agree",
            cpu.len()
        );
    }
}

// Each grid walk is checked on the GPU through one of its two split kernels, render for one
// and ray lists for the other, in tests of their own so that lavapipe compiles them side by
// side: each takes it minutes, and both kernels of a walk run the same split reads, which
// `cpu_reads_split_scenes_as_whole_ones` checks for every walk.

#[test]
fn split_grids_on_the_gpu_render_as_whole_ones() {
    let pair = pair();
    split_on_the_gpu_equals_whole("split grids", &pair.grids, &pair.bounds, true, false);
}

#[test]
fn split_stacked_grids_on_the_gpu_trace_as_whole_ones() {
    let pair = pair();
    split_on_the_gpu_equals_whole("split stacked grids", &stacked_grids(), &pair.bounds, false, true);
}

/// Displaced grids' formats are read from whole bindings alone: a scene of them that one
/// binding cannot hold is refused as it is uploaded, naming the buffer and the limit.
#[test]
fn displaced_grids_larger_than_a_binding_are_refused() {
    let Some(mut gpu) = gpu_or_skip("displaced_grids_larger_than_a_binding_are_refused") else {
        return;
    };
    let grids = displaced_grids(&baked_ball(3));
    assert!(grids.needs_whole_bindings());
    let largest = scene_buffers(&grids).iter().map(|b| b.size().bytes).max().unwrap();
    gpu.limit_bindings(largest / 2).unwrap();
    let err = gpu.upload(&grids).err().expect("refused").to_string();
    for part in ["buffer needs", "bytes per binding", "whole bindings", "--backend cpu"] {
        assert!(err.contains(part), "{err:?} lacks {part:?}");
    }
    assert!(!err.contains('\n'), "{err:?} is not one line");
}

#[test]
fn split_triangles_on_the_gpu_equal_whole_ones() {
    let pair = pair();
    split_on_the_gpu_equals_whole("split triangles", &pair.triangles, &pair.bounds, true, true);
}

/// The same through the binary, as a user forces it: and a scene that cannot be bound at all
/// is refused before it is built, naming its buffers and the adapter's limits.
#[test]
fn binding_limit_from_the_environment() {
    if gpu_or_skip("binding_limit_from_the_environment").is_none() {
        return;
    }
    let dir = gridrt_tests::scratch("split");
    // The baseline renders (its split kernel compiles far faster than the grids'), and the
    // grids are refused before their build.
    let run = |limit: &str, out: &str, mode: &str| {
        std::process::Command::new(gridrt_tests::gridrt_exe())
            .args([
                "render",
                "--backend",
                "gpu",
                "--levels",
                "2",
                "--mode",
                mode,
                "--width",
                "96",
                "--height",
                "72",
                "-o",
            ])
            .arg(dir.join(out))
            .env("GRIDRT_GPU_BINDING_LIMIT", limit)
            .output()
            .unwrap()
    };
    let whole = run("1G", "whole.png", "triangles");
    assert!(whole.status.success(), "{}", String::from_utf8_lossy(&whole.stderr));
    let cut = run("64K", "split.png", "triangles");
    assert!(cut.status.success(), "{}", String::from_utf8_lossy(&cut.stderr));
    let read = |f: &str| image::open(dir.join(f)).unwrap().to_rgba8().into_raw();
    assert_eq!(read("whole.png"), read("split.png"), "the split render differs");
    let refused = run("1K", "refused.png", "grid");
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success());
    for part in [
        "grid vertex",
        "at least",
        "bytes per binding",
        "storage buffers per shader stage",
    ] {
        assert!(stderr.contains(part), "{stderr:?} lacks {part:?}");
    }
    assert!(
        !stderr.contains("B per micro-triangle"),
        "built before refusing: {stderr:?}"
    );
    assert!(!dir.join("refused.png").exists());
    let bad = run("lots", "bad.png", "grid");
    assert!(String::from_utf8_lossy(&bad.stderr).contains("GRIDRT_GPU_BINDING_LIMIT=lots"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A displaced micro-mesh file whose grids one binding cannot hold is refused before it is
/// built, on one line naming the file.
#[test]
fn displaced_files_larger_than_a_binding_are_refused_naming_the_file() {
    if gpu_or_skip("displaced_files_larger_than_a_binding_are_refused_naming_the_file").is_none() {
        return;
    }
    let mesh = baked_ball(4);
    let grids = displaced_grids(&mesh);
    let largest = scene_buffers(&grids).iter().map(|b| b.size().bytes).max().unwrap();
    let dir = gridrt_tests::scratch("split-displaced");
    let file = dir.join("ball.gltf");
    gridrt::micromesh::gltf::write(&file, &mesh, &gridrt::mesh::frame::LocalFrame::IDENTITY).unwrap();
    let png = dir.join("ball.png");
    let o = std::process::Command::new(gridrt_tests::gridrt_exe())
        .args(["render", "--backend", "gpu", "--width", "32", "--height", "24"])
        .arg(&file)
        .arg("-o")
        .arg(&png)
        .env("GRIDRT_GPU_BINDING_LIMIT", (largest / 2).to_string())
        .output()
        .unwrap();
    let err = gridrt_tests::stderr(&o);
    assert!(!o.status.success(), "{err}");
    let lines: Vec<&str> = err.lines().filter(|l| l.starts_with("error")).collect();
    assert_eq!(lines.len(), 1, "{err}");
    for part in ["ball.gltf", "buffer needs", "whole bindings"] {
        assert!(lines[0].contains(part), "{err:?} lacks {part:?}");
    }
    assert!(!err.contains("B per micro-triangle"), "built before refusing: {err:?}");
    assert!(!png.exists());
}
