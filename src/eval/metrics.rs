//! The six metrics of Tables II-IV, per episode and averaged.
//!
//! - collision: a collision involving the ego;
//! - failure: no collision, and the ego has not passed the conflict point by the horizon;
//! - (ours) other collision: the episode ended with a collision between two other players
//!   (it ends the episode for everyone, so an ego still on the ramp then counts as a failure);
//! - minimum inter-vehicle distance: the smallest centre-to-centre Euclidean distance between
//!   the ego and any other player over the episode (before the merge this includes the lateral
//!   offset of the ramp);
//! - average ego speed, average `|u|` of the ego's applied acceleration, average jerk
//!   magnitude `|u_t - u_{t-1}| / dt`, over the steps simulated.

use crate::engine::outcome::{EgoStats, EpisodeOutcome};
use serde::Serialize;

/// Metrics of one episode.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct EpisodeMetrics {
    /// A collision involving the ego.
    pub collision: bool,
    /// The ego did not pass the conflict point (and did not collide).
    pub failure: bool,
    /// A collision between two other players (not counted as the ego's).
    pub other_collision: bool,
    /// Minimum ego distance (m).
    pub min_distance: f64,
    /// Average ego speed (m/s).
    pub mean_speed: f64,
    /// Average ego acceleration magnitude (m/s^2).
    pub mean_abs_accel: f64,
    /// Average ego jerk magnitude (m/s^3).
    pub mean_abs_jerk: f64,
}

impl EpisodeMetrics {
    /// CSV header of the four continuous metrics, in [`Self::motion_csv`]'s order.
    pub const CSV_MOTION: &str = "min_distance,mean_speed,mean_abs_accel,mean_abs_jerk";

    /// The four continuous metrics as CSV fields (see [`Self::CSV_MOTION`]).
    pub fn motion_csv(&self) -> String {
        format!(
            "{},{},{},{}",
            self.min_distance, self.mean_speed, self.mean_abs_accel, self.mean_abs_jerk
        )
    }

    /// Metrics of an outcome.
    pub fn of(o: &EpisodeOutcome) -> Self {
        let collision = o.collision.is_some_and(|c| c.a == 0 || c.b == 0);
        EpisodeMetrics {
            other_collision: o.collision.is_some() && !collision,
            ..Self::from_stats(&o.ego, collision, o.ego_merged_at.is_some())
        }
    }

    /// Metrics from the ego's running statistics, whether it collided and whether it merged
    /// (passed the conflict point).
    pub fn from_stats(ego: &EgoStats, collision: bool, merged: bool) -> Self {
        let steps = ego.steps.max(1) as f64;
        EpisodeMetrics {
            collision,
            failure: !collision && !merged,
            other_collision: false,
            min_distance: ego.min_distance,
            mean_speed: ego.sum_speed / steps,
            mean_abs_accel: ego.sum_abs_accel / steps,
            mean_abs_jerk: ego.sum_abs_jerk / (steps - 1.0).max(1.0),
        }
    }
}

/// Averages over episodes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Summary {
    /// Episodes.
    pub episodes: usize,
    /// Episodes with an ego collision.
    pub collisions: usize,
    /// Episodes where the ego failed to merge.
    pub failures: usize,
    /// Episodes ended by a collision between other players.
    pub other_collisions: usize,
    /// Mean of the per-episode minimum distance (m).
    pub min_distance: f64,
    /// Mean ego speed (m/s).
    pub mean_speed: f64,
    /// Mean ego acceleration magnitude (m/s^2).
    pub mean_abs_accel: f64,
    /// Mean ego jerk magnitude (m/s^3).
    pub mean_abs_jerk: f64,
}

impl Summary {
    /// Summary of episode metrics.
    pub fn of(metrics: &[EpisodeMetrics]) -> Self {
        let n = metrics.len().max(1) as f64;
        // 0.0 + ...: an empty sum of f64 is -0.0, which would print as "-0.0000".
        let mean = |f: fn(&EpisodeMetrics) -> f64| (0.0 + metrics.iter().map(f).sum::<f64>()) / n;
        Summary {
            episodes: metrics.len(),
            collisions: metrics.iter().filter(|m| m.collision).count(),
            failures: metrics.iter().filter(|m| m.failure).count(),
            other_collisions: metrics.iter().filter(|m| m.other_collision).count(),
            min_distance: mean(|m| m.min_distance),
            mean_speed: mean(|m| m.mean_speed),
            mean_abs_accel: mean(|m| m.mean_abs_accel),
            mean_abs_jerk: mean(|m| m.mean_abs_jerk),
        }
    }

    /// A Markdown table, one row per metric.
    pub fn markdown(&self, title: &str) -> String {
        format!(
            "| {title} | value |\n|---|---|\n| Collision rate | {}/{} |\n| Failure rate | {}/{} |\n\
             | Average minimum inter-vehicle distance (m) | {:.4} |\n| Average ego vehicle speed (m/s) | {:.4} |\n\
             | Average acceleration magnitude (m/s^2) | {:.4} |\n| Average jerk magnitude (m/s^3) | {:.4} |\n",
            self.collisions,
            self.episodes,
            self.failures,
            self.episodes,
            self.min_distance,
            self.mean_speed,
            self.mean_abs_accel,
            self.mean_abs_jerk
        )
    }
}
