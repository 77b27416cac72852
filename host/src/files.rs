//! Files gridrt reads and writes, and what it promises about them:
//! - an input is read only when it is a plain file: a named pipe or a device would block or
//!   never end ([`read_plain_file`]);
//! - every output is checked before any work: its folder takes files, its name has its
//!   format's extension, it is no folder, and it is none of the files the run reads, through
//!   whatever links or other names ([`check_output`], [`check_not_input`]);
//! - a file is written under a temporary name and renamed over its own, so nobody ever sees
//!   it half written ([`write_atomically`]);
//! - a set of files (a glTF and the files it names) appears whole or not at all: the side
//!   files under names of their own, then the file users open renamed over the old one, then
//!   the old side files removed ([`write_set`]).

use std::path::{Path, PathBuf};

use crate::error::{error, fail, Result};

/// The bytes of `path` where it is a plain file (links followed); otherwise, or where it
/// cannot be read, the reason, without the name: `is a named pipe, not a file`.
pub fn read_plain_file(path: &Path) -> std::result::Result<Vec<u8>, String> {
    let mut bytes = Vec::new();
    std::io::Read::read_to_end(&mut open_plain_file(path)?, &mut bytes).map_err(|e| io_reason(&e))?;
    Ok(bytes)
}

/// `path` opened for reading where it is a plain file (links followed); otherwise the reason,
/// as [`read_plain_file`] gives it.
pub fn open_plain_file(path: &Path) -> std::result::Result<std::fs::File, String> {
    let meta = std::fs::metadata(path).map_err(|e| io_reason(&e))?;
    if !meta.is_file() {
        return Err(format!("is {}, not a file", file_kind(&meta)));
    }
    std::fs::File::open(path).map_err(|e| io_reason(&e))
}

/// What a file that is not a plain file is, for messages.
fn file_kind(meta: &std::fs::Metadata) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let t = meta.file_type();
        if t.is_fifo() {
            return "a named pipe";
        }
        if t.is_socket() {
            return "a socket";
        }
        if t.is_char_device() || t.is_block_device() {
            return "a device";
        }
    }
    if meta.is_dir() {
        "a folder"
    } else {
        "something other than a plain file"
    }
}

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

/// The extension of `path`, lower-cased: formats are named case-insensitively.
pub fn extension(path: &Path) -> Option<String> {
    path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase)
}

/// [`check_writable`] for a file of one format: the name must also end in `.extension`.
pub fn check_output(path: &Path, extension: &str) -> Result<()> {
    refuse_folder(path)?;
    let ext = self::extension(path);
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
pub fn check_not_input(output: &Path, inputs: &[impl AsRef<Path>]) -> Result<()> {
    if let Some(input) = inputs.iter().map(AsRef::as_ref).find(|input| same_file(output, input)) {
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
pub fn same_file(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(a), Ok(b)) => (a.dev(), a.ino()) == (b.dev(), b.ino()),
        _ => false,
    }
}

#[cfg(not(unix))]
pub fn same_file(a: &Path, b: &Path) -> bool {
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
pub fn folder_of(path: &Path) -> &Path {
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
/// (killed while writing it).
fn remove_stale_temporaries(path: &Path) {
    let Some(name) = path.file_name().map(|n| n.to_string_lossy().into_owned()) else {
        return;
    };
    remove_stale_temporaries_in(folder_of(path), |written| written == name);
}

/// Removes the temporary files in `folder` of files whose names `written` accepts, left by
/// processes no longer running. Only where the system lists running processes (`/proc`).
fn remove_stale_temporaries_in(folder: &Path, written: impl Fn(&str) -> bool) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(folder) else {
        return;
    };
    for entry in entries.flatten() {
        let file = entry.file_name().to_string_lossy().into_owned();
        let Some((name, rest)) = file.rsplit_once(TEMPORARY_MARK) else {
            continue;
        };
        let pid = rest.strip_suffix(".tmp").and_then(|p| p.parse::<u32>().ok());
        let Some(pid) = pid.filter(|_| written(name)) else {
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

/// The OS reason without Rust's " (os error 2)" suffix: `No such file or directory`.
pub fn io_reason(e: &std::io::Error) -> String {
    let s = e.to_string();
    match s.rfind(" (os error ") {
        Some(i) => s[..i].to_string(),
        None => s,
    }
}

/// A file of a set that the set's main file names: its extension and its bytes.
pub struct SideFile {
    pub extension: &'static str,
    pub bytes: Vec<u8>,
}

/// How [`write_set`] writes the main file of a set and reads an older one.
pub trait MainFile {
    /// The main file's bytes, naming the side files by `names` (in the order given, file
    /// names without a folder).
    fn bytes(&self, names: &[String]) -> Result<Vec<u8>>;
    /// The files an older main file's `bytes` names beside it (file names as written there).
    fn side_names(&self, bytes: &[u8]) -> Vec<String>;
}

/// Writes a set of files that must be read together: `sides` beside `main`, each named
/// `STEM.TAG.EXTENSION` where `TAG` is a hash of their bytes, then `main` itself, renamed over
/// the old one last, then the old set's side files of that form that the new set does not
/// share. A reader of `main` at any moment, a kill or a full disk at any step, and writers
/// of the same set at once leave the old set or a new one whole (beside, at worst, side
/// files nothing names). Nothing in `keep` (the run's inputs) is ever written or removed.
/// Returns the paths written, `main` first.
pub fn write_set(main: &Path, sides: &[SideFile], writer: &impl MainFile, keep: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let stem = main.file_stem().unwrap_or_default().to_string_lossy().into_owned();
    let tag = content_tag(sides);
    let names: Vec<String> = sides.iter().map(|s| format!("{stem}.{tag}.{}", s.extension)).collect();
    let paths: Vec<PathBuf> = names.iter().map(|n| main.with_file_name(n)).collect();
    check_not_input(main, keep)?;
    for path in &paths {
        check_not_input(path, keep)?;
    }
    let extensions: Vec<&str> = sides.iter().map(|s| s.extension).collect();
    remove_stale_temporaries(main);
    remove_stale_temporaries_in(folder_of(main), |name| side_tag(name, &stem, &extensions).is_some());
    let write_side = |path: &Path, side: &SideFile| write_durably(path, &side.bytes);
    for (path, side) in paths.iter().zip(sides) {
        write_side(path, side)?;
    }
    let bytes = writer.bytes(&names)?;
    // Commits one at a time in a folder: another writer's removal of the files its old set
    // named cannot then meet this set's files between the check below and the rename.
    let _lock = lock_folder(folder_of(main));
    for (path, side) in paths.iter().zip(sides) {
        if !path.is_file() {
            write_side(path, side)?;
        }
    }
    let old = read_plain_file(main).map(|b| writer.side_names(&b)).unwrap_or_default();
    write_durably(main, &bytes)?;
    for name in old {
        let path = main.with_file_name(&name);
        let ours = side_tag(&name, &stem, &extensions).is_some() && !names.contains(&name);
        if ours && !keep.iter().any(|k| same_file(&path, k)) {
            let _ = std::fs::remove_file(&path);
        }
    }
    Ok(std::iter::once(main.to_path_buf()).chain(paths).collect())
}

/// [`write_atomically`] of `bytes`, on the disk before the rename: a set's main file never
/// reaches the disk ahead of the files it names.
fn write_durably(path: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    write_atomically(path, |temp| {
        let failed = |e: std::io::Error| error!(Output, "{}: cannot write: {}", path.display(), io_reason(&e));
        let mut file = std::fs::File::create(temp).map_err(failed)?;
        file.write_all(bytes).map_err(failed)?;
        file.sync_all().map_err(failed)
    })
}

/// Hex digits of a side file's tag.
const TAG_DIGITS: usize = 8;

/// The tag of a set's side files: a hash (FNV-1a) of their bytes, so that the same set is
/// written under the same names and another set under others.
fn content_tag(sides: &[SideFile]) -> String {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    for byte in sides.iter().flat_map(|s| s.bytes.iter().chain(s.extension.as_bytes())) {
        hash = (hash ^ *byte as u64).wrapping_mul(0x0100_0000_01b3);
    }
    format!("{:0width$x}", (hash ^ (hash >> 32)) as u32, width = TAG_DIGITS)
}

/// The tag of `name` where it is a side file of set `stem` (`STEM.TAG.EXTENSION`, one of
/// `extensions`), as [`write_set`] names them.
fn side_tag<'a>(name: &'a str, stem: &str, extensions: &[&str]) -> Option<&'a str> {
    let rest = name.strip_prefix(stem)?.strip_prefix('.')?;
    let (tag, extension) = rest.split_once('.')?;
    let hex = tag.len() == TAG_DIGITS && tag.bytes().all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b));
    (hex && extensions.contains(&extension)).then_some(tag)
}

/// An exclusive lock on `folder`, held until the file returned is dropped; `None` where the
/// system gives none.
fn lock_folder(folder: &Path) -> Option<std::fs::File> {
    let file = std::fs::File::open(folder).ok()?;
    file.lock().ok()?;
    Some(file)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A main file that lists its side files' names, a line each.
    struct Listing;

    impl MainFile for Listing {
        fn bytes(&self, names: &[String]) -> Result<Vec<u8>> {
            Ok(names.join("\n").into_bytes())
        }
        fn side_names(&self, bytes: &[u8]) -> Vec<String> {
            String::from_utf8_lossy(bytes).lines().map(str::to_string).collect()
        }
    }

    fn scratch(test: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("gridrt-files-{test}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn sides(text: &str) -> Vec<SideFile> {
        vec![
            SideFile {
                extension: "bin",
                bytes: format!("{text} buffer").into_bytes(),
            },
            SideFile {
                extension: "bary",
                bytes: format!("{text} micromap").into_bytes(),
            },
        ]
    }

    fn listing(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    /// A new set replaces the old one whole: the main file names the new side files, the
    /// old ones are gone, a file of the user's beside them stays, and writing the same set
    /// again changes nothing.
    #[test]
    fn a_new_set_replaces_the_old_whole() {
        let dir = scratch("replace");
        let main = dir.join("out.gltf");
        std::fs::write(dir.join("out.bin"), "the user's own").unwrap();
        let first = write_set(&main, &sides("first"), &Listing, &[]).unwrap();
        assert_eq!(first.len(), 3);
        let second = write_set(&main, &sides("second"), &Listing, &[]).unwrap();
        assert_ne!(first[1], second[1]);
        let named = Listing.side_names(&std::fs::read(&main).unwrap());
        assert_eq!(
            named,
            second[1..]
                .iter()
                .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
                .collect::<Vec<_>>()
        );
        let mut expected = vec!["out.bin".to_string(), "out.gltf".to_string()];
        expected.extend(named);
        expected.sort();
        assert_eq!(listing(&dir), expected);
        assert_eq!(write_set(&main, &sides("second"), &Listing, &[]).unwrap(), second);
        assert_eq!(listing(&dir), expected);
    }

    /// The old set's side files that are inputs of the run stay, and a side file can never
    /// be an input.
    #[test]
    fn inputs_are_never_removed_or_written() {
        let dir = scratch("inputs");
        let main = dir.join("out.gltf");
        let old = write_set(&main, &sides("old"), &Listing, &[]).unwrap();
        write_set(&main, &sides("new"), &Listing, &old[1..]).unwrap();
        assert!(old[1..].iter().all(|p| p.is_file()), "an input was removed");
        let again = dir.join("again.gltf");
        let e = write_set(&main, &sides("new"), &Listing, &[again.clone(), main.clone()]).unwrap_err();
        assert!(e.to_string().contains("is the input"), "{e}");
    }

    /// A set whose side files were removed (by another writer) between their writing and the
    /// commit has them written again; a main file killed before its rename leaves the old set.
    #[test]
    fn the_main_file_names_only_files_that_exist() {
        let dir = scratch("commit");
        let main = dir.join("out.gltf");
        write_set(&main, &sides("old"), &Listing, &[]).unwrap();
        let before = std::fs::read(&main).unwrap();
        // A writer that fails making its main file leaves the old set as it was.
        struct Failing;
        impl MainFile for Failing {
            fn bytes(&self, _: &[String]) -> Result<Vec<u8>> {
                fail!(Output, "disk full")
            }
            fn side_names(&self, _: &[u8]) -> Vec<String> {
                Vec::new()
            }
        }
        assert!(write_set(&main, &sides("new"), &Failing, &[]).is_err());
        assert_eq!(std::fs::read(&main).unwrap(), before);
        for name in Listing.side_names(&before) {
            assert!(dir.join(name).is_file());
        }
    }

    #[test]
    fn plain_files_alone_are_read() {
        let dir = scratch("plain");
        assert_eq!(read_plain_file(&dir).unwrap_err(), "is a folder, not a file");
        #[cfg(unix)]
        {
            let fifo = dir.join("pipe.bary");
            let made = std::process::Command::new("mkfifo").arg(&fifo).status();
            if made.is_ok_and(|s| s.success()) {
                assert_eq!(read_plain_file(&fifo).unwrap_err(), "is a named pipe, not a file");
            }
        }
        std::fs::write(dir.join("a.bin"), b"abc").unwrap();
        assert_eq!(read_plain_file(&dir.join("a.bin")).unwrap(), b"abc");
        assert!(read_plain_file(&dir.join("missing.bin"))
            .unwrap_err()
            .contains("No such file"));
    }

    #[test]
    fn side_names_are_recognised_strictly() {
        let ext = ["bin", "bary"];
        assert_eq!(side_tag("out.0123abcd.bin", "out", &ext), Some("0123abcd"));
        for other in [
            "out.bin",
            "out.0123abcd.png",
            "out.0123ABCD.bin",
            "out.0123abc.bin",
            "outx.0123abcd.bin",
            "x/out.0123abcd.bin",
        ] {
            assert_eq!(side_tag(other, "out", &ext), None, "{other}");
        }
    }
}
