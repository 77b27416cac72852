//! gridrt: a ray tracer for triangular grid primitives (micro-meshes) on ordinary GPUs.
//!
//! A base mesh is subdivided `L` times; each base triangle becomes a *grid* of `4^L`
//! micro-triangles with implicit connectivity, shared edge and corner vertices and a 4-ary
//! sphere hierarchy, under an SAH BVH over the grids. Rendering the built-in scene takes four
//! calls ([`pipeline`]):
//!
//! ```
//! use gridrt::backend::Backend;
//! use gridrt::pipeline::{BuildOptions, RenderOptions};
//! use gridrt::{camera, input, scene::Scene};
//!
//! // The built-in scene; `Some(path)` loads a .obj or .ply file.
//! let input = input::open(None)?;
//! let scene = Scene::build(&input.mesh, &BuildOptions::levels(3))?;
//! let view = camera::frame(&scene.bounds(), 64, 48);
//! // `Backend::open(BackendChoice::Auto)` takes the GPU when there is one.
//! let image = Backend::CPU.render(&scene, &view, &RenderOptions::default())?;
//! assert_eq!(image.pixels.len(), 64 * 48);
//! # Ok::<(), gridrt::error::Error>(())
//! ```
//!
//! Every fallible call returns an [`error::Error`]: one line, and a kind that says whether the
//! input, the options, the limits, the GPU or the output failed. The library prints nothing.
//!
//! Underneath, data flows one way: [`mesh`] loads a base mesh, [`subdiv`] subdivides it (and
//! [`quantize`] may snap its inner vertices to 16 bits), [`grid`] and [`triangles`] build the
//! two representations (each over [`bvh`]), and a [`backend`] traces them: the CPU
//! ([`scene`]) or the GPU (`gpu`), with the one implementation in `gridrt_shared`.
//!
//! Displaced micro-meshes (a base mesh, directions, and a micromap of 11-bit values per
//! triangle) have one home, [`micromesh`]: the type and its decoding, baking, and the `.bary`
//! and glTF files. [`surface_distance`] measures how far apart two surfaces are (`gridrt
//! compare`).
//!
//! Every `gridrt` command is one call of [`request`], which makes the decisions the command
//! line would (a request struct in, an answer out, progress through [`progress::Progress`]):
//!
//! ```no_run
//! use gridrt::request::render::{render_files, RenderRequest};
//!
//! let request = RenderRequest::new(vec!["bunny.obj".into()], "bunny.png");
//! let rendered = render_files(&request, &mut gridrt::progress::Silent)?;
//! println!("{:?} on {}", rendered.outputs, rendered.device);
//! # Ok::<(), gridrt::error::Error>(())
//! ```

pub mod backend;
pub mod bit_writer;
pub mod bvh;
pub mod camera;
pub mod error;
pub mod files;
pub mod grid;
pub mod heat_map;
pub mod image_io;
pub mod input;
pub mod lagrangian;
pub mod limits;
pub mod lod;
pub mod mesh;
pub mod micromesh;
pub mod pipeline;
pub mod progress;
pub mod quantize;
pub mod rays;
pub mod request;
pub mod scene;
pub mod split;
pub mod subdiv;
pub mod surface_distance;
pub mod triangles;
