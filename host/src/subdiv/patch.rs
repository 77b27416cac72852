//! One base triangle subdivided on its own, from its neighbourhood: what the lean grid build
//! runs grid after grid instead of subdividing the whole mesh at once.
//!
//! Why a neighbourhood is enough: Loop's rules read a vertex's one ring and an edge's two
//! faces, so after any number of rounds a base triangle `T`'s vertices depend only on the base
//! faces that share a vertex with `T` (the support of a Loop patch; Stam 1998). A patch starts
//! as those faces. After each round it keeps only the faces touching `T`'s own vertices: `T`
//! at the new depth and one ring of faces around it. Every rule the next round applies to `T`'s
//! vertices and to the edges leaving them then sees all of their faces, exactly as in the whole
//! mesh. Vertices further out come out wrong (their rings are cut short), and are dropped by
//! the same pruning before anything reads them.
//!
//! Why the results are bit for bit those of [`super::subdivide`]: `refine` adds neighbours in
//! the order of their edges' ids and breaks ties between faces by face id. The patch keeps the
//! whole mesh's order in both: base vertices sorted by id and base faces by index, new
//! vertices and faces in the order `refine` makes them, and pruning never reorders. So every
//! vertex of `T` is the same sum, summed in the same order.

use gridrt_shared::glam::Vec3;
use gridrt_shared::grid_index::{grid_size, lattice_index, vertex_count};

use super::{children, refine, Creases, Face, Scheme};
use crate::mesh::Mesh;

/// What every patch of one base mesh starts from: the mesh, its faces by vertex, and the
/// creases chosen on the whole of it.
pub struct PatchSource<'a> {
    pub mesh: &'a Mesh,
    pub vertex_faces: &'a VertexFaces,
    pub creases: &'a Creases,
}

/// For each base vertex, the base faces using it.
pub struct VertexFaces {
    start: Vec<u32>,
    faces: Vec<u32>,
}

impl VertexFaces {
    pub fn new(mesh: &Mesh) -> VertexFaces {
        let mut start = vec![0u32; mesh.positions.len() + 1];
        for t in &mesh.triangles {
            for &v in t {
                start[v as usize + 1] += 1;
            }
        }
        for v in 0..mesh.positions.len() {
            start[v + 1] += start[v];
        }
        let mut next = start.clone();
        let mut faces = vec![0u32; mesh.triangles.len() * 3];
        for (f, t) in mesh.triangles.iter().enumerate() {
            for &v in t {
                faces[next[v as usize] as usize] = f as u32;
                next[v as usize] += 1;
            }
        }
        VertexFaces { start, faces }
    }

    pub fn at(&self, v: u32) -> &[u32] {
        &self.faces[self.start[v as usize] as usize..self.start[v as usize + 1] as usize]
    }

    /// Base faces all patches start with together, counted with repeats: the sum over
    /// vertices of their face count squared. Grows with the square of a vertex's valence, so a
    /// fan of thousands of faces around one vertex shows here.
    pub fn patch_faces(&self) -> u64 {
        self.start.windows(2).map(|w| ((w[1] - w[0]) as u64).pow(2)).sum()
    }
}

/// Scratch space of [`subdivide_triangle`], reused from one triangle to the next.
#[derive(Default)]
pub struct Patch {
    positions: Vec<Vec3>,
    faces: Vec<Face>,
    ids: Vec<u32>,
    keep: Vec<bool>,
}

/// Base triangle `t` of `source.mesh` subdivided `levels` times: its `vertex_count(levels)`
/// lattice vertices in `lattice_index` order, into `lattice`, bit for bit as
/// [`super::subdivide_creased`] places them.
pub fn subdivide_triangle(
    source: &PatchSource,
    t: u32,
    levels: u32,
    scheme: Scheme,
    patch: &mut Patch,
    lattice: &mut Vec<Vec3>,
) {
    patch.start(source, t);
    for round in 1..=levels {
        let (positions, mids) = refine(&patch.positions, &patch.faces, scheme);
        patch.positions = positions;
        patch.faces = children(&patch.faces, &mids);
        if round < levels {
            patch.prune(t);
        }
    }
    let n = grid_size(levels);
    lattice.clear();
    lattice.resize(vertex_count(levels) as usize, Vec3::ZERO);
    for f in patch.faces.iter().filter(|f| f.base == t) {
        for (&v, &[i, j]) in f.v.iter().zip(&f.lattice) {
            lattice[lattice_index(i, j, n) as usize] = patch.positions[v as usize];
        }
    }
}

impl Patch {
    /// The base faces sharing a vertex with `t`, in index order, over their vertices in id order.
    fn start(&mut self, source: &PatchSource, t: u32) {
        let (mesh, vertex_faces) = (source.mesh, source.vertex_faces);
        let faces = &mut self.ids;
        faces.clear();
        faces.extend(mesh.triangles[t as usize].iter().flat_map(|&v| vertex_faces.at(v)));
        faces.sort_unstable();
        faces.dedup();
        let mut vertices: Vec<u32> = faces.iter().flat_map(|&f| mesh.triangles[f as usize]).collect();
        vertices.sort_unstable();
        vertices.dedup();
        let local = |v: u32| vertices.binary_search(&v).expect("a vertex of the patch") as u32;
        self.faces.clear();
        self.faces.extend(
            faces
                .iter()
                .map(|&f| Face::base(mesh.triangles[f as usize].map(local), f, source.creases.of(f as usize))),
        );
        self.positions.clear();
        self.positions
            .extend(vertices.iter().map(|&v| mesh.positions[v as usize]));
    }

    /// Keeps the faces of `t` and those touching its vertices, and only their vertices,
    /// renumbered in the order they had.
    fn prune(&mut self, t: u32) {
        let own = &mut self.keep;
        own.clear();
        own.resize(self.positions.len(), false);
        for f in self.faces.iter().filter(|f| f.base == t) {
            for &v in &f.v {
                own[v as usize] = true;
            }
        }
        let own = &*own;
        self.faces
            .retain(|f| f.base == t || f.v.iter().any(|&v| own[v as usize]));
        let ids = &mut self.ids;
        ids.clear();
        ids.resize(self.positions.len(), u32::MAX);
        for f in &self.faces {
            for &v in &f.v {
                ids[v as usize] = 0;
            }
        }
        let mut kept = 0;
        for (v, id) in ids.iter_mut().enumerate() {
            if *id == 0 {
                *id = kept;
                self.positions[kept as usize] = self.positions[v];
                kept += 1;
            }
        }
        self.positions.truncate(kept as usize);
        for f in &mut self.faces {
            f.v = f.v.map(|v| ids[v as usize]);
        }
    }
}
