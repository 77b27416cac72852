//! Smooth normals for grids: the lattice's finite differences follow the surface the
//! micro-vertices sample, inside grids and across their shared edges, on both backends.

use gridrt::backend::{Backend, BackendChoice};
use gridrt::camera;
use gridrt::grid::{build_lean, GridBuild, GridScene};
use gridrt::image_io::fraction_within;
use gridrt::input;
use gridrt::mesh::scene::octahedron;
use gridrt::mesh::Mesh;
use gridrt::pipeline::{BuildOptions, RenderOptions, Representation, Shading};
use gridrt::scene::Scene;
use gridrt::subdiv::Scheme;
use gridrt_shared::glam::Vec3;
use gridrt_shared::grid_index::triangle_count;
use gridrt_shared::layout::Hit;
use gridrt_shared::triangle::triangle_normal;
use gridrt_tests::{gpu_or_skip, Rng};

/// A flat `cells x cells` square in the xy plane over `[-1, 1]^2`, two triangles a cell.
fn square(cells: u32) -> Mesh {
    let row = cells + 1;
    let positions = (0..row * row)
        .map(|k| {
            let (i, j) = (k % row, k / row);
            Vec3::new(i as f32, j as f32, 0.0) * (2.0 / cells as f32) - Vec3::new(1.0, 1.0, 0.0)
        })
        .collect();
    let mut triangles = Vec::new();
    for j in 0..cells {
        for i in 0..cells {
            let v = j * row + i;
            triangles.push([v, v + 1, v + row + 1]);
            triangles.push([v, v + row + 1, v + row]);
        }
    }
    Mesh { positions, triangles }
}

/// A smooth height field and its unit normal.
fn height(x: f32, y: f32) -> f32 {
    0.25 * (2.0 * x + 0.5).sin() * (1.5 * y).cos()
}

fn height_normal(x: f32, y: f32) -> Vec3 {
    let dx = 0.5 * (2.0 * x + 0.5).cos() * (1.5 * y).cos();
    let dy = -0.375 * (2.0 * x + 0.5).sin() * (1.5 * y).sin();
    Vec3::new(-dx, -dy, 1.0).normalize()
}

/// The square's grids, flat-subdivided (`f32` inner vertices), every vertex then lifted onto
/// the height field: a grid whose micro-vertices sample a known smooth surface.
fn lifted_grids(levels: u32, lift: bool) -> GridScene {
    let build = GridBuild {
        scheme: Scheme::Flat,
        quantized: false,
        ..GridBuild::new(levels)
    };
    let mut grids = build_lean(&square(4), &build).unwrap();
    if lift {
        for [x, y, z] in grids.vertices.as_chunks_mut::<3>().0 {
            *z = height(f32::from_bits(*x), f32::from_bits(*y)).to_bits();
        }
    }
    grids
}

/// The angle between two directions (by its tangent: exact near zero, where `acos` is not).
fn angle(a: Vec3, b: Vec3) -> f32 {
    let (a, b) = (a.normalize(), b.normalize());
    a.cross(b).length().atan2(a.dot(b))
}

/// Mean and largest angle (radians) from the height field's normal, over random points of
/// random micro-triangles at depth `level` rendered at `lod`, of the smooth normals and of
/// the micro-triangles' own.
fn normal_errors(grids: &GridScene, lod: u32, level: u32, surface: fn(f32, f32) -> Vec3) -> ([f32; 2], [f32; 2]) {
    let view = grids.view_as(gridrt_shared::layout::GridParams { lod, ..grids.params });
    let per_grid = triangle_count(lod);
    let mut rng = Rng::new(u64::from(7 * lod + level));
    let (mut smooth, mut flat) = ([0.0f32, 0.0], [0.0f32, 0.0]);
    let samples = 4000;
    for _ in 0..samples {
        let grid = rng.next_u32() % grids.grid_count() as u32;
        let t = rng.next_u32() % triangle_count(level);
        let prim = grid * per_grid + (t << (2 * (lod - level)));
        let (mut u, mut v) = (rng.next_f32(), rng.next_f32());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        let [a, b, c] = view.micro_triangle(prim, level);
        let p = a * (1.0 - u - v) + b * u + c * v;
        let hit = Hit {
            t: 1.0,
            u,
            v,
            prim,
            normal: triangle_normal(a, b, c).to_array(),
            level,
        };
        let truth = surface(p.x, p.y);
        let s = angle(view.smooth_normal(&hit), truth);
        let f = angle(Vec3::from(hit.normal), truth);
        smooth = [smooth[0] + s / samples as f32, smooth[1].max(s)];
        flat = [flat[0] + f / samples as f32, flat[1].max(f)];
    }
    (smooth, flat)
}

/// On a surface the lattice samples, smooth normals are far closer to the surface's than the
/// micro-triangles' own, at every depth a grid may be rendered at, and everywhere: the
/// largest error (which falls on base edges and corners, differenced one-sided) stays small.
#[test]
fn smooth_normals_follow_the_sampled_surface() {
    for levels in [3, 4] {
        let grids = lifted_grids(levels, true);
        // Depth 1 has no inner lattice point: every difference is first-order, one-sided.
        for lod in 2..=levels {
            let (smooth, flat) = normal_errors(&grids, lod, lod, height_normal);
            assert!(
                smooth[0] < flat[0] / 3.0,
                "L = {levels}, depth {lod}: smooth {smooth:?}, flat {flat:?}"
            );
            assert!(
                smooth[1] < flat[1] / 2.0,
                "L = {levels}, depth {lod}: smooth {smooth:?}, flat {flat:?}"
            );
        }
        // Coarse grids among finer ones: a hit's depth, not the scene's, sets the stencil.
        let (smooth, flat) = normal_errors(&grids, levels, levels - 1, height_normal);
        assert!(smooth[0] < flat[0] / 3.0, "L = {levels}, level {}", levels - 1);
    }
}

/// A flat surface keeps its one normal everywhere, edges and corners included.
#[test]
fn a_flat_grid_keeps_its_normal() {
    let grids = lifted_grids(3, false);
    let (smooth, _) = normal_errors(&grids, 3, 3, |_, _| Vec3::Z);
    assert!(smooth[1] < 1e-5, "{smooth:?}");
}

/// An octahedron, Loop-subdivided (quantized) to L = 3: a round closed surface.
fn grid_scene() -> Scene {
    Scene::build(&octahedron(), &BuildOptions::levels(3)).unwrap()
}

/// Neighbouring pixels, both at least two pixels inside the surface (`covered`), whose
/// colours differ by more than `step` in a channel: the facets' edges, not the silhouette.
fn steps(image: &[u32], covered: &[bool], width: usize, step: i32) -> usize {
    let rows = image.len() / width;
    let inside = |x: usize, y: usize| {
        (x.saturating_sub(2)..(x + 3).min(width))
            .all(|i| (y.saturating_sub(2)..(y + 3).min(rows)).all(|j| covered[j * width + i]))
    };
    let channel = |p: u32, c: u32| ((p >> (8 * c)) & 0xff) as i32;
    let differ = |a: u32, b: u32| (0..3).any(|c| (channel(a, c) - channel(b, c)).abs() > step);
    let mut count = 0;
    for y in 0..rows - 1 {
        for x in 0..width - 1 {
            let p = image[y * width + x];
            if inside(x, y) && inside(x + 1, y) && differ(p, image[y * width + x + 1]) {
                count += 1;
            }
            if inside(x, y) && inside(x, y + 1) && differ(p, image[(y + 1) * width + x]) {
                count += 1;
            }
        }
    }
    count
}

/// Rendered, smooth normals leave far fewer steps between neighbouring pixels inside the
/// surface than flat ones, and the GPU draws the CPU's picture.
#[test]
fn smooth_shading_renders_alike_on_both_backends() {
    let scene = grid_scene();
    let (width, height) = (160, 120);
    let view = camera::frame(&scene.bounds(), width, height);
    let covered: Vec<bool> = Backend::CPU
        .trace(&scene, &gridrt::rays::view_rays(&view))
        .unwrap()
        .iter()
        .map(|h| h.prim != gridrt_shared::layout::NO_HIT)
        .collect();
    let gpu = gpu_or_skip("smooth_shading_renders_alike_on_both_backends")
        .map(|_| Backend::open(BackendChoice::Gpu).unwrap());
    for shading in [Shading::Normal, Shading::EyeLight, Shading::Level] {
        let options = |smooth_normals| RenderOptions {
            shading,
            smooth_normals,
            ..RenderOptions::default()
        };
        let flat = Backend::CPU.render(&scene, &view, &options(false)).unwrap();
        let smooth = Backend::CPU.render(&scene, &view, &options(true)).unwrap();
        let width = width as usize;
        let (flat_steps, smooth_steps) = (
            steps(&flat.pixels, &covered, width, 6),
            steps(&smooth.pixels, &covered, width, 6),
        );
        // The headlight's falloff towards the silhouette leaves steps of its own.
        let fewer = if shading == Shading::Normal { 4 } else { 2 };
        assert!(
            smooth_steps * fewer < flat_steps,
            "{shading:?}: {smooth_steps} steps smooth, {flat_steps} flat"
        );
        if let Some(gpu) = &gpu {
            let on_gpu = gpu.render(&scene, &view, &options(true)).unwrap();
            let within = fraction_within(&on_gpu.pixels, &smooth.pixels, 2);
            assert!(within >= 0.995, "{shading:?}: {:.3}% agree", 100.0 * within);
        }
    }
}

/// The baseline has no lattice: asking it for smooth normals is refused, not ignored.
#[test]
fn the_baseline_refuses_smooth_normals() {
    let input = input::open(None).unwrap();
    let options = BuildOptions {
        representation: Representation::Triangles,
        ..BuildOptions::levels(1)
    };
    let scene = Scene::build(&input.mesh, &options).unwrap();
    let view = camera::frame(&scene.bounds(), 16, 12);
    let render = RenderOptions {
        smooth_normals: true,
        ..RenderOptions::default()
    };
    let error = Backend::CPU.render(&scene, &view, &render).unwrap_err().to_string();
    assert!(error.contains("smooth normals"), "{error}");
}

/// Where grids meet, their smooth normals at a shared vertex agree better than the
/// micro-triangles around it do: by far along base edges; less so at the octahedron's base
/// vertices, where four grids meet at an extraordinary vertex and each sees two of its edges.
#[test]
fn grids_agree_where_they_meet() {
    let scene = grid_scene();
    let Scene::Grids(grids) = &scene else {
        unreachable!("built as grids")
    };
    let view = grids.view();
    let per_grid = triangle_count(3);
    // Every micro-triangle corner: its smooth normal and its triangle's, by position.
    let mut at: std::collections::HashMap<[u32; 3], (Vec<Vec3>, Vec<Vec3>)> = Default::default();
    for prim in 0..grids.grid_count() as u32 * per_grid {
        let [a, b, c] = view.micro_triangle(prim, 3);
        let normal = triangle_normal(a, b, c);
        for (p, (u, v)) in [a, b, c].into_iter().zip([(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)]) {
            let hit = Hit {
                t: 1.0,
                u,
                v,
                prim,
                normal: normal.to_array(),
                level: 3,
            };
            let entry = at.entry(p.to_array().map(f32::to_bits)).or_default();
            entry.0.push(view.smooth_normal(&hit));
            entry.1.push(normal);
        }
    }
    let spread = |normals: &[Vec3]| {
        normals
            .iter()
            .flat_map(|a| normals.iter().map(move |b| angle(*a, *b)))
            .fold(0.0, f32::max)
    };
    let (mut edges, mut corners) = (0, 0);
    for (smooth, flat) in at.values() {
        let (s, f) = (spread(smooth), spread(flat));
        // A base vertex is the corner of one micro-triangle in each of its four grids.
        let corner = flat.len() == 4;
        let better = if corner { 1.2 } else { 2.0 };
        assert!(s * better < f, "smooth normals {s} rad apart, micro-triangles {f}");
        edges += (s > 0.0 && !corner) as usize;
        corners += corner as usize;
    }
    // 12 base edges of 7 inner lattice points each, and 6 base vertices.
    assert_eq!((edges, corners), (12 * 7, 6));
}
