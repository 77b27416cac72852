//! Displaced micro-meshes in glTF: NVIDIA's draft extensions `NV_micromaps` (the file's
//! micromaps, each a `.bary` by `uri` or in a `bufferView`) and `NV_displacement_micromap` (on a
//! triangle primitive: which micromap and group, which of its triangles each primitive
//! triangle takes, and the per-vertex `directions`), read into one displaced mesh in the file's
//! units and double precision.
//!
//! Read as the extension describes: a primitive's triangle `t` takes the group's triangle
//! `mapIndices[t]` (or `t + mapOffset`); `directionBounds` (per vertex bias and scale) move
//! the position and scale the direction before anything is interpolated; the node transform
//! moves positions and turns directions; `primitiveFlags` decimate the edges towards coarser
//! neighbours (see `gridrt_shared::displacement::decimated_point`). Refused by name for now:
//! primitives without `directions` (the vertex normals would stand in), strips and fans,
//! mirroring node transforms, and a scene that mixes displaced and plain primitives.

use std::path::Path;

use gridrt_shared::glam::{DMat4, DVec3};
use serde_json::Value;

use super::gltf::{
    add_primitive, describe, open_document, read_accessor, read_uri, split_file, view_bytes, OpenedGltf,
};
use super::WorldMesh;
use crate::bary::{self, Micromap, MicromapGroup, MicromapTriangle};
use crate::displaced::DisplacedMesh;
use crate::error::{error, fail, Result};
use crate::mesh::frame::LocalFrame;
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;

/// A displaced micro-mesh in the file's units.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DisplacedWorld {
    pub positions: Vec<DVec3>,
    pub directions: Vec<DVec3>,
    pub triangles: Vec<[u32; 3]>,
    /// Triangle `t`'s values displace triangle `t`.
    pub micromap: Micromap,
    /// Per triangle, its `primitiveFlags` (see `DisplacedMesh::decimated_edges`); empty when
    /// no primitive has any.
    pub decimated_edges: Vec<u8>,
}

impl DisplacedWorld {
    /// Appends `other` after this mesh: its vertices, triangles and micromap.
    pub fn append(&mut self, other: &DisplacedWorld) {
        let first = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.directions.extend_from_slice(&other.directions);
        let triangles = self.triangles.len();
        self.triangles
            .extend(other.triangles.iter().map(|t| t.map(|i| i + first)));
        self.micromap.append(&other.micromap);
        self.add_decimated_edges(triangles, &other.decimated_edges);
    }

    /// Flags for the triangles from `first` on (none: all zero), keeping the list empty while
    /// no triangle has any.
    fn add_decimated_edges(&mut self, first: usize, flags: &[u8]) {
        if flags.iter().all(|&f| f == 0) {
            if !self.decimated_edges.is_empty() {
                self.decimated_edges.resize(self.triangles.len(), 0);
            }
            return;
        }
        self.decimated_edges.resize(first, 0);
        self.decimated_edges.extend_from_slice(flags);
        self.decimated_edges.resize(self.triangles.len(), 0);
    }

    /// The mesh in its local frame (centred on its base positions' bounds, scaled by a power
    /// of two; the directions scaled alike), and that frame.
    pub fn into_local(self) -> (DisplacedMesh, LocalFrame) {
        let directions = self.directions;
        let micromap = self.micromap;
        let decimated_edges = self.decimated_edges;
        let (base, frame) = WorldMesh {
            positions: self.positions,
            triangles: self.triangles,
        }
        .into_local();
        let mesh = DisplacedMesh {
            positions: base.positions,
            directions: directions.iter().map(|d| (*d * frame.scale).as_vec3()).collect(),
            triangles: base.triangles,
            micromap,
            decimated_edges,
        };
        (mesh, frame)
    }
}

/// Reads a `.gltf` or `.glb` file's bytes as a displaced micro-mesh; `.bary` files are read
/// from `folder` as buffers are. `Ok(None)` when no primitive is displaced. Errors carry no
/// file name; the caller adds it.
pub fn parse_displaced(bytes: &[u8], folder: Option<&Path>) -> Result<Option<DisplacedWorld>> {
    let (json, bin) = split_file(bytes)?;
    let opened = open_document(json, bin, folder)?;
    let Some(micromaps) = opened.raw.pointer("/extensions/NV_micromaps/micromaps") else {
        return Ok(None);
    };
    let micromaps: Vec<Micromap> = (micromaps.as_array().into_iter().flatten().enumerate())
        .map(|(k, entry)| read_micromap(entry, &opened, folder).map_err(|e| error!(Input, "micromap {k}: {e}")))
        .collect::<Result<_>>()?;
    let nodes: Vec<gltf::Node> = opened.document.nodes().collect();
    let mut out = DisplacedWorld::default();
    for &(n, transform) in &opened.drawn {
        let Some(m) = nodes[n].mesh() else { continue };
        for primitive in m.primitives() {
            let at = format!(
                "/meshes/{}/primitives/{}/extensions/NV_displacement_micromap",
                m.index(),
                primitive.index()
            );
            let Some(extension) = opened.raw.pointer(&at) else {
                fail!(
                    Input,
                    "mesh {} primitive {} is not displaced while others are: gridrt reads one or the other",
                    m.index(),
                    primitive.index()
                );
            };
            let source = Primitive {
                opened: &opened,
                primitive: &primitive,
                extension,
                transform,
                micromaps: &micromaps,
            };
            source
                .append_to(&mut out)
                .map_err(|e| error!(Input, "mesh {} primitive {}: {e}", m.index(), primitive.index()))?;
        }
    }
    Ok(Some(out))
}

/// A micromap's `.bary` bytes, from its `uri` or its `bufferView`, read.
fn read_micromap(entry: &Value, opened: &OpenedGltf, folder: Option<&Path>) -> Result<Micromap> {
    let uri = entry.get("uri").and_then(Value::as_str);
    match (uri, entry.get("bufferView").and_then(Value::as_u64)) {
        (Some(uri), _) => bary::read(&read_uri(uri, folder)?.0),
        (None, Some(v)) => {
            let view = (opened.document.views().nth(v as usize))
                .ok_or_else(|| error!(Input, "its bufferView {v} does not exist"))?;
            bary::read(view_bytes(&view, &opened.buffers)?)
        }
        _ => fail!(Input, "it has neither a uri nor a bufferView"),
    }
}

/// One displaced primitive and what it needs from its file.
struct Primitive<'a> {
    opened: &'a OpenedGltf,
    primitive: &'a gltf::Primitive<'a>,
    extension: &'a Value,
    transform: DMat4,
    micromaps: &'a [Micromap],
}

impl Primitive<'_> {
    fn index(&self, key: &str) -> Option<usize> {
        self.extension.get(key).and_then(Value::as_u64).map(|v| v as usize)
    }

    /// Accessor `key` of the extension, checked to be `dimensions` of FLOAT (or, with
    /// `integers`, of an unsigned integer type), read as `N` components per element.
    fn accessor<const N: usize>(
        &self,
        key: &str,
        dimensions: Dimensions,
        integers: bool,
    ) -> Result<Option<Vec<[f64; N]>>> {
        let Some(a) = self.index(key) else { return Ok(None) };
        let accessor = (self.opened.document.accessors().nth(a))
            .ok_or_else(|| error!(Input, "its {key} accessor {a} does not exist"))?;
        let ty = accessor.data_type();
        let fits = match integers {
            true => matches!(ty, DataType::U8 | DataType::U16 | DataType::U32),
            false => ty == DataType::F32,
        };
        if accessor.dimensions() != dimensions || !fits || accessor.normalized() {
            fail!(Input, "its {key} accessor {a} is {}", describe(&accessor));
        }
        let values = read_accessor::<N>(&accessor, &self.opened.buffers)
            .map_err(|e| error!(Input, "{key} accessor {a}: {e}"))?;
        Ok(Some(values))
    }

    fn append_to(&self, out: &mut DisplacedWorld) -> Result<()> {
        if self.primitive.mode() != Mode::Triangles {
            fail!(
                Input,
                "displaced strips and fans are not supported: write a triangle list"
            );
        }
        if self.transform.determinant() < 0.0 {
            fail!(
                Input,
                "its node transform mirrors it, which displaced primitives do not support yet"
            );
        }
        let directions = self
            .accessor::<3>("directions", Dimensions::Vec3, false)?
            .ok_or_else(|| {
                error!(
                    Input,
                    "it has no directions accessor (vertex normals as directions are not supported yet)"
                )
            })?;
        let flags = self.primitive_flags()?;
        let mut base = WorldMesh::default();
        add_primitive(&mut base, self.primitive, &DMat4::IDENTITY, &self.opened.buffers)?;
        if directions.len() != base.positions.len() {
            fail!(
                Input,
                "{} directions for {} positions",
                directions.len(),
                base.positions.len()
            );
        }
        let mut positions = base.positions;
        let mut directions: Vec<DVec3> = directions.into_iter().map(DVec3::from_array).collect();
        if let Some(bounds) = self.accessor::<2>("directionBounds", Dimensions::Vec2, false)? {
            if bounds.len() != positions.len() {
                fail!(
                    Input,
                    "{} direction bounds for {} positions",
                    bounds.len(),
                    positions.len()
                );
            }
            for ((p, d), [bias, scale]) in positions.iter_mut().zip(&mut directions).zip(bounds) {
                *p += *d * bias;
                *d *= scale;
            }
        }
        let first_vertex = out.positions.len() as u32;
        out.positions
            .extend(positions.iter().map(|&p| self.transform.transform_point3(p)));
        out.directions
            .extend(directions.iter().map(|&d| self.transform.transform_vector3(d)));
        let first_triangle = out.triangles.len();
        out.triangles
            .extend(base.triangles.iter().map(|t| t.map(|i| first_vertex + i)));
        if flags.as_ref().is_some_and(|f| f.len() != base.triangles.len()) {
            fail!(
                Input,
                "its primitiveFlags hold {} flags for {} triangles",
                flags.as_ref().map_or(0, Vec::len),
                base.triangles.len()
            );
        }
        out.add_decimated_edges(first_triangle, &flags.unwrap_or_default());
        self.append_values(base.triangles.len(), &mut out.micromap)
    }

    /// The `primitiveFlags` accessor: one unsigned byte per triangle, bit `e` set when the
    /// neighbour across edge `e` is a level coarser.
    fn primitive_flags(&self) -> Result<Option<Vec<u8>>> {
        let Some(flags) = self.accessor::<1>("primitiveFlags", Dimensions::Scalar, true)? else {
            return Ok(None);
        };
        if let Some(&[bad]) = flags.iter().find(|&&[f]| f > 255.0) {
            fail!(Input, "its primitiveFlags hold {bad}, more than a byte");
        }
        Ok(Some(flags.iter().map(|&[f]| f as u8).collect()))
    }

    /// Each of the primitive's `count` triangles' values, taken from its micromap group.
    fn append_values(&self, count: usize, out: &mut Micromap) -> Result<()> {
        let k = self
            .index("micromap")
            .ok_or_else(|| error!(Input, "its extension names no micromap"))?;
        let map = self
            .micromaps
            .get(k)
            .ok_or_else(|| error!(Input, "micromap {k} does not exist"))?;
        let g = self.index("groupIndex").unwrap_or(0);
        let group = map
            .groups
            .get(g)
            .ok_or_else(|| error!(Input, "micromap {k} has no group {g}"))?;
        let offset = self.index("mapOffset").unwrap_or(0);
        let mapping = self.accessor::<1>("mapIndices", Dimensions::Scalar, true)?;
        if mapping.as_ref().is_some_and(|m| m.len() < count) {
            fail!(Input, "its mapIndices hold fewer than its {count} triangles");
        }
        // A compressed code describes each triangle's values on their own (the grids'
        // layout checks them against it), so it holds for any selection of them.
        out.join_value_code(map.value_code);
        out.groups.push(MicromapGroup {
            triangle_first: out.triangles.len() as u32,
            triangle_count: count as u32,
            bias: group.bias,
            scale: group.scale,
        });
        for t in 0..count {
            let within = match &mapping {
                Some(m) => m[t][0] as usize,
                None => t + offset,
            };
            if within >= group.triangle_count as usize {
                fail!(
                    Input,
                    "triangle {t} takes micromap triangle {within} of a group of {}",
                    group.triangle_count
                );
            }
            let source = group.triangle_first as usize + within;
            out.triangles.push(MicromapTriangle {
                level: map.triangles[source].level,
                first_value: out.values.len() as u32,
            });
            out.values.extend_from_slice(map.triangle_values(source));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bary::values_per_triangle;
    use gridrt_shared::glam::Vec3;

    fn sample() -> DisplacedMesh {
        let values = |seed: u16, level| {
            (0..values_per_triangle(level) as u16)
                .map(|k| (k * 90 + seed) % 2048)
                .collect()
        };
        DisplacedMesh {
            positions: vec![
                Vec3::new(-0.5, -0.5, 0.0),
                Vec3::new(0.5, -0.5, 0.0),
                Vec3::new(0.0, 0.5, 0.25),
                Vec3::new(0.6, 0.6, 0.1),
            ],
            directions: vec![Vec3::Z, Vec3::new(0.0, 0.1, 1.0), Vec3::new(0.1, 0.0, 1.0), Vec3::Z],
            triangles: vec![[0, 1, 2], [1, 3, 2]],
            micromap: Micromap::from_triangles(-0.01, 0.02, &[(2, values(0, 2)), (1, values(7, 1))]),
            decimated_edges: vec![0b010, 0],
        }
    }

    /// gridrt's writer's files read back as the same mesh, in the input's units.
    #[test]
    fn written_files_read_back_as_written() {
        let mesh = sample();
        let (path, frame) = crate::micromesh_gltf::write_far_from_origin(&mesh, "gltf-micromap");
        let dir = path.parent().unwrap();
        let read = parse_displaced(&std::fs::read(&path).unwrap(), Some(dir))
            .unwrap()
            .unwrap();
        assert_eq!(read.micromap, mesh.micromap);
        assert_eq!(read.triangles, mesh.triangles);
        assert_eq!(read.decimated_edges, mesh.decimated_edges);
        let world: Vec<DVec3> = mesh.positions.iter().map(|&p| frame.to_world(p)).collect();
        assert_eq!(read.positions, world);
        let directions: Vec<DVec3> = mesh.directions.iter().map(|d| d.as_dvec3() / frame.scale).collect();
        assert_eq!(read.directions, directions);
        // Back in a local frame, it decodes.
        let (local, _) = read.into_local();
        local.check().unwrap();
        assert_eq!(local.decoded().triangles.len(), 16 + 4);
    }

    /// A micro-mesh of compressed values reads back with their code, so its grids store them
    /// compressed; read twice side by side it keeps the code, beside a plain copy it does not.
    #[test]
    fn a_value_code_reads_back() {
        let mut mesh = sample();
        let values = mesh.micromap.triangle_values(0).to_vec();
        mesh.micromap = Micromap::from_triangles(-0.01, 0.02, &[(2, values.clone()), (2, values)]);
        mesh.decimated_edges.clear();
        let options = crate::grid::compressed::ValueCompression::bounded(1e-2);
        let compressed = crate::grid::compressed::compress(&mesh, &options).unwrap();
        let (path, _) = crate::micromesh_gltf::write_far_from_origin(&compressed.mesh, "gltf-value-code");
        let bytes = std::fs::read(&path).unwrap();
        let read = parse_displaced(&bytes, path.parent()).unwrap().unwrap();
        assert_eq!(read.micromap, compressed.mesh.micromap);
        assert_eq!(read.micromap.value_code, Some(compressed.code));
        let mut twice = read.clone();
        twice.append(&read);
        assert_eq!(twice.micromap.value_code, Some(compressed.code));
        let (local, _) = twice.into_local();
        let grids = crate::grid::displaced::build(&local, &crate::grid::GridOptions::for_displaced()).unwrap();
        assert_eq!(grids.params.displaced, gridrt_shared::layout::DISPLACED_COMPRESSED);
        let mut plain = read.clone();
        plain.micromap.value_code = None;
        let mut mixed = read.clone();
        mixed.append(&plain);
        assert_eq!(mixed.micromap.value_code, None);
    }

    /// A GLB laid out by hand: the micromap in a bufferView, its triangles taken in reverse
    /// through mapIndices from group 1, direction bounds moving positions and scaling
    /// directions.
    #[test]
    fn another_tools_layout_reads() {
        let level = 1;
        let value = |t: u16| vec![t * 100; values_per_triangle(level)];
        let mut map = Micromap::from_triangles(0.0, 1.0, &[(level, value(9))]);
        let second = Micromap::from_triangles(0.5, 2.0, &[(level, value(1)), (level, value(2))]);
        map.groups.push(MicromapGroup {
            triangle_first: 1,
            ..second.groups[0]
        });
        for t in &second.triangles {
            map.triangles.push(MicromapTriangle {
                level: t.level,
                first_value: map.values.len() as u32 + t.first_value,
            });
        }
        map.values.extend(&second.values);
        let bary = bary::write(&map);
        let floats = |v: &[f32]| v.iter().flat_map(|f| f.to_le_bytes()).collect::<Vec<u8>>();
        let mut bin = floats(&[0., 0., 0., 1., 0., 0., 0., 1., 0., 1., 1., 0.]); // 48: positions
        bin.extend(floats(&[0., 0., 1.].repeat(4))); // 48: directions
        bin.extend(floats(&[0.5, 2.0].repeat(4))); // 32: bounds
        bin.extend([0u32, 1, 2, 1, 3, 2, 1, 0].iter().flat_map(|i| i.to_le_bytes())); // 24 + 8: indices, map
        let bary_at = bin.len();
        bin.extend(&bary);
        let json = serde_json::json!({
            "asset": {"version": "2.0"},
            "extensionsUsed": ["NV_micromaps", "NV_displacement_micromap"],
            "extensions": {"NV_micromaps": {"micromaps": [{"bufferView": 5, "mimeType": "model/vnd.bary"}]}},
            "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0, "translation": [10, 0, 0]}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 3, "extensions": {
                "NV_displacement_micromap": {"micromap": 0, "groupIndex": 1, "directions": 1,
                    "directionBounds": 2, "mapIndices": 4}}}]}],
            "buffers": [{"byteLength": bin.len()}],
            "bufferViews": [
                {"buffer": 0, "byteOffset": 0, "byteLength": 48},
                {"buffer": 0, "byteOffset": 48, "byteLength": 48},
                {"buffer": 0, "byteOffset": 96, "byteLength": 32},
                {"buffer": 0, "byteOffset": 128, "byteLength": 24},
                {"buffer": 0, "byteOffset": 152, "byteLength": 8},
                {"buffer": 0, "byteOffset": bary_at, "byteLength": bary.len()},
            ],
            "accessors": [
                {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
                {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
                {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
                {"bufferView": 3, "componentType": 5125, "count": 6, "type": "SCALAR"},
                {"bufferView": 4, "componentType": 5125, "count": 2, "type": "SCALAR"},
            ],
        });
        let glb = crate::mesh::gltf::glb_container(&serde_json::to_vec(&json).unwrap(), &bin);
        let read = parse_displaced(&glb, None).unwrap().unwrap();
        // Bounds: bias 0.5 along +z, scale 2; then the node's translation.
        assert_eq!(read.positions[3], DVec3::new(11.0, 1.0, 0.5));
        assert_eq!(read.directions[0], DVec3::new(0.0, 0.0, 2.0));
        // mapIndices [1, 0] in group 1: triangle 0 takes the group's second (values 200).
        assert_eq!(read.micromap.triangle_values(0)[0], 200);
        assert_eq!(read.micromap.triangle_values(1)[0], 100);
        assert_eq!(
            (read.micromap.groups[0].bias, read.micromap.groups[0].scale),
            (0.5, 2.0)
        );
    }
}
