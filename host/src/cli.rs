//! The `gridrt` command line: argument definitions and the commands behind them.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Result};
use clap::{Parser, Subcommand, ValueEnum};
use gridrt_shared::layout::{SHADE_EYE_LIGHT, SHADE_NORMAL, SHADE_PRIMITIVE};

use crate::bvh::Aabb;
use crate::gpu::{Gpu, NoAdapter};
use crate::mesh::{self, Mesh};
use crate::rays::RayOrder;
use crate::scene::{render_cpu, Scene};
use crate::subdiv::{self, Scheme, Subdivided};
use crate::{bench, camera, grid, image_io, stats, triangles};

#[derive(Parser, Debug)]
#[command(
    name = "gridrt",
    version,
    about = "Ray tracing of triangular grid primitives (micro-meshes) on the GPU and the CPU"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Render a mesh (or the built-in scene) to a PNG.
    Render(RenderArgs),
    /// Print the memory and build time of both representations of a mesh.
    Stats(StatsArgs),
    /// Measure memory, build time and ray throughput of grids against the baseline.
    Bench(BenchArgs),
}

#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    /// The GPU if wgpu finds an adapter, otherwise the CPU.
    Auto,
    Gpu,
    Cpu,
}

#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Grid primitives: sphere hierarchy per base triangle, BVH over grids.
    Grid,
    /// The baseline: every micro-triangle in an indexed list under an SAH BVH.
    Triangles,
}

#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SubdivisionArg {
    Loop,
    Flat,
}

#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shading {
    /// Headlight on a plain material.
    Eye,
    /// Geometric normal as colour.
    Normal,
    /// One colour per micro-triangle.
    Primitive,
}

/// What to build: shared by `render` and `stats`.
#[derive(clap::Args, Debug, Clone)]
pub struct BuildArgs {
    /// Subdivision depth L: every base triangle becomes a grid of 4^L micro-triangles.
    #[arg(long, short = 'L', default_value_t = 3, value_parser = clap::value_parser!(u32).range(0..=6))]
    pub levels: u32,
    #[arg(long, value_enum, default_value_t = SubdivisionArg::Loop)]
    pub subdivision: SubdivisionArg,
    /// Levels at the bottom of each grid's sphere hierarchy that get no spheres.
    #[arg(long, default_value_t = grid::DEFAULT_EXCLUDED_LEVELS, value_parser = clap::value_parser!(u32).range(1..=3))]
    pub excluded_levels: u32,
    /// Store sphere radii as half floats (rounded up) instead of 32-bit floats.
    #[arg(long)]
    pub half_radii: bool,
    /// Store no leaf thicknesses and cull leaves by their spheres alone (smaller, faster to
    /// build, slower to trace; see README).
    #[arg(long)]
    pub no_leaf_footprint: bool,
    /// How each grid stores its inner vertices: 16-bit codes around the grid's centre (a
    /// vertex moves by at most 2^-15 of the grid's radius; edges and corners stay exact), or
    /// 32-bit floats. Both representations get the same positions.
    #[arg(long, value_enum, default_value_t = InnerVertices::Quantized)]
    pub inner_vertices: InnerVertices,
}

#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum InnerVertices {
    Quantized,
    F32,
}

impl BuildArgs {
    pub fn grid_options(&self) -> grid::GridOptions {
        grid::GridOptions {
            excluded_levels: self.excluded_levels,
            half_radii: self.half_radii,
            leaf_footprint: !self.no_leaf_footprint,
        }
    }
}

#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// Mesh to render (.obj or .ply); the built-in scene when absent.
    pub mesh: Option<PathBuf>,
    #[arg(long, value_enum, default_value_t = Backend::Auto)]
    pub backend: Backend,
    #[arg(long, value_enum, default_value_t = Mode::Grid)]
    pub mode: Mode,
    #[command(flatten)]
    pub build: BuildArgs,
    /// Depth to render, at most L (level of detail from the same data); L when absent.
    #[arg(long)]
    pub lod: Option<u32>,
    #[arg(long, default_value_t = 960)]
    pub width: u32,
    #[arg(long, default_value_t = 720)]
    pub height: u32,
    #[arg(long, value_enum, default_value_t = Shading::Eye)]
    pub shading: Shading,
    #[arg(long, short, default_value = "render.png")]
    pub output: PathBuf,
}

#[derive(clap::Args, Debug)]
pub struct StatsArgs {
    /// Mesh to measure (.obj or .ply); the built-in scene when absent.
    pub mesh: Option<PathBuf>,
    #[command(flatten)]
    pub build: BuildArgs,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Meshes to measure (.obj or .ply).
    #[arg(required = true)]
    pub meshes: Vec<PathBuf>,
    #[command(flatten)]
    pub build: BuildArgs,
    #[arg(long, value_enum, default_value_t = Backend::Cpu)]
    pub backend: Backend,
    /// Camera views on an orbit around each mesh.
    #[arg(long, default_value_t = 4)]
    pub views: u32,
    #[arg(long, default_value_t = 480)]
    pub width: u32,
    #[arg(long, default_value_t = 360)]
    pub height: u32,
    /// Ambient-occlusion rays per primary hit.
    #[arg(long, default_value_t = 4)]
    pub ao_samples: u32,
    /// Order of the ray lists (both representations trace the same list).
    #[arg(long, value_enum, default_value_t = RayOrder::Scanline)]
    pub ray_order: RayOrder,
    /// Untimed runs before the timed ones.
    #[arg(long, default_value_t = 1)]
    pub warmup: usize,
    /// Timed runs per representation and ray kind; the median is reported.
    #[arg(long, default_value_t = 5)]
    pub repeats: usize,
    /// Builds per representation; the median is reported.
    #[arg(long, default_value_t = 11)]
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
    #[arg(long, default_value = crate::chart::DEFAULT_FONT)]
    pub font: PathBuf,
}

pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render(args) => render(&args),
        Command::Stats(args) => stats::run(&args),
        Command::Bench(args) => bench::run(&args),
    }
}

/// The mesh named on the command line, or the built-in scene; with a display name.
pub fn load(path: Option<&Path>) -> Result<(String, Mesh)> {
    match path {
        Some(p) => Ok((p.display().to_string(), mesh::load_mesh(p)?)),
        None => Ok(("default scene".to_string(), mesh::scene::default_scene())),
    }
}

/// The GPU the backend choice asks for: none for `cpu`; for `auto`, none (with a note saying
/// the CPU does the `work`) when wgpu finds no adapter at all. Any other GPU failure is an error.
pub fn open_gpu(backend: Backend, work: &str) -> Result<Option<Gpu>> {
    match backend {
        Backend::Cpu => Ok(None),
        Backend::Gpu => Gpu::new().map(Some),
        Backend::Auto => match Gpu::new() {
            Ok(gpu) => Ok(Some(gpu)),
            Err(e) if e.is::<NoAdapter>() => {
                eprintln!("note: {e}; {work} on the CPU");
                Ok(None)
            }
            Err(e) => Err(e),
        },
    }
}

pub fn subdivide(mesh: &Mesh, build: &BuildArgs) -> Subdivided {
    let scheme = match build.subdivision {
        SubdivisionArg::Loop => Scheme::Loop,
        SubdivisionArg::Flat => Scheme::Flat,
    };
    let mut sub = subdiv::subdivide(mesh, build.levels, scheme);
    if build.inner_vertices == InnerVertices::Quantized {
        sub.quantize_inner();
    }
    sub
}

fn render(args: &RenderArgs) -> Result<()> {
    if args.width == 0 || args.height == 0 {
        bail!("the image must be at least 1x1 pixels");
    }
    let lod = args.lod.unwrap_or(args.build.levels);
    if lod > args.build.levels {
        bail!("--lod {lod} is deeper than --levels {}", args.build.levels);
    }
    let (name, mesh) = load(args.mesh.as_deref())?;
    let started = Instant::now();
    let sub = subdivide(&mesh, &args.build);
    let scene = match args.mode {
        Mode::Grid => {
            let mut g = grid::build(&mesh, &sub, &args.build.grid_options())?;
            g.set_lod(lod)?;
            Scene::Grids(g)
        }
        Mode::Triangles => Scene::Triangles(triangles::build(&sub.positions, &sub.micro_triangles(lod))),
    };
    eprintln!(
        "{name}: {} base triangles, {} micro-triangles at depth {lod}, built in {:.2} s",
        mesh.triangles.len(),
        mesh.triangles.len() as u64 * 4u64.pow(lod),
        started.elapsed().as_secs_f64()
    );
    let bounds = Aabb::from_points(sub.positions.iter().copied());
    let shading = match args.shading {
        Shading::Eye => SHADE_EYE_LIGHT,
        Shading::Normal => SHADE_NORMAL,
        Shading::Primitive => SHADE_PRIMITIVE,
    };
    let frame = scene.frame(camera::frame(&bounds, args.width, args.height), shading);
    let started = Instant::now();
    let (pixels, device) = match open_gpu(args.backend, "rendering")? {
        Some(gpu) => (gpu.render(&scene, &frame)?, gpu.describe()),
        None => (render_cpu(&scene, &frame), "CPU".to_string()),
    };
    image_io::write_png(&args.output, &pixels, args.width, args.height)?;
    eprintln!(
        "rendered {}x{} on {device} in {:.3} s -> {}",
        args.width,
        args.height,
        started.elapsed().as_secs_f64(),
        args.output.display()
    );
    Ok(())
}
