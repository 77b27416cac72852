//! NVIDIA's `.bary` files (the BaryFile format, version 00100): the displacement values of a
//! micromap, one list per base triangle, read and written.
//!
//! A file is a header (a 16-byte version identifier, the total size, and where the table of
//! properties lies), the table (64 bytes a property: a 128-bit identifier, a byte range, and
//! supercompression fields that must say "none"), and the properties' bytes. Three properties
//! are mandatory: the values (a `ValuesInfo` header then the values), the groups (triangle and
//! value ranges, the subdivision levels used, and the bias and scale that map a stored value
//! to a displacement) and the triangles (each its values' offset within its group, its
//! subdivision level and a block format). Other properties are skipped when reading, except
//! the mesh properties ([`mesh_properties`]) and gridrt's own value code (see
//! [`Micromap::value_code`]): the widths of the compressed code whose decoder gives exactly
//! these values, so that a reader that knows the code traces them compressed, while any other
//! reads the same values plain.
//!
//! What is supported: per-vertex scalar displacements as 11-bit unorm values, packed
//! (`eR11_unorm_packed_align32`: each triangle's values one LSB-first bit stream over
//! little-endian 32-bit words, padded to a whole word, offsets and counts in bytes) or one to
//! 16 bits (`eR11_unorm_pack16`), in u-major order: for `u` in `0..=N`, for `v` in `0..=N-u`,
//! the vertex with barycentrics `(N-u-v, u, v)` on the triangle's corners, `N = 2^level`, or
//! in bird-curve order ([`bird_curve`]), or compressed in NVIDIA's blocks
//! (`eDispC1_r11_unorm_block`, decoded on reading: [`compressed_blocks`]). Per-triangle
//! values are refused by name. Every offset, count and level in a file is checked against the
//! bytes there are before anything is read, so a damaged file gives a one-line error, never a
//! panic or a huge allocation.

pub mod bird_curve;
pub mod compressed_blocks;
pub mod mesh_properties;

pub use mesh_properties::MeshProperties;
use mesh_properties::MeshProperty;

use crate::bit_writer::BitWriter;
use crate::error::{error, fail, Result};
use gridrt_shared::compressed_values::{ValueCode, MAX_LEVELS, VALUE_BITS, WIDTH_BITS};

/// The version identifier every file starts with: "«BARY 00100»\r\n\x1A\n".
pub const MAGIC: [u8; 16] = *b"\xABBARY 00100\xBB\r\n\x1A\n";

/// The deepest subdivision level read: `(2^10 + 1)(2^10 + 2) / 2` values a triangle already.
pub const MAX_LEVEL: u32 = 10;

const HEADER_BYTES: usize = 40;
const PROPERTY_INFO_BYTES: usize = 64;
const VALUES_INFO_BYTES: usize = 24;
const GROUP_BYTES: usize = 56;
const TRIANGLE_BYTES: usize = 8;

const VALUES_ID: [u32; 4] = [0xb44d_aa04, 0xc9e0_44d5, 0x9a94_4de0, 0xcfd8_fe35];
const GROUPS_ID: [u32; 4] = [0x39ee_40d0, 0x9dc4_4517, 0x8e5a_b15d, 0xb09c_74bc];
const TRIANGLES_ID: [u32; 4] = [0x0045_8e68, 0xee59_426c, 0xb3bf_1b7f, 0x749d_eb8e];
const HISTOGRAM_ENTRIES_ID: [u32; 4] = [0x6e75_6bc1, 0x839a_438a, 0xad4a_745e, 0x556c_3851];
const GROUP_HISTOGRAMS_ID: [u32; 4] = [0x400d_972f, 0x76dd_4337, 0x9900_c6e9, 0xc9c4_6ffe];
/// Where compressed blocks start, and the alignment their values' header states.
const BLOCK_ALIGNMENT: usize = 128;
/// gridrt's own property: a version word, then a [`ValueCode`]'s levels and widths.
const VALUE_CODE_ID: [u32; 4] = [0x6772_6964, 0x7274_2d76, 0x616c_7565, 0x636f_6465];
const VALUE_CODE_VERSION: u32 = 1;
const VALUE_CODE_BYTES: usize = 12;

const FORMAT_DISP_C1_BLOCK: u32 = 1_000_397_000;
const FORMAT_R11_PACK16: u32 = 1_000_397_001;
const FORMAT_R11_PACKED_ALIGN32: u32 = 1_000_397_002;
const LAYOUT_U_MAJOR: u32 = 1;
const LAYOUT_BIRD_CURVE: u32 = 2;
const FREQUENCY_PER_VERTEX: u32 = 1;

/// The largest 11-bit unorm value: `d = value / 2047 * scale + bias`.
pub const UNORM11_MAX: u16 = 2047;

/// A micromap's displacement values, as a program uses them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Micromap {
    pub groups: Vec<MicromapGroup>,
    pub triangles: Vec<MicromapTriangle>,
    /// Every triangle's values, each triangle's in u-major order, back to back.
    pub values: Vec<u16>,
    /// Set when the values are exactly those a compressed code of these widths decodes to
    /// (see `crate::grid::compressed`): displaced grids then store them compressed.
    pub value_code: Option<ValueCode>,
    /// Set when the values are to be written in NVIDIA's compressed blocks
    /// ([`compressed_blocks`]), as they were read: [`write`] stores each triangle in its
    /// level's format where that gives every value back (it does for values it decoded), and
    /// exactly in level-3 blocks otherwise.
    pub nv_blocks: bool,
}

/// Consecutive triangles sharing one mapping of stored values to displacements.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MicromapGroup {
    pub triangle_first: u32,
    pub triangle_count: u32,
    /// A stored value `q` is the displacement `q / 2047 * scale + bias`.
    pub bias: f32,
    pub scale: f32,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MicromapTriangle {
    pub level: u32,
    /// Where its values start in [`Micromap::values`].
    pub first_value: u32,
}

/// Values of one triangle at `level`: the vertices of its level-`level` lattice.
pub fn values_per_triangle(level: u32) -> usize {
    let n = 1usize << level;
    (n + 1) * (n + 2) / 2
}

/// Bytes of one triangle's values packed 11 bits each into whole 32-bit words.
pub fn packed_bytes(level: u32) -> usize {
    (values_per_triangle(level) * 11).div_ceil(32) * 4
}

impl Micromap {
    /// Triangle `t`'s values, u-major.
    pub fn triangle_values(&self, t: usize) -> &[u16] {
        let triangle = &self.triangles[t];
        let first = triangle.first_value as usize;
        &self.values[first..first + values_per_triangle(triangle.level)]
    }

    /// Appends `other`'s groups, triangles and values after this micromap's. The values keep
    /// a compressed code only where both parts had the same one.
    pub fn append(&mut self, other: &Micromap) {
        self.join_storage(other);
        let (triangles, values) = (self.triangles.len() as u32, self.values.len() as u32);
        self.groups.extend(other.groups.iter().map(|g| MicromapGroup {
            triangle_first: g.triangle_first + triangles,
            ..*g
        }));
        self.triangles.extend(other.triangles.iter().map(|t| MicromapTriangle {
            first_value: t.first_value + values,
            ..*t
        }));
        self.values.extend_from_slice(&other.values);
    }

    /// How the values are kept once some of `other`'s are appended: its value code and
    /// blocks when there are none yet, otherwise what both share.
    pub fn join_storage(&mut self, other: &Micromap) {
        let first = self.triangles.is_empty();
        self.value_code = match first {
            true => other.value_code,
            false => self.value_code.filter(|_| self.value_code == other.value_code),
        };
        self.nv_blocks = (first || self.nv_blocks) && other.nv_blocks;
    }

    /// A micromap of one group: each triangle's level and values (u-major), in order.
    pub fn from_triangles(bias: f32, scale: f32, triangles: &[(u32, Vec<u16>)]) -> Micromap {
        let mut map = Micromap {
            groups: vec![MicromapGroup {
                triangle_first: 0,
                triangle_count: triangles.len() as u32,
                bias,
                scale,
            }],
            ..Micromap::default()
        };
        for (level, values) in triangles {
            assert_eq!(
                values.len(),
                values_per_triangle(*level),
                "values of a level-{level} triangle"
            );
            map.triangles.push(MicromapTriangle {
                level: *level,
                first_value: map.values.len() as u32,
            });
            map.values.extend(values.iter().map(|&v| v.min(UNORM11_MAX)));
        }
        map
    }
}

/// Little-endian reads at byte offsets, checked.
struct Reader<'a>(&'a [u8]);

impl Reader<'_> {
    fn u32(&self, at: usize) -> Result<u32> {
        let b = self
            .0
            .get(at..at.saturating_add(4))
            .ok_or_else(|| error!(Input, "truncated at byte {at}"))?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn u64(&self, at: usize) -> Result<u64> {
        Ok(u64::from(self.u32(at)?) | u64::from(self.u32(at + 4)?) << 32)
    }

    fn f32(&self, at: usize) -> Result<f32> {
        Ok(f32::from_bits(self.u32(at)?))
    }
}

/// A byte range of the file, checked to lie within it.
fn range(file: &Reader, at: usize, what: &str) -> Result<std::ops::Range<usize>> {
    let (offset, length) = (file.u64(at)?, file.u64(at + 8)?);
    let end = offset.checked_add(length).filter(|&e| e <= file.0.len() as u64);
    match end {
        Some(end) => Ok(offset as usize..end as usize),
        None => fail!(
            Input,
            "{what} spans bytes {offset} to {} of a {}-byte file",
            offset as u128 + length as u128,
            file.0.len()
        ),
    }
}

/// Reads a `.bary` file's bytes. Errors carry no file name; the caller adds it.
pub fn read(bytes: &[u8]) -> Result<Micromap> {
    Ok(read_with_mesh(bytes)?.0)
}

/// Reads a `.bary` file's bytes: its micromap, and the mesh properties it carries.
pub fn read_with_mesh(bytes: &[u8]) -> Result<(Micromap, MeshProperties)> {
    let file = Reader(bytes);
    let start = &bytes[..bytes.len().min(MAGIC.len())];
    if bytes.len() < HEADER_BYTES && start == &MAGIC[..start.len()] {
        fail!(
            Input,
            "truncated: {} bytes, less than the {HEADER_BYTES}-byte header of a .bary file",
            bytes.len()
        );
    }
    if bytes.len() < HEADER_BYTES || bytes[..16] != MAGIC {
        let shown = String::from_utf8_lossy(&bytes[..bytes.len().min(16)])
            .escape_debug()
            .to_string();
        fail!(
            Input,
            "not a .bary file of version 00100: it starts with \"{shown}\" ({} bytes)",
            bytes.len()
        );
    }
    let total = file.u64(16)?;
    if total != bytes.len() as u64 {
        let what = if total > bytes.len() as u64 {
            "truncated"
        } else {
            "damaged"
        };
        fail!(
            Input,
            "{what}: its header declares {total} bytes, the file has {}",
            bytes.len()
        );
    }
    let table = range(&file, 24, "the property table")?;
    if table.start < HEADER_BYTES || !table.len().is_multiple_of(PROPERTY_INFO_BYTES) {
        fail!(
            Input,
            "damaged property table: {} bytes at byte {}",
            table.len(),
            table.start
        );
    }
    let (mut values, mut groups, mut triangles, mut code) = (None, None, None, None);
    let mut mesh_ranges: [Option<std::ops::Range<usize>>; MeshProperty::ALL.len()] = Default::default();
    for at in table.clone().step_by(PROPERTY_INFO_BYTES) {
        let id = [0, 4, 8, 12].map(|k| file.u32(at + k).unwrap_or(0));
        let mesh = MeshProperty::ALL.iter().position(|(_, i)| *i == id);
        let (slot, name) = match (id, mesh) {
            (_, Some(k)) => (&mut mesh_ranges[k], MeshProperty::ALL[k].0.name()),
            (VALUES_ID, _) => (&mut values, "values"),
            (GROUPS_ID, _) => (&mut groups, "groups"),
            (TRIANGLES_ID, _) => (&mut triangles, "triangles"),
            (VALUE_CODE_ID, _) => (&mut code, "gridrt value code"),
            _ => continue,
        };
        if file.u32(at + 32)? != 0 {
            fail!(
                Input,
                "its {name} property is supercompressed, which no reader supports"
            );
        }
        let bytes = range(&file, at + 16, &format!("its {name} property"))?;
        if slot.replace(bytes).is_some() {
            fail!(Input, "its {name} property appears twice");
        }
    }
    let mut mesh = MeshProperties::default();
    for (&(property, _), bytes) in MeshProperty::ALL.iter().zip(mesh_ranges) {
        if let Some(bytes) = bytes {
            mesh.read(&file, property, bytes)?;
        }
    }
    let missing = |name: &str| error!(Input, "it has no {name} property");
    let values = values.ok_or_else(|| missing("values"))?;
    let groups = groups.ok_or_else(|| missing("groups"))?;
    let triangles = triangles.ok_or_else(|| missing("triangles"))?;
    let stream = value_stream(&file, values)?;
    let mut map = decode(&file, &stream, groups, triangles)?;
    map.nv_blocks = stream.storage == Storage::Blocks;
    if let Some(code) = code {
        map.value_code = value_code(&file, code, &map.triangles)?;
    }
    Ok((map, mesh))
}

/// gridrt's value code property, checked against the triangles' levels. A code of another
/// version is skipped (the values read plain).
fn value_code(
    file: &Reader,
    bytes: std::ops::Range<usize>,
    triangles: &[MicromapTriangle],
) -> Result<Option<ValueCode>> {
    if bytes.len() < VALUE_CODE_BYTES {
        fail!(Input, "its gridrt value code property has {} bytes", bytes.len());
    }
    if file.u32(bytes.start)? != VALUE_CODE_VERSION {
        return Ok(None);
    }
    let code = ValueCode {
        levels: file.u32(bytes.start + 4)?,
        widths: file.u32(bytes.start + 8)?,
    };
    let fits = (0..=MAX_LEVELS).contains(&code.levels)
        && code.widths >> (WIDTH_BITS * code.levels) == 0
        && (1..=code.levels).all(|l| code.width(l) <= VALUE_BITS);
    if !fits {
        fail!(
            Input,
            "its gridrt value code property is damaged: levels {}, widths {:#x}",
            code.levels,
            code.widths
        );
    }
    // The code is for the deepest level, which triangles of mixed levels share.
    let deepest = triangles.iter().map(|t| t.level).max().unwrap_or(code.levels);
    if deepest != code.levels {
        fail!(
            Input,
            "its gridrt value code is for level {}, and its deepest triangle is at level {deepest}",
            code.levels,
        );
    }
    Ok(Some(code))
}

/// How a file stores its values.
#[derive(Clone, Copy, PartialEq)]
enum Storage {
    /// 11-bit values packed into words; offsets in bytes.
    Packed,
    /// One value to two bytes; offsets in values.
    Pack16,
    /// Compressed blocks ([`compressed_blocks`]); offsets in bytes.
    Blocks,
}

impl Storage {
    /// The bytes of a unit of offset and count: a value's bytes, or one byte where values
    /// are packed or blocked.
    fn unit_bytes(self) -> usize {
        match self {
            Storage::Pack16 => 2,
            Storage::Packed | Storage::Blocks => 1,
        }
    }
}

/// How the values are stored, and their bytes.
struct ValueStream<'a> {
    storage: Storage,
    /// Each triangle's values in bird-curve order ([`bird_curve`]) rather than u-major.
    bird_curve: bool,
    bytes: &'a [u8],
}

fn value_stream<'a>(file: &Reader<'a>, values: std::ops::Range<usize>) -> Result<ValueStream<'a>> {
    if values.len() < VALUES_INFO_BYTES {
        fail!(
            Input,
            "its values property has {} bytes, less than its header",
            values.len()
        );
    }
    let at = values.start;
    let [format, layout, frequency, count, size, alignment] =
        [0, 4, 8, 12, 16, 20].map(|k| file.u32(at + k).unwrap_or(0));
    let storage = match format {
        FORMAT_R11_PACKED_ALIGN32 => Storage::Packed,
        FORMAT_R11_PACK16 => Storage::Pack16,
        FORMAT_DISP_C1_BLOCK => Storage::Blocks,
        other => fail!(
            Input,
            "its values have format {other}: gridrt reads 11-bit unorm displacements (eR11_unorm_packed_align32, eR11_unorm_pack16 or eDispC1_r11_unorm_block)"
        ),
    };
    // Blocks fix their own order of values, whatever the layout says.
    let bird_curve = match layout {
        _ if storage == Storage::Blocks => false,
        LAYOUT_U_MAJOR => false,
        LAYOUT_BIRD_CURVE => true,
        other => fail!(Input, "its values have an unknown layout {other}"),
    };
    if frequency != FREQUENCY_PER_VERTEX {
        fail!(
            Input,
            "its values are not per vertex (frequency {frequency}): gridrt reads vertex displacements"
        );
    }
    let expected_size = storage.unit_bytes() as u32;
    if size != expected_size {
        fail!(
            Input,
            "its values claim {size} bytes each where the format has {expected_size}"
        );
    }
    if alignment < 4 || !alignment.is_power_of_two() {
        fail!(
            Input,
            "its values' alignment of {alignment} bytes is not a power of two of at least 4"
        );
    }
    let start = VALUES_INFO_BYTES.next_multiple_of(alignment as usize);
    let length = count as usize * size as usize;
    let bytes = file
        .0
        .get(at + start..at + start + length)
        .filter(|_| start + length <= values.len());
    let bytes = bytes.ok_or_else(|| {
        error!(
            Input,
            "its {count} values of {size} bytes do not fit in its values property of {} bytes",
            values.len()
        )
    })?;
    Ok(ValueStream {
        storage,
        bird_curve,
        bytes,
    })
}

/// The groups and triangles, each triangle's values read from the stream.
fn decode(
    file: &Reader,
    stream: &ValueStream,
    groups: std::ops::Range<usize>,
    triangles: std::ops::Range<usize>,
) -> Result<Micromap> {
    if !groups.len().is_multiple_of(GROUP_BYTES) || !triangles.len().is_multiple_of(TRIANGLE_BYTES) {
        fail!(
            Input,
            "its groups ({} bytes) or triangles ({} bytes) are not whole records",
            groups.len(),
            triangles.len()
        );
    }
    let triangle_count = triangles.len() / TRIANGLE_BYTES;
    let mut map = Micromap::default();
    let mut next_triangle = 0u32;
    let mut bird_positions: Vec<Option<Vec<u32>>> = vec![None; MAX_LEVEL as usize + 1];
    for (g, at) in groups.step_by(GROUP_BYTES).enumerate() {
        let [first, count, value_first, value_count] = [0, 4, 8, 12].map(|k| file.u32(at + k).unwrap_or(0));
        if first != next_triangle || first as usize + count as usize > triangle_count {
            fail!(
                Input,
                "group {g} holds triangles {first} to {} of {triangle_count}: groups must cover the triangles in order",
                first as u64 + count as u64
            );
        }
        next_triangle = first + count;
        let unit = stream.storage.unit_bytes();
        let group_bytes = (value_first as usize * unit)..(value_first as usize + value_count as usize) * unit;
        let group_values = stream.bytes.get(group_bytes).ok_or_else(|| {
            error!(
                Input,
                "group {g}'s values {value_first} to {} lie past the values stored",
                value_first as u64 + value_count as u64
            )
        })?;
        let (bias, scale) = (file.f32(at + 24)?, file.f32(at + 40)?);
        if !(bias.is_finite() && scale.is_finite()) {
            fail!(Input, "group {g}'s bias {bias} or scale {scale} is not a finite number");
        }
        map.groups.push(MicromapGroup {
            triangle_first: first,
            triangle_count: count,
            bias,
            scale,
        });
        // Offsets ascend, each triangle's values after the last one's: so no file decodes to
        // more values than it stores.
        let mut free_from = 0usize;
        for t in first as usize..(first + count) as usize {
            let at = triangles.start + t * TRIANGLE_BYTES;
            let (offset, word) = (file.u32(at)? as usize, file.u32(at + 4)?);
            let (level, block_format) = (word & 0xffff, (word >> 16) as u16);
            if offset < free_from {
                fail!(
                    Input,
                    "triangle {t}'s values at {offset} overlap the triangle before it's"
                );
            }
            let (mut values, length) = triangle_values(stream.storage, group_values, offset, level, block_format)
                .map_err(|e| error!(Input, "triangle {t}: {e}"))?;
            if stream.bird_curve {
                let positions =
                    bird_positions[level as usize].get_or_insert_with(|| bird_curve::u_major_positions(level));
                let mut u_major = vec![0; values.len()];
                for (&p, &value) in positions.iter().zip(&values) {
                    u_major[p as usize] = value;
                }
                values = u_major;
            }
            free_from = offset + length;
            map.triangles.push(MicromapTriangle {
                level,
                first_value: map.values.len() as u32,
            });
            map.values.extend(values);
        }
    }
    if next_triangle as usize != triangle_count {
        fail!(
            Input,
            "its groups cover {next_triangle} of its {triangle_count} triangles"
        );
    }
    Ok(map)
}

/// One triangle's values from its group's bytes, and how many units of offset (bytes or
/// values) they take there.
fn triangle_values(
    storage: Storage,
    group: &[u8],
    offset: usize,
    level: u32,
    block_format: u16,
) -> Result<(Vec<u16>, usize)> {
    if level > MAX_LEVEL {
        fail!(
            Input,
            "subdivision level {level} is past the deepest gridrt reads ({MAX_LEVEL})"
        );
    }
    let count = values_per_triangle(level);
    let (start, length) = match storage {
        Storage::Packed => (offset, packed_bytes(level)),
        Storage::Pack16 => (offset * 2, count * 2),
        Storage::Blocks => (offset, compressed_blocks::triangle_bytes(level, block_format)?),
    };
    let bytes = group.get(start..start + length).ok_or_else(|| {
        error!(
            Input,
            "its level-{level} values at {offset} lie past its group's {} bytes",
            group.len()
        )
    })?;
    let word = |k: usize| u32::from_le_bytes([bytes[4 * k], bytes[4 * k + 1], bytes[4 * k + 2], bytes[4 * k + 3]]);
    let values = match storage {
        Storage::Blocks => return Ok((compressed_blocks::triangle_values(bytes, level, block_format)?, length)),
        Storage::Packed => (0..count)
            .map(|i| {
                // Value i is bits 11i .. 11i + 10 of the stream, which may straddle two words.
                let bit = 11 * i;
                let (k, shift) = (bit / 32, bit % 32);
                let low = word(k) >> shift;
                let high = if shift > 21 { word(k + 1) << (32 - shift) } else { 0 };
                ((low | high) & 0x7ff) as u16
            })
            .collect(),
        Storage::Pack16 => (0..count)
            .map(|i| u16::from_le_bytes([bytes[2 * i], bytes[2 * i + 1]]) & 0x7ff)
            .collect(),
    };
    Ok((values, length / storage.unit_bytes()))
}

/// Packs values 11 bits each, LSB first, into little-endian words: [`packed_bytes`] bytes.
fn pack(values: &[u16], out: &mut Vec<u8>) {
    let values = values.iter().map(|&v| u32::from(v.min(UNORM11_MAX)));
    let mut words = BitWriter::packed(values.clone(), 11);
    words.resize((values.len() * 11).div_ceil(32), 0);
    out.extend(words.iter().flat_map(|w| w.to_le_bytes()));
}

/// Each triangle's values in NVIDIA's blocks, where `map` asks for them.
fn exact_blocks(map: &Micromap) -> Option<Vec<compressed_blocks::EncodedTriangle>> {
    map.nv_blocks.then(|| {
        (0..map.triangles.len())
            .map(|t| compressed_blocks::encode_exactly(map.triangle_values(t), map.triangles[t].level))
            .collect()
    })
}

/// The bytes of a `.bary` file holding `map`: its values per vertex, packed 11 bits each
/// (`eR11_unorm_packed_align32`, u-major) or in NVIDIA's blocks ([`Micromap::nv_blocks`]), its
/// groups and triangles, and its value code if it has one.
pub fn write(map: &Micromap) -> Vec<u8> {
    let blocks = exact_blocks(map);
    let mut values = Vec::new();
    let mut triangles = Vec::with_capacity(map.triangles.len() * TRIANGLE_BYTES);
    let mut groups = Vec::with_capacity(map.groups.len() * GROUP_BYTES);
    let mut histograms = Vec::new();
    for group in &map.groups {
        if blocks.is_some() {
            values.resize(values.len().next_multiple_of(BLOCK_ALIGNMENT), 0);
        }
        let value_first = values.len();
        let range = group.triangle_first as usize..(group.triangle_first + group.triangle_count) as usize;
        let levels = range.clone().map(|t| map.triangles[t].level);
        let (min_level, max_level) = (levels.clone().min().unwrap_or(0), levels.max().unwrap_or(0));
        let mut histogram = std::collections::BTreeMap::new();
        for t in range {
            if let Some(blocks) = &blocks {
                // A triangle's blocks start at a multiple of their size within the group.
                let size = compressed_blocks::block_bytes(blocks[t].block_format);
                values.resize(value_first + (values.len() - value_first).next_multiple_of(size), 0);
                *histogram
                    .entry((map.triangles[t].level, blocks[t].block_format))
                    .or_insert(0) += 1;
            }
            triangles.extend(((values.len() - value_first) as u32).to_le_bytes());
            triangles.extend((map.triangles[t].level as u16).to_le_bytes());
            match &blocks {
                Some(blocks) => {
                    triangles.extend(blocks[t].block_format.to_le_bytes());
                    values.extend(&blocks[t].bytes);
                }
                None => {
                    triangles.extend(0u16.to_le_bytes());
                    pack(map.triangle_values(t), &mut values);
                }
            }
        }
        let words = [
            group.triangle_first,
            group.triangle_count,
            value_first as u32,
            (values.len() - value_first) as u32,
            min_level,
            max_level,
        ];
        histograms.push(histogram);
        groups.extend(words.iter().flat_map(|w| w.to_le_bytes()));
        for first in [group.bias, group.scale] {
            groups.extend([first, 0.0, 0.0, 0.0].iter().flat_map(|f| f.to_le_bytes()));
        }
    }
    // Blocks are aligned to 128 bytes, and in bird-curve order within.
    let (format, layout, alignment) = match blocks {
        Some(_) => (FORMAT_DISP_C1_BLOCK, LAYOUT_BIRD_CURVE, BLOCK_ALIGNMENT as u32),
        None => (FORMAT_R11_PACKED_ALIGN32, LAYOUT_U_MAJOR, 4),
    };
    let info = [format, layout, FREQUENCY_PER_VERTEX, values.len() as u32, 1, alignment];
    let mut header: Vec<u8> = info.iter().flat_map(|w| w.to_le_bytes()).collect();
    header.resize(VALUES_INFO_BYTES.next_multiple_of(alignment as usize), 0);
    let values: Vec<u8> = header.into_iter().chain(values).collect();
    let mut properties = vec![(VALUES_ID, values), (GROUPS_ID, groups), (TRIANGLES_ID, triangles)];
    if blocks.is_some() {
        // Compressed values must say how many triangles take each block format and level.
        let (entries, ranges) = block_histograms(&histograms);
        properties.push((HISTOGRAM_ENTRIES_ID, entries));
        properties.push((GROUP_HISTOGRAMS_ID, ranges));
    }
    if let Some(code) = map.value_code {
        let words = [VALUE_CODE_VERSION, code.levels, code.widths];
        properties.push((VALUE_CODE_ID, words.iter().flat_map(|w| w.to_le_bytes()).collect()));
    }
    container(&properties)
}

/// The histogram properties of compressed values: for each group, how many of its
/// triangles take each pairing of level and block format (entries of count, level and block
/// format), and each group's range of those entries.
fn block_histograms(groups: &[std::collections::BTreeMap<(u32, u16), u32>]) -> (Vec<u8>, Vec<u8>) {
    let (mut entries, mut ranges) = (Vec::new(), Vec::new());
    let mut first = 0u32;
    for group in groups {
        for (&(level, block_format), &count) in group {
            entries.extend([count, level, block_format as u32].iter().flat_map(|w| w.to_le_bytes()));
        }
        ranges.extend([first, group.len() as u32].iter().flat_map(|w| w.to_le_bytes()));
        first += group.len() as u32;
    }
    (entries, ranges)
}

/// Header, property table and properties, each right after the one before at a 4-byte
/// boundary, in table order (as NVIDIA's reader requires: no other gaps).
fn container(properties: &[([u32; 4], Vec<u8>)]) -> Vec<u8> {
    let table = properties.len() * PROPERTY_INFO_BYTES;
    let mut offsets = Vec::new();
    let mut end = HEADER_BYTES + table;
    for (_, bytes) in properties {
        end = end.next_multiple_of(4);
        offsets.push(end);
        end += bytes.len();
    }
    let mut out = Vec::with_capacity(end);
    out.extend(MAGIC);
    out.extend((end as u64).to_le_bytes());
    out.extend((HEADER_BYTES as u64).to_le_bytes());
    out.extend((table as u64).to_le_bytes());
    for ((id, bytes), offset) in properties.iter().zip(&offsets) {
        out.extend(id.iter().flat_map(|w| w.to_le_bytes()));
        out.extend((*offset as u64).to_le_bytes());
        out.extend((bytes.len() as u64).to_le_bytes());
        // No supercompression: scheme, padding, uncompressed length and global data all zero.
        out.extend([0u8; 32]);
    }
    for ((_, bytes), &offset) in properties.iter().zip(&offsets) {
        out.resize(offset, 0);
        out.extend(bytes);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(seed: &mut u64) -> u64 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        *seed >> 33
    }

    fn sample_map() -> Micromap {
        let mut seed = 11;
        let triangles: Vec<(u32, Vec<u16>)> = [0, 1, 2, 3, 5, 3]
            .iter()
            .map(|&level| {
                let values = (0..values_per_triangle(level))
                    .map(|_| (lcg(&mut seed) % 2048) as u16)
                    .collect();
                (level, values)
            })
            .collect();
        Micromap::from_triangles(-0.25, 1.5, &triangles)
    }

    #[test]
    fn packed_sizes_match_the_format() {
        let sizes: Vec<usize> = (0..=5).map(packed_bytes).collect();
        assert_eq!(sizes, [8, 12, 24, 64, 212, 772]);
    }

    #[test]
    fn a_written_file_reads_back_identically() {
        let map = sample_map();
        let bytes = write(&map);
        assert_eq!(read(&bytes).unwrap(), map);
    }

    /// Properties follow the table in its order, each at the first 4-byte boundary after the
    /// one before, and end the file: NVIDIA's reader takes no other layout.
    #[test]
    fn properties_are_packed_in_table_order() {
        let blocks = Micromap {
            nv_blocks: true,
            ..sample_map()
        };
        for map in [sample_map(), blocks] {
            let bytes = write(&map);
            let word = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
            let (table, length) = (word(24), word(32));
            assert_eq!(table, HEADER_BYTES);
            let mut end = table + length;
            for at in (table..table + length).step_by(PROPERTY_INFO_BYTES) {
                assert_eq!(word(at + 16), end.next_multiple_of(4));
                end = word(at + 16) + word(at + 24);
            }
            assert_eq!(end, bytes.len());
        }
    }

    /// Values asked for in blocks are written so, and read back identically: in their level's
    /// format where it gives them back (levels up to 3 always; deeper, values it decoded), in
    /// level-3 blocks otherwise.
    #[test]
    fn values_in_blocks_read_back_identically() {
        let block_formats = |bytes: &[u8]| {
            let table = u64::from_le_bytes(bytes[184..192].try_into().unwrap()) as usize;
            let count = u64::from_le_bytes(bytes[192..200].try_into().unwrap()) as usize / TRIANGLE_BYTES;
            let format = |t: usize| u16::from_le_bytes(bytes[table + 8 * t + 6..table + 8 * t + 8].try_into().unwrap());
            (0..count).map(format).collect::<Vec<u16>>()
        };
        let random = Micromap {
            nv_blocks: true,
            ..sample_map()
        };
        let bytes = write(&random);
        assert_eq!(read(&bytes).unwrap(), random);
        // Levels 0, 1, 2, 3, 5, 3: random values at level 5 take exact level-3 blocks.
        assert_eq!(block_formats(&bytes), [1, 1, 1, 1, 1, 1]);
        let decoded: Vec<(u32, Vec<u16>)> = (0..random.triangles.len())
            .map(|t| {
                let level = random.triangles[t].level;
                let values = compressed_blocks::encode_triangle(random.triangle_values(t), level).decoded;
                (level, values)
            })
            .collect();
        let blocks = Micromap {
            nv_blocks: true,
            ..Micromap::from_triangles(-0.25, 1.5, &decoded)
        };
        let bytes = write(&blocks);
        assert_eq!(read(&bytes).unwrap(), blocks);
        assert_eq!(block_formats(&bytes), [1, 1, 1, 1, 3, 1]);
        // What the format asks of compressed files: each triangle's blocks at a multiple of
        // their size (64 or 128 bytes), a histogram of (count, level, block format) and each
        // group's range of it.
        let words = |id: [u32; 4]| -> Vec<u32> {
            let word = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
            let (table, length) = (word(24) as usize, word(32) as usize);
            let at = (table..table + length)
                .step_by(PROPERTY_INFO_BYTES)
                .find(|&at| [0, 4, 8, 12].map(|k| word(at + k)) == id)
                .expect("the property");
            let (offset, length) = (word(at + 16) as usize, word(at + 24) as usize);
            (offset..offset + length).step_by(4).map(word).collect()
        };
        let offsets: Vec<u32> = words(TRIANGLES_ID).into_iter().step_by(2).collect();
        assert_eq!(offsets, [0, 64, 128, 192, 256, 384]);
        assert_eq!(
            words(HISTOGRAM_ENTRIES_ID),
            [1, 0, 1, 1, 1, 1, 1, 2, 1, 2, 3, 1, 1, 5, 3]
        );
        assert_eq!(words(GROUP_HISTOGRAMS_ID), [0, 5]);
    }

    #[test]
    fn a_value_code_reads_back_beside_the_same_values() {
        let plain = Micromap::from_triangles(0.0, 1.0, &[(3, vec![5; 45]), (3, vec![9; 45])]);
        let coded = Micromap {
            value_code: Some(ValueCode {
                levels: 3,
                widths: 0x453,
            }),
            ..plain.clone()
        };
        let bytes = write(&coded);
        assert_eq!(read(&bytes).unwrap(), coded);
        let plain_bytes = write(&plain);
        assert!(bytes.len() <= plain_bytes.len() + PROPERTY_INFO_BYTES + 8 + VALUE_CODE_BYTES);
        // The code's property id changed: skipped like any unknown property.
        let table = HEADER_BYTES + 3 * PROPERTY_INFO_BYTES;
        let mut unknown = bytes.clone();
        unknown[table] ^= 1;
        assert_eq!(read(&unknown).unwrap(), plain);
        let damaged = |at: usize, word: u32| {
            let offset = u64::from_le_bytes(bytes[table + 16..table + 24].try_into().unwrap()) as usize;
            let mut bytes = bytes.clone();
            bytes[offset + at..offset + at + 4].copy_from_slice(&word.to_le_bytes());
            read(&bytes).map_err(|e| e.to_string())
        };
        let e = damaged(4, 4).unwrap_err();
        assert!(e.contains("value code is for level 4") && !e.contains('\n'), "{e}");
        let e = damaged(8, 0xc00).unwrap_err();
        assert!(e.contains("value code property is damaged"), "{e}");
        assert_eq!(damaged(0, 2).unwrap(), plain, "a later version is skipped");
    }

    /// A file laid out by hand from the format's description, independently of `write`: one
    /// group, one level-1 triangle (six values), the properties in another order (triangles,
    /// an unknown property, groups, values) and the values as 16-bit words.
    #[test]
    fn a_file_written_by_hand_is_read() {
        let le = |words: &[u32]| words.iter().flat_map(|w| w.to_le_bytes()).collect::<Vec<u8>>();
        let values = [0u16, 2047, 1, 1024, 77, 2000];
        let mut values_property = le(&[FORMAT_R11_PACK16, 1, 1, 6, 2, 4]);
        values_property.extend(values.iter().flat_map(|v| v.to_le_bytes()));
        let mut groups_property = le(&[0, 1, 0, 6, 1, 1]);
        groups_property.extend(le(&[0.5f32.to_bits(), 0, 0, 0, 2.0f32.to_bits(), 0, 0, 0]));
        let triangles_property = le(&[0, 1]);
        let unknown = vec![7u8; 12];
        let properties = [
            (TRIANGLES_ID, triangles_property),
            ([1, 2, 3, 4], unknown),
            (GROUPS_ID, groups_property),
            (VALUES_ID, values_property),
        ];
        let map = read(&container(&properties)).unwrap();
        assert_eq!(map.groups[0].bias, 0.5);
        assert_eq!(map.groups[0].scale, 2.0);
        assert_eq!(
            map.triangles,
            vec![MicromapTriangle {
                level: 1,
                first_value: 0
            }]
        );
        assert_eq!(map.triangle_values(0), values);
    }

    /// The packed stream bit by bit: value i at bits 11i .. 11i + 10, straddling words.
    #[test]
    fn packing_is_lsb_first_across_words() {
        let mut out = Vec::new();
        pack(&[1, 2, 2047], &mut out);
        let word0 = u32::from_le_bytes(out[0..4].try_into().unwrap());
        let word1 = u32::from_le_bytes(out[4..8].try_into().unwrap());
        assert_eq!(word0, 1 | 2 << 11 | (2047 & 0x3ff) << 22);
        assert_eq!(word1, 2047 >> 10);
    }

    /// The fuzz target's seeds, written by a script of their own from the format's
    /// description: packed and 16-bit values, mixed and uniform levels.
    #[test]
    fn the_seed_files_read() {
        let seeds = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../fuzz/corpus/bary"));
        for (name, levels) in [
            ("packed_levels_0_to_3.bary", vec![0, 1, 2, 3]),
            ("pack16_levels_1_2.bary", vec![1, 2]),
            ("uniform_level_3.bary", vec![3; 4]),
            ("uniform_level_3_value_code.bary", vec![3; 4]),
            ("packed_levels_0_to_3_bird_curve.bary", vec![0, 1, 2, 3]),
            // The first file's values in NVIDIA's level-3 blocks, one a triangle.
            ("blocks_levels_0_to_3.bary", vec![0, 1, 2, 3]),
        ] {
            let map = read(&std::fs::read(seeds.join(name)).unwrap()).unwrap_or_else(|e| panic!("{name}: {e}"));
            let read_levels: Vec<u32> = map.triangles.iter().map(|t| t.level).collect();
            assert_eq!(read_levels, levels, "{name}");
            // The script's values: (37 i + 101 k) mod 2048 for value i of triangle k, stored
            // i-th in the file's layout.
            for (k, &level) in levels.iter().enumerate() {
                let mut expected = vec![0u16; values_per_triangle(level)];
                let positions = match name.contains("bird_curve") {
                    true => bird_curve::u_major_positions(level),
                    false => (0..expected.len() as u32).collect(),
                };
                for (i, &p) in positions.iter().enumerate() {
                    expected[p as usize] = ((37 * i + 101 * k) % 2048) as u16;
                }
                assert_eq!(map.triangle_values(k), expected, "{name} triangle {k}");
            }
            assert_eq!((map.groups[0].bias, map.groups[0].scale), (0.0, 1.0));
            let code = map.value_code.map(|c| (c.levels, c.widths));
            assert_eq!(code, name.contains("value_code").then_some((3, 0x456)), "{name}");
        }
    }

    /// The same bytes in bird-curve order are the same values, each where the curve puts it.
    #[test]
    fn bird_curve_values_read_in_u_major_order() {
        let good = write(&sample_map());
        let values_at = u64::from_le_bytes(good[56..64].try_into().unwrap()) as usize;
        let mut bird = good.clone();
        bird[values_at + 4] = LAYOUT_BIRD_CURVE as u8;
        let (u_major, bird) = (read(&good).unwrap(), read(&bird).unwrap());
        for t in 0..u_major.triangles.len() {
            let level = u_major.triangles[t].level;
            let positions = bird_curve::u_major_positions(level);
            let stored = u_major.triangle_values(t);
            for (k, &p) in positions.iter().enumerate() {
                assert_eq!(bird.triangle_values(t)[p as usize], stored[k], "triangle {t} value {k}");
            }
        }
    }

    #[test]
    fn damaged_files_give_one_line_errors() {
        let good = write(&sample_map());
        let expect = |bytes: &[u8], needle: &str| {
            let e = read(bytes).unwrap_err().to_string();
            assert!(e.contains(needle) && !e.contains('\n'), "{needle:?}: {e}");
        };
        expect(b"not a bary file at all, not at all", "not a .bary file");
        expect(&good[..good.len() - 4], "truncated: its header declares");
        let mut compressed = good.clone();
        let values_at = u64::from_le_bytes(good[56..64].try_into().unwrap()) as usize;
        compressed[values_at..values_at + 4].copy_from_slice(&FORMAT_DISP_C1_BLOCK.to_le_bytes());
        expect(&compressed, "triangle 0: its block format 0 is none of eDispC1's");
        let mut unknown_layout = good.clone();
        unknown_layout[values_at + 4] = 7;
        expect(&unknown_layout, "unknown layout 7");
        let mut deep = good.clone();
        let triangles_at = u64::from_le_bytes(good[184..192].try_into().unwrap()) as usize;
        deep[triangles_at + 4] = 40;
        expect(&deep, "triangle 0: subdivision level 40");
        let mut no_groups = good.clone();
        no_groups[104..108].copy_from_slice(&[9; 4]);
        expect(&no_groups, "no groups property");
        let mut seed = 5;
        for round in 0..2000 {
            let mut bytes = good.clone();
            for _ in 0..1 + round % 4 {
                let at = (lcg(&mut seed) as usize) % bytes.len();
                bytes[at] = lcg(&mut seed) as u8;
            }
            let _ = read(&bytes);
        }
    }
}
