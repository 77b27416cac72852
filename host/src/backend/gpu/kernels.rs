//! Which kernel runs a job on a scene, and what its pipeline carries.
//!
//! The module has a kernel per job (render a tile, trace a list of rays) and representation,
//! reading whole buffers or a split scene, and split scenes of displaced grids have kernels of
//! their own. A grid kernel is made into a pipeline per format and walk: its specialisation
//! constant 0 says what the pipeline carries (`gridrt_shared::buffer::carries`), and the
//! driver folds the rest away, so a scene pays for its own format and walk alone.
//!
//! Guarantees: every scene and job has one kernel, and the bits it is given are within what
//! its module carries (see the `kernel` crate's families) and include the walk the scene's
//! hierarchies need.

use gridrt_shared::buffer::carries;

use crate::grid::format::GridFormat;
use crate::scene::Scene;

/// What a dispatch does: render a tile, or trace a list of rays.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub(super) enum Job {
    Render,
    Trace,
}

/// A pipeline as it is made: the kernel's entry point and what it carries (its specialisation
/// constant 0; `None` for the triangle kernels, which have none).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub(super) struct Kernel {
    pub entry: &'static str,
    pub carries: Option<u32>,
    /// Where the pipeline is kept among [`PIPELINES`].
    pub slot: usize,
}

/// Pipelines without smooth normals: triangles 4, split plain grids 2 jobs x 2 formats x 2
/// walks, grids on whole buffers 2 jobs x 3 formats x 2 walks.
const PLAIN_PIPELINES: usize = 4 + 8 + 12;

/// How many pipelines can be made: each grid render again with smooth normals (see
/// [`Kernel::lit_smooth`]), in the slots after the others.
pub(super) const PIPELINES: usize = 2 * PLAIN_PIPELINES;

impl Kernel {
    /// The kernel and specialisation that run `job` on `scene`, bound whole or `split`.
    pub fn of(scene: &Scene, job: Job, split: bool) -> Kernel {
        let job = (job == Job::Trace) as usize;
        let grids = match scene {
            Scene::Triangles(_) => return Kernel::triangles(job, split),
            Scene::Grids(grids) => grids,
        };
        let one_visit = grids.params.one_visit();
        if !split {
            return Kernel::grids(job, grids.format(), one_visit);
        }
        // `Gpu::upload` binds displaced grids' formats whole; tight headers and relative radii
        // may be split, and cost a pipeline that reads them registers.
        debug_assert!(!scene.needs_whole_bindings());
        Kernel::split_grids(job, scene.uses_displaced_formats() as usize, one_visit)
    }

    /// This render's pipeline for frames lit with smooth normals: grid kernels carry their
    /// code then alone (`carries::SMOOTH_NORMALS`), since it is the largest part of a render
    /// outside the traversal. Triangle kernels light with geometric normals either way.
    pub fn lit_smooth(self) -> Kernel {
        match self.carries {
            Some(carried) => Kernel {
                carries: Some(carried | carries::SMOOTH_NORMALS),
                slot: PLAIN_PIPELINES + self.slot,
                ..self
            },
            None => self,
        }
    }

    /// The grid kernel of `job` (0 render, 1 trace) on a split scene, for grids of plain
    /// grids' formats (0) or with tight headers and relative radii (1), walked by one visit or
    /// with the stack.
    fn split_grids(job: usize, format: usize, one_visit: bool) -> Kernel {
        Kernel {
            entry: pick(job, "render_grids_split", "trace_grids_rays_split"),
            carries: Some((GridFormat::ALL[format].parts() & carries::DISPLACED_FORMATS) | walk(one_visit)),
            slot: 4 + 4 * format + 2 * one_visit as usize + job,
        }
    }

    /// The triangle kernel of `job` (0 render, 1 trace).
    fn triangles(job: usize, split: bool) -> Kernel {
        Kernel {
            entry: match split {
                false => pick(job, "render_triangles", "trace_triangles_rays"),
                true => pick(job, "render_triangles_split", "trace_triangles_rays_split"),
            },
            carries: None,
            slot: 2 * split as usize + job,
        }
    }

    /// The grid kernel of `job` (0 render, 1 trace) on whole buffers, for grids of
    /// `format`, walked by one visit or with the stack.
    fn grids(job: usize, format: GridFormat, one_visit: bool) -> Kernel {
        Kernel {
            entry: pick(job, "render_grids", "trace_grids_rays"),
            carries: Some(format.parts() | walk(one_visit)),
            slot: 12 + 4 * format.index() + 2 * one_visit as usize + job,
        }
    }
}

/// The kernels made when the device opens: plain scenes on whole buffers (a driver that
/// rejects the module says so at once).
pub(super) fn made_at_start() -> [Kernel; 6] {
    [
        Kernel::triangles(0, false),
        Kernel::triangles(1, false),
        Kernel::grids(0, GridFormat::Plain, true),
        Kernel::grids(1, GridFormat::Plain, true),
        Kernel::grids(0, GridFormat::Plain, false),
        Kernel::grids(1, GridFormat::Plain, false),
    ]
}

/// The entry point of `job` (0 render, 1 trace).
fn pick(job: usize, render: &'static str, trace: &'static str) -> &'static str {
    if job == 0 {
        render
    } else {
        trace
    }
}

/// The walk bit of grids walked by one visit or with the stack.
fn walk(one_visit: bool) -> u32 {
    if one_visit {
        carries::ONE_VISIT
    } else {
        carries::STACK
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every kernel and specialisation the host can ask for keeps a pipeline slot of its own.
    #[test]
    fn each_pipeline_has_its_own_slot() {
        let mut kernels = Vec::new();
        for job in 0..2 {
            kernels.extend([false, true].map(|split| Kernel::triangles(job, split)));
            for one_visit in [false, true] {
                kernels.extend((0..2).map(|format| Kernel::split_grids(job, format, one_visit)));
                kernels.extend(GridFormat::ALL.map(|format| Kernel::grids(job, format, one_visit)));
            }
        }
        assert_eq!(kernels.len(), PLAIN_PIPELINES);
        let renders: Vec<Kernel> = kernels
            .iter()
            .filter(|k| k.entry.starts_with("render"))
            .copied()
            .collect();
        kernels.extend(renders.iter().map(|k| k.lit_smooth()).filter(|k| k.carries.is_some()));
        for (i, a) in kernels.iter().enumerate() {
            assert!(a.slot < PIPELINES);
            for b in &kernels[i + 1..] {
                assert!(a.slot != b.slot || a == b, "{a:?} and {b:?} share a slot");
            }
        }
    }
}
