//! `gridrt bake` end to end: a detailed mesh in, a displaced micro-mesh (glTF + .bin + .bary)
//! out, its report, and the files read back by the other commands.

use std::path::{Path, PathBuf};

use gridrt::mesh::Mesh;
use gridrt_tests::{bumpy_ball, fails_with, gridrt, render_small, scratch, side_files, stderr, TINY_BENCH};

fn write_obj(path: &Path, mesh: &Mesh, offset: f64) {
    let mut text = String::new();
    for p in &mesh.positions {
        let p = p.as_dvec3() + offset;
        text += &format!("v {} {} {}\n", p.x, p.y, p.z);
    }
    for t in &mesh.triangles {
        text += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    std::fs::write(path, text).unwrap();
}

fn o_str(path: &Path) -> &str {
    path.to_str().unwrap()
}

fn json(args: &[&str]) -> serde_json::Value {
    let o = gridrt(args);
    assert!(o.status.success(), "gridrt {args:?}: {}", stderr(&o));
    serde_json::from_slice(&o.stdout).unwrap()
}

/// `compare` measures the distance `bake` reported for `out`, and `render` draws it.
fn reads_back_as_measured(reference: &Path, out: &Path, report: &serde_json::Value) {
    let rms = report["symmetric"]["rms"].as_f64().unwrap();
    let compared = json(&["compare", o_str(reference), o_str(out), "--samples", "20000", "--json"]);
    assert!(
        (compared["symmetric"]["rms"].as_f64().unwrap() - rms).abs() < 0.05 * rms,
        "{compared} vs {report}"
    );
    let o = render_small(out, &out.with_extension("png"));
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A ball 1e6 from the origin bakes to its budget, close to itself, into three files that
/// `compare` and `render` read back.
#[test]
fn a_mesh_bakes_into_files_the_other_commands_read() {
    let dir = scratch("bake");
    let reference = dir.join("ball.obj");
    write_obj(&reference, &bumpy_ball(5), 1e6);
    let out = dir.join("ball.gltf");
    let (r, o) = (reference.to_str().unwrap(), out.to_str().unwrap());
    let report = json(&["bake", r, "-L", "3", "-o", o, "--samples", "20000", "--json"]);
    let base = report["base_triangles"].as_u64().unwrap();
    assert!((100..=128).contains(&base), "{report}");
    assert_eq!(report["micro_triangles"].as_u64().unwrap(), 64 * base);
    assert_eq!(report["reference_triangles"].as_u64().unwrap(), 8192);
    let rms = report["symmetric"]["rms"].as_f64().unwrap();
    assert!(rms < 1e-3, "{report}");
    // Compressed by default, within a quarter more distance than the plain bake.
    let compression = &report["compression"];
    let plain_rms = compression["uncompressed_symmetric"]["rms"].as_f64().unwrap();
    assert!(rms <= 1.25 * plain_rms, "{report}");
    assert_eq!(compression["widths"].as_array().map(Vec::len), Some(3), "{report}");
    // The files as written: the distance `compare` measures is the one `bake` reported.
    let mut written = vec![out.clone()];
    written.extend(side_files(&out));
    assert_eq!(written.len(), 3, "{written:?}");
    for (file, ext) in written.iter().zip(["gltf", "bin", "bary"]) {
        assert!(file.is_file(), "{}", file.display());
        let name = file.file_name().unwrap().to_str().unwrap();
        assert!(name.starts_with("ball.") && name.ends_with(ext), "{name}");
    }
    let files: u64 = written.iter().map(|f| std::fs::metadata(f).unwrap().len()).sum();
    assert_eq!(report["file_bytes"].as_u64().unwrap(), files);
    reads_back_as_measured(&reference, &out, &report);

    bench_measures_as_bake_did(&dir, (&reference, &out), &report);

    // The file says how its values compress: `stats` builds them compressed, and plain when
    // asked, from the same values.
    let grid_bytes = |extra: &[&str]| {
        let mut args = vec!["stats", o_str(&out), "--json"];
        args.extend(extra);
        json(&args)["grid"]["bytes"].as_u64().unwrap()
    };
    assert_eq!(Some(grid_bytes(&[])), report["grid_bytes"].as_u64());
    let said = stderr(&gridrt(&["stats", o_str(&out)]));
    assert!(
        said.contains("its values are compressed (base edges at widths ["),
        "{said}"
    );
    assert!(grid_bytes(&["--plain-values"]) > grid_bytes(&[]) * 11 / 10, "{report}");
    let plain = dir.join("plain.gltf");
    let plain_report = json(&[
        "bake",
        r,
        "-L",
        "3",
        "-o",
        o_str(&plain),
        "--samples",
        "20000",
        "--plain-values",
        "--json",
    ]);
    assert!(plain_report["compression"].is_null(), "{plain_report}");
    assert_eq!(
        plain_report["grid_bytes"].as_u64(),
        Some(grid_bytes(&["--plain-values"]))
    );

    // Onto a base the user made: the same ball, coarse.
    let base = dir.join("base.obj");
    write_obj(&base, &bumpy_ball(2), 1e6);
    let onto = dir.join("onto.gltf");
    let report = json(&[
        "bake",
        r,
        "--base",
        base.to_str().unwrap(),
        "-L",
        "2",
        "-o",
        onto.to_str().unwrap(),
        "--samples",
        "20000",
        "--json",
    ]);
    assert_eq!(report["base_triangles"].as_u64().unwrap(), 128, "{report}");
    assert!(report["symmetric"]["rms"].as_f64().unwrap() < 2e-3, "{report}");
}

/// The benchmark of a bake against its reference: the same distance and bytes as `bake`
/// reported, the reference's bytes far above the grids'.
fn bench_measures_as_bake_did(dir: &Path, (reference, out): (&Path, &Path), report: &serde_json::Value) {
    let rms = report["symmetric"]["rms"].as_f64().unwrap();
    let json_path = dir.join("bench.json");
    let mut args = vec!["bench", o_str(out), "--reference", o_str(reference)];
    args.extend(TINY_BENCH);
    args.extend(["--json", json_path.to_str().unwrap()]);
    let o = gridrt(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let bench: serde_json::Value = serde_json::from_slice(&std::fs::read(&json_path).unwrap()).unwrap();
    let against = &bench[0]["reference"];
    assert_eq!(against["triangles"].as_u64(), Some(8192), "{bench}");
    assert!(against["bytes"].as_u64().unwrap() > 10 * bench[0]["grid"]["bytes"].as_u64().unwrap());
    // What the GPU gets, as bake reported it, is what bench built from the file.
    assert_eq!(bench[0]["grid"]["bytes"], report["grid_bytes"], "{bench} vs {report}");
    assert!(
        (against["distance"]["rms"].as_f64().unwrap() - rms).abs() < 0.05 * rms,
        "{bench}"
    );
    assert!(String::from_utf8_lossy(&o.stdout).contains("Against the mesh it was baked from, ball.obj"));
}

/// `--nv-blocks` writes the values in NVIDIA's compressed blocks, 128 bytes a level-4
/// triangle, and what the blocks decode to is what `bake` measured and `compare` reads back.
#[test]
fn a_bake_in_nvidia_blocks_reads_back_as_measured() {
    let dir = scratch("bake-nv-blocks");
    let reference = dir.join("ball.obj");
    write_obj(&reference, &bumpy_ball(5), 0.0);
    let out = dir.join("ball.gltf");
    let (r, o) = (o_str(&reference), o_str(&out));
    let report = json(&[
        "bake",
        r,
        "-L",
        "4",
        "-o",
        o,
        "--samples",
        "20000",
        "--nv-blocks",
        "--json",
    ]);
    let base = report["base_triangles"].as_u64().unwrap();
    assert_eq!(
        report["nv_blocks"]["value_bytes"].as_u64(),
        Some(128 * base),
        "{report}"
    );
    assert!(report["compression"].is_null(), "{report}");
    let (rms, before) = (
        report["symmetric"]["rms"].as_f64().unwrap(),
        report["nv_blocks"]["before_symmetric"]["rms"].as_f64().unwrap(),
    );
    assert!(rms <= 1.25 * before, "{report}");
    let map = gridrt::micromesh::bary::read(&std::fs::read(&side_files(&out)[1]).unwrap()).unwrap();
    assert!(map.nv_blocks && map.triangles.iter().all(|t| t.level == 4));
    reads_back_as_measured(&reference, &out, &report);
    fails_with(
        &["bake", r, "--nv-blocks", "--compress-values", "1e-4"],
        &[],
        &["cannot be used with"],
    );
}

/// Outputs are checked before any work: not an input, a glTF name; a base and a budget
/// together are refused.
#[test]
fn bake_refuses_bad_outputs_before_any_work() {
    let dir = scratch("bake-refusals");
    let reference = dir.join("ball.obj");
    write_obj(&reference, &bumpy_ball(2), 0.0);
    let r = reference.to_str().unwrap();
    fails_with(
        &["bake", r, "-o", dir.join("out.ply").to_str().unwrap()],
        &[],
        &["out.ply", "*.gltf"],
    );
    // A baked file as the reference of the next bake, written over itself.
    let first = dir.join("first.gltf");
    let o = gridrt(&["bake", r, "-L", "1", "-o", first.to_str().unwrap(), "--samples", "100"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let f = first.to_str().unwrap();
    fails_with(&["bake", f, "-o", f], &[], &["first.gltf", "is the input"]);
    let o = gridrt(&["bake", r, "--base", r, "--base-triangles", "4"]);
    assert!(
        !o.status.success() && stderr(&o).contains("cannot be used with"),
        "{}",
        stderr(&o)
    );
}

/// A byte budget tighter than the error bound needs is kept, the bound given up and the
/// report saying so, and one out of reach is said to be; a level per base triangle writes a
/// file of mixed levels that `render` reads, its values plain when asked, compressed within a
/// bound given or by default, and its displaced grids' bytes reported; levels per base
/// triangle for a budget of bytes keep within it.
#[test]
fn bake_keeps_to_a_byte_budget_and_mixes_levels() {
    let dir = scratch("bake-budget");
    let reference = dir.join("ball.obj");
    write_obj(&reference, &bumpy_ball(4), 0.0);
    let r = o_str(&reference);
    let args = |out: &Path, extra: &[&str]| {
        let out = o_str(out).to_string();
        let mut args: Vec<String> = ["bake", r, "-L", "3", "-o", &out, "--samples", "5000"]
            .map(String::from)
            .to_vec();
        args.extend(extra.iter().map(|a| a.to_string()));
        args
    };
    let bake = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let args = args(&out, &[extra, &["--json"]].concat());
        (json(&args.iter().map(String::as_str).collect::<Vec<_>>()), out)
    };
    let (free, _) = bake("free.gltf", &["--max-bytes", "100"]);
    let free_bytes = free["grid_bytes"].as_u64().unwrap() as f64;
    check_value_budgets(&bake, &free);
    check_mixed_levels(&bake, &dir);
    // Levels per triangle for a budget of everything the GPU gets: within it and near it,
    // of mixed levels; one out of reach is said to be.
    let budget = (0.9 * free_bytes) as u64;
    let (within, _) = bake("within.gltf", &["--within-bytes", &budget.to_string()]);
    let bytes = within["grid_bytes"].as_u64().unwrap();
    assert!(bytes <= budget && 10 * bytes >= 8 * budget, "{budget}: {within}");
    let levels = within["level_micro_triangles"].as_array().unwrap();
    assert!(levels.iter().filter(|c| c.as_u64() > Some(0)).count() >= 2, "{within}");
    assert_eq!(within["compression"]["budget_met"], true, "{within}");
    let args = args(&dir.join("unreachable.gltf"), &["--within-bytes", "100"]);
    let o = gridrt(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("over the budget of 100 B (--within-bytes)"), "{text}");
}

/// A bake of the test's ball with more arguments, as JSON, and the glTF it wrote.
type Bake<'a> = &'a dyn Fn(&str, &[&str]) -> (serde_json::Value, PathBuf);

/// `--max-bytes`: a budget below the `free` bake's bytes binds and is met; one the rest of
/// the bytes alone exceed is out of reach; the level's default is met or not worth the error.
fn check_value_budgets(bake: Bake, free: &serde_json::Value) {
    let micro = free["micro_triangles"].as_u64().unwrap() as f64;
    let free_bytes = free["grid_bytes"].as_u64().unwrap() as f64;
    assert_eq!(free["compression"]["budget_binds"], false, "{free}");
    let budget = format!("{:.4}", 0.95 * free_bytes / micro);
    let (tight, _) = bake("tight.gltf", &["--max-bytes", &budget]);
    let bytes = tight["grid_bytes"].as_u64().unwrap() as f64;
    assert!(bytes <= budget.parse::<f64>().unwrap() * micro, "{tight}");
    let c = &tight["compression"];
    assert_eq!(
        (&c["budget_binds"], &c["budget_met"]),
        (&true.into(), &true.into()),
        "{tight}"
    );
    assert!(c["added_error"].as_f64() > c["max_added_error"].as_f64(), "{tight}");
    // One that the rest of the bytes alone exceed is said to be out of reach, and the values
    // take their fewest bits.
    let (out_of_reach, _) = bake("unreachable.gltf", &["--max-bytes", "0.05"]);
    let c = &out_of_reach["compression"];
    assert_eq!(
        (&c["budget_met"], &c["budget_default"]),
        (&false.into(), &false.into()),
        "{out_of_reach}"
    );
    assert!(
        c["added_error"].as_f64() > c["max_added_error"].as_f64(),
        "{out_of_reach}"
    );
    // The level's default budget is met, or, out of reach, not worth the error: the values
    // keep their bound.
    let (default, _) = bake("default.gltf", &[]);
    let c = &default["compression"];
    assert_eq!(c["budget_default"], true, "{default}");
    match c["budget_met"].as_bool().unwrap() {
        true => assert!(default["grid_bytes"].as_f64().unwrap() <= micro, "{default}"),
        false => assert!(c["added_error"].as_f64() <= c["max_added_error"].as_f64(), "{default}"),
    }
}

/// `--max-error`: levels per triangle, with the values plain, compressed as asked and
/// compressed by default; rendered watertight.
fn check_mixed_levels(bake: Bake, dir: &Path) {
    let (mixed, out) = bake("mixed.gltf", &["--max-error", "2e-3", "--plain-values"]);
    let levels: Vec<u64> = (mixed["level_micro_triangles"].as_array().unwrap().iter())
        .map(|c| c.as_u64().unwrap())
        .collect();
    assert!(levels.iter().filter(|&&c| c > 0).count() >= 2, "{mixed}");
    assert_eq!(levels.iter().sum::<u64>(), mixed["micro_triangles"].as_u64().unwrap());
    assert!(
        mixed["grid_bytes"].as_u64().unwrap() > 0 && mixed["compression"].is_null(),
        "{mixed}"
    );
    let o = render_small(&out, &dir.join("mixed.png"));
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    // Rendered, each triangle counts at its own level, as the bake counts it, and its seams
    // are closed.
    let micro_triangles = mixed["micro_triangles"].as_u64().unwrap();
    assert!(
        err.contains(&format!("{micro_triangles} micro-triangles at depth")),
        "{err}"
    );
    assert!(!err.contains("cracks"), "{err}");
    let json_text = std::fs::read_to_string(&out).unwrap();
    assert!(json_text.contains("primitiveFlags"), "{json_text}");
    let (compressed, out) = bake(
        "mixed_compressed.gltf",
        &["--max-error", "2e-3", "--compress-values", "1e-4"],
    );
    assert_eq!(compressed["level_micro_triangles"], mixed["level_micro_triangles"]);
    // The values are compressed where that takes fewer bytes, and stay plain, exact, where
    // it does not (a tight bound on coarse levels).
    let c = &compressed["compression"];
    let (bytes, plain_bytes) = (compressed["grid_bytes"].as_u64(), mixed["grid_bytes"].as_u64());
    match c["kept_plain"].as_bool() {
        Some(true) => assert!(
            bytes == plain_bytes && compressed["symmetric"] == mixed["symmetric"],
            "{compressed}"
        ),
        Some(false) => assert!(bytes < plain_bytes, "{compressed}"),
        None => panic!("{compressed}"),
    }
    let o = render_small(&out, &dir.join("mixed_compressed.png"));
    assert!(o.status.success(), "{}", stderr(&o));
    // By default the values are compressed too, and the levels leave the compression room:
    // chosen for a tighter bound, they take more micro-triangles.
    let (default, _) = bake("mixed_default.gltf", &["--max-error", "2e-3"]);
    let c = &default["compression"];
    assert!(!c.is_null() && c["max_bytes"].is_null(), "{default}");
    assert!(
        default["micro_triangles"].as_u64() > mixed["micro_triangles"].as_u64(),
        "{default}\n{mixed}"
    );
}
