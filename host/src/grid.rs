//! Builds the grid representation from a subdivided mesh: the three vertex areas (inner per
//! grid, edge per base edge, corner per base vertex), the per-grid headers, the sphere radii
//! and the top-level BVH over grids.

use std::collections::HashMap;

use anyhow::{bail, Result};
use gridrt_shared::glam::Vec3;
use gridrt_shared::grid_index::{
    edge_vertex_count, grid_size, inner_index, inner_vertex_count, level_start, sphere_count, sub_triangle,
    triangle_count, Lattice,
};
use gridrt_shared::layout::{BvhNode, GridHeader, GridParams, MAX_HEADER_ID};
use gridrt_shared::traverse::{sphere_center, MAX_SPHERE_LEVEL};
use rayon::prelude::*;

use crate::bvh::{self, Aabb, BuildParams};
use crate::mesh::Mesh;
use crate::subdiv::Subdivided;

/// Sphere levels left out at the bottom by default: leaves of 16 micro-triangles.
pub const DEFAULT_EXCLUDED_LEVELS: u32 = 2;

/// Everything the grid traversal reads, as uploaded.
#[derive(Clone, Debug)]
pub struct GridScene {
    pub nodes: Vec<BvhNode>,
    pub headers: Vec<GridHeader>,
    /// Inner area, then edge area, then corner area; xyz per vertex.
    pub vertices: Vec<f32>,
    pub radii: Vec<f32>,
    pub params: GridParams,
    /// `base_triangle[slot]`: which base triangle the grid stored at `slot` is.
    pub base_triangle: Vec<u32>,
}

impl GridScene {
    pub fn view(&self) -> gridrt_shared::traverse::GridScene<'_> {
        gridrt_shared::traverse::GridScene {
            headers: &self.headers,
            vertices: &self.vertices,
            radii: &self.radii,
            params: self.params,
        }
    }

    /// Renders depth `lod` instead of the full depth (no rebuild).
    pub fn set_lod(&mut self, lod: u32) -> Result<()> {
        if lod > self.params.levels {
            bail!("level of detail {lod} is deeper than the {} levels built", self.params.levels);
        }
        self.params.lod = lod;
        Ok(())
    }

    /// Maps a hit's primitive id to `base triangle * 4^lod + micro-triangle`, the numbering of
    /// [`Subdivided::micro_triangles`].
    pub fn micro_triangle_id(&self, prim: u32) -> u32 {
        let per_grid = triangle_count(self.params.lod);
        self.base_triangle[(prim / per_grid) as usize] * per_grid + prim % per_grid
    }

    /// Bytes of each uploaded part.
    pub fn memory(&self) -> Vec<(&'static str, usize)> {
        let inner = (self.params.edge_offset * 3) as usize;
        let edge = ((self.params.corner_offset - self.params.edge_offset) * 3) as usize;
        let corner = self.vertices.len() - inner - edge;
        vec![
            ("top_bvh", std::mem::size_of_val(self.nodes.as_slice())),
            ("headers", std::mem::size_of_val(self.headers.as_slice())),
            ("inner_vertices", inner * 4),
            ("edge_vertices", edge * 4),
            ("corner_vertices", corner * 4),
            ("sphere_radii", std::mem::size_of_val(self.radii.as_slice())),
        ]
    }
}

/// Top-level builder settings: a leaf may hold a few grids, which saves nodes (memory) at
/// little cost since each grid is culled by its root sphere first.
pub fn top_level_params() -> BuildParams {
    BuildParams {
        max_leaf_size: 4,
        traversal_cost: 1.0,
        intersection_cost: 1.0,
    }
}

/// Builds the grids of `sub` (subdivided from `base`), leaving the last `excluded` levels of
/// the sphere hierarchy out.
pub fn build(base: &Mesh, sub: &Subdivided, excluded: u32) -> Result<GridScene> {
    let levels = sub.levels;
    let leaf_level = levels.saturating_sub(excluded);
    if leaf_level > MAX_SPHERE_LEVEL {
        bail!("a sphere hierarchy of {} levels is deeper than the traversal supports ({})", leaf_level + 1, MAX_SPHERE_LEVEL + 1);
    }
    if levels - leaf_level > gridrt_shared::grid_index::MAX_LEAF_DEPTH {
        bail!("leaves of {} micro-triangles are more than the static index list holds", triangle_count(levels - leaf_level));
    }
    let grids = base.triangles.len();
    if (grids as u64) * (triangle_count(levels) as u64) >= u32::MAX as u64 {
        bail!("{grids} grids of {} micro-triangles overflow 32-bit primitive ids", triangle_count(levels));
    }
    let n = grid_size(levels);

    // Undirected base edges, each stored once from its lower to its higher vertex id.
    let mut edge_ids: HashMap<(u32, u32), u32> = HashMap::new();
    let mut edge_owner: Vec<(usize, usize)> = Vec::new(); // (grid, edge within grid)
    if base.positions.len() > MAX_HEADER_ID as usize + 1 {
        bail!("{} base vertices are more than a grid header can address ({})", base.positions.len(), MAX_HEADER_ID + 1);
    }
    let mut headers_by_base = Vec::with_capacity(grids);
    for (g, t) in base.triangles.iter().enumerate() {
        let mut edges = [0; 3];
        for e in 0..3 {
            let (a, b) = (t[e], t[(e + 1) % 3]);
            edges[e] = *edge_ids.entry((a.min(b), a.max(b))).or_insert_with(|| {
                edge_owner.push((g, e));
                edge_owner.len() as u32 - 1
            });
        }
        headers_by_base.push((edges, *t));
    }
    if edge_owner.len() > MAX_HEADER_ID as usize + 1 {
        bail!("{} base edges are more than a grid header can address ({})", edge_owner.len(), MAX_HEADER_ID + 1);
    }

    // Top level first, so grids can be stored in leaf order and need no indirection.
    let boxes: Vec<Aabb> = (0..grids)
        .into_par_iter()
        .map(|g| Aabb::from_points(lattice_points(n).map(|p| sub.positions[sub.vertex(g, p) as usize])))
        .collect();
    let top = bvh::build(&boxes, &top_level_params());

    let inner_count = inner_vertex_count(levels);
    let edge_len = edge_vertex_count(levels);
    let edge_offset = grids as u32 * inner_count;
    let corner_offset = edge_offset + edge_ids.len() as u32 * edge_len;
    let mut vertices: Vec<Vec3> = Vec::with_capacity(corner_offset as usize + base.positions.len());
    for &g in &top.order {
        for j in 1..n.saturating_sub(1) {
            for i in 1..n - j {
                debug_assert_eq!(inner_index(i, j, n) as usize, vertices.len() % inner_count.max(1) as usize);
                vertices.push(sub.positions[sub.vertex(g as usize, [i, j]) as usize]);
            }
        }
    }
    for &(g, e) in &edge_owner {
        let t = base.triangles[g];
        let reversed = t[e] > t[(e + 1) % 3];
        for s in 1..n {
            // Walk from the lower base vertex to the higher one.
            let step = if reversed { n - s } else { s };
            vertices.push(sub.positions[sub.vertex(g, edge_point(e, step, n)) as usize]);
        }
    }
    // Base vertex v stays vertex v through subdivision (at its moved position).
    vertices.extend_from_slice(&sub.positions[..base.positions.len()]);

    let headers: Vec<GridHeader> = top
        .order
        .iter()
        .map(|&g| {
            let (edges, corners) = headers_by_base[g as usize];
            GridHeader::new(edges, corners)
        })
        .collect();
    let params = GridParams {
        levels,
        lod: levels,
        leaf_level,
        sphere_count: sphere_count(leaf_level),
        inner_count,
        edge_offset,
        corner_offset,
        _pad: 0,
    };
    let radii: Vec<f32> = top
        .order
        .par_iter()
        .flat_map_iter(|&g| grid_radii(sub, g as usize, leaf_level))
        .collect();
    Ok(GridScene {
        nodes: top.nodes,
        headers,
        vertices: vertices.iter().flat_map(|v| v.to_array()).collect(),
        radii,
        params,
        base_triangle: top.order,
    })
}

/// All lattice points of a grid of size `n`.
fn lattice_points(n: u32) -> impl Iterator<Item = Lattice> {
    (0..=n).flat_map(move |j| (0..=n - j).map(move |i| [i, j]))
}

/// The point `step` steps along grid edge `e` (from corner `e` towards corner `e + 1`).
fn edge_point(e: usize, step: u32, n: u32) -> Lattice {
    match e {
        0 => [step, 0],
        1 => [n - step, step],
        _ => [0, n - step],
    }
}

/// Radii of one grid's spheres in breadth-first order: for each sub-triangle down to
/// `leaf_level`, the largest distance from the mean of its corners (computed exactly as the
/// traversal does) to any micro-vertex inside it, padded for the rounding of the GPU's own
/// centre computation.
pub fn grid_radii(sub: &Subdivided, g: usize, leaf_level: u32) -> Vec<f32> {
    let n = grid_size(sub.levels);
    let pos = |p: Lattice| sub.positions[sub.vertex(g, p) as usize];
    let mut radii = Vec::with_capacity(sphere_count(leaf_level) as usize);
    for level in 0..=leaf_level {
        for index in 0..triangle_count(level) {
            debug_assert_eq!(radii.len() as u32, level_start(level) + index);
            let [a, b, c] = sub_triangle(n, level, index);
            let center = sphere_center(pos(a), pos(b), pos(c));
            let m = n >> level;
            let mut r2 = 0f32;
            for lb in 0..=m {
                for la in 0..=m - lb {
                    let p = lattice_in(a, b, c, m, la, lb);
                    r2 = r2.max(pos(p).distance_squared(center));
                }
            }
            let r = r2.sqrt();
            radii.push(r + (r + center.abs().max_element()) * 1e-5);
        }
    }
    radii
}

/// Lattice point `(la, lb)` of the sub-triangle `(a, b, c)` whose edges span `m` lattice steps.
fn lattice_in(a: Lattice, b: Lattice, c: Lattice, m: u32, la: u32, lb: u32) -> Lattice {
    let step = |from: u32, to: u32, k: u32| (to as i64 - from as i64) / m as i64 * k as i64;
    [
        (a[0] as i64 + step(a[0], b[0], la) + step(a[0], c[0], lb)) as u32,
        (a[1] as i64 + step(a[1], b[1], la) + step(a[1], c[1], lb)) as u32,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::scene::{cube, default_scene};
    use crate::subdiv::{subdivide, Scheme};
    use gridrt_shared::grid_index::vertex_slot;

    fn lattice_vertex(scene: &GridScene, slot: usize, p: Lattice) -> Vec3 {
        let g = &scene.params;
        let s = vertex_slot(
            p,
            grid_size(g.levels),
            slot as u32,
            &scene.headers[slot],
            g.inner_count,
            g.edge_offset,
            g.corner_offset,
        ) as usize;
        Vec3::new(scene.vertices[3 * s], scene.vertices[3 * s + 1], scene.vertices[3 * s + 2])
    }

    /// Reading a grid back through its header gives exactly the subdivided vertices, shared
    /// edges and corners included, whichever way a grid walks its edges.
    #[test]
    fn every_grid_reads_back_its_vertices() {
        for levels in 0..=4 {
            let mesh = default_scene();
            let sub = subdivide(&mesh, levels, Scheme::Loop);
            let scene = build(&mesh, &sub, DEFAULT_EXCLUDED_LEVELS).unwrap();
            let n = grid_size(levels);
            for (slot, &base) in scene.base_triangle.iter().enumerate() {
                for p in lattice_points(n) {
                    let expect = sub.positions[sub.vertex(base as usize, p) as usize];
                    assert_eq!(lattice_vertex(&scene, slot, p), expect, "L={levels} grid {base} at {p:?}");
                }
            }
            // Nothing stored twice: one slot per distinct subdivided vertex.
            assert_eq!(scene.vertices.len() / 3, sub.positions.len(), "L={levels}");
        }
    }

    /// Every micro-vertex lies inside the sphere of each of its ancestor sub-triangles, with
    /// the centre computed as the traversal computes it.
    #[test]
    fn spheres_are_conservative() {
        for (mesh, levels, excluded) in [(default_scene(), 3, 2), (cube(), 5, 2), (cube(), 4, 1), (cube(), 4, 3)] {
            let sub = subdivide(&mesh, levels, Scheme::Loop);
            let scene = build(&mesh, &sub, excluded).unwrap();
            let n = grid_size(levels);
            let g = &scene.params;
            for slot in 0..scene.headers.len() {
                for level in 0..=g.leaf_level {
                    for index in 0..triangle_count(level) {
                        let c = sub_triangle(n, level, index).map(|p| lattice_vertex(&scene, slot, p));
                        let center = sphere_center(c[0], c[1], c[2]);
                        let r = scene.radii[slot * g.sphere_count as usize + (level_start(level) + index) as usize];
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

    #[test]
    fn sizes_follow_the_layout() {
        let mesh = cube();
        let sub = subdivide(&mesh, 3, Scheme::Loop);
        let scene = build(&mesh, &sub, 2).unwrap();
        assert_eq!(scene.radii.len(), 12 * 5);
        assert_eq!(scene.params.inner_count, 21);
        // 18 edges of 7 vertices, 8 corners.
        assert_eq!(scene.vertices.len() / 3, 12 * 21 + 18 * 7 + 8);
        assert!(scene.set_lod_checked(4).is_err());
    }

    impl GridScene {
        fn set_lod_checked(&self, lod: u32) -> Result<()> {
            self.clone().set_lod(lod)
        }
    }
}
