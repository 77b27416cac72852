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
    for (name, mesh) in closed_meshes().into_iter().chain([("fins", fins())]) {
        let vertex_faces = VertexFaces::new(&mesh);
        let mut patch = Patch::default();
        let mut lattice = Vec::new();
        for levels in 0..=4 {
            for scheme in [Scheme::Loop, Scheme::Flat] {
                let whole = subdivide(&mesh, levels, scheme);
                let n = grid_size(levels);
                for t in 0..mesh.triangles.len() {
                    subdivide_triangle(&mesh, &vertex_faces, t as u32, levels, scheme, &mut patch, &mut lattice);
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
