//! Displaced micro-meshes in glTF: NVIDIA's draft extensions `NV_micromaps` (the file's
//! micromaps, each a `.bary` by `uri` or in a `bufferView`) and `NV_displacement_micromap` (on a
//! triangle primitive: which micromap and group, which of its triangles each primitive
//! triangle takes, and the per-vertex `directions`), read into one displaced mesh in the file's
//! units and double precision.
//!
//! Read as the extension describes: a primitive's triangle `t` takes the group's triangle
//! `mapIndices[t] + mapOffset` (or `t + mapOffset`); `directionBounds` (per vertex bias and
//! scale) move the position and scale the direction before anything is interpolated; the
//! node transform moves positions and turns directions; `primitiveFlags` decimate the edges
//! towards coarser neighbours (see `gridrt_shared::displacement::decimated_point`). Where a
//! primitive has no accessor of its own for the directions, bounds, mapping or flags, those
//! the `.bary` carries hold (from the extension's `*Offset`), and directions default to the
//! vertex normals last. Directions and bounds may be half floats (component type 5131, which
//! the extension adds), directions `VEC3` or `VEC4`. Refused by name for now: strips and
//! fans, mirroring node transforms, and a scene that mixes displaced and plain primitives.

use std::path::Path;

use gridrt_shared::glam::{DMat4, DVec3};
use serde_json::Value;

use crate::error::{error, fail, Result};
use crate::mesh::frame::LocalFrame;
use crate::mesh::gltf::{
    add_primitive, check_drawn_size, describe, open_document, read_accessor, read_uri, split_file, view_bytes,
    OpenedGltf,
};
use crate::mesh::WorldMesh;
use crate::micromesh::bary::{self, MeshProperties, Micromap, MicromapGroup, MicromapTriangle};
use crate::micromesh::DisplacedMesh;
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
    /// Where the file is read otherwise than it may mean, one line each (a default taken for
    /// what it leaves out); a caller shows them.
    pub warnings: Vec<String>,
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
        for warning in &other.warnings {
            self.warn(warning);
        }
    }

    /// Adds `warning`, once.
    fn warn(&mut self, warning: &str) {
        if !self.warnings.iter().any(|w| w == warning) {
            self.warnings.push(warning.to_string());
        }
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
        if let Some((m, p)) = first_displaced_primitive(&opened.raw) {
            fail!(
                Input,
                "mesh {m} primitive {p} is displaced (NV_displacement_micromap) but the file lists no micromaps \
                 (no NV_micromaps at its root): its values are missing"
            );
        }
        return Ok(None);
    };
    let micromaps: Vec<(Micromap, MeshProperties)> = (micromaps.as_array().into_iter().flatten().enumerate())
        .map(|(k, entry)| read_micromap(entry, &opened, folder).map_err(|e| error!(Input, "micromap {k}: {e}")))
        .collect::<Result<_>>()?;
    check_drawn_size(
        &opened,
        |mesh, primitive| {
            let at = format!(
                "/meshes/{mesh}/primitives/{}/extensions/NV_displacement_micromap/micromap",
                primitive.index()
            );
            let map = opened.raw.pointer(&at).and_then(Value::as_u64);
            map.and_then(|k| micromaps.get(k as usize))
                .map_or(1.0, |(m, _)| mean_micro_triangles(m))
        },
        crate::limits::DECODED_BYTES_PER_MICRO_TRIANGLE,
        "micro-triangles",
    )?;
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

/// Micro-triangles per triangle of `micromap`, on average over its triangles.
fn mean_micro_triangles(micromap: &Micromap) -> f64 {
    let all: f64 = micromap.triangles.iter().map(|t| 4f64.powi(t.level as i32)).sum();
    all / micromap.triangles.len().max(1) as f64
}

/// The first primitive, as (mesh, primitive), that carries `NV_displacement_micromap`.
fn first_displaced_primitive(raw: &Value) -> Option<(usize, usize)> {
    let meshes = raw.get("meshes")?.as_array()?;
    meshes.iter().enumerate().find_map(|(m, mesh)| {
        let primitives = mesh.get("primitives")?.as_array()?;
        let p = primitives
            .iter()
            .position(|p| p.pointer("/extensions/NV_displacement_micromap").is_some())?;
        Some((m, p))
    })
}

/// A micromap's `.bary` bytes, from its `uri` or its `bufferView`, read with the mesh
/// properties it carries.
fn read_micromap(entry: &Value, opened: &OpenedGltf, folder: Option<&Path>) -> Result<(Micromap, MeshProperties)> {
    let uri = entry.get("uri").and_then(Value::as_str);
    match (uri, entry.get("bufferView").and_then(Value::as_u64)) {
        (Some(uri), _) => {
            let (bytes, source) = read_uri(uri, folder)?;
            bary::read_with_mesh(&bytes).map_err(|e| e.prefixed(source))
        }
        (None, Some(v)) => {
            let view = (opened.document.views().nth(v as usize))
                .ok_or_else(|| error!(Input, "its bufferView {v} does not exist"))?;
            bary::read_with_mesh(view_bytes(&view, &opened.buffers)?)
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
    micromaps: &'a [(Micromap, MeshProperties)],
}

impl Primitive<'_> {
    fn index(&self, key: &str) -> Option<usize> {
        self.extension.get(key).and_then(Value::as_u64).map(|v| v as usize)
    }

    /// The micromap the extension names, and its mesh properties.
    fn micromap(&self) -> Result<&(Micromap, MeshProperties)> {
        let k = self
            .index("micromap")
            .ok_or_else(|| error!(Input, "its extension names no micromap"))?;
        self.micromaps
            .get(k)
            .ok_or_else(|| error!(Input, "micromap {k} does not exist"))
    }

    /// The extension's accessor `key`, if it names one.
    fn accessor_of(&self, key: &str) -> Result<Option<(gltf::Accessor<'_>, bool)>> {
        let Some(a) = self.index(key) else { return Ok(None) };
        let accessor = (self.opened.document.accessors().nth(a))
            .ok_or_else(|| error!(Input, "its {key} accessor {a} does not exist"))?;
        Ok(Some((accessor, self.opened.half_floats.contains(&a))))
    }

    /// Accessor `key` of the extension, checked to be `dimensions` of unsigned integers.
    fn integers(&self, key: &str) -> Result<Option<Vec<u64>>> {
        let Some((accessor, half)) = self.accessor_of(key)? else {
            return Ok(None);
        };
        let integer = matches!(accessor.data_type(), DataType::U8 | DataType::U16 | DataType::U32);
        if accessor.dimensions() != Dimensions::Scalar || !integer || half || accessor.normalized() {
            let what = if half {
                "of half floats".into()
            } else {
                describe(&accessor)
            };
            fail!(Input, "its {key} accessor {} is {what}", accessor.index());
        }
        let values = read_accessor::<1>(&accessor, &self.opened.buffers)
            .map_err(|e| error!(Input, "{key} accessor {}: {e}", accessor.index()))?;
        Ok(Some(values.iter().map(|&[v]| v as u64).collect()))
    }

    /// Accessor `key` of the extension, checked to be one of `dimensions` of floats or half
    /// floats, each element's first `N` components.
    fn floats<const N: usize>(&self, key: &str, dimensions: &[Dimensions]) -> Result<Option<Vec<[f64; N]>>> {
        let Some((accessor, half)) = self.accessor_of(key)? else {
            return Ok(None);
        };
        let float = half || accessor.data_type() == DataType::F32;
        if !dimensions.contains(&accessor.dimensions()) || !float || accessor.normalized() {
            fail!(
                Input,
                "its {key} accessor {} is {}",
                accessor.index(),
                describe(&accessor)
            );
        }
        let widened = match accessor.dimensions() {
            Dimensions::Vec2 => widen(read_accessor::<2>(&accessor, &self.opened.buffers)),
            Dimensions::Vec3 => widen(read_accessor::<3>(&accessor, &self.opened.buffers)),
            _ => widen(read_accessor::<4>(&accessor, &self.opened.buffers)),
        }
        .map_err(|e| error!(Input, "{key} accessor {}: {e}", accessor.index()))?;
        let value = |x: f64| match half {
            true => half::f16::from_bits(x as u16).to_f64(),
            false => x,
        };
        Ok(Some(
            widened.iter().map(|e| std::array::from_fn(|c| value(e[c]))).collect(),
        ))
    }

    /// The primitive's own elements (`own`, read from an accessor of the extension), else
    /// `count` elements of the micromap's mesh property that `property` picks, from the element
    /// the extension's `offset_key` names (0 by default), each made one of the primitive's by
    /// `convert`; `None` where neither has them.
    fn own_or_micromaps<T, U>(
        &self,
        own: Option<Vec<U>>,
        (property, offset_key): (impl Fn(&MeshProperties) -> Option<&Vec<T>>, &str),
        count: usize,
        convert: impl Fn(&T) -> U,
    ) -> Result<Option<Vec<U>>> {
        if own.is_some() {
            return Ok(own);
        }
        let Some(all) = property(&self.micromap()?.1) else {
            return Ok(None);
        };
        let first = self.index(offset_key).unwrap_or(0);
        match all.get(first..first.saturating_add(count)) {
            Some(some) => Ok(Some(some.iter().map(convert).collect())),
            None => fail!(
                Input,
                "its micromap holds {} elements where its {offset_key} of {first} needs {count}",
                all.len()
            ),
        }
    }

    fn append_to(&self, out: &mut DisplacedWorld) -> Result<()> {
        match self.primitive.mode() {
            Mode::Triangles => {}
            Mode::TriangleStrip | Mode::TriangleFan => fail!(
                Input,
                "displaced strips and fans are not supported: write a triangle list"
            ),
            mode => fail!(
                Input,
                "it is drawn as {mode:?} (mode {}), but a micromap displaces triangles alone",
                mode.as_gl_enum()
            ),
        }
        if self.transform.determinant() < 0.0 {
            fail!(
                Input,
                "its node transform mirrors it, which displaced primitives do not support yet"
            );
        }
        let mut base = WorldMesh::default();
        add_primitive(&mut base, self.primitive, &DMat4::IDENTITY, &self.opened.buffers)?;
        let flags = self.primitive_flags(base.triangles.len())?;
        let mut positions = base.positions;
        let (mut directions, from_normals) = self.directions(positions.len())?;
        if from_normals {
            out.warn(
                "a displaced primitive has no directions (no accessor, none in its micromap): its vertex normals \
                 displace it, as the extension allows; if it was baked along other directions it renders off",
            );
        }
        if let Some(bounds) = self.direction_bounds(positions.len())? {
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
        out.add_decimated_edges(first_triangle, &flags.unwrap_or_default());
        self.append_values(base.triangles.len(), &mut out.micromap)
    }

    /// Each of the primitive's `vertices` vertices' direction: from the `directions`
    /// accessor, else from the micromap's, else the vertex normals, as the extension says.
    /// The directions, and whether they are the vertex normals the extension falls back on.
    fn directions(&self, vertices: usize) -> Result<(Vec<DVec3>, bool)> {
        let found = self.own_or_micromaps(
            self.floats::<3>("directions", &[Dimensions::Vec3, Dimensions::Vec4])?,
            (|m| m.directions.as_ref(), "directionsOffset"),
            vertices,
            |d| d.map(f64::from),
        )?;
        let from_normals = found.is_none();
        let directions = match found {
            Some(d) => d,
            None => self.normals()?.ok_or_else(|| {
                error!(
                    Input,
                    "it has no directions: no directions accessor, none in its micromap, and no vertex normals"
                )
            })?,
        };
        if directions.len() != vertices {
            fail!(Input, "{} directions for {vertices} positions", directions.len());
        }
        Ok((directions.into_iter().map(DVec3::from_array).collect(), from_normals))
    }

    /// The primitive's `NORMAL` attribute, which directions default to.
    fn normals(&self) -> Result<Option<Vec<[f64; 3]>>> {
        let Some(accessor) = self.primitive.get(&gltf::Semantic::Normals) else {
            return Ok(None);
        };
        let a = accessor.index();
        if accessor.dimensions() != Dimensions::Vec3 || accessor.data_type() != DataType::F32 || accessor.normalized() {
            fail!(
                Input,
                "its NORMAL accessor {a}, which its directions default to, is {}",
                describe(&accessor)
            );
        }
        let normals = read_accessor::<3>(&accessor, &self.opened.buffers)
            .map_err(|e| error!(Input, "NORMAL accessor {a}: {e}"))?;
        Ok(Some(normals))
    }

    /// Each vertex's bias and scale: from the `directionBounds` accessor, else from the
    /// micromap's; none when neither has them.
    fn direction_bounds(&self, vertices: usize) -> Result<Option<Vec<[f64; 2]>>> {
        let Some(bounds) = self.own_or_micromaps(
            self.floats::<2>("directionBounds", &[Dimensions::Vec2])?,
            (|m| m.direction_bounds.as_ref(), "directionBoundsOffset"),
            vertices,
            |b| b.map(f64::from),
        )?
        else {
            return Ok(None);
        };
        if bounds.len() != vertices {
            fail!(Input, "{} direction bounds for {vertices} positions", bounds.len());
        }
        Ok(Some(bounds))
    }

    /// Each of the primitive's `count` triangles' flags (bit `e` set when the neighbour
    /// across edge `e` is a level coarser): from the `primitiveFlags` accessor, else from the
    /// micromap's.
    fn primitive_flags(&self, count: usize) -> Result<Option<Vec<u8>>> {
        let Some(flags) = self.own_or_micromaps(
            self.integers("primitiveFlags")?,
            (|m| m.triangle_flags.as_ref(), "primitiveFlagsOffset"),
            count,
            |&f| f as u64,
        )?
        else {
            return Ok(None);
        };
        if flags.len() != count {
            fail!(
                Input,
                "its primitiveFlags hold {} flags for {count} triangles",
                flags.len()
            );
        }
        if let Some(bad) = flags.iter().find(|&&f| f > 255) {
            fail!(Input, "its primitiveFlags hold {bad}, more than a byte");
        }
        Ok(Some(flags.iter().map(|&f| f as u8).collect()))
    }

    /// Each of the primitive's `count` triangles' triangle within its group, before
    /// `mapOffset`: from the `mapIndices` accessor, else from the micromap's mappings; none
    /// (the triangle's own index) when neither has them.
    fn mapping(&self, count: usize) -> Result<Option<Vec<u64>>> {
        let Some(mapping) = self.own_or_micromaps(
            self.integers("mapIndices")?,
            (|m| m.triangle_mappings.as_ref(), "mapIndicesOffset"),
            count,
            |&m| m as u64,
        )?
        else {
            return Ok(None);
        };
        if mapping.len() < count {
            fail!(Input, "its mapIndices hold fewer than its {count} triangles");
        }
        Ok(Some(mapping))
    }

    /// Each of the primitive's `count` triangles' values, taken from its micromap group.
    fn append_values(&self, count: usize, out: &mut Micromap) -> Result<()> {
        let map = &self.micromap()?.0;
        let g = self.index("groupIndex").unwrap_or(0);
        let group = map.groups.get(g).ok_or_else(|| {
            error!(
                Input,
                "micromap {} has no group {g}",
                self.index("micromap").unwrap_or(0)
            )
        })?;
        let offset = self.index("mapOffset").unwrap_or(0);
        let mapping = self.mapping(count)?;
        // A compressed code or NVIDIA's blocks describe each triangle's values on their own
        // (the grids' layout and the writer check them), so they hold for any selection.
        out.join_storage(map);
        out.groups.push(MicromapGroup {
            triangle_first: out.triangles.len() as u32,
            triangle_count: count as u32,
            bias: group.bias,
            scale: group.scale,
        });
        for t in 0..count {
            // The offset applies to mapped triangles too.
            let within = match &mapping {
                Some(m) => (m[t] as usize).saturating_add(offset),
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

/// Elements of fewer components padded to four with zeros.
fn widen<const M: usize>(values: Result<Vec<[f64; M]>>) -> Result<Vec<[f64; 4]>> {
    Ok(values?
        .iter()
        .map(|e| std::array::from_fn(|c| e.get(c).copied().unwrap_or(0.0)))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::micromesh::bary::values_per_triangle;
    use gridrt_shared::displacement::u_major_index;
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
        let (path, frame) = crate::micromesh::gltf::write_far_from_origin(&mesh, "gltf-micromap");
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
        let (path, _) = crate::micromesh::gltf::write_far_from_origin(&compressed.mesh, "gltf-value-code");
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

    /// A micro-mesh of values in NVIDIA's blocks reads back with them, through the glTF's
    /// group and triangle selection; beside plain values it is no longer in blocks.
    #[test]
    fn values_in_blocks_read_back() {
        let mesh = sample();
        let mesh = mesh.in_nv_blocks().0;
        let (path, _) = crate::micromesh::gltf::write_far_from_origin(&mesh, "gltf-nv-blocks");
        let bytes = std::fs::read(&path).unwrap();
        let read = parse_displaced(&bytes, path.parent()).unwrap().unwrap();
        assert_eq!(read.micromap, mesh.micromap);
        assert!(read.micromap.nv_blocks);
        let mut plain = read.clone();
        plain.micromap.nv_blocks = false;
        let mut mixed = read.clone();
        mixed.append(&plain);
        assert!(!mixed.micromap.nv_blocks);
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

    /// A `.bary` laid out by hand from the BaryFile headers: its properties (identifier and
    /// bytes) after the header and the property table.
    fn hand_bary(properties: &[([u32; 4], Vec<u8>)]) -> Vec<u8> {
        let table = 64 * properties.len();
        let mut payload = Vec::new();
        let mut entries = Vec::new();
        for (id, bytes) in properties {
            let at = 40 + table + payload.len();
            entries.extend(id.iter().flat_map(|w| w.to_le_bytes()));
            entries.extend((at as u64).to_le_bytes());
            entries.extend((bytes.len() as u64).to_le_bytes());
            entries.extend([0u8; 32]);
            payload.extend(bytes);
            payload.resize(payload.len().next_multiple_of(4), 0);
        }
        let mut file = bary::MAGIC.to_vec();
        file.extend(((40 + table + payload.len()) as u64).to_le_bytes());
        file.extend(40u64.to_le_bytes());
        file.extend((table as u64).to_le_bytes());
        file.extend(entries);
        file.extend(payload);
        file
    }

    fn words(w: &[u32]) -> Vec<u8> {
        w.iter().flat_map(|x| x.to_le_bytes()).collect()
    }

    fn floats(v: &[f32]) -> Vec<u8> {
        v.iter().flat_map(|x| x.to_le_bytes()).collect()
    }

    /// Two level-1 triangles of values one to two bytes (`eR11_unorm_pack16`), u-major:
    /// triangle `t`'s values are `100 * (t + 1) + k`.
    fn two_triangle_properties() -> Vec<([u32; 4], Vec<u8>)> {
        let mut values = words(&[1_000_397_001, 1, 1, 12, 2, 4]);
        values.extend((0..12u16).flat_map(|k| (100 * (k / 6 + 1) + k % 6).to_le_bytes()));
        let mut group = words(&[0, 2, 0, 12, 1, 1]);
        group.extend(floats(&[0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0]));
        let triangles = words(&[0, 1, 6, 1]);
        vec![
            ([0xb44d_aa04, 0xc9e0_44d5, 0x9a94_4de0, 0xcfd8_fe35], values),
            ([0x39ee_40d0, 0x9dc4_4517, 0x8e5a_b15d, 0xb09c_74bc], group),
            ([0x0045_8e68, 0xee59_426c, 0xb3bf_1b7f, 0x749d_eb8e], triangles),
        ]
    }

    /// A GLB of a unit square in two triangles (with `normals`, vertex normals +z), displaced
    /// by `bary` with `extension`'s settings; `extra` bytes follow the square's for accessors
    /// 3 on (`accessors`, their views in `views`).
    fn square_glb(bary: &[u8], extension: Value, extra: (&[u8], Value, Value), normals: bool) -> Vec<u8> {
        let mut bin = floats(&[0., 0., 0., 1., 0., 0., 0., 1., 0., 1., 1., 0.]); // 48: positions
        bin.extend(floats(&[0., 0., 1.].repeat(4))); // 48: normals
        bin.extend(words(&[0, 1, 2, 1, 3, 2])); // 24: indices
        let (extra_bytes, accessors, views) = extra;
        bin.extend(extra_bytes);
        let bary_at = bin.len();
        bin.extend(bary);
        let mut all_views = vec![
            serde_json::json!({"buffer": 0, "byteOffset": 0, "byteLength": 48}),
            serde_json::json!({"buffer": 0, "byteOffset": 48, "byteLength": 48}),
            serde_json::json!({"buffer": 0, "byteOffset": 96, "byteLength": 24}),
        ];
        all_views.extend(views.as_array().unwrap().iter().cloned());
        let micromap_view = all_views.len();
        all_views.push(serde_json::json!({"buffer": 0, "byteOffset": bary_at, "byteLength": bary.len()}));
        let mut all_accessors = vec![
            serde_json::json!({"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}),
            serde_json::json!({"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"}),
            serde_json::json!({"bufferView": 2, "componentType": 5125, "count": 6, "type": "SCALAR"}),
        ];
        all_accessors.extend(accessors.as_array().unwrap().iter().cloned());
        let attributes = match normals {
            true => serde_json::json!({"POSITION": 0, "NORMAL": 1}),
            false => serde_json::json!({"POSITION": 0}),
        };
        let json = serde_json::json!({
            "asset": {"version": "2.0"},
            "extensionsUsed": ["NV_micromaps", "NV_displacement_micromap"],
            "extensions": {"NV_micromaps": {"micromaps": [{"bufferView": micromap_view, "mimeType": "model/vnd.bary"}]}},
            "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": attributes, "indices": 2,
                "extensions": {"NV_displacement_micromap": extension}}]}],
            "buffers": [{"byteLength": bin.len()}],
            "bufferViews": all_views,
            "accessors": all_accessors,
        });
        crate::mesh::gltf::glb_container(&serde_json::to_vec(&json).unwrap(), &bin)
    }

    /// A micro-mesh laid out as NVlabs' micromesh-tools writes one: a `.gltf` beside its
    /// `.bin` and `.bary`; 11-bit values packed per triangle into whole words, with counts and
    /// offsets in bytes and five bytes of slack after them; a property of per-triangle
    /// minima and maxima no reader needs; no histograms; `u8` primitive flags and a buffer
    /// view of levels no accessor uses; the odd points of a decimated edge holding 0. A
    /// level-2 triangle decimates its edge towards a level-1 one: the values read as written,
    /// and the seam is closed.
    #[test]
    fn a_file_laid_out_as_micromesh_tools_writes_one_reads() {
        let (levels, flags) = ([2u32, 1], [0b010u8, 0]);
        let value = |t: usize, k: usize| (300 + 7 * k + 500 * t) as u16;
        let mut values: Vec<Vec<u16>> = (0..2)
            .map(|t| (0..values_per_triangle(levels[t])).map(|k| value(t, k)).collect())
            .collect();
        // Triangle 0's edge 1 (`u + v = 4`, from base vertex 1 to 2) is triangle 1's edge 0
        // (`v = 0`, from base vertex 2 to 1): the finer side's odd points are unused (0), the
        // rest hold the coarser side's values.
        let coarse = |u: u32| values[1][u_major_index([u, 0], 2) as usize];
        let seam = [
            ([4, 0], coarse(2)),
            ([3, 1], 0),
            ([2, 2], coarse(1)),
            ([1, 3], 0),
            ([0, 4], coarse(0)),
        ];
        for (p, q) in seam {
            values[0][u_major_index(p, 4) as usize] = q;
        }
        let (mut packed, mut triangles) = (Vec::new(), Vec::new());
        for (t, v) in values.iter().enumerate() {
            triangles.extend(words(&[packed.len() as u32 * 4]));
            triangles.extend((levels[t] as u16).to_le_bytes());
            triangles.extend(0u16.to_le_bytes());
            let mut bits = crate::bit_writer::BitWriter::default();
            v.iter().for_each(|&q| bits.push(q as u32, 11));
            packed.extend(bits.words.iter().take((v.len() * 11).div_ceil(32)));
        }
        let bytes = packed.len() as u32 * 4;
        let mut values_property = words(&[1_000_397_002, 1, 1, bytes, 1, 4]);
        values_property.extend(words(&packed));
        values_property.extend([0u8; 5]);
        let mut group = words(&[0, 2, 0, bytes, 1, 2]);
        group.extend(floats(&[0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0]));
        let mut minima_maxima = words(&[1_000_397_001, 4, 2, 4]);
        minima_maxima.extend([0u16, 2047, 0, 2047].iter().flat_map(|q| q.to_le_bytes()));
        let bary = hand_bary(&[
            ([0xb44d_aa04, 0xc9e0_44d5, 0x9a94_4de0, 0xcfd8_fe35], values_property),
            ([0x39ee_40d0, 0x9dc4_4517, 0x8e5a_b15d, 0xb09c_74bc], group),
            ([0x0045_8e68, 0xee59_426c, 0xb3bf_1b7f, 0x749d_eb8e], triangles),
            ([0x1111_2222, 0x3333_4444, 0x5555_6666, 0x7777_8888], minima_maxima),
        ]);
        let mut bin = words(&[0, 1, 2, 2, 1, 3]); // 24: indices
        bin.extend(floats(&[0., 0., 0., 1., 0., 0., 0., 1., 0., 1., 1., 0.])); // 48: positions
        bin.extend(floats(&[0., 0., 0.5].repeat(4))); // 48: directions
        bin.extend(levels.map(|l| l as u8)); // 2: levels, unused
        bin.extend(flags); // 2: primitive flags
        let json = serde_json::json!({
            "asset": {"version": "2.0"},
            "extensionsUsed": ["NV_micromaps", "NV_displacement_micromap"],
            "extensions": {"NV_micromaps": {"micromaps": [{"uri": "base_mesh.bary"}]}},
            "buffers": [{"byteLength": bin.len(), "uri": "base_mesh.bin"}],
            "bufferViews": [
                {"name": "indices", "buffer": 0, "byteOffset": 0, "byteLength": 24, "target": 34963},
                {"name": "positions", "buffer": 0, "byteOffset": 24, "byteLength": 48, "target": 34962},
                {"name": "directions", "buffer": 0, "byteOffset": 72, "byteLength": 48, "target": 34962},
                {"name": "subdivision_levels", "buffer": 0, "byteOffset": 120, "byteLength": 2, "target": 34962},
                {"name": "topology_flags", "buffer": 0, "byteOffset": 122, "byteLength": 2, "target": 34962},
            ],
            "accessors": [
                {"bufferView": 0, "componentType": 5125, "count": 6, "type": "SCALAR"},
                {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
                {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC3"},
                {"bufferView": 4, "componentType": 5121, "count": 2, "type": "SCALAR"},
            ],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 1}, "indices": 0, "extensions": {
                "NV_displacement_micromap": {"micromap": 0, "groupIndex": 0, "directions": 2,
                    "primitiveFlags": 3}}}]}],
            "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}], "scene": 0,
        });
        let gltf = crate::mesh::test_util::write_temp("base_mesh.gltf", &serde_json::to_vec(&json).unwrap());
        let dir = gltf.parent().unwrap();
        std::fs::write(dir.join("base_mesh.bin"), &bin).unwrap();
        std::fs::write(dir.join("base_mesh.bary"), &bary).unwrap();
        let read = parse_displaced(&std::fs::read(&gltf).unwrap(), Some(dir))
            .unwrap()
            .unwrap();
        for (t, v) in values.iter().enumerate() {
            assert_eq!(read.micromap.triangles[t].level, levels[t]);
            assert_eq!(read.micromap.triangle_values(t), &v[..], "triangle {t}");
        }
        assert_eq!(read.decimated_edges, flags);
        assert_eq!(read.directions[3], DVec3::new(0.0, 0.0, 0.5));
        let (local, _) = read.into_local();
        local.check().unwrap();
        assert_eq!(local.open_seams(), 0);
        // Welded, the seam closes: 16 + 4 micro-triangles less the two the flag collapses, on
        // 13 points of the finer side (two unused) and 6 of the coarser, 3 of them shared.
        let welded = local.decoded_welded();
        assert_eq!(
            (welded.triangles.len(), welded.positions.len()),
            (16 + 4 - 2, 13 + 6 - 3)
        );
    }

    fn halves(v: &[f32]) -> Vec<u8> {
        v.iter().flat_map(|&f| half::f16::from_f32(f).to_le_bytes()).collect()
    }

    /// Directions as VEC4 half floats and bounds as VEC2 half floats (the component type
    /// the extension adds), and mapIndices with a mapOffset, which applies to them too.
    #[test]
    fn half_float_directions_and_bounds_read() {
        let mut properties = two_triangle_properties();
        // Three triangles, so that mapIndices [1, 0] and mapOffset 1 take triangles 2 and 1.
        let mut values = words(&[1_000_397_001, 1, 1, 18, 2, 4]);
        values.extend((0..18u16).flat_map(|k| (100 * (k / 6 + 1) + k % 6).to_le_bytes()));
        properties[0].1 = values;
        properties[1].1[4..8].copy_from_slice(&3u32.to_le_bytes());
        properties[1].1[12..16].copy_from_slice(&18u32.to_le_bytes());
        properties[2].1 = words(&[0, 1, 6, 1, 12, 1]);
        let mut extra = halves(&[0.0, 0.0, 2.0, 0.0].repeat(4)); // 32: directions
        extra.extend(halves(&[0.5, 3.0].repeat(4))); // 16: bounds
        extra.extend([1u8, 0]); // 2: map indices
        let glb = square_glb(
            &hand_bary(&properties),
            serde_json::json!({"micromap": 0, "directions": 3, "directionBounds": 4,
                "mapIndices": 5, "mapOffset": 1}),
            (
                &extra,
                serde_json::json!([
                    {"bufferView": 3, "componentType": 5131, "count": 4, "type": "VEC4"},
                    {"bufferView": 4, "componentType": 5131, "count": 4, "type": "VEC2"},
                    {"bufferView": 5, "componentType": 5121, "count": 2, "type": "SCALAR"},
                ]),
                serde_json::json!([
                    {"buffer": 0, "byteOffset": 120, "byteLength": 32},
                    {"buffer": 0, "byteOffset": 152, "byteLength": 16},
                    {"buffer": 0, "byteOffset": 168, "byteLength": 2},
                ]),
            ),
            true,
        );
        let read = parse_displaced(&glb, None).unwrap().unwrap();
        // Bias 0.5 along (0, 0, 2), scale 3.
        assert_eq!(read.positions[1], DVec3::new(1.0, 0.0, 1.0));
        assert_eq!(read.directions[1], DVec3::new(0.0, 0.0, 6.0));
        assert_eq!(read.micromap.triangle_values(0)[0], 300);
        assert_eq!(read.micromap.triangle_values(1)[0], 200);
    }

    /// Without a directions accessor, the micromap's own directions (from directionsOffset),
    /// triangle mappings and flags hold; without those, the vertex normals; without normals
    /// either, the file is refused.
    #[test]
    fn directions_default_to_the_micromaps_then_the_normals() {
        let mut properties = two_triangle_properties();
        let mut directions = words(&[106, 5, 12, 4]);
        for d in 0..5 {
            directions.extend(floats(&[0.0, d as f32, 1.0]));
        }
        properties.push(([0xf262_d687, 0xb928_4aeb, 0xa706_803c, 0xcbed_ae52], directions));
        let mut mappings = words(&[74, 2, 2, 4]);
        mappings.extend([1u8, 0, 0, 0]);
        properties.push(([0x9cdc_3ad0, 0x92bb_4a8a, 0xb465_8759, 0x42d4_1d54], mappings));
        let mut flags = words(&[13, 2, 1, 4]);
        flags.extend([0u8, 0b100]);
        properties.push(([0x90f9_eed3, 0x4ec3_4974, 0x970c_755c, 0xaf5b_53a3], flags));
        let no_extra = || (&[][..], serde_json::json!([]), serde_json::json!([]));
        let extension = serde_json::json!({"micromap": 0, "directionsOffset": 1});
        let glb = square_glb(&hand_bary(&properties), extension, no_extra(), true);
        let read = parse_displaced(&glb, None).unwrap().unwrap();
        assert_eq!(read.directions[3], DVec3::new(0.0, 4.0, 1.0));
        assert_eq!(read.micromap.triangle_values(0)[0], 200);
        assert_eq!(read.decimated_edges, vec![0, 0b100]);

        let plain = two_triangle_properties();
        let glb = square_glb(&hand_bary(&plain), serde_json::json!({"micromap": 0}), no_extra(), true);
        let read = parse_displaced(&glb, None).unwrap().unwrap();
        assert_eq!(read.directions, vec![DVec3::Z; 4]);
        assert_eq!(read.micromap.triangle_values(0)[0], 100);

        let glb = square_glb(
            &hand_bary(&plain),
            serde_json::json!({"micromap": 0}),
            no_extra(),
            false,
        );
        let e = parse_displaced(&glb, None).unwrap_err().to_string();
        assert!(
            e.contains("no directions accessor, none in its micromap, and no vertex normals"),
            "{e}"
        );
    }

    /// Half floats anywhere else than the extension's directions and bounds are refused.
    #[test]
    fn half_floats_elsewhere_are_refused() {
        let mut glb = square_glb(
            &hand_bary(&two_triangle_properties()),
            serde_json::json!({"micromap": 0}),
            (&[][..], serde_json::json!([]), serde_json::json!([])),
            true,
        );
        // The normals' component type 5126 becomes 5131.
        let at = glb.windows(4).rposition(|w| w == b"5126").unwrap();
        glb[at..at + 4].copy_from_slice(b"5131");
        let e = parse_displaced(&glb, None).unwrap_err().to_string();
        assert!(e.contains("accessor 1 holds half floats"), "{e}");
    }
}
