//! Merge geometry of a SUMO network (`sumo_nets/*/merge.toml`): where the conflict point is,
//! which lanes are the ramp and the target lane, which vehicle types mpgdrive may drive.
//!
//! Positions are distances along the lanes ([`crate::sumo::positions`]): the first target
//! lane starts at `target_start` (0 unless set), so any network shape works: curved ramps,
//! rotated or bending freeways.

use crate::config::{ConfigError, check, finite, load_toml, non_negative};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Which players of an ego's game the MPG policy drives besides the ego.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PlayerControl {
    /// Every player: the ego's eight (Table I policies), or every vehicle in the control zone
    /// (traffic policies): the game, everyone on the shared policy.
    All,
    /// Only players whose vehicle type is controllable (with traffic policies: inside the
    /// control zone). With no controllable freeway vehicles, the egos alone.
    Controllable,
}

/// The contents of `merge.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MergeGeometry {
    /// Position of the conflict point (m): on the acceleration lane.
    pub conflict_point: f64,
    /// A controllable ramp vehicle becomes an ego once its centre passes this position (m).
    pub control_from: f64,
    /// Control of a merged ego ends this far past the conflict point (m).
    pub release_after: f64,
    /// From this position on (m; on the acceleration lane) a ramp vehicle the policy drives
    /// changes to the target lane at the first gap the merge gate's entry check finds safe,
    /// and at the conflict point at the latest. Unset: at the conflict point, as the internal
    /// simulator merges.
    #[serde(default)]
    pub merge_from: Option<f64>,
    /// The desired speed a traffic policy observes (m/s). Unset: the speed limit of the
    /// target lane beside the acceleration lane. Either way within the range the policy was
    /// trained on (`traffic.desired_speed`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub desired_speed: Option<f64>,
    /// Lanes of the ramp, in driving order, the acceleration lane last (egos drive here before
    /// merging).
    pub ramp_lanes: Vec<String>,
    /// Lanes of the target lane, in driving order (players drive here; an ego merges into
    /// one).
    pub target_lanes: Vec<String>,
    /// Position of the start of the first target lane (m; default 0). The bundled networks
    /// set it so that positions are their network x (NGSIM's Local_Y on `i80_merge`).
    #[serde(default)]
    pub target_start: f64,
    /// Vehicle types mpgdrive may drive as egos.
    pub controllable_types: Vec<String>,
    /// Which players the MPG policy drives.
    pub players: PlayerControl,
}

impl MergeGeometry {
    /// Reads and checks a `merge.toml`.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let g: MergeGeometry = load_toml(path)?;
        g.validate()?;
        Ok(g)
    }

    /// Range checks that need no network.
    pub fn validate(&self) -> Result<(), ConfigError> {
        finite("conflict_point", self.conflict_point)?;
        finite("control_from", self.control_from)?;
        non_negative("release_after", self.release_after)?;
        finite("target_start", self.target_start)?;
        if let Some(v) = self.desired_speed {
            finite("desired_speed", v)?;
            check("desired_speed", v > 0.0, format!("{v} must be positive"))?;
        }
        if let Some(from) = self.merge_from {
            finite("merge_from", from)?;
            check(
                "merge_from",
                from <= self.conflict_point,
                format!("{from} must not lie past conflict_point {}", self.conflict_point),
            )?;
        }
        check(
            "control_from",
            self.control_from < self.conflict_point,
            format!(
                "{} must lie before conflict_point {}",
                self.control_from, self.conflict_point
            ),
        )?;
        for (key, list) in [
            ("ramp_lanes", &self.ramp_lanes),
            ("target_lanes", &self.target_lanes),
            ("controllable_types", &self.controllable_types),
        ] {
            check(key, !list.is_empty(), "must not be empty".into())?;
        }
        Ok(())
    }

    /// Checks every lane id against the network's lanes and names the ones that exist.
    pub fn check_lanes(&self, network_lanes: &[String]) -> Result<(), ConfigError> {
        for (key, list) in [
            ("ramp_lanes", &self.ramp_lanes),
            ("target_lanes", &self.target_lanes),
        ] {
            if let Some(bad) = list.iter().find(|l| !network_lanes.contains(l)) {
                let existing: Vec<&str> = network_lanes
                    .iter()
                    .filter(|l| !l.starts_with(':'))
                    .map(String::as_str)
                    .collect();
                return Err(ConfigError::Invalid {
                    key: key.into(),
                    message: format!(
                        "lane `{bad}` is not in the network; its lanes are: {}",
                        existing.join(", ")
                    ),
                });
            }
        }
        Ok(())
    }

    /// Whether a lane is a ramp lane.
    pub fn is_ramp(&self, lane: &str) -> bool {
        self.ramp_lanes.iter().any(|l| l == lane)
    }

    /// Whether a lane is a target lane.
    pub fn is_target(&self, lane: &str) -> bool {
        self.target_lanes.iter().any(|l| l == lane)
    }

    /// The target lane next to ramp lane `lane` on the same edge (index + 1), if it is one.
    pub fn merge_lane(&self, lane: &str) -> Option<(String, i32)> {
        let (edge, index) = split_lane_id(lane)?;
        let next = format!("{edge}_{}", index + 1);
        self.is_target(&next).then_some((next, index + 1))
    }
}

/// Splits a SUMO lane id `<edge>_<index>` into its edge and index.
pub fn split_lane_id(lane: &str) -> Option<(&str, i32)> {
    let (edge, index) = lane.rsplit_once('_')?;
    Some((edge, index.parse().ok()?))
}
