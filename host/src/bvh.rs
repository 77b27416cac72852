//! Binned SAH builder for binary BVHs, shared by the baseline (over triangles) and the top level
//! of the grid scene (over grids).
//!
//! The output is the flat node array the traversal in `gridrt_shared::traverse` walks: children
//! of an interior node are adjacent, and each leaf covers a contiguous range of the primitive
//! order, so the caller reorders its primitives once and needs no index indirection.

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
    pub traversal_cost: f32,
    pub intersection_cost: f32,
}

impl Default for BuildParams {
    fn default() -> Self {
        BuildParams {
            max_leaf_size: 4,
            traversal_cost: 1.0,
            intersection_cost: 1.0,
        }
    }
}

/// A built hierarchy: `order[k]` is the original index of the primitive at position `k`.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    pub nodes: Vec<BvhNode>,
    pub order: Vec<u32>,
}

const BINS: usize = 16;
/// Leaves are forced below this depth so traversal stacks never overflow.
const DEPTH_LIMIT: usize = MAX_BVH_DEPTH - 2;

fn to_node(b: &Aabb, first: u32, count: u32) -> BvhNode {
    BvhNode {
        min: b.min.to_array(),
        first,
        max: b.max.to_array(),
        count,
    }
}

/// Builds a BVH over primitive boxes. Empty input gives an empty hierarchy.
pub fn build(boxes: &[Aabb], params: &BuildParams) -> Bvh {
    let n = boxes.len();
    if n == 0 {
        return Bvh::default();
    }
    let centers: Vec<Vec3> = boxes.iter().map(Aabb::center).collect();
    let mut order: Vec<u32> = (0..n as u32).collect();
    let mut nodes = Vec::with_capacity(2 * n / params.max_leaf_size.max(1) as usize + 1);
    nodes.push(BvhNode::default());
    // (node, start, end, depth)
    let mut tasks = vec![(0usize, 0usize, n, 0usize)];
    while let Some((node, start, end, depth)) = tasks.pop() {
        let prims = &mut order[start..end];
        let bounds = prims.iter().fold(Aabb::EMPTY, |b, &p| b.union(boxes[p as usize]));
        let count = prims.len();
        let leaf = to_node(&bounds, start as u32, count as u32);
        if count == 1 || depth >= DEPTH_LIMIT {
            nodes[node] = leaf;
            continue;
        }
        let split = find_split(prims, boxes, &centers, &bounds, params);
        let mid = match split {
            Some((axis, position, cost)) => {
                let leaf_cost = count as f32 * params.intersection_cost;
                if count <= params.max_leaf_size as usize && leaf_cost <= cost {
                    nodes[node] = leaf;
                    continue;
                }
                partition(prims, |p| centers[p as usize][axis] < position)
            }
            // All centroids coincide: no plane separates them.
            None if count <= params.max_leaf_size as usize => {
                nodes[node] = leaf;
                continue;
            }
            None => count / 2,
        };
        let left = nodes.len();
        nodes.push(BvhNode::default());
        nodes.push(BvhNode::default());
        nodes[node] = to_node(&bounds, left as u32, 0);
        tasks.push((left + 1, start + mid, end, depth + 1));
        tasks.push((left, start, start + mid, depth + 1));
    }
    Bvh { nodes, order }
}

/// Best binned split plane over the three axes: `(axis, plane, SAH cost)`, the cost relative to
/// the node's own area. `None` when every centroid is in the same place.
fn find_split(
    prims: &[u32],
    boxes: &[Aabb],
    centers: &[Vec3],
    bounds: &Aabb,
    params: &BuildParams,
) -> Option<(usize, f32, f32)> {
    let cb = prims
        .iter()
        .fold(Aabb::EMPTY, |b, &p| b.grow(centers[p as usize]));
    let extent = cb.max - cb.min;
    let mut bin_box = [[Aabb::EMPTY; BINS]; 3];
    let mut bin_count = [[0u32; BINS]; 3];
    let scale = Vec3::select(
        extent.cmpgt(Vec3::ZERO),
        Vec3::splat(BINS as f32) / extent,
        Vec3::ZERO,
    );
    for &p in prims {
        let rel = (centers[p as usize] - cb.min) * scale;
        for axis in 0..3 {
            let b = (rel[axis] as usize).min(BINS - 1);
            bin_box[axis][b] = bin_box[axis][b].union(boxes[p as usize]);
            bin_count[axis][b] += 1;
        }
    }
    let inv_area = 1.0 / bounds.area().max(f32::MIN_POSITIVE);
    let mut best: Option<(usize, f32, f32)> = None;
    for axis in 0..3 {
        if extent[axis] <= 0.0 {
            continue;
        }
        // Sweep from the right to get the right-hand areas, then from the left.
        let mut right_area = [0f32; BINS];
        let mut right_count = [0u32; BINS];
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
        for b in (1..BINS).rev() {
            acc = acc.union(bin_box[axis][b]);
            cnt += bin_count[axis][b];
            right_area[b] = acc.area();
            right_count[b] = cnt;
        }
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
        for b in 0..BINS - 1 {
            acc = acc.union(bin_box[axis][b]);
            cnt += bin_count[axis][b];
            if cnt == 0 || right_count[b + 1] == 0 {
                continue;
            }
            let cost = params.traversal_cost
                + params.intersection_cost
                    * (acc.area() * cnt as f32 + right_area[b + 1] * right_count[b + 1] as f32)
                    * inv_area;
            if best.is_none_or(|(_, _, c)| cost < c) {
                let plane = cb.min[axis] + extent[axis] * (b + 1) as f32 / BINS as f32;
                best = Some((axis, plane, cost));
            }
        }
    }
    best
}

/// In-place partition; returns how many elements satisfy `left`. Never returns 0 or the full
/// length for a split that `find_split` found, because that split had both sides populated
/// under the same binning arithmetic... except for rounding at the plane, which the midpoint
/// fallback below covers.
fn partition(items: &mut [u32], left: impl Fn(u32) -> bool) -> usize {
    let mut i = 0;
    for k in 0..items.len() {
        if left(items[k]) {
            items.swap(i, k);
            i += 1;
        }
    }
    if i == 0 || i == items.len() {
        items.len() / 2
    } else {
        i
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::triangles;
    use gridrt_shared::layout::Hit;
    use gridrt_shared::ray::{Ray, T_FAR};
    use gridrt_shared::triangle::intersect_triangle;

    /// A deterministic soup of random triangles of mixed sizes, some sliver-thin.
    fn random_mesh(seed: u64, count: usize) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut s = seed;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut positions = Vec::new();
        let mut tris = Vec::new();
        for k in 0..count {
            let c = Vec3::new(next(), next(), next()) * 10.0;
            let size = if k % 7 == 0 { 3.0 } else { 0.3 };
            for _ in 0..3 {
                positions.push(c + (Vec3::new(next(), next(), next()) - 0.5) * size);
            }
            tris.push([3 * k as u32, 3 * k as u32 + 1, 3 * k as u32 + 2]);
        }
        (positions, tris)
    }

    fn brute_force(positions: &[Vec3], tris: &[[u32; 3]], ray: &Ray) -> Hit {
        let mut hit = Hit::miss(T_FAR);
        for (k, t) in tris.iter().enumerate() {
            let [a, b, c] = t.map(|v| positions[v as usize]);
            if let Some((d, u, v)) = intersect_triangle(a, b, c, ray, hit.t) {
                hit = Hit { t: d, u, v, prim: k as u32, ..hit };
            }
        }
        hit
    }

    #[test]
    fn every_primitive_in_exactly_one_leaf_and_children_inside_parents() {
        for (seed, count) in [(1, 1), (2, 2), (3, 17), (4, 1000), (5, 5000)] {
            let (positions, tris) = random_mesh(seed, count);
            let boxes: Vec<Aabb> =
                tris.iter().map(|t| Aabb::from_points(t.iter().map(|&v| positions[v as usize]))).collect();
            let bvh = build(&boxes, &BuildParams::default());
            let mut seen = vec![0u32; count];
            let node_box = |n: &BvhNode| Aabb { min: Vec3::from(n.min), max: Vec3::from(n.max) };
            for n in &bvh.nodes {
                if n.is_leaf() {
                    for k in n.first..n.first + n.count {
                        let p = bvh.order[k as usize] as usize;
                        seen[p] += 1;
                        assert!(node_box(n).contains(&boxes[p]), "primitive outside its leaf");
                    }
                } else {
                    for c in [n.first, n.first + 1] {
                        assert!(node_box(n).contains(&node_box(&bvh.nodes[c as usize])), "child outside parent");
                    }
                }
            }
            assert!(seen.iter().all(|&s| s == 1), "seed {seed}: a primitive is not in exactly one leaf");
            assert!(depth(&bvh.nodes) <= MAX_BVH_DEPTH);
            let mut sorted = bvh.order.clone();
            sorted.sort();
            assert_eq!(sorted, (0..count as u32).collect::<Vec<_>>());
        }
    }

    #[test]
    fn coincident_centroids_still_build() {
        let b = Aabb { min: Vec3::ZERO, max: Vec3::ONE };
        let bvh = build(&vec![b; 100], &BuildParams::default());
        assert!(bvh.nodes.iter().filter(|n| n.is_leaf()).all(|n| n.count <= 4));
        assert_eq!(bvh.order.len(), 100);
    }

    #[test]
    fn traversal_equals_brute_force() {
        for (seed, count) in [(11, 3), (12, 200), (13, 3000)] {
            let (positions, tris) = random_mesh(seed, count);
            let scene = triangles::build(&positions, &tris);
            let mut s = seed;
            let mut next = move || {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (s >> 40) as f32 / (1u64 << 24) as f32
            };
            for _ in 0..5000 {
                let origin = Vec3::new(next(), next(), next()) * 14.0 - 2.0;
                let dir = (Vec3::new(next(), next(), next()) - 0.5).normalize();
                let ray = Ray::new(origin, dir);
                let expect = brute_force(&positions, &tris, &ray);
                let got = gridrt_shared::traverse::trace_triangles(&scene.nodes, &scene.view(), &ray, T_FAR);
                assert_eq!(got.is_hit(), expect.is_hit());
                if expect.is_hit() {
                    assert!((got.t - expect.t).abs() <= 1e-5 * expect.t.abs().max(1e-3));
                    // Ties between overlapping triangles aside, the same triangle.
                    let got_tri = scene.original[got.prim as usize];
                    if got.t != expect.t || got_tri != expect.prim {
                        let [a, b, c] = tris[got_tri as usize].map(|v| positions[v as usize]);
                        let again = intersect_triangle(a, b, c, &ray, T_FAR).unwrap();
                        assert!((again.0 - expect.t).abs() <= 1e-5 * expect.t.abs().max(1e-3));
                    }
                }
            }
        }
    }
}
