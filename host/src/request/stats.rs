//! `gridrt stats`: the memory and build time of both representations of one mesh, grids
//! against the baseline, built as [`BuildRequest`] asks (see [`stats_file`]); and the timing
//! the bench shares: the median of a few builds, within a time budget.

use std::path::Path;
use std::time::Instant;

use serde::Serialize;
use serde_json::{Map, Value};

use super::build::BuildRequest;
use crate::error::Result;
use crate::grid::{self, GridScene};
use crate::limits;
use crate::mesh::Mesh;
use crate::micromesh::DisplacedMesh;
use crate::progress::{self, Progress};
use crate::subdiv::Subdivided;
use crate::triangles::{self, TriangleScene};

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
    build: &BuildRequest,
    repeats: usize,
    progress: &mut dyn Progress,
) -> Result<(Stats, GridScene, TriangleScene)> {
    let micro_list = sub.micro_triangles(sub.levels);
    let layout = grid::layout(mesh, sub, &build.grid_options())?;
    let (grid_s, grids) = progress::run(progress, "build grids", || {
        median_time_of(repeats, || layout.clone(), grid::build_from_layout)
    });
    let (tri_s, tris) = progress::run(progress, "build triangles", || {
        median_time(repeats, || triangles::build(&sub.positions, &micro_list))
    });
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
    build: &BuildRequest,
    repeats: usize,
    progress: &mut dyn Progress,
) -> Result<(Stats, GridScene, TriangleScene)> {
    let build = build.as_displaced(micromesh.deepest_level().unwrap_or(0));
    let layout = grid::displaced::layout(micromesh, &build.grid_options())?;
    let (grid_s, grids) = progress::run(progress, "build grids", || {
        median_time_of(repeats, || layout.clone(), grid::build_from_layout)
    });
    let (tri_s, tris) = progress::run(progress, "build triangles", || {
        median_time(repeats, || triangles::build(&decoded.positions, &decoded.triangles))
    });
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
pub fn check_work(name: &str, mesh: &Mesh, build: &BuildRequest, extra: u64) -> Result<()> {
    build.check_grid_limits(name, mesh)?;
    limits::check_build(
        &format!("measuring both representations of {name}"),
        mesh.triangles.len(),
        build.levels,
        limits::Builds::Both,
        extra,
        "use fewer --levels, or `gridrt render --mode grid` for the grids alone",
    )
}

/// `gridrt stats`: the mesh at `path` (the built-in scene when `None`) measured in both
/// representations, the median of up to [`BUILD_REPEATS`] builds each. A displaced
/// micro-mesh: displaced grids against its decoded triangles. Refused before any build when
/// both would not fit in memory.
pub fn stats_file(path: Option<&Path>, build: &BuildRequest, progress: &mut dyn Progress) -> Result<Stats> {
    let input = super::open_for_build(path.as_slice(), build, progress)?;
    let (name, mesh) = (&input.name, &input.mesh);
    // A displaced micro-mesh is checked as its decoded triangles, the larger of the two.
    let checked = build.for_input(&input);
    check_work(name, mesh, &checked, 0)?;
    match input.displaced_grids() {
        Some(m) => Ok(measure_displaced(name, (m, mesh), build, BUILD_REPEATS, progress)?.0),
        None => {
            let sub = progress::run(progress, "subdivide", || checked.subdivide(mesh));
            Ok(measure(name, mesh, &sub, &checked, BUILD_REPEATS, progress)?.0)
        }
    }
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
