//! The base mesh: the reference decimated to a triangle budget by meshoptimizer's
//! error-driven edge collapse (quadric error, borders collapsed only along themselves), then
//! compacted to the vertices it uses.
//!
//! Raw scans are not manifold: edges of three or four triangles, neighbours facing opposite
//! ways, sheets pinched at a vertex. The simplifier locks every vertex it cannot classify, and
//! on such a scan stops far above the budget. So it is given a tidier copy of the same
//! surface: triangles turned to agree with their neighbours across every two-triangle edge
//! (each connected patch keeping the orientation most of its triangles had), and each vertex
//! split into one copy per fan of triangles joined through such edges. The copies share their
//! position, which the simplifier's permissive mode moves together, as one vertex; they are
//! merged back afterwards.
//!
//! Guarantees: every base vertex is a reference vertex (collapses keep one of the two
//! endpoints), so base corners lie on the reference surface; no triangle repeats a vertex
//! or another triangle's vertices. The budget is a target the simplifier may stop above.

use gridrt_shared::glam::Vec3;
use meshopt::{SimplifyOptions, VertexDataAdapter};

use crate::mesh::Mesh;

/// `reference` decimated to about `target_triangles` (none fewer than one).
pub fn decimate(reference: &Mesh, target_triangles: usize) -> Mesh {
    if target_triangles >= reference.triangles.len() {
        return reference.clone();
    }
    let oriented = orient(&reference.triangles);
    let fans = split_into_fans(&oriented, reference.positions.len());
    let indices: Vec<u32> = fans.triangles.iter().flatten().copied().collect();
    let floats: Vec<f32> = (fans.original.iter())
        .flat_map(|&v| reference.positions[v as usize].to_array())
        .collect();
    let bytes: &[u8] = bytemuck::cast_slice(&floats);
    let vertices = VertexDataAdapter::new(bytes, 12, 0).expect("12-byte vertices, positions first");
    // The largest relative error: the triangle budget alone decides where to stop.
    let kept = meshopt::simplify(
        &indices,
        &vertices,
        3 * target_triangles.max(1),
        1.0,
        SimplifyOptions::Permissive,
        None,
    );
    let merged: Vec<u32> = kept.iter().map(|&i| fans.original[i as usize]).collect();
    compact(&reference.positions, &merged)
}

/// Every edge of `triangles` as `(smaller vertex, larger vertex, triangle, corner)`, the edge
/// running from corner `corner` to the next; sorted, so an edge's triangles are neighbours.
fn sorted_edges(triangles: &[[u32; 3]]) -> Vec<(u32, u32, u32, u8)> {
    let mut edges: Vec<_> = (triangles.iter().enumerate())
        .flat_map(|(t, tri)| {
            (0..3u8).map(move |k| {
                let (a, b) = (tri[k as usize], tri[(k as usize + 1) % 3]);
                (a.min(b), a.max(b), t as u32, k)
            })
        })
        .collect();
    edges.sort_unstable();
    edges
}

/// The pairs of triangles that are an edge's only two: `((t, k), (u, j))` with the edge
/// running from corner `k` of `t` and from corner `j` of `u`.
fn two_triangle_edges(triangles: &[[u32; 3]]) -> Vec<((u32, u8), (u32, u8))> {
    let edges = sorted_edges(triangles);
    edges
        .chunk_by(|x, y| (x.0, x.1) == (y.0, y.1))
        .filter(|group| group.len() == 2)
        .map(|g| ((g[0].2, g[0].3), (g[1].2, g[1].3)))
        .collect()
}

/// `triangles`, some reversed so that across every two-triangle edge neighbours run the edge
/// in opposite directions (as far as the surface is orientable); each patch so joined keeps
/// the orientation most of its triangles had.
fn orient(triangles: &[[u32; 3]]) -> Vec<[u32; 3]> {
    let pairs = two_triangle_edges(triangles);
    let mut neighbours = vec![Vec::new(); triangles.len()];
    for &((t, k), (u, j)) in &pairs {
        // The edge runs the same way in both (not oriented alike) when its first corners agree.
        let same_way = triangles[t as usize][k as usize] == triangles[u as usize][j as usize];
        neighbours[t as usize].push((u, same_way));
        neighbours[u as usize].push((t, same_way));
    }
    let mut flip: Vec<Option<bool>> = vec![None; triangles.len()];
    let mut out = triangles.to_vec();
    for start in 0..triangles.len() {
        if flip[start].is_some() {
            continue;
        }
        flip[start] = Some(false);
        let (mut patch, mut stack) = (vec![start], vec![start]);
        while let Some(t) = stack.pop() {
            for &(u, same_way) in &neighbours[t] {
                if flip[u as usize].is_none() {
                    // Reversed relative to the original exactly when the two disagree.
                    flip[u as usize] = Some(flip[t].unwrap() ^ same_way);
                    patch.push(u as usize);
                    stack.push(u as usize);
                }
            }
        }
        let flipped = patch.iter().filter(|&&t| flip[t] == Some(true)).count();
        let keep_majority = 2 * flipped > patch.len();
        for &t in &patch {
            if flip[t] != Some(keep_majority) {
                out[t].swap(1, 2);
            }
        }
    }
    out
}

/// Triangles over per-fan vertex copies, and the reference vertex of each copy.
struct Fans {
    triangles: Vec<[u32; 3]>,
    original: Vec<u32>,
}

/// Gives each fan of triangles around a vertex (triangles joined through two-triangle
/// edges) a vertex of its own: vertex `v`'s first fan keeps id `v`, the others get new ids.
fn split_into_fans(triangles: &[[u32; 3]], vertices: usize) -> Fans {
    // Union-find over corners (3 t + k): corners at one vertex across a two-triangle edge.
    let mut parent: Vec<u32> = (0..3 * triangles.len() as u32).collect();
    fn root(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            parent[x as usize] = parent[parent[x as usize] as usize];
            x = parent[x as usize];
        }
        x
    }
    for ((t, k), (u, _)) in two_triangle_edges(triangles) {
        for end in 0..2 {
            let corner = (k as u32 + end) % 3;
            let v = triangles[t as usize][corner as usize];
            let other = (0..3).find(|&c| triangles[u as usize][c] == v).unwrap() as u32;
            let (a, b) = (root(&mut parent, 3 * t + corner), root(&mut parent, 3 * u + other));
            if a != b {
                parent[b as usize] = a;
            }
        }
    }
    let mut copy_of_root = vec![u32::MAX; parent.len()];
    let mut vertex_taken = vec![false; vertices];
    let mut fans = Fans {
        triangles: triangles.to_vec(),
        original: (0..vertices as u32).collect(),
    };
    for (t, tri) in triangles.iter().enumerate() {
        for (k, &v) in tri.iter().enumerate() {
            let r = root(&mut parent, 3 * t as u32 + k as u32) as usize;
            if copy_of_root[r] == u32::MAX {
                copy_of_root[r] = if vertex_taken[v as usize] {
                    fans.original.push(v);
                    fans.original.len() as u32 - 1
                } else {
                    vertex_taken[v as usize] = true;
                    v
                };
            }
            fans.triangles[t][k] = copy_of_root[r];
        }
    }
    fans
}

/// The triangles of `indices` over only the vertices they use, in the reference's order
/// (so the ids that order edge interpolation follow the reference's numbering).
fn compact(positions: &[Vec3], indices: &[u32]) -> Mesh {
    let mut new_id = vec![u32::MAX; positions.len()];
    for &i in indices {
        new_id[i as usize] = 0;
    }
    let mut mesh = Mesh::default();
    for (old, id) in new_id.iter_mut().enumerate() {
        if *id == 0 {
            *id = mesh.positions.len() as u32;
            mesh.positions.push(positions[old]);
        }
    }
    let mut seen = std::collections::HashSet::new();
    mesh.triangles = (indices.as_chunks::<3>().0.iter())
        .map(|t| t.map(|i| new_id[i as usize]))
        .filter(|&[a, b, c]| a != b && b != c && a != c)
        .filter(|t| {
            let mut key = *t;
            key.sort_unstable();
            seen.insert(key)
        })
        .collect();
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat square of `n` x `n` cells, two triangles each.
    pub(crate) fn square(n: u32) -> Mesh {
        let mut mesh = Mesh::default();
        for j in 0..=n {
            for i in 0..=n {
                mesh.positions.push(Vec3::new(i as f32, j as f32, 0.0));
            }
        }
        let id = |i: u32, j: u32| j * (n + 1) + i;
        for j in 0..n {
            for i in 0..n {
                mesh.triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                mesh.triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        mesh
    }

    #[test]
    fn a_flat_square_decimates_to_its_budget_on_reference_vertices() {
        let reference = square(16);
        let base = decimate(&reference, 8);
        assert!(base.triangles.len() <= 8, "{} triangles", base.triangles.len());
        assert!(!base.triangles.is_empty());
        assert!(base.positions.iter().all(|p| reference.positions.contains(p)));
        // Every vertex is used, and the square's corners (where its border turns) are kept.
        let mut used = vec![false; base.positions.len()];
        base.triangles.iter().flatten().for_each(|&i| used[i as usize] = true);
        assert!(used.iter().all(|&u| u));
        for corner in [Vec3::ZERO, Vec3::new(16.0, 0.0, 0.0), Vec3::new(16.0, 16.0, 0.0)] {
            assert!(base.positions.contains(&corner), "{corner}");
        }
    }

    /// A square whose every other triangle is reversed, with a fin: a third triangle on one
    /// of its edges (the kind of scan the simplifier alone would stop on).
    #[test]
    fn an_unoriented_finned_square_still_reaches_its_budget() {
        let mut reference = square(16);
        for t in reference.triangles.iter_mut().step_by(2) {
            t.swap(1, 2);
        }
        let apex = reference.positions.len() as u32;
        reference.positions.push(Vec3::new(8.5, 8.0, 1.0));
        let [a, b, _] = reference.triangles[300];
        reference.triangles.push([a, b, apex]);
        let base = decimate(&reference, 16);
        assert!(base.triangles.len() <= 16, "{} triangles", base.triangles.len());
        // Oriented: the triangles of the flat part all face one way.
        let up = (base.triangles.iter())
            .map(|t| t.map(|i| base.positions[i as usize]))
            .filter(|[a, b, c]| a.z == 0.0 && b.z == 0.0 && c.z == 0.0)
            .map(|[a, b, c]| (b - a).cross(c - a).z.signum())
            .sum::<f32>();
        let flat = (base.triangles.iter())
            .filter(|t| t.iter().all(|&i| base.positions[i as usize].z == 0.0))
            .count();
        assert_eq!(up.abs(), flat as f32);
    }

    #[test]
    fn orientation_follows_the_majority() {
        // Three triangles of a strip, the middle one reversed.
        let triangles = [[0, 1, 2], [2, 1, 3], [2, 3, 4]];
        let mut mixed = triangles;
        mixed[1].swap(1, 2);
        assert_eq!(orient(&mixed), triangles);
    }

    #[test]
    fn fans_split_a_pinched_vertex() {
        // Two triangles touching only at vertex 0, and a pair sharing the edge 5-6.
        let triangles = [[0, 1, 2], [0, 3, 4], [5, 6, 7], [6, 5, 8]];
        let fans = split_into_fans(&triangles, 9);
        assert_eq!(fans.triangles[0], [0, 1, 2]);
        assert_eq!(fans.triangles[1], [9, 3, 4]);
        assert_eq!(fans.triangles[3], [6, 5, 8]);
        assert_eq!(fans.original[9], 0);
    }

    #[test]
    fn a_budget_above_the_reference_keeps_it() {
        let reference = square(2);
        assert_eq!(decimate(&reference, 100), reference);
    }
}
