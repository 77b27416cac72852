//! Builds the grid representation from a subdivided mesh: the three vertex areas (inner per
//! grid, edge per base edge, corner per base vertex), the per-grid headers, the sphere radii
//! and the top-level BVH over grids.

use std::collections::HashMap;

use anyhow::{bail, Result};
use gridrt_shared::glam::Vec3;
use gridrt_shared::grid_index::{
    edge_vertex_count, grid_size, inner_index, inner_vertex_count, lattice_index, lattice_points, level_start,
    sphere_count, sub_triangle, triangle_count, GridSlots, Lattice,
};
use gridrt_shared::layout::{BvhNode, GridHeader, GridParams, MAX_HEADER_ID};
use gridrt_shared::quantize;
use gridrt_shared::traverse::{sphere_center, MAX_SPHERE_LEVEL};
use rayon::prelude::*;

use crate::bvh::{self, Aabb, BuildParams};
use crate::mesh::Mesh;
use crate::subdiv::Subdivided;

/// Sphere levels left out at the bottom by default: leaves of 16 micro-triangles.
pub const DEFAULT_EXCLUDED_LEVELS: u32 = 2;

/// Choices of the grid representation.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct GridOptions {
    /// Levels at the bottom of the sphere hierarchy that get no spheres.
    pub excluded_levels: u32,
    /// Store radii as half floats (rounded up, so spheres only grow) instead of `f32`.
    pub half_radii: bool,
}

impl Default for GridOptions {
    fn default() -> Self {
        GridOptions {
            excluded_levels: DEFAULT_EXCLUDED_LEVELS,
            half_radii: false,
        }
    }
}

/// Everything the grid traversal reads, as uploaded.
#[derive(Clone, Debug)]
pub struct GridScene {
    pub nodes: Vec<BvhNode>,
    pub headers: Vec<GridHeader>,
    /// Words: each grid's inner area (`f32` triples or 16-bit codes), then the edge and corner
    /// areas as `f32` triples (see `gridrt_shared::traverse::GridScene`).
    pub vertices: Vec<u32>,
    /// Sphere radii: `f32` bits, or half floats two per word (see `GridParams::half_radii`).
    pub radii: Vec<u32>,
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
            bail!(
                "level of detail {lod} is deeper than the {} levels built",
                self.params.levels
            );
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
        let inner = self.params.edge_word as usize;
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

/// The grids as subdivision hands them over, in base-triangle order: headers and the three
/// vertex areas, but no acceleration structure yet.
#[derive(Clone, Debug)]
pub struct GridLayout {
    pub levels: u32,
    pub leaf_level: u32,
    pub half_radii: bool,
    pub headers: Vec<GridHeader>,
    /// Inner area (grid after grid), edge area, corner area: every position, decoded.
    pub vertices: Vec<Vec3>,
    /// The inner areas as 16-bit codes, grid after grid, when the subdivided mesh was
    /// quantized (`gridrt_shared::quantize`).
    pub inner_codes: Option<Vec<u32>>,
    pub edge_offset: u32,
    pub corner_offset: u32,
}

impl GridLayout {
    /// Where grid `g` finds its vertices, resolved from its header as the GPU resolves it.
    #[inline]
    fn slots(&self, g: usize) -> GridSlots {
        GridSlots::new(
            &self.headers[g],
            g as u32,
            grid_size(self.levels),
            inner_vertex_count(self.levels),
            self.edge_offset,
            self.corner_offset,
        )
    }
}

/// Lays out the grids of `sub` (subdivided from `base`): shared edge and corner vertices
/// stored once.
pub fn layout(base: &Mesh, sub: &Subdivided, options: &GridOptions) -> Result<GridLayout> {
    let levels = sub.levels;
    let leaf_level = levels.saturating_sub(options.excluded_levels);
    if leaf_level > MAX_SPHERE_LEVEL {
        bail!(
            "a sphere hierarchy of {} levels is deeper than the traversal supports ({})",
            leaf_level + 1,
            MAX_SPHERE_LEVEL + 1
        );
    }
    if levels - leaf_level > gridrt_shared::grid_index::MAX_LEAF_DEPTH {
        bail!(
            "leaves of {} micro-triangles are more than the static index list holds",
            triangle_count(levels - leaf_level)
        );
    }
    let grids = base.triangles.len();
    if (grids as u64) * (triangle_count(levels) as u64) >= u32::MAX as u64 {
        bail!(
            "{grids} grids of {} micro-triangles overflow 32-bit primitive ids",
            triangle_count(levels)
        );
    }
    if base.positions.len() > MAX_HEADER_ID as usize + 1 {
        bail!(
            "{} base vertices are more than a grid header can address ({})",
            base.positions.len(),
            MAX_HEADER_ID + 1
        );
    }
    let n = grid_size(levels);

    // Undirected base edges, each stored once from its lower to its higher vertex id.
    let mut edge_ids: HashMap<(u32, u32), u32> = HashMap::with_capacity(grids * 3 / 2 + 16);
    let mut edge_owner: Vec<(usize, usize)> = Vec::new(); // (grid, edge within grid)
    let mut headers = Vec::with_capacity(grids);
    for (g, t) in base.triangles.iter().enumerate() {
        let mut edges = [0; 3];
        for e in 0..3 {
            let (a, b) = (t[e], t[(e + 1) % 3]);
            edges[e] = *edge_ids.entry((a.min(b), a.max(b))).or_insert_with(|| {
                edge_owner.push((g, e));
                edge_owner.len() as u32 - 1
            });
        }
        headers.push(GridHeader::new(edges, *t));
    }
    if edge_owner.len() > MAX_HEADER_ID as usize + 1 {
        bail!(
            "{} base edges are more than a grid header can address ({})",
            edge_owner.len(),
            MAX_HEADER_ID + 1
        );
    }

    let inner_count = inner_vertex_count(levels);
    // The traversal addresses 16-bit codes in halves below a flag bit (2^31).
    let inner_words = match sub.inner_codes {
        Some(_) => quantize::inner_words(inner_count),
        None => 3 * inner_count,
    };
    if (grids as u64) * (inner_words as u64) + 3 * (sub.positions.len() as u64) >= 1 << 30 {
        bail!(
            "{grids} grids of {} micro-triangles need more than 4 GiB of vertices",
            triangle_count(levels)
        );
    }
    let edge_offset = grids as u32 * inner_count;
    let corner_offset = edge_offset + edge_owner.len() as u32 * edge_vertex_count(levels);
    let mut vertices: Vec<Vec3> = Vec::with_capacity(corner_offset as usize + base.positions.len());
    for g in 0..grids {
        for j in 1..n.saturating_sub(1) {
            for i in 1..n - j {
                debug_assert_eq!(
                    inner_index(i, j, n) as usize,
                    vertices.len() % inner_count.max(1) as usize
                );
                vertices.push(sub.positions[sub.vertex(g, [i, j]) as usize]);
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
    Ok(GridLayout {
        levels,
        leaf_level,
        half_radii: options.half_radii,
        headers,
        vertices,
        edge_offset,
        corner_offset,
        inner_codes: sub.inner_codes.clone(),
    })
}

/// Lays out and builds in one go.
pub fn build(base: &Mesh, sub: &Subdivided, options: &GridOptions) -> Result<GridScene> {
    Ok(build_from_layout(&layout(base, sub, options)?))
}

/// The grid representation's build proper, what `stats` and `bench` time: grid bounds, the
/// top-level BVH, grids reordered into its leaf order, and the sphere radii.
pub fn build_from_layout(layout: &GridLayout) -> GridScene {
    let grids = layout.headers.len();
    let spheres = sphere_count(layout.leaf_level) as usize;
    // One pass over each grid's vertices gives its box and its radii.
    let mut boxes = vec![Aabb::EMPTY; grids];
    let mut radii_by_base = vec![0f32; grids * spheres];
    boxes
        .par_iter_mut()
        .zip(radii_by_base.par_chunks_mut(spheres))
        .enumerate()
        .for_each_init(Vec::new, |points, (g, (bounds, radii))| {
            *bounds = grid_bounds_and_radii(layout, g, radii, points)
        });
    let top = bvh::build(&boxes, &top_level_params());

    // Store grids in leaf order, so leaves name contiguous ranges and need no indirection.
    let inner_count = inner_vertex_count(layout.levels) as usize;
    let inner_words = match &layout.inner_codes {
        Some(_) => quantize::inner_words(inner_count as u32) as usize,
        None => 3 * inner_count,
    };
    let shared_count = layout.vertices.len() - layout.edge_offset as usize;
    let mut vertices = vec![0u32; grids * inner_words + 3 * shared_count];
    let (inner, shared) = vertices.split_at_mut(grids * inner_words);
    if inner_words > 0 {
        let grid_words = inner.par_chunks_mut(inner_words).zip(&top.order);
        match &layout.inner_codes {
            Some(codes) => grid_words.for_each(|(dst, &g)| {
                dst.copy_from_slice(&codes[g as usize * inner_words..(g as usize + 1) * inner_words])
            }),
            None => grid_words.for_each(|(dst, &g)| {
                let src = &layout.vertices[g as usize * inner_count..(g as usize + 1) * inner_count];
                for (d, v) in dst.as_chunks_mut::<3>().0.iter_mut().zip(src) {
                    *d = v.to_array().map(f32::to_bits);
                }
            }),
        }
    }
    shared
        .par_chunks_mut(3)
        .zip(&layout.vertices[layout.edge_offset as usize..])
        .for_each(|(d, v)| d.copy_from_slice(&v.to_array().map(f32::to_bits)));
    let headers: Vec<GridHeader> = top.order.iter().map(|&g| layout.headers[g as usize]).collect();
    let radii: Vec<f32> = top
        .order
        .iter()
        .flat_map(|&g| &radii_by_base[g as usize * spheres..(g as usize + 1) * spheres])
        .copied()
        .collect();

    let radius_scale = radius_scale(radii.iter().fold(0f32, |m, &r| m.max(r)));
    let radii = if layout.half_radii {
        radii
            .chunks(2)
            .map(|pair| {
                let lo = encode_radius(pair[0], radius_scale) as u32;
                let hi = pair.get(1).map_or(0, |&r| encode_radius(r, radius_scale) as u32);
                lo | (hi << 16)
            })
            .collect()
    } else {
        radii.iter().map(|r| r.to_bits()).collect()
    };
    GridScene {
        nodes: top.nodes,
        headers,
        vertices,
        radii,
        params: GridParams {
            levels: layout.levels,
            lod: layout.levels,
            leaf_level: layout.leaf_level,
            sphere_count: spheres as u32,
            inner_count: inner_count as u32,
            edge_offset: layout.edge_offset,
            corner_offset: layout.corner_offset,
            quantized_inner: layout.inner_codes.is_some() as u32,
            inner_words: inner_words as u32,
            edge_word: (grids * inner_words) as u32,
            half_radii: layout.half_radii as u32,
            radius_scale,
            _pad: [0; 4],
        },
        base_triangle: top.order,
    }
}

/// The power of two that brings the largest radius to about 2^14 in half-float units: far
/// from overflow (65504) and with the smallest radii still well above the subnormal range.
fn radius_scale(max_radius: f32) -> f32 {
    if max_radius <= 0.0 || !max_radius.is_finite() {
        return 1.0;
    }
    2f32.powi(max_radius.log2().ceil() as i32 - 14)
}

/// The smallest half float, in units of `scale`, that is not below `r`.
pub fn encode_radius(r: f32, scale: f32) -> u16 {
    let v = r / scale;
    let bits = v.to_bits();
    let exponent = ((bits >> 23) & 0xff) as i32 - 127;
    let h = if v <= 0.0 {
        0
    } else if exponent < -14 {
        // Subnormal half: units of 2^-24, rounded up.
        (v * 16_777_216.0).ceil() as u32
    } else {
        let mantissa = (bits & 0x7f_ffff) >> 13;
        let rest = bits & 0x1fff;
        (((exponent + 15) as u32) << 10 | mantissa) + (rest != 0) as u32
    };
    h.min(0x7bff) as u16
}

/// The point `step` steps along grid edge `e` (from corner `e` towards corner `e + 1`).
fn edge_point(e: usize, step: u32, n: u32) -> Lattice {
    match e {
        0 => [step, 0],
        1 => [n - step, step],
        _ => [0, n - step],
    }
}

/// The bounds of grid `g`, and its spheres' radii in breadth-first order: for each
/// sub-triangle down to the leaf level, the largest distance from the mean of its corners
/// (computed exactly as the traversal does) to any micro-vertex inside it, padded for the
/// rounding of the GPU's own centre computation.
fn grid_bounds_and_radii(layout: &GridLayout, g: usize, radii: &mut [f32], points: &mut Vec<Vec3>) -> Aabb {
    let n = grid_size(layout.levels);
    // Gather the grid once (into a buffer reused across grids); everything below reads it.
    let slots = layout.slots(g);
    points.clear();
    points.extend(lattice_points(n).map(|p| layout.vertices[slots.slot(p) as usize]));
    let pos = |p: Lattice| points[lattice_index(p[0], p[1], n) as usize];
    let mut slot = 0;
    for level in 0..=layout.leaf_level {
        for index in 0..triangle_count(level) {
            debug_assert_eq!(slot as u32, level_start(level) + index);
            let [a, b, c] = sub_triangle(n, level, index);
            let center = sphere_center(pos(a), pos(b), pos(c));
            // Every lattice point of the sub-triangle: a + la e1 + lb e2, with its edges
            // spanning m steps.
            let m = (n >> level) as i64;
            let e1 = [(b[0] as i64 - a[0] as i64) / m, (b[1] as i64 - a[1] as i64) / m];
            let e2 = [(c[0] as i64 - a[0] as i64) / m, (c[1] as i64 - a[1] as i64) / m];
            let mut r2 = 0f32;
            for lb in 0..=m {
                for la in 0..=m - lb {
                    let p = [
                        (a[0] as i64 + la * e1[0] + lb * e2[0]) as u32,
                        (a[1] as i64 + la * e1[1] + lb * e2[1]) as u32,
                    ];
                    r2 = r2.max(pos(p).distance_squared(center));
                }
            }
            let r = r2.sqrt();
            radii[slot] = r + (r + center.abs().max_element()) * 1e-5;
            slot += 1;
        }
    }
    Aabb::from_points(points.iter().copied())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::scene::{cube, default_scene};
    use crate::subdiv::{subdivide, Scheme};

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
            assert_eq!(g.edge_word, scene.headers.len() as u32 * per_grid);
            let shared = sub.positions.len() - g.edge_offset as usize;
            assert_eq!(scene.vertices.len(), g.edge_word as usize + 3 * shared, "L={levels}");
        }
    }

    /// Every micro-vertex lies inside the sphere of each of its ancestor sub-triangles, with
    /// the centre computed as the traversal computes it.
    #[test]
    fn spheres_are_conservative() {
        for (mesh, levels, excluded, half_radii) in [
            (default_scene(), 3, 2, false),
            (default_scene(), 3, 2, true),
            (cube(), 5, 2, true),
            (cube(), 4, 1, false),
            (cube(), 4, 3, true),
        ] {
            let sub = subdivide(&mesh, levels, Scheme::Loop);
            let options = GridOptions {
                excluded_levels: excluded,
                half_radii,
            };
            let scene = build(&mesh, &sub, &options).unwrap();
            let n = grid_size(levels);
            let g = &scene.params;
            for slot in 0..scene.headers.len() {
                for level in 0..=g.leaf_level {
                    for index in 0..triangle_count(level) {
                        let c = sub_triangle(n, level, index).map(|p| lattice_vertex(&scene, slot, p));
                        let center = sphere_center(c[0], c[1], c[2]);
                        let r = scene.view().radius(slot as u32, level_start(level) + index);
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
    fn half_radii_round_up() {
        let scale = radius_scale(3.7);
        for k in 0..100_000 {
            let r = 3.7 * (k as f32 / 100_000.0).powi(3);
            let back = gridrt_shared::sphere::decode_radius(encode_radius(r, scale) as u32, scale);
            assert!(back >= r, "{r} encoded as {back}");
            assert!(
                back <= r * (1.0 + 1.0 / 1024.0) + scale * 2f32.powi(-24),
                "{r} encoded as {back}"
            );
        }
    }

    #[test]
    fn sizes_follow_the_layout() {
        let mesh = cube();
        let sub = subdivide(&mesh, 3, Scheme::Loop);
        let scene = build(&mesh, &sub, &GridOptions::default()).unwrap();
        assert_eq!(scene.radii.len(), 12 * 5);
        let half = build(
            &mesh,
            &sub,
            &GridOptions {
                half_radii: true,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(half.radii.len(), 12 * 5 / 2);
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
}
