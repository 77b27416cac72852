//! `gridrt export`: a mesh subdivided and written, in the input's own units, as binary PLY,
//! in one call: [`export_file`]. The output is checked before anything is read, and is never
//! one of the inputs.

use std::path::PathBuf;

use serde::Serialize;

use crate::error::{fail, Result};
use crate::mesh::ply::write_ply;
use crate::progress::{self, Progress};
use crate::subdiv::{self, Scheme};
use crate::{files, input, limits};

/// `export`'s subdivision depth when none is given.
pub const DEFAULT_EXPORT_LEVELS: u32 = 3;

/// What to export (see `gridrt export --help`).
#[derive(Clone, Debug, PartialEq)]
pub struct ExportRequest {
    /// The mesh to subdivide; the built-in scene when `None`. A displaced micro-mesh is
    /// written as its decoded micro-triangles.
    pub mesh: Option<PathBuf>,
    /// Subdivision depth; `None`: [`DEFAULT_EXPORT_LEVELS`], or none for a displaced
    /// micro-mesh.
    pub levels: Option<u32>,
    pub scheme: Scheme,
    /// Edges folding by more than this many degrees stay sharp.
    pub crease_angle: Option<f32>,
    /// The `.ply` to write.
    pub output: PathBuf,
}

/// What was written.
#[derive(Serialize, Debug, Clone)]
pub struct Exported {
    pub name: String,
    pub micro_triangles: usize,
    pub vertices: usize,
    pub levels: u32,
    pub output: PathBuf,
}

/// Subdivides the requested mesh and writes its micro-triangles as binary PLY.
pub fn export_file(request: &ExportRequest, progress: &mut dyn Progress) -> Result<Exported> {
    files::check_output(&request.output, "ply")?;
    let paths: Vec<&std::path::Path> = request.mesh.iter().map(PathBuf::as_path).collect();
    files::check_not_input(&request.output, &input::files_read(&paths))?;
    let input = super::open_reporting(&paths, progress)?;
    let (name, mesh, frame) = (&input.name, &input.mesh, &input.frame);
    let levels = match (input.displaced, request.levels) {
        (Some(d), Some(asked)) => fail!(
            Options,
            "{name}: is a displaced micro-mesh of {} base triangles at levels {} to {}: export writes its decoded \
             micro-triangles at those levels, so --levels {asked} does not apply; leave it out",
            d.base_triangles,
            d.min_level,
            d.max_level
        ),
        (Some(_), None) => 0,
        (None, asked) => asked.unwrap_or(DEFAULT_EXPORT_LEVELS),
    };
    limits::check_build(
        &format!("subdividing {name}"),
        mesh.triangles.len(),
        levels,
        limits::Builds::Grids,
        0,
        "use fewer --levels",
    )?;
    let sub = progress::run(progress, "subdivide", || {
        let creases = subdiv::Creases::chosen(mesh, request.crease_angle);
        subdiv::subdivide_creased(mesh, levels, request.scheme, &creases)
    });
    let triangles = sub.micro_triangles(levels);
    progress::run(progress, "write", || {
        let positions: Vec<_> = sub.positions.iter().map(|&p| frame.to_world(p).as_vec3()).collect();
        write_ply(&request.output, &positions, &triangles)
    })?;
    Ok(Exported {
        name: name.clone(),
        micro_triangles: triangles.len(),
        vertices: sub.positions.len(),
        levels,
        output: request.output.clone(),
    })
}
