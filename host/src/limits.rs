//! What a run will need, checked against what the machine has before any long work starts:
//! a clear refusal naming the figure instead of a panic, an allocation failure or the
//! out-of-memory killer minutes later.

use crate::error::{error, Result};

/// A scene buffer's name and size in bytes, possibly before it exists.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BufferSize {
    pub name: &'static str,
    pub bytes: u64,
    /// The size is a lower bound (known before the build only roughly).
    pub at_least: bool,
}

impl BufferSize {
    /// Its size for messages: `N bytes`, or `at least N bytes` for a lower bound.
    pub fn bytes_text(&self) -> String {
        let least = if self.at_least { "at least " } else { "" };
        format!("{least}{} bytes", self.bytes)
    }
}

/// Peak host bytes per micro-triangle of subdividing the whole mesh and building each
/// representation from it, measured (peak resident size over micro-triangles at several
/// depths, see docs/RESULTS.md "Peak host memory") and rounded up.
pub const GRID_BYTES_PER_MICRO_TRIANGLE: u64 = 72;
pub const TRIANGLES_BYTES_PER_MICRO_TRIANGLE: u64 = 168;

/// Peak host bytes of the lean grid build (`grid::build_lean`), per micro-triangle and per
/// base triangle: measured the same way (docs/RESULTS.md "Scale") and rounded up.
pub const LEAN_GRID_BYTES_PER_MICRO_TRIANGLE: u64 = 6;
pub const LEAN_GRID_BYTES_PER_BASE_TRIANGLE: u64 = 400;

/// Host memory a CPU Vulkan device (lavapipe) takes to hold an uploaded scene: copies of the
/// scene's bytes, plus the driver's own; measured (peak resident size of GPU renders against
/// CPU renders, docs/RESULTS.md "Scale") and rounded up.
pub const CPU_DEVICE_COPIES: u64 = 2;
pub const CPU_DEVICE_BYTES: u64 = 512 << 20;

/// Host bytes per pixel of an image being rendered and written: the packed pixels and the
/// byte copy the PNG encoder reads.
pub const IMAGE_BYTES_PER_PIXEL: u64 = 8;

/// Peak host bytes per triangle of loading a glTF scene (positions in `f64` per corner
/// before welding, the weld's table, the triangles), and per micro-triangle of decoding a
/// displaced micro-mesh (its decoded mesh, welded, in the file's units for `bake` and
/// `compare`), measured (peak resident size over triangles drawn, see docs/RESULTS.md "Peak
/// host memory") and rounded up.
pub const LOADED_BYTES_PER_TRIANGLE: u64 = 96;
pub const DECODED_BYTES_PER_MICRO_TRIANGLE: u64 = 176;

/// Peak host bytes per micro-triangle of baking (both passes' crossings, the fit's lines,
/// samples and nearest-point BVH), measured the same way and rounded up.
pub const BAKE_BYTES_PER_MICRO_TRIANGLE: u64 = 300;

/// Which representations a run builds.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Builds {
    /// Grids, each subdivided on its own (`grid::build_lean`).
    LeanGrids,
    /// The whole mesh subdivided, then grids.
    Grids,
    /// The whole mesh subdivided, then the baseline.
    Triangles,
    /// The whole mesh subdivided, then both.
    Both,
}

/// Micro-triangles of `base_triangles` subdivided `levels` times.
pub fn micro_triangles(base_triangles: usize, levels: u32) -> u64 {
    (base_triangles as u64).saturating_mul(4u64.saturating_pow(levels))
}

/// Estimated peak host bytes of building `builds` for `base_triangles` subdivided `levels`
/// times.
pub fn build_bytes(base_triangles: usize, levels: u32, builds: Builds) -> u64 {
    let micro = micro_triangles(base_triangles, levels);
    let per = |bytes: u64| micro.saturating_mul(bytes);
    match builds {
        Builds::LeanGrids => per(LEAN_GRID_BYTES_PER_MICRO_TRIANGLE)
            .saturating_add((base_triangles as u64).saturating_mul(LEAN_GRID_BYTES_PER_BASE_TRIANGLE)),
        Builds::Grids => per(GRID_BYTES_PER_MICRO_TRIANGLE),
        Builds::Triangles => per(TRIANGLES_BYTES_PER_MICRO_TRIANGLE),
        // Both are alive at once in `stats` and `bench`.
        Builds::Both => per(GRID_BYTES_PER_MICRO_TRIANGLE + TRIANGLES_BYTES_PER_MICRO_TRIANGLE),
    }
}

/// Refuses `what` at `levels` (of a mesh of `base_triangles`) when building `builds`, plus
/// `extra` bytes the caller needs besides, would not fit in the memory available.
pub fn check_build(
    what: &str,
    base_triangles: usize,
    levels: u32,
    builds: Builds,
    extra: u64,
    advice: &str,
) -> Result<()> {
    let micro = micro_triangles(base_triangles, levels);
    check_memory(
        build_bytes(base_triangles, levels, builds).saturating_add(extra),
        available_memory()?,
        &format!("{what} at --levels {levels} ({micro} micro-triangles)"),
        advice,
    )
}

/// Environment variable that sets a lower ceiling than the machine's free memory, e.g. `8G`
/// on a machine shared with other work.
pub const MEMORY_LIMIT_VAR: &str = "GRIDRT_MEMORY_LIMIT";

/// Bytes of memory a run may use: what the system can still hand out without swapping
/// (Linux's `MemAvailable`), or less if [`MEMORY_LIMIT_VAR`] says so; `None` where neither is
/// known, and then nothing is refused.
pub fn available_memory() -> Result<Option<u64>> {
    let system = system_available_memory();
    let Ok(text) = std::env::var(MEMORY_LIMIT_VAR) else {
        return Ok(system);
    };
    let limit = parse_bytes(&text).ok_or_else(|| {
        error!(
            Options,
            "{MEMORY_LIMIT_VAR}={text:?}: expected a byte count such as 8G, 500M or 1000000"
        )
    })?;
    Ok(Some(system.map_or(limit, |s| s.min(limit))))
}

fn system_available_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// `123`, `64K`, `500M`, `8G` or `1T` (powers of 1024; a trailing `B` or `iB` allowed).
pub fn parse_bytes(text: &str) -> Option<u64> {
    let t = text.trim().to_ascii_uppercase();
    let t = t.strip_suffix("IB").or_else(|| t.strip_suffix('B')).unwrap_or(&t);
    let (digits, shift) = match t.chars().last()? {
        'K' => (&t[..t.len() - 1], 10),
        'M' => (&t[..t.len() - 1], 20),
        'G' => (&t[..t.len() - 1], 30),
        'T' => (&t[..t.len() - 1], 40),
        _ => (t, 0),
    };
    let value: f64 = digits.trim().parse().ok()?;
    (value.is_finite() && value >= 0.0).then(|| (value * (1u64 << shift) as f64) as u64)
}

/// `bytes` as a short human figure: `7.7 GB`, `310 MB`.
pub fn human(bytes: u64) -> String {
    let b = bytes as f64;
    if b >= 1e9 {
        format!("{:.1} GB", b / 1e9)
    } else if b >= 1e6 {
        format!("{:.0} MB", b / 1e6)
    } else {
        format!("{:.0} kB", b / 1e3)
    }
}

/// Refuses, with the figures, a run whose estimated peak memory `need` exceeds `available`.
/// `what` says what needs it, `advice` what to do instead.
pub fn check_memory(need: u64, available: Option<u64>, what: &str, advice: &str) -> Result<()> {
    match available {
        Some(have) if need > have => Err(error!(
            Limits,
            "{what} needs about {} of memory, more than the {} available (free memory, or \
             {MEMORY_LIMIT_VAR}); {advice}",
            human(need),
            human(have)
        )),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refusals_name_both_figures() {
        let e = check_memory(31_000_000_000, Some(22_000_000_000), "the build", "use fewer levels")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "the build needs about 31.0 GB of memory, more than the 22.0 GB available (free memory, or \
             GRIDRT_MEMORY_LIMIT); use fewer levels"
        );
        assert!(check_memory(1, Some(2), "x", "y").is_ok());
        assert!(check_memory(u64::MAX, None, "x", "y").is_ok());
    }

    #[test]
    fn estimates_grow_with_the_work_and_never_wrap() {
        assert_eq!(micro_triangles(47_794, 5), 48_941_056);
        assert!(build_bytes(1_000, 3, Builds::Both) > build_bytes(1_000, 3, Builds::Grids));
        assert!(build_bytes(1_000, 3, Builds::Grids) > build_bytes(1_000, 3, Builds::LeanGrids));
        assert!(build_bytes(1_000, 4, Builds::LeanGrids) > build_bytes(1_000, 3, Builds::LeanGrids));
        assert_eq!(build_bytes(usize::MAX, 9, Builds::Both), u64::MAX);
        assert_eq!(build_bytes(usize::MAX, 9, Builds::LeanGrids), u64::MAX);
    }

    #[test]
    fn byte_counts_parse() {
        assert_eq!(parse_bytes("123"), Some(123));
        assert_eq!(parse_bytes("64k"), Some(64 << 10));
        assert_eq!(parse_bytes("500M"), Some(500 << 20));
        assert_eq!(parse_bytes("8G"), Some(8 << 30));
        assert_eq!(parse_bytes("1.5GiB"), Some(3 << 29));
        assert_eq!(parse_bytes(" 2 TB "), Some(2 << 40));
        for bad in ["", "G", "lots", "-1G", "1X"] {
            assert_eq!(parse_bytes(bad), None, "{bad}");
        }
    }
}
