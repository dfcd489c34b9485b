//! What a rollout returns: per-episode outcome, ego statistics, collisions and the optional
//! step-by-step trajectory.

use crate::game::reward::TermValues;
use crate::world::scenarios::merged_between;
use crate::world::state::{Scene, Vehicle};

/// A collision: the step after which the boxes overlap, and the two players.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Collision {
    /// Step `t` whose action led to the overlap at `t + 1`.
    pub step: usize,
    /// First player (lower index).
    pub a: usize,
    /// Second player.
    pub b: usize,
}

/// Running statistics of the ego over an episode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EgoStats {
    /// Smallest centre-to-centre (Euclidean) distance between the ego and any other player.
    pub min_distance: f64,
    /// Smallest longitudinal distance `|x_j - x_ego|` between the ego and any other player in
    /// its lane (infinite while none has shared it): the paper's notion of the metric.
    pub min_lane_distance: f64,
    /// Sum of the ego's speed over the steps.
    pub sum_speed: f64,
    /// Sum of `|u|` of the ego's applied acceleration.
    pub sum_abs_accel: f64,
    /// Sum of `|u_t - u_{t-1}| / dt` over steps after the first.
    pub sum_abs_jerk: f64,
    /// Steps counted in the sums.
    pub steps: usize,
    last_accel: f64,
    /// `min_distance` squared, compared first: the square root is only taken for a new minimum.
    min_distance_sq: f64,
}

impl Default for EgoStats {
    fn default() -> Self {
        EgoStats {
            min_distance: f64::INFINITY,
            min_lane_distance: f64::INFINITY,
            sum_speed: 0.0,
            sum_abs_accel: 0.0,
            sum_abs_jerk: 0.0,
            steps: 0,
            last_accel: 0.0,
            min_distance_sq: f64::INFINITY,
        }
    }
}

impl EgoStats {
    /// Adds one step: the ego is `scene.vehicles[0]`, the distance runs over the others.
    pub fn update(&mut self, scene: &Scene, ego_accel: f64, dt: f64) {
        self.update_vehicle(scene, 0, ego_accel, dt);
    }

    /// Adds one step of vehicle `i` applying `accel`; the distance runs over the others.
    pub fn update_vehicle(&mut self, scene: &Scene, i: usize, accel: f64, dt: f64) {
        let ego = &scene.vehicles[i];
        let others = scene.vehicles.iter().enumerate().filter(|&(j, _)| j != i);
        for (_, other) in others {
            let (dx, dy) = (other.x - ego.x, other.y - ego.y);
            let d_sq = dx * dx + dy * dy;
            if d_sq < self.min_distance_sq {
                self.min_distance_sq = d_sq;
                self.min_distance = self.min_distance.min(dx.hypot(dy));
            }
            if other.on_ramp == ego.on_ramp {
                self.min_lane_distance = self.min_lane_distance.min((other.x - ego.x).abs());
            }
        }
        self.sum_speed += ego.v;
        self.sum_abs_accel += accel.abs();
        if self.steps > 0 {
            self.sum_abs_jerk += (accel - self.last_accel).abs() / dt;
        }
        self.last_accel = accel;
        self.steps += 1;
    }
}

/// Everything recorded step by step (with [`crate::engine::rollout::Recording::Full`]); `n` players per row.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trajectory {
    /// States `s_0 .. s_steps`: `(steps + 1) * n` vehicles.
    pub states: Vec<Vehicle>,
    /// Actions before projection, `steps * n`.
    pub raw_actions: Vec<f64>,
    /// Applied actions, `steps * n`.
    pub actions: Vec<f64>,
    /// Unweighted reward terms, `steps * n`.
    pub terms: Vec<TermValues>,
    /// Rewards `r_i`, `steps * n`.
    pub rewards: Vec<f64>,
    /// Potential `phi` per step.
    pub potential: Vec<f64>,
}

/// The result of one episode.
#[derive(Debug, Clone, PartialEq)]
pub struct EpisodeOutcome {
    /// Steps simulated (fewer than requested after a terminating collision).
    pub steps: usize,
    /// First collision, if any (see [`crate::engine::rollout`] for which pairs count).
    pub collision: Option<Collision>,
    /// Two players that no policy drives (non-learning surrounding players, neither the ego)
    /// overlapped: they do not react to each other, so they drive through and the episode goes on.
    pub others_overlapped: bool,
    /// First step at whose end the ego had passed the conflict point.
    pub ego_merged_at: Option<usize>,
    /// Discounted return `J_i = sum_t gamma^t r_i` per player.
    pub returns: Vec<f64>,
    /// Discounted potential `sum_t gamma^t phi`.
    pub potential_return: f64,
    /// Statistics of every vehicle over the episode (the ego first): the same measures as the
    /// ego's, for studies of every controlled vehicle in merge traffic.
    pub vehicles: Vec<EgoStats>,
    /// Final state.
    pub final_scene: Scene,
    /// Step-by-step record ([`crate::engine::rollout::Recording::Full`] only).
    pub trajectory: Option<Trajectory>,
}

impl EpisodeOutcome {
    /// The ego's statistics.
    pub fn ego(&self) -> &EgoStats {
        &self.vehicles[0]
    }

    /// The players the ego merged between ([`merged_between`] of the first state after it
    /// passed the conflict point); `None` if it never merged or the episode was not recorded
    /// in full.
    pub fn merged_between(&self) -> Option<[usize; 2]> {
        let m = self.ego_merged_at?;
        let n = self.final_scene.len();
        // Step m's action led to state m + 1.
        let states = self.trajectory.as_ref()?.states.get((m + 1) * n..(m + 2) * n)?;
        Some(merged_between(&Scene::new(states.to_vec())))
    }
}
