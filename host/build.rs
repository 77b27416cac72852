fn main() -> Result<(), Box<dyn std::error::Error>> {
    #[cfg(feature = "gpu")]
    {
        // The shaders' own build: line tables only slow its passes down (the module keeps no
        // debug information), and wgpu validates the module as it loads it, so the
        // compiler's own validation pass is skipped.
        std::env::set_var("CARGO_PROFILE_RELEASE_DEBUG", "false");
        let mut builder = spirv_builder::SpirvBuilder::new(
            concat!(env!("CARGO_MANIFEST_DIR"), "/../kernel"),
            "spirv-unknown-vulkan1.1",
        )
        .extra_arg("--no-spirv-val");
        builder.build_script.defaults = true;
        builder.build_script.env_shader_spv_path = Some(true);
        builder.build()?;
    }
    Ok(())
}
