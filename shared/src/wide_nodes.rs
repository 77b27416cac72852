//! The grids' top level in wide nodes: up to seven children a node, each child's box six
//! 8-bit codes in its node's own frame, after the compressed wide BVHs of Ylitie, Karras and
//! Laine ("Efficient Incoherent Ray Traversal on GPUs Through Compressed Wide BVHs", HPG
//! 2017, <https://research.nvidia.com/publication/2017-07_efficient-incoherent-ray-traversal-gpus-through-compressed-wide-bvhs>).
//! A node takes 64 bytes for what the binary hierarchy spends 16 or 32 bytes a node on, about
//! twice as many nodes as it has leaves.
//!
//! # Layout
//! The hierarchy sits in a `BvhNode`-typed buffer, so every kernel binds it as any other top
//! level. Element 0 is a header: the scene's frame (origin in `min`, step per code in `max`,
//! [`WIDE`] in `count`). Node `k` fills elements `1 + 2k` and `2 + 2k`, read as sixteen words
//! in field order (`min`, `first`, `max`, `count` of each):
//! - words 3 and 7: the first inner child's node and the first grid of the leaf children.
//!   Inner children are consecutive nodes and leaf children's grids consecutive grids, both
//!   in child order.
//! - word 11: three bits a child (0: none, 1 to [`MAX_LEAF_GRIDS`]: a leaf of that many
//!   grids, [`INNER`]: a node), children packed from the first, then the frame's z exponent
//!   in the top byte.
//! - word 15 and the top half of word 13: the frame's origin as codes of the scene's frame,
//!   at most [`ORIGIN_CODE_MAX`].
//! - word 14: the frame's x and y exponents.
//! - the 42 bytes of words 0-2, 4-6, 8-10, 12 and the bottom half of 13: byte `6 k + f` holds
//!   field `f` of child `k`: the box's lower x, y, z codes, then its upper ones counted down
//!   from 255.
//!
//! A frame's step per code is a power of two (an exponent biased by 127), so every product
//! `code * step` is exact and `origin + code * step` is rounded once, fused or not: the CPU
//! and every GPU decode the same bits.
//!
//! Words that sit in float fields never read as a NaN or an infinity, so moving them through
//! float registers keeps their bits: a code in a top byte is never `0x7f` or `0xff` (the
//! builder moves such codes one step outwards), origin codes stay at most
//! [`ORIGIN_CODE_MAX`], and word 14's top byte is zero.
//!
//! # Guarantees
//! Each decoded child box holds the child's whole subtree (the builder checks it with these
//! very functions); the walk visits children nearest first and pops a waiting entry only while
//! it can hold a closer hit, so it finds the binary hierarchy's closest hit.

use crate::aabb::{intersect_aabb, intersect_aabbs};
use crate::buffer::Buffer;
use crate::cost::Tally;
use crate::glam::{Vec3, Vec4};
use crate::layout::BvhNode;
use crate::ray::{Ray, T_FAR};
use crate::traverse::{kept_distance, WalkStack, NO_NODE, TOP_STACK};

/// `count` of the header element of a wide hierarchy (never a node's count).
pub const WIDE: u32 = u32::MAX - 1;

/// Most children a node has.
pub const WIDTH: u32 = 7;

/// A child's three bits when it is a node.
pub const INNER: u32 = 7;

/// Most grids a leaf child holds.
pub const MAX_LEAF_GRIDS: u32 = 6;

/// Largest origin code: its word's top byte then never reads as part of a NaN.
pub const ORIGIN_CODE_MAX: u32 = 0x7f7f;

/// Largest box code.
pub const CODE_MAX: u32 = 255;

/// Entries the walk's stack holds; the builder keeps to it (see [`stack_need`]).
pub const STACK_ENTRIES: usize = TOP_STACK;

/// Exponents (biased) a frame may use: steps of `2^-118` to `2^127`, so that no product of a
/// code and a step, nor any decoded coordinate, is a denormal (which GPUs may flush).
pub const MIN_EXPONENT: u32 = 9;
pub const MAX_EXPONENT: u32 = 254;

/// A stack entry for a leaf: this bit, the first grid shifted by [`LEAF_SHIFT`], the count.
pub const LEAF: u32 = 1 << 31;
pub const LEAF_SHIFT: u32 = 3;

/// Most grids a wide hierarchy can name.
pub const MAX_GRIDS: u32 = 1 << (31 - LEAF_SHIFT);

/// A node's sixteen words.
pub type NodeWords = [u32; 16];

/// A node's frame: the point of code 0, and the step per code.
#[derive(Copy, Clone)]
pub struct Frame {
    pub origin: Vec3,
    pub step: Vec3,
}

impl Frame {
    /// The point codes `codes` stand for: one rounding per axis (see the module docs).
    #[inline(always)]
    pub fn point(&self, codes: Vec3) -> Vec3 {
        self.origin + self.step * codes
    }
}

/// The step of biased exponent `e`.
#[inline(always)]
pub fn step_of(e: u32) -> f32 {
    f32::from_bits(e << 23)
}

/// The scene's frame, from the header element.
#[inline]
pub fn scene_frame(header: &BvhNode) -> Frame {
    Frame {
        origin: Vec3::from(header.min),
        step: Vec3::from(header.max),
    }
}

/// Node `k`'s words.
#[inline(always)]
pub fn load_node<N: Buffer<BvhNode>>(nodes: N, k: u32) -> NodeWords {
    let a = nodes.load(1 + 2 * k);
    let b = nodes.load(2 + 2 * k);
    [
        a.min[0].to_bits(),
        a.min[1].to_bits(),
        a.min[2].to_bits(),
        a.first,
        a.max[0].to_bits(),
        a.max[1].to_bits(),
        a.max[2].to_bits(),
        a.count,
        b.min[0].to_bits(),
        b.min[1].to_bits(),
        b.min[2].to_bits(),
        b.first,
        b.max[0].to_bits(),
        b.max[1].to_bits(),
        b.max[2].to_bits(),
        b.count,
    ]
}

/// The word and shift of code byte `j` (`6 k + f`).
#[inline(always)]
pub fn code_slot(j: u32) -> (usize, u32) {
    let q = j / 4;
    ((q + q / 3) as usize, 8 * (j % 4))
}

/// Node `w`'s frame, within the scene's frame `scene`.
#[inline(always)]
pub fn node_frame(w: &NodeWords, scene: &Frame) -> Frame {
    let codes = Vec3::new((w[15] & 0xffff) as f32, (w[15] >> 16) as f32, (w[13] >> 16) as f32);
    Frame {
        origin: scene.point(codes),
        step: Vec3::new(
            step_of(w[14] & 0xff),
            step_of((w[14] >> 8) & 0xff),
            step_of(w[11] >> 24),
        ),
    }
}

/// Child `k`'s three bits.
#[inline(always)]
pub fn child_kind(w: &NodeWords, k: u32) -> u32 {
    (w[11] >> (3 * k)) & 7
}

/// Child `k`'s six codes as stored (the upper ones counted down from [`CODE_MAX`]).
#[inline(always)]
fn child_code(w: &NodeWords, k: u32, f: u32) -> u32 {
    let (word, shift) = code_slot(6 * k + f);
    (w[word] >> shift) & 0xff
}

/// The boxes of children `FIRST .. FIRST + 4` in frame `frame`, child `FIRST + j` in lane `j`:
/// their lower and upper corners, one `Vec4` an axis, each coordinate the origin plus the exact
/// product of a code and the step (as [`Frame::point`]). Slots past the last ([`WIDTH`])
/// decode bytes of other fields, and their lanes mean nothing.
#[inline(always)]
pub fn child_boxes<const FIRST: u32>(w: &NodeWords, frame: &Frame) -> ([Vec4; 3], [Vec4; 3]) {
    let codes = |f: u32| {
        Vec4::new(
            child_code(w, FIRST, f) as f32,
            child_code(w, FIRST + 1, f) as f32,
            child_code(w, FIRST + 2, f) as f32,
            child_code(w, FIRST + 3, f) as f32,
        )
    };
    let top = Vec4::splat(CODE_MAX as f32);
    let origin = [frame.origin.x, frame.origin.y, frame.origin.z];
    let step = [frame.step.x, frame.step.y, frame.step.z];
    let point = |a: usize, codes: Vec4| Vec4::splat(origin[a]) + Vec4::splat(step[a]) * codes;
    let lo = [point(0, codes(0)), point(1, codes(1)), point(2, codes(2))];
    let hi = [
        point(0, top - codes(3)),
        point(1, top - codes(4)),
        point(2, top - codes(5)),
    ];
    (lo, hi)
}

/// Child `k`'s box in frame `frame`: its lane of [`child_boxes`], the walk's own decode.
pub fn child_box(w: &NodeWords, k: u32, frame: &Frame) -> (Vec3, Vec3) {
    let (lo, hi) = if k < 4 {
        child_boxes::<0>(w, frame)
    } else {
        child_boxes::<4>(w, frame)
    };
    let lane = (k % 4) as usize;
    let corner = |c: [Vec4; 3]| Vec3::new(c[0].to_array()[lane], c[1].to_array()[lane], c[2].to_array()[lane]);
    (corner(lo), corner(hi))
}

/// Where `ray` enters the boxes of children `FIRST .. FIRST + 4` closer than `t`, in the four
/// lanes (see [`child_boxes`]).
#[inline(always)]
fn child_entries<const FIRST: u32>(w: &NodeWords, frame: &Frame, ray: &Ray, t: f32) -> Vec4 {
    let (lo, hi) = child_boxes::<FIRST>(w, frame);
    intersect_aabbs(lo, hi, ray, t)
}

/// The box of a whole node: its frame's 255 codes.
#[inline]
pub fn frame_box(frame: &Frame) -> (Vec3, Vec3) {
    (frame.origin, frame.point(Vec3::splat(CODE_MAX as f32)))
}

/// Where `ray` enters the root's box closer than `t`, [`T_FAR`] where it misses it.
#[inline(always)]
pub(crate) fn root_entry<N: Buffer<BvhNode>, T: Tally>(
    nodes: N,
    scene: &Frame,
    ray: &Ray,
    t: f32,
    tally: &mut T,
) -> f32 {
    let (lo, hi) = frame_box(&node_frame(&load_node(nodes, 0), scene));
    tally.nodes(1);
    intersect_aabb(lo, hi, ray, t)
}

/// The grids a leaf entry names, as a node's range (`first`, `count`).
#[inline(always)]
pub(crate) fn leaf_grids(entry: u32) -> BvhNode {
    BvhNode {
        first: (entry & !LEAF) >> LEAF_SHIFT,
        count: entry & ((1 << LEAF_SHIFT) - 1),
        ..BvhNode::default()
    }
}

/// Takes entries off `stack` until a leaf the ray may hit closer than `t`, opening the nodes
/// on the way; the leaf's entry, or [`NO_NODE`] when the stack runs out.
#[inline(always)]
pub(crate) fn next_leaf<N: Buffer<BvhNode>, S: WalkStack, T: Tally>(
    nodes: N,
    scene: &Frame,
    ray: &Ray,
    t: f32,
    stack: &mut S,
    sp: &mut usize,
    tally: &mut T,
) -> u32 {
    loop {
        let entry = stack.pop_closer(sp, t);
        if entry == NO_NODE || entry & LEAF != 0 {
            return entry;
        }
        let w = load_node(nodes, entry);
        let mut open = OpenNode {
            frame: node_frame(&w, scene),
            node: w[3],
            grid: w[7],
            w,
            entered: Entered::NONE,
        };
        // Every slot's box tested first, four side by side, then one copy of the child's visit
        // per slot, empty ones skipped: in each the slot is a constant, so every code's word
        // and shift are too (a loop over the slots, which not every compiler unrolls,
        // computes them as it goes).
        let first = child_entries::<0>(&open.w, &open.frame, ray, t);
        let last = child_entries::<4>(&open.w, &open.frame, ray, t);
        open.visit::<0, _>(first.x, tally);
        open.visit::<1, _>(first.y, tally);
        open.visit::<2, _>(first.z, tally);
        open.visit::<3, _>(first.w, tally);
        open.visit::<4, _>(last.x, tally);
        open.visit::<5, _>(last.y, tally);
        open.visit::<6, _>(last.z, tally);
        open.entered.push_onto(stack, sp);
    }
}

const _: () = assert!(WIDTH == 7, "next_leaf visits seven slots");

/// A node the walk opened: its words and frame, the node and the grid its next inner and leaf
/// children begin at, and the children the ray enters so far.
struct OpenNode {
    w: NodeWords,
    frame: Frame,
    node: u32,
    grid: u32,
    entered: Entered,
}

impl OpenNode {
    /// Child slot `K`, whose box the ray enters at `t_enter` ([`T_FAR`] where it misses it or
    /// enters beyond the closest hit): where it is entered, it is sorted in among the
    /// children entered before it.
    #[inline(always)]
    fn visit<const K: u32, T: Tally>(&mut self, t_enter: f32, tally: &mut T) {
        let kind = child_kind(&self.w, K);
        if kind != 0 {
            tally.nodes(1);
            let child = if kind == INNER {
                self.node
            } else {
                LEAF | self.grid << LEAF_SHIFT | kind
            };
            if t_enter < T_FAR {
                self.entered.insert(child, t_enter);
            }
            if kind == INNER {
                self.node += 1;
            } else {
                self.grid += kind;
            }
        }
    }
}

/// The children of a node that the ray enters, in the order they go onto the walk's stack:
/// farthest first, so the nearest is on top; of two at the same distance the later slot
/// goes on top. Held in registers: every slot is read and written at an index fixed in the
/// code (an array indexed at run time is slow private memory on a GPU, or a chain of
/// selects per access), so a child is sorted in by exchanges of neighbouring slots, and the
/// stack is written by one loop. Slots past `count` hold a distance of -1, nearer than any.
struct Entered {
    entry: [u32; WIDTH as usize],
    t: [f32; WIDTH as usize],
    count: u32,
}

impl Entered {
    const NONE: Entered = Entered {
        entry: [0; WIDTH as usize],
        t: [-1.0; WIDTH as usize],
        count: 0,
    };

    /// Sorts in `entry`, entered at `t`, above every child entered at least as far (as kept
    /// on the stack, see [`kept_distance`]), as an insertion into the stack would.
    #[inline(always)]
    fn insert(&mut self, entry: u32, t: f32) {
        // The last slot is free: a node has at most seven children, and this is not the
        // eighth. From there the new child moves down past the free slots and the nearer
        // children; the children already in order never trade places.
        self.entry[6] = entry;
        self.t[6] = kept_distance(t);
        self.order::<5>();
        self.order::<4>();
        self.order::<3>();
        self.order::<2>();
        self.order::<1>();
        self.order::<0>();
        self.count += 1;
    }

    /// Puts slots `J` and `J + 1` in order: the nearer one above.
    #[inline(always)]
    fn order<const J: usize>(&mut self) {
        let (t, entry) = (self.t[J], self.entry[J]);
        if t < self.t[J + 1] {
            self.t[J] = self.t[J + 1];
            self.entry[J] = self.entry[J + 1];
            self.t[J + 1] = t;
            self.entry[J + 1] = entry;
        }
    }

    /// Slot `k`'s entry and distance, picked by comparisons (see the type's docs).
    #[inline(always)]
    fn slot(&self, k: u32) -> (u32, f32) {
        if k == 0 {
            (self.entry[0], self.t[0])
        } else if k == 1 {
            (self.entry[1], self.t[1])
        } else if k == 2 {
            (self.entry[2], self.t[2])
        } else if k == 3 {
            (self.entry[3], self.t[3])
        } else if k == 4 {
            (self.entry[4], self.t[4])
        } else if k == 5 {
            (self.entry[5], self.t[5])
        } else {
            (self.entry[6], self.t[6])
        }
    }

    /// Pushes the entered children onto `stack`, `sp` high, the nearest last; one loop, so
    /// one copy of the stack's write.
    #[inline(always)]
    fn push_onto<S: WalkStack>(&self, stack: &mut S, sp: &mut usize) {
        let mut k = 0;
        while k < self.count {
            // The builder keeps every walk within the stack (see `stack_need` on the host).
            if *sp < S::CAPACITY {
                let (entry, t) = self.slot(k);
                stack.push(*sp, entry, t);
                *sp += 1;
            }
            k += 1;
        }
    }
}
