//! Property tests of the traversal: on random meshes (degenerate, sliver, huge and tiny
//! triangles among them) and random rays, the grid traversal, the baseline BVH and a brute
//! force loop over every micro-triangle find the same closest hit; and both walks of a grid
//! hierarchy find the same, bit for bit, wherever both apply, as do the code of a scene's
//! format and code carrying every format.

use gridrt::grid::{self, GridOptions, RadiusFormat, TopFormat};
use gridrt::mesh::Mesh;
use gridrt::scene::{closest_hit_slack, hit_uncertainty, hits_only_by_rounding, Scene};
use gridrt::subdiv::{subdivide, Scheme};
use gridrt::triangles;
use gridrt_shared::buffer::carries;
use gridrt_shared::glam::Vec3;
use gridrt_shared::ray::{Ray, T_FAR};
use gridrt_shared::traverse::trace;
use gridrt_shared::triangle::intersect_triangle;
use proptest::prelude::*;
use proptest::test_runner::RngSeed;

/// A coordinate from a mix of scales: most of unit size, some a million times smaller or
/// larger, some repeated exactly (degenerate and sliver triangles).
fn coordinate() -> impl Strategy<Value = f32> {
    prop_oneof![
        6 => -1.0f32..1.0,
        1 => (-1.0f32..1.0).prop_map(|c| c * 1e-6),
        1 => (-1.0f32..1.0).prop_map(|c| c * 1e6),
        1 => Just(0.0f32),
        1 => Just(0.5f32),
    ]
}

fn mesh() -> impl Strategy<Value = Mesh> {
    (3usize..10).prop_flat_map(|n| {
        (
            prop::collection::vec(prop::array::uniform3(coordinate()), n),
            prop::collection::vec(prop::array::uniform3(0..n as u32), 1..12),
        )
            .prop_map(|(points, triangles)| Mesh {
                positions: points.into_iter().map(Vec3::from).collect(),
                triangles,
            })
    })
}

#[derive(Debug, Clone)]
struct Build {
    levels: u32,
    lod: u32,
    flat: bool,
    quantized: bool,
    options: GridOptions,
}

fn build() -> impl Strategy<Value = Build> {
    (
        0u32..4,
        0u32..4,
        any::<bool>(),
        any::<bool>(),
        1u32..4,
        0u32..3,
        any::<bool>(),
        0u32..6,
    )
        .prop_map(
            |(levels, lod, flat, quantized, excluded_levels, radii, leaf_footprint, top_and_headers)| Build {
                levels,
                lod: lod.min(levels),
                flat,
                quantized,
                options: GridOptions {
                    excluded_levels,
                    radii: [RadiusFormat::F32, RadiusFormat::Half, RadiusFormat::Relative][radii as usize],
                    leaf_footprint,
                    top: [TopFormat::Full, TopFormat::Compact, TopFormat::Wide][top_and_headers as usize % 3],
                    tight_headers: top_and_headers >= 3,
                    own_rooms: true,
                },
            },
        )
}

/// The closest `t` over every triangle, by the same watertight test the traversals use, and
/// that triangle.
fn brute_force(positions: &[Vec3], list: &[[u32; 3]], ray: &Ray) -> Option<(f32, [Vec3; 3])> {
    list.iter()
        .filter_map(|t| {
            let corners = t.map(|i| positions[i as usize]);
            let [a, b, c] = corners;
            intersect_triangle(a, b, c, ray, T_FAR).map(|h| (h.0, corners))
        })
        .min_by(|x, y| x.0.total_cmp(&y.0))
}

proptest! {
    // A fixed seed: every run (CI included) tries the same cases; `PROPTEST_CASES` and a
    // different seed here explore further.
    #![proptest_config(ProptestConfig {
        cases: 2000,
        rng_seed: RngSeed::Fixed(0x6772_6964),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn grid_equals_baseline_equals_brute_force(
        mesh in mesh(),
        b in build(),
        rays in prop::collection::vec((prop::array::uniform3(-2.0f32..2.0), prop::array::uniform3(-1.0f32..1.0)), 48),
    ) {
        let Ok((mut mesh, _)) = mesh.validate("random") else { return Ok(()) };
        mesh.into_local_frame();
        let mut sub = subdivide(&mesh, b.levels, if b.flat { Scheme::Flat } else { Scheme::Loop });
        if b.quantized {
            sub.quantize_inner();
        }
        let mut g = grid::build(&mesh, &sub, &b.options).expect("grid build");
        g.set_lod(b.lod).unwrap();
        let list = sub.micro_triangles(b.lod);
        // Where one visit walks every hierarchy, the stack-free walk must find exactly what
        // the stack finds (`Scene::trace` takes the former there, so the rest checks both).
        if g.params.one_visit() {
            let view = g.view();
            let stacked_view = view.carrying::<{ carries::ALL }>(carries::ALL & !carries::ONE_VISIT);
            for &(origin, target) in &rays {
                let ray = Ray::new(Vec3::from(origin), Vec3::from(target) - Vec3::from(origin));
                let stacked = trace(g.top(), &stacked_view, &ray, T_FAR);
                let one_visit = trace(g.top(), &view, &ray, T_FAR);
                prop_assert_eq!(stacked, one_visit, "for {:?}", ray);
            }
        }
        // `Scene::trace` reads the grids by the code of their format alone; code carrying
        // every part must find the same, bit for bit.
        let grids = Scene::Grids(g);
        let Scene::Grids(g) = &grids else { unreachable!() };
        for &(origin, target) in &rays {
            let ray = Ray::new(Vec3::from(origin), Vec3::from(target) - Vec3::from(origin));
            prop_assert_eq!(trace(g.top(), &g.view(), &ray, T_FAR), grids.trace(&ray, T_FAR), "for {:?}", ray);
        }
        let tris = Scene::Triangles(triangles::build(&sub.positions, &list));
        for (origin, target) in rays {
            let dir = Vec3::from(target) - Vec3::from(origin);
            if dir.length_squared() < 1e-6 {
                continue;
            }
            let ray = Ray::new(Vec3::from(origin), dir.normalize());
            let truth = brute_force(&sub.positions, &list, &ray);
            let (gh, th) = (grids.trace(&ray, T_FAR), tris.trace(&ray, T_FAR));
            // The same hit up to the triangle test's rounding (`closest_hit_slack`); a miss
            // where brute force hits is a hole unless that hit is within rounding of the origin.
            for (name, scene, hit) in [("baseline", &tris, th), ("grid", &grids, gh)] {
                match truth {
                    Some((t, closest)) if hit.is_hit() => {
                        let slack = closest_hit_slack(&ray, [closest, scene.triangle(hit.prim)]);
                        let close = (hit.t - t).abs() <= 1e-5 * t + slack;
                        prop_assert!(close, "{} t {} vs {} (allowed {}) for {:?}", name, hit.t, t, slack, ray);
                    }
                    // A hit the traversal culled must lie within rounding of the origin, or
                    // exist only by the triangle test's rounding.
                    Some((t, closest)) => prop_assert!(
                        t <= hit_uncertainty(&ray, closest) || hits_only_by_rounding(&ray, closest),
                        "{} missed a hit at {} for {:?}", name, t, ray
                    ),
                    None => prop_assert!(!hit.is_hit(), "{} hit what brute force misses, {:?}", name, ray),
                }
            }
        }
    }
}
