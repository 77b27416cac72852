//! Meshes in any units and at any place render the same picture: the default scene written
//! to OBJ files scaled by 1e-10 .. 1e8 and moved by up to 1e7 times its size, rendered by the
//! `gridrt` binary on both backends, against the same scene at unit scale.
//!
//! The files hold every digit of `p * scale + offset * size` in `f64`, as a scan's or a
//! CAD tool's text would: gridrt reads them in `f64` and moves them to the local frame
//! there, so however far the mesh is placed it renders the unit picture. Tolerance: at
//! least 99% of pixels within 2/255 per channel of the unit render, on the same backend;
//! what may differ is the rounding of the scaled coordinates themselves (a power of ten
//! is not a power of two), a few silhouette pixels and shading steps.

use std::path::Path;
use std::process::Command;

use gridrt::mesh::scene::default_scene;
use gridrt::mesh::Mesh;
use gridrt_tests::{gpu_or_skip, gridrt_exe};

const WIDTH: u32 = 160;
const HEIGHT: u32 = 120;

/// The mesh as an OBJ file with every vertex `p * scale + offset * size`, computed and written
/// in `f64` (every digit), `size` being the mesh's largest extent.
fn write_obj(mesh: &Mesh, scale: f64, offset: f64, path: &Path) {
    let (lo, hi) = mesh.bounds();
    let size = (hi - lo).max_element() as f64;
    let shift = [offset * size, offset * size * 0.5, -offset * size * 0.25];
    let mut text = String::new();
    for p in &mesh.positions {
        let c: Vec<String> = (0..3)
            .map(|k| ((p[k] as f64) * scale + shift[k] * scale).to_string())
            .collect();
        text += &format!("v {}\n", c.join(" "));
    }
    for t in &mesh.triangles {
        text += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    std::fs::write(path, text).unwrap();
}

fn render(obj: &Path, backend: &str, png: &Path) -> Vec<u32> {
    let o = Command::new(gridrt_exe())
        .args(["render", obj.to_str().unwrap(), "--backend", backend, "--levels", "2"])
        .args(["--width", &WIDTH.to_string(), "--height", &HEIGHT.to_string()])
        .args(["--output", png.to_str().unwrap()])
        .output()
        .expect("run gridrt");
    assert!(
        o.status.success(),
        "{}: {}",
        obj.display(),
        String::from_utf8_lossy(&o.stderr)
    );
    let img = image::open(png).unwrap().to_rgba8();
    img.pixels().map(|p| u32::from_le_bytes(p.0)).collect()
}

fn check_backend(backend: &str) {
    let dir = gridrt_tests::scratch("scale");
    let mesh = default_scene();
    let unit_obj = dir.join(format!("unit-{backend}.obj"));
    write_obj(&mesh, 1.0, 0.0, &unit_obj);
    let unit = render(&unit_obj, backend, &dir.join(format!("unit-{backend}.png")));
    let first = unit[0];
    assert!(
        unit.iter().filter(|&&p| p != first).count() > unit.len() / 4,
        "unit render is blank"
    );
    let cases = [
        (1e-10, 0.0),
        (1e-6, 0.0),
        (1e-3, 0.0),
        (1e3, 0.0),
        (1e6, 0.0),
        (1e8, 0.0),
        (1.0, 1e2),
        (1.0, 1e4),
        (1e-6, 1e4),
        (1e6, 1e4),
        (1.0, 1e5),
        (1.0, 1e7),
        (1e-3, 1e7),
        (1e6, 1e7),
    ];
    for (scale, offset) in cases {
        let name = format!("{backend}-s{scale:e}-o{offset:e}");
        let obj = dir.join(format!("{name}.obj"));
        write_obj(&mesh, scale, offset, &obj);
        let image = render(&obj, backend, &dir.join(format!("{name}.png")));
        let near = gridrt::image_io::fraction_within(&unit, &image, 2);
        eprintln!("{name}: {:.3}% of pixels within 2/255 of the unit render", 100.0 * near);
        assert!(
            near >= 0.99,
            "{name}: only {:.3}% of pixels match the unit render",
            100.0 * near
        );
    }
}

#[test]
fn any_scale_and_offset_renders_the_unit_picture_on_the_cpu() {
    check_backend("cpu");
}

#[test]
fn any_scale_and_offset_renders_the_unit_picture_on_the_gpu() {
    if gpu_or_skip("scale on the GPU").is_some() {
        check_backend("gpu");
    }
}
