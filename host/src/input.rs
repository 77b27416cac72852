//! What a user's file holds, opened: a triangle mesh (`.obj`, `.ply`, `.gltf`, `.glb`, see
//! [`crate::mesh`]) or a displaced micro-mesh (glTF with NVIDIA's micromap extensions, see
//! [`crate::micromesh`]), or several of one kind side by side, moved into the local frame
//! where everything after loading works. A micro-mesh comes with its decoded micro-triangles,
//! so the commands that take any mesh take it too. Errors are one line naming the file.

use std::path::Path;

use gridrt_shared::glam::DVec3;

use crate::error::{error, fail, Result};
use crate::mesh::frame::LocalFrame;
use crate::mesh::{self, one_line, Cleaning, Mesh, WorldMesh};
use crate::micromesh::{gltf_micromap, DisplacedMesh};

/// Loads .obj, .ply, .gltf or .glb (case-insensitive extension) and validates it, in the
/// file's units rounded to `f32`. Every error is one line that starts with the file path.
/// [`load_mesh_quiet`] and [`open`] say what cleaning changed.
pub fn load_mesh(path: &Path) -> Result<Mesh> {
    Ok(load_mesh_quiet(path)?.0)
}

/// A mesh ready for the pipeline, and where it came from.
pub struct Input {
    /// The file's name as given, or `default scene`.
    pub name: String,
    /// The mesh in its local frame (see [`crate::mesh::frame`]).
    pub mesh: Mesh,
    /// Maps the mesh back to the file's units.
    pub frame: LocalFrame,
    /// What cleaning changed or found, summed over the files: vertices welded, degenerate
    /// triangles dropped, triangles without area.
    pub cleaning: Cleaning,
    /// Set when the input is a displaced micro-mesh: `mesh` then holds its decoded
    /// micro-triangles, to be traced as they are (no further subdivision).
    pub displaced: Option<DisplacedSource>,
    /// The displaced micro-mesh itself, in the same frame as `mesh` (whose triangles are its
    /// decoded micro-triangles, point for point).
    pub micromesh: Option<DisplacedMesh>,
    /// Where a file was read otherwise than it may mean (a default taken for what it leaves
    /// out), one line each naming the file; a caller shows them.
    pub warnings: Vec<String>,
}

/// A displaced micro-mesh that was loaded as its decoded micro-triangles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DisplacedSource {
    pub base_triangles: usize,
    pub min_level: u32,
    pub max_level: u32,
}

/// Loads `path` (`.obj`, `.ply`, `.gltf` or `.glb`), or the built-in scene when `None`, and moves it into its
/// local frame, where everything after loading works. Errors are one line naming the file.
pub fn open(path: Option<&Path>) -> Result<Input> {
    open_all(path.as_slice())
}

/// Several files as one mesh (each loaded and checked on its own, then put side by side in
/// the files' common units, in double precision), or the built-in scene when `paths` is
/// empty; in its local frame.
pub fn open_all(paths: &[&Path]) -> Result<Input> {
    let Some(first) = paths.first() else {
        let (mesh, frame) = WorldMesh::from(mesh::scene::default_scene()).into_local();
        return Ok(Input {
            name: "default scene".to_string(),
            mesh,
            frame,
            cleaning: Cleaning::default(),
            displaced: None,
            micromesh: None,
            warnings: Vec::new(),
        });
    };
    let mut name = first.display().to_string();
    let mut loaded = read_file(first)?;
    for path in &paths[1..] {
        let next = read_file(path)?;
        name = format!("{name} + {}", path.display());
        match (&mut loaded, next) {
            (Loaded::Plain(all, cleaning), Loaded::Plain(next, next_cleaning)) => {
                let base = all.positions.len() as u32;
                let before = (all.triangles.len() + cleaning.dropped) as u32;
                all.positions.extend(next.positions);
                all.triangles.extend(next.triangles.iter().map(|t| t.map(|i| base + i)));
                cleaning.add(next_cleaning, before);
            }
            (Loaded::Displaced(all), Loaded::Displaced(next)) => all.append(&next),
            (first_loaded, _) => {
                let (micro, plain) = match first_loaded {
                    Loaded::Displaced(_) => (first, path),
                    Loaded::Plain(..) => (path, first),
                };
                fail!(
                    Input,
                    "{} is a displaced micro-mesh and {} is not: render them apart",
                    micro.display(),
                    plain.display()
                );
            }
        }
    }
    let (all, cleaning) = match loaded {
        Loaded::Displaced(all) => return open_displaced(all, name),
        Loaded::Plain(all, cleaning) => (all, cleaning),
    };
    Ok(Input::plain(name, all, cleaning))
}

/// A mesh given as arrays (vertices in any units, triangles as vertex indices), checked
/// and cleaned as a file's mesh is ([`WorldMesh::validate`]) and moved into its local frame;
/// `name` stands for a file in messages.
pub fn from_arrays(name: &str, positions: Vec<[f64; 3]>, triangles: Vec<[u32; 3]>) -> Result<Input> {
    let world = WorldMesh {
        positions: positions.into_iter().map(DVec3::from).collect(),
        triangles,
    };
    let (world, cleaning) = world.validate(name)?;
    Ok(Input::plain(name.to_string(), world, cleaning))
}

impl Input {
    /// The displaced micro-mesh this input brings, when it has levels to build displaced
    /// grids of (the grids' representation of it; the baseline traces [`Input::mesh`]).
    pub fn displaced_grids(&self) -> Option<&DisplacedMesh> {
        self.micromesh.as_ref().filter(|m| m.deepest_level().is_some())
    }

    /// A plain mesh, checked and cleaned, moved into its local frame.
    fn plain(name: String, world: WorldMesh, cleaning: Cleaning) -> Input {
        let (mesh, frame) = world.into_local();
        Input {
            name,
            mesh,
            frame,
            cleaning,
            displaced: None,
            micromesh: None,
            warnings: Vec::new(),
        }
    }
}

/// Displaced micro-meshes side by side, in the local frame of their base meshes: the
/// micro-mesh itself, and its decoded micro-triangles (points decoded alike stored once) as
/// the mesh, so that both decode the same points.
fn open_displaced(mut all: gltf_micromap::DisplacedWorld, name: String) -> Result<Input> {
    let warnings = std::mem::take(&mut all.warnings);
    let (micromesh, frame) = all.into_local();
    micromesh.check().map_err(|e| e.prefixed(&name))?;
    let micromesh = micromesh.with_ranges_folded();
    let mesh = micromesh.decoded_welded();
    let levels = micromesh.micromap.triangles.iter().map(|t| t.level);
    let source = DisplacedSource {
        base_triangles: micromesh.triangles.len(),
        min_level: levels.clone().min().unwrap_or(0),
        max_level: levels.max().unwrap_or(0),
    };
    Ok(Input {
        name,
        mesh,
        frame,
        cleaning: Cleaning::default(),
        displaced: Some(source),
        micromesh: Some(micromesh),
        warnings,
    })
}

/// [`load_mesh`] without the warning: returns the number of dropped degenerate triangles instead.
pub fn load_mesh_quiet(path: &Path) -> Result<(Mesh, usize)> {
    let (mesh, cleaning) = load_world(path)?;
    Ok((mesh.to_f32(), cleaning.dropped))
}

/// Loads and validates one file, in its own units and in double precision (a displaced
/// micro-mesh as its decoded micro-triangles).
pub fn load_world(path: &Path) -> Result<(WorldMesh, Cleaning)> {
    load_world_warning(path).map(|(mesh, cleaning, _)| (mesh, cleaning))
}

/// [`load_world`], with the warnings of [`Input::warnings`].
pub fn load_world_warning(path: &Path) -> Result<(WorldMesh, Cleaning, Vec<String>)> {
    match read_file(path)? {
        Loaded::Plain(mesh, cleaning) => Ok((mesh, cleaning, Vec::new())),
        Loaded::Displaced(mut displaced) => {
            let warnings = std::mem::take(&mut displaced.warnings);
            let (local, frame) = displaced.into_local();
            let decoded = local.decoded();
            let world = WorldMesh {
                positions: decoded.positions.iter().map(|&p| frame.to_world(p)).collect(),
                triangles: decoded.triangles,
            };
            let (world, cleaning) = world.validate(&path.display().to_string())?;
            Ok((world, cleaning, warnings))
        }
    }
}

/// Every file that loading `paths` reads: each of them, and the files a glTF names beside it
/// (buffers, micromaps). An output must be none of them.
pub fn files_read(paths: &[&Path]) -> Vec<std::path::PathBuf> {
    let mut files = Vec::new();
    for &path in paths {
        files.push(path.to_path_buf());
        if mesh::is_gltf(path) {
            files.extend(mesh::gltf::files_named(path));
        }
    }
    files
}

/// One file as read: a triangle mesh (validated), or a displaced micro-mesh (checked).
enum Loaded {
    Plain(WorldMesh, Cleaning),
    Displaced(gltf_micromap::DisplacedWorld),
}

/// Reads, parses and checks one file, once.
fn read_file(path: &Path) -> Result<Loaded> {
    let name = path.display().to_string();
    let bytes = mesh::read_mesh_bytes(path)?;
    if mesh::is_gltf(path) && bytes.windows(24).any(|w| w == b"NV_displacement_micromap") {
        let named = |e: crate::error::Error| error!(Input, "{name}: {}", one_line(&e.to_string()));
        if let Some(mut displaced) = gltf_micromap::parse_displaced(&bytes, path.parent()).map_err(named)? {
            for warning in &mut displaced.warnings {
                *warning = format!("{name}: {warning}");
            }
            // Checked in the frame it is decoded in, so the error names this file.
            displaced.clone().into_local().0.check().map_err(named)?;
            return Ok(Loaded::Displaced(displaced));
        }
    }
    let (mesh, cleaning) = mesh::parse_world(&bytes, path)?;
    Ok(Loaded::Plain(mesh, cleaning))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::test_util::write_temp;
    use gridrt_shared::glam::Vec3;

    /// Several files open as one mesh in their common units, then in one local frame; a bad
    /// one is named.
    #[test]
    fn several_files_open_as_one_mesh() {
        let a = write_temp("a.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        let b = write_temp("b.obj", b"v 4 0 0\nv 5 0 0\nv 4 1 0\nv 9 9 9\nf 1 2 3\nf 1 1 2\n");
        let all = open_all(&[&a, &b]).unwrap();
        assert_eq!(all.name, format!("{} + {}", a.display(), b.display()));
        assert_eq!(all.cleaning.dropped, 1);
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
}
