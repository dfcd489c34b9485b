//! A run's checkpoint: its policy file `BASE.ckpt.{safetensors,json}` and Adam's state
//! `BASE.ckpt.adam.safetensors`, the sidecar written last.
//!
//! Each file is replaced atomically, but no single rename replaces three files, so a crash
//! while a checkpoint is written could leave new weights beside the old sidecar. A write
//! therefore first keeps a copy of the checkpoint it replaces under `BASE.ckpt.prev.*`
//! (sidecar last), then writes the new files (sidecar last), then removes the kept ones
//! (sidecar first). Whenever the process stops, one complete checkpoint remains, and
//! [`latest`] finds it: the kept one while the new sidecar has not replaced the old.

use super::TrainError;
use crate::atomic::with_suffix;
use crate::policy::file;
use std::io::ErrorKind;
use std::path::{Path, PathBuf};

/// The checkpoint base path of a run (`BASE.ckpt`).
pub fn checkpoint_path(out: &Path) -> PathBuf {
    with_suffix(out, ".ckpt")
}

/// Where a checkpoint is kept while the next one is written (`BASE.ckpt.prev`).
fn previous_path(out: &Path) -> PathBuf {
    with_suffix(out, ".ckpt.prev")
}

/// The optimiser state of the checkpoint based at `ckpt` (Adam's steps and moments).
pub fn moments_path(ckpt: &Path) -> PathBuf {
    with_suffix(ckpt, ".adam.safetensors")
}

/// A checkpoint's files: weights, optimiser state and, written last, the sidecar.
fn files(ckpt: &Path) -> [PathBuf; 3] {
    let (weights, sidecar) = file::paths(ckpt);
    [weights, moments_path(ckpt), sidecar]
}

/// The epochs a checkpoint's sidecar says it holds, if it has a readable one.
fn epochs(ckpt: &Path) -> Option<u64> {
    let text = std::fs::read_to_string(file::paths(ckpt).1).ok()?;
    serde_json::from_str::<serde_json::Value>(&text)
        .ok()?
        .get("epochs")?
        .as_u64()
}

/// The base path of the run's last complete checkpoint, if it has one: `BASE.ckpt`, or
/// `BASE.ckpt.prev` when the write of the next one was cut short.
pub fn latest(out: &Path) -> Option<PathBuf> {
    let (current, previous) = (checkpoint_path(out), previous_path(out));
    match (epochs(&current), epochs(&previous)) {
        (_, None) => file::paths(&current).1.exists().then_some(current),
        (Some(now), Some(before)) if now > before => Some(current),
        _ => Some(previous),
    }
}

/// `result` of an operation on `path`, a missing file counting as done.
fn unless_missing(path: &Path, result: std::io::Result<()>) -> Result<(), TrainError> {
    match result {
        Err(e) if e.kind() != ErrorKind::NotFound => Err(TrainError::Io {
            path: path.to_path_buf(),
            source: e,
        }),
        _ => Ok(()),
    }
}

fn remove(path: &Path) -> Result<(), TrainError> {
    unless_missing(path, std::fs::remove_file(path))
}

/// Removes the checkpoint kept at `ckpt`, its sidecar first so that it never looks complete.
fn remove_kept(ckpt: &Path) -> Result<(), TrainError> {
    files(ckpt).iter().rev().try_for_each(|f| remove(f))
}

/// Writes a checkpoint of the run at `out` with `save`, which writes the three files of the
/// base path it is given, each by a rename and the sidecar last.
pub fn write(out: &Path, save: impl FnOnce(&Path) -> Result<(), TrainError>) -> Result<(), TrainError> {
    let (current, previous) = (checkpoint_path(out), previous_path(out));
    // When the kept checkpoint is the last complete one, the current files may be a mixture:
    // keep it as it is.
    if latest(out).as_ref() == Some(&current) {
        remove_kept(&previous)?;
        // A checkpoint from before the optimiser state was kept has none to copy.
        for (from, to) in files(&current).iter().zip(files(&previous)) {
            unless_missing(&to, crate::atomic::copy(from, &to))?;
        }
    }
    save(&current)?;
    remove_kept(&previous)
}

/// Removes every file of the run's checkpoints (the finished policy supersedes them).
pub fn remove_all(out: &Path) {
    for ckpt in [checkpoint_path(out), previous_path(out)] {
        let _ = remove_kept(&ckpt);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        crate::atomic::test_dir(&format!("ckpt-{name}"))
    }

    /// A checkpoint of `epochs` at `ckpt` whose weights and state hold `tag`, each file
    /// replaced by a rename as the trainer does.
    fn put(ckpt: &Path, epochs: u64, tag: &str) {
        let [weights, state, sidecar] = files(ckpt);
        crate::atomic::write(&weights, tag).unwrap();
        crate::atomic::write(&state, tag).unwrap();
        crate::atomic::write(&sidecar, format!("{{\"epochs\": {epochs}}}")).unwrap();
    }

    fn read(path: &Path) -> String {
        std::fs::read_to_string(path).unwrap()
    }

    #[test]
    fn the_latest_complete_checkpoint_is_found_after_a_cut_at_any_point() {
        let d = dir("latest");
        let out = d.join("seed3");
        let (current, previous) = (checkpoint_path(&out), previous_path(&out));
        assert_eq!(latest(&out), None, "no checkpoint yet");
        // The first write cut before its sidecar: nothing to resume.
        std::fs::write(&files(&current)[0], "w10").unwrap();
        assert_eq!(latest(&out), None);
        put(&current, 10, "w10");
        assert_eq!(latest(&out), Some(current.clone()));
        // The next write cut after the old files were kept and the new weights written.
        for (from, to) in files(&current).iter().zip(files(&previous)) {
            std::fs::copy(from, to).unwrap();
        }
        crate::atomic::write(&files(&current)[0], "w20").unwrap();
        assert_eq!(latest(&out), Some(previous.clone()));
        assert_eq!(
            read(&files(&previous)[0]),
            "w10",
            "the kept weights are the old ones"
        );
        // Cut after the new sidecar: the new checkpoint is complete.
        put(&current, 20, "w20");
        assert_eq!(latest(&out), Some(current.clone()));
        // Cut while the kept files were removed, sidecar first.
        std::fs::remove_file(&files(&previous)[2]).unwrap();
        assert_eq!(latest(&out), Some(current));
        let _ = std::fs::remove_dir_all(d);
    }

    #[test]
    fn a_write_after_a_cut_keeps_the_complete_checkpoint_and_leaves_one() {
        let d = dir("write");
        let out = d.join("seed3");
        let (current, previous) = (checkpoint_path(&out), previous_path(&out));
        // A cut write of epoch 20 over epoch 10: epoch 10 is kept; the current files mixed.
        put(&previous, 10, "w10");
        put(&current, 10, "w20");
        // The resumed run's next write (epoch 20 again) must not keep the mixture.
        write(&out, |ckpt| {
            assert_eq!(read(&files(&previous)[0]), "w10", "still kept during the write");
            put(ckpt, 20, "new");
            Ok(())
        })
        .unwrap();
        assert_eq!(latest(&out), Some(current.clone()));
        assert!(files(&previous).iter().all(|f| !f.exists()), "kept files removed");
        // An uncut write keeps the current checkpoint while it writes the next, even one
        // without an optimiser state (written before it was kept).
        std::fs::remove_file(&files(&current)[1]).unwrap();
        write(&out, |ckpt| {
            assert_eq!(latest(&out), Some(previous.clone()), "mid-write");
            assert_eq!(read(&files(&previous)[0]), "new");
            assert!(!files(&previous)[1].exists());
            put(ckpt, 30, "newer");
            Ok(())
        })
        .unwrap();
        assert_eq!(read(&files(&current)[0]), "newer");
        assert!(files(&previous).iter().all(|f| !f.exists()));
        remove_all(&out);
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 0, "nothing left");
        let _ = std::fs::remove_dir_all(d);
    }
}
