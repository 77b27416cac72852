//! A structure-aware mutator for glTF and GLB files: it edits the parsed JSON (numbers,
//! strings, arrays and objects swapped for values that matter to a loader: component types,
//! accessor types, indices just past the end, paths out of the folder, huge numbers), the
//! binary chunk's bytes, and the GLB container's length fields, then writes the file back
//! out. Byte-level mutation alone rarely keeps the JSON parseable, and so rarely gets past
//! the parser to the code that reads accessors, buffers and nodes.

use serde_json::Value;

/// libFuzzer's own byte mutator: `(data, size, max_size) -> new size`.
pub type ByteMutator = fn(&mut [u8], usize, usize) -> usize;

/// Mutates the file in `data[..size]` in place (up to `max_size` bytes), returning its new
/// size; falls back to `bytes` where the input is not a glTF file it can take apart.
pub fn mutate(data: &mut [u8], size: usize, max_size: usize, seed: u32, bytes: ByteMutator) -> usize {
    let mut rng = Rng(u64::from(seed).wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1);
    let file = File::split(&data[..size]);
    let mutated = match rng.below(8) {
        0..=3 => file.and_then(|f| f.with_json_mutated(&mut rng)).map(|f| f.write()),
        4 => file.map(|f| f.with_bin_mutated(bytes, &mut rng).write()),
        5 => file.map(|f| f.write_with_bad_length(&mut rng)),
        6 => file.map(|mut f| {
            f.binary = !f.binary;
            f.write()
        }),
        _ => None,
    };
    match mutated {
        Some(out) if out.len() <= max_size => {
            data[..out.len()].copy_from_slice(&out);
            out.len()
        }
        _ => bytes(data, size, max_size),
    }
}

/// A small xorshift generator, seeded by libFuzzer.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }

    fn pick<T: Clone>(&mut self, items: &[T]) -> T {
        items[self.below(items.len())].clone()
    }
}

/// A glTF file taken apart: its JSON, its binary chunk, and whether it is a GLB.
struct File {
    json: Value,
    bin: Vec<u8>,
    binary: bool,
}

const JSON_CHUNK: u32 = 0x4E4F_534A;
const BIN_CHUNK: u32 = 0x004E_4942;

impl File {
    fn split(bytes: &[u8]) -> Option<File> {
        if !bytes.starts_with(b"glTF") {
            let json = serde_json::from_slice(bytes).ok()?;
            return Some(File {
                json,
                bin: Vec::new(),
                binary: false,
            });
        }
        let word = |at: usize| Some(u32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?));
        let (json_len, kind) = (word(12)? as usize, word(16)?);
        if kind != JSON_CHUNK {
            return None;
        }
        let json = serde_json::from_slice(bytes.get(20..20 + json_len)?).ok()?;
        let at = 20 + json_len;
        let bin = match (word(at), word(at + 4)) {
            (Some(n), Some(BIN_CHUNK)) => bytes.get(at + 8..at + 8 + n as usize)?.to_vec(),
            _ => Vec::new(),
        };
        Some(File {
            json,
            bin,
            binary: true,
        })
    }

    fn write(&self) -> Vec<u8> {
        let json = serde_json::to_vec(&self.json).unwrap_or_default();
        if !self.binary {
            return json;
        }
        let pad = |mut v: Vec<u8>, with: u8| {
            while !v.len().is_multiple_of(4) {
                v.push(with);
            }
            v
        };
        let (json, bin) = (pad(json, b' '), pad(self.bin.clone(), 0));
        let mut out = Vec::with_capacity(28 + json.len() + bin.len());
        let total = 12 + 8 + json.len() + if bin.is_empty() { 0 } else { 8 + bin.len() };
        out.extend(b"glTF");
        out.extend(2u32.to_le_bytes());
        out.extend((total as u32).to_le_bytes());
        out.extend((json.len() as u32).to_le_bytes());
        out.extend(JSON_CHUNK.to_le_bytes());
        out.extend(&json);
        if !bin.is_empty() {
            out.extend((bin.len() as u32).to_le_bytes());
            out.extend(BIN_CHUNK.to_le_bytes());
            out.extend(&bin);
        }
        out
    }

    /// The GLB written with its total length or a chunk's length changed.
    fn write_with_bad_length(mut self, rng: &mut Rng) -> Vec<u8> {
        self.binary = true;
        let mut out = self.write();
        let json_len = u32::from_le_bytes(out[12..16].try_into().unwrap_or_default()) as usize;
        let at = rng.pick(&[8, 12, 20 + json_len]);
        if let Some(field) = out.get_mut(at..at + 4) {
            let old = u32::from_le_bytes(field.try_into().unwrap_or_default());
            let new = match rng.below(4) {
                0 => old.wrapping_add(1 + rng.below(8) as u32),
                1 => old.wrapping_sub(1 + rng.below(8) as u32),
                2 => 0,
                _ => u32::MAX - rng.below(4) as u32,
            };
            field.copy_from_slice(&new.to_le_bytes());
        }
        if rng.below(2) == 0 {
            out.truncate(rng.below(out.len() + 1));
        }
        out
    }

    fn with_bin_mutated(mut self, bytes: ByteMutator, rng: &mut Rng) -> File {
        let size = self.bin.len();
        self.bin.resize(size * 2 + 64, 0);
        let max = self.bin.len();
        let new = bytes(&mut self.bin, size, max);
        self.bin.truncate(new);
        if rng.below(4) == 0 {
            self.binary = true;
        }
        self
    }

    fn with_json_mutated(mut self, rng: &mut Rng) -> Option<File> {
        let mut paths = Vec::new();
        collect_paths(&self.json, String::new(), &mut paths);
        let target = rng.pick(&paths);
        let donor = self.json.pointer(&rng.pick(&paths)).cloned().unwrap_or(Value::Null);
        let value = self.json.pointer_mut(&target)?;
        match rng.below(6) {
            0 => *value = Value::from(rng.pick(NUMBERS)),
            1 => *value = Value::from(rng.pick(STRINGS)),
            2 => *value = donor,
            3 => match value {
                Value::Object(map) if !map.is_empty() => {
                    let key = map.keys().nth(rng.below(map.len()))?.clone();
                    map.remove(&key);
                }
                Value::Array(list) if !list.is_empty() => {
                    list.remove(rng.below(list.len()));
                }
                _ => *value = Value::Null,
            },
            4 => match value {
                Value::Object(map) => {
                    let number = Value::from(rng.pick(NUMBERS));
                    let small = Value::from(rng.below(4) as u64);
                    map.insert(rng.pick(KEYS).to_string(), rng.pick(&[number, small, donor]));
                }
                Value::Array(list) => list.push(donor),
                _ => *value = Value::Array(vec![donor]),
            },
            _ => {
                let nested = (0..1 + rng.below(3))
                    .map(|_| Value::from(rng.below(4) as u64))
                    .collect();
                *value = Value::Array(nested);
            }
        }
        Some(self)
    }
}

/// The JSON pointer of every value in `value`.
fn collect_paths(value: &Value, at: String, out: &mut Vec<String>) {
    match value {
        Value::Object(map) => {
            for (key, v) in map {
                let key = key.replace('~', "~0").replace('/', "~1");
                collect_paths(v, format!("{at}/{key}"), out);
            }
        }
        Value::Array(list) => {
            for (k, v) in list.iter().enumerate() {
                collect_paths(v, format!("{at}/{k}"), out);
            }
        }
        _ => {}
    }
    out.push(at);
}

/// Numbers a loader must treat with care.
const NUMBERS: &[f64] = &[
    0.0,
    1.0,
    2.0,
    3.0,
    4.0,
    5.0,
    6.0,
    9.0,
    12.0,
    36.0,
    -1.0,
    0.5,
    5120.0,
    5121.0,
    5122.0,
    5123.0,
    5125.0,
    5126.0,
    65535.0,
    65536.0,
    2147483647.0,
    4294967295.0,
    4294967296.0,
    1e39,
    -1e39,
    1e-45,
    1e300,
    3.4e38,
];

/// Strings a loader must treat with care.
const STRINGS: &[&str] = &[
    "SCALAR",
    "VEC2",
    "VEC3",
    "VEC4",
    "MAT4",
    "2.0",
    "../../../../etc/passwd",
    "/etc/passwd",
    "%2e%2e/x.bin",
    "file:///etc/passwd",
    "scene.bin",
    "data:application/octet-stream;base64,AAAAAAAAgD8AAAAAAACAPwAAAAA=",
    "data:application/octet-stream;base64,!!",
    "data:,plain",
    "KHR_mesh_quantization",
    "KHR_draco_mesh_compression",
];

/// Object keys that change what a loader reads.
const KEYS: &[&str] = &[
    "children",
    "mesh",
    "matrix",
    "translation",
    "rotation",
    "scale",
    "byteStride",
    "byteOffset",
    "byteLength",
    "count",
    "sparse",
    "indices",
    "mode",
    "normalized",
    "uri",
    "bufferView",
    "scene",
];
