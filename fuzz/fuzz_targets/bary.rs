//! Any bytes as a `.bary` file: a micromap whose every triangle holds its level's values, or a
//! one-line error; never a panic or an allocation beyond what the file stores. A micromap
//! that reads is then written as a micro-mesh's set of files over another set, and must read
//! back from them, the folder holding that set alone.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    gridrt_fuzz::check_bary(data);
});
