//! Everything that runs per ray, written once and compiled twice: natively for the CPU backend and
//! the tests, and to SPIR-V (through `kernel`) for the GPU backend.
//!
//! Nothing here allocates or knows where its slices live: the same functions read wgpu storage
//! buffers inside a shader and plain `Vec`s on the host.
//!
//! A choice among values on a run-time number is an `if` chain here, never a `match`: a shader
//! compiler makes a `match` into selects that start from the variable's value before it, and
//! a loop around the choice then keeps that value in a register for nothing.
#![no_std]

pub use spirv_std::glam;

pub mod aabb;
pub mod bit_fields;
pub mod buffer;
pub mod camera;
pub mod compressed_values;
pub mod cost;
pub mod displacement;
pub mod footprint;
pub mod grid_index;
pub mod grid_slots;
pub mod grid_traverse;
pub mod layout;
pub mod lod;
pub mod min_max;
pub mod quantize;
pub mod ray;
pub mod sample;
pub mod shade;
pub mod smooth_normal;
pub mod sphere;
pub mod top_nodes;
pub mod traverse;
pub mod triangle;
pub mod value_tables;
pub mod wide_nodes;
