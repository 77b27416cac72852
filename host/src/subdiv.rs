//! Subdivision of a base mesh into grids: `L` rounds of Loop (or midpoint) subdivision over the
//! whole mesh, so neighbouring grids share their edge and corner vertices by construction, while
//! every face remembers which base triangle and which lattice cell it came from.
//!
//! Loop rules (Loop 1987; boundary rules as in Hoppe et al. 1994): an edge used by exactly two
//! triangles is smooth, any other edge (boundary or non-manifold) is a crease. A vertex is
//! smooth when all its edges are smooth and its triangles form one fan; on exactly two creases
//! it follows them (`3/4 v + 1/8 (a + b)`); anything else is a corner and stays where it is.

use crate::mesh::Mesh;
use gridrt_shared::glam::Vec3;
use gridrt_shared::grid_index::{grid_size, lattice_index, sub_triangle, triangle_count, vertex_count, Lattice};

#[derive(Copy, Clone, Debug, PartialEq, Eq, Default)]
pub enum Scheme {
    /// Loop subdivision: a smooth limit surface.
    #[default]
    Loop,
    /// Midpoint subdivision: micro-vertices stay on the base triangles.
    Flat,
}

/// A base mesh subdivided `levels` times.
#[derive(Clone, Debug)]
pub struct Subdivided {
    pub levels: u32,
    /// Every vertex of the subdivided mesh. Base vertex `v` keeps id `v` (at its new position).
    pub positions: Vec<Vec3>,
    /// For each base triangle, its `vertex_count(levels)` lattice vertices in
    /// [`lattice_index`] order, as ids into `positions`.
    pub grids: Vec<u32>,
    /// Once [`Subdivided::quantize_inner`] has run: each grid's inner vertices as 16-bit codes
    /// (`quantize::inner_words` words per grid, base-triangle order), which `positions` then
    /// hold decoded.
    pub inner_codes: Option<Vec<u32>>,
}

impl Subdivided {
    pub fn grid_count(&self) -> usize {
        self.grids.len() / vertex_count(self.levels) as usize
    }

    /// Vertex id of lattice point `p` of grid `grid`.
    #[inline]
    pub fn vertex(&self, grid: usize, p: Lattice) -> u32 {
        let n = grid_size(self.levels);
        self.grids[grid * vertex_count(self.levels) as usize + lattice_index(p[0], p[1], n) as usize]
    }

    /// The micro-triangles at depth `lod <= levels` as an indexed list: triangle
    /// `grid * 4^lod + t` is sub-triangle `t` (recursion order) of base triangle `grid`, with
    /// the corner order the grid traversal uses.
    pub fn micro_triangles(&self, lod: u32) -> Vec<[u32; 3]> {
        let n = grid_size(self.levels);
        let per_grid = triangle_count(lod);
        let mut out = Vec::with_capacity(self.grid_count() * per_grid as usize);
        for g in 0..self.grid_count() {
            for t in 0..per_grid {
                let c = sub_triangle(n, lod, t);
                out.push([self.vertex(g, c[0]), self.vertex(g, c[1]), self.vertex(g, c[2])]);
            }
        }
        out
    }
}

/// A face during subdivision: its vertices, its base triangle and its lattice corners.
#[derive(Copy, Clone)]
struct Face {
    v: [u32; 3],
    base: u32,
    lattice: [Lattice; 3],
}

pub fn subdivide(mesh: &Mesh, levels: u32, scheme: Scheme) -> Subdivided {
    let mut positions = mesh.positions.clone();
    let mut faces: Vec<Face> = mesh
        .triangles
        .iter()
        .enumerate()
        .map(|(b, &v)| Face {
            v,
            base: b as u32,
            lattice: [[0, 0], [1, 0], [0, 1]],
        })
        .collect();
    for _ in 0..levels {
        let (new_positions, mids) = refine(&positions, &faces, scheme);
        let mut next = Vec::with_capacity(faces.len() * 4);
        for (f, m) in faces.iter().zip(&mids) {
            // Lattice coordinates double at each round; midpoints land on the new odd points.
            let l = f.lattice.map(|p| [2 * p[0], 2 * p[1]]);
            let corners = [(f.v[0], l[0]), (f.v[1], l[1]), (f.v[2], l[2])];
            let mid = |e: usize| {
                let (a, b) = (l[e], l[(e + 1) % 3]);
                (m[e], [(a[0] + b[0]) / 2, (a[1] + b[1]) / 2])
            };
            let (ab, bc, ca) = (mid(0), mid(1), mid(2));
            // Same child order and corner order as `grid_index::child_corners`.
            for tri in [
                [corners[0], ab, ca],
                [ab, corners[1], bc],
                [ca, bc, corners[2]],
                [bc, ca, ab],
            ] {
                next.push(Face {
                    v: tri.map(|c| c.0),
                    base: f.base,
                    lattice: tri.map(|c| c.1),
                });
            }
        }
        positions = new_positions;
        faces = next;
    }
    let n = grid_size(levels);
    let per_grid = vertex_count(levels) as usize;
    let mut grids = vec![u32::MAX; mesh.triangles.len() * per_grid];
    for f in &faces {
        for c in 0..3 {
            let [i, j] = f.lattice[c];
            grids[f.base as usize * per_grid + lattice_index(i, j, n) as usize] = f.v[c];
        }
    }
    debug_assert!(grids.iter().all(|&v| v != u32::MAX));
    Subdivided {
        levels,
        positions,
        grids,
        inner_codes: None,
    }
}

/// One round: the new positions (old vertices first, then one per edge) and, for every face,
/// the ids of the new vertices on its edges `(v0 v1)`, `(v1 v2)`, `(v2 v0)`.
fn refine(positions: &[Vec3], faces: &[Face], scheme: Scheme) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let nv = positions.len();
    // Group the face edges by their undirected vertex pair.
    let mut keys: Vec<(u64, u32)> = Vec::with_capacity(faces.len() * 3);
    for (f, face) in faces.iter().enumerate() {
        for e in 0..3 {
            let (a, b) = (face.v[e], face.v[(e + 1) % 3]);
            let key = ((a.min(b) as u64) << 32) | a.max(b) as u64;
            keys.push((key, (f * 3 + e) as u32));
        }
    }
    keys.sort_unstable();
    let mut mids = vec![[0u32; 3]; faces.len()];
    let mut edges: Vec<(u32, u32, std::ops::Range<usize>)> = Vec::new();
    let mut start = 0;
    while start < keys.len() {
        let mut end = start + 1;
        while end < keys.len() && keys[end].0 == keys[start].0 {
            end += 1;
        }
        let id = (nv + edges.len()) as u32;
        for &(_, fe) in &keys[start..end] {
            mids[fe as usize / 3][fe as usize % 3] = id;
        }
        let key = keys[start].0;
        edges.push(((key >> 32) as u32, key as u32, start..end));
        start = end;
    }

    // Fans: corners of faces at the same vertex are joined across every edge they share, so a
    // vertex whose corners end up in one set has one connected fan.
    let mut fans = UnionFind::new(faces.len() * 3);
    let corner_at = |fe: u32, v: u32| {
        let f = fe as usize / 3;
        let c = faces[f].v.iter().position(|&x| x == v).unwrap();
        f * 3 + c
    };
    for (a, b, range) in &edges {
        let group = &keys[range.clone()];
        for w in group.windows(2) {
            fans.union(corner_at(w[0].1, *a), corner_at(w[1].1, *a));
            fans.union(corner_at(w[0].1, *b), corner_at(w[1].1, *b));
        }
    }
    let mut fan_root = vec![u32::MAX; nv];
    let mut single_fan = vec![true; nv];
    for (f, face) in faces.iter().enumerate() {
        for c in 0..3 {
            let v = face.v[c] as usize;
            let root = fans.find(f * 3 + c) as u32;
            if fan_root[v] == u32::MAX {
                fan_root[v] = root;
            } else if fan_root[v] != root {
                single_fan[v] = false;
            }
        }
    }

    let mut neighbour_sum = vec![Vec3::ZERO; nv];
    let mut valence = vec![0u32; nv];
    let mut crease_sum = vec![Vec3::ZERO; nv];
    let mut creases = vec![0u32; nv];
    let mut new_positions = positions.to_vec();
    new_positions.reserve(edges.len());
    for (a, b, range) in &edges {
        let (pa, pb) = (positions[*a as usize], positions[*b as usize]);
        let (a, b) = (*a as usize, *b as usize);
        neighbour_sum[a] += pb;
        neighbour_sum[b] += pa;
        valence[a] += 1;
        valence[b] += 1;
        let smooth = range.len() == 2;
        if !smooth {
            crease_sum[a] += pb;
            crease_sum[b] += pa;
            creases[a] += 1;
            creases[b] += 1;
        }
        let p = if smooth && scheme == Scheme::Loop {
            let opposite = |fe: u32| {
                let face = &faces[fe as usize / 3];
                let e = fe as usize % 3;
                positions[face.v[(e + 2) % 3] as usize]
            };
            (pa + pb) * 0.375 + (opposite(keys[range.start].1) + opposite(keys[range.start + 1].1)) * 0.125
        } else {
            (pa + pb) * 0.5
        };
        new_positions.push(p);
    }
    if scheme == Scheme::Loop {
        for v in 0..nv {
            let p = positions[v];
            new_positions[v] = if valence[v] == 0 {
                p
            } else if creases[v] == 0 && single_fan[v] {
                let beta = loop_beta(valence[v]);
                p * (1.0 - valence[v] as f32 * beta) + neighbour_sum[v] * beta
            } else if creases[v] == 2 && single_fan[v] {
                p * 0.75 + crease_sum[v] * 0.125
            } else {
                p
            };
        }
    }
    (new_positions, mids)
}

/// Loop's vertex weight for valence `n`: `(5/8 - (3/8 + 1/4 cos(2 pi / n))^2) / n`.
pub fn loop_beta(n: u32) -> f32 {
    let n = n as f64;
    let c = 0.375 + 0.25 * (2.0 * std::f64::consts::PI / n).cos();
    ((0.625 - c * c) / n) as f32
}

struct UnionFind {
    parent: Vec<u32>,
}

impl UnionFind {
    fn new(n: usize) -> Self {
        UnionFind {
            parent: (0..n as u32).collect(),
        }
    }

    fn find(&mut self, mut x: usize) -> usize {
        while self.parent[x] as usize != x {
            let up = self.parent[self.parent[x] as usize];
            self.parent[x] = up;
            x = up as usize;
        }
        x
    }

    fn union(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            self.parent[ra.max(rb)] = ra.min(rb) as u32;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::scene::{cube, default_scene, tetrahedron};
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

    fn euler(tris: &[[u32; 3]]) -> i64 {
        let mut verts: Vec<u32> = tris.iter().flatten().copied().collect();
        verts.sort();
        verts.dedup();
        verts.len() as i64 - edge_use(tris).len() as i64 + tris.len() as i64
    }

    #[test]
    fn closed_meshes_stay_closed_with_the_same_euler_characteristic() {
        for (name, mesh) in [
            ("tetrahedron", tetrahedron()),
            ("cube", cube()),
            ("default scene", default_scene()),
        ] {
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
}
