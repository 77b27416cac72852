//! PNG output and image comparison.

use std::path::Path;

use crate::error::{error, fail, Result};

/// Checks, before any work, that `path` can take a file of the given kind: its parent folder
/// exists and takes new files, it is not a folder itself (nor ends in a separator, which
/// only a folder's name may), and anything already there is a plain file that writing
/// replaces. Leaves nothing behind, and clears what an earlier run killed while writing
/// `path` left beside it.
pub fn check_writable(path: &Path) -> Result<()> {
    let name = path.display();
    refuse_folder(path)?;
    if let Ok(meta) = std::fs::metadata(path) {
        if !meta.is_file() {
            fail!(
                Output,
                "{name}: is not a plain file (a device or a pipe): name a file to write"
            );
        }
    }
    let parent = folder_of(path);
    if !parent.is_dir() {
        fail!(
            Output,
            "{name}: cannot write: folder {} does not exist",
            parent.display()
        );
    }
    remove_stale_temporaries(path);
    let probe = temporary_sibling(path);
    std::fs::File::create(&probe).map_err(|e| error!(Output, "{name}: cannot write: {}", io_reason(&e)))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// Refuses a folder, or a name ending in a separator (which only a folder's name may).
fn refuse_folder(path: &Path) -> Result<()> {
    if path.is_dir() {
        fail!(Output, "{}: is a folder, not a file name", path.display());
    }
    if path.as_os_str().to_string_lossy().ends_with(std::path::is_separator) {
        fail!(
            Output,
            "{}: names a folder (it ends in a separator), not a file",
            path.display()
        );
    }
    Ok(())
}

/// [`check_writable`] for a file of one format: the name must also end in `.extension`.
pub fn check_output(path: &Path, extension: &str) -> Result<()> {
    refuse_folder(path)?;
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

/// Refuses an output that is one of the `inputs` (the same file, through whatever links or
/// other names): writing it would destroy what is being read.
pub fn check_not_input(output: &Path, inputs: &[&Path]) -> Result<()> {
    if let Some(input) = inputs.iter().find(|input| same_file(output, input)) {
        fail!(
            Output,
            "{}: is the input {}: writing it would destroy the input; name another file",
            output.display(),
            input.display()
        );
    }
    Ok(())
}

/// Whether two paths name one existing file.
#[cfg(unix)]
fn same_file(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(a), Ok(b)) => (a.dev(), a.ino()) == (b.dev(), b.ino()),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file(a: &Path, b: &Path) -> bool {
    matches!((a.canonicalize(), b.canonicalize()), (Ok(a), Ok(b)) if a == b)
}

/// Refuses two outputs of one run that are one file: the second would overwrite the first.
pub fn check_distinct(outputs: &[&Path]) -> Result<()> {
    for (k, a) in outputs.iter().enumerate() {
        for b in &outputs[k + 1..] {
            let same_name = a == b || matches!((absolute(a), absolute(b)), (Some(x), Some(y)) if x == y);
            if same_name || same_file(a, b) {
                fail!(
                    Output,
                    "{} and {} are one file: each output needs a name of its own",
                    a.display(),
                    b.display()
                );
            }
        }
    }
    Ok(())
}

/// The folder `path` is in (`.` for a bare file name).
fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// `path` made absolute, its folder's links resolved (the file itself may not exist yet).
fn absolute(path: &Path) -> Option<std::path::PathBuf> {
    Some(folder_of(path).canonicalize().ok()?.join(path.file_name()?))
}

/// The suffix that marks a file being written, before the process id.
const TEMPORARY_MARK: &str = ".gridrt-";

/// A name beside `path` for writing before renaming over it.
fn temporary_sibling(path: &Path) -> std::path::PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(format!("{TEMPORARY_MARK}{}.tmp", std::process::id()));
    path.with_file_name(name)
}

/// Removes the temporary files beside `path` that processes no longer running left behind
/// (killed while writing it). Only where the system lists running processes (`/proc`).
fn remove_stale_temporaries(path: &Path) {
    let Some(name) = path.file_name() else {
        return;
    };
    if !Path::new("/proc/self").exists() {
        return;
    }
    let folder = folder_of(path);
    let prefix = format!("{}{TEMPORARY_MARK}", name.to_string_lossy());
    let Ok(entries) = std::fs::read_dir(folder) else {
        return;
    };
    for entry in entries.flatten() {
        let file = entry.file_name().to_string_lossy().into_owned();
        let pid = file.strip_prefix(&prefix).and_then(|rest| rest.strip_suffix(".tmp"));
        let Some(pid) = pid.and_then(|p| p.parse::<u32>().ok()) else {
            continue;
        };
        if pid != std::process::id() && !Path::new("/proc").join(pid.to_string()).exists() {
            let _ = std::fs::remove_file(entry.path());
        }
    }
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
