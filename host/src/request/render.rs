//! `gridrt render`: meshes (or the built-in scene) rendered to PNG files in one call,
//! [`render_files`]. A displaced micro-mesh renders as displaced grids at its own levels
//! (the baseline traces its decoded triangles); any other mesh is subdivided as
//! [`BuildRequest`] asks.
//!
//! Guarantees: every refusal comes before the long work: options that contradict each
//! other, outputs that are not writable `.png` paths or are inputs, a view with no
//! direction, a build, image or upload that would not fit in memory or in the device's
//! bindings. A turntable's frames share one build and one upload.

use std::cell::OnceCell;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use super::build::BuildRequest;
use super::naming_input;
use crate::backend::{Backend, BackendChoice, Uploaded};
use crate::camera::{self, FileViewpoint, Viewpoint};
use crate::error::{fail, ErrorKind, Result};
use crate::heat_map::CostSummary;
use crate::input::{self, Input};
use crate::lod::LodReport;
use crate::mesh::{self, Mesh};
use crate::micromesh::DisplacedMesh;
use crate::pipeline::{BuildOptions, Image, RenderOptions, Representation, Shading};
use crate::progress::{self, Progress};
use crate::scene::Scene;
use crate::subdiv::Scheme;
use crate::{files, grid, limits, triangles};
use gridrt_shared::glam::Vec3;
use gridrt_shared::layout::Camera;

/// Micro-triangle size on screen that [`Lod::Auto`] aims at, in pixels.
pub const DEFAULT_LOD_PIXELS: f32 = 1.0;

/// The depth grids render at below their levels built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lod {
    /// Every grid at this depth.
    Depth(u32),
    /// Each grid as deep as its size on screen asks (see [`RenderRequest::lod_pixels`]).
    Auto,
}

/// What to render, and how (see `gridrt render --help`).
#[derive(Clone, Debug, PartialEq)]
pub struct RenderRequest {
    /// Meshes rendered together; the built-in scene when empty.
    pub meshes: Vec<PathBuf>,
    pub backend: BackendChoice,
    pub representation: Representation,
    pub build: BuildRequest,
    /// `None`: every level built.
    pub lod: Option<Lod>,
    /// With [`Lod::Auto`]: the size on screen, in pixels, micro-triangles are kept within.
    pub lod_pixels: f32,
    pub width: u32,
    pub height: u32,
    /// `None`: lit for the built-in scene, the headlight for meshes.
    pub shading: Option<Shading>,
    /// Smooth normals on grids.
    pub smooth: bool,
    /// Ambient-occlusion rays per pixel.
    pub ao_samples: u32,
    /// How far ambient-occlusion rays look, in the file's units; `None`: a tenth of the
    /// mesh's diagonal.
    pub ao_distance: Option<f64>,
    /// Tests per pixel the cost heat map shows white; `None`: the frame's 99th percentile.
    pub heat_white: Option<u32>,
    /// Where the camera stands, in the file's units.
    pub camera: FileViewpoint,
    /// Frames around the target, written as OUTPUT_000.png, OUTPUT_001.png, ...
    pub turntable: Option<u32>,
    pub output: PathBuf,
}

impl RenderRequest {
    /// `meshes` (the built-in scene when empty) rendered to `output` at the defaults of
    /// `gridrt render`.
    pub fn new(meshes: Vec<PathBuf>, output: impl Into<PathBuf>) -> Self {
        RenderRequest {
            meshes,
            backend: BackendChoice::Auto,
            representation: Representation::Grids,
            build: BuildRequest::default(),
            lod: None,
            lod_pixels: DEFAULT_LOD_PIXELS,
            width: 960,
            height: 720,
            shading: None,
            smooth: false,
            ao_samples: 16,
            ao_distance: None,
            heat_white: None,
            camera: FileViewpoint::default(),
            turntable: None,
            output: output.into(),
        }
    }
}

/// What a render made.
#[derive(Clone, Debug, PartialEq)]
pub struct Rendered {
    /// The files written, one per frame.
    pub outputs: Vec<PathBuf>,
    /// The device that rendered them.
    pub device: String,
}

/// Renders the request's meshes to its output files, reporting stages (load, device, build,
/// render, write), notes, warnings and a line per frame written through `progress`.
pub fn render_files(request: &RenderRequest, progress: &mut dyn Progress) -> Result<Rendered> {
    let outputs = request.checked_outputs()?;
    let paths: Vec<&Path> = request.meshes.iter().map(PathBuf::as_path).collect();
    let input = super::open_for_build(&paths, &request.build, progress)?;
    let plan = Plan::of(request, &input)?;
    if input.displaced.is_none() && paths.len() == 1 {
        suggest_bake(&input.name, &input.mesh, &plan.request.build, progress);
    }
    let target = plan.checked_view(&input)?;
    let backend = plan.checked_backend(&input, progress)?;
    let scene = plan.build(&input, progress)?;
    progress.say(&plan.scene_line(&input, &scene));
    let frames = Frames {
        plan: &plan,
        input: &input,
        backend: &backend,
        scene: &scene,
        target,
        render: plan.request.render_options(&input.frame),
        uploaded: OnceCell::new(),
    };
    for (k, output) in outputs.iter().enumerate() {
        frames.render(k as u32, output, progress)?;
    }
    Ok(Rendered {
        outputs,
        device: backend.describe(),
    })
}

impl RenderRequest {
    /// Refuses, before any work, options that contradict each other, and returns the PNG
    /// files the render will write (one per turntable frame), each a writable `.png` path
    /// and none of them an input.
    fn checked_outputs(&self) -> Result<Vec<PathBuf>> {
        let lod = self.build_options().lod.unwrap_or(self.build.levels);
        // A displaced micro-mesh has a level of its own, checked once it is loaded.
        let displaced_file = self.meshes.iter().any(|m| mesh::is_gltf(m));
        if lod > self.build.levels && !displaced_file {
            fail!(Options, "--lod {lod} is deeper than --levels {}", self.build.levels);
        }
        self.check_mode()?;
        let frames = self.turntable.unwrap_or(1);
        let outputs: Vec<PathBuf> = (0..frames)
            .map(|k| frame_path(&self.output, k, self.turntable))
            .collect();
        let paths: Vec<&Path> = self.meshes.iter().map(PathBuf::as_path).collect();
        let inputs = input::files_read(&paths);
        for output in &outputs {
            files::check_png_path(output)?;
            files::check_not_input(output, &inputs)?;
        }
        Ok(outputs)
    }

    /// Host bytes of the image being rendered and written.
    fn image_bytes(&self) -> u64 {
        (self.width as u64 * self.height as u64).saturating_mul(limits::IMAGE_BYTES_PER_PIXEL)
    }

    /// This request for a displaced micro-mesh's decoded micro-triangles: built as they are,
    /// at one depth.
    fn as_decoded(&self) -> RenderRequest {
        RenderRequest {
            build: self.build.as_decoded(),
            lod: None,
            ..self.clone()
        }
    }

    /// This request for a displaced micro-mesh of `level` as displaced grids: its own level
    /// is built, and a depth to render must not be deeper.
    fn as_displaced(&self, level: u32) -> Result<RenderRequest> {
        if let Some(Lod::Depth(depth)) = self.lod {
            if depth > level {
                fail!(Options, "--lod {depth} is deeper than the micro-mesh's level ({level})");
            }
        }
        Ok(RenderRequest {
            build: self.build.as_displaced(level),
            ..self.clone()
        })
    }

    /// The build options of this request.
    pub fn build_options(&self) -> BuildOptions {
        BuildOptions {
            representation: self.representation,
            grid: self.build.grid_build(),
            lod: match self.lod {
                Some(Lod::Depth(depth)) => Some(depth),
                Some(Lod::Auto) | None => None,
            },
        }
    }

    /// The shading asked for, or the default: lit for the built-in scene (a picture worth
    /// showing, cheap at its size), the headlight for meshes (one ray per pixel, whatever
    /// their size).
    fn shading(&self) -> Shading {
        match (self.shading, self.meshes.is_empty()) {
            (Some(shading), _) => shading,
            (None, true) => Shading::Lit,
            (None, false) => Shading::EyeLight,
        }
    }

    /// The render options of this request; lengths are in the file's units, `frame` takes
    /// them to the mesh's local frame.
    pub fn render_options(&self, frame: &mesh::frame::LocalFrame) -> RenderOptions {
        RenderOptions {
            shading: self.shading(),
            ao_samples: self.ao_samples,
            ao_distance: self.ao_distance.map(|d| (d * frame.scale) as f32),
            heat_white: self.heat_white,
            lod_pixels: (self.lod == Some(Lod::Auto)).then_some(self.lod_pixels),
            smooth_normals: self.smooth,
        }
    }

    /// Refuses, before any work, what needs grids asked of the baseline.
    fn check_mode(&self) -> Result<()> {
        if self.representation == Representation::Triangles {
            let one_depth = "the baseline has one depth, fixed when it is built";
            let needs_grids = [
                (self.lod == Some(Lod::Auto), "--lod auto", one_depth),
                (self.shading == Some(Shading::Level), "--shading level", one_depth),
                (
                    self.smooth,
                    "--smooth",
                    "the baseline's triangle list has no neighbours to take normals from",
                ),
            ];
            if let Some((_, flag, why)) = needs_grids.iter().find(|(asked, ..)| *asked) {
                fail!(Options, "{flag} needs grids (--mode grid): {why}");
            }
        }
        Ok(())
    }
}

/// What a loaded input is built as: the request as it applies to it, its build options,
/// the depth rendered, the displaced micro-mesh when it becomes displaced grids, and the
/// viewpoint in the mesh's local frame.
struct Plan<'a> {
    request: RenderRequest,
    options: BuildOptions,
    lod: u32,
    displaced_grids: Option<&'a DisplacedMesh>,
    viewpoint: Viewpoint,
}

impl<'a> Plan<'a> {
    /// A displaced micro-mesh becomes displaced grids; for the baseline, its decoded
    /// micro-triangles are traced as they are.
    fn of(request: &RenderRequest, input: &'a Input) -> Result<Plan<'a>> {
        let grids = request.representation == Representation::Grids;
        let displaced_grids = input.displaced_grids().filter(|_| grids);
        let (request, lod) = match (displaced_grids, input.displaced) {
            (Some(m), _) => {
                let request = request.as_displaced(m.deepest_level().unwrap_or(0))?;
                let lod = request.build_options().lod.unwrap_or(request.build.levels);
                (request, lod)
            }
            (None, Some(_)) => (request.as_decoded(), 0),
            (None, None) => {
                let lod = request.build_options().lod.unwrap_or(request.build.levels);
                if lod > request.build.levels {
                    fail!(Options, "--lod {lod} is deeper than --levels {}", request.build.levels);
                }
                (request.clone(), lod)
            }
        };
        Ok(Plan {
            options: request.build_options(),
            viewpoint: request.camera.local(&input.frame),
            request,
            lod,
            displaced_grids,
        })
    }

    /// Refuses, before the build, a render whose build and image would not fit in memory,
    /// or whose view has no direction (bounds only matter for defaults); returns the first
    /// frame's target, which a turntable's later frames turn about.
    fn checked_view(&self, input: &Input) -> Result<Vec3> {
        let (name, request) = (&input.name, &self.request);
        match self.displaced_grids {
            Some(m) => check_render_memory(name, &m.base_mesh(), request)?,
            None => check_render_memory(name, &input.mesh, request)?,
        }
        let placed = camera::placement(&input.mesh.positions, &self.viewpoint, request.width, request.height)
            .map_err(naming_input(name, ErrorKind::Input))?;
        Ok(placed.target)
    }

    /// The backend, opened once the scene's least sizes are known, and checked to bind the
    /// scene's buffers and hold its uploads.
    fn checked_backend(&self, input: &Input, progress: &mut dyn Progress) -> Result<Backend> {
        let (name, request) = (&input.name, &self.request);
        let sizes = self.least_buffer_sizes(input)?;
        let backend = progress::run(progress, "device", || Backend::open(request.backend))?;
        super::note_fallback(&backend, "rendering", progress);
        let displaced = self.displaced_grids.is_some();
        backend.check_fits(&sizes, displaced).map_err(|e| e.prefixed(name))?;
        check_upload_memory(name, &sizes, &backend, request)?;
        Ok(backend)
    }

    /// The least sizes of the scene's buffers, from the mesh's counts, before it is built.
    fn least_buffer_sizes(&self, input: &Input) -> Result<Vec<limits::BufferSize>> {
        let (name, build) = (&input.name, &self.request.build);
        Ok(match (self.request.representation, self.displaced_grids) {
            (Representation::Grids, Some(m)) => {
                grid::displaced::least_buffer_sizes(m, &build.grid_options()).map_err(|e| e.prefixed(name))?
            }
            (Representation::Grids, None) => build.check_grid_limits(name, &input.mesh)?,
            (Representation::Triangles, _) => triangles::least_buffer_sizes(
                input.mesh.positions.len() as u64,
                limits::micro_triangles(input.mesh.triangles.len(), self.lod),
            ),
        })
    }

    /// The scene traced: displaced grids, grids (a bar over the base triangles) or the
    /// baseline's triangles.
    fn build(&self, input: &Input, progress: &mut dyn Progress) -> Result<Scene> {
        let (mesh, options) = (&input.mesh, &self.options);
        match (self.request.representation, self.displaced_grids) {
            (Representation::Grids, Some(m)) => progress::run(progress, "build", || Scene::build_displaced(m, options)),
            (Representation::Grids, None) => {
                progress::run_counted(progress, "build", mesh.triangles.len() as u64, |advance| {
                    Scene::build_reporting(mesh, options, &|n| advance(n as u64))
                })
            }
            (Representation::Triangles, _) => progress::run(progress, "build", || Scene::build(mesh, options)),
        }
    }

    /// The line that says what the scene holds: its triangles at the depth rendered and bytes.
    fn scene_line(&self, input: &Input, scene: &Scene) -> String {
        let base_triangles = self
            .displaced_grids
            .map_or(input.mesh.triangles.len(), |m| m.triangles.len());
        // A displaced micro-mesh's triangles each have their own level.
        let micro_at = |depth: u32| match self.displaced_grids {
            Some(m) => m.micro_triangles_at(depth),
            None => limits::micro_triangles(base_triangles, depth),
        };
        let micro = micro_at(self.lod);
        // Grids hold every level built, whatever depth renders.
        let stored = match scene {
            Scene::Grids(_) => micro_at(self.request.build.levels),
            Scene::Triangles(_) => micro,
        };
        let up_to = if self.request.lod == Some(Lod::Auto) {
            "up to "
        } else {
            ""
        };
        format!(
            "{}: {} base triangles, {micro} micro-triangles at depth {up_to}{}, {} ({:.2} B per micro-triangle)",
            input.name,
            base_triangles,
            self.lod,
            limits::human(scene.memory() as u64),
            scene.memory() as f64 / stored as f64
        )
    }
}

/// The frames of one render: one scene on one backend, uploaded once, by the first frame
/// that needs it, rendered with one set of options about the first frame's `target`.
struct Frames<'a> {
    plan: &'a Plan<'a>,
    input: &'a Input,
    backend: &'a Backend,
    scene: &'a Scene,
    target: Vec3,
    render: RenderOptions,
    uploaded: OnceCell<Uploaded>,
}

impl Frames<'_> {
    /// Frame `k` rendered and written to `output`. A turntable turns the orbit's azimuth by
    /// equal steps, the first frame the plain view; the later frames turn about the first
    /// one's target, so the mesh does not wander.
    fn render(&self, k: u32, output: &Path, progress: &mut dyn Progress) -> Result<()> {
        let (request, viewpoint, render) = (&self.plan.request, self.plan.viewpoint, &self.render);
        let (width, height) = (request.width, request.height);
        let frames = request.turntable.unwrap_or(1);
        let turned = Viewpoint {
            azimuth_degrees: viewpoint.azimuth_degrees + 360.0 * k as f32 / frames as f32,
            target: viewpoint.target.or((k > 0).then_some(self.target)),
            ..viewpoint
        };
        let view = camera::view_of(&self.input.mesh.positions, &turned, width, height)?;
        if let (Scene::Grids(grids), Some(_)) = (self.scene, render.lod_pixels) {
            let report = LodReport::measure(grids, &render.frame(self.scene, &view));
            progress.say(&describe_lod(&report, request.lod_pixels));
        }
        let image = self.image(&view, render, progress)?;
        progress::run(progress, "write", || image.write_png(output))?;
        let device = self.backend.describe();
        progress.say(&format!(
            "rendered {width}x{height} on {device} -> {}",
            output.display()
        ));
        Ok(())
    }

    /// One frame: the cost heat map (counted on the CPU), or the image on the backend, the
    /// scene uploaded to it the first time.
    fn image(&self, view: &Camera, render: &RenderOptions, progress: &mut dyn Progress) -> Result<Image> {
        let (backend, scene) = (self.backend, self.scene);
        let limits = naming_input(&self.input.name, ErrorKind::Limits);
        if render.shading == Shading::Cost {
            let costs = progress::run(progress, "render", || {
                backend.render_costs(scene, view, render).map_err(&limits)
            })?;
            let summary = costs.summary();
            let white = summary.white(render.heat_white);
            progress.say(&describe_costs(&summary, white, render.heat_white.is_none()));
            return Ok(costs.heat_map(white));
        }
        // Ambient occlusion renders in passes: a bar over its samples.
        let samples = match render.shading {
            Shading::AmbientOcclusion | Shading::Lit => render.ao_samples as u64,
            _ => 0,
        };
        progress::run_counted(progress, "render", samples, |advance| {
            let uploaded = match self.uploaded.get() {
                Some(u) => u,
                None => {
                    let u = backend.upload(scene).map_err(&limits)?;
                    self.uploaded.get_or_init(|| u)
                }
            };
            let seen = AtomicU64::new(0);
            let done = |done: u32| advance((done as u64).saturating_sub(seen.swap(done as u64, Ordering::Relaxed)));
            backend
                .render_uploaded(scene, uploaded, view, render, &done)
                .map_err(&limits)
        })
    }
}

/// Triangles from which a mesh is taken for a detailed one (a scan, a sculpt, a CAD
/// tessellation) rather than a control mesh to subdivide.
const DENSE_TRIANGLES: usize = 10_000;

/// Points a user who subdivides a dense mesh to `bake`: Loop subdivision rounds such a mesh
/// into another shape, and a displaced micro-mesh keeps its own in far less memory.
fn suggest_bake(name: &str, mesh: &Mesh, build: &BuildRequest, progress: &mut dyn Progress) {
    if mesh.triangles.len() >= DENSE_TRIANGLES && build.levels > 0 && build.scheme == Scheme::Loop {
        progress.note(&format!(
            "{name}: {} triangles is a detailed mesh, not a control mesh: Loop subdivision rounds its edges and \
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
pub fn frame_path(output: &Path, k: u32, turntable: Option<u32>) -> PathBuf {
    let Some(frames) = turntable else {
        return output.to_path_buf();
    };
    let digits = (frames - 1).max(1).ilog10() as usize + 1;
    let stem = output.file_stem().unwrap_or_default().to_string_lossy();
    output.with_file_name(format!("{stem}_{k:0width$}.png", width = digits.max(3)))
}

/// Refuses, before building, a render whose scene, with the copies the device keeps of it in
/// host memory (lavapipe's), and image would not fit in memory.
fn check_upload_memory(
    name: &str,
    sizes: &[limits::BufferSize],
    device: &Backend,
    request: &RenderRequest,
) -> Result<()> {
    let scene: u64 = sizes.iter().map(|b| b.bytes).sum();
    let copies = device.host_upload_bytes(scene);
    if copies == 0 {
        return Ok(());
    }
    limits::check_memory(
        scene.saturating_add(copies).saturating_add(request.image_bytes()),
        limits::available_memory()?,
        &format!("{name} uploaded to {}", device.describe()),
        "use fewer --levels, or --backend cpu",
    )
}

/// Refuses a render whose build and image would not fit in memory, before building.
fn check_render_memory(name: &str, mesh: &Mesh, request: &RenderRequest) -> Result<()> {
    let (builds, mode) = match request.representation {
        Representation::Grids if grid::lean_build_applies(mesh) => (limits::Builds::LeanGrids, "grid"),
        Representation::Grids => (limits::Builds::Grids, "grid"),
        Representation::Triangles => (limits::Builds::Triangles, "triangles"),
    };
    let image = request.image_bytes();
    limits::check_memory(
        image,
        limits::available_memory()?,
        &format!("a {}x{} image", request.width, request.height),
        "render a smaller image",
    )?;
    limits::check_build(
        &format!("{name} in {mode} mode"),
        mesh.triangles.len(),
        request.build.levels,
        builds,
        image,
        "use fewer --levels",
    )
}
