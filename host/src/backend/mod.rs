//! Where rays are traced: the CPU ([`cpu`]: rayon over the same `gridrt_shared` code the
//! kernels run) or, built with the `gpu` feature (on by default), a wgpu adapter ([`gpu`]).
//! One type, so that the choice between them is made in one place.

pub mod cpu;
#[cfg(feature = "gpu")]
pub mod gpu;

use crate::error::Result;
use gridrt_shared::layout::{Camera, FrameParams, HitRecord, RayRecord, SHADE_COST};
use gridrt_shared::shade::{ao_accumulate, ao_pixel};
use rayon::prelude::*;

use crate::heat_map::CostImage;
use crate::limits::BufferSize;
use crate::pipeline::{Image, RenderOptions, Shading};
use crate::scene::Scene;
use cpu::{render_cpu, time_traces_cpu, trace_cpu};
#[cfg(feature = "gpu")]
use gpu::{Gpu, GpuScene, TimedList, Timing};

/// Most ambient-occlusion samples per pixel one render pass casts.
pub const AO_SAMPLES_PER_PASS: u32 = 8;

/// [`AO_SAMPLES_PER_PASS`] for grids of compressed values. Lavapipe ends a kernel's loops once
/// all of them together have run 65535 times in one invocation, silently; decoding values
/// runs loops of its own, and a pixel of deep grids that casts eight rays can reach that.
pub const AO_SAMPLES_PER_PASS_COMPRESSED: u32 = 2;

/// Most ambient-occlusion samples per pixel one render pass of `scene` casts.
pub fn ao_samples_per_pass(scene: &Scene) -> u32 {
    match scene.has_compressed_values() {
        true => AO_SAMPLES_PER_PASS_COMPRESSED,
        false => AO_SAMPLES_PER_PASS,
    }
}

/// Which backend to open.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum BackendChoice {
    /// The GPU if wgpu finds an adapter, otherwise the CPU.
    #[default]
    Auto,
    Gpu,
    Cpu,
}

impl std::str::FromStr for BackendChoice {
    type Err = crate::error::Error;

    /// The names the CLI's `--backend` takes: auto, gpu, cpu.
    fn from_str(name: &str) -> Result<BackendChoice> {
        Ok(match name {
            "auto" => BackendChoice::Auto,
            "gpu" => BackendChoice::Gpu,
            "cpu" => BackendChoice::Cpu,
            _ => crate::error::fail!(Options, "no backend is called {name:?}: auto, gpu or cpu"),
        })
    }
}

/// What timing a list of rays through one scene gives ([`Backend::time_traces`]).
pub struct TimedTrace {
    /// The hits of the last repetition.
    pub hits: Vec<HitRecord>,
    /// The seconds of each timed repetition (after the warm-up).
    pub seconds: Vec<f64>,
}

/// A scene where a backend reads it ([`Backend::upload`]): on a GPU its buffers, uploaded once
/// for any number of traces and renders; on the CPU nothing (it reads the scene itself). It
/// belongs to the scene and the backend it was made from.
pub struct Uploaded {
    #[cfg(feature = "gpu")]
    gpu: Option<GpuScene>,
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
                Err(e) if e.kind() == crate::error::ErrorKind::NoGpu => Ok(Backend::Cpu {
                    fallback: Some(e.to_string()),
                }),
                Err(e) => Err(e),
            },
            #[cfg(not(feature = "gpu"))]
            BackendChoice::Gpu => Err(crate::error::error!(
                NoGpu,
                "this gridrt was built without the `gpu` feature; use --backend cpu"
            )),
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
    /// be bound on this device (the CPU takes any); `whole_only`: displaced grids, which the GPU
    /// reads from whole bindings alone.
    pub fn check_fits(&self, sizes: &[BufferSize], whole_only: bool) -> Result<()> {
        match self {
            Backend::Cpu { .. } => {
                let _ = (sizes, whole_only);
                Ok(())
            }
            #[cfg(feature = "gpu")]
            Backend::Gpu(gpu) => gpu.check_fits(sizes, whole_only),
        }
    }

    /// Renders `scene` as `camera` sees it.
    pub fn render(&self, scene: &Scene, camera: &Camera, options: &RenderOptions) -> Result<Image> {
        self.render_reporting(scene, camera, options, &|_| {})
    }

    /// [`Backend::render`], calling `progress(samples)` with the ambient-occlusion samples per
    /// pixel cast so far after each pass (ambient occlusion is rendered progressively, at most
    /// [`ao_samples_per_pass`] samples a pass, so no one dispatch runs long).
    pub fn render_reporting(
        &self,
        scene: &Scene,
        camera: &Camera,
        options: &RenderOptions,
        progress: &dyn Fn(u32),
    ) -> Result<Image> {
        options.check(scene)?;
        let uploaded = self.upload_to_render(scene, options.shading.code())?;
        self.render_uploaded(scene, &uploaded, camera, options, progress)
    }

    /// [`Backend::render_reporting`] of a scene already [`Backend::upload`]ed.
    pub fn render_uploaded(
        &self,
        scene: &Scene,
        uploaded: &Uploaded,
        camera: &Camera,
        options: &RenderOptions,
        progress: &dyn Fn(u32),
    ) -> Result<Image> {
        options.check(scene)?;
        if options.shading == Shading::Cost {
            let costs = self.render_costs(scene, camera, options)?;
            let white = costs.summary().white(options.heat_white);
            return Ok(costs.heat_map(white));
        }
        let frame = options.frame(scene, camera);
        let pixels = if matches!(options.shading, Shading::AmbientOcclusion | Shading::Lit) {
            self.render_ambient_occlusion(scene, uploaded, &frame, progress)?
        } else {
            self.render_frame_uploaded(scene, uploaded, &frame)?
        };
        Ok(Image {
            width: camera.width,
            height: camera.height,
            pixels,
        })
    }

    /// Ambient occlusion in passes of at most [`ao_samples_per_pass`] samples per pixel, the
    /// open rays of each pixel added up over them, then coloured.
    fn render_ambient_occlusion(
        &self,
        scene: &Scene,
        uploaded: &Uploaded,
        frame: &FrameParams,
        progress: &dyn Fn(u32),
    ) -> Result<Vec<u32>> {
        let samples = frame.ao_samples;
        let per_pass = ao_samples_per_pass(scene);
        let passes: Vec<FrameParams> = (0..samples.div_ceil(per_pass).max(1))
            .map(|k| {
                let first = k * per_pass;
                FrameParams {
                    ao_first_sample: first,
                    ao_samples: per_pass.min(samples - first),
                    ..*frame
                }
            })
            .collect();
        let mut open = vec![0u32; (frame.camera.width * frame.camera.height) as usize];
        for pass in &passes {
            let counts = self.render_frame_uploaded(scene, uploaded, pass)?;
            // A primary ray misses in every pass or in none.
            for (sum, pixel) in open.iter_mut().zip(counts) {
                *sum = ao_accumulate(*sum, pixel);
            }
            progress(pass.ao_first_sample + pass.ao_samples);
        }
        let width = frame.camera.width;
        Ok(open
            .par_iter()
            .enumerate()
            .map(|(i, &o)| ao_pixel(frame, i as u32 % width, i as u32 / width, o, samples))
            .collect())
    }

    /// The tests each pixel's primary ray makes, for the cost heat map (of `options`, only
    /// the level of detail counts). Counted on the CPU whatever the backend: the counts are the
    /// traversal's, the same on every device, and the GPU keeps no kernels for them.
    pub fn render_costs(&self, scene: &Scene, camera: &Camera, options: &RenderOptions) -> Result<CostImage> {
        let options = RenderOptions {
            shading: Shading::Cost,
            ..*options
        };
        options.check(scene)?;
        let packed = self.render_frame(scene, &options.frame(scene, camera))?;
        Ok(CostImage::from_packed(camera.width, camera.height, &packed))
    }

    /// Renders one frame as the kernels take it: packed RGBA8 (packed costs for the heat map,
    /// counts of open rays for an ambient-occlusion pass: see
    /// [`gridrt_shared::shade::render_pixel`]), row-major, top row first. The heat map's
    /// counts come from the CPU (see [`Backend::render_costs`]).
    pub fn render_frame(&self, scene: &Scene, frame: &FrameParams) -> Result<Vec<u32>> {
        let uploaded = self.upload_to_render(scene, frame.shading)?;
        self.render_frame_uploaded(scene, &uploaded, frame)
    }

    /// [`Backend::upload`] for a render of `shading` (a `SHADE_*` code): nothing for the cost
    /// heat map, which is counted on the CPU whatever the backend (see `render_costs`).
    fn upload_to_render(&self, scene: &Scene, shading: u32) -> Result<Uploaded> {
        match shading {
            SHADE_COST => Ok(Uploaded::nothing()),
            _ => self.upload(scene),
        }
    }

    /// [`Backend::render_frame`] of a scene already [`Backend::upload`]ed.
    fn render_frame_uploaded(&self, scene: &Scene, uploaded: &Uploaded, frame: &FrameParams) -> Result<Vec<u32>> {
        match (self, uploaded.on_gpu()) {
            #[cfg(feature = "gpu")]
            (Backend::Gpu(gpu), Some(on_gpu)) if frame.shading != SHADE_COST => gpu.render_uploaded(on_gpu, frame),
            _ => Ok(render_cpu(scene, frame)),
        }
    }

    /// Makes `scene` ready for this backend: on a GPU, uploads its buffers (refusing, naming
    /// them, a scene this adapter cannot bind); on the CPU, nothing.
    pub fn upload(&self, scene: &Scene) -> Result<Uploaded> {
        match self {
            Backend::Cpu { .. } => {
                let _ = scene;
                Ok(Uploaded::nothing())
            }
            #[cfg(feature = "gpu")]
            Backend::Gpu(gpu) => Ok(Uploaded {
                gpu: Some(gpu.upload(scene)?),
            }),
        }
    }

    /// The closest hit of each of `rays`, in order (a miss: `prim` is
    /// [`gridrt_shared::layout::NO_HIT`]).
    pub fn trace(&self, scene: &Scene, rays: &[RayRecord]) -> Result<Vec<HitRecord>> {
        self.trace_uploaded(scene, &self.upload(scene)?, rays)
    }

    /// [`Backend::trace`] through a scene already [`Backend::upload`]ed.
    pub fn trace_uploaded(&self, scene: &Scene, uploaded: &Uploaded, rays: &[RayRecord]) -> Result<Vec<HitRecord>> {
        match (self, uploaded.on_gpu()) {
            #[cfg(feature = "gpu")]
            (Backend::Gpu(gpu), Some(on_gpu)) => gpu.trace(on_gpu, rays),
            _ => Ok(trace_cpu(scene, rays)),
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
        let TimedTrace { hits, seconds } = self.time_traces(&[scene], rays, warmup, repeats)?.remove(0);
        Ok((hits, seconds))
    }

    /// Traces `rays` through each of `scenes`, `warmup + repeats` times; per
    /// scene, in order, what [`TimedTrace`] holds. The scenes take turns at every repetition
    /// (the first of one is the last of the next), so that a change in the device's speed while
    /// they run (clocks, heat, other work on the machine) meets them alike: the ratio of their
    /// times, which a benchmark reports, does not depend on which ran when.
    pub fn time_traces(
        &self,
        scenes: &[&Scene],
        rays: &[RayRecord],
        warmup: usize,
        repeats: usize,
    ) -> Result<Vec<TimedTrace>> {
        match self {
            Backend::Cpu { .. } => Ok(time_traces_cpu(scenes, rays, warmup, repeats)),
            #[cfg(feature = "gpu")]
            Backend::Gpu(gpu) => {
                let uploaded = (scenes.iter())
                    .map(|scene| gpu.upload(scene))
                    .collect::<Result<Vec<_>>>()?;
                let lists = gpu.time_traces(&uploaded, rays, warmup + repeats)?;
                Ok((lists.into_iter())
                    .map(|TimedList { hits, mut seconds }| {
                        seconds.drain(..warmup.min(seconds.len()));
                        TimedTrace { hits, seconds }
                    })
                    .collect())
            }
        }
    }
}

impl Uploaded {
    fn nothing() -> Uploaded {
        Uploaded {
            #[cfg(feature = "gpu")]
            gpu: None,
        }
    }

    #[cfg(feature = "gpu")]
    fn on_gpu(&self) -> Option<&GpuScene> {
        self.gpu.as_ref()
    }

    #[cfg(not(feature = "gpu"))]
    fn on_gpu(&self) -> Option<&()> {
        None
    }
}
