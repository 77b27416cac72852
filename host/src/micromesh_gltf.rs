//! Writing a displaced micro-mesh as glTF 2.0 with NVIDIA's draft extensions `NV_micromaps`
//! and `NV_displacement_micromap`: `NAME.gltf`, its buffer `NAME.bin` (base positions,
//! directions, indices) and its micromap `NAME.bary` side by side.
//!
//! The base mesh is written in its local frame, with the node's translation (the frame's
//! centre, every digit of its `f64`) and scale (a power of two) taking it back to the input's
//! units: a mesh far from the origin keeps in the file the precision it had in gridrt. The
//! directions are in the same local units, so the node's scale applies to them as the
//! extension's `p = lerp(P) + lerp(D) * d` needs. The micromap's triangle `t` displaces the
//! primitive's triangle `t` (no `mapIndices`); its group's bias and scale hold the range.
//! Decimated edges, when any, are the primitive's `primitiveFlags`.

use std::path::{Path, PathBuf};

use serde_json::json;

use crate::bary;
use crate::displaced::DisplacedMesh;
use crate::error::{error, Result};
use crate::image_io::write_atomically;
use crate::mesh::frame::LocalFrame;

/// The three files a micro-mesh is written to, named after `gltf`'s stem.
pub fn companion_paths(gltf: &Path) -> (PathBuf, PathBuf) {
    (gltf.with_extension("bin"), gltf.with_extension("bary"))
}

/// Writes `mesh` (in `frame`'s local units) to `path` (a `.gltf`), its `.bin` and its `.bary`.
pub fn write(path: &Path, mesh: &DisplacedMesh, frame: &LocalFrame) -> Result<()> {
    let (bin_path, bary_path) = companion_paths(path);
    let file_name = |p: &Path| {
        p.file_name()
            .map_or(String::new(), |f| f.to_string_lossy().into_owned())
    };
    let (bin, document) = document(mesh, frame, &file_name(&bin_path), &file_name(&bary_path));
    let failed = |p: &Path, e: std::io::Error| error!(Output, "{}: cannot write: {e}", p.display());
    write_atomically(&bin_path, |temp| {
        std::fs::write(temp, &bin).map_err(|e| failed(&bin_path, e))
    })?;
    let bary = bary::write(&mesh.micromap);
    write_atomically(&bary_path, |temp| {
        std::fs::write(temp, &bary).map_err(|e| failed(&bary_path, e))
    })?;
    let text = serde_json::to_string_pretty(&document).map_err(|e| error!(Output, "{e}"))?;
    write_atomically(path, |temp| {
        std::fs::write(temp, text + "\n").map_err(|e| failed(path, e))
    })
}

/// The buffer's bytes and the glTF document that names them and the micromap.
fn document(mesh: &DisplacedMesh, frame: &LocalFrame, bin: &str, bary: &str) -> (Vec<u8>, serde_json::Value) {
    let floats = |v: &[gridrt_shared::glam::Vec3]| -> Vec<u8> {
        v.iter().flat_map(|p| p.to_array()).flat_map(f32::to_le_bytes).collect()
    };
    let mut buffer = floats(&mesh.positions);
    let directions_at = buffer.len();
    buffer.extend(floats(&mesh.directions));
    let indices_at = buffer.len();
    buffer.extend(mesh.triangles.iter().flatten().flat_map(|i| i.to_le_bytes()));
    let flags_at = buffer.len();
    buffer.extend_from_slice(&mesh.decimated_edges);
    let vertices = mesh.positions.len();
    let (lo, hi) = mesh.positions.iter().fold(
        (
            gridrt_shared::glam::Vec3::INFINITY,
            gridrt_shared::glam::Vec3::NEG_INFINITY,
        ),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let view = |offset: usize, length: usize| json!({"buffer": 0, "byteOffset": offset, "byteLength": length});
    let unit = 1.0 / frame.scale;
    let mut document = json!({
        "asset": {"version": "2.0", "generator": "gridrt"},
        "extensionsUsed": ["NV_micromaps", "NV_displacement_micromap"],
        "extensions": {"NV_micromaps": {"micromaps": [{"uri": bary}]}},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{
            "mesh": 0,
            "translation": frame.centre.to_array(),
            "scale": [unit, unit, unit],
        }],
        "meshes": [{"primitives": [{
            "attributes": {"POSITION": 0},
            "indices": 2,
            "mode": 4,
            "extensions": {"NV_displacement_micromap": {"micromap": 0, "directions": 1}},
        }]}],
        "buffers": [{"uri": bin, "byteLength": buffer.len()}],
        "bufferViews": [
            view(0, directions_at),
            view(directions_at, indices_at - directions_at),
            view(indices_at, flags_at - indices_at),
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": vertices, "type": "VEC3",
             "min": lo.to_array(), "max": hi.to_array()},
            {"bufferView": 1, "componentType": 5126, "count": vertices, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5125, "count": 3 * mesh.triangles.len(), "type": "SCALAR"},
        ],
    });
    if !mesh.decimated_edges.is_empty() {
        // One unsigned byte per triangle.
        let views = document["bufferViews"].as_array_mut().expect("views");
        views.push(view(flags_at, buffer.len() - flags_at));
        let accessors = document["accessors"].as_array_mut().expect("accessors");
        accessors
            .push(json!({"bufferView": 3, "componentType": 5121, "count": mesh.triangles.len(), "type": "SCALAR"}));
        let extension = &mut document["meshes"][0]["primitives"][0]["extensions"]["NV_displacement_micromap"];
        extension["primitiveFlags"] = json!(3);
    }
    (buffer, document)
}

/// Writes `mesh` 1e7 from the origin, in a scratch folder named for `test`: the file and
/// the frame it was written in.
#[cfg(test)]
pub(crate) fn write_far_from_origin(
    mesh: &DisplacedMesh,
    test: &str,
) -> (crate::mesh::test_util::ScratchFile, LocalFrame) {
    let path = crate::mesh::test_util::ScratchFile::new(test, "baked.gltf");
    let frame = LocalFrame {
        centre: gridrt_shared::glam::DVec3::new(1.0e7 + 0.125, -3.0, 2.5e6),
        scale: 0.25,
    };
    write(&path, mesh, &frame).unwrap();
    (path, frame)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bary::{values_per_triangle, Micromap};
    use gridrt_shared::glam::{DVec3, Vec3};

    fn sample() -> DisplacedMesh {
        let level = 2;
        let values: Vec<u16> = (0..values_per_triangle(level) as u16).map(|k| k * 90).collect();
        DisplacedMesh {
            positions: vec![
                Vec3::new(-0.5, -0.5, 0.0),
                Vec3::new(0.5, -0.5, 0.0),
                Vec3::new(0.0, 0.5, 0.25),
            ],
            directions: vec![Vec3::Z, Vec3::new(0.0, 0.1, 1.0), Vec3::new(0.1, 0.0, 1.0)],
            triangles: vec![[0, 1, 2]],
            micromap: Micromap::from_triangles(-0.01, 0.02, &[(level, values)]),
            decimated_edges: Vec::new(),
        }
    }

    /// The written glTF parses as the base mesh in the input's units (far from the origin,
    /// exactly), its micromap reads back equal, and its JSON names the extensions and the
    /// directions.
    #[test]
    fn written_files_read_back() {
        let mesh = sample();
        let (path, frame) = write_far_from_origin(&mesh, "micromesh-gltf");
        let dir = path.parent().unwrap();
        // The glTF alone, without its extensions: the base mesh (loading decodes it).
        let base = crate::mesh::gltf::parse_gltf(&std::fs::read(&path).unwrap(), Some(dir)).unwrap();
        let expected: Vec<DVec3> = mesh.positions.iter().map(|&p| frame.to_world(p)).collect();
        assert_eq!(base.positions, expected);
        assert_eq!(base.triangles, mesh.triangles);
        let (_, bary_path) = companion_paths(&path);
        assert_eq!(bary::read(&std::fs::read(bary_path).unwrap()).unwrap(), mesh.micromap);
        let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
        assert_eq!(json["extensions"]["NV_micromaps"]["micromaps"][0]["uri"], "baked.bary");
        let extension = &json["meshes"][0]["primitives"][0]["extensions"]["NV_displacement_micromap"];
        assert_eq!(
            (extension["micromap"].as_u64(), extension["directions"].as_u64()),
            (Some(0), Some(1))
        );
        assert_eq!(json["accessors"][1]["type"], "VEC3");
    }
}
