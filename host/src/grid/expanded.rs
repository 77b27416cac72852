//! Displaced micro-meshes of mixed levels laid out on the deepest level's lattice, as
//! displaced grids hold them, plain or compressed: each triangle keeps its own level's values
//! at the matching points of the deeper lattice, the points between them are the means of
//! their parents (which compressed values predict exactly, so they cost no correction), and a
//! base edge holds the values of the triangle that renders it finest, so both sides of it
//! read the same bits.

use gridrt_shared::displacement::{decimated_grid_point, u_major_index};
use gridrt_shared::grid_index::{edge_point, grid_size, lattice_points, parents, Lattice};

use super::BaseEdges;
use crate::micromesh::DisplacedMesh;

/// `mesh` (ranges folded, of mixed levels) with every triangle at the deepest level, as
/// displaced grids of mixed levels hold it: each triangle's own values at its own level's
/// points of the deeper lattice, the points between them filled (see [`expanded_values`]),
/// and on each base edge the values of the triangle that renders it finest (see
/// [`edge_sources`]), so that every triangle holds the same values there and each finds
/// the points it renders. The decimated edges are left to [`DisplacedMesh::own_levels`].
pub(crate) fn expanded_mesh(mesh: &DisplacedMesh) -> DisplacedMesh {
    let levels = mesh.deepest_level().unwrap_or(0);
    let n = grid_size(levels);
    let edges = BaseEdges::new(&mesh.base_mesh());
    let mut values: Vec<Vec<u16>> = (0..mesh.triangles.len())
        .map(|g| expanded_values(mesh, g, levels))
        .collect();
    let sources = edge_sources(&edges, mesh);
    for (g, ids) in edges.of_grid.iter().enumerate() {
        for (e, &id) in ids.iter().enumerate() {
            let (sg, se) = sources[id as usize];
            if sg == g {
                continue;
            }
            let (t, ts) = (mesh.triangles[g], mesh.triangles[sg]);
            let along = t[e] == ts[se];
            for k in 1..n {
                let from = edge_point(se as u32, if along { k } else { n - k }, n);
                values[g][u_major_index(edge_point(e as u32, k, n), n) as usize] =
                    values[sg][u_major_index(from, n) as usize];
            }
        }
    }
    let triangles: Vec<(u32, Vec<u16>)> = values.into_iter().map(|v| (levels, v)).collect();
    let mut micromap = crate::micromesh::bary::Micromap::from_triangles(0.0, 1.0, &triangles);
    micromap.value_code = mesh.micromap.value_code;
    DisplacedMesh {
        positions: mesh.positions.clone(),
        directions: mesh.directions.clone(),
        triangles: mesh.triangles.clone(),
        micromap,
        decimated_edges: Vec::new(),
    }
}

/// Triangle `g`'s values on the scene's level-`levels` lattice, in u-major order: its own
/// level's at the points of that level, and each point between them the mean of the two
/// coarser points it halves (rounded up), finer after coarser, as compressed values predict
/// a point (see `gridrt_shared::compressed_values`), so that their corrections are zero. A
/// point on a base edge has its parents on that edge, so the values on an edge follow from
/// that edge's alone.
fn expanded_values(mesh: &DisplacedMesh, g: usize, levels: u32) -> Vec<u16> {
    let own = mesh.micromap.triangles[g].level;
    let (n, shift) = (grid_size(levels), levels - own);
    let values = mesh.micromap.triangle_values(g);
    let mut out = vec![0u16; crate::micromesh::bary::values_per_triangle(levels)];
    for [i, j] in lattice_points(grid_size(own)) {
        out[u_major_index([i << shift, j << shift], n) as usize] =
            values[u_major_index([i, j], grid_size(own)) as usize];
    }
    // The odd points of decimated edges render nowhere (their grid renders the even ones in
    // their place, as does its coarser neighbour): they are filled like the finer points.
    let fill = |out: &mut [u16], p: Lattice, step: u32| {
        let [a, b] = parents(p, step);
        let sum = out[u_major_index(a, n) as usize] as u32 + out[u_major_index(b, n) as usize] as u32;
        out[u_major_index(p, n) as usize] = ((sum + 1) >> 1) as u16;
    };
    let decimated = mesh.decimated(g);
    for p in lattice_points(n) {
        if decimated_grid_point(p, n, shift, decimated) != p {
            fill(&mut out, p, 1 << shift);
        }
    }
    for h in (0..shift).rev().map(|k| 1u32 << k) {
        for p in lattice_points(n).filter(|&p| new_at_spacing(p, h)) {
            fill(&mut out, p, h);
        }
    }
    out
}

/// Whether lattice point `p` is on the lattice of spacing `h` but not on the one of `2 h`.
pub(super) fn new_at_spacing([i, j]: Lattice, h: u32) -> bool {
    (i | j) % h == 0 && (i | j) & h != 0
}

/// For each base edge, the grid and edge within it whose values the edge area stores: the
/// grid that renders the edge finest (its own level, one less where its edge is decimated),
/// so every grid finds there the points it renders. The owners where levels are one.
fn edge_sources(edges: &BaseEdges, mesh: &DisplacedMesh) -> Vec<(usize, usize)> {
    let mut sources = edges.owner.clone();
    if mesh.uniform_level().is_some() {
        return sources;
    }
    let rendered = |g: usize, e: usize| mesh.rendered_edge_level(g, e);
    for (g, ids) in edges.of_grid.iter().enumerate() {
        for (e, &id) in ids.iter().enumerate() {
            let (sg, se) = sources[id as usize];
            if rendered(g, e) > rendered(sg, se) {
                sources[id as usize] = (g, e);
            }
        }
    }
    sources
}
