//! Fields of any width up to 32 bits written end to end into 32-bit words, from bit 0 of
//! word 0, each field's lowest bit first: the order in which
//! `gridrt_shared::bit_fields::read_bits` reads them back, and the order of the
//! `.bary` format's packed 11-bit values.

/// A growing run of packed fields.
#[derive(Default)]
pub struct BitWriter {
    pub words: Vec<u32>,
    /// Bits written so far.
    pub bits: usize,
}

impl BitWriter {
    /// Appends the low `width` bits of `field`; a zero width writes nothing.
    pub fn push(&mut self, field: u32, width: u32) {
        if width == 0 {
            return;
        }
        let (word, shift) = (self.bits / 32, self.bits % 32);
        self.words
            .resize((self.bits + width as usize).div_ceil(32).max(word + 1), 0);
        let field = (field as u64 & ((1u64 << width) - 1)) << shift;
        self.words[word] |= field as u32;
        if shift + width as usize > 32 {
            self.words[word + 1] |= (field >> 32) as u32;
        }
        self.bits += width as usize;
    }

    /// `values` as `width`-bit fields end to end.
    pub fn packed(values: impl IntoIterator<Item = u32>, width: u32) -> Vec<u32> {
        let mut out = BitWriter::default();
        for v in values {
            out.push(v, width);
        }
        out.words
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gridrt_shared::bit_fields::read_bits;

    /// Fields of every width read back as the traversal reads them, across word boundaries.
    #[test]
    fn fields_read_back() {
        let mut out = BitWriter::default();
        let fields: Vec<(u32, u32)> = (0..200u32)
            .map(|k| (k.wrapping_mul(2_654_435_761) >> (k % 7), 1 + k % 31))
            .collect();
        for &(v, w) in &fields {
            out.push(v, w);
        }
        assert_eq!(out.bits, fields.iter().map(|&(_, w)| w as usize).sum::<usize>());
        out.words.push(0);
        let mut bit = 0;
        for &(v, w) in &fields {
            assert_eq!(
                read_bits(out.words.as_slice(), bit, w),
                v & ((1 << w) - 1),
                "field at {bit}"
            );
            bit += w;
        }
        assert_eq!(BitWriter::packed([0x7ff; 32], 11).len(), 11);
    }
}
