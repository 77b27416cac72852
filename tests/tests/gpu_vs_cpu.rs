//! The GPU kernels and the CPU loop run the same `gridrt_shared` code: their images must agree.
//!
//! Tolerance: at least 99.5% of pixels within 2/255 in every channel. The GPU may contract
//! `a * b + c` into fused multiply-adds and evaluate `powf`/`sqrt` with a few ulps of
//! difference, so a pixel can round to the neighbouring 8-bit value, and a ray that grazes
//! a silhouette or a shared edge can resolve to the other side; the remaining 0.5% allows for
//! those silhouette pixels, and no more.

use gridrt::backend::cpu::render_cpu;
use gridrt::camera;
use gridrt::image_io::{fraction_within, pixel_difference};
use gridrt::input::load_mesh;
use gridrt::mesh::scene::default_scene;
use gridrt::mesh::Mesh;
use gridrt::scene::Scene;
use gridrt::subdiv::Scheme;
use gridrt_shared::layout::{SHADE_EYE_LIGHT, SHADE_NORMAL};
use gridrt_tests::{build_pair, gpu_or_skip, meshes_dir_or_skip};

const TOLERANCE: u32 = 2;
const MIN_FRACTION: f64 = 0.995;

fn compare(gpu: &gridrt::backend::gpu::Gpu, name: &str, scene: &Scene, bounds: &gridrt::bvh::Aabb, shading: u32) {
    let frame = scene.frame(camera::frame(bounds, 256, 192), shading);
    let cpu_image = render_cpu(scene, &frame);
    let gpu_image = gpu.render(scene, &frame).expect("GPU render");
    let within = fraction_within(&cpu_image, &gpu_image, TOLERANCE);
    let exact = fraction_within(&cpu_image, &gpu_image, 0);
    let worst = cpu_image
        .iter()
        .zip(&gpu_image)
        .map(|(a, b)| pixel_difference(*a, *b))
        .max()
        .unwrap();
    eprintln!(
        "{name}: {:.3}% identical, {:.3}% within {TOLERANCE}/255, worst {worst}/255",
        100.0 * exact,
        100.0 * within
    );
    assert!(
        within >= MIN_FRACTION,
        "{name}: only {:.3}% of pixels agree",
        100.0 * within
    );
    // Not a blank picture: the scene covers a good part of the frame.
    let background = cpu_image[0];
    let covered = cpu_image.iter().filter(|&&p| p != background).count();
    assert!(
        covered > cpu_image.len() / 10,
        "{name}: the scene covers too little of the image"
    );
}

fn both_modes(gpu: &gridrt::backend::gpu::Gpu, name: &str, mesh: &Mesh, levels: u32) {
    let pair = build_pair(mesh, levels, levels, Scheme::Loop);
    compare(
        gpu,
        &format!("{name} triangles"),
        &pair.triangles,
        &pair.bounds,
        SHADE_EYE_LIGHT,
    );
    compare(
        gpu,
        &format!("{name} grids"),
        &pair.grids,
        &pair.bounds,
        SHADE_EYE_LIGHT,
    );
    compare(
        gpu,
        &format!("{name} grids, normals"),
        &pair.grids,
        &pair.bounds,
        SHADE_NORMAL,
    );
}

/// Grid options whose hierarchies at `L = 3` are deeper than one visit walks (see
/// `GridParams::one_visit`): the kernels with the sub-triangle stack, here over a wide top
/// level.
fn stacked_options() -> gridrt::grid::GridOptions {
    gridrt::grid::GridOptions {
        excluded_levels: 1,
        radii: gridrt::grid::RadiusFormat::Half,
        leaf_footprint: true,
        top: gridrt::grid::TopFormat::Wide,
        tight_headers: true,
        own_rooms: true,
    }
}

#[test]
fn default_scene_gpu_equals_cpu() {
    let Some(gpu) = gpu_or_skip("default_scene_gpu_equals_cpu") else {
        return;
    };
    both_modes(&gpu, "default scene L=0", &default_scene(), 0);
    both_modes(&gpu, "default scene L=3", &default_scene(), 3);
    // Coarser level of detail from the same grid data.
    let mut pair = build_pair(&default_scene(), 3, 1, Scheme::Loop);
    if let Scene::Grids(g) = &mut pair.grids {
        g.set_lod(1).unwrap();
    }
    compare(&gpu, "default scene L=3 lod 1", &pair.grids, &pair.bounds, SHADE_NORMAL);
    let options = gridrt::grid::GridOptions {
        leaf_footprint: false,
        ..stacked_options()
    };
    let pair = gridrt_tests::build_pair_from(&default_scene(), 3, 3, Scheme::Loop, &options, false);
    compare(
        &gpu,
        "default scene L=3 half radii, 1 level out, f32 inner vertices",
        &pair.grids,
        &pair.bounds,
        SHADE_NORMAL,
    );
}

#[test]
fn teapot_gpu_equals_cpu() {
    let Some(gpu) = gpu_or_skip("teapot_gpu_equals_cpu") else {
        return;
    };
    let Some(dir) = meshes_dir_or_skip("teapot_gpu_equals_cpu") else {
        return;
    };
    both_modes(&gpu, "teapot L=2", &load_mesh(&dir.join("teapot.obj")).unwrap(), 2);
}

/// The ray-list kernels the benchmark times find the same hits as the CPU.
#[test]
fn ray_lists_gpu_equal_cpu() {
    let Some(gpu) = gpu_or_skip("ray_lists_gpu_equal_cpu") else {
        return;
    };
    use gridrt::backend::cpu::trace_cpu;
    use gridrt::rays::{ao_rays, primary_rays};
    let pair = build_pair(&default_scene(), 3, 3, Scheme::Loop);
    let primary = primary_rays(&pair.bounds, 2, 96, 64);
    let first = trace_cpu(&pair.triangles, &primary);
    let ao = ao_rays(&primary, &first, 2, &pair.bounds, |p| pair.triangles.normal(p));
    assert!(ao.len() > primary.len() / 4);
    // One level fewer out of the sphere hierarchy: its grids take the kernels with the stack.
    let stacked = gridrt_tests::build_pair_with(&default_scene(), 3, 3, Scheme::Loop, &stacked_options());
    let scenes = [
        ("grids", &pair.grids),
        ("grids, stacked walk", &stacked.grids),
        ("triangles", &pair.triangles),
    ];
    for (name, scene) in scenes {
        let uploaded = gpu.upload(scene).unwrap();
        for (kind, rays) in [("primary", &primary), ("ao", &ao)] {
            let cpu = trace_cpu(scene, rays);
            let gpu_hits = gpu.trace(&uploaded, rays).unwrap();
            assert_eq!(cpu.len(), gpu_hits.len());
            let same = cpu
                .iter()
                .zip(&gpu_hits)
                .filter(|(a, b)| a.prim == b.prim && (a.t - b.t).abs() <= 1e-4 * a.t.abs().max(1e-6))
                .count();
            let fraction = same as f64 / cpu.len() as f64;
            eprintln!(
                "{name} {kind}: {} rays, {:.4}% same hit on GPU and CPU",
                rays.len(),
                100.0 * fraction
            );
            assert!(fraction >= 0.999, "{name} {kind}: only {:.4}% agree", 100.0 * fraction);
        }
    }
}

/// Scenes timed in turn keep the hits each finds alone, over a list cut into several
/// batches.
#[test]
fn scenes_in_turn_keep_their_hits() {
    let Some(mut gpu) = gpu_or_skip("scenes_in_turn_keep_their_hits") else {
        return;
    };
    let pair = build_pair(&default_scene(), 3, 3, Scheme::Loop);
    let rays = gridrt::rays::primary_rays(&pair.bounds, 2, 256, 192);
    // Bindings small enough that the list takes several batches, large enough that the scene
    // is still bound whole.
    gpu.limit_bindings(1 << 20).unwrap();
    let grids = gpu.upload(&pair.grids).unwrap();
    let triangles = gpu.upload(&pair.triangles).unwrap();
    assert!(
        !grids.is_split(),
        "the default scene no longer fits the test's bindings"
    );
    let record = std::mem::size_of::<gridrt_shared::layout::RayRecord>();
    assert!(rays.len() * record > 2 << 20, "the list fits fewer than three batches");
    let alone = [gpu.trace(&grids, &rays).unwrap(), gpu.trace(&triangles, &rays).unwrap()];
    let timed = gpu.time_traces(&[grids, triangles], &rays, 3).unwrap();
    for ((list, alone), name) in timed.iter().zip(&alone).zip(["grids", "triangles"]) {
        assert_eq!(list.seconds.len(), 3, "{name}: one time per repetition");
        assert!(list.hits == *alone, "{name}: the hits taken in turn differ");
    }
}
