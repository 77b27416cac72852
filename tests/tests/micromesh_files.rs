//! Micro-mesh files (glTF + buffer + `.bary`) as safe as plain meshes, tried as a careless or
//! hostile user would: no input overwritten by any file a command writes, no mixed output
//! set, sizes refused before the work, no wait on a pipe, and nothing that reads otherwise
//! than the file or the options say without a word. Every file is made here.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use gridrt::mesh::Mesh;
use gridrt_shared::glam::Vec3;
use gridrt_tests::{bumpy_ball, fails_with, gridrt, gridrt_exe, render_small, scratch, side_files, stderr};
use serde_json::{json, Value};

fn s(path: &Path) -> &str {
    path.to_str().expect("a UTF-8 path")
}

fn write_obj(path: &Path, mesh: &Mesh) {
    let mut text = String::new();
    for p in &mesh.positions {
        text += &format!("v {} {} {}\n", p.x, p.y, p.z);
    }
    for t in &mesh.triangles {
        text += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    std::fs::write(path, text).unwrap();
}

/// Runs gridrt, which must succeed; returns its stderr.
fn succeeds(args: &[&str]) -> String {
    let o = gridrt(args);
    let err = stderr(&o);
    assert!(o.status.success(), "gridrt {args:?} failed: {err}");
    assert!(!err.contains("panicked"), "{err}");
    err
}

/// A bumpy ball of 128 triangles in `dir`, baked at `level` to `name`: the reference and the
/// glTF.
fn baked(dir: &Path, name: &str, level: u32) -> (PathBuf, PathBuf) {
    let reference = dir.join("ball.obj");
    if !reference.exists() {
        write_obj(&reference, &bumpy_ball(2));
    }
    let out = dir.join(name);
    let level = level.to_string();
    succeeds(&[
        "bake",
        s(&reference),
        "-L",
        &level,
        "-o",
        s(&out),
        "--samples",
        "200",
        "-q",
    ]);
    (reference, out)
}

fn read_json(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// `gltf`'s document changed by `edit`, written as `name` beside it, naming the same side
/// files.
fn edited(gltf: &Path, name: &str, edit: impl FnOnce(&mut Value)) -> PathBuf {
    let mut document = read_json(gltf);
    edit(&mut document);
    let path = gltf.with_file_name(name);
    std::fs::write(&path, serde_json::to_vec_pretty(&document).unwrap()).unwrap();
    path
}

/// `gltf` copied as `name`, its buffer and micromap copied to `bin` and `bary` beside it.
fn copied(gltf: &Path, name: &str, bin: &str, bary: &str) -> PathBuf {
    let sides = side_files(gltf);
    std::fs::copy(&sides[0], gltf.with_file_name(bin)).unwrap();
    std::fs::copy(&sides[1], gltf.with_file_name(bary)).unwrap();
    edited(gltf, name, |d| {
        d["buffers"][0]["uri"] = json!(bin);
        d["extensions"]["NV_micromaps"]["micromaps"][0]["uri"] = json!(bary);
    })
}

fn bytes(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The names in `dir`, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = (std::fs::read_dir(dir).unwrap())
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// No file a command writes is one it reads: neither the buffer and micromap a bake writes
/// beside its glTF (which take names of their own), nor a picture or a PLY named as a file
/// an input glTF reads, through another name or a hard link.
#[test]
fn outputs_never_overwrite_what_the_inputs_read() {
    let dir = scratch("mm-inputs");
    let (_, first) = baked(&dir, "first.gltf", 1);
    // x.gltf reads y.bin and y.bary: baking it to y.gltf leaves them as they were.
    let x = copied(&first, "x.gltf", "y.bin", "y.bary");
    let before = (bytes(&dir.join("y.bin")), bytes(&dir.join("y.bary")));
    let y = dir.join("y.gltf");
    succeeds(&["bake", s(&x), "-L", "1", "-o", s(&y), "--samples", "200", "-q"]);
    assert_eq!((bytes(&dir.join("y.bin")), bytes(&dir.join("y.bary"))), before);
    succeeds(&["stats", s(&x), "-q"]);
    succeeds(&["stats", s(&y), "-q"]);
    // Baking again to y.gltf, whose side files x2.gltf reads now: they stay.
    let x2 = edited(&y, "x2.gltf", |_| {});
    let read_by_x2 = side_files(&x2);
    let kept: Vec<Vec<u8>> = read_by_x2.iter().map(|p| bytes(p)).collect();
    succeeds(&["bake", s(&x2), "-L", "2", "-o", s(&y), "--samples", "200", "-q"]);
    assert_eq!(read_by_x2.iter().map(|p| bytes(p)).collect::<Vec<_>>(), kept);
    succeeds(&["stats", s(&x2), "-q"]);

    // A picture named as the buffer its input reads.
    let shot = copied(&first, "shot.gltf", "shot.png", "shot.bary");
    let buffer = bytes(&dir.join("shot.png"));
    let png = dir.join("shot.png");
    fails_with(
        &["render", s(&shot), "--backend", "cpu", "-o", s(&png)],
        &[],
        &["shot.png", "is the input"],
    );
    assert_eq!(bytes(&png), buffer);
    // A PLY that is a hard link to the micromap its input reads.
    let link = dir.join("link.ply");
    std::fs::hard_link(dir.join("shot.bary"), &link).unwrap();
    let micromap = bytes(&link);
    fails_with(
        &["export", s(&shot), "-o", s(&link)],
        &[],
        &["link.ply", "is the input"],
    );
    assert_eq!(bytes(&link), micromap);
}

/// A bake over an earlier one replaces the whole set: the glTF names the new buffer and
/// micromap, the old ones are gone, nothing else in the folder is touched; bakes into one
/// output at once all succeed and leave one whole set.
#[test]
fn an_output_set_is_replaced_whole() {
    let dir = scratch("mm-sets");
    let (reference, out) = baked(&dir, "out.gltf", 1);
    std::fs::write(dir.join("out.bin"), "a file of the user's").unwrap();
    let old = side_files(&out);
    let (_, out) = baked(&dir, "out.gltf", 2);
    let new = side_files(&out);
    assert!(old.iter().all(|p| !p.exists()), "{:?}", listing(&dir));
    assert!(new.iter().all(|p| p.is_file()));
    let mut expected = vec!["ball.obj".to_string(), "out.bin".into(), "out.gltf".into()];
    expected.extend(
        new.iter()
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned()),
    );
    expected.sort();
    assert_eq!(listing(&dir), expected);
    assert_eq!(bytes(&dir.join("out.bin")), b"a file of the user's");

    // Six bakes of two kinds into one output at once.
    let children: Vec<_> = (0..6)
        .map(|k| {
            Command::new(gridrt_exe())
                .args(["bake", s(&reference), "-L", if k % 2 == 0 { "1" } else { "2" }])
                .args(["-o", s(&out), "--samples", "200", "-q"])
                .stderr(Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for child in children {
        let o = child.wait_with_output().unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let stats = gridrt(&["stats", s(&out), "--json", "-q"]);
    assert!(stats.status.success(), "{}", stderr(&stats));
    let stats: Value = serde_json::from_slice(&stats.stdout).unwrap();
    let micro = stats["micro_triangles"]
        .as_u64()
        .or(stats["grid"]["micro_triangles"].as_u64());
    assert!(matches!(micro, Some(512) | Some(2048)), "{stats}");
    assert!(side_files(&out).iter().all(|p| p.is_file()));
    assert!(
        !listing(&dir).iter().any(|n| n.ends_with(".tmp")),
        "{:?}",
        listing(&dir)
    );
}

/// Sizes a user can pass are checked against memory before any work: samples, fitting
/// rounds, and instances of a micro-mesh counted before they are expanded.
#[test]
fn sizes_are_refused_before_any_work() {
    let dir = scratch("mm-sizes");
    let (reference, out) = baked(&dir, "out.gltf", 1);
    let r = s(&reference);
    let limit = [("GRIDRT_MEMORY_LIMIT", "200M")];
    let started = Instant::now();
    fails_with(
        &["bake", r, "--samples", "100000000000"],
        &limit,
        &["--samples", "memory"],
    );
    fails_with(
        &["compare", r, s(&out), "--samples", "2000000000"],
        &limit,
        &["--samples", "memory"],
    );
    fails_with(
        &["bake", r, "--fit-rounds", "4294967295"],
        &[],
        &["--fit-rounds", "0..=100"],
    );
    // 20,000 nodes drawing the same displaced mesh: 10 million micro-triangles.
    let many = edited(&out, "many.gltf", |d| {
        d["nodes"] = json!((0..20_000)
            .map(|k| json!({"mesh": 0, "translation": [k as f64, 0.0, 0.0]}))
            .collect::<Vec<_>>());
        d["scenes"][0]["nodes"] = json!((0..20_000).collect::<Vec<_>>());
    });
    fails_with(
        &["stats", s(&many)],
        &limit,
        &["many.gltf", "20000 meshes drawn", "memory"],
    );
    assert!(
        started.elapsed() < Duration::from_secs(60),
        "took {:?}",
        started.elapsed()
    );
}

/// Runs gridrt with a deadline; `None` if it was still running then (and was killed).
fn within(args: &[&str], seconds: u64) -> Option<std::process::Output> {
    let mut child = (Command::new(gridrt_exe()).args(args))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(seconds);
    while Instant::now() < deadline {
        if child.try_wait().unwrap().is_some() {
            return Some(child.wait_with_output().unwrap());
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let _ = child.kill();
    let _ = child.wait();
    None
}

/// A named pipe is refused, as a mesh or as the micromap a glTF names, not waited on.
#[cfg(unix)]
#[test]
fn pipes_are_refused_not_waited_on() {
    let dir = scratch("mm-pipes");
    let (_, out) = baked(&dir, "out.gltf", 1);
    let pipe = dir.join("pipe.bary");
    let made = Command::new("mkfifo").arg(&pipe).status();
    if !made.is_ok_and(|s| s.success()) {
        eprintln!("skipped: no mkfifo");
        return;
    }
    let piped = edited(&out, "piped.gltf", |d| {
        d["extensions"]["NV_micromaps"]["micromaps"][0]["uri"] = json!("pipe.bary");
    });
    let o = within(&["stats", s(&piped)], 30).expect("waited on a named pipe");
    let err = stderr(&o);
    assert!(
        !o.status.success() && err.contains("pipe.bary") && err.contains("named pipe"),
        "{err}"
    );
    let mesh_pipe = dir.join("pipe.obj");
    Command::new("mkfifo").arg(&mesh_pipe).status().unwrap();
    let o = within(&["stats", s(&mesh_pipe)], 30).expect("waited on a named pipe");
    assert!(stderr(&o).contains("is a named pipe, not a file"), "{}", stderr(&o));
}

/// A file that leaves out what its micro-mesh needs is refused, or read with the default
/// the extension gives and a warning; never silently as something else.
#[test]
fn files_that_say_less_are_refused_or_warned_about() {
    let dir = scratch("mm-less");
    let (_, out) = baked(&dir, "out.gltf", 1);
    let no_root = edited(&out, "no-root.gltf", |d| {
        d["extensions"].as_object_mut().unwrap().remove("NV_micromaps");
    });
    fails_with(
        &["stats", s(&no_root)],
        &[],
        &["no-root.gltf", "primitive 0", "NV_micromaps"],
    );
    // Without directions, the normals displace it: said, not silent.
    let normals = edited(&out, "normals.gltf", |d| {
        let primitive = &mut d["meshes"][0]["primitives"][0];
        primitive["attributes"]["NORMAL"] = json!(1);
        let extension = primitive["extensions"]["NV_displacement_micromap"]
            .as_object_mut()
            .unwrap();
        extension.remove("directions");
    });
    let err = succeeds(&["stats", s(&normals), "-q"]);
    assert!(
        err.contains("warning: ") && err.contains("normals.gltf") && err.contains("vertex normals"),
        "{err}"
    );
    let short = edited(&out, "short.gltf", |d| {
        let count = d["accessors"][2]["count"].as_u64().unwrap();
        d["accessors"][2]["count"] = json!(count - 1);
    });
    fails_with(&["stats", s(&short)], &[], &["short.gltf", "not whole triangles"]);
    let lines = edited(&out, "lines.gltf", |d| {
        d["meshes"][0]["primitives"][0]["mode"] = json!(1)
    });
    let err = fails_with(&["stats", s(&lines)], &[], &["lines.gltf", "Lines"]);
    assert!(!err.contains("strips"), "{err}");
    fails_with(
        &["export", s(&out), "-L", "5"],
        &[],
        &["out.gltf", "--levels 5 does not apply"],
    );
}

/// A square of two triangles, its corners at 0 and 1.
fn square() -> Mesh {
    Mesh {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// Bakes that lose part of the reference, miss it, or miss the bound asked for say so on
/// stderr with the figure; a small mesh bakes whole by default.
#[test]
fn bakes_that_fall_short_say_so() {
    let dir = scratch("mm-short");
    let square_obj = dir.join("square.obj");
    write_obj(&square_obj, &square());
    let out = dir.join("square.gltf");
    let json_out = gridrt(&[
        "bake",
        s(&square_obj),
        "-o",
        s(&out),
        "--samples",
        "2000",
        "--json",
        "-q",
    ]);
    assert!(json_out.status.success(), "{}", stderr(&json_out));
    assert!(!stderr(&json_out).contains("warning"), "{}", stderr(&json_out));
    let report: Value = serde_json::from_slice(&json_out.stdout).unwrap();
    assert_eq!(report["base_triangles"], 2, "{report}");
    assert!(report["reference_to_baked"]["max"].as_f64().unwrap() < 1e-3, "{report}");

    // The ball on a base of one triangle: most of it is lost, and the bake says so.
    let (reference, _) = baked(&dir, "ball.gltf", 1);
    let o = gridrt(&[
        "bake",
        s(&reference),
        "--base-triangles",
        "1",
        "-o",
        s(&dir.join("one.gltf")),
        "-q",
    ]);
    let err = stderr(&o);
    if o.status.success() {
        assert!(
            err.contains("warning: ") && err.contains("part of the reference is lost"),
            "{err}"
        );
    } else {
        assert!(err.contains("ball.obj") && err.contains("--base-triangles"), "{err}");
    }
    // A base far from the reference: its lines meet nothing.
    let far = dir.join("far.obj");
    let moved = Mesh {
        positions: square()
            .positions
            .iter()
            .map(|p| *p * 0.5 + Vec3::new(0.0, 0.0, 5.0))
            .collect(),
        ..square()
    };
    write_obj(&far, &moved);
    let err = succeeds(&[
        "bake",
        s(&reference),
        "--base",
        s(&far),
        "-L",
        "2",
        "-o",
        s(&dir.join("far.gltf")),
        "-q",
    ]);
    assert!(err.contains("warning: ") && err.contains("met no surface"), "{err}");
    // A bound no level reaches.
    let err = succeeds(&[
        "bake",
        s(&reference),
        "--max-error",
        "0",
        "-L",
        "2",
        "-o",
        s(&dir.join("exact.gltf")),
        "-q",
    ]);
    assert!(err.contains("--max-error 0") && err.contains("is not met"), "{err}");

    // A surface without area has no distance.
    let flat = dir.join("flat.obj");
    std::fs::write(&flat, "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nf 1 2 3\nf 2 3 4\n").unwrap();
    fails_with(&["compare", s(&reference), s(&flat)], &[], &["flat.obj", "no area"]);
}

/// Errors say what is wrong with which file, in one line.
#[test]
fn messages_name_the_file_and_the_problem() {
    let dir = scratch("mm-messages");
    let (_, out) = baked(&dir, "out.gltf", 1);
    let micromap = bytes(&side_files(&out)[1]);
    std::fs::write(dir.join("cut.bary"), &micromap[..39]).unwrap();
    let cut = edited(&out, "cut.gltf", |d| {
        d["extensions"]["NV_micromaps"]["micromaps"][0]["uri"] = json!("cut.bary");
    });
    fails_with(
        &["stats", s(&cut)],
        &[],
        &["cut.gltf", "cut.bary", "truncated: 39 bytes"],
    );
    // A GLB whose magic is damaged.
    let mut glb = b"glTX".to_vec();
    glb.extend(&bytes(&out)[4..]);
    std::fs::write(dir.join("bad.glb"), &glb).unwrap();
    let err = fails_with(&["stats", s(&dir.join("bad.glb"))], &[], &["bad.glb", "GLB"]);
    assert!(!err.contains("expected value"), "{err}");
    // A micro-mesh of no size: every base position at one point, no direction.
    let flat_bin = dir.join("point.bin");
    let json = read_json(&out);
    let vertices = json["accessors"][0]["count"].as_u64().unwrap() as usize;
    let mut bin = bytes(&side_files(&out)[0]);
    bin[..24 * vertices].fill(0);
    std::fs::write(&flat_bin, &bin).unwrap();
    let point = edited(&out, "point.gltf", |d| {
        d["buffers"][0]["uri"] = json!("point.bin");
        d["accessors"][0]["min"] = json!([0.0, 0.0, 0.0]);
        d["accessors"][0]["max"] = json!([0.0, 0.0, 0.0]);
    });
    let o = render_small(&point, &dir.join("point.png"));
    let err = stderr(&o);
    assert!(
        !o.status.success() && err.contains("point.gltf") && !err.contains("eye is on the target"),
        "{err}"
    );
    // Quiet means no notes; warnings and errors still show.
    assert!(succeeds(&["stats", s(&out)]).contains("note: "));
    assert!(!succeeds(&["stats", s(&out), "-q"]).contains("note: "));
}
