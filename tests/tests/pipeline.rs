//! The library's front door, as an embedder uses it: open, build, frame, render.

use gridrt::backend::{Backend, BackendChoice};
use gridrt::camera;
use gridrt::image_io::fraction_within;
use gridrt::mesh;
use gridrt::pipeline::{BuildOptions, RenderOptions, Representation, Shading};
use gridrt::scene::{render_cpu, Scene};
use gridrt_tests::gpu_or_skip;

/// The GPU backend, or `None` where the tests skip it.
fn gpu_backend(test: &str) -> Option<Backend> {
    gpu_or_skip(test).map(|_| Backend::open(BackendChoice::Gpu).unwrap())
}

/// The built-in scene at L = 2 in both representations, built through the pipeline.
fn both_scenes() -> Vec<(Representation, Scene)> {
    let input = mesh::open(None).unwrap();
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
    let input = mesh::open(None).unwrap();
    assert_eq!((input.name.as_str(), input.dropped), ("default scene", 0));
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
    let input = mesh::open(None).unwrap();
    let deeper = BuildOptions {
        lod: Some(4),
        ..BuildOptions::levels(3)
    };
    let e = Scene::build(&input.mesh, &deeper).err().expect("refused").to_string();
    assert!(e.contains("level of detail 4"), "{e}");
    let e = mesh::open(Some("no/such/mesh.ply".as_ref()))
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("no/such/mesh.ply") && !e.contains('\n'), "{e}");
}

/// Ambient occlusion: the same rays from the same pixels on both backends, darker where the
/// scene closes in, and no darker than the plain material where the rays look nowhere.
#[test]
fn ambient_occlusion_agrees_across_backends_and_darkens() {
    let gpu = gpu_backend("ambient_occlusion_agrees_across_backends_and_darkens");
    for (representation, scene) in both_scenes() {
        let view = camera::frame(&scene.bounds(), 96, 72);
        let ao = RenderOptions {
            shading: Shading::AmbientOcclusion,
            ao_samples: 8,
            ..RenderOptions::default()
        };
        let image = Backend::CPU.render(&scene, &view, &ao).unwrap();
        if let Some(gpu) = &gpu {
            let on_gpu = gpu.render(&scene, &view, &ao).unwrap();
            let within = fraction_within(&on_gpu.pixels, &image.pixels, 2);
            assert!(within >= 0.99, "{representation:?}: {:.3}% agree", 100.0 * within);
        }
        // Rays that look (almost) nowhere see nothing: the plain material everywhere.
        let blind = RenderOptions {
            ao_distance: Some(1e-6),
            ..ao
        };
        let open = Backend::CPU.render(&scene, &view, &blind).unwrap();
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
