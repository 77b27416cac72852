//! The GPU backend: headless wgpu compute running the rust-gpu kernels (built from `kernel/` by
//! the build script and embedded here) on whatever adapter exists, lavapipe included.

use std::time::Instant;

use anyhow::{bail, Context, Result};
use gridrt_shared::grid_index::MICRO_TRIANGLES;
use gridrt_shared::layout::{FrameParams, HitRecord, RayRecord, TraceParams, TRACE_WORKGROUP_SIZE, WORKGROUP_SIZE};
use wgpu::util::DeviceExt;

use crate::scene::Scene;

/// The SPIR-V module of the `kernel` crate.
pub const KERNEL_SPV: &[u8] = include_bytes!(env!("kernel.spv"));

/// One representation's pipelines: an image renderer and a ray-list tracer.
struct Pipelines {
    render: wgpu::ComputePipeline,
    trace: wgpu::ComputePipeline,
}

pub struct Gpu {
    device: wgpu::Device,
    queue: wgpu::Queue,
    limits: wgpu::Limits,
    timestamps: bool,
    pub adapter: wgpu::AdapterInfo,
    triangles: Pipelines,
    grids: Pipelines,
}

/// A scene's geometry in GPU buffers, uploaded once and traced many times.
pub struct GpuScene<'a> {
    scene: &'a Scene,
    buffers: Vec<wgpu::Buffer>,
}

/// wgpu found no adapter at all: the one GPU failure that falling back to the CPU answers.
#[derive(Debug)]
pub struct NoAdapter(pub String);

impl std::fmt::Display for NoAdapter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "no GPU adapter found ({}); install a Vulkan driver (Debian: mesa-vulkan-drivers libvulkan1) or use \
             --backend cpu",
            self.0
        )
    }
}

impl std::error::Error for NoAdapter {}

/// How a dispatch was timed.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Timing {
    /// GPU timestamp queries around the compute pass.
    Timestamps,
    /// Wall time from submission to completion (the adapter has no timestamp queries).
    FenceToFence,
}

impl Gpu {
    /// Opens the first adapter wgpu finds (a real GPU before a software one). Fails with a
    /// message saying what to do when there is none.
    pub fn new() -> Result<Gpu> {
        quiet_device_select_layer();
        let instance = wgpu::Instance::new(&wgpu::InstanceDescriptor {
            backends: wgpu::Backends::from_env().unwrap_or(wgpu::Backends::PRIMARY),
            ..Default::default()
        });
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
        }))
        .map_err(|e| NoAdapter(e.to_string()))?;
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
        .context("cannot open the GPU device")?;
        // Validation errors become `Err`s here instead of wgpu's default panic.
        device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("kernel"),
            source: wgpu::util::make_spirv(KERNEL_SPV),
        });
        let pipeline = |entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: None,
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let triangles = Pipelines {
            render: pipeline("render_triangles"),
            trace: pipeline("trace_triangles_rays"),
        };
        let grids = Pipelines {
            render: pipeline("render_grids"),
            trace: pipeline("trace_grids_rays"),
        };
        if let Some(e) = pollster::block_on(device.pop_error_scope()) {
            bail!("the GPU driver rejected the gridrt kernels: {}", error_chain(&e));
        }
        Ok(Gpu {
            adapter: adapter.get_info(),
            device,
            queue,
            limits,
            timestamps,
            triangles,
            grids,
        })
    }

    /// One line naming the adapter, e.g. `llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, Cpu)`.
    pub fn describe(&self) -> String {
        format!(
            "{} ({:?}, {:?})",
            self.adapter.name, self.adapter.backend, self.adapter.device_type
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

    /// Refuses, before any work, an image this adapter cannot render in one dispatch: its
    /// pixels must fit in one storage buffer and its workgroups in the dispatch limits.
    pub fn check_image(&self, width: u32, height: u32) -> Result<()> {
        let bytes = width as u64 * height as u64 * 4;
        let limit = self.buffer_limit();
        if bytes > limit {
            bail!(
                "a {width}x{height} image needs {bytes} bytes on the GPU, more than the {limit} bytes this GPU ({}) \
                 allows in one storage buffer; render a smaller image or use --backend cpu",
                self.adapter.name
            );
        }
        let groups = self.limits.max_compute_workgroups_per_dimension as u64 * WORKGROUP_SIZE as u64;
        if width as u64 > groups || height as u64 > groups {
            bail!(
                "a {width}x{height} image is wider or taller than the {groups} pixels this GPU ({}) dispatches at \
                 once; render a smaller image or use --backend cpu",
                self.adapter.name
            );
        }
        Ok(())
    }

    fn buffer_limit(&self) -> u64 {
        (self.limits.max_storage_buffer_binding_size as u64).min(self.limits.max_buffer_size)
    }

    fn check_size(&self, name: &str, bytes: u64) -> Result<()> {
        let limit = self.buffer_limit();
        if bytes > limit {
            bail!(
                "the {name} buffer needs {bytes} bytes, more than the {limit} bytes this GPU ({}) allows in one \
                 storage buffer; use fewer levels, fewer rays or --backend cpu",
                self.adapter.name
            );
        }
        Ok(())
    }

    fn storage(&self, name: &str, bytes: &[u8]) -> Result<wgpu::Buffer> {
        self.check_size(name, bytes.len() as u64)?;
        // wgpu rejects zero-sized bindings; an empty area still needs a placeholder.
        let contents: &[u8] = if bytes.is_empty() { &[0; 16] } else { bytes };
        Ok(self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(name),
            contents,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        }))
    }

    fn output(&self, name: &str, bytes: u64) -> Result<(wgpu::Buffer, wgpu::Buffer)> {
        self.check_size(name, bytes)?;
        let make = |usage| {
            self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(name),
                size: bytes.max(16),
                usage,
                mapped_at_creation: false,
            })
        };
        Ok((
            make(wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC),
            make(wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST),
        ))
    }

    /// Uploads a scene's geometry, in the binding order the kernels expect after their
    /// parameters (binding 0).
    pub fn upload<'a>(&self, scene: &'a Scene) -> Result<GpuScene<'a>> {
        let buffers = match scene {
            Scene::Triangles(s) => vec![
                self.storage("BVH", bytemuck::cast_slice(&s.nodes))?,
                self.storage("vertex", bytemuck::cast_slice(&s.positions))?,
                self.storage("index", bytemuck::cast_slice(&s.indices))?,
            ],
            Scene::Grids(s) => vec![
                self.storage("top-level BVH", bytemuck::cast_slice(&s.nodes))?,
                self.storage("grid header", bytemuck::cast_slice(&s.headers))?,
                self.storage("grid vertex", bytemuck::cast_slice(&s.vertices))?,
                self.storage("sphere radius", bytemuck::cast_slice(&s.radii))?,
                self.storage("static index list", bytemuck::cast_slice(&MICRO_TRIANGLES))?,
            ],
        };
        Ok(GpuScene { scene, buffers })
    }

    fn pipelines(&self, scene: &Scene) -> &Pipelines {
        match scene {
            Scene::Triangles(_) => &self.triangles,
            Scene::Grids(_) => &self.grids,
        }
    }

    fn bind(&self, pipeline: &wgpu::ComputePipeline, buffers: &[&wgpu::Buffer]) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &pipeline.get_bind_group_layout(0),
            entries: &entries,
        })
    }

    /// Encodes one dispatch (optionally between two timestamps), submits it and waits.
    fn dispatch(
        &self,
        pipeline: &wgpu::ComputePipeline,
        bind_group: &wgpu::BindGroup,
        groups: (u32, u32),
        copy: Option<(&wgpu::Buffer, &wgpu::Buffer, u64)>,
        queries: Option<&(wgpu::QuerySet, wgpu::Buffer, wgpu::Buffer)>,
    ) -> Result<()> {
        self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let mut encoder = self.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: None,
                timestamp_writes: queries.map(|(set, _, _)| wgpu::ComputePassTimestampWrites {
                    query_set: set,
                    beginning_of_pass_write_index: Some(0),
                    end_of_pass_write_index: Some(1),
                }),
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, bind_group, &[]);
            pass.dispatch_workgroups(groups.0, groups.1, 1);
        }
        if let Some((set, resolve, readback)) = queries {
            encoder.resolve_query_set(set, 0..2, resolve, 0);
            encoder.copy_buffer_to_buffer(resolve, 0, readback, 0, 16);
        }
        if let Some((from, to, bytes)) = copy {
            encoder.copy_buffer_to_buffer(from, 0, to, 0, bytes);
        }
        self.queue.submit([encoder.finish()]);
        if let Some(e) = pollster::block_on(self.device.pop_error_scope()) {
            bail!("the GPU rejected the dispatch: {}", error_chain(&e));
        }
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .context("GPU device lost")?;
        Ok(())
    }

    /// Renders one frame; packed RGBA8, row-major, top row first (as `render_cpu`).
    pub fn render(&self, scene: &Scene, frame: &FrameParams) -> Result<Vec<u32>> {
        let uploaded = self.upload(scene)?;
        self.render_uploaded(&uploaded, frame)
    }

    pub fn render_uploaded(&self, scene: &GpuScene, frame: &FrameParams) -> Result<Vec<u32>> {
        let (w, h) = (frame.camera.width, frame.camera.height);
        let bytes = w as u64 * h as u64 * 4;
        let params = self.storage("frame parameters", bytemuck::bytes_of(frame))?;
        let (image, readback) = self.output("image", bytes)?;
        let pipeline = &self.pipelines(scene.scene).render;
        let mut buffers = vec![&params];
        buffers.extend(scene.buffers.iter());
        buffers.push(&image);
        let bind_group = self.bind(pipeline, &buffers);
        let groups = (w.div_ceil(WORKGROUP_SIZE), h.div_ceil(WORKGROUP_SIZE));
        self.dispatch(pipeline, &bind_group, groups, Some((&image, &readback, bytes)), None)?;
        self.read_back(&readback, bytes)
    }

    /// Workgroup grid and parameters for `count` rays.
    fn trace_params(&self, scene: &Scene, count: u32) -> ((u32, u32), TraceParams) {
        let groups = count.div_ceil(TRACE_WORKGROUP_SIZE).max(1);
        let x = groups.min(self.limits.max_compute_workgroups_per_dimension.min(32768));
        let y = groups.div_ceil(x);
        let params = TraceParams {
            grid: match scene {
                Scene::Triangles(_) => Default::default(),
                Scene::Grids(s) => s.params,
            },
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

    /// Traces `rays` `repeats` times; returns the hits and the seconds of each repetition,
    /// measured as [`Gpu::timing`] says.
    pub fn time_trace(
        &self,
        scene: &GpuScene,
        rays: &[RayRecord],
        repeats: usize,
    ) -> Result<(Vec<HitRecord>, Vec<f64>)> {
        let count = u32::try_from(rays.len()).context("too many rays for one dispatch")?;
        let ((x, y), params) = self.trace_params(scene.scene, count);
        let params = self.storage("trace parameters", bytemuck::bytes_of(&params))?;
        let ray_buffer = self.storage("ray", bytemuck::cast_slice(rays))?;
        let bytes = rays.len() as u64 * std::mem::size_of::<HitRecord>() as u64;
        let (hits, readback) = self.output("hit", bytes)?;
        let pipeline = &self.pipelines(scene.scene).trace;
        let mut buffers = vec![&params];
        buffers.extend(scene.buffers.iter());
        buffers.extend([&ray_buffer, &hits]);
        let bind_group = self.bind(pipeline, &buffers);
        let queries = self.timestamps.then(|| {
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
            (
                set,
                make(wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC),
                make(wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST),
            )
        });
        let period = self.queue.get_timestamp_period() as f64 * 1e-9;
        let mut seconds = Vec::with_capacity(repeats);
        for k in 0..repeats.max(1) {
            let last = k + 1 == repeats.max(1);
            let copy = last.then_some((&hits, &readback, bytes));
            let start = Instant::now();
            self.dispatch(pipeline, &bind_group, (x, y), copy, queries.as_ref())?;
            let wall = start.elapsed().as_secs_f64();
            seconds.push(match &queries {
                Some((_, _, ts)) => {
                    let t: Vec<u64> = bytemuck::cast_slice(&self.read_back_bytes(ts, 16)?).to_vec();
                    t[1].saturating_sub(t[0]) as f64 * period
                }
                None => wall,
            });
        }
        let hits = bytemuck::cast_slice(&self.read_back_bytes(&readback, bytes)?).to_vec();
        Ok((hits, seconds))
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
            .context("GPU device lost while reading back")?;
        rx.recv()?.context("cannot read back from the GPU")?;
        let data = slice.get_mapped_range().to_vec();
        buffer.unmap();
        Ok(data)
    }
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
