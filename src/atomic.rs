//! Atomic file output: write a temporary file next to the target, then rename it, so a reader
//! (or a crash) never leaves a half-written file under the real name.

use std::path::{Path, PathBuf};

/// The temporary name used while writing `path`: a hidden file in the same directory whose
/// name ends like the target's, so tools that look at the extension still recognise it.
pub fn temporary(path: &Path) -> PathBuf {
    let mut name = std::ffi::OsString::from(format!(".{}.tmp.", std::process::id()));
    name.push(path.file_name().unwrap_or_default());
    path.with_file_name(name)
}

/// `path` with `suffix` appended to its file name (`seed0` + `.ckpt` = `seed0.ckpt`), unlike
/// `Path::with_extension`, which would replace an existing extension.
pub fn with_suffix(path: &Path, suffix: &str) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(suffix);
    path.with_file_name(name)
}

/// Writes `contents` to `path` atomically.
pub fn write(path: &Path, contents: impl AsRef<[u8]>) -> std::io::Result<()> {
    let tmp = temporary(path);
    std::fs::write(&tmp, contents)?;
    std::fs::rename(&tmp, path)
}

/// Copies `from` to `to` atomically.
pub fn copy(from: &Path, to: &Path) -> std::io::Result<()> {
    let tmp = temporary(to);
    std::fs::copy(from, &tmp)?;
    std::fs::rename(&tmp, to)
}
