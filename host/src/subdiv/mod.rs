//! Subdivision of a base mesh into grids: `L` rounds of Loop (or midpoint) subdivision over the
//! whole mesh, so neighbouring grids share their edge and corner vertices by construction, while
//! every face remembers which base triangle and which lattice cell it came from.
//!
//! Loop rules (Loop 1987; boundary rules as in Hoppe et al. 1994): an edge used by exactly two
//! triangles is smooth, any other edge (boundary or non-manifold) is a crease. A vertex is
//! smooth when all its edges are smooth and its triangles form one fan; on exactly two creases
//! it follows them (`3/4 v + 1/8 (a + b)`); anything else is a corner and stays where it is.
//! Edges may also be chosen as creases ([`Creases`], by dihedral angle): a vertex on one such
//! edge (a dart) stays smooth, and the halves of a crease are creases in the next round.

use crate::mesh::Mesh;
use gridrt_shared::glam::Vec3;
use gridrt_shared::grid_index::{grid_size, lattice_index, sub_triangle, triangle_count, vertex_count, Lattice};

mod creases;
mod patch;
pub use creases::Creases;
pub use patch::{subdivide_triangle, Patch, PatchSource, VertexFaces};

#[derive(Copy, Clone, Debug, PartialEq, Eq, Default)]
pub enum Scheme {
    /// Loop subdivision: a smooth limit surface.
    #[default]
    Loop,
    /// Midpoint subdivision: micro-vertices stay on the base triangles.
    Flat,
}

impl std::str::FromStr for Scheme {
    type Err = crate::error::Error;

    /// The names the CLI's `--subdivision` takes: loop, flat.
    fn from_str(name: &str) -> crate::error::Result<Scheme> {
        Ok(match name {
            "loop" => Scheme::Loop,
            "flat" => Scheme::Flat,
            _ => crate::error::fail!(Options, "no subdivision is called {name:?}: loop or flat"),
        })
    }
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

/// A face during subdivision: its vertices, its base triangle, its lattice corners, and which
/// of its edges (bit `e`: corner `e` to corner `e + 1`) lie on a chosen crease.
#[derive(Copy, Clone)]
struct Face {
    v: [u32; 3],
    base: u32,
    lattice: [Lattice; 3],
    crease: u8,
}

impl Face {
    /// Base triangle `base` itself, with vertices `v`: the whole lattice, one step across.
    fn base(v: [u32; 3], base: u32, crease: u8) -> Face {
        Face {
            v,
            base,
            lattice: [[0, 0], [1, 0], [0, 1]],
            crease,
        }
    }

    /// Whether edge `e` lies on a chosen crease.
    fn is_crease(&self, e: usize) -> bool {
        self.crease & (1 << e) != 0
    }
}

/// `mesh` subdivided `levels` times, with only its boundaries and non-manifold edges as creases.
pub fn subdivide(mesh: &Mesh, levels: u32, scheme: Scheme) -> Subdivided {
    subdivide_creased(mesh, levels, scheme, &Creases::none())
}

/// `mesh` subdivided `levels` times, keeping `creases` as well as its boundaries sharp.
pub fn subdivide_creased(mesh: &Mesh, levels: u32, scheme: Scheme, creases: &Creases) -> Subdivided {
    let mut positions = mesh.positions.clone();
    let mut faces: Vec<Face> = mesh
        .triangles
        .iter()
        .enumerate()
        .map(|(b, &v)| Face::base(v, b as u32, creases.of(b)))
        .collect();
    for _ in 0..levels {
        let (new_positions, mids) = refine(&positions, &faces, scheme);
        positions = new_positions;
        faces = children(&faces, &mids);
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

/// The four faces each face splits into, given the new vertices on its edges (from [`refine`]):
/// lattice coordinates double at each round and the midpoints land on the new odd points.
/// Same child order and corner order as `grid_index::child_corners`. A child edge along a
/// parent edge is a crease when that edge is; the inner edges are not.
fn children(faces: &[Face], mids: &[[u32; 3]]) -> Vec<Face> {
    let mut next = Vec::with_capacity(faces.len() * 4);
    for (f, m) in faces.iter().zip(mids) {
        let l = f.lattice.map(|p| [2 * p[0], 2 * p[1]]);
        let corners = [(f.v[0], l[0]), (f.v[1], l[1]), (f.v[2], l[2])];
        let mid = |e: usize| {
            let (a, b) = (l[e], l[(e + 1) % 3]);
            (m[e], [(a[0] + b[0]) / 2, (a[1] + b[1]) / 2])
        };
        let (ab, bc, ca) = (mid(0), mid(1), mid(2));
        // Child edges on parent edges: child 0's edges 0 and 2, child 1's 0 and 1, child 2's 1
        // and 2; the middle child's are all inner.
        let c = f.crease;
        let child_creases = [c & 0b101, c & 0b011, c & 0b110, 0];
        for (tri, crease) in [
            [corners[0], ab, ca],
            [ab, corners[1], bc],
            [ca, bc, corners[2]],
            [bc, ca, ab],
        ]
        .into_iter()
        .zip(child_creases)
        {
            next.push(Face {
                v: tri.map(|c| c.0),
                base: f.base,
                lattice: tri.map(|c| c.1),
                crease,
            });
        }
    }
    next
}

/// One round: the new positions (old vertices first, then one per edge) and, for every face,
/// the ids of the new vertices on its edges `(v0 v1)`, `(v1 v2)`, `(v2 v0)`.
fn refine(positions: &[Vec3], faces: &[Face], scheme: Scheme) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let nv = positions.len();
    let edges = Edges::of(faces, nv);
    let single_fan = single_fans(faces, &edges, nv);
    let mut around = Around::new(nv);
    let mut new_positions = positions.to_vec();
    new_positions.reserve(edges.list.len());
    for (a, b, range) in &edges.list {
        let (pa, pb) = (positions[*a as usize], positions[*b as usize]);
        let manifold = range.len() == 2;
        let chosen = edges.keys[range.clone()]
            .iter()
            .any(|&(_, fe)| faces[fe as usize / 3].is_crease(fe as usize % 3));
        let smooth = manifold && !chosen;
        around.add_edge([*a as usize, *b as usize], [pa, pb], smooth, manifold);
        let p = if smooth && scheme == Scheme::Loop {
            let opposite = |fe: u32| {
                let face = &faces[fe as usize / 3];
                let e = fe as usize % 3;
                positions[face.v[(e + 2) % 3] as usize]
            };
            let (k0, k1) = (edges.keys[range.start].1, edges.keys[range.start + 1].1);
            (pa + pb) * 0.375 + (opposite(k0) + opposite(k1)) * 0.125
        } else {
            (pa + pb) * 0.5
        };
        new_positions.push(p);
    }
    if scheme == Scheme::Loop {
        for v in 0..nv {
            new_positions[v] = around.vertex_point(v, positions[v], single_fan[v]);
        }
    }
    (new_positions, edges.mids)
}

/// The faces' edges, each undirected vertex pair once: `keys` lists every face edge
/// (`3 * face + edge`) by its pair, sorted; `list` holds each pair's vertices and its run of
/// `keys`; `mids[face][edge]` the new vertex on that edge (numbered after the `nv` old ones).
struct Edges {
    keys: Vec<(u64, u32)>,
    list: Vec<(u32, u32, std::ops::Range<usize>)>,
    mids: Vec<[u32; 3]>,
}

impl Edges {
    fn of(faces: &[Face], nv: usize) -> Edges {
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
        let mut list: Vec<(u32, u32, std::ops::Range<usize>)> = Vec::new();
        let mut start = 0;
        while start < keys.len() {
            let mut end = start + 1;
            while end < keys.len() && keys[end].0 == keys[start].0 {
                end += 1;
            }
            let id = (nv + list.len()) as u32;
            for &(_, fe) in &keys[start..end] {
                mids[fe as usize / 3][fe as usize % 3] = id;
            }
            let key = keys[start].0;
            list.push(((key >> 32) as u32, key as u32, start..end));
            start = end;
        }
        Edges { keys, list, mids }
    }
}

/// Per vertex, whether its corners form one connected fan: corners of faces at the same vertex
/// are joined across every edge they share.
fn single_fans(faces: &[Face], edges: &Edges, nv: usize) -> Vec<bool> {
    let mut fans = UnionFind::new(faces.len() * 3);
    let corner_at = |fe: u32, v: u32| {
        let f = fe as usize / 3;
        let c = faces[f].v.iter().position(|&x| x == v).unwrap();
        f * 3 + c
    };
    for (a, b, range) in &edges.list {
        let group = &edges.keys[range.clone()];
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
    single_fan
}

/// What Loop's rule for an old vertex reads of its edges: its neighbours, and those across
/// crease edges (boundaries, non-manifold edges and chosen creases).
struct Around {
    neighbour_sum: Vec<Vec3>,
    valence: Vec<u32>,
    crease_sum: Vec<Vec3>,
    creases: Vec<u32>,
    /// Crease edges that are boundaries or non-manifold, not chosen ones.
    open: Vec<u32>,
}

impl Around {
    fn new(nv: usize) -> Around {
        Around {
            neighbour_sum: vec![Vec3::ZERO; nv],
            valence: vec![0; nv],
            crease_sum: vec![Vec3::ZERO; nv],
            creases: vec![0; nv],
            open: vec![0; nv],
        }
    }

    /// Edge `[a, b]` at positions `[pa, pb]`.
    fn add_edge(&mut self, [a, b]: [usize; 2], [pa, pb]: [Vec3; 2], smooth: bool, manifold: bool) {
        self.neighbour_sum[a] += pb;
        self.neighbour_sum[b] += pa;
        self.valence[a] += 1;
        self.valence[b] += 1;
        if !smooth {
            self.crease_sum[a] += pb;
            self.crease_sum[b] += pa;
            self.creases[a] += 1;
            self.creases[b] += 1;
        }
        if !manifold {
            self.open[a] += 1;
            self.open[b] += 1;
        }
    }

    /// Old vertex `v`'s new position, from its old one `p`.
    fn vertex_point(&self, v: usize, p: Vec3, single_fan: bool) -> Vec3 {
        let (valence, creases) = (self.valence[v], self.creases[v]);
        if valence == 0 {
            p
        } else if single_fan && (creases == 0 || (creases == 1 && self.open[v] == 0)) {
            // Smooth, or a dart: one chosen crease ending inside a smooth surface.
            let beta = loop_beta(valence);
            p * (1.0 - valence as f32 * beta) + self.neighbour_sum[v] * beta
        } else if creases == 2 && single_fan {
            p * 0.75 + self.crease_sum[v] * 0.125
        } else {
            p
        }
    }
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
mod tests;
