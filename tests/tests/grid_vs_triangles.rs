//! The grid traversal and the baseline traversal of the same micro-triangles must report the
//! same closest hit.

use gridrt::backend::cpu::render_cpu;
use gridrt::bvh::Aabb;
use gridrt::camera;
use gridrt::grid::{GridOptions, RadiusFormat, TopFormat};
use gridrt::image_io::fraction_within;
use gridrt::input::load_mesh;
use gridrt::mesh::{scene::default_scene, Mesh};
use gridrt::subdiv::Scheme;
use gridrt_shared::layout::SHADE_NORMAL;
use gridrt_shared::ray::{Ray, T_FAR};
use gridrt_tests::{build_pair, build_pair_from, meshes_dir_or_skip, Rng};

struct Agreement {
    rays: usize,
    hits: usize,
    same: usize,
    /// Different micro-triangle at the same distance: a ray through a shared edge or vertex,
    /// which either neighbour may claim depending on the order they are tested in.
    ties: usize,
}

/// Random rays from around the scene towards random points in it; the comparison the issue
/// asks for: same micro-triangle and `t` within 1e-4 relative.
fn compare(mesh: &Mesh, levels: u32, lod: u32, scheme: Scheme, rays: usize, seed: u64) -> Agreement {
    compare_with(mesh, levels, lod, scheme, &GridOptions::default(), true, rays, seed)
}

#[allow(clippy::too_many_arguments)]
fn compare_with(
    mesh: &Mesh,
    levels: u32,
    lod: u32,
    scheme: Scheme,
    options: &GridOptions,
    quantized: bool,
    rays: usize,
    seed: u64,
) -> Agreement {
    let pair = build_pair_from(mesh, levels, lod, scheme, options, quantized);
    let b = pair.bounds;
    let margin = (b.max - b.min) * 0.25;
    let outer = Aabb {
        min: b.min - margin,
        max: b.max + margin,
    };
    let mut rng = Rng::new(seed);
    let mut a = Agreement {
        rays,
        hits: 0,
        same: 0,
        ties: 0,
    };
    for k in 0..rays {
        let origin = rng.point_in(&outer);
        // Half aimed into the scene, half in random directions (from inside too).
        let dir = if k % 2 == 0 {
            (rng.point_in(&b) - origin).normalize()
        } else {
            rng.direction()
        };
        if !dir.is_finite() {
            continue;
        }
        let ray = Ray::new(origin, dir);
        let g = pair.grids.trace(&ray, T_FAR);
        let t = pair.triangles.trace(&ray, T_FAR);
        if !g.is_hit() && !t.is_hit() {
            a.same += 1;
            continue;
        }
        if g.is_hit() != t.is_hit() {
            continue;
        }
        a.hits += 1;
        let close = (g.t - t.t).abs() <= 1e-4 * t.t.abs().max(1e-6);
        let same_triangle = pair.grids.original_triangle(g.prim) == pair.triangles.original_triangle(t.prim);
        if same_triangle && close {
            a.same += 1;
        } else if close {
            a.ties += 1;
        }
    }
    a
}

fn check(name: &str, a: Agreement) {
    let agree = a.same as f64 / a.rays as f64;
    eprintln!(
        "{name}: {} rays, {} hits, {:.5}% same micro-triangle and t, {} ties at shared edges, {} other",
        a.rays,
        a.hits,
        100.0 * agree,
        a.ties,
        a.rays - a.same - a.ties
    );
    assert!(a.hits > a.rays / 10, "{name}: too few rays hit anything to compare");
    assert!(agree >= 0.9999, "{name}: only {:.5}% of rays agree", 100.0 * agree);
    // Whatever disagrees must at least be a tie: the same distance on a neighbour.
    assert_eq!(a.same + a.ties, a.rays, "{name}: a disagreement that is not a tie");
}

#[test]
fn default_scene_l3() {
    check(
        "default scene L=3",
        compare(&default_scene(), 3, 3, Scheme::Loop, 300_000, 1),
    );
}

#[test]
fn default_scene_coarser_levels_of_detail() {
    for lod in 0..3 {
        let a = compare(&default_scene(), 3, lod, Scheme::Loop, 40_000, 2 + lod as u64);
        check(&format!("default scene L=3 lod {lod}"), a);
    }
}

#[test]
fn default_scene_flat_and_other_depths() {
    check(
        "default scene flat L=3",
        compare(&default_scene(), 3, 3, Scheme::Flat, 40_000, 7),
    );
    for levels in [1, 2, 4] {
        let a = compare(
            &default_scene(),
            levels,
            levels,
            Scheme::Loop,
            40_000,
            10 + levels as u64,
        );
        check(&format!("default scene L={levels}"), a);
    }
}

/// The other grid variants: half-float radii, one or three sphere levels left out, 32-bit
/// inner vertices, and a compact top level.
#[test]
fn default_scene_grid_variants() {
    use RadiusFormat::{Half, Relative, F32};
    use TopFormat::{Compact, Full, Wide};
    for (excluded_levels, radii, quantized, leaf_footprint, top) in [
        (2, Half, true, true, Full),
        (1, F32, true, true, Full),
        (3, Half, true, true, Full),
        (2, F32, false, true, Full),
        (2, F32, true, false, Full),
        (2, F32, true, true, Compact),
        (1, Half, true, true, Compact),
        (1, Relative, true, true, Full),
        (2, Relative, true, true, Compact),
        (2, Relative, true, true, Wide),
        (1, F32, true, true, Wide),
    ] {
        let options = GridOptions {
            excluded_levels,
            radii,
            leaf_footprint,
            top,
            tight_headers: top != Full,
            own_rooms: true,
        };
        let a = compare_with(
            &default_scene(),
            3,
            3,
            Scheme::Loop,
            &options,
            quantized,
            40_000,
            20 + excluded_levels as u64,
        );
        check(&format!("default scene L=3 {options:?} quantized {quantized}"), a);
    }
}

#[test]
fn bunny_l3() {
    let Some(dir) = meshes_dir_or_skip("bunny_l3") else {
        return;
    };
    let mesh = load_mesh(&dir.join("bunny.obj")).unwrap();
    check("bunny L=3", compare(&mesh, 3, 3, Scheme::Loop, 300_000, 3));
}

/// Same pictures: the grid image equals the triangle image of the same micro-triangles.
#[test]
fn grid_image_equals_triangle_image() {
    let mesh = default_scene();
    let pair = build_pair(&mesh, 3, 3, Scheme::Loop);
    let cam = camera::frame(&pair.bounds, 320, 240);
    // Normal shading: the same micro-triangle gives the same colour in both.
    let a = render_cpu(&pair.grids, &pair.grids.frame(cam, SHADE_NORMAL));
    let b = render_cpu(&pair.triangles, &pair.triangles.frame(cam, SHADE_NORMAL));
    let exact = fraction_within(&a, &b, 0);
    let near = fraction_within(&a, &b, 2);
    eprintln!(
        "grid vs triangle image: {:.4}% identical, {:.4}% within 2/255",
        100.0 * exact,
        100.0 * near
    );
    assert!(near >= 0.995);
}

/// A hit's triangle read back from either representation is the same micro-triangle.
#[test]
fn hit_triangles_read_back_alike() {
    let pair = build_pair(&default_scene(), 3, 2, Scheme::Loop);
    let mut rng = Rng::new(5);
    let mut checked = 0;
    for _ in 0..2000 {
        let origin = rng.point_in(&pair.bounds) * 1.5;
        let ray = Ray::new(origin, rng.direction());
        let (g, t) = (pair.grids.trace(&ray, T_FAR), pair.triangles.trace(&ray, T_FAR));
        if g.is_hit() && t.is_hit() && g.t == t.t {
            assert_eq!(pair.grids.triangle(g.prim), pair.triangles.triangle(t.prim));
            assert_eq!(pair.grids.normal(g.prim).to_array(), g.normal);
            checked += 1;
        }
    }
    assert!(checked > 200, "only {checked} hits compared");
}
