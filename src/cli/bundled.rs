//! The bundled configurations and policies (`configs/`, `policies/`), found from any folder.
//!
//! The binary carries them (`build.rs` embeds every file of both folders). A default such as
//! `configs/traffic.toml` or `policies/traffic/mpg`, or the same name typed by the user, is
//! used as a path relative to the current directory when it exists there (the repository's
//! root: a retrained policy there is the one used); otherwise under `$MPGDRIVE_HOME` when that
//! is set and holds it; otherwise the bundled copy, written once into the per-user cache
//! (`${XDG_CACHE_HOME:-$HOME/.cache}/mpgdrive/bundle-<version>-<hash>`). Any other path is the
//! user's and stays relative to the current directory.

use anyhow::{Context, Result};
use std::path::{Path, PathBuf};

include!(concat!(env!("OUT_DIR"), "/bundle.rs"));

/// The environment variable naming a folder that holds `configs/` and `policies/`.
pub const HOME_VAR: &str = "MPGDRIVE_HOME";

/// Where `path` is found: itself when it exists, or, when it names a bundled file or folder,
/// `$MPGDRIVE_HOME/path` or the bundled copy (module docs).
pub fn resolve(path: &Path) -> Result<PathBuf> {
    if path.exists() || !is_bundled(path) {
        return Ok(path.to_path_buf());
    }
    if let Some(home) = std::env::var_os(HOME_VAR) {
        let there = Path::new(&home).join(path);
        if there.exists() {
            return Ok(there);
        }
    }
    Ok(unpacked()?.join(path))
}

/// Whether `path` is a bundled file or a folder of bundled files (relative, `/`-separated).
fn is_bundled(path: &Path) -> bool {
    let Some(name) = path.to_str().filter(|_| path.is_relative()) else {
        return false;
    };
    let name = name.trim_start_matches("./").trim_end_matches('/');
    FILES
        .iter()
        .any(|(f, _)| *f == name || f.strip_prefix(name).is_some_and(|rest| rest.starts_with('/')))
}

/// The folder holding the bundled files, written on first use: into a temporary folder beside
/// it, then renamed, so that a reader never sees half of it.
fn unpacked() -> Result<PathBuf> {
    let cache = match std::env::var_os("XDG_CACHE_HOME").filter(|v| !v.is_empty()) {
        Some(dir) => PathBuf::from(dir),
        None => PathBuf::from(std::env::var_os("HOME").context("neither XDG_CACHE_HOME nor HOME is set")?)
            .join(".cache"),
    };
    let dir = cache.join("mpgdrive").join(format!(
        "bundle-{}-{:016x}",
        env!("CARGO_PKG_VERSION"),
        fingerprint()
    ));
    if dir.is_dir() {
        return Ok(dir);
    }
    let parent = dir.parent().expect("has a parent");
    std::fs::create_dir_all(parent).with_context(|| format!("creating {}", parent.display()))?;
    let tmp = parent.join(format!(".bundle.{}.tmp", std::process::id()));
    let written = (|| -> std::io::Result<()> {
        for (name, bytes) in FILES {
            let file = tmp.join(name);
            std::fs::create_dir_all(file.parent().expect("has a parent"))?;
            std::fs::write(file, bytes)?;
        }
        Ok(())
    })();
    let renamed = written.and_then(|()| std::fs::rename(&tmp, &dir));
    if renamed.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    // Another process may have unpacked the same bundle first.
    if !dir.is_dir() {
        renamed.with_context(|| {
            format!(
                "unpacking the bundled configurations and policies into {}",
                dir.display()
            )
        })?;
    }
    Ok(dir)
}

/// FNV-1a over every bundled file's name and bytes: a new bundle gets a new folder.
fn fingerprint() -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for (name, bytes) in FILES {
        for &b in name.as_bytes().iter().chain([0u8].iter()).chain(bytes.iter()) {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bundle_holds_the_shipped_configurations_and_policies() {
        for name in [
            "configs/paper.toml",
            "configs/traffic.toml",
            "policies/traffic/mpg/seed0.safetensors",
        ] {
            let (_, bytes) = FILES.iter().find(|(f, _)| *f == name).expect(name);
            let on_disk = std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join(name)).unwrap();
            assert_eq!(*bytes, on_disk.as_slice(), "{name}");
        }
        assert!(is_bundled(Path::new("policies/traffic/mpg")));
        assert!(is_bundled(Path::new("./configs/paper.toml")));
        assert!(!is_bundled(Path::new("policies/traffic/m")));
        assert!(!is_bundled(Path::new("my.toml")));
    }
}
