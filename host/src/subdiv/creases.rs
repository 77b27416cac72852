//! Sharp edges chosen by angle: which base edges subdivide with the crease rules besides the
//! boundaries and non-manifold edges, which always do.
//!
//! Loop subdivision rounds every edge, so a hard-surface model (a box, an arch, a machined
//! part) melts into a blob. Marking the edges where the surface folds by more than a given
//! dihedral angle as creases keeps them: a crease's new vertices are its midpoints, a vertex on
//! two creases follows the curve they form, and a vertex on more is a corner (Hoppe et al.
//! 1994, "Piecewise smooth surface reconstruction"). The flags are found once on the whole base
//! mesh, so every grid, subdivided alone, sees the same creases as its neighbours.

use std::f64::consts::PI;

use gridrt_shared::glam::DVec3;

use crate::mesh::Mesh;

/// Per base triangle, bit `e` set when its edge `e` (corner `e` to corner `(e + 1) % 3`) is a
/// chosen crease. Empty: none chosen.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Creases {
    bits: Vec<u8>,
}

impl Creases {
    /// No chosen creases: only boundaries and non-manifold edges stay sharp.
    pub fn none() -> Self {
        Creases::default()
    }

    /// The edges of `mesh` shared by two triangles whose normals differ by more than
    /// `degrees`. Degenerate triangles (no normal) make no creases; neighbours wound against
    /// each other are compared as if wound alike, so a flat sheet with a flipped triangle has
    /// no crease. `degrees >= 180` (or not a number) chooses none.
    pub fn from_angle(mesh: &Mesh, degrees: f32) -> Self {
        if degrees.is_nan() || degrees >= 180.0 {
            return Creases::none();
        }
        let cos_limit = (degrees.max(0.0) as f64 * PI / 180.0).cos();
        let normals: Vec<DVec3> = mesh
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| mesh.positions[v as usize].as_dvec3());
                (b - a).cross(c - a)
            })
            .collect();
        let mut bits = vec![0u8; mesh.triangles.len()];
        let mut chosen = false;
        for pair in shared_edges(mesh) {
            let [(f, e), (g, h)] = pair;
            let (nf, ng) = (normals[f as usize], normals[g as usize]);
            let len = (nf.length_squared() * ng.length_squared()).sqrt();
            if len == 0.0 || !len.is_finite() {
                continue;
            }
            // Opposite directions along the shared edge: wound alike.
            let (tf, tg) = (mesh.triangles[f as usize], mesh.triangles[g as usize]);
            let alike = tf[e as usize] == tg[(h as usize + 1) % 3];
            let cos = nf.dot(ng) / len * if alike { 1.0 } else { -1.0 };
            if cos < cos_limit {
                bits[f as usize] |= 1 << e;
                bits[g as usize] |= 1 << h;
                chosen = true;
            }
        }
        if !chosen {
            bits.clear();
        }
        Creases { bits }
    }

    /// [`Creases::from_angle`] for `Some(degrees)`, [`Creases::none`] for `None`.
    pub fn chosen(mesh: &Mesh, degrees: Option<f32>) -> Self {
        degrees.map_or_else(Creases::none, |d| Creases::from_angle(mesh, d))
    }

    /// Crease bits of base triangle `t`.
    #[inline]
    pub fn of(&self, t: usize) -> u8 {
        self.bits.get(t).copied().unwrap_or(0)
    }

    /// How many edges were chosen (each counted once).
    pub fn edge_count(&self) -> usize {
        self.bits.iter().map(|b| b.count_ones() as usize).sum::<usize>() / 2
    }
}

/// Every edge used by exactly two triangles, as its two `(triangle, edge)` uses.
fn shared_edges(mesh: &Mesh) -> Vec<[(u32, u32); 2]> {
    let mut keys: Vec<(u64, u32)> = Vec::with_capacity(mesh.triangles.len() * 3);
    for (f, t) in mesh.triangles.iter().enumerate() {
        for e in 0..3 {
            let (a, b) = (t[e], t[(e + 1) % 3]);
            keys.push((((a.min(b) as u64) << 32) | a.max(b) as u64, (3 * f + e) as u32));
        }
    }
    keys.sort_unstable();
    let mut pairs = Vec::new();
    let mut start = 0;
    while start < keys.len() {
        let mut end = start + 1;
        while end < keys.len() && keys[end].0 == keys[start].0 {
            end += 1;
        }
        if end - start == 2 {
            let use_of = |k: (u64, u32)| (k.1 / 3, k.1 % 3);
            pairs.push([use_of(keys[start]), use_of(keys[start + 1])]);
        }
        start = end;
    }
    pairs
}
