//! The build itself: binning, split search, parallel subtrees in fixed slots, compaction.

use gridrt_shared::glam::{BVec3A, Vec3A};
use gridrt_shared::layout::BvhNode;
use rayon::prelude::*;

use super::{Aabb, BuildParams, Bvh};

const BINS: usize = 16;
/// Subtrees at least this large go to another rayon task; below it the task costs more than it saves.
const PARALLEL_SUBTREE: usize = 256;
/// Nodes of at least two chunks bin and bound their primitives chunk by chunk in parallel, so the first levels,
/// before there are subtrees enough for every thread, do not run on one.
pub(super) const CHUNK: usize = 1 << 15;
/// Nodes up to this size (most of those that look for a split) sort their primitives by bin instead of clearing
/// and sweeping every bin. At most `BINS`, which sizes the sweep's arrays.
const SMALL: usize = 8;
const _: () = assert!(SMALL <= BINS);

/// The builder's box, in SIMD lanes.
#[derive(Copy, Clone)]
struct Bounds {
    min: Vec3A,
    max: Vec3A,
}

impl Bounds {
    const EMPTY: Bounds = Bounds::new(Vec3A::INFINITY, Vec3A::NEG_INFINITY);

    const fn new(min: Vec3A, max: Vec3A) -> Bounds {
        Bounds { min, max }
    }

    #[inline]
    fn union(self, o: Bounds) -> Bounds {
        Bounds::new(self.min.min(o.min), self.max.max(o.max))
    }

    #[inline]
    fn grow(self, p: Vec3A) -> Bounds {
        Bounds::new(self.min.min(p), self.max.max(p))
    }

    /// `grow` in the lanes of `m`: a select, where a branch would be mispredicted.
    #[inline]
    fn grow_where(self, m: BVec3A, p: Vec3A) -> Bounds {
        Bounds::new(
            Vec3A::select(m, self.min.min(p), self.min),
            Vec3A::select(m, self.max.max(p), self.max),
        )
    }

    /// Twice the centroid: binning only compares centroids, so the halving is left out.
    #[inline]
    fn centroid2(&self) -> Vec3A {
        self.min + self.max
    }

    /// Half the surface area (the SAH only uses ratios); zero for an empty box.
    #[inline]
    fn half_area(&self) -> f32 {
        let d = (self.max - self.min).max(Vec3A::ZERO);
        d.x * d.y + d.y * d.z + d.z * d.x
    }

    fn to_node(self, first: u32, count: u32) -> BvhNode {
        let (min, max) = (self.min.to_array(), self.max.to_array());
        BvhNode { min, first, max, count }
    }
}

/// Maps (doubled) centroids to bins. The partition goes through the same arithmetic, so every primitive lands on
/// the side its bin was counted on, and the children's boxes and counts can be taken from the bins.
struct Binning {
    origin: Vec3A,
    scale: Vec3A,
}

impl Binning {
    fn new(centroids: &Bounds) -> Binning {
        let extent = centroids.max - centroids.min;
        let scale = Vec3A::select(extent.cmpgt(Vec3A::ZERO), BINS as f32 / extent, Vec3A::ZERO);
        Binning {
            origin: centroids.min,
            scale,
        }
    }

    /// The bins on the three axes. Clamping in float (which also sends NaN to bin 0) spares the conversions their
    /// saturation checks, and the mask (a no-op) spares the bin arrays their bounds checks.
    #[inline]
    fn bins(&self, c: Vec3A) -> [usize; 3] {
        let rel = ((c - self.origin) * self.scale).max(Vec3A::ZERO);
        let rel = rel.min(Vec3A::splat((BINS - 1) as f32));
        rel.to_array().map(|x| x as i32 as usize & (BINS - 1))
    }

    /// Whether `bins(c)[axis] <= bin`, for `bin < BINS - 1`, without the conversion (NaN is in bin 0).
    #[inline]
    fn goes_left(&self, c: Vec3A, axis: usize, bin: usize) -> bool {
        let rel = (c[axis] - self.origin[axis]) * self.scale[axis];
        rel < (bin + 1) as f32 || rel.is_nan()
    }
}

/// Per axis and bin: the union of the boxes whose centroids fall in it, and their number.
#[derive(Copy, Clone)]
struct Bins {
    boxes: [[Bounds; BINS]; 3],
    counts: [[u32; BINS]; 3],
}

impl Bins {
    const EMPTY: Bins = Bins {
        boxes: [[Bounds::EMPTY; BINS]; 3],
        counts: [[0; BINS]; 3],
    };

    fn add(&mut self, boxes: &[Bounds], binning: &Binning) {
        for b in boxes {
            for (axis, k) in binning.bins(b.centroid2()).into_iter().enumerate() {
                self.boxes[axis][k] = self.boxes[axis][k].union(*b);
                self.counts[axis][k] += 1;
            }
        }
    }

    fn merge(mut self, o: Bins) -> Bins {
        for (x, y) in self.boxes.iter_mut().flatten().zip(o.boxes.iter().flatten()) {
            *x = x.union(*y);
        }
        for (x, y) in self.counts.iter_mut().flatten().zip(o.counts.iter().flatten()) {
            *x += y;
        }
        self
    }

    /// Unions and counts are exact, so the parallel result is the sequential one, whatever the chunking.
    fn fill(&mut self, boxes: &[Bounds], binning: &Binning) {
        if boxes.len() < 2 * CHUNK {
            return self.add(boxes, binning);
        }
        let chunks = boxes.par_chunks(CHUNK).map(|chunk| {
            let mut bins = Bins::EMPTY;
            bins.add(chunk, binning);
            bins
        });
        *self = self.merge(chunks.reduce(|| Bins::EMPTY, Bins::merge));
    }
}

/// A split plane: primitives whose bin on `axis` is at most `bin` go left. `cost` is the SAH cost relative to the
/// node's own area, `left` the left side's box and count, `right` the right side's box.
#[derive(Copy, Clone)]
struct Split {
    cost: f32,
    axis: usize,
    bin: usize,
    left: (Bounds, u32),
    right: Bounds,
}

/// Offers the planes of one axis to `best`, given `len` groups of primitives (box, count, bin) in increasing bin
/// order: occupied bins, or primitives sorted by bin. Planes between the same two occupied bins give the same
/// partition and cost, so each gap is offered once, at its lowest plane: the one a sweep over all the bins keeps,
/// as it keeps the first of equal costs. Only strictly cheaper splits replace the best, so ties go to the lower axis
/// and plane. `costs`: traversal cost, intersection cost, 1 / the node's area.
#[inline]
fn sweep(
    best: &mut Option<Split>,
    costs: (f32, f32, f32),
    axis: usize,
    len: usize,
    group: impl Fn(usize) -> (Bounds, u32, usize),
) {
    let (traversal, intersection, inv_area) = costs;
    // Area times count of everything right of each gap. Only the best split needs the box itself.
    let mut right = [0f32; BINS];
    let (mut acc, mut count) = (Bounds::EMPTY, 0);
    for j in (1..len).rev() {
        let (b, c, _) = group(j);
        (acc, count) = (acc.union(b), count + c);
        right[j] = acc.half_area() * count as f32;
    }
    let (mut acc, mut count) = (Bounds::EMPTY, 0);
    for j in 0..len.saturating_sub(1) {
        let (b, c, bin) = group(j);
        (acc, count) = (acc.union(b), count + c);
        if bin == group(j + 1).2 {
            continue;
        }
        let cost = traversal + intersection * (acc.half_area() * count as f32 + right[j + 1]) * inv_area;
        if best.is_none_or(|s| cost < s.cost) {
            let (left, right) = (
                (acc, count),
                (j + 1..len).fold(Bounds::EMPTY, |r, i| r.union(group(i).0)),
            );
            *best = Some(Split {
                cost,
                axis,
                bin,
                left,
                right,
            });
        }
    }
}

/// The best binned split over the three axes; `None` when every centroid is in the same place.
fn find_split(boxes: &[Bounds], binning: &Binning, costs: (f32, f32, f32)) -> Option<Split> {
    let mut best = None;
    let n = boxes.len();
    let live = |axis: &usize| binning.scale[*axis] > 0.0;
    if n == 2 {
        // About 40% of the searches. The general search below finds the same split with the same arithmetic:
        // the one plane (bin 0, as the two centroids bound the bins) on the first axis that separates the two.
        let axis = (0..3).find(live)?;
        let (a, b) = (boxes[0], boxes[1]);
        let (l, r) = if binning.goes_left(a.centroid2(), axis, 0) {
            (a, b)
        } else {
            (b, a)
        };
        let cost = costs.0 + costs.1 * (l.half_area() + r.half_area()) * costs.2;
        return Some(Split {
            cost,
            axis,
            bin: 0,
            left: (l, 1),
            right: r,
        });
    } else if n <= SMALL {
        // Bin in the high bits, primitive in the low ones, padding (MAX) last: sorting the keys sorts by bin.
        let mut keys = [[u32::MAX; SMALL]; 3];
        for (k, b) in boxes.iter().enumerate() {
            let bins = binning.bins(b.centroid2());
            for axis in 0..3 {
                keys[axis][k] = (bins[axis] * SMALL + k) as u32;
            }
        }
        for axis in (0..3).filter(live) {
            let keys = &mut keys[axis];
            sort_keys(keys, n);
            let group = |j: usize| (boxes[keys[j] as usize % SMALL], 1, keys[j] as usize / SMALL);
            sweep(&mut best, costs, axis, n, group);
        }
    } else {
        let mut bins = Bins::EMPTY;
        bins.fill(boxes, binning);
        for axis in (0..3).filter(live) {
            let (mut occupied, mut m) = ([0; BINS], 0);
            for (k, &c) in bins.counts[axis].iter().enumerate() {
                occupied[m] = k;
                m += (c > 0) as usize;
            }
            let (boxes, counts) = (&bins.boxes[axis], &bins.counts[axis]);
            sweep(&mut best, costs, axis, m, |j| {
                (boxes[occupied[j]], counts[occupied[j]], occupied[j])
            });
        }
    }
    best
}

/// Sorting networks: the order of a few keys is a coin toss, so branch-free compare-exchanges beat any sort that
/// branches on it. Pairs of indices, for up to four keys and up to eight.
fn sort_keys(keys: &mut [u32; SMALL], n: usize) {
    const FOUR: [usize; 10] = [0, 1, 2, 3, 0, 2, 1, 3, 1, 2];
    const EIGHT: [usize; 38] = [
        0, 2, 1, 3, 4, 6, 5, 7, 0, 4, 1, 5, 2, 6, 3, 7, 0, 1, 2, 3, 4, 5, 6, 7, 2, 4, 3, 5, 1, 4, 3, 6, 1, 2, 3, 4, 5,
        6,
    ];
    let network: &[usize] = if n <= 4 { &FOUR } else { &EIGHT };
    for &[i, j] in network.as_chunks::<2>().0 {
        (keys[i], keys[j]) = (keys[i].min(keys[j]), keys[i].max(keys[j]));
    }
}

/// Bounds of the boxes and of their doubled centroids.
fn bounds_of(boxes: &[Bounds]) -> (Bounds, Bounds) {
    let one = |(b, c): (Bounds, Bounds), p: &Bounds| (b.union(*p), c.grow(p.centroid2()));
    let empty = (Bounds::EMPTY, Bounds::EMPTY);
    if boxes.len() < 2 * CHUNK {
        return boxes.iter().fold(empty, one);
    }
    let chunks = boxes.par_chunks(CHUNK).map(|chunk| chunk.iter().fold(empty, one));
    chunks.reduce(|| empty, |(b, c), (d, e)| (b.union(d), c.union(e)))
}

/// One subtree's share of the work: its primitives' boxes and original indices, which it reorders in place (`first`
/// is where they start in the whole), its node and the slots below it.
///
/// A subtree over `m` primitives has at most `2m - 1` nodes, so `below` holds `2m - 2` slots, from slot `at`: the
/// children pair, then the `2l - 2` below the left child, then the right child's. Parallel subtrees thus write
/// disjoint slices, and the slots do not depend on which thread finishes first; they already form a valid
/// hierarchy, which `compact` rids of the slots that leaves left unused.
struct Task<'a> {
    boxes: &'a mut [Bounds],
    index: &'a mut [u32],
    node: &'a mut BvhNode,
    below: &'a mut [BvhNode],
    first: u32,
    at: u32,
}

impl<'a> Task<'a> {
    fn split(self, mid: usize) -> (Task<'a>, Task<'a>) {
        let (lb, rb) = self.boxes.split_at_mut(mid);
        let (li, ri) = self.index.split_at_mut(mid);
        let ([ln, rn], below) = self.below.split_first_chunk_mut::<2>().unwrap();
        let (lw, rw) = below.split_at_mut(2 * mid - 2);
        let (first, at) = (self.first + mid as u32, self.at + 2 * mid as u32);
        let left = Task {
            boxes: lb,
            index: li,
            node: ln,
            below: lw,
            first: self.first,
            at: self.at + 2,
        };
        let right = Task {
            boxes: rb,
            index: ri,
            node: rn,
            below: rw,
            first,
            at,
        };
        (left, right)
    }

    /// Partition on `left(doubled centroid)`; returns the left count and both sides' centroid bounds, which cost
    /// little here. Branch-free (Lomuto with an unconditional swap): the side of a primitive is a coin toss to the
    /// branch predictor, and a mispredicted branch costs more than the swap.
    fn partition(&mut self, left: impl Fn(Vec3A) -> bool) -> (usize, Bounds, Bounds) {
        let (mut i, mut lc, mut rc) = (0, Bounds::EMPTY, Bounds::EMPTY);
        for k in 0..self.boxes.len() {
            let (b, c) = (self.boxes[k], self.boxes[k].centroid2());
            let l = left(c);
            let m = BVec3A::splat(l);
            (lc, rc) = (lc.grow_where(m, c), rc.grow_where(!m, c));
            // A swap through registers; `slice::swap` goes through the stack.
            (self.boxes[k], self.boxes[i]) = (self.boxes[i], b);
            self.index.swap(i, k);
            i += l as usize;
        }
        (i, lc, rc)
    }

    /// Reorders the primitives so that the first half's centroids lie below the second
    /// half's along `axis`; the half's size.
    fn halve(&mut self, axis: usize) -> usize {
        let mid = self.boxes.len() / 2;
        let mut keyed: Vec<(f32, Bounds, u32)> = (self.boxes.iter().zip(self.index.iter()))
            .map(|(b, &i)| (b.centroid2()[axis], *b, i))
            .collect();
        keyed.select_nth_unstable_by(mid, |a, b| a.0.total_cmp(&b.0));
        for (k, (_, b, i)) in keyed.into_iter().enumerate() {
            (self.boxes[k], self.index[k]) = (b, i);
        }
        mid
    }
}

/// Most primitives a subtree whose leaves lie at most `height` levels below its root holds when every split
/// halves: leaves of `max_leaf_size`.
fn halving_capacity(params: &BuildParams, height: usize) -> usize {
    (params.max_leaf_size as usize).saturating_mul(1usize.checked_shl(height as u32).unwrap_or(usize::MAX))
}

/// Builds the subtree of `task`, whose boxes and doubled centroids are bounded by `bounds`; returns its node
/// count. A subtree is kept within `params.max_depth`: where the SAH's split leaves a side more primitives than
/// halving splits can hold in the depth left, the primitives are halved at their centroids' median instead, so
/// leaves stay small at any depth limit a scene's size allows.
fn subtree(params: &BuildParams, mut task: Task, bounds: (Bounds, Bounds), depth: usize) -> usize {
    let (node, centroids) = bounds;
    let count = task.boxes.len();
    let leaf = node.to_node(task.first, count as u32);
    if count == 1 || depth >= params.max_depth {
        *task.node = leaf;
        return 1;
    }
    let binning = Binning::new(&centroids);
    let inv_area = 1.0 / node.half_area().max(f32::MIN_POSITIVE);
    let costs = (params.traversal_cost, params.intersection_cost, inv_area);
    let small_enough = count <= params.max_leaf_size as usize;
    let (mid, left, right) = match find_split(task.boxes, &binning, costs) {
        Some(s) if small_enough && count as f32 * params.intersection_cost <= s.cost => {
            *task.node = leaf;
            return 1;
        }
        Some(s) => {
            let (n, lc, rc) = task.partition(|c| binning.goes_left(c, s.axis, s.bin));
            if n == s.left.1 as usize {
                (n, (s.left.0, lc), (s.right, rc))
            } else {
                // Unreachable while `goes_left` agrees with `bins`; there so that a disagreement would cost
                // quality, not a panic.
                let mid = if n == 0 || n == count { count / 2 } else { n };
                (mid, bounds_of(&task.boxes[..mid]), bounds_of(&task.boxes[mid..]))
            }
        }
        // All centroids coincide: no plane separates them.
        None if small_enough => {
            *task.node = leaf;
            return 1;
        }
        None => {
            let mid = count / 2;
            (mid, bounds_of(&task.boxes[..mid]), bounds_of(&task.boxes[mid..]))
        }
    };
    let room = halving_capacity(params, params.max_depth - depth - 1);
    let (mid, left, right) = if mid.max(count - mid) > room {
        let extent = centroids.max - centroids.min;
        let axis = (extent.y > extent.x) as usize;
        let axis = if extent.z > extent[axis] { 2 } else { axis };
        let mid = task.halve(axis);
        (mid, bounds_of(&task.boxes[..mid]), bounds_of(&task.boxes[mid..]))
    } else {
        (mid, left, right)
    };
    *task.node = node.to_node(task.at, 0);
    let (l, r) = task.split(mid);
    let child = |task, bounds| subtree(params, task, bounds, depth + 1);
    let (l, r) = match count >= PARALLEL_SUBTREE {
        true => rayon::join(|| child(l, left), || child(r, right)),
        false => (child(l, left), child(r, right)),
    };
    1 + l + r
}

/// Copies the reachable slots, in the order a sequential depth-first build allocates nodes: each interior node's
/// children pair when it is split, the left subtree before the right. That is the slots' own order, so the reads
/// stream forward.
fn compact(slots: &[BvhNode], count: usize) -> Vec<BvhNode> {
    let mut nodes = Vec::with_capacity(count);
    nodes.push(slots[0]);
    let mut stack = vec![0];
    while let Some(k) = stack.pop() {
        let n = nodes[k];
        if n.is_leaf() {
            continue;
        }
        let c = nodes.len();
        nodes.push(slots[n.first as usize]);
        nodes.push(slots[n.first as usize + 1]);
        nodes[k].first = c as u32;
        stack.push(c + 1);
        stack.push(c);
    }
    nodes
}

/// Builds a BVH over primitive boxes. Empty input gives an empty hierarchy. The result depends on the input
/// alone, not on the number of threads.
pub fn build(boxes: &[Aabb], params: &BuildParams) -> Bvh {
    let n = boxes.len();
    if n == 0 {
        return Bvh::default();
    }
    let mut work: Vec<Bounds> = boxes
        .par_iter()
        .map(|b| Bounds::new(b.min.into(), b.max.into()))
        .collect();
    let mut order: Vec<u32> = (0..n as u32).collect();
    let bounds = bounds_of(&work);
    // Zeroed `u32`s come from the allocator already zeroed, so slots that stay unused are never touched.
    let mut raw = vec![0u32; (2 * n - 1) * size_of::<BvhNode>() / size_of::<u32>()];
    let (node, below) = bytemuck::cast_slice_mut(&mut raw).split_first_mut().unwrap();
    let (boxes, index) = (&mut work[..], &mut order[..]);
    let task = Task {
        boxes,
        index,
        node,
        below,
        first: 0,
        at: 1,
    };
    let count = subtree(params, task, bounds, 0);
    drop(work);
    let nodes = compact(bytemuck::cast_slice(&raw), count);
    Bvh { nodes, order }
}
