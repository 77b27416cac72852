use super::builder::CHUNK;
use super::*;
use crate::triangles;
use gridrt_shared::layout::Hit;
use gridrt_shared::ray::{Ray, T_FAR};
use gridrt_shared::traverse::MAX_BVH_DEPTH;
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
            hit = Hit {
                t: d,
                u,
                v,
                prim: k as u32,
                ..hit
            };
        }
    }
    hit
}

#[test]
fn every_primitive_in_exactly_one_leaf_and_children_inside_parents() {
    for (seed, count) in [(1, 1), (2, 2), (3, 17), (4, 1000), (5, 5000)] {
        let (positions, tris) = random_mesh(seed, count);
        let boxes: Vec<Aabb> = tris
            .iter()
            .map(|t| Aabb::from_points(t.iter().map(|&v| positions[v as usize])))
            .collect();
        let bvh = build(&boxes, &BuildParams::default());
        let mut seen = vec![0u32; count];
        let node_box = |n: &BvhNode| Aabb {
            min: Vec3::from(n.min),
            max: Vec3::from(n.max),
        };
        for n in &bvh.nodes {
            if n.is_leaf() {
                for k in n.first..n.first + n.count {
                    let p = bvh.order[k as usize] as usize;
                    seen[p] += 1;
                    assert!(node_box(n).contains(&boxes[p]), "primitive outside its leaf");
                }
            } else {
                for c in [n.first, n.first + 1] {
                    assert!(
                        node_box(n).contains(&node_box(&bvh.nodes[c as usize])),
                        "child outside parent"
                    );
                }
            }
        }
        assert!(
            seen.iter().all(|&s| s == 1),
            "seed {seed}: a primitive is not in exactly one leaf"
        );
        assert!(depth(&bvh.nodes) <= MAX_BVH_DEPTH);
        let mut sorted = bvh.order.clone();
        sorted.sort();
        assert_eq!(sorted, (0..count as u32).collect::<Vec<_>>());
    }
}

#[test]
fn same_tree_on_any_number_of_threads() {
    // Large enough for parallel binning at the root and parallel subtrees below it.
    let (positions, tris) = random_mesh(21, 3 * CHUNK);
    let boxes: Vec<Aabb> = tris
        .iter()
        .map(|t| Aabb::from_points(t.iter().map(|&v| positions[v as usize])))
        .collect();
    let on = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| build(&boxes, &BuildParams::default()))
    };
    let (one, four) = (on(1), on(4));
    assert!(one.nodes == four.nodes && one.order == four.order);
}

#[test]
fn coincident_centroids_still_build() {
    let b = Aabb {
        min: Vec3::ZERO,
        max: Vec3::ONE,
    };
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
            let got = gridrt_shared::traverse::trace_triangles(scene.nodes.as_slice(), &scene.view(), &ray, T_FAR);
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

/// Boxes on a geometric progression, each twice as far out as the last: the SAH peels them off
/// one or a few at a time, a chain far deeper than the count calls for. Under a depth limit the
/// builder halves at the median where the SAH would go too deep, so every leaf stays small,
/// and the tree stays a valid one that finds every box.
#[test]
fn depth_limit_keeps_leaves_small() {
    let boxes: Vec<Aabb> = (0..1000)
        .map(|k| {
            let x = 1.02f32.powi(k);
            Aabb {
                min: Vec3::new(x, 0.0, 0.0),
                max: Vec3::new(x * 1.01, 1.0, 1.0),
            }
        })
        .collect();
    let unlimited = build(&boxes, &BuildParams::default());
    let params = BuildParams {
        max_depth: 9,
        ..BuildParams::default()
    };
    assert!(
        depth(&unlimited.nodes) > params.max_depth + 1,
        "the SAH alone goes deep here"
    );
    let bvh = build(&boxes, &params);
    assert!(depth(&bvh.nodes) <= params.max_depth + 1);
    let leaves: Vec<&BvhNode> = bvh.nodes.iter().filter(|n| n.is_leaf()).collect();
    assert!(leaves.iter().all(|n| n.count <= params.max_leaf_size));
    let mut sorted = bvh.order.clone();
    sorted.sort();
    assert_eq!(sorted, (0..boxes.len() as u32).collect::<Vec<_>>());
    for n in leaves {
        for k in n.first..n.first + n.count {
            let b = &boxes[bvh.order[k as usize] as usize];
            let leaf = Aabb {
                min: Vec3::from(n.min),
                max: Vec3::from(n.max),
            };
            assert!(leaf.contains(b), "a box outside its leaf");
        }
    }
}
