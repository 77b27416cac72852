//! Helpers shared by the integration tests.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use gridrt::backend::gpu::Gpu;
use gridrt::bvh::Aabb;
use gridrt::error::ErrorKind;
use gridrt::grid;
use gridrt::mesh::Mesh;
use gridrt::micromesh::bake::{bake, BakeOptions, Base};
use gridrt::micromesh::DisplacedMesh;
use gridrt::pipeline::{BuildOptions, Representation};
use gridrt::scene::Scene;
use gridrt::subdiv::{subdivide, Scheme, Subdivided};
use gridrt_shared::glam::Vec3;

/// The GPU, or `None` with the reason printed when there is no adapter at all; any other GPU
/// failure fails the test. Under CI (`CI=true`) a missing adapter fails
/// the test instead: CI must exercise the GPU path.
pub fn gpu_or_skip(test: &str) -> Option<Gpu> {
    match Gpu::new() {
        Ok(gpu) => {
            eprintln!("{test}: GPU tests on {}", gpu.describe());
            Some(gpu)
        }
        Err(e) if e.kind() != ErrorKind::NoGpu => panic!("{test}: the GPU backend failed: {e:#}"),
        Err(e) if std::env::var("CI").is_ok_and(|v| v == "true") => {
            panic!("{test}: CI=true but no GPU adapter: {e:#}")
        }
        Err(e) => {
            eprintln!("{test}: SKIPPED: {e:#}");
            None
        }
    }
}

/// `../shared/meshes` beside the repository, if present.
pub fn meshes_dir() -> Option<PathBuf> {
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/meshes"));
    dir.is_dir().then_some(dir)
}

/// `../shared/meshes`, or `None` with the skip printed for `test` when it is not there.
pub fn meshes_dir_or_skip(test: &str) -> Option<PathBuf> {
    let dir = meshes_dir();
    if dir.is_none() {
        eprintln!("{test}: SKIPPED, ../shared/meshes not found");
    }
    dir
}

/// The `gridrt` binary, built first: `cargo test` builds the test programs of this crate but
/// not other packages' binaries, so without this the CLI tests would find no binary on a
/// fresh checkout, or a stale one after a change. The build runs once per test program,
/// through the same cargo, profile and target folder as the tests (a no-op when up to date),
/// and the binary is found beside the test executable's profile folder.
pub fn gridrt_exe() -> PathBuf {
    static BUILT: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    BUILT
        .get_or_init(|| {
            let manifest = concat!(env!("CARGO_MANIFEST_DIR"), "/../Cargo.toml");
            let mut build = std::process::Command::new(env!("CARGO"));
            build.args([
                "build",
                "--quiet",
                "--manifest-path",
                manifest,
                "-p",
                "gridrt",
                "--bin",
                "gridrt",
            ]);
            if !cfg!(debug_assertions) {
                build.arg("--release");
            }
            let status = build.status().expect("run cargo to build gridrt");
            assert!(status.success(), "cargo could not build the gridrt binary");
            let test_exe = std::env::current_exe().expect("test executable path");
            test_exe
                .ancestors()
                .map(|dir| dir.join("gridrt"))
                .find(|exe| exe.is_file())
                .unwrap_or_else(|| panic!("no gridrt binary above {}", test_exe.display()))
        })
        .clone()
}

/// Both representations of `mesh` subdivided `levels` times, rendered at depth `lod`.
pub struct Pair {
    pub sub: Subdivided,
    pub grids: Scene,
    pub triangles: Scene,
    pub bounds: Aabb,
}

pub fn build_pair(mesh: &Mesh, levels: u32, lod: u32, scheme: Scheme) -> Pair {
    build_pair_with(mesh, levels, lod, scheme, &grid::GridOptions::default())
}

/// Inner vertices quantized, as the CLI builds by default.
pub fn build_pair_with(mesh: &Mesh, levels: u32, lod: u32, scheme: Scheme, options: &grid::GridOptions) -> Pair {
    build_pair_from(mesh, levels, lod, scheme, options, true)
}

pub fn build_pair_from(
    mesh: &Mesh,
    levels: u32,
    lod: u32,
    scheme: Scheme,
    options: &grid::GridOptions,
    quantized: bool,
) -> Pair {
    // Both through the library's pipeline, as the CLI builds them: grids each subdivided on
    // their own, the baseline from the whole subdivided mesh.
    let mut options = BuildOptions {
        representation: Representation::Grids,
        grid: grid::GridBuild {
            levels,
            scheme,
            crease_angle: None,
            options: *options,
            quantized,
        },
        lod: Some(lod),
    };
    let grids = Scene::build(mesh, &options).expect("grid build");
    options.representation = Representation::Triangles;
    let triangles = Scene::build(mesh, &options).expect("baseline build");
    // The same micro-mesh, for brute force and bounds.
    let mut sub = subdivide(mesh, levels, scheme);
    if quantized {
        sub.quantize_inner();
    }
    let bounds = Aabb::from_points(sub.positions.iter().copied());
    Pair {
        sub,
        grids,
        triangles,
        bounds,
    }
}

/// A small deterministic generator (PCG32), so every run tests the same rays.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407))
    }

    pub fn next_u32(&mut self) -> u32 {
        let old = self.0;
        self.0 = old.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        xorshifted.rotate_right((old >> 59) as u32)
    }

    /// Uniform in `[0, 1)`.
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 / (1u32 << 24) as f32
    }

    /// Uniform on the unit sphere.
    pub fn direction(&mut self) -> Vec3 {
        let z = 2.0 * self.next_f32() - 1.0;
        let phi = std::f32::consts::TAU * self.next_f32();
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    /// Uniform in a box.
    pub fn point_in(&mut self, b: &Aabb) -> Vec3 {
        b.min + (b.max - b.min) * Vec3::new(self.next_f32(), self.next_f32(), self.next_f32())
    }
}

/// A scratch folder of a test's own, removed when dropped.
pub struct Scratch(tempfile::TempDir);

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        self.0.path()
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        self.0.path()
    }
}

/// A fresh scratch folder whose name starts `gridrt-{test}-`; it goes with the value.
pub fn scratch(test: &str) -> Scratch {
    let folder = tempfile::Builder::new().prefix(&format!("gridrt-{test}-")).tempdir();
    Scratch(folder.expect("make a scratch folder"))
}

/// Runs the `gridrt` binary with `args`.
/// `bench` flags for the smallest run that still measures: one 32x24 view, one repeat.
pub const TINY_BENCH: [&str; 8] = ["--width", "32", "--height", "24", "--views", "1", "--repeats", "1"];

pub fn gridrt(args: &[&str]) -> Output {
    Command::new(gridrt_exe()).args(args).output().expect("run gridrt")
}

/// `gridrt render INPUT` on the CPU backend at 64x48, written to `png`.
pub fn render_small(input: &std::path::Path, png: &std::path::Path) -> Output {
    let [input, png] = [input, png].map(|p| p.to_str().expect("a UTF-8 path"));
    gridrt(&[
        "render",
        input,
        "--backend",
        "cpu",
        "--width",
        "64",
        "--height",
        "48",
        "-o",
        png,
    ])
}

/// What a run printed on standard error.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Runs gridrt with extra environment variables; expects a failure with exactly one line
/// starting with `error`, containing every one of `needles`, no panic, and nothing built.
/// Returns stderr.
pub fn fails_with(args: &[&str], env: &[(&str, &str)], needles: &[&str]) -> String {
    let o = Command::new(gridrt_exe())
        .args(args)
        .envs(env.iter().copied())
        .output()
        .expect("run gridrt");
    let err = stderr(&o);
    assert!(!o.status.success(), "gridrt {args:?} succeeded: {err}");
    assert!(!err.contains("panicked"), "gridrt {args:?} panicked: {err}");
    let lines: Vec<&str> = err.lines().filter(|l| l.starts_with("error")).collect();
    assert_eq!(lines.len(), 1, "gridrt {args:?}: expected one error line, got {err}");
    for needle in needles {
        assert!(
            lines[0].contains(needle),
            "gridrt {args:?}: error lacks {needle:?}: {err}"
        );
    }
    // Refused before any work: nothing was built.
    assert!(
        !err.contains("B per micro-triangle"),
        "gridrt {args:?} built before failing: {err}"
    );
    err
}

/// The files a glTF names beside it (its buffers', then its micromaps' `uri`s), as paths in
/// its folder.
pub fn side_files(gltf: &std::path::Path) -> Vec<PathBuf> {
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(gltf).expect("read the glTF")).expect("JSON");
    (gridrt::mesh::gltf::uris_named(&json).iter())
        .map(|uri| gltf.with_file_name(uri))
        .collect()
}

/// A bumpy ball of `8 * 4^levels` triangles around the origin: a detailed closed surface to
/// bake.
pub fn bumpy_ball(levels: u32) -> Mesh {
    let octahedron = gridrt::mesh::scene::octahedron();
    let sub = subdivide(&octahedron, levels, Scheme::Flat);
    let bump = |p: Vec3| p * (1.0 + 0.05 * (5.0 * p.x).sin() * (4.0 * p.y).cos());
    let mesh = Mesh {
        positions: sub.positions.iter().map(|p| bump(p.normalize())).collect(),
        triangles: sub.micro_triangles(levels),
    };
    gridrt::mesh::WorldMesh::from(mesh).validate("ball").unwrap().0.to_f32()
}

/// A bumpy ball baked at `levels` on a base of 64 triangles.
pub fn baked_ball(levels: u32) -> DisplacedMesh {
    let reference = bumpy_ball(4);
    let options = BakeOptions {
        base: Base::Decimated { triangles: 64 },
        ..BakeOptions::for_reference(&reference, levels)
    };
    bake(&reference, &options).unwrap().mesh
}

/// The ball baked at `levels`, then each base triangle taken down to a level of its own: the
/// deepest at one triangle, one level less for each step away from it across edges, to level
/// 1 at least (so neighbours differ by one at most), its values those of its level's points,
/// and the finer side of each step decimating the edge. Levels 1 to `levels`, with decimated
/// edges at every step.
pub fn mixed_ball(levels: u32) -> DisplacedMesh {
    use gridrt_shared::displacement::u_major_index;
    let mut mesh = baked_ball(levels);
    let triangles = mesh.triangles.clone();
    // Steps from triangle 0 across shared edges, breadth first.
    let mut by_edge = std::collections::HashMap::<(u32, u32), Vec<usize>>::new();
    for (t, c) in triangles.iter().enumerate() {
        for e in 0..3 {
            let (a, b) = (c[e], c[(e + 1) % 3]);
            by_edge.entry((a.min(b), a.max(b))).or_default().push(t);
        }
    }
    let mut steps = vec![u32::MAX; triangles.len()];
    let mut queue = std::collections::VecDeque::from([0usize]);
    steps[0] = 0;
    while let Some(t) = queue.pop_front() {
        for e in 0..3 {
            let (a, b) = (triangles[t][e], triangles[t][(e + 1) % 3]);
            for &u in &by_edge[&(a.min(b), a.max(b))] {
                if steps[u] == u32::MAX {
                    steps[u] = steps[t] + 1;
                    queue.push_back(u);
                }
            }
        }
    }
    let own: Vec<u32> = steps.iter().map(|&d| levels.saturating_sub(d).max(1)).collect();
    let n = 1u32 << levels;
    let mut micromap = mesh.micromap.clone();
    micromap.values.clear();
    micromap.triangles.clear();
    for (t, &l) in own.iter().enumerate() {
        let (values, shift, m) = (mesh.micromap.triangle_values(t), levels - l, 1u32 << l);
        micromap.triangles.push(gridrt::micromesh::bary::MicromapTriangle {
            level: l,
            first_value: micromap.values.len() as u32,
        });
        for i in 0..=m {
            for j in 0..=m - i {
                micromap
                    .values
                    .push(values[u_major_index([i << shift, j << shift], n) as usize]);
            }
        }
    }
    micromap.value_code = None;
    mesh.micromap = micromap;
    mesh.decimated_edges = gridrt::micromesh::bake::levels::decimated_edges(&triangles, &own);
    assert!((1..=levels).all(|l| own.contains(&l)), "{own:?}");
    assert!(mesh.decimated_edges.iter().filter(|&&f| f != 0).count() >= 4);
    mesh.check().unwrap();
    mesh
}

/// `mesh` with its values compressed loosely enough that most levels lose bits (and clamped
/// corrections, shifts and zero widths all occur).
pub fn loosely_compressed(mesh: &DisplacedMesh) -> DisplacedMesh {
    let loose = gridrt::grid::compressed::ValueCompression::bounded(2e-3);
    gridrt::grid::compressed::compress(mesh, &loose).unwrap().mesh
}

/// `mesh` built as displaced grids in their default formats.
pub fn displaced_grids(mesh: &DisplacedMesh) -> Scene {
    Scene::build_displaced(mesh, &BuildOptions::for_displaced()).unwrap()
}
