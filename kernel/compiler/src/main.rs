//! Compiles the `kernel` crate (its entry points and `gridrt-shared`) to one SPIR-V module
//! and copies it to the path given as the only argument.
//!
//! The host's build script runs this when `kernel/compiled/` does not match the sources; it
//! is the one place that says how the module is built.

use std::error::Error;
use std::path::{Path, PathBuf};

fn main() -> Result<(), Box<dyn Error>> {
    let output = std::env::args_os()
        .nth(1)
        .map(PathBuf::from)
        .ok_or("usage: gridrt-kernel-compiler OUTPUT.spv")?;
    let kernel = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    // Line tables only slow the compiler's passes down (the module keeps no debug
    // information), and wgpu validates the module as it loads it, so the compiler's own
    // validation pass is skipped.
    std::env::set_var("CARGO_PROFILE_RELEASE_DEBUG", "false");
    let result = spirv_builder::SpirvBuilder::new(kernel, "spirv-unknown-vulkan1.1")
        .extra_arg("--no-spirv-val")
        .build()?;
    let module = result.module.unwrap_single();
    std::fs::copy(module, &output).map_err(|e| format!("copying {} to {}: {e}", module.display(), output.display()))?;
    Ok(())
}
