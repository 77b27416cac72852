//! Triangle meshes as loaded from disk (OBJ, PLY, glTF) or generated in code.
//!
//! Loaders read coordinates in double precision into a [`WorldMesh`], in the file's own units;
//! [`WorldMesh::validate`] checks and cleans it (welds equal positions, drops degenerate
//! triangles), and [`WorldMesh::into_local`] moves it, still in double precision, into the
//! [`frame::LocalFrame`] where everything after loading works in `f32` as a [`Mesh`].

use std::collections::{HashMap, HashSet};
use std::path::Path;

use crate::error::{error, fail, Result};
use gridrt_shared::glam::{DVec3, Vec3};

pub mod frame;
pub mod gltf;
pub mod obj;
pub mod ply;
pub mod scene;

/// A triangle mesh ready to build: positions and counter-clockwise triangles.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
}

/// A triangle mesh as a file holds it: positions in the file's units, in double precision, so
/// that a mesh far from the origin keeps every digit its file has until it is moved into its
/// local frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WorldMesh {
    pub positions: Vec<DVec3>,
    pub triangles: Vec<[u32; 3]>,
}

/// What [`WorldMesh::validate`] changed or found.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Cleaning {
    /// Vertices merged into an earlier vertex at the same position (a mesh split at UV or
    /// normal seams, or drawn without an index list).
    pub welded: usize,
    /// Triangles dropped: a repeated vertex, or the same three vertices as an earlier one.
    pub dropped: usize,
    /// Triangles kept whose corners are (to `f32` precision) on one line: they have no area.
    pub zero_area: usize,
    /// The dropped triangles, by their index in the file, in order.
    pub dropped_triangles: Vec<u32>,
}

impl Cleaning {
    /// Adds what cleaning another file changed, whose triangles come after `before` of the
    /// files so far.
    pub fn add(&mut self, other: Cleaning, before: u32) {
        self.welded += other.welded;
        self.dropped += other.dropped;
        self.zero_area += other.zero_area;
        (self.dropped_triangles).extend(other.dropped_triangles.iter().map(|&t| t + before));
    }

    /// The index in the file (or files, one after another) of the cleaned mesh's triangle
    /// `kept`: triangles keep their order, so it lies past each dropped triangle that has at
    /// most `kept` kept ones before it (`dropped_triangles[j] - j` of them, growing with `j`).
    pub fn file_triangle(&self, kept: u32) -> u32 {
        let dropped = &self.dropped_triangles;
        let (mut lo, mut hi) = (0, dropped.len());
        while lo < hi {
            let mid = (lo + hi) / 2;
            match dropped[mid] - mid as u32 <= kept {
                true => lo = mid + 1,
                false => hi = mid,
            }
        }
        kept + lo as u32
    }
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

    /// [`WorldMesh::validate`] for a mesh made in `f32` (a generated one): the cleaned mesh
    /// and the number of triangles dropped.
    pub fn validate(self, source: &str) -> Result<(Mesh, usize)> {
        let (world, cleaning) = WorldMesh::from(self).validate(source)?;
        Ok((world.to_f32(), cleaning.dropped))
    }
}

impl From<Mesh> for WorldMesh {
    fn from(mesh: Mesh) -> Self {
        WorldMesh {
            positions: mesh.positions.iter().map(|p| p.as_dvec3()).collect(),
            triangles: mesh.triangles,
        }
    }
}

impl WorldMesh {
    /// The mesh with its positions rounded to `f32`, in the same units.
    pub fn to_f32(&self) -> Mesh {
        Mesh {
            positions: self.positions.iter().map(|p| p.as_vec3()).collect(),
            triangles: self.triangles.clone(),
        }
    }

    /// Min/max over all positions (infinite and inverted when empty).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        self.positions
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &p| {
                (lo.min(p), hi.max(p))
            })
    }

    /// Checks and cleans a freshly loaded mesh. Errors: a position that is not finite (naming
    /// the first such vertex), an index out of range (naming triangle and index), no triangle
    /// left, or a mesh with no size. Then, in this order:
    /// - vertices at exactly the same position are welded into the first of them, because a
    ///   grid shares its edge and corner vertices with its neighbours through the indices: an
    ///   exporter that splits vertices at UV or normal seams, or writes no index list, would
    ///   otherwise leave every such seam open;
    /// - triangles that repeat a vertex, and triangles with the same three vertices as an
    ///   earlier one (in any order: a double-sided export's back faces), are dropped. Such a
    ///   duplicate adds nothing to the surface, and would share its inner subdivision vertices
    ///   with the first (Loop subdivision names new vertices by the edges they split), where
    ///   the grids need each inner vertex to belong to one grid;
    /// - vertices no triangle uses are removed (the others keep their order): a stray point
    ///   of a scan would otherwise count in the bounds that frame the picture.
    ///
    /// `source` is the file name used in messages.
    pub fn validate(mut self, source: &str) -> Result<(WorldMesh, Cleaning)> {
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
        let welded = self.weld();
        let before = self.triangles.len();
        let mut seen = HashSet::with_capacity(before);
        let (mut index, mut dropped_triangles) = (0u32, Vec::new());
        self.triangles.retain(|&[a, b, c]| {
            let mut key = [a, b, c];
            key.sort_unstable();
            let keep = a != b && b != c && c != a && seen.insert(key);
            if !keep {
                dropped_triangles.push(index);
            }
            index += 1;
            keep
        });
        let dropped = before - self.triangles.len();
        if self.triangles.is_empty() {
            self.check_size(source)?;
            if dropped > 0 {
                fail!(
                    Input,
                    "{source}: no triangles left after dropping {dropped} degenerate triangles ({DEGENERATE})"
                );
            }
            fail!(Input, "{source}: no triangles");
        }
        self.remove_unused_vertices();
        self.check_size(source)?;
        let zero_area = self.triangles.iter().filter(|&&t| self.has_no_area(t)).count();
        Ok((
            self,
            Cleaning {
                welded,
                dropped,
                zero_area,
                dropped_triangles,
            },
        ))
    }

    /// Refuses a mesh whose vertices all lie at one point (or so close together that no frame
    /// can tell them apart): nothing of it could be seen. Called where every vertex counts:
    /// once the unused ones are gone, or when no triangle is left.
    fn check_size(&self, source: &str) -> Result<()> {
        let Some((&first, rest)) = self.positions.split_first() else {
            return Ok(());
        };
        let extent = rest.iter().fold(0.0f64, |e, p| e.max((*p - first).abs().max_element()));
        if extent < f64::MIN_POSITIVE {
            fail!(
                Input,
                "{source}: the mesh has no size: all its vertices are at ({}, {}, {})",
                first.x,
                first.y,
                first.z
            );
        }
        Ok(())
    }

    /// True when the triangle's corners lie on one line, as far as `f32` can tell.
    fn has_no_area(&self, t: [u32; 3]) -> bool {
        let [a, b, c] = t.map(|i| self.positions[i as usize]);
        let (u, v) = (b - a, c - a);
        u.cross(v).length() <= 1e-7 * u.length() * v.length()
    }

    /// Points every triangle at the first vertex of its position; returns how many vertices
    /// some triangle used that were merged so.
    fn weld(&mut self) -> usize {
        // -0.0 and 0.0 are one position.
        let key = |p: DVec3| (p + DVec3::ZERO).to_array().map(f64::to_bits);
        let mut first: HashMap<[u64; 3], u32> = HashMap::with_capacity(self.positions.len());
        let canonical: Vec<u32> = (0..)
            .zip(&self.positions)
            .map(|(i, &p)| *first.entry(key(p)).or_insert(i))
            .collect();
        let mut merged = vec![false; self.positions.len()];
        for i in self.triangles.iter_mut().flatten() {
            let to = canonical[*i as usize];
            if to != *i {
                merged[*i as usize] = true;
                *i = to;
            }
        }
        merged.iter().filter(|&&m| m).count()
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

    /// The mesh's [`frame::LocalFrame`]: centred on its bounds, scaled to unit size (the
    /// identity for an empty mesh).
    pub fn local_frame(&self) -> frame::LocalFrame {
        if self.positions.is_empty() {
            return frame::LocalFrame::IDENTITY;
        }
        let (lo, hi) = self.bounds();
        frame::LocalFrame::of_bounds(lo, hi)
    }

    /// Moves the mesh into its [`frame::LocalFrame`] (in double precision, then rounded once
    /// to `f32`) and returns it with that frame.
    pub fn into_local(self) -> (Mesh, frame::LocalFrame) {
        let frame = self.local_frame();
        let positions = self.local_positions(&frame);
        let mesh = Mesh {
            positions,
            triangles: self.triangles,
        };
        (mesh, frame)
    }

    /// The mesh moved into `frame` (another mesh's, to compare the two in one frame).
    pub fn in_frame(&self, frame: &frame::LocalFrame) -> Mesh {
        Mesh {
            positions: self.local_positions(frame),
            triangles: self.triangles.clone(),
        }
    }

    fn local_positions(&self, frame: &frame::LocalFrame) -> Vec<Vec3> {
        self.positions.iter().map(|&p| frame.to_local(p)).collect()
    }
}

/// What a dropped triangle is, for messages.
pub const DEGENERATE: &str = "a repeated vertex, or the same three vertices as an earlier triangle";

/// Reads a plain mesh file (`.obj`, `.ply`, `.gltf` or `.glb`; a glTF's micromaps left to
/// `crate::input`) and validates it, in the file's units and double precision. Every error is
/// one line that starts with the file path.
pub fn read_world(path: &Path) -> Result<(WorldMesh, Cleaning)> {
    let bytes = read_mesh_bytes(path)?;
    parse_world(&bytes, path)
}

/// The bytes of a mesh file, refused with a one-line error naming it when its extension is
/// not one gridrt reads, when it cannot be read, or when it is empty.
pub fn read_mesh_bytes(path: &Path) -> Result<Vec<u8>> {
    let name = path.display().to_string();
    if !matches!(
        crate::files::extension(path).as_deref(),
        Some("obj" | "ply" | "gltf" | "glb")
    ) {
        fail!(Input, "{name}: unsupported format (expected .obj, .ply, .gltf or .glb)");
    }
    let bytes = crate::files::read_plain_file(path).map_err(|reason| error!(Input, "{name}: cannot open: {reason}"))?;
    if bytes.is_empty() {
        fail!(Input, "{name}: no triangles (empty file)");
    }
    Ok(bytes)
}

/// Whether `path` names a glTF file (`.gltf` or `.glb`), which may hold a displaced micro-mesh.
pub fn is_gltf(path: &Path) -> bool {
    matches!(crate::files::extension(path).as_deref(), Some("gltf" | "glb"))
}

/// Parses `bytes`, read from `path` (whose extension says the format), as a plain mesh and
/// validates it.
pub fn parse_world(bytes: &[u8], path: &Path) -> Result<(WorldMesh, Cleaning)> {
    let name = path.display().to_string();
    let parsed = match crate::files::extension(path).as_deref() {
        Some("obj") => obj::parse_obj(bytes),
        Some("ply") => ply::parse_ply(bytes),
        Some("glb") => gltf::parse_glb(bytes, path.parent()),
        _ => gltf::parse_gltf(bytes, path.parent()),
    };
    let mesh = parsed.map_err(|e| error!(Input, "{name}: {}", one_line(&e.to_string())))?;
    mesh.validate(&name)
}

pub use crate::files::io_reason;

/// Guards the one-line promise against messages that quote file content.
pub(crate) fn one_line(s: &str) -> String {
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

/// Shared helpers for the loader tests: scratch files and error checks.
#[cfg(test)]
pub(crate) mod test_util {
    use std::path::{Path, PathBuf};

    use super::*;

    /// A file in a scratch folder of its own; the folder goes when this is dropped.
    pub struct ScratchFile {
        path: PathBuf,
        _folder: tempfile::TempDir,
    }

    impl ScratchFile {
        /// A path for a file named `name` in a fresh folder whose name starts `gridrt-{test}-`.
        pub fn new(test: &str, name: &str) -> Self {
            let folder = tempfile::Builder::new()
                .prefix(&format!("gridrt-{test}-"))
                .tempdir()
                .unwrap();
            let path = folder.path().join(name);
            ScratchFile { path, _folder: folder }
        }
    }

    impl std::ops::Deref for ScratchFile {
        type Target = Path;
        fn deref(&self) -> &Path {
            &self.path
        }
    }

    impl AsRef<Path> for ScratchFile {
        fn as_ref(&self) -> &Path {
            &self.path
        }
    }

    /// Writes `bytes` to a file named `name` in a scratch folder of its own.
    pub fn write_temp(name: &str, bytes: &[u8]) -> ScratchFile {
        let file = ScratchFile::new("mesh-test", name);
        std::fs::write(&file, bytes).unwrap();
        file
    }

    /// Loads `bytes` as file `name` and asserts a one-line error naming the path and containing every `needles`.
    pub fn expect_err(name: &str, bytes: &[u8], needles: &[&str]) -> String {
        let path = write_temp(name, bytes);
        let result = std::panic::catch_unwind(|| read_world(&path));
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
        let _ = std::panic::catch_unwind(|| read_world(&path)).expect("loader panicked");
    }

    /// Loads `bytes` as file `name`, expecting success.
    pub fn load_ok(name: &str, bytes: &[u8]) -> (Mesh, usize) {
        let path = write_temp(name, bytes);
        let (mesh, cleaning) = read_world(&path).unwrap_or_else(|e| panic!("{e:#}"));
        (mesh.to_f32(), cleaning.dropped)
    }
}

#[cfg(test)]
mod tests {
    use super::test_util::*;
    use super::*;

    #[test]
    fn kept_triangles_know_their_index_in_the_file() {
        let mesh = Mesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
            triangles: vec![[0, 0, 1], [0, 1, 2], [2, 1, 0], [0, 1, 3], [3, 3, 3], [1, 2, 3]],
        };
        let (clean, cleaning) = WorldMesh::from(mesh.clone()).validate("m").unwrap();
        assert_eq!(cleaning.dropped_triangles, vec![0, 2, 4]);
        for kept in 0..clean.triangles.len() as u32 {
            let file = cleaning.file_triangle(kept) as usize;
            assert_eq!(clean.triangles[kept as usize], mesh.triangles[file]);
        }
        // A second file's triangles come after the first's, dropped ones included.
        let mut both = cleaning.clone();
        both.add(cleaning, 6);
        assert_eq!(both.dropped_triangles, vec![0, 2, 4, 6, 8, 10]);
        assert_eq!([3, 4, 5].map(|k| both.file_triangle(k)), [7, 9, 11]);
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
        let e = format!("{:#}", read_world(&missing).unwrap_err());
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
            // The teapot's patches repeat the vertices along their seams: welded.
            ("teapot.obj", 992, 529),
            // The dragons' files also hold 2 and 16 vertices no face uses.
            ("dragon_res4.ply", 11102, 5203),
            ("dragon_res3.ply", 47794, 22982),
        ] {
            let (m, cleaning) = read_world(&dir.join(file)).unwrap_or_else(|e| panic!("{e:#}"));
            let (m, dropped) = (m.to_f32(), cleaning.dropped);
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
