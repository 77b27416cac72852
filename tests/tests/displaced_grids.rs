//! Displaced grids (a baked micro-mesh traced from its 11-bit values, plain or compressed)
//! against the same micro-triangles decoded into a list under the baseline's BVH: the same
//! closest hits, no leaks at shared edges and corners, and the same pictures on the GPU and
//! the CPU. Micro-meshes of mixed levels (a level per base triangle, decimated edges where
//! levels step) likewise, and a file of them, as another tool writes it, watertight.

use gridrt::backend::cpu::render_cpu;
use gridrt::backend::Backend;
use gridrt::bvh::Aabb;
use gridrt::camera;
use gridrt::grid::TopFormat;
use gridrt::image_io::fraction_within;
use gridrt::micromesh::DisplacedMesh;
use gridrt::pipeline::{BuildOptions, RenderOptions, Representation, Shading};
use gridrt::scene::Scene;
use gridrt_shared::glam::Vec3;
use gridrt_shared::layout::Hit;
use gridrt_shared::layout::{FrameParams, RayRecord, NO_HIT, SHADE_EYE_LIGHT};
use gridrt_shared::ray::{Ray, T_FAR};
use gridrt_shared::traverse::trace;
use gridrt_tests::{baked_ball, gpu_or_skip, loosely_compressed, mixed_ball, Rng};

/// The ball's values plain, and compressed loosely.
fn variants(levels: u32) -> [(&'static str, DisplacedMesh); 2] {
    let mesh = baked_ball(levels);
    let compressed = loosely_compressed(&mesh);
    [("plain", mesh), ("compressed", compressed)]
}

/// Mixed balls of deepest levels 3 and 4, their values plain, and compressed as loosely as
/// [`variants`]'.
fn mixed_variants() -> Vec<(&'static str, DisplacedMesh)> {
    let (l3, l4) = (mixed_ball(3), mixed_ball(4));
    vec![
        ("mixed compressed", loosely_compressed(&l3)),
        ("mixed compressed", loosely_compressed(&l4)),
        ("mixed", l3),
        ("mixed", l4),
    ]
}

fn build(mesh: &DisplacedMesh, representation: Representation, lod: Option<u32>) -> Scene {
    let options = BuildOptions {
        representation,
        lod,
        ..BuildOptions::for_displaced()
    };
    Scene::build_displaced(mesh, &options).unwrap()
}

fn both(mesh: &DisplacedMesh) -> (Scene, Scene) {
    (
        build(mesh, Representation::Grids, None),
        build(mesh, Representation::Triangles, None),
    )
}

/// Random rays: the same micro-triangle at the same distance, or a tie at a shared edge.
#[test]
fn displaced_grids_hit_as_their_decoded_triangles() {
    let all = [0, 1, 2, 3, 4].into_iter().flat_map(variants);
    for (variant, mesh) in all.chain(mixed_variants()) {
        let levels = mesh.deepest_level().unwrap();
        let (grids, triangles) = both(&mesh);
        let b = triangles.bounds();
        let outer = Aabb {
            min: b.min - (b.max - b.min) * 0.25,
            max: b.max + (b.max - b.min) * 0.25,
        };
        let mut rng = Rng::new(levels as u64 + 1);
        let (mut hits, mut same, mut ties) = (0, 0, 0);
        let rays = 20_000;
        for k in 0..rays {
            let origin = rng.point_in(&outer);
            let dir = match k % 2 {
                0 => (rng.point_in(&b) - origin).normalize(),
                _ => rng.direction(),
            };
            let ray = Ray::new(origin, dir);
            let (g, t) = (grids.trace(&ray, T_FAR), triangles.trace(&ray, T_FAR));
            assert_eq!(g, every_part(&grids, &ray), "{variant} L{levels} ray {k}: format code");
            assert_eq!(
                g.is_hit(),
                t.is_hit(),
                "{variant} L{levels} ray {k}: one hits, the other not"
            );
            if !g.is_hit() {
                continue;
            }
            hits += 1;
            assert!(
                (g.t - t.t).abs() <= 1e-4 * t.t,
                "L{levels} ray {k}: t {} vs {}",
                g.t,
                t.t
            );
            match same_corners(grids.hit_triangle(&g), triangles.hit_triangle(&t)) {
                true => same += 1,
                false => ties += 1,
            }
        }
        eprintln!("{variant} L{levels}: {rays} rays, {hits} hits, {same} on the same micro-triangle, {ties} ties");
        assert!(
            hits > rays / 5 && ties * 1000 < hits,
            "{variant} L{levels}: {hits} hits, {ties} ties"
        );
    }
}

/// The closest hit of `ray` found by code carrying every grid format (`Scene::trace` carries
/// the scene's own alone).
fn every_part(grids: &Scene, ray: &Ray) -> Hit {
    let Scene::Grids(g) = grids else { panic!("not grids") };
    trace(g.top(), &g.view(), ray, T_FAR)
}

/// Whether two triangles have the same corners, in any order.
fn same_corners(a: [Vec3; 3], b: [Vec3; 3]) -> bool {
    let sorted = |t: [Vec3; 3]| {
        let mut bits = t.map(|p| p.to_array().map(f32::to_bits));
        bits.sort();
        bits
    };
    sorted(a) == sorted(b)
}

/// Rays through the micro-vertices on base edges and corners, where two or more grids meet,
/// cross the closed surface: none passes through, on the CPU nor, traced as a ray list, on
/// the GPU.
#[test]
fn shared_edges_of_displaced_grids_do_not_leak() {
    let gpu = gpu_or_skip("shared_edges_of_displaced_grids_do_not_leak");
    for (variant, mesh) in variants(3) {
        let mesh = mesh.with_ranges_folded();
        let grids = build(&mesh, Representation::Grids, None);
        let n = 8;
        let mut rng = Rng::new(5);
        let mut rays = Vec::new();
        for t in 0..mesh.triangles.len() {
            let points = mesh.micro_vertices(t);
            let lattice = gridrt_shared::grid_index::lattice_points(n);
            for (p, [i, j]) in points.iter().zip(lattice) {
                if i != 0 && j != 0 && i + j != n {
                    continue;
                }
                // From outside, aimed at the point through the ball's centre region.
                let dir = (Vec3::ZERO - *p).normalize() + rng.direction() * 0.2;
                let origin = *p - dir * 3.0;
                let hit = grids.trace(&Ray::new(origin, dir), T_FAR);
                assert!(
                    hit.is_hit() && hit.t <= 3.0 * 1.0001,
                    "{variant}: a ray through {p} leaked"
                );
                rays.push(RayRecord {
                    origin: origin.to_array(),
                    t_max: T_FAR,
                    dir: dir.to_array(),
                    _pad: 0,
                });
            }
        }
        assert!(rays.len() > 1000, "{}", rays.len());
        if let Some(gpu) = &gpu {
            let hits = gpu.trace(&gpu.upload(&grids).unwrap(), &rays).unwrap();
            let leaked = hits.iter().filter(|h| h.prim == NO_HIT || h.t > 3.0 * 1.0001).count();
            assert_eq!(
                leaked,
                0,
                "{variant}: {leaked} of {} rays leaked on the GPU",
                rays.len()
            );
        }
    }
}

/// The GPU decodes what the CPU does: the pictures agree (see gpu_vs_cpu.rs for the
/// tolerance), at the full depth and a coarser level of detail, in every value format, of one
/// level and of mixed levels.
#[test]
fn displaced_grids_gpu_equals_cpu() {
    let Some(gpu) = gpu_or_skip("displaced_grids_gpu_equals_cpu") else {
        return;
    };
    let all = variants(3).into_iter().chain(mixed_variants());
    for ((variant, mesh), lod) in all.flat_map(|v| [(v.clone(), 3), (v, 1)]) {
        let grids = build(&mesh, Representation::Grids, Some(lod));
        let frame = grids.frame(camera::frame(&grids.bounds(), 256, 192), SHADE_EYE_LIGHT);
        let cpu = render_cpu(&grids, &frame);
        let on_gpu = gpu.render(&grids, &frame).expect("GPU render");
        let within = fraction_within(&cpu, &on_gpu, 2);
        eprintln!(
            "{variant} displaced grids lod {lod}: {:.3}% of pixels within 2/255",
            100.0 * within
        );
        assert!(within >= 0.995, "{variant} lod {lod}: {within}");
    }
}

/// Lit with smooth normals, displaced grids render alike on both backends, plain and
/// compressed, walked by the root's visit alone (L = 3) and with the stack (L = 4): the GPU
/// runs a pipeline of its own for such frames, which must not fall back to flat normals.
#[test]
fn smooth_displaced_grids_gpu_equals_cpu() {
    let Some(gpu) = gpu_or_skip("smooth_displaced_grids_gpu_equals_cpu") else {
        return;
    };
    for (variant, mesh) in variants(3).into_iter().chain(variants(4)) {
        let grids = build(&mesh, Representation::Grids, None);
        let flat = grids.frame(camera::frame(&grids.bounds(), 160, 120), SHADE_EYE_LIGHT);
        let smooth = FrameParams {
            smooth_normals: 1,
            ..flat
        };
        let cpu = render_cpu(&grids, &smooth);
        let changed = 1.0 - fraction_within(&cpu, &render_cpu(&grids, &flat), 2);
        assert!(
            changed > 0.05,
            "{variant}: smooth normals change {changed} of the pixels"
        );
        let within = fraction_within(&cpu, &gpu.render(&grids, &smooth).expect("GPU render"), 2);
        assert!(within >= 0.995, "{variant}: {within}");
    }
}

/// The ray-list kernels find the hits the CPU does, in every value format, walked by the
/// root's visit alone (L = 3) and with the stack (L = 4), of one level and of mixed levels;
/// at L = 3 under a wide and a binary top level.
#[test]
fn displaced_ray_lists_gpu_equal_cpu() {
    let Some(gpu) = gpu_or_skip("displaced_ray_lists_gpu_equal_cpu") else {
        return;
    };
    use gridrt::backend::cpu::trace_cpu;
    use gridrt::rays::{ao_rays, primary_rays};
    let all = [3, 4].into_iter().flat_map(variants);
    for (variant, mesh) in all.chain(mixed_variants()) {
        let levels = mesh.deepest_level().unwrap();
        let grids = build(&mesh, Representation::Grids, None);
        let primary = primary_rays(&grids.bounds(), 2, 96, 64);
        // From all around the ball, at points in its box (a convex ball's own occlusion rays
        // would hit nothing).
        let mut rng = Rng::new(levels as u64);
        let b = grids.bounds();
        let around: Vec<RayRecord> = (0..4096)
            .map(|_| {
                let origin = (b.min + b.max) * 0.5 + rng.direction() * (b.max - b.min).length();
                let dir = (rng.point_in(&b) - origin).normalize();
                RayRecord {
                    origin: origin.to_array(),
                    t_max: T_FAR,
                    dir: dir.to_array(),
                    _pad: 0,
                }
            })
            .collect();
        let first = trace_cpu(&grids, &primary);
        let ao = ao_rays(&primary, &first, 4, &b, |p| grids.normal(p));
        let uploaded = gpu.upload(&grids).unwrap();
        for top in [TopFormat::Wide, TopFormat::Compact] {
            if levels != 3 {
                break;
            }
            let mut options = BuildOptions::for_displaced();
            options.grid.options.top = top;
            let scene = Scene::build_displaced(&mesh, &options).unwrap();
            let uploaded = gpu.upload(&scene).unwrap();
            for (kind, rays) in [("primary", &primary), ("ao", &ao)] {
                let gpu_hits = gpu.trace(&uploaded, rays).unwrap();
                let cpu = trace_cpu(&scene, rays);
                let same = (cpu.iter().zip(&gpu_hits))
                    .filter(|(a, b)| a.prim == b.prim && (a.t - b.t).abs() <= 1e-4 * a.t.abs().max(1e-6))
                    .count();
                eprintln!(
                    "{variant} L3 {kind}, {top:?} top: {} rays, {same} the same as on the CPU",
                    rays.len()
                );
                assert!(
                    same * 1000 >= rays.len() * 999,
                    "{variant} {kind}, {top:?} top: {same} the same"
                );
            }
        }
        for (kind, rays) in [("primary", &primary), ("around", &around), ("ao", &ao)] {
            let cpu = trace_cpu(&grids, rays);
            let on_gpu = gpu.trace(&uploaded, rays).unwrap();
            let same = (cpu.iter().zip(&on_gpu))
                .filter(|(a, b)| a.prim == b.prim && (a.t - b.t).abs() <= 1e-4 * a.t.abs().max(1e-6))
                .count();
            let hits = cpu.iter().filter(|h| h.prim != NO_HIT).count();
            eprintln!(
                "{variant} L{levels} {kind}: {} rays, {hits} hits, {same} the same on the GPU",
                rays.len()
            );
            assert!(
                kind == "ao" || hits > rays.len() / 10,
                "{variant} L{levels} {kind}: {hits} hits"
            );
            assert!(
                same * 1000 >= rays.len() * 999,
                "{variant} L{levels} {kind}: {same} the same"
            );
        }
    }
}

/// Lit pictures (sixteen occlusion rays a pixel, in passes) agree on the GPU and the CPU in
/// every value format, on grids deep enough that a pixel's decoding runs long loops.
#[test]
fn displaced_occlusion_gpu_equals_cpu() {
    let Some(gpu) = gpu_or_skip("displaced_occlusion_gpu_equals_cpu") else {
        return;
    };
    let gpu = Backend::Gpu(Box::new(gpu));
    for (variant, mesh) in variants(4) {
        let grids = build(&mesh, Representation::Grids, None);
        let view = camera::frame(&grids.bounds(), 96, 72);
        let options = RenderOptions {
            shading: Shading::Lit,
            ao_samples: 16,
            ..RenderOptions::default()
        };
        let cpu = Backend::CPU.render(&grids, &view, &options).unwrap();
        let on_gpu = gpu.render(&grids, &view, &options).unwrap();
        let within = fraction_within(&cpu.pixels, &on_gpu.pixels, 2);
        eprintln!("{variant} L4 lit: {:.3}% of pixels within 2/255", 100.0 * within);
        assert!(within >= 0.995, "{variant}: {within}");
    }
}

/// A closed tetrahedron written by hand as another tool would: faces 0 and 1 at level 2,
/// faces 2 and 3 at level 1, the finer faces' edges towards the coarser ones flagged in
/// `primitiveFlags`, their odd points there holding 0 (as files store them). Rays at every
/// point and micro-edge of every base edge never pass through, neither its decoded triangles
/// nor its displaced grids; without the flags they do.
#[test]
fn mixed_levels_with_decimated_edges_render_watertight() {
    use gridrt::micromesh::bary::{write, Micromap};
    use gridrt_shared::displacement::u_major_index;
    use gridrt_shared::grid_index::{grid_size, lattice_points};

    let (levels, flags) = ([2, 2, 1, 1], [0b110u8, 0b011, 0, 0]);
    let values = |face: usize| -> Vec<u16> {
        let n = grid_size(levels[face]);
        let mut v = vec![0u16; lattice_points(n).count()];
        for [i, j] in lattice_points(n) {
            // Edge e's points, `s` steps from its first corner.
            let on_edge = [(j == 0, i), (i + j == n, j), (i == 0, n - j)];
            let odd_decimated = (0..3).any(|e| on_edge[e].0 && flags[face] >> e & 1 != 0 && on_edge[e].1 % 2 == 1);
            v[u_major_index([i, j], n) as usize] = if odd_decimated {
                0
            } else if on_edge.iter().any(|e| e.0) {
                1024
            } else {
                1500 + 97 * (i + 2 * j) as u16 % 400
            };
        }
        v
    };
    let map = Micromap::from_triangles(0.0, 0.3, &(0..4).map(|f| (levels[f], values(f))).collect::<Vec<_>>());
    let dir = gridrt_tests::scratch("mixed-levels");
    std::fs::write(dir.join("tetra.bary"), write(&map)).unwrap();
    let leaks = |flags: [u8; 4]| leaks_through_seams(&write_tetra_gltf(&dir, flags), levels, flags);
    assert_eq!(leaks(flags), [0, 0], "decoded triangles, displaced grids");
    let [triangles, grids] = leaks([0; 4]);
    assert!(triangles > 0 && grids > 0, "without the flags the seams should crack");
}

/// The corners of the tetrahedron the seam test displaces.
const TETRA_POSITIONS: [[f32; 3]; 4] = [[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]];

/// Its faces, outwards.
const TETRA_FACES: [[u32; 3]; 4] = [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]];

/// The tetrahedron as a glTF displaced micro-mesh in `dir`, over the micromap `tetra.bary`
/// there, with `flags` as its primitive flags.
fn write_tetra_gltf(dir: &std::path::Path, flags: [u8; 4]) -> std::path::PathBuf {
    let floats = |v: &[[f32; 3]]| v.iter().flatten().flat_map(|f| f.to_le_bytes()).collect::<Vec<u8>>();
    let mut bin = floats(&TETRA_POSITIONS);
    let directions = TETRA_POSITIONS.map(|p| (Vec3::from(p).normalize()).to_array());
    bin.extend(floats(&directions));
    bin.extend(TETRA_FACES.iter().flatten().flat_map(|i| i.to_le_bytes()));
    bin.extend(flags);
    std::fs::write(dir.join("tetra.bin"), &bin).unwrap();
    let json = serde_json::json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["NV_micromaps", "NV_displacement_micromap"],
        "extensions": {"NV_micromaps": {"micromaps": [{"uri": "tetra.bary"}]}},
        "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 2, "extensions": {
            "NV_displacement_micromap": {"micromap": 0, "directions": 1, "primitiveFlags": 3}}}]}],
        "buffers": [{"uri": "tetra.bin", "byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 48},
            {"buffer": 0, "byteOffset": 96, "byteLength": 48},
            {"buffer": 0, "byteOffset": 144, "byteLength": 4},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [-1, -1, -1], "max": [1, 1, 1]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5125, "count": 12, "type": "SCALAR"},
            {"bufferView": 3, "componentType": 5121, "count": 4, "type": "SCALAR"},
        ],
    });
    let path = dir.join("tetra.gltf");
    std::fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    path
}

/// Rays from outside through each base edge's decoded points and the midpoints between
/// them, aimed at the centre: how many pass through the surface, as decoded triangles and
/// as displaced grids.
fn leaks_through_seams(path: &std::path::Path, levels: [u32; 4], flags: [u8; 4]) -> [u32; 2] {
    use gridrt_shared::grid_index::grid_size;

    let input = gridrt::input::open(Some(path)).unwrap();
    let micromesh = input.micromesh.as_ref().unwrap();
    let expected = if flags == [0; 4] { vec![] } else { flags.to_vec() };
    assert_eq!(micromesh.decimated_edges, expected);
    let triangles = Scene::Triangles(gridrt::triangles::build(&input.mesh.positions, &input.mesh.triangles));
    let grids = build(micromesh, Representation::Grids, None);
    let centre = triangles.bounds().center();
    let mut rng = Rng::new(17);
    let (mut rays, mut leaked) = (0, [0; 2]);
    for (t, &level) in levels.iter().enumerate().take(4) {
        let n = grid_size(level);
        let points = micromesh.micro_vertices(t);
        let at = |p: [u32; 2]| points[gridrt_shared::grid_index::lattice_index(p[0], p[1], n) as usize];
        for s in 0..n {
            for (a, b) in [
                ([s, 0], [s + 1, 0]),
                ([n - s, s], [n - s - 1, s + 1]),
                ([0, n - s], [0, n - s - 1]),
            ] {
                for target in [at(a), (at(a) + at(b)) * 0.5] {
                    for _ in 0..4 {
                        let dir = (centre - target).normalize() + rng.direction() * 0.3;
                        let origin = target - dir * 3.0;
                        rays += 1;
                        for (scene, leaked) in [&triangles, &grids].into_iter().zip(&mut leaked) {
                            let hit = scene.trace(&Ray::new(origin, dir), T_FAR);
                            *leaked += (!hit.is_hit() || hit.t > 3.0 * 1.0001) as u32;
                        }
                    }
                }
            }
        }
    }
    assert!(rays >= 100, "{rays}");
    leaked
}
