//! Triangle meshes as loaded from disk (OBJ, PLY, glTF) or generated in code.

use std::path::Path;

use crate::error::{error, fail, Result};
use gridrt_shared::glam::Vec3;

pub mod frame;
pub mod gltf;
pub mod obj;
pub mod ply;
pub mod scene;

/// A triangle mesh as loaded: positions and counter-clockwise triangles.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
}

impl Mesh {
    /// Min/max over all positions; `(Vec3::INFINITY, Vec3::NEG_INFINITY)` for an empty mesh so that
    /// merging bounds needs no special case.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.positions
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
                (lo.min(p), hi.max(p))
            })
    }

    /// Checks and cleans a freshly loaded mesh: error if any position is not finite (name the first offending
    /// vertex index), if any index is out of range (name triangle and index), or if no triangle is left.
    /// Dropped, and their count returned: triangles that repeat a vertex index, and triangles with the same three
    /// vertices as an earlier one (in any order: a double-sided export's back faces). Such a duplicate adds nothing
    /// to the surface, and would share its inner subdivision vertices with the first (Loop subdivision names new
    /// vertices by the edges they split), where the grids need each inner vertex to belong to one grid.
    /// Vertices no triangle uses are removed (the others keep their order): a stray point of a
    /// scan would otherwise count in the bounds that frame the picture.
    /// `source` is the file name used in messages.
    pub fn validate(mut self, source: &str) -> Result<(Mesh, usize)> {
        if let Some(i) = self.positions.iter().position(|p| !p.is_finite()) {
            let p = self.positions[i];
            fail!(
                Input,
                "{source}: vertex {i} has a non-finite coordinate ({}, {}, {})",
                p.x,
                p.y,
                p.z
            );
        }
        let n = self.positions.len();
        for (t, tri) in self.triangles.iter().enumerate() {
            if let Some(&i) = tri.iter().find(|&&i| i as usize >= n) {
                fail!(
                    Input,
                    "{source}: triangle {t} refers to vertex {i} but the mesh has {n} vertices"
                );
            }
        }
        let before = self.triangles.len();
        let mut seen = std::collections::HashSet::with_capacity(before);
        self.triangles.retain(|&[a, b, c]| {
            let mut key = [a, b, c];
            key.sort_unstable();
            a != b && b != c && c != a && seen.insert(key)
        });
        let dropped = before - self.triangles.len();
        if self.triangles.is_empty() {
            if dropped > 0 {
                fail!(
                    Input,
                    "{source}: no triangles left after dropping {dropped} degenerate triangles ({DEGENERATE})"
                );
            }
            fail!(Input, "{source}: no triangles");
        }
        self.remove_unused_vertices();
        Ok((self, dropped))
    }

    /// Drops the vertices no triangle refers to, renumbering the rest in their order.
    fn remove_unused_vertices(&mut self) {
        let mut new_id = vec![u32::MAX; self.positions.len()];
        for &i in self.triangles.iter().flatten() {
            new_id[i as usize] = 0;
        }
        let mut kept = 0u32;
        for (id, p) in new_id.iter_mut().zip(0..) {
            if *id == 0 {
                *id = kept;
                self.positions[kept as usize] = self.positions[p];
                kept += 1;
            }
        }
        self.positions.truncate(kept as usize);
        for i in self.triangles.iter_mut().flatten() {
            *i = new_id[*i as usize];
        }
    }
}

/// What a dropped triangle is, for messages.
pub const DEGENERATE: &str = "a repeated vertex, or the same three vertices as an earlier triangle";

/// Loads .obj, .ply, .gltf or .glb (case-insensitive extension) and validates it. Every error is one line that starts with the
/// file path. Degenerate triangles are dropped silently: [`load_mesh_quiet`] and [`open`] say how many.
pub fn load_mesh(path: &Path) -> Result<Mesh> {
    Ok(load_mesh_quiet(path)?.0)
}

/// A mesh ready for the pipeline, and where it came from.
pub struct Input {
    /// The file's name as given, or `default scene`.
    pub name: String,
    /// The mesh in its local frame (see [`frame`]).
    pub mesh: Mesh,
    /// Maps the mesh back to the file's units.
    pub frame: frame::LocalFrame,
    /// Degenerate triangles dropped while loading (a repeated vertex, or the same three
    /// vertices as an earlier triangle).
    pub dropped: usize,
}

/// Loads `path` (`.obj`, `.ply`, `.gltf` or `.glb`), or the built-in scene when `None`, and moves it into its
/// local frame, where everything after loading works. Errors are one line naming the file.
pub fn open(path: Option<&Path>) -> Result<Input> {
    open_all(path.as_slice())
}

/// Several files as one mesh (each loaded and checked on its own, then put side by side in
/// the files' common units), or the built-in scene when `paths` is empty; in its local frame.
pub fn open_all(paths: &[&Path]) -> Result<Input> {
    let mut all = match paths.first() {
        Some(first) => open_world(first)?,
        None => Input {
            name: "default scene".to_string(),
            mesh: scene::default_scene(),
            frame: frame::LocalFrame::IDENTITY,
            dropped: 0,
        },
    };
    let rest = paths.get(1..).unwrap_or_default();
    for path in rest {
        let next = open_world(path)?;
        let base = all.mesh.positions.len() as u32;
        all.mesh.positions.extend(next.mesh.positions);
        all.mesh
            .triangles
            .extend(next.mesh.triangles.iter().map(|t| t.map(|i| base + i)));
        all.name = format!("{} + {}", all.name, next.name);
        all.dropped += next.dropped;
    }
    all.frame = all.mesh.into_local_frame();
    Ok(all)
}

/// A file loaded and checked, still in its own units.
fn open_world(path: &Path) -> Result<Input> {
    let (mesh, dropped) = load_mesh_quiet(path)?;
    Ok(Input {
        name: path.display().to_string(),
        mesh,
        frame: frame::LocalFrame::IDENTITY,
        dropped,
    })
}

/// [`load_mesh`] without the warning: returns the number of dropped degenerate triangles instead.
pub fn load_mesh_quiet(path: &Path) -> Result<(Mesh, usize)> {
    let name = path.display().to_string();
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    let folder = path.parent();
    let parse = |bytes: &[u8]| match ext.as_deref() {
        Some("obj") => obj::parse_obj(bytes),
        Some("ply") => ply::parse_ply(bytes),
        _ => gltf::parse_gltf(bytes, folder),
    };
    if !matches!(ext.as_deref(), Some("obj" | "ply" | "gltf" | "glb")) {
        fail!(Input, "{name}: unsupported format (expected .obj, .ply, .gltf or .glb)");
    }
    let bytes = std::fs::read(path).map_err(|e| error!(Input, "{name}: cannot open: {}", io_reason(&e)))?;
    if bytes.is_empty() {
        fail!(Input, "{name}: no triangles (empty file)");
    }
    let mesh = parse(&bytes).map_err(|e| error!(Input, "{name}: {}", one_line(&e.to_string())))?;
    mesh.validate(&name)
}

pub use crate::image_io::io_reason;

/// Guards the one-line promise against messages that quote file content.
fn one_line(s: &str) -> String {
    s.replace(['\n', '\r'], " ")
}

/// An optionally signed run of decimal digits: a number, however far out of range.
pub(crate) fn is_integer(word: &str) -> bool {
    let digits = word.strip_prefix(['-', '+']).unwrap_or(word);
    !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit())
}

/// Shortens and escapes a token from the file for an error message.
pub(crate) fn quote(token: &str) -> String {
    const MAX: usize = 32;
    match token.char_indices().nth(MAX) {
        Some((i, _)) => format!("{:?}...", &token[..i]),
        None => format!("{token:?}"),
    }
}

/// Shared helpers for the loader tests: unique scratch files and error checks.
#[cfg(test)]
pub(crate) mod test_util {
    use std::path::PathBuf;
    use std::sync::atomic::{AtomicUsize, Ordering};

    use super::*;

    /// Writes `bytes` to a fresh file named `name` in a per-process, per-call temp folder.
    pub fn write_temp(name: &str, bytes: &[u8]) -> PathBuf {
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("gridrt-mesh-test-{}-{n}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        path
    }

    /// Loads `bytes` as file `name` and asserts a one-line error naming the path and containing every `needles`.
    pub fn expect_err(name: &str, bytes: &[u8], needles: &[&str]) -> String {
        let path = write_temp(name, bytes);
        let result = std::panic::catch_unwind(|| load_mesh_quiet(&path));
        let msg = match result {
            Ok(Ok((m, _))) => panic!("{name}: expected an error, loaded {} triangles", m.triangles.len()),
            Ok(Err(e)) => format!("{e:#}"),
            Err(_) => panic!("{name}: loader panicked"),
        };
        let shown = path.display().to_string();
        assert!(
            msg.starts_with(&format!("{shown}: ")),
            "message does not start with the path: {msg}"
        );
        assert!(!msg.contains('\n'), "message is not one line: {msg}");
        for needle in needles {
            assert!(msg.contains(needle), "message lacks {needle:?}: {msg}");
        }
        msg
    }

    /// Overwrites `flips` bytes of `bytes` at pseudo-random places with pseudo-random values,
    /// then loads the result as file `name`: any error is fine, a panic is not.
    pub fn load_scrambled(name: &str, mut bytes: Vec<u8>, seed: &mut u64, flips: usize) {
        for _ in 0..flips {
            *seed ^= *seed << 13;
            *seed ^= *seed >> 7;
            *seed ^= *seed << 17;
            let at = (*seed % bytes.len() as u64) as usize;
            bytes[at] = (*seed >> 40) as u8;
        }
        let path = write_temp(name, &bytes);
        let _ = std::panic::catch_unwind(|| load_mesh_quiet(&path)).expect("loader panicked");
    }

    /// Loads `bytes` as file `name`, expecting success.
    pub fn load_ok(name: &str, bytes: &[u8]) -> (Mesh, usize) {
        let path = write_temp(name, bytes);
        load_mesh_quiet(&path).unwrap_or_else(|e| panic!("{e:#}"))
    }
}

#[cfg(test)]
mod tests {
    use super::test_util::*;
    use super::*;

    /// Several files open as one mesh in their common units, then in one local frame; a bad
    /// one is named.
    #[test]
    fn several_files_open_as_one_mesh() {
        let a = write_temp("a.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        let b = write_temp("b.obj", b"v 4 0 0\nv 5 0 0\nv 4 1 0\nv 9 9 9\nf 1 2 3\nf 1 1 2\n");
        let all = open_all(&[&a, &b]).unwrap();
        assert_eq!(all.name, format!("{} + {}", a.display(), b.display()));
        assert_eq!(all.dropped, 1);
        assert_eq!(all.mesh.triangles, vec![[0, 1, 2], [3, 4, 5]]);
        let world: Vec<_> = all
            .mesh
            .positions
            .iter()
            .map(|&p| all.frame.to_world(p).as_vec3())
            .collect();
        assert_eq!(world[3], Vec3::new(4.0, 0.0, 0.0));
        assert_eq!(open_all(&[]).unwrap().name, "default scene");
        let missing = a.with_file_name("missing.ply");
        let e = open_all(&[&a, &missing]).err().unwrap().to_string();
        assert!(e.starts_with(&missing.display().to_string()), "{e}");
    }

    #[test]
    fn validate_drops_degenerates_and_rejects_bad_meshes() {
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
        let mesh = Mesh {
            positions: p.clone(),
            triangles: vec![[0, 1, 2], [0, 0, 1], [2, 1, 2], [2, 1, 0], [1, 2, 0], [0, 1, 2]],
        };
        let (clean, dropped) = mesh.validate("m").unwrap();
        assert_eq!((clean.triangles, dropped), (vec![[0, 1, 2]], 5));

        // Unused vertices go, the others keep their order.
        let far = Vec3::splat(1e30);
        let sparse = Mesh {
            positions: vec![far, Vec3::X, far, Vec3::Y, Vec3::Z, far],
            triangles: vec![[4, 1, 3], [3, 1, 4]],
        };
        let (clean, dropped) = sparse.validate("m").unwrap();
        assert_eq!(clean.positions, vec![Vec3::X, Vec3::Y, Vec3::Z]);
        assert_eq!((clean.triangles, dropped), (vec![[2, 0, 1]], 1));

        let oob = Mesh {
            positions: p.clone(),
            triangles: vec![[0, 1, 2], [0, 1, 7]],
        };
        let e = oob.validate("m").unwrap_err().to_string();
        assert!(e.contains("m: triangle 1 refers to vertex 7"), "{e}");

        let mut nan = Mesh {
            positions: p.clone(),
            triangles: vec![[0, 1, 2]],
        };
        nan.positions[1].y = f32::NAN;
        let e = nan.validate("m").unwrap_err().to_string();
        assert!(e.contains("m: vertex 1 has a non-finite"), "{e}");

        let e = Mesh::default().validate("m").unwrap_err().to_string();
        assert_eq!(e, "m: no triangles");
        let e = Mesh {
            positions: p,
            triangles: vec![[1, 1, 1]],
        }
        .validate("m")
        .unwrap_err()
        .to_string();
        assert!(e.starts_with("m: no triangles left"), "{e}");
    }

    #[test]
    fn bounds_cover_all_positions() {
        let m = Mesh {
            positions: vec![Vec3::new(1.0, -2.0, 3.0), Vec3::new(-1.0, 5.0, 0.0)],
            triangles: vec![],
        };
        assert_eq!(m.bounds(), (Vec3::new(-1.0, -2.0, 0.0), Vec3::new(1.0, 5.0, 3.0)));
    }

    #[test]
    fn generic_errors() {
        expect_err("empty.obj", b"", &["no triangles"]);
        expect_err("empty.ply", b"", &["no triangles"]);
        expect_err(
            "x.stl",
            b"solid x\n",
            &["unsupported format (expected .obj, .ply, .gltf or .glb)"],
        );
        expect_err("noext", b"v 0 0 0\n", &["unsupported format"]);
        let missing = std::env::temp_dir().join("gridrt-definitely-missing-dir/missing.obj");
        let e = format!("{:#}", load_mesh(&missing).unwrap_err());
        assert_eq!(
            e,
            format!("{}: cannot open: No such file or directory", missing.display())
        );
    }

    #[test]
    fn extension_is_case_insensitive() {
        let (m, _) = load_ok("upper.OBJ", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        assert_eq!(m.triangles.len(), 1);
        let (m, _) = load_ok("upper.PlY", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
        assert_eq!(m.triangles.len(), 1);
    }

    /// The Stanford/npm meshes shipped next to the project; skipped when the folder is absent.
    #[test]
    fn real_meshes_load() {
        let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/meshes"));
        if !dir.is_dir() {
            println!("skipping real_meshes_load: {} is missing", dir.display());
            return;
        }
        for (file, tris, verts) in [
            ("bunny.obj", 3674, 1839),
            ("teapot.obj", 992, 792),
            // The dragons' files also hold 2 and 16 vertices no face uses.
            ("dragon_res4.ply", 11102, 5203),
            ("dragon_res3.ply", 47794, 22982),
        ] {
            let (m, dropped) = load_mesh_quiet(&dir.join(file)).unwrap_or_else(|e| panic!("{e:#}"));
            let (lo, hi) = m.bounds();
            println!(
                "{file}: {} triangles, {} vertices, {dropped} dropped, bounds {lo} .. {hi}",
                m.triangles.len(),
                m.positions.len()
            );
            assert_eq!(
                (m.triangles.len() + dropped, m.positions.len()),
                (tris, verts),
                "{file}"
            );
        }
    }
}
