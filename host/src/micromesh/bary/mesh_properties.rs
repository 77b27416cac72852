//! The mesh properties a `.bary` file may carry for the 3D mesh it goes with: per vertex the
//! displacement directions and direction bounds, per mesh triangle the mapping to the file's
//! triangles and the edge flags (BaryFile's `eMeshDisplacementDirections`,
//! `eMeshDisplacementDirectionBounds`, `eMeshTriangleMappings`, `eMeshTriangleFlags`).
//!
//! A glTF primitive's own accessors override them; where it has none, a reader must take them
//! from here (the extension's `directionsOffset` and the like index into them), or it draws
//! another surface than the file's. Each property is a header (element format, count, byte
//! size, byte alignment), then, from the next multiple of the alignment, the elements.
//!
//! Guarantees: a property whose format is not one the format allows for it, whose elements
//! are narrower than their format or do not fit in its bytes is refused with its name; no
//! element is read past the property's bytes.

use super::Reader;
use crate::error::{fail, Result};

/// Which mesh property an identifier names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum MeshProperty {
    Directions,
    DirectionBounds,
    TriangleMappings,
    TriangleFlags,
}

impl MeshProperty {
    pub(super) const ALL: [(MeshProperty, [u32; 4]); 4] = [
        (
            MeshProperty::Directions,
            [0xf262_d687, 0xb928_4aeb, 0xa706_803c, 0xcbed_ae52],
        ),
        (
            MeshProperty::DirectionBounds,
            [0x25bf_3c65, 0x2923_4ae1, 0x95ef_e43c, 0xeb87_066c],
        ),
        (
            MeshProperty::TriangleMappings,
            [0x9cdc_3ad0, 0x92bb_4a8a, 0xb465_8759, 0x42d4_1d54],
        ),
        (
            MeshProperty::TriangleFlags,
            [0x90f9_eed3, 0x4ec3_4974, 0x970c_755c, 0xaf5b_53a3],
        ),
    ];

    pub(super) fn name(self) -> &'static str {
        match self {
            MeshProperty::Directions => "mesh displacement directions",
            MeshProperty::DirectionBounds => "mesh direction bounds",
            MeshProperty::TriangleMappings => "mesh triangle mappings",
            MeshProperty::TriangleFlags => "mesh triangle flags",
        }
    }
}

/// Element formats (BaryFile's `Format`, the numbers of the matching Vulkan formats).
const R8_UINT: u32 = 13;
const R16_UINT: u32 = 74;
const RG16_SFLOAT: u32 = 83;
const RGB16_SFLOAT: u32 = 90;
const RGBA16_SFLOAT: u32 = 97;
const R32_UINT: u32 = 98;
const RG32_SFLOAT: u32 = 103;
const RGB32_SFLOAT: u32 = 106;
const RGBA32_SFLOAT: u32 = 109;

/// A property's header: format, count, byte size, byte alignment.
const INFO_BYTES: usize = 16;

/// The mesh properties of a `.bary` file, those it has.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshProperties {
    pub directions: Option<Vec<[f32; 3]>>,
    /// Per vertex, a bias and a scale: the vertex moves by `bias * direction` and its
    /// direction is scaled by `scale`.
    pub direction_bounds: Option<Vec<[f32; 2]>>,
    /// Per mesh triangle, the file's triangle it takes (before the group's first).
    pub triangle_mappings: Option<Vec<u32>>,
    /// Per mesh triangle, bit `e` set when the neighbour across edge `e` is a level coarser.
    pub triangle_flags: Option<Vec<u8>>,
}

impl MeshProperties {
    /// Reads `property` from its bytes `at` in `file` into these properties.
    pub(super) fn read(&mut self, file: &Reader, property: MeshProperty, at: std::ops::Range<usize>) -> Result<()> {
        let elements = Elements::new(file, at, property)?;
        match property {
            MeshProperty::Directions => {
                let floats = elements.floats(&[RGB32_SFLOAT, RGBA32_SFLOAT, RGB16_SFLOAT, RGBA16_SFLOAT])?;
                self.directions = Some(floats.iter().map(|f| [f[0], f[1], f[2]]).collect());
            }
            MeshProperty::DirectionBounds => {
                let floats = elements.floats(&[RG32_SFLOAT, RG16_SFLOAT])?;
                self.direction_bounds = Some(floats.iter().map(|f| [f[0], f[1]]).collect());
            }
            MeshProperty::TriangleMappings => {
                self.triangle_mappings = Some(elements.integers(&[R32_UINT, R16_UINT])?);
            }
            MeshProperty::TriangleFlags => {
                let flags = elements.integers(&[R8_UINT])?;
                self.triangle_flags = Some(flags.iter().map(|&f| f as u8).collect());
            }
        }
        Ok(())
    }
}

/// A property's elements, checked to fit its bytes.
struct Elements<'a> {
    bytes: &'a [u8],
    format: u32,
    count: usize,
    stride: usize,
    property: MeshProperty,
}

impl<'a> Elements<'a> {
    fn new(file: &Reader<'a>, at: std::ops::Range<usize>, property: MeshProperty) -> Result<Elements<'a>> {
        let name = property.name();
        if at.len() < INFO_BYTES {
            fail!(
                Input,
                "its {name} property has {} bytes, less than its header",
                at.len()
            );
        }
        let [format, count, stride, alignment] = [0, 4, 8, 12].map(|k| file.u32(at.start + k).unwrap_or(0));
        if alignment == 0 || !alignment.is_power_of_two() {
            fail!(Input, "its {name} have an alignment of {alignment} bytes");
        }
        let start = INFO_BYTES.next_multiple_of(alignment as usize);
        let needed = (count as u64) * (stride as u64) + start as u64;
        if needed > at.len() as u64 {
            fail!(
                Input,
                "its {name} hold {count} elements of {stride} bytes, past the property's {} bytes",
                at.len()
            );
        }
        Ok(Elements {
            bytes: &file.0[at.start + start..at.end],
            format,
            count: count as usize,
            stride: stride as usize,
            property,
        })
    }

    /// The format, checked to be one of `allowed` with elements at least as wide as it.
    fn check(&self, allowed: &[u32]) -> Result<(usize, usize)> {
        let (components, width) = match self.format {
            R8_UINT => (1, 1),
            R16_UINT => (1, 2),
            R32_UINT => (1, 4),
            RG16_SFLOAT => (2, 2),
            RGB16_SFLOAT => (3, 2),
            RGBA16_SFLOAT => (4, 2),
            RG32_SFLOAT => (2, 4),
            RGB32_SFLOAT => (3, 4),
            RGBA32_SFLOAT => (4, 4),
            _ => (0, 0),
        };
        let name = self.property.name();
        if !allowed.contains(&self.format) {
            fail!(
                Input,
                "its {name} have element format {}, which they may not",
                self.format
            );
        }
        if self.stride < components * width {
            fail!(
                Input,
                "its {name} have elements of {} bytes, narrower than their format",
                self.stride
            );
        }
        Ok((components, width))
    }

    fn element(&self, k: usize) -> &[u8] {
        &self.bytes[k * self.stride..(k + 1) * self.stride]
    }

    /// Each element's components as `f32` (half floats widened), up to four.
    fn floats(&self, allowed: &[u32]) -> Result<Vec<[f32; 4]>> {
        let (components, width) = self.check(allowed)?;
        Ok((0..self.count)
            .map(|k| {
                let e = self.element(k);
                let mut out = [0.0; 4];
                for (c, slot) in out.iter_mut().enumerate().take(components) {
                    let b = &e[c * width..(c + 1) * width];
                    *slot = match width {
                        2 => half::f16::from_le_bytes([b[0], b[1]]).to_f32(),
                        _ => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
                    };
                }
                out
            })
            .collect())
    }

    /// Each element as an unsigned integer.
    fn integers(&self, allowed: &[u32]) -> Result<Vec<u32>> {
        let (_, width) = self.check(allowed)?;
        Ok((0..self.count)
            .map(|k| {
                let e = self.element(k);
                match width {
                    1 => e[0] as u32,
                    2 => u16::from_le_bytes([e[0], e[1]]) as u32,
                    _ => u32::from_le_bytes([e[0], e[1], e[2], e[3]]),
                }
            })
            .collect())
    }
}
