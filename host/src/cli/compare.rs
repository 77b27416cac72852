//! `gridrt compare`: how far apart two surfaces are (see `gridrt::surface_distance`), as
//! fractions of the reference's bounding-box diagonal.

use std::path::Path;

use anyhow::Result;
use serde::Serialize;

use super::CompareArgs;
use gridrt::mesh::{self, WorldMesh};
use gridrt::surface_distance::{self, DistanceSummary, Sampling, SurfaceDistance};

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
    let (reference, _) = mesh::load_world(&args.reference)?;
    let (other, _) = mesh::load_world(&args.other)?;
    let distance = measure_in_frame(&reference, &other, args.samples);
    let diagonal = distance.a_diagonal;
    let report = Report {
        reference: args.reference.display().to_string(),
        other: args.other.display().to_string(),
        diagonal,
        reference_to_other: distance.a_to_b.relative_to(diagonal),
        other_to_reference: distance.b_to_a.relative_to(diagonal),
        symmetric: distance.symmetric.relative_to(diagonal),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", table(&report, &args.reference, &args.other));
    }
    Ok(())
}

/// Both meshes in the reference's local frame (moved in `f64`, one rounding to `f32`), measured
/// there; lengths are given back in the files' units.
fn measure_in_frame(reference: &WorldMesh, other: &WorldMesh, samples: usize) -> SurfaceDistance {
    let (a, frame) = reference.clone().into_local();
    let b = other.in_frame(&frame);
    let d = surface_distance::measure(
        &a,
        &b,
        &Sampling {
            samples,
            ..Sampling::default()
        },
    );
    let world = |s: DistanceSummary| s.relative_to(frame.scale);
    SurfaceDistance {
        a_to_b: world(d.a_to_b),
        b_to_a: world(d.b_to_a),
        symmetric: world(d.symmetric),
        a_diagonal: d.a_diagonal / frame.scale,
    }
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
