//! The `gridrt` command line: argument definitions and the commands behind them.

use std::path::PathBuf;

use anyhow::Result;
use clap::{Parser, Subcommand, ValueEnum};

use gridrt::backend::BackendChoice;
use gridrt::camera::{self, FileViewpoint};
use gridrt::grid;
use gridrt::pipeline::{Representation, Shading};
use gridrt::rays::RayOrder;
use gridrt::request::build::BuildRequest;
use gridrt::request::export::{export_file, ExportRequest};
use gridrt::request::render::{render_files, Lod, RenderRequest, DEFAULT_LOD_PIXELS};
use gridrt::subdiv::Scheme;
use gridrt_shared::glam::DVec3;
use progress::Stages;

mod bake;
mod bench;
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
    /// The library's build request for these arguments.
    pub fn request(&self) -> BuildRequest {
        BuildRequest {
            levels: self.levels,
            scheme: self.subdivision.scheme(),
            crease_angle: self.crease_angle,
            excluded_levels: self.excluded_levels,
            radii: self.radii.map(RadiiArg::format),
            top: match (self.wide_top, self.compact_top, self.full_top) {
                (true, ..) => Some(grid::TopFormat::Wide),
                (_, true, _) => Some(grid::TopFormat::Compact),
                (.., true) => Some(grid::TopFormat::Full),
                _ => None,
            },
            tight_headers: self.tight_headers,
            leaf_footprint: !self.no_leaf_footprint,
            quantized: self.inner_vertices == InnerVertices::Quantized,
            compress_values: self.compress_values,
            plain_values: self.plain_values,
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
    pub lod: Option<Lod>,
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
    /// The viewpoint, in the file's units.
    pub fn viewpoint(&self) -> FileViewpoint {
        FileViewpoint {
            eye: self.eye,
            target: self.target,
            up: self.up.as_vec3(),
            fov_degrees: self.fov,
            azimuth_degrees: self.azimuth,
            elevation_degrees: self.elevation,
            distance: self.distance,
        }
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

fn parse_lod(text: &str) -> std::result::Result<Lod, String> {
    match text.trim() {
        "auto" => Ok(Lod::Auto),
        t => t
            .parse()
            .map(Lod::Depth)
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
    /// The library's request for these arguments.
    pub fn request(&self) -> RenderRequest {
        RenderRequest {
            meshes: self.meshes.clone(),
            backend: self.backend.choice(),
            representation: self.mode.representation(),
            build: self.build.request(),
            lod: self.lod,
            lod_pixels: self.lod_pixels,
            width: self.width,
            height: self.height,
            shading: self.shading.map(ShadingArg::shading),
            smooth: self.smooth,
            ao_samples: self.ao_samples,
            ao_distance: self.ao_distance,
            heat_white: self.heat_white,
            camera: self.camera.viewpoint(),
            turntable: self.turntable,
            output: self.output.clone(),
        }
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
    #[arg(long, default_value = gridrt::request::bench::chart::DEFAULT_FONT)]
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
        Command::Stats(args) => stats::run(&args, &mut stages),
        Command::Bench(args) => bench::run(&args, &mut stages),
        Command::Export(args) => export(&args, &mut stages),
        Command::Compare(args) => compare::run(&args, &mut stages),
        Command::Bake(args) => bake::run(&args, &mut stages),
    }
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

fn render(args: &RenderArgs, stages: &mut Stages) -> Result<()> {
    render_files(&args.request(), stages)?;
    stages.report();
    Ok(())
}

/// Subdivides a mesh and writes the micro-mesh, in the input's units, as binary PLY.
fn export(args: &ExportArgs, stages: &mut Stages) -> Result<()> {
    let request = ExportRequest {
        mesh: args.mesh.clone(),
        levels: args.levels,
        scheme: args.subdivision.scheme(),
        crease_angle: args.crease_angle,
        output: args.output.clone(),
    };
    let e = export_file(&request, stages)?;
    stages.say(format!(
        "{}: {} micro-triangles, {} vertices at --levels {} -> {}",
        e.name,
        e.micro_triangles,
        e.vertices,
        e.levels,
        e.output.display()
    ));
    stages.report();
    Ok(())
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
