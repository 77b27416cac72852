//! Where rays are traced: the CPU (rayon over the same `gridrt_shared` code the kernels run)
//! or, built with the `gpu` feature (on by default), a wgpu adapter. One type, so that the
//! choice between them is made in one place.

use std::time::Instant;

use anyhow::Result;
use gridrt_shared::layout::{FrameParams, HitRecord, RayRecord};

#[cfg(feature = "gpu")]
use crate::gpu::{Gpu, NoAdapter, Timing};
use crate::limits::BufferSize;
use crate::rays::trace_cpu;
use crate::scene::{render_cpu, Scene};

/// Which device the user asks for.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum DeviceChoice {
    /// The GPU if wgpu finds an adapter, otherwise the CPU.
    Auto,
    Gpu,
    Cpu,
}

pub enum Device {
    Cpu,
    #[cfg(feature = "gpu")]
    Gpu(Box<Gpu>),
}

impl Device {
    /// The device `choice` asks for: for `auto`, the CPU (with a note saying the CPU does the
    /// `work`) when wgpu finds no adapter at all. Any other GPU failure is an error.
    pub fn open(choice: DeviceChoice, work: &str) -> Result<Device> {
        match choice {
            DeviceChoice::Cpu => Ok(Device::Cpu),
            #[cfg(feature = "gpu")]
            DeviceChoice::Gpu => Ok(Device::Gpu(Box::new(Gpu::new()?))),
            #[cfg(feature = "gpu")]
            DeviceChoice::Auto => match Gpu::new() {
                Ok(gpu) => Ok(Device::Gpu(Box::new(gpu))),
                Err(e) if e.is::<NoAdapter>() => {
                    eprintln!("note: {e}; {work} on the CPU");
                    Ok(Device::Cpu)
                }
                Err(e) => Err(e),
            },
            #[cfg(not(feature = "gpu"))]
            DeviceChoice::Gpu => anyhow::bail!("this gridrt was built without the `gpu` feature; use --backend cpu"),
            #[cfg(not(feature = "gpu"))]
            DeviceChoice::Auto => {
                let _ = work; // no GPU to fall back from
                Ok(Device::Cpu)
            }
        }
    }

    /// `cpu` or `gpu`.
    pub fn kind(&self) -> &'static str {
        match self {
            Device::Cpu => "cpu",
            #[cfg(feature = "gpu")]
            Device::Gpu(_) => "gpu",
        }
    }

    /// One line naming the device.
    pub fn describe(&self) -> String {
        match self {
            Device::Cpu => format!("CPU, {} threads", rayon::current_num_threads()),
            #[cfg(feature = "gpu")]
            Device::Gpu(gpu) => gpu.describe(),
        }
    }

    /// How [`Device::time_trace`] measures.
    pub fn timing(&self) -> &'static str {
        match self {
            Device::Cpu => "wall clock",
            #[cfg(feature = "gpu")]
            Device::Gpu(gpu) => match gpu.timing() {
                Timing::Timestamps => "GPU timestamp queries",
                Timing::FenceToFence => "fence to fence (no timestamp queries on this adapter)",
            },
        }
    }

    /// Host bytes that handing `bytes` of scene buffers to this device costs besides the scene
    /// itself (none on the CPU backend).
    pub fn host_upload_bytes(&self, bytes: u64) -> u64 {
        match self {
            Device::Cpu => {
                let _ = bytes;
                0
            }
            #[cfg(feature = "gpu")]
            Device::Gpu(gpu) => gpu.host_upload_bytes(bytes),
        }
    }

    /// Refuses, before it is built, a scene whose buffers will be at least `sizes` and cannot
    /// be bound on this device (the CPU takes any).
    pub fn check_fits(&self, sizes: &[BufferSize]) -> Result<()> {
        match self {
            Device::Cpu => {
                let _ = sizes;
                Ok(())
            }
            #[cfg(feature = "gpu")]
            Device::Gpu(gpu) => gpu.check_fits(sizes),
        }
    }

    /// Renders one frame: packed RGBA8, row-major, top row first.
    pub fn render(&self, scene: &Scene, frame: &FrameParams) -> Result<Vec<u32>> {
        match self {
            Device::Cpu => Ok(render_cpu(scene, frame)),
            #[cfg(feature = "gpu")]
            Device::Gpu(gpu) => gpu.render(scene, frame),
        }
    }

    /// Traces `rays` `warmup + repeats` times: the hits of the last run and the seconds of
    /// each timed (after the warm-up) run.
    pub fn time_trace(
        &self,
        scene: &Scene,
        rays: &[RayRecord],
        warmup: usize,
        repeats: usize,
    ) -> Result<(Vec<HitRecord>, Vec<f64>)> {
        match self {
            Device::Cpu => {
                let mut hits = Vec::new();
                let mut seconds = Vec::new();
                for k in 0..warmup + repeats {
                    let start = Instant::now();
                    hits = trace_cpu(scene, rays);
                    if k >= warmup {
                        seconds.push(start.elapsed().as_secs_f64());
                    }
                }
                Ok((hits, seconds))
            }
            #[cfg(feature = "gpu")]
            Device::Gpu(gpu) => {
                let uploaded = gpu.upload(scene)?;
                let (hits, mut seconds) = gpu.time_trace(&uploaded, rays, warmup + repeats)?;
                seconds.drain(..warmup.min(seconds.len()));
                Ok((hits, seconds))
            }
        }
    }
}
