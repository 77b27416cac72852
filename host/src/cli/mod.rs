//! The `gridrt` command line: argument definitions and the commands behind them.

use std::path::{Path, PathBuf};

use anyhow::{bail, Result};
use clap::{Parser, Subcommand, ValueEnum};

use gridrt::backend::{Backend, BackendChoice, Uploaded};
use gridrt::camera::{FileViewpoint, Viewpoint};
use gridrt::heat_map::CostSummary;
use gridrt::input::{self, Input};
use gridrt::lod::LodReport;
use gridrt::mesh::frame::LocalFrame;
use gridrt::mesh::{self, Mesh};
use gridrt::pipeline::{BuildOptions, RenderOptions, Representation, Shading};
use gridrt::rays::RayOrder;
use gridrt::scene::Scene;
use gridrt::subdiv::{self, Scheme, Subdivided};
use gridrt::{camera, files, grid, limits, triangles};
use gridrt_shared::glam::DVec3;
use progress::{note, Stages};

mod bake;
mod bench;
mod chart;
mod compare;
mod progress;
mod stats;

#[derive(Parser, Debug)]
#[command(
    name = "gridrt",
    version,
    about = "Ray tracing of triangular grid primitives (micro-meshes) on the GPU and the CPU"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
    /// Print nothing but warnings and errors: no progress, sizes or timings.
    #[arg(long, short, global = true)]
    pub quiet: bool,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    // Negative numbers are values: `--levels -1` is refused as out of range, not taken for
    // a flag.
    /// Render a mesh (or the built-in scene) to a PNG.
    #[command(allow_negative_numbers = true)]
    Render(RenderArgs),
    /// Print the memory and build time of both representations of a mesh.
    #[command(allow_negative_numbers = true)]
    Stats(StatsArgs),
    /// Measure memory, build time and ray throughput of grids against the baseline.
    #[command(allow_negative_numbers = true)]
    Bench(BenchArgs),
    /// Write a mesh subdivided L times as binary PLY, in the input's own units.
    #[command(allow_negative_numbers = true)]
    Export(ExportArgs),
    /// Measure how far apart two surfaces are: RMS, 99th percentile and maximum of the
    /// distances from points sampled on each to the other.
    #[command(allow_negative_numbers = true)]
    Compare(CompareArgs),
    /// Bake a detailed mesh into a displaced micro-mesh (glTF + .bary): a decimated base
    /// mesh with one 11-bit displacement per micro-vertex.
    #[command(allow_negative_numbers = true)]
    Bake(BakeArgs),
}

/// Where rays are traced.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum BackendArg {
    /// The GPU if wgpu finds an adapter, otherwise the CPU.
    Auto,
    Gpu,
    Cpu,
}

/// The backend `arg` names; for `auto` on a machine without a GPU, a note saying the CPU does
/// the `work`.
pub fn open_backend(arg: BackendArg, work: &str) -> Result<Backend> {
    let backend = Backend::open(arg.choice())?;
    if let Some(reason) = backend.fallback() {
        note!("note: {reason}; {work} on the CPU");
    }
    Ok(backend)
}

impl BackendArg {
    fn choice(self) -> BackendChoice {
        match self {
            BackendArg::Auto => BackendChoice::Auto,
            BackendArg::Gpu => BackendChoice::Gpu,
            BackendArg::Cpu => BackendChoice::Cpu,
        }
    }
}

/// The order a benchmark traces its rays in (see `gridrt::rays::RayOrder`).
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum RayOrderArg {
    /// Primary rays row by row, AO rays hit by hit.
    Scanline,
    /// Primary rays in 8x8 pixel tiles, AO rays by direction octant and origin.
    Coherent,
}

impl RayOrderArg {
    pub fn order(self) -> RayOrder {
        match self {
            RayOrderArg::Scanline => RayOrder::Scanline,
            RayOrderArg::Coherent => RayOrder::Coherent,
        }
    }
}

#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Grid primitives: sphere hierarchy per base triangle, BVH over grids.
    Grid,
    /// The baseline: every micro-triangle in an indexed list under an SAH BVH.
    Triangles,
}

impl Mode {
    fn representation(self) -> Representation {
        match self {
            Mode::Grid => Representation::Grids,
            Mode::Triangles => Representation::Triangles,
        }
    }
}

#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SubdivisionArg {
    Loop,
    Flat,
}

#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShadingArg {
    /// Headlight on a plain material.
    Eye,
    /// Geometric normal as colour.
    Normal,
    /// One colour per micro-triangle.
    Primitive,
    /// Ambient occlusion alone on a plain material (--ao-samples rays per pixel, looking
    /// --ao-distance far).
    Ao,
    /// A key light and a sky on clay, both dimmed by ambient occlusion (the same rays as
    /// --shading ao).
    Lit,
    /// Distance from the eye, white near to black far.
    Depth,
    /// Cost heat map: BVH nodes, spheres and micro-triangles tested per pixel (scale printed).
    Cost,
    /// Each grid coloured by the depth it renders at, blue (0) to red (6): see --lod auto.
    Level,
}

impl ShadingArg {
    fn shading(self) -> Shading {
        match self {
            ShadingArg::Eye => Shading::EyeLight,
            ShadingArg::Normal => Shading::Normal,
            ShadingArg::Primitive => Shading::Primitive,
            ShadingArg::Ao => Shading::AmbientOcclusion,
            ShadingArg::Lit => Shading::Lit,
            ShadingArg::Depth => Shading::Depth,
            ShadingArg::Cost => Shading::Cost,
            ShadingArg::Level => Shading::Level,
        }
    }
}

/// What to build: shared by `render` and `stats`.
#[derive(clap::Args, Debug, Clone)]
pub struct BuildArgs {
    /// Subdivision depth L: every base triangle becomes a grid of 4^L micro-triangles.
    #[arg(long, short = 'L', default_value_t = 3, value_parser = clap::value_parser!(u32).range(0..=6))]
    pub levels: u32,
    #[arg(long, value_enum, default_value_t = SubdivisionArg::Loop)]
    pub subdivision: SubdivisionArg,
    /// Keep edges sharp where the surface folds by more than this many degrees (0 to 180;
    /// boundaries always stay sharp). Without it, Loop subdivision rounds every edge.
    #[arg(long, value_name = "DEGREES", value_parser = parse_crease_angle)]
    pub crease_angle: Option<f32>,
    /// Levels at the bottom of each grid's sphere hierarchy that get no spheres.
    #[arg(long, default_value_t = grid::DEFAULT_EXCLUDED_LEVELS, value_parser = clap::value_parser!(u32).range(1..=3))]
    pub excluded_levels: u32,
    /// How sphere radii are stored, each rounded up so spheres only grow: 32-bit floats
    /// (the default for subdivided meshes), half floats, or a byte in 255ths of the grid's
    /// root radius (the default for displaced micro-meshes; leaves two or more sphere levels
    /// down then take half a byte, in 16ths of their parent's radius, beside their thickness).
    #[arg(long, value_enum)]
    pub radii: Option<RadiiArg>,
    /// Store the top-level BVH in wide 64-byte nodes of up to seven children, each child's box
    /// as 8-bit codes in its node's frame, rounded outwards (the default for displaced
    /// micro-meshes).
    #[arg(long)]
    pub wide_top: bool,
    /// Store the top-level BVH in compact binary 16-byte nodes, boxes as 15-bit codes of the
    /// scene's box rounded outwards.
    #[arg(long, conflicts_with = "wide_top")]
    pub compact_top: bool,
    /// Store a displaced micro-mesh's top-level BVH in full binary 32-byte nodes.
    #[arg(long, conflicts_with_all = ["compact_top", "wide_top"])]
    pub full_top: bool,
    /// Store each grid's six ids in as many bits as the mesh's counts need rather than in a
    /// 16-byte header (always so for displaced micro-meshes).
    #[arg(long)]
    pub tight_headers: bool,
    /// Store no leaf thicknesses and cull leaves by their spheres alone (smaller, faster to
    /// build, slower to trace; see docs/usage.md).
    #[arg(long)]
    pub no_leaf_footprint: bool,
    /// How each grid stores its inner vertices: 16-bit codes around the grid's centre (a
    /// vertex moves by at most 2^-15 of the grid's radius; edges and corners stay exact), or
    /// 32-bit floats. Both representations get the same positions.
    #[arg(long, value_enum, default_value_t = InnerVertices::Quantized)]
    pub inner_vertices: InnerVertices,
    /// A displaced micro-mesh's values compressed (corrections to midpoint predictions, a
    /// width per level), adding at most this RMS error, as a fraction of the bounding-box
    /// diagonal. Grids and the triangles they are compared with both get the compressed values.
    /// A micro-mesh baked by gridrt comes with its values compressed already.
    #[arg(long, value_name = "MAX_ADDED_ERROR", value_parser = parse_value_error)]
    pub compress_values: Option<f32>,
    /// Store a displaced micro-mesh's values plain (11 bits each) in the grids, even where its
    /// file says how to compress them.
    #[arg(long, conflicts_with = "compress_values")]
    pub plain_values: bool,
}

fn parse_byte_budget(s: &str) -> std::result::Result<f64, String> {
    match s.parse::<f64>() {
        Ok(b) if b.is_finite() && b > 0.0 => Ok(b),
        _ => Err(format!("'{s}' is not a byte budget: bytes per micro-triangle, above 0")),
    }
}

fn parse_value_error(s: &str) -> std::result::Result<f32, String> {
    match s.parse::<f32>() {
        Ok(e) if e.is_finite() && e >= 0.0 => Ok(e),
        _ => Err(format!(
            "'{s}' is not an error bound: a fraction of the diagonal, at least 0"
        )),
    }
}

/// Compresses the values of `input`'s displaced micro-mesh when `build` asks for it, so
/// everything after (grids, the baseline's triangles) traces the compressed surface, or
/// drops their code when it asks for them plain.
pub fn compress_values(input: &mut Input, build: &BuildArgs) -> Result<()> {
    if let (true, Some(micromesh)) = (build.plain_values, &mut input.micromesh) {
        micromesh.micromap.value_code = None;
    }
    let (Some(bound), Some(micromesh)) = (build.compress_values, &input.micromesh) else {
        return Ok(());
    };
    let options = grid::compressed::ValueCompression::bounded(bound);
    let compressed = grid::compressed::compress(micromesh, &options).map_err(|e| e.prefixed(&input.name))?;
    note!(
        "note: {}: values compressed to {:.2} bits each (base edges at widths {:?} bits per level, each grid \
         at its own), adding {:.3e} of the diagonal (RMS)",
        input.name,
        compressed.bits_per_value(),
        grid::compressed::level_widths(&compressed.code),
        compressed.added_error
    );
    input.mesh = compressed.mesh.decoded_welded();
    input.micromesh = Some(compressed.mesh);
    Ok(())
}

#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum RadiiArg {
    F32,
    Half,
    Relative,
}

impl RadiiArg {
    fn format(self) -> grid::RadiusFormat {
        match self {
            RadiiArg::F32 => grid::RadiusFormat::F32,
            RadiiArg::Half => grid::RadiusFormat::Half,
            RadiiArg::Relative => grid::RadiusFormat::Relative,
        }
    }
}

#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum InnerVertices {
    Quantized,
    F32,
}

impl BuildArgs {
    /// Refuses, before subdividing, a mesh whose grids could not be addressed at these levels;
    /// returns the sizes their buffers will have (see `grid::check_limits`).
    pub fn check_grid_limits(&self, name: &str, mesh: &Mesh) -> Result<Vec<limits::BufferSize>> {
        grid::check_limits(mesh, &self.grid_build()).map_err(|e| e.prefixed(name).into())
    }

    /// These arguments for a displaced micro-mesh's decoded micro-triangles: no further
    /// subdivision.
    pub fn as_decoded(&self) -> BuildArgs {
        BuildArgs {
            levels: 0,
            subdivision: SubdivisionArg::Flat,
            ..self.clone()
        }
    }

    /// The grid build these arguments ask for.
    pub fn grid_build(&self) -> grid::GridBuild {
        grid::GridBuild {
            levels: self.levels,
            scheme: self.subdivision.scheme(),
            crease_angle: self.crease_angle,
            options: self.grid_options(),
            quantized: self.inner_vertices == InnerVertices::Quantized,
        }
    }

    pub fn grid_options(&self) -> grid::GridOptions {
        grid::GridOptions {
            excluded_levels: self.excluded_levels,
            radii: self.radii.unwrap_or(RadiiArg::F32).format(),
            leaf_footprint: !self.no_leaf_footprint,
            top: match (self.wide_top, self.compact_top) {
                (true, _) => grid::TopFormat::Wide,
                (_, true) => grid::TopFormat::Compact,
                _ => grid::TopFormat::Full,
            },
            tight_headers: self.tight_headers,
            own_rooms: true,
        }
    }

    /// These arguments for a displaced micro-mesh of `level` built as displaced grids: its own
    /// level, no subdivision, radii relative to each grid's root unless `--radii` says
    /// otherwise, a wide top level unless `--compact-top` or `--full-top`, tight headers.
    pub fn as_displaced(&self, level: u32) -> BuildArgs {
        BuildArgs {
            levels: level,
            subdivision: SubdivisionArg::Flat,
            radii: Some(self.radii.unwrap_or(RadiiArg::Relative)),
            wide_top: !self.full_top && !self.compact_top,
            tight_headers: true,
            ..self.clone()
        }
    }
}

#[derive(clap::Args, Debug, Clone)]
pub struct RenderArgs {
    /// Meshes to render together (.obj, .ply, .gltf or .glb); the built-in scene when none.
    pub meshes: Vec<PathBuf>,
    #[arg(long, value_enum, default_value_t = BackendArg::Auto)]
    pub backend: BackendArg,
    #[arg(long, value_enum, default_value_t = Mode::Grid)]
    pub mode: Mode,
    #[command(flatten)]
    pub build: BuildArgs,
    /// Depth to render, at most L (level of detail from the same data), or `auto`: each grid
    /// as deep as its size on screen asks (see --lod-pixels). L when absent.
    #[arg(long, value_name = "DEPTH|auto", value_parser = parse_lod)]
    pub lod: Option<LodArg>,
    /// With --lod auto: the size on screen, in pixels, that micro-triangles are kept within.
    #[arg(long, default_value_t = DEFAULT_LOD_PIXELS, value_parser = parse_positive_f32, allow_hyphen_values = true)]
    pub lod_pixels: f32,
    #[arg(long, default_value_t = 960, value_parser = clap::value_parser!(u32).range(1..))]
    pub width: u32,
    #[arg(long, default_value_t = 720, value_parser = clap::value_parser!(u32).range(1..))]
    pub height: u32,
    /// How to colour pixels [default: lit for the built-in scene, eye for meshes].
    #[arg(long, value_enum)]
    pub shading: Option<ShadingArg>,
    /// Light grids with smooth normals, interpolated across micro-triangles from the lattice
    /// around each hit (eye, normal, primitive, level and lit shading).
    #[arg(long)]
    pub smooth: bool,
    /// Ambient-occlusion rays per pixel (`--shading ao`).
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub ao_samples: u32,
    /// How far ambient-occlusion rays look, in the file's units; a tenth of the mesh's
    /// bounding-box diagonal when absent.
    #[arg(long, value_parser = parse_positive, allow_hyphen_values = true)]
    pub ao_distance: Option<f64>,
    /// Tests per pixel shown white by `--shading cost` (to compare pictures on one scale);
    /// the frame's 99th percentile when absent.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub heat_white: Option<u32>,
    #[command(flatten)]
    pub camera: CameraArgs,
    /// Render N frames around the target (the azimuth turning by 360/N degrees each), written
    /// as OUTPUT_000.png, OUTPUT_001.png, ...
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=100_000), conflicts_with = "eye")]
    pub turntable: Option<u32>,
    #[arg(long, short, default_value = "render.png")]
    pub output: PathBuf,
}

/// Where the camera stands, in the mesh file's units; whatever is left out is chosen from the
/// mesh's bounds (the whole mesh in view, from the front-right, somewhat above).
#[derive(clap::Args, Debug, Clone)]
pub struct CameraArgs {
    /// Eye position, `x,y,z`; without it the eye orbits the target (see --azimuth).
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true)]
    pub eye: Option<DVec3>,
    /// Point looked at, `x,y,z`; the centre of the mesh's bounds when absent.
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true)]
    pub target: Option<DVec3>,
    /// Up in the picture, `x,y,z`.
    #[arg(long, value_parser = parse_point, default_value = "0,1,0", allow_hyphen_values = true)]
    pub up: DVec3,
    /// Vertical field of view, in degrees.
    #[arg(long, default_value_t = camera::FOV_DEGREES)]
    pub fov: f32,
    /// Degrees around the up axis from the front (+z with +y up) towards +x, without --eye.
    #[arg(long, default_value_t = 35.0, allow_hyphen_values = true)]
    pub azimuth: f32,
    /// Degrees above the horizon, without --eye.
    #[arg(long, default_value_t = 25.0, allow_hyphen_values = true)]
    pub elevation: f32,
    /// Distance from the target, without --eye; where the whole mesh fits when absent.
    #[arg(long, value_parser = parse_positive, allow_hyphen_values = true)]
    pub distance: Option<f64>,
}

impl CameraArgs {
    /// The viewpoint in the mesh's local frame.
    pub fn viewpoint(&self, frame: &LocalFrame) -> Viewpoint {
        FileViewpoint {
            eye: self.eye,
            target: self.target,
            up: self.up.as_vec3(),
            fov_degrees: self.fov,
            azimuth_degrees: self.azimuth,
            elevation_degrees: self.elevation,
            distance: self.distance,
        }
        .local(frame)
    }
}

/// `x,y,z`: three finite numbers.
fn parse_point(text: &str) -> std::result::Result<DVec3, String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let numbers: Vec<f64> = parts
        .iter()
        .filter_map(|p| p.parse().ok())
        .filter(|v: &f64| v.is_finite())
        .collect();
    match numbers.as_slice() {
        &[x, y, z] if parts.len() == 3 => Ok(DVec3::new(x, y, z)),
        _ => Err(format!("expected three numbers x,y,z, found {text:?}")),
    }
}

/// `--lod`: a depth, or each grid's own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LodArg {
    Depth(u32),
    Auto,
}

/// Micro-triangle size on screen that `--lod auto` aims at, in pixels.
pub const DEFAULT_LOD_PIXELS: f32 = 1.0;

fn parse_lod(text: &str) -> std::result::Result<LodArg, String> {
    match text.trim() {
        "auto" => Ok(LodArg::Auto),
        t => t
            .parse()
            .map(LodArg::Depth)
            .map_err(|_| format!("expected a depth (0, 1, 2, ...) or auto, found {text:?}")),
    }
}

fn parse_positive_f32(text: &str) -> std::result::Result<f32, String> {
    parse_positive(text).map(|v| v as f32)
}

/// A finite number above zero.
fn parse_positive(text: &str) -> std::result::Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("expected a number above zero, found {text:?}")),
    }
}

impl RenderArgs {
    /// Host bytes of the image being rendered and written.
    fn image_bytes(&self) -> u64 {
        (self.width as u64 * self.height as u64).saturating_mul(limits::IMAGE_BYTES_PER_PIXEL)
    }

    /// These arguments for a displaced micro-mesh's decoded micro-triangles: built as they
    /// are, at one depth.
    fn as_decoded(&self) -> RenderArgs {
        RenderArgs {
            build: self.build.as_decoded(),
            lod: None,
            ..self.clone()
        }
    }

    /// These arguments for a displaced micro-mesh of `level` as displaced grids: its own
    /// level is built, and a depth to render must not be deeper.
    fn as_displaced(&self, level: u32) -> Result<RenderArgs> {
        if let Some(LodArg::Depth(depth)) = self.lod {
            if depth > level {
                bail!("--lod {depth} is deeper than the micro-mesh's level ({level})");
            }
        }
        Ok(RenderArgs {
            build: self.build.as_displaced(level),
            ..self.clone()
        })
    }

    /// The library's build options for these arguments.
    pub fn build_options(&self) -> BuildOptions {
        BuildOptions {
            representation: self.mode.representation(),
            grid: self.build.grid_build(),
            lod: match self.lod {
                Some(LodArg::Depth(depth)) => Some(depth),
                Some(LodArg::Auto) | None => None,
            },
        }
    }

    /// The shading asked for, or the default: lit for the built-in scene (a picture worth
    /// showing, cheap at its size), the headlight for meshes (one ray per pixel, whatever
    /// their size).
    fn shading_arg(&self) -> ShadingArg {
        match (self.shading, self.meshes.is_empty()) {
            (Some(shading), _) => shading,
            (None, true) => ShadingArg::Lit,
            (None, false) => ShadingArg::Eye,
        }
    }

    /// The library's render options for these arguments; lengths are in the file's units,
    /// `frame` takes them to the mesh's local frame.
    pub fn render_options(&self, frame: &LocalFrame) -> RenderOptions {
        RenderOptions {
            shading: self.shading_arg().shading(),
            ao_samples: self.ao_samples,
            ao_distance: self.ao_distance.map(|d| (d * frame.scale) as f32),
            heat_white: self.heat_white,
            lod_pixels: (self.lod == Some(LodArg::Auto)).then_some(self.lod_pixels),
            smooth_normals: self.smooth,
        }
    }

    /// Refuses, before any work, what needs grids asked of the baseline.
    fn check_mode(&self) -> Result<()> {
        if self.mode == Mode::Triangles {
            let one_depth = "the baseline has one depth, fixed when it is built";
            let needs_grids = [
                (self.lod == Some(LodArg::Auto), "--lod auto", one_depth),
                (self.shading == Some(ShadingArg::Level), "--shading level", one_depth),
                (
                    self.smooth,
                    "--smooth",
                    "the baseline's triangle list has no neighbours to take normals from",
                ),
            ];
            if let Some((_, flag, why)) = needs_grids.iter().find(|(asked, ..)| *asked) {
                bail!("{flag} needs grids (--mode grid): {why}");
            }
        }
        Ok(())
    }
}

#[derive(clap::Args, Debug)]
pub struct ExportArgs {
    /// Mesh to subdivide (.obj, .ply, .gltf or .glb); the built-in scene when absent. A
    /// displaced micro-mesh is written as its decoded micro-triangles, at its own levels.
    pub mesh: Option<PathBuf>,
    /// Subdivision depth L: every base triangle becomes 4^L micro-triangles [default: 3; a
    /// displaced micro-mesh takes none].
    #[arg(long, short = 'L', value_parser = clap::value_parser!(u32).range(0..=6))]
    pub levels: Option<u32>,
    #[arg(long, value_enum, default_value_t = SubdivisionArg::Loop)]
    pub subdivision: SubdivisionArg,
    /// Keep edges sharp where the surface folds by more than this many degrees (0 to 180;
    /// boundaries always stay sharp). Without it, Loop subdivision rounds every edge.
    #[arg(long, value_name = "DEGREES", value_parser = parse_crease_angle)]
    pub crease_angle: Option<f32>,
    #[arg(long, short, default_value = "micro.ply")]
    pub output: PathBuf,
}

#[derive(clap::Args, Debug)]
pub struct CompareArgs {
    /// The reference surface (.obj, .ply, .gltf or .glb): distances are given as fractions of
    /// its bounding-box diagonal.
    pub reference: PathBuf,
    /// The surface compared with it, in the same units.
    pub other: PathBuf,
    /// Points sampled on each surface, by area.
    #[arg(long, default_value_t = 1_000_000, value_parser = at_least_one())]
    pub samples: usize,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct BakeArgs {
    /// The detailed mesh to bake (.obj, .ply, .gltf or .glb), as it is: duplicates, holes,
    /// non-manifold edges and several parts are fine.
    pub reference: PathBuf,
    /// Triangles of the base mesh the reference is decimated to [default: 1/64 of the
    /// reference's, so that level 3 has about as many micro-triangles as the reference, and
    /// no fewer than 128 (all of a smaller reference's)].
    #[arg(long, value_name = "N", value_parser = at_least_one(), conflicts_with = "base")]
    pub base_triangles: Option<usize>,
    /// Bake onto this base mesh (in the reference's units) instead of decimating.
    #[arg(long, value_name = "BASE_MESH")]
    pub base: Option<PathBuf>,
    /// Subdivision level L: every base triangle gets 4^L micro-triangles.
    #[arg(long, short = 'L', default_value_t = 3, value_parser = clap::value_parser!(u32).range(0..=6))]
    pub levels: u32,
    /// Rounds of fitting the values to the reference in the least-squares sense after the
    /// rays have found it (0: every micro-vertex stays on the reference); at most 100, and
    /// fewer are taken once a round no longer brings the surface closer.
    #[arg(
        long,
        value_name = "N",
        default_value_t = gridrt::micromesh::bake::refine::Refinement::default().rounds,
        value_parser = clap::value_parser!(u32).range(0..=gridrt::micromesh::bake::refine::MAX_ROUNDS as i64)
    )]
    pub fit_rounds: u32,
    /// The glTF to write; its buffer (.bin) and micromap (.bary) go beside it.
    #[arg(long, short, default_value = "baked.gltf")]
    pub output: PathBuf,
    /// Compress the values adding at most this RMS error, as a fraction of the base mesh's
    /// bounding-box diagonal [default: half the uncompressed bake's own RMS distance from the
    /// reference].
    #[arg(long, value_name = "MAX_ADDED_ERROR", value_parser = parse_value_error, conflicts_with = "plain_values")]
    pub compress_values: Option<f32>,
    /// Leave the values uncompressed: 11 bits each in the displaced grids, and no value code
    /// in the .bary (which holds the values plain either way, for any reader).
    #[arg(long)]
    pub plain_values: bool,
    /// Most bytes per micro-triangle for everything the GPU gets as displaced grids: where
    /// the error bound needs more, the values give up error until they fit [default with the
    /// default bound: 1.0, 0.5 and 0.2 at levels 3, 4 and 5 (and 6), the budgets of the
    /// hardware's displacement blocks with the hierarchy on top; none below level 3].
    #[arg(long, value_name = "BYTES", value_parser = parse_byte_budget, conflicts_with = "plain_values")]
    pub max_bytes: Option<f64>,
    /// Give each base triangle its own level, up to --levels, in the fewest bytes that keep
    /// the symmetric RMS distance from the reference within about this fraction of its
    /// bounding-box diagonal: every level is fitted to the reference, each triangle takes the
    /// one where a byte saved costs more error than a rate all share, neighbours within a
    /// level of each other, the finer side decimating the edge between them (glTF's
    /// primitiveFlags). Such micro-meshes render as displaced grids of mixed levels. Their
    /// values are then compressed as by default, and the levels keep 1/1.12 of the bound,
    /// leaving the rest to the compression; with --compress-values or --plain-values the
    /// levels keep all of it.
    #[arg(long, value_name = "MAX_ERROR", value_parser = parse_value_error, conflicts_with = "max_bytes")]
    pub max_error: Option<f32>,
    /// Give each base triangle its own level, up to --levels, as --max-error does, but as
    /// close to the reference as BYTES bytes of everything the GPU gets allow (values
    /// compressed as by default, or --plain-values): the levels are chosen for a share of the
    /// budget, their values compressed and the whole measured, and the share corrected, a
    /// few rounds, then the values take what is left of the budget. Where even the coarsest
    /// levels do not fit, the summary says so.
    #[arg(
        long,
        value_name = "BYTES",
        value_parser = clap::value_parser!(u64).range(1..),
        conflicts_with_all = ["max_error", "max_bytes", "compress_values", "nv_blocks"]
    )]
    pub within_bytes: Option<u64>,
    /// Store the values in NVIDIA's compressed displacement blocks (eDispC1_r11_unorm_block),
    /// as other micro-mesh tools and the fixed-function hardware take them: exact up to level
    /// 3, 256 micro-triangles in 128 bytes at level 4, 1024 in 128 from level 5 (with
    /// --max-error, a triangle whose format cannot match a finer neighbour's edge keeps its
    /// values exactly, 64 micro-triangles in 64 bytes). The values become those the blocks
    /// decode to; gridrt traces them plain (11 bits each).
    #[arg(long, conflicts_with_all = ["compress_values", "max_bytes"])]
    pub nv_blocks: bool,
    /// Points sampled on each surface, by area, to measure the baked mesh's distance from
    /// the reference.
    #[arg(long, default_value_t = 1_000_000, value_parser = at_least_one())]
    pub samples: usize,
    /// Print one JSON object instead of the summary.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct StatsArgs {
    /// Mesh to measure (.obj, .ply, .gltf or .glb); the built-in scene when absent.
    pub mesh: Option<PathBuf>,
    #[command(flatten)]
    pub build: BuildArgs,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Meshes to measure (.obj, .ply, .gltf or .glb).
    #[arg(required = true)]
    pub meshes: Vec<PathBuf>,
    #[command(flatten)]
    pub build: BuildArgs,
    #[arg(long, value_enum, default_value_t = BackendArg::Cpu)]
    pub backend: BackendArg,
    /// Camera views on an orbit around each mesh.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..))]
    pub views: u32,
    #[arg(long, default_value_t = 480, value_parser = clap::value_parser!(u32).range(1..))]
    pub width: u32,
    #[arg(long, default_value_t = 360, value_parser = clap::value_parser!(u32).range(1..))]
    pub height: u32,
    /// Ambient-occlusion rays per primary hit.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..))]
    pub ao_samples: u32,
    /// Order of the ray lists (both representations trace the same list).
    #[arg(long, value_enum, default_value_t = RayOrderArg::Scanline)]
    pub ray_order: RayOrderArg,
    /// Untimed runs before the timed ones.
    #[arg(long, default_value_t = 1)]
    pub warmup: usize,
    /// Timed runs per representation and ray kind; the median is reported.
    #[arg(long, default_value_t = 5, value_parser = at_least_one())]
    pub repeats: usize,
    /// Builds per representation at most (fewer once they have taken a few seconds); the
    /// median is reported.
    #[arg(long, default_value_t = 11, value_parser = at_least_one())]
    pub build_repeats: usize,
    /// Also write the results as JSON (one object per mesh, in an array).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Also write the markdown table to a file.
    #[arg(long)]
    pub markdown: Option<PathBuf>,
    /// Also draw the three ratios per mesh as a PNG chart.
    #[arg(long)]
    pub chart: Option<PathBuf>,
    /// TrueType font for the chart's labels.
    #[arg(long, default_value = chart::DEFAULT_FONT)]
    pub font: PathBuf,
    /// The mesh a micro-mesh was baked from: traced on the same rays under the baseline's
    /// BVH, with its bytes and build time, and its distance from the micro-mesh.
    #[arg(long, value_name = "REFERENCE")]
    pub reference: Option<PathBuf>,
}

fn at_least_one() -> clap::builder::RangedU64ValueParser<usize> {
    clap::builder::RangedU64ValueParser::new().range(1..)
}

pub fn run(cli: Cli) -> Result<()> {
    let mut stages = Stages::new(cli.quiet);
    match cli.command {
        Command::Render(args) => render(&args, &mut stages),
        Command::Stats(args) => stats::run(&args, cli.quiet),
        Command::Bench(args) => bench::run(&args, cli.quiet),
        Command::Export(args) => export(&args, &mut stages),
        Command::Compare(args) => compare::run(&args),
        Command::Bake(args) => bake::run(&args, &mut stages),
    }
}

/// The mesh named on the command line, or the built-in scene, in its local frame (see
/// `gridrt::input::open`), warning about dropped degenerate triangles.
pub fn load(path: Option<&Path>) -> Result<Input> {
    load_all(path.as_slice())
}

/// [`load`] for several meshes rendered together.
pub fn load_all(paths: &[&Path]) -> Result<Input> {
    let input = input::open_all(paths)?;
    for warning in &input.warnings {
        eprintln!("warning: {warning}");
    }
    let cleaning = &input.cleaning;
    if let Some(d) = input.displaced {
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
        note!(
            "note: {}: a displaced micro-mesh of {} base triangles at {levels}, {} micro-triangles{values}",
            input.name,
            d.base_triangles,
            input.mesh.triangles.len()
        );
    } else if cleaning.welded > 0 {
        note!(
            "note: {}: welded {} vertices to others at the same position (split at seams, or unindexed)",
            input.name,
            cleaning.welded
        );
    }
    if let Some(seams) = (input.micromesh.as_ref().map(|m| m.open_seams())).filter(|&n| n > 0) {
        eprintln!(
            "warning: {}: {seams} base edges are rendered at different levels by the triangles on either side \
             (levels more than one apart, or primitiveFlags that do not decimate the finer side): \
             the surface has cracks along them",
            input.name
        );
    }
    if cleaning.dropped > 0 {
        eprintln!(
            "warning: {}: dropped {} degenerate triangles ({})",
            input.name,
            cleaning.dropped,
            mesh::DEGENERATE
        );
    }
    if cleaning.zero_area == input.mesh.triangles.len() {
        eprintln!(
            "warning: {}: every triangle has zero area (its corners lie on one line): nothing of it can be seen",
            input.name
        );
    } else if cleaning.zero_area > 0 {
        note!(
            "note: {}: {} of {} triangles have zero area (corners on one line)",
            input.name,
            cleaning.zero_area,
            input.mesh.triangles.len()
        );
    }
    Ok(input)
}

impl SubdivisionArg {
    fn scheme(self) -> Scheme {
        match self {
            SubdivisionArg::Loop => Scheme::Loop,
            SubdivisionArg::Flat => Scheme::Flat,
        }
    }
}

/// A dihedral angle in degrees, from 0 to 180.
fn parse_crease_angle(text: &str) -> std::result::Result<f32, String> {
    match text.trim().parse::<f32>() {
        Ok(degrees) if (0.0..=180.0).contains(&degrees) => Ok(degrees),
        Ok(_) => Err("a crease angle is between 0 and 180 degrees".into()),
        Err(_) => Err(format!("'{text}' is not a number of degrees")),
    }
}

pub fn subdivide(mesh: &Mesh, build: &BuildArgs) -> Subdivided {
    let creases = build.grid_build().creases(mesh);
    let mut sub = subdiv::subdivide_creased(mesh, build.levels, build.subdivision.scheme(), &creases);
    if build.inner_vertices == InnerVertices::Quantized {
        sub.quantize_inner();
    }
    sub
}

fn render(args: &RenderArgs, stages: &mut Stages) -> Result<()> {
    let options = args.build_options();
    let lod = options.lod.unwrap_or(args.build.levels);
    // A displaced micro-mesh has a level of its own, checked once it is loaded.
    let displaced_file = args.meshes.iter().any(|m| mesh::is_gltf(m));
    if lod > args.build.levels && !displaced_file {
        bail!("--lod {lod} is deeper than --levels {}", args.build.levels);
    }
    args.check_mode()?;
    let frames = args.turntable.unwrap_or(1);
    let paths: Vec<&Path> = args.meshes.iter().map(PathBuf::as_path).collect();
    let outputs = render_outputs(args, &paths)?;
    let Input {
        name,
        mesh,
        frame,
        displaced,
        micromesh,
        ..
    } = stages.run("load", || {
        let mut input = load_all(&paths)?;
        compress_values(&mut input, &args.build)?;
        anyhow::Ok(input)
    })?;
    // A displaced micro-mesh becomes displaced grids; for the baseline, its decoded
    // micro-triangles are traced as they are.
    let displaced_grids = micromesh.filter(|m| args.mode == Mode::Grid && m.deepest_level().is_some());
    let (as_decoded, as_displaced);
    let (args, options, lod) = match (&displaced_grids, displaced) {
        (Some(m), _) => {
            as_displaced = args.as_displaced(m.deepest_level().unwrap_or(0))?;
            let options = as_displaced.build_options();
            let lod = options.lod.unwrap_or(as_displaced.build.levels);
            (&as_displaced, options, lod)
        }
        (None, Some(_)) => {
            as_decoded = args.as_decoded();
            (&as_decoded, as_decoded.build_options(), 0)
        }
        (None, None) if lod > args.build.levels => {
            bail!("--lod {lod} is deeper than --levels {}", args.build.levels)
        }
        (None, None) => (args, options, lod),
    };
    let base_triangles = displaced_grids
        .as_ref()
        .map_or(mesh.triangles.len(), |m| m.triangles.len());
    if displaced.is_none() && paths.len() == 1 {
        suggest_bake(&name, &mesh, &args.build, stages);
    }
    let viewpoint = args.camera.viewpoint(&frame);
    // A view with no direction is refused before the build (bounds only matter for defaults).
    match &displaced_grids {
        Some(m) => check_render_memory(&name, &m.base_mesh(), args)?,
        None => check_render_memory(&name, &mesh, args)?,
    }
    let placed = camera::placement(&mesh.positions, &viewpoint, args.width, args.height)
        .map_err(naming_input(&name, gridrt::error::ErrorKind::Input))?;
    let sizes = least_buffer_sizes(args, &name, &mesh, displaced_grids.as_ref(), lod)?;
    let backend = stages.run("device", || open_backend(args.backend, "rendering"))?;
    let displaced = args.mode == Mode::Grid && displaced_grids.is_some();
    backend.check_fits(&sizes, displaced).map_err(|e| e.prefixed(&name))?;
    check_upload_memory(&name, &sizes, &backend, args)?;
    let scene = build_scene(stages, args, &mesh, displaced_grids.as_ref(), &options)?;
    stages.say(scene_line(
        &name,
        &scene,
        displaced_grids.as_ref(),
        base_triangles,
        lod,
        args,
    ));
    let render = args.render_options(&frame);
    // Uploaded once, by the first frame that needs it, for every frame of a turntable.
    let uploaded = std::cell::OnceCell::new();
    for (k, output) in (0..frames).zip(&outputs) {
        // A turntable turns the orbit's azimuth by equal steps, the first frame the plain view.
        // The later frames turn about the first one's target, so the mesh does not wander.
        let turned = Viewpoint {
            azimuth_degrees: viewpoint.azimuth_degrees + 360.0 * k as f32 / frames as f32,
            target: viewpoint.target.or((k > 0).then_some(placed.target)),
            ..viewpoint
        };
        let view = camera::view_of(&mesh.positions, &turned, args.width, args.height)?;
        if let (Scene::Grids(grids), Some(_)) = (&scene, render.lod_pixels) {
            let report = LodReport::measure(grids, &render.frame(&scene, &view));
            stages.say(describe_lod(&report, args.lod_pixels));
        }
        let target = (&backend, &scene, &uploaded);
        let image = render_image(stages, target, &view, &render, &name)?;
        stages.run("write", || image.write_png(output))?;
        let (width, height, device) = (args.width, args.height, backend.describe());
        stages.say(format!("rendered {width}x{height} on {device} -> {}", output.display()));
    }
    stages.report();
    Ok(())
}

/// The PNG files a render writes (one per turntable frame), checked before any work: each
/// a writable `.png` path, none of them an input.
fn render_outputs(args: &RenderArgs, paths: &[&Path]) -> Result<Vec<PathBuf>> {
    let frames = args.turntable.unwrap_or(1);
    let outputs: Vec<PathBuf> = (0..frames)
        .map(|k| frame_path(&args.output, k, args.turntable))
        .collect();
    let inputs = input::files_read(paths);
    for output in &outputs {
        files::check_png_path(output)?;
        files::check_not_input(output, &inputs)?;
    }
    Ok(outputs)
}

/// The least sizes of the scene's buffers, from the mesh's counts, before it is built.
fn least_buffer_sizes(
    args: &RenderArgs,
    name: &str,
    mesh: &Mesh,
    displaced_grids: Option<&gridrt::micromesh::DisplacedMesh>,
    lod: u32,
) -> Result<Vec<limits::BufferSize>> {
    Ok(match (args.mode, displaced_grids) {
        (Mode::Grid, Some(m)) => {
            grid::displaced::least_buffer_sizes(m, &args.build.grid_options()).map_err(|e| e.prefixed(name))?
        }
        (Mode::Grid, None) => args.build.check_grid_limits(name, mesh)?,
        (Mode::Triangles, _) => triangles::least_buffer_sizes(
            mesh.positions.len() as u64,
            limits::micro_triangles(mesh.triangles.len(), lod),
        ),
    })
}

/// The scene `render` traces: displaced grids, grids (a bar over the base triangles) or the
/// baseline's triangles.
fn build_scene(
    stages: &mut Stages,
    args: &RenderArgs,
    mesh: &Mesh,
    displaced_grids: Option<&gridrt::micromesh::DisplacedMesh>,
    options: &BuildOptions,
) -> Result<Scene> {
    Ok(match (args.mode, displaced_grids) {
        (Mode::Grid, Some(m)) => stages.run("build", || Scene::build_displaced(m, options))?,
        (Mode::Grid, None) => stages.run_counted("build", mesh.triangles.len() as u64, |bar| {
            Scene::build_reporting(mesh, options, &|n| bar.inc(n as u64))
        })?,
        (Mode::Triangles, _) => stages.run("build", || Scene::build(mesh, options))?,
    })
}

/// The line that says what the scene holds: its triangles at the depth rendered and bytes.
fn scene_line(
    name: &str,
    scene: &Scene,
    displaced_grids: Option<&gridrt::micromesh::DisplacedMesh>,
    base_triangles: usize,
    lod: u32,
    args: &RenderArgs,
) -> String {
    // A displaced micro-mesh's triangles each have their own level.
    let micro_at = |depth: u32| match displaced_grids {
        Some(m) => m.micro_triangles_at(depth),
        None => limits::micro_triangles(base_triangles, depth),
    };
    let micro = micro_at(lod);
    // Grids hold every level built, whatever depth renders.
    let stored = match scene {
        Scene::Grids(_) => micro_at(args.build.levels),
        Scene::Triangles(_) => micro,
    };
    let up_to = if args.lod == Some(LodArg::Auto) { "up to " } else { "" };
    format!(
        "{name}: {} base triangles, {micro} micro-triangles at depth {up_to}{lod}, {} ({:.2} B per micro-triangle)",
        base_triangles,
        limits::human(scene.memory() as u64),
        scene.memory() as f64 / stored as f64
    )
}

/// One frame of `render`: the cost heat map (counted on the CPU), or the image on the
/// backend, the scene uploaded to it the first time.
fn render_image(
    stages: &mut Stages,
    (backend, scene, uploaded): (&Backend, &Scene, &std::cell::OnceCell<Uploaded>),
    view: &gridrt_shared::layout::Camera,
    render: &RenderOptions,
    name: &str,
) -> Result<gridrt::pipeline::Image> {
    let limits = naming_input(name, gridrt::error::ErrorKind::Limits);
    if render.shading == Shading::Cost {
        let costs = stages.run("render", || backend.render_costs(scene, view, render).map_err(&limits))?;
        let summary = costs.summary();
        let white = summary.white(render.heat_white);
        stages.say(describe_costs(&summary, white, render.heat_white.is_none()));
        return Ok(costs.heat_map(white));
    }
    // Ambient occlusion renders in passes: a bar over its samples.
    let samples = match render.shading {
        Shading::AmbientOcclusion | Shading::Lit => render.ao_samples as u64,
        _ => 0,
    };
    stages
        .run_counted("render", samples, |bar| {
            let uploaded = match uploaded.get() {
                Some(u) => u,
                None => {
                    let u = backend.upload(scene).map_err(&limits)?;
                    uploaded.get_or_init(|| u)
                }
            };
            (backend.render_uploaded(scene, uploaded, view, render, &|done| bar.set_position(done as u64)))
                .map_err(&limits)
        })
        .map_err(Into::into)
}

/// Triangles from which a mesh is taken for a detailed one (a scan, a sculpt, a CAD
/// tessellation) rather than a control mesh to subdivide.
const DENSE_TRIANGLES: usize = 10_000;

/// Points a user who subdivides a dense mesh to `bake`: Loop subdivision rounds such a mesh
/// into another shape, and a displaced micro-mesh keeps its own in far less memory.
fn suggest_bake(name: &str, mesh: &Mesh, build: &BuildArgs, stages: &Stages) {
    if mesh.triangles.len() >= DENSE_TRIANGLES && build.levels > 0 && build.subdivision == SubdivisionArg::Loop {
        stages.say(format!(
            "note: {name}: {} triangles is a detailed mesh, not a control mesh: Loop subdivision rounds its edges and \
             thin parts into another shape. To trace its own shape compactly, bake it: gridrt bake {name} -o \
             baked.gltf (then render baked.gltf)",
            mesh.triangles.len()
        ));
    }
}

/// How many grids render at each depth, and the cracks between them, in one line.
fn describe_lod(report: &LodReport, pixels: f32) -> String {
    let depths: Vec<String> = report
        .grids_per_level
        .iter()
        .enumerate()
        .filter(|(_, &n)| n > 0)
        .map(|(d, n)| format!("{n} at {d}"))
        .collect();
    format!(
        "level of detail ({pixels} px): grids {}; {} base edges between grids of different depths, \
         widest crack {:.2} px",
        depths.join(", "),
        report.mismatched_edges,
        report.widest_crack_pixels
    )
}

/// The heat map's scale and what it shows, in one line.
fn describe_costs(s: &CostSummary, white: u32, percentile: bool) -> String {
    let why = if percentile {
        format!("the 99th percentile; the costliest pixel {}", s.max_total)
    } else {
        format!("--heat-white; the costliest pixel {}", s.max_total)
    };
    format!(
        "cost per pixel: {:.1} BVH nodes, {:.1} spheres, {:.1} triangles tested on average; \
         black 0 to white {white} tests ({why})",
        s.mean_nodes, s.mean_spheres, s.mean_triangles
    )
}

/// Where frame `k` goes: `output` itself, or for a turntable `output`'s name with the frame
/// number, `render_007.png`.
fn frame_path(output: &Path, k: u32, turntable: Option<u32>) -> PathBuf {
    let Some(frames) = turntable else {
        return output.to_path_buf();
    };
    let digits = (frames - 1).max(1).ilog10() as usize + 1;
    let stem = output.file_stem().unwrap_or_default().to_string_lossy();
    output.with_file_name(format!("{stem}_{k:0width$}.png", width = digits.max(3)))
}

/// `export`'s subdivision depth when none is given.
const DEFAULT_EXPORT_LEVELS: u32 = 3;

/// Subdivides a mesh and writes the micro-mesh, in the input's units, as binary PLY.
fn export(args: &ExportArgs, stages: &mut Stages) -> Result<()> {
    files::check_output(&args.output, "ply")?;
    let paths: Vec<&Path> = args.mesh.iter().map(PathBuf::as_path).collect();
    files::check_not_input(&args.output, &input::files_read(&paths))?;
    let Input {
        name,
        mesh,
        frame,
        displaced,
        ..
    } = stages.run("load", || load(args.mesh.as_deref()))?;
    // A displaced micro-mesh is written as its decoded micro-triangles.
    let levels = match (displaced, args.levels) {
        (Some(d), Some(asked)) => bail!(
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
    let sub = stages.run("subdivide", || {
        let creases = subdiv::Creases::chosen(&mesh, args.crease_angle);
        subdiv::subdivide_creased(&mesh, levels, args.subdivision.scheme(), &creases)
    });
    let triangles = sub.micro_triangles(levels);
    stages.run("write", || {
        let positions: Vec<_> = sub.positions.iter().map(|&p| frame.to_world(p).as_vec3()).collect();
        mesh::ply::write_ply(&args.output, &positions, &triangles)
    })?;
    stages.say(format!(
        "{name}: {} micro-triangles, {} vertices at --levels {} -> {}",
        triangles.len(),
        sub.positions.len(),
        levels,
        args.output.display()
    ));
    stages.report();
    Ok(())
}

/// Refuses, before building, a render whose scene, with the copies the device keeps of it in
/// host memory (lavapipe's), and image would not fit in memory.
fn check_upload_memory(name: &str, sizes: &[limits::BufferSize], device: &Backend, args: &RenderArgs) -> Result<()> {
    let scene: u64 = sizes.iter().map(|b| b.bytes).sum();
    let copies = device.host_upload_bytes(scene);
    if copies == 0 {
        return Ok(());
    }
    Ok(limits::check_memory(
        scene.saturating_add(copies).saturating_add(args.image_bytes()),
        limits::available_memory()?,
        &format!("{name} uploaded to {}", device.describe()),
        "use fewer --levels, or --backend cpu",
    )?)
}

/// An error of `kind` names the input it came from (a refusal of the scene's size found as
/// it is uploaded, `Limits`; one about its contents, `Input`); others say what failed as they
/// are.
pub(crate) fn naming_input(
    name: &str,
    kind: gridrt::error::ErrorKind,
) -> impl Fn(gridrt::error::Error) -> gridrt::error::Error + '_ {
    move |e| if e.kind() == kind { e.prefixed(name) } else { e }
}

/// Refuses a render whose build and image would not fit in memory, before building.
fn check_render_memory(name: &str, mesh: &Mesh, args: &RenderArgs) -> Result<()> {
    let (builds, mode) = match args.mode {
        Mode::Grid if grid::lean_build_applies(mesh) => (limits::Builds::LeanGrids, "grid"),
        Mode::Grid => (limits::Builds::Grids, "grid"),
        Mode::Triangles => (limits::Builds::Triangles, "triangles"),
    };
    let image = args.image_bytes();
    limits::check_memory(
        image,
        limits::available_memory()?,
        &format!("a {}x{} image", args.width, args.height),
        "render a smaller image",
    )?;
    Ok(limits::check_build(
        &format!("{name} in {mode} mode"),
        mesh.triangles.len(),
        args.build.levels,
        builds,
        image,
        "use fewer --levels",
    )?)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `--shading` and the library's names (which Python takes) are one list.
    #[test]
    fn shading_names_are_the_librarys() {
        for arg in ShadingArg::value_variants() {
            let name = arg.to_possible_value().expect("a name").get_name().to_string();
            assert_eq!(name.parse::<Shading>().ok(), Some(arg.shading()), "{name}");
        }
        assert!("toon".parse::<Shading>().is_err());
    }

    /// `--backend`, `--mode` and `--subdivision` and the library's names: one list each.
    #[test]
    fn option_names_are_the_librarys() {
        fn name<T: ValueEnum>(arg: &T) -> String {
            arg.to_possible_value().expect("a name").get_name().to_string()
        }
        for arg in BackendArg::value_variants() {
            assert_eq!(name(arg).parse::<BackendChoice>().ok(), Some(arg.choice()));
        }
        for arg in Mode::value_variants() {
            assert_eq!(name(arg).parse::<Representation>().ok(), Some(arg.representation()));
        }
        for arg in SubdivisionArg::value_variants() {
            assert_eq!(name(arg).parse::<Scheme>().ok(), Some(arg.scheme()));
        }
        assert!("vulkan".parse::<BackendChoice>().is_err() && "quads".parse::<Representation>().is_err());
        assert!("catmull-clark".parse::<Scheme>().is_err());
    }
}
