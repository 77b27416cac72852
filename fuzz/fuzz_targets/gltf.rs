//! Any bytes as a glTF or GLB file (external buffers looked for in an empty folder): a mesh
//! that passes validation, or a one-line error; never a panic, a stack overflow or a read
//! outside the folder. The mutator edits the JSON, the binary chunk and the GLB container
//! (see `gridrt_fuzz::gltf_mutation`), so that inputs reach past the parser.
#![no_main]

use libfuzzer_sys::{fuzz_mutator, fuzz_target, fuzzer_mutate};

fuzz_target!(|data: &[u8]| {
    gridrt_fuzz::check_gltf(data);
});

fuzz_mutator!(|data: &mut [u8], size: usize, max_size: usize, seed: u32| {
    gridrt_fuzz::gltf_mutation::mutate(data, size, max_size, seed, fuzzer_mutate)
});
