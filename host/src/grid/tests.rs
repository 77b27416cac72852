//! Grid builds read back: vertices, sphere radii, leaf thicknesses and sizes.

use super::*;
use crate::mesh::scene::{cube, default_scene, fins};
use crate::subdiv::{subdivide, Scheme};
use gridrt_shared::grid_index::{lattice_points, level_start, sub_triangle};
use gridrt_shared::grid_traverse::sphere_center;

fn lattice_vertex(scene: &GridScene, slot: usize, p: Lattice) -> Vec3 {
    let view = scene.view();
    view.vertex(&view.open(slot as u32), p)
}

/// Reading a grid back through its header gives exactly the subdivided vertices, shared
/// edges and corners included, whichever way a grid walks its edges.
#[test]
fn every_grid_reads_back_its_vertices() {
    for (levels, quantized) in (0..=4).flat_map(|l| [(l, false), (l, true)]) {
        let mesh = default_scene();
        let mut sub = subdivide(&mesh, levels, Scheme::Loop);
        if quantized {
            sub.quantize_inner();
        }
        let scene = build(&mesh, &sub, &GridOptions::default()).unwrap();
        let n = grid_size(levels);
        for (slot, &base) in scene.base_triangle.iter().enumerate() {
            for p in lattice_points(n) {
                let expect = sub.positions[sub.vertex(base as usize, p) as usize];
                assert_eq!(
                    lattice_vertex(&scene, slot, p),
                    expect,
                    "L={levels} grid {base} at {p:?}"
                );
            }
        }
        // Nothing stored twice: one slot per distinct subdivided vertex.
        let g = &scene.params;
        assert_eq!(g.corner_offset as usize + mesh.positions.len(), sub.positions.len());
        let per_grid = match quantized {
            true => quantize::inner_words(g.inner_count),
            false => 3 * g.inner_count,
        };
        assert_eq!(g.edge_word, scene.grid_count() as u32 * per_grid);
        let shared = sub.positions.len() - g.edge_offset as usize;
        assert_eq!(scene.vertices.len(), g.edge_word as usize + 3 * shared, "L={levels}");
    }
}

/// `mesh` Loop-subdivided `levels` times, as grids with `excluded` sphere levels left out.
fn loop_grids(mesh: &Mesh, levels: u32, excluded: u32, radii: RadiusFormat) -> GridScene {
    let sub = subdivide(mesh, levels, Scheme::Loop);
    let options = GridOptions {
        excluded_levels: excluded,
        radii,
        ..Default::default()
    };
    build(mesh, &sub, &options).unwrap()
}

/// Every micro-vertex lies inside the sphere of each of its ancestor sub-triangles, with
/// the centre computed as the traversal computes it.
#[test]
fn spheres_are_conservative() {
    use RadiusFormat::{Half, Relative, F32};
    for (mesh, levels, excluded, radii) in [
        (default_scene(), 3, 2, F32),
        (default_scene(), 3, 2, Half),
        (default_scene(), 3, 2, Relative),
        (cube(), 5, 2, Half),
        (cube(), 5, 2, Relative),
        (cube(), 4, 1, F32),
        (cube(), 4, 1, Relative),
        (cube(), 4, 2, Half),
        (cube(), 3, 3, Half),
    ] {
        let scene = loop_grids(&mesh, levels, excluded, radii);
        let n = grid_size(levels);
        let g = &scene.params;
        for slot in 0..scene.grid_count() {
            for level in 0..=g.leaf_level {
                for index in 0..triangle_count(level) {
                    let c = sub_triangle(n, level, index).map(|p| lattice_vertex(&scene, slot, p));
                    let center = sphere_center(c[0], c[1], c[2]);
                    let view = scene.view();
                    let r = view.radius(&view.open(slot as u32), level_start(level) + index);
                    // Every micro-triangle below this node, through its corners.
                    let below = levels - level;
                    for t in 0..triangle_count(below) {
                        let id = index * triangle_count(below) + t;
                        for p in sub_triangle(n, levels, id) {
                            let d = lattice_vertex(&scene, slot, p).distance(center);
                            assert!(d <= r, "vertex at {d} outside sphere {r} (level {level})");
                        }
                    }
                }
            }
        }
    }
}

/// Every micro-vertex of a leaf lies within the leaf's stored thickness of its flat place
/// (the same lattice point of the flat triangle of the leaf's corners), hence of that
/// triangle; and the thickness is no larger than it has to be.
#[test]
fn leaf_thickness_is_conservative() {
    for (mesh, levels, excluded, radii) in [
        (default_scene(), 3, 2, RadiusFormat::F32),
        (cube(), 4, 1, RadiusFormat::Half),
        (cube(), 5, 1, RadiusFormat::Relative),
        (cube(), 3, 3, RadiusFormat::F32),
    ] {
        let scene = loop_grids(&mesh, levels, excluded, radii);
        let n = grid_size(levels);
        let leaf_level = scene.params.leaf_level;
        let m = (n >> leaf_level) as i32;
        let mut thick = 0;
        for slot in 0..scene.grid_count() {
            for leaf in 0..triangle_count(leaf_level) {
                let lattice = sub_triangle(n, leaf_level, leaf).map(|p| [p[0] as i32, p[1] as i32]);
                let c = lattice.map(|p| lattice_vertex(&scene, slot, [p[0] as u32, p[1] as u32]));
                let view = scene.view();
                let open = view.open(slot as u32);
                let d = view.thickness(&open, leaf, view.radius(&open, level_start(leaf_level) + leaf));
                let moved = farthest_from_flat(lattice, m, |p| lattice_vertex(&scene, slot, p));
                assert!(moved <= d, "a vertex moved {moved} from its flat place, thickness {d}");
                let size = (c[1] - c[0]).length().max((c[2] - c[0]).length());
                // Codes step in 2 / 255ths of the leaf's radius; leaf pairs' in 32nds of it
                // below a quarter, then in quarters.
                let r = view.radius(&open, level_start(leaf_level) + leaf);
                let step = match scene.params.leaf_pairs() {
                    true if moved < 0.2 * r => r / 32.0,
                    true => r / 4.0,
                    false => 2.0 * r / 255.0,
                };
                assert!(
                    d <= moved + 3.0 * step + size * 1e-3,
                    "thickness {d}, farthest move {moved}"
                );
                thick += (moved > 1e-3 * size) as usize;
            }
        }
        assert!(thick > 0, "every leaf was flat: the test proves nothing");
    }
}

#[test]
fn sizes_follow_the_layout() {
    let mesh = cube();
    let sub = subdivide(&mesh, 3, Scheme::Loop);
    let scene = build(&mesh, &sub, &GridOptions::default()).unwrap();
    // Five f32 radii per grid, then four leaf thickness codes (one word).
    assert_eq!(scene.params.thickness_word, 12 * 5);
    assert_eq!(scene.radii.len(), 12 * 5 + 12);
    let half = build(
        &mesh,
        &sub,
        &GridOptions {
            radii: RadiusFormat::Half,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(half.radii.len(), 12 * 5 / 2 + 12);
    // The root's radius, then four bytes in one word.
    let relative = build(
        &mesh,
        &sub,
        &GridOptions {
            radii: RadiusFormat::Relative,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(relative.radii.len(), 12 * 2 + 12);
    // Two levels above the leaves: the root's radius and its children's bytes, then the
    // sixteen leaves' radius and thickness bytes in four words.
    let deeper = build(
        &mesh,
        &subdivide(&mesh, 4, Scheme::Loop),
        &GridOptions {
            radii: RadiusFormat::Relative,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(deeper.params.leaf_pairs());
    assert_eq!(deeper.radii.len(), 12 * 2 + 12 * 4);
    let bare = build(
        &mesh,
        &sub,
        &GridOptions {
            leaf_footprint: false,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(bare.radii.len(), 12 * 5);
    assert_eq!(scene.params.inner_count, 21);
    // 18 edges of 7 vertices, 8 corners.
    assert_eq!(scene.vertices.len() / 3, 12 * 21 + 18 * 7 + 8);
    // Quantized: an exponent and 21 x 3 codes in 32 words per grid.
    let mut quantized = sub.clone();
    quantized.quantize_inner();
    let q = build(&mesh, &quantized, &GridOptions::default()).unwrap();
    assert_eq!(q.params.inner_words, 32);
    assert_eq!(q.vertices.len(), 12 * 32 + 3 * (18 * 7 + 8));
    assert!(scene.set_lod_checked(4).is_err());
}

impl GridScene {
    fn set_lod_checked(&self, lod: u32) -> Result<()> {
        self.clone().set_lod(lod)
    }
}

/// A mesh whose grids the vertex buffer cannot address is refused by a check that needs no
/// subdivision; one with more base edges than packed headers hold is not refused.
#[test]
fn meshes_beyond_grid_addresses_are_refused_up_front() {
    // A strip of T triangles has 2T + 1 edges and T + 2 vertices.
    let ok = strip(MAX_HEADER_ID / 2 - 1);
    check_limits(&ok, &GridBuild::new(3)).unwrap();
    check_limits(&strip(MAX_HEADER_ID / 2 + 1), &GridBuild::new(3)).unwrap();
    // Vertex words: 16-bit inner codes take the buffer past its addresses at L = 6 only.
    check_limits(&ok, &GridBuild::new(5)).unwrap();
    let e = check_limits(&ok, &GridBuild::new(6)).unwrap_err().to_string();
    assert!(e.contains("more than a grid scene can address"), "{e}");
}

/// The buffer sizes known before the build are those of the built scene, but for the
/// top-level BVH's, which they bound from below.
#[test]
fn buffer_sizes_are_known_before_the_build() {
    let half = GridOptions {
        radii: RadiusFormat::Half,
        leaf_footprint: false,
        excluded_levels: 1,
        top: TopFormat::Compact,
        tight_headers: true,
        own_rooms: true,
    };
    for mesh in [default_scene(), fins(), cube()] {
        for (levels, options, quantized) in [
            (0, GridOptions::default(), true),
            (2, GridOptions::default(), false),
            (3, half, true),
            (4, GridOptions::default(), true),
            (4, GridOptions::for_displaced(), true),
        ] {
            let build = GridBuild {
                options,
                quantized,
                ..GridBuild::new(levels)
            };
            let known = check_limits(&mesh, &build).unwrap();
            let scene = crate::scene::Scene::Grids(build_lean(&mesh, &build).unwrap());
            let built = crate::split::scene_buffers(&scene);
            assert_eq!(known.len(), built.len());
            assert_eq!(known.iter().filter(|k| k.at_least).count(), 1);
            for (k, b) in known.iter().zip(&built) {
                let bytes = b.words.len() as u64 * 4;
                assert_eq!(k.name, b.name);
                match k.at_least {
                    true => assert!(k.bytes <= bytes && k.bytes > 0, "{k:?} against {bytes}"),
                    false => assert_eq!(k.bytes, bytes, "{} at L = {levels}, {options:?}", k.name),
                }
            }
        }
    }
}

/// A zigzag strip of `triangles` triangles in the plane z = 0.
fn strip(triangles: u32) -> Mesh {
    Mesh {
        positions: (0..triangles + 2)
            .map(|i| Vec3::new(i as f32 * 0.5, (i % 2) as f32, 0.0))
            .collect(),
        triangles: (0..triangles)
            .map(|i| {
                if i % 2 == 0 {
                    [i, i + 1, i + 2]
                } else {
                    [i + 1, i, i + 2]
                }
            })
            .collect(),
    }
}

/// Tight headers hold the ids packed headers hold, each in as many bits as its count needs.
#[test]
fn tight_headers_hold_the_same_ids() {
    for mesh in [default_scene(), cube(), fins()] {
        let sub = subdivide(&mesh, 2, Scheme::Loop);
        let packed = build(&mesh, &sub, &GridOptions::default()).unwrap();
        let options = GridOptions {
            tight_headers: true,
            ..Default::default()
        };
        let tight = build(&mesh, &sub, &options).unwrap();
        let edges = BaseEdges::new(&mesh).owner.len() as u32;
        let bits = |count: u32| 32 - (count.max(2) - 1).leading_zeros();
        assert_eq!(
            tight.params.header_bits,
            bits(edges) | bits(mesh.positions.len() as u32) << 8
        );
        assert!(tight.headers.len() < packed.headers.len());
        let (a, b) = (packed.view(), tight.view());
        for g in 0..packed.grid_count() as u32 {
            assert_eq!(a.ids(g), b.ids(g), "grid {g}");
        }
        // And back to wide headers, as a mesh past 2^21 ids gets them.
        let wide = tight.with_wide_headers();
        for g in 0..packed.grid_count() as u32 {
            assert_eq!(a.ids(g), wide.view().ids(g), "grid {g}");
        }
    }
}

/// Packed headers hold ids below 2^21: a mesh with more base edges or vertices gets wide
/// headers, and its grids still find their own corners and edges.
#[test]
fn meshes_past_packed_ids_get_wide_headers() {
    let packed = MAX_HEADER_ID as u64 + 1;
    assert!(!needs_wide_headers(packed, packed));
    assert!(needs_wide_headers(packed + 1, 3));
    assert!(needs_wide_headers(3, packed + 1));
    let flat = GridBuild {
        scheme: Scheme::Flat,
        ..GridBuild::new(1)
    };
    let small = build_lean(&strip(1000), &flat).unwrap();
    assert_eq!(small.params.wide_headers, 0);
    assert_eq!(small.headers.len(), small.grid_count());
    // 2^21 + 3 edges.
    let base = strip(MAX_HEADER_ID / 2 + 1);
    let scene = build_lean(&base, &flat).unwrap();
    assert_eq!(scene.params.wide_headers, 1);
    assert_eq!(scene.headers.len(), 2 * scene.grid_count());
    let view = scene.view();
    let edges = BaseEdges::new(&base);
    let mut highest_edge = 0;
    for slot in 0..scene.grid_count() {
        let t = scene.base_triangle[slot] as usize;
        let ids = view.ids(slot as u32);
        assert_eq!(ids.corners, base.triangles[t]);
        assert_eq!(ids.edges, edges.of_grid[t]);
        highest_edge = highest_edge.max(ids.edges.into_iter().max().unwrap());
        // The midpoint of edge 0, read through the ids, lies between its corners.
        let open = view.open(slot as u32);
        let mid = view.vertex(&open, [1, 0]);
        let [a, b, _] = base.triangles[t].map(|v| base.positions[v as usize]);
        assert!(
            mid.distance(a.lerp(b, 0.5)) < 1e-3,
            "grid {slot}: {mid} between {a} and {b}"
        );
    }
    assert!(highest_edge > MAX_HEADER_ID);
}

/// The lean build (each grid subdivided on its own, written straight into place) gives
/// exactly the scene of subdividing the whole mesh first: every buffer, bit for bit.
#[test]
fn the_lean_build_equals_the_whole_mesh_build() {
    // A fan of 300 faces: too costly for patches, so the lean build subdivides it whole.
    let fan = Mesh {
        positions: std::iter::once(Vec3::Z)
            .chain((0..300).map(|k| {
                let a = k as f32 * std::f32::consts::TAU / 300.0;
                Vec3::new(a.cos(), a.sin(), 0.0)
            }))
            .collect(),
        triangles: (0..300).map(|k| [0, 1 + k, 1 + (k + 1) % 300]).collect(),
    };
    assert!(!lean_build_applies(&fan) && lean_build_applies(&fins()));
    let options = [
        GridOptions::default(),
        GridOptions {
            excluded_levels: 1,
            radii: RadiusFormat::Half,
            leaf_footprint: false,
            top: TopFormat::Wide,
            tight_headers: true,
            own_rooms: true,
        },
        GridOptions::for_displaced(),
    ];
    for (name, mesh) in [
        ("default scene", default_scene()),
        ("cube", cube()),
        ("fins", fins()),
        ("fan", fan),
    ] {
        for levels in 0..=4 {
            for (scheme, quantized, options) in [
                (Scheme::Loop, true, options[0]),
                (Scheme::Loop, false, options[1]),
                (Scheme::Flat, true, options[1]),
            ] {
                let mut sub = subdivide(&mesh, levels, scheme);
                if quantized {
                    sub.quantize_inner();
                }
                let whole = build(&mesh, &sub, &options).unwrap();
                let lean = build_lean(
                    &mesh,
                    &GridBuild {
                        levels,
                        scheme,
                        crease_angle: None,
                        options,
                        quantized,
                    },
                )
                .unwrap();
                assert!(lean == whole, "{name} L={levels} {scheme:?} quantized={quantized}");
            }
        }
    }
}

#[test]
fn records_reorder_in_place() {
    let order = [3u32, 0, 4, 1, 2, 5];
    let mut data: Vec<u32> = (0..12).collect();
    reorder_records(&mut data, 2, &order);
    assert_eq!(data, [6, 7, 0, 1, 8, 9, 2, 3, 4, 5, 10, 11]);
}

/// How far a leaf's lattice points lie from their flat places at most: the leaf's corners are
/// lattice points `lattice`, `m` steps a side, and `at` gives a lattice point's position; a
/// point's flat place is the same point of the flat triangle of the corners' positions.
pub(crate) fn farthest_from_flat(lattice: [[i32; 2]; 3], m: i32, at: impl Fn([u32; 2]) -> Vec3) -> f32 {
    let c = lattice.map(|p| at([p[0] as u32, p[1] as u32]));
    let mut moved = 0f32;
    for lb in 0..=m {
        for la in 0..=m - lb {
            let p = [0, 1].map(|x| {
                lattice[0][x] + (la * (lattice[1][x] - lattice[0][x]) + lb * (lattice[2][x] - lattice[0][x])) / m
            });
            let (u, w) = (la as f32 / m as f32, lb as f32 / m as f32);
            let flat = c[0] + (c[1] - c[0]) * u + (c[2] - c[0]) * w;
            moved = moved.max(at([p[0] as u32, p[1] as u32]).distance(flat));
        }
    }
    moved
}

/// A top level the SAH alone would build deeper than a binary walk's stack holds (nested
/// boxes, each 1.2 times the last, peeled off one or a few at a time) stays within it: a
/// binary walk pushes at most one node per level below the root, so every waiting node has a
/// slot.
#[test]
fn top_levels_fit_the_binary_walks_stack() {
    use crate::bvh::{build, depth};
    use gridrt_shared::traverse::BINARY_TOP_STACK;
    let boxes: Vec<Aabb> = (0..480)
        .map(|k| {
            let x = 1.2f32.powi(k - 240);
            Aabb {
                min: Vec3::ZERO,
                max: Vec3::splat(x),
            }
        })
        .collect();
    let params = top_level_params();
    let unlimited = BuildParams {
        max_depth: usize::MAX / 2,
        ..params
    };
    let d = depth(&build(&boxes, &unlimited).nodes);
    assert!(d > BINARY_TOP_STACK, "the SAH alone goes {d} deep");
    assert!(depth(&build(&boxes, &params).nodes) < BINARY_TOP_STACK);
}
