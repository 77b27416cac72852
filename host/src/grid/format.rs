//! The format a scene's grids are stored in, and the traversal code that reads each.
//!
//! A GPU pipeline carries the parts of the traversal its scene's format needs and no other
//! (`gridrt_shared::buffer::carries`). The CPU backend reads a scene the same way: the shared
//! traversal is compiled once per format with what that format leaves out as constants, so a
//! scene of Loop grids never tests, per vertex read, whether its grids hold displacement values.
//!
//! Guarantees: every scene has one format, and the parts of that format are enough to read it:
//! the same hits as code carrying every part.

use gridrt_shared::buffer::{carries, KernelWords};
use gridrt_shared::layout::{GridHeader, GridParams, DISPLACED_COMPRESSED};

use super::GridScene;

/// What a scene's grids are stored as, for the code that reads them.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum GridFormat {
    /// Plain grids' formats alone: `f32` or quantized vertices, 16-byte headers, stored radii
    /// and a binary top level.
    Plain,
    /// Any format made for displaced grids short of compressed values: plain values, tight
    /// headers, relative radii or a wide top level.
    Displaced,
    /// Displaced grids of compressed values.
    Compressed,
}

impl GridFormat {
    /// Every format, in the order of [`GridFormat::index`].
    pub const ALL: [GridFormat; 3] = [GridFormat::Plain, GridFormat::Displaced, GridFormat::Compressed];

    /// What the format adds to the walks and the lighting: bits of `carries`.
    pub const fn parts(self) -> u32 {
        match self {
            GridFormat::Plain => 0,
            GridFormat::Displaced => carries::DISPLACED_FORMATS | carries::DISPLACED_GRIDS,
            GridFormat::Compressed => {
                carries::DISPLACED_FORMATS | carries::DISPLACED_GRIDS | carries::DECODER | carries::ONLY_COMPRESSED
            }
        }
    }

    /// Its place among [`GridFormat::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }
}

/// What the CPU carries for a format: the format's parts, both walks and smooth normals.
const fn cpu_parts(format: GridFormat) -> u32 {
    format.parts() | carries::STACK | carries::ONE_VISIT | carries::SMOOTH_NORMALS
}

pub const CPU_PLAIN: u32 = cpu_parts(GridFormat::Plain);
pub const CPU_DISPLACED: u32 = cpu_parts(GridFormat::Displaced);
pub const CPU_COMPRESSED: u32 = cpu_parts(GridFormat::Compressed);

/// A scene as code carrying `MOST` reads it (see [`GridScene::format_view`]).
pub type FormatView<'a, const MOST: u32> =
    gridrt_shared::grid_traverse::GridScene<'a, &'a [GridHeader], KernelWords<&'a [u32], MOST>>;

impl GridScene {
    /// The format of this scene's grids.
    pub fn format(&self) -> GridFormat {
        if self.params.displaced == DISPLACED_COMPRESSED {
            GridFormat::Compressed
        } else if self.params.uses_displaced_formats() || self.has_wide_top() {
            GridFormat::Displaced
        } else {
            GridFormat::Plain
        }
    }

    /// The scene under `params` (its own, or a frame's level of detail), read by code that
    /// carries `MOST` (one of [`CPU_PLAIN`], [`CPU_DISPLACED`], [`CPU_COMPRESSED`], the one of
    /// its format: see `read_as_format!`).
    pub fn format_view<const MOST: u32>(&self, params: GridParams) -> FormatView<'_, MOST> {
        self.view_as(params).carrying(MOST)
    }
}

/// `$body` with `$view` bound to grid scene `$grids` under `$params`, read by the code of its
/// format alone (see the module's documentation): one expansion of `$body` per format.
macro_rules! read_as_format {
    ($grids:expr, $params:expr, |$view:ident| $body:expr) => {{
        use $crate::grid::format::{GridFormat, CPU_COMPRESSED, CPU_DISPLACED, CPU_PLAIN};
        let (grids, params) = ($grids, $params);
        match grids.format() {
            GridFormat::Plain => {
                let $view = grids.format_view::<CPU_PLAIN>(params);
                $body
            }
            GridFormat::Displaced => {
                let $view = grids.format_view::<CPU_DISPLACED>(params);
                $body
            }
            GridFormat::Compressed => {
                let $view = grids.format_view::<CPU_COMPRESSED>(params);
                $body
            }
        }
    }};
}
pub(crate) use read_as_format;
