//! Where a grid's lattice points live in a buffer: its ids (see [`GridIds`]) resolved, once
//! per visit, into the arithmetic that finds each point's slot in the inner area of its own,
//! the edge area (each base edge's points stored once, so neighbours read the same ones) or
//! the corner area. Nothing is stored but the ids.

use crate::grid_index::{inner_index, Lattice};
use crate::layout::GridIds;

/// A grid's ids resolved, once per visit, into the arithmetic that finds its vertices.
/// Addresses count in any unit: vertex slots (one per vertex), or buffer words or halves
/// (`stride` per vertex), so the traversal gets buffer positions without converting.
#[derive(Copy, Clone)]
pub struct GridSlots {
    n: u32,
    inner_first: u32,
    stride: u32,
    /// How many levels coarser than the lattice of size `n` the inner area (bits 0 to 3) and
    /// each edge's area (four bits each from bit 4) hold their points: they hold the
    /// multiples of `2^shift`. Zero but in displaced grids of mixed levels.
    shifts: u32,
    corners: [u32; 3],
    /// Address of step 0 along each edge, and the step between addresses (`+stride` or
    /// `-stride` as a wrapping `u32`), so a reversed edge needs no branch.
    edge_start: [u32; 3],
    edge_step: [u32; 3],
}

/// Where a grid's areas begin, each of its own level (see [`GridSlots::leveled`]).
#[derive(Copy, Clone)]
pub struct LeveledAreas {
    /// The grid's first inner point, and how many levels coarser than the grid's lattice its
    /// inner area is.
    pub inner_first: u32,
    pub inner_shift: u32,
    /// Each edge's first point (from its lower corner id), and how many levels coarser.
    pub edge_first: [u32; 3],
    pub edge_shifts: [u32; 3],
    /// The first point of the corner area.
    pub corner_first: u32,
    /// Units per point.
    pub stride: u32,
}

impl GridSlots {
    /// Vertex slots: the inner area of `grid` at `grid * inner_count`, then the edge area at
    /// `edge_offset`, then the corner area at `corner_offset`.
    #[inline]
    pub fn new(ids: &GridIds, grid: u32, n: u32, inner_count: u32, edge_offset: u32, corner_offset: u32) -> Self {
        Self::addressed(ids, n, grid * inner_count, edge_offset, corner_offset, 1)
    }

    /// Addresses of `stride` units per vertex: the grid's first inner vertex at
    /// `inner_first`, the first vertex of the edge area at `edge_first`, the first of the
    /// corner area at `corner_first`.
    #[inline]
    pub fn addressed(ids: &GridIds, n: u32, inner_first: u32, edge_first: u32, corner_first: u32, stride: u32) -> Self {
        let edge = |e: u32| edge_first + ids.edge(e) * (n - 1) * stride;
        Self::leveled(
            ids,
            n,
            LeveledAreas {
                inner_first,
                inner_shift: 0,
                edge_first: [edge(0), edge(1), edge(2)],
                edge_shifts: [0; 3],
                corner_first,
                stride,
            },
        )
    }

    /// Addresses of a grid on a lattice of size `n` whose areas each hold the points of a
    /// coarser level of it (a displaced grid of mixed levels): `areas` says where and which.
    #[inline]
    pub fn leveled(ids: &GridIds, n: u32, areas: LeveledAreas) -> Self {
        let stride = areas.stride;
        let edge = |e: u32| {
            let base = areas.edge_first[e as usize];
            let points = (n >> areas.edge_shifts[e as usize]) - 1;
            if ids.edge_reversed(e) {
                // Step s is stored at points - s.
                (base + points * stride, stride.wrapping_neg())
            } else {
                (base.wrapping_sub(stride), stride)
            }
        };
        let (e0, e1, e2) = (edge(0), edge(1), edge(2));
        let [s0, s1, s2] = areas.edge_shifts;
        GridSlots {
            n,
            inner_first: areas.inner_first,
            stride,
            shifts: areas.inner_shift | s0 << 4 | s1 << 8 | s2 << 12,
            corners: [
                areas.corner_first + ids.corner(0) * stride,
                areas.corner_first + ids.corner(1) * stride,
                areas.corner_first + ids.corner(2) * stride,
            ],
            edge_start: [e0.0, e1.0, e2.0],
            edge_step: [e0.1, e1.1, e2.1],
        }
    }

    /// Where the vertex at lattice point `(i, j)` lives in the vertex buffer: the grid's own
    /// inner area, the shared area of one of its base edges, or the shared corner area. A
    /// point of an area that holds a coarser level must be one of that level's.
    #[inline]
    pub fn slot(&self, p: Lattice) -> u32 {
        let [i, j] = p;
        let n = self.n;
        let k = n - i - j;
        let along = |e: usize, s: u32| {
            let shift = (self.shifts >> (4 * e + 4)) & 15;
            self.edge_start[e].wrapping_add((s >> shift).wrapping_mul(self.edge_step[e]))
        };
        // The inside first (most of a leaf's vertices), then the corners and the three edges.
        if i != 0 && j != 0 && k != 0 {
            let shift = self.shifts & 15;
            self.inner_first + inner_index(i >> shift, j >> shift, n >> shift) * self.stride
        } else if i == 0 && j == 0 {
            self.corners[0]
        } else if i == n {
            self.corners[1]
        } else if j == n {
            self.corners[2]
        } else if j == 0 {
            along(0, i)
        } else if k == 0 {
            along(1, j)
        } else {
            along(2, k)
        }
    }
}

/// [`GridSlots::slot`] for a single look-up.
#[inline]
pub fn vertex_slot(
    p: Lattice,
    n: u32,
    grid: u32,
    ids: &GridIds,
    inner_count: u32,
    edge_offset: u32,
    corner_offset: u32,
) -> u32 {
    GridSlots::new(ids, grid, n, inner_count, edge_offset, corner_offset).slot(p)
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::grid_index::{edge_vertex_count, grid_size, inner_vertex_count, lattice_points, vertex_count};
    use crate::layout::MAX_HEADER_ID;
    use std::collections::BTreeSet;

    /// Every lattice point of a grid lands in a distinct slot, and the slots fill the inner,
    /// edge and corner areas exactly, for both orientations of every edge.
    #[test]
    fn vertex_slots_are_a_bijection() {
        for levels in 1..=5 {
            let n = grid_size(levels);
            let inner = inner_vertex_count(levels);
            let edge = edge_vertex_count(levels);
            // Every order of the corner ids, so every edge is walked both ways.
            for corners in [[4u32, 1, 7], [1, 4, 7], [7, 4, 1], [1, 7, 4], [4, 7, 1], [7, 1, 4]] {
                let header = GridIds {
                    edges: [2, 5, 0],
                    corners,
                };
                let (grid, edge_offset, corner_offset) = (3, 1000, 5000);
                let slots: BTreeSet<u32> = lattice_points(n)
                    .map(|p| vertex_slot(p, n, grid, &header, inner, edge_offset, corner_offset))
                    .collect();
                assert_eq!(slots.len() as u32, vertex_count(levels));
                let mut expected = BTreeSet::new();
                expected.extend((0..inner).map(|k| grid * inner + k));
                for id in [2u32, 5, 0] {
                    expected.extend((0..edge).map(|k| edge_offset + id * edge + k));
                }
                expected.extend([4u32, 1, 7].map(|c| corner_offset + c));
                assert_eq!(slots, expected, "levels {levels} corners {corners:?}");
            }
        }
    }

    /// A reversed edge is read backwards: the vertex `s` steps from corner 0 on edge 0 is the
    /// one `n - s` steps from the other end when the corner ids are swapped.
    #[test]
    fn reversed_edges_read_backwards() {
        let n = 8;
        let fwd = GridIds {
            edges: [0, 1, 2],
            corners: [3, 4, 5],
        };
        let back = GridIds {
            edges: [0, 1, 2],
            corners: [4, 3, 5],
        };
        assert!(!fwd.edge_reversed(0) && back.edge_reversed(0));
        for s in 1..n {
            let a = vertex_slot([s, 0], n, 0, &fwd, 21, 100, 200);
            let b = vertex_slot([n - s, 0], n, 0, &back, 21, 100, 200);
            assert_eq!(a, b);
        }
    }

    /// Ids survive both header forms: packed up to 21 bits, wide up to 32.
    #[test]
    fn header_ids_round_trip() {
        let ids = [
            [0, 1, 2],
            [MAX_HEADER_ID, 0, MAX_HEADER_ID],
            [1 << 20, (1 << 11) + 5, 2047],
            [77, 3 << 19, 9],
        ];
        for edges in ids {
            for corners in ids {
                let g = GridIds { edges, corners };
                assert_eq!(g.pack().ids(), g);
                let [a, b] = g.pack_wide();
                assert_eq!(GridIds::from_wide(a, b), g);
            }
        }
        let wide = GridIds {
            edges: [u32::MAX, 1 << 21, 5],
            corners: [1 << 30, 0, u32::MAX - 1],
        };
        let [a, b] = wide.pack_wide();
        assert_eq!(GridIds::from_wide(a, b), wide);
    }
}
