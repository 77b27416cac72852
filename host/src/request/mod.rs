//! Every `gridrt` command as one library call: a request (a plain struct holding the
//! command's options, see `gridrt COMMAND --help`), the call, and what it found. The command
//! line parses its arguments into a request, makes the call and prints the answer; every
//! decision (which backend, which build for which input, what is checked before long work)
//! is made here.
//!
//! | command | request | call |
//! |---|---|---|
//! | `render` | [`render::RenderRequest`] | [`render::render_files`] |
//! | `stats` | [`build::BuildRequest`] | [`stats::stats_file`] |
//! | `bench` | [`bench::BenchRequest`] | [`bench::bench_files`] |
//! | `compare` | paths and samples | [`compare::compare_files`] |
//! | `export` | [`export::ExportRequest`] | [`export::export_file`] |
//! | `bake` | [`bake::BakeRequest`] | [`bake::bake_file`] |
//!
//! Each reports its stages, notes and warnings through [`Progress`]; none prints.

use std::path::Path;

use crate::backend::{Backend, BackendChoice};
use crate::error::Result;
use crate::grid;
use crate::input::{self, Input};
use crate::mesh;
use crate::progress::Progress;

pub mod bench;
pub mod build;
pub mod compare;
pub mod export;
pub mod render;
pub mod stats;

/// `gridrt bake`'s request and call, at home with the rest of baking.
pub use crate::micromesh::bake::request as bake;

/// The files named (or the built-in scene when none), opened as one input (see
/// [`input::open_all`]) in the stage `load`, with what loading found reported: its
/// warnings, and notes on a displaced micro-mesh, welded vertices, dropped and zero-area
/// triangles.
pub fn open_reporting(paths: &[&Path], progress: &mut dyn Progress) -> Result<Input> {
    let input = crate::progress::run(progress, "load", || input::open_all(paths))?;
    for warning in &input.warnings {
        progress.warning(warning);
    }
    if let Some(line) = displaced_line(&input) {
        progress.note(&line);
    } else if input.cleaning.welded > 0 {
        progress.note(&format!(
            "{}: welded {} vertices to others at the same position (split at seams, or unindexed)",
            input.name, input.cleaning.welded
        ));
    }
    if let Some(seams) = (input.micromesh.as_ref().map(|m| m.open_seams())).filter(|&n| n > 0) {
        progress.warning(&format!(
            "{}: {seams} base edges are rendered at different levels by the triangles on either side \
             (levels more than one apart, or primitiveFlags that do not decimate the finer side): \
             the surface has cracks along them",
            input.name
        ));
    }
    report_cleaning(&input, progress);
    Ok(input)
}

/// [`open_reporting`], then the values of a displaced micro-mesh compressed (or made plain)
/// as `build` asks, within the same stage.
pub fn open_for_build(paths: &[&Path], build: &build::BuildRequest, progress: &mut dyn Progress) -> Result<Input> {
    let mut input = open_reporting(paths, progress)?;
    if let Some(note) = crate::progress::run(progress, "load", || build.compress_values(&mut input))? {
        progress.note(&note);
    }
    Ok(input)
}

/// What a displaced micro-mesh holds, in one line.
fn displaced_line(input: &Input) -> Option<String> {
    let d = input.displaced?;
    let levels = match d.min_level == d.max_level {
        true => format!("level {}", d.max_level),
        false => format!("levels {} to {}", d.min_level, d.max_level),
    };
    let map = input.micromesh.as_ref().map(|m| &m.micromap);
    let values = match (map.and_then(|m| m.value_code), map.is_some_and(|m| m.nv_blocks)) {
        (Some(c), _) => format!(
            "; its values are compressed (base edges at widths {:?} bits per level, each grid at its own)",
            grid::compressed::level_widths(&c)
        ),
        (None, true) => {
            "; its values, read from NVIDIA's compressed blocks, are traced plain (--compress-values compresses them)"
                .into()
        }
        (None, false) => String::new(),
    };
    Some(format!(
        "{}: a displaced micro-mesh of {} base triangles at {levels}, {} micro-triangles{values}",
        input.name,
        d.base_triangles,
        input.mesh.triangles.len()
    ))
}

/// Dropped degenerate triangles and triangles without area.
fn report_cleaning(input: &Input, progress: &mut dyn Progress) {
    let (cleaning, triangles) = (&input.cleaning, input.mesh.triangles.len());
    if cleaning.dropped > 0 {
        progress.warning(&format!(
            "{}: dropped {} degenerate triangles ({})",
            input.name,
            cleaning.dropped,
            mesh::DEGENERATE
        ));
    }
    if cleaning.zero_area == triangles {
        progress.warning(&format!(
            "{}: every triangle has zero area (its corners lie on one line): nothing of it can be seen",
            input.name
        ));
    } else if cleaning.zero_area > 0 {
        progress.note(&format!(
            "{}: {} of {} triangles have zero area (corners on one line)",
            input.name, cleaning.zero_area, triangles
        ));
    }
}

/// The backend `choice` names; for `Auto` on a machine without a GPU, a note saying the CPU
/// does the `work`.
pub fn open_backend(choice: BackendChoice, work: &str, progress: &mut dyn Progress) -> Result<Backend> {
    let backend = Backend::open(choice)?;
    note_fallback(&backend, work, progress);
    Ok(backend)
}

/// Where `Auto` found no GPU, a note saying the CPU does the `work`.
fn note_fallback(backend: &Backend, work: &str, progress: &mut dyn Progress) {
    if let Some(reason) = backend.fallback() {
        progress.note(&format!("{reason}; {work} on the CPU"));
    }
}

/// An error of `kind` names the input it came from (a refusal of the scene's size found as
/// it is uploaded, `Limits`; one about its contents, `Input`); others say what failed as they
/// are.
pub fn naming_input(
    name: &str,
    kind: crate::error::ErrorKind,
) -> impl Fn(crate::error::Error) -> crate::error::Error + '_ {
    move |e| if e.kind() == kind { e.prefixed(name) } else { e }
}
