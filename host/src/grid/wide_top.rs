//! Packing the grids' top-level BVH into wide nodes (see `gridrt_shared::wide_nodes` for the
//! layout and the walk).
//!
//! Collapse: sibling leaves of few grids first become one leaf; then the wide nodes of least
//! expected walk cost that hold the binary hierarchy, each node's children a cut of its binary
//! subtree (found by dynamic programming, see [`Plan`]), at the widest width whose walk keeps
//! within its stack. Nodes are numbered breadth first, so each node's inner children are
//! consecutive, and the grids are reordered so that each node's leaf children name
//! consecutive grids.
//!
//! Encoding: each node's frame origin is rounded down to the scene's code lattice, its step per
//! axis is the smallest power of two that reaches the node's far corner in 255 codes, and each
//! child's codes are rounded outwards; every decoded box is then checked, with the decoder the
//! traversal runs, to hold its child. A hierarchy that fails anywhere (a code, the stack bound
//! at every width, the grid count) is left binary: wide packing is a saving, never a change of
//! what the traversal finds.

use gridrt_shared::glam::Vec3;
use gridrt_shared::layout::BvhNode;
use gridrt_shared::wide_nodes::{
    child_box, child_kind, code_slot, load_node, node_frame, scene_frame, step_of, Frame, NodeWords, CODE_MAX, INNER,
    MAX_EXPONENT, MAX_GRIDS, MAX_LEAF_GRIDS, MIN_EXPONENT, ORIGIN_CODE_MAX, STACK_ENTRIES, WIDE, WIDTH,
};

use crate::bvh::{Aabb, Bvh};

/// A wide hierarchy and the grid order it needs: `order[slot]` is the position in the
/// binary hierarchy's primitive order of the grid stored at `slot`.
pub struct WideTop {
    pub nodes: Vec<BvhNode>,
    pub order: Vec<u32>,
}

/// `bvh` (binary, root first) packed wide, or `None` where it must stay binary.
pub fn pack(bvh: &Bvh) -> Option<WideTop> {
    pack_within(bvh, STACK_ENTRIES)
}

/// [`pack`] for a walk whose stack holds `capacity` entries (at most [`STACK_ENTRIES`]).
fn pack_within(bvh: &Bvh, capacity: usize) -> Option<WideTop> {
    let binary = &bvh.nodes;
    let root = binary.first()?;
    if bvh.order.len() as u64 >= MAX_GRIDS as u64 {
        return None;
    }
    let merged = merge_sibling_leaves(binary);
    let binary = merged.as_slice();
    // Each wide level leaves up to its width less one entries waiting, so the collapse
    // narrows the nodes of a deep hierarchy where the stack needs it (narrower nodes are still
    // far fewer bytes than binary ones); a hierarchy too deep for even binary nodes within the
    // stack stays binary.
    let groups = collapse(binary, WIDTH as usize, capacity);
    let first_inner = first_inner_children(&groups, binary);
    if stack_need(&groups, binary, &first_inner) > capacity {
        return None;
    }
    let scene = scene_frame_of(&aabb(root))?;
    let mut nodes = vec![BvhNode {
        min: scene.origin.to_array(),
        first: groups.len() as u32,
        max: scene.step.to_array(),
        count: WIDE,
    }];
    let mut order = Vec::with_capacity(bvh.order.len());
    for (children, &first_node) in groups.iter().zip(&first_inner) {
        let first_grid = order.len() as u32;
        for &c in children {
            let n = &binary[c as usize];
            if n.is_leaf() {
                order.extend(n.first..n.first + n.count);
            }
        }
        let words = encode(binary, children, &scene, [first_node, first_grid])?;
        nodes.extend(elements(&words));
    }
    let wide = WideTop { nodes, order };
    holds_every_child(&wide.nodes, &groups, binary).then_some(wide)
}

/// Most grids of the leaves [`merge_sibling_leaves`] makes.
pub const MERGED_LEAF_GRIDS: u32 = 4;

/// `binary` with every inner node whose two children are leaves of [`MERGED_LEAF_GRIDS`]
/// grids or fewer in all made a leaf of them (their grids are consecutive). Why: a slot of a
/// wide node then holds them all, so fewer nodes hold the grids, for more grids tested where
/// a ray enters the pair's box; the SAH alone keeps such pairs apart, having no cost for
/// bytes. The merged children stay in the buffer, unreachable.
fn merge_sibling_leaves(binary: &[BvhNode]) -> Vec<BvhNode> {
    let mut merged = binary.to_vec();
    // Children come after their parent (depth-first order), so backwards is bottom-up.
    for n in (0..merged.len()).rev() {
        let node = merged[n];
        if node.is_leaf() {
            continue;
        }
        let (l, r) = (merged[node.first as usize], merged[node.first as usize + 1]);
        if l.is_leaf() && r.is_leaf() && l.count + r.count <= MERGED_LEAF_GRIDS && l.first + l.count == r.first {
            merged[n].first = l.first;
            merged[n].count = l.count + r.count;
        }
    }
    merged
}

/// The wide nodes of at most `width` children as lists of binary nodes (their children),
/// breadth first from the root, each as wide as the walk's stack of `capacity` entries leaves
/// room for (see [`Plan::children_within`]).
fn collapse(binary: &[BvhNode], width: usize, capacity: usize) -> Vec<Vec<u32>> {
    let plan = Plan::new(binary, width);
    let needs = Needs::of(binary, &plan);
    let mut groups = vec![];
    let mut queue = std::collections::VecDeque::from([(0u32, 0usize)]);
    while let Some((n, waiting)) = queue.pop_front() {
        let children = match binary[n as usize].is_leaf() {
            true => vec![n],
            false => plan.children_within(binary, n, waiting, &needs, capacity),
        };
        let after = waiting + children.len() - 1;
        queue.extend(
            (children.iter())
                .filter(|&&c| !binary[c as usize].is_leaf())
                .map(|&c| (c, after)),
        );
        groups.push(children);
    }
    groups
}

/// For each binary node, the stack entries its subtree's walk needs (none waiting above it)
/// when collapsed as planned, and when kept binary (two children a node: the floor a collapse
/// can always fall back to).
struct Needs {
    planned: Vec<usize>,
    binary: Vec<usize>,
}

impl Needs {
    fn of(binary: &[BvhNode], plan: &Plan) -> Needs {
        let (mut planned, mut kept) = (vec![0; binary.len()], vec![0; binary.len()]);
        let mut children = vec![];
        // Children come after their parent (depth-first order), so backwards is bottom-up.
        for n in (0..binary.len()).rev() {
            let node = &binary[n];
            if node.is_leaf() {
                continue;
            }
            let (l, r) = (node.first as usize, node.first as usize + 1);
            kept[n] = 2.max(1 + kept[l].max(kept[r]));
            children.clear();
            let k = plan.choice[n][1] as usize;
            plan.fill(binary, n as u32, k, &mut children);
            planned[n] = (children.iter()).fold(k, |most, &c| most.max(k - 1 + planned[c as usize]));
        }
        Needs { planned, binary: kept }
    }
}

/// Slots a subtree can fill in its wide parent: 1 (itself) to [`WIDTH`].
const SLOTS: usize = WIDTH as usize + 1;

/// What the walk spends, in child box tests: on opening a wide node (loading and decoding it,
/// putting its entered children on the stack), and on each grid of a leaf it enters (its ids,
/// base triangle and shell test, and for the share of grids that pass, their
/// whole visit).
const NODE_COST: f64 = 2.0;
const GRID_COST: f64 = 16.0;

/// The collapse of least expected walk cost, by dynamic programming over the binary nodes
/// (after Ylitie, Karras and Laine's): a ray enters each box with odds in proportion to its
/// surface area, so each node and each number of slots `k` it may fill in its wide parent gets
/// the least cost of its subtree weighted by area (`k = 1`: it is a leaf, or a wide node of
/// its own whose children's boxes the walk tests; `k > 1`: it is opened into `k` slots, shared
/// out between its two children).
struct Plan {
    /// For `k > 1`, the slots given to the left child; for `k = 1`, the slots of its own node.
    choice: Vec<[u8; SLOTS]>,
    /// The least cost, per node and slots (infinite where a subtree has fewer leaves than
    /// slots).
    cost: Vec<[f64; SLOTS]>,
}

impl Plan {
    /// The plan for nodes of at most `width` children (`2 ..= WIDTH`).
    fn new(binary: &[BvhNode], width: usize) -> Plan {
        let mut cost = vec![[f64::INFINITY; SLOTS]; binary.len()];
        let mut choice = vec![[0u8; SLOTS]; binary.len()];
        // Children come after their parent (depth-first order), so backwards is bottom-up.
        for n in (0..binary.len()).rev() {
            let node = &binary[n];
            let area = aabb(node).area() as f64;
            if node.is_leaf() {
                cost[n][1] = area * GRID_COST * node.count as f64;
                continue;
            }
            let (l, r) = (node.first as usize, node.first as usize + 1);
            for k in 2..=width {
                for left in 1..k {
                    let c = cost[l][left] + cost[r][k - left];
                    if c < cost[n][k] {
                        cost[n][k] = c;
                        choice[n][k] = left as u8;
                    }
                }
            }
            // Of equal costs, the widest: fewer levels to walk.
            for k in (2..=width).rev() {
                let own = area * (NODE_COST + k as f64) + cost[n][k];
                if own < cost[n][1] {
                    cost[n][1] = own;
                    choice[n][1] = k as u8;
                }
            }
        }
        Plan { choice, cost }
    }

    /// The children of inner node `n`'s wide node, `waiting` entries already on the stack
    /// when it is opened: the widest the plan allows whose children's subtrees, collapsed as
    /// planned, then keep within the stack; failing that, the widest whose children's subtrees
    /// keep within it walked binary. Binary children (`k = 2`) always pass the second test
    /// when the parent's choice did, so a hierarchy whose binary walk keeps within `capacity`
    /// collapses within it, narrowing its nodes near the root first, where there are fewest.
    fn children_within(&self, binary: &[BvhNode], n: u32, waiting: usize, needs: &Needs, capacity: usize) -> Vec<u32> {
        let preferred = self.choice[n as usize][1] as usize;
        let mut children = vec![];
        for need in [&needs.planned, &needs.binary] {
            for k in (2..=preferred).rev() {
                if !self.cost[n as usize][k].is_finite() {
                    continue;
                }
                children.clear();
                self.fill(binary, n, k, &mut children);
                let fits = |c: &u32| waiting + k - 1 + need[*c as usize] <= capacity;
                if waiting + k <= capacity && children.iter().all(fits) {
                    return children;
                }
            }
        }
        children
    }

    /// `n` opened into `k` slots (itself when `k` is 1), appended to `children`.
    fn fill(&self, binary: &[BvhNode], n: u32, k: usize, children: &mut Vec<u32>) {
        if k == 1 {
            children.push(n);
            return;
        }
        let left = self.choice[n as usize][k] as usize;
        let first = binary[n as usize].first;
        self.fill(binary, first, left, children);
        self.fill(binary, first + 1, k - left, children);
    }
}

fn aabb(n: &BvhNode) -> Aabb {
    Aabb {
        min: Vec3::from(n.min),
        max: Vec3::from(n.max),
    }
}

/// The scene's frame: a power-of-two step that spans the box in [`ORIGIN_CODE_MAX`] codes,
/// its origin a step below the box.
fn scene_frame_of(b: &Aabb) -> Option<Frame> {
    let extent = b.max - b.min;
    let step = Vec3::from_array(std::array::from_fn(|a| {
        step_of(exponent_for(extent[a] as f64 / (ORIGIN_CODE_MAX - 2) as f64))
    }));
    let origin = b.min - step;
    (origin.is_finite() && step.is_finite() && (b.max - origin).cmplt(step * ORIGIN_CODE_MAX as f32).all())
        .then_some(Frame { origin, step })
}

/// The biased exponent of the smallest power of two at least `span` (clamped to the usable
/// range).
fn exponent_for(span: f64) -> u32 {
    // Clamped first: an infinite span (a box of overflowing extent) must not overflow the sum.
    let e = if span > 0.0 {
        span.log2().ceil().clamp(-1000.0, 1000.0) as i64
    } else {
        -1000
    };
    (e + 127).clamp(MIN_EXPONENT as i64, MAX_EXPONENT as i64) as u32
}

/// A node's sixteen words: frame, child boxes, kinds and links.
fn encode(
    binary: &[BvhNode],
    children: &[u32],
    scene: &Frame,
    [first_node, first_grid]: [u32; 2],
) -> Option<NodeWords> {
    let boxes: Vec<Aabb> = children.iter().map(|&c| aabb(&binary[c as usize])).collect();
    let bounds = boxes.iter().fold(boxes[0], |b, &c| b.union(c));
    let origin_codes: [u32; 3] =
        std::array::from_fn(|a| lower_code(bounds.min[a], scene.origin[a], scene.step[a], ORIGIN_CODE_MAX));
    let mut w: NodeWords = [0; 16];
    w[15] = origin_codes[0] | origin_codes[1] << 16;
    w[13] = origin_codes[2] << 16;
    let origin = node_frame(&w, scene).origin;
    if (0..3).any(|a| origin[a] > bounds.min[a]) {
        return None;
    }
    let mut exponents = [0u32; 3];
    let mut codes = vec![[0u32; 6]; children.len()];
    for a in 0..3 {
        let mut e = exponent_for((bounds.max[a] as f64 - origin[a] as f64) / CODE_MAX as f64);
        loop {
            let step = step_of(e);
            let fit: Option<Vec<[u32; 2]>> = boxes
                .iter()
                .map(|b| {
                    let lo = lower_code(b.min[a], origin[a], step, CODE_MAX);
                    let hi = upper_code(b.max[a], origin[a], step)?;
                    Some([lo, hi])
                })
                .collect();
            if let Some(fit) = fit {
                for (c, [lo, hi]) in codes.iter_mut().zip(fit) {
                    c[a] = lo;
                    c[3 + a] = CODE_MAX - hi;
                }
                break;
            }
            if e >= MAX_EXPONENT {
                return None;
            }
            e += 1;
        }
        exponents[a] = e;
    }
    for (k, c) in codes.iter().enumerate() {
        for (f, &stored) in c.iter().enumerate() {
            let (word, shift) = code_slot((6 * k + f) as u32);
            // A top byte of 0x7f or 0xff would let its float-field word read as a NaN; one code
            // down moves a lower bound down, or an upper one (counted down) up: both outwards.
            let stored = if shift == 24 && stored & 0x7f == 0x7f {
                stored - 1
            } else {
                stored
            };
            w[word] |= stored << shift;
        }
    }
    let kinds = children.iter().enumerate().map(|(k, &c)| {
        let n = &binary[c as usize];
        let kind = if n.is_leaf() { n.count } else { INNER };
        kind << (3 * k)
    });
    if children.iter().any(|&c| binary[c as usize].count > MAX_LEAF_GRIDS) {
        return None;
    }
    w[3] = first_node;
    w[7] = first_grid;
    w[11] = kinds.fold(0, |m, k| m | k) | exponents[2] << 24;
    w[14] = exponents[0] | exponents[1] << 8;
    Some(w)
}

/// The largest code at most `max` whose point `origin + code * step` is at most `x`.
fn lower_code(x: f32, origin: f32, step: f32, max: u32) -> u32 {
    let mut code = (((x as f64 - origin as f64) / step as f64).floor().max(0.0) as u64).min(max as u64) as u32;
    while code > 0 && origin + step * code as f32 > x {
        code -= 1;
    }
    code
}

/// The smallest code whose point is at least `x`, or `None` past [`CODE_MAX`].
fn upper_code(x: f32, origin: f32, step: f32) -> Option<u32> {
    let mut code = ((x as f64 - origin as f64) / step as f64).ceil().max(0.0) as u64;
    while code <= CODE_MAX as u64 && origin + step * (code as f32) < x {
        code += 1;
    }
    (code <= CODE_MAX as u64).then_some(code as u32)
}

/// A node's words as the two buffer elements it fills.
fn elements(w: &NodeWords) -> [BvhNode; 2] {
    let f = |i: usize| f32::from_bits(w[i]);
    let element = |o: usize| BvhNode {
        min: [f(o), f(o + 1), f(o + 2)],
        first: w[o + 3],
        max: [f(o + 4), f(o + 5), f(o + 6)],
        count: w[o + 7],
    };
    [element(0), element(8)]
}

/// The most entries the walk's stack holds at once: at a node, the entries its ancestors left
/// waiting plus its own children.
fn stack_need(groups: &[Vec<u32>], binary: &[BvhNode], first_inner: &[u32]) -> usize {
    let mut most = 0;
    let mut todo = vec![(0usize, 0usize)];
    while let Some((k, waiting)) = todo.pop() {
        let children = &groups[k];
        most = most.max(waiting + children.len());
        let first = first_inner[k] as usize;
        for i in first..first + inner_count(binary, children) as usize {
            todo.push((i, waiting + children.len() - 1));
        }
    }
    most
}

/// How many of `children` are inner nodes.
fn inner_count(binary: &[BvhNode], children: &[u32]) -> u32 {
    children.iter().filter(|&&c| !binary[c as usize].is_leaf()).count() as u32
}

/// Each wide node's first inner child: nodes are numbered in the order [`collapse`] lists
/// them (breadth first), the root 0, so each node's inner children are consecutive.
fn first_inner_children(groups: &[Vec<u32>], binary: &[BvhNode]) -> Vec<u32> {
    let mut next = 1;
    groups
        .iter()
        .map(|children| {
            let first = next;
            next += inner_count(binary, children);
            first
        })
        .collect()
}

/// Whether every decoded child box holds its binary node's box, every float-field word reads
/// as a finite float, and the links name what the collapse made.
fn holds_every_child(nodes: &[BvhNode], groups: &[Vec<u32>], binary: &[BvhNode]) -> bool {
    let scene = scene_frame(&nodes[0]);
    groups.iter().enumerate().all(|(k, children)| {
        let w = load_node(nodes, k as u32);
        let frame = node_frame(&w, &scene);
        let finite = (0..16).filter(|i| i % 4 != 3).all(|i| f32::from_bits(w[i]).is_finite());
        finite
            && children.iter().enumerate().all(|(i, &c)| {
                let n = &binary[c as usize];
                let (lo, hi) = child_box(&w, i as u32, &frame);
                let kind = child_kind(&w, i as u32);
                let kind_ok = if n.is_leaf() { kind == n.count } else { kind == INNER };
                kind_ok && lo.cmple(Vec3::from(n.min)).all() && hi.cmpge(Vec3::from(n.max)).all()
            })
            && (children.len() as u32 >= WIDTH || child_kind(&w, children.len() as u32) == 0)
    })
}

/// The box around everything a wide hierarchy holds: its root's decoded child boxes.
pub fn bounds(nodes: &[BvhNode]) -> Aabb {
    let scene = scene_frame(&nodes[0]);
    let w = load_node(nodes, 0);
    let frame = node_frame(&w, &scene);
    (0..WIDTH)
        .take_while(|&k| child_kind(&w, k) != 0)
        .map(|k| {
            let (min, max) = child_box(&w, k, &frame);
            Aabb { min, max }
        })
        .reduce(Aabb::union)
        .unwrap_or(Aabb {
            min: frame.origin,
            max: frame.origin,
        })
}

/// The most grids any leaf child holds.
pub fn leaf_size(nodes: &[BvhNode]) -> u32 {
    (0..nodes[0].first)
        .flat_map(|k| {
            let w = load_node(nodes, k);
            (0..WIDTH).map(move |i| child_kind(&w, i))
        })
        .filter(|&kind| kind != INNER)
        .max()
        .unwrap_or(1)
        .max(1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::build;
    use crate::grid::top_level_params;
    use gridrt_shared::cost::{Tally, Uncounted};
    use gridrt_shared::layout::Hit;
    use gridrt_shared::ray::Ray;
    use gridrt_shared::top_nodes::TopNodes;
    use gridrt_shared::traverse::{Hierarchy, LeafPrimitives};

    /// Boxes as primitives: a hit is the entry into the box, named by its original index.
    struct Boxes {
        boxes: Vec<Aabb>,
        original: Vec<u32>,
    }

    impl LeafPrimitives for Boxes {
        type Stack = gridrt_shared::traverse::TopStack;
        type Scratch = ();
        fn scratch(&self, _ray: &Ray) {}
        fn intersect_leaf<T: Tally>(&self, first: u32, count: u32, ray: &Ray, hit: &mut Hit, _: &mut (), _: &mut T) {
            for i in first..first + count {
                let b = &self.boxes[i as usize];
                let t = gridrt_shared::aabb::intersect_aabb(b.min, b.max, ray, hit.t);
                if t < hit.t {
                    hit.t = t;
                    hit.prim = self.original[i as usize];
                }
            }
        }
        fn triangle(&self, _prim: u32, _level: u32) -> [Vec3; 3] {
            [Vec3::ZERO; 3]
        }
    }

    /// Boxes of many sizes far from the origin, some flat.
    fn scattered_boxes(n: usize) -> Vec<Aabb> {
        let mut seed = 12345u32;
        let mut next = move || {
            seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
            (seed >> 8) as f32 / (1 << 24) as f32
        };
        (0..n)
            .map(|i| {
                let at = Vec3::new(1000.0 + 40.0 * next(), -5.0 + 10.0 * next(), 3.0 * next());
                let size = Vec3::new(next(), next(), next()) * if i % 3 == 0 { 0.01 } else { 1.0 };
                let size = if i % 7 == 0 {
                    size * Vec3::new(1.0, 0.0, 1.0)
                } else {
                    size
                };
                Aabb {
                    min: at,
                    max: at + size,
                }
            })
            .collect()
    }

    fn in_order(boxes: &[Aabb], order: &[u32]) -> Boxes {
        Boxes {
            boxes: order.iter().map(|&i| boxes[i as usize]).collect(),
            original: order.to_vec(),
        }
    }

    /// Checks that the wide walk of `wide` finds the binary walk's closest box for 2,000 rays
    /// (`ray(i)`), and gives how many hit.
    fn same_hits(boxes: &[Aabb], bvh: &Bvh, wide: &WideTop, ray: impl Fn(u32) -> Ray) -> u32 {
        let binary = in_order(boxes, &bvh.order);
        let order: Vec<u32> = wide.order.iter().map(|&k| bvh.order[k as usize]).collect();
        let grids = in_order(boxes, &order);
        let top = TopNodes::new(wide.nodes.as_slice());
        assert!(top.is_wide());
        let mut hits = 0;
        for i in 0..2000 {
            let ray = ray(i);
            let mut want = Hit::miss(1e30);
            bvh.nodes.as_slice().search(&binary, &ray, &mut want, &mut Uncounted);
            let mut got = Hit::miss(1e30);
            top.search(&grids, &ray, &mut got, &mut Uncounted);
            assert_eq!((got.t, got.prim), (want.t, want.prim), "ray {i}");
            hits += want.is_hit() as u32;
        }
        hits
    }

    /// The wide walk finds the binary walk's closest box for every ray, and each grid is named
    /// by exactly one leaf.
    #[test]
    fn wide_walk_finds_what_the_binary_walk_finds() {
        let boxes = scattered_boxes(3000);
        let bvh = build(&boxes, &top_level_params());
        let wide = pack(&bvh).expect("packs wide");
        let mut seen = wide.order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..boxes.len() as u32).collect::<Vec<_>>());
        assert!(wide.nodes.len() * 2 < bvh.nodes.len(), "{} elements", wide.nodes.len());
        let hits = same_hits(&boxes, &bvh, &wide, |i| {
            let a = i as f32 * 0.618;
            let origin = Vec3::new(1020.0 + 60.0 * a.cos(), 30.0 * (1.3 * a).sin(), -20.0);
            let target = Vec3::new(1000.0 + (i % 41) as f32, -5.0 + (i % 11) as f32, 1.5);
            Ray::new(origin, target - origin)
        });
        assert!(hits > 1000, "{hits} hits");
        assert!(bounds(&wide.nodes).contains(&aabb(&bvh.nodes[0])));
    }

    /// Spans past the float range, none and NaN give exponents in range, without overflow.
    #[test]
    fn exponents_stay_in_range() {
        assert_eq!(exponent_for(f64::INFINITY), MAX_EXPONENT);
        assert_eq!(exponent_for(1e300), MAX_EXPONENT);
        assert_eq!(exponent_for(0.0), MIN_EXPONENT);
        assert_eq!(exponent_for(f64::NAN), MIN_EXPONENT);
        assert_eq!(exponent_for(1.0), 127);
        assert_eq!(exponent_for(3.0), 129);
    }

    /// A chain of `leaves` leaves: every inner node one leaf and one node.
    fn chain(leaves: u32) -> Bvh {
        let mut nodes = vec![];
        for i in 0..leaves {
            let lo = [i as f32; 3];
            let whole = [leaves as f32; 3];
            let inner = i + 1 < leaves;
            let at = nodes.len() as u32;
            nodes.push(BvhNode {
                min: lo,
                first: if inner { at + 1 } else { i },
                max: whole,
                count: if inner { 0 } else { 1 },
            });
            if inner {
                nodes.push(BvhNode {
                    min: lo,
                    first: i,
                    max: [i as f32 + 1.0; 3],
                    count: 1,
                });
            }
        }
        // Node `at`'s children: the leaf at `at + 1` and the next node at `at + 2`.
        Bvh {
            nodes,
            order: (0..leaves).collect(),
        }
    }

    /// A hierarchy too deep for the walk's stack at any width stays binary.
    #[test]
    fn a_hierarchy_too_deep_for_the_stack_stays_binary() {
        assert!(pack(&chain(100)).is_none());
    }

    /// One too deep for the widest nodes (small boxes all over a sphere, as the grids of a
    /// large scan lie) takes narrower ones, within the stack, and the walk still finds what
    /// the binary walk finds. A stack of fewer entries than the walk's stands in for a larger
    /// scan: the least-cost collapse of this one keeps within the walk's own.
    #[test]
    fn a_deep_hierarchy_takes_narrower_nodes() {
        let n = 40_000;
        let boxes: Vec<Aabb> = (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
                let (r, a) = ((1.0 - z * z).sqrt(), i as f32 * 2.399_963);
                let c = Vec3::new(r * a.cos(), r * a.sin(), z);
                Aabb {
                    min: c - Vec3::splat(0.01),
                    max: c + Vec3::splat(0.01),
                }
            })
            .collect();
        let bvh = build(&boxes, &top_level_params());
        let merged = merge_sibling_leaves(&bvh.nodes);
        let widest = collapse(&merged, WIDTH as usize, usize::MAX);
        let need = stack_need(&widest, &merged, &first_inner_children(&widest, &merged));
        let capacity = 24;
        assert!(need > capacity, "{need}");
        let wide = pack_within(&bvh, capacity).expect("packs narrower");
        assert!(wide.nodes.len() * 2 < bvh.nodes.len(), "{} elements", wide.nodes.len());
        let hits = same_hits(&boxes, &bvh, &wide, |i| {
            let a = i as f32 * 0.618;
            let origin = Vec3::new(3.0 * a.cos(), 3.0 * (1.3 * a).sin(), 2.0 * (0.7 * a).cos());
            Ray::new(origin, -origin + Vec3::new(0.1 * a.sin(), 0.0, 0.05))
        });
        assert!(hits > 1000, "{hits} hits");
    }
}
