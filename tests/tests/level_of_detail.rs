//! Level of detail per grid (`RenderOptions::lod_pixels`) and level colouring, through the
//! pipeline on both backends.

use gridrt::backend::Backend;
use gridrt::camera::{self, Viewpoint};
use gridrt::grid::GridScene;
use gridrt::image_io::fraction_within;
use gridrt::lod::LodReport;
use gridrt::mesh::Mesh;
use gridrt::pipeline::{BuildOptions, Image, RenderOptions, Representation, Shading};
use gridrt::scene::Scene;
use gridrt_shared::glam::Vec3;
use gridrt_shared::layout::Camera;
use gridrt_shared::shade::level_color;
use gridrt_tests::gpu_or_skip;

const LEVELS: u32 = 4;

/// A bumpy strip of ground, 40 units wide and 80 long (towards -z), in 2-unit squares.
fn ground() -> Mesh {
    let (columns, rows) = (20u32, 40u32);
    let mut positions = Vec::new();
    for r in 0..=rows {
        for c in 0..=columns {
            let (x, z) = (-20.0 + 2.0 * c as f32, -2.0 * r as f32);
            positions.push(Vec3::new(x, 0.3 * ((x * 1.7).sin() + (z * 0.9).cos()), z));
        }
    }
    let at = |r: u32, c: u32| r * (columns + 1) + c;
    let mut triangles = Vec::new();
    for r in 0..rows {
        for c in 0..columns {
            triangles.push([at(r, c), at(r, c + 1), at(r + 1, c)]);
            triangles.push([at(r, c + 1), at(r + 1, c + 1), at(r + 1, c)]);
        }
    }
    Mesh { positions, triangles }
}

/// Above the strip's near end, looking along it.
fn along_the_ground(scene: &Scene) -> Camera {
    let viewpoint = Viewpoint {
        eye: Some(Vec3::new(0.0, 12.0, 4.0)),
        target: Some(Vec3::new(0.0, 0.0, -40.0)),
        fov_degrees: 50.0,
        ..Viewpoint::default()
    };
    camera::view(&scene.bounds(), &viewpoint, 160, 120).unwrap()
}

fn grids(scene: &Scene) -> &GridScene {
    match scene {
        Scene::Grids(g) => g,
        Scene::Triangles(_) => unreachable!("built as grids"),
    }
}

/// The depth a level-coloured pixel shows, or `None` for the background: the palette colour
/// whose channel ratios are nearest (light and gamma scale all three channels alike, so the
/// ratios survive them).
fn level_of(pixel: u32) -> Option<u32> {
    let channels = [pixel & 0xff, (pixel >> 8) & 0xff, (pixel >> 16) & 0xff].map(|c| c as f32);
    let ratios = |c: [f32; 3]| {
        let max = c[0].max(c[1]).max(c[2]);
        c.map(|v| v / max)
    };
    let seen = ratios(channels);
    let distance = |level: u32| {
        let palette = ratios(level_color(level).to_array().map(|v| v.powf(1.0 / 2.2)));
        (0..3).map(|i| (palette[i] - seen[i]).abs()).sum::<f32>()
    };
    let best = (0..=6).min_by(|&a, &b| distance(a).total_cmp(&distance(b)))?;
    (distance(best) < 0.08).then_some(best)
}

/// The most common level of each row of a level-coloured picture with enough ground in it.
fn row_levels(image: &Image) -> Vec<(u32, u32)> {
    let width = image.width as usize;
    (0..image.height)
        .filter_map(|y| {
            let row = &image.pixels[y as usize * width..][..width];
            let mut count = [0usize; 7];
            row.iter()
                .filter_map(|&p| level_of(p))
                .for_each(|l| count[l as usize] += 1);
            let (level, &n) = count.iter().enumerate().max_by_key(|(_, &n)| n)?;
            (n > width / 8).then_some((y, level as u32))
        })
        .collect()
}

#[test]
fn lod_auto_renders_farther_grids_coarser() {
    let scene = Scene::build(&ground(), &BuildOptions::levels(LEVELS)).unwrap();
    let view = along_the_ground(&scene);
    let options = RenderOptions {
        shading: Shading::Level,
        lod_pixels: Some(4.0),
        ..RenderOptions::default()
    };
    let image = Backend::CPU.render(&scene, &view, &options).unwrap();
    let rows = row_levels(&image);
    assert!(rows.len() > 40, "only {} rows of ground", rows.len());
    // Rows run from the far end (top) to the near end (bottom): never finer farther away.
    for pair in rows.windows(2) {
        assert!(
            pair[0].1 <= pair[1].1,
            "row {} at level {} above row {} at {}",
            pair[0].0,
            pair[0].1,
            pair[1].0,
            pair[1].1
        );
    }
    let (far, near) = (rows[0].1, rows[rows.len() - 1].1);
    assert!(near >= 3 && far + 2 <= near, "levels {far} far to {near} near");
    // The report counts the same choice: every grid once, several depths, cracks measured and
    // narrower than the target size of the coarser side's triangles.
    let report = LodReport::measure(grids(&scene), &options.frame(&scene, &view));
    assert_eq!(report.grids_per_level.iter().sum::<usize>(), grids(&scene).grid_count());
    assert!(report.grids_per_level.iter().filter(|&&n| n > 0).count() >= 3);
    assert!(report.mismatched_edges > 0);
    assert!(
        report.widest_crack_pixels > 0.0 && report.widest_crack_pixels < 2.0,
        "{report:?}"
    );
    if let Some(gpu) = gpu_or_skip("lod_auto_renders_farther_grids_coarser") {
        let gpu = Backend::Gpu(Box::new(gpu));
        for shading in [Shading::Level, Shading::AmbientOcclusion] {
            let options = RenderOptions {
                shading,
                ao_samples: 4,
                ..options
            };
            let cpu = Backend::CPU.render(&scene, &view, &options).unwrap();
            let on_gpu = gpu.render(&scene, &view, &options).unwrap();
            assert!(fraction_within(&on_gpu.pixels, &cpu.pixels, 2) >= 0.995, "{shading:?}");
        }
    }
}

/// The extremes of the target size are the fixed depths: a tiny one renders every grid in
/// full, a huge one every grid as its base triangle.
#[test]
fn lod_auto_spans_the_fixed_depths() {
    let mesh = ground();
    let full = Scene::build(&mesh, &BuildOptions::levels(LEVELS)).unwrap();
    let coarsest = Scene::build(
        &mesh,
        &BuildOptions {
            lod: Some(0),
            ..BuildOptions::levels(LEVELS)
        },
    )
    .unwrap();
    let view = along_the_ground(&full);
    let normal = RenderOptions {
        shading: Shading::Normal,
        ..RenderOptions::default()
    };
    let render = |scene: &Scene, lod_pixels| {
        let options = RenderOptions { lod_pixels, ..normal };
        Backend::CPU.render(scene, &view, &options).unwrap().pixels
    };
    assert!(render(&full, Some(1e-6)) == render(&full, None));
    assert!(render(&full, Some(1e9)) == render(&coarsest, None));
    assert!(render(&full, Some(1e9)) != render(&full, None));
}

#[test]
fn what_needs_grids_is_refused_for_the_baseline() {
    let options = BuildOptions {
        representation: Representation::Triangles,
        ..BuildOptions::levels(1)
    };
    let scene = Scene::build(&ground(), &options).unwrap();
    let view = along_the_ground(&scene);
    for asked in [
        RenderOptions {
            lod_pixels: Some(2.0),
            ..RenderOptions::default()
        },
        RenderOptions {
            shading: Shading::Level,
            ..RenderOptions::default()
        },
    ] {
        let error = Backend::CPU.render(&scene, &view, &asked).unwrap_err().to_string();
        assert!(error.contains("baseline"), "{error}");
    }
    let grids = Scene::build(&ground(), &BuildOptions::levels(1)).unwrap();
    for pixels in [0.0, -1.0, f32::NAN] {
        let asked = RenderOptions {
            lod_pixels: Some(pixels),
            ..RenderOptions::default()
        };
        assert!(Backend::CPU.render(&grids, &view, &asked).is_err());
    }
}
