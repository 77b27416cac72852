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
                let [a, b] = parents(p, spacing).map(|q| out[u_major_index(q, n) as usize] as i32);
                ((((a + b + 1) >> 1) + (correction << shift)) & 0x7ff) as u32
            };
            out[u_major_index(p, n) as usize] = value as u16;
        }
    }
    out
}

/// The values of a level-`level` triangle whose blocks of format `block_format` are `bytes`
/// (at least as many as it takes: see [`triangle_bytes`]), in u-major order.
pub fn triangle_values(bytes: &[u8], level: u32, block_format: u16) -> Result<Vec<u16>> {
    let format = format_of(block_format)?;
    let m = level.min(format.level);
    let order = bird_curve::points(m);
    let blocks = bytes.chunks_exact(format.bytes);
    if level <= format.level {
        let block = blocks.into_iter().next().expect("checked by triangle_bytes");
        return Ok(decode_block(format, block, m, &order));
    }
    let n = grid_size(level);
    let mut out = vec![0u16; values_per_triangle(level)];
    let side = grid_size(format.level);
    for (corners, block) in bird_curve::triangles(level - format.level).into_iter().zip(blocks) {
        // The block's corners on the triangle's lattice, and its lattice's unit steps there.
        let [w, u, v] = corners.map(|c| [(c[0] * side) as i32, (c[1] * side) as i32]);
        let step = |to: [i32; 2]| [(to[0] - w[0]) / side as i32, (to[1] - w[1]) / side as i32];
        let (du, dv) = (step(u), step(v));
        let values = decode_block(format, block, m, &order);
        for &p in &order {
            let value = values[u_major_index(p, side) as usize];
            let at = [
                w[0] + p[0] as i32 * du[0] + p[1] as i32 * dv[0],
                w[1] + p[0] as i32 * du[1] + p[1] as i32 * dv[1],
            ];
            out[u_major_index([at[0] as u32, at[1] as u32], n) as usize] = value;
        }
    }
    Ok(out)
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
    use crate::bary::bird_curve::tests::REFERENCE;

    /// Writes `value` in `width` bits at bit `bit`, least significant first.
    fn put(block: &mut [u8], bit: u32, width: u32, value: u32) {
        for k in 0..width {
            let (at, b) = (((bit + k) / 8) as usize, (bit + k) % 8);
            block[at] = (block[at] & !(1 << b)) | ((((value >> k) & 1) as u8) << b);
        }
    }

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
        use crate::bary::{container, read, FORMAT_DISP_C1_BLOCK, GROUPS_ID, TRIANGLES_ID, VALUES_ID};
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
