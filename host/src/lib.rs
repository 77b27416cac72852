//! gridrt: a ray tracer for triangular grid primitives (micro-meshes) on ordinary GPUs.
//!
//! Data flows one way: [`mesh`] loads a base mesh, [`subdiv`] subdivides it (and
//! [`quantize`] may snap its inner vertices to 16 bits), [`grid`] and
//! [`triangles`] build the two representations (each over [`bvh`]), and [`scene`] (CPU) or
//! [`gpu`] traces them with the one implementation in `gridrt_shared`.

pub mod bench;
pub mod bvh;
pub mod camera;
pub mod chart;
pub mod cli;
pub mod device;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod grid;
pub mod image_io;
pub mod limits;
pub mod mesh;
pub mod progress;
pub mod quantize;
pub mod rays;
pub mod scene;
pub mod split;
pub mod stats;
pub mod subdiv;
pub mod triangles;
