//! Any bytes as a small mesh and build options, through the whole path a render takes
//! (validate, local frame, subdivide, build both representations, trace): no panic, and the
//! grids and the baseline find the same closest hits.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    gridrt_fuzz::run_pipeline(data);
});
