//! `gridrt bake`: a detailed mesh baked into a displaced micro-mesh (see `gridrt::micromesh::bake`),
//! written as glTF + `.bary`, with its size and its distance from the reference.

use std::path::{Path, PathBuf};

use anyhow::{bail, Result};
use serde::Serialize;

use super::progress::Stages;
use super::BakeArgs;
use gridrt::files;
use gridrt::grid::compressed::{compress, CompressedMesh, Compressor, ValueCompression};
use gridrt::grid::{self, GridOptions};
use gridrt::input;
use gridrt::micromesh;
use gridrt::micromesh::bake::refine::Refinement;
use gridrt::micromesh::bake::{self, BakeOptions, BakeReport, Base};
use gridrt::micromesh::DisplacedMesh;
use gridrt::surface_distance::{self, DistanceSummary, Sampling, SurfaceDistance};

#[derive(Serialize)]
struct Report {
    reference: String,
    reference_triangles: usize,
    output: String,
    #[serde(flatten)]
    bake: BakeReport,
    /// Bytes of the three files written (glTF, its buffer, its micromap).
    file_bytes: u64,
    /// The micromap's bytes alone (values and their tables).
    micromap_bytes: u64,
    /// Everything the GPU gets to trace the result as displaced grids at their defaults:
    /// values, base mesh, headers, radii, leaf thicknesses, top-level BVH.
    /// `None` where the micro-mesh is too large for displaced grids (rendered as triangles).
    grid_bytes: Option<u64>,
    /// The budget for `grid_bytes` the levels were chosen for (`--within-bytes`).
    within_bytes: Option<u64>,
    /// Micro-triangles at each level `0 ..= 6`, where base triangles have their own levels
    /// (`--max-error`).
    level_micro_triangles: Option<Vec<u64>>,
    bake_seconds: f64,
    /// How the values were compressed; `None` where they were left plain.
    compression: Option<CompressionReport>,
    /// The values in NVIDIA's blocks (`--nv-blocks`).
    nv_blocks: Option<BlocksReport>,
    /// Distances between the decoded micro-mesh written and the reference, as fractions of
    /// the reference's bounding-box diagonal.
    reference_to_baked: DistanceSummary,
    baked_to_reference: DistanceSummary,
    symmetric: DistanceSummary,
}

#[derive(Serialize)]
struct CompressionReport {
    /// Bits of a correction on the base edges at each level, coarse to fine (each grid has
    /// its own widths).
    widths: Vec<u32>,
    /// Bits per stored value, all blocks together.
    bits_per_value: f64,
    /// The bound asked for and the RMS error added over every value, as fractions of the
    /// base mesh's bounding-box diagonal.
    max_added_error: f32,
    added_error: f32,
    /// The byte budget per micro-triangle (everything the GPU gets), where one applies,
    /// whether it is the level's default, whether the bound gave way to it, and whether it
    /// was met (the rest of the bytes may take more than a budget allows: the values then
    /// take their fewest bits for a budget asked for, and keep their bound for a default).
    max_bytes: Option<f64>,
    budget_default: bool,
    budget_binds: bool,
    budget_met: bool,
    /// The symmetric distance before compression, as `symmetric` is given.
    uncompressed_symmetric: DistanceSummary,
    /// Whether the values stay plain, exact, because compressed they took more of the GPU's
    /// bytes (see [`fewer_bytes`]); the fields above then describe the compression tried.
    kept_plain: bool,
}

#[derive(Serialize)]
struct BlocksReport {
    /// The blocks' bytes, all triangles together.
    value_bytes: u64,
    /// The symmetric distance before the values went through the blocks.
    before_symmetric: DistanceSummary,
}

pub fn run(args: &BakeArgs, stages: &mut Stages) -> Result<()> {
    let inputs = check_outputs(args)?;
    let (reference, cleaning, warnings) = stages.run("load", || input::load_world_warning(&args.reference))?;
    for warning in warnings {
        eprintln!("warning: {warning}");
    }
    if cleaning.welded + cleaning.dropped > 0 {
        stages.say(format!(
            "note: {}: welded {} vertices, dropped {} degenerate or repeated triangles",
            args.reference.display(),
            cleaning.welded,
            cleaning.dropped
        ));
    }
    let frame = reference.local_frame();
    let reference_mesh = reference.in_frame(&frame);
    let name = args.reference.display().to_string();
    surface_distance::check_area(&reference_mesh, &name)?;
    let base = match &args.base {
        Some(path) => {
            let (base, _, warnings) = stages.run("load base", || input::load_world_warning(path))?;
            for warning in warnings {
                eprintln!("warning: {warning}");
            }
            Base::Given(base.in_frame(&frame))
        }
        None => Base::Decimated {
            triangles: args
                .base_triangles
                .unwrap_or(bake::default_base_triangles(reference_mesh.triangles.len())),
        },
    };
    let defaults = BakeOptions::for_reference(&reference_mesh, args.levels);
    let options = BakeOptions {
        base,
        refinement: Refinement {
            rounds: args.fit_rounds,
            ..defaults.refinement
        },
        ..defaults
    };
    let started = std::time::Instant::now();
    // The distance of the bake from the reference, where choosing its levels measured it.
    let mut measured = None;
    let named = |e: gridrt::error::Error| e.prefixed(&name);
    let baked = match (args.max_error, args.within_bytes) {
        (None, Some(bytes)) => {
            let (baked, distance) = stages
                .run("bake", || bake_within_bytes(&reference_mesh, &options, bytes, args))
                .map_err(named)?;
            measured = distance;
            baked
        }
        (None, None) => stages
            .run("bake", || bake::bake(&reference_mesh, &options))
            .map_err(named)?,
        (Some(max_error), _) => {
            let (lo, hi) = reference_mesh.bounds();
            let share = if compression_follows(args) {
                bake::levels_error_share()
            } else {
                1.0
            };
            let target = bake::levels::LevelTarget::MaxError(share * max_error * (hi - lo).length());
            stages
                .run("bake", || bake::levels::bake_levels(&reference_mesh, &options, target))
                .map_err(named)?
        }
    };
    let bake_seconds = started.elapsed().as_secs_f64();
    let sampling = Sampling {
        samples: args.samples,
        ..Sampling::default()
    };
    let measure = |stages: &mut Stages, mesh: &DisplacedMesh| {
        let decoded = mesh.decoded();
        stages.run("measure", || {
            surface_distance::measure(&reference_mesh, &decoded, &sampling)
        })
    };
    let plain = match measured {
        Some(distance) => distance,
        None => measure(stages, &baked.mesh),
    };
    let mut nv_blocks = None;
    let (mesh, compression, d) = match compression_bound(args, &baked.mesh, &plain) {
        None if args.nv_blocks => {
            let (mesh, value_bytes) = stages.run("blocks", || baked.mesh.in_nv_blocks());
            let d = measure(stages, &mesh);
            nv_blocks = Some(BlocksReport {
                value_bytes,
                before_symmetric: plain.symmetric.relative_to(plain.a_diagonal),
            });
            (mesh, None, d)
        }
        None => (baked.mesh, None, plain),
        Some(options) => {
            let micro_triangles = baked.report.micro_triangles;
            let budget = byte_budget(args, micro_triangles).map(|per_micro| ByteBudget {
                per_micro,
                micro_triangles,
                asked: args.max_bytes.is_some() || args.within_bytes.is_some(),
            });
            let (compressed, mut budget) = stages.run("compress", || compress_within(&baked.mesh, options, budget))?;
            let kept_plain = match fewer_bytes(&baked.mesh, &compressed.mesh) {
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
                false => measure(stages, &compressed.mesh),
            };
            let report = CompressionReport {
                widths: grid::compressed::level_widths(&compressed.code),
                bits_per_value: compressed.bits_per_value(),
                max_added_error: options.max_added_error,
                added_error: compressed.added_error,
                max_bytes: budget.max_bytes,
                budget_default: budget.default,
                budget_binds: budget.binds,
                budget_met: budget.met,
                uncompressed_symmetric: plain.symmetric.relative_to(plain.a_diagonal),
                kept_plain,
            };
            let mesh = if kept_plain { baked.mesh } else { compressed.mesh };
            (mesh, Some(report), d)
        }
    };
    let outputs = stages.run("write", || {
        micromesh::gltf::write_keeping(&args.output, &mesh, &frame, &inputs)
    })?;
    let bytes = |p: &Path| std::fs::metadata(p).map_or(0, |m| m.len());
    let report = Report {
        reference: args.reference.display().to_string(),
        reference_triangles: reference_mesh.triangles.len(),
        output: args.output.display().to_string(),
        bake: baked.report,
        file_bytes: outputs.iter().map(|p| bytes(p)).sum(),
        micromap_bytes: bytes(&outputs[2]),
        grid_bytes: grid_memory(&mesh).map(|parts| total(&parts)),
        within_bytes: args.within_bytes,
        level_micro_triangles: (args.max_error.is_some() || args.within_bytes.is_some())
            .then(|| bake::levels::level_counts(&mesh)),
        bake_seconds,
        compression,
        nv_blocks,
        reference_to_baked: d.a_to_b.relative_to(d.a_diagonal),
        baked_to_reference: d.b_to_a.relative_to(d.a_diagonal),
        symmetric: d.symmetric.relative_to(d.a_diagonal),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", summary(&report));
    }
    let outcome = bake::Outcome {
        report: &report.bake,
        base: &options.base,
        reference_to_baked: &report.reference_to_baked,
        symmetric: &report.symmetric,
        max_error: args.max_error,
    };
    for line in bake::shortfalls(&outcome) {
        eprintln!("warning: {name} -> {}: {line}", args.output.display());
    }
    stages.report();
    Ok(())
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
    reference: &gridrt::mesh::Mesh,
    options: &BakeOptions,
    bytes: u64,
    args: &BakeArgs,
) -> gridrt::error::Result<(bake::Baked, Option<SurfaceDistance>)> {
    use bake::levels::{LevelFitting, LevelTarget};
    let fitting = LevelFitting::new(reference, options)?;
    // Measured as the bake will measure the levels kept, so their compression lands where
    // it landed here.
    let sampling = Sampling {
        samples: args.samples,
        ..Sampling::default()
    };
    // The tries either side of the budget: (share, bytes landed, bake and its distance).
    let mut below: Option<(u64, u64, (bake::Baked, Option<SurfaceDistance>))> = None;
    let mut above: Option<(u64, u64)> = None;
    let mut last = None;
    let mut share = bytes;
    for _ in 0..BUDGET_ROUNDS {
        let baked = fitting.bake(LevelTarget::MaxBytes(share))?;
        let distance =
            (compresses(args)).then(|| surface_distance::measure(reference, &baked.mesh.decoded(), &sampling));
        let laid_out = match distance.and_then(|d| compression_bound(args, &baked.mesh, &d)) {
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
fn byte_budget(args: &BakeArgs, micro_triangles: u64) -> Option<f64> {
    if let Some(bytes) = args.within_bytes {
        return Some(bytes as f64 / micro_triangles.max(1) as f64);
    }
    match (args.max_bytes, args.compress_values) {
        (Some(bytes), _) => Some(bytes),
        (None, Some(_)) => None,
        // Levels chosen per triangle have spent the bytes the error needs.
        (None, None) if args.max_error.is_some() => None,
        (None, None) => bake::default_byte_budget(args.levels),
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
fn compression_bound(args: &BakeArgs, mesh: &DisplacedMesh, plain: &SurfaceDistance) -> Option<ValueCompression> {
    if !compresses(args) {
        return None;
    }
    Some(match args.compress_values {
        Some(bound) => ValueCompression::bounded(bound),
        None => ValueCompression::within(mesh, bake::COMPRESSION_ERROR_SHARE * plain.symmetric.rms as f32),
    })
}

/// Whether the baked values are compressed (see [`compression_bound`]).
fn compresses(args: &BakeArgs) -> bool {
    !(args.plain_values || args.nv_blocks || args.levels == 0)
}

/// Whether the values will be compressed within the default share of the bake's own
/// distance, which `--max-error` then leaves room for.
fn compression_follows(args: &BakeArgs) -> bool {
    compresses(args) && args.compress_values.is_none()
}

/// The glTF and the samples, checked before any work: the glTF writable, and none of the
/// files the run reads (the meshes, and the buffers and micromaps a glTF among them names),
/// the samples within memory. Its buffer and micromap
/// take names of their own as they are written, never an input's. Returns those files.
fn check_outputs(args: &BakeArgs) -> Result<Vec<PathBuf>> {
    surface_distance::check_samples(args.samples, "--samples")?;
    files::check_output(&args.output, "gltf")?;
    let mut paths = vec![args.reference.as_path()];
    paths.extend(args.base.as_deref());
    let inputs = input::files_read(&paths);
    files::check_not_input(&args.output, &inputs)?;
    if args
        .base
        .as_deref()
        .is_some_and(|b| files::same_file(b, &args.reference) || b == args.reference)
    {
        bail!(
            "--base {}: is the reference itself; give a coarser mesh",
            args.reference.display()
        );
    }
    Ok(inputs)
}

fn summary(r: &Report) -> String {
    let b = &r.bake;
    let per_micro = |bytes: u64| bytes as f64 / b.micro_triangles.max(1) as f64;
    let share = |count: u64| 100.0 * count as f64 / b.values.max(1) as f64;
    let row = |what: &str, s: &DistanceSummary| format!("| {what} | {:.3e} | {:.3e} | {:.3e} |\n", s.rms, s.p99, s.max);
    format!(
        "{} ({} triangles) -> {}\n\
         base: {} triangles, {} vertices; {}: {} micro-triangles ({:.1} per reference triangle)\n\
         files: {} bytes, {:.2} B per micro-triangle (micromap {:.2} B)\n\
         displaced grids, all the GPU gets: {}\n\
         bake: {:.2} s; {} of {} values ({:.3}%) met no surface within reach, {} ({:.3}%) were clamped\n\
         {}\n\
         Distance to the reference, as fractions of its bounding-box diagonal:\n\n\
         | from | RMS | 99th percentile | max |\n|---|---:|---:|---:|\n{}{}{}{}",
        r.reference,
        r.reference_triangles,
        r.output,
        b.base_triangles,
        b.base_vertices,
        match &r.level_micro_triangles {
            Some(counts) => format!(
                "levels up to {} (micro-triangles by level: {})",
                b.levels,
                (counts.iter().enumerate())
                    .filter(|(_, &c)| c > 0)
                    .map(|(l, c)| format!("{l}: {c}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            None => format!("level {}", b.levels),
        },
        b.micro_triangles,
        b.micro_triangles as f64 / r.reference_triangles.max(1) as f64,
        r.file_bytes,
        per_micro(r.file_bytes),
        per_micro(r.micromap_bytes),
        match (r.grid_bytes, r.within_bytes) {
            (Some(bytes), Some(budget)) if bytes > budget => format!(
                "{bytes} bytes, {:.2} B per micro-triangle, over the budget of {budget} B (--within-bytes): even the \
                 coarsest levels take more",
                per_micro(bytes)
            ),
            (Some(bytes), _) => format!("{bytes} bytes, {:.2} B per micro-triangle", per_micro(bytes)),
            (None, _) => "too large to trace as displaced grids (rendered as triangles)".into(),
        },
        r.bake_seconds,
        b.misses,
        b.values,
        share(b.misses),
        b.clamped,
        share(b.clamped),
        match &r.compression {
            Some(c) if c.kept_plain => format!(
                "values: plain, 11 bits each: compressed within the bound (to {:.2} bits each) they took more bytes of \
                 what the GPU gets\n",
                c.bits_per_value
            ),
            Some(c) => format!(
                "values: compressed to {:.2} bits each (base edges at widths {:?} bits per level, each grid at \
                 its own), adding {:.3e} of the base's diagonal (RMS, bound {:.3e}{})\n",
                c.bits_per_value,
                c.widths,
                c.added_error,
                c.max_added_error,
                match (c.max_bytes, c.budget_default, c.budget_met, c.budget_binds) {
                    _ if r.within_bytes.is_some() => match (c.budget_met, c.budget_binds) {
                        (false, _) => "; the budget (--within-bytes) is out of reach, and the values take their \
                                       fewest bits"
                            .to_string(),
                        (true, true) => ", exceeded to fit the budget (--within-bytes)".to_string(),
                        (true, false) => "; within the budget (--within-bytes)".to_string(),
                    },
                    (Some(b), false, false, _) => format!(
                        "; the budget of {b} B per micro-triangle (--max-bytes) is out of reach: the rest of the \
                         bytes take too many, and the values their fewest bits"
                    ),
                    (Some(b), true, false, _) => format!(
                        "; the default budget of {b} B per micro-triangle is out of reach (the rest of the bytes \
                         take too many), so the values keep their bound"
                    ),
                    (Some(b), _, true, true) =>
                        format!(", exceeded to fit the budget of {b} B per micro-triangle (--max-bytes)"),
                    (Some(b), _, true, false) => format!("; budget {b} B per micro-triangle"),
                    (None, ..) => String::new(),
                }
            ),
            None if r.nv_blocks.is_some() => format!(
                "values: in NVIDIA's compressed blocks (eDispC1), {} bytes, {:.3} B per micro-triangle (traced plain, \
                 11 bits each)\n",
                r.nv_blocks.as_ref().map_or(0, |b| b.value_bytes),
                per_micro(r.nv_blocks.as_ref().map_or(0, |b| b.value_bytes))
            ),
            None if r.level_micro_triangles.is_some() => {
                "values: plain, 11 bits each (--compress-values bounds a compression)\n".into()
            }
            None => "values: plain, 11 bits each\n".into(),
        },
        row("reference to baked", &r.reference_to_baked),
        row("baked to reference", &r.baked_to_reference),
        row("both (symmetric)", &r.symmetric),
        match (&r.compression, &r.nv_blocks) {
            (Some(c), _) if !c.kept_plain => row("both, before compression", &c.uncompressed_symmetric),
            (Some(_), _) => String::new(),
            (None, Some(b)) => row("both, before the blocks", &b.before_symmetric),
            (None, None) => String::new(),
        },
    )
}
