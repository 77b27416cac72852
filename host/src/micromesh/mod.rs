//! The displaced micro-mesh, one concept in one place: a base mesh, a direction vector per
//! base vertex and a micromap of 11-bit displacement values per base triangle (see
//! `gridrt_shared::displacement` for what a micro-vertex is).
//!
//! - this file: the type ([`DisplacedMesh`]), its checks, and its decoding into the
//!   micro-triangles it stands for;
//! - [`bake`]: making one from a detailed mesh (simplify, directions, cast, fit, levels);
//! - [`bary`]: NVIDIA's `.bary` micromap files, read and written (their compressed blocks too);
//! - [`gltf_micromap`] reads, and [`gltf`] writes, glTF with NVIDIA's micromap extensions;
//! - the grid formats that trace one live in `grid::displaced` and `grid::compressed`.
//!
//! The decoded triangles are what a triangle BVH over the same surface traces (the baseline
//! next to displaced grids) and what `export` writes. Every micro-vertex is computed by the
//! shared decoder, so a point on a base edge comes out with the same bits from both triangles
//! that share the edge: welding the decoded mesh's equal positions closes every seam.

pub mod bake;
pub mod bary;
pub mod gltf;
pub mod gltf_micromap;

use crate::error::{fail, Result};
use crate::mesh::Mesh;
use crate::micromesh::bary::{compressed_blocks, Micromap};
use gridrt_shared::displacement::{
    decimated_point, displaced_point, u_major_index, unorm11_displacement, DisplacedTriangle, DECIMATED_EDGES,
};
use gridrt_shared::glam::Vec3;
use gridrt_shared::grid_index::{edge_point, grid_size, lattice_points, sub_triangle, triangle_count};

/// A base mesh with per-vertex directions and a micromap whose triangle `t` displaces base
/// triangle `t`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DisplacedMesh {
    pub positions: Vec<Vec3>,
    pub directions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub micromap: Micromap,
    /// Per triangle, its edges whose neighbours are one level coarser (see
    /// `gridrt_shared::displacement::DECIMATED_EDGES`); empty when none is.
    pub decimated_edges: Vec<u8>,
}

/// The deepest subdivision level decoded.
pub const MAX_LEVEL: u32 = 6;

impl DisplacedMesh {
    /// Refuses what cannot be decoded: directions not one per vertex, a micromap of another
    /// triangle count, a level past [`MAX_LEVEL`], non-finite positions or directions.
    /// Errors carry no file name; the caller adds it.
    pub fn check(&self) -> Result<()> {
        let (vertices, triangles) = (self.positions.len(), self.triangles.len());
        if self.directions.len() != vertices {
            fail!(
                Input,
                "{} displacement directions for {vertices} vertices",
                self.directions.len()
            );
        }
        if self.micromap.triangles.len() != triangles {
            fail!(
                Input,
                "its micromap has {} triangles, its mesh {triangles}",
                self.micromap.triangles.len()
            );
        }
        if !self.decimated_edges.is_empty() && self.decimated_edges.len() != triangles {
            fail!(
                Input,
                "{} triangle flags for {triangles} triangles",
                self.decimated_edges.len()
            );
        }
        if let Some(t) = self.micromap.triangles.iter().position(|t| t.level > MAX_LEVEL) {
            let level = self.micromap.triangles[t].level;
            fail!(
                Input,
                "triangle {t} is subdivided {level} times, past the deepest gridrt decodes ({MAX_LEVEL})"
            );
        }
        let finite = |v: &[Vec3]| v.iter().position(|p| !p.is_finite());
        if let Some(i) = finite(&self.positions).or(finite(&self.directions)) {
            fail!(Input, "vertex {i}'s position or direction is not finite");
        }
        if let Some(&bad) = self.triangles.iter().flatten().find(|&&i| i as usize >= vertices) {
            fail!(Input, "a triangle refers to vertex {bad} of {vertices}");
        }
        Ok(())
    }

    /// The base mesh alone: positions and triangles.
    pub fn base_mesh(&self) -> Mesh {
        Mesh {
            positions: self.positions.clone(),
            triangles: self.triangles.clone(),
        }
    }

    /// Base triangle `t` as the decoder reads it.
    pub fn base_triangle(&self, t: usize) -> DisplacedTriangle {
        let ids = self.triangles[t];
        DisplacedTriangle {
            positions: ids.map(|i| self.positions[i as usize]),
            directions: ids.map(|i| self.directions[i as usize]),
            ids,
        }
    }

    /// The bias and scale of the micromap group that holds triangle `t`.
    fn bias_scale(&self, t: usize) -> (f32, f32) {
        let group = self
            .micromap
            .groups
            .iter()
            .find(|g| (g.triangle_first as usize..(g.triangle_first + g.triangle_count) as usize).contains(&t));
        group.map_or((0.0, 1.0), |g| (g.bias, g.scale))
    }

    /// Triangle `t`'s decimated edges (see [`Self::decimated_edges`]).
    pub fn decimated(&self, t: usize) -> u32 {
        self.decimated_edges.get(t).map_or(0, |&f| f as u32 & DECIMATED_EDGES)
    }

    /// The level triangle `t` renders its edge `e` (from its corner `e` to corner `e + 1`)
    /// at: its own, one less where the edge is decimated.
    pub fn rendered_edge_level(&self, t: usize, e: usize) -> u32 {
        let level = self.micromap.triangles[t].level;
        level - (level > 0 && self.decimated(t) >> e & 1 != 0) as u32
    }

    /// Base edges that the triangles around them render at different levels (see
    /// [`Self::rendered_edge_level`]): levels more than one apart, a step of one whose finer
    /// side does not decimate the edge, or a decimated edge beside a triangle of its own
    /// level. The surface cracks along them: files that follow NVIDIA's micro-maps have none.
    pub fn open_seams(&self) -> usize {
        if self.uniform_level().is_some() {
            return 0;
        }
        let mut levels: std::collections::HashMap<(u32, u32), (u32, u32)> = std::collections::HashMap::new();
        for (t, c) in self.triangles.iter().enumerate() {
            for e in 0..3 {
                let (a, b) = (c[e], c[(e + 1) % 3]);
                let level = self.rendered_edge_level(t, e);
                let range = levels.entry((a.min(b), a.max(b))).or_insert((level, level));
                *range = (range.0.min(level), range.1.max(level));
            }
        }
        levels.values().filter(|(lowest, highest)| lowest != highest).count()
    }

    /// The same surface with its values as NVIDIA's compressed blocks decode them, to be
    /// written so (see [`crate::micromesh::bary::compressed_blocks`]), and the blocks' bytes.
    ///
    /// Points that neighbours share keep one value: triangles are encoded finest first, each
    /// taking on its edges the values its encoded neighbours decoded there. Where its format
    /// cannot give those back (a coarser format beside a finer one's lossy edge), the triangle
    /// keeps its values exactly, in level-3 blocks.
    pub fn in_nv_blocks(&self) -> (DisplacedMesh, u64) {
        let map = &self.micromap;
        let mut out = DisplacedMesh {
            micromap: Micromap {
                nv_blocks: true,
                value_code: None,
                ..map.clone()
            },
            ..self.clone()
        };
        let mut order: Vec<usize> = (0..self.triangles.len()).collect();
        order.sort_by_key(|&t| std::cmp::Reverse(map.triangles[t].level));
        // (edge's lower vertex, its upper vertex, position along it in 2^-16) -> value
        let mut shared = std::collections::HashMap::new();
        let mut bytes = 0;
        for t in order {
            let level = map.triangles[t].level;
            let edge_points = self.edge_points(t);
            let mut values = map.triangle_values(t).to_vec();
            for &(at, key) in &edge_points {
                if let Some(&value) = shared.get(&key) {
                    values[at] = value;
                }
            }
            let encoded = compressed_blocks::encode_triangle(&values, level);
            let kept = edge_points
                .iter()
                .all(|&(at, key)| shared.get(&key).is_none_or(|&v| encoded.decoded[at] == v));
            let block_bytes = if kept {
                values = encoded.decoded;
                encoded.bytes.len()
            } else {
                compressed_blocks::encode_exactly(&values, level).bytes.len()
            };
            bytes += block_bytes as u64;
            for &(at, key) in &edge_points {
                shared.entry(key).or_insert(values[at]);
            }
            let first = map.triangles[t].first_value as usize;
            out.micromap.values[first..first + values.len()].copy_from_slice(&values);
        }
        (out, bytes)
    }

    /// Triangle `t`'s points on its base edges that are part of the surface (not the odd
    /// points of a decimated edge): each its u-major index, and a key the triangle across the
    /// edge gives the same point.
    fn edge_points(&self, t: usize) -> Vec<(usize, (u32, u32, u32))> {
        let n = grid_size(self.micromap.triangles[t].level);
        let corners = self.triangles[t];
        let decimated = self.decimated(t);
        let mut points = Vec::new();
        for e in 0..3 {
            let (a, b) = (corners[e], corners[(e + 1) % 3]);
            for s in 1..n {
                if decimated >> e & 1 != 0 && s % 2 == 1 {
                    continue;
                }
                let p = edge_point(e as u32, s, n);
                // The position from the lower-numbered end, in units fine enough for any level.
                let along = |s: u32| s * ((1 << 16) / n);
                let key = if a < b { (a, b, along(s)) } else { (b, a, along(n - s)) };
                points.push((u_major_index(p, n) as usize, key));
            }
        }
        points
    }

    /// Every micro-vertex of triangle `t` at its level, in lattice order; on a decimated edge,
    /// an odd point is decoded where it snaps to (its own value is not part of the surface).
    pub fn micro_vertices(&self, t: usize) -> Vec<Vec3> {
        let level = self.micromap.triangles[t].level;
        let n = grid_size(level);
        let base = self.base_triangle(t);
        let values = self.micromap.triangle_values(t);
        let (bias, scale) = self.bias_scale(t);
        let decimated = self.decimated(t);
        lattice_points(n)
            .map(|p| {
                let p = decimated_point(p, n, decimated);
                let q = values[u_major_index(p, n) as usize];
                displaced_point(&base, p, n, unorm11_displacement(q as u32, scale, bias))
            })
            .collect()
    }

    /// The same surface with every group's bias and scale folded into the base mesh (each
    /// position moved by `bias` directions, each direction scaled by `scale`) and one group of
    /// bias 0 and scale 1: the form displaced grids decode, a value being its unorm alone. A
    /// vertex shared by triangles of groups with different ranges gets a copy per range.
    pub fn with_ranges_folded(&self) -> DisplacedMesh {
        let mut folded = DisplacedMesh {
            micromap: Micromap {
                groups: vec![crate::micromesh::bary::MicromapGroup {
                    triangle_first: 0,
                    triangle_count: self.triangles.len() as u32,
                    bias: 0.0,
                    scale: 1.0,
                }],
                ..self.micromap.clone()
            },
            decimated_edges: self.decimated_edges.clone(),
            ..Default::default()
        };
        // (vertex, bias bits, scale bits) -> folded vertex id
        let mut copies = std::collections::HashMap::new();
        for t in 0..self.triangles.len() {
            let (bias, scale) = self.bias_scale(t);
            let triangle = self.triangles[t].map(|v| {
                *copies.entry((v, bias.to_bits(), scale.to_bits())).or_insert_with(|| {
                    let (p, d) = (self.positions[v as usize], self.directions[v as usize]);
                    folded.positions.push(p + d * bias);
                    folded.directions.push(d * scale);
                    folded.positions.len() as u32 - 1
                })
            });
            folded.triangles.push(triangle);
        }
        folded
    }

    /// The level every triangle is subdivided to, or `None` when they differ, when an edge is
    /// decimated (as only a neighbour of another level asks) or when there are none.
    pub fn uniform_level(&self) -> Option<u32> {
        if (0..self.triangles.len()).any(|t| self.decimated(t) != 0) {
            return None;
        }
        let first = self.micromap.triangles.first()?.level;
        self.micromap
            .triangles
            .iter()
            .all(|t| t.level == first)
            .then_some(first)
    }

    /// Micro-triangles rendered at depth `depth`: each triangle's own level's, or `depth`'s
    /// where that is shallower, less those its decimated edges collapse (at its own level),
    /// so as many as [`Self::decoded_welded`] keeps.
    pub fn micro_triangles_at(&self, depth: u32) -> u64 {
        (0..self.triangles.len())
            .map(|t| self.rendered_micro_triangles(t, depth))
            .sum()
    }

    /// [`Self::micro_triangles_at`] of triangle `t` alone.
    pub fn rendered_micro_triangles(&self, t: usize, depth: u32) -> u64 {
        let level = self.micromap.triangles[t].level;
        match self.decimated(t) {
            decimated if decimated != 0 && depth >= level => kept_triangles(level, decimated),
            _ => triangle_count(level.min(depth)) as u64,
        }
    }

    /// The deepest level of any triangle: the lattice displaced grids of mixed levels share
    /// (see [`Self::own_levels`]). `None` without triangles.
    pub fn deepest_level(&self) -> Option<u32> {
        self.micromap.triangles.iter().map(|t| t.level).max()
    }

    /// Each triangle's own level and decimated edges as displaced grids of mixed levels hold
    /// them (`gridrt_shared::layout::GridParams::level_element`): its decimated edges in the
    /// low three bits, its level above. Empty when every triangle is of one level.
    pub fn own_levels(&self) -> Vec<u8> {
        if self.uniform_level().is_some() {
            return Vec::new();
        }
        (0..self.triangles.len())
            .map(|t| (self.decimated(t) | self.micromap.triangles[t].level << 3) as u8)
            .collect()
    }

    /// [`Self::decoded`] with the points that decode to the same bits (shared edges and
    /// corners, seen from each side) stored once; the triangles as they are, in order, less
    /// those a decimated edge collapsed.
    pub fn decoded_welded(&self) -> Mesh {
        let decoded = self.decoded();
        let mut ids = std::collections::HashMap::with_capacity(decoded.positions.len());
        let mut welded = Mesh::default();
        let remap: Vec<u32> = (decoded.positions.iter())
            .map(|p| {
                *ids.entry(p.to_array().map(f32::to_bits)).or_insert_with(|| {
                    welded.positions.push(*p);
                    welded.positions.len() as u32 - 1
                })
            })
            .collect();
        let decimated = !self.decimated_edges.is_empty();
        welded.triangles = (decoded.triangles.iter())
            .map(|t| t.map(|i| remap[i as usize]))
            .filter(|[a, b, c]| !decimated || (a != b && b != c && c != a))
            .collect();
        welded
    }

    /// The micro-triangles, each base triangle's at its own level, with the parent's winding.
    /// Vertices are stored per base triangle (those on shared edges once for each side, with
    /// equal bits); `WorldMesh::validate` welds them.
    pub fn decoded(&self) -> Mesh {
        let mut mesh = Mesh::default();
        for t in 0..self.triangles.len() {
            let level = self.micromap.triangles[t].level;
            let n = grid_size(level);
            let first = mesh.positions.len() as u32;
            mesh.positions.extend(self.micro_vertices(t));
            let index = |[i, j]: [u32; 2]| first + gridrt_shared::grid_index::lattice_index(i, j, n);
            mesh.triangles
                .extend((0..triangle_count(level)).map(|k| sub_triangle(n, level, k).map(index)));
        }
        mesh
    }
}

/// Micro-triangles of a level-`level` triangle that its `decimated` edges leave with three
/// distinct corners.
fn kept_triangles(level: u32, decimated: u32) -> u64 {
    let n = grid_size(level);
    (0..triangle_count(level))
        .filter(|&k| {
            let [a, b, c] = sub_triangle(n, level, k).map(|p| decimated_point(p, n, decimated));
            a != b && b != c && c != a
        })
        .count() as u64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::WorldMesh;
    use crate::micromesh::bary::{values_per_triangle, Micromap};

    /// Two triangles sharing the edge between vertices 1 and 2, in opposite orientations,
    /// whose values agree on that edge (as a micromap's must) and differ elsewhere.
    fn two_triangles(level: u32) -> DisplacedMesh {
        let n = grid_size(level);
        let positions = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.3, 0.1, 0.0),
            Vec3::new(0.2, 1.1, 0.1),
            Vec3::new(1.4, 1.2, -0.2),
        ];
        let directions = vec![Vec3::Z, Vec3::new(0.1, 0.0, 0.9), Vec3::new(0.0, 0.2, 1.1), Vec3::Z];
        let triangles = vec![[0, 1, 2], [3, 2, 1]];
        // Any values inside; on the shared edge, the same function of the distance from
        // vertex 1 on both sides. Triangle 0's corners 1 and 2 are vertices 1 and 2: the point
        // k steps from vertex 1 is (n - k, k). Triangle 1's corners 1 and 2 are vertices 2 and
        // 1: the same point is (k, n - k).
        let values = |t: u32, edge: fn(u32, u32) -> [u32; 2]| -> Vec<u16> {
            let mut v = vec![0u16; values_per_triangle(level)];
            for [i, j] in lattice_points(n) {
                v[u_major_index([i, j], n) as usize] = ((500 + 13 * i + 7 * j + 300 * t) % 2048) as u16;
            }
            for k in 0..=n {
                v[u_major_index(edge(k, n), n) as usize] = (100 + 37 * k) as u16;
            }
            v
        };
        let first = values(0, |k, n| [n - k, k]);
        let second = values(1, |k, n| [k, n - k]);
        DisplacedMesh {
            positions,
            directions,
            triangles,
            micromap: Micromap::from_triangles(-0.05, 0.2, &[(level, first), (level, second)]),
            decimated_edges: Vec::new(),
        }
    }

    /// Micro-edges of the decoded, welded mesh that one micro-triangle alone uses.
    fn open_micro_edges(mesh: &DisplacedMesh) -> usize {
        let (welded, _) = WorldMesh::from(mesh.decoded()).validate("decoded").unwrap();
        let mut uses = std::collections::HashMap::new();
        for t in &welded.triangles {
            for e in 0..3 {
                let (a, b) = (t[e], t[(e + 1) % 3]);
                *uses.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        uses.values().filter(|&&u| u == 1).count()
    }

    /// [`two_triangles`] with rough values on their seam, alike on both sides: value
    /// `seam(k)` at `k` of 64 steps from vertex 1.
    fn rough_seam(level: u32) -> DisplacedMesh {
        let seam = |k: u32| (600 + 19 * k + (k * k * 7919) % 97) as u16;
        let mut mesh = two_triangles(level);
        let n = grid_size(level);
        let step = 64 / n;
        for (t, at) in [(0, [1, 0]), (1, [0, 1])] {
            let first = mesh.micromap.triangles[t].first_value as usize;
            for k in 0..=n {
                let p = [at[0] * (n - k) + at[1] * k, at[1] * (n - k) + at[0] * k];
                mesh.micromap.values[first + u_major_index(p, n) as usize] = seam(k * step);
            }
        }
        mesh
    }

    /// In NVIDIA's blocks the seam stays closed: between two level-5 triangles, whose
    /// corrections there lose detail, and between a level-5 triangle and a level-4 one, whose
    /// coarser format takes the finer side's values on the seam.
    #[test]
    fn seams_stay_closed_in_nvidia_blocks() {
        let uniform = rough_seam(5);
        assert_eq!(open_micro_edges(&uniform), 4 * 32);
        let (blocks, bytes) = uniform.in_nv_blocks();
        assert_eq!(bytes, 2 * 128);
        assert_ne!(blocks.micromap.values, uniform.micromap.values, "lossy");
        assert_eq!(open_micro_edges(&blocks), 4 * 32);

        let (fine, coarse) = (rough_seam(5), rough_seam(4));
        let mixed = DisplacedMesh {
            micromap: Micromap::from_triangles(
                -0.05,
                0.2,
                &[
                    (5, fine.micromap.triangle_values(0).to_vec()),
                    (4, coarse.micromap.triangle_values(1).to_vec()),
                ],
            ),
            decimated_edges: vec![0b010, 0],
            ..fine
        };
        assert_eq!(open_micro_edges(&mixed), 2 * 32 + 2 * 16);
        let (blocks, _) = mixed.in_nv_blocks();
        assert_ne!(blocks.micromap.values, mixed.micromap.values, "lossy");
        assert_eq!(open_micro_edges(&blocks), 2 * 32 + 2 * 16);
    }

    #[test]
    fn shared_edges_weld_into_one_watertight_seam() {
        for level in [0, 1, 3] {
            let mesh = two_triangles(level);
            mesh.check().unwrap();
            let decoded = mesh.decoded();
            let n = grid_size(level);
            assert_eq!(decoded.triangles.len(), 2 * triangle_count(level) as usize);
            let (welded, cleaning) = WorldMesh::from(decoded).validate("decoded").unwrap();
            // The n + 1 points of the shared edge are decoded twice, bit for bit.
            assert_eq!(cleaning.welded, n as usize + 1, "level {level}");
            assert_eq!(
                welded.positions.len(),
                2 * values_per_triangle(level) - (n as usize + 1),
                "level {level}"
            );
        }
    }

    /// A level-3 triangle beside a level-2 one, its edge towards it decimated (the odd values
    /// there are junk, as the flag says they are unused): the seam closes, every micro-edge
    /// along it shared by one micro-triangle on each side.
    #[test]
    fn decimated_edges_meet_their_coarser_neighbours() {
        let (fine, coarse) = (two_triangles(3), two_triangles(2));
        let mut fine_values = fine.micromap.triangle_values(0).to_vec();
        let n = grid_size(3);
        for k in (1..n).step_by(2) {
            fine_values[u_major_index([n - k, k], n) as usize] = 2047;
        }
        // The fine side's even seam points take the coarse side's values: `two_triangles`
        // gives point k of 2^L steps from vertex 1 the value 100 + 37 k.
        for k in (0..=n).step_by(2) {
            fine_values[u_major_index([n - k, k], n) as usize] = (100 + 37 * k / 2) as u16;
        }
        let coarse_values = coarse.micromap.triangle_values(1).to_vec();
        let mut mesh = DisplacedMesh {
            micromap: Micromap::from_triangles(-0.05, 0.2, &[(3, fine_values), (2, coarse_values)]),
            ..fine
        };
        // Less the outer boundary: the fine triangle's two other edges (8 micro-edges each)
        // and the coarse one's (4 each).
        let open_seam = |mesh: &DisplacedMesh| open_micro_edges(mesh) - (2 * 8 + 2 * 4);
        assert!(open_seam(&mesh) > 0, "without the flag the seam has cracks");
        mesh.decimated_edges = vec![0b010, 0];
        mesh.check().unwrap();
        assert_eq!(mesh.uniform_level(), None);
        assert_eq!(open_seam(&mesh), 0);
        assert_eq!(mesh.with_ranges_folded().decimated_edges, mesh.decimated_edges);
        // Welded, the micro-triangles the flag collapsed are gone: along the seam, four of
        // the fine side's eight.
        assert_eq!(mesh.decoded_welded().triangles.len(), 64 + 16 - 4);
        assert_eq!(mesh.micro_triangles_at(MAX_LEVEL), 64 + 16 - 4);
        assert_eq!(
            mesh.micro_triangles_at(2),
            16 + 16,
            "a shallower depth decimates nothing"
        );
        mesh.decimated_edges = vec![0b010];
        assert!(mesh
            .check()
            .unwrap_err()
            .to_string()
            .contains("1 triangle flags for 2 triangles"));
    }

    /// Folding moves no micro-vertex by more than rounding, and leaves a bias-free micromap;
    /// two groups of different ranges split their shared vertices.
    #[test]
    fn folded_ranges_decode_to_the_same_surface() {
        let mut mesh = two_triangles(2);
        let plain = mesh.with_ranges_folded();
        assert_eq!(plain.positions.len(), 4);
        mesh.micromap.groups = vec![
            crate::micromesh::bary::MicromapGroup {
                triangle_first: 0,
                triangle_count: 1,
                bias: -0.05,
                scale: 0.2,
            },
            crate::micromesh::bary::MicromapGroup {
                triangle_first: 1,
                triangle_count: 1,
                bias: 0.1,
                scale: 0.5,
            },
        ];
        let folded = mesh.with_ranges_folded();
        assert_eq!(folded.positions.len(), 6);
        assert_eq!(folded.micromap.groups.len(), 1);
        for t in 0..2 {
            for (a, b) in mesh.micro_vertices(t).iter().zip(folded.micro_vertices(t)) {
                assert!((*a - b).length() < 1e-6, "{a} {b}");
            }
        }
    }

    #[test]
    fn values_move_vertices_along_their_directions() {
        let mesh = two_triangles(2);
        let vertices = mesh.micro_vertices(0);
        // Corner 0 (vertex 0): value of lattice (0, 0), displaced along +z from the origin.
        let q = mesh.micromap.triangle_values(0)[0];
        let d = unorm11_displacement(q as u32, 0.2, -0.05);
        assert_eq!(vertices[0], Vec3::new(0.0, 0.0, d));
    }

    #[test]
    fn inconsistent_meshes_are_refused() {
        let mut mesh = two_triangles(1);
        mesh.directions.pop();
        assert!(mesh
            .check()
            .unwrap_err()
            .to_string()
            .contains("3 displacement directions for 4 vertices"));
        let mut mesh = two_triangles(1);
        mesh.triangles.push([0, 1, 3]);
        assert!(mesh
            .check()
            .unwrap_err()
            .to_string()
            .contains("micromap has 2 triangles, its mesh 3"));
        let mut mesh = two_triangles(1);
        mesh.micromap.triangles[1].level = 9;
        assert!(mesh.check().unwrap_err().to_string().contains("subdivided 9 times"));
    }
}
