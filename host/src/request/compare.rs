//! `gridrt compare`: how far apart two surfaces are (see [`crate::surface_distance`]), as
//! fractions of the reference's bounding-box diagonal, in one call: [`compare_files`].

use std::path::Path;

use serde::Serialize;

use crate::error::Result;
use crate::input;
use crate::progress::Progress;
use crate::surface_distance::{self, DistanceSummary, Sampling};

/// The distances between two surfaces, each way and both ways.
#[derive(Serialize, Debug, Clone)]
pub struct Comparison {
    pub reference: String,
    pub other: String,
    /// The reference's bounding-box diagonal, in its file's units; every distance below is a
    /// fraction of it.
    pub diagonal: f64,
    pub reference_to_other: DistanceSummary,
    pub other_to_reference: DistanceSummary,
    pub symmetric: DistanceSummary,
}

/// The surfaces at `reference` and `other` (in the same units) compared on `samples` points
/// sampled on each by area; files without area are refused before sampling.
pub fn compare_files(
    reference: &Path,
    other: &Path,
    samples: usize,
    progress: &mut dyn Progress,
) -> Result<Comparison> {
    surface_distance::check_samples(samples, "--samples")?;
    let (a, _, warnings) = input::load_world_warning(reference)?;
    let (b, _, more) = input::load_world_warning(other)?;
    for warning in warnings.iter().chain(&more) {
        progress.warning(warning);
    }
    // Both meshes in the reference's local frame (moved in `f64`, one rounding to `f32`):
    // a ratio of lengths there is the ratio in the files' units.
    let frame = a.local_frame();
    let sampling = Sampling {
        samples,
        ..Sampling::default()
    };
    let (a, b) = (a.in_frame(&frame), b.in_frame(&frame));
    surface_distance::check_area(&a, &reference.display().to_string())?;
    surface_distance::check_area(&b, &other.display().to_string())?;
    let d = crate::progress::run(progress, "measure", || surface_distance::measure(&a, &b, &sampling));
    Ok(Comparison {
        reference: reference.display().to_string(),
        other: other.display().to_string(),
        diagonal: d.a_diagonal / frame.scale,
        reference_to_other: d.a_to_b.relative_to(d.a_diagonal),
        other_to_reference: d.b_to_a.relative_to(d.a_diagonal),
        symmetric: d.symmetric.relative_to(d.a_diagonal),
    })
}
