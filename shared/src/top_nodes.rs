//! The grids' top-level BVH in any of three forms, searched through one [`Hierarchy`]: full
//! binary nodes (32 bytes, `f32` boxes), compact binary nodes (16 bytes) whose boxes are 15-bit
//! fractions of the scene's box, rounded outwards, or wide nodes ([`crate::wide_nodes`]). The
//! binary forms are also read node by node through [`Buffer`].
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

use crate::buffer::Buffer;
use crate::cost::Tally;
use crate::glam::Vec3;
use crate::layout::{BvhNode, Hit};
use crate::ray::Ray;
use crate::traverse::{traverse_bvh, BinaryWalk, Hierarchy, LeafPrimitives, LeafWalk, WalkStack, NO_NODE};
use crate::wide_nodes::{leaf_grids, next_leaf, root_entry, Frame, WIDE};

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
    /// Whether the nodes are wide, which only [`TopWalk`] reads.
    #[inline]
    pub fn is_wide(self) -> bool {
        self.wide
    }

    /// The walk over these nodes in their form; wide nodes are walked only where `WIDE_WALK`
    /// (the code carries the wide walk) and `wide_walk` (the pipeline keeps it) say so (see
    /// [`TopWalk`]).
    #[inline(always)]
    pub fn walk<const WIDE_WALK: bool>(self, wide_walk: bool) -> TopWalk<N, WIDE_WALK> {
        TopWalk {
            wide: wide_walk && self.wide,
            top: self,
        }
    }

    /// The scene's frame, which wide nodes' frames are codes of: the compact frame's fields.
    #[inline(always)]
    fn scene_frame(self) -> Frame {
        Frame {
            origin: self.origin,
            step: self.step,
        }
    }
}

impl<N: Buffer<BvhNode>> Hierarchy for TopNodes<N> {
    #[inline(always)]
    fn search<P: LeafPrimitives, T: Tally>(self, prims: &P, ray: &Ray, hit: &mut Hit, tally: &mut T) {
        // Constants in a kernel: its module (`WIDE_WALK`) or its pipeline
        // (`displaced_grids`) leaves the wide walk out where it carries no displaced grids.
        if P::WIDE_WALK {
            traverse_bvh(self.walk::<true>(prims.displaced_grids()), prims, ray, hit, tally)
        } else {
            traverse_bvh(self.walk::<false>(false), prims, ray, hit, tally)
        }
    }
}

/// The walk over the grids' top level in any of its forms: binary nodes (full or compact) read
/// one by one, or wide nodes as `crate::wide_nodes` walks them, every entry on the stack, nodes
/// and leaves alike, sorted nearest on top.
///
/// `wide`: whether the nodes are wide and the pipeline keeps the wide walk; `WIDE_WALK`: whether
/// the code carries it at all. Kernels that leave displaced grids out leave the wide walk out
/// (see `LeafPrimitives::WIDE_WALK` and `LeafPrimitives::displaced_grids`).
#[derive(Copy, Clone)]
pub struct TopWalk<N, const WIDE_WALK: bool> {
    top: TopNodes<N>,
    wide: bool,
}

impl<N: Buffer<BvhNode>, const WIDE_WALK: bool> LeafWalk for TopWalk<N, WIDE_WALK> {
    #[inline(always)]
    fn enter<T: Tally>(self, ray: &Ray, t: f32, tally: &mut T) -> f32 {
        let top = self.top;
        if WIDE_WALK && self.wide {
            root_entry(top.nodes, &top.scene_frame(), ray, t, tally)
        } else {
            BinaryWalk(top).enter(ray, t, tally)
        }
    }

    #[inline(always)]
    fn next_leaf<S: WalkStack, T: Tally>(
        self,
        ray: &Ray,
        t: f32,
        stack: &mut S,
        sp: &mut usize,
        tally: &mut T,
    ) -> BvhNode {
        let top = self.top;
        if WIDE_WALK && self.wide {
            let entry = next_leaf(top.nodes, &top.scene_frame(), ray, t, stack, sp, tally);
            if entry == NO_NODE {
                BvhNode::default()
            } else {
                leaf_grids(entry)
            }
        } else {
            BinaryWalk(top).next_leaf(ray, t, stack, sp, tally)
        }
    }
}

/// Binary nodes one by one (full or compact; not wide ones).
impl<N: Buffer<BvhNode>> Buffer<BvhNode> for TopNodes<N> {
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
