//! Compressed displacement values (the format of `gridrt_shared::compressed_values`): the
//! encoder, which picks the base edges' correction widths, each grid's own widths and each
//! block's shifts, and the blocks as displaced grids store them.
//!
//! Guarantees:
//! - Closed loop: every correction is chosen against the values the decoder will already
//!   have made (coarser levels, the base edges, the corners), so the decoded values are the
//!   encoder's own, bit for bit. [`compress`] (and [`Compressor`]) hands back the micro-mesh with those values, so
//!   the grids, the triangles they are compared against and any file written from it all hold
//!   the same surface. Laying that micro-mesh out again ([`encode_exact`]) loses nothing: each
//!   grid takes the narrowest widths that decode its values exactly.
//! - Each block takes, per level, the shift whose corrections leave the least squared error.
//! - One set of widths is lowered one level at a time, always where a bit saved costs the
//!   least added error, for as long as the added RMS error stays within the bound asked for;
//!   the base edges keep it. Each grid then gets its own widths: all grids narrow theirs as
//!   long as a bit saved adds less error than one rate they share, the largest rate that keeps
//!   the whole within the same bound. Smooth grids so give their bits to detailed ones.
//! - A base edge's values are encoded once, from its lower base vertex id, and both grids that
//!   share the edge read that one block: the surface stays watertight.
//! - In grids of mixed levels each block holds the levels it renders, and no bits for finer
//!   ones (see [`level_sorted_edges`] for the base edges' order).

use crate::bit_writer::BitWriter;
use gridrt_shared::compressed_values::{
    inner_new_count, ValueCode, MAX_LEVELS, SHIFT_BITS, VALUE_BITS, VALUE_MAX, WIDTH_BITS,
};
use gridrt_shared::displacement::{interpolated, u_major_index};
use gridrt_shared::grid_index::{corner_point, grid_size, parents, Lattice};

use rayon::prelude::*;

use super::expanded::expanded_mesh;
use super::value_tables::{level_sorted_edges, write_edge_levels, Rendered};
use super::{stored_edge_point, BaseEdges};
use crate::error::{fail, Result};
use crate::micromesh::bary::MicromapTriangle;
use crate::micromesh::DisplacedMesh;

/// Widest correction: a whole value.
const MAX_WIDTH: u32 = VALUE_BITS;
/// How much wider than the scene's a grid's widths may be.
const EXTRA_WIDTH: u32 = 3;

/// What [`compress`] aims for.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct ValueCompression {
    /// Most RMS error the compression may add, over every stored value, as a fraction of the
    /// base mesh's bounding-box diagonal.
    pub max_added_error: f32,
    /// Most bits all the values may take: where the error bound needs more, the grids give
    /// up error for bits until they fit, and the bound is exceeded.
    pub max_bits: Option<u64>,
}

impl Default for ValueCompression {
    fn default() -> Self {
        ValueCompression::bounded(1e-4)
    }
}

impl ValueCompression {
    /// An error bound alone (see [`Self::max_added_error`]).
    pub fn bounded(max_added_error: f32) -> ValueCompression {
        ValueCompression {
            max_added_error,
            max_bits: None,
        }
    }

    /// A bound of `distance` in `mesh`'s own units.
    pub fn within(mesh: &DisplacedMesh, distance: f32) -> ValueCompression {
        ValueCompression::bounded(distance / diagonal(&mesh.with_ranges_folded()))
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
    /// Bits of the corrections, shifts, widths and corners, all blocks together, and the
    /// values they store (each shared one once).
    pub bits: u64,
    pub points: u64,
}

impl CompressedMesh {
    /// Bits per stored value, all blocks together.
    pub fn bits_per_value(&self) -> f64 {
        self.bits as f64 / self.points.max(1) as f64
    }
}

/// Compresses `mesh`'s values as tightly as `options` allow.
pub fn compress(mesh: &DisplacedMesh, options: &ValueCompression) -> Result<CompressedMesh> {
    Ok(Compressor::new(mesh, options.max_added_error)?.within(options.max_bits))
}

/// A micro-mesh's values made ready to compress within an error bound, and then within any
/// number of bits: the scene's widths and each grid's choices are found once, so that a
/// caller looking for the bits that fit a byte budget pays only for the last step each try.
pub struct Compressor {
    /// The values to compress, ranges folded, every triangle at the deepest level (see
    /// [`expanded_mesh`]).
    folded: DisplacedMesh,
    edges: BaseEdges,
    rendered: Rendered,
    diagonal: f32,
    scene_code: ValueCode,
    allocation: Allocation,
    /// The fewest bits within the error bound.
    bounded: Encoded,
}

impl Compressor {
    /// `mesh`'s values compressed within `max_added_error` (see
    /// [`ValueCompression::max_added_error`]). Triangles of mixed levels are compressed as
    /// displaced grids hold them (see [`expanded_mesh`]): the points no grid renders count for
    /// no error, so a coarser grid's finer levels take no bits of its own.
    pub fn new(mesh: &DisplacedMesh, max_added_error: f32) -> Result<Compressor> {
        let Some(levels) = mesh.deepest_level() else {
            fail!(Input, "it has no base triangles");
        };
        let folded = mesh.with_ranges_folded();
        let (edges, rendered) = level_sorted_edges(&folded);
        let folded = match rendered.own.is_empty() {
            true => folded,
            false => expanded_mesh(&folded),
        };
        let diagonal = diagonal(&folded);
        let bound = max_added_error as f64 * diagonal as f64;
        // First one set of widths for every block, as narrow as the bound allows: the base
        // edges keep it.
        let mut widths = [MAX_WIDTH; MAX_LEVELS as usize];
        let mut best = encode(&folded, &edges, &rendered, code(levels, &widths), |_| {
            code(levels, &widths)
        });
        loop {
            // The level whose narrower corrections add the least error per bit saved.
            let mut choice: Option<(f64, [u32; MAX_LEVELS as usize], Encoded)> = None;
            for l in 0..levels as usize {
                if widths[l] == 0 {
                    continue;
                }
                let mut trial = widths;
                trial[l] -= 1;
                let trial_code = code(levels, &trial);
                let encoded = encode(&folded, &edges, &rendered, trial_code, |_| trial_code);
                if encoded.rms() > bound {
                    continue;
                }
                let cost = best.cost_of(&encoded);
                if choice.as_ref().is_none_or(|(c, ..)| cost < *c) {
                    choice = Some((cost, trial, encoded));
                }
            }
            let Some((_, trial, encoded)) = choice else { break };
            widths = trial;
            best = encoded;
        }
        // Then each grid its own widths, within the same bound.
        let scene_code = code(levels, &widths);
        let allocation = Allocation::new(&folded, &edges, &rendered, scene_code);
        let grid_codes = allocation.within_error(bound * bound * best.points as f64);
        let each = encode(&folded, &edges, &rendered, scene_code, |g| grid_codes[g]);
        if each.rms() <= bound.max(best.rms()) && each.bits <= best.bits {
            best = each;
        }
        Ok(Compressor {
            folded,
            edges,
            rendered,
            diagonal,
            scene_code,
            allocation,
            bounded: best,
        })
    }

    /// The values within the error bound, or, where that takes more than `max_bits`, in
    /// `max_bits` with the least error (the bound then exceeded).
    pub fn within(&self, max_bits: Option<u64>) -> CompressedMesh {
        let Some(max_bits) = max_bits.filter(|&b| b < self.bounded.bits) else {
            return self.finish(self.bounded.clone());
        };
        // The grids' own blocks give up the bits the rest (base edges, corners) cannot.
        let best = &self.bounded;
        let inner_bits: u64 = (best.grid_blocks.iter()).map(|&(_, bits)| bits as u64).sum();
        let grid_codes = (self.allocation).within_bits(max_bits.saturating_sub(best.bits - inner_bits));
        self.finish(encode(
            &self.folded,
            &self.edges,
            &self.rendered,
            self.scene_code,
            |g| grid_codes[g],
        ))
    }

    /// The micro-mesh holding `encoded`'s values, each triangle at its own level.
    fn finish(&self, encoded: Encoded) -> CompressedMesh {
        let mut mesh = self.folded.clone();
        mesh.micromap.values.clear();
        mesh.micromap.triangles.clear();
        let n = grid_size(self.scene_code.levels);
        for (g, values) in encoded.values.iter().enumerate() {
            mesh.micromap.triangles.push(MicromapTriangle {
                level: self.rendered.own_level(g, self.scene_code.levels),
                first_value: mesh.micromap.values.len() as u32,
            });
            let shift = self.scene_code.levels - self.rendered.own_level(g, self.scene_code.levels);
            // Its own level's points, u-major as a micromap holds them.
            let m = n >> shift;
            let own = (0..=m).flat_map(|i| (0..=m - i).map(move |j| [i << shift, j << shift]));
            mesh.micromap
                .values
                .extend(own.map(|p| values[u_major_index(p, n) as usize]));
        }
        mesh.decimated_edges = self.rendered.decimated_edges();
        mesh.micromap.value_code = Some(self.scene_code);
        CompressedMesh {
            added_error: (encoded.rms() / self.diagonal as f64) as f32,
            bits: encoded.bits,
            points: encoded.points,
            mesh,
            code: self.scene_code,
        }
    }
}

/// The code of `levels` levels with widths `w`, level 1 first.
fn code(levels: u32, w: &[u32; MAX_LEVELS as usize]) -> ValueCode {
    ValueCode {
        levels,
        widths: (0..levels as usize).fold(0, |acc, l| acc | w[l] << (WIDTH_BITS * l as u32)),
    }
}

/// Each grid's choices of widths, for a single trade-off of bits against error to pick from
/// (Lagrangian allocation: every grid stops narrowing where a bit saved would cost more error
/// than the one rate all grids share).
struct Allocation {
    /// Each grid's widths narrowed one level at a time, always where a bit saved costs the
    /// least error, and the scene's widths.
    choices: Vec<Vec<Choice>>,
    /// The squared error of the base edges and corners (at the scene's code).
    shared_error: f64,
}

impl Allocation {
    fn new(mesh: &DisplacedMesh, edges: &BaseEdges, rendered: &Rendered, scene: ValueCode) -> Allocation {
        let shared = SharedValues::encode(mesh, edges, rendered, scene);
        let choices = (0..mesh.triangles.len())
            .into_par_iter()
            .map(|g| {
                let own = rendered.own_level(g, scene.levels);
                let trial = |c: ValueCode| {
                    let (block, _) = encode_grid(mesh, g, c, &shared, edges, rendered);
                    Choice {
                        code: c,
                        bits: c.at_levels(own).inner_block_bits() as u64,
                        squared_error: block.squared_error,
                    }
                };
                // From a few bits wider than the scene's at each level: a grid that needs more
                // than that is rare, and each bit more lengthens every grid's path.
                let mut widths = [0; MAX_LEVELS as usize];
                for (l, w) in widths.iter_mut().enumerate().take(scene.levels as usize) {
                    *w = (scene.width(l as u32 + 1) + EXTRA_WIDTH).min(MAX_WIDTH);
                }
                let mut path = vec![trial(scene), trial(code(scene.levels, &widths))];
                loop {
                    let now = path[path.len() - 1];
                    let narrower = (0..own as usize)
                        .filter(|&l| widths[l] > 0)
                        .map(|l| {
                            let mut w = widths;
                            w[l] -= 1;
                            (w, trial(code(scene.levels, &w)))
                        })
                        .min_by(|(_, a), (_, b)| now.cost_of(a).total_cmp(&now.cost_of(b)));
                    let Some((w, next)) = narrower else { break };
                    widths = w;
                    path.push(next);
                }
                path
            })
            .collect();
        Allocation {
            choices,
            shared_error: shared.squared_error,
        }
    }

    /// Each grid's choice at `rate` (squared error per bit), and their squared error and bits.
    fn pick(&self, rate: f64) -> (f64, u64, Vec<ValueCode>) {
        let picked: Vec<&Choice> = (self.choices.iter())
            .map(|c| {
                c.iter()
                    .min_by(|a, b| a.price(rate).total_cmp(&b.price(rate)))
                    .expect("every grid has a choice")
            })
            .collect();
        (
            picked.iter().map(|c| c.squared_error).sum(),
            picked.iter().map(|c| c.bits).sum(),
            picked.iter().map(|c| c.code).collect(),
        )
    }

    /// The rate that `fits` says is the last to fit, where rates below it (`low_fits`) or
    /// above it do, by bisection of its logarithm.
    fn bisect(&self, low_fits: bool, fits: impl Fn(&(f64, u64, Vec<ValueCode>)) -> bool) -> Vec<ValueCode> {
        let rate = crate::lagrangian::bisect_rate(low_fits, |rate| fits(&self.pick(rate)));
        self.pick(rate).2
    }

    /// The widths whose squared error, with the base edges', stays within `budget` in the
    /// fewest bits: the largest rate that keeps within it (at the smallest every grid takes
    /// its least error).
    fn within_error(&self, budget: f64) -> Vec<ValueCode> {
        let budget = budget - self.shared_error;
        self.bisect(true, |(error, ..)| *error <= budget)
    }

    /// The widths whose blocks take at most `bits` in all, with the least error: the
    /// smallest rate that keeps within them (at the largest every grid takes its fewest).
    fn within_bits(&self, bits: u64) -> Vec<ValueCode> {
        self.bisect(false, |(_, b, _)| *b <= bits)
    }
}

/// One grid's block at one code: its bits and the squared error it leaves.
#[derive(Copy, Clone)]
struct Choice {
    code: ValueCode,
    bits: u64,
    squared_error: f64,
}

impl Choice {
    /// Error added per bit saved, going from `self` to `other`.
    fn cost_of(&self, other: &Choice) -> f64 {
        error_per_bit_saved((self.bits, self.squared_error), (other.bits, other.squared_error))
    }

    /// Bits, with error at `rate` squared error per bit.
    fn price(&self, rate: f64) -> f64 {
        self.bits as f64 + self.squared_error / rate
    }
}

/// A micro-mesh's values encoded: the base edges with the scene's code, each grid with its
/// own.
#[derive(Clone, Debug, Default)]
pub struct Encoded {
    /// Each grid's block (its widths, shifts and corrections) and its length in bits.
    pub grid_blocks: Vec<(Vec<u32>, u32)>,
    /// The base edges' blocks end to end, by edge id (after their table of levels, in grids
    /// of mixed levels), then every base vertex's value.
    pub shared: Vec<u32>,
    /// Bits of `shared` before the corners' values.
    pub edge_area_bits: u64,
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

    /// Error added per bit saved, going from `self` to `other`.
    fn cost_of(&self, other: &Encoded) -> f64 {
        error_per_bit_saved((self.bits, self.squared_error), (other.bits, other.squared_error))
    }
}

/// Squared error added per bit saved going from `(bits, squared error)` `from` to `to`.
fn error_per_bit_saved(from: (u64, f64), to: (u64, f64)) -> f64 {
    let saved = from.0.saturating_sub(to.0).max(1) as f64;
    (to.1 - from.1).max(0.0) / saved
}

/// Encodes the values of `mesh` (ranges folded, one level): the base edges with `scene`
/// (ids by `edges`, from the corners), then grid `g` with `grid_code(g)` (from its corners and
/// edges as decoded).
pub(super) fn encode(
    mesh: &DisplacedMesh,
    edges: &BaseEdges,
    rendered: &Rendered,
    scene: ValueCode,
    grid_code: impl Fn(usize) -> ValueCode + Sync,
) -> Encoded {
    let shared = SharedValues::encode(mesh, edges, rendered, scene);
    let grid_blocks: Vec<(BlockEncoder, Vec<u16>)> = (0..mesh.triangles.len())
        .into_par_iter()
        .map(|g| encode_grid(mesh, g, grid_code(g), &shared, edges, rendered))
        .collect();
    let mut out = Encoded {
        squared_error: shared.squared_error,
        points: shared.points,
        bits: shared.bits,
        shared: shared.words,
        edge_area_bits: shared.edge_area_bits,
        ..Encoded::default()
    };
    for (block, values) in grid_blocks {
        out.squared_error += block.squared_error;
        out.points += block.points;
        let mut words = BitWriter::default();
        block.write(&mut words);
        out.bits += words.bits as u64;
        out.grid_blocks.push((words.words, words.bits as u32));
        out.values.push(values);
    }
    out
}

/// Encodes `mesh` (ranges folded, one level) with no loss, for values a compressed code made:
/// the base edges with `scene`, each grid with the narrowest widths that decode its values
/// exactly. `None` when some value is off every such code.
pub(super) fn encode_exact(
    mesh: &DisplacedMesh,
    (edges, rendered): (&BaseEdges, &Rendered),
    scene: ValueCode,
) -> Option<Encoded> {
    let codes: Option<Vec<ValueCode>> = (0..mesh.triangles.len())
        .into_par_iter()
        .map(|g| exact_code(mesh, g, rendered.own_level(g, scene.levels)))
        .collect();
    let codes = codes?;
    let encoded = encode(mesh, edges, rendered, scene, |g| codes[g]);
    let exact = (0..mesh.triangles.len()).all(|g| encoded.values[g] == mesh.micromap.triangle_values(g));
    exact.then_some(encoded)
}

/// The narrowest widths, level by level up to `own`, at which grid `g`'s inner values decode
/// exactly from its own corners and edges (finer points are their parents' means); `None`
/// where no width does.
fn exact_code(mesh: &DisplacedMesh, g: usize, own: u32) -> Option<ValueCode> {
    let n = grid_size(mesh.micromap.triangles[g].level);
    let truth = mesh.micromap.triangle_values(g);
    let at = |p: Lattice| u_major_index(p, n) as usize;
    let mut widths = [0; MAX_LEVELS as usize];
    for l in 1..=own {
        let targets: Vec<Target> = new_inner_points(l, n)
            .into_iter()
            .map(|p| {
                let [pa, pb] = parents(p, n >> l);
                Target {
                    truth: truth[at(p)],
                    parents: (truth[at(pa)], truth[at(pb)]),
                    unit: 1.0,
                    counted: true,
                }
            })
            .collect();
        let exact = |width: u32, shift: u32| targets.iter().all(|t| t.encode(width, shift).1 == t.truth as u32);
        widths[l as usize - 1] =
            (0..=MAX_WIDTH).find(|&w| (0..=if w == 0 { 0 } else { VALUE_BITS }).any(|s| exact(w, s)))?;
    }
    Some(code(own, &widths))
}

/// Distance one value step moves lattice point `p` of grid `g` (of size `n`).
fn unit(mesh: &DisplacedMesh, g: usize, p: Lattice, n: u32) -> f32 {
    interpolated(&mesh.base_triangle(g), p, n).1.length() / VALUE_MAX as f32
}

/// The values every grid takes from what it shares: the base edges' and corners', as decoded.
struct SharedValues {
    /// Each base vertex's value.
    corner_values: Vec<u16>,
    /// Each base edge's values, along its stored direction, corners included.
    edge_values: Vec<Vec<u16>>,
    /// The base edges' blocks end to end, by edge id (after their table of levels, in grids
    /// of mixed levels), then the corners' values.
    words: Vec<u32>,
    /// Bits of `words` before the corners' values.
    edge_area_bits: u64,
    bits: u64,
    squared_error: f64,
    points: u64,
}

impl SharedValues {
    /// Corners as plain values, from the first grid that uses each base vertex; each base
    /// edge along its stored direction (from its lower vertex id) with `code`, from the grid
    /// that owns it.
    fn encode(mesh: &DisplacedMesh, edges: &BaseEdges, rendered: &Rendered, code: ValueCode) -> SharedValues {
        let n = grid_size(code.levels);
        let mut corner_values = vec![0u16; mesh.positions.len()];
        let mut corner_seen = vec![false; mesh.positions.len()];
        for (g, t) in mesh.triangles.iter().enumerate() {
            for (c, &v) in t.iter().enumerate() {
                if !std::mem::replace(&mut corner_seen[v as usize], true) {
                    corner_values[v as usize] =
                        mesh.micromap.triangle_values(g)[u_major_index(corner_point(c as u32, n), n) as usize];
                }
            }
        }
        let edge_blocks: Vec<(BlockEncoder, Vec<u16>)> = (edges.owner.par_iter().enumerate())
            .map(|(id, &(g, e))| {
                let t = mesh.triangles[g];
                let original = mesh.micromap.triangle_values(g);
                let (from, to) = (t[e], t[(e + 1) % 3]);
                let point = |s: u32| stored_edge_point(&t, e, s, n);
                let mut values: Vec<u16> = (0..=n).map(|s| original[u_major_index(point(s), n) as usize]).collect();
                values[0] = corner_values[from.min(to) as usize];
                values[n as usize] = corner_values[from.max(to) as usize];
                let truth = values.clone();
                let held = code.at_levels(rendered.edge_level(id, code.levels));
                let mut block = BlockEncoder::new(held);
                for l in 1..=code.levels {
                    let step = n >> l;
                    let targets: Vec<Target> = (1..=(1 << l >> 1))
                        .map(|k| {
                            let s = (2 * k - 1) * step;
                            Target {
                                truth: truth[s as usize],
                                parents: (values[(s - step) as usize], values[(s + step) as usize]),
                                unit: unit(mesh, g, point(s), n),
                                counted: rendered.edge_point(id, s),
                            }
                        })
                        .collect();
                    let decoded = match l <= held.levels {
                        true => block.level(l, &targets),
                        false => targets.iter().map(Target::mean).collect(),
                    };
                    for (k, q) in decoded.into_iter().enumerate() {
                        values[((2 * k + 1) as u32 * step) as usize] = q;
                    }
                }
                (block, values)
            })
            .collect();
        let mut out = BitWriter::default();
        if !rendered.own.is_empty() {
            write_edge_levels(&rendered.edge_levels, |l| code.at_levels(l).edge_block_bits(), &mut out);
        }
        let (mut squared_error, mut points) = (0.0, corner_values.len() as u64);
        let mut edge_values = Vec::with_capacity(edges.owner.len());
        for (block, values) in edge_blocks {
            squared_error += block.squared_error;
            points += block.points;
            block.write(&mut out);
            edge_values.push(values);
        }
        let edge_area_bits = out.bits as u64;
        for &q in &corner_values {
            out.push(q as u32, VALUE_BITS);
        }
        let bits = out.bits as u64;
        out.words.push(0);
        SharedValues {
            corner_values,
            edge_values,
            words: out.words,
            edge_area_bits,
            bits,
            squared_error,
            points,
        }
    }
}

/// Grid `g`'s block at `code` (its widths first), from its corners and edges as decoded, and
/// its decoded values.
fn encode_grid(
    mesh: &DisplacedMesh,
    g: usize,
    code: ValueCode,
    shared: &SharedValues,
    edges: &BaseEdges,
    rendered: &Rendered,
) -> (BlockEncoder, Vec<u16>) {
    let levels = mesh.micromap.triangles[g].level;
    let n = grid_size(levels);
    let t = mesh.triangles[g];
    let truth = mesh.micromap.triangle_values(g);
    let mut values = truth.to_vec();
    for c in 0..3 {
        values[u_major_index(corner_point(c as u32, n), n) as usize] = shared.corner_values[t[c] as usize];
    }
    for e in 0..3 {
        let edge = &shared.edge_values[edges.of_grid[g][e] as usize];
        for s in 1..n {
            values[u_major_index(stored_edge_point(&t, e, s, n), n) as usize] = edge[s as usize];
        }
    }
    let at = |p: Lattice| u_major_index(p, n) as usize;
    let held = code.at_levels(rendered.own_level(g, levels));
    let mut block = BlockEncoder::with_widths(held);
    for l in 1..=levels {
        let step = n >> l;
        let points = new_inner_points(l, n);
        let targets: Vec<Target> = points
            .iter()
            .map(|&p| {
                let [pa, pb] = parents(p, step);
                Target {
                    truth: truth[at(p)],
                    parents: (values[at(pa)], values[at(pb)]),
                    unit: unit(mesh, g, p, n),
                    counted: rendered.inner_point(g, p),
                }
            })
            .collect();
        let decoded = match l <= held.levels {
            true => block.level(l, &targets),
            false => targets.iter().map(Target::mean).collect(),
        };
        for (&p, q) in points.iter().zip(decoded) {
            values[at(p)] = q;
        }
    }
    (block, values)
}

/// The inner points new at level `l` of a grid of size `n`, in the order the format stores
/// them (row by row on the level's lattice).
fn new_inner_points(l: u32, n: u32) -> Vec<Lattice> {
    let (step, m) = (n >> l, 1u32 << l);
    let mut points = Vec::with_capacity(inner_new_count(l) as usize);
    for a in 1..m {
        for b in 1..m - a {
            if a % 2 == 1 || b % 2 == 1 {
                points.push([a * step, b * step]);
            }
        }
    }
    points
}

/// A point to encode: its true value, its parents' decoded values, the distance a value
/// step moves it, and whether a grid renders it (see [`Rendered`]): the error of one that
/// none does counts for nothing.
struct Target {
    truth: u16,
    parents: (u16, u16),
    unit: f32,
    counted: bool,
}

/// One block's shifts and corrections, level by level.
struct BlockEncoder {
    code: ValueCode,
    /// Whether the block begins with its widths (a grid's block).
    own_widths: bool,
    shifts: u32,
    corrections: Vec<(u32, u32)>,
    squared_error: f64,
    points: u64,
}

impl BlockEncoder {
    fn new(code: ValueCode) -> Self {
        BlockEncoder {
            code,
            own_widths: false,
            shifts: 0,
            corrections: Vec::new(),
            squared_error: 0.0,
            points: 0,
        }
    }

    /// A grid's block, which begins with its widths.
    fn with_widths(code: ValueCode) -> Self {
        BlockEncoder {
            own_widths: true,
            ..BlockEncoder::new(code)
        }
    }

    /// Encodes level `l`'s points with the shift that leaves the least squared error (then
    /// the least error in values, where points do not move); returns their decoded values.
    fn level(&mut self, l: u32, targets: &[Target]) -> Vec<u16> {
        let width = self.code.width(l);
        let shifts = if width == 0 { 0 } else { (1 << SHIFT_BITS) - 1 };
        let mut best: Option<((f64, u64), u32)> = None;
        for shift in 0..=shifts.min(VALUE_BITS) {
            let error = targets.iter().fold((0.0, 0), |(e, v), t| {
                let (point, value) = t.error(width, shift);
                (e + point, v + value)
            });
            if best.is_none_or(|(e, _)| error < e) {
                best = Some((error, shift));
            }
        }
        let ((error, _), shift) = best.unwrap_or(((0.0, 0), 0));
        self.shifts |= shift << (SHIFT_BITS * (l - 1));
        self.squared_error += error;
        self.points += targets.iter().filter(|t| t.counted).count() as u64;
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
        if self.own_widths {
            out.push(self.code.widths, self.code.width_bits());
        }
        out.push(self.shifts, self.code.shift_bits());
        for &(field, width) in &self.corrections {
            out.push(field, width);
        }
    }
}

impl Target {
    /// Its parents' mean, the value of a point finer than its block holds.
    fn mean(&self) -> u16 {
        ((self.parents.0 as u32 + self.parents.1 as u32 + 1) >> 1) as u16
    }

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

    /// The squared distance the point moves and the squared change of its value, encoded
    /// at `width` and `shift`.
    fn error(&self, width: u32, shift: u32) -> (f64, u64) {
        if !self.counted {
            return (0.0, 0);
        }
        let (_, q) = self.encode(width, shift);
        let v = q as i64 - self.truth as i64;
        let d = v as f64 * self.unit as f64;
        (d * d, (v * v) as u64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::displaced::{build, layout};
    use crate::grid::GridOptions;
    use crate::micromesh::bary::Micromap;
    use gridrt_shared::compressed_values::CodedScene;
    use gridrt_shared::glam::Vec3;
    use gridrt_shared::grid_index::lattice_points;
    use gridrt_shared::value_tables::EDGE_LEVEL_WORDS;

    /// A closed tetrahedron at `levels` whose values follow a bumpy function of each point's
    /// undisplaced position, plus a hash of it as noise inside each triangle (none on triangle
    /// 0, up to `noise` on triangle 3): neighbours agree on shared edges.
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
                        let inner = p[0] > 0 && p[1] > 0 && p[0] + p[1] < n;
                        let noise = if inner { noise * t as u32 / 3 } else { 0 };
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
                let compressed = compress(&mesh, &ValueCompression::bounded(bound)).unwrap();
                let grids = build(&compressed.mesh, &GridOptions::for_displaced()).unwrap();
                let params = grids.params;
                let code = ValueCode {
                    levels,
                    widths: params.value_widths,
                };
                assert_eq!(code, compressed.code);
                let scene = CodedScene {
                    code,
                    edge_bit: 32 * params.edge_word,
                    edge_block_bits: params.edge_block_bits,
                    corner_bit: params.corner_bit,
                    offset_bits: params.block_offset_bits,
                    mixed: false,
                };
                let (n, view, buffer) = (grid_size(levels), grids.view(), &grids.vertices[..]);
                for slot in 0..4 {
                    let g = grids.base_triangle[slot] as usize;
                    let grid = scene.open(buffer, &view.ids(slot as u32), slot as u32, levels);
                    let values = compressed.mesh.micromap.triangle_values(g);
                    for p in lattice_points(n) {
                        let q = grid.value(buffer, p);
                        assert_eq!(
                            q,
                            values[u_major_index(p, n) as usize] as u32,
                            "L{levels} {bound} grid {g} {p:?}"
                        );
                    }
                    windows_decode_their_points(&grid, buffer, n);
                }
            }
        }
    }

    /// A leaf test's window of the whole grid's lattice, whatever its bounds, decodes each of
    /// its points to the value the single-point path reads (the rest of the lattice is left
    /// as it was).
    fn windows_decode_their_points(grid: &gridrt_shared::compressed_values::CodedGrid, buffer: &[u32], n: u32) {
        use gridrt_shared::compressed_values::{PackedValues, SubLattice};
        use gridrt_shared::grid_index::lattice_index;
        let corners = grid.sub_triangle_values(buffer, 0, 0);
        let whole = SubLattice {
            first: [0, 0],
            step: 1,
            k: n.trailing_zeros(),
        };
        let points: Vec<_> = lattice_points(n).map(|p| (p, grid.value(buffer, p))).collect();
        let bounds = [0, 1, n / 2 - 1, n / 2, n / 2 + 1, n - 1, n];
        for &la_lo in &bounds {
            for &la_hi in bounds.iter().filter(|&&h| h >= la_lo) {
                for &lb_lo in &bounds {
                    for &lb_hi in bounds.iter().filter(|&&h| h >= lb_lo) {
                        let window = [la_lo, la_hi, lb_lo, lb_hi];
                        let mut out = PackedValues::<281>::filled(0xffff);
                        grid.decode_lattice(buffer, whole, corners, window, &mut out);
                        for &(p, value) in &points {
                            if (la_lo..=la_hi).contains(&p[0]) && (lb_lo..=lb_hi).contains(&p[1]) {
                                let decoded = out.get(lattice_index(p[0], p[1], n));
                                assert_eq!(decoded, value, "window {window:?} {p:?}");
                            }
                        }
                    }
                }
            }
        }
    }

    /// In grids of mixed levels every block holds its own levels only: the tetrahedron's
    /// first triangle at level 3 and the rest at level 2 render every base edge at level 2,
    /// so each edge's block holds two levels, after the table of levels, and each level-2
    /// grid's block two levels' widths and shifts; every point reads back as compressed.
    #[test]
    fn blocks_of_mixed_levels_hold_their_own_levels() {
        let fine = tetrahedron(3, 40);
        let n = grid_size(3);
        let own: Vec<(u32, Vec<u16>)> = (0..4)
            .map(|t| {
                let values = fine.micromap.triangle_values(t);
                match t {
                    0 => (3, values.to_vec()),
                    _ => {
                        let coarse =
                            lattice_points(n / 2).map(|[i, j]| values[u_major_index([2 * i, 2 * j], n) as usize]);
                        (2, coarse.collect())
                    }
                }
            })
            .collect();
        let mixed = DisplacedMesh {
            micromap: Micromap::from_triangles(0.0, 1.0, &own),
            decimated_edges: vec![0b111, 0, 0, 0],
            ..fine
        };
        let compressed = compress(&mixed, &ValueCompression::bounded(1e-3)).unwrap();
        let grids = build(&compressed.mesh, &GridOptions::for_displaced()).unwrap();
        let params = grids.params;
        let edge_bits = compressed.code.at_levels(2).edge_block_bits();
        assert_eq!(
            params.corner_bit - 32 * params.edge_word,
            32 * EDGE_LEVEL_WORDS + 6 * edge_bits
        );
        let (folded, levels) = (compressed.mesh.with_ranges_folded(), [3, 2, 2, 2]);
        let (edges, rendered) = level_sorted_edges(&folded);
        let exact = encode_exact(&expanded_mesh(&folded), (&edges, &rendered), compressed.code).unwrap();
        for (g, &(_, bits)) in exact.grid_blocks.iter().enumerate() {
            let held = 2 * (WIDTH_BITS + SHIFT_BITS);
            assert!(
                levels[g] == 3 || bits >= held && bits < held + 3 * 11,
                "grid {g}: {bits} bits"
            );
        }
        let view = grids.view();
        for (slot, &t) in grids.base_triangle.iter().enumerate() {
            let open = view.open(slot as u32);
            let (level, t) = (levels[t as usize], t as usize);
            let shift = 3 - level;
            for (q, want) in lattice_points(grid_size(level)).zip(folded.micro_vertices(t)) {
                assert_eq!(
                    view.vertex(&open, [q[0] << shift, q[1] << shift]),
                    want,
                    "triangle {t} at {q:?}"
                );
            }
        }
    }

    /// Each grid takes its own widths: the noisiest more bits than the others, and
    /// laying the result out again finds widths that decode every value as compressed.
    #[test]
    fn smooth_grids_take_fewer_bits() {
        let mesh = tetrahedron(4, 200);
        let compressed = compress(&mesh, &ValueCompression::bounded(2e-3)).unwrap();
        let folded = &compressed.mesh;
        let (edges, rendered) = level_sorted_edges(folded);
        let exact = encode_exact(folded, (&edges, &rendered), compressed.code).unwrap();
        assert!(exact.bits <= compressed.bits, "{} > {}", exact.bits, compressed.bits);
        let bits: Vec<u32> = exact.grid_blocks.iter().map(|b| b.1).collect();
        assert!(bits[3] > bits[0].max(bits[1]).max(bits[2]), "{bits:?}");
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
            let c = compress(&mesh, &ValueCompression::bounded(bound)).unwrap();
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

    /// A bit budget below what the error bound needs is kept, trading error for bits; one
    /// above it changes nothing.
    #[test]
    fn compression_keeps_to_its_bit_budget() {
        let mesh = tetrahedron(4, 40);
        let bounded = compress(&mesh, &ValueCompression::bounded(1e-4)).unwrap();
        let within = |max_bits| ValueCompression {
            max_bits: Some(max_bits),
            ..ValueCompression::bounded(1e-4)
        };
        let loose = compress(&mesh, &within(bounded.bits + 1)).unwrap();
        assert_eq!(loose.mesh.micromap.values, bounded.mesh.micromap.values);
        let max_bits = bounded.bits * 2 / 3;
        let tight = compress(&mesh, &within(max_bits)).unwrap();
        assert!(tight.bits <= max_bits, "{} > {max_bits}", tight.bits);
        assert!(tight.added_error > bounded.added_error);
    }

    /// Values that no longer match their code are refused by the layout, not stored wrong.
    #[test]
    fn values_off_their_code_are_refused() {
        let mut compressed = compress(&tetrahedron(3, 40), &ValueCompression::bounded(1e-2))
            .unwrap()
            .mesh;
        // A point on a base edge, which both grids read from one block of the edges' widths.
        compressed.micromap.values[1] ^= 0x155;
        let err = layout(&compressed, &GridOptions::for_displaced()).unwrap_err();
        assert!(err.to_string().contains("compressed code"), "{err}");
    }
}
