//! Stanford PLY, `ascii`, `binary_little_endian` and `binary_big_endian` 1.0, read by hand.
//!
//! Only `vertex` x/y/z and the `face` index list (or, where a file has no faces, the `tristrips` one) are kept;
//! every other property and element is read and skipped, because in PLY the only way past data is to decode it.
//! Polygons are fan-triangulated. Triangle strips, as some scans are distributed, are split at each `-1`; every
//! other triangle of a strip is turned so that all face the same way, and those with a repeated vertex (which join
//! strips) are left out.

use crate::error::{error, fail, Error, Result};
use gridrt_shared::glam::DVec3;

use super::{is_integer, quote, WorldMesh};

mod write;
pub use write::write_ply;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn from_name(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    fn is_float(self) -> bool {
        matches!(self, Self::F32 | Self::F64)
    }
}

enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

struct Property {
    name: String,
    kind: Kind,
}

struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
}

struct Header {
    big_endian: Option<bool>, // None: ascii
    elements: Vec<Element>,
    data_start: usize,
    lines: usize,
}

/// Parses a PLY file's bytes. Errors carry no file name; the caller adds it.
pub fn parse_ply(bytes: &[u8]) -> Result<WorldMesh> {
    let header = parse_header(bytes)?;
    let roles = Roles::find(&header)?;
    let data = &bytes[header.data_start..];
    match header.big_endian {
        None => check_line_count(data, &header)?,
        Some(_) => check_not_text(data, &header)?,
    }
    match header.big_endian {
        None => read_body(
            &mut Ascii {
                bytes: data,
                pos: 0,
                line: header.lines + 1,
                starts_element: true,
            },
            &header,
            &roles,
        ),
        Some(big_endian) => read_body(
            &mut Binary {
                bytes: data,
                pos: 0,
                big_endian,
            },
            &header,
            &roles,
        ),
    }
}

/// An ASCII body holds one line per element: fewer lines than the header's counts add up to
/// means the counts are wrong (or the file is cut short), which reading on would only report
/// as a line with the wrong number of values, elements later.
fn check_line_count(data: &[u8], header: &Header) -> Result<()> {
    let declared: usize = (header.elements.iter())
        .filter(|e| !e.props.is_empty())
        .fold(0usize, |sum, e| sum.saturating_add(e.count));
    let lines = data
        .split(|&b| b == b'\n')
        .filter(|line| line.iter().any(|b| !b.is_ascii_whitespace()))
        .count();
    if lines < declared {
        let counts: Vec<String> = (header.elements.iter())
            .filter(|e| !e.props.is_empty())
            .map(|e| format!("{} {}", e.count, plural(&e.name)))
            .collect();
        let counts = match counts.split_last() {
            Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
            _ => counts.concat(),
        };
        fail!(
            Input,
            "truncated, or the header's counts are wrong: it declares {} ({declared} lines), the body has {lines} lines",
            counts
        );
    }
    Ok(())
}

/// A body that reads as lines of numbers under a header that says binary: the format line
/// is wrong, and decoding the text as binary would report nonsense values.
fn check_not_text(data: &[u8], header: &Header) -> Result<()> {
    let sample = &data[..data.len().min(256)];
    let numeric = |b: &u8| b.is_ascii_digit() || b" \t\r\n+-.eE".contains(b);
    if sample.len() >= 8 && sample.contains(&b'\n') && sample.iter().all(numeric) {
        let format = if header.big_endian == Some(true) {
            "binary_big_endian"
        } else {
            "binary_little_endian"
        };
        fail!(
            Input,
            "the header says {format} but the body is ASCII text (lines of numbers): its format line should say ascii"
        );
    }
    Ok(())
}

fn parse_header(bytes: &[u8]) -> Result<Header> {
    let (mut pos, mut line_no) = (0, 0);
    let (mut big_endian, mut format_seen) = (None, false);
    let mut elements: Vec<Element> = Vec::new();
    loop {
        if pos >= bytes.len() {
            fail!(Input, "truncated header: no end_header line");
        }
        let newline = bytes[pos..].iter().position(|&b| b == b'\n');
        let end = newline.map_or(bytes.len(), |n| pos + n);
        let raw = String::from_utf8_lossy(&bytes[pos..end]);
        let text = raw.trim_end_matches('\r');
        pos = end + 1;
        line_no += 1;
        if line_no == 1 && text.trim_end() != "ply" {
            fail!(
                Input,
                "bad magic: expected \"ply\" on the first line, found {}",
                quote(text)
            );
        }
        // A header line cut off by the end of the file would otherwise be misread as a short, wrong line.
        if newline.is_none() && text.trim() != "end_header" {
            fail!(Input, "truncated header: no end_header line");
        }
        if line_no == 1 {
            continue;
        }
        let bad = |what: &str| error!(Input, "header line {line_no}: {what}: {}", quote(text));
        let words: Vec<&str> = text.split_whitespace().collect();
        match words.as_slice() {
            [] | ["comment" | "obj_info", ..] => {}
            ["format", format, "1.0"] => {
                big_endian = match *format {
                    "ascii" => None,
                    "binary_little_endian" => Some(false),
                    "binary_big_endian" => Some(true),
                    _ => fail!(Input, "{}", unsupported(text)),
                };
                format_seen = true;
            }
            ["format", ..] => fail!(Input, "{}", unsupported(text)),
            ["element", name, count] => {
                let count = count
                    .parse()
                    .map_err(|_| bad("element count is not a non-negative integer"))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            ["property", rest @ ..] => {
                let kind = match rest {
                    ["list", count, item, _] => {
                        let count = Scalar::from_name(count).ok_or_else(|| bad("unknown list length type"))?;
                        let item = Scalar::from_name(item).ok_or_else(|| bad("unknown list item type"))?;
                        if count.is_float() {
                            return Err(bad("list length type must be an integer type"));
                        }
                        Kind::List { count, item }
                    }
                    [ty, _] => Kind::Scalar(Scalar::from_name(ty).ok_or_else(|| bad("unknown property type"))?),
                    _ => return Err(bad("malformed property")),
                };
                let name = rest.last().unwrap_or(&"").to_string();
                let element = elements.last_mut().ok_or_else(|| bad("property before any element"))?;
                element.props.push(Property { name, kind });
            }
            ["end_header"] => break,
            _ => return Err(bad("unknown header line")),
        }
    }
    if !format_seen {
        fail!(Input, "header has no format line");
    }
    Ok(Header {
        big_endian,
        elements,
        data_start: pos.min(bytes.len()),
        lines: line_no,
    })
}

fn unsupported(line: &str) -> String {
    format!(
        "unsupported PLY format {} (expected ascii, binary_little_endian or binary_big_endian 1.0)",
        quote(line)
    )
}

/// Which element and properties carry the geometry.
struct Roles {
    vertex: usize,
    xyz: [usize; 3],
    /// The element of the triangles: faces, or triangle strips (`strips`).
    face: usize,
    strips: bool,
    indices: usize,
    vertex_count: usize,
}

/// Where a triangle strip's index list starts a new strip.
const STRIP_RESTART: u32 = u32::MAX;

impl Roles {
    fn find(header: &Header) -> Result<Roles> {
        let elements = &header.elements;
        let vertex = elements
            .iter()
            .position(|e| e.name == "vertex")
            .ok_or_else(|| error!(Input, "header has no 'element vertex'"))?;
        let props = &elements[vertex].props;
        let mut xyz = [0; 3];
        for (axis, slot) in ["x", "y", "z"].into_iter().zip(&mut xyz) {
            *slot = props
                .iter()
                .position(|p| p.name == axis)
                .ok_or_else(|| error!(Input, "vertex element has no property '{axis}'"))?;
            if !matches!(props[*slot].kind, Kind::Scalar(_)) {
                fail!(Input, "vertex property '{axis}' is a list, expected a number");
            }
        }
        let faces = elements.iter().position(|e| e.name == "face");
        let strips = elements.iter().position(|e| e.name == "tristrips");
        let face = faces.or(strips).ok_or_else(|| {
            error!(
                Input,
                "no triangles: header has no 'element face' or 'element tristrips' (point clouds are not supported)"
            )
        })?;
        let props = &elements[face].props;
        let indices = props
            .iter()
            .position(|p| p.name == "vertex_indices" || p.name == "vertex_index")
            .ok_or_else(|| {
                error!(
                    Input,
                    "{} element has no property 'vertex_indices'", elements[face].name
                )
            })?;
        match props[indices].kind {
            Kind::List { item, .. } if !item.is_float() => {}
            _ => fail!(
                Input,
                "face property '{}' must be a list of integers",
                props[indices].name
            ),
        }
        Ok(Roles {
            vertex,
            xyz,
            face,
            strips: faces.is_none(),
            indices,
            vertex_count: elements[vertex].count,
        })
    }
}

enum ReadErr {
    Eof,
    Bad {
        line: usize,
        token: String,
    },
    /// An ASCII element's line ended before its last property.
    LineEnds {
        line: usize,
    },
    /// An ASCII element's line goes on after its last property.
    Extra {
        line: usize,
        token: String,
    },
}

trait Source {
    fn read(&mut self, ty: Scalar) -> Result<f64, ReadErr>;
    /// Called after an element's last property.
    fn end_element(&mut self) -> Result<(), ReadErr>;
    /// The line being read, for messages (ASCII only).
    fn line(&self) -> Option<usize>;
    fn len(&self) -> usize;
}

/// Whitespace-separated tokens, one element per line as the format has it: a line with a
/// value too many or too few is reported at that line, not where the shift shows later.
struct Ascii<'a> {
    bytes: &'a [u8],
    pos: usize,
    line: usize,
    starts_element: bool,
}

impl Ascii<'_> {
    /// Skips blanks within the line; true when the line (or the file) ends there.
    fn at_line_end(&mut self) -> bool {
        let b = self.bytes;
        while self.pos < b.len() && matches!(b[self.pos], b' ' | b'\t' | b'\r') {
            self.pos += 1;
        }
        self.pos >= b.len() || b[self.pos] == b'\n'
    }
}

impl Source for Ascii<'_> {
    fn read(&mut self, ty: Scalar) -> Result<f64, ReadErr> {
        let b = self.bytes;
        if !std::mem::replace(&mut self.starts_element, false) && self.at_line_end() && self.pos < b.len() {
            return Err(ReadErr::LineEnds { line: self.line });
        }
        while self.pos < b.len() && b[self.pos].is_ascii_whitespace() {
            self.line += usize::from(b[self.pos] == b'\n');
            self.pos += 1;
        }
        let start = self.pos;
        while self.pos < b.len() && !b[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        if start == self.pos {
            return Err(ReadErr::Eof);
        }
        let token = std::str::from_utf8(&b[start..self.pos]).unwrap_or("");
        // Integers must be written as integers: "3.0" as a list length or index is a damaged file.
        let value = if ty.is_float() {
            token.parse::<f64>().ok()
        } else {
            // Digits past 64 bits are still a number (far out of range), not a damaged token.
            token
                .parse::<i64>()
                .ok()
                .map(|i| i as f64)
                .or_else(|| is_integer(token).then(|| token.parse::<f64>().ok()).flatten())
        };
        value.ok_or_else(|| ReadErr::Bad {
            line: self.line,
            token: String::from_utf8_lossy(&b[start..self.pos]).into(),
        })
    }

    fn end_element(&mut self) -> Result<(), ReadErr> {
        self.starts_element = true;
        if self.at_line_end() {
            return Ok(());
        }
        let start = self.pos;
        while self.pos < self.bytes.len() && !self.bytes[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        Err(ReadErr::Extra {
            line: self.line,
            token: String::from_utf8_lossy(&self.bytes[start..self.pos]).into(),
        })
    }

    fn line(&self) -> Option<usize> {
        Some(self.line)
    }

    fn len(&self) -> usize {
        self.bytes.len()
    }
}

struct Binary<'a> {
    bytes: &'a [u8],
    pos: usize,
    big_endian: bool,
}

impl Binary<'_> {
    fn take<const N: usize>(&mut self) -> Result<[u8; N], ReadErr> {
        let slice = self.bytes.get(self.pos..self.pos + N).ok_or(ReadErr::Eof)?;
        self.pos += N;
        let mut a: [u8; N] = slice.try_into().map_err(|_| ReadErr::Eof)?;
        if self.big_endian {
            a.reverse();
        }
        Ok(a)
    }
}

impl Source for Binary<'_> {
    fn read(&mut self, ty: Scalar) -> Result<f64, ReadErr> {
        Ok(match ty {
            Scalar::I8 => i8::from_le_bytes(self.take()?) as f64,
            Scalar::U8 => u8::from_le_bytes(self.take()?) as f64,
            Scalar::I16 => i16::from_le_bytes(self.take()?) as f64,
            Scalar::U16 => u16::from_le_bytes(self.take()?) as f64,
            Scalar::I32 => i32::from_le_bytes(self.take()?) as f64,
            Scalar::U32 => u32::from_le_bytes(self.take()?) as f64,
            Scalar::F32 => f32::from_le_bytes(self.take()?) as f64,
            Scalar::F64 => f64::from_le_bytes(self.take()?),
        })
    }

    fn end_element(&mut self) -> Result<(), ReadErr> {
        Ok(())
    }

    fn line(&self) -> Option<usize> {
        None
    }

    fn len(&self) -> usize {
        self.bytes.len()
    }
}

fn plural(element: &str) -> String {
    match element {
        "vertex" => "vertices".into(),
        "face" => "faces".into(),
        other => format!("'{other}' elements"),
    }
}

fn read_error(err: ReadErr, element: &Element, i: usize, property: &str) -> Error {
    let (name, count) = (&element.name, element.count);
    match err {
        ReadErr::Eof => error!(
            Input,
            "truncated: expected {count} {}, file ends after {i}",
            plural(name)
        ),
        ReadErr::Bad { line, token } => error!(
            Input,
            "line {line}: expected a number for property '{property}' of {name} {i}, found {}",
            quote(&token)
        ),
        ReadErr::LineEnds { line } => error!(Input, "line {line}: {name} {i} ends before its property '{property}'"),
        ReadErr::Extra { line, token } => error!(
            Input,
            "line {line}: {name} {i} has more values than the header declares, starting at {}",
            quote(&token)
        ),
    }
}

/// A vertex's coordinates must be finite and fit in `f32`.
fn check_position(xyz: &[f64; 3], i: usize, line: Option<usize>) -> Result<()> {
    let at = line.map(|l| format!("line {l}: ")).unwrap_or_default();
    for (axis, &v) in ["x", "y", "z"].into_iter().zip(xyz) {
        if !v.is_finite() {
            fail!(Input, "{at}vertex {i} has a non-finite {axis} coordinate {v}");
        }
        if v.abs() > f32::MAX as f64 {
            fail!(
                Input,
                "{at}vertex {i}: {axis} coordinate {v:e} is beyond the 32-bit float range (+-3.4e38)"
            );
        }
    }
    Ok(())
}

fn read_body(src: &mut impl Source, header: &Header, roles: &Roles) -> Result<WorldMesh> {
    let mut mesh = WorldMesh::default();
    let mut polygon: Vec<u32> = Vec::new();
    for (e, element) in header.elements.iter().enumerate() {
        // An element without properties occupies no bytes; looping over a huge count of them would only hang.
        if element.props.is_empty() {
            continue;
        }
        let (is_vertex, is_face) = (e == roles.vertex, e == roles.face);
        // The header's count is untrusted: every element takes at least one byte, which bounds the reservation.
        let reserve = element.count.min(src.len());
        if is_vertex {
            mesh.positions.reserve(reserve);
        } else if is_face {
            mesh.triangles.reserve(reserve);
        }
        for i in 0..element.count {
            let mut xyz = [0.0f64; 3];
            polygon.clear();
            for (p, prop) in element.props.iter().enumerate() {
                let fail = |err| read_error(err, element, i, &prop.name);
                match prop.kind {
                    Kind::Scalar(ty) => {
                        let v = src.read(ty).map_err(fail)?;
                        if let Some(axis) = roles.xyz.iter().position(|&a| is_vertex && a == p) {
                            xyz[axis] = v;
                        }
                    }
                    Kind::List { count, item } => {
                        let n = src.read(count).map_err(fail)?;
                        if n < 0.0 {
                            fail!(
                                Input,
                                "{} {i}: property '{}' has a negative length {n}",
                                element.name,
                                prop.name
                            );
                        }
                        let keep = is_face && p == roles.indices;
                        for _ in 0..n as u64 {
                            let v = src.read(item).map_err(fail)?;
                            if keep && roles.strips && v == -1.0 {
                                polygon.push(STRIP_RESTART);
                            } else if keep {
                                if !(0.0..roles.vertex_count as f64).contains(&v) {
                                    let n = roles.vertex_count;
                                    let name = &element.name;
                                    fail!(Input, "{name} {i} refers to vertex {v} but the file has {n} vertices");
                                }
                                polygon.push(v as u32);
                            }
                        }
                    }
                }
            }
            src.end_element().map_err(|err| read_error(err, element, i, ""))?;
            if is_vertex {
                check_position(&xyz, i, src.line())?;
                mesh.positions.push(DVec3::from_array(xyz));
            } else if is_face && roles.strips {
                strip_triangles(&polygon, &mut mesh.triangles);
            } else if is_face {
                if polygon.len() < 3 {
                    fail!(Input, "face {i} has only {} vertices", polygon.len());
                }
                mesh.triangles
                    .extend(polygon.windows(2).skip(1).map(|w| [polygon[0], w[0], w[1]]));
            }
        }
    }
    Ok(mesh)
}

/// Appends the triangles of `indices`, triangle strips separated by [`STRIP_RESTART`]: the
/// `k`-th of a strip is its points `k, k + 1, k + 2`, the first two swapped for odd `k`, so
/// that all face the way the first does. A triangle with a repeated point has no area: such
/// triangles join strips, and are left out.
fn strip_triangles(indices: &[u32], triangles: &mut Vec<[u32; 3]>) {
    for strip in indices.split(|&v| v == STRIP_RESTART) {
        for (k, w) in strip.windows(3).enumerate() {
            let t = if k % 2 == 0 {
                [w[0], w[1], w[2]]
            } else {
                [w[1], w[0], w[2]]
            };
            if t[0] != t[1] && t[1] != t[2] && t[2] != t[0] {
                triangles.push(t);
            }
        }
    }
}

#[cfg(test)]
mod tests;
