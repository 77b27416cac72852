//! The baseline: micro-triangles as a plain indexed triangle list under a full SAH BVH.

use gridrt_shared::glam::Vec3;
use gridrt_shared::layout::BvhNode;

use crate::bvh::{self, Aabb, BuildParams};
use crate::limits::BufferSize;

#[derive(Clone, Debug)]
pub struct TriangleScene {
    pub nodes: Vec<BvhNode>,
    /// xyz per vertex.
    pub positions: Vec<f32>,
    /// Three per triangle, in BVH leaf order.
    pub indices: Vec<u32>,
    /// `original[slot]`: the input index of the triangle stored at `slot`.
    pub original: Vec<u32>,
}

/// Builder settings of the baseline: the usual SAH with leaves of up to four triangles.
pub fn build_params() -> BuildParams {
    BuildParams::default()
}

/// Lower bounds on the baseline's buffer sizes before it is built, in the order of
/// `crate::split::scene_buffers`: `vertices` at least (the base mesh's), `triangles` exact.
pub fn least_buffer_sizes(vertices: u64, triangles: u64) -> Vec<BufferSize> {
    vec![
        BufferSize {
            name: "BVH",
            bytes: bvh::least_node_count(triangles, &build_params()) * 32,
            at_least: true,
        },
        BufferSize {
            name: "vertex",
            bytes: vertices * 12,
            at_least: true,
        },
        BufferSize {
            name: "index",
            bytes: triangles * 12,
            at_least: false,
        },
    ]
}

pub fn build(positions: &[Vec3], triangles: &[[u32; 3]]) -> TriangleScene {
    let boxes: Vec<Aabb> = triangles
        .iter()
        .map(|t| Aabb::from_points(t.iter().map(|&v| positions[v as usize])))
        .collect();
    let bvh = bvh::build(&boxes, &build_params());
    TriangleScene {
        nodes: bvh.nodes,
        positions: positions.iter().flat_map(|v| v.to_array()).collect(),
        indices: bvh.order.iter().flat_map(|&t| triangles[t as usize]).collect(),
        original: bvh.order,
    }
}

impl TriangleScene {
    /// The scene as the traversal reads it.
    pub fn view(&self) -> gridrt_shared::traverse::TriangleMesh<&[f32], &[u32]> {
        gridrt_shared::traverse::TriangleMesh {
            positions: self.positions.as_slice(),
            indices: self.indices.as_slice(),
        }
    }

    pub fn memory(&self) -> Vec<(&'static str, usize)> {
        vec![
            ("bvh", std::mem::size_of_val(self.nodes.as_slice())),
            ("vertices", std::mem::size_of_val(self.positions.as_slice())),
            ("indices", std::mem::size_of_val(self.indices.as_slice())),
        ]
    }
}
