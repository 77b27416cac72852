//! A bake as a user asks for it, one call: a reference file baked into a displaced micro-mesh
//! within an error bound or a byte budget, written as glTF + `.bary`, and measured against
//! the reference. `gridrt bake` is this call plus printing; every decision (the base, the
//! levels, how the values are compressed to fit a budget) is made here.
//!
//! Guarantees: nothing is read or written before the request is checked (its options, and
//! that the output is none of the files it reads); the output files are written whole, never
//! over an input; the summary's distances are measured on the micro-mesh as written.

use std::path::{Path, PathBuf};

use serde::Serialize;

use super::refine::Refinement;
use super::{BakeOptions, BakeReport, Baked, Base};
use crate::error::{fail, Result};
use crate::grid::compressed::{compress, CompressedMesh, Compressor, ValueCompression};
use crate::grid::{self, GridOptions};
use crate::mesh::frame::LocalFrame;
use crate::mesh::Mesh;
use crate::micromesh::{self, DisplacedMesh};
use crate::progress::{self, Progress};
use crate::surface_distance::{self, DistanceSummary, Sampling, SurfaceDistance};
use crate::{files, input};

/// What to bake, and how: the options of `gridrt bake` (see `gridrt bake --help`).
#[derive(Clone, Debug, PartialEq)]
pub struct BakeRequest {
    /// The detailed mesh (.obj, .ply, .gltf, .glb).
    pub reference: PathBuf,
    /// A base mesh to bake onto, in the reference's units, instead of decimating.
    pub base: Option<PathBuf>,
    /// Triangles of the decimated base; `None`: 1/64 of the reference's, at least 128.
    pub base_triangles: Option<usize>,
    /// Subdivision level (each base triangle's most, with `max_error` or `within_bytes`).
    pub levels: u32,
    /// Rounds of least-squares fitting.
    pub fit_rounds: u32,
    /// The glTF to write; its buffer and micromap go beside it.
    pub output: PathBuf,
    /// Compress the values adding at most this RMS error (a fraction of the base's diagonal);
    /// `None`: half the uncompressed bake's own distance from the reference.
    pub compress_values: Option<f32>,
    /// Leave the values uncompressed.
    pub plain_values: bool,
    /// Most bytes per micro-triangle of everything the GPU gets; `None`: the level's default.
    pub max_bytes: Option<f64>,
    /// A level per base triangle within this symmetric RMS distance (a fraction of the
    /// reference's diagonal).
    pub max_error: Option<f32>,
    /// A level per base triangle, as close as this many bytes of everything the GPU gets allow.
    pub within_bytes: Option<u64>,
    /// Store the values in NVIDIA's compressed blocks.
    pub nv_blocks: bool,
    /// Points sampled on each surface to measure the distance.
    pub samples: usize,
}

impl BakeRequest {
    /// `reference` baked to `output` at the defaults of `gridrt bake`.
    pub fn new(reference: impl Into<PathBuf>, output: impl Into<PathBuf>) -> Self {
        BakeRequest {
            reference: reference.into(),
            base: None,
            base_triangles: None,
            levels: 3,
            fit_rounds: Refinement::default().rounds,
            output: output.into(),
            compress_values: None,
            plain_values: false,
            max_bytes: None,
            max_error: None,
            within_bytes: None,
            nv_blocks: false,
            samples: 1_000_000,
        }
    }

    /// Refuses options out of range or that exclude each other (the command line's parser
    /// refuses the same before this).
    pub fn check(&self) -> Result<()> {
        if self.levels > 6 {
            fail!(Options, "level {}: at most 6", self.levels);
        }
        if self.fit_rounds > super::refine::MAX_ROUNDS {
            fail!(
                Options,
                "{} fitting rounds: at most {}",
                self.fit_rounds,
                super::refine::MAX_ROUNDS
            );
        }
        let finite = |v: Option<f64>| v.is_none_or(|v| v.is_finite() && v >= 0.0);
        if !finite(self.compress_values.map(f64::from)) || !finite(self.max_error.map(f64::from)) {
            fail!(Options, "an error bound is a fraction of the diagonal, at least 0");
        }
        if self.max_bytes.is_some_and(|b| !(b.is_finite() && b > 0.0)) {
            fail!(Options, "a byte budget is bytes per micro-triangle, above 0");
        }
        if self.base_triangles == Some(0) || self.within_bytes == Some(0) || self.samples == 0 {
            fail!(Options, "base triangles, a budget in bytes and samples are at least 1");
        }
        let given = |set: bool, name: &'static str| set.then_some(name);
        let exclusive = [
            [
                given(self.base.is_some(), "a base"),
                given(self.base_triangles.is_some(), "base triangles"),
            ],
            [
                given(self.compress_values.is_some(), "a compression bound"),
                given(self.plain_values, "plain values"),
            ],
            [
                given(self.max_bytes.is_some(), "a byte budget"),
                given(self.plain_values, "plain values"),
            ],
            [
                given(self.max_error.is_some(), "an error bound"),
                given(self.max_bytes.is_some(), "a byte budget"),
            ],
            [
                given(self.nv_blocks, "NVIDIA's blocks"),
                given(self.compress_values.is_some(), "a compression bound"),
            ],
            [
                given(self.nv_blocks, "NVIDIA's blocks"),
                given(self.max_bytes.is_some(), "a byte budget"),
            ],
        ];
        let within = given(self.within_bytes.is_some(), "a budget in bytes");
        let with_within = [
            self.max_error.is_some(),
            self.max_bytes.is_some(),
            self.compress_values.is_some(),
            self.nv_blocks,
        ];
        if within.is_some() && with_within.iter().any(|&b| b) {
            fail!(
                Options,
                "a budget in bytes chooses the levels and the values' bits itself: give it alone"
            );
        }
        if let Some([Some(a), Some(b)]) = exclusive.iter().find(|pair| pair.iter().all(Option::is_some)) {
            fail!(Options, "{a} and {b} cannot be asked for together");
        }
        Ok(())
    }
}

/// Bakes `request.reference` into `request.output` (with its `.bin` and `.bary` beside it) and
/// measures the result against the reference, reporting stages, notes and warnings to
/// `progress`.
pub fn bake_file(request: &BakeRequest, progress: &mut dyn Progress) -> Result<BakeSummary> {
    request.check()?;
    let inputs = check_outputs(request)?;
    let (reference, cleaning, warnings) =
        progress::run(progress, "load", || input::load_world_warning(&request.reference))?;
    for warning in warnings {
        progress.warning(&warning);
    }
    if cleaning.welded + cleaning.dropped > 0 {
        progress.note(&format!(
            "{}: welded {} vertices, dropped {} degenerate or repeated triangles",
            request.reference.display(),
            cleaning.welded,
            cleaning.dropped
        ));
    }
    let frame = reference.local_frame();
    let reference_mesh = reference.in_frame(&frame);
    let name = request.reference.display().to_string();
    surface_distance::check_area(&reference_mesh, &name)?;
    let options = bake_options(request, &reference_mesh, &frame, progress)?;
    let started = std::time::Instant::now();
    let named = |e: crate::error::Error| e.prefixed(&name);
    // The bake, and its distance from the reference where choosing its levels measured it.
    let (baked, measured) =
        progress::run(progress, "bake", || bake_levels(&reference_mesh, &options, request)).map_err(named)?;
    let bake_seconds = started.elapsed().as_secs_f64();
    let (report, micro_triangles) = (baked.report, baked.report.micro_triangles);
    let sampling = Sampling {
        samples: request.samples,
        ..Sampling::default()
    };
    let measure = |progress: &mut dyn Progress, mesh: &DisplacedMesh| {
        let decoded = mesh.decoded();
        progress::run(progress, "measure", || {
            surface_distance::measure(&reference_mesh, &decoded, &sampling)
        })
    };
    let plain = match measured {
        Some(distance) => distance,
        None => measure(progress, &baked.mesh),
    };
    let Values {
        mesh,
        compression,
        nv_blocks,
        distance: d,
    } = store_values(request, baked.mesh, micro_triangles, plain, progress, &measure)?;
    let outputs = progress::run(progress, "write", || {
        micromesh::gltf::write_keeping(&request.output, &mesh, &frame, &inputs)
    })?;
    let bytes = |p: &Path| std::fs::metadata(p).map_or(0, |m| m.len());
    let mut summary = BakeSummary {
        reference: request.reference.display().to_string(),
        reference_triangles: reference_mesh.triangles.len(),
        output: request.output.display().to_string(),
        bake: report,
        file_bytes: outputs.iter().map(|p| bytes(p)).sum(),
        micromap_bytes: bytes(&outputs[2]),
        grid_bytes: grid_memory(&mesh).map(|parts| total(&parts)),
        within_bytes: request.within_bytes,
        level_micro_triangles: (request.max_error.is_some() || request.within_bytes.is_some())
            .then(|| super::levels::level_counts(&mesh)),
        bake_seconds,
        compression,
        nv_blocks,
        reference_to_baked: d.a_to_b.relative_to(d.a_diagonal),
        baked_to_reference: d.b_to_a.relative_to(d.a_diagonal),
        symmetric: d.symmetric.relative_to(d.a_diagonal),
        shortfalls: Vec::new(),
    };
    let outcome = super::Outcome {
        report: &summary.bake,
        base: &options.base,
        reference_to_baked: &summary.reference_to_baked,
        symmetric: &summary.symmetric,
        max_error: request.max_error,
    };
    summary.shortfalls = (super::shortfalls(&outcome).into_iter())
        .map(|line| format!("{name} -> {}: {line}", request.output.display()))
        .collect();
    Ok(summary)
}

/// The bake's options: the base (the one given, moved into the reference's frame, or the
/// reference decimated), the level and the fitting rounds asked for.
fn bake_options(
    request: &BakeRequest,
    reference: &Mesh,
    frame: &LocalFrame,
    progress: &mut dyn Progress,
) -> Result<BakeOptions> {
    let base = match &request.base {
        Some(path) => {
            let (base, _, warnings) = progress::run(progress, "load base", || input::load_world_warning(path))?;
            for warning in warnings {
                progress.warning(&warning);
            }
            Base::Given(base.in_frame(frame))
        }
        None => Base::Decimated {
            triangles: (request.base_triangles).unwrap_or(super::default_base_triangles(reference.triangles.len())),
        },
    };
    let defaults = BakeOptions::for_reference(reference, request.levels);
    let options = BakeOptions {
        base,
        refinement: Refinement {
            rounds: request.fit_rounds,
            ..defaults.refinement
        },
        ..defaults
    };
    Ok(options)
}

/// The values a bake is written with, and the distance of the result from the reference.
struct Values {
    mesh: DisplacedMesh,
    compression: Option<CompressionReport>,
    nv_blocks: Option<BlocksReport>,
    distance: SurfaceDistance,
}

/// `mesh`'s values as the request stores them: plain, in NVIDIA's blocks, or compressed within
/// the bound and any byte budget (kept plain where that takes fewer of the GPU's bytes);
/// `plain` is the plain values' distance from the reference, `measure` measures another.
fn store_values(
    request: &BakeRequest,
    mesh: DisplacedMesh,
    micro_triangles: u64,
    plain: SurfaceDistance,
    progress: &mut dyn Progress,
    measure: &dyn Fn(&mut dyn Progress, &DisplacedMesh) -> SurfaceDistance,
) -> Result<Values> {
    Ok(match compression_bound(request, &mesh, &plain) {
        None if request.nv_blocks => {
            let (mesh, value_bytes) = progress::run(progress, "blocks", || mesh.in_nv_blocks());
            let d = measure(progress, &mesh);
            let blocks = BlocksReport {
                value_bytes,
                before_symmetric: plain.symmetric.relative_to(plain.a_diagonal),
            };
            Values {
                mesh,
                compression: None,
                nv_blocks: Some(blocks),
                distance: d,
            }
        }
        None => Values {
            mesh,
            compression: None,
            nv_blocks: None,
            distance: plain,
        },
        Some(bound) => {
            let budget = byte_budget(request, micro_triangles).map(|per_micro| ByteBudget {
                per_micro,
                micro_triangles,
                asked: request.max_bytes.is_some() || request.within_bytes.is_some(),
            });
            let (compressed, mut budget) =
                progress::run(progress, "compress", || compress_within(&mesh, bound, budget))?;
            let kept_plain = match fewer_bytes(&mesh, &compressed.mesh) {
                Some((plain_parts, true)) => {
                    budget.binds = false;
                    budget.met |= budget.max_bytes.is_none_or(|per_micro| {
                        total(&plain_parts) as f64 <= (per_micro * micro_triangles as f64).floor()
                    });
                    true
                }
                _ => false,
            };
            let d = match kept_plain {
                true => plain,
                false => measure(progress, &compressed.mesh),
            };
            let report = CompressionReport {
                widths: grid::compressed::level_widths(&compressed.code),
                bits_per_value: compressed.bits_per_value(),
                max_added_error: bound.max_added_error,
                added_error: compressed.added_error,
                max_bytes: budget.max_bytes,
                budget_default: budget.default,
                budget_binds: budget.binds,
                budget_met: budget.met,
                uncompressed_symmetric: plain.symmetric.relative_to(plain.a_diagonal),
                kept_plain,
            };
            Values {
                mesh: if kept_plain { mesh } else { compressed.mesh },
                compression: Some(report),
                nv_blocks: None,
                distance: d,
            }
        }
    })
}

/// The bake at the request's levels: one level, a level per base triangle within an error
/// bound, or within a budget of bytes (whose choice measures the distance it lands at).
fn bake_levels(
    reference: &Mesh,
    options: &BakeOptions,
    request: &BakeRequest,
) -> Result<(Baked, Option<SurfaceDistance>)> {
    match (request.max_error, request.within_bytes) {
        (None, Some(bytes)) => bake_within_bytes(reference, options, bytes, request),
        (None, None) => Ok((super::bake(reference, options)?, None)),
        (Some(max_error), _) => {
            let (lo, hi) = reference.bounds();
            let share = match compression_follows(request) {
                true => super::levels_error_share(),
                false => 1.0,
            };
            let target = super::levels::LevelTarget::MaxError(share * max_error * (hi - lo).length());
            Ok((super::levels::bake_levels(reference, options, target)?, None))
        }
    }
}

/// What a bake made, as `gridrt bake` reports it (its `--json` object).
#[derive(Debug, Serialize)]
pub struct BakeSummary {
    pub reference: String,
    pub reference_triangles: usize,
    pub output: String,
    #[serde(flatten)]
    pub bake: BakeReport,
    /// Bytes of the three files written (glTF, its buffer, its micromap).
    pub file_bytes: u64,
    /// The micromap's bytes alone (values and their tables).
    pub micromap_bytes: u64,
    /// Everything the GPU gets to trace the result as displaced grids at their defaults:
    /// values, base mesh, headers, radii, leaf thicknesses, top-level BVH.
    /// `None` where the micro-mesh is too large for displaced grids (rendered as triangles).
    pub grid_bytes: Option<u64>,
    /// The budget for `grid_bytes` the levels were chosen for (`--within-bytes`).
    pub within_bytes: Option<u64>,
    /// Micro-triangles at each level `0 ..= 6`, where base triangles have their own levels
    /// (`--max-error`).
    pub level_micro_triangles: Option<Vec<u64>>,
    pub bake_seconds: f64,
    /// How the values were compressed; `None` where they were left plain.
    pub compression: Option<CompressionReport>,
    /// The values in NVIDIA's blocks (`--nv-blocks`).
    pub nv_blocks: Option<BlocksReport>,
    /// Distances between the decoded micro-mesh written and the reference, as fractions of
    /// the reference's bounding-box diagonal.
    pub reference_to_baked: DistanceSummary,
    pub baked_to_reference: DistanceSummary,
    pub symmetric: DistanceSummary,
    /// Where the bake fell short of what was asked (one line each, naming the files): a
    /// caller shows them as warnings.
    #[serde(skip)]
    pub shortfalls: Vec<String>,
}

/// How the values were compressed.
#[derive(Debug, Serialize)]
pub struct CompressionReport {
    /// Bits of a correction on the base edges at each level, coarse to fine (each grid has
    /// its own widths).
    pub widths: Vec<u32>,
    /// Bits per stored value, all blocks together.
    pub bits_per_value: f64,
    /// The bound asked for and the RMS error added over every value, as fractions of the
    /// base mesh's bounding-box diagonal.
    pub max_added_error: f32,
    pub added_error: f32,
    /// The byte budget per micro-triangle (everything the GPU gets), where one applies,
    /// whether it is the level's default, whether the bound gave way to it, and whether it
    /// was met (the rest of the bytes may take more than a budget allows: the values then
    /// take their fewest bits for a budget asked for, and keep their bound for a default).
    pub max_bytes: Option<f64>,
    pub budget_default: bool,
    pub budget_binds: bool,
    pub budget_met: bool,
    /// The symmetric distance before compression, as `symmetric` is given.
    pub uncompressed_symmetric: DistanceSummary,
    /// Whether the values stay plain, exact, because compressed they took more of the GPU's
    /// bytes (see [`fewer_bytes`]); the fields above then describe the compression tried.
    pub kept_plain: bool,
}

/// The values in NVIDIA's blocks.
#[derive(Debug, Serialize)]
pub struct BlocksReport {
    /// The blocks' bytes, all triangles together.
    pub value_bytes: u64,
    /// The symmetric distance before the values went through the blocks.
    pub before_symmetric: DistanceSummary,
}

/// The parts of everything the GPU gets to trace `mesh` as displaced grids at their defaults,
/// in bytes; `None` where it is too large for displaced grids.
fn grid_memory(mesh: &DisplacedMesh) -> Option<Vec<(&'static str, u64)>> {
    let grids = grid::displaced::build(mesh, &GridOptions::for_displaced()).ok()?;
    Some(
        grids
            .memory()
            .into_iter()
            .map(|(part, bytes)| (part, bytes as u64))
            .collect(),
    )
}

/// Bytes of all `parts` (see [`grid_memory`]).
fn total(parts: &[(&str, u64)]) -> u64 {
    parts.iter().map(|&(_, bytes)| bytes).sum()
}

/// The parts of what the GPU gets (see [`grid_memory`]) that hold the values.
const VALUE_PARTS: [&str; 3] = ["inner_values", "value_block_table", "edge_and_corner_values"];

/// What the GPU gets (see [`grid_memory`]) of `plain` or of `compressed`, the same
/// micro-mesh with its values compressed, and whether it is `plain`'s: `plain`'s where its
/// values take no more bytes (a tight bound on coarse levels can take more bits than plain
/// values do, each block spending its widths and shifts on few points, and plain values are
/// then both smaller and exact), else `compressed`'s, `None` where that cannot be laid out.
fn fewer_bytes(plain: &DisplacedMesh, compressed: &DisplacedMesh) -> Option<(Vec<(&'static str, u64)>, bool)> {
    match (grid_memory(plain), grid_memory(compressed)) {
        (Some(plain), Some(compressed)) if total(&plain) <= total(&compressed) => Some((plain, true)),
        (_, compressed) => compressed.map(|parts| (parts, false)),
    }
}

/// Rounds of choosing levels for `--within-bytes`.
const BUDGET_ROUNDS: usize = 6;

/// Levels per base triangle for a budget of `bytes` of everything the GPU gets
/// (`--within-bytes`). The levels' choice knows their plain values' bytes alone, so it aims
/// at a share of the budget: each round chooses the levels for a share, compresses their
/// values as the bake will (the bound from the same measure of their distance) and measures
/// the whole. With tries on one side of the budget only, the next share is scaled by the
/// room the budget leaves the values over what they took (the rest, base mesh, headers and
/// top level, changes little with the levels); with tries on both sides, it is where the
/// line through the nearest two meets the budget. The finest levels that fitted are kept,
/// or the last, coarsest, try, with their distance from the reference where it was
/// measured; the values are then compressed within the budget itself.
fn bake_within_bytes(
    reference: &Mesh,
    options: &BakeOptions,
    bytes: u64,
    request: &BakeRequest,
) -> Result<(Baked, Option<SurfaceDistance>)> {
    use super::levels::{LevelFitting, LevelTarget};
    let fitting = LevelFitting::new(reference, options)?;
    // Measured as the bake will measure the levels kept, so their compression lands where
    // it landed here.
    let sampling = Sampling {
        samples: request.samples,
        ..Sampling::default()
    };
    // The tries either side of the budget: (share, bytes landed, bake and its distance).
    let mut below: Option<(u64, u64, (Baked, Option<SurfaceDistance>))> = None;
    let mut above: Option<(u64, u64)> = None;
    let mut last = None;
    let mut share = bytes;
    for _ in 0..BUDGET_ROUNDS {
        let baked = fitting.bake(LevelTarget::MaxBytes(share))?;
        let distance =
            (compresses(request)).then(|| surface_distance::measure(reference, &baked.mesh.decoded(), &sampling));
        let laid_out = match distance.and_then(|d| compression_bound(request, &baked.mesh, &d)) {
            Some(compression) => {
                let compressed = compress(&baked.mesh, &compression)?.mesh;
                fewer_bytes(&baked.mesh, &compressed).map(|(parts, _)| parts)
            }
            None => grid_memory(&baked.mesh),
        };
        let Some(parts) = laid_out else {
            return Ok((baked, distance));
        };
        let landed = total(&parts);
        let values: u64 = (parts.iter().filter(|(part, _)| VALUE_PARTS.contains(part)))
            .map(|&(_, b)| b)
            .sum();
        // What the values may take: the budget less the rest, which the levels change little.
        let room = bytes.saturating_sub(landed - values);
        if landed <= bytes {
            // Close enough: within a fiftieth below the budget.
            let close = 50 * (bytes - landed) <= bytes;
            below = Some((share, landed, (baked, distance)));
            if close {
                break;
            }
        } else {
            above = Some((share, landed));
            last = Some((baked, distance));
        }
        let next = match (&below, above) {
            (Some((s0, b0, _)), Some((s1, b1))) => {
                let at = *s0 as f64 + (bytes - b0) as f64 * (s1 - s0) as f64 / (b1 - b0).max(1) as f64;
                let next = at as u64;
                if next > *s0 && next < s1 {
                    next
                } else {
                    (s0 + s1) / 2
                }
            }
            // One side only: the share scaled by the room for the values over what they took,
            // at most doubled.
            _ => (share as f64 * (room as f64 / values.max(1) as f64).min(2.0)) as u64,
        };
        if next == share || next == 0 {
            break;
        }
        share = next;
    }
    Ok(below.map(|(_, _, b)| b).or(last).expect("at least one round"))
}

/// The byte budget per micro-triangle, of `micro_triangles`: the one asked for, or with the
/// default error bound and one level the default for the level.
fn byte_budget(request: &BakeRequest, micro_triangles: u64) -> Option<f64> {
    if let Some(bytes) = request.within_bytes {
        return Some(bytes as f64 / micro_triangles.max(1) as f64);
    }
    match (request.max_bytes, request.compress_values) {
        (Some(bytes), _) => Some(bytes),
        (None, Some(_)) => None,
        // Levels chosen per triangle have spent the bytes the error needs.
        (None, None) if request.max_error.is_some() => None,
        (None, None) => super::default_byte_budget(request.levels),
    }
}

/// What a byte budget did to a compression (see [`compress_within`]): the budget, whether it
/// was the level's default, whether the bound gave way to it, whether it was met.
struct BudgetOutcome {
    max_bytes: Option<f64>,
    default: bool,
    binds: bool,
    met: bool,
}

/// A byte budget per micro-triangle, for so many micro-triangles; `asked` when the user set it
/// rather than the level's default.
#[derive(Clone, Copy)]
struct ByteBudget {
    per_micro: f64,
    micro_triangles: u64,
    asked: bool,
}

/// `mesh`'s values compressed within `options`' bound, or, where everything the GPU gets
/// would then take more than `budget`, within the bits that fit it; and what the budget did.
/// A budget out of reach (the values at their fewest bits do not fit it either) is kept as
/// closely as the fewest bits allow when asked for; a default one out of reach is not worth
/// the error, and the values keep their bound.
fn compress_within(
    mesh: &DisplacedMesh,
    options: ValueCompression,
    budget: Option<ByteBudget>,
) -> Result<(CompressedMesh, BudgetOutcome)> {
    let unbudgeted = || BudgetOutcome {
        max_bytes: None,
        default: false,
        binds: false,
        met: true,
    };
    let Some(ByteBudget {
        per_micro,
        micro_triangles,
        asked,
    }) = budget
    else {
        return Ok((compress(mesh, &options)?, unbudgeted()));
    };
    let allowed = (per_micro * micro_triangles as f64).floor() as u64;
    let Some(plain) = grid_memory(mesh) else {
        return Ok((compress(mesh, &options)?, unbudgeted()));
    };
    // What the values may take: the budget less the rest (base mesh, headers, radii, top
    // level), whose sizes the values do not change, less the block table with entries wide
    // enough to address every bit the values may take.
    let rest: u64 = (plain.iter().filter(|(part, _)| !VALUE_PARTS.contains(part)))
        .map(|&(_, bytes)| bytes)
        .sum();
    let table_bits = (64 - (8 * allowed).leading_zeros() as u64) * mesh.triangles.len() as u64 + 32;
    let mut max_bits = (8 * allowed.saturating_sub(rest)).saturating_sub(table_bits);
    let compressor = Compressor::new(mesh, options.max_added_error)?;
    // Within the bound the whole may fit already, whatever the estimate says.
    let bounded = compressor.within(None);
    if grid_memory(&bounded.mesh).is_some_and(|parts| total(&parts) <= allowed) {
        let outcome = BudgetOutcome {
            max_bytes: Some(per_micro),
            default: !asked,
            binds: false,
            met: true,
        };
        return Ok((bounded, outcome));
    }
    let mut compressed = compressor.within(Some(max_bits));
    // The table, the blocks' word padding and the top level come out a little off the
    // estimate: twice at most, the bits move by what the whole missed the budget by, while
    // the budget binds and the miss is more than a hundredth of it.
    // A try that fits is kept should a later one not.
    let missed = |c: &CompressedMesh| grid_memory(&c.mesh).map_or(0, |parts| allowed as i64 - total(&parts) as i64);
    let mut miss = missed(&compressed);
    let mut fitting = None;
    for _ in 0..2 {
        let binds = compressed.added_error > options.max_added_error;
        if (miss >= 0 && (!binds || miss <= allowed as i64 / 100)) || (miss < 0 && max_bits == 0) {
            break;
        }
        max_bits = (compressed.bits as i64 + 8 * miss - 64).max(0) as u64;
        let next = compressor.within(Some(max_bits));
        if miss >= 0 {
            fitting = Some(compressed);
        }
        compressed = next;
        miss = missed(&compressed);
    }
    if let (true, Some(fits)) = (miss < 0, fitting) {
        (compressed, miss) = (fits, 0);
    }
    if miss < 0 && !asked {
        compressed = bounded;
    }
    let outcome = BudgetOutcome {
        max_bytes: Some(per_micro),
        default: !asked,
        binds: compressed.added_error > options.max_added_error,
        met: miss >= 0,
    };
    Ok((compressed, outcome))
}

/// How to compress the baked values: `None` to leave them plain (as asked, or at level 0,
/// where a base triangle has its corners alone). The bound is the one asked for, or by
/// default a share of the uncompressed bake's own distance from the reference.
fn compression_bound(request: &BakeRequest, mesh: &DisplacedMesh, plain: &SurfaceDistance) -> Option<ValueCompression> {
    if !compresses(request) {
        return None;
    }
    Some(match request.compress_values {
        Some(bound) => ValueCompression::bounded(bound),
        None => ValueCompression::within(mesh, super::COMPRESSION_ERROR_SHARE * plain.symmetric.rms as f32),
    })
}

/// Whether the baked values are compressed (see [`compression_bound`]).
fn compresses(request: &BakeRequest) -> bool {
    !(request.plain_values || request.nv_blocks || request.levels == 0)
}

/// Whether the values will be compressed within the default share of the bake's own
/// distance, which `--max-error` then leaves room for.
fn compression_follows(request: &BakeRequest) -> bool {
    compresses(request) && request.compress_values.is_none()
}

/// The glTF and the samples, checked before any work: the glTF writable, and none of the
/// files the run reads (the meshes, and the buffers and micromaps a glTF among them names),
/// the samples within memory. Its buffer and micromap
/// take names of their own as they are written, never an input's. Returns those files.
fn check_outputs(request: &BakeRequest) -> Result<Vec<PathBuf>> {
    surface_distance::check_samples(request.samples, "--samples")?;
    files::check_output(&request.output, "gltf")?;
    let mut paths = vec![request.reference.as_path()];
    paths.extend(request.base.as_deref());
    let inputs = input::files_read(&paths);
    files::check_not_input(&request.output, &inputs)?;
    if (request.base)
        .as_deref()
        .is_some_and(|b| files::same_file(b, &request.reference) || b == request.reference)
    {
        fail!(
            Options,
            "--base {}: is the reference itself; give a coarser mesh",
            request.reference.display()
        );
    }
    Ok(inputs)
}
