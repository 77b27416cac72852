//! Timing ray lists: a batch of rays made ready once (its buffers made and bound) and traced
//! as often as a benchmark asks; several scenes traced on one list take turns at every
//! repetition.
//!
//! Why turns: a benchmark's figure is a ratio between two scenes (grids and their triangles),
//! and a device's speed changes while it runs (clocks, heat, other work on the machine). Timed
//! one block after the other, the two scenes can meet different speeds and the ratio moves
//! with them; taking turns ([`in_turn`]), both meet each speed alike.

use gridrt_shared::layout::{HitRecord, RayRecord};
use std::time::Instant;

use super::{Dispatch, Gpu, GpuScene, Job, Queries};
use crate::error::Result;
use crate::rays::in_turn;

/// A batch of a list, ready to trace through one scene: a thread per ray, one dispatch.
struct ReadyBatch<'p> {
    pipeline: &'p wgpu::ComputePipeline,
    bind_groups: Vec<wgpu::BindGroup>,
    groups: (u32, u32),
    hits: wgpu::Buffer,
    readback: wgpu::Buffer,
    queries: Option<Queries>,
}

/// What timing a list through one scene gives: the hits of the last repetition and the
/// seconds of each.
pub struct TimedList {
    pub hits: Vec<HitRecord>,
    pub seconds: Vec<f64>,
}

impl Gpu {
    /// Traces `rays` through each of `scenes` `repeats` times, the scenes taking turns at every
    /// repetition (the first of one is the last of the next); per scene, in order, the hits and
    /// the seconds of each repetition (all its batches), measured as [`Gpu::timing`] says.
    pub fn time_traces(&self, scenes: &[GpuScene], rays: &[RayRecord], repeats: usize) -> Result<Vec<TimedList>> {
        let repeats = repeats.max(1);
        let batch = self.ray_batch();
        let mut timed: Vec<TimedList> = (scenes.iter())
            .map(|_| TimedList {
                hits: Vec::with_capacity(rays.len()),
                seconds: vec![0.0; repeats],
            })
            .collect();
        for list in rays.chunks(batch.max(1)) {
            let ready = (scenes.iter())
                .map(|s| self.ready_batch(s, list))
                .collect::<Result<Vec<_>>>()?;
            for k in 0..repeats {
                for turn in 0..ready.len() {
                    let s = in_turn(k, turn, ready.len());
                    timed[s].seconds[k] += self.run_batch(&ready[s])?;
                }
            }
            for (t, r) in timed.iter_mut().zip(&ready) {
                t.hits.extend(self.batch_hits(r, list.len())?);
            }
        }
        Ok(timed)
    }

    fn ready_batch<'p>(&'p self, scene: &GpuScene, rays: &[RayRecord]) -> Result<ReadyBatch<'p>> {
        let pipeline = self.pipeline(scene, Job::Trace, false)?;
        let (groups, params) = self.trace_params(scene, rays.len() as u32);
        let params = self.buffer("trace parameters", bytemuck::bytes_of(&params));
        let ray_buffer = self.buffer("ray", bytemuck::cast_slice(rays));
        let (hits, readback) = self.output("hit", hit_bytes(rays.len()));
        let bind_groups = self.bind(pipeline, &[&params, &ray_buffer, &hits], scene);
        Ok(ReadyBatch {
            pipeline,
            bind_groups,
            groups,
            hits,
            readback,
            queries: self.timestamps.then(|| self.queries()),
        })
    }

    /// Traces a ready batch once; returns its seconds.
    fn run_batch(&self, batch: &ReadyBatch) -> Result<f64> {
        let start = Instant::now();
        self.dispatch(&Dispatch {
            pipeline: batch.pipeline,
            bind_groups: &batch.bind_groups,
            groups: batch.groups,
            copy: None,
            queries: batch.queries.as_ref(),
        })?;
        self.seconds(batch.queries.as_ref(), start.elapsed().as_secs_f64())
    }

    /// The hits of a ready batch of `rays` rays, as its last run left them.
    fn batch_hits(&self, batch: &ReadyBatch, rays: usize) -> Result<Vec<HitRecord>> {
        let (hits, readback) = (&batch.hits, &batch.readback);
        let bytes = hit_bytes(rays);
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(hits, 0, readback, 0, bytes);
        self.queue.submit([encoder.finish()]);
        Ok(bytemuck::cast_slice(&self.read_back_bytes(readback, bytes)?).to_vec())
    }

    /// Seconds of a timed span: between the timestamps of `queries` where the adapter has
    /// them, `wall` otherwise.
    pub(super) fn seconds(&self, queries: Option<&Queries>, wall: f64) -> Result<f64> {
        Ok(match queries {
            Some(q) => {
                let t: Vec<u64> = bytemuck::cast_slice(&self.read_back_bytes(&q.readback, 16)?).to_vec();
                t[1].saturating_sub(t[0]) as f64 * self.queue.get_timestamp_period() as f64 * 1e-9
            }
            None => wall,
        })
    }
}

fn hit_bytes(rays: usize) -> u64 {
    rays as u64 * std::mem::size_of::<HitRecord>() as u64
}
