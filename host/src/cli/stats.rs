//! `gridrt stats`: memory and build time of both representations of one mesh.

use std::time::Instant;

use anyhow::Result;
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use serde_json::{Map, Value};

use super::{BuildArgs, StatsArgs};
use gridrt::grid::{self, GridScene};
use gridrt::input::Input;
use gridrt::limits;
use gridrt::mesh::Mesh;
use gridrt::micromesh::DisplacedMesh;
use gridrt::subdiv::Subdivided;
use gridrt::triangles::{self, TriangleScene};

/// Builds timed per representation at most; the median is reported.
pub const BUILD_REPEATS: usize = 7;

/// Once the timed runs of one measurement have taken this long together, no more are
/// started: a large mesh is built once or twice instead of seven times, so a measurement
/// takes time in proportion to its work.
pub const REPEAT_BUDGET_SECONDS: f64 = 3.0;

#[derive(Serialize, Debug, Clone)]
pub struct Representation {
    pub bytes: usize,
    pub bytes_per_triangle: f64,
    pub build_seconds: f64,
    pub parts: Map<String, Value>,
}

#[derive(Serialize, Debug, Clone)]
pub struct Stats {
    pub mesh: String,
    pub levels: u32,
    pub base_triangles: usize,
    pub micro_triangles: usize,
    pub grid: Representation,
    pub triangles: Representation,
    pub compression_gain: f64,
    pub construction_gain: f64,
}

/// Median wall time of up to `repeats` runs of `f` (fewer once they exceed
/// [`REPEAT_BUDGET_SECONDS`]), and the last result.
pub fn median_time<T>(repeats: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    median_time_of(repeats, || (), |_| f())
}

/// [`median_time`] of `f` on a fresh input from `input` each time. Made and freed outside
/// the timer: the input, and the previous run's result.
pub fn median_time_of<I, T>(repeats: usize, input: impl FnMut() -> I, f: impl FnMut(&mut I) -> T) -> (f64, T) {
    median_time_within(repeats, REPEAT_BUDGET_SECONDS, input, f)
}

/// [`median_time_of`] with its time budget given: no run starts once the runs so far took
/// more than `budget` seconds together (the first always runs).
fn median_time_within<I, T>(
    repeats: usize,
    budget: f64,
    mut input: impl FnMut() -> I,
    mut f: impl FnMut(&mut I) -> T,
) -> (f64, T) {
    let mut times = Vec::with_capacity(repeats);
    let mut last = None;
    for _ in 0..repeats.max(1) {
        if times.iter().sum::<f64>() > budget {
            break;
        }
        let mut x = input();
        drop(last.take());
        // Every worker thread awake before the clock starts: a build that follows a pause
        // (here, making its input) would otherwise also time the pool waking up.
        rayon::broadcast(|_| ());
        let start = Instant::now();
        let result = f(&mut x);
        times.push(start.elapsed().as_secs_f64());
        last = Some(result);
    }
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], last.unwrap())
}

fn representation(parts: Vec<(&'static str, usize)>, micro: usize, seconds: f64) -> Representation {
    let bytes = parts.iter().map(|p| p.1).sum();
    Representation {
        bytes,
        bytes_per_triangle: bytes as f64 / micro.max(1) as f64,
        build_seconds: seconds,
        parts: parts
            .into_iter()
            .map(|(k, v)| (k.to_string(), Value::from(v)))
            .collect(),
    }
}

/// Both representations as built, with their median build times, over `micro` micro-triangles.
struct Built<'a> {
    grids: (&'a GridScene, f64),
    triangles: (&'a TriangleScene, f64),
    micro: usize,
}

impl Built<'_> {
    fn stats(&self, name: &str, levels: u32, base_triangles: usize) -> Stats {
        let grid = representation(self.grids.0.memory(), self.micro, self.grids.1);
        let triangles = representation(self.triangles.0.memory(), self.micro, self.triangles.1);
        Stats {
            mesh: name.to_string(),
            levels,
            base_triangles,
            micro_triangles: self.micro,
            compression_gain: triangles.bytes as f64 / grid.bytes.max(1) as f64,
            construction_gain: triangles.build_seconds / grid.build_seconds.max(1e-12),
            grid,
            triangles,
        }
    }
}

/// Measures both representations of `mesh` subdivided as `sub`. Timed: for grids, their
/// bounds, the top-level BVH, the reordering into its leaf order and the sphere radii; for
/// triangles, their bounds, the SAH BVH and the reordering of the index list. Not timed: the
/// subdivision and the laying out of its result (the grid vertex areas, the triangle list),
/// which both representations start from.
/// Returns the built representations too, for whoever traces them next.
pub fn measure(
    name: &str,
    mesh: &Mesh,
    sub: &Subdivided,
    build: &BuildArgs,
    repeats: usize,
    progress: &dyn Fn(&str),
) -> Result<(Stats, GridScene, TriangleScene)> {
    let micro_list = sub.micro_triangles(sub.levels);
    let layout = grid::layout(mesh, sub, &build.grid_options())?;
    progress(&format!("building the grids (up to {repeats} times)"));
    let (grid_s, grids) = median_time_of(repeats, || layout.clone(), grid::build_from_layout);
    progress(&format!("building the baseline (up to {repeats} times)"));
    let (tri_s, tris) = median_time(repeats, || triangles::build(&sub.positions, &micro_list));
    let built = Built {
        grids: (&grids, grid_s),
        triangles: (&tris, tri_s),
        micro: micro_list.len(),
    };
    let stats = built.stats(name, sub.levels, mesh.triangles.len());
    Ok((stats, grids, tris))
}

/// [`measure`] for a displaced micro-mesh of one level: displaced grids against `decoded`, its
/// micro-triangles as the loader decoded them (points decoded alike stored once). Timed as [`measure`] times: for
/// grids, everything after laying out their values; for triangles, everything after
/// decoding.
pub fn measure_displaced(
    name: &str,
    (micromesh, decoded): (&DisplacedMesh, &Mesh),
    build: &BuildArgs,
    repeats: usize,
    progress: &dyn Fn(&str),
) -> Result<(Stats, GridScene, TriangleScene)> {
    let build = build.as_displaced(micromesh.deepest_level().unwrap_or(0));
    let layout = grid::displaced::layout(micromesh, &build.grid_options())?;
    progress(&format!("building the displaced grids (up to {repeats} times)"));
    let (grid_s, grids) = median_time_of(repeats, || layout.clone(), grid::build_from_layout);
    progress(&format!("building the baseline (up to {repeats} times)"));
    let (tri_s, tris) = median_time(repeats, || triangles::build(&decoded.positions, &decoded.triangles));
    let built = Built {
        grids: (&grids, grid_s),
        triangles: (&tris, tri_s),
        micro: decoded.triangles.len(),
    };
    let stats = built.stats(name, grids.params.levels, micromesh.triangles.len());
    Ok((stats, grids, tris))
}

/// Refuses to measure a mesh whose two representations would not fit in memory together
/// (`extra`: bytes the caller needs besides), or whose grids could not be addressed.
pub fn check_work(name: &str, mesh: &Mesh, build: &BuildArgs, extra: u64) -> Result<()> {
    build.check_grid_limits(name, mesh)?;
    Ok(limits::check_build(
        &format!("measuring both representations of {name}"),
        mesh.triangles.len(),
        build.levels,
        limits::Builds::Both,
        extra,
        "use fewer --levels, or `gridrt render --mode grid` for the grids alone",
    )?)
}

/// A spinner on stderr naming the current step (hidden when stderr is not a terminal, or
/// when `quiet`).
pub fn spinner(quiet: bool) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new_spinner();
    bar.set_style(ProgressStyle::with_template("{spinner} {elapsed} {msg}").expect("valid template"));
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    bar
}

pub fn run(args: &StatsArgs, quiet: bool) -> Result<()> {
    let bar = spinner(quiet);
    bar.set_message("loading");
    let Input {
        name,
        mesh,
        displaced,
        micromesh,
        ..
    } = {
        let mut input = super::load(args.mesh.as_deref())?;
        super::compress_values(&mut input, &args.build)?;
        input
    };
    let step = |step: &str| bar.set_message(format!("{name}: {step}"));
    // A displaced micro-mesh: displaced grids against its decoded triangles.
    let s = match (micromesh.filter(|m| m.deepest_level().is_some()), displaced) {
        (Some(m), _) => {
            check_work(&name, &mesh, &args.build.as_decoded(), 0)?;
            measure_displaced(&name, (&m, &mesh), &args.build, BUILD_REPEATS, &step)?.0
        }
        (None, displaced) => {
            let build = match displaced {
                Some(_) => args.build.as_decoded(),
                None => args.build.clone(),
            };
            check_work(&name, &mesh, &build, 0)?;
            step("subdividing");
            let sub = super::subdivide(&mesh, &build);
            measure(&name, &mesh, &sub, &build, BUILD_REPEATS, &step)?.0
        }
    };
    bar.finish_and_clear();
    if args.json {
        println!("{}", serde_json::to_string(&s)?);
        return Ok(());
    }
    println!(
        "{}: L = {}, {} base triangles, {} micro-triangles",
        s.mesh, s.levels, s.base_triangles, s.micro_triangles
    );
    for (label, r) in [("grid", &s.grid), ("triangles", &s.triangles)] {
        println!(
            "  {label:<10} {:>12} bytes  {:>6.2} B/triangle  build {:>9.4} s",
            r.bytes, r.bytes_per_triangle, r.build_seconds
        );
        for (part, bytes) in &r.parts {
            println!("    {part:<16} {bytes:>12}");
        }
    }
    println!(
        "  compression gain {:.2}x, construction gain {:.1}x",
        s.compression_gain, s.construction_gain
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repeats_stop_once_the_budget_is_spent() {
        let mut runs = 0;
        let (_, last) = median_time_within(
            7,
            0.0,
            || (),
            |_| {
                runs += 1;
                std::thread::sleep(std::time::Duration::from_millis(1));
                runs
            },
        );
        assert_eq!((runs, last), (1, 1));
        let mut runs = 0;
        median_time_within(7, f64::INFINITY, || (), |_| runs += 1);
        assert_eq!(runs, 7);
    }
}
