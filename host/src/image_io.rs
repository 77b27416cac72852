//! PNG output and image comparison.

use std::path::Path;

use crate::error::{error, Result};
use crate::files::write_atomically;

/// Writes packed RGBA8 pixels (red in the low byte) as a PNG.
pub fn write_png(path: &Path, pixels: &[u32], width: u32, height: u32) -> Result<()> {
    write_png_bytes(path, &rgba_bytes(pixels), width, height)
}

/// Packed RGBA8 pixels (red in the low byte) as bytes, red first.
pub fn rgba_bytes(pixels: &[u32]) -> Vec<u8> {
    pixels.iter().flat_map(|p| p.to_le_bytes()).collect()
}

/// Writes RGBA8 bytes, row by row from the top, as a PNG (through a temporary file, so a
/// failure leaves no partial one).
pub fn write_png_bytes(path: &Path, bytes: &[u8], width: u32, height: u32) -> Result<()> {
    write_atomically(path, |temp| {
        image::save_buffer_with_format(
            temp,
            bytes,
            width,
            height,
            image::ColorType::Rgba8,
            image::ImageFormat::Png,
        )
        .map_err(|e| error!(Output, "{}: cannot write PNG: {e}", path.display()))
    })
}

/// Largest per-channel difference of two pixels.
pub fn pixel_difference(a: u32, b: u32) -> u32 {
    (0..4)
        .map(|c| ((a >> (8 * c)) & 0xff).abs_diff((b >> (8 * c)) & 0xff))
        .max()
        .unwrap_or(0)
}

/// Fraction of pixels whose every channel differs by at most `tolerance`.
pub fn fraction_within(a: &[u32], b: &[u32], tolerance: u32) -> f64 {
    assert_eq!(a.len(), b.len(), "images of different sizes");
    let close = a
        .iter()
        .zip(b)
        .filter(|(x, y)| pixel_difference(**x, **y) <= tolerance)
        .count();
    close as f64 / a.len().max(1) as f64
}
