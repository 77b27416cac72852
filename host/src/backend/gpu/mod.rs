//! The GPU backend: headless wgpu compute running the rust-gpu kernels (built from `kernel/` by
//! the build script and embedded here) on whatever adapter exists, lavapipe included.

mod kernels;
mod turns;

pub use turns::TimedList;

use crate::error::{error, fail, Error, Result};
use gridrt_shared::buffer::SPLIT_CHUNKS;
use gridrt_shared::grid_index::MICRO_TRIANGLES;
use gridrt_shared::layout::{
    FrameParams, GridParams, HitRecord, RayRecord, SplitParams, TraceParams, RENDER_WORKGROUP, SHADE_COST,
    TRACE_WORKGROUP_SIZE,
};
use wgpu::util::DeviceExt;

use crate::limits::parse_bytes;
use crate::limits::{self, BufferSize};
use crate::scene::Scene;
use crate::split::{check_chunks, chunk_words, scene_buffers, split};

/// The SPIR-V module of the `kernel` crate.
pub const KERNEL_SPV: &[u8] = include_bytes!(env!("kernel.spv"));

use kernels::{Job, Kernel, PIPELINES};

pub struct Gpu {
    device: wgpu::Device,
    queue: wgpu::Queue,
    limits: wgpu::Limits,
    /// Largest buffer a binding takes: the adapter's limit, or a smaller one asked for.
    binding_limit: u64,
    timestamps: bool,
    pub adapter: wgpu::AdapterInfo,
    module: wgpu::ShaderModule,
    /// The pipelines (see [`Kernel`]), each made the first time it runs but the plain scenes'
    /// on whole buffers, made when the device opens: the split ones bind more buffers than
    /// some adapters allow, and all take drivers long to compile.
    pipelines: [std::sync::OnceLock<wgpu::ComputePipeline>; PIPELINES],
}

/// A scene's geometry in GPU buffers, uploaded once and traced many times.
pub struct GpuScene {
    /// The kernel of each job ([`Job::Render`], [`Job::Trace`]) for this scene.
    kernels: [Kernel; 2],
    /// Plain and displaced grids' parameters (zeros for triangles).
    grid: GridParams,
    /// The scene's bindings in set 0, after the kernel's own.
    buffers: Vec<wgpu::Buffer>,
    /// A split scene's chunks (set 1) and where its buffers lie among them.
    chunks: Option<(Vec<wgpu::Buffer>, SplitParams)>,
}

impl GpuScene {
    /// Whether the scene is split over several bindings per buffer.
    pub fn is_split(&self) -> bool {
        self.chunks.is_some()
    }

    fn split_params(&self) -> SplitParams {
        self.chunks.as_ref().map(|c| c.1).unwrap_or_default()
    }

    fn kernel(&self, job: Job) -> Kernel {
        self.kernels[(job == Job::Trace) as usize]
    }

    fn new(scene: &Scene, buffers: Vec<wgpu::Buffer>, chunks: Option<(Vec<wgpu::Buffer>, SplitParams)>) -> GpuScene {
        let split = chunks.is_some();
        GpuScene {
            kernels: [Job::Render, Job::Trace].map(|job| Kernel::of(scene, job, split)),
            grid: match scene {
                Scene::Triangles(_) => GridParams::default(),
                Scene::Grids(grids) => grids.params,
            },
            buffers,
            chunks,
        }
    }
}

/// How a dispatch was timed.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Timing {
    /// GPU timestamp queries around the compute pass.
    Timestamps,
    /// Wall time from submission to completion (the adapter has no timestamp queries).
    FenceToFence,
}

/// Storage buffers a split kernel binds: its chunks and at most four of its own.
const SPLIT_BINDINGS: u32 = SPLIT_CHUNKS + 4;

/// Environment variable that lowers the largest buffer gridrt binds on the GPU (e.g. `1M`):
/// to try the split path, and tiled dispatches, on a small scene.
pub const BINDING_LIMIT_VAR: &str = "GRIDRT_GPU_BINDING_LIMIT";

/// Smallest binding limit that can be asked for: a tile of one row of a wide image and a node
/// must fit.
const MIN_BINDING_LIMIT: u64 = 1 << 10;

impl Gpu {
    /// Opens the first adapter wgpu finds (a real GPU before a software one). Fails with a
    /// message saying what to do when there is none.
    pub fn new() -> Result<Gpu> {
        quiet_device_select_layer();
        let instance = wgpu::Instance::new(&wgpu::InstanceDescriptor {
            backends: wgpu::Backends::from_env().unwrap_or(wgpu::Backends::PRIMARY),
            flags: instance_flags(),
            ..Default::default()
        });
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
        }))
        .map_err(|e| {
            error!(
                NoGpu,
                "no GPU adapter found ({e}); install a Vulkan driver (Debian: mesa-vulkan-drivers libvulkan1) or use \
                 --backend cpu"
            )
        })?;
        let limits = adapter.limits();
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("gridrt"),
            required_features: if timestamps {
                wgpu::Features::TIMESTAMP_QUERY
            } else {
                wgpu::Features::empty()
            },
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| error!(Gpu, "cannot open the GPU device: {e}"))?;
        // Validation errors become `Err`s here instead of wgpu's default panic.
        device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("kernel"),
            source: wgpu::util::make_spirv(KERNEL_SPV),
        });
        let pipelines: [std::sync::OnceLock<wgpu::ComputePipeline>; PIPELINES] =
            std::array::from_fn(|_| Default::default());
        for kernel in kernels::made_at_start() {
            let _ = pipelines[kernel.slot].set(compute_pipeline(&device, &module, &kernel));
        }
        if let Some(e) = pollster::block_on(device.pop_error_scope()) {
            fail!(Gpu, "the GPU driver rejected the gridrt kernels: {}", error_chain(&e));
        }
        let mut gpu = Gpu {
            adapter: adapter.get_info(),
            binding_limit: (limits.max_storage_buffer_binding_size as u64).min(limits.max_buffer_size),
            device,
            queue,
            limits,
            timestamps,
            module,
            pipelines,
        };
        if let Some(value) = std::env::var_os(BINDING_LIMIT_VAR) {
            let text = value.to_string_lossy();
            let bytes = parse_bytes(&text).ok_or_else(|| {
                error!(
                    Options,
                    "{BINDING_LIMIT_VAR}={text} is not a size in bytes (such as 64K or 1M)"
                )
            })?;
            gpu.limit_bindings(bytes)?;
        }
        Ok(gpu)
    }

    /// Binds no buffer larger than `bytes` (at least 1 KiB), below the adapter's own limit:
    /// larger scenes are split, images rendered in more tiles and ray lists in more batches.
    pub fn limit_bindings(&mut self, bytes: u64) -> Result<()> {
        if bytes < MIN_BINDING_LIMIT {
            fail!(
                Options,
                "a binding limit of {bytes} bytes is below the smallest gridrt takes, {MIN_BINDING_LIMIT} bytes"
            );
        }
        self.binding_limit = self.binding_limit.min(bytes);
        Ok(())
    }

    /// One line naming the adapter, e.g. `llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, Cpu)`.
    pub fn describe(&self) -> String {
        format!(
            "{} ({:?}, {:?})",
            self.adapter.name, self.adapter.backend, self.adapter.device_type
        )
    }

    /// The adapter and the limits that decide how a scene is bound, for messages.
    fn describe_limits(&self) -> String {
        format!(
            "this GPU ({}: at most {} bytes per binding, {} storage buffers per shader stage)",
            self.adapter.name, self.binding_limit, self.limits.max_storage_buffers_per_shader_stage
        )
    }

    /// How [`Gpu::time_trace`] measures on this adapter.
    pub fn timing(&self) -> Timing {
        if self.timestamps {
            Timing::Timestamps
        } else {
            Timing::FenceToFence
        }
    }

    /// Refuses a split scene on an adapter that cannot bind one.
    fn check_split_bindings(&self) -> Result<()> {
        let allowed = self.limits.max_storage_buffers_per_shader_stage;
        if allowed < SPLIT_BINDINGS || self.limits.max_bind_groups < 2 {
            fail!(
                Limits,
                "the scene is larger than one binding of {}, and reading it in chunks takes {SPLIT_BINDINGS} storage \
                 buffers in two bind groups; use fewer levels or --backend cpu",
                self.describe_limits()
            );
        }
        Ok(())
    }

    /// The pipeline that runs `job` on `scene` (see [`Kernel::of`]), with smooth normals
    /// where a render asks for them, made on first use.
    fn pipeline(&self, scene: &GpuScene, job: Job, smooth: bool) -> Result<&wgpu::ComputePipeline> {
        let kernel = if smooth {
            scene.kernel(job).lit_smooth()
        } else {
            scene.kernel(job)
        };
        if let Some(p) = self.pipelines[kernel.slot].get() {
            return Ok(p);
        }
        if scene.is_split() {
            self.check_split_bindings()?;
        }
        self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let pipeline = compute_pipeline(&self.device, &self.module, &kernel);
        if let Some(e) = pollster::block_on(self.device.pop_error_scope()) {
            fail!(
                Gpu,
                "the GPU driver rejected the gridrt kernel {}: {}",
                kernel.entry,
                error_chain(&e)
            );
        }
        Ok(self.pipelines[kernel.slot].get_or_init(|| pipeline))
    }

    fn buffer(&self, name: &str, contents: &[u8]) -> wgpu::Buffer {
        // wgpu rejects zero-sized bindings; an empty area still needs a placeholder.
        let contents: &[u8] = if contents.is_empty() { &[0; 16] } else { contents };
        self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(name),
            contents,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        })
    }

    /// A storage buffer and the buffer it is read back through.
    fn output(&self, name: &str, bytes: u64) -> (wgpu::Buffer, wgpu::Buffer) {
        let make = |usage| {
            self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(name),
                size: bytes.max(16),
                usage,
                mapped_at_creation: false,
            })
        };
        (
            make(wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC),
            make(wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST),
        )
    }

    /// Host bytes an upload of `bytes` of scene buffers costs besides the scene itself: on a
    /// device that is the CPU (lavapipe) the driver's buffers, and the copies made on the way
    /// to them, live in host memory (measured, docs/RESULTS.md "Scale"); elsewhere nothing
    /// counted here.
    pub fn host_upload_bytes(&self, bytes: u64) -> u64 {
        match self.adapter.device_type {
            wgpu::DeviceType::Cpu => bytes
                .saturating_mul(limits::CPU_DEVICE_COPIES)
                .saturating_add(limits::CPU_DEVICE_BYTES),
            _ => 0,
        }
    }

    /// Refuses, before it is built, a scene whose buffers will be at least `sizes` and cannot
    /// be bound on this adapter: the check [`Gpu::upload`] makes on the built scene. With
    /// `whole_only` (displaced grids' formats, see [`Scene::needs_whole_bindings`]) every buffer
    /// must fit in one binding.
    pub fn check_fits(&self, sizes: &[BufferSize], whole_only: bool) -> Result<()> {
        if self.binds_whole(sizes) {
            return Ok(());
        }
        if whole_only {
            return Err(self.refusing_split(sizes));
        }
        self.check_split_bindings()?;
        check_chunks(
            sizes,
            chunk_words(self.binding_limit),
            SPLIT_CHUNKS,
            &self.describe_limits(),
        )
    }

    /// Why a scene in displaced grids' formats whose buffers do not fit one binding each is
    /// refused: no kernel reads those formats in chunks (each read of a split scene branches
    /// over its chunks, and their decoders read at many places).
    fn refusing_split(&self, sizes: &[BufferSize]) -> Error {
        let too_large: Vec<String> = (sizes.iter())
            .filter(|b| b.bytes > self.binding_limit)
            .map(|b| format!("the {} buffer needs {}", b.name, b.bytes_text()))
            .collect();
        error!(
            Limits,
            "{}, more than one binding of {} holds, and displaced grids are read from whole bindings only; \
             use fewer levels or --backend cpu",
            too_large.join(", "),
            self.describe_limits()
        )
    }

    /// Whether every buffer fits in one binding, so that none need be split.
    fn binds_whole(&self, sizes: &[BufferSize]) -> bool {
        sizes.iter().all(|b| b.bytes <= self.binding_limit)
    }

    /// Uploads a scene's geometry: each buffer in one binding when every one fits, otherwise
    /// all of them in chunks (see [`crate::split`]). What cannot be bound is refused, naming
    /// the buffers and this adapter's limits, before anything is uploaded.
    pub fn upload(&self, scene: &Scene) -> Result<GpuScene> {
        let buffers = scene_buffers(scene);
        let statics = match scene {
            Scene::Triangles(_) => vec![],
            Scene::Grids(_) => vec![self.buffer("static index list", bytemuck::cast_slice(&MICRO_TRIANGLES))],
        };
        let sizes: Vec<BufferSize> = buffers.iter().map(|b| b.size()).collect();
        if self.binds_whole(&sizes) {
            let mut all = statics;
            all.extend(
                buffers
                    .iter()
                    .map(|b| self.buffer(b.name, bytemuck::cast_slice(b.words))),
            );
            return Ok(GpuScene::new(scene, all, None));
        }
        self.check_fits(&sizes, scene.needs_whole_bindings())?;
        let split = split(scene, chunk_words(self.binding_limit), &self.describe_limits())?;
        let mut chunks: Vec<wgpu::Buffer> = (split.chunks.iter())
            .map(|c| self.buffer("scene chunk", bytemuck::cast_slice(c)))
            .collect();
        chunks.resize_with(SPLIT_CHUNKS as usize, || self.buffer("unused chunk", &[]));
        Ok(GpuScene::new(scene, statics, Some((chunks, split.params))))
    }

    /// Bind groups of a dispatch: the kernel's own buffers `own`, then the scene's.
    fn bind(&self, pipeline: &wgpu::ComputePipeline, own: &[&wgpu::Buffer], scene: &GpuScene) -> Vec<wgpu::BindGroup> {
        let mut set0 = own.to_vec();
        set0.extend(scene.buffers.iter());
        let mut groups = vec![self.bind_group(pipeline, 0, &set0)];
        if let Some((chunks, _)) = &scene.chunks {
            let set1: Vec<&wgpu::Buffer> = chunks.iter().collect();
            groups.push(self.bind_group(pipeline, 1, &set1));
        }
        groups
    }

    /// A bind group of `buffers` at bindings 0, 1, ... of set `set`.
    fn bind_group(&self, pipeline: &wgpu::ComputePipeline, set: u32, buffers: &[&wgpu::Buffer]) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = (buffers.iter().enumerate())
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &pipeline.get_bind_group_layout(set),
            entries: &entries,
        })
    }

    /// Encodes one dispatch (optionally between two timestamps), submits it and waits.
    fn dispatch(&self, job: &Dispatch) -> Result<()> {
        self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let mut encoder = self.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: None,
                timestamp_writes: job.queries.map(|q| wgpu::ComputePassTimestampWrites {
                    query_set: &q.set,
                    beginning_of_pass_write_index: Some(0),
                    end_of_pass_write_index: Some(1),
                }),
            });
            pass.set_pipeline(job.pipeline);
            for (set, group) in job.bind_groups.iter().enumerate() {
                pass.set_bind_group(set as u32, group, &[]);
            }
            pass.dispatch_workgroups(job.groups.0, job.groups.1, 1);
        }
        if let Some(q) = job.queries {
            encoder.resolve_query_set(&q.set, 0..2, &q.resolve, 0);
            encoder.copy_buffer_to_buffer(&q.resolve, 0, &q.readback, 0, 16);
        }
        if let Some((from, to, bytes)) = job.copy {
            encoder.copy_buffer_to_buffer(from, 0, to, 0, bytes);
        }
        self.queue.submit([encoder.finish()]);
        if let Some(e) = pollster::block_on(self.device.pop_error_scope()) {
            fail!(Gpu, "the GPU rejected the dispatch: {}", error_chain(&e));
        }
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| error!(Gpu, "GPU device lost: {e}"))?;
        Ok(())
    }

    /// Renders one frame; packed RGBA8, row-major, top row first (as `render_cpu`).
    pub fn render(&self, scene: &Scene, frame: &FrameParams) -> Result<Vec<u32>> {
        let uploaded = self.upload(scene)?;
        self.render_uploaded(&uploaded, frame)
    }

    /// Largest tile (width, height) one dispatch renders: its pixels in one binding, its
    /// workgroups within the dispatch limits.
    fn tile_size(&self, width: u32, height: u32) -> (u32, u32) {
        let groups = self.limits.max_compute_workgroups_per_dimension as u64;
        let [gx, gy] = RENDER_WORKGROUP.map(u64::from);
        let pixels = self.binding_limit / 4;
        let w = (width as u64).min(groups * gx).min(pixels);
        let h = (height as u64).min(groups * gy).min(pixels / w);
        (w as u32, h as u32)
    }

    /// Renders a frame in tiles, each into a buffer of its own read back into the image.
    pub fn render_uploaded(&self, scene: &GpuScene, frame: &FrameParams) -> Result<Vec<u32>> {
        let (width, height) = (frame.camera.width, frame.camera.height);
        let (tile_w, tile_h) = self.tile_size(width, height);
        let tile_bytes = tile_w as u64 * tile_h as u64 * 4;
        let params = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame parameters"),
            size: std::mem::size_of::<FrameParams>() as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let (tile, readback) = self.output("image tile", tile_bytes);
        if frame.shading == SHADE_COST {
            fail!(
                Options,
                "the cost heat map is counted on the CPU (Backend::render_costs), not by a GPU kernel"
            );
        }
        let pipeline = self.pipeline(scene, Job::Render, frame.smooth_normals != 0)?;
        let bind_groups = self.bind(pipeline, &[&params, &tile], scene);
        let mut image = vec![0u32; width as usize * height as usize];
        for y in (0..height).step_by(tile_h as usize) {
            for x in (0..width).step_by(tile_w as usize) {
                let (w, h) = (tile_w.min(width - x), tile_h.min(height - y));
                let tile_frame = FrameParams {
                    split: scene.split_params(),
                    tile_x: x,
                    tile_y: y,
                    tile_width: w,
                    tile_height: h,
                    ..*frame
                };
                self.queue.write_buffer(&params, 0, bytemuck::bytes_of(&tile_frame));
                let bytes = w as u64 * h as u64 * 4;
                self.dispatch(&Dispatch {
                    pipeline,
                    bind_groups: &bind_groups,
                    groups: (w.div_ceil(RENDER_WORKGROUP[0]), h.div_ceil(RENDER_WORKGROUP[1])),
                    copy: Some((&tile, &readback, bytes)),
                    queries: None,
                })?;
                let pixels = self.read_back(&readback, bytes)?;
                for (row, line) in pixels.chunks(w as usize).enumerate() {
                    let at = (y as usize + row) * width as usize + x as usize;
                    image[at..at + w as usize].copy_from_slice(line);
                }
            }
        }
        Ok(image)
    }

    /// Rays one dispatch traces: their records and hits each in one binding, their
    /// workgroups within the dispatch limits.
    fn ray_batch(&self) -> usize {
        let per_binding = self.binding_limit / std::mem::size_of::<RayRecord>() as u64;
        let groups = self.limits.max_compute_workgroups_per_dimension as u64;
        let per_dispatch = groups * groups.min(32768) * TRACE_WORKGROUP_SIZE as u64;
        per_binding.min(per_dispatch).min(u32::MAX as u64) as usize
    }

    /// Workgroup grid and parameters for `count` rays.
    fn trace_params(&self, scene: &GpuScene, count: u32) -> ((u32, u32), TraceParams) {
        let groups = count.div_ceil(TRACE_WORKGROUP_SIZE).max(1);
        let x = groups.min(self.limits.max_compute_workgroups_per_dimension.min(32768));
        let y = groups.div_ceil(x);
        let params = TraceParams {
            grid: scene.grid,
            split: scene.split_params(),
            ray_count: count,
            threads_per_row: x * TRACE_WORKGROUP_SIZE,
            _pad: [0; 2],
        };
        ((x, y), params)
    }

    /// Traces a list of rays: closest hit of each.
    pub fn trace(&self, scene: &GpuScene, rays: &[RayRecord]) -> Result<Vec<HitRecord>> {
        let (hits, _) = self.time_trace(scene, rays, 1)?;
        Ok(hits)
    }

    /// Traces `rays` `repeats` times, in batches within the adapter's limits; returns the hits
    /// and the seconds of each repetition (all its batches), measured as [`Gpu::timing`] says.
    pub fn time_trace(
        &self,
        scene: &GpuScene,
        rays: &[RayRecord],
        repeats: usize,
    ) -> Result<(Vec<HitRecord>, Vec<f64>)> {
        let TimedList { hits, seconds } = self.time_traces(std::slice::from_ref(scene), rays, repeats)?.remove(0);
        Ok((hits, seconds))
    }

    /// Two timestamps around a compute pass, and the buffers they are read back through.
    fn queries(&self) -> Queries {
        let set = self.device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("trace timestamps"),
            ty: wgpu::QueryType::Timestamp,
            count: 2,
        });
        let make = |usage| {
            self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamps"),
                size: 16,
                usage,
                mapped_at_creation: false,
            })
        };
        Queries {
            set,
            resolve: make(wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC),
            readback: make(wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST),
        }
    }

    fn read_back(&self, buffer: &wgpu::Buffer, bytes: u64) -> Result<Vec<u32>> {
        Ok(bytemuck::cast_slice(&self.read_back_bytes(buffer, bytes)?).to_vec())
    }

    fn read_back_bytes(&self, buffer: &wgpu::Buffer, bytes: u64) -> Result<Vec<u8>> {
        let slice = buffer.slice(..bytes);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| error!(Gpu, "GPU device lost while reading back: {e}"))?;
        rx.recv()
            .map_err(|e| error!(Gpu, "cannot read back from the GPU: {e}"))?
            .map_err(|e| error!(Gpu, "cannot read back from the GPU: {e}"))?;
        let data = slice.get_mapped_range().to_vec();
        buffer.unmap();
        Ok(data)
    }
}

/// One compute dispatch: what runs, on what, and what is copied or timed after it.
struct Dispatch<'a> {
    pipeline: &'a wgpu::ComputePipeline,
    bind_groups: &'a [wgpu::BindGroup],
    groups: (u32, u32),
    /// `bytes` from the first buffer to the second after the pass.
    copy: Option<(&'a wgpu::Buffer, &'a wgpu::Buffer, u64)>,
    queries: Option<&'a Queries>,
}

/// Timestamp queries around a pass.
struct Queries {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    readback: wgpu::Buffer,
}

/// The pipeline of `kernel`, its layout taken from the shader.
fn compute_pipeline(device: &wgpu::Device, module: &wgpu::ShaderModule, kernel: &Kernel) -> wgpu::ComputePipeline {
    let carries = kernel.carries.map(|c| [("0", c as f64)]);
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(kernel.entry),
        layout: None,
        module,
        entry_point: Some(kernel.entry),
        compilation_options: wgpu::PipelineCompilationOptions {
            constants: carries.as_ref().map_or(&[], |c| &c[..]),
            ..Default::default()
        },
        cache: None,
    })
}

/// wgpu's instance flags for this build, as the environment adjusts them.
fn instance_flags() -> wgpu::InstanceFlags {
    wgpu::InstanceFlags::from_build_config().with_env()
}

/// Mesa's device-select Vulkan layer, on by default wherever Mesa's drivers are installed,
/// orders adapters by asking a Wayland compositor which GPU drives the display. Without a
/// session (`XDG_RUNTIME_DIR` unset: a server, a container, CI) the Wayland client library
/// prints "error: XDG_RUNTIME_DIR is invalid or not set" to stderr from inside it, twice,
/// on every successful run. wgpu chooses among the adapters itself, so the layer is switched
/// off there, through its own off switch, unless the user asked it to pick a device.
fn quiet_device_select_layer() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let unset = |name| std::env::var_os(name).is_none();
        if unset("XDG_RUNTIME_DIR") && unset("NODEVICE_SELECT") && unset("MESA_VK_DEVICE_SELECT") {
            // Before any Vulkan call of this process: the loader reads it when the instance is
            // made, and every `Gpu::new` passes through this `Once` first.
            std::env::set_var("NODEVICE_SELECT", "1");
        }
    });
}

/// A wgpu error with its causes on one line (its `Display` alone says only "Validation Error").
fn error_chain(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(cause) = source {
        text.push_str(": ");
        text.push_str(cause.to_string().trim());
        source = cause.source();
    }
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}
