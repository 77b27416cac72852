//! Any bytes as an OBJ file: a mesh that passes validation, or an error; never a panic.
#![no_main]

use gridrt_fuzz::check_loaded;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    check_loaded(gridrt::mesh::obj::parse_obj(data));
});
