//! Binned SAH builder for binary BVHs, shared by the baseline (over triangles) and the top level
//! of the grid scene (over grids).
//!
//! The output is the flat node array the traversal in `gridrt_shared::traverse` walks: children
//! of an interior node are adjacent, and each leaf covers a contiguous range of the primitive
//! order, so the caller reorders its primitives once and needs no index indirection.
//!
//! The build runs on rayon (subtrees in parallel, the first levels' binning in parallel chunks), yet
//! its output depends on the input alone: every node owns fixed slots, so no result depends on which
//! thread finishes first (see `Task`).

mod builder;
#[cfg(test)]
mod tests;

pub use builder::build;

use gridrt_shared::glam::Vec3;
use gridrt_shared::layout::BvhNode;
use gridrt_shared::traverse::MAX_BVH_DEPTH;

/// An axis-aligned box; `EMPTY` is the identity of `union`.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    pub fn from_points(points: impl IntoIterator<Item = Vec3>) -> Aabb {
        points.into_iter().fold(Aabb::EMPTY, |b, p| b.grow(p))
    }

    #[inline]
    pub fn grow(self, p: Vec3) -> Aabb {
        Aabb {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    #[inline]
    pub fn union(self, o: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    /// The eight corners: corner `k` takes x from bit 0 of `k`, y from bit 1, z from bit 2
    /// (clear: the minimum, set: the maximum).
    pub fn corners(&self) -> [Vec3; 8] {
        std::array::from_fn(|k| {
            let pick = |bit: usize, lo: f32, hi: f32| if k & bit == 0 { lo } else { hi };
            Vec3::new(
                pick(1, self.min.x, self.max.x),
                pick(2, self.min.y, self.max.y),
                pick(4, self.min.z, self.max.z),
            )
        })
    }

    #[inline]
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// Surface area; zero for an empty box.
    #[inline]
    pub fn area(&self) -> f32 {
        let d = (self.max - self.min).max(Vec3::ZERO);
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }

    pub fn contains(&self, o: &Aabb) -> bool {
        self.min.cmple(o.min).all() && self.max.cmpge(o.max).all()
    }
}

/// Builder settings. The costs are the SAH's: one node visit against one primitive test.
#[derive(Copy, Clone, Debug)]
pub struct BuildParams {
    pub max_leaf_size: u32,
    /// Deepest a leaf may lie below the root (the root at 0): a walk's stack holds one entry a
    /// level, so the stack of the walk reading the hierarchy sets it.
    pub max_depth: usize,
    pub traversal_cost: f32,
    pub intersection_cost: f32,
}

impl Default for BuildParams {
    fn default() -> Self {
        BuildParams {
            max_leaf_size: 4,
            max_depth: MAX_BVH_DEPTH - 2,
            traversal_cost: 1.0,
            intersection_cost: 1.0,
        }
    }
}

/// Fewest nodes a hierarchy over `primitives` can have: leaves of at most `max_leaf_size`
/// primitives, two children per inner node.
pub fn least_node_count(primitives: u64, params: &BuildParams) -> u64 {
    (2 * primitives.div_ceil(params.max_leaf_size as u64)).max(2) - 1
}

/// A built hierarchy: `order[k]` is the original index of the primitive at position `k`.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    pub nodes: Vec<BvhNode>,
    pub order: Vec<u32>,
}

/// Standard SAH cost of a built hierarchy, relative to its root's area.
pub fn sah_cost(nodes: &[BvhNode], params: &BuildParams) -> f32 {
    let Some(root) = nodes.first() else {
        return 0.0;
    };
    let area = |n: &BvhNode| {
        Aabb {
            min: Vec3::from(n.min),
            max: Vec3::from(n.max),
        }
        .area() as f64
    };
    // Summed in f64: millions of small f32 terms would lose the digits that compare builders.
    let total: f64 = nodes
        .iter()
        .map(|n| {
            if n.is_leaf() {
                area(n) * n.count as f64 * params.intersection_cost as f64
            } else {
                area(n) * params.traversal_cost as f64
            }
        })
        .sum();
    (total / area(root).max(f32::MIN_POSITIVE as f64)) as f32
}

/// Depth of the deepest leaf (the root alone has depth 1).
pub fn depth(nodes: &[BvhNode]) -> usize {
    if nodes.is_empty() {
        return 0;
    }
    let mut deepest = 0;
    let mut stack = vec![(0usize, 1usize)];
    while let Some((i, d)) = stack.pop() {
        deepest = deepest.max(d);
        let n = &nodes[i];
        if !n.is_leaf() {
            stack.push((n.first as usize, d + 1));
            stack.push((n.first as usize + 1, d + 1));
        }
    }
    deepest
}
