//! `gridrt compare`: how far apart two surfaces are (see `gridrt::surface_distance`), as
//! fractions of the reference's bounding-box diagonal.

use std::path::Path;

use anyhow::Result;
use serde::Serialize;

use super::CompareArgs;
use gridrt::input;
use gridrt::surface_distance::{self, DistanceSummary, Sampling};

#[derive(Serialize)]
struct Report {
    reference: String,
    other: String,
    /// The reference's bounding-box diagonal, in its file's units; every distance below is a
    /// fraction of it.
    diagonal: f64,
    reference_to_other: DistanceSummary,
    other_to_reference: DistanceSummary,
    symmetric: DistanceSummary,
}

pub fn run(args: &CompareArgs) -> Result<()> {
    surface_distance::check_samples(args.samples, "--samples")?;
    let (reference, _, mut warnings) = input::load_world_warning(&args.reference)?;
    let (other, _, more) = input::load_world_warning(&args.other)?;
    warnings.extend(more);
    for warning in warnings {
        eprintln!("warning: {warning}");
    }
    // Both meshes in the reference's local frame (moved in `f64`, one rounding to `f32`):
    // a ratio of lengths there is the ratio in the files' units.
    let frame = reference.local_frame();
    let sampling = Sampling {
        samples: args.samples,
        ..Sampling::default()
    };
    let (reference, other) = (reference.in_frame(&frame), other.in_frame(&frame));
    surface_distance::check_area(&reference, &args.reference.display().to_string())?;
    surface_distance::check_area(&other, &args.other.display().to_string())?;
    let d = surface_distance::measure(&reference, &other, &sampling);
    let report = Report {
        reference: args.reference.display().to_string(),
        other: args.other.display().to_string(),
        diagonal: d.a_diagonal / frame.scale,
        reference_to_other: d.a_to_b.relative_to(d.a_diagonal),
        other_to_reference: d.b_to_a.relative_to(d.a_diagonal),
        symmetric: d.symmetric.relative_to(d.a_diagonal),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", table(&report, &args.reference, &args.other));
    }
    Ok(())
}

fn table(report: &Report, reference: &Path, other: &Path) -> String {
    let name = |p: &Path| {
        p.file_name()
            .map_or(p.display().to_string(), |f| f.to_string_lossy().into())
    };
    let (a, b) = (name(reference), name(other));
    let row = |what: &str, s: &DistanceSummary| {
        format!(
            "| {what} | {:.3e} | {:.3e} | {:.3e} | {} |\n",
            s.rms, s.p99, s.max, s.samples
        )
    };
    format!(
        "Surface distance, as fractions of {a}'s bounding-box diagonal ({:.6e} in its units):\n\n\
         | from | RMS | 99th percentile | max | samples |\n|---|---:|---:|---:|---:|\n{}{}{}",
        report.diagonal,
        row(&format!("{a} to {b}"), &report.reference_to_other),
        row(&format!("{b} to {a}"), &report.other_to_reference),
        row("both (symmetric)", &report.symmetric),
    )
}
