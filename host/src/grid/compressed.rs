//! Compressed displacement values (the format of `gridrt_shared::compressed_values`): the
//! encoder, which picks each level's correction width for a whole micro-mesh and each block's
//! shifts, and the blocks as displaced grids store them.
//!
//! Guarantees:
//! - Closed loop: every correction is chosen against the values the decoder will already
//!   have made (coarser levels, the base edges, the corners), so the decoded values are the
//!   encoder's own, bit for bit. [`compress`] hands back the micro-mesh with those values, so
//!   the grids, the triangles they are compared against and any file written from it all hold
//!   the same surface; encoding that micro-mesh again with the same widths loses nothing.
//! - Each block takes, per level, the shift whose corrections leave the least squared error.
//! - Widths are lowered one level at a time, always where a bit saved costs the least added
//!   error, for as long as the added RMS error stays within the bound asked for.
//! - A base edge's values are encoded once, from its lower base vertex id, and both grids that
//!   share the edge read that one block: the surface stays watertight.

use crate::bit_writer::BitWriter;
use gridrt_shared::compressed_values::{
    inner_new_count, ValueCode, MAX_LEVELS, SHIFT_BITS, VALUE_BITS, VALUE_MAX, WIDTH_BITS,
};
use gridrt_shared::displacement::{interpolated, u_major_index};
use gridrt_shared::grid_index::{grid_size, Lattice};

use rayon::prelude::*;

use super::{corner_point, edge_point, BaseEdges};
use crate::bary::MicromapTriangle;
use crate::displaced::DisplacedMesh;
use crate::error::{fail, Result};

/// Widest correction: a whole value.
const MAX_WIDTH: u32 = VALUE_BITS;

/// What [`compress`] aims for.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct ValueCompression {
    /// Most RMS error the compression may add, over every stored value, as a fraction of the
    /// base mesh's bounding-box diagonal.
    pub max_added_error: f32,
}

impl Default for ValueCompression {
    fn default() -> Self {
        ValueCompression { max_added_error: 1e-4 }
    }
}

impl ValueCompression {
    /// A bound of `distance` in `mesh`'s own units.
    pub fn within(mesh: &DisplacedMesh, distance: f32) -> ValueCompression {
        ValueCompression {
            max_added_error: distance / diagonal(&mesh.with_ranges_folded()),
        }
    }
}

/// A code's correction widths, in bits, level 1 (the coarsest) first.
pub fn level_widths(code: &ValueCode) -> Vec<u32> {
    (1..=code.levels).map(|l| code.width(l)).collect()
}

/// The bounding-box diagonal of a folded micro-mesh's base, which bounds are relative to.
fn diagonal(folded: &DisplacedMesh) -> f32 {
    let (lo, hi) = folded.base_mesh().bounds();
    (hi - lo).length().max(f32::MIN_POSITIVE)
}

/// A micro-mesh's values, compressed.
#[derive(Clone, Debug)]
pub struct CompressedMesh {
    /// The micro-mesh (ranges folded) holding the decoded values, with its code.
    pub mesh: DisplacedMesh,
    pub code: ValueCode,
    /// RMS error added over every stored value, as a fraction of the diagonal.
    pub added_error: f32,
    /// Bits of the corrections, shifts and corners, all blocks together.
    pub bits: u64,
}

/// Compresses `mesh`'s values (a micro-mesh of one level) as tightly as `options` allow.
pub fn compress(mesh: &DisplacedMesh, options: &ValueCompression) -> Result<CompressedMesh> {
    let Some(levels) = mesh.uniform_level() else {
        fail!(Input, "its base triangles are subdivided to different levels");
    };
    let folded = mesh.with_ranges_folded();
    let edges = BaseEdges::new(&folded.base_mesh());
    let diagonal = diagonal(&folded);
    let bound = options.max_added_error as f64 * diagonal as f64;
    let mut widths = [MAX_WIDTH; MAX_LEVELS as usize];
    let code = |w: &[u32; MAX_LEVELS as usize]| ValueCode {
        levels,
        widths: (0..levels as usize).fold(0, |acc, l| acc | w[l] << (WIDTH_BITS * l as u32)),
    };
    let mut best = encode(&folded, &edges, code(&widths));
    loop {
        // The level whose narrower corrections add the least error per bit saved.
        let mut choice: Option<(f64, [u32; MAX_LEVELS as usize], Encoded)> = None;
        for l in 0..levels as usize {
            if widths[l] == 0 {
                continue;
            }
            let mut trial = widths;
            trial[l] -= 1;
            let encoded = encode(&folded, &edges, code(&trial));
            if encoded.rms() > bound {
                continue;
            }
            let saved = best.bits.saturating_sub(encoded.bits).max(1) as f64;
            let cost = (encoded.squared_error - best.squared_error).max(0.0) / saved;
            if choice.as_ref().is_none_or(|(c, ..)| cost < *c) {
                choice = Some((cost, trial, encoded));
            }
        }
        let Some((_, trial, encoded)) = choice else { break };
        widths = trial;
        best = encoded;
    }
    let mut mesh = folded;
    mesh.micromap.values = best.values.concat();
    let per_triangle = best.values.first().map_or(0, Vec::len) as u32;
    mesh.micromap.triangles = (0..mesh.triangles.len() as u32)
        .map(|t| MicromapTriangle {
            level: levels,
            first_value: t * per_triangle,
        })
        .collect();
    mesh.micromap.value_code = Some(code(&widths));
    Ok(CompressedMesh {
        added_error: (best.rms() / diagonal as f64) as f32,
        bits: best.bits,
        mesh,
        code: code(&widths),
    })
}

/// A micro-mesh's values encoded with one code.
#[derive(Clone, Debug, Default)]
pub struct Encoded {
    /// Each grid's block, in whole words.
    pub grid_blocks: Vec<Vec<u32>>,
    /// The base edges' blocks end to end, by edge id, then every base vertex's value.
    pub shared: Vec<u32>,
    /// Each grid's decoded values, u-major.
    pub values: Vec<Vec<u16>>,
    /// Sum of the squared distances the decoded points moved, each stored point once.
    pub squared_error: f64,
    pub points: u64,
    pub bits: u64,
}

impl Encoded {
    /// RMS distance the decoded points moved.
    pub fn rms(&self) -> f64 {
        (self.squared_error / self.points.max(1) as f64).sqrt()
    }
}

/// Encodes the values of `mesh` (ranges folded, one level) with `code`, edges by `edges`'
/// ids: base edges first (from the corners), then each grid (from its corners and edges).
pub(super) fn encode(mesh: &DisplacedMesh, edges: &BaseEdges, code: ValueCode) -> Encoded {
    let n = grid_size(code.levels);
    let grids = mesh.triangles.len();
    let original: Vec<&[u16]> = (0..grids).map(|g| mesh.micromap.triangle_values(g)).collect();
    // Distance one value step moves lattice point `p` of grid `g`.
    let unit = |g: usize, p: Lattice| interpolated(&mesh.base_triangle(g), p, n).1.length() / VALUE_MAX as f32;
    let mut out = Encoded::default();

    // Corners: plain values, from the first grid that uses each base vertex.
    let mut corner_values = vec![0u16; mesh.positions.len()];
    let mut corner_seen = vec![false; mesh.positions.len()];
    for (g, t) in mesh.triangles.iter().enumerate() {
        for (c, &v) in t.iter().enumerate() {
            if !std::mem::replace(&mut corner_seen[v as usize], true) {
                corner_values[v as usize] = original[g][u_major_index(corner_point(c, n), n) as usize];
            }
        }
    }

    // Base edges, each along its stored direction (from its lower vertex id), from the grid
    // that owns it.
    let edge_blocks: Vec<(BlockEncoder, Vec<u16>)> = edges
        .owner
        .par_iter()
        .map(|&(g, e)| {
            let t = mesh.triangles[g];
            let (from, to) = (t[e], t[(e + 1) % 3]);
            let point = |s: u32| edge_point(e, if from <= to { s } else { n - s }, n);
            let mut values: Vec<u16> = (0..=n)
                .map(|s| original[g][u_major_index(point(s), n) as usize])
                .collect();
            values[0] = corner_values[from.min(to) as usize];
            values[n as usize] = corner_values[from.max(to) as usize];
            let truth = values.clone();
            let mut block = BlockEncoder::new(code);
            for l in 1..=code.levels {
                let step = n >> l;
                let targets: Vec<Target> = (1..=(1 << l >> 1))
                    .map(|k| {
                        let s = (2 * k - 1) * step;
                        Target {
                            truth: truth[s as usize],
                            parents: (values[(s - step) as usize], values[(s + step) as usize]),
                            unit: unit(g, point(s)),
                        }
                    })
                    .collect();
                for (k, q) in block.level(l, &targets).into_iter().enumerate() {
                    values[((2 * k + 1) as u32 * step) as usize] = q;
                }
            }
            (block, values)
        })
        .collect();
    let mut shared = BitWriter::default();
    let mut edge_values: Vec<Vec<u16>> = Vec::with_capacity(edges.owner.len());
    for (block, values) in edge_blocks {
        out.squared_error += block.squared_error;
        out.points += block.points;
        block.write(&mut shared);
        edge_values.push(values);
    }
    for &q in &corner_values {
        shared.push(q as u32, VALUE_BITS);
    }
    out.points += corner_values.len() as u64;
    out.bits += shared.bits as u64;
    shared.words.push(0);
    out.shared = shared.words;

    // Grids: corners and edges as decoded above, then the inner points level by level.
    let grid_blocks: Vec<(BlockEncoder, Vec<u16>)> = (0..grids)
        .into_par_iter()
        .map(|g| encode_grid(mesh, g, code, &original, &corner_values, &edge_values, edges, &unit))
        .collect();
    for (block, values) in grid_blocks {
        out.squared_error += block.squared_error;
        out.points += block.points;
        let mut words = BitWriter::default();
        block.write(&mut words);
        out.bits += words.bits as u64;
        words.words.resize(code.inner_block_bits().div_ceil(32) as usize, 0);
        out.grid_blocks.push(words.words);
        out.values.push(values);
    }
    out
}

/// Grid `g`'s block, from its corners and edges as decoded, and its decoded values.
#[allow(clippy::too_many_arguments)]
fn encode_grid(
    mesh: &DisplacedMesh,
    g: usize,
    code: ValueCode,
    original: &[&[u16]],
    corner_values: &[u16],
    edge_values: &[Vec<u16>],
    edges: &BaseEdges,
    unit: &(impl Fn(usize, Lattice) -> f32 + Sync),
) -> (BlockEncoder, Vec<u16>) {
    let n = grid_size(code.levels);
    let t = mesh.triangles[g];
    let mut values = original[g].to_vec();
    for c in 0..3 {
        values[u_major_index(corner_point(c, n), n) as usize] = corner_values[t[c] as usize];
    }
    for e in 0..3 {
        let edge = &edge_values[edges.of_grid[g][e] as usize];
        let forward = t[e] <= t[(e + 1) % 3];
        for s in 1..n {
            values[u_major_index(edge_point(e, s, n), n) as usize] = edge[if forward { s } else { n - s } as usize];
        }
    }
    let truth = original[g];
    let at = |p: Lattice| u_major_index(p, n) as usize;
    let mut block = BlockEncoder::new(code);
    for l in 1..=code.levels {
        let step = n >> l;
        let m = 1u32 << l;
        let mut points = Vec::with_capacity(inner_new_count(l) as usize);
        for a in 1..m {
            for b in 1..m - a {
                if a % 2 == 1 || b % 2 == 1 {
                    points.push([a * step, b * step]);
                }
            }
        }
        let targets: Vec<Target> = points
            .iter()
            .map(|&p| {
                let (pa, pb) = parents(p, step);
                Target {
                    truth: truth[at(p)],
                    parents: (values[at(pa)], values[at(pb)]),
                    unit: unit(g, p),
                }
            })
            .collect();
        for (&p, q) in points.iter().zip(block.level(l, &targets)) {
            values[at(p)] = q;
        }
    }
    (block, values)
}

/// The two points of the coarser lattice (spacing `2 step`) that inner point `p`, new on the
/// lattice of spacing `step`, halves.
fn parents(p: Lattice, step: u32) -> (Lattice, Lattice) {
    let [i, j] = p;
    match ((i / step) % 2, (j / step) % 2) {
        (1, 0) => ([i - step, j], [i + step, j]),
        (0, 1) => ([i, j - step], [i, j + step]),
        _ => ([i - step, j + step], [i + step, j - step]),
    }
}

/// A point to encode: its true value, its parents' decoded values, and the distance a value
/// step moves it.
struct Target {
    truth: u16,
    parents: (u16, u16),
    unit: f32,
}

/// One block's shifts and corrections, level by level.
struct BlockEncoder {
    code: ValueCode,
    shifts: u32,
    corrections: Vec<(u32, u32)>,
    squared_error: f64,
    points: u64,
}

impl BlockEncoder {
    fn new(code: ValueCode) -> Self {
        BlockEncoder {
            code,
            shifts: 0,
            corrections: Vec::new(),
            squared_error: 0.0,
            points: 0,
        }
    }

    /// Encodes level `l`'s points with the shift that leaves the least squared error;
    /// returns their decoded values.
    fn level(&mut self, l: u32, targets: &[Target]) -> Vec<u16> {
        let width = self.code.width(l);
        let shifts = if width == 0 { 0 } else { (1 << SHIFT_BITS) - 1 };
        let mut best: Option<(f64, u32)> = None;
        for shift in 0..=shifts.min(VALUE_BITS) {
            let error: f64 = targets.iter().map(|t| t.error(width, shift)).sum();
            if best.is_none_or(|(e, _)| error < e) {
                best = Some((error, shift));
            }
        }
        let (error, shift) = best.unwrap_or((0.0, 0));
        self.shifts |= shift << (SHIFT_BITS * (l - 1));
        self.squared_error += error;
        self.points += targets.len() as u64;
        targets
            .iter()
            .map(|t| {
                let (field, q) = t.encode(width, shift);
                self.corrections.push((field, width));
                q as u16
            })
            .collect()
    }

    fn write(&self, out: &mut BitWriter) {
        out.push(self.shifts, self.code.shift_bits());
        for &(field, width) in &self.corrections {
            out.push(field, width);
        }
    }
}

impl Target {
    /// The `width`-bit field closest to the truth at `shift`, and the value it decodes to.
    fn encode(&self, width: u32, shift: u32) -> (u32, u32) {
        let (a, b) = (self.parents.0 as u32, self.parents.1 as u32);
        if width == 0 {
            return (0, gridrt_shared::compressed_values::corrected(a, b, 0, 0, shift));
        }
        let mean = ((a + b + 1) >> 1) as i32;
        let step = 1i32 << shift;
        let residual = self.truth as i32 - mean;
        let half = (1i32 << (width - 1)) - 1;
        let rounded = (residual + residual.signum() * step / 2) / step;
        let correction = rounded.clamp(-half - 1, half);
        // Clamping to the value range may favour the neighbour towards the truth.
        let field = |c: i32| (c as u32) & ((1u32 << width) - 1);
        let decode = |c: i32| gridrt_shared::compressed_values::corrected(a, b, field(c), width, shift);
        let best = [correction, (correction - 1).max(-half - 1), (correction + 1).min(half)]
            .into_iter()
            .min_by_key(|&c| (decode(c) as i32 - self.truth as i32).abs())
            .unwrap_or(correction);
        (field(best), decode(best))
    }

    fn error(&self, width: u32, shift: u32) -> f64 {
        let (_, q) = self.encode(width, shift);
        let d = (q as f64 - self.truth as f64) * self.unit as f64;
        d * d
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bary::Micromap;
    use crate::grid::displaced::layout;
    use crate::grid::GridOptions;
    use gridrt_shared::compressed_values::CodedScene;
    use gridrt_shared::glam::Vec3;
    use gridrt_shared::grid_index::lattice_points;

    /// A closed tetrahedron at `levels` whose values follow a bumpy function of each point's
    /// undisplaced position, plus a hash of it as noise: neighbours agree on shared edges.
    fn tetrahedron(levels: u32, noise: u32) -> DisplacedMesh {
        let positions = vec![
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(1.0, -1.0, -1.0),
            Vec3::new(-1.0, 1.0, -1.0),
            Vec3::new(-1.0, -1.0, 1.0),
        ];
        let triangles = vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]];
        let mut mesh = DisplacedMesh {
            directions: positions.iter().map(|p| *p * 0.3).collect(),
            positions,
            triangles,
            ..Default::default()
        };
        let n = grid_size(levels);
        let values: Vec<(u32, Vec<u16>)> = (0..4)
            .map(|t| {
                let base = mesh.base_triangle(t);
                let mut values = vec![0u16; lattice_points(n).count()];
                for p in lattice_points(n) {
                    values[u_major_index(p, n) as usize] = {
                        let x = interpolated(&base, p, n).0;
                        let hash = x
                            .to_array()
                            .iter()
                            .fold(7u32, |h, c| (h ^ c.to_bits()).wrapping_mul(0x9e37_79b1));
                        let smooth = 1024.0 + 700.0 * (3.0 * x.x).sin() * (2.0 * x.y + x.z).cos();
                        (smooth as i64 + (hash >> 7) as i64 % (noise as i64 + 1)).clamp(0, 2047) as u16
                    };
                }
                (levels, values)
            })
            .collect();
        mesh.micromap = Micromap::from_triangles(0.0, 1.0, &values);
        mesh
    }

    /// Every lattice point the shared decoder reads from the laid-out buffer, at every level
    /// and across widths down to nothing, is the value the encoder decoded.
    #[test]
    fn shared_decoder_reads_what_the_encoder_decoded() {
        for levels in 1..=5 {
            for bound in [0.0, 1e-3, 1e-2, 1.0] {
                let mesh = tetrahedron(levels, 40);
                let compressed = compress(&mesh, &ValueCompression { max_added_error: bound }).unwrap();
                let grids = layout(&compressed.mesh, &GridOptions::for_displaced()).unwrap();
                let shape = &grids.shape;
                let code = shape.value_code.unwrap();
                assert_eq!(code, compressed.code);
                let mut buffer = grids.buffer.clone();
                buffer[..grids.inner_by_grid.len()].copy_from_slice(&grids.inner_by_grid);
                let scene = CodedScene {
                    code,
                    edge_bit: 32 * 4 * shape.inner_words,
                    edge_block_bits: code.edge_block_bits(),
                    corner_bit: shape.corner_bit,
                };
                let n = grid_size(levels);
                for g in 0..4 {
                    let grid = scene.open(&buffer[..], &grids.ids[g], 32 * g as u32 * shape.inner_words);
                    let values = compressed.mesh.micromap.triangle_values(g);
                    for p in lattice_points(n) {
                        let q = grid.value(&buffer[..], p);
                        assert_eq!(
                            q,
                            values[u_major_index(p, n) as usize] as u32,
                            "L{levels} {bound} grid {g} {p:?}"
                        );
                    }
                }
            }
        }
    }

    /// The added error stays within the bound, measured from the values; a looser bound
    /// stores fewer bits; no bound at all keeps every value.
    #[test]
    fn compression_keeps_to_its_error_bound() {
        let mesh = tetrahedron(4, 40);
        let diagonal = {
            let (lo, hi) = mesh.base_mesh().bounds();
            (hi - lo).length()
        };
        let mut last_bits = u64::MAX;
        for bound in [0.0, 1e-4, 1e-3, 1e-2] {
            let c = compress(&mesh, &ValueCompression { max_added_error: bound }).unwrap();
            assert!(c.added_error <= bound, "{bound}: {}", c.added_error);
            assert!(c.bits <= last_bits, "{bound}: {} bits", c.bits);
            last_bits = c.bits;
            // Measured on every lattice point of every triangle (shared ones counted twice).
            let (mut sum, mut count) = (0.0f64, 0);
            for t in 0..4 {
                let (before, after) = (mesh.micro_vertices(t), c.mesh.micro_vertices(t));
                for (a, b) in before.iter().zip(&after) {
                    sum += (*a - *b).length_squared() as f64;
                    count += 1;
                }
            }
            let rms = (sum / count as f64).sqrt() / diagonal as f64;
            assert!(rms <= 1.5 * bound as f64 + 1e-9, "{bound}: measured {rms}");
            if bound == 0.0 {
                assert_eq!(c.mesh.micromap.values, mesh.micromap.values);
            }
        }
    }

    /// Values that no longer match their code are refused by the layout, not stored wrong.
    #[test]
    fn values_off_their_code_are_refused() {
        let mut compressed = compress(&tetrahedron(3, 40), &ValueCompression { max_added_error: 1e-2 })
            .unwrap()
            .mesh;
        let k = compressed.micromap.values.len() / 2;
        compressed.micromap.values[k] ^= 0x155;
        let err = layout(&compressed, &GridOptions::for_displaced()).unwrap_err();
        assert!(err.to_string().contains("compressed code"), "{err}");
    }
}
