//! Writing a displaced micro-mesh as glTF 2.0 with NVIDIA's draft extensions `NV_micromaps`
//! and `NV_displacement_micromap`: `NAME.gltf`, its buffer `NAME.TAG.bin` (base positions,
//! directions, indices) and its micromap `NAME.TAG.bary` side by side, `TAG` a hash of their
//! bytes. The three appear whole or not at all (see `files::write_set`): a reader, a kill or
//! a second writer never meets a new buffer beside an old glTF.
//!
//! The base mesh is written in its local frame, with the node's translation (the frame's
//! centre, every digit of its `f64`) and scale (a power of two) taking it back to the input's
//! units: a mesh far from the origin keeps in the file the precision it had in gridrt. The
//! directions are in the same local units, so the node's scale applies to them as the
//! extension's `p = lerp(P) + lerp(D) * d` needs. The micromap's triangle `t` displaces the
//! primitive's triangle `t` (no `mapIndices`); its group's bias and scale hold the range.
//! Decimated edges, when any, are the primitive's `primitiveFlags`.

use std::path::{Path, PathBuf};

use serde_json::{json, Value};

use crate::error::{error, Result};
use crate::files::{self, MainFile, SideFile};
use crate::mesh::frame::LocalFrame;
use crate::micromesh::bary;
use crate::micromesh::DisplacedMesh;

/// Writes `mesh` (in `frame`'s local units) to `path` (a `.gltf`), its buffer and its
/// micromap beside it; returns the three paths, the glTF first.
pub fn write(path: &Path, mesh: &DisplacedMesh, frame: &LocalFrame) -> Result<Vec<PathBuf>> {
    write_keeping(path, mesh, frame, &[])
}

/// [`write`], never writing or removing a file of `keep` (the files the run reads): where the
/// glTF replaced names one of them, it stays.
pub fn write_keeping(path: &Path, mesh: &DisplacedMesh, frame: &LocalFrame, keep: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let (bin, document) = document(mesh, frame);
    let sides = [
        SideFile {
            extension: "bin",
            bytes: bin,
        },
        SideFile {
            extension: "bary",
            bytes: bary::write(&mesh.micromap),
        },
    ];
    files::write_set(path, &sides, &Gltf(document), keep)
}

/// The glTF document of a micro-mesh, its buffer and micromap named as [`files::write_set`]
/// names them.
struct Gltf(Value);

impl MainFile for Gltf {
    fn bytes(&self, names: &[String]) -> Result<Vec<u8>> {
        let mut document = self.0.clone();
        document["buffers"][0]["uri"] = json!(names[0]);
        document["extensions"]["NV_micromaps"]["micromaps"][0]["uri"] = json!(names[1]);
        let text = serde_json::to_string_pretty(&document).map_err(|e| error!(Output, "{e}"))?;
        Ok((text + "\n").into_bytes())
    }

    fn side_names(&self, bytes: &[u8]) -> Vec<String> {
        serde_json::from_slice::<Value>(bytes).map_or(Vec::new(), |old| crate::mesh::gltf::uris_named(&old))
    }
}

/// The buffer's bytes and the glTF document that names them and the micromap.
fn document(mesh: &DisplacedMesh, frame: &LocalFrame) -> (Vec<u8>, Value) {
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
        "extensions": {"NV_micromaps": {"micromaps": [{"uri": ""}]}},
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
        "buffers": [{"uri": "", "byteLength": buffer.len()}],
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
    use crate::micromesh::bary::{values_per_triangle, Micromap};
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
        let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
        let bary_name = json["extensions"]["NV_micromaps"]["micromaps"][0]["uri"]
            .as_str()
            .unwrap();
        assert!(
            bary_name.starts_with("baked.") && bary_name.ends_with(".bary"),
            "{bary_name}"
        );
        assert_eq!(
            bary::read(&std::fs::read(dir.join(bary_name)).unwrap()).unwrap(),
            mesh.micromap
        );
        let extension = &json["meshes"][0]["primitives"][0]["extensions"]["NV_displacement_micromap"];
        assert_eq!(
            (extension["micromap"].as_u64(), extension["directions"].as_u64()),
            (Some(0), Some(1))
        );
        assert_eq!(json["accessors"][1]["type"], "VEC3");
    }
}
