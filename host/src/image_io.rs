//! PNG output and image comparison.

use std::path::Path;

use crate::error::{error, fail, Result};

/// Checks, before any work, that `path` can take a file of the given kind: its parent folder
/// exists and takes new files, and it is not a folder itself. Leaves nothing behind.
pub fn check_writable(path: &Path) -> Result<()> {
    let name = path.display();
    if path.is_dir() {
        fail!(Output, "{name}: is a folder, not a file name");
    }
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !parent.is_dir() {
        fail!(
            Output,
            "{name}: cannot write: folder {} does not exist",
            parent.display()
        );
    }
    let probe = temporary_sibling(path);
    std::fs::File::create(&probe).map_err(|e| error!(Output, "{name}: cannot write: {}", io_reason(&e)))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// [`check_writable`] for a file of one format: the name must also end in `.extension`.
pub fn check_output(path: &Path, extension: &str) -> Result<()> {
    if path.is_dir() {
        fail!(Output, "{}: is a folder, not a file name", path.display());
    }
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    if ext.as_deref() != Some(extension) {
        let found = match &ext {
            Some(e) => format!("'.{e}'"),
            None => "no extension".to_string(),
        };
        fail!(
            Output,
            "{}: unsupported format ({found}); gridrt writes {} here, name the file *.{extension}",
            path.display(),
            extension.to_ascii_uppercase()
        );
    }
    check_writable(path)
}

/// [`check_output`] for the one image format written, PNG.
pub fn check_png_path(path: &Path) -> Result<()> {
    check_output(path, "png")
}

/// A name beside `path` for writing before renaming over it.
fn temporary_sibling(path: &Path) -> std::path::PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".gridrt-{}.tmp", std::process::id()));
    path.with_file_name(name)
}

/// Runs `write` on a temporary file beside `path`, then renames it over `path`: a failure
/// never leaves a truncated or empty file under the real name.
pub fn write_atomically(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let temp = temporary_sibling(path);
    let result = write(&temp).and_then(|()| {
        std::fs::rename(&temp, path).map_err(|e| error!(Output, "{}: cannot write: {}", path.display(), io_reason(&e)))
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&temp);
    }
    result
}

/// Writes packed RGBA8 pixels (red in the low byte) as a PNG.
pub fn write_png(path: &Path, pixels: &[u32], width: u32, height: u32) -> Result<()> {
    let bytes: Vec<u8> = pixels.iter().flat_map(|p| p.to_le_bytes()).collect();
    write_atomically(path, |temp| {
        image::save_buffer_with_format(
            temp,
            &bytes,
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

/// The OS reason without Rust's " (os error 2)" suffix: `No such file or directory`.
pub fn io_reason(e: &std::io::Error) -> String {
    let s = e.to_string();
    match s.rfind(" (os error ") {
        Some(i) => s[..i].to_string(),
        None => s,
    }
}
