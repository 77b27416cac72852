//! `gridrt bench`: the published Table 1 measured here, on the same rays for both
//! representations, in one call: [`bench_files`]. Memory, build time and ray throughput of
//! grids against the baseline, per mesh, and with a reference the mesh a micro-mesh was
//! baked from traced on the same rays.
//!
//! Guarantees: every input is loaded, and every output checked (writable, none of them an
//! input), before the first mesh is measured; both representations are checked to fit in
//! memory and on the device before the backend traces anything.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;

use super::build::BuildRequest;
use super::naming_input;
use super::stats::{self, Stats};
use crate::backend::cpu::trace_cpu;
use crate::backend::{Backend, BackendChoice, TimedTrace};
use crate::bvh::Aabb;
use crate::error::{error, fail, Result};
use crate::input::Input;
use crate::mesh::{Mesh, WorldMesh};
use crate::progress::{self, Progress};
use crate::rays::{ao_rays, primary_rays, reorder, RayOrder};
use crate::scene::Scene;
use crate::{files, limits, triangles};
use chart::{write_chart, ChartRow};
use gridrt_shared::layout::{HitRecord, RayRecord};

pub mod chart;

/// What to measure, and how (see `gridrt bench --help`).
#[derive(Clone, Debug, PartialEq)]
pub struct BenchRequest {
    /// Meshes to measure, one row each.
    pub meshes: Vec<PathBuf>,
    pub build: BuildRequest,
    pub backend: BackendChoice,
    /// Camera views on an orbit around each mesh.
    pub views: u32,
    pub width: u32,
    pub height: u32,
    /// Ambient-occlusion rays per primary hit.
    pub ao_samples: u32,
    /// Order of the ray lists (both representations trace the same list).
    pub ray_order: RayOrder,
    /// Untimed runs before the timed ones.
    pub warmup: usize,
    /// Timed runs per representation and ray kind; the median is reported.
    pub repeats: usize,
    /// Builds per representation at most (fewer once they have taken a few seconds).
    pub build_repeats: usize,
    /// The mesh a micro-mesh was baked from, traced on the same rays.
    pub reference: Option<PathBuf>,
    /// Where the results go besides the answer: JSON, the markdown table, a PNG chart.
    pub outputs: BenchOutputs,
}

/// The files a bench writes besides returning its results.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct BenchOutputs {
    pub json: Option<PathBuf>,
    pub markdown: Option<PathBuf>,
    pub chart: Option<PathBuf>,
    /// TrueType font for the chart's labels.
    pub font: PathBuf,
}

impl BenchRequest {
    /// `meshes` measured at the defaults of `gridrt bench`, writing nothing.
    pub fn new(meshes: Vec<PathBuf>) -> Self {
        BenchRequest {
            meshes,
            build: BuildRequest::default(),
            backend: BackendChoice::Cpu,
            views: 4,
            width: 480,
            height: 360,
            ao_samples: 4,
            ray_order: RayOrder::Scanline,
            warmup: 1,
            repeats: 5,
            build_repeats: 11,
            reference: None,
            outputs: BenchOutputs {
                font: chart::DEFAULT_FONT.into(),
                ..BenchOutputs::default()
            },
        }
    }
}

/// Measures every mesh of the request (a row each), writes the outputs it names, and
/// returns the rows.
pub fn bench_files(request: &BenchRequest, progress: &mut dyn Progress) -> Result<Vec<BenchResult>> {
    let (meshes, reference) = load_inputs(request, progress)?;
    let device = open_checked(request, &meshes, progress)?;
    let results = (meshes.iter())
        .map(|input| measure_mesh(request, input, reference.as_ref(), &device, progress))
        .collect::<Result<Vec<_>>>()?;
    write_outputs(&request.outputs, &results)?;
    Ok(results)
}

#[derive(Serialize, Debug, Clone, Copy, Default)]
pub struct PerKind<T = f64> {
    pub primary: T,
    pub ao: T,
}

#[derive(Serialize, Debug, Clone, Copy, Default)]
pub struct PerRepresentation {
    pub grid: PerKind,
    pub triangles: PerKind,
}

/// One mesh's row: the keys of `gridrt stats` and the ray tracing figures.
#[derive(Serialize, Debug, Clone)]
pub struct BenchResult {
    #[serde(flatten)]
    pub stats: Stats,
    pub backend: String,
    pub device: String,
    pub timing: String,
    pub views: u32,
    pub width: u32,
    pub height: u32,
    pub ray_order: RayOrder,
    pub rays: PerKind,
    pub mrays_per_s: PerRepresentation,
    /// `(max - min) / median` of the repetitions, per representation and ray kind.
    pub spread: PerRepresentation,
    pub rt_impact_percent: PerKind,
    /// Fraction of rays whose closest hit (micro-triangle) is the same in both.
    pub hit_agreement: PerKind,
    /// With `--reference`: the mesh the micro-mesh was baked from, as the baseline builds it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference: Option<ReferenceResult>,
}

/// The reference mesh under the baseline's SAH BVH, on the same rays, and how far the
/// micro-mesh lies from it.
#[derive(Serialize, Debug, Clone)]
pub struct ReferenceResult {
    pub mesh: String,
    pub triangles: usize,
    pub bytes: usize,
    pub build_seconds: f64,
    pub mrays_per_s: PerKind,
    /// Symmetric distance between the reference and the micro-mesh's decoded triangles, as
    /// fractions of the reference's bounding-box diagonal.
    pub distance: crate::surface_distance::DistanceSummary,
}

/// Host bytes per traced ray: its record, its hit, and the copies the ray lists and
/// their reordering hold.
const RAY_BYTES: u64 = 2 * std::mem::size_of::<RayRecord>() as u64 + 2 * std::mem::size_of::<HitRecord>() as u64;

/// Every file the run will write, checked before the first mesh is measured.
fn check_outputs(request: &BenchRequest) -> Result<()> {
    let asked = &request.outputs;
    if let Some(json) = &asked.json {
        files::check_output(json, "json")?;
    }
    if let Some(markdown) = &asked.markdown {
        files::check_output(markdown, "md")?;
    }
    let outputs: Vec<&Path> = [&asked.json, &asked.markdown, &asked.chart]
        .into_iter()
        .flatten()
        .map(|p| p.as_path())
        .collect();
    files::check_distinct(&outputs)?;
    let mut read: Vec<&Path> = request.meshes.iter().map(|p| p.as_path()).collect();
    read.extend(request.reference.as_deref());
    let mut inputs = crate::input::files_read(&read);
    inputs.push(asked.font.clone());
    for output in &outputs {
        files::check_not_input(output, &inputs)?;
    }
    if let Some(chart) = &asked.chart {
        files::check_png_path(chart)?;
        if let Err(e) = std::fs::metadata(&asked.font) {
            fail!(
                Input,
                "{}: cannot read the chart's font: {}",
                asked.font.display(),
                files::io_reason(&e)
            );
        }
    }
    Ok(())
}

/// Median and relative spread of a set of timings.
fn summarize(mut seconds: Vec<f64>) -> (f64, f64) {
    seconds.sort_by(f64::total_cmp);
    let median = seconds[seconds.len() / 2];
    let spread = (seconds[seconds.len() - 1] - seconds[0]) / median.max(1e-12);
    (median, spread)
}

fn agreement(a: &Scene, ha: &[HitRecord], b: &Scene, hb: &[HitRecord]) -> f64 {
    let same = ha
        .iter()
        .zip(hb)
        .filter(|(x, y)| {
            let (hx, hy) = (
                x.prim != gridrt_shared::layout::NO_HIT,
                y.prim != gridrt_shared::layout::NO_HIT,
            );
            // The same numbering, or the same corners (grids of mixed levels number their
            // micro-triangles apart from their decoded triangles).
            let same = |x: u32, y: u32| {
                let corners = |s: &Scene, p: u32| {
                    let mut bits = s.triangle(p).map(|v| v.to_array().map(f32::to_bits));
                    bits.sort();
                    bits
                };
                a.original_triangle(x) == b.original_triangle(y) || corners(a, x) == corners(b, y)
            };
            hx == hy && (!hx || same(x.prim, y.prim))
        })
        .count();
    same as f64 / ha.len().max(1) as f64
}

/// Refuses, before building, a mesh whose representations the device cannot bind, or whose
/// uploads it would keep copies of in host memory (lavapipe) beyond what is free.
fn check_device(name: &str, mesh: &Mesh, device: &Backend, build: &BuildRequest, ray_bytes: u64) -> Result<()> {
    let micro = limits::micro_triangles(mesh.triangles.len(), build.levels);
    let baseline = triangles::least_buffer_sizes(mesh.positions.len() as u64, micro);
    let mut largest = 0;
    for sizes in [build.check_grid_limits(name, mesh)?, baseline] {
        // Displaced grids' sizes are known once built: their upload checks that they bind whole.
        device.check_fits(&sizes, false).map_err(|e| e.prefixed(name))?;
        largest = largest.max(sizes.iter().map(|b| b.bytes).sum::<u64>());
    }
    // One representation is uploaded at a time, while both are alive on the host.
    match device.host_upload_bytes(largest) {
        0 => Ok(()),
        copies => Ok(limits::check_build(
            &format!(
                "measuring {name} on {}, which keeps its uploads in host memory,",
                device.describe()
            ),
            mesh.triangles.len(),
            build.levels,
            limits::Builds::Both,
            ray_bytes.saturating_add(copies),
            "use fewer --levels, or --backend cpu",
        )?),
    }
}

/// Every mesh, loaded before the first is measured (a bad file is reported at once), and the
/// reference, checked against the request.
fn load_inputs(request: &BenchRequest, progress: &mut dyn Progress) -> Result<(Vec<Input>, Option<WorldMesh>)> {
    if request.meshes.is_empty() {
        fail!(Options, "name at least one mesh to benchmark");
    }
    check_outputs(request)?;
    let meshes = (request.meshes.iter())
        .map(|path| super::open_for_build(&[path.as_path()], &request.build, progress))
        .collect::<Result<Vec<_>>>()?;
    if let Some(input) = (meshes.iter()).find(|m| m.displaced.is_some() && m.displaced_grids().is_none()) {
        fail!(Input, "{}: a displaced micro-mesh without base triangles", input.name);
    }
    if request.reference.is_some() && meshes.len() != 1 {
        fail!(
            Options,
            "--reference compares one micro-mesh with the mesh it was baked from: name one mesh"
        );
    }
    let reference = match &request.reference {
        Some(path) => Some(crate::input::load_world(path)?.0),
        None => None,
    };
    Ok((meshes, reference))
}

/// Host bytes the rays of one mesh take.
fn ray_bytes(request: &BenchRequest) -> u64 {
    let rays_per_view = request.width as u64 * request.height as u64 * (1 + request.ao_samples as u64);
    (request.views as u64 * rays_per_view).saturating_mul(RAY_BYTES)
}

/// The backend, once every mesh is known to fit in memory and on it.
fn open_checked(request: &BenchRequest, meshes: &[Input], progress: &mut dyn Progress) -> Result<Backend> {
    let ray_bytes = ray_bytes(request);
    for input in meshes {
        stats::check_work(&input.name, &input.mesh, &request.build.for_input(input), ray_bytes)?;
    }
    let device = super::open_backend(request.backend, "benchmarking", progress)?;
    for input in meshes {
        let build = request.build.for_input(input);
        check_device(&input.name, &input.mesh, &device, &build, ray_bytes)?;
    }
    Ok(device)
}

/// One mesh's row: both representations built and measured, then traced on the same rays.
fn measure_mesh(
    request: &BenchRequest,
    input: &Input,
    reference: Option<&WorldMesh>,
    device: &Backend,
    progress: &mut dyn Progress,
) -> Result<BenchResult> {
    let (stats, grids, tris, bounds) = build_both(request, input, progress)?;
    let (primary, ao) = progress::run(progress, "rays", || bench_rays(request, &tris, &bounds));
    // The reference in this mesh's frame, under the baseline's BVH.
    let reference = reference.map(|world| {
        let mesh = world.in_frame(&input.frame);
        let (seconds, scene) = stats::median_time(request.build_repeats, || {
            triangles::build(&mesh.positions, &mesh.triangles)
        });
        (Scene::Triangles(scene), mesh, seconds)
    });
    let contenders = Contenders {
        grids: &grids,
        tris: &tris,
        reference: reference.as_ref().map(|(scene, ..)| scene),
    };
    let mut timed = Timed::default();
    for (is_primary, rays) in [(true, &primary), (false, &ao)] {
        progress::run(progress, "trace", || {
            time_kind(request, &input.name, device, &contenders, rays, is_primary, &mut timed)
        })?;
    }
    let reference = reference.map(|(scene, mesh, seconds)| {
        progress::run(progress, "distance", || {
            reference_result(request, (&scene, &mesh, seconds), &input.mesh, &timed)
        })
    });
    Ok(row(request, device, stats, (&primary, &ao), timed, reference))
}

/// The reference's figures, and its distance from the micro-mesh's decoded triangles.
fn reference_result(
    request: &BenchRequest,
    (scene, reference, seconds): (&Scene, &Mesh, f64),
    decoded: &Mesh,
    timed: &Timed,
) -> ReferenceResult {
    let d = crate::surface_distance::measure(reference, decoded, &Default::default());
    ReferenceResult {
        mesh: (request.reference.as_ref()).map_or(String::new(), |p| p.display().to_string()),
        triangles: reference.triangles.len(),
        bytes: scene.memory(),
        build_seconds: seconds,
        mrays_per_s: timed.reference,
        distance: d.symmetric.relative_to(d.a_diagonal),
    }
}

/// One mesh's row from what was measured.
fn row(
    request: &BenchRequest,
    device: &Backend,
    stats: Stats,
    (primary, ao): (&[RayRecord], &[RayRecord]),
    timed: Timed,
    reference: Option<ReferenceResult>,
) -> BenchResult {
    let impact = |g: f64, t: f64| (t / g - 1.0) * 100.0;
    let mrays = timed.mrays;
    BenchResult {
        stats,
        backend: device.kind().to_string(),
        device: device.describe(),
        timing: device.timing().to_string(),
        views: request.views,
        width: request.width,
        height: request.height,
        ray_order: request.ray_order,
        rays: PerKind {
            primary: primary.len() as f64,
            ao: ao.len() as f64,
        },
        rt_impact_percent: PerKind {
            primary: impact(mrays.grid.primary, mrays.triangles.primary),
            ao: impact(mrays.grid.ao, mrays.triangles.ao),
        },
        mrays_per_s: mrays,
        spread: timed.spread,
        hit_agreement: timed.agree,
        reference,
    }
}

/// Both representations of one mesh, measured as `gridrt stats` measures them, and the box
/// their rays are aimed at. A displaced micro-mesh: displaced grids against its decoded
/// micro-triangles.
fn build_both(
    request: &BenchRequest,
    input: &Input,
    progress: &mut dyn Progress,
) -> Result<(Stats, Scene, Scene, Aabb)> {
    let Input { name, mesh, .. } = input;
    let (measured, bounds) = match input.displaced_grids() {
        Some(micromesh) => {
            let measured =
                stats::measure_displaced(name, (micromesh, mesh), &request.build, request.build_repeats, progress)?;
            (measured, Aabb::from_points(mesh.positions.iter().copied()))
        }
        None => {
            let sub = progress::run(progress, "subdivide", || request.build.subdivide(mesh));
            let measured = stats::measure(name, mesh, &sub, &request.build, request.build_repeats, progress)?;
            (measured, Aabb::from_points(sub.positions.iter().copied()))
        }
    };
    let (stats, grids, tris) = measured;
    Ok((stats, Scene::Grids(grids), Scene::Triangles(tris), bounds))
}

/// The primary rays of the orbit views and their AO rays, in the order asked for. AO rays
/// start from the baseline's hits (the same as the grids' up to ties).
fn bench_rays(request: &BenchRequest, tris: &Scene, bounds: &Aabb) -> (Vec<RayRecord>, Vec<RayRecord>) {
    let mut primary = primary_rays(bounds, request.views, request.width, request.height);
    let first_hits = trace_cpu(tris, &primary);
    let mut ao = ao_rays(&primary, &first_hits, request.ao_samples, bounds, |p| tris.normal(p));
    reorder(
        request.ray_order,
        &mut primary,
        &mut ao,
        request.views,
        request.width,
        request.height,
        bounds,
    );
    (primary, ao)
}

/// The scenes timed against each other: the grids, the baseline, and the reference if any.
struct Contenders<'a> {
    grids: &'a Scene,
    tris: &'a Scene,
    reference: Option<&'a Scene>,
}

/// What the timed runs found, per ray kind.
#[derive(Default)]
struct Timed {
    mrays: PerRepresentation,
    spread: PerRepresentation,
    agree: PerKind,
    reference: PerKind,
}

impl<T> PerKind<T> {
    fn kind_mut(&mut self, primary: bool) -> &mut T {
        match primary {
            true => &mut self.primary,
            false => &mut self.ao,
        }
    }
}

/// Times one kind of rays through the contenders, which take turns at every repetition.
fn time_kind(
    request: &BenchRequest,
    name: &str,
    device: &Backend,
    contenders: &Contenders,
    rays: &[RayRecord],
    primary: bool,
    timed: &mut Timed,
) -> Result<()> {
    let mut scenes = vec![contenders.grids, contenders.tris];
    scenes.extend(contenders.reference);
    let mut traces = (device.time_traces(&scenes, rays, request.warmup, request.repeats))
        .map_err(naming_input(name, crate::error::ErrorKind::Limits))?;
    let rate = |t: &TimedTrace| {
        let (median, rel) = summarize(t.seconds.clone());
        (rays.len() as f64 / median / 1e6, rel)
    };
    if let Some(t) = traces.get(2) {
        *timed.reference.kind_mut(primary) = rate(t).0;
    }
    traces.truncate(2);
    let [grid, triangles]: [TimedTrace; 2] = traces.try_into().map_err(|_| error!(Gpu, "one timing per scene"))?;
    (
        *timed.mrays.grid.kind_mut(primary),
        *timed.spread.grid.kind_mut(primary),
    ) = rate(&grid);
    (
        *timed.mrays.triangles.kind_mut(primary),
        *timed.spread.triangles.kind_mut(primary),
    ) = rate(&triangles);
    *timed.agree.kind_mut(primary) = agreement(contenders.grids, &grid.hits, contenders.tris, &triangles.hits);
    Ok(())
}

/// The JSON, the chart and the table, where asked.
fn write_outputs(asked: &BenchOutputs, results: &[BenchResult]) -> Result<()> {
    if let Some(path) = &asked.json {
        let json = serde_json::to_string_pretty(&results).map_err(|e| error!(Output, "{}: {e}", path.display()))?;
        std::fs::write(path, json + "\n").map_err(|e| cannot_write(path, e))?;
    }
    if let Some(path) = &asked.chart {
        let rows: Vec<ChartRow> = (results.iter())
            .map(|r| ChartRow {
                mesh: &r.stats.mesh,
                compression_gain: r.stats.compression_gain,
                construction_gain: r.stats.construction_gain,
                rt_impact_primary: r.rt_impact_percent.primary,
                rt_impact_ao: r.rt_impact_percent.ao,
            })
            .collect();
        let backend = results.first().map_or("", |r| r.backend.as_str());
        write_chart(&rows, backend, path, &asked.font)?;
    }
    if let Some(path) = &asked.markdown {
        std::fs::write(path, markdown(results)).map_err(|e| cannot_write(path, e))?;
    }
    Ok(())
}

/// A file that could not be written, in one line.
fn cannot_write(path: &Path, e: std::io::Error) -> crate::error::Error {
    error!(Output, "{}: cannot write: {e}", path.display())
}

fn file_name(path: &str) -> String {
    (std::path::Path::new(path).file_name())
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.to_string())
}

/// The published Table 1 columns (RT impact, compression gain, construction gain) plus
/// bytes per triangle and throughput.
pub fn markdown(results: &[BenchResult]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| mesh | micro-triangles | RT impact primary | RT impact AO | compression gain | construction gain | \
         grid B/tri | triangles B/tri | grid Mrays/s (primary / AO) | triangles Mrays/s (primary / AO) |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in results {
        let name = file_name(&r.stats.mesh);
        let _ = writeln!(
            s,
            "| {name} | {} | {:+.1}% | {:+.1}% | {:.2}x | {:.1}x | {:.2} | {:.2} | {:.2} / {:.2} | {:.2} / {:.2} |",
            r.stats.micro_triangles,
            r.rt_impact_percent.primary,
            r.rt_impact_percent.ao,
            r.stats.compression_gain,
            r.stats.construction_gain,
            r.stats.grid.bytes_per_triangle,
            r.stats.triangles.bytes_per_triangle,
            r.mrays_per_s.grid.primary,
            r.mrays_per_s.grid.ao,
            r.mrays_per_s.triangles.primary,
            r.mrays_per_s.triangles.ao,
        );
    }
    for r in results {
        let Some(reference) = &r.reference else { continue };
        let grid_bytes = r.stats.grid.bytes as f64;
        let _ = writeln!(
            s,
            "\nAgainst the mesh it was baked from, {} ({} triangles) under the same BVH as the baseline: {} bytes \
             ({:.1}x the grids'), built in {:.4} s, {:.2} / {:.2} Mrays/s (primary / AO); the micro-mesh lies at \
             RMS {:.3e}, 99th percentile {:.3e}, max {:.3e} of its bounding-box diagonal from it.",
            file_name(&reference.mesh),
            reference.triangles,
            reference.bytes,
            reference.bytes as f64 / grid_bytes.max(1.0),
            reference.build_seconds,
            reference.mrays_per_s.primary,
            reference.mrays_per_s.ao,
            reference.distance.rms,
            reference.distance.p99,
            reference.distance.max,
        );
    }
    s
}
