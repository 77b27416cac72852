//! The bird-curve order of a triangle's values (BaryFile's `eTriangleBirdCurve` layout), as
//! positions in the u-major order gridrt reads.
//!
//! The bird curve is a space-filling curve over a triangle's micro-triangles, defined by
//! recursion: a triangle of ordered corners `(A, B, C)` is walked as its sub-triangle at `A`,
//! its middle one, its sub-triangle at `B`, then its sub-triangle at `C`, whose ordered
//! corners are `(A, AB, AC)`, `(AC, BC, AB)`, `(AB, B, BC)` and `(BC, AC, C)` (`AB` the
//! midpoint of `A` and `B`), from the base triangle's `(W, U, V)`. Its vertices come level by
//! level, as subdivision makes them: the three corners `W`, `U`, `V`, then for each level `l`
//! the upright triangles of level `l - 1` in curve order (those oriented as the base, which
//! between them hold every edge once), each giving its edges' midpoints `WV`, `UV`, `WU`.

use gridrt_shared::displacement::u_major_index;
use gridrt_shared::grid_index::{grid_size, Lattice};

/// A triangle's corners in lattice coordinates `[u, v]`, in curve order.
pub type Corners = [Lattice; 3];

fn midpoint(a: Lattice, b: Lattice) -> Lattice {
    [(a[0] + b[0]) / 2, (a[1] + b[1]) / 2]
}

/// The triangles of `level` in curve order, in coordinates of the level's lattice.
pub fn triangles(level: u32) -> Vec<Corners> {
    let n = grid_size(level);
    let mut triangles = vec![[[0, 0], [n, 0], [0, n]]];
    for _ in 0..level {
        triangles = (triangles.iter())
            .flat_map(|&[a, b, c]| {
                let (ab, ac, bc) = (midpoint(a, b), midpoint(a, c), midpoint(b, c));
                [[a, ab, ac], [ac, bc, ab], [ab, b, bc], [bc, ac, c]]
            })
            .collect();
    }
    triangles
}

/// The vertices of a level-`level` triangle in bird-curve order, as points of its lattice.
pub fn points(level: u32) -> Vec<Lattice> {
    let n = grid_size(level);
    let mut order = vec![[0, 0], [n, 0], [0, n]];
    for l in 1..=level {
        // Level `l - 1`'s lattice, doubled so that its midpoints are whole, and how much
        // finer the finest lattice is than that.
        let scale = 1 << (level - l);
        for [a, b, c] in triangles(l - 1) {
            let [a, b, c] = [a, b, c].map(|p| [2 * p[0], 2 * p[1]]);
            // Upright: its corners, in any order, are W, U = W + (1, 0), V = W + (0, 1).
            let w = [a, b, c]
                .into_iter()
                .min_by_key(|p| p[0] + p[1])
                .expect("three corners");
            let (u, v) = ([w[0] + 2, w[1]], [w[0], w[1] + 2]);
            let mut corners = [a, b, c];
            corners.sort();
            let mut upright = [w, u, v];
            upright.sort();
            if corners != upright {
                continue;
            }
            for p in [midpoint(w, v), midpoint(u, v), midpoint(w, u)] {
                order.push([p[0] * scale, p[1] * scale]);
            }
        }
    }
    order
}

/// For each value of a level-`level` triangle in bird-curve order, its position in u-major
/// order.
pub fn u_major_positions(level: u32) -> Vec<u32> {
    let n = grid_size(level);
    points(level).into_iter().map(|p| u_major_index(p, n)).collect()
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::micromesh::bary::values_per_triangle;

    /// Bird-curve index of each value in u-major order, as the reference implementation in
    /// NVIDIA's BaryFile library (`baryValueLayoutGetIndex`) gives them.
    pub(crate) const REFERENCE: [&[u32]; 4] = [
        &[0, 2, 1],
        &[0, 3, 2, 5, 4, 1],
        &[0, 6, 3, 12, 2, 8, 7, 14, 13, 5, 9, 4, 11, 10, 1],
        &[
            0, 15, 6, 21, 3, 39, 12, 42, 2, 17, 16, 23, 22, 41, 40, 44, 43, 8, 18, 7, 24, 14, 36, 13, 20, 19, 26, 25,
            38, 37, 5, 27, 9, 33, 4, 29, 28, 35, 34, 11, 30, 10, 32, 31, 1,
        ],
    ];

    #[test]
    fn the_order_is_the_reference_implementations() {
        for (level, reference) in REFERENCE.iter().enumerate() {
            let positions = u_major_positions(level as u32);
            let mut bird_of = vec![u32::MAX; positions.len()];
            for (bird, &u_major) in positions.iter().enumerate() {
                bird_of[u_major as usize] = bird as u32;
            }
            assert_eq!(&bird_of[..], *reference, "level {level}");
        }
    }

    #[test]
    fn every_value_comes_once() {
        for level in 0..=6 {
            let mut positions = u_major_positions(level);
            positions.sort();
            let all: Vec<u32> = (0..values_per_triangle(level) as u32).collect();
            assert_eq!(positions, all, "level {level}");
        }
    }
}
