//! The `gridrt` binary end to end: pictures, JSON and error messages as a user sees them.

use std::path::Path;
use std::process::Command;

use gridrt_tests::{
    fails_with, gpu_or_skip, gridrt, gridrt_exe, meshes_dir, meshes_dir_or_skip, render_small, scratch, stderr,
    TINY_BENCH,
};

/// Runs gridrt, which must succeed, and returns the line of its report starting with `prefix`.
fn report_line(args: &[&str], prefix: &str) -> String {
    let o = gridrt(args);
    let err = stderr(&o);
    assert!(o.status.success(), "gridrt {args:?} failed: {err}");
    err.lines()
        .find(|l| l.starts_with(prefix))
        .unwrap_or_else(|| panic!("gridrt {args:?}: no line starting {prefix:?} in {err}"))
        .to_string()
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

/// Share of the picture's pixels that are not background (the background is a vertical
/// gradient, so each row's leftmost pixel, inside the framing margin, is its colour).
fn covered(path: &Path) -> f64 {
    let img = image::open(path).unwrap().to_rgb8();
    let (width, height) = img.dimensions();
    let mut covered = 0usize;
    for y in 0..height {
        let background = img.get_pixel(0, y);
        let apart = |x: u32| -> i32 {
            let p = img.get_pixel(x, y);
            (0..3).map(|c| (p[c] as i32 - background[c] as i32).abs()).sum()
        };
        covered += (0..width).filter(|&x| apart(x) > 6).count();
    }
    covered as f64 / (width * height) as f64
}

/// The default view frames the mesh by its vertices, not by its box: each of the meshes
/// covers at least the share of a 320x240 picture the assertion names.
#[test]
fn auto_framing_fills_the_picture() {
    let Some(meshes) = meshes_dir_or_skip("auto_framing_fills_the_picture") else {
        return;
    };
    let dir = scratch("framing");
    for name in ["bunny.obj", "teapot.obj", "dragon_res3.ply", "dragon_res4.ply"] {
        let out = dir.join(format!("{name}.png"));
        let mesh = meshes.join(name);
        render_ok(&[mesh.to_str().unwrap(), "--backend", "cpu"], &out, 320, 240);
        let share = covered(&out);
        assert!(share >= 0.30, "{name} covers {:.1}% of the picture", 100.0 * share);
    }
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

/// A render says what it built and how long each stage took; `--quiet` says nothing.
#[test]
fn render_reports_its_stages_unless_quiet() {
    let dir = scratch("stages");
    let out = dir.join("stages.png");
    let out = out.to_str().unwrap();
    let o = gridrt(&[
        "render",
        "--backend",
        "cpu",
        "--width",
        "32",
        "--height",
        "24",
        "-o",
        out,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("B per micro-triangle"), "{err}");
    let timings = err.lines().last().unwrap_or_default();
    for stage in ["load ", "build ", "render ", "write ", "total "] {
        assert!(timings.contains(stage), "no {stage:?} time in {err:?}");
    }
    let ply = dir.join("quiet.ply");
    for mut args in [
        vec![
            "render",
            "--quiet",
            "--backend",
            "cpu",
            "--width",
            "32",
            "--height",
            "24",
            "-o",
            out,
        ],
        vec!["export", "-q", "--levels", "1", "-o"],
    ] {
        if args[0] == "export" {
            args.push(ply.to_str().unwrap());
        }
        let o = gridrt(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        assert_eq!(stderr(&o), "", "gridrt {args:?} was not quiet");
    }
}

/// The camera flags: the defaults spelled out change nothing, another side changes the
/// picture, and a view without a direction is refused before any work.
#[test]
fn the_camera_can_be_placed() {
    let dir = scratch("camera");
    let png = |name: &str| dir.join(name).to_str().unwrap().to_string();
    let render = |extra: &[&str], out: &str| {
        let mut args = vec![
            "render",
            "--backend",
            "cpu",
            "--levels",
            "1",
            "--width",
            "48",
            "--height",
            "36",
            "-o",
            out,
        ];
        args.extend_from_slice(extra);
        let o = gridrt(&args);
        assert!(o.status.success(), "gridrt {args:?}: {}", stderr(&o));
        // Empty where the output is a turntable's frames.
        std::fs::read(out).unwrap_or_default()
    };
    let default = render(&[], &png("default.png"));
    let spelled = ["--azimuth", "35", "--elevation", "25", "--fov", "40", "--up", "0,1,0"];
    assert!(
        render(&spelled, &png("spelled.png")) == default,
        "the defaults spelled out differ"
    );
    assert!(render(&["--azimuth", "-145"], &png("behind.png")) != default);
    let placed = render(&["--eye", "3,2,4", "--target", "0,0,0"], &png("placed.png"));
    assert!(placed != default);
    check_png(&dir.join("placed.png"), 48, 36);
    // A turntable: N frames, the first the plain view, each another.
    let spin = dir.join("spin.png");
    render(&["--turntable", "3"], spin.to_str().unwrap());
    let frames: Vec<Vec<u8>> = (0..3)
        .map(|k| std::fs::read(dir.join(format!("spin_00{k}.png"))).unwrap())
        .collect();
    assert!(frames[0] == default && frames[1] != frames[0] && frames[2] != frames[1]);
    assert!(!spin.exists());
    for (args, needle) in [
        (&["--turntable", "2", "--eye", "1,2,3"][..], "cannot be used with"),
        (&["--turntable", "0"], "--turntable"),
        (&["--eye", "1,2"][..], "x,y,z"),
        (&["--distance", "-1"], "above zero"),
        (&["--eye", "1,1,1", "--target", "1,1,1"], "no direction"),
        (&["--fov", "180"], "field of view"),
        (&["--up", "0,0,0"], "no length"),
    ] {
        let mut all = vec!["render", "--backend", "cpu", "-o", "x.png"];
        all.extend_from_slice(args);
        let o = gridrt(&all);
        assert!(!o.status.success(), "gridrt {all:?} succeeded");
        let err = stderr(&o);
        assert!(err.contains(needle), "gridrt {all:?}: {err}");
        assert!(!err.contains("B per micro-triangle"), "built before refusing: {err}");
    }
}

#[test]
fn renders_a_mesh_file() {
    let Some(meshes) = meshes_dir_or_skip("renders_a_mesh_file") else {
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
        let out = dir.join("broken.png");
        let args = [
            "render",
            path.to_str().unwrap(),
            "--backend",
            "cpu",
            "--output",
            out.to_str().unwrap(),
        ];
        fails_with(&args, &[], &[path.to_str().unwrap(), problem]);
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

#[test]
fn huge_images_are_refused_before_any_work() {
    let dir = scratch("huge_image");
    let out = dir.join("huge.png");
    let out = out.to_str().unwrap();
    let limit = [("GRIDRT_MEMORY_LIMIT", "8G")];
    for size in ["65536", "100000", "4294967295"] {
        let args = [
            "render",
            "--backend",
            "cpu",
            "--width",
            size,
            "--height",
            size,
            "-o",
            out,
        ];
        fails_with(&args, &limit, &[&format!("{size}x{size} image"), "memory"]);
    }
    assert!(!Path::new(out).exists(), "a refused render left a file");
}

#[test]
fn bad_output_paths_are_refused_before_any_work() {
    let dir = scratch("bad_output");
    let jpg = dir.join("x.jpg");
    fails_with(
        &["render", "--backend", "cpu", "-o", jpg.to_str().unwrap()],
        &[],
        &["x.jpg", "unsupported format ('.jpg')", "PNG"],
    );
    assert!(!jpg.exists(), "a refused render left {}", jpg.display());
    let nowhere = dir.join("no/such/folder/x.png");
    fails_with(
        &["render", "--backend", "cpu", "-o", nowhere.to_str().unwrap()],
        &[],
        &["x.png", "does not exist"],
    );
    fails_with(
        &["render", "--backend", "cpu", "-o", dir.to_str().unwrap()],
        &[],
        &["is a folder"],
    );
    fails_with(
        &["bench", "x.obj", "--chart", jpg.to_str().unwrap()],
        &[],
        &["unsupported format"],
    );
}

#[test]
fn counts_below_one_are_refused() {
    for flag in [
        "--repeats",
        "--views",
        "--build-repeats",
        "--ao-samples",
        "--width",
        "--height",
    ] {
        fails_with(&["bench", "x.obj", flag, "0"], &[], &[flag, "0"]);
    }
    fails_with(&["render", "--width", "0"], &[], &["--width", "0"]);
}

/// Leaves too large for one leaf test with their siblings (three levels left out under a
/// sphere level) are refused up front; three levels out of three leave only the root, which
/// works.
#[test]
fn leaves_past_the_static_list_are_refused() {
    fails_with(
        &["render", "--backend", "cpu", "--levels", "4", "--excluded-levels", "3"],
        &[],
        &["64 micro-triangles", "static index list", "at most 2"],
    );
    let dir = scratch("root_leaf");
    let out = dir.join("root_leaf.png");
    let o = Command::new(gridrt_exe())
        .args([
            "render",
            "--backend",
            "cpu",
            "--levels",
            "3",
            "--excluded-levels",
            "3",
            "-q",
            "-o",
        ])
        .arg(&out)
        .output()
        .expect("run gridrt");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.exists());
}

/// On a device that is the CPU (lavapipe), an uploaded scene's copies live in host memory too:
/// a render whose build fits but whose upload would not is refused before the build.
#[test]
fn uploads_beyond_host_memory_are_refused_before_any_work() {
    let Some(gpu) = gpu_or_skip("uploads_beyond_host_memory_are_refused_before_any_work") else {
        return;
    };
    if gpu.host_upload_bytes(1) == 0 {
        eprintln!("SKIPPED: {} keeps scenes in its own memory", gpu.describe());
        return;
    }
    let args = [
        "render",
        "--backend",
        "gpu",
        "--width",
        "32",
        "--height",
        "24",
        "-o",
        "x.png",
    ];
    let needles = ["default scene uploaded to", "memory", "--backend cpu"];
    fails_with(&args, &[("GRIDRT_MEMORY_LIMIT", "300M")], &needles);
    if let Some(meshes) = meshes_dir() {
        let teapot = meshes.join("teapot.obj");
        let bench = [
            "bench",
            teapot.to_str().unwrap(),
            "--backend",
            "gpu",
            "--width",
            "32",
            "--height",
            "24",
        ];
        let needles = ["teapot.obj on ", "host memory", "--backend cpu"];
        fails_with(&bench, &[("GRIDRT_MEMORY_LIMIT", "300M")], &needles);
    }
    // The same render on the CPU backend fits.
    let dir = scratch("upload_memory");
    let out = dir.join("cpu.png");
    let cpu = Command::new(gridrt_exe())
        .args([
            "render",
            "--backend",
            "cpu",
            "-q",
            "--width",
            "32",
            "--height",
            "24",
            "-o",
        ])
        .arg(&out)
        .env("GRIDRT_MEMORY_LIMIT", "300M")
        .output()
        .expect("run gridrt");
    assert!(cpu.status.success(), "{}", stderr(&cpu));
}

#[test]
fn builds_beyond_memory_are_refused_before_any_work() {
    let limit = [("GRIDRT_MEMORY_LIMIT", "100M")];
    fails_with(
        &["stats", "--levels", "6"],
        &limit,
        &["--levels 6", "2293760 micro-triangles", "memory", "GRIDRT_MEMORY_LIMIT"],
    );
    fails_with(
        &[
            "render",
            "--levels",
            "6",
            "--mode",
            "triangles",
            "--backend",
            "cpu",
            "-o",
            "x.png",
        ],
        &limit,
        &["triangles mode at --levels 6", "memory", "fewer --levels"],
    );
    fails_with(
        &["stats"],
        &[("GRIDRT_MEMORY_LIMIT", "lots")],
        &["GRIDRT_MEMORY_LIMIT=\"lots\""],
    );
    if let Some(meshes) = meshes_dir() {
        let dragon = meshes.join("dragon_res3.ply");
        fails_with(
            &["stats", dragon.to_str().unwrap(), "--levels", "5"],
            &[("GRIDRT_MEMORY_LIMIT", "4G")],
            // 46,540 base triangles once 1,254 duplicate faces are dropped.
            &["dragon_res3.ply", "--levels 5", "47656960 micro-triangles"],
        );
    }
}

/// A successful GPU run prints no line starting with "error" (the Vulkan layers' complaints
/// about a missing desktop session included).
#[test]
fn a_successful_gpu_run_prints_no_error() {
    if gpu_or_skip("a_successful_gpu_run_prints_no_error").is_none() {
        return;
    }
    let dir = scratch("quiet_gpu");
    let out = dir.join("quiet.png");
    let o = Command::new(gridrt_exe())
        .args(["render", "--backend", "gpu", "--width", "64", "--height", "48", "-o"])
        .arg(&out)
        .env_remove("XDG_RUNTIME_DIR")
        .output()
        .expect("run gridrt");
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(!err.lines().any(|l| l.to_lowercase().contains("error")), "{err}");
}

/// `gridrt export` writes the micro-mesh in the input's units; loaded again and subdivided
/// 0 times it is the same micro-triangles: the same corners, in the same order.
#[test]
fn export_round_trips() {
    use gridrt::mesh::scene::default_scene;
    use gridrt::subdiv::{subdivide, Scheme};

    let dir = scratch("export");
    let out = dir.join("micro.ply");
    let o = gridrt(&["export", "--levels", "2", "-o", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Parsed as written (loading would weld the vertices that coincide in f32).
    let back = gridrt::mesh::ply::parse_ply(&std::fs::read(&out).unwrap())
        .unwrap()
        .to_f32();

    let mut mesh = default_scene();
    let frame = mesh.into_local_frame();
    let sub = subdivide(&mesh, 2, Scheme::Loop);
    let expected = sub.micro_triangles(2);
    assert_eq!(back.triangles.len(), mesh.triangles.len() * 16);
    assert_eq!(back.triangles, expected);
    let world: Vec<_> = sub.positions.iter().map(|&p| frame.to_world(p).as_vec3()).collect();
    assert_eq!(back.positions, world);
    // Within rounding of the scene as given (the frame's round trip is exact to f32).
    let (lo, hi) = default_scene().bounds();
    let (blo, bhi) = back.bounds();
    assert!((lo - blo).abs().max_element() < 0.5 && (hi - bhi).abs().max_element() < 0.5);

    // And rendered at --levels 0 it is a picture.
    render_ok(
        &[out.to_str().unwrap(), "--backend", "cpu", "--levels", "0"],
        &dir.join("micro.png"),
        96,
        64,
    );
    fails_with(
        &["export", "-o", dir.join("micro.obj").to_str().unwrap()],
        &[],
        &["unsupported format ('.obj')", "PLY"],
    );
}

/// `--crease-angle 30` keeps a cube a cube: exported, every micro-vertex lies on its surface
/// and every one on its edges stays on them, in millimetres far from the origin as at the
/// unit scale. Without it Loop subdivision rounds the corners off.
#[test]
fn creases_keep_a_cube_sharp() {
    let dir = scratch("creases");
    let cube = dir.join("cube.obj");
    let (lo, size) = (2500.0f64, 40.0f64);
    let mut obj = String::new();
    for i in 0..8 {
        let c = |bit: u32| lo + if i & bit != 0 { size } else { 0.0 };
        obj += &format!("v {} {} {}\n", c(1), c(2), c(4));
    }
    // Quads, counter-clockwise from outside, as faces of 1-based vertex ids.
    obj += "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n";
    std::fs::write(&cube, obj).unwrap();
    let levels = 3;
    let per_edge = (1 << levels) - 1;
    for (creased, on_edges) in [(true, 12 * per_edge + 8), (false, 0)] {
        let out = dir.join(format!("cube_{creased}.ply"));
        let mut args = vec!["export", "-q", cube.to_str().unwrap(), "--levels", "3"];
        if creased {
            args.extend(["--crease-angle", "30"]);
        }
        args.extend(["-o", out.to_str().unwrap()]);
        let o = gridrt(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        let (micro, _) = gridrt::input::load_mesh_quiet(&out).unwrap();
        let tolerance = size * 1e-5;
        let at_bound = |x: f32| {
            let x = x as f64;
            (x - lo).abs() < tolerance || (x - lo - size).abs() < tolerance
        };
        let bounds_hit = |p: &gridrt_shared::glam::Vec3| p.to_array().into_iter().filter(|&x| at_bound(x)).count();
        if creased {
            assert!(
                micro.positions.iter().all(|p| bounds_hit(p) >= 1),
                "a vertex left the cube's faces"
            );
        }
        let edge_vertices = micro.positions.iter().filter(|p| bounds_hit(p) >= 2).count();
        assert_eq!(edge_vertices, on_edges, "creased: {creased}");
    }
    fails_with(
        &["render", cube.to_str().unwrap(), "--crease-angle", "200"],
        &[],
        &["--crease-angle", "between 0 and 180"],
    );
}

/// `--shading depth` and `--shading cost` render pictures; the heat map prints its scale
/// (the 99th percentile's tests, or `--heat-white`'s) and how many tests of each kind a pixel
/// makes on average.
#[test]
fn depth_and_cost_shading_render_and_cost_prints_its_scale() {
    let dir = scratch("shading");
    render_ok(
        &["--backend", "cpu", "--levels", "2", "--shading", "depth"],
        &dir.join("depth.png"),
        96,
        64,
    );
    let cost = dir.join("cost.png");
    for (white, expect) in [
        (None, "99th percentile"),
        (Some("500"), "white 500 tests (--heat-white"),
    ] {
        let mut args = vec!["--backend", "cpu", "--levels", "2", "--shading", "cost"];
        if let Some(w) = white {
            args.extend(["--heat-white", w]);
        }
        let mut all = vec!["render"];
        all.extend(&args);
        all.extend(["--width", "96", "--height", "64", "-o", cost.to_str().unwrap()]);
        let line = report_line(&all, "cost per pixel");
        assert!(line.contains(expect) && line.contains("spheres"), "{line}");
        check_png(&cost, 96, 64);
    }
    fails_with(
        &["render", "--shading", "cost", "--heat-white", "0"],
        &[],
        &["--heat-white"],
    );
}

#[test]
fn lod_auto_states_its_depths_and_cracks() {
    let dir = scratch("lod");
    let out = dir.join("level.png");
    let args = [
        "render",
        "--backend",
        "cpu",
        "--levels",
        "4",
        "--lod",
        "auto",
        "--lod-pixels",
        "3",
        "--shading",
        "level",
        "--width",
        "96",
        "--height",
        "64",
        "-o",
    ];
    let line = report_line(
        &[&args[..], &[out.to_str().unwrap()]].concat(),
        "level of detail (3 px): grids ",
    );
    assert!(line.contains("widest crack") && line.contains(" px"), "{line}");
    check_png(&out, 96, 64);
    for (flag, value) in [("--lod", "auto"), ("--shading", "level")] {
        fails_with(&["render", "--mode", "triangles", flag, value], &[], &[flag, "grids"]);
    }
    fails_with(&["render", "--lod", "coarse"], &[], &["--lod", "auto"]);
    fails_with(
        &["render", "--lod", "auto", "--lod-pixels", "0"],
        &[],
        &["--lod-pixels"],
    );
}

/// A hard-surface part as glTF, in millimetres far from the origin: a 40 mm cube on a
/// 100 x 10 x 60 mm plinth, two primitives of one mesh under a node that moves it by 5 m and
/// turns it a quarter about y. Returns the document (buffer `uri` given, or none for a GLB)
/// and its binary buffer.
fn machined_part(uri: Option<&str>) -> (String, Vec<u8>) {
    let cube = |min: [f32; 3], max: [f32; 3]| -> Vec<f32> {
        (0..8)
            .flat_map(|k| {
                let pick = |axis: usize| if k >> axis & 1 == 1 { max[axis] } else { min[axis] };
                [pick(0), pick(1), pick(2)]
            })
            .collect()
    };
    // Outward-wound faces of a box whose corner k has x, y, z from bits 0, 1, 2 of k.
    let faces: [u16; 36] = [
        0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5,
    ];
    let mut bin = Vec::new();
    for v in cube([-20.0, 10.0, -20.0], [20.0, 50.0, 20.0])
        .iter()
        .chain(&cube([-50.0, 0.0, -30.0], [50.0, 10.0, 30.0]))
    {
        bin.extend(v.to_le_bytes());
    }
    for i in faces {
        bin.extend(i.to_le_bytes());
    }
    let uri = uri.map_or(String::new(), |u| format!(r#""uri": "{u}", "#));
    let json = format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "scene": 0,
  "scenes": [{{"nodes": [0]}}],
  "nodes": [{{"mesh": 0, "translation": [5000, 0, 0], "rotation": [0, 0.7071068, 0, 0.7071068]}}],
  "meshes": [{{"primitives": [
    {{"attributes": {{"POSITION": 0}}, "indices": 2}},
    {{"attributes": {{"POSITION": 1}}, "indices": 2}}
  ]}}],
  "buffers": [{{{uri}"byteLength": {len}}}],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": 96}},
    {{"buffer": 0, "byteOffset": 96, "byteLength": 96}},
    {{"buffer": 0, "byteOffset": 192, "byteLength": 72}}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3", "min": [-20, 10, -20], "max": [20, 50, 20]}},
    {{"bufferView": 1, "componentType": 5126, "count": 8, "type": "VEC3", "min": [-50, 0, -30], "max": [50, 10, 30]}},
    {{"bufferView": 2, "componentType": 5123, "count": 36, "type": "SCALAR"}}
  ]
}}"#,
        len = bin.len()
    );
    (json, bin)
}

/// glTF end to end through the binary: a part with a node transform and two primitives, as
/// `.gltf` with an external buffer and as `.glb`, renders the same picture creased and
/// smooth-shaded; the report counts both primitives' triangles.
#[test]
fn renders_gltf_files_end_to_end() {
    let dir = scratch("gltf");
    let (json, bin) = machined_part(Some("part.bin"));
    std::fs::write(dir.join("part.bin"), &bin).unwrap();
    std::fs::write(dir.join("part.gltf"), json).unwrap();
    let (json, bin) = machined_part(None);
    std::fs::write(
        dir.join("part.glb"),
        gridrt::mesh::gltf::glb_container(json.as_bytes(), &bin),
    )
    .unwrap();
    let mut pictures = Vec::new();
    for file in ["part.gltf", "part.glb"] {
        let input = dir.join(file);
        let out = dir.join(file).with_extension("png");
        let args = [
            "render",
            input.to_str().unwrap(),
            "--backend",
            "cpu",
            "--crease-angle",
            "30",
            "--smooth",
            "--width",
            "96",
            "--height",
            "72",
            "-o",
            out.to_str().unwrap(),
        ];
        let line = report_line(&args, input.to_str().unwrap());
        assert!(line.contains("24 base triangles"), "{line}");
        check_png(&out, 96, 72);
        pictures.push(std::fs::read(&out).unwrap());
    }
    assert!(pictures[0] == pictures[1], "the .gltf and the .glb render differently");
}

/// `--smooth` renders grids and is refused for the baseline; ambient occlusion renders
/// through its passes.
#[test]
fn smooth_shading_and_ambient_occlusion_render() {
    let dir = scratch("smooth");
    render_ok(
        &["--backend", "cpu", "--levels", "2", "--smooth", "--shading", "normal"],
        &dir.join("smooth.png"),
        96,
        64,
    );
    render_ok(
        &[
            "--backend",
            "cpu",
            "--levels",
            "2",
            "--shading",
            "ao",
            "--ao-samples",
            "20",
        ],
        &dir.join("ao.png"),
        96,
        64,
    );
    fails_with(
        &["render", "--mode", "triangles", "--smooth"],
        &[],
        &["--smooth", "grids"],
    );
}

/// `compare`: two parallel squares a quarter apart (in millimetres, far from the origin) are
/// a quarter apart everywhere, as a fraction of the reference's diagonal; a surface is at no
/// distance from itself.
#[test]
fn compare_measures_the_distance_between_surfaces() {
    let dir = scratch("compare");
    let square = |z: f64| {
        let v: String = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
            .iter()
            .map(|(x, y)| format!("v {} {} {}\n", 1e6 + x, 2e6 + y, z))
            .collect();
        v + "f 1 2 3\nf 1 3 4\n"
    };
    let (a, b) = (dir.join("a.obj"), dir.join("b.obj"));
    std::fs::write(&a, square(5.0)).unwrap();
    std::fs::write(&b, square(5.25)).unwrap();
    let (a, b) = (a.to_str().unwrap(), b.to_str().unwrap());
    let o = gridrt(&["compare", a, b, "--samples", "2000", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(
        (report["diagonal"].as_f64().unwrap() - 2f64.sqrt()).abs() < 1e-9,
        "{report}"
    );
    for key in ["reference_to_other", "other_to_reference", "symmetric"] {
        let rms = report[key]["rms"].as_f64().unwrap();
        assert!((rms - 0.25 / 2f64.sqrt()).abs() < 1e-6, "{key}: {report}");
    }
    let o = gridrt(&["compare", a, a, "--samples", "2000"]);
    let table = String::from_utf8_lossy(&o.stdout);
    let both = table.lines().find(|l| l.starts_with("| both (symmetric) |")).unwrap();
    let max: f64 = both.split('|').nth(4).unwrap().trim().parse().unwrap();
    assert!(max < 1e-12 && both.ends_with("| 4000 |"), "{table}");
}

/// A displaced micro-mesh of two level-3 triangles sharing an edge, written to `gltf`.
fn two_displaced_triangles(gltf: &std::path::Path) -> std::path::PathBuf {
    use gridrt::mesh::frame::LocalFrame;
    use gridrt::micromesh::bary::{values_per_triangle, Micromap};
    use gridrt::micromesh::DisplacedMesh;
    use gridrt_shared::glam::Vec3;

    let level = 3;
    let values = |seed: u32| -> Vec<u16> {
        (0..values_per_triangle(level) as u32)
            .map(|k| ((k * 7919 + seed) % 2048) as u16)
            .collect()
    };
    // Values on the shared edge (vertices 1 and 2) must agree: constant there on both sides.
    let mut first = values(1);
    let mut second = values(2);
    let n = 1u32 << level;
    for k in 0..=n {
        first[gridrt_shared::displacement::u_major_index([n - k, k], n) as usize] = 1000;
        second[gridrt_shared::displacement::u_major_index([k, n - k], n) as usize] = 1000;
    }
    let mesh = DisplacedMesh {
        positions: vec![
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
        ],
        directions: vec![Vec3::Z; 4],
        triangles: vec![[0, 1, 2], [3, 2, 1]],
        micromap: Micromap::from_triangles(-0.1, 0.2, &[(level, first), (level, second)]),
        decimated_edges: Vec::new(),
    };
    gridrt::micromesh::gltf::write(gltf, &mesh, &LocalFrame::IDENTITY).unwrap();
    gltf.to_path_buf()
}

/// A displaced micro-mesh (glTF + .bin + .bary as gridrt writes them) renders, measures and
/// benchmarks as displaced grids, and exports as its decoded micro-triangles, welded along
/// the shared base edge.
#[test]
fn displaced_micro_meshes_are_decoded_not_subdivided() {
    let dir = scratch("displaced");
    let gltf = two_displaced_triangles(&dir.join("baked.gltf"));
    let g = gltf.to_str().unwrap();

    let png = dir.join("baked.png");
    let o = render_small(&gltf, &png);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("a displaced micro-mesh of 2 base triangles at level 3, 128 micro-triangles"),
        "{err}"
    );
    // Traced as displaced grids: 2 grids of 64 micro-triangles.
    assert!(
        err.contains("baked.gltf: 2 base triangles, 128 micro-triangles at depth 3"),
        "{err}"
    );
    // Its own level bounds the depth rendered, whatever --levels says.
    let shallow = dir.join("shallow.png");
    let o = gridrt(&[
        "render",
        g,
        "--backend",
        "cpu",
        "--lod",
        "2",
        "--levels",
        "1",
        "-o",
        shallow.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    fails_with(
        &[
            "render",
            g,
            "--backend",
            "cpu",
            "--lod",
            "4",
            "-o",
            shallow.to_str().unwrap(),
        ],
        &[],
        &["--lod 4 is deeper than the micro-mesh's level (3)"],
    );
    check_png(&png, 64, 48);

    let ply = dir.join("decoded.ply");
    let o = gridrt(&["export", g, "-o", ply.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let decoded = gridrt::mesh::ply::parse_ply(&std::fs::read(&ply).unwrap()).unwrap();
    // 45 lattice points a triangle, the 9 of the shared edge welded into one row.
    assert_eq!((decoded.triangles.len(), decoded.positions.len()), (128, 81));

    let o = gridrt(&["stats", g, "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let stats: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(
        (stats["levels"].as_u64(), stats["micro_triangles"].as_u64()),
        (Some(3), Some(128))
    );
    assert!(stats["grid"]["parts"]["inner_values"].as_u64().is_some(), "{stats}");

    let o = gridrt(&[&["bench", g][..], &TINY_BENCH].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("| baked.gltf | 128 |"));
}
