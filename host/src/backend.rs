//! Where rays are traced: the CPU (rayon over the same `gridrt_shared` code the kernels run)
//! or, built with the `gpu` feature (on by default), a wgpu adapter. One type, so that the
//! choice between them is made in one place.

use std::time::Instant;

use anyhow::Result;
use gridrt_shared::layout::{Camera, FrameParams, HitRecord, RayRecord};

#[cfg(feature = "gpu")]
use crate::gpu::{Gpu, NoAdapter, Timing};
use crate::heat_map::CostImage;
use crate::limits::BufferSize;
use crate::pipeline::{Image, RenderOptions, Shading};
use crate::rays::trace_cpu;
use crate::scene::{render_cpu, Scene};

/// Which backend to open.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum BackendChoice {
    /// The GPU if wgpu finds an adapter, otherwise the CPU.
    #[default]
    Auto,
    Gpu,
    Cpu,
}

/// A CPU or a GPU, behind one interface: everything that traces takes a `&Backend`.
pub enum Backend {
    /// The CPU; `fallback` says why, when `Auto` found no GPU.
    Cpu { fallback: Option<String> },
    #[cfg(feature = "gpu")]
    Gpu(Box<Gpu>),
}

impl Backend {
    /// The CPU backend.
    pub const CPU: Backend = Backend::Cpu { fallback: None };

    /// The backend `choice` asks for: for `Auto`, the CPU when wgpu finds no adapter at all
    /// (see [`Backend::fallback`]). Any other GPU failure is an error.
    pub fn open(choice: BackendChoice) -> Result<Backend> {
        match choice {
            BackendChoice::Cpu => Ok(Backend::CPU),
            #[cfg(feature = "gpu")]
            BackendChoice::Gpu => Ok(Backend::Gpu(Box::new(Gpu::new()?))),
            #[cfg(feature = "gpu")]
            BackendChoice::Auto => match Gpu::new() {
                Ok(gpu) => Ok(Backend::Gpu(Box::new(gpu))),
                Err(e) if e.is::<NoAdapter>() => Ok(Backend::Cpu {
                    fallback: Some(e.to_string()),
                }),
                Err(e) => Err(e),
            },
            #[cfg(not(feature = "gpu"))]
            BackendChoice::Gpu => anyhow::bail!("this gridrt was built without the `gpu` feature; use --backend cpu"),
            #[cfg(not(feature = "gpu"))]
            BackendChoice::Auto => Ok(Backend::CPU),
        }
    }

    /// Why `Auto` chose the CPU, when it did because there was no GPU.
    pub fn fallback(&self) -> Option<&str> {
        match self {
            Backend::Cpu { fallback } => fallback.as_deref(),
            #[cfg(feature = "gpu")]
            Backend::Gpu(_) => None,
        }
    }

    /// `cpu` or `gpu`.
    pub fn kind(&self) -> &'static str {
        match self {
            Backend::Cpu { .. } => "cpu",
            #[cfg(feature = "gpu")]
            Backend::Gpu(_) => "gpu",
        }
    }

    /// One line naming the device.
    pub fn describe(&self) -> String {
        match self {
            Backend::Cpu { .. } => format!("CPU, {} threads", rayon::current_num_threads()),
            #[cfg(feature = "gpu")]
            Backend::Gpu(gpu) => gpu.describe(),
        }
    }

    /// How [`Backend::time_trace`] measures.
    pub fn timing(&self) -> &'static str {
        match self {
            Backend::Cpu { .. } => "wall clock",
            #[cfg(feature = "gpu")]
            Backend::Gpu(gpu) => match gpu.timing() {
                Timing::Timestamps => "GPU timestamp queries",
                Timing::FenceToFence => "fence to fence (no timestamp queries on this adapter)",
            },
        }
    }

    /// Host bytes that handing `bytes` of scene buffers to this device costs besides the scene
    /// itself (none on the CPU backend).
    pub fn host_upload_bytes(&self, bytes: u64) -> u64 {
        match self {
            Backend::Cpu { .. } => {
                let _ = bytes;
                0
            }
            #[cfg(feature = "gpu")]
            Backend::Gpu(gpu) => gpu.host_upload_bytes(bytes),
        }
    }

    /// Refuses, before it is built, a scene whose buffers will be at least `sizes` and cannot
    /// be bound on this device (the CPU takes any).
    pub fn check_fits(&self, sizes: &[BufferSize]) -> Result<()> {
        match self {
            Backend::Cpu { .. } => {
                let _ = sizes;
                Ok(())
            }
            #[cfg(feature = "gpu")]
            Backend::Gpu(gpu) => gpu.check_fits(sizes),
        }
    }

    /// Renders `scene` as `camera` sees it.
    pub fn render(&self, scene: &Scene, camera: &Camera, options: &RenderOptions) -> Result<Image> {
        options.check(scene)?;
        if options.shading == Shading::Cost {
            let costs = self.render_costs(scene, camera, options)?;
            let white = costs.summary().white(options.heat_white);
            return Ok(costs.heat_map(white));
        }
        let pixels = self.render_frame(scene, &options.frame(scene, camera))?;
        Ok(Image {
            width: camera.width,
            height: camera.height,
            pixels,
        })
    }

    /// The tests each pixel's primary ray makes, for the cost heat map (of `options`, only
    /// the level of detail counts).
    pub fn render_costs(&self, scene: &Scene, camera: &Camera, options: &RenderOptions) -> Result<CostImage> {
        let options = RenderOptions {
            shading: Shading::Cost,
            ..*options
        };
        options.check(scene)?;
        let packed = self.render_frame(scene, &options.frame(scene, camera))?;
        Ok(CostImage::from_packed(camera.width, camera.height, &packed))
    }

    /// Renders one frame as the kernels take it: packed RGBA8 (or packed costs for the heat
    /// map), row-major, top row first.
    pub fn render_frame(&self, scene: &Scene, frame: &FrameParams) -> Result<Vec<u32>> {
        match self {
            Backend::Cpu { .. } => Ok(render_cpu(scene, frame)),
            #[cfg(feature = "gpu")]
            Backend::Gpu(gpu) => gpu.render(scene, frame),
        }
    }

    /// The closest hit of each of `rays`, in order (a miss: `prim` is
    /// [`gridrt_shared::layout::NO_HIT`]).
    pub fn trace(&self, scene: &Scene, rays: &[RayRecord]) -> Result<Vec<HitRecord>> {
        match self {
            Backend::Cpu { .. } => Ok(trace_cpu(scene, rays)),
            #[cfg(feature = "gpu")]
            Backend::Gpu(gpu) => gpu.trace(&gpu.upload(scene)?, rays),
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
            Backend::Cpu { .. } => {
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
            Backend::Gpu(gpu) => {
                let uploaded = gpu.upload(scene)?;
                let (hits, mut seconds) = gpu.time_trace(&uploaded, rays, warmup + repeats)?;
                seconds.drain(..warmup.min(seconds.len()));
                Ok((hits, seconds))
            }
        }
    }
}
