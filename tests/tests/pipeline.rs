//! The library's front door, as an embedder uses it: open, build, frame, render.

use gridrt::backend::cpu::render_cpu;
use gridrt::backend::{Backend, BackendChoice, AO_SAMPLES_PER_PASS};
use gridrt::camera;
use gridrt::image_io::fraction_within;
use gridrt::input;
use gridrt::pipeline::{BuildOptions, RenderOptions, Representation, Shading};
use gridrt::scene::Scene;
use gridrt_shared::layout::{AO_MISS, AO_OPEN_MASK, NO_HIT};
use gridrt_shared::shade::ao_pixel;
use gridrt_tests::gpu_or_skip;

/// The GPU backend, or `None` where the tests skip it.
fn gpu_backend(test: &str) -> Option<Backend> {
    gpu_or_skip(test).map(|_| Backend::open(BackendChoice::Gpu).unwrap())
}

/// The built-in scene at L = 2 in both representations, built through the pipeline.
fn both_scenes() -> Vec<(Representation, Scene)> {
    let input = input::open(None).unwrap();
    [Representation::Grids, Representation::Triangles]
        .map(|representation| {
            let options = BuildOptions {
                representation,
                ..BuildOptions::levels(2)
            };
            (representation, Scene::build(&input.mesh, &options).unwrap())
        })
        .into()
}

#[test]
fn the_pipeline_renders_both_representations_on_both_backends() {
    let input = input::open(None).unwrap();
    assert_eq!((input.name.as_str(), input.cleaning.dropped), ("default scene", 0));
    let gpu = gpu_backend("the_pipeline_renders_both_representations_on_both_backends");
    let mut images = Vec::new();
    for (representation, scene) in both_scenes() {
        let view = camera::frame(&scene.bounds(), 80, 60);
        let render = RenderOptions {
            shading: Shading::Normal,
            ..RenderOptions::default()
        };
        let image = Backend::CPU.render(&scene, &view, &render).unwrap();
        assert_eq!((image.width, image.height), (80, 60));
        // The very pixels the CPU loop renders for this frame.
        assert!(image.pixels == render_cpu(&scene, &scene.frame(view, Shading::Normal.code())));
        if let Some(gpu) = &gpu {
            let on_gpu = gpu.render(&scene, &view, &render).unwrap();
            assert!(
                fraction_within(&on_gpu.pixels, &image.pixels, 2) >= 0.995,
                "{representation:?}"
            );
        }
        images.push(image);
    }
    // Grids and the baseline hold the same micro-triangles.
    assert!(fraction_within(&images[0].pixels, &images[1].pixels, 2) >= 0.995);
}

#[test]
fn the_pipeline_refuses_what_it_cannot_build() {
    let input = input::open(None).unwrap();
    let deeper = BuildOptions {
        lod: Some(4),
        ..BuildOptions::levels(3)
    };
    let e = Scene::build(&input.mesh, &deeper).err().expect("refused").to_string();
    assert!(e.contains("level of detail 4"), "{e}");
    let e = input::open(Some("no/such/mesh.ply".as_ref()))
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("no/such/mesh.ply") && !e.contains('\n'), "{e}");
}

/// Ambient occlusion, plain and lit: the same rays from the same pixels on both backends
/// (at least 99.5% of pixels within 2/255), darker where the scene closes in, and no darker
/// than unoccluded where the rays look nowhere.
#[test]
fn ambient_occlusion_agrees_across_backends_and_darkens() {
    let gpu = gpu_backend("ambient_occlusion_agrees_across_backends_and_darkens");
    let scenes = both_scenes();
    let modes = [Shading::AmbientOcclusion, Shading::Lit];
    for ((representation, scene), shading) in scenes.iter().flat_map(|s| modes.map(|m| (s, m))) {
        let view = camera::frame(&scene.bounds(), 96, 72);
        let ao = RenderOptions {
            shading,
            ao_samples: 8,
            smooth_normals: *representation == Representation::Grids,
            ..RenderOptions::default()
        };
        let image = Backend::CPU.render(scene, &view, &ao).unwrap();
        if let Some(gpu) = &gpu {
            let on_gpu = gpu.render(scene, &view, &ao).unwrap();
            let within = fraction_within(&on_gpu.pixels, &image.pixels, 2);
            assert!(
                within >= 0.995,
                "{representation:?} {shading:?}: {:.3}% agree",
                100.0 * within
            );
        }
        // Rays that look (almost) nowhere see nothing: the plain material everywhere.
        let blind = RenderOptions {
            ao_distance: Some(1e-6),
            ..ao
        };
        let open = Backend::CPU.render(scene, &view, &blind).unwrap();
        let red = |p: u32| p & 0xff;
        let darker = image
            .pixels
            .iter()
            .zip(&open.pixels)
            .filter(|(a, b)| red(**a) < red(**b))
            .count();
        assert!(image.pixels.iter().zip(&open.pixels).all(|(a, b)| red(*a) <= red(*b)));
        assert!(
            darker > image.pixels.len() / 50,
            "{representation:?}: only {darker} pixels occluded"
        );
    }
}

/// Ambient occlusion renders progressively: passes of samples whose open rays add up to
/// exactly those of one pass casting them all (the lights of lit shading kept once), the
/// progress reported after each.
#[test]
fn ambient_occlusion_passes_add_up_to_one() {
    for shading in [Shading::AmbientOcclusion, Shading::Lit] {
        occlusion_passes_add_up_to_one(shading);
    }
}

fn occlusion_passes_add_up_to_one(shading: Shading) {
    let (_, scene) = both_scenes().remove(0);
    let view = camera::frame(&scene.bounds(), 64, 48);
    let samples = 2 * AO_SAMPLES_PER_PASS + 3;
    let options = RenderOptions {
        shading,
        ao_samples: samples,
        ..RenderOptions::default()
    };
    let reported = std::sync::Mutex::new(Vec::new());
    let image = Backend::CPU
        .render_reporting(&scene, &view, &options, &|done| reported.lock().unwrap().push(done))
        .unwrap();
    assert_eq!(
        reported.into_inner().unwrap(),
        [AO_SAMPLES_PER_PASS, 2 * AO_SAMPLES_PER_PASS, samples]
    );
    // One pass of every sample, coloured the same way.
    let frame = options.frame(&scene, &view);
    let counts = Backend::CPU.render_frame(&scene, &frame).unwrap();
    let open = |c: u32| c & AO_OPEN_MASK;
    assert!(counts.contains(&AO_MISS) && counts.iter().any(|&c| open(c) > 0 && open(c) < samples));
    let whole: Vec<u32> = counts
        .iter()
        .enumerate()
        .map(|(i, &c)| ao_pixel(&frame, i as u32 % 64, i as u32 / 64, c, samples))
        .collect();
    assert!(image.pixels == whole);
}

/// Every shading mode through the pipeline: a picture that is not blank, the same on the GPU
/// as on the CPU (within the tolerance `gpu_vs_cpu` explains), and each mode a picture of its
/// own.
#[test]
fn every_shading_mode_agrees_across_backends() {
    let gpu = gpu_backend("every_shading_mode_agrees_across_backends");
    let modes = [
        Shading::EyeLight,
        Shading::Normal,
        Shading::Primitive,
        Shading::AmbientOcclusion,
        Shading::Lit,
        Shading::Depth,
        Shading::Cost,
    ];
    for (representation, scene) in both_scenes() {
        let view = camera::frame(&scene.bounds(), 96, 72);
        let mut pictures = Vec::new();
        // Level colouring is for grids (the baseline refuses it, see `level_of_detail`).
        let modes: Vec<Shading> = match representation {
            Representation::Grids => [&modes[..], &[Shading::Level]].concat(),
            Representation::Triangles => modes.to_vec(),
        };
        for &shading in &modes {
            let options = RenderOptions {
                shading,
                ao_samples: 4,
                ..RenderOptions::default()
            };
            let image = Backend::CPU.render(&scene, &view, &options).unwrap();
            let background = image.pixels[0];
            let covered = image.pixels.iter().filter(|&&p| p != background).count();
            assert!(
                covered > image.pixels.len() / 10,
                "{representation:?} {shading:?}: blank"
            );
            if let Some(gpu) = &gpu {
                let on_gpu = gpu.render(&scene, &view, &options).unwrap();
                let within = fraction_within(&on_gpu.pixels, &image.pixels, 2);
                assert!(
                    within >= 0.995,
                    "{representation:?} {shading:?}: {:.3}% agree",
                    100.0 * within
                );
            }
            pictures.push(image);
        }
        for (a, b) in (0..modes.len()).flat_map(|a| (a + 1..modes.len()).map(move |b| (a, b))) {
            assert!(
                fraction_within(&pictures[a].pixels, &pictures[b].pixels, 2) < 0.9,
                "{representation:?}: {:?} looks like {:?}",
                modes[a],
                modes[b]
            );
        }
    }
}

/// The heat map counts what each traversal does: a ray that misses the scene's box tests one
/// node and nothing else; grids test spheres, the baseline none; every hit tests a triangle.
/// Asked of the GPU backend, it counts the same (on the CPU: the GPU keeps no kernels for it).
#[test]
fn the_cost_heat_map_counts_each_traversals_tests() {
    let gpu = gpu_backend("the_cost_heat_map_counts_each_traversals_tests");
    for (representation, scene) in both_scenes() {
        // Far enough that the corners miss the scene's box.
        let bounds = scene.bounds();
        let far = camera::Viewpoint {
            distance: Some(2.0 * (bounds.max - bounds.min).length()),
            ..camera::Viewpoint::default()
        };
        let view = camera::view(&bounds, &far, 64, 48).unwrap();
        let costs = Backend::CPU
            .render_costs(&scene, &view, &RenderOptions::default())
            .unwrap();
        let corner = costs.costs[0];
        assert_eq!((corner.nodes, corner.spheres, corner.triangles), (1, 0, 0));
        let hits = Backend::CPU.trace(&scene, &gridrt::rays::view_rays(&view)).unwrap();
        assert!(hits.iter().any(|h| h.prim != NO_HIT));
        for (c, hit) in costs.costs.iter().zip(&hits) {
            if hit.prim != NO_HIT {
                assert!(
                    c.triangles > 0 && c.nodes > 1,
                    "{representation:?}: a hit without tests"
                );
            }
            match representation {
                Representation::Grids => assert!(c.triangles == 0 || c.spheres > 0),
                Representation::Triangles => assert_eq!(c.spheres, 0),
            }
        }
        let summary = costs.summary();
        assert!(summary.p99_total <= summary.max_total && summary.mean_triangles > 0.0);
        if let Some(gpu) = &gpu {
            let on_gpu = gpu.render_costs(&scene, &view, &RenderOptions::default()).unwrap();
            assert!(on_gpu.costs == costs.costs, "{representation:?}: the counts differ");
        }
    }
}

/// `Backend::trace` takes any rays: the primary rays of a view find the scene in both
/// representations, and the GPU finds the same hits.
#[test]
fn the_backends_trace_ray_lists_alike() {
    let gpu = gpu_backend("the_backends_trace_ray_lists_alike");
    for (representation, scene) in both_scenes() {
        let rays = gridrt::rays::view_rays(&camera::frame(&scene.bounds(), 64, 48));
        let hits = Backend::CPU.trace(&scene, &rays).unwrap();
        assert_eq!(hits.len(), rays.len());
        let found = hits.iter().filter(|h| h.prim != NO_HIT).count();
        assert!(found > rays.len() / 10, "{representation:?}: {found} hits");
        if let Some(gpu) = &gpu {
            let on_gpu = gpu.trace(&scene, &rays).unwrap();
            let same = on_gpu.iter().zip(&hits).filter(|(a, b)| a.prim == b.prim).count();
            assert!(
                same as f64 >= 0.999 * rays.len() as f64,
                "{representation:?}: {same} agree"
            );
        }
    }
}
