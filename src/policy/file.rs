//! Policy files: weights in safetensors (`NAME.safetensors`) plus a JSON sidecar
//! (`NAME.json`) holding the observation layout version, network sizes and scales, action
//! scale, training configuration, seed, the command that made it, code version and metrics.
//!
//! Both files are written to temporary names and renamed, so a reader never sees half a
//! policy. A file whose layout does not match, or whose weights are truncated or corrupted, is
//! refused with a [`PolicyError`].

use crate::atomic::with_suffix;
use crate::config::Config;
use crate::policy::mode::Mode;
use crate::policy::network::{NetSpec, PolicyNet};
use crate::policy::observation::Layout;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Marker of the sidecar format.
pub const FORMAT: &str = "mpgdrive-policy";

/// A policy file problem.
#[derive(Debug, thiserror::Error)]
pub enum PolicyError {
    /// Reading or writing failed.
    #[error("cannot access {path}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The sidecar is not valid JSON of the expected shape.
    #[error("{path}: not an mpgdrive policy sidecar: {message}")]
    Sidecar {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The policy was made for another observation layout or player count.
    #[error("{path}: {message}")]
    Mismatch {
        /// The file.
        path: PathBuf,
        /// What does not match.
        message: String,
    },
    /// The weights could not be read or do not fit the network.
    #[error("{path}: unreadable or mismatched weights: {message}")]
    Weights {
        /// The file.
        path: PathBuf,
        /// libtorch's message.
        message: String,
    },
}

/// The JSON sidecar.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Sidecar {
    /// Always [`FORMAT`].
    pub format: String,
    /// Observation layout version ([`Layout::version`]).
    pub obs_layout_version: u32,
    /// Network sizes and scales.
    pub net: NetSpec,
    /// What the policy learned: shared policy for every player, or ego only.
    pub mode: Mode,
    /// Training seed.
    pub seed: u64,
    /// Epochs trained.
    pub epochs: usize,
    /// The command line that produced the file.
    pub command: String,
    /// mpgdrive version.
    pub code_version: String,
    /// The full configuration used.
    pub config: Config,
    /// Final training metrics.
    pub metrics: serde_json::Value,
}

/// The two file paths of a policy named by `base`: `base` itself may name either file
/// (`.safetensors` or `.json`) or neither (then both extensions are appended).
pub fn paths(base: &Path) -> (PathBuf, PathBuf) {
    let stem = match base.extension().and_then(|e| e.to_str()) {
        Some("safetensors" | "json") => base.with_extension(""),
        _ => base.to_path_buf(),
    };
    (with_suffix(&stem, ".safetensors"), with_suffix(&stem, ".json"))
}

/// The world rules a trained policy's behaviour rests on, by configuration key: the step, the
/// limits, the vehicle box, the geometry and the feasibility rules (flags as 0 or 1).
fn world_rules(c: &Config) -> [(&'static str, f64); 23] {
    let flag = |b: bool| if b { 1.0 } else { 0.0 };
    [
        ("sim.dt", c.sim.dt),
        ("vehicle.max_accel", c.vehicle.max_accel),
        ("vehicle.v_min", c.vehicle.v_min),
        ("vehicle.v_max", c.vehicle.v_max),
        ("vehicle.length", c.vehicle.length),
        ("vehicle.width", c.vehicle.width),
        ("scenario.conflict_point", c.scenario.conflict_point),
        ("scenario.lane_width", c.scenario.lane_width),
        ("sim.feasibility", flag(c.sim.feasibility)),
        ("sim.tau_s", c.sim.tau_s),
        ("sim.safety_gap", c.sim.safety_gap),
        ("sim.time_headway", c.sim.time_headway),
        (
            "sim.projection_order (1: sequential, 2: shared)",
            match c.sim.projection_order {
                crate::config::ProjectionOrder::Simultaneous => 0.0,
                crate::config::ProjectionOrder::Sequential => 1.0,
                crate::config::ProjectionOrder::Shared => 2.0,
            },
        ),
        ("sim.shared_correction", c.sim.shared_correction),
        ("sim.merge_gate", flag(c.sim.merge_gate)),
        ("sim.b_safe", c.sim.b_safe),
        (
            "scenario.entry (1: gap)",
            flag(c.scenario.entry == crate::config::Entry::Gap),
        ),
        ("sim.reaction_time", c.sim.reaction_time),
        ("sim.project_non_learning", flag(c.sim.project_non_learning)),
        ("sim.players_make_room", flag(c.sim.players_make_room)),
        (
            "sim.feasibility_across_lanes",
            flag(c.sim.feasibility_across_lanes),
        ),
        (
            "scenario.yield_zone",
            crate::world::geometry::Road::new(c).yield_zone,
        ),
        ("reward.v_desired", c.reward.v_desired),
    ]
}

/// Refuses a policy (`path`, its sidecar) trained under other world rules than `run`'s,
/// naming the first setting that differs.
pub fn check_rules(path: &Path, sidecar: &Sidecar, run: &Config) -> Result<(), PolicyError> {
    match first_difference(&world_rules(&sidecar.config), &world_rules(run)) {
        None => Ok(()),
        Some((key, was, now)) => Err(PolicyError::Mismatch {
            path: path.to_path_buf(),
            message: format!(
                "trained with {key} = {was}, this run's configuration has {now}; use the configuration it was trained with{}",
                ALLOW_HINT
            ),
        }),
    }
}

/// The first reward setting of `run` other than the one `sidecar`'s policy was trained with,
/// as "key = trained, this run's", or `None`. The policy acts the same under another reward
/// (it is no world rule), but the returns and potentials a run reports are its own reward's.
pub fn reward_difference(sidecar: &Sidecar, run: &Config) -> Option<String> {
    let terms = |c: &Config| {
        let r = &c.reward;
        [
            ("reward.v_c", r.v_c),
            ("reward.epsilon", r.epsilon),
            ("reward.w_speed", r.w_speed),
            ("reward.w_comfort", r.w_comfort),
            ("reward.w_ttc", r.w_ttc),
            ("reward.w_conflict", r.w_conflict),
            ("reward.w_speed_ramp", r.speed_weight_on_ramp()),
            (
                "reward.conflict_ends_at_x_c",
                f64::from(u8::from(r.conflict_ends_at_x_c)),
            ),
            ("reward.conflict_clearance", r.conflict_clearance),
            (
                "reward.conflict_signed_time",
                f64::from(u8::from(r.conflict_signed_time)),
            ),
        ]
    };
    first_difference(&terms(&sidecar.config), &terms(run))
        .map(|(key, was, now)| format!("{key} = {was}, this run's {now}"))
}

/// The first setting whose value differs between two lists of the same keys: (key, the
/// first's value, the second's).
fn first_difference(
    a: &[(&'static str, f64)],
    b: &[(&'static str, f64)],
) -> Option<(&'static str, f64, f64)> {
    a.iter()
        .zip(b)
        .find(|(x, y)| x.1 != y.1)
        .map(|(&(key, was), &(_, now))| (key, was, now))
}

/// How to use a policy under other rules anyway (the commands that allow it).
const ALLOW_HINT: &str = " (eval --allow-policy-mismatch evaluates it anyway)";

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> PolicyError + '_ {
    move |source| PolicyError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Writes `net` and `sidecar` atomically next to `base`.
pub fn save(base: &Path, net: &PolicyNet, sidecar: &Sidecar) -> Result<(), PolicyError> {
    let (weights, json) = paths(base);
    if let Some(dir) = weights.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(io(dir))?;
    }
    // tch chooses the format from the extension, which the temporary name keeps.
    let write_weights = |tmp: &Path| {
        net.vs.save(tmp).map_err(|e| PolicyError::Weights {
            path: weights.clone(),
            message: e.to_string(),
        })
    };
    crate::atomic::write_with(&weights, write_weights, io(&weights))?;
    let text = serde_json::to_string_pretty(sidecar).expect("a sidecar serialises");
    crate::atomic::write(&json, text).map_err(io(&json))?;
    Ok(())
}

/// Reads a policy; `layout` is the observation it must read.
pub fn load(base: &Path, layout: Layout) -> Result<(PolicyNet, Sidecar), PolicyError> {
    let (weights, json) = paths(base);
    let text = std::fs::read_to_string(&json).map_err(io(&json))?;
    let sidecar: Sidecar = serde_json::from_str(&text).map_err(|e| PolicyError::Sidecar {
        path: json.clone(),
        message: e.to_string(),
    })?;
    let mismatch = |message: String| PolicyError::Mismatch {
        path: json.clone(),
        message,
    };
    if sidecar.format != FORMAT {
        return Err(mismatch(format!(
            "format {:?}, expected {FORMAT:?}",
            sidecar.format
        )));
    }
    if sidecar.obs_layout_version != layout.version() {
        return Err(mismatch(format!(
            "observation layout version {}, the configuration's world (scenario.kind) reads version {}",
            sidecar.obs_layout_version,
            layout.version()
        )));
    }
    let expected = NetSpec::new(layout, sidecar.net.hidden, sidecar.net.action_scale);
    if sidecar.net != expected {
        return Err(mismatch(format!(
            "made for {} players (observation width {}), the configuration has {}",
            sidecar.net.n_agents,
            sidecar.net.obs_dim,
            layout.one_hot()
        )));
    }
    let mut net = PolicyNet::new(sidecar.net.clone());
    net.vs.load(&weights).map_err(|e| PolicyError::Weights {
        path: weights.clone(),
        message: e.to_string(),
    })?;
    Ok((net, sidecar))
}
