//! Smooth shading normals for grids, from the lattice alone: nothing is stored per vertex.
//!
//! A grid's micro-vertices sample a smooth surface on a regular triangular lattice, so the
//! surface's two tangents at a lattice point are finite differences of its neighbours'
//! positions. Each corner of the hit micro-triangle gets the normal `d/du x d/dv` from two of
//! the lattice's three edge directions, and the hit's normal interpolates the three with the
//! hit's barycentrics.
//!
//! Inside a grid the differences are central. On a base edge one tangent runs along the edge,
//! whose vertices both grids share, so both sides compute it alike; the other reaches into the
//! grid one-sided, to second order where the lattice leaves room, so the two grids' normals
//! differ only by the surface's higher-order terms and the seam between them stays soft.
//! Each difference weighs its points by their distances (a quadratic through them, by chord
//! length): Loop subdivision spaces the vertices around an extraordinary base vertex (one
//! not shared by six triangles) unevenly, and a stencil that assumes even steps there tilts
//! the tangent out of the surface. Differences are taken at the depth the grid is rendered
//! at (its level of detail), so a coarser grid shades from the vertices it shows.

use crate::buffer::Buffer;
use crate::glam::Vec3;
use crate::grid_index::Lattice;
use crate::grid_traverse::{GridScene, OpenGrid};
use crate::layout::{GridHeader, Hit};
// On the GPU, float methods come from a trait (GLSL.std.450 underneath); natively from core.
#[cfg(target_arch = "spirv")]
use spirv_std::num_traits::Float;

/// Lattice step of edge direction `d`: 0 along `u` `(1, 0)`, 1 along `v` `(0, 1)`, 2 along `w`
/// `(-1, 1)`. Their derivatives pair up into the same normal, `d/du x d/dv`, taken in this
/// order: `u x v = u x (v - u) = v x (v - u)`.
#[inline]
fn direction(d: u32) -> [i32; 2] {
    if d == 0 {
        [1, 0]
    } else if d == 1 {
        [0, 1]
    } else {
        [-1, 1]
    }
}

/// Room a point with lattice coordinates `(i, j, k = m - i - j)`, in steps, has along
/// direction `d`: steps backwards, then forwards, before it leaves the grid. Each direction
/// keeps one coordinate fixed and trades the other two.
#[inline]
fn room(ijk: [u32; 3], d: u32) -> [u32; 2] {
    let [i, j, k] = ijk;
    if d == 0 {
        [i, k]
    } else if d == 1 {
        [j, k]
    } else {
        [j, i]
    }
}

/// How good a difference the room allows: central, one-sided to second order, to first
/// order, none.
#[inline]
fn quality(room: [u32; 2]) -> u32 {
    let [back, forward] = room;
    if back >= 1 && forward >= 1 {
        3
    } else if back >= 2 || forward >= 2 {
        2
    } else if back >= 1 || forward >= 1 {
        1
    } else {
        0
    }
}

/// The two points, in steps along a direction, that the difference the room allows reads:
/// both neighbours (central), the next two forwards or backwards (second order one-sided),
/// or the one neighbour there is (first order, the second offset zero).
#[inline]
fn stencil(room: [u32; 2]) -> [i32; 2] {
    let [back, forward] = room;
    if back >= 1 && forward >= 1 {
        [-1, 1]
    } else if forward >= 2 {
        [1, 2]
    } else if back >= 2 {
        [-1, -2]
    } else if forward >= 1 {
        [1, 0]
    } else {
        [-1, 0]
    }
}

/// A tangent (up to its length) along the direction whose points `offsets` (see [`stencil`])
/// lie at `d0` and `d1` from the point: the derivative at the point of the quadratic through
/// the three, parametrised by chord length.
#[inline]
fn tangent(offsets: [i32; 2], d0: Vec3, d1: Vec3) -> Vec3 {
    if offsets[1] == 0 {
        // First order: towards the one neighbour, or away from it.
        return d0 * offsets[0] as f32;
    }
    if offsets[0] + offsets[1] == 0 {
        // Central, neighbours `h0` behind and `h1` ahead.
        let (h0, h1) = (d0.length(), d1.length());
        return d1 * (h0 * h0) - d0 * (h1 * h1);
    }
    // One-sided, points at `a` and `b > a` along the curve; negated when they lie behind.
    let a = d0.length();
    let b = a + (d1 - d0).length();
    (d0 * (b * b) - d1 * (a * a)) * offsets[0] as f32
}

/// The two directions a point differentiates along, in the order their cross product is
/// taken: the one keeping its smallest coordinate fixed (along the edge, for a point on one),
/// and of the other two the one with the better difference.
#[inline]
fn directions(ijk: [u32; 3]) -> [u32; 2] {
    let [i, j, k] = ijk;
    let first = if j <= i && j <= k {
        0
    } else if i <= k {
        1
    } else {
        2
    };
    let (x, y) = if first == 0 {
        (1, 2)
    } else if first == 1 {
        (0, 2)
    } else {
        (0, 1)
    };
    let second = if quality(room(ijk, y)) > quality(room(ijk, x)) {
        y
    } else {
        x
    };
    if first < second {
        [first, second]
    } else {
        [second, first]
    }
}

impl<H: Buffer<GridHeader>, W: Buffer<u32>> GridScene<'_, H, W> {
    /// The unit smooth normal of `open`'s surface at lattice point `p`, differentiated with
    /// steps of `step` lattice units over a lattice `m` steps a side; zero where the
    /// differences vanish (a degenerate patch).
    fn lattice_normal(&self, open: &OpenGrid, p: Lattice, step: u32, m: u32) -> Vec3 {
        let (i, j) = (p[0] / step, p[1] / step);
        let ijk = [i, j, m - i - j];
        let pair = directions(ijk);
        let stencils = [stencil(room(ijk, pair[0])), stencil(room(ijk, pair[1]))];
        // Positions relative to `p`'s, so a grid far from the origin loses no more than one
        // near it. Each direction's tangent is made as soon as its second point is read, so
        // that no more than one point waits for its pair.
        let mut centre = Vec3::ZERO;
        let (mut first, mut along_first, mut along_second) = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
        // One loop and one vertex read for `p` (pass 0) and the four points, which the shader
        // compiler must not unroll: each read inlines the buffer access, which split scenes
        // and compressed values make long.
        let mut k = 0;
        while k < 5 + self.opaque_zero() as usize {
            let (offset, dir) = if k == 0 {
                (0, [0, 0])
            } else {
                (stencils[(k - 1) / 2][(k - 1) % 2], direction(pair[(k - 1) / 2]))
            };
            // A first-order stencil's second point is not read: it stays zero.
            let mut v = Vec3::ZERO;
            if k == 0 || offset != 0 {
                let q = [
                    (p[0] as i32 + offset * dir[0] * step as i32) as u32,
                    (p[1] as i32 + offset * dir[1] * step as i32) as u32,
                ];
                v = self.vertex(open, q);
                if k == 0 {
                    centre = v;
                } else {
                    v -= centre;
                }
            }
            if k > 0 {
                if k % 2 == 1 {
                    first = v;
                } else {
                    let t = tangent(stencils[k / 2 - 1], first, v);
                    if k == 2 {
                        along_first = t;
                    } else {
                        along_second = t;
                    }
                }
            }
            k += 1;
        }
        let n = along_first.cross(along_second);
        let len2 = n.dot(n);
        if len2 > 0.0 {
            n / len2.sqrt()
        } else {
            Vec3::ZERO
        }
    }

    /// The smooth shading normal at `hit` (a grid hit, see [`Hit`]): the lattice normals of its
    /// micro-triangle's corners at the depth it was rendered at, interpolated with its
    /// barycentrics. A corner whose lattice normal leans more than [`SMOOTH_LIMIT_COS`] away
    /// from the micro-triangle's own takes the triangle's instead: a sliver's corner, whose
    /// two edges nearly line up, has no reliable tangent plane of its own, and one wrong
    /// normal would shade the whole corner of the triangle. Its geometric normal where the
    /// micro-triangle is degenerate.
    pub fn smooth_normal(&self, hit: &Hit) -> Vec3 {
        let geometric = Vec3::from(hit.normal);
        let len2 = geometric.dot(geometric);
        if len2 == 0.0 {
            return geometric;
        }
        let face = geometric / len2.sqrt();
        let level = hit.level;
        let (open, corners) = self.locate(hit.prim, level);
        let step = 1 << (self.params.levels - level);
        let weights = [1.0 - hit.u - hit.v, hit.u, hit.v];
        let mut n = Vec3::ZERO;
        let mut c = 0;
        while c < 3 + self.opaque_zero() as usize {
            let mut corner = self.lattice_normal(&open, corners[c], step, 1 << level);
            if corner.dot(face) < SMOOTH_LIMIT_COS {
                corner = face;
            }
            n += corner * weights[c];
            c += 1;
        }
        n
    }
}

/// Cosine of the largest angle between a corner's smooth normal and its micro-triangle's
/// normal that the smooth normal is used at: 60 degrees, far beyond the facets' angles on a
/// surface the lattice resolves, and below those of folds it does not.
pub const SMOOTH_LIMIT_COS: f32 = 0.5;

#[cfg(test)]
mod tests {
    use super::*;

    /// Every lattice point of every depth up to 6 finds two different directions it can
    /// difference along, and reads only points inside the grid.
    #[test]
    fn every_point_has_two_directions_inside_the_grid() {
        for level in 0..=6u32 {
            let m = 1u32 << level;
            for i in 0..=m {
                for j in 0..=m - i {
                    let ijk = [i, j, m - i - j];
                    let [a, b] = directions(ijk);
                    assert!(a < b, "{ijk:?}");
                    for d in [a, b] {
                        let r = room(ijk, d);
                        assert!(quality(r) > 0, "{ijk:?} along {d}");
                        for offset in stencil(r) {
                            let s = direction(d);
                            let (qi, qj) = (i as i32 + offset * s[0], j as i32 + offset * s[1]);
                            assert!(qi >= 0 && qj >= 0 && qi + qj <= m as i32, "{ijk:?} along {d}");
                        }
                    }
                }
            }
        }
    }

    /// On a curve sampled at uneven steps, every tangent points along the curve's derivative
    /// (exactly for a quadratic in chord length; here a parabola, closely).
    #[test]
    fn tangents_follow_unevenly_sampled_curves() {
        let curve = |s: f32| Vec3::new(s, 0.3 * s * s, 0.0);
        let along = Vec3::new(1.0, 0.3, 0.0).normalize(); // the derivative at s = 0.5
        for (offsets, at) in [([-1, 1], [0.3, 0.8]), ([1, 2], [0.55, 0.7]), ([-1, -2], [0.42, 0.2])] {
            let p = curve(0.5);
            let t = tangent(offsets, curve(at[0]) - p, curve(at[1]) - p).normalize();
            assert!(t.dot(along) > 0.9999, "{offsets:?}: {t}");
        }
        // Even steps: the textbook stencils, (4 p1 - p2 - 3 p0) / 2 and (p1 - p-1) / 2.
        let (d0, d1) = (Vec3::new(1.0, 0.1, 0.0), Vec3::new(2.0, 0.0, 0.0));
        let even = tangent([1, 2], d0, d1);
        assert!(even.normalize().dot((4.0 * d0 - d1).normalize()) > 0.99999);
        let back = Vec3::new(-1.0, 0.1, 0.0);
        assert!(tangent([-1, 1], back, d0).normalize().dot((d0 - back).normalize()) > 0.99999);
    }
}
