//! The `gridrt` binary end to end: pictures, JSON and error messages as a user sees them.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use gridrt_tests::{gpu_or_skip, gridrt_exe, meshes_dir};

fn scratch(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("gridrt-cli-{}-{test}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn gridrt(args: &[&str]) -> Output {
    Command::new(gridrt_exe()).args(args).output().expect("run gridrt")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A PNG of the asked size that is not a single flat colour.
fn check_png(path: &Path, width: u32, height: u32) {
    let img = image::open(path)
        .unwrap_or_else(|e| panic!("{}: not a PNG: {e}", path.display()))
        .to_rgba8();
    assert_eq!(img.dimensions(), (width, height));
    let first = img.get_pixel(0, 0);
    let different = img.pixels().filter(|p| *p != first).count();
    assert!(
        different > (width * height / 20) as usize,
        "{}: almost blank",
        path.display()
    );
}

fn render_ok(args: &[&str], out: &Path, width: u32, height: u32) {
    let w = width.to_string();
    let h = height.to_string();
    let mut all = vec!["render"];
    all.extend_from_slice(args);
    all.extend(["--width", &w, "--height", &h, "--output", out.to_str().unwrap()]);
    let o = gridrt(&all);
    assert!(o.status.success(), "gridrt {all:?} failed: {}", stderr(&o));
    check_png(out, width, height);
}

#[test]
fn renders_the_default_scene() {
    let dir = scratch("default");
    render_ok(&["--backend", "cpu"], &dir.join("grid.png"), 160, 120);
    render_ok(
        &["--backend", "cpu", "--mode", "triangles", "--levels", "2"],
        &dir.join("tri.png"),
        160,
        120,
    );
    render_ok(
        &["--backend", "cpu", "--lod", "1", "--shading", "primitive"],
        &dir.join("lod.png"),
        96,
        64,
    );
    if gpu_or_skip("renders_the_default_scene").is_some() {
        render_ok(&["--backend", "gpu"], &dir.join("gpu.png"), 160, 120);
    }
}

#[test]
fn renders_a_mesh_file() {
    let Some(meshes) = meshes_dir() else {
        eprintln!("renders_a_mesh_file: SKIPPED, ../shared/meshes not found");
        return;
    };
    let dir = scratch("mesh");
    let teapot = meshes.join("teapot.obj");
    let dragon = meshes.join("dragon_res4.ply");
    render_ok(
        &[teapot.to_str().unwrap(), "--backend", "cpu"],
        &dir.join("teapot.png"),
        128,
        96,
    );
    render_ok(
        &[dragon.to_str().unwrap(), "--backend", "cpu", "--levels", "1"],
        &dir.join("dragon.png"),
        128,
        96,
    );
    if gpu_or_skip("renders_a_mesh_file").is_some() {
        render_ok(
            &[dragon.to_str().unwrap(), "--backend", "gpu", "--levels", "2"],
            &dir.join("dragon_gpu.png"),
            128,
            96,
        );
    }
}

/// Broken input ends with one line naming the file and the problem, a non-zero exit code and
/// no panic.
#[test]
fn broken_inputs_give_one_line_errors() {
    let dir = scratch("broken");
    let truncated = dir.join("truncated.ply");
    std::fs::write(
        &truncated,
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
         element face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n",
    )
    .unwrap();
    let bad_index = dir.join("bad_index.obj");
    std::fs::write(&bad_index, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n").unwrap();
    let empty = dir.join("empty.obj");
    std::fs::write(&empty, "").unwrap();
    let missing = dir.join("missing.ply");
    for (path, problem) in [
        (&truncated, "truncated"),
        (&bad_index, "9"),
        (&empty, "no triangles"),
        (&missing, "cannot open"),
    ] {
        let o = gridrt(&[
            "render",
            path.to_str().unwrap(),
            "--backend",
            "cpu",
            "--output",
            "/dev/null",
        ]);
        let err = stderr(&o);
        assert!(!o.status.success(), "{}: accepted", path.display());
        assert!(!err.contains("panicked"), "{}: panicked: {err}", path.display());
        let lines: Vec<&str> = err.lines().filter(|l| l.starts_with("error")).collect();
        assert_eq!(lines.len(), 1, "{}: expected one error line, got {err}", path.display());
        assert!(
            lines[0].contains(path.to_str().unwrap()),
            "error does not name the file: {err}"
        );
        assert!(
            lines[0].to_lowercase().contains(problem),
            "error does not say '{problem}': {err}"
        );
    }
}

#[test]
fn stats_prints_one_json_object() {
    let o = gridrt(&["stats", "--levels", "3", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object on stdout");
    for key in [
        "mesh",
        "levels",
        "base_triangles",
        "micro_triangles",
        "grid",
        "triangles",
    ] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
    let base = v["base_triangles"].as_u64().unwrap();
    assert_eq!(v["micro_triangles"].as_u64().unwrap(), base * 64);
    for rep in ["grid", "triangles"] {
        let r = &v[rep];
        let parts: u64 = r["parts"]
            .as_object()
            .unwrap()
            .values()
            .map(|x| x.as_u64().unwrap())
            .sum();
        assert_eq!(
            r["bytes"].as_u64().unwrap(),
            parts,
            "{rep}: bytes are the sum of the parts"
        );
        assert!(r["build_seconds"].as_f64().unwrap() > 0.0);
    }
    let gain = v["compression_gain"].as_f64().unwrap();
    let expected = v["triangles"]["bytes"].as_f64().unwrap() / v["grid"]["bytes"].as_f64().unwrap();
    assert!((gain - expected).abs() < 1e-9);
    assert!(v["construction_gain"].as_f64().unwrap() > 0.0);
}

/// Without any Vulkan driver, `--backend gpu` fails with one line saying what to do and
/// `--backend auto` falls back to the CPU.
#[test]
fn no_adapter_is_a_clear_error() {
    let dir = scratch("no_adapter");
    let out = dir.join("auto.png");
    let run = |backend: &str| {
        Command::new(gridrt_exe())
            .args([
                "render",
                "--backend",
                backend,
                "--width",
                "64",
                "--height",
                "48",
                "--output",
            ])
            .arg(&out)
            // Point the Vulkan loader at no driver at all.
            .env("VK_ICD_FILENAMES", dir.join("none.json"))
            .env("VK_DRIVER_FILES", dir.join("none.json"))
            .env("WGPU_BACKEND", "vulkan")
            .output()
            .expect("run gridrt")
    };
    let gpu = run("gpu");
    let err = stderr(&gpu);
    assert!(!gpu.status.success(), "rendered without an adapter: {err}");
    let lines: Vec<&str> = err.lines().filter(|l| l.starts_with("error")).collect();
    assert_eq!(lines.len(), 1, "{err}");
    assert!(
        lines[0].contains("no GPU adapter") && lines[0].contains("--backend cpu"),
        "{err}"
    );
    let auto = run("auto");
    assert!(auto.status.success(), "{}", stderr(&auto));
    assert!(stderr(&auto).contains("rendering on the CPU"));
    check_png(&out, 64, 48);
}
