//! `gridrt bake`: a detailed mesh baked into a displaced micro-mesh (one library call,
//! `gridrt::micromesh::bake::request::bake_file`), then its summary printed.

use anyhow::Result;

use super::progress::Stages;
use super::BakeArgs;
use gridrt::micromesh::bake::request::{bake_file, BakeRequest, BakeSummary, CompressionReport};
use gridrt::surface_distance::DistanceSummary;

pub fn run(args: &BakeArgs, stages: &mut Stages) -> Result<()> {
    let summary = bake_file(&args.request(), stages)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print!("{}", self::summary(&summary));
    }
    for line in &summary.shortfalls {
        eprintln!("warning: {line}");
    }
    stages.report();
    Ok(())
}

impl BakeArgs {
    /// The library's request for these arguments.
    fn request(&self) -> BakeRequest {
        BakeRequest {
            reference: self.reference.clone(),
            base: self.base.clone(),
            base_triangles: self.base_triangles,
            levels: self.levels,
            fit_rounds: self.fit_rounds,
            output: self.output.clone(),
            compress_values: self.compress_values,
            plain_values: self.plain_values,
            max_bytes: self.max_bytes,
            max_error: self.max_error,
            within_bytes: self.within_bytes,
            nv_blocks: self.nv_blocks,
            samples: self.samples,
        }
    }
}

fn summary(r: &BakeSummary) -> String {
    let b = &r.bake;
    let per_micro = |bytes: u64| per_micro(r, bytes);
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
        levels_line(r),
        b.micro_triangles,
        b.micro_triangles as f64 / r.reference_triangles.max(1) as f64,
        r.file_bytes,
        per_micro(r.file_bytes),
        per_micro(r.micromap_bytes),
        grid_line(r),
        r.bake_seconds,
        b.misses,
        b.values,
        share(b.misses),
        b.clamped,
        share(b.clamped),
        values_line(r),
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

/// Bytes per micro-triangle of the bake.
fn per_micro(r: &BakeSummary, bytes: u64) -> f64 {
    bytes as f64 / r.bake.micro_triangles.max(1) as f64
}

/// The level, or the levels per base triangle with their micro-triangles.
fn levels_line(r: &BakeSummary) -> String {
    let b = &r.bake;
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
    }
}

/// What the displaced grids take, or why there are none.
fn grid_line(r: &BakeSummary) -> String {
    let per_micro = |bytes: u64| per_micro(r, bytes);
    match (r.grid_bytes, r.within_bytes) {
        (Some(bytes), Some(budget)) if bytes > budget => format!(
            "{bytes} bytes, {:.2} B per micro-triangle, over the budget of {budget} B (--within-bytes): even the \
             coarsest levels take more",
            per_micro(bytes)
        ),
        (Some(bytes), _) => format!("{bytes} bytes, {:.2} B per micro-triangle", per_micro(bytes)),
        (None, _) => "too large to trace as displaced grids (rendered as triangles)".into(),
    }
}

/// How the values are stored: plain, compressed (within which budget), or NVIDIA's blocks.
fn values_line(r: &BakeSummary) -> String {
    let per_micro = |bytes: u64| per_micro(r, bytes);
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
            budget_clause(r, c)
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
    }
}

/// What became of a byte budget, after the compression's figures.
fn budget_clause(r: &BakeSummary, c: &CompressionReport) -> String {
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
        (Some(b), _, true, true) => format!(", exceeded to fit the budget of {b} B per micro-triangle (--max-bytes)"),
        (Some(b), _, true, false) => format!("; budget {b} B per micro-triangle"),
        (None, ..) => String::new(),
    }
}
