//! Implicit indexing of a grid primitive: nothing here is stored, everything is arithmetic.
//!
//! A grid is a base triangle subdivided `L` times. Its vertices sit on a triangular lattice
//! `(i, j)`, `i, j >= 0`, `i + j <= n` with `n = 2^L`; corner 0 is `(0, 0)`, corner 1 `(n, 0)`,
//! corner 2 `(0, n)`, and the position of `(i, j)` belongs to the barycentric point
//! `(1 - (i + j) / n, i / n, j / n)` of the base triangle.
//!
//! Sub-triangles follow the subdivision recursion: the children of `(a, b, c)` with edge
//! midpoints `ab`, `bc`, `ca` are `(a, ab, ca)`, `(ab, b, bc)`, `(ca, bc, c)` and the inverted
//! middle `(bc, ca, ab)`, all with the parent's winding. A sub-triangle at level `l` is named by
//! its index `p < 4^l`, whose base-4 digits (most significant first) are the children taken
//! from the root. In breadth-first order its node id is `(4^l - 1) / 3 + p`, so the children of
//! node `id` are `4 id + 1 ..= 4 id + 4`.

/// A lattice point `(i, j)` of a grid.
pub type Lattice = [u32; 2];

/// Lattice edge length of a grid of depth `levels`.
#[inline]
pub const fn grid_size(levels: u32) -> u32 {
    1 << levels
}

/// All lattice vertices of a grid, corners and edges included.
#[inline]
pub const fn vertex_count(levels: u32) -> u32 {
    let n = grid_size(levels);
    (n + 1) * (n + 2) / 2
}

/// Vertices strictly inside a grid (owned by that grid alone).
#[inline]
pub const fn inner_vertex_count(levels: u32) -> u32 {
    let n = grid_size(levels);
    if n < 3 {
        0
    } else {
        (n - 1) * (n - 2) / 2
    }
}

/// Vertices strictly inside one base edge.
#[inline]
pub const fn edge_vertex_count(levels: u32) -> u32 {
    grid_size(levels) - 1
}

/// Micro-triangles of a grid rendered at depth `levels`.
#[inline]
pub const fn triangle_count(levels: u32) -> u32 {
    1 << (2 * levels)
}

/// First breadth-first node id of `level`: `(4^level - 1) / 3`.
#[inline]
pub const fn level_start(level: u32) -> u32 {
    ((1u32 << (2 * level)) - 1) / 3
}

/// Spheres stored per grid when levels `0 ..= leaf_level` have one.
#[inline]
pub const fn sphere_count(leaf_level: u32) -> u32 {
    level_start(leaf_level + 1)
}

/// Row-major position of `(i, j)` among all lattice vertices (rows of constant `j`).
#[inline]
pub const fn lattice_index(i: u32, j: u32, n: u32) -> u32 {
    j * (n + 1) - (j * j - j) / 2 + i
}

/// All lattice points of a grid of size `n`, in [`lattice_index`] order.
pub fn lattice_points(n: u32) -> impl Iterator<Item = Lattice> {
    (0..=n).flat_map(move |j| (0..=n - j).map(move |i| [i, j]))
}

/// The lattice points strictly inside a grid of size `n`, in [`inner_index`] order.
pub fn inner_points(n: u32) -> impl Iterator<Item = Lattice> {
    (1..n.saturating_sub(1)).flat_map(move |j| (1..n - j).map(move |i| [i, j]))
}

/// The inverse of [`lattice_index`].
pub const fn lattice_from_index(index: u32, n: u32) -> Lattice {
    let mut j = 0;
    let mut start = 0;
    while start + (n + 1 - j) <= index {
        start += n + 1 - j;
        j += 1;
    }
    [index - start, j]
}

#[inline]
const fn midpoint(a: Lattice, b: Lattice) -> Lattice {
    [(a[0] + b[0]) / 2, (a[1] + b[1]) / 2]
}

/// The two lattice points whose midpoint is `p`, a point new at spacing `h` (a multiple of
/// `h`, not of `2 h`, in one coordinate at least): the ends of the coarser edge it halves.
/// Values that are predicted level by level are predicted from these, on both targets.
#[inline]
pub const fn parents(p: Lattice, h: u32) -> [Lattice; 2] {
    let [i, j] = p;
    if j & h == 0 {
        [[i - h, j], [i + h, j]]
    } else if i & h == 0 {
        [[i, j - h], [i, j + h]]
    } else {
        [[i - h, j + h], [i + h, j - h]]
    }
}

/// The lattice point of a grid's corner `c` (0..3) in a lattice of side `n`.
#[inline]
pub const fn corner_point(c: u32, n: u32) -> Lattice {
    if c == 0 {
        [0, 0]
    } else if c == 1 {
        [n, 0]
    } else {
        [0, n]
    }
}

/// The lattice point `step` steps along a grid's edge `e` (0..3), from corner `e` towards
/// corner `e + 1`, in a lattice of side `n`: step 0 is corner `e`, step `n` corner `e + 1`.
#[inline]
pub const fn edge_point(e: u32, step: u32, n: u32) -> Lattice {
    if e == 0 {
        [step, 0]
    } else if e == 1 {
        [n - step, step]
    } else {
        [0, n - step]
    }
}

/// Corners of child `digit` (0..4) of the sub-triangle `(a, b, c)`.
#[inline]
pub const fn child_corners(corners: [Lattice; 3], digit: u32) -> [Lattice; 3] {
    let [a, b, c] = corners;
    let ab = midpoint(a, b);
    let bc = midpoint(b, c);
    let ca = midpoint(c, a);
    if digit == 0 {
        [a, ab, ca]
    } else if digit == 1 {
        [ab, b, bc]
    } else if digit == 2 {
        [ca, bc, c]
    } else {
        [bc, ca, ab]
    }
}

/// Lattice corners of sub-triangle `index` at `level` of a grid with lattice size `n`.
#[inline]
pub const fn sub_triangle(n: u32, level: u32, index: u32) -> [Lattice; 3] {
    let mut corners = [[0, 0], [n, 0], [0, n]];
    let mut l = level;
    while l > 0 {
        l -= 1;
        corners = child_corners(corners, (index >> (2 * l)) & 3);
    }
    corners
}

/// Deepest leaf resolution the static triangle list covers: a leaf holds up to `4^3` triangles.
pub const MAX_LEAF_DEPTH: u32 = 3;

/// Offset of the `4^k` triangles of a depth-`k` leaf in [`MICRO_TRIANGLES`].
#[inline]
pub const fn micro_table_offset(k: u32) -> u32 {
    level_start(k)
}

/// Words of the triangle lists in [`MICRO_TRIANGLES`]; the cell tables follow.
const TRIANGLE_LISTS: u32 = level_start(MAX_LEAF_DEPTH + 1);

/// Offset in [`MICRO_TRIANGLES`] of the cell table of a depth-`k` leaf: two words per lattice
/// point `p` (its [`lattice_index`]), for the upright cell `(la, lb), (la + 1, lb), (la, lb +
/// 1)` at `2 p` and the inverted cell `(la + 1, lb), (la, lb + 1), (la + 1, lb + 1)` at
/// `2 p + 1`. Each holds the micro-triangle covering that cell as its triangle-list entry
/// with its index `t` in bits 24 and up.
///
/// In closed form, since every leaf test asks: the tables before depth `k` hold
/// `sum_{j<k} (2^j + 1)(2^j + 2) = (4^k - 1) / 3 + 3 (2^k - 1) + 2 k` words.
#[inline]
pub const fn micro_cell_offset(k: u32) -> u32 {
    TRIANGLE_LISTS + level_start(k) + 3 * ((1 << k) - 1) + 2 * k
}

/// The static index list: for every leaf depth `k <= MAX_LEAF_DEPTH`, the `4^k` triangles of a
/// sub-triangle subdivided `k` times, in recursion order, as the [`lattice_index`] of each
/// corner in the sub-triangle's own lattice (`2^k` steps a side), eight bits each: corner `c`
/// in bits `8c .. 8c + 8`; then the same triangles by lattice cell (see
/// [`micro_cell_offset`]), so a leaf can test just the cells around the ray. A leaf loads its
/// vertices once; the list then names each triangle's three. The same list serves every grid,
/// every leaf and every level of detail.
pub const MICRO_TRIANGLES: [u32; micro_cell_offset(MAX_LEAF_DEPTH + 1) as usize] = build_micro_triangles();

const fn build_micro_triangles() -> [u32; micro_cell_offset(MAX_LEAF_DEPTH + 1) as usize] {
    let mut table = [0u32; micro_cell_offset(MAX_LEAF_DEPTH + 1) as usize];
    let mut k = 0;
    while k <= MAX_LEAF_DEPTH {
        let m = 1 << k;
        let mut t = 0;
        while t < triangle_count(k) {
            let c = sub_triangle(m, k, t);
            let mut packed = 0;
            let mut v = 0;
            // The cell's anchor: the smallest coordinates among the corners.
            let (mut la, mut lb) = (m, m);
            while v < 3 {
                packed |= lattice_index(c[v][0], c[v][1], m) << (8 * v);
                if c[v][0] < la {
                    la = c[v][0];
                }
                if c[v][1] < lb {
                    lb = c[v][1];
                }
                v += 1;
            }
            table[(micro_table_offset(k) + t) as usize] = packed;
            // Upright cells contain their anchor, inverted ones do not.
            let upright = (c[0][0] == la && c[0][1] == lb)
                || (c[1][0] == la && c[1][1] == lb)
                || (c[2][0] == la && c[2][1] == lb);
            let cell = 2 * lattice_index(la, lb, m) + !upright as u32;
            table[(micro_cell_offset(k) + cell) as usize] = packed | (t << 24);
            t += 1;
        }
        k += 1;
    }
    table
}

/// Lattice corners of micro-triangle `t` of a leaf sub-triangle `leaf` subdivided `k` more
/// times, read from the static list.
#[inline]
pub fn leaf_triangle(leaf: [Lattice; 3], k: u32, t: u32) -> [Lattice; 3] {
    let packed = MICRO_TRIANGLES[(micro_table_offset(k) + t) as usize];
    let m = 1 << k;
    let [a, b, c] = leaf;
    // Edge vectors of the leaf, per unit of the local lattice (exact: they are multiples of m).
    let e1 = [(b[0] as i32 - a[0] as i32) / m, (b[1] as i32 - a[1] as i32) / m];
    let e2 = [(c[0] as i32 - a[0] as i32) / m, (c[1] as i32 - a[1] as i32) / m];
    let mut out = [[0u32; 2]; 3];
    let mut v = 0;
    while v < 3 {
        let [la, lb] = lattice_from_index((packed >> (8 * v)) & 0xff, m as u32);
        let (la, lb) = (la as i32, lb as i32);
        out[v] = [
            (a[0] as i32 + la * e1[0] + lb * e2[0]) as u32,
            (a[1] as i32 + la * e1[1] + lb * e2[1]) as u32,
        ];
        v += 1;
    }
    out
}

/// Index of inner vertex `(i, j)` (`i, j >= 1`, `i + j <= n - 1`) within its grid: rows of
/// constant `j`, row `j` holding `n - 1 - j` vertices.
#[inline]
pub const fn inner_index(i: u32, j: u32, n: u32) -> u32 {
    let r = j - 1;
    r * (n - 1) - r * (r + 1) / 2 + (i - 1)
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::collections::BTreeSet;
    use std::vec::Vec;

    fn lattice(n: u32) -> Vec<Lattice> {
        lattice_points(n).collect()
    }

    #[test]
    fn lattice_index_is_a_bijection() {
        for levels in 0..=5 {
            let n = grid_size(levels);
            for (k, p) in lattice(n).into_iter().enumerate() {
                assert_eq!(lattice_index(p[0], p[1], n), k as u32);
                assert_eq!(lattice_from_index(k as u32, n), p);
            }
        }
    }

    /// The level-L sub-triangles are exactly the micro-triangles of the lattice, each once:
    /// `n^2` distinct triangles with unit edges, all with the base winding.
    #[test]
    fn sub_triangles_tile_the_grid() {
        for levels in 0..=5 {
            let n = grid_size(levels);
            let mut seen = BTreeSet::new();
            for t in 0..triangle_count(levels) {
                let c = sub_triangle(n, levels, t);
                let area2 = (c[1][0] as i64 - c[0][0] as i64) * (c[2][1] as i64 - c[0][1] as i64)
                    - (c[2][0] as i64 - c[0][0] as i64) * (c[1][1] as i64 - c[0][1] as i64);
                assert_eq!(area2, 1, "unit area and counter-clockwise");
                let mut key = c;
                key.sort();
                assert!(seen.insert(key), "triangle {t} at level {levels} repeated");
            }
            assert_eq!(seen.len() as u32, n * n);
        }
    }

    /// Children of BFS node `id` are `4 id + 1 ..= 4 id + 4` and lie inside their parent.
    #[test]
    fn breadth_first_numbering() {
        let n = grid_size(5);
        for level in 0..4 {
            for p in 0..triangle_count(level) {
                let id = level_start(level) + p;
                for c in 0..4 {
                    assert_eq!(level_start(level + 1) + 4 * p + c, 4 * id + 1 + c);
                    let child = sub_triangle(n, level + 1, 4 * p + c);
                    assert_eq!(child, child_corners(sub_triangle(n, level, p), c));
                }
            }
        }
        assert_eq!(sphere_count(1), 5);
        assert_eq!(sphere_count(0), 1);
    }

    /// The static list gives the same micro-triangles, in the same order and with the same
    /// corner order, as walking the recursion from the root, for every leaf and depth.
    #[test]
    fn static_list_matches_the_recursion() {
        for levels in 0..=5u32 {
            let n = grid_size(levels);
            for leaf_level in 0..=levels {
                let k = levels - leaf_level;
                if k > MAX_LEAF_DEPTH {
                    continue;
                }
                for p in 0..triangle_count(leaf_level) {
                    let leaf = sub_triangle(n, leaf_level, p);
                    for t in 0..triangle_count(k) {
                        assert_eq!(
                            leaf_triangle(leaf, k, t),
                            sub_triangle(n, levels, p * triangle_count(k) + t)
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn inner_index_is_dense() {
        for levels in 0..=5 {
            let n = grid_size(levels);
            let mut k = 0;
            for j in 1..n.saturating_sub(1) {
                for i in 1..n - j {
                    assert_eq!(inner_index(i, j, n), k);
                    k += 1;
                }
            }
            assert_eq!(k, inner_vertex_count(levels));
            // The iterator walks them in the same order, and they are the points off every edge.
            let walked: Vec<Lattice> = inner_points(n).collect();
            assert_eq!(walked.len() as u32, k);
            for (k, &[i, j]) in walked.iter().enumerate() {
                assert_eq!(inner_index(i, j, n), k as u32);
            }
            let off_edges = lattice_points(n).filter(|&[i, j]| i > 0 && j > 0 && i + j < n).count();
            assert_eq!(off_edges as u32, k);
        }
    }

    /// Every cell of a leaf's lattice names the static list's triangle on it: the cell's own
    /// three points, as the same entry (same corner order) and the right index; every triangle
    /// lies on exactly one cell.
    #[test]
    fn cell_table_names_each_cells_triangle() {
        for k in 0..=MAX_LEAF_DEPTH {
            let m = 1 << k;
            let mut seen = BTreeSet::new();
            for lb in 0..m {
                for la in 0..m - lb {
                    let p = lattice_index(la, lb, m);
                    let upright = [[la, lb], [la + 1, lb], [la, lb + 1]];
                    let inverted = [[la + 1, lb], [la, lb + 1], [la + 1, lb + 1]];
                    for (half, points) in [(0, upright), (1, inverted)] {
                        if half == 1 && la + lb + 2 > m {
                            continue;
                        }
                        let entry = MICRO_TRIANGLES[(micro_cell_offset(k) + 2 * p + half) as usize];
                        let t = entry >> 24;
                        assert!(t < triangle_count(k));
                        assert_eq!(
                            entry & 0xff_ffff,
                            MICRO_TRIANGLES[(micro_table_offset(k) + t) as usize],
                            "k {k} cell ({la}, {lb}) half {half}"
                        );
                        let mut corners: Vec<u32> = (0..3).map(|v| (entry >> (8 * v)) & 0xff).collect();
                        let mut expected: Vec<u32> = points.iter().map(|q| lattice_index(q[0], q[1], m)).collect();
                        corners.sort();
                        expected.sort();
                        assert_eq!(corners, expected, "k {k} cell ({la}, {lb}) half {half}");
                        assert!(seen.insert(t), "triangle {t} on two cells");
                    }
                }
            }
            assert_eq!(seen.len() as u32, triangle_count(k));
            // Each depth's table holds two words per lattice point, right after the last.
            assert_eq!(micro_cell_offset(k + 1) - micro_cell_offset(k), 2 * vertex_count(k));
        }
        assert_eq!(micro_cell_offset(0), micro_table_offset(MAX_LEAF_DEPTH + 1));
    }
}
