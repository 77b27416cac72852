//! Embedding gridrt: load a mesh (or the built-in scene), build it as grids, render it on the
//! GPU if there is one, and write a PNG.
//!
//! `cargo run --release --example embed -- [MESH] [LEVELS]`

use std::process::ExitCode;

use gridrt::backend::{Backend, BackendChoice};
use gridrt::error::{ErrorKind, Result};
use gridrt::pipeline::{BuildOptions, RenderOptions};
use gridrt::{camera, input, scene::Scene};

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let path = args.next();
    let Ok(levels) = args.next().map_or(Ok(3), |l| l.parse()) else {
        eprintln!("LEVELS must be a number");
        return ExitCode::FAILURE;
    };
    match render(path.as_deref(), levels) {
        Ok(()) => ExitCode::SUCCESS,
        // Errors say what failed: a broken file is the user's to fix, anything else ours.
        Err(e) if e.kind() == ErrorKind::Input => {
            eprintln!("cannot use that mesh: {e}");
            ExitCode::from(2)
        }
        Err(e) => {
            eprintln!("{e}");
            ExitCode::FAILURE
        }
    }
}

fn render(path: Option<&str>, levels: u32) -> Result<()> {
    let input = input::open(path.map(std::path::Path::new))?;
    let scene = Scene::build(&input.mesh, &BuildOptions::levels(levels))?;
    let view = camera::frame(&scene.bounds(), 640, 480);
    let backend = Backend::open(BackendChoice::Auto)?;
    let options = RenderOptions {
        smooth_normals: true,
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
