//! Bit fields packed end to end, least significant bit first, in a buffer of 32-bit words:
//! how displaced grids store their values, tables and headers, read alike on the CPU and
//! the GPU.

use crate::buffer::Buffer;

/// `width` bits of `buffer` from bit `bit`, for any `width` up to 32: two reads of at most
/// 16 bits where one of up to 25 may not do.
#[inline]
pub fn read_long_bits<B: Buffer<u32>>(buffer: B, bit: u32, width: u32) -> u32 {
    if width <= 16 {
        read_bits(buffer, bit, width)
    } else {
        read_bits(buffer, bit, 16) | read_bits(buffer, bit + 16, width - 16) << 16
    }
}

/// `width` bits of `buffer` from bit `bit` (`width <= 25`: they span at most two words; the
/// word after them must exist).
#[inline]
pub fn read_bits<B: Buffer<u32>>(buffer: B, bit: u32, width: u32) -> u32 {
    let (word, shift) = (bit >> 5, bit & 31);
    // Shifted in two steps, so a field that starts a word shifts the next one out entirely
    // rather than by 32, which shifts by nothing on some targets.
    let low = buffer.load(word) >> shift;
    let high = (buffer.load(word + 1) << 1) << (31 - shift);
    (low | high) & ((1 << width) - 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bits_read_across_words() {
        let words = [0xdead_beefu32, 0x1234_5678, 0];
        assert_eq!(read_bits(&words[..], 0, 8), 0xef);
        assert_eq!(read_bits(&words[..], 28, 8), 0x8d);
        assert_eq!(read_bits(&words[..], 32, 24), 0x34_5678);
        assert_eq!(read_long_bits(&words[..], 4, 32), 0x8dea_dbee);
        assert_eq!(read_long_bits(&words[..], 36, 20), 0x3_4567);
        assert_eq!(read_long_bits(&words[..], 0, 12), 0xeef);
    }
}
