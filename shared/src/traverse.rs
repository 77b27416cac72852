//! Closest-hit traversal: one binary-BVH loop, used both for the baseline (leaves hold
//! triangles) and as the top level of the grid scene (leaves hold grids, each searched by the
//! bottom-level loop over its sphere hierarchy, [`crate::grid_traverse`]).

use crate::aabb::intersect_aabb;
use crate::buffer::{Buffer, Chunks, Split};
use crate::cost::{Tally, Uncounted};
use crate::glam::Vec3;
use crate::layout::{BvhNode, Hit, SplitParams, TRIANGLE_INDICES, TRIANGLE_POSITIONS};
use crate::ray::{Ray, T_FAR};
use crate::triangle::{intersect_triangle, triangle_normal};

/// Deepest triangle BVH the traversal can walk; the builder never makes a deeper one.
pub const MAX_BVH_DEPTH: usize = 64;

/// Entries the stack of the grids' top-level walk holds for a wide top level: the builder
/// narrows a wide level's nodes until its walk fits (`crate::wide_nodes::STACK_ENTRIES`).
/// Three quarters of the baseline's: a GPU keeps the stack in registers, which the grids'
/// bottom level needs, while a wide top level's walk leaves up to six entries waiting a level,
/// and a shorter stack makes a large scene's wide nodes narrower, many more of them
/// (docs/RESULTS.md).
pub const TOP_STACK: usize = 48;

/// The first entries of [`TopStack`], all a binary top level's walk uses: the builder keeps
/// the grids' binary hierarchy within `BINARY_TOP_STACK - 2` levels (see the host's builder
/// settings). A kernel that walks binary top levels alone keeps no register for the rest,
/// which only a wide top level's walk reaches.
pub const BINARY_TOP_STACK: usize = 40;

/// What a BVH leaf refers to.
pub trait LeafPrimitives {
    /// Whether the code reading these primitives may carry the wide top level's walk, a
    /// constant: kernels whose module leaves displaced grids out leave it out.
    const WIDE_WALK: bool = true;

    /// Whether the code reading these primitives carries what displaced grids alone hold
    /// (see `crate::buffer::carries::DISPLACED_GRIDS`), the wide top level's walk among them.
    #[inline(always)]
    fn displaced_grids(&self) -> bool {
        true
    }

    /// The walk's stack, as deep as the builder keeps hierarchies over these primitives.
    type Stack: WalkStack + Default;

    /// Working memory of the leaf tests and the per-ray constants they need, made once per
    /// ray rather than once per leaf: on GPUs every fresh local array costs a store per element.
    type Scratch;
    fn scratch(&self, ray: &Ray) -> Self::Scratch;
    /// Intersects primitives `first .. first + count`, taking the closest hit closer than
    /// `hit.t` into `hit`, and reports its tests to `tally`.
    fn intersect_leaf<T: Tally>(
        &self,
        first: u32,
        count: u32,
        ray: &Ray,
        hit: &mut Hit,
        scratch: &mut Self::Scratch,
        tally: &mut T,
    );
    /// Corners of the triangle a hit names `prim` at depth `level` (see [`Hit`]).
    fn triangle(&self, prim: u32, level: u32) -> [Vec3; 3];
    /// The normal to light `hit` with when smooth shading is asked for: the geometric one
    /// unless the primitives know their surface better.
    fn smooth_normal(&self, hit: &Hit) -> Vec3 {
        Vec3::from(hit.normal)
    }
}

/// A hierarchy the closest-hit walk searches: a binary BVH read through a [`Buffer`], or the
/// grids' top level in whichever form it is stored (`crate::top_nodes::TopNodes`).
pub trait Hierarchy: Copy {
    /// Takes the closest hit along `ray` closer than `hit.t` into `hit`, reporting every test
    /// to `tally`.
    fn search<P: LeafPrimitives, T: Tally>(self, prims: &P, ray: &Ray, hit: &mut Hit, tally: &mut T);
}

impl Hierarchy for &[BvhNode] {
    #[inline(always)]
    fn search<P: LeafPrimitives, T: Tally>(self, prims: &P, ray: &Ray, hit: &mut Hit, tally: &mut T) {
        traverse_bvh(BinaryWalk(self), prims, ray, hit, tally)
    }
}

impl Hierarchy for Split<'_, BvhNode> {
    #[inline(always)]
    fn search<P: LeafPrimitives, T: Tally>(self, prims: &P, ray: &Ray, hit: &mut Hit, tally: &mut T) {
        traverse_bvh(BinaryWalk(self), prims, ray, hit, tally)
    }
}

/// The stack entry of a hierarchy's root, in every form.
pub const ROOT: u32 = 0;

/// A walk over a hierarchy's nodes down to its leaves, nearest first, the entries it passes
/// waiting on a [`WalkStack`] with their entry distances, the root's entry being [`ROOT`]. The
/// closest-hit loop ([`traverse_bvh`]) drives it, so a kernel holds one leaf test whatever form
/// the nodes take: binary ([`BinaryWalk`]) or the grids' top level in any of its forms
/// (`crate::top_nodes::TopWalk`).
pub trait LeafWalk: Copy {
    /// Where `ray` enters the root's box closer than `t`; [`T_FAR`] where it misses it or the
    /// hierarchy is empty.
    fn enter<T: Tally>(self, ray: &Ray, t: f32, tally: &mut T) -> f32;
    /// Takes entries off `stack` (`sp` high) down to the next leaf the ray may hit closer than
    /// `t`, the entries passed on the way left waiting; the leaf as a node of its primitives,
    /// or a node with `count` 0 when the walk is over.
    fn next_leaf<S: WalkStack, T: Tally>(
        self,
        ray: &Ray,
        t: f32,
        stack: &mut S,
        sp: &mut usize,
        tally: &mut T,
    ) -> BvhNode;
}

/// The walk over binary nodes (full `f32` boxes, or anything read node by node as such).
#[derive(Copy, Clone)]
pub struct BinaryWalk<N>(pub N);

impl<N: Buffer<BvhNode>> LeafWalk for BinaryWalk<N> {
    #[inline(always)]
    fn enter<T: Tally>(self, ray: &Ray, t: f32, tally: &mut T) -> f32 {
        if self.0.is_empty() {
            return T_FAR;
        }
        let root = self.0.load(ROOT);
        tally.nodes(1);
        intersect_aabb(Vec3::from(root.min), Vec3::from(root.max), ray, t)
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
        match pop_entered(self.0, ray, t, stack, sp, tally) {
            Some(node) => descend(self.0, ray, t, node, stack, sp, tally),
            // An inner node where nothing is left to pop: its `count` is 0.
            None => BvhNode::default(),
        }
    }
}

/// Closest hit along `ray` within `t_max`, with its triangle's normal: found once, after the
/// traversal, from the closest triangle's corners loaded again.
pub fn trace<N: Hierarchy, P: LeafPrimitives>(nodes: N, prims: &P, ray: &Ray, t_max: f32) -> Hit {
    trace_tallied(nodes, prims, ray, t_max, &mut Uncounted)
}

/// [`trace`], reporting every test it makes to `tally`.
pub fn trace_tallied<N: Hierarchy, P: LeafPrimitives, T: Tally>(
    nodes: N,
    prims: &P,
    ray: &Ray,
    t_max: f32,
    tally: &mut T,
) -> Hit {
    with_normal(prims, closest_hit(nodes, prims, ray, t_max, tally))
}

/// `hit` with its triangle's normal, if it is a hit.
#[inline]
pub fn with_normal<P: LeafPrimitives>(prims: &P, mut hit: Hit) -> Hit {
    if hit.is_hit() {
        let [a, b, c] = prims.triangle(hit.prim, hit.level);
        hit.normal = triangle_normal(a, b, c).to_array();
    }
    hit
}

/// Closest hit along `ray` within `t_max`, without its normal: all a list of rays asks for.
/// (On SIMD hardware the normal's loads cost every ray of a group, hit or not.)
#[inline]
pub fn closest_hit<N: Hierarchy, P: LeafPrimitives, T: Tally>(
    nodes: N,
    prims: &P,
    ray: &Ray,
    t_max: f32,
    tally: &mut T,
) -> Hit {
    let mut hit = Hit::miss(t_max);
    nodes.search(prims, ray, &mut hit, tally);
    hit
}

/// No node: the stack is empty.
pub const NO_NODE: u32 = u32::MAX;

/// Closest hit along `ray` closer than `hit.t`. A near-first, stack-based loop: `walk` goes
/// down to the nearer child while the farther one waits on the stack with its entry distance,
/// so it can be skipped once a closer hit is known.
///
/// Shaped while-while (Aila and Laine 2009): the walk descends to the next leaf, popping past
/// dead ends, and the leaf is tested after it, once per leaf rather than inside every node
/// step. On SIMD hardware a group's rays then test their leaves together, and some targets
/// (lavapipe) run the code under a branch even when none of the group's rays takes it: with
/// the leaf test inside the node loop, every node step paid for a grid's whole bottom level.
/// A shader inlines the leaf test whole at each call, so this loop is its only call site,
/// whatever form the nodes take.
pub fn traverse_bvh<W: LeafWalk, P: LeafPrimitives, T: Tally>(
    walk: W,
    prims: &P,
    ray: &Ray,
    hit: &mut Hit,
    tally: &mut T,
) {
    let t_root = walk.enter(ray, hit.t, tally);
    if t_root == T_FAR {
        // Before any working memory is made: clearing it would cost a missing ray more than
        // the box test.
        return;
    }
    let mut stack = P::Stack::default();
    // The root's entry distance is kept for the walks that read it (see `WalkStack`).
    stack.push(0, ROOT, t_root);
    let mut sp = 1usize;
    let mut scratch = prims.scratch(ray);
    // Every loop here tests its condition at the bottom: in lockstep a loop tested at the top
    // runs its body once more than any ray needs (with every lane masked off), and for the
    // outer loop that pass is a whole leaf test.
    loop {
        let leaf = walk.next_leaf(ray, hit.t, &mut stack, &mut sp, tally);
        if !leaf.is_leaf() {
            break;
        }
        prims.intersect_leaf(leaf.first, leaf.count, ray, hit, &mut scratch, tally);
    }
}

/// From node `n` down to the next leaf the ray may hit closer than `t`, nearer child first,
/// the farther one waiting on `stack` (`sp` high) with its entry distance; dead ends pop the
/// nearest waiting node that is still closer than `t`. Returns the leaf, or an inner node
/// when nothing is left to pop.
#[inline(always)]
fn descend<N: Buffer<BvhNode>, S: WalkStack, T: Tally>(
    nodes: N,
    ray: &Ray,
    t: f32,
    mut n: BvhNode,
    stack: &mut S,
    sp: &mut usize,
    tally: &mut T,
) -> BvhNode {
    if !n.is_leaf() {
        loop {
            let left = nodes.load(n.first);
            let right = nodes.load(n.first + 1);
            tally.nodes(2);
            let tl = intersect_aabb(Vec3::from(left.min), Vec3::from(left.max), ray, t);
            let tr = intersect_aabb(Vec3::from(right.min), Vec3::from(right.max), ray, t);
            if tl == T_FAR && tr == T_FAR {
                match pop_entered(nodes, ray, t, stack, sp, tally) {
                    Some(popped) => n = popped,
                    None => break,
                }
            } else {
                let (near, far, t_far) = if tl <= tr {
                    (n.first, n.first + 1, tr)
                } else {
                    (n.first + 1, n.first, tl)
                };
                if t_far < T_FAR && *sp < S::BINARY_CAPACITY {
                    stack.push_binary(*sp, far);
                    *sp += 1;
                }
                n = nodes.load(near);
            }
            if n.is_leaf() {
                break;
            }
        }
    }
    n
}

/// The nearest node waiting on a binary walk's `stack` (`sp` high) that the ray still enters
/// closer than `t`, loaded and its box tested again (a closer hit may have come since it was
/// put there), or `None`. A binary walk keeps no entry distances: a stack of nodes alone takes
/// half the registers on a GPU, and a node's box is in the node the walk loads next anyway.
#[inline(always)]
fn pop_entered<N: Buffer<BvhNode>, S: WalkStack, T: Tally>(
    nodes: N,
    ray: &Ray,
    t: f32,
    stack: &mut S,
    sp: &mut usize,
    tally: &mut T,
) -> Option<BvhNode> {
    let mut entered = BvhNode::default();
    let found = pop_until(sp, |at| {
        entered = nodes.load(stack.binary_node(at));
        tally.nodes(1);
        intersect_aabb(Vec3::from(entered.min), Vec3::from(entered.max), ray, t) < t
    });
    if found {
        Some(entered)
    } else {
        None
    }
}

/// Pops a stack `sp` high down to the first slot that `takes` (asked from the top down), which
/// is left popped with `sp` at it; whether one was taken.
#[inline(always)]
fn pop_until(sp: &mut usize, mut takes: impl FnMut(usize) -> bool) -> bool {
    let mut taken = false;
    if *sp > 0 {
        // Tested at the bottom (see `traverse_bvh`).
        loop {
            *sp -= 1;
            if takes(*sp) {
                taken = true;
                break;
            }
            if *sp == 0 {
                break;
            }
        }
    }
    taken
}

/// Where a walk keeps the entries it passes: a node per slot, and the entry distance where
/// the walk keeps it (the wide walk, whose leaf entries have no box of their own).
pub trait WalkStack {
    /// Entries it holds.
    const CAPACITY: usize;
    /// Entries a binary walk uses, the first ones (see [`BINARY_TOP_STACK`]).
    const BINARY_CAPACITY: usize = Self::CAPACITY;
    fn push(&mut self, at: usize, node: u32, t: f32);
    /// A node alone: its distance is never read.
    fn push_node(&mut self, at: usize, node: u32);
    fn node(&self, at: usize) -> u32;
    fn t(&self, at: usize) -> f32;
    /// [`Self::push_node`] for a binary walk, at `at < BINARY_CAPACITY`.
    #[inline(always)]
    fn push_binary(&mut self, at: usize, node: u32) {
        self.push_node(at, node);
    }
    /// [`Self::node`] for a binary walk, at `at < BINARY_CAPACITY`.
    #[inline(always)]
    fn binary_node(&self, at: usize) -> u32 {
        self.node(at)
    }
    /// The nearest waiting node that can still hold a hit closer than `t`, or [`NO_NODE`].
    #[inline(always)]
    fn pop_closer(&self, sp: &mut usize, t: f32) -> u32 {
        if pop_until(sp, |at| self.t(at) < t) {
            self.node(*sp)
        } else {
            NO_NODE
        }
    }
}

/// The distance a walk's stack keeps for an entry at `t`: its top 16 bits (see
/// [`PackedDistances`]).
#[inline(always)]
pub(crate) fn kept_distance(t: f32) -> f32 {
    f32::from_bits(t.to_bits() & 0xffff_0000)
}

/// Entry distances kept as their top 16 bits, two to a word: truncating a distance (never
/// negative, see [`crate::aabb::intersect_aabb`]) rounds it down, so a popped entry is still
/// taken wherever it could hold a closer hit, and the distances take a third of a stack's
/// registers rather than half of them.
#[derive(Copy, Clone)]
struct PackedDistances<const HALF: usize>([u32; HALF]);

impl<const HALF: usize> PackedDistances<HALF> {
    /// The word and shift of slot `at`'s distance.
    #[inline(always)]
    fn slot(at: usize) -> (usize, u32) {
        (at >> 1, 16 * (at as u32 & 1))
    }

    #[inline(always)]
    fn set(&mut self, at: usize, t: f32) {
        let (word, shift) = Self::slot(at);
        self.0[word] = (self.0[word] & !(0xffff << shift)) | (t.to_bits() >> 16) << shift;
    }

    #[inline(always)]
    fn get(&self, at: usize) -> f32 {
        let (word, shift) = Self::slot(at);
        f32::from_bits(((self.0[word] >> shift) & 0xffff) << 16)
    }
}

/// A ray's stack in private memory: `N` entries, their distances in `HALF = N / 2` words
/// (see [`PackedDistances`]).
pub struct LocalStack<const N: usize, const HALF: usize> {
    nodes: [u32; N],
    t: PackedDistances<HALF>,
}

/// The stack of the baseline's walk.
pub type BaselineStack = LocalStack<MAX_BVH_DEPTH, { MAX_BVH_DEPTH / 2 }>;

impl<const N: usize, const HALF: usize> Default for LocalStack<N, HALF> {
    #[inline(always)]
    fn default() -> Self {
        LocalStack {
            nodes: [0u32; N],
            t: PackedDistances([0u32; HALF]),
        }
    }
}

impl<const N: usize, const HALF: usize> WalkStack for LocalStack<N, HALF> {
    const CAPACITY: usize = {
        assert!(2 * HALF == N, "a distance word holds two entries");
        N
    };
    #[inline(always)]
    fn push(&mut self, at: usize, node: u32, t: f32) {
        self.nodes[at] = node;
        self.t.set(at, t);
    }
    #[inline(always)]
    fn push_node(&mut self, at: usize, node: u32) {
        self.nodes[at] = node;
    }
    #[inline(always)]
    fn node(&self, at: usize) -> u32 {
        self.nodes[at]
    }
    #[inline(always)]
    fn t(&self, at: usize) -> f32 {
        self.t.get(at)
    }
}

/// Entries of [`TopStack`] past [`BINARY_TOP_STACK`].
const WIDE_ONLY_ENTRIES: usize = TOP_STACK - BINARY_TOP_STACK;

/// The stack of the grids' top-level walk: [`TOP_STACK`] entries, the first
/// [`BINARY_TOP_STACK`] in one array and the rest, which only the wide walk reaches, in
/// another, so that a kernel walking binary top levels alone keeps registers for the first.
pub struct TopStack {
    nodes: [u32; BINARY_TOP_STACK],
    wide_only: [u32; WIDE_ONLY_ENTRIES],
    t: PackedDistances<{ TOP_STACK / 2 }>,
}

impl Default for TopStack {
    #[inline(always)]
    fn default() -> Self {
        TopStack {
            nodes: [0u32; BINARY_TOP_STACK],
            wide_only: [0u32; WIDE_ONLY_ENTRIES],
            t: PackedDistances([0u32; TOP_STACK / 2]),
        }
    }
}

impl WalkStack for TopStack {
    const CAPACITY: usize = TOP_STACK;
    const BINARY_CAPACITY: usize = BINARY_TOP_STACK;
    #[inline(always)]
    fn push(&mut self, at: usize, node: u32, t: f32) {
        self.push_node(at, node);
        self.t.set(at, t);
    }
    #[inline(always)]
    fn push_node(&mut self, at: usize, node: u32) {
        if at < BINARY_TOP_STACK {
            self.nodes[at] = node;
        } else {
            self.wide_only[at - BINARY_TOP_STACK] = node;
        }
    }
    #[inline(always)]
    fn node(&self, at: usize) -> u32 {
        if at < BINARY_TOP_STACK {
            self.nodes[at]
        } else {
            self.wide_only[at - BINARY_TOP_STACK]
        }
    }
    #[inline(always)]
    fn t(&self, at: usize) -> f32 {
        self.t.get(at)
    }
    #[inline(always)]
    fn push_binary(&mut self, at: usize, node: u32) {
        self.nodes[at] = node;
    }
    #[inline(always)]
    fn binary_node(&self, at: usize) -> u32 {
        self.nodes[at]
    }
}

/// Vertex `index` of a flat xyz array.
#[inline]
pub fn load_vec3<F: Buffer<f32>>(data: F, index: u32) -> Vec3 {
    Vec3::from(data.load3(3 * index))
}

/// The `f32` triple stored as bits at `words[word ..]`.
#[inline]
pub(crate) fn load_vec3_bits<W: Buffer<u32>>(words: W, word: u32) -> Vec3 {
    let [x, y, z] = words.load3(word);
    Vec3::new(f32::from_bits(x), f32::from_bits(y), f32::from_bits(z))
}

/// Takes a closer hit `found` (`t` and barycentrics) on primitive `prim`; the normal is
/// found once, after the traversal.
#[inline]
pub(crate) fn record_hit(hit: &mut Hit, found: (f32, f32, f32), prim: u32) {
    hit.t = found.0;
    hit.u = found.1;
    hit.v = found.2;
    hit.prim = prim;
}

/// The baseline: an indexed triangle list (`positions` xyz per vertex, `indices` three per
/// triangle) whose triangles the BVH leaves name by index; plain slices, or split buffers
/// (see [`crate::buffer`]).
pub struct TriangleMesh<F, I> {
    pub positions: F,
    pub indices: I,
}

impl<'a> TriangleMesh<Split<'a, f32>, Split<'a, u32>> {
    /// The triangle list of a split scene (its BVH is `Split::new(chunks, split, TRIANGLE_NODES)`).
    #[inline(always)]
    pub fn split(chunks: &Chunks<'a>, split: &SplitParams) -> Self {
        TriangleMesh {
            positions: Split::new(chunks, split, TRIANGLE_POSITIONS),
            indices: Split::new(chunks, split, TRIANGLE_INDICES),
        }
    }
}

impl<F: Buffer<f32>, I: Buffer<u32>> TriangleMesh<F, I> {
    /// The three corners of triangle `tri`. (Always inlined: as a call it costs the baseline's
    /// CPU traversal 2% more instructions.)
    #[inline(always)]
    pub fn corners(&self, tri: u32) -> [Vec3; 3] {
        let [a, b, c] = self.indices.load3(3 * tri);
        [
            load_vec3(self.positions, a),
            load_vec3(self.positions, b),
            load_vec3(self.positions, c),
        ]
    }
}

impl<F: Buffer<f32>, I: Buffer<u32>> LeafPrimitives for TriangleMesh<F, I> {
    type Stack = BaselineStack;
    type Scratch = ();

    fn scratch(&self, _ray: &Ray) {}

    fn intersect_leaf<T: Tally>(&self, first: u32, count: u32, ray: &Ray, hit: &mut Hit, _: &mut (), tally: &mut T) {
        tally.triangles(count);
        // The closest hit in plain locals, as in the grids' leaves.
        let mut closest = (hit.t, 0.0, 0.0);
        let mut closest_tri = 0;
        let mut tri = first;
        // Tested at the bottom (see `traverse_bvh`); the builder makes no empty leaves.
        loop {
            let [v0, v1, v2] = self.corners(tri);
            if let Some(found) = intersect_triangle(v0, v1, v2, ray, closest.0) {
                closest = found;
                closest_tri = tri;
            }
            tri += 1;
            if tri >= first + count {
                break;
            }
        }
        if closest.0 < hit.t {
            record_hit(hit, closest, closest_tri);
        }
    }

    #[inline]
    fn triangle(&self, prim: u32, _level: u32) -> [Vec3; 3] {
        self.corners(prim)
    }
}

/// Closest hit in a triangle mesh.
pub fn trace_triangles<N: Hierarchy, F: Buffer<f32>, I: Buffer<u32>>(
    nodes: N,
    mesh: &TriangleMesh<F, I>,
    ray: &Ray,
    t_max: f32,
) -> Hit {
    trace(nodes, mesh, ray, t_max)
}
