//! The two-phase schedule for grid ray lists: rounds of a top-level walk kernel, which takes
//! every ray still walking to its next leaf (the first round, every ray of the batch from the
//! root, a kernel of its own that reads no state) and queues (ray, grid, closest distance so
//! far) for the leaf's grids, each followed by a kernel that visits one queued grid per thread
//! as far as its spheres and footprints and queues the visits that need a leaf test, two small
//! kernels that sort those by size (the lattice points of their windows), and a kernel that
//! runs one queued leaf test per thread. The walk merges the visits' results at its next
//! round. Once few rays still walk they finish in one pass, their grids visited in place, each
//! thread taking the next ray of the list as soon as its own is done.
//!
//! Why: in the one-pass walk a SIMD group visits a grid at the pace of its lanes that have one,
//! the others masked; queued, every lane of a group visits one, and every lane of a group of
//! leaf tests runs one, of about the same size once sorted (docs/RESULTS.md, "Two-phase"). It
//! takes scenes whose grids are walked by their root's visit alone, bound whole.

use gridrt_shared::layout::{
    HitRecord, LeafEntry, QueueEntry, RayRecord, WalkState, FINISH_RAYS_PER_THREAD, FINISH_RAYS_PER_THREAD_COMPRESSED,
    LEAF_TEST_CLASSES, TRACE_WORKGROUP_SIZE,
};
use gridrt_shared::traverse::MAX_BVH_DEPTH;
use std::time::Instant;

use super::turns::{TimedList, TimedScene};
use super::{compute_pipeline, Gpu, GpuScene};
use crate::error::{error, fail, Result};
use crate::scene::Scene;

/// The rays still walking finish in one pass once fewer than this fraction (1 / FINISH_BELOW)
/// of the list is left: every round costs a fixed time however few its rays (its dispatches
/// and a share of a read-back of the count), and the last rounds hold a handful.
const FINISH_BELOW: u32 = 32;

/// Rounds encoded in one submission, the count read back after the last: each read-back
/// leaves the device idle while the host waits, and a round with no ray left is an empty
/// indirect dispatch.
const ROUNDS_PER_SUBMIT: usize = 2;

/// A ray's saved stack: `MAX_BVH_DEPTH` slots of a node and its distance.
const STACK_BYTES: u64 = 2 * MAX_BVH_DEPTH as u64 * 4;

/// Which of the schedule's kernel sets a scene's grids take: those of plain grids' formats,
/// those of displaced grids' (see `Scene::uses_displaced_formats`), or those that also carry
/// the decoder of compressed values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum GridFormats {
    Plain,
    Displaced,
    Compressed,
}

impl GridFormats {
    /// How many kernel sets there are.
    pub(super) const COUNT: usize = 3;

    fn of(scene: &Scene) -> GridFormats {
        if scene.has_compressed_values() {
            GridFormats::Compressed
        } else if scene.uses_displaced_formats() {
            GridFormats::Displaced
        } else {
            GridFormats::Plain
        }
    }

    /// The suffixes of the kernels' entry points: the walk's (it reads the top level alone, so
    /// compressed values take the displaced grids' walk), then the grid kernels'.
    fn suffixes(self) -> (&'static str, &'static str) {
        match self {
            GridFormats::Plain => ("", ""),
            GridFormats::Displaced => ("_displaced", "_displaced"),
            GridFormats::Compressed => ("_displaced", "_compressed"),
        }
    }

    /// Most rays a thread of the finish takes (the kernel's own limit).
    fn finish_rays_per_thread(self) -> u32 {
        match self {
            GridFormats::Compressed => FINISH_RAYS_PER_THREAD_COMPRESSED,
            _ => FINISH_RAYS_PER_THREAD,
        }
    }
}

/// The schedule's kernels.
pub(super) struct Kernels {
    walk_first: wgpu::ComputePipeline,
    walk: wgpu::ComputePipeline,
    visit: wgpu::ComputePipeline,
    order_classes: wgpu::ComputePipeline,
    sort_leaves: wgpu::ComputePipeline,
    test_leaves: wgpu::ComputePipeline,
    finish: wgpu::ComputePipeline,
}

/// One batch's buffers and bind groups; lists and counters come in pairs, read by one round
/// and written for the next.
pub(super) struct Batch {
    rays: u32,
    /// Which kernels the scene's grids take.
    formats: GridFormats,
    hits: wgpu::Buffer,
    readback: wgpu::Buffer,
    /// Each an indirect dispatch's three group counts, then the number of items.
    counts: [wgpu::Buffer; 2],
    queue_count: wgpu::Buffer,
    leaf_count: wgpu::Buffer,
    class_counts: wgpu::Buffer,
    /// How many rays past its dispatch's threads the finish has taken (cleared before it).
    next: wgpu::Buffer,
    count_readback: wgpu::Buffer,
    /// Timestamps around a run of the rounds, where the adapter has them.
    queries: Option<super::Queries>,
    /// The first round's walk, then the later rounds' by the list they read.
    walk_first: wgpu::BindGroup,
    walk: [wgpu::BindGroup; 2],
    finish: [wgpu::BindGroup; 2],
    visit: wgpu::BindGroup,
    order_classes: wgpu::BindGroup,
    sort_leaves: wgpu::BindGroup,
    test_leaves: wgpu::BindGroup,
}

impl GpuScene<'_> {
    /// Whether the two-phase schedule takes this scene: grids walked by their root's visit
    /// alone, bound whole.
    pub fn takes_two_phase(&self) -> bool {
        matches!(self.scene, Scene::Grids(g) if g.params.one_visit() && !self.is_split())
    }
}

impl Batch {
    /// The buffer the hits are written to, and the one they are read back through.
    pub(super) fn hit_buffers(&self) -> (&wgpu::Buffer, &wgpu::Buffer) {
        (&self.hits, &self.readback)
    }
}

impl Gpu {
    /// Whether `Schedule::Auto` takes the two-phase schedule here: on a device that is the CPU
    /// (lavapipe), where a SIMD group runs the code of every branch any lane takes, the
    /// rounds keep the lanes on the same work; a real GPU jumps over what no lane takes, and
    /// there one pass is faster (docs/RESULTS.md, "Table 1, a real GPU").
    pub fn prefers_two_phase(&self) -> bool {
        self.adapter.device_type == wgpu::DeviceType::Cpu
    }

    /// Traces a list of rays by the two-phase schedule `repeats` times: the hits, and the
    /// seconds of each repetition (from the first round's start to the last's end, by GPU
    /// timestamps where the adapter has them).
    pub fn time_trace_two_phase(
        &self,
        scene: &GpuScene,
        rays: &[RayRecord],
        repeats: usize,
    ) -> Result<(Vec<HitRecord>, Vec<f64>)> {
        let timed = TimedScene { scene, two_phase: true };
        let TimedList { hits, seconds } = self.time_traces(&[timed], rays, repeats)?.remove(0);
        Ok((hits, seconds))
    }

    /// Most entries of a scene's leaves (grids), once the scene is known to take the schedule.
    fn widest_leaf(scene: &GpuScene) -> Result<u32> {
        match scene.scene {
            Scene::Grids(g) if scene.takes_two_phase() => Ok(g.leaf_size()),
            _ => fail!(
                Options,
                "the two-phase schedule traces grids walked by their root's visit alone (sphere levels down to 1, \
                 as at the default --levels 3), bound whole; this scene is not, use the one-pass schedule"
            ),
        }
    }

    /// Most rays a batch of `scene` may hold: its stacks within one binding, and its queue (up
    /// to its widest leaf's entries a ray) within one dispatch.
    pub(super) fn two_phase_batch(&self, scene: &GpuScene) -> Result<usize> {
        let widest_leaf = Self::widest_leaf(scene)?;
        let groups = self.limits.max_compute_workgroups_per_dimension as u64;
        let by_queue = groups * TRACE_WORKGROUP_SIZE as u64 / widest_leaf as u64;
        let by_stack = self.binding_limit / STACK_BYTES;
        let by_queue_binding = self.binding_limit / (widest_leaf as u64 * std::mem::size_of::<QueueEntry>() as u64);
        Ok((self.ray_batch() as u64)
            .min(by_queue)
            .min(by_stack)
            .min(by_queue_binding)
            .max(1) as usize)
    }

    /// The schedule's kernels for grids of `formats`, made on first use.
    fn two_phase_kernels(&self, formats: GridFormats) -> &Kernels {
        let (walk, grids) = formats.suffixes();
        self.two_phase[formats as usize].get_or_init(|| {
            let pipeline = |entry: &str| compute_pipeline(&self.device, &self.module, entry);
            Kernels {
                walk_first: pipeline(&format!("walk_first_rounds{walk}")),
                walk: pipeline(&format!("walk_rounds{walk}")),
                visit: pipeline(&format!("visit_queued{grids}")),
                order_classes: pipeline("order_leaf_classes"),
                sort_leaves: pipeline("sort_queued_leaves"),
                test_leaves: pipeline(&format!("test_queued_leaves{grids}")),
                finish: pipeline(&format!("finish_walks{grids}")),
            }
        })
    }

    pub(super) fn two_phase_batch_buffers(&self, scene: &GpuScene, rays: &[RayRecord]) -> Result<Batch> {
        let widest_leaf = Self::widest_leaf(scene)?;
        let n = rays.len() as u64;
        let storage = |name: &str, bytes: u64, extra: wgpu::BufferUsages| {
            self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(name),
                size: bytes.max(16),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | extra,
                mapped_at_creation: false,
            })
        };
        let plain = wgpu::BufferUsages::empty();
        let counter = wgpu::BufferUsages::INDIRECT | wgpu::BufferUsages::COPY_SRC;
        let ray_buffer = self.buffer("ray", bytemuck::cast_slice(rays));
        let (hits, readback) = self.output("hit", n * std::mem::size_of::<HitRecord>() as u64);
        let states = storage("walk state", n * std::mem::size_of::<WalkState>() as u64, plain);
        let stacks = storage("walk stack", n * STACK_BYTES, plain);
        let lists = [
            storage("walking rays", n * 4, plain),
            storage("walking rays", n * 4, plain),
        ];
        let entries = n * widest_leaf as u64;
        let queue = storage("queue", entries * std::mem::size_of::<QueueEntry>() as u64, plain);
        let results = storage(
            "queue results",
            entries * std::mem::size_of::<HitRecord>() as u64,
            plain,
        );
        let counts = [storage("count", 16, counter), storage("count", 16, counter)];
        let queue_count = storage("queue count", 16, counter);
        let leaves = storage("leaf queue", entries * std::mem::size_of::<LeafEntry>() as u64, plain);
        let leaf_count = storage("leaf count", 16, counter);
        let sorted_leaves = storage(
            "sorted leaf queue",
            entries * std::mem::size_of::<LeafEntry>() as u64,
            plain,
        );
        let class_bytes = LEAF_TEST_CLASSES as u64 * 4;
        let class_counts = storage("leaf class counts", class_bytes, plain);
        let class_starts = storage("leaf class starts", class_bytes, plain);
        let next = storage("rays taken", 16, plain);
        let count_readback = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("count read-back"),
            size: 16,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let (_, params) = self.trace_params(scene, n as u32);
        let params = self.buffer("trace parameters", bytemuck::bytes_of(&params));
        let formats = GridFormats::of(scene.scene);
        let kernels = self.two_phase_kernels(formats);
        // The scene's bindings: static index list, top-level BVH, headers, vertices, radii.
        let [micro_triangles, nodes, headers, vertices, radii] = [0, 1, 2, 3, 4].map(|k| &scene.buffers[k]);
        let walk = |from: usize| {
            self.bind_group(
                &kernels.walk,
                0,
                &[
                    &ray_buffer,
                    &hits,
                    nodes,
                    &states,
                    &stacks,
                    &lists[from],
                    &lists[1 - from],
                    &queue,
                    &results,
                    &counts[from],
                    &counts[1 - from],
                    &queue_count,
                ],
            )
        };
        let finish = |from: usize| {
            self.bind_group(
                &kernels.finish,
                0,
                &[
                    &params,
                    &ray_buffer,
                    &hits,
                    nodes,
                    &states,
                    &stacks,
                    &lists[from],
                    &results,
                    &counts[from],
                    micro_triangles,
                    headers,
                    vertices,
                    radii,
                    &next,
                ],
            )
        };
        let visit = self.bind_group(
            &kernels.visit,
            0,
            &[
                &params,
                &ray_buffer,
                &queue,
                &results,
                &queue_count,
                headers,
                vertices,
                radii,
                &leaves,
                &leaf_count,
                &class_counts,
            ],
        );
        let order_classes = self.bind_group(&kernels.order_classes, 0, &[&class_counts, &class_starts]);
        let sort_leaves = self.bind_group(
            &kernels.sort_leaves,
            0,
            &[&params, &leaves, &leaf_count, &class_starts, &sorted_leaves],
        );
        let test_leaves = self.bind_group(
            &kernels.test_leaves,
            0,
            &[
                &params,
                &ray_buffer,
                &queue,
                &results,
                &sorted_leaves,
                &leaf_count,
                micro_triangles,
                headers,
                vertices,
                radii,
            ],
        );
        // The first round reads no list: its thread `i` walks ray `i`.
        let walk_first = self.bind_group(
            &kernels.walk_first,
            0,
            &[
                &ray_buffer,
                &hits,
                nodes,
                &states,
                &stacks,
                &lists[1],
                &queue,
                &counts[0],
                &counts[1],
                &queue_count,
            ],
        );
        let (walk, finish) = ([walk(0), walk(1)], [finish(0), finish(1)]);
        Ok(Batch {
            rays: n as u32,
            formats,
            hits,
            readback,
            counts,
            queue_count,
            leaf_count,
            class_counts,
            next,
            count_readback,
            queries: self.timestamps.then(|| self.queries()),
            walk_first,
            walk,
            finish,
            visit,
            order_classes,
            sort_leaves,
            test_leaves,
        })
    }

    /// One round: the walk of every ray of the batch (round 0) or of the list the last round
    /// wrote, then the visits it queued, then the leaf tests they queued, sorted by size class;
    /// the rays still walking are listed for the next round in the other list. Round 0 opens
    /// the timed span of `queries`.
    fn encode_round(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        batch: &Batch,
        round: usize,
        queries: Option<&super::Queries>,
    ) {
        let kernels = self.two_phase_kernels(batch.formats);
        let from = round % 2;
        encoder.clear_buffer(&batch.counts[1 - from], 0, None);
        encoder.clear_buffer(&batch.queue_count, 0, None);
        encoder.clear_buffer(&batch.leaf_count, 0, None);
        encoder.clear_buffer(&batch.class_counts, 0, None);
        let opening = queries
            .filter(|_| round == 0)
            .map(|q| wgpu::ComputePassTimestampWrites {
                query_set: &q.set,
                beginning_of_pass_write_index: Some(0),
                end_of_pass_write_index: None,
            });
        match round {
            0 => {
                let groups = batch.rays.div_ceil(TRACE_WORKGROUP_SIZE);
                direct_pass(encoder, &kernels.walk_first, &batch.walk_first, groups, opening);
            }
            _ => indirect_pass(encoder, &kernels.walk, &batch.walk[from], &batch.counts[from], opening),
        }
        indirect_pass(encoder, &kernels.visit, &batch.visit, &batch.queue_count, None);
        direct_pass(encoder, &kernels.order_classes, &batch.order_classes, 1, None);
        indirect_pass(
            encoder,
            &kernels.sort_leaves,
            &batch.sort_leaves,
            &batch.leaf_count,
            None,
        );
        indirect_pass(
            encoder,
            &kernels.test_leaves,
            &batch.test_leaves,
            &batch.leaf_count,
            None,
        );
    }

    /// Workgroups for a kernel whose threads take the rays of a list of `rays` in turn, each at
    /// most `per_thread`: as many as the device runs at once (`finish_groups`), but no more
    /// than a thread per ray, and enough to take the whole list.
    fn groups_taking_turns(&self, rays: u32, per_thread: u32) -> u32 {
        let one_each = rays.div_ceil(TRACE_WORKGROUP_SIZE);
        let fewest = rays.div_ceil(TRACE_WORKGROUP_SIZE * per_thread);
        one_each.min(self.finish_groups).max(fewest).max(1)
    }

    /// Runs the rounds of one batch until no ray walks on; returns their seconds.
    pub(super) fn run_rounds(&self, batch: &Batch) -> Result<f64> {
        let n = batch.rays;
        let kernels = self.two_phase_kernels(batch.formats);
        let queries = batch.queries.as_ref();
        self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        self.queue.write_buffer(
            &batch.counts[0],
            0,
            bytemuck::cast_slice(&[n.div_ceil(TRACE_WORKGROUP_SIZE), 1, 1, n]),
        );
        let start = Instant::now();
        let mut round = 0;
        let finish = loop {
            let mut encoder = self.device.create_command_encoder(&Default::default());
            for _ in 0..ROUNDS_PER_SUBMIT {
                self.encode_round(&mut encoder, batch, round, queries);
                round += 1;
            }
            let to = round % 2;
            encoder.copy_buffer_to_buffer(&batch.counts[to], 0, &batch.count_readback, 0, 16);
            self.queue.submit([encoder.finish()]);
            let count: Vec<u32> = bytemuck::cast_slice(&self.read_back_bytes(&batch.count_readback, 16)?).to_vec();
            let walking = count[3];
            if walking == 0 {
                break None;
            }
            if walking * FINISH_BELOW < n {
                break Some((to, walking));
            }
        };
        // The last pass: the rays still walking finish in one pass each, or nothing; it
        // closes the timed span.
        let mut encoder = self.device.create_command_encoder(&Default::default());
        let closing = queries.map(|q| wgpu::ComputePassTimestampWrites {
            query_set: &q.set,
            beginning_of_pass_write_index: None,
            end_of_pass_write_index: Some(1),
        });
        match finish {
            Some((from, walking)) => {
                let groups = self.groups_taking_turns(walking, batch.formats.finish_rays_per_thread());
                encoder.clear_buffer(&batch.next, 0, None);
                direct_pass(&mut encoder, &kernels.finish, &batch.finish[from], groups, closing);
            }
            None => drop(encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: None,
                timestamp_writes: closing,
            })),
        }
        if let Some(q) = queries {
            encoder.resolve_query_set(&q.set, 0..2, &q.resolve, 0);
            encoder.copy_buffer_to_buffer(&q.resolve, 0, &q.readback, 0, 16);
        }
        self.queue.submit([encoder.finish()]);
        if let Some(e) = pollster::block_on(self.device.pop_error_scope()) {
            fail!(
                Gpu,
                "the GPU rejected the two-phase schedule: {}",
                super::error_chain(&e)
            );
        }
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| error!(Gpu, "GPU device lost: {e}"))?;
        self.seconds(queries, start.elapsed().as_secs_f64())
    }
}

/// Most workgroups the finish launches on `adapter`, unless its list needs more (each thread
/// takes at most `FINISH_RAYS_PER_THREAD` rays, fewer for compressed values). Each finish
/// thread takes another ray when its own is done, so a device that runs few workgroups at once
/// (a CPU adapter: about one a core, each running its SIMD groups one after another) gets only
/// as many, and their first groups share the list between them, no lane idle while rays are
/// left. A GPU, which runs far more threads at once than the finish has rays, gets a thread
/// per ray.
pub(super) fn finish_groups_for(adapter: &wgpu::AdapterInfo) -> u32 {
    if adapter.device_type == wgpu::DeviceType::Cpu {
        std::thread::available_parallelism().map_or(1, |n| n.get()) as u32
    } else {
        u32::MAX
    }
}

/// A pass of one dispatch of `pipeline`, `groups` workgroups.
fn direct_pass(
    encoder: &mut wgpu::CommandEncoder,
    pipeline: &wgpu::ComputePipeline,
    group: &wgpu::BindGroup,
    groups: u32,
    timestamps: Option<wgpu::ComputePassTimestampWrites>,
) {
    bound_pass(encoder, pipeline, group, timestamps).dispatch_workgroups(groups, 1, 1);
}

/// A pass of one indirect dispatch of `pipeline`, its group counts read from the head of the
/// counter block `count`.
fn indirect_pass(
    encoder: &mut wgpu::CommandEncoder,
    pipeline: &wgpu::ComputePipeline,
    group: &wgpu::BindGroup,
    count: &wgpu::Buffer,
    timestamps: Option<wgpu::ComputePassTimestampWrites>,
) {
    bound_pass(encoder, pipeline, group, timestamps).dispatch_workgroups_indirect(count, 0);
}

/// A compute pass with `pipeline` and its bind group set, ready for its dispatch.
fn bound_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    pipeline: &wgpu::ComputePipeline,
    group: &wgpu::BindGroup,
    timestamps: Option<wgpu::ComputePassTimestampWrites>,
) -> wgpu::ComputePass<'e> {
    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: None,
        timestamp_writes: timestamps,
    });
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, group, &[]);
    pass
}
