//! Subdivision checked against the Loop stencils, closedness and the limit positions.

use super::*;
use crate::mesh::scene::{cube, default_scene, fins, tetrahedron};
use std::collections::HashMap;

/// Undirected edge -> number of faces using it, over the micro-triangles.
fn edge_use(tris: &[[u32; 3]]) -> HashMap<(u32, u32), u32> {
    let mut m = HashMap::new();
    for t in tris {
        for e in 0..3 {
            let (a, b) = (t[e], t[(e + 1) % 3]);
            *m.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    m
}

fn closed_meshes() -> [(&'static str, Mesh); 3] {
    [
        ("tetrahedron", tetrahedron()),
        ("cube", cube()),
        ("default scene", default_scene()),
    ]
}

fn euler(tris: &[[u32; 3]]) -> i64 {
    let mut verts: Vec<u32> = tris.iter().flatten().copied().collect();
    verts.sort();
    verts.dedup();
    verts.len() as i64 - edge_use(tris).len() as i64 + tris.len() as i64
}

#[test]
fn closed_meshes_stay_closed_with_the_same_euler_characteristic() {
    for (name, mesh) in closed_meshes() {
        let chi = euler(&mesh.triangles);
        for levels in 1..=3 {
            for scheme in [Scheme::Loop, Scheme::Flat] {
                let sub = subdivide(&mesh, levels, scheme);
                let micro = sub.micro_triangles(levels);
                assert_eq!(micro.len(), mesh.triangles.len() << (2 * levels));
                assert_eq!(euler(&micro), chi, "{name} L={levels}");
                assert!(
                    edge_use(&micro).values().all(|&c| c == 2),
                    "{name} L={levels}: not closed"
                );
            }
        }
    }
}

#[test]
fn level_five_is_consistent() {
    let mesh = tetrahedron();
    let sub = subdivide(&mesh, 5, Scheme::Loop);
    let micro = sub.micro_triangles(5);
    assert_eq!(euler(&micro), 2);
    assert!(edge_use(&micro).values().all(|&c| c == 2));
    // V = 2 + F / 2 for a closed genus-0 triangle mesh.
    assert_eq!(sub.positions.len(), 2 + micro.len() / 2);
}

/// One round reproduces the Loop stencils exactly.
#[test]
fn one_round_matches_the_loop_stencils() {
    let mesh = tetrahedron();
    let sub = subdivide(&mesh, 1, Scheme::Loop);
    let p = &mesh.positions;
    let beta = loop_beta(3);
    for v in 0..4 {
        let ring: Vec3 = (0..4).filter(|&u| u != v).map(|u| p[u]).sum();
        let expect = p[v] * (1.0 - 3.0 * beta) + ring * beta;
        assert!(sub.positions[v].distance(expect) < 1e-6, "vertex {v}");
    }
    // Edge (v0 v1) of triangle 0: the two opposite vertices are the remaining two.
    let [a, b, _] = mesh.triangles[0];
    let others: Vec3 = (0..4u32).filter(|&u| u != a && u != b).map(|u| p[u as usize]).sum();
    let expect = (p[a as usize] + p[b as usize]) * 0.375 + others * 0.125;
    assert!(sub.positions[sub.vertex(0, [1, 0]) as usize].distance(expect) < 1e-6);
}

/// Corners converge to the Loop limit position `v_inf = (3/8 v + beta sum) / (3/8 + n beta)`,
/// and exactly as the stencil predicts: `v_k - v_inf = (5/8 - n beta)^k (v_0 - v_inf)`.
#[test]
fn corners_converge_to_the_limit_positions() {
    for mesh in [tetrahedron(), cube()] {
        let mut ring = vec![Vec::new(); mesh.positions.len()];
        for t in &mesh.triangles {
            for e in 0..3 {
                let (a, b) = (t[e] as usize, t[(e + 1) % 3] as usize);
                if !ring[a].contains(&b) {
                    ring[a].push(b);
                    ring[b].push(a);
                }
            }
        }
        for levels in [1, 3, 5] {
            let sub = subdivide(&mesh, levels, Scheme::Loop);
            for (v, neighbours) in ring.iter().enumerate() {
                let n = neighbours.len() as f32;
                let beta = loop_beta(neighbours.len() as u32);
                let sum: Vec3 = neighbours.iter().map(|&u| mesh.positions[u]).sum();
                let limit = (mesh.positions[v] * 0.375 + sum * beta) / (0.375 + n * beta);
                let shrink = (0.625 - n * beta).powi(levels as i32);
                let expect = limit + (mesh.positions[v] - limit) * shrink;
                let got = sub.positions[v];
                assert!(
                    got.distance(expect) < 1e-5,
                    "valence {n}, L={levels}: {got} vs {expect}"
                );
                if levels == 5 {
                    assert!(got.distance(limit) < 2e-3, "valence {n}: not near the limit");
                }
            }
        }
    }
}

#[test]
fn boundaries_and_non_manifold_edges_are_creases() {
    // Three triangles on one edge (0, 1), plus an open boundary everywhere else.
    let mesh = Mesh {
        positions: vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::new(0.5, 1.0, 0.0),
            Vec3::new(0.5, -1.0, 0.0),
            Vec3::new(0.5, 0.0, 1.0),
        ],
        triangles: vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]],
    };
    let sub = subdivide(&mesh, 2, Scheme::Loop);
    // The non-manifold edge's midpoint is the plain midpoint, shared by all three grids.
    let mid = sub.vertex(0, [2, 0]);
    assert_eq!(sub.positions[mid as usize], Vec3::new(0.5, 0.0, 0.0));
    assert_eq!(sub.vertex(2, [2, 0]), mid);
    assert_eq!(sub.vertex(1, [2, 0]), mid);
    // Vertices 0 and 1 lie on more than two creases: corners, they stay.
    assert_eq!(sub.positions[0], Vec3::ZERO);
    assert_eq!(sub.positions[1], Vec3::X);
    // Every position is finite.
    assert!(sub.positions.iter().all(|p| p.is_finite()));
}

#[test]
fn flat_subdivision_stays_on_the_base_triangles() {
    let mesh = cube();
    let sub = subdivide(&mesh, 3, Scheme::Flat);
    let n = grid_size(3) as f32;
    for (g, t) in mesh.triangles.iter().enumerate() {
        let [a, b, c] = t.map(|v| mesh.positions[v as usize]);
        for j in 0..=8u32 {
            for i in 0..=8 - j {
                let expect = a + (b - a) * (i as f32 / n) + (c - a) * (j as f32 / n);
                assert!(sub.positions[sub.vertex(g, [i, j]) as usize].distance(expect) < 1e-5);
            }
        }
    }
}

/// Each base triangle subdivided from its neighbourhood alone comes out bit for bit as in the
/// whole mesh: smooth, boundary, non-manifold and corner rules, both schemes, any depth.
#[test]
fn a_triangle_subdivided_alone_matches_the_whole_mesh() {
    let meshes = closed_meshes()
        .into_iter()
        .chain([("fins", fins()), ("house", house())]);
    for (name, mesh) in meshes {
        matches_whole_mesh(name, &mesh, &Creases::none());
        matches_whole_mesh(&format!("{name} creased"), &mesh, &Creases::from_angle(&mesh, 30.0));
    }
    let dart = dart_fan();
    let creases = Creases::from_angle(&dart, 70.0);
    assert_eq!(creases.edge_count(), 1);
    matches_whole_mesh("dart", &dart, &creases);
}

/// Six triangles around an inner vertex, one spoke folded by 98 degrees and the others by at
/// most 49: at 70 degrees, one crease ending inside the surface (a dart).
fn dart_fan() -> Mesh {
    let lift = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let mut positions = vec![Vec3::ZERO];
    positions.extend((0..6).map(|k| {
        let a = k as f32 * std::f32::consts::FRAC_PI_3;
        Vec3::new(a.cos(), a.sin(), lift[k])
    }));
    let triangles = (0..6).map(|k| [0, 1 + k, 1 + (k + 1) % 6]).collect();
    Mesh { positions, triangles }
}

/// A dart's inner vertex moves by the smooth rule, not held as a corner.
#[test]
fn a_dart_vertex_stays_smooth() {
    let dart = dart_fan();
    let sub = subdivide_creased(&dart, 1, Scheme::Loop, &Creases::from_angle(&dart, 70.0));
    let beta = loop_beta(6);
    let sum: Vec3 = dart.positions[1..].iter().copied().sum();
    let expect = dart.positions[0] * (1.0 - 6.0 * beta) + sum * beta;
    assert!(
        sub.positions[0].distance(expect) < 1e-6,
        "{} != {expect}",
        sub.positions[0]
    );
}

fn matches_whole_mesh(name: &str, mesh: &Mesh, creases: &Creases) {
    {
        let vertex_faces = VertexFaces::new(mesh);
        let source = PatchSource {
            mesh,
            vertex_faces: &vertex_faces,
            creases,
        };
        let mut patch = Patch::default();
        let mut lattice = Vec::new();
        for levels in 0..=4 {
            for scheme in [Scheme::Loop, Scheme::Flat] {
                let whole = subdivide_creased(mesh, levels, scheme, creases);
                let n = grid_size(levels);
                for t in 0..mesh.triangles.len() {
                    subdivide_triangle(&source, t as u32, levels, scheme, &mut patch, &mut lattice);
                    for j in 0..=n {
                        for i in 0..=n - j {
                            let expect = whole.positions[whole.vertex(t, [i, j]) as usize];
                            let got = lattice[lattice_index(i, j, n) as usize];
                            assert_eq!(
                                got.to_array().map(f32::to_bits),
                                expect.to_array().map(f32::to_bits),
                                "{name} {scheme:?} L={levels} triangle {t} at ({i}, {j})"
                            );
                        }
                    }
                }
            }
        }
    }
}

/// A closed box with a gabled roof of 20 degree slopes (the ridge folds by 40 degrees, the
/// eaves by 70): 10 vertices, 16 triangles.
fn house() -> Mesh {
    let rise = 20f32.to_radians().tan();
    let mut positions: Vec<Vec3> = (0..8)
        .map(|i| Vec3::new(sign(i & 1), sign(i & 2), sign(i & 4)))
        .collect();
    positions.push(Vec3::new(-1.0, 1.0 + rise, 0.0));
    positions.push(Vec3::new(1.0, 1.0 + rise, 0.0));
    let faces: [&[u32]; 7] = [
        &[0, 1, 3, 2],
        &[0, 1, 5, 4],
        &[0, 2, 6, 4],
        &[1, 3, 7, 5],
        &[4, 5, 7, 6],
        &[2, 3, 9, 8],
        &[6, 7, 9, 8],
    ];
    let mut triangles: Vec<[u32; 3]> = faces
        .iter()
        .flat_map(|f| [[f[0], f[1], f[2]], [f[0], f[2], f[3]]])
        .collect();
    // The gables.
    triangles.extend([[2, 8, 6], [3, 7, 9]]);
    crate::mesh::scene::orient_convex(Mesh { positions, triangles })
}

fn sign(bit: u32) -> f32 {
    if bit == 0 {
        -1.0
    } else {
        1.0
    }
}

/// A cube creased at 30 degrees keeps every micro-vertex of its edges on those edges and every
/// face flat: subdivided, it is still the cube. Without creases it rounds.
#[test]
fn a_creased_cube_keeps_its_edges_and_faces() {
    let mesh = cube();
    let creases = Creases::from_angle(&mesh, 30.0);
    assert_eq!(creases.edge_count(), 12, "the cube's edges, not its faces' diagonals");
    for levels in 1..=4 {
        let sub = subdivide_creased(&mesh, levels, Scheme::Loop, &creases);
        let n = grid_size(levels);
        for g in 0..mesh.triangles.len() {
            for j in 0..=n {
                for i in 0..=n - j {
                    let p = sub.positions[sub.vertex(g, [i, j]) as usize];
                    // On the cube's surface: one coordinate at +-1, the others within.
                    let on_face = p.to_array().iter().filter(|c| (c.abs() - 1.0).abs() < 1e-6).count();
                    assert!(on_face >= 1 && p.abs().max_element() < 1.0 + 1e-6, "L={levels} {p}");
                    let on_lattice_edge = j == 0 || i == 0 || i + j == n;
                    let edge = if j == 0 {
                        0
                    } else if i + j == n {
                        1
                    } else {
                        2
                    };
                    if on_lattice_edge && creases.of(g) & (1 << edge) != 0 {
                        assert!(on_face >= 2, "L={levels} grid {g} ({i}, {j}) left its edge: {p}");
                    }
                }
            }
        }
    }
    // Without creases the corners are pulled in.
    let round = subdivide(&mesh, 2, Scheme::Loop);
    assert!(round.positions[0].length() < 3f32.sqrt() - 0.1);
}

#[test]
fn crease_angles_choose_the_folds_sharper_than_them() {
    let mesh = house();
    // The floor's 4 edges and the walls' 4 corners (90 degrees), 4 gable rakes (90), 2 eaves
    // (70) and the ridge (40); the gables lie flat on their walls.
    assert_eq!(Creases::from_angle(&mesh, 30.0).edge_count(), 15);
    assert_eq!(Creases::from_angle(&mesh, 50.0).edge_count(), 14);
    assert_eq!(Creases::from_angle(&mesh, 80.0).edge_count(), 12);
    assert_eq!(Creases::from_angle(&mesh, 0.0).edge_count(), 15);
    assert_eq!(Creases::from_angle(&mesh, 180.0), Creases::none());
    assert_eq!(Creases::from_angle(&mesh, f32::NAN), Creases::none());
    // Scale and offset change no angle.
    let moved = Mesh {
        positions: mesh.positions.iter().map(|p| *p * 1e4 + Vec3::splat(3e5)).collect(),
        triangles: mesh.triangles.clone(),
    };
    assert_eq!(Creases::from_angle(&moved, 30.0), Creases::from_angle(&mesh, 30.0));
    // A triangle wound against its neighbours does not fold the flat cube face it lies in.
    let mut flipped = cube();
    flipped.triangles[0].swap(1, 2);
    assert_eq!(Creases::from_angle(&flipped, 30.0).edge_count(), 12);
}

#[test]
fn patch_faces_grow_with_the_square_of_valence() {
    // Every cube vertex has 4 to 6 faces; a fan of k faces around one vertex adds k^2.
    let fan = Mesh {
        positions: (0..=10)
            .map(|k| match k {
                0 => Vec3::ZERO,
                k => {
                    let a = k as f32;
                    Vec3::new(a.cos(), a.sin(), 0.0)
                }
            })
            .collect(),
        triangles: (1..10).map(|k| [0, k, k + 1]).collect(),
    };
    // Centre: 9 faces; rim ends 1 face each; rim middles 2 faces each.
    assert_eq!(VertexFaces::new(&fan).patch_faces(), 81 + 2 + 8 * 4);
}
