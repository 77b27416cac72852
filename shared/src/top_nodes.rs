//! The grids' top-level BVH in any of three forms, searched through one [`Hierarchy`]: full
//! binary nodes (32 bytes, `f32` boxes), compact binary nodes (16 bytes) whose boxes are 15-bit
//! fractions of the scene's box, rounded outwards, or wide nodes ([`crate::wide_nodes`]). The
//! binary forms are also read node by node through [`Buffer`] (the two-phase schedule's walk).
//!
//! A compact hierarchy is stored in the same `BvhNode`-typed buffer, so every kernel binds it
//! as before: element 0 is a header (the quantization frame: origin in `min`, the step per
//! unit of code in `max`, [`COMPACT`] in `count`), and each later element holds two nodes,
//! node `i` in element `1 + i / 2`, half `i % 2`. A node is four words: three hold its six
//! box codes, two to a word, and the fourth its link, `first << 3 | count`. The code words
//! sit in the element's float fields and the links in its integer ones; codes stay below
//! `0x7f80`, so no code word reads as a NaN or an infinity, and moving it through float
//! registers keeps its bits.
//!
//! Guarantees: a decoded box holds the node's box (the builder checks this under both ways
//! a GPU may round `origin + step * code`, fused or not, and keeps the full form where it
//! cannot); decoding is the same arithmetic on the CPU and the GPU; the topology (links,
//! leaf ranges) is the full hierarchy's, so both forms visit the same nodes.

use crate::aabb::intersect_aabb;
use crate::buffer::Buffer;
use crate::cost::Tally;
use crate::glam::Vec3;
use crate::layout::{BvhNode, Hit, HitRecord, WalkState};
use crate::ray::Ray;
use crate::ray::T_FAR;
use crate::traverse::{
    descend, traverse_bvh, walk_first_round, walk_round, Hierarchy, LeafPrimitives, LocalStack, WalkStack, NO_NODE,
};
use crate::wide_nodes::{leaf_grids, next_leaf, push_root, scene_frame, walk_first_round_wide, walk_round_wide, WIDE};

/// `count` of the header element of a compact hierarchy (never a node's count).
pub const COMPACT: u32 = u32::MAX;

/// The largest box code: below `0x7f80`, so no code word's exponent bits are all ones.
pub const CODE_MAX: u32 = 0x7f7f;

/// Bits of a link word that hold a leaf's count.
pub const COUNT_BITS: u32 = 3;

/// The top-level nodes of a grid scene, full, compact or wide (see the module docs).
#[derive(Copy, Clone)]
pub struct TopNodes<N> {
    nodes: N,
    compact: bool,
    wide: bool,
    origin: Vec3,
    step: Vec3,
}

impl<N: Buffer<BvhNode>> TopNodes<N> {
    /// The hierarchy stored in `nodes`, in whichever form its first element says.
    #[inline]
    pub fn new(nodes: N) -> Self {
        let header = if nodes.is_empty() {
            BvhNode::default()
        } else {
            nodes.load(0)
        };
        TopNodes {
            nodes,
            compact: header.count == COMPACT,
            wide: header.count == WIDE,
            origin: Vec3::from(header.min),
            step: Vec3::from(header.max),
        }
    }
}

impl<N: Buffer<BvhNode>> TopNodes<N> {
    /// Whether the nodes are wide, which only [`Hierarchy::search`] and the two-phase rounds
    /// read.
    #[inline]
    pub fn is_wide(self) -> bool {
        self.wide
    }

    /// The two-phase schedule's first round (see `crate::traverse::walk_first_round`) over
    /// these nodes in their form. `WIDE_WALK`: whether the kernel carries the wide walk (plain
    /// grids' kernels do not, see `LeafPrimitives::DISPLACED_FORMATS`).
    #[inline(always)]
    pub fn first_round<const WIDE_WALK: bool, S: WalkStack>(
        self,
        ray: &Ray,
        t_max: f32,
        state: &mut WalkState,
        stack: &mut S,
    ) -> BvhNode {
        if WIDE_WALK && !N::SPLIT && self.wide {
            walk_first_round_wide(self.nodes, ray, t_max, state, stack)
        } else {
            walk_first_round(self, ray, t_max, state, stack)
        }
    }

    /// Every later round of the two-phase schedule (see `crate::traverse::walk_round`) over
    /// these nodes in their form, as [`Self::first_round`].
    #[inline(always)]
    pub fn next_round<const WIDE_WALK: bool, R: Buffer<HitRecord>, S: WalkStack>(
        self,
        results: R,
        ray: &Ray,
        state: &mut WalkState,
        stack: &mut S,
    ) -> BvhNode {
        if WIDE_WALK && !N::SPLIT && self.wide {
            walk_round_wide(self.nodes, results, ray, state, stack)
        } else {
            walk_round(self, results, ray, state, stack)
        }
    }
}

impl<N: Buffer<BvhNode>> Hierarchy for TopNodes<N> {
    #[inline(always)]
    fn search<P: LeafPrimitives, T: Tally>(self, prims: &P, ray: &Ray, hit: &mut Hit, tally: &mut T) {
        // Split kernels leave the wide walk out: with it their first compile takes far longer.
        // Split scenes never hold a wide top level (the host refuses to split one), and plain
        // grids' kernels leave it out too (see `LeafPrimitives::DISPLACED_FORMATS`).
        if !N::SPLIT && P::DISPLACED_FORMATS {
            self.search_either(prims, ray, hit, tally)
        } else {
            traverse_bvh(self, prims, ray, hit, tally)
        }
    }
}

impl<N: Buffer<BvhNode>> TopNodes<N> {
    /// Closest hit along `ray` closer than `hit.t`, walking binary nodes as
    /// `crate::traverse::traverse_bvh` does or wide ones as their two-phase rounds do
    /// (`crate::wide_nodes`): either walk down to the next leaf, then one test of that leaf's
    /// grids. A shader inlines each call of the leaf test whole, so a kernel that carries both
    /// walks holds one copy of the grids' traversal rather than one per walk.
    ///
    /// The wide walk keeps every entry on the stack, nodes and leaves alike, sorted nearest on
    /// top, and takes the next leaf off it; the binary walk goes down to the next leaf, the
    /// farther children waiting on the stack, and pops the nearest one left after the leaf's
    /// test.
    #[inline(always)]
    fn search_either<P: LeafPrimitives, T: Tally>(self, prims: &P, ray: &Ray, hit: &mut Hit, tally: &mut T) {
        if self.nodes.is_empty() {
            return;
        }
        let wide = self.wide;
        let scene = scene_frame(&self.nodes.load(0));
        let mut stack = LocalStack::new();
        let mut sp = 0usize;
        // The binary walk's node to go down from next.
        let mut node = 0u32;
        if wide {
            sp = push_root(self.nodes, &scene, ray, hit.t, &mut stack, tally);
            if sp == 0 {
                return;
            }
        } else {
            let root = self.load(0);
            tally.nodes(1);
            if intersect_aabb(Vec3::from(root.min), Vec3::from(root.max), ray, hit.t) == T_FAR {
                return;
            }
        }
        let mut scratch = prims.scratch(ray);
        // Tested at the bottom, as `traverse_bvh`'s loop, but for the walk's end found on the
        // way to a leaf.
        loop {
            let leaf = if wide {
                let entry = next_leaf(self.nodes, &scene, ray, hit.t, &mut stack, &mut sp, tally);
                if entry == NO_NODE {
                    BvhNode::default()
                } else {
                    leaf_grids(entry)
                }
            } else {
                descend(self, ray, hit.t, self.load(node), &mut stack, &mut sp, tally)
            };
            if !leaf.is_leaf() {
                break;
            }
            prims.intersect_leaf(leaf.first, leaf.count, ray, hit, &mut scratch, tally);
            if !wide {
                node = stack.pop_closer(&mut sp, hit.t);
                if node == NO_NODE {
                    break;
                }
            }
        }
    }
}

/// Binary nodes one by one (full or compact; not wide ones).
impl<N: Buffer<BvhNode>> Buffer<BvhNode> for TopNodes<N> {
    const SPLIT: bool = N::SPLIT;

    #[inline]
    fn load(self, index: u32) -> BvhNode {
        if !self.compact {
            return self.nodes.load(index);
        }
        let pair = self.nodes.load(1 + (index >> 1));
        let words = if index & 1 == 0 {
            [
                pair.min[0].to_bits(),
                pair.min[1].to_bits(),
                pair.min[2].to_bits(),
                pair.first,
            ]
        } else {
            [
                pair.max[0].to_bits(),
                pair.max[1].to_bits(),
                pair.max[2].to_bits(),
                pair.count,
            ]
        };
        decode_node(words, self.origin, self.step)
    }

    #[inline]
    fn is_empty(self) -> bool {
        self.nodes.is_empty()
    }
}

/// A compact node's four words as a full node, in the frame `origin`, `step`.
#[inline]
pub fn decode_node(words: [u32; 4], origin: Vec3, step: Vec3) -> BvhNode {
    let low = |w: u32| (w & 0xffff) as f32;
    let high = |w: u32| (w >> 16) as f32;
    let lo = Vec3::new(low(words[0]), high(words[0]), low(words[1]));
    let hi = Vec3::new(high(words[1]), low(words[2]), high(words[2]));
    BvhNode {
        min: decode_point(lo, origin, step).to_array(),
        first: words[3] >> COUNT_BITS,
        max: decode_point(hi, origin, step).to_array(),
        count: words[3] & ((1 << COUNT_BITS) - 1),
    }
}

/// The point that box codes `codes` stand for.
#[inline]
pub fn decode_point(codes: Vec3, origin: Vec3, step: Vec3) -> Vec3 {
    origin + step * codes
}
