//! NVIDIA's block-compressed displacements (`eDispC1_r11_unorm_block`), decoded into a
//! triangle's 11-bit values in u-major order.
//!
//! A triangle is stored as blocks of one format (its `blockFormat`), each covering a
//! sub-triangle of the format's level `S`: 64 micro-triangles in 64 bytes (`S = 3`), 256 in
//! 128 (`S = 4`) or 1024 in 128 (`S = 5`). A triangle of level `L > S` is split into the
//! `4^(L - S)` sub-triangles of level `L - S`, one block each, in bird-curve order; each block's
//! corners W, U, V are its sub-triangle's corners in the order the curve gives them (see
//! [`super::bird_curve`]). A triangle of level `L <= S` is one block, read to level `L`.
//!
//! Within a block the values come level by level, in the bird-curve order of the block's own
//! lattice, each level a run of fields of one width:
//! - level 0, the corners: 11-bit values;
//! - in the level-3 format every level holds 11-bit values (45 values in 495 bits);
//! - in the others, a level `l >= 1` holds two's-complement corrections. A point's value is
//!   the rounded mean `(a + b + 1) >> 1` of its parents' (the ends of the edge it halves,
//!   [`parents`]) plus its correction shifted left, modulo 2048. The shift is the level's,
//!   one for points inside the block and one for each of its edges W-U, U-V and V-W, four
//!   fields at a fixed place in the block's last 64 bits.
//!
//! Levels with ever fewer bits per correction are what make the deeper formats small: the
//! coarse levels set the shape, the fine ones only nudge it.

use super::bird_curve;
use super::values_per_triangle;
use crate::error::{fail, Result};
use gridrt_shared::displacement::u_major_index;
use gridrt_shared::grid_index::{grid_size, parents, Lattice};

/// The deepest level a block format covers.
const MAX_BLOCK_LEVEL: usize = 5;

/// Where a level's four shifts lie: their first bit, counted from the start of the block's
/// last 64 bits, and the bits each takes.
#[derive(Clone, Copy)]
struct ShiftFields {
    first_bit: u32,
    width: u32,
}

/// One of the three block formats.
struct BlockFormat {
    /// The level `S` a block covers.
    level: u32,
    bytes: usize,
    /// Each level's field width.
    widths: [u32; MAX_BLOCK_LEVEL + 1],
    /// Each level's shifts; none where they are all zero.
    shifts: [Option<ShiftFields>; MAX_BLOCK_LEVEL + 1],
    /// Whether levels past the corners hold corrections to predictions rather than values.
    predicted: bool,
}

const fn shifts(first_bit: u32, width: u32) -> Option<ShiftFields> {
    Some(ShiftFields { first_bit, width })
}

/// `eR11_unorm_lvl3_pack512`, `eR11_unorm_lvl4_pack1024` and `eR11_unorm_lvl5_pack1024`:
/// block formats 1, 2 and 3.
const FORMATS: [BlockFormat; 3] = [
    BlockFormat {
        level: 3,
        bytes: 64,
        widths: [11, 11, 11, 11, 0, 0],
        shifts: [None; MAX_BLOCK_LEVEL + 1],
        predicted: false,
    },
    BlockFormat {
        level: 4,
        bytes: 128,
        widths: [11, 11, 11, 10, 5, 0],
        shifts: [None, None, None, shifts(58, 1), shifts(46, 3), None],
        predicted: true,
    },
    BlockFormat {
        level: 5,
        bytes: 128,
        widths: [11, 11, 8, 4, 2, 1],
        shifts: [None, None, shifts(54, 2), shifts(42, 3), shifts(26, 4), shifts(10, 4)],
        predicted: true,
    },
];

/// The number of values new at level `l`: the three corners at level 0.
fn new_values(l: u32) -> usize {
    match l {
        0 => 3,
        _ => values_per_triangle(l) - values_per_triangle(l - 1),
    }
}

impl BlockFormat {
    fn of(code: u16) -> Option<&'static BlockFormat> {
        FORMATS.get((code as usize).wrapping_sub(1))
    }

    /// The first bit of level `l`'s fields.
    fn level_start(&self, l: u32) -> u32 {
        (0..l).map(|k| new_values(k) as u32 * self.widths[k as usize]).sum()
    }

    /// How many blocks a level-`level` triangle takes.
    fn blocks(&self, level: u32) -> usize {
        1 << (2 * level.saturating_sub(self.level))
    }
}

/// `width` bits at bit `bit` of `bytes`, least significant first (`width <= 16`).
fn bits(bytes: &[u8], bit: u32, width: u32) -> u32 {
    let first = (bit / 8) as usize;
    let word = (0..3).fold(0u32, |w, k| w | (*bytes.get(first + k).unwrap_or(&0) as u32) << (8 * k));
    (word >> (bit % 8)) & ((1 << width) - 1)
}

/// Which of a level's four shifts applies at `p` of a block of lattice size `n`: 0 inside,
/// 1 on edge W-U, 2 on edge U-V, 3 on edge V-W.
fn shift_slot(p: Lattice, n: u32) -> u32 {
    let [u, v] = p;
    if u + v == n {
        2
    } else if u == 0 {
        3
    } else if v == 0 {
        1
    } else {
        0
    }
}

/// A block decoded to level `m <= S`, as values of its level-`m` lattice in u-major order;
/// `order` is [`bird_curve::points`]`(m)`.
fn decode_block(format: &BlockFormat, block: &[u8], m: u32, order: &[Lattice]) -> Vec<u16> {
    let n = grid_size(m);
    let last_word = (8 * format.bytes - 64) as u32;
    let mut out = vec![0u16; values_per_triangle(m)];
    let mut points = order.iter();
    for l in 0..=m {
        let (width, start) = (format.widths[l as usize], format.level_start(l));
        let shifts = format.shifts[l as usize];
        let spacing = n >> l;
        for k in 0..new_values(l) as u32 {
            let p = *points.next().expect("a point for every value");
            let field = bits(block, start + k * width, width);
            let value = if l == 0 || !format.predicted {
                field
            } else {
                let shift = shifts.map_or(0, |s| {
                    bits(block, last_word + s.first_bit + s.width * shift_slot(p, n), s.width)
                });
                let correction = ((field << (32 - width)) as i32) >> (32 - width);
                corrected(predicted(&out, p, spacing, n), correction, shift) as u32
            };
            out[u_major_index(p, n) as usize] = value as u16;
        }
    }
    out
}

/// Where a block lies on its triangle's lattice: block point `(i, j)` is triangle point
/// `w + i du + j dv`.
struct BlockFrame {
    w: [i32; 2],
    du: [i32; 2],
    dv: [i32; 2],
}

impl BlockFrame {
    /// The blocks of a level-`level` triangle in a format of level `s`, in file order: one,
    /// the triangle itself, where `level <= s`.
    fn all(level: u32, s: u32) -> Vec<BlockFrame> {
        let side = grid_size(s) as i32;
        bird_curve::triangles(level.saturating_sub(s))
            .into_iter()
            .map(|corners| {
                let [w, u, v] = corners.map(|c| [c[0] as i32 * side, c[1] as i32 * side]);
                let step = |to: [i32; 2]| [(to[0] - w[0]) / side, (to[1] - w[1]) / side];
                BlockFrame {
                    w,
                    du: step(u),
                    dv: step(v),
                }
            })
            .collect()
    }

    /// Block point `p`'s position in the triangle's u-major values of lattice size `n`.
    fn at(&self, p: Lattice, n: u32) -> usize {
        let (i, j) = (p[0] as i32, p[1] as i32);
        let at = [
            self.w[0] + i * self.du[0] + j * self.dv[0],
            self.w[1] + i * self.du[1] + j * self.dv[1],
        ];
        u_major_index([at[0] as u32, at[1] as u32], n) as usize
    }
}

/// The values of a level-`level` triangle whose blocks of format `block_format` are `bytes`
/// (at least as many as it takes: see [`triangle_bytes`]), in u-major order.
pub fn triangle_values(bytes: &[u8], level: u32, block_format: u16) -> Result<Vec<u16>> {
    let format = format_of(block_format)?;
    let m = level.min(format.level);
    let order = bird_curve::points(m);
    let (n, side) = (grid_size(level), grid_size(m));
    let mut out = vec![0u16; values_per_triangle(level)];
    for (frame, block) in BlockFrame::all(level, format.level)
        .iter()
        .zip(bytes.chunks_exact(format.bytes))
    {
        let values = decode_block(format, block, m, &order);
        for &p in &order {
            out[frame.at(p, n)] = values[u_major_index(p, side) as usize];
        }
    }
    Ok(out)
}

/// A triangle's values in blocks: their format, their bytes, and the values they decode to
/// (u-major).
#[derive(Clone, Debug, PartialEq)]
pub struct EncodedTriangle {
    pub block_format: u16,
    pub bytes: Vec<u8>,
    pub decoded: Vec<u16>,
}

/// The block format gridrt writes a level-`level` triangle in: the level-3 format (values
/// exact) up to level 3, then the level-4 one, then the level-5 one, split into blocks
/// deeper than that.
pub fn block_format_for(level: u32) -> u16 {
    match level {
        0..=3 => EXACT_FORMAT,
        4 => 2,
        _ => 3,
    }
}

/// A level-`level` triangle's u-major `values` in blocks of [`block_format_for`] its level.
///
/// Each correction is the one the field holds that takes the prediction nearest the point's
/// value, sums taken modulo 2048 as the decoder takes them; each level's four shifts are
/// those of least squared error over their points. Both depend only on the points' values and their
/// parents' decoded ones, never on the order a block walks them in, so two triangles of one
/// level holding the same values on a shared edge decode it alike.
pub fn encode_triangle(values: &[u16], level: u32) -> EncodedTriangle {
    encode_in(values, level, block_format_for(level))
}

/// [`encode_triangle`] where it gives every value back, otherwise the values exactly in
/// level-3 blocks (which hold any values: a block of 45 values of 11 bits).
pub fn encode_exactly(values: &[u16], level: u32) -> EncodedTriangle {
    let encoded = encode_triangle(values, level);
    match encoded.decoded == values {
        true => encoded,
        false => encode_in(values, level, EXACT_FORMAT),
    }
}

/// The block format whose values are stored as they are.
const EXACT_FORMAT: u16 = 1;

fn encode_in(values: &[u16], level: u32, block_format: u16) -> EncodedTriangle {
    let format = BlockFormat::of(block_format).expect("a format of the three");
    let m = level.min(format.level);
    let order = bird_curve::points(m);
    let (n, side) = (grid_size(level), grid_size(m));
    let mut bytes = Vec::new();
    let mut decoded = vec![0u16; values.len()];
    for frame in BlockFrame::all(level, format.level) {
        let mut truth = vec![0u16; values_per_triangle(m)];
        for &p in &order {
            truth[u_major_index(p, side) as usize] = values[frame.at(p, n)];
        }
        let (block, block_values) = encode_block(format, &truth, m, &order);
        for &p in &order {
            decoded[frame.at(p, n)] = block_values[u_major_index(p, side) as usize];
        }
        bytes.extend(block);
    }
    EncodedTriangle {
        block_format,
        bytes,
        decoded,
    }
}

/// A point to encode at a level: its shift's slot, its parents' rounded mean and its true
/// value.
struct Target {
    slot: u32,
    predicted: i32,
    truth: i32,
}

/// The correction of `width` bits which, shifted by `shift`, takes `predicted` nearest to
/// `truth`, sums taken modulo 2048 as the decoder does (so an 11-bit correction reaches any
/// value), and the value it gives.
fn correction(predicted: i32, truth: i32, shift: u32, width: u32) -> (i32, i32) {
    let (step, limit) = (1 << shift, 1 << (width - 1));
    [0, -VALUES, VALUES]
        .map(|wrap| {
            let nearest = (truth - predicted + wrap + step / 2).div_euclid(step);
            let c = nearest.clamp(-limit, limit - 1);
            (c, corrected(predicted, c, shift))
        })
        .into_iter()
        .min_by_key(|&(c, value)| ((value - truth).abs(), c.abs()))
        .expect("three candidates")
}

/// The prediction of point `p`, new at spacing `h` of a lattice of size `n`: the rounded mean
/// of its parents' values in `values` (u-major).
fn predicted(values: &[u16], p: Lattice, h: u32, n: u32) -> i32 {
    let [a, b] = parents(p, h).map(|q| values[u_major_index(q, n) as usize] as i32);
    (a + b + 1) >> 1
}

/// `predicted` moved by correction `c` shifted by `shift`, modulo 2048.
fn corrected(predicted: i32, c: i32, shift: u32) -> i32 {
    (predicted + (c << shift)) & (VALUES - 1)
}

/// How many values there are: 2^11.
const VALUES: i32 = 0x800;

/// Level `m <= S` of a block whose true values are `truth` (u-major on its level-`m`
/// lattice): the block's bytes and the values they decode to.
fn encode_block(format: &BlockFormat, truth: &[u16], m: u32, order: &[Lattice]) -> (Vec<u8>, Vec<u16>) {
    let n = grid_size(m);
    let last_word = (8 * format.bytes - 64) as u32;
    let mut block = vec![0u8; format.bytes];
    let mut out = vec![0u16; truth.len()];
    let mut points = order.iter();
    for l in 0..=m {
        let (width, start) = (format.widths[l as usize], format.level_start(l));
        let level_points: Vec<Lattice> = points.by_ref().take(new_values(l)).copied().collect();
        if l == 0 || !format.predicted {
            for (k, &p) in level_points.iter().enumerate() {
                let value = truth[u_major_index(p, n) as usize];
                put(&mut block, start + k as u32 * width, width, value as u32);
                out[u_major_index(p, n) as usize] = value;
            }
            continue;
        }
        let targets: Vec<Target> = (level_points.iter())
            .map(|&p| Target {
                slot: shift_slot(p, n),
                predicted: predicted(&out, p, n >> l, n),
                truth: truth[u_major_index(p, n) as usize] as i32,
            })
            .collect();
        let fields = format.shifts[l as usize];
        let mut shifts = [0u32; 4];
        for (slot, shift) in shifts.iter_mut().enumerate() {
            let squared_error = |s: u32| -> i64 {
                (targets.iter().filter(|t| t.slot == slot as u32))
                    .map(|t| ((correction(t.predicted, t.truth, s, width).1 - t.truth) as i64).pow(2))
                    .sum()
            };
            let choices = fields.map_or(1, |f| 1 << f.width);
            *shift = (0..choices).min_by_key(|&s| (squared_error(s), s)).unwrap_or(0);
            if let Some(f) = fields {
                put(
                    &mut block,
                    last_word + f.first_bit + f.width * slot as u32,
                    f.width,
                    *shift,
                );
            }
        }
        for (k, (t, &p)) in targets.iter().zip(&level_points).enumerate() {
            let shift = shifts[t.slot as usize];
            let (c, value) = correction(t.predicted, t.truth, shift, width);
            put(
                &mut block,
                start + k as u32 * width,
                width,
                c as u32 & ((1 << width) - 1),
            );
            out[u_major_index(p, n) as usize] = value as u16;
        }
    }
    (block, out)
}

/// Writes `value`'s low `width` bits at bit `bit` of `bytes`, least significant first.
fn put(bytes: &mut [u8], bit: u32, width: u32, value: u32) {
    for k in 0..width {
        let (at, b) = (((bit + k) / 8) as usize, (bit + k) % 8);
        bytes[at] = (bytes[at] & !(1 << b)) | ((((value >> k) & 1) as u8) << b);
    }
}

/// The bytes of one block of format `block_format` (one of the three).
pub fn block_bytes(block_format: u16) -> usize {
    BlockFormat::of(block_format).map_or(0, |f| f.bytes)
}

/// The bytes a level-`level` triangle takes in blocks of format `block_format`.
pub fn triangle_bytes(level: u32, block_format: u16) -> Result<usize> {
    let format = format_of(block_format)?;
    Ok(format.blocks(level) * format.bytes)
}

fn format_of(block_format: u16) -> Result<&'static BlockFormat> {
    match BlockFormat::of(block_format) {
        Some(format) => Ok(format),
        None => fail!(
            Input,
            "its block format {block_format} is none of eDispC1's (1 to 3: levels 3, 4 and 5)"
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::micromesh::bary::bird_curve::tests::REFERENCE;

    /// Twice the noise [`surface`] adds: the finest levels' corrections of a bit or two
    /// follow the surface, not the noise.
    const MAX_SMOOTH_ERROR: i32 = 16;

    /// The lattice points of size `n` in u-major order, as the format's description lists them.
    fn u_major_points(n: u32) -> Vec<Lattice> {
        (0..=n).flat_map(|u| (0..=n - u).map(move |v| [u, v])).collect()
    }

    /// A level-3 block of the first format holding `value(p)` at each point `p`, laid out from
    /// the bird-curve index NVIDIA's reference implementation gives each u-major position.
    fn flat_block(value: impl Fn(Lattice) -> u16) -> Vec<u8> {
        let mut block = vec![0u8; 64];
        for (q, p) in u_major_points(8).into_iter().enumerate() {
            put(&mut block, 11 * REFERENCE[3][q], 11, value(p) as u32);
        }
        block
    }

    #[test]
    fn level_3_blocks_hold_values_in_bird_curve_order() {
        let value = |p: Lattice| (37 * p[0] + 101 * p[1] + 5) as u16 % 2048;
        let block = flat_block(value);
        let expected: Vec<u16> = u_major_points(8).into_iter().map(value).collect();
        assert_eq!(triangle_values(&block, 3, 1).unwrap(), expected);
        // A coarser triangle reads the first levels of its block only.
        let coarse: Vec<u16> = u_major_points(4)
            .into_iter()
            .map(|p| value([2 * p[0], 2 * p[1]]))
            .collect();
        assert_eq!(triangle_values(&block, 2, 1).unwrap(), coarse);
    }

    /// A level-4 triangle in level-3 blocks: four blocks over the sub-triangles the format's
    /// split gives, `(w, uw, vw)`, `(vw, uv, uw)`, `(uw, u, uv)`, `(uv, vw, v)`, each laid out in
    /// its own corners' frame.
    #[test]
    fn a_split_triangle_reads_its_blocks_in_curve_order() {
        let value = |p: [i32; 2]| (29 * p[0] + 211 * p[1] + 3) as u16 % 2048;
        let (w, u, v) = ([0, 0], [16, 0], [0, 16]);
        let mid = |a: [i32; 2], b: [i32; 2]| [(a[0] + b[0]) / 2, (a[1] + b[1]) / 2];
        let (uw, uv, vw) = (mid(u, w), mid(u, v), mid(v, w));
        let mut bytes = Vec::new();
        for [a, b, c] in [[w, uw, vw], [vw, uv, uw], [uw, u, uv], [uv, vw, v]] {
            bytes.extend(flat_block(|p| {
                let (i, j) = (p[0] as i32, p[1] as i32);
                value([
                    a[0] + (i * (b[0] - a[0]) + j * (c[0] - a[0])) / 8,
                    a[1] + (i * (b[1] - a[1]) + j * (c[1] - a[1])) / 8,
                ])
            }));
        }
        let expected: Vec<u16> = u_major_points(16)
            .into_iter()
            .map(|p| value([p[0] as i32, p[1] as i32]))
            .collect();
        assert_eq!(triangle_values(&bytes, 4, 1).unwrap(), expected);
    }

    /// A level-4 block: corners, then corrections added to rounded means, modulo 2048, with
    /// the edge's shift.
    #[test]
    fn predicted_blocks_add_shifted_corrections_to_rounded_means() {
        let mut block = vec![0u8; 128];
        for (k, corner) in [100, 1000, 2000].into_iter().enumerate() {
            put(&mut block, 11 * k as u32, 11, corner);
        }
        let at = |p: Lattice| u_major_index(p, 16) as usize;
        let plain = triangle_values(&block, 4, 2).unwrap();
        // Midpoints of W-U, no correction: (100 + 1000 + 1) >> 1, then (100 + 550 + 1) >> 1.
        assert_eq!((plain[at([8, 0])], plain[at([4, 0])]), (550, 325));
        // Along V-W: 1050, 575, 338, 219.
        assert_eq!(plain[at([0, 1])], 219);
        // The first value of level 4 is the midpoint W-V of the level-3 triangle at W, on the
        // edge V-W: its correction of -3 (5 bits at bit 465) shifted by 2 (the fourth 3-bit
        // shift of level 4, at bit 46 of the last 64).
        put(&mut block, 465, 5, 0b11101);
        put(&mut block, 1024 - 64 + 46 + 3 * 3, 3, 2);
        let corrected = triangle_values(&block, 4, 2).unwrap();
        let moved: Vec<usize> = (0..plain.len()).filter(|&q| plain[q] != corrected[q]).collect();
        assert_eq!(moved, [at([0, 1])]);
        assert_eq!(corrected[at([0, 1])], 219 - 12);
        // Level 1's third value is the midpoint W-U; a correction of -600 wraps around.
        put(&mut block, 33 + 2 * 11, 11, 2048 - 600);
        assert_eq!(triangle_values(&block, 4, 2).unwrap()[at([8, 0])], 1998);
    }

    /// A whole file laid out by hand: two triangles in blocks of two formats, the values
    /// aligned to 128 bytes as the format asks.
    #[test]
    fn a_file_of_blocks_is_read() {
        use crate::micromesh::bary::{container, read, FORMAT_DISP_C1_BLOCK, GROUPS_ID, TRIANGLES_ID, VALUES_ID};
        let le = |words: &[u32]| words.iter().flat_map(|w| w.to_le_bytes()).collect::<Vec<u8>>();
        let first = flat_block(|p| (p[0] * 9 + p[1]) as u16);
        let mut second = vec![0u8; 128];
        for (k, corner) in [7, 700, 1400].into_iter().enumerate() {
            put(&mut second, 11 * k as u32, 11, corner);
        }
        put(&mut second, 33, 11, 5);
        let file = |value_bytes: u32| {
            let mut values = le(&[FORMAT_DISP_C1_BLOCK, 2, 1, value_bytes, 1, 128]);
            values.resize(128, 0);
            values.extend(&first);
            values.extend(&second);
            let mut groups = le(&[0, 2, 0, value_bytes, 3, 4]);
            groups.extend(le(&[0, 0, 0, 0, 1.0f32.to_bits(), 0, 0, 0]));
            let triangles = le(&[0, 3 | 1 << 16, 64, 4 | 2 << 16]);
            container(&[(VALUES_ID, values), (GROUPS_ID, groups), (TRIANGLES_ID, triangles)])
        };
        let map = read(&file(192)).unwrap();
        assert_eq!(map.triangle_values(0), triangle_values(&first, 3, 1).unwrap());
        assert_eq!(map.triangle_values(1), triangle_values(&second, 4, 2).unwrap());
        assert_eq!(
            map.triangle_values(1)[u_major_index([0, 8], 16) as usize],
            ((7 + 1400 + 1) >> 1) + 5
        );
        let e = read(&file(150)).unwrap_err().to_string();
        assert!(e.contains("triangle 1: its level-4 values at 64 lie past"), "{e}");
    }

    fn lcg(seed: &mut u64) -> u32 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (*seed >> 33) as u32
    }

    /// A smooth surface with a little noise, as baked values are, on a lattice of size `n`.
    fn surface(n: u32, seed: &mut u64) -> Vec<u16> {
        u_major_points(n)
            .into_iter()
            .map(|[i, j]| {
                let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
                let smooth = 1000.0 + 600.0 * (3.0 * x).sin() * (2.0 * y + 0.5).cos();
                (smooth as u32 + lcg(seed) % 9) as u16
            })
            .collect()
    }

    #[test]
    fn encoded_triangles_decode_to_what_the_encoder_says() {
        let mut seed = 3;
        for level in 0..=6 {
            for values in [
                surface(grid_size(level), &mut seed),
                (0..values_per_triangle(level))
                    .map(|_| (lcg(&mut seed) % 2048) as u16)
                    .collect(),
            ] {
                let encoded = encode_triangle(&values, level);
                assert_eq!(
                    encoded.bytes.len(),
                    triangle_bytes(level, encoded.block_format).unwrap()
                );
                let read = triangle_values(&encoded.bytes, level, encoded.block_format).unwrap();
                assert_eq!(read, encoded.decoded, "level {level}");
                if level <= 3 {
                    assert_eq!(encoded.decoded, values, "level {level} is exact");
                }
            }
        }
    }

    /// Eleven-bit corrections reach any value through the wrap: points far from their
    /// parents' mean keep the levels of 11-bit corrections exact.
    #[test]
    fn wide_corrections_wrap_to_any_value() {
        let corner = |[i, j]: Lattice| [[0, 0], [16, 0], [0, 16]].contains(&[i, j]);
        let values: Vec<u16> = u_major_points(16)
            .into_iter()
            .map(|p| if corner(p) { 10 } else { 2000 })
            .collect();
        let encoded = encode_triangle(&values, 4);
        for p in u_major_points(16)
            .into_iter()
            .filter(|p| p[0] % 4 == 0 && p[1] % 4 == 0)
        {
            let at = u_major_index(p, 16) as usize;
            assert_eq!(encoded.decoded[at], values[at], "{p:?}");
        }
    }

    /// On a smooth surface the corrections' widths suffice: every value within a few steps
    /// (level 3 and below are exact: see above).
    #[test]
    fn smooth_values_encode_closely() {
        let mut seed = 8;
        for level in [4, 5, 6] {
            let values = surface(grid_size(level), &mut seed);
            let encoded = encode_triangle(&values, level);
            let worst = (values.iter().zip(&encoded.decoded))
                .map(|(&a, &b)| (a as i32 - b as i32).abs())
                .max();
            assert!(worst <= Some(MAX_SMOOTH_ERROR), "level {level}: {worst:?}");
        }
    }

    /// Two level-6 triangles (four blocks each) sharing an edge, each walking it the other way
    /// and in another block edge slot: the edge decodes alike in both.
    #[test]
    fn neighbours_decode_their_shared_edge_alike() {
        let (level, mut seed) = (6, 21);
        let n = grid_size(level);
        let first = surface(n, &mut seed);
        let mut second = surface(n, &mut seed);
        // The first's edge W-U, from W, is the second's edge U-V, from U.
        for i in 0..=n {
            second[u_major_index([n - i, i], n) as usize] = first[u_major_index([i, 0], n) as usize];
        }
        let (a, b) = (encode_triangle(&first, level), encode_triangle(&second, level));
        for i in 0..=n {
            let (p, q) = (u_major_index([i, 0], n) as usize, u_major_index([n - i, i], n) as usize);
            assert_eq!(a.decoded[p], b.decoded[q], "edge point {i}");
        }
        let lossy = (0..=n).filter(|&i| {
            let p = u_major_index([i, 0], n) as usize;
            a.decoded[p] != first[p]
        });
        assert!(lossy.count() > 0, "the test needs a lossy edge");
    }

    #[test]
    fn unknown_block_formats_are_refused() {
        for format in [0, 4, 0xffff] {
            let e = triangle_bytes(3, format).unwrap_err().to_string();
            assert!(e.contains(&format!("block format {format}")), "{e}");
        }
        assert_eq!(triangle_bytes(2, 2).unwrap(), 128);
        assert_eq!(triangle_bytes(6, 1).unwrap(), 64 * 64);
        assert_eq!(triangle_bytes(6, 3).unwrap(), 4 * 128);
    }
}
