//! Shared helpers for the integration tests.
#![allow(dead_code)]

use mpgdrive::config::Config;
use mpgdrive::world::state::{Scene, Vehicle};
use std::path::Path;

/// The tiny test setting.
pub fn smoke() -> Config {
    Config::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/smoke.toml")).unwrap()
}

/// The paper's setting.
pub fn paper() -> Config {
    Config::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/paper.toml")).unwrap()
}

/// A vehicle in the target lane (`ramp = false`) or on the ramp at `y = -3.66`.
pub fn car(x: f64, v: f64, ramp: bool) -> Vehicle {
    Vehicle {
        x,
        y: if ramp { -3.66 } else { 0.0 },
        v,
        phi: 0.0,
        on_ramp: ramp,
    }
}

/// A scene from vehicles, ego first.
pub fn scene(vehicles: Vec<Vehicle>) -> Scene {
    Scene::new(vehicles)
}

/// The mpgdrive binary, run from the crate root.
pub fn bin() -> std::process::Command {
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_mpgdrive"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"));
    c
}

/// Runs `mpgdrive cosim --json` with `args`, the configuration `sumocfg` and `--out out`;
/// asserts it succeeded and returns its runs (the JSON on stdout) and its stderr.
pub fn cosim_json(args: &[&str], sumocfg: &Path, out: &Path) -> (serde_json::Value, String) {
    let output = bin()
        .arg("cosim")
        .args(args)
        .arg("--json")
        .arg("--sumocfg")
        .arg(sumocfg)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(output.status.success(), "{stderr}");
    (serde_json::from_slice(&output.stdout).unwrap(), stderr)
}

/// The SUMO collisions of a cosim run (`cosim.json`) that involve a controlled vehicle.
pub fn controlled_collisions(run: &serde_json::Value) -> usize {
    run["collisions"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["controlled"] == true)
        .count()
}

/// The egos of a cosim run (`cosim.json`) that finished.
pub fn finished_egos(run: &serde_json::Value) -> usize {
    run["egos"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["finished"] == true)
        .count()
}

/// A fresh, empty directory for a test under Cargo's scratch directory (target/tmp), so a
/// run leaves one set, which the next run replaces and `cargo clean` removes.
pub fn fresh_dir(name: &str) -> std::path::PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The names of the checkpoint files (`*.ckpt*`) left in `dir`.
pub fn checkpoint_files(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".ckpt"))
        .collect()
}

/// The real NGSIM sample of ../shared/data/ngsim, when it is there (a clone elsewhere may not
/// have it: the tests that need it say so and pass).
pub fn real_sample() -> Option<std::path::PathBuf> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data/ngsim/i80_0400_lanes1-3_reconstructed.csv");
    if path.is_file() {
        Some(path)
    } else {
        eprintln!("skipped: {} is not here", path.display());
        None
    }
}

/// Merge traffic (configs/traffic.toml).
pub fn traffic() -> Config {
    Config::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/traffic.toml")).unwrap()
}
