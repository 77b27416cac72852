//! Embedding gridrt: load a mesh (or the built-in scene), build it as grids, render it on the
//! GPU if there is one, and write a PNG.
//!
//! `cargo run --release --example embed -- [MESH] [LEVELS]`

use anyhow::Result;
use gridrt::backend::{Backend, BackendChoice};
use gridrt::pipeline::{BuildOptions, RenderOptions, Shading};
use gridrt::{camera, mesh, scene::Scene};

fn main() -> Result<()> {
    let mut args = std::env::args().skip(1);
    let path = args.next();
    let levels = args.next().map_or(Ok(3), |l| l.parse())?;

    let input = mesh::open(path.as_deref().map(std::path::Path::new))?;
    let scene = Scene::build(&input.mesh, &BuildOptions::levels(levels))?;
    let view = camera::frame(&scene.bounds(), 640, 480);
    let backend = Backend::open(BackendChoice::Auto)?;
    let options = RenderOptions {
        shading: Shading::Normal,
        ..RenderOptions::default()
    };
    backend
        .render(&scene, &view, &options)?
        .write_png("embed.png".as_ref())?;
    println!(
        "{}: {} bytes of grids, rendered on {} -> embed.png",
        input.name,
        scene.memory(),
        backend.describe()
    );
    Ok(())
}
