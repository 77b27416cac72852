//! glTF 2.0 (`.gltf` with external or embedded buffers, `.glb`): the document parsed and
//! validated by the `gltf` crate, everything read from it checked here first.
//!
//! Every triangle primitive of every mesh in the default scene (or the first scene, or every
//! root node when the file has none) becomes part of one mesh, each with its node's transform
//! (parents' included) applied in double precision, read from the JSON text itself rather
//! than as the `f32` the crate keeps. A transform that mirrors (negative determinant) would
//! turn its triangles inside out, so their winding is reversed. Points and lines are skipped;
//! strips and fans are split into triangles.
//!
//! What the file says is not trusted: the GLB container's header and chunks are checked
//! before the JSON is parsed; the node hierarchy is walked without recursion and must form
//! trees (no cycles, no node with two parents), however deep; POSITION and index accessors
//! must have the types the specification gives them, and every byte they name must lie in
//! its buffer view and buffer, before anything is read. Buffers are read from the GLB's
//! binary chunk, from `data:` URIs, or from files inside the asset's own folder: an absolute
//! path, a `..` step, a URL or a link leading out of the folder is refused, so that an asset
//! cannot make gridrt read any other file.

use std::path::{Path, PathBuf};

use crate::error::{error, fail, Result};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;
use gridrt_shared::glam::{DMat4, DQuat, DVec3};
use serde_json::Value;

use super::{quote, WorldMesh};

/// Parses a `.gltf` file's bytes (a GLB container too, if that is what they hold); external
/// buffers are read from `folder` and never from outside it. Errors carry no file name; the
/// caller adds it.
pub fn parse_gltf(bytes: &[u8], folder: Option<&Path>) -> Result<WorldMesh> {
    let (json, bin) = split_file(bytes)?;
    parse_document(json, bin, folder)
}

/// Parses a `.glb` file's bytes: the binary container, then its JSON and binary chunks.
pub fn parse_glb(bytes: &[u8], folder: Option<&Path>) -> Result<WorldMesh> {
    let (json, bin) = glb_chunks(bytes)?;
    parse_document(json, bin, folder)
}

const GLB_JSON: u32 = 0x4E4F_534A;
const GLB_BIN: u32 = 0x004E_4942;

/// The JSON chunk and the binary chunk (if any) of a GLB container, its header and chunk
/// lengths checked against the bytes there are.
fn glb_chunks(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>)> {
    let word = |at: usize| {
        bytes
            .get(at..at + 4)
            .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
    };
    if !bytes.starts_with(b"glTF") {
        let start = String::from_utf8_lossy(&bytes[..bytes.len().min(4)]).into_owned();
        let hint = match bytes.iter().find(|b| !b.is_ascii_whitespace()) {
            Some(b'{') => " (it looks like JSON: name it .gltf)",
            _ => "",
        };
        fail!(
            Input,
            "not a GLB file: it starts with {} instead of \"glTF\"{hint}",
            quote(&start)
        );
    }
    let (Some(version), Some(length)) = (word(4), word(8)) else {
        fail!(
            Input,
            "truncated GLB: {} bytes, less than its 12-byte header",
            bytes.len()
        );
    };
    if version != 2 {
        fail!(Input, "GLB version {version}: gridrt reads glTF 2.0 (version 2)");
    }
    if length as usize != bytes.len() {
        let what = if (length as usize) > bytes.len() {
            "truncated GLB"
        } else {
            "damaged GLB"
        };
        fail!(
            Input,
            "{what}: its header declares {length} bytes, the file has {}",
            bytes.len()
        );
    }
    let (mut at, mut json, mut bin) = (12usize, None, None);
    for chunk in 0.. {
        if at >= bytes.len() {
            break;
        }
        let (Some(size), Some(kind)) = (word(at), word(at + 4)) else {
            fail!(Input, "truncated GLB: chunk {chunk}'s 8-byte header is cut off");
        };
        let data = bytes
            .get(at + 8..(at + 8).saturating_add(size as usize))
            .ok_or_else(|| {
                error!(
                    Input,
                    "truncated GLB: chunk {chunk} declares {size} bytes, {} remain",
                    bytes.len() - (at + 8).min(bytes.len())
                )
            })?;
        match (chunk, kind) {
            (0, GLB_JSON) => json = Some(data),
            (0, _) => fail!(Input, "damaged GLB: its first chunk is not JSON (type {kind:#010x})"),
            (1, GLB_BIN) => bin = Some(data),
            // Chunks of other types are for extensions, and are skipped.
            _ => {}
        }
        at += 8 + size as usize;
    }
    let json = json.ok_or_else(|| error!(Input, "damaged GLB: no JSON chunk"))?;
    Ok((json, bin))
}

/// A glTF document checked and ready to read: the crate's view of it, its JSON as plain
/// values (for numbers in full precision and for extensions), its buffers' bytes, and the
/// nodes its scene draws with their transforms, parents first.
pub(crate) struct OpenedGltf {
    pub document: gltf::Document,
    pub raw: Value,
    pub buffers: Vec<Vec<u8>>,
    pub drawn: Vec<(usize, DMat4)>,
    /// The accessors of half floats (see [`HALF_FLOAT`]): the crate reads their bits as
    /// unsigned shorts.
    pub half_floats: Vec<usize>,
}

/// The component type `NV_displacement_micromap` adds for half floats (IEEE binary16), for
/// its directions and direction bounds.
const HALF_FLOAT: u64 = 5131;
/// What the crate, which knows no half floats, is told such an accessor holds instead.
const UNSIGNED_SHORT: u64 = 5123;

/// Parses and checks a document (the JSON, and a GLB's binary chunk if any).
pub(crate) fn open_document(json: &[u8], bin: Option<&[u8]>, folder: Option<&Path>) -> Result<OpenedGltf> {
    // The text as plain JSON first: for the node transforms' numbers in full precision, and
    // for what the crate's validation would index without checking.
    let raw: Value = serde_json::from_slice(json).map_err(|e| error!(Input, "{e}"))?;
    check_position_accessors_exist(&raw)?;
    let half_floats = half_float_accessors(&raw)?;
    let document = match half_floats.is_empty() {
        true => gltf::Gltf::from_slice(json),
        false => {
            let mut patched = raw.clone();
            for &a in &half_floats {
                patched["accessors"][a]["componentType"] = UNSIGNED_SHORT.into();
            }
            let text = serde_json::to_vec(&patched).map_err(|e| error!(Input, "{e}"))?;
            gltf::Gltf::from_slice(&text)
        }
    };
    let document = document.map_err(|e| error!(Input, "{e}"))?.document;
    let transforms = node_transforms(&raw, document.nodes().len())?;
    let roots = node_roots(&document)?;
    let buffers = load_buffers(&document, bin, folder)?;
    let drawn = scene_nodes(&document, &transforms, roots)?;
    Ok(OpenedGltf {
        document,
        raw,
        buffers,
        drawn,
        half_floats,
    })
}

/// The accessors of half floats, checked to be used by nothing but the displacement
/// extension, which reads them as such (a mesh attribute or index of them is refused).
fn half_float_accessors(raw: &Value) -> Result<Vec<usize>> {
    let accessors = raw.get("accessors").and_then(Value::as_array);
    let halves: Vec<usize> = (accessors.into_iter().flatten().enumerate())
        .filter(|(_, a)| a.get("componentType").and_then(Value::as_u64) == Some(HALF_FLOAT))
        .map(|(k, _)| k)
        .collect();
    let meshes = raw.get("meshes").and_then(Value::as_array);
    let primitives = (meshes.into_iter().flatten())
        .filter_map(|m| m.get("primitives").and_then(Value::as_array))
        .flatten();
    for p in primitives {
        let targets = p.get("targets").and_then(Value::as_array).into_iter().flatten();
        let attributes = p.get("attributes").into_iter().chain(targets);
        let used = (attributes.filter_map(Value::as_object))
            .flat_map(|a| a.values())
            .chain(p.get("indices"))
            .filter_map(Value::as_u64);
        if let Some(a) = used.map(|a| a as usize).find(|a| halves.contains(a)) {
            fail!(
                Input,
                "accessor {a} holds half floats (componentType 5131), which only NV_displacement_micromap's directions and direction bounds may"
            );
        }
    }
    Ok(halves)
}

/// The JSON and binary chunk of a `.gltf` or `.glb` file's bytes.
pub(crate) fn split_file(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>)> {
    if bytes.starts_with(b"glTF") {
        return glb_chunks(bytes);
    }
    // JSON text starts with its object's brace (after a byte-order mark or blanks).
    let text = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    if text.iter().find(|b| !b.is_ascii_whitespace()) != Some(&b'{') {
        let start = String::from_utf8_lossy(&bytes[..bytes.len().min(4)]).into_owned();
        fail!(
            Input,
            "neither a GLB container nor glTF JSON: it starts with {} instead of \"glTF\" or \"{{\"",
            quote(&start)
        );
    }
    Ok((bytes, None))
}

/// Reads the document's default scene into one mesh.
fn parse_document(json: &[u8], bin: Option<&[u8]>, folder: Option<&Path>) -> Result<WorldMesh> {
    let opened = open_document(json, bin, folder)?;
    check_drawn_size(
        &opened,
        |_, _| 1.0,
        crate::limits::LOADED_BYTES_PER_TRIANGLE,
        "triangles",
    )?;
    let nodes: Vec<gltf::Node> = opened.document.nodes().collect();
    let mut mesh = WorldMesh::default();
    for &(n, transform) in &opened.drawn {
        let Some(m) = nodes[n].mesh() else { continue };
        for primitive in m.primitives() {
            add_primitive(&mut mesh, &primitive, &transform, &opened.buffers)
                .map_err(|e| error!(Input, "mesh {} primitive {}: {e}", m.index(), primitive.index()))?;
        }
    }
    if mesh.triangles.is_empty() {
        fail!(Input, "no triangle primitives in its scene");
    }
    Ok(mesh)
}

/// Refuses, before anything is expanded, a scene whose drawn triangles would not fit in
/// memory at `bytes_per` bytes each: every primitive counted once per node that draws it
/// (instances), from its accessors' counts, each triangle as `weight` of the mesh's index and
/// the primitive says
/// (the micro-triangles a displaced one decodes to). `what` names what is counted.
pub(crate) fn check_drawn_size(
    opened: &OpenedGltf,
    weight: impl Fn(usize, &gltf::Primitive) -> f64,
    bytes_per: u64,
    what: &str,
) -> Result<()> {
    let nodes: Vec<gltf::Node> = opened.document.nodes().collect();
    let (mut drawn, mut instances) = (0.0f64, 0usize);
    for &(n, _) in &opened.drawn {
        let Some(mesh) = nodes[n].mesh() else { continue };
        instances += 1;
        for primitive in mesh.primitives() {
            let corners = match (primitive.indices(), primitive.get(&gltf::Semantic::Positions)) {
                (Some(indices), _) => indices.count(),
                (None, Some(positions)) => positions.count(),
                (None, None) => 0,
            };
            drawn += (corners / 3) as f64 * weight(mesh.index(), &primitive);
        }
    }
    let count = drawn as u64;
    // A file that asks for more than there is, is refused as its contents are: an input error.
    crate::limits::check_memory(
        count.saturating_mul(bytes_per),
        crate::limits::available_memory()?,
        &format!("its scene's {count} {what} ({instances} meshes drawn, instances counted)"),
        "draw fewer instances, or give it more memory",
    )
    .map_err(|e| error!(Input, "{}", e.message()))
}

/// Refuses a primitive whose POSITION names an accessor the file does not have: the `gltf`
/// crate's validation looks that accessor up (for its bounds) before it checks the index,
/// and panics. Anything else malformed there is left to the crate to report.
fn check_position_accessors_exist(raw: &Value) -> Result<()> {
    let accessors = raw.get("accessors").and_then(Value::as_array).map_or(0, Vec::len);
    let meshes = raw.get("meshes").and_then(Value::as_array).into_iter().flatten();
    for (m, mesh) in meshes.enumerate() {
        let primitives = mesh.get("primitives").and_then(Value::as_array).into_iter().flatten();
        for (p, primitive) in primitives.enumerate() {
            let position = primitive.pointer("/attributes/POSITION").and_then(Value::as_u64);
            if let Some(a) = position.filter(|&a| a >= accessors as u64) {
                fail!(
                    Input,
                    "mesh {m} primitive {p}: its POSITION accessor {a} does not exist (the file has {accessors})"
                );
            }
        }
    }
    Ok(())
}

/// Each node's own transform, from the JSON's numbers as `f64`: its matrix, or its
/// translation, rotation and scale. Every number must be a finite 32-bit float, as the
/// specification has them.
fn node_transforms(raw: &Value, count: usize) -> Result<Vec<DMat4>> {
    let nodes = raw.get("nodes").and_then(Value::as_array);
    (0..count)
        .map(|i| {
            let node = nodes.and_then(|n| n.get(i));
            let numbers = |field: &str, n: usize| -> Result<Option<Vec<f64>>> {
                let Some(value) = node.and_then(|node| node.get(field)) else {
                    return Ok(None);
                };
                let list: Vec<f64> = (value.as_array().into_iter().flatten())
                    .filter_map(Value::as_f64)
                    .collect();
                if list.len() != n {
                    fail!(Input, "node {i}: its {field} is not {n} numbers");
                }
                if let Some(v) = list.iter().find(|v| !v.is_finite() || v.abs() > f32::MAX as f64) {
                    fail!(
                        Input,
                        "node {i}: its {field} holds {v:e}, beyond the 32-bit float range (+-3.4e38)"
                    );
                }
                Ok(Some(list))
            };
            if let Some(m) = numbers("matrix", 16)? {
                return Ok(DMat4::from_cols_slice(&m));
            }
            let t = numbers("translation", 3)?.unwrap_or(vec![0.0; 3]);
            let r = numbers("rotation", 4)?.unwrap_or(vec![0.0, 0.0, 0.0, 1.0]);
            let s = numbers("scale", 3)?.unwrap_or(vec![1.0; 3]);
            let rotation = DQuat::from_xyzw(r[0], r[1], r[2], r[3]);
            if rotation.length() == 0.0 {
                fail!(Input, "node {i}: its rotation (0, 0, 0, 0) is no rotation");
            }
            Ok(DMat4::from_scale_rotation_translation(
                DVec3::from_slice(&s),
                rotation.normalize(),
                DVec3::from_slice(&t),
            ))
        })
        .collect()
}

/// Refuses a node hierarchy that is not a set of trees: a node that is the child of two
/// nodes (or twice of one), and a cycle, which no walk from a root would ever leave. Returns
/// the roots, the nodes no other names as a child.
fn node_roots(document: &gltf::Document) -> Result<Vec<usize>> {
    let nodes: Vec<gltf::Node> = document.nodes().collect();
    let count = nodes.len();
    let mut parent = vec![None; count];
    for node in &nodes {
        for child in node.children() {
            if let Some(other) = parent[child.index()].replace(node.index()) {
                fail!(
                    Input,
                    "node {} is a child of both node {other} and node {}: glTF nodes form trees",
                    child.index(),
                    node.index()
                );
            }
        }
    }
    // Each node has one parent at most: the nodes no walk from a root reaches are on cycles.
    let roots: Vec<usize> = (0..count).filter(|&i| parent[i].is_none()).collect();
    let mut reached = vec![false; count];
    let mut stack = roots.clone();
    while let Some(i) = stack.pop() {
        reached[i] = true;
        stack.extend(nodes[i].children().map(|c| c.index()));
    }
    if let Some(i) = reached.iter().position(|&r| !r) {
        fail!(
            Input,
            "node {i} is its own ancestor: the node hierarchy has a cycle (glTF nodes form trees)"
        );
    }
    Ok(roots)
}

/// Every node of the default scene (or the first, or every root node when there is no
/// scene) with its transform, parents first, walked with a stack of its own so that no depth
/// of nesting can overflow the call stack.
fn scene_nodes(document: &gltf::Document, local: &[DMat4], roots: Vec<usize>) -> Result<Vec<(usize, DMat4)>> {
    let nodes: Vec<gltf::Node> = document.nodes().collect();
    let roots: Vec<usize> = match document.default_scene().or_else(|| document.scenes().next()) {
        Some(scene) => scene.nodes().map(|n| n.index()).collect(),
        None => roots,
    };
    let mut visited = vec![false; nodes.len()];
    let mut out = Vec::new();
    let mut stack: Vec<(usize, DMat4)> = roots.iter().rev().map(|&r| (r, DMat4::IDENTITY)).collect();
    while let Some((i, parent)) = stack.pop() {
        if std::mem::replace(&mut visited[i], true) {
            fail!(
                Input,
                "node {i} is drawn twice by its scene (a scene lists a node and one of its ancestors)"
            );
        }
        let transform = parent * local[i];
        if !transform.is_finite() {
            fail!(
                Input,
                "node {i}: its transform, with its parents', is not finite (the product overflows)"
            );
        }
        stack.extend(
            nodes[i]
                .children()
                .map(|c| (c.index(), transform))
                .collect::<Vec<_>>()
                .into_iter()
                .rev(),
        );
        out.push((i, transform));
    }
    Ok(out)
}

/// Every buffer's bytes (as many as it declares), from the GLB's binary chunk, a `data:` URI
/// or a file inside `folder`.
fn load_buffers(document: &gltf::Document, bin: Option<&[u8]>, folder: Option<&Path>) -> Result<Vec<Vec<u8>>> {
    document
        .buffers()
        .map(|buffer| {
            let i = buffer.index();
            let (mut bytes, from) = match buffer.source() {
                gltf::buffer::Source::Bin => match bin {
                    Some(bin) => (bin.to_vec(), "the GLB's binary chunk".to_string()),
                    None => fail!(Input, "buffer {i} has no uri and the file has no binary chunk"),
                },
                gltf::buffer::Source::Uri(uri) => {
                    read_uri(uri, folder).map_err(|e| error!(Input, "buffer {i}: {e}"))?
                }
            };
            let declared = buffer.length();
            if bytes.len() < declared {
                fail!(
                    Input,
                    "buffer {i} declares {declared} bytes but {from} holds {}",
                    bytes.len()
                );
            }
            bytes.truncate(declared);
            Ok(bytes)
        })
        .collect()
}

/// The files in its folder that the `.gltf` or `.glb` file `path` names: its buffers' and its
/// micromaps' `uri`s (data URIs and names that cannot be read from the folder left out).
/// Nothing is read but the document (a GLB's binary chunk is not); a file that cannot be
/// read names none.
pub fn files_named(path: &Path) -> Vec<PathBuf> {
    let Some(json) = document_bytes(path) else {
        return Vec::new();
    };
    let Ok(raw) = serde_json::from_slice::<Value>(&json) else {
        return Vec::new();
    };
    let folder = path.parent();
    (uris_named(&raw).iter())
        .filter(|uri| !uri.starts_with("data:"))
        .filter_map(|uri| asset_file(uri, folder).ok())
        .collect()
}

/// The JSON of the glTF file `path`: the whole of a `.gltf`, the JSON chunk of a GLB (its
/// header and chunk header read first, the binary chunk left unread).
fn document_bytes(path: &Path) -> Option<Vec<u8>> {
    use std::io::Read;
    let mut file = crate::files::open_plain_file(path).ok()?;
    let mut head = Vec::new();
    (&mut file).take(20).read_to_end(&mut head).ok()?;
    if !head.starts_with(b"glTF") {
        file.read_to_end(&mut head).ok()?;
        return Some(head);
    }
    let length = u32::from_le_bytes(head.get(12..16)?.try_into().ok()?);
    let mut json = Vec::new();
    file.take(length as u64).read_to_end(&mut json).ok()?;
    Some(json)
}

/// The `uri`s a glTF document names: its buffers', then its micromaps' (`NV_micromaps`).
pub fn uris_named(document: &Value) -> Vec<String> {
    let uris = |list: Option<&Value>| -> Vec<String> {
        (list.and_then(Value::as_array).into_iter().flatten())
            .filter_map(|entry| entry.get("uri")?.as_str().map(str::to_string))
            .collect()
    };
    let mut named = uris(document.get("buffers"));
    named.extend(uris(document.pointer("/extensions/NV_micromaps/micromaps")));
    named
}

/// The bytes a buffer's `uri` names, and where they came from (for messages).
pub(crate) fn read_uri(uri: &str, folder: Option<&Path>) -> Result<(Vec<u8>, String)> {
    if let Some(data) = uri.strip_prefix("data:") {
        let Some((_, encoded)) = data.split_once(";base64,") else {
            fail!(Input, "its data URI is not base64-encoded");
        };
        use base64::Engine;
        let bytes = base64::engine::general_purpose::STANDARD
            .decode(encoded.trim_end())
            .map_err(|e| error!(Input, "its data URI is not valid base64 ({e})"))?;
        return Ok((bytes, "its data URI".into()));
    }
    let path = asset_file(uri, folder)?;
    let bytes = crate::files::read_plain_file(&path)
        .map_err(|reason| error!(Input, "cannot read {}: {reason}", path.display()))?;
    Ok((bytes, path.display().to_string()))
}

/// The file a relative URI names inside `folder`; refuses a URL, an absolute path, a `..`
/// step, and a path that links out of the folder.
fn asset_file(uri: &str, folder: Option<&Path>) -> Result<PathBuf> {
    let outside = |why: &str| {
        error!(
            Input,
            "its uri {} {why}: gridrt reads buffers only from files in the asset's folder",
            quote(uri)
        )
    };
    let scheme = uri.split_once(':').map(|(s, _)| s).filter(|s| {
        s.chars().next().is_some_and(|c| c.is_ascii_alphabetic())
            && s.chars().all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c))
    });
    if scheme.is_some() {
        return Err(outside("is a URL or a drive path"));
    }
    let relative = percent_decode(uri).ok_or_else(|| outside("is not a valid URI"))?;
    if relative.starts_with(['/', '\\']) {
        return Err(outside("is an absolute path"));
    }
    if relative.split(['/', '\\']).any(|step| step == "..") {
        return Err(outside("steps out of its folder (..)"));
    }
    let Some(folder) = folder else {
        return Err(outside("names a file, and the asset has no folder"));
    };
    let folder = if folder.as_os_str().is_empty() {
        Path::new(".")
    } else {
        folder
    };
    let path = folder.join(&relative);
    // Links are followed before comparing: one inside the folder may point anywhere.
    let (Ok(real_folder), Ok(real_path)) = (folder.canonicalize(), path.canonicalize()) else {
        return Ok(path); // Missing: reading it says so.
    };
    if !real_path.starts_with(&real_folder) {
        return Err(outside("leads out of the asset's folder through a link"));
    }
    Ok(path)
}

/// `%XX` escapes decoded (URIs in glTF are RFC 3986); `None` for a broken escape, invalid
/// UTF-8 or a NUL.
fn percent_decode(uri: &str) -> Option<String> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok().filter(|s| !s.contains('\0'))
}

/// A buffer view's bytes, checked to lie in its buffer.
pub(crate) fn view_bytes<'a>(view: &gltf::buffer::View, buffers: &'a [Vec<u8>]) -> Result<&'a [u8]> {
    let (v, b) = (view.index(), view.buffer().index());
    let buffer = &buffers[b];
    let range = view.offset()..view.offset().saturating_add(view.length());
    buffer.get(range).ok_or_else(|| {
        error!(
            Input,
            "buffer view {v} ends at byte {} of buffer {b}, which has {} bytes",
            view.offset() as u128 + view.length() as u128,
            buffer.len()
        )
    })
}

/// The bytes of an accessor's elements: `count` elements of `size` bytes, `stride` apart,
/// from `start` in its view's `bytes`; every one of them checked to lie in its view and buffer.
struct Elements<'a> {
    bytes: &'a [u8],
    start: usize,
    stride: usize,
    size: usize,
    count: usize,
}

impl<'a> Elements<'a> {
    /// Element `k`'s bytes.
    fn get(&self, k: usize) -> &'a [u8] {
        let at = self.start + k * self.stride;
        &self.bytes[at..at + self.size]
    }

    /// `count` elements of `size` bytes at `offset` in `view` (its stride, or packed), or a
    /// message naming what reaches past what.
    fn in_view(
        view: &gltf::buffer::View,
        offset: usize,
        count: usize,
        size: usize,
        buffers: &'a [Vec<u8>],
    ) -> Result<Elements<'a>> {
        let v = view.index();
        let bytes = view_bytes(view, buffers)?;
        let stride = view.stride().unwrap_or(size);
        if stride < size {
            fail!(
                Input,
                "buffer view {v}'s stride of {stride} bytes is less than its elements' {size}"
            );
        }
        let needed = match count {
            0 => 0,
            n => offset as u128 + (n as u128 - 1) * stride as u128 + size as u128,
        };
        if needed > view.length() as u128 {
            fail!(
                Input,
                "its {count} elements reach byte {needed} of buffer view {v}, which has {} bytes",
                view.length()
            );
        }
        Ok(Elements {
            bytes,
            start: offset,
            stride,
            size,
            count,
        })
    }
}

/// Names of the types and component types the specification numbers.
pub(crate) fn describe(accessor: &gltf::Accessor) -> String {
    let component = match accessor.data_type() {
        DataType::I8 => "BYTE",
        DataType::U8 => "UNSIGNED_BYTE",
        DataType::I16 => "SHORT",
        DataType::U16 => "UNSIGNED_SHORT",
        DataType::U32 => "UNSIGNED_INT",
        DataType::F32 => "FLOAT",
    };
    let normalized = if accessor.normalized() { " normalized" } else { "" };
    format!("{:?}{normalized} {component}", accessor.dimensions()).to_uppercase()
}

/// An accessor's values as `f64`, each element's `N` components; its sparse substitutions
/// applied. The caller has checked its type.
pub(crate) fn read_accessor<const N: usize>(accessor: &gltf::Accessor, buffers: &[Vec<u8>]) -> Result<Vec<[f64; N]>> {
    let ty = accessor.data_type();
    let width = ty.size();
    let decode =
        |bytes: &[u8]| -> [f64; N] { std::array::from_fn(|c| component(ty, &bytes[c * width..(c + 1) * width])) };
    let count = accessor.count();
    let mut values = match accessor.view() {
        Some(view) => {
            let elements = Elements::in_view(&view, accessor.offset(), count, N * width, buffers)?;
            (0..elements.count).map(|k| decode(elements.get(k))).collect()
        }
        // No view: zeros, unless sparse values replace them.
        None => {
            if count > buffers.iter().map(Vec::len).sum::<usize>().max(1 << 20) {
                fail!(Input, "its {count} elements have no buffer view to read from");
            }
            vec![[0.0; N]; count]
        }
    };
    if let Some(sparse) = accessor.sparse() {
        let n = sparse.count();
        let (indices, at) = (sparse.indices(), sparse.values());
        let index_type = match indices.index_type() {
            gltf::accessor::sparse::IndexType::U8 => DataType::U8,
            gltf::accessor::sparse::IndexType::U16 => DataType::U16,
            gltf::accessor::sparse::IndexType::U32 => DataType::U32,
        };
        let index_elements = Elements::in_view(&indices.view(), indices.offset(), n, index_type.size(), buffers)
            .map_err(|e| error!(Input, "sparse indices: {e}"))?;
        let value_elements = Elements::in_view(&at.view(), at.offset(), n, N * width, buffers)
            .map_err(|e| error!(Input, "sparse values: {e}"))?;
        for k in 0..n {
            let index = component(index_type, index_elements.get(k)) as usize;
            let slot = values
                .get_mut(index)
                .ok_or_else(|| error!(Input, "sparse index {index} is past its {count} elements"))?;
            *slot = decode(value_elements.get(k));
        }
    }
    Ok(values)
}

/// One little-endian component.
fn component(ty: DataType, b: &[u8]) -> f64 {
    match ty {
        DataType::I8 => b[0] as i8 as f64,
        DataType::U8 => b[0] as f64,
        DataType::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
        DataType::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
        DataType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
        DataType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
    }
}

pub(crate) fn add_primitive(
    mesh: &mut WorldMesh,
    primitive: &gltf::Primitive,
    transform: &DMat4,
    buffers: &[Vec<u8>],
) -> Result<()> {
    if !matches!(
        primitive.mode(),
        Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
    ) {
        return Ok(());
    }
    let accessor = primitive
        .get(&gltf::Semantic::Positions)
        .ok_or_else(|| error!(Input, "no POSITION attribute"))?;
    let a = accessor.index();
    if accessor.dimensions() != Dimensions::Vec3 || accessor.data_type() != DataType::F32 || accessor.normalized() {
        fail!(
            Input,
            "its POSITION accessor {a} is {}: glTF positions are VEC3 FLOAT (quantized positions, KHR_mesh_quantization, are not supported)",
            describe(&accessor)
        );
    }
    let positions: Vec<DVec3> = read_accessor::<3>(&accessor, buffers)
        .map_err(|e| error!(Input, "POSITION accessor {a}: {e}"))?
        .into_iter()
        .map(|p| transform.transform_point3(DVec3::from_array(p)))
        .collect();
    let count = positions.len() as u32;
    let indices: Vec<u32> = match primitive.indices() {
        Some(accessor) => {
            let a = accessor.index();
            let integer = matches!(accessor.data_type(), DataType::U8 | DataType::U16 | DataType::U32);
            if accessor.dimensions() != Dimensions::Scalar || !integer || accessor.normalized() {
                fail!(
                    Input,
                    "its index accessor {a} is {}: glTF indices are SCALAR UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT",
                    describe(&accessor)
                );
            }
            read_accessor::<1>(&accessor, buffers)
                .map_err(|e| error!(Input, "index accessor {a}: {e}"))?
                .into_iter()
                .map(|[i]| i as u32)
                .collect()
        }
        None => (0..count).collect(),
    };
    if let Some(&bad) = indices.iter().find(|&&i| i >= count) {
        fail!(Input, "index {bad} is out of range ({count} positions)");
    }
    if primitive.mode() == Mode::Triangles && !indices.len().is_multiple_of(3) {
        let what = match primitive.indices() {
            Some(_) => "indices",
            None => "positions, drawn without indices,",
        };
        fail!(
            Input,
            "its {} {what} are not whole triangles: a triangle list needs a multiple of 3",
            indices.len()
        );
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

/// A GLB container of a glTF document `json` and its binary buffer `bin`: header, JSON
/// chunk, binary chunk, each padded to four bytes (what [`parse_glb`] reads).
pub fn glb_container(json: &[u8], bin: &[u8]) -> Vec<u8> {
    let pad = |mut v: Vec<u8>, with: u8| {
        while !v.len().is_multiple_of(4) {
            v.push(with);
        }
        v
    };
    let (json, bin) = (pad(json.to_vec(), b' '), pad(bin.to_vec(), 0));
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

#[cfg(test)]
mod tests {
    use super::super::read_world;
    use super::super::test_util::{expect_err, load_ok, load_scrambled, write_temp};
    use super::*;

    fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
        glb_container(json.as_bytes(), bin)
    }
    use gridrt_shared::glam::Vec3;

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

    /// The mirrored document as parsed, before cleaning.
    fn check(mesh: &WorldMesh) {
        assert_eq!(mesh.triangles.len(), 4);
        assert_eq!(mesh.positions.len(), 12);
        // The first primitive under the root: scaled by 2, moved by 10.
        assert_eq!(
            &mesh.positions[..3],
            &[
                DVec3::new(10., 0., 0.),
                DVec3::new(12., 0., 0.),
                DVec3::new(10., 2., 0.)
            ]
        );
        assert_eq!(mesh.triangles[0], [0, 1, 2]);
        // The child mirrors x inside the root's transform, and keeps the triangles' facing.
        assert_eq!(mesh.positions[7], DVec3::new(8., 0., 0.));
        assert_eq!(mesh.triangles[2], [6, 8, 7]);
        let normal = |t: [u32; 3]| {
            let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
            (b - a).cross(c - a)
        };
        assert!(normal(mesh.triangles[0]).z > 0.0 && normal(mesh.triangles[2]).z > 0.0);
    }

    /// A file through the glTF parser alone, as [`check`] wants it; then loaded whole, where
    /// the mirrored copy shares its edge along x = 10 with the original: welded.
    fn parse_and_check(path: &Path) {
        let parse = if path.extension().is_some_and(|e| e == "glb") {
            parse_glb
        } else {
            parse_gltf
        };
        check(&parse(&std::fs::read(path).unwrap(), path.parent()).unwrap());
        let (mesh, cleaning) = read_world(path).unwrap();
        assert_eq!((mesh.positions.len(), cleaning.welded), (8, 4));
    }

    #[test]
    fn embedded_external_and_binary_buffers_load_alike() {
        let embedded = document(Some(&format!(
            "data:application/octet-stream;base64,{}",
            base64(&buffer())
        )));
        parse_and_check(&write_temp("embedded.gltf", embedded.as_bytes()));
        let bin = write_temp("scene.bin", &buffer());
        let gltf = bin.with_file_name("scene.gltf");
        std::fs::write(&gltf, document(Some("scene.bin"))).unwrap();
        parse_and_check(&gltf);
        let spaced = bin.with_file_name("my scene.bin");
        std::fs::write(&spaced, buffer()).unwrap();
        std::fs::write(&gltf, document(Some("my%20scene.bin"))).unwrap();
        parse_and_check(&gltf);
        parse_and_check(&write_temp("scene.glb", &glb(&document(None), &buffer())));
    }

    #[test]
    fn broken_gltf_files_give_one_line_errors() {
        expect_err(
            "missing.gltf",
            document(Some("nowhere.bin")).as_bytes(),
            &["buffer 0: cannot read", "nowhere.bin"],
        );
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

    /// `document(None)` as a GLB with its nodes replaced by `nodes` (a JSON array).
    fn with_nodes(nodes: &str) -> Vec<u8> {
        let doc = document(None);
        let start = doc.find("\"nodes\": [\n").unwrap();
        let end = start + doc[start..].find("],\n  \"meshes\"").unwrap() + 1;
        glb(
            &format!("{}\"nodes\": {nodes}{}", &doc[..start], &doc[end..]),
            &buffer(),
        )
    }

    #[test]
    fn node_hierarchies_must_be_trees_of_any_depth() {
        let cycle = with_nodes(r#"[{"mesh": 0, "children": [1]}, {"children": [0]}]"#);
        expect_err("cycle.glb", &cycle, &["node 0 is its own ancestor", "cycle"]);
        let own_child = with_nodes(r#"[{"mesh": 0, "children": [0]}, {}]"#);
        expect_err("self.glb", &own_child, &["node 0 is its own ancestor"]);
        let two_parents = with_nodes(r#"[{"children": [2]}, {"children": [2]}, {"mesh": 0}]"#);
        expect_err(
            "parents.glb",
            &two_parents,
            &["node 2 is a child of both node 0 and node 1"],
        );
        // 50,000 nodes deep, each moving its children by one along x: no recursion to overflow.
        let depth = 50_000;
        let nodes: Vec<String> = (0..depth)
            .map(|i| match i + 1 < depth {
                true => format!(r#"{{"translation": [1, 0, 0], "children": [{}]}}"#, i + 1),
                false => r#"{"mesh": 0}"#.to_string(),
            })
            .collect();
        let deep = with_nodes(&format!("[{}]", nodes.join(",")));
        let (mesh, _) = load_ok("deep.glb", &deep);
        assert_eq!(mesh.positions[0], Vec3::new((depth - 1) as f32, 0.0, 0.0));
    }

    #[test]
    fn accessors_of_the_wrong_type_or_size_are_refused() {
        let doc = document(None);
        let index = r#""componentType": 5123, "count": 3, "type": "SCALAR""#;
        for (name, replacement) in [
            ("float.glb", r#""componentType": 5126, "count": 3, "type": "SCALAR""#),
            ("short.glb", r#""componentType": 5122, "count": 3, "type": "SCALAR""#),
            ("vec3.glb", r#""componentType": 5123, "count": 1, "type": "VEC3""#),
        ] {
            let bad = glb(&doc.replace(index, replacement), &buffer());
            expect_err(name, &bad, &["index accessor 2", "glTF indices are SCALAR"]);
        }
        let position = r#""componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]"#;
        for (name, replacement, what) in [
            (
                "vec2.glb",
                r#""componentType": 5126, "count": 3, "type": "VEC2", "min": [0, 0, 0], "max": [1, 1, 0]"#,
                "VEC2 FLOAT",
            ),
            (
                "ubyte.glb",
                r#""componentType": 5121, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]"#,
                "VEC3 UNSIGNED_BYTE",
            ),
            (
                "nshort.glb",
                r#""componentType": 5122, "normalized": true, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]"#,
                "VEC3 NORMALIZED SHORT",
            ),
        ] {
            let bad = glb(&doc.replace(position, replacement), &buffer());
            expect_err(name, &bad, &["POSITION accessor 0 is", what, "VEC3 FLOAT"]);
        }
        let short = glb(
            &doc.replace(
                position,
                r#""componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]"#,
            ),
            &buffer(),
        );
        expect_err(
            "short.glb",
            &short,
            &["POSITION accessor 0: its 4 elements reach byte 48 of buffer view 0, which has 36 bytes"],
        );
        let missing = glb(&doc.replace(r#""POSITION": 0"#, r#""POSITION": 7"#), &buffer());
        expect_err(
            "missing.glb",
            &missing,
            &["mesh 0 primitive 0: its POSITION accessor 7 does not exist (the file has 3)"],
        );
        let past_buffer = glb(&doc.replace(r#""byteLength": 6}"#, r#""byteLength": 60}"#), &buffer());
        expect_err(
            "view.glb",
            &past_buffer,
            &["buffer view 2 ends at byte 132 of buffer 0, which has 80 bytes"],
        );
    }

    #[test]
    fn buffers_are_read_only_from_the_assets_folder() {
        let folder = write_temp("scene.bin", &buffer());
        let folder = folder.parent().unwrap();
        let inside = folder.join("inside.gltf");
        std::fs::write(&inside, document(Some("scene.bin"))).unwrap();
        assert!(read_world(&inside).is_ok());
        let escaped = document(Some("sub%2F..%2Fscene.bin"));
        for (name, uri, why) in [
            ("up.gltf", "../../../../etc/passwd", "steps out of its folder"),
            ("up-escaped.gltf", "%2e%2e/scene.bin", "steps out of its folder"),
            ("absolute.gltf", "/etc/passwd", "is an absolute path"),
            ("url.gltf", "file:///etc/passwd", "is a URL"),
            ("http.gltf", "https://example.com/scene.bin", "is a URL"),
        ] {
            let e = expect_err(name, document(Some(uri)).as_bytes(), &["buffer 0: its uri", why]);
            assert!(e.contains("only from files in the asset's folder"), "{e}");
        }
        expect_err("escaped.gltf", escaped.as_bytes(), &["steps out of its folder"]);
        #[cfg(unix)]
        {
            let link = folder.join("link.bin");
            let outside = write_temp("outside.bin", &buffer());
            std::os::unix::fs::symlink(&outside, &link).unwrap();
            let linked = folder.join("link.gltf");
            std::fs::write(&linked, document(Some("link.bin"))).unwrap();
            let e = read_world(&linked).unwrap_err().to_string();
            assert!(e.contains("leads out of the asset's folder through a link"), "{e}");
        }
    }

    #[test]
    fn damaged_glb_containers_are_named() {
        let good = glb(&document(None), &buffer());
        let mut magic = good.clone();
        magic[3] = b'X';
        expect_err("magic.glb", &magic, &["not a GLB file", "\"glTX\""]);
        expect_err(
            "json.glb",
            document(None).as_bytes(),
            &["not a GLB file", "it looks like JSON: name it .gltf"],
        );
        expect_err(
            "cut.glb",
            &good[..good.len() - 10],
            &["truncated GLB: its header declares"],
        );
        let mut version = good.clone();
        version[4] = 1;
        expect_err("v1.glb", &version, &["GLB version 1"]);
        let mut chunk = good.clone();
        chunk[12] = 0xff;
        chunk[13] = 0xff;
        expect_err("chunk.glb", &chunk, &["truncated GLB: chunk 0 declares"]);
        // A GLB named .gltf is still read as one.
        assert!(load_ok("binary.gltf", &good).0.triangles.len() == 4);
    }

    #[test]
    fn node_transforms_are_read_in_double_precision_and_checked() {
        let far = with_nodes(r#"[{"mesh": 0, "translation": [10000000.125, 0, 0]}]"#);
        let path = write_temp("far.glb", &far);
        let (mesh, _) = read_world(&path).unwrap();
        assert_eq!(mesh.positions[1], DVec3::new(10000001.125, 0.0, 0.0));
        let huge = with_nodes(r#"[{"mesh": 0, "translation": [1e39, 0, 0]}]"#);
        expect_err(
            "huge.glb",
            &huge,
            &["node 0: its translation holds 1e39, beyond the 32-bit float range"],
        );
        let flat = with_nodes(r#"[{"mesh": 0, "scale": [0, 0, 0]}]"#);
        expect_err(
            "flat.glb",
            &flat,
            &["the mesh has no size: all its vertices are at (0, 0, 0)"],
        );
    }

    /// Two triangles sharing an edge, drawn without indices (each with its own three
    /// vertices, as an exporter splitting at seams writes them), load as one welded square.
    #[test]
    fn unindexed_triangles_are_welded() {
        let mut b = Vec::new();
        for p in [
            [0f32, 0., 0.],
            [1., 0., 0.],
            [1., 1., 0.],
            [0., 0., 0.],
            [1., 1., 0.],
            [0., 1., 0.],
        ] {
            b.extend(p.iter().flat_map(|c| c.to_le_bytes()));
        }
        let doc = r#"{"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
            "buffers": [{"byteLength": 72}], "bufferViews": [{"buffer": 0, "byteLength": 72}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 6, "type": "VEC3",
            "min": [0, 0, 0], "max": [1, 1, 0]}]}"#;
        let path = write_temp("seams.glb", &glb(doc, &b));
        let (mesh, cleaning) = read_world(&path).unwrap();
        assert_eq!((mesh.positions.len(), cleaning.welded), (4, 2));
        assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    }
}
