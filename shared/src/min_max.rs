//! Minimum and maximum of two floats that are never NaN: the distances and coordinates of the
//! box, sphere, footprint and shell tests (finite differences times finite factors).
//!
//! Each is one comparison and a select, as glam's vector minimum and maximum are, which every
//! target compiles to one instruction. `f32::min` and `f32::max` promise to pass over a NaN,
//! which costs x86-64 several instructions on the box test's critical path, and a shader
//! compiler a few more too.

/// The smaller of `a` and `b`, neither a NaN.
#[inline(always)]
pub fn min_of(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// The larger of `a` and `b`, neither a NaN.
#[inline(always)]
pub fn max_of(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}
