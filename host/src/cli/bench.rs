//! `gridrt bench`: the published Table 1 measured here, on the same rays for both
//! representations: memory, build time and ray throughput of grids against the baseline.

use std::fmt::Write as _;

use anyhow::{bail, Result};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;

use super::chart::{write_chart, ChartRow};
use super::stats::{self, Stats};
use super::{BenchArgs, BuildArgs};
use gridrt::backend::cpu::trace_cpu;
use gridrt::backend::{Backend, TimedTrace};
use gridrt::bvh::Aabb;
use gridrt::input::Input;
use gridrt::mesh::{Mesh, WorldMesh};
use gridrt::rays::{ao_rays, primary_rays, reorder, RayOrder};
use gridrt::scene::Scene;
use gridrt::{limits, triangles};
use gridrt_shared::layout::{HitRecord, RayRecord};

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
    pub distance: gridrt::surface_distance::DistanceSummary,
}

/// Host bytes per traced ray: its record, its hit, and the copies the ray lists and
/// their reordering hold.
const RAY_BYTES: u64 = 2 * std::mem::size_of::<RayRecord>() as u64 + 2 * std::mem::size_of::<HitRecord>() as u64;

/// Every file the run will write, checked before the first mesh is measured.
fn check_outputs(args: &BenchArgs) -> Result<()> {
    if let Some(json) = &args.json {
        gridrt::files::check_output(json, "json")?;
    }
    if let Some(markdown) = &args.markdown {
        gridrt::files::check_output(markdown, "md")?;
    }
    let outputs: Vec<&std::path::Path> = [&args.json, &args.markdown, &args.chart]
        .into_iter()
        .flatten()
        .map(|p| p.as_path())
        .collect();
    gridrt::files::check_distinct(&outputs)?;
    let mut read: Vec<&std::path::Path> = args.meshes.iter().map(|p| p.as_path()).collect();
    read.extend(args.reference.as_deref());
    let mut inputs = gridrt::input::files_read(&read);
    inputs.push(args.font.clone());
    for output in &outputs {
        gridrt::files::check_not_input(output, &inputs)?;
    }
    if let Some(chart) = &args.chart {
        gridrt::files::check_png_path(chart)?;
        if let Err(e) = std::fs::metadata(&args.font) {
            bail!(
                "{}: cannot read the chart's font: {}",
                args.font.display(),
                gridrt::mesh::io_reason(&e)
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

/// The displaced micro-mesh an input brings, when it has triangles (displaced grids).
fn grids_of(input: &Input) -> Option<&gridrt::micromesh::DisplacedMesh> {
    input.micromesh.as_ref().filter(|m| m.deepest_level().is_some())
}

/// The build arguments an input's limits are checked under: a displaced micro-mesh's decoded
/// triangles are not subdivided further (and its grids are smaller than their baseline).
fn build_of(input: &Input, build: &BuildArgs) -> BuildArgs {
    match input.displaced {
        Some(_) => build.as_decoded(),
        None => build.clone(),
    }
}

/// Refuses, before building, a mesh whose representations the device cannot bind, or whose
/// uploads it would keep copies of in host memory (lavapipe) beyond what is free.
fn check_device(name: &str, mesh: &Mesh, device: &Backend, build: &BuildArgs, ray_bytes: u64) -> Result<()> {
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

pub fn run(args: &BenchArgs, quiet: bool) -> Result<()> {
    let (meshes, reference) = load_inputs(args)?;
    let device = open_checked(args, &meshes)?;
    // Per mesh: load+subdivide, stats, rays, then 4 timed runs.
    let steps = 7;
    let bar = match quiet {
        true => ProgressBar::hidden(),
        false => ProgressBar::new((args.meshes.len() * steps) as u64),
    };
    bar.set_style(ProgressStyle::with_template("{bar:30} {pos}/{len} {msg}").unwrap());
    let results = (meshes.iter())
        .map(|input| measure_mesh(args, input, reference.as_ref(), &device, &bar))
        .collect::<Result<Vec<_>>>()?;
    bar.finish_and_clear();
    write_outputs(args, &results)
}

/// Every mesh, loaded before the first is measured (a bad file is reported at once), and the
/// reference, checked against the arguments.
fn load_inputs(args: &BenchArgs) -> Result<(Vec<Input>, Option<WorldMesh>)> {
    if args.meshes.is_empty() {
        bail!("name at least one mesh to benchmark");
    }
    check_outputs(args)?;
    let meshes = args
        .meshes
        .iter()
        .map(|path| {
            let mut input = super::load(Some(path))?;
            super::compress_values(&mut input, &args.build)?;
            Ok(input)
        })
        .collect::<Result<Vec<_>>>()?;
    if let Some(input) = (meshes.iter()).find(|m| m.displaced.is_some() && grids_of(m).is_none()) {
        bail!("{}: a displaced micro-mesh without base triangles", input.name);
    }
    if args.reference.is_some() && meshes.len() != 1 {
        bail!("--reference compares one micro-mesh with the mesh it was baked from: name one mesh");
    }
    let reference = match &args.reference {
        Some(path) => Some(gridrt::input::load_world(path)?.0),
        None => None,
    };
    Ok((meshes, reference))
}

/// Host bytes the rays of one mesh take.
fn ray_bytes(args: &BenchArgs) -> u64 {
    let rays_per_view = args.width as u64 * args.height as u64 * (1 + args.ao_samples as u64);
    (args.views as u64 * rays_per_view).saturating_mul(RAY_BYTES)
}

/// The backend, once every mesh is known to fit in memory and on it.
fn open_checked(args: &BenchArgs, meshes: &[Input]) -> Result<Backend> {
    let ray_bytes = ray_bytes(args);
    for input in meshes {
        stats::check_work(&input.name, &input.mesh, &build_of(input, &args.build), ray_bytes)?;
    }
    let device = super::open_backend(args.backend, "benchmarking")?;
    for input in meshes {
        check_device(
            &input.name,
            &input.mesh,
            &device,
            &build_of(input, &args.build),
            ray_bytes,
        )?;
    }
    Ok(device)
}

/// One mesh's row: both representations built and measured, then traced on the same rays.
fn measure_mesh(
    args: &BenchArgs,
    input: &Input,
    reference: Option<&WorldMesh>,
    device: &Backend,
    bar: &ProgressBar,
) -> Result<BenchResult> {
    let Input { name, mesh, .. } = input;
    let (stats, grids, tris, bounds) = build_both(args, input, bar)?;
    bar.inc(1);
    bar.set_message(format!("{name}: generating rays"));
    let (primary, ao) = bench_rays(args, &tris, &bounds);
    bar.inc(1);
    // The reference in this mesh's frame, under the baseline's BVH.
    let reference = reference.map(|world| {
        let mesh = world.in_frame(&input.frame);
        let (seconds, scene) = stats::median_time(args.build_repeats, || {
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
        let kind = if is_primary { "primary" } else { "ao" };
        bar.set_message(format!(
            "{name}: {} {kind} rays through grids and triangles",
            rays.len()
        ));
        time_kind(args, name, device, &contenders, rays, is_primary, &mut timed)?;
        bar.inc(2);
    }
    let impact = |g: f64, t: f64| (t / g - 1.0) * 100.0;
    let mrays = timed.mrays;
    Ok(BenchResult {
        stats,
        backend: device.kind().to_string(),
        device: device.describe(),
        timing: device.timing().to_string(),
        views: args.views,
        width: args.width,
        height: args.height,
        ray_order: args.ray_order.order(),
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
        reference: reference.map(|(scene, reference, seconds)| {
            bar.set_message(format!("{name}: measuring the distance to the reference"));
            let d = gridrt::surface_distance::measure(&reference, mesh, &Default::default());
            ReferenceResult {
                mesh: (args.reference.as_ref()).map_or(String::new(), |p| p.display().to_string()),
                triangles: reference.triangles.len(),
                bytes: scene.memory(),
                build_seconds: seconds,
                mrays_per_s: timed.reference,
                distance: d.symmetric.relative_to(d.a_diagonal),
            }
        }),
    })
}

/// Both representations of one mesh, measured as `gridrt stats` measures them, and the box
/// their rays are aimed at. A displaced micro-mesh: displaced grids against its decoded
/// micro-triangles.
fn build_both(args: &BenchArgs, input: &Input, bar: &ProgressBar) -> Result<(Stats, Scene, Scene, Aabb)> {
    let Input { name, mesh, .. } = input;
    let step = |step: &str| bar.set_message(format!("{name}: {step}"));
    let (measured, bounds) = match grids_of(input) {
        Some(micromesh) => {
            bar.inc(1);
            let measured = stats::measure_displaced(name, (micromesh, mesh), &args.build, args.build_repeats, &step)?;
            (measured, Aabb::from_points(mesh.positions.iter().copied()))
        }
        None => {
            step("subdividing");
            let sub = super::subdivide(mesh, &args.build);
            bar.inc(1);
            let measured = stats::measure(name, mesh, &sub, &args.build, args.build_repeats, &step)?;
            (measured, Aabb::from_points(sub.positions.iter().copied()))
        }
    };
    let (stats, grids, tris) = measured;
    Ok((stats, Scene::Grids(grids), Scene::Triangles(tris), bounds))
}

/// The primary rays of the orbit views and their AO rays, in the order asked for. AO rays
/// start from the baseline's hits (the same as the grids' up to ties).
fn bench_rays(args: &BenchArgs, tris: &Scene, bounds: &Aabb) -> (Vec<RayRecord>, Vec<RayRecord>) {
    let mut primary = primary_rays(bounds, args.views, args.width, args.height);
    let first_hits = trace_cpu(tris, &primary);
    let mut ao = ao_rays(&primary, &first_hits, args.ao_samples, bounds, |p| tris.normal(p));
    reorder(
        args.ray_order.order(),
        &mut primary,
        &mut ao,
        args.views,
        args.width,
        args.height,
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
    args: &BenchArgs,
    name: &str,
    device: &Backend,
    contenders: &Contenders,
    rays: &[RayRecord],
    primary: bool,
    timed: &mut Timed,
) -> Result<()> {
    let mut scenes = vec![contenders.grids, contenders.tris];
    scenes.extend(contenders.reference);
    let mut traces = (device.time_traces(&scenes, rays, args.warmup, args.repeats))
        .map_err(super::naming_input(name, gridrt::error::ErrorKind::Limits))?;
    let rate = |t: &TimedTrace| {
        let (median, rel) = summarize(t.seconds.clone());
        (rays.len() as f64 / median / 1e6, rel)
    };
    if let Some(t) = traces.get(2) {
        *timed.reference.kind_mut(primary) = rate(t).0;
    }
    traces.truncate(2);
    let [grid, triangles]: [TimedTrace; 2] = traces.try_into().map_err(|_| anyhow::anyhow!("one timing per scene"))?;
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

/// The table printed and written, the JSON and the chart, as asked.
fn write_outputs(args: &BenchArgs, results: &[BenchResult]) -> Result<()> {
    let table = markdown(results);
    print!("{table}");
    if let Some(path) = &args.json {
        std::fs::write(path, serde_json::to_string_pretty(&results)? + "\n")
            .map_err(|e| anyhow::anyhow!("{}: cannot write: {e}", path.display()))?;
    }
    if let Some(path) = &args.chart {
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
        write_chart(&rows, backend, path, &args.font)?;
    }
    if let Some(path) = &args.markdown {
        std::fs::write(path, table).map_err(|e| anyhow::anyhow!("{}: cannot write: {e}", path.display()))?;
    }
    Ok(())
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
