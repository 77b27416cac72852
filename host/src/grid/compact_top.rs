//! Packing the grids' top-level BVH into compact nodes: 16 bytes each instead of 32, boxes as
//! 15-bit codes of the scene's box (see `gridrt_shared::top_nodes` for the layout and how
//! the traversal reads it).
//!
//! Each box is rounded outwards by a whole code step more than it needs, and then checked:
//! its decoded corners must hold the node's box whether the GPU computes
//! `origin + step * code` with one rounding (fused) or two. A hierarchy that fails the check
//! anywhere, or whose links do not fit their bits, is kept in full form: compact packing is
//! a saving, never a change of what the traversal finds.

use gridrt_shared::glam::Vec3;
use gridrt_shared::layout::BvhNode;
use gridrt_shared::top_nodes::{CODE_MAX, COMPACT, COUNT_BITS};

/// `nodes` (a full hierarchy, root first) packed compact, or `None` where it must stay full.
pub fn pack(nodes: &[BvhNode]) -> Option<Vec<BvhNode>> {
    let root = nodes.first()?;
    let (lo, hi) = (Vec3::from(root.min), Vec3::from(root.max));
    // One code of margin below and above the scene's box.
    let step = (hi - lo) / (CODE_MAX - 2) as f32;
    let origin = lo - step;
    if !(origin.is_finite() && step.is_finite()) {
        return None;
    }
    let mut packed = vec![BvhNode {
        min: origin.to_array(),
        first: nodes.len() as u32,
        max: step.to_array(),
        count: COMPACT,
    }];
    for pair in nodes.chunks(2) {
        let a = encode(&pair[0], origin, step)?;
        let b = match pair.get(1) {
            Some(n) => encode(n, origin, step)?,
            None => [0; 4],
        };
        packed.push(BvhNode {
            min: [a[0], a[1], a[2]].map(f32::from_bits),
            first: a[3],
            max: [b[0], b[1], b[2]].map(f32::from_bits),
            count: b[3],
        });
    }
    Some(packed)
}

/// A node's four compact words, or `None` where they would not hold it.
fn encode(node: &BvhNode, origin: Vec3, step: Vec3) -> Option<[u32; 4]> {
    let (min, max) = (Vec3::from(node.min), Vec3::from(node.max));
    let lo = codes(min, origin, step, |x| x.floor() - 1.0);
    let hi = codes(max, origin, step, |x| x.ceil() + 1.0);
    let held = (0..3).all(|k| {
        decoded(lo[k], origin[k], step[k]).iter().all(|&d| d <= min[k])
            && decoded(hi[k], origin[k], step[k]).iter().all(|&d| d >= max[k])
    });
    let fits = node.count < (1 << COUNT_BITS) && node.first < (1 << (32 - COUNT_BITS));
    let link = node.first << COUNT_BITS | node.count;
    (held && fits).then_some([lo[0] | lo[1] << 16, lo[2] | hi[0] << 16, hi[1] | hi[2] << 16, link])
}

/// The codes of `p`, each `round`ed from its exact fraction of a step and clamped.
fn codes(p: Vec3, origin: Vec3, step: Vec3, round: impl Fn(f32) -> f32) -> [u32; 3] {
    std::array::from_fn(|k| {
        let exact = if step[k] > 0.0 {
            (p[k] - origin[k]) / step[k]
        } else {
            0.0
        };
        round(exact).clamp(0.0, CODE_MAX as f32) as u32
    })
}

/// What a GPU may compute for `origin + step * code`: rounded twice, or once (fused).
fn decoded(code: u32, origin: f32, step: f32) -> [f32; 2] {
    let c = code as f32;
    [origin + step * c, step.mul_add(c, origin)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use gridrt_shared::buffer::Buffer;
    use gridrt_shared::top_nodes::TopNodes;

    fn node(min: [f32; 3], max: [f32; 3], first: u32, count: u32) -> BvhNode {
        BvhNode { min, first, max, count }
    }

    /// A small hierarchy far from the origin, with a flat axis and a tiny leaf.
    fn hierarchy() -> Vec<BvhNode> {
        let o = 1000.0;
        vec![
            node([o, -2.0, 5.0], [o + 3.0, 1.0, 5.0], 1, 0),
            node([o, -2.0, 5.0], [o + 1e-4, -1.9999, 5.0], 3, 2),
            node([o + 0.3, -1.0, 5.0], [o + 3.0, 1.0, 5.0], 3, 0),
            node([o + 1.1, 0.2, 5.0], [o + 1.7, 0.9, 5.0], 0, 4),
            node([o + 0.3, -1.0, 5.0], [o + 3.0, 0.1, 5.0], 4, 1),
        ]
    }

    /// Every decoded node holds its box and keeps its links; the buffer is half the size.
    #[test]
    fn compact_nodes_hold_their_boxes_and_links() {
        let full = hierarchy();
        let packed = pack(&full).unwrap();
        assert_eq!(packed.len(), 1 + full.len().div_ceil(2));
        let top = TopNodes::new(packed.as_slice());
        for (i, n) in full.iter().enumerate() {
            let d = top.load(i as u32);
            assert_eq!((d.first, d.count), (n.first, n.count), "node {i}");
            for k in 0..3 {
                assert!(
                    d.min[k] <= n.min[k] && d.max[k] >= n.max[k],
                    "node {i} axis {k}: {d:?} vs {n:?}"
                );
            }
            // Outwards by a few steps at most.
            let span = full[0].max[0] - full[0].min[0];
            assert!(n.min[0] - d.min[0] < 4.0 * span / CODE_MAX as f32, "node {i}");
        }
        // A full hierarchy reads as it is.
        let as_is = TopNodes::new(full.as_slice());
        assert_eq!(as_is.load(3), full[3]);
    }

    /// Links too large for their bits keep the hierarchy full.
    #[test]
    fn oversized_links_stay_full() {
        let mut full = hierarchy();
        full[2].first = 1 << 29;
        assert!(pack(&full).is_none());
    }
}
