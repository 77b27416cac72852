//! The GPU backend: headless wgpu compute running the rust-gpu kernels (built from `kernel/` by
//! the build script and embedded here) on whatever adapter exists, lavapipe included.

use anyhow::{anyhow, bail, Context, Result};
use gridrt_shared::layout::{FrameParams, WORKGROUP_SIZE};
use wgpu::util::DeviceExt;

use crate::scene::Scene;

/// The SPIR-V module of the `kernel` crate.
pub const KERNEL_SPV: &[u8] = include_bytes!(env!("kernel.spv"));

pub struct Gpu {
    device: wgpu::Device,
    queue: wgpu::Queue,
    limits: wgpu::Limits,
    pub adapter: wgpu::AdapterInfo,
    triangles: wgpu::ComputePipeline,
    grids: wgpu::ComputePipeline,
}

impl Gpu {
    /// Opens the first adapter wgpu finds (a real GPU before a software one). Fails with a
    /// message saying what to do when there is none.
    pub fn new() -> Result<Gpu> {
        let instance = wgpu::Instance::new(&wgpu::InstanceDescriptor {
            backends: wgpu::Backends::from_env().unwrap_or(wgpu::Backends::PRIMARY),
            ..Default::default()
        });
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
        }))
        .map_err(|e| {
            anyhow!(
                "no GPU adapter found ({e}); install a Vulkan driver (Debian: mesa-vulkan-drivers libvulkan1) \
                 or use --backend cpu"
            )
        })?;
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("gridrt"),
            required_features: wgpu::Features::empty(),
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
        let triangles = pipeline("render_triangles");
        let grids = pipeline("render_grids");
        if let Some(e) = pollster::block_on(device.pop_error_scope()) {
            bail!("the GPU driver rejected the gridrt kernels: {e}");
        }
        Ok(Gpu {
            adapter: adapter.get_info(),
            device,
            queue,
            limits,
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

    fn storage(&self, name: &str, bytes: &[u8]) -> Result<wgpu::Buffer> {
        let limit = (self.limits.max_storage_buffer_binding_size as u64).min(self.limits.max_buffer_size);
        if bytes.len() as u64 > limit {
            bail!(
                "the {name} buffer needs {} bytes, more than the {limit} bytes this GPU ({}) allows in one storage \
                 buffer; render fewer levels or use --backend cpu",
                bytes.len(),
                self.adapter.name
            );
        }
        // wgpu rejects zero-sized bindings; an empty area still needs a placeholder.
        let contents: &[u8] = if bytes.is_empty() { &[0; 16] } else { bytes };
        Ok(self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(name),
            contents,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        }))
    }

    /// Renders one frame; packed RGBA8, row-major, top row first (as `render_cpu`).
    pub fn render(&self, scene: &Scene, frame: &FrameParams) -> Result<Vec<u32>> {
        let (w, h) = (frame.camera.width, frame.camera.height);
        let pixels = (w as u64) * (h as u64);
        let out_bytes = pixels * 4;
        let params = self.storage("frame parameters", bytemuck::bytes_of(frame))?;
        let (pipeline, mut buffers) = match scene {
            Scene::Triangles(s) => (
                &self.triangles,
                vec![
                    params,
                    self.storage("BVH", bytemuck::cast_slice(&s.nodes))?,
                    self.storage("vertex", bytemuck::cast_slice(&s.positions))?,
                    self.storage("index", bytemuck::cast_slice(&s.indices))?,
                ],
            ),
            Scene::Grids(s) => (
                &self.grids,
                vec![
                    params,
                    self.storage("top-level BVH", bytemuck::cast_slice(&s.nodes))?,
                    self.storage("grid header", bytemuck::cast_slice(&s.headers))?,
                    self.storage("grid vertex", bytemuck::cast_slice(&s.vertices))?,
                    self.storage("sphere radius", bytemuck::cast_slice(&s.radii))?,
                ],
            ),
        };
        if out_bytes > self.limits.max_storage_buffer_binding_size as u64 {
            bail!("a {w}x{h} image is larger than this GPU's storage buffer limit");
        }
        let output = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("image"),
            size: out_bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let readback = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("image readback"),
            size: out_bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        buffers.push(output);
        let layout = pipeline.get_bind_group_layout(0);
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        let bind_group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &layout,
            entries: &entries,
        });
        self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let mut encoder = self.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.dispatch_workgroups(w.div_ceil(WORKGROUP_SIZE), h.div_ceil(WORKGROUP_SIZE), 1);
        }
        encoder.copy_buffer_to_buffer(buffers.last().unwrap(), 0, &readback, 0, out_bytes);
        self.queue.submit([encoder.finish()]);
        if let Some(e) = pollster::block_on(self.device.pop_error_scope()) {
            bail!("the GPU rejected the render: {e}");
        }
        self.read_back(&readback)
    }

    fn read_back(&self, buffer: &wgpu::Buffer) -> Result<Vec<u32>> {
        let slice = buffer.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .context("GPU device lost while rendering")?;
        rx.recv()?.context("cannot read the image back from the GPU")?;
        let data = bytemuck::cast_slice(&slice.get_mapped_range()).to_vec();
        buffer.unmap();
        Ok(data)
    }
}
