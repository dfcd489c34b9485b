//! Atomic file output: write a temporary file next to the target, then rename it, so a reader
//! (or a crash) never leaves a half-written file under the real name.

use std::path::{Path, PathBuf};

/// The temporary name used while writing `path`: a hidden file in the same directory whose
/// name ends like the target's, so tools that look at the extension still recognise it.
fn temporary(path: &Path) -> PathBuf {
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

/// Writes `path` atomically with a writer of its own: `write` fills the temporary file it is
/// given, which is then renamed to `path` (`renamed` turns a failed rename into `E`). When
/// either fails, the temporary file is removed, so a failed write leaves no file behind.
pub fn write_with<E>(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), E>,
    renamed: impl FnOnce(std::io::Error) -> E,
) -> Result<(), E> {
    let tmp = temporary(path);
    let done = write(&tmp).and_then(|()| std::fs::rename(&tmp, path).map_err(renamed));
    if done.is_err() {
        // The error to report is the write's; a temporary file that was never made is fine.
        let _ = std::fs::remove_file(&tmp);
    }
    done
}

/// Writes `contents` to `path` atomically.
pub fn write(path: &Path, contents: impl AsRef<[u8]>) -> std::io::Result<()> {
    write_with(path, |tmp| std::fs::write(tmp, contents), |e| e)
}

/// Copies `from` to `to` atomically.
pub fn copy(from: &Path, to: &Path) -> std::io::Result<()> {
    write_with(to, |tmp| std::fs::copy(from, tmp).map(drop), |e| e)
}

/// An empty directory for a unit test's files, named after `name` and the process.
#[cfg(test)]
pub(crate) fn test_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("mpgdrive-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn a_failed_write_or_rename_leaves_the_old_file_and_no_temporary_one() {
        let dir = test_dir("atomic");
        let path = dir.join("out.csv");
        write(&path, "old").unwrap();
        // The writer fails after it wrote half of its file.
        let failed = write_with(
            &path,
            |tmp| {
                std::fs::write(tmp, "ha").unwrap();
                Err("disk full")
            },
            |_| "rename",
        );
        assert_eq!(failed, Err("disk full"));
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old");
        assert_eq!(names(&dir), ["out.csv"]);
        // The rename fails: the target is a directory that holds a file.
        let blocked = dir.join("taken");
        std::fs::create_dir_all(blocked.join("inside")).unwrap();
        assert!(write(&blocked, "new").is_err());
        assert!(copy(&path, &blocked).is_err());
        assert_eq!(names(&dir), ["out.csv", "taken"]);
        // A copy of a missing file fails before it makes anything.
        assert!(copy(&dir.join("missing"), &dir.join("copy")).is_err());
        assert_eq!(names(&dir), ["out.csv", "taken"]);
        // Both succeed under the real names only.
        write(&path, "new").unwrap();
        copy(&path, &dir.join("copy")).unwrap();
        assert_eq!(std::fs::read_to_string(dir.join("copy")).unwrap(), "new");
        assert_eq!(names(&dir), ["copy", "out.csv", "taken"]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
