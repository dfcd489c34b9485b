//! Shared helpers for the integration tests.
#![allow(dead_code)]

use mpgdrive::config::Config;
use mpgdrive::sim::state::{Scene, Vehicle};
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
    Scene { vehicles }
}
