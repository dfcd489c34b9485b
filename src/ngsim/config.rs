//! The NGSIM settings (`configs/ngsim.toml`): which rows to keep, the smoothing filter, the
//! lane geometry used to reassign lanes, and where merge scenarios start.

use crate::config::{ConfigError, check, load_toml, positive};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// NGSIM frames are 0.1 s apart.
pub const FRAME_SECONDS: f64 = 0.1;

/// Everything `mpgdrive ngsim` needs besides the paper configuration.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct NgsimConfig {
    /// Rows kept from the data.transportation.gov CSV (its `Location` column).
    pub location: String,
    /// Savitzky-Golay filter.
    pub smoothing: SmoothingConfig,
    /// Lane geometry.
    pub lanes: LaneConfig,
    /// Merge scenarios.
    pub merge: MergeConfig,
}

/// Savitzky-Golay filter of the positions.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SmoothingConfig {
    /// Window length in frames (odd).
    pub window: usize,
    /// Polynomial order (below the window).
    pub order: usize,
}

/// Lanes of the study area in `Local_X` (lateral distance from the left edge).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LaneConfig {
    /// Lane width (m); lane `k` (from 1) spans `[(k - 1) w, k w)`.
    pub width: f64,
    /// Freeway lanes, numbered 1 (left-most) to this; the on-ramp is the next number.
    pub freeway_lanes: u8,
    /// Downstream end of the on-ramp (m of `Local_Y`): past it a vehicle right of the freeway
    /// lanes is in the right-most freeway lane.
    pub ramp_end: f64,
}

impl LaneConfig {
    /// The on-ramp's lane number (one past the freeway lanes: 7 at I-80).
    pub fn ramp_lane(&self) -> u8 {
        self.freeway_lanes + 1
    }

    /// The target lane of a merge: the right-most freeway lane (6 at I-80).
    pub fn target_lane(&self) -> u8 {
        self.freeway_lanes
    }

    /// The lane at lateral position `x` and longitudinal position `y` (both m).
    pub fn lane_at(&self, x: f64, y: f64) -> u8 {
        let last = if y < self.ramp_end {
            self.ramp_lane()
        } else {
            self.freeway_lanes
        };
        // Clamped before the conversion: a far-off (or NaN) position must not overflow.
        let k = (x / self.width).floor().clamp(0.0, f64::from(last) - 1.0);
        if k.is_nan() { 1 } else { k as u8 + 1 }
    }

    /// Lateral offset of lane `lane`'s centre from the target lane's centre, positive to the
    /// left (the internal simulator's `y`: the ramp is at `-width`).
    pub fn offset(&self, lane: u8) -> f64 {
        (f64::from(self.target_lane()) - f64::from(lane)) * self.width
    }
}

/// Where merge scenarios start and how many are replayed.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MergeConfig {
    /// Conflict point `x_c` (m of `Local_Y`); replaces `scenario.conflict_point`.
    pub conflict_point: f64,
    /// A scenario starts when the ego's centre is this far before the conflict point (m).
    pub start_distance: f64,
    /// At most this many scenarios are replayed (the first by start time).
    pub max_scenarios: usize,
}

impl NgsimConfig {
    /// Reads and validates a TOML file.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let config: NgsimConfig = load_toml(path)?;
        config.validate()?;
        Ok(config)
    }

    /// Checks ranges; the first problem found is returned.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let s = &self.smoothing;
        check(
            "smoothing.window",
            s.window % 2 == 1 && s.window > s.order,
            format!(
                "{} must be odd and larger than smoothing.order ({})",
                s.window, s.order
            ),
        )?;
        positive("lanes.width", self.lanes.width)?;
        check(
            "lanes.freeway_lanes",
            (1..=20).contains(&self.lanes.freeway_lanes),
            "must be between 1 and 20".into(),
        )?;
        positive("lanes.ramp_end", self.lanes.ramp_end)?;
        positive("merge.conflict_point", self.merge.conflict_point)?;
        positive("merge.start_distance", self.merge.start_distance)?;
        check(
            "merge.max_scenarios",
            self.merge.max_scenarios >= 1,
            "must be at least 1".into(),
        )
    }
}
