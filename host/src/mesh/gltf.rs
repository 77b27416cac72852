//! glTF 2.0 (`.gltf` with external or embedded buffers, `.glb`) through the `gltf` crate.
//!
//! Every triangle primitive of every mesh in the default scene (or the first scene, or every
//! node when the file has none) becomes part of one mesh, each with its node's transform
//! (parents' included) applied in double precision. A transform that mirrors (negative
//! determinant) would turn its triangles inside out, so their winding is reversed. Points and
//! lines are skipped; strips and fans are split into triangles.

use std::path::Path;

use crate::error::{error, fail, Result};
use gltf::mesh::Mode;
use gridrt_shared::glam::{DMat4, DVec3, Vec3};

use super::Mesh;

/// Parses a glTF or GLB file's bytes; external buffers are read relative to `folder`. Errors
/// carry no file name; the caller adds it.
pub fn parse_gltf(bytes: &[u8], folder: Option<&Path>) -> Result<Mesh> {
    let gltf::Gltf { document, blob } = gltf::Gltf::from_slice(bytes).map_err(|e| error!(Input, "{e}"))?;
    let buffers =
        gltf::import_buffers(&document, folder, blob).map_err(|e| error!(Input, "cannot read its buffers: {e}"))?;
    let mut mesh = Mesh::default();
    let scene = document.default_scene().or_else(|| document.scenes().next());
    match scene {
        Some(scene) => {
            for node in scene.nodes() {
                add_node(&mut mesh, &node, DMat4::IDENTITY, &buffers)?;
            }
        }
        // No scene: every root node (a node no other names as a child).
        None => {
            let mut is_child = vec![false; document.nodes().len()];
            for child in document.nodes().flat_map(|n| n.children()) {
                is_child[child.index()] = true;
            }
            for node in document.nodes().filter(|n| !is_child[n.index()]) {
                add_node(&mut mesh, &node, DMat4::IDENTITY, &buffers)?;
            }
        }
    }
    if mesh.triangles.is_empty() {
        fail!(Input, "no triangle primitives in its scene");
    }
    Ok(mesh)
}

/// Adds `node`'s mesh and its children's under `parent`'s transform.
fn add_node(mesh: &mut Mesh, node: &gltf::Node, parent: DMat4, buffers: &[gltf::buffer::Data]) -> Result<()> {
    let local = DMat4::from_cols_array_2d(&node.transform().matrix().map(|c| c.map(f64::from)));
    let transform = parent * local;
    if let Some(m) = node.mesh() {
        for primitive in m.primitives() {
            add_primitive(mesh, &primitive, &transform, buffers)
                .map_err(|e| error!(Input, "mesh {} primitive {}: {e}", m.index(), primitive.index()))?;
        }
    }
    for child in node.children() {
        add_node(mesh, &child, transform, buffers)?;
    }
    Ok(())
}

fn add_primitive(
    mesh: &mut Mesh,
    primitive: &gltf::Primitive,
    transform: &DMat4,
    buffers: &[gltf::buffer::Data],
) -> Result<()> {
    if !matches!(
        primitive.mode(),
        Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
    ) {
        return Ok(());
    }
    let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
    let positions: Vec<Vec3> = reader
        .read_positions()
        .ok_or_else(|| error!(Input, "no POSITION attribute"))?
        .map(|p| transform.transform_point3(DVec3::from(p.map(f64::from))).as_vec3())
        .collect();
    let count = positions.len() as u32;
    let indices: Vec<u32> = match reader.read_indices() {
        Some(indices) => indices.into_u32().collect(),
        None => (0..count).collect(),
    };
    if let Some(&bad) = indices.iter().find(|&&i| i >= count) {
        fail!(Input, "index {bad} is out of range ({count} positions)");
    }
    let base = mesh.positions.len() as u32;
    let mirrored = transform.determinant() < 0.0;
    let triangles = triangle_list(primitive.mode(), &indices);
    mesh.triangles.extend(triangles.into_iter().map(|[a, b, c]| {
        let t = if mirrored { [a, c, b] } else { [a, b, c] };
        t.map(|i| base + i)
    }));
    mesh.positions.extend(positions);
    Ok(())
}

/// The triangles of a list, strip or fan of indices, counter-clockwise as glTF orders them.
fn triangle_list(mode: Mode, indices: &[u32]) -> Vec<[u32; 3]> {
    match mode {
        Mode::TriangleStrip => (0..indices.len().saturating_sub(2))
            .map(|k| {
                let [a, b, c] = [indices[k], indices[k + 1], indices[k + 2]];
                if k % 2 == 0 {
                    [a, b, c]
                } else {
                    [b, a, c]
                }
            })
            .collect(),
        Mode::TriangleFan => (1..indices.len().saturating_sub(1))
            .map(|k| [indices[0], indices[k], indices[k + 1]])
            .collect(),
        _ => indices.as_chunks::<3>().0.to_vec(),
    }
}

#[cfg(test)]
mod tests {
    use super::super::load_mesh_quiet;
    use super::super::test_util::{expect_err, load_scrambled, write_temp};
    use super::*;

    /// Little-endian bytes of the scene's one buffer: a unit right triangle (three positions)
    /// and its indices, then a second triangle's positions, drawn without indices.
    fn buffer() -> Vec<u8> {
        let mut b = Vec::new();
        for p in [
            [0f32, 0., 0.],
            [1., 0., 0.],
            [0., 1., 0.],
            [0., 0., 1.],
            [1., 0., 1.],
            [0., 1., 1.],
        ] {
            b.extend(p.iter().flat_map(|c| c.to_le_bytes()));
        }
        b.extend([0u16, 1, 2, 0].iter().flat_map(|i| i.to_le_bytes()));
        b
    }

    fn base64(bytes: &[u8]) -> String {
        const ABC: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
        let mut out = String::new();
        for chunk in bytes.chunks(3) {
            let n = chunk
                .iter()
                .enumerate()
                .fold(0u32, |n, (k, &b)| n | (b as u32) << (16 - 8 * k));
            for k in 0..4 {
                match k <= chunk.len() {
                    true => out.push(ABC[(n >> (18 - 6 * k) & 63) as usize] as char),
                    false => out.push('='),
                }
            }
        }
        out
    }

    /// One mesh of two primitives (indexed, then not), under a node translated by (10, 0, 0)
    /// and scaled by 2, whose child draws the mesh again mirrored in x; `uri` is the buffer's.
    fn document(uri: Option<&str>) -> String {
        let uri = uri.map_or(String::new(), |u| format!(r#""uri": "{u}", "#));
        format!(
            r#"{{
  "asset": {{"version": "2.0"}},
  "scene": 0,
  "scenes": [{{"nodes": [0]}}],
  "nodes": [
    {{"mesh": 0, "translation": [10, 0, 0], "scale": [2, 2, 2], "children": [1]}},
    {{"mesh": 0, "scale": [-1, 1, 1]}}
  ],
  "meshes": [{{"primitives": [
    {{"attributes": {{"POSITION": 0}}, "indices": 2}},
    {{"attributes": {{"POSITION": 1}}, "mode": 4}}
  ]}}],
  "buffers": [{{{uri}"byteLength": 80}}],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": 36}},
    {{"buffer": 0, "byteOffset": 36, "byteLength": 36}},
    {{"buffer": 0, "byteOffset": 72, "byteLength": 6}}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 1], "max": [1, 1, 1]}},
    {{"bufferView": 2, "componentType": 5123, "count": 3, "type": "SCALAR"}}
  ]
}}"#
        )
    }

    fn check(mesh: &Mesh) {
        assert_eq!(mesh.triangles.len(), 4);
        assert_eq!(mesh.positions.len(), 12);
        // The first primitive under the root: scaled by 2, moved by 10.
        assert_eq!(
            &mesh.positions[..3],
            &[Vec3::new(10., 0., 0.), Vec3::new(12., 0., 0.), Vec3::new(10., 2., 0.)]
        );
        assert_eq!(mesh.triangles[0], [0, 1, 2]);
        // The child mirrors x inside the root's transform, and keeps the triangles' facing.
        assert_eq!(mesh.positions[7], Vec3::new(8., 0., 0.));
        assert_eq!(mesh.triangles[2], [6, 8, 7]);
        let normal = |t: [u32; 3]| {
            let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
            (b - a).cross(c - a)
        };
        assert!(normal(mesh.triangles[0]).z > 0.0 && normal(mesh.triangles[2]).z > 0.0);
    }

    #[test]
    fn embedded_external_and_binary_buffers_load_alike() {
        let embedded = document(Some(&format!(
            "data:application/octet-stream;base64,{}",
            base64(&buffer())
        )));
        check(
            &load_mesh_quiet(&write_temp("embedded.gltf", embedded.as_bytes()))
                .unwrap()
                .0,
        );

        let bin = write_temp("scene.bin", &buffer());
        let gltf = bin.with_file_name("scene.gltf");
        std::fs::write(&gltf, document(Some("scene.bin"))).unwrap();
        check(&load_mesh_quiet(&gltf).unwrap().0);

        check(
            &load_mesh_quiet(&write_temp("scene.glb", &glb(&document(None), &buffer())))
                .unwrap()
                .0,
        );
    }

    /// A GLB container: header, JSON chunk, binary chunk, each padded to four bytes.
    fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
        let pad = |mut v: Vec<u8>, with: u8| {
            while !v.len().is_multiple_of(4) {
                v.push(with);
            }
            v
        };
        let (json, bin) = (pad(json.as_bytes().to_vec(), b' '), pad(bin.to_vec(), 0));
        let mut out = Vec::new();
        out.extend(b"glTF");
        out.extend(2u32.to_le_bytes());
        out.extend((12 + 8 + json.len() as u32 + 8 + bin.len() as u32).to_le_bytes());
        out.extend((json.len() as u32).to_le_bytes());
        out.extend(b"JSON");
        out.extend(&json);
        out.extend((bin.len() as u32).to_le_bytes());
        out.extend(b"BIN\0");
        out.extend(&bin);
        out
    }

    #[test]
    fn broken_gltf_files_give_one_line_errors() {
        expect_err("missing.gltf", document(Some("nowhere.bin")).as_bytes(), &["buffers"]);
        expect_err("junk.gltf", b"{ not json", &[]);
        expect_err("junk.glb", b"glTF\x02\0\0\0\x10\0\0\0", &[]);
        let no_positions = document(None).replace(r#""POSITION": 0"#, r#""NORMAL": 0"#);
        expect_err("nopos.glb", &glb(&no_positions, &buffer()), &["POSITION"]);
        let bad_index = {
            let mut b = buffer();
            b[72] = 9;
            b
        };
        expect_err(
            "index.glb",
            &glb(&document(None), &bad_index),
            &["index 9 is out of range"],
        );
        let mut seed = 0x9e37_79b9_7f4a_7c15;
        for _ in 0..200 {
            load_scrambled("scrambled.glb", glb(&document(None), &buffer()), &mut seed, 4);
        }
    }
}
