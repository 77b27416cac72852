//! Hostile and everyday files and arguments, as a new user meets them: every case ends in a
//! correct picture or one error line naming the file and the real problem, before any long
//! work, and no input is ever overwritten.

use std::path::Path;

use gridrt_tests::{fails_with, gridrt, scratch, stderr};

const SQUARE: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n";

fn write(path: &Path, text: impl AsRef<[u8]>) -> &str {
    std::fs::write(path, text).unwrap();
    path.to_str().unwrap()
}

/// `render` of the built-in scene, small, on the CPU, plus `extra`.
fn render_args<'a>(extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec![
        "render",
        "--backend",
        "cpu",
        "--levels",
        "1",
        "--width",
        "32",
        "--height",
        "24",
    ];
    args.extend_from_slice(extra);
    args
}

#[test]
fn an_output_that_is_the_input_is_refused() {
    let dir = scratch("output_is_input");
    let mesh = dir.join("mesh.obj");
    write(&mesh, SQUARE);
    let ply = dir.join("mesh.ply");
    let o = gridrt(&[
        "export",
        mesh.to_str().unwrap(),
        "--levels",
        "0",
        "-o",
        ply.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let before = std::fs::read(&ply).unwrap();
    let p = ply.to_str().unwrap();
    fails_with(&["export", p, "-o", p], &[], &["mesh.ply", "is the input", "destroy"]);
    #[cfg(unix)]
    {
        let link = dir.join("link.ply");
        std::os::unix::fs::symlink(&ply, &link).unwrap();
        fails_with(
            &["export", p, "-o", link.to_str().unwrap()],
            &[],
            &["link.ply", "is the input"],
        );
        let hard = dir.join("hard.ply");
        std::fs::hard_link(&ply, &hard).unwrap();
        fails_with(&["export", hard.to_str().unwrap(), "-o", p], &[], &["is the input"]);
    }
    assert_eq!(std::fs::read(&ply).unwrap(), before, "the input changed");
}

#[test]
fn every_output_is_checked_before_any_work() {
    let dir = scratch("outputs");
    let d = dir.to_str().unwrap();
    let slash = format!("{d}/new.png/");
    fails_with(&render_args(&["-o", &slash]), &[], &["new.png/", "names a folder"]);
    fails_with(
        &["export", "-o", &format!("{d}/e.ply/")],
        &[],
        &["e.ply/", "names a folder"],
    );
    let obj = dir.join("x.obj");
    let x = write(&obj, SQUARE);
    fails_with(
        &["bench", x, "--json", &format!("{d}/x.json/")],
        &[],
        &["names a folder"],
    );
    #[cfg(unix)]
    {
        fails_with(&["bench", x, "--json", "/dev/full"], &[], &["/dev/full"]);
        let fifo = dir.join("fifo.png");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if made.is_ok_and(|s| s.success()) {
            fails_with(
                &render_args(&["-o", fifo.to_str().unwrap()]),
                &[],
                &["fifo.png", "not a plain file"],
            );
        }
    }
    fails_with(
        &["bench", x, "--json", &format!("{d}/a.x")],
        &[],
        &["a.x", "unsupported format ('.x')", "*.json"],
    );
    fails_with(&["bench", x, "--markdown", &format!("{d}/a.txt")], &[], &["*.md"]);
    fails_with(
        &[
            "bench",
            x,
            "--json",
            &format!("{d}/a.md"),
            "--markdown",
            &format!("{d}/a.md"),
        ],
        &[],
        &["*.json"],
    );
    #[cfg(unix)]
    {
        // Two names, one file: the second write would replace the first.
        let json = dir.join("same.json");
        write(&json, "[]");
        let markdown = dir.join("same.md");
        std::os::unix::fs::symlink(&json, &markdown).unwrap();
        fails_with(
            &[
                "bench",
                x,
                "--json",
                json.to_str().unwrap(),
                "--markdown",
                markdown.to_str().unwrap(),
            ],
            &[],
            &["are one file"],
        );
    }
    // Every frame of a turntable, not just the first.
    std::fs::create_dir_all(dir.join("spin_001.png")).unwrap();
    let spin = format!("{d}/spin.png");
    fails_with(
        &render_args(&["--turntable", "3", "-o", &spin]),
        &[],
        &["spin_001.png", "is a folder"],
    );
    assert!(
        !dir.join("spin_000.png").exists(),
        "a refused turntable wrote its first frame"
    );
}

#[test]
fn a_killed_runs_temporary_file_is_removed() {
    let dir = scratch("stale");
    let out = dir.join("out.png");
    // A process id past any system's limit: no such process is running.
    let stale = dir.join("out.png.gridrt-2147483646.tmp");
    write(&stale, "half a picture");
    let o = gridrt(&render_args(&["-o", out.to_str().unwrap()]));
    assert!(o.status.success(), "{}", stderr(&o));
    if Path::new("/proc/self").exists() {
        assert!(!stale.exists(), "the stale temporary file is still there");
    }
}

#[test]
fn arguments_out_of_range_are_named() {
    let e = fails_with(&["render", "--levels", "-1"], &[], &["-1", "--levels"]);
    assert!(!e.contains("-- -1"), "{e}");
    fails_with(
        &render_args(&["--fov", "0.000001"]),
        &[],
        &["0.000001", "too narrow", "at least"],
    );
    fails_with(&render_args(&["--fov", "0.0001"]), &[], &["too narrow"]);
    fails_with(
        &render_args(&["--distance", "1e30"]),
        &[],
        &["times the scene's size from the target"],
    );
    let narrowest = format!("{}", gridrt::camera::narrowest_fov_degrees(24) * 1.01);
    let dir = scratch("fov");
    let o = gridrt(&render_args(&[
        "--fov",
        &narrowest,
        "-o",
        dir.join("n.png").to_str().unwrap(),
    ]));
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn meshes_with_no_size_or_no_area_are_named() {
    let dir = scratch("no_size");
    let point = dir.join("point.obj");
    let p = write(&point, "v 2 3 4\nv 2 3 4\nv 2 3 4\nf 1 2 3\n");
    fails_with(
        &render_args(&[p]),
        &[],
        &["point.obj", "the mesh has no size", "(2, 3, 4)"],
    );
    let line = dir.join("line.obj");
    let l = write(&line, "v 0 0 0\nv 1 1 1\nv 2 2 2\nv 3 3 3\nf 1 2 3\nf 2 3 4\n");
    let out = dir.join("line.png");
    let o = gridrt(&render_args(&[l, "-o", out.to_str().unwrap()]));
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("warning: ") && err.contains("line.obj: every triangle has zero area"),
        "{err}"
    );
}

#[test]
fn unknown_obj_statements_are_errors_naming_their_line() {
    let dir = scratch("obj_statements");
    for (name, line) in [
        ("ff.obj", "ff 1 2 4"),
        ("upper.obj", "F 1 4 3"),
        ("foo.obj", "foo bar"),
        ("nul.obj", "\0"),
    ] {
        let path = dir.join(name);
        let p = write(&path, format!("{SQUARE}{line}\n"));
        let word = line.split(' ').next().unwrap();
        fails_with(
            &render_args(&[p]),
            &[],
            &[name, "line 7", "unknown statement", &format!("{word:?}")],
        );
    }
    let surface = dir.join("surf.obj");
    let s = write(&surface, format!("{SQUARE}cstype bspline\nsurf 0 1 0 1 1 2 3 4\n"));
    fails_with(&render_args(&[s]), &[], &["line 7", "\"cstype\"", "not supported"]);
    // Statements that shape nothing are fine.
    let fine = dir.join("fine.obj");
    let f = write(
        &fine,
        format!("mtllib a.mtl\no a\ng b\ns 1\nusemtl m\nvt 0 0\nvn 0 0 1\n{SQUARE}l 1 2\np 1\n"),
    );
    let o = gridrt(&render_args(&[f, "-o", dir.join("fine.png").to_str().unwrap()]));
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn damaged_plys_name_the_real_problem() {
    let dir = scratch("ply");
    let header = |format: &str, vertices: usize| {
        format!(
            "ply\nformat {format} 1.0\nelement vertex {vertices}\nproperty float x\nproperty float y\n\
             property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n"
        )
    };
    let body = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n";
    let binary = dir.join("binary.ply");
    let b = write(&binary, header("binary_little_endian", 4) + body);
    fails_with(
        &render_args(&[b]),
        &[],
        &["binary.ply", "says binary_little_endian but the body is ASCII text"],
    );
    let over = dir.join("over.ply");
    let o = write(&over, header("ascii", 5) + body);
    fails_with(
        &render_args(&[o]),
        &[],
        &[
            "over.ply",
            "declares 5 vertices and 2 faces (7 lines), the body has 6 lines",
        ],
    );
}

/// The glTF fuzz target's seeds (`fuzz/corpus/gltf`): hostile files made from the
/// specification, and each what the command line must say of it.
const GLTF_SEEDS: &[(&str, Option<&str>)] = &[
    ("bad_magic.glb", Some("not a GLB file: it starts with \"glTX\"")),
    (
        "chunk_too_long.glb",
        Some("truncated GLB: chunk 0 declares 65535 bytes"),
    ),
    (
        "cycle.glb",
        Some("node 0 is its own ancestor: the node hierarchy has a cycle"),
    ),
    ("own_child.glb", Some("node 0 is its own ancestor")),
    ("two_parents.glb", Some("node 2 is a child of both node 0 and node 1")),
    (
        "index_float.glb",
        Some("index accessor 2 is SCALAR FLOAT: glTF indices are SCALAR"),
    ),
    ("index_short.glb", Some("index accessor 2 is SCALAR SHORT")),
    ("index_vec3.glb", Some("index accessor 2 is VEC3 UNSIGNED_SHORT")),
    (
        "position_vec2.glb",
        Some("POSITION accessor 0 is VEC2 FLOAT: glTF positions are VEC3 FLOAT"),
    ),
    ("position_ubyte.glb", Some("POSITION accessor 0 is VEC3 UNSIGNED_BYTE")),
    (
        "position_normalized_short.glb",
        Some("POSITION accessor 0 is VEC3 NORMALIZED SHORT"),
    ),
    (
        "position_too_short.glb",
        Some("its 4 elements reach byte 48 of buffer view 0, which has 36 bytes"),
    ),
    ("scale_zero.glb", Some("the mesh has no size")),
    (
        "translation_1e39.glb",
        Some("node 0: its translation holds 1e39, beyond the 32-bit float range"),
    ),
    (
        "truncated.glb",
        Some("truncated GLB: its header declares 920 bytes, the file has 910"),
    ),
    (
        "uri_absolute.gltf",
        Some("buffer 0: its uri \"/etc/passwd\" is an absolute path"),
    ),
    ("uri_escaped_parent.gltf", Some("steps out of its folder")),
    ("uri_file_url.gltf", Some("is a URL")),
    (
        "uri_parent.gltf",
        Some("buffer 0: its uri \"../../../../etc/passwd\" steps out of its folder"),
    ),
    (
        "position_accessor_missing.glb",
        Some("its POSITION accessor 0 does not exist (the file has 0)"),
    ),
    ("deep_1000.glb", None),
    ("displaced_dome.glb", None),
    ("displaced_decimated_edges.glb", None),
    ("displaced_half_float_directions.glb", None),
    ("displaced_bary_mesh_properties.glb", None),
    ("embedded.gltf", None),
    ("matrix_far.glb", None),
    ("scene.glb", None),
    ("sparse.glb", None),
    ("unindexed_strip.glb", None),
];

#[test]
fn gltf_seeds_render_or_name_their_problem() {
    let seeds = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../fuzz/corpus/gltf"));
    let on_disk = std::fs::read_dir(seeds).unwrap().count();
    assert_eq!(
        on_disk,
        GLTF_SEEDS.len(),
        "a seed without a test, or a test without a seed"
    );
    let dir = scratch("gltf_seeds");
    let out = dir.join("seed.png");
    for (name, problem) in GLTF_SEEDS {
        let path = seeds.join(name);
        let args = render_args(&[path.to_str().unwrap(), "-o", out.to_str().unwrap()]);
        match problem {
            Some(problem) => {
                fails_with(&args, &[], &[&format!("error: {}: ", path.display()), problem]);
            }
            None => {
                let o = gridrt(&args);
                assert!(o.status.success(), "{name}: {}", stderr(&o));
            }
        }
    }
}

#[test]
fn gltf_seams_are_welded_and_said() {
    let seeds = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../fuzz/corpus/gltf"));
    let strip = seeds.join("unindexed_strip.glb");
    let dir = scratch("welded");
    let out = dir.join("strip.png");
    let o = gridrt(&render_args(&[strip.to_str().unwrap(), "-o", out.to_str().unwrap()]));
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("unindexed_strip.glb: welded 4 vertices"), "{err}");
}
