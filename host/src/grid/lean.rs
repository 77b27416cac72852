//! The lean grid build: each base triangle subdivided on its own from its neighbourhood
//! (`crate::subdiv::subdivide_triangle`) and written straight into the final buffers, in
//! parallel chunks of grids, so the whole micro-mesh never exists at once.
//!
//! Each shared vertex is still stored once: a base edge's vertices are written by the grid
//! that owns the edge (the first to use it), a base vertex by the first grid using it. Every
//! grid computes its shared vertices bit for bit as its neighbours do, so which one writes
//! them changes nothing, and the result equals [`super::build`] on the whole subdivided mesh.
//!
//! Edge ids are handed out in the order grids first use them, so the edges a run of grids owns
//! are one contiguous run of the edge area: each parallel task gets its own slice of it.

use crate::error::Result;
use gridrt_shared::glam::{Vec3, Vec3A};
use gridrt_shared::grid_index::{grid_size, inner_points, inner_vertex_count, lattice_index, Lattice};
use gridrt_shared::grid_traverse::sphere_center;
use rayon::prelude::*;

use super::spheres::{bounds_and_radii, SphereTable};
use super::{
    assemble, check_counts, chunks_or_empty, edge_points, BaseEdges, GridOptions, GridScene, GridShape, PerGrid,
    PerGridTask,
};
use crate::mesh::Mesh;
use crate::quantize::quantize_grid;
use crate::subdiv::{subdivide_creased, subdivide_triangle, Creases, Patch, PatchSource, Scheme, VertexFaces};

/// Average base faces per patch (see `VertexFaces::patch_faces`) above which the lean build
/// gives way to subdividing the whole mesh: a closed regular mesh starts its patches with 18
/// faces per triangle, while a vertex with thousands of faces puts all of them in each of its
/// triangles' patches, and the work would grow with the square of its valence.
const MAX_PATCH_FACES_PER_TRIANGLE: u64 = 64;

/// Whether [`build_lean`] subdivides `base` grid by grid (else it subdivides the whole mesh,
/// needing the memory of [`super::build`]).
pub fn lean_build_applies(base: &Mesh) -> bool {
    patches_fit(&VertexFaces::new(base), base)
}

fn patches_fit(vertex_faces: &VertexFaces, base: &Mesh) -> bool {
    vertex_faces.patch_faces() <= MAX_PATCH_FACES_PER_TRIANGLE * base.triangles.len() as u64
}

/// What to build from a base mesh: depth, subdivision scheme and creases, grid options and
/// the inner vertices' form.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct GridBuild {
    /// Subdivision depth `L`: each base triangle becomes a grid of `4^L` micro-triangles.
    pub levels: u32,
    pub scheme: Scheme,
    /// Edges whose dihedral angle exceeds this many degrees stay sharp (see [`Creases`]);
    /// `None`: only boundaries and non-manifold edges do.
    pub crease_angle: Option<f32>,
    pub options: GridOptions,
    /// Inner vertices as 16-bit codes (`gridrt_shared::quantize`) rather than `f32` triples.
    pub quantized: bool,
}

impl GridBuild {
    /// Loop subdivision to depth `levels`, default options, quantized inner vertices.
    pub fn new(levels: u32) -> Self {
        GridBuild {
            levels,
            scheme: Scheme::Loop,
            crease_angle: None,
            options: GridOptions::default(),
            quantized: true,
        }
    }

    /// The creases chosen on `base` by [`GridBuild::crease_angle`].
    pub fn creases(&self, base: &Mesh) -> Creases {
        Creases::chosen(base, self.crease_angle)
    }
}

/// `base` subdivided and built as grids: the same scene as subdividing the whole mesh and
/// calling [`super::build`], in a fraction of the memory.
pub fn build_lean(base: &Mesh, build: &GridBuild) -> Result<GridScene> {
    build_lean_reporting(base, build, &|_| {})
}

/// [`build_lean`], calling `progress(grids)` (from any thread) as each run of grids is
/// written; the top-level BVH is built after the last.
pub fn build_lean_reporting(base: &Mesh, build: &GridBuild, progress: &(dyn Fn(usize) + Sync)) -> Result<GridScene> {
    let GridBuild {
        levels,
        scheme,
        options,
        quantized,
        ..
    } = *build;
    let options = &options;
    let edges = BaseEdges::new(base);
    check_counts(base, edges.owner.len() as u64, levels, options, quantized)?;
    let vertex_faces = VertexFaces::new(base);
    let creases = build.creases(base);
    if !patches_fit(&vertex_faces, base) {
        let mut sub = subdivide_creased(base, levels, scheme, &creases);
        if quantized {
            sub.quantize_inner();
        }
        return super::build(base, &sub, options);
    }
    let grids = base.triangles.len();
    let shape = GridShape::new(base, edges.owner.len(), levels, options, quantized);
    let ids = edges.ids(base);
    let mut buffer = vec![0u32; shape.buffer_words(grids, base.positions.len())];
    let mut per_grid = PerGrid::new(grids, &shape);
    let builder = Builder {
        base,
        vertex_faces,
        creases,
        edges,
        corner_owner: corner_owners(base),
        shape,
        scheme,
        table: SphereTable::new(levels, shape.leaf_level),
    };
    let corners = builder.write_grids(&mut buffer, &mut per_grid, progress);
    // Base vertices no triangle uses keep their place; the others were moved by subdivision.
    let corner_start = grids * shape.inner_words as usize + 3 * (shape.corner_offset - shape.edge_offset) as usize;
    let corner_area = &mut buffer[corner_start..];
    for (v, p) in base.positions.iter().enumerate() {
        corner_area[3 * v..][..3].copy_from_slice(&p.to_array().map(f32::to_bits));
    }
    for (v, p) in corners.into_iter().flatten() {
        corner_area[3 * v as usize..][..3].copy_from_slice(&p.to_array().map(f32::to_bits));
    }
    // The base mesh's connectivity is done with: freed before the top-level BVH's build, the
    // build's peak.
    drop(builder);
    Ok(assemble(&shape, &ids, &per_grid, buffer))
}

/// The first grid using each base vertex, which stores its final position.
fn corner_owners(base: &Mesh) -> Vec<u32> {
    let mut owner = vec![u32::MAX; base.positions.len()];
    for (g, t) in base.triangles.iter().enumerate().rev() {
        for &v in t {
            owner[v as usize] = g as u32;
        }
    }
    owner
}

/// What every grid's subdivision and build reads.
struct Builder<'a> {
    base: &'a Mesh,
    vertex_faces: VertexFaces,
    creases: Creases,
    edges: BaseEdges,
    corner_owner: Vec<u32>,
    shape: GridShape,
    scheme: Scheme,
    table: SphereTable,
}

/// One task's grids: their per-grid parts, their inner areas and the edges they own.
struct Task<'a> {
    per_grid: PerGridTask<'a>,
    inner: &'a mut [u32],
    edges: &'a mut [u32],
    first_edge: usize,
}

/// Reused from grid to grid within a task.
#[derive(Default)]
struct Scratch {
    patch: Patch,
    lattice: Vec<Vec3>,
    inner: Vec<Vec3>,
    snapped: Vec<Vec3>,
    points: Vec<Vec3A>,
}

impl Builder<'_> {
    /// Subdivides and writes every grid: inner areas (base-triangle order) and edge areas into
    /// `buffer`, boxes and radii into `per_grid`. Returns the corners each task owns, as
    /// `(base vertex, position)`.
    fn write_grids(
        &self,
        buffer: &mut [u32],
        per_grid: &mut PerGrid,
        progress: &(dyn Fn(usize) + Sync),
    ) -> Vec<Vec<(u32, Vec3)>> {
        let shape = &self.shape;
        let grids = self.base.triangles.len();
        let words = shape.inner_words as usize;
        let edge_words = 3 * (grid_size(shape.levels) as usize - 1);
        let (inner_area, rest) = buffer.split_at_mut(grids * words);
        let mut edge_area = &mut rest[..3 * (shape.corner_offset - shape.edge_offset) as usize];
        let mut first_edge = 0;
        let mut tasks = Vec::new();
        for (per_grid, inner) in per_grid.tasks().into_iter().zip(chunks_or_empty(inner_area, words)) {
            let end = self.edges_owned_before(per_grid.grids.end);
            let (edges, rest) = std::mem::take(&mut edge_area).split_at_mut((end - first_edge) * edge_words);
            edge_area = rest;
            tasks.push(Task {
                per_grid,
                inner,
                edges,
                first_edge,
            });
            first_edge = end;
        }
        tasks
            .into_par_iter()
            .map_init(Scratch::default, |scratch, task| {
                let grids = task.per_grid.grids.len();
                let corners = self.write_task(task, scratch);
                progress(grids);
                corners
            })
            .collect()
    }

    /// Edges owned by grids before `g` (all edges when `g` is past the last grid).
    fn edges_owned_before(&self, g: usize) -> usize {
        self.edges.owner.partition_point(|&(owner, _)| owner < g)
    }

    fn write_task(&self, mut task: Task, scratch: &mut Scratch) -> Vec<(u32, Vec3)> {
        let words = self.shape.inner_words as usize;
        let mut corners = Vec::new();
        for (i, g) in task.per_grid.grids.clone().enumerate() {
            self.subdivide(g, &mut task.inner[i * words..][..words], scratch);
            let (bounds, radii, thickness) = task.per_grid.grid(i);
            scratch.points.clear();
            scratch.points.extend(scratch.lattice.iter().map(|&p| Vec3A::from(p)));
            *bounds = bounds_and_radii(&self.table, &scratch.points, radii, thickness);
            self.write_edges(g, &scratch.lattice, &mut task);
            let n = grid_size(self.shape.levels);
            let t = self.base.triangles[g];
            for (c, p) in [[0, 0], [n, 0], [0, n]].into_iter().enumerate() {
                if self.corner_owner[t[c] as usize] == g as u32 {
                    corners.push((t[c], scratch.lattice[at(p, n)]));
                }
            }
        }
        corners
    }

    /// Grid `g`'s lattice into `scratch.lattice`, its inner vertices stored into `inner` (and
    /// replaced in the lattice by their decoded codes when quantized).
    fn subdivide(&self, g: usize, inner: &mut [u32], scratch: &mut Scratch) {
        let levels = self.shape.levels;
        let n = grid_size(levels);
        let lattice = &mut scratch.lattice;
        let source = PatchSource {
            mesh: self.base,
            vertex_faces: &self.vertex_faces,
            creases: &self.creases,
        };
        subdivide_triangle(&source, g as u32, levels, self.scheme, &mut scratch.patch, lattice);
        if inner_vertex_count(levels) == 0 {
            return;
        }
        scratch.inner.clear();
        scratch.inner.extend(inner_points(n).map(|p| lattice[at(p, n)]));
        if !self.shape.quantized_inner {
            for (w, p) in inner.chunks_mut(3).zip(&scratch.inner) {
                w.copy_from_slice(&p.to_array().map(f32::to_bits));
            }
            return;
        }
        let origin = sphere_center(lattice[at([0, 0], n)], lattice[at([n, 0], n)], lattice[at([0, n], n)]);
        scratch.snapped.resize(scratch.inner.len(), Vec3::ZERO);
        quantize_grid(origin, &scratch.inner, inner, &mut scratch.snapped);
        for (p, &v) in inner_points(n).zip(&scratch.snapped) {
            lattice[at(p, n)] = v;
        }
    }

    /// The vertices of the base edges grid `g` owns, into the task's part of the edge area.
    fn write_edges(&self, g: usize, lattice: &[Vec3], task: &mut Task) {
        let n = grid_size(self.shape.levels);
        let t = self.base.triangles[g];
        let per_edge = 3 * (n as usize - 1);
        for e in 0..3 {
            let id = self.edges.of_grid[g][e] as usize;
            if self.edges.owner[id] != (g, e) {
                continue;
            }
            let area = &mut task.edges[(id - task.first_edge) * per_edge..][..per_edge];
            for (w, p) in area.chunks_mut(3).zip(edge_points(&t, e, n)) {
                w.copy_from_slice(&lattice[at(p, n)].to_array().map(f32::to_bits));
            }
        }
    }
}

#[inline]
fn at(p: Lattice, n: u32) -> usize {
    lattice_index(p[0], p[1], n) as usize
}
