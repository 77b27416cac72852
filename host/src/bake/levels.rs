//! A level per base triangle: a micro-mesh baked at one level `L` becomes one whose every base
//! triangle takes the coarsest level whose surface stays within a bound of the level-`L`
//! surface, flat regions coarse and detailed ones fine, as NVIDIA's displacement micro-map
//! tools do.
//!
//! Guarantees:
//! - Nothing is baked again: a triangle at level `l` keeps the level-`L` values at its own
//!   lattice points (every `2^(L - l)`-th), so a shared edge holds the same values on both
//!   sides at every level.
//! - Across every base edge the levels differ by at most one (coarse triangles are raised
//!   where a neighbour needs it). The finer triangles of a level change decimate that edge
//!   (`DisplacedMesh::decimated_edges`, glTF's `primitiveFlags`): they keep its even points,
//!   the coarser side's, so the surface stays watertight; the odd points there are not part
//!   of the surface and store 0, as other tools' files do.
//! - The bound is on each triangle's RMS distance, over its level-`L` lattice points, from the
//!   level-`L` surface to the one of the level it takes, measured before decimation; a
//!   decimated edge moves a few points of the finer side onto the coarser side's surface.
//!
//! The coarse levels keep values fitted at level `L`, not refitted at their own: at equal
//! bytes, such a mixed micro-mesh is not yet closer to the reference than a uniform bake
//! (docs/RESULTS.md, "A level per base triangle").

use std::collections::HashMap;

use gridrt_shared::displacement::{decimated_point, u_major_index};
use gridrt_shared::glam::Vec3;
use gridrt_shared::grid_index::{grid_size, lattice_index, lattice_points, triangle_count};

use crate::bary::Micromap;
use crate::displaced::DisplacedMesh;

/// For each triangle of `mesh` (one level `L`, ranges folded), the RMS distance from its
/// level-`L` micro-vertices to the surface of each level `0 ..= L`, at the same barycentrics
/// (zero at level `L`).
pub fn coarsening_errors(mesh: &DisplacedMesh, levels: u32) -> Vec<Vec<f32>> {
    use rayon::prelude::*;
    let n = grid_size(levels);
    (0..mesh.triangles.len())
        .into_par_iter()
        .map(|t| {
            let points = mesh.micro_vertices(t);
            let at = |i: u32, j: u32| points[lattice_index(i, j, n) as usize];
            (0..=levels)
                .map(|l| {
                    let s = 1 << (levels - l);
                    let squares: f32 = lattice_points(n)
                        .map(|[i, j]| (at(i, j) - coarse_point(&at, [i, j], s)).length_squared())
                        .sum();
                    (squares / lattice_points(n).count() as f32).sqrt()
                })
                .collect()
        })
        .collect()
}

/// Where level-`L` lattice point `p` lies on the surface of the level whose lattice step is
/// `s` level-`L` steps: in the coarse micro-triangle that holds it, interpolated from that
/// micro-triangle's corners (`at` gives a level-`L` point's position).
fn coarse_point(at: &impl Fn(u32, u32) -> Vec3, p: [u32; 2], s: u32) -> Vec3 {
    let ([i, j], [ri, rj]) = ([p[0] / s, p[1] / s], [p[0] % s, p[1] % s]);
    let (x, y, s) = (ri as f32, rj as f32, s as f32);
    let corner = |a: u32, b: u32| at(a * s as u32, b * s as u32);
    if ri + rj <= s as u32 {
        // The upright cell at (i, j); a point of the coarse lattice itself when ri = rj = 0.
        let c = corner(i, j);
        if ri == 0 && rj == 0 {
            return c;
        }
        c * ((s - x - y) / s) + corner(i + 1, j) * (x / s) + corner(i, j + 1) * (y / s)
    } else {
        // The inverted cell between (i + 1, j), (i, j + 1) and (i + 1, j + 1).
        corner(i + 1, j + 1) * ((x + y - s) / s) + corner(i, j + 1) * ((s - x) / s) + corner(i + 1, j) * ((s - y) / s)
    }
}

/// Each triangle's level: the coarsest whose error (see [`coarsening_errors`]) is at most
/// `max_error`, then raised until the levels across every edge differ by at most one.
pub fn choose_levels(triangles: &[[u32; 3]], errors: &[Vec<f32>], max_error: f32) -> Vec<u32> {
    let mut levels: Vec<u32> = (errors.iter())
        .map(|e| e.iter().position(|&x| x <= max_error).unwrap_or(e.len() - 1) as u32)
        .collect();
    let edges = edge_triangles(triangles);
    // Raising only ever increases levels, up to the finest: this ends.
    loop {
        let mut changed = false;
        for around in edges.values() {
            let finest = around.iter().map(|&t| levels[t]).max().unwrap_or(0);
            for &t in around {
                if levels[t] + 1 < finest {
                    levels[t] = finest - 1;
                    changed = true;
                }
            }
        }
        if !changed {
            return levels;
        }
    }
}

/// The triangles around each edge (a pair of vertex ids, smaller first).
fn edge_triangles(triangles: &[[u32; 3]]) -> HashMap<(u32, u32), Vec<usize>> {
    let mut edges: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for (t, v) in triangles.iter().enumerate() {
        for e in 0..3 {
            let (a, b) = (v[e], v[(e + 1) % 3]);
            edges.entry((a.min(b), a.max(b))).or_default().push(t);
        }
    }
    edges
}

/// Each triangle's edges towards a neighbour one level coarser (see
/// `DisplacedMesh::decimated_edges`).
pub fn decimated_edges(triangles: &[[u32; 3]], levels: &[u32]) -> Vec<u8> {
    let edges = edge_triangles(triangles);
    (triangles.iter().enumerate())
        .map(|(t, v)| {
            (0..3).fold(0u8, |flags, e| {
                let (a, b) = (v[e], v[(e + 1) % 3]);
                let coarser = edges[&(a.min(b), a.max(b))].iter().any(|&o| levels[o] + 1 == levels[t]);
                flags | (coarser as u8) << e
            })
        })
        .collect()
}

/// `mesh` (one level, ranges folded) with triangle `t` at `levels[t]` (at most its own),
/// its values taken from its own, and its edges towards coarser neighbours decimated.
pub fn with_levels(mesh: &DisplacedMesh, levels: &[u32]) -> DisplacedMesh {
    let finest = mesh.uniform_level().expect("one level");
    let group = mesh.micromap.groups[0];
    let flags = decimated_edges(&mesh.triangles, levels);
    let triangles: Vec<(u32, Vec<u16>)> = (0..mesh.triangles.len())
        .map(|t| {
            let (l, own) = (levels[t], mesh.micromap.triangle_values(t));
            let (n, s, big) = (grid_size(l), 1 << (finest - l), grid_size(finest));
            let mut values = vec![0; lattice_points(n).count()];
            for p in lattice_points(n) {
                if decimated_point(p, n, flags[t] as u32) == p {
                    values[u_major_index(p, n) as usize] = own[u_major_index([p[0] * s, p[1] * s], big) as usize];
                }
            }
            (l, values)
        })
        .collect();
    let decimated = flags.iter().any(|&f| f != 0);
    DisplacedMesh {
        micromap: Micromap::from_triangles(group.bias, group.scale, &triangles),
        decimated_edges: if decimated { flags } else { Vec::new() },
        ..mesh.clone()
    }
}

/// `mesh` (one level, ranges folded) with each triangle at the coarsest level whose surface
/// stays within `max_error` (in the mesh's units) of its own (see the module docs).
pub fn adaptive(mesh: &DisplacedMesh, max_error: f32) -> DisplacedMesh {
    let finest = mesh.uniform_level().expect("one level");
    let errors = coarsening_errors(mesh, finest);
    let levels = choose_levels(&mesh.triangles, &errors, max_error);
    with_levels(mesh, &levels)
}

/// Micro-triangles of each level `0 ..= 6` in `mesh`.
pub fn level_counts(mesh: &DisplacedMesh) -> Vec<u64> {
    let mut counts = vec![0u64; crate::displaced::MAX_LEVEL as usize + 1];
    for t in &mesh.micromap.triangles {
        counts[t.level as usize] += triangle_count(t.level) as u64;
    }
    counts
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bary::values_per_triangle;

    /// A flat strip of four triangles at level 3, bumpy only in the last one.
    fn strip() -> DisplacedMesh {
        let positions = (0..6)
            .map(|k| Vec3::new((k / 2) as f32, (k % 2) as f32, 0.0))
            .collect::<Vec<_>>();
        let triangles = vec![[0, 2, 1], [1, 2, 3], [2, 4, 3], [3, 4, 5]];
        let n = grid_size(3);
        let values = |t: usize| {
            let mut v = vec![1000u16; values_per_triangle(3)];
            if t == 3 {
                for [i, j] in lattice_points(n) {
                    if i > 0 && j > 0 && i + j < n {
                        v[u_major_index([i, j], n) as usize] = 1000 + ((i * 7 + j * 13) % 5) as u16 * 200;
                    }
                }
            }
            (3, v)
        };
        DisplacedMesh {
            directions: vec![Vec3::Z; 6],
            positions,
            triangles,
            micromap: Micromap::from_triangles(0.0, 0.1, &(0..4).map(values).collect::<Vec<_>>()),
            decimated_edges: Vec::new(),
        }
    }

    /// Flat triangles go as coarse as their neighbours allow; the bumpy one stays fine; levels
    /// step by one across edges, and the finer side of each step decimates it.
    #[test]
    fn flat_triangles_coarsen_and_neighbours_stay_within_a_level() {
        let mesh = strip();
        let errors = coarsening_errors(&mesh, 3);
        assert!(errors[0].iter().all(|&e| e < 1e-6), "{:?}", errors[0]);
        assert!(errors[3][2] > 0.01);
        let levels = choose_levels(&mesh.triangles, &errors, 1e-4);
        assert_eq!(levels, vec![0, 1, 2, 3]);
        let adaptive = adaptive(&mesh, 1e-4);
        adaptive.check().unwrap();
        // Each finer triangle flags its edge towards the coarser one: 1-2 is triangle 1's
        // edge 0, 3-2 triangle 2's edge 2, 3-4 triangle 3's edge 0.
        assert_eq!(adaptive.decimated_edges, vec![0, 0b001, 0b100, 0b001]);
        // The surface is the same up to the bound, and watertight where levels change.
        let (welded, _) = crate::mesh::WorldMesh::from(adaptive.decoded())
            .validate("adaptive")
            .unwrap();
        let mut uses: HashMap<(u32, u32), u32> = HashMap::new();
        for t in &welded.triangles {
            for e in 0..3 {
                let (a, b) = (t[e], t[(e + 1) % 3]);
                *uses.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        // The strip's outline only, each side at its triangle's level: triangle 0's bottom
        // and left (1 + 1), 1's top (2), 2's bottom (4), 3's right and top (8 + 8).
        let boundary = uses.values().filter(|&&u| u == 1).count();
        assert_eq!(boundary, 1 + 1 + 2 + 4 + 8 + 8);
    }
}
