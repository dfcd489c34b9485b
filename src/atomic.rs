//! Atomic file output: write a temporary file next to the target, then rename it, so a reader
//! (or a crash) never leaves a half-written file under the real name.

use std::path::{Path, PathBuf};

/// The temporary name used while writing `path` (same directory, same extension last, so
/// tools that look at the extension still recognise it).
pub fn temporary(path: &Path) -> PathBuf {
    let mut name = std::ffi::OsString::from(".");
    name.push(path.file_name().unwrap_or_default());
    name.push(format!(".{}.tmp", std::process::id()));
    let tmp = path.with_file_name(name);
    match path.extension() {
        Some(ext) => tmp.with_extension(format!("tmp.{}", ext.to_string_lossy())),
        None => tmp,
    }
}

/// Writes `contents` to `path` atomically.
pub fn write(path: &Path, contents: impl AsRef<[u8]>) -> std::io::Result<()> {
    let tmp = temporary(path);
    std::fs::write(&tmp, contents)?;
    std::fs::rename(&tmp, path)
}
