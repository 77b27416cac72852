//! What to build from a mesh, as `render`, `stats` and `bench` are asked: the subdivision,
//! the grids' storage, and what becomes of a displaced micro-mesh's values. One request
//! serves a subdivided mesh and a displaced micro-mesh alike: [`BuildRequest::as_displaced`]
//! and [`BuildRequest::as_decoded`] give the build each part of it takes.

use crate::error::Result;
use crate::grid::{self, RadiusFormat, TopFormat};
use crate::input::Input;
use crate::limits;
use crate::mesh::Mesh;
use crate::subdiv::{self, Scheme, Subdivided};

/// The build options of `gridrt render`, `stats` and `bench` (see their `--help`).
#[derive(Clone, Debug, PartialEq)]
pub struct BuildRequest {
    /// Subdivision depth `L`: every base triangle becomes a grid of `4^L` micro-triangles.
    pub levels: u32,
    pub scheme: Scheme,
    /// Edges folding by more than this many degrees stay sharp; `None`: only boundaries.
    pub crease_angle: Option<f32>,
    /// Levels at the bottom of each grid's sphere hierarchy without spheres.
    pub excluded_levels: u32,
    /// How sphere radii are stored; `None`: 32-bit floats for subdivided meshes, relative
    /// bytes for displaced micro-meshes.
    pub radii: Option<RadiusFormat>,
    /// How the top-level BVH is stored; `None`: full nodes for subdivided meshes, wide ones
    /// for displaced micro-meshes.
    pub top: Option<TopFormat>,
    /// Each grid's ids in as few bits as the counts need (always for displaced micro-meshes).
    pub tight_headers: bool,
    /// Leaf thicknesses stored, to cull leaves by more than their spheres.
    pub leaf_footprint: bool,
    /// Inner vertices as 16-bit codes rather than 32-bit floats.
    pub quantized: bool,
    /// Compress a displaced micro-mesh's values adding at most this RMS error (a fraction of
    /// the diagonal).
    pub compress_values: Option<f32>,
    /// Store a displaced micro-mesh's values plain, whatever its file says.
    pub plain_values: bool,
}

impl Default for BuildRequest {
    /// The defaults of the command line: Loop subdivision to level 3, quantized inner
    /// vertices, leaf footprints.
    fn default() -> Self {
        BuildRequest {
            levels: 3,
            scheme: Scheme::Loop,
            crease_angle: None,
            excluded_levels: grid::DEFAULT_EXCLUDED_LEVELS,
            radii: None,
            top: None,
            tight_headers: false,
            leaf_footprint: true,
            quantized: true,
            compress_values: None,
            plain_values: false,
        }
    }
}

impl BuildRequest {
    /// Refuses, before subdividing, a mesh whose grids could not be addressed at these levels;
    /// returns the sizes their buffers will have (see `grid::check_limits`).
    pub fn check_grid_limits(&self, name: &str, mesh: &Mesh) -> Result<Vec<limits::BufferSize>> {
        grid::check_limits(mesh, &self.grid_build()).map_err(|e| e.prefixed(name))
    }

    /// This build for a displaced micro-mesh's decoded micro-triangles: no further
    /// subdivision.
    pub fn as_decoded(&self) -> BuildRequest {
        BuildRequest {
            levels: 0,
            scheme: Scheme::Flat,
            ..self.clone()
        }
    }

    /// This build for a displaced micro-mesh of `level` built as displaced grids: its own
    /// level, no subdivision, radii relative to each grid's root and a wide top level unless
    /// asked otherwise, tight headers.
    pub fn as_displaced(&self, level: u32) -> BuildRequest {
        BuildRequest {
            levels: level,
            scheme: Scheme::Flat,
            radii: Some(self.radii.unwrap_or(RadiusFormat::Relative)),
            top: Some(self.top.unwrap_or(TopFormat::Wide)),
            tight_headers: true,
            ..self.clone()
        }
    }

    /// The grid build this request asks for.
    pub fn grid_build(&self) -> grid::GridBuild {
        grid::GridBuild {
            levels: self.levels,
            scheme: self.scheme,
            crease_angle: self.crease_angle,
            options: self.grid_options(),
            quantized: self.quantized,
        }
    }

    /// The grids' storage this request asks for.
    pub fn grid_options(&self) -> grid::GridOptions {
        grid::GridOptions {
            excluded_levels: self.excluded_levels,
            radii: self.radii.unwrap_or(RadiusFormat::F32),
            leaf_footprint: self.leaf_footprint,
            top: self.top.unwrap_or(TopFormat::Full),
            tight_headers: self.tight_headers,
            own_rooms: true,
        }
    }

    /// `mesh` subdivided as asked, inner vertices quantized when asked.
    pub fn subdivide(&self, mesh: &Mesh) -> Subdivided {
        let creases = self.grid_build().creases(mesh);
        let mut sub = subdiv::subdivide_creased(mesh, self.levels, self.scheme, &creases);
        if self.quantized {
            sub.quantize_inner();
        }
        sub
    }

    /// Compresses the values of `input`'s displaced micro-mesh when asked, so everything
    /// after (grids, the baseline's triangles) traces the compressed surface, or drops their
    /// code when they are asked plain. Returns a note on the compression made, if any.
    pub fn compress_values(&self, input: &mut Input) -> Result<Option<String>> {
        if let (true, Some(micromesh)) = (self.plain_values, &mut input.micromesh) {
            micromesh.micromap.value_code = None;
        }
        let (Some(bound), Some(micromesh)) = (self.compress_values, &input.micromesh) else {
            return Ok(None);
        };
        let options = grid::compressed::ValueCompression::bounded(bound);
        let compressed = grid::compressed::compress(micromesh, &options).map_err(|e| e.prefixed(&input.name))?;
        let note = format!(
            "{}: values compressed to {:.2} bits each (base edges at widths {:?} bits per level, each grid \
             at its own), adding {:.3e} of the diagonal (RMS)",
            input.name,
            compressed.bits_per_value(),
            grid::compressed::level_widths(&compressed.code),
            compressed.added_error
        );
        input.mesh = compressed.mesh.decoded_welded();
        input.micromesh = Some(compressed.mesh);
        Ok(Some(note))
    }

    /// The build an input's limits are checked under: a displaced micro-mesh's decoded
    /// triangles are not subdivided further (and its grids are smaller than their baseline).
    pub fn for_input(&self, input: &Input) -> BuildRequest {
        match input.displaced {
            Some(_) => self.as_decoded(),
            None => self.clone(),
        }
    }
}
