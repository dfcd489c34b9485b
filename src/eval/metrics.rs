//! The six metrics of Tables II-IV, per episode and averaged.
//!
//! - collision: a collision involving the ego;
//! - failure: no collision, and the ego has not passed the conflict point by the horizon;
//! - (ours) other collision: two other players collided; between two policy-driven players
//!   it ends the episode for everyone (an ego still on the ramp then counts as a failure);
//!   two players no policy drives drive through each other and the episode goes on
//!   ([`crate::engine::rollout`]);
//! - minimum inter-vehicle distance (ours): the smallest centre-to-centre Euclidean distance
//!   between the ego and any other player over the episode (before the merge this includes the
//!   lateral offset of the ramp, so it stays small while the ego drives beside the target lane);
//! - minimum in-lane distance (the paper's notion, as its figures of 13-41 m suggest): the
//!   smallest longitudinal centre distance `|x_j - x_ego|` between the ego and any other player
//!   in the ego's lane over the episode; undefined in an episode where no player shared the
//!   ego's lane, and averaged over the episodes where it is defined;
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
    /// A collision between two other players (not counted as the ego's; see the module docs).
    pub other_collision: bool,
    /// Minimum ego distance (m).
    pub min_distance: f64,
    /// Minimum in-lane distance (m), when a player shared the ego's lane.
    pub min_lane_distance: Option<f64>,
    /// Average ego speed (m/s).
    pub mean_speed: f64,
    /// Average ego acceleration magnitude (m/s^2).
    pub mean_abs_accel: f64,
    /// Average ego jerk magnitude (m/s^3).
    pub mean_abs_jerk: f64,
}

impl EpisodeMetrics {
    /// CSV header of the four continuous metrics, in [`Self::motion_csv`]'s order.
    pub const CSV_MOTION: &str = "min_distance,mean_speed,mean_abs_accel,mean_abs_jerk,min_lane_distance";

    /// The continuous metrics as CSV fields (see [`Self::CSV_MOTION`]; an undefined in-lane
    /// distance is an empty field).
    pub fn motion_csv(&self) -> String {
        format!(
            "{},{},{},{},{}",
            self.min_distance,
            self.mean_speed,
            self.mean_abs_accel,
            self.mean_abs_jerk,
            self.min_lane_distance.map_or(String::new(), |d| d.to_string())
        )
    }

    /// Metrics of an outcome.
    pub fn of(o: &EpisodeOutcome) -> Self {
        let collision = o.collision.is_some_and(|c| c.a == 0 || c.b == 0);
        EpisodeMetrics {
            other_collision: o.others_overlapped || (o.collision.is_some() && !collision),
            ..Self::from_stats(o.ego(), collision, o.ego_merged_at.is_some())
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
            min_lane_distance: ego.min_lane_distance.is_finite().then_some(ego.min_lane_distance),
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
    /// Episodes with a collision between other players.
    pub other_collisions: usize,
    /// Mean of the per-episode minimum distance (m).
    pub min_distance: f64,
    /// Mean of the per-episode minimum in-lane distance over the episodes where it is defined.
    pub min_lane_distance: Option<f64>,
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
            min_lane_distance: mean_defined(metrics.iter().filter_map(|m| m.min_lane_distance)),
            mean_speed: mean(|m| m.mean_speed),
            mean_abs_accel: mean(|m| m.mean_abs_accel),
            mean_abs_jerk: mean(|m| m.mean_abs_jerk),
        }
    }

    /// A Markdown table, one row per metric.
    pub fn markdown(&self, title: &str) -> String {
        format!(
            "| {title} | value |\n|---|---|\n| Collision rate | {}/{} |\n| Failure rate | {}/{} |\n\
             | Average minimum inter-vehicle distance (m) | {:.4} |\n| Average minimum in-lane distance (m) | {} |\n\
             | Average ego vehicle speed (m/s) | {:.4} |\n\
             | Average acceleration magnitude (m/s^2) | {:.4} |\n| Average jerk magnitude (m/s^3) | {:.4} |\n",
            self.collisions,
            self.episodes,
            self.failures,
            self.episodes,
            self.min_distance,
            distance_cell(self.min_lane_distance),
            self.mean_speed,
            self.mean_abs_accel,
            self.mean_abs_jerk
        )
    }
}

/// The mean of `values`, none when there are none.
pub fn mean_defined(values: impl Iterator<Item = f64>) -> Option<f64> {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    (n > 0).then(|| sum / n as f64)
}

/// A distance for a table: 4 decimals, or "n/a" when undefined.
pub fn distance_cell(d: Option<f64>) -> String {
    d.map_or("n/a".to_string(), |d| format!("{d:.4}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::state::Scene;
    use crate::world::state::cruising_car as car;

    #[test]
    fn the_in_lane_distance_counts_only_players_in_the_egos_lane() {
        let mut stats = EgoStats::default();
        // On the ramp: a ramp player 20 m behind, a target-lane player 5 m ahead and one lane over.
        let before = Scene::new(vec![car(100.0, true), car(80.0, true), car(105.0, false)]);
        stats.update(&before, 0.0, 0.1);
        // Merged: the target-lane player 8 m ahead shares its lane, the ramp player does not.
        let after = Scene::new(vec![car(110.0, false), car(109.0, true), car(118.0, false)]);
        stats.update(&after, 0.0, 0.1);
        let m = EpisodeMetrics::from_stats(&stats, false, true);
        assert_eq!(m.min_lane_distance, Some(8.0));
        // Ours: the Euclidean distance, 1 m ahead and one lane over after the merge.
        assert!((m.min_distance - 1.0f64.hypot(3.66)).abs() < 1e-12);
    }

    #[test]
    fn an_episode_without_a_lane_mate_has_no_in_lane_distance_and_is_left_out_of_the_mean() {
        let mut stats = EgoStats::default();
        let alone = Scene::new(vec![car(100.0, true), car(105.0, false)]);
        stats.update(&alone, 0.0, 0.1);
        let lonely = EpisodeMetrics::from_stats(&stats, false, false);
        assert_eq!(lonely.min_lane_distance, None);
        let close = EpisodeMetrics {
            min_lane_distance: Some(8.0),
            ..lonely
        };
        let far = EpisodeMetrics {
            min_lane_distance: Some(12.0),
            ..lonely
        };
        assert_eq!(Summary::of(&[lonely, close, far]).min_lane_distance, Some(10.0));
        assert_eq!(Summary::of(&[lonely]).min_lane_distance, None);
        assert!(
            Summary::of(&[lonely])
                .markdown("t")
                .contains("| Average minimum in-lane distance (m) | n/a |")
        );
    }
}
