//! `gridrt compare`: one library call (`gridrt::request::compare::compare_files`), then its
//! table or JSON printed.

use std::path::Path;

use super::progress::Stages;
use super::CompareArgs;
use anyhow::Result;
use gridrt::request::compare::{compare_files, Comparison};
use gridrt::surface_distance::DistanceSummary;

pub fn run(args: &CompareArgs, stages: &mut Stages) -> Result<()> {
    let report = compare_files(&args.reference, &args.other, args.samples, stages)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", table(&report, &args.reference, &args.other));
    }
    Ok(())
}

fn table(report: &Comparison, reference: &Path, other: &Path) -> String {
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
