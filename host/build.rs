fn main() -> Result<(), Box<dyn std::error::Error>> {
    #[cfg(feature = "gpu")]
    {
        let mut builder = spirv_builder::SpirvBuilder::new(
            concat!(env!("CARGO_MANIFEST_DIR"), "/../kernel"),
            "spirv-unknown-vulkan1.1",
        );
        builder.build_script.defaults = true;
        builder.build_script.env_shader_spv_path = Some(true);
        builder.build()?;
    }
    Ok(())
}
