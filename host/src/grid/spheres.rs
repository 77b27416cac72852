//! The bottom level's sphere radii: for each sub-triangle down to the leaf level, the largest
//! distance from the mean of its corners (computed exactly as the traversal does) to any
//! micro-vertex inside it. Also the encodings of radii: half floats, or bytes relative to the
//! grid's root.

use gridrt_shared::displacement::decimated_grid_point;
use gridrt_shared::glam::{Vec3, Vec3A};
use gridrt_shared::grid_index::{
    grid_size, inner_points, lattice_index, lattice_points, parents, sub_triangle, triangle_count, Lattice,
};
use gridrt_shared::grid_traverse::sphere_center;
use gridrt_shared::layout::{RADII_F32, RADII_HALF, RADII_RELATIVE};
use gridrt_shared::sphere::{byte_thickness, leaf_radius, leaf_thickness, relative_radius, relative_radius_at};

use super::GridLayout;
use crate::bvh::Aabb;

/// Which lattice points every sphere of a grid covers: the same for all grids of a build, so
/// worked out once, and each grid's radii are then a plain loop over its gathered points.
pub(super) struct SphereTable {
    /// Lattice index of each inner vertex (in the order the inner area stores them), and the
    /// lattice points on the grid's boundary (corners and edges) with their lattice indices.
    inner: Vec<u16>,
    boundary: Vec<(Lattice, u16)>,
    /// Each sphere's corners (breadth-first order), as lattice indices.
    corners: Vec<[u16; 3]>,
    /// The lattice points under sphere `s` are `points[start[s] .. start[s + 1]]`.
    start: Vec<u32>,
    points: Vec<u16>,
    /// Lattice steps along a leaf's side. A sub-triangle's points are listed in rows of
    /// constant `lb` (`la` = 0 ..= m - lb), the point `(la, lb)` being `a + la e1 + lb e2`.
    leaf_side: u32,
}

impl SphereTable {
    pub(super) fn new(levels: u32, leaf_level: u32) -> SphereTable {
        let n = grid_size(levels);
        let index = |p: [i64; 2]| lattice_index(p[0] as u32, p[1] as u32, n) as u16;
        let at = |p: Lattice| lattice_index(p[0], p[1], n) as u16;
        let mut table = SphereTable {
            inner: inner_points(n).map(at).collect(),
            boundary: lattice_points(n)
                .filter(|&[i, j]| i == 0 || j == 0 || i + j == n)
                .map(|p| (p, at(p)))
                .collect(),
            corners: Vec::new(),
            start: vec![0],
            points: Vec::new(),
            leaf_side: n >> leaf_level,
        };
        for level in 0..=leaf_level {
            for t in 0..triangle_count(level) {
                let c = sub_triangle(n, level, t).map(|p| [p[0] as i64, p[1] as i64]);
                table.corners.push(c.map(index));
                // Every lattice point of the sub-triangle: a + la e1 + lb e2, with its edges
                // spanning m steps.
                let m = (n >> level) as i64;
                let e1 = [(c[1][0] - c[0][0]) / m, (c[1][1] - c[0][1]) / m];
                let e2 = [(c[2][0] - c[0][0]) / m, (c[2][1] - c[0][1]) / m];
                for lb in 0..=m {
                    for la in 0..=m - lb {
                        let p = [c[0][0] + la * e1[0] + lb * e2[0], c[0][1] + la * e1[1] + lb * e2[1]];
                        table.points.push(index(p));
                    }
                }
                table.start.push(table.points.len() as u32);
            }
        }
        table
    }
}

/// The bounds of grid `g`, its spheres' radii in breadth-first order, each padded for the
/// rounding of the GPU's own centre computation, and each leaf's thickness: how far its
/// micro-vertices may be from the flat triangle of its corners, a bound found in the same pass
/// as the largest move of a vertex from its flat place (the same lattice point of that flat
/// triangle), encoded by [`thickness_code`].
/// `points` is scratch space.
pub(super) fn grid_bounds_and_radii(
    layout: &GridLayout,
    table: &SphereTable,
    g: usize,
    radii: &mut [f32],
    thickness: &mut [u8],
    points: &mut Vec<Vec3A>,
) -> Aabb {
    // Gather the grid in lattice order: its own inner area is contiguous, the boundary is
    // found through the header.
    let slots = layout.slots(g);
    points.resize(table.inner.len() + table.boundary.len(), Vec3A::ZERO);
    let inner = &layout.vertices[g * table.inner.len()..(g + 1) * table.inner.len()];
    for (&at, &v) in table.inner.iter().zip(inner) {
        points[at as usize] = v.into();
    }
    for &(p, at) in &table.boundary {
        points[at as usize] = layout.vertices[slots.slot(p) as usize].into();
    }
    if let Some(&own) = layout.own_levels.get(g) {
        rendered_points(points, layout.shape.levels, own as u32);
    }
    bounds_and_radii(table, points, radii, thickness)
}

/// A grid of mixed levels' points (in lattice order, on the scene's level-`levels` lattice) as
/// the traversal renders them, its own level and decimated edges `own` (see
/// `GridParams::level_element`): a point a decimated edge moves is where it moves to, and each
/// point finer than the grid's own level the midpoint of the two coarser ones it halves. Every
/// point under a sub-triangle then lies in the hull of the micro-triangles the grid renders
/// there, so the radii and thicknesses found over all of them hold for those.
fn rendered_points(points: &mut [Vec3A], levels: u32, own: u32) {
    let n = grid_size(levels);
    let shift = levels - (own >> 3);
    let at = |p: Lattice| lattice_index(p[0], p[1], n) as usize;
    for p in lattice_points(n) {
        let moved = decimated_grid_point(p, n, shift, own & 7);
        if moved != p {
            points[at(p)] = points[at(moved)];
        }
    }
    for h in (0..shift).rev().map(|k| 1u32 << k) {
        for p in lattice_points(n).filter(|&p| super::expanded::new_at_spacing(p, h)) {
            let [a, b] = parents(p, h);
            points[at(p)] = (points[at(a)] + points[at(b)]) * 0.5;
        }
    }
}

/// [`grid_bounds_and_radii`] of a grid whose vertices `points` are already in lattice order.
pub(super) fn bounds_and_radii(table: &SphereTable, points: &[Vec3A], radii: &mut [f32], thickness: &mut [u8]) -> Aabb {
    let mut bounds = (points[0], points[0]);
    for &p in points.iter() {
        bounds = (bounds.0.min(p), bounds.1.max(p));
    }
    let first_leaf = table.corners.len() - thickness.len();
    for (s, (corners, radius)) in table.corners.iter().zip(radii).enumerate() {
        let [a, b, c] = corners.map(|k| Vec3::from(points[k as usize]));
        // The centre exactly as the traversal computes it, then SIMD lanes for the scan.
        let center = sphere_center(a, b, c);
        let centre = Vec3A::from(center);
        let range = table.start[s] as usize..table.start[s + 1] as usize;
        let mut r2 = 0f32;
        let mut moved2 = 0f32;
        if s < first_leaf {
            for &k in &table.points[range] {
                let d = points[k as usize] - centre;
                let d2 = d.dot(d);
                r2 = if d2 > r2 { d2 } else { r2 };
            }
        } else {
            // A leaf: also how far each vertex lies from its flat place, walking the flat
            // triangle's lattice along with the leaf's points (rows of constant `lb`).
            let m = table.leaf_side;
            let step = 1.0 / m as f32;
            let (a, along, up) = (Vec3A::from(a), Vec3A::from(b - a) * step, Vec3A::from(c - a) * step);
            let mut ks = table.points[range].iter();
            let mut row = a;
            for lb in 0..=m {
                let mut flat = row;
                for (_, &k) in (0..=m - lb).zip(&mut ks) {
                    let p = points[k as usize];
                    let d = p - centre;
                    let d2 = d.dot(d);
                    r2 = if d2 > r2 { d2 } else { r2 };
                    let moved = p - flat;
                    let m2 = moved.dot(moved);
                    moved2 = if m2 > moved2 { m2 } else { moved2 };
                    flat += along;
                }
                row += up;
            }
        }
        let r = r2.sqrt();
        let scale = center.abs().max_element();
        *radius = r + (r + scale) * 1e-5;
        if s >= first_leaf {
            let d = moved2.sqrt() * (1.0 + 1e-5) + (r + scale) * 1e-5;
            thickness[s - first_leaf] = thickness_code(d, *radius);
        }
    }
    Aabb {
        min: bounds.0.into(),
        max: bounds.1.into(),
    }
}

/// A leaf's thickness `d` in 8 bits, as a fraction of its sphere's radius `r`: every vertex
/// and its flat place lie within `r` of the sphere's centre, so `d <= 2 r`. The code is
/// `ceil(127.5 d / r)` and a step more, decoded as `2 r code / 255`, never below `d`. Computed
/// per grid in the radius pass, with no scale shared across grids, so nothing waits for the
/// whole mesh.
pub fn thickness_code(d: f32, r: f32) -> u8 {
    if d <= 0.0 {
        0
    } else if d >= 2.0 * r {
        255
    } else {
        // One more step than the f64 quotient asks, against the f32 rounding of the decode.
        ((d as f64 / r as f64 * 127.5).ceil() as u32 + 1).min(255) as u8
    }
}

/// How a grid scene stores its sphere radii (see `GridParams::radius_format`).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum RadiusFormat {
    /// One `f32` per radius.
    F32,
    /// Half floats in units of a power of two per scene, two to a word.
    Half,
    /// Per grid, the root's `f32`, then a byte per sphere below it in 255ths of the root's
    /// radius: a quarter of `f32` radii, and a visit reads four children in one load. Leaves
    /// two or more levels down (with footprints) take four bits instead, relative to their
    /// parents, beside their thicknesses (see `GridParams::leaf_pairs`).
    Relative,
}

impl RadiusFormat {
    /// Its `GridParams::radius_format`.
    pub fn code(self) -> u32 {
        match self {
            RadiusFormat::F32 => RADII_F32,
            RadiusFormat::Half => RADII_HALF,
            RadiusFormat::Relative => RADII_RELATIVE,
        }
    }
}

/// One grid's radii `radii` (breadth-first, each the least the sphere needs) into `into`,
/// [`relative_radius_words`] words: the root's radius, then each other radius's byte, the
/// smallest whose decoded radius is not below the radius it stands for. Where a sphere needs
/// more than the root (possible, as its centre is not the root's), the root's stored radius
/// grows to it: each byte can then code it, and the root's sphere only grows.
pub(super) fn encode_relative_radii(radii: &[f32], into: &mut [u32]) {
    let root = radii.iter().fold(0f32, |m, &r| m.max(r));
    encode_radii_under(radii, root, into);
}

/// [`encode_relative_radii`] with the root's stored radius `root`, at least each of `radii`.
fn encode_radii_under(radii: &[f32], root: f32, into: &mut [u32]) {
    into.fill(0);
    into[0] = root.to_bits();
    for (k, &r) in radii.iter().enumerate().skip(1) {
        let code = relative_code(r, root);
        into[1 + (k - 1) / 4] |= code << (8 * ((k - 1) % 4));
    }
}

/// One grid's spheres in leaf pairs (see `GridParams::thickness_word`): `radii` (breadth-first,
/// the `leaves` last) as relative radii into `radius_words` but for the leaves, whose bytes in
/// `leaf_words` hold their thickness codes on entry and each leaf's radius and thickness codes
/// on return. A leaf's radius is coded against its parent's radius as decoded, and its
/// thickness against its own as decoded, so each only grows.
pub(super) fn encode_leaf_pairs(radii: &[f32], leaves: usize, radius_words: &mut [u32], leaf_words: &mut [u32]) {
    let first_leaf = radii.len() - leaves;
    // The root at least every sphere, leaves included, so each parent's byte can grow to
    // twice any leaf below it.
    let root = radii.iter().fold(0f32, |m, &r| m.max(r));
    encode_radii_under(&radii[..first_leaf], root, radius_words);
    for (l, &needed) in radii[first_leaf..].iter().enumerate() {
        let parent_node = ((first_leaf + l - 1) / 4) as u32;
        // A leaf needs at most twice its parent's radius; where padding or rounding asks a
        // little more, the parent grows (the root already holds every leaf).
        let mut parent = relative_radius_at(&*radius_words, 0, parent_node);
        while leaf_radius(parent, 15) < needed && parent_node > 0 {
            let k = parent_node as usize - 1;
            let (word, shift) = (&mut radius_words[1 + k / 4], 8 * (k % 4));
            let code = ((*word >> shift) & 0xff) + 1;
            if code > 255 {
                break;
            }
            *word = (*word & !(0xff << shift)) | (code << shift);
            parent = relative_radius_at(&*radius_words, 0, parent_node);
        }
        let radius_code = (0..15).find(|&k| leaf_radius(parent, k) >= needed).unwrap_or(15);
        let radius = leaf_radius(parent, radius_code);
        let (word, shift) = (&mut leaf_words[l / 4], 8 * (l % 4));
        let thickness = byte_thickness(needed, (*word >> shift) & 0xff) * (1.0 + 1e-6);
        let thickness_code = (0..15).find(|&k| leaf_thickness(radius, k) >= thickness).unwrap_or(15);
        *word = (*word & !(0xff << shift)) | ((radius_code | thickness_code << 4) << shift);
    }
}

/// One grid's thickness codes (`words`, a byte per leaf), made against the radii its spheres
/// need (`radii`, breadth-first, the leaves last), recoded against the radii `radius_words`
/// decode to: thickness is decoded as a fraction of the decoded radius, which may be larger.
pub(super) fn rescale_thickness(radius_words: &[u32], radii: &[f32], leaves: usize, words: &mut [u32]) {
    let first = radii.len() - leaves;
    for (l, &needed) in radii[first..].iter().enumerate() {
        let decoded = relative_radius_at(radius_words, 0, (first + l) as u32);
        let (word, shift) = (&mut words[l / 4], 8 * (l % 4));
        let code = (*word >> shift) & 0xff;
        // The thickness the code stood for, and its code against the decoded radius.
        let thickness = byte_thickness(needed, code) * (1.0 + 1e-6);
        let recoded = thickness_code(thickness, decoded) as u32;
        *word = (*word & !(0xff << shift)) | (recoded.min(code) << shift);
    }
}

/// The smallest byte whose [`relative_radius`] of `root` is not below `r` (`r <= root`).
fn relative_code(r: f32, root: f32) -> u32 {
    if r <= 0.0 || root <= 0.0 {
        return 0;
    }
    let mut code = ((r as f64 / root as f64 * 255.0).ceil() as u32).min(255);
    // The decode's own f32 rounding may land just below `r`.
    while code < 255 && relative_radius(root, code, 0) < r {
        code += 1;
    }
    code
}

/// The power of two that brings the largest radius to about 2^14 in half-float units: far
/// from overflow (65504) and with the smallest radii still well above the subnormal range.
pub(super) fn radius_scale(max_radius: f32) -> f32 {
    if max_radius <= 0.0 || !max_radius.is_finite() {
        return 1.0;
    }
    2f32.powi(max_radius.log2().ceil() as i32 - 14)
}

/// The smallest half float, in units of `scale`, that is not below `r`.
pub fn encode_radius(r: f32, scale: f32) -> u16 {
    let v = r / scale;
    let bits = v.to_bits();
    let exponent = ((bits >> 23) & 0xff) as i32 - 127;
    let h = if v <= 0.0 {
        0
    } else if exponent < -14 {
        // Subnormal half: units of 2^-24, rounded up.
        (v * 16_777_216.0).ceil() as u32
    } else {
        let mantissa = (bits & 0x7f_ffff) >> 13;
        let rest = bits & 0x1fff;
        (((exponent + 15) as u32) << 10 | mantissa) + (rest != 0) as u32
    };
    h.min(0x7bff) as u16
}

#[cfg(test)]
mod tests {
    use super::*;
    use gridrt_shared::layout::relative_radius_words;

    /// Every decoded radius holds the radius it stands for, within a code step of the root's.
    #[test]
    fn relative_radii_round_up() {
        let radii: Vec<f32> = (0..21)
            .map(|k| {
                if k == 0 {
                    2.5
                } else {
                    2.6 * ((k * 37 % 21) as f32 / 21.0).powi(2)
                }
            })
            .collect();
        let words = relative_radius_words(radii.len() as u32) as usize;
        let mut into = vec![0; words];
        encode_relative_radii(&radii, &mut into);
        let root = f32::from_bits(into[0]);
        assert!(radii.iter().all(|&r| r <= root), "the root grows to the largest radius");
        for (k, &r) in radii.iter().enumerate().skip(1) {
            let back = relative_radius_at(into.as_slice(), 0, k as u32);
            assert!(back >= r && back <= r + root / 255.0 * 1.001, "{r} decoded as {back}");
        }
    }

    #[test]
    fn half_radii_round_up() {
        let scale = radius_scale(3.7);
        for k in 0..100_000 {
            let r = 3.7 * (k as f32 / 100_000.0).powi(3);
            let back = gridrt_shared::sphere::decode_radius(encode_radius(r, scale) as u32, scale);
            assert!(back >= r, "{r} encoded as {back}");
            assert!(
                back <= r * (1.0 + 1.0 / 1024.0) + scale * 2f32.powi(-24),
                "{r} encoded as {back}"
            );
        }
    }
}
