//! Per-agent rewards and the potential (Theorem 3).
//!
//! ```text
//! r_i = w_speed_i s1_i + w_comfort s2_i + sum_{j != i} r_ij
//! r_ij = w_ttc [same lane] ttc_ij + w_conflict [different lanes] gap_ij
//! phi  = sum_i (w_speed_i s1_i + w_comfort s2_i) + sum_i sum_{j < i} r_ij
//! ```
//!
//! `w_speed_i` is `w_speed_ramp` while vehicle `i` is on the ramp and `w_speed` in the target
//! lane (the paper's `omega_{i,11}`, per vehicle): a function of the vehicle's own state, so its
//! speed term stays a self term of Theorem 1.
//!
//! Each term is also logged unweighted per agent ([`TermValues`]); pair terms are logged as the
//! sum over the agent's partners.

use crate::config::{Config, ConflictForm};
use crate::game::terms;
use crate::world::state::{Scene, Vehicle};

/// Unweighted reward terms of one agent at one step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TermValues {
    /// `-(v - v_d)^2`.
    pub speed: f64,
    /// `-u^2`.
    pub comfort: f64,
    /// Sum over same-lane partners of the TTC term.
    pub ttc: f64,
    /// Sum over different-lane partners of the conflict time-gap term.
    pub conflict: f64,
}

impl TermValues {
    /// Names of the terms, in the order of [`TermValues::as_array`].
    pub const NAMES: [&'static str; 4] = ["speed", "comfort", "ttc", "conflict"];

    /// The terms as an array, in the order of [`TermValues::NAMES`].
    pub fn as_array(&self) -> [f64; 4] {
        [self.speed, self.comfort, self.ttc, self.conflict]
    }
}

/// What a pair reward gives player `i` from its interaction with `j`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairTerms {
    /// The weighted pair reward `r_ij`.
    pub reward: f64,
    /// The unweighted same-lane TTC term (0 for players in different lanes).
    pub ttc: f64,
    /// The unweighted conflict time-gap term (0 for players in the same lane).
    pub conflict: f64,
}

/// A pairwise reward `r_ij(s_i, s_j)`, weighted. `i` and `j` are player indices, so a test can
/// build a deliberately asymmetric one.
pub trait PairReward: Sync {
    /// The weighted pair reward of `i` from its interaction with `j`, and its unweighted parts
    /// for logging.
    fn pair(&self, i: usize, j: usize, a: &Vehicle, b: &Vehicle) -> PairTerms;

    /// True when `r_ij = r_ji` for every pair, so each pair needs computing once.
    fn is_symmetric(&self) -> bool;
}

/// The paper's reward (Section V-iii) with the configured weights.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PaperReward {
    /// Desired speed (m/s).
    pub v_desired: f64,
    /// `v_c` (m/s).
    pub v_c: f64,
    /// `epsilon`.
    pub epsilon: f64,
    /// Conflict point (m).
    pub conflict_point: f64,
    /// Weights `(w_speed, w_comfort, w_ttc, w_conflict)`.
    pub weights: [f64; 4],
    /// Speed-tracking weight of a vehicle on the ramp.
    pub w_speed_ramp: f64,
    /// The conflict term's form ([`crate::config::RewardConfig::conflict_form`]).
    pub conflict_form: ConflictForm,
}

impl PaperReward {
    /// The reward of a configuration.
    pub fn new(config: &Config) -> Self {
        let r = &config.reward;
        PaperReward {
            v_desired: r.v_desired,
            v_c: r.v_c,
            epsilon: r.epsilon,
            conflict_point: config.scenario.conflict_point,
            weights: [r.w_speed, r.w_comfort, r.w_ttc, r.w_conflict],
            w_speed_ramp: r.speed_weight_on_ramp(),
            conflict_form: r.conflict_form(),
        }
    }

    /// The reward in `scene`: with its own desired speed `v_d`, when it has one, the speed
    /// term tracks `v_d` with its weight scaled by [`speed_weight`].
    pub fn in_scene(&self, scene: &Scene) -> Self {
        let Some(v_d) = scene.v_desired else {
            return *self;
        };
        let mut weights = self.weights;
        let factor = speed_weight(self.v_desired, v_d);
        weights[0] *= factor;
        PaperReward {
            v_desired: v_d,
            weights,
            w_speed_ramp: self.w_speed_ramp * factor,
            ..*self
        }
    }

    /// The speed-tracking weight of vehicle `v`: by the lane it is in.
    pub fn speed_weight_of(&self, v: &Vehicle) -> f64 {
        if v.on_ramp {
            self.w_speed_ramp
        } else {
            self.weights[0]
        }
    }

    /// Unweighted self terms `(speed, comfort)` of a vehicle applying `u`.
    pub fn self_terms(&self, v: &Vehicle, u: f64) -> (f64, f64) {
        (terms::speed_tracking(&v.v, self.v_desired), terms::comfort(&u))
    }
}

impl PairReward for PaperReward {
    fn pair(&self, _i: usize, _j: usize, a: &Vehicle, b: &Vehicle) -> PairTerms {
        let [_, _, w_ttc, w_conflict] = self.weights;
        if a.on_ramp == b.on_ramp {
            let ttc = terms::same_lane_ttc(&a.x, &a.v, &b.x, &b.v, self.v_c, self.epsilon);
            PairTerms {
                reward: w_ttc * ttc,
                ttc,
                conflict: 0.0,
            }
        } else {
            let conflict = terms::conflict_term(
                self.conflict_form,
                &a.x,
                &a.v,
                &b.x,
                &b.v,
                self.conflict_point,
                self.epsilon,
            );
            PairTerms {
                reward: w_conflict * conflict,
                ttc: 0.0,
                conflict,
            }
        }
    }

    fn is_symmetric(&self) -> bool {
        true
    }
}

/// The speed term's weight factor in a scene of desired speed `v_d`, for a configuration of
/// desired speed `v_ref` (`reward.v_desired`): `(v_ref / v_d)^2`, so that the term measures the
/// speed error relative to the road's speed. Without it the squared errors of fast roads
/// (up to 4 times as large at 30 m/s as at 15) outweighed the slow roads' in the objective.
pub fn speed_weight(v_ref: f64, v_d: f64) -> f64 {
    (v_ref / v_d).powi(2)
}

/// Rewards of every agent at one step, and the potential.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StepRewards {
    /// `r_i` per agent.
    pub reward: Vec<f64>,
    /// Unweighted terms per agent.
    pub terms: Vec<TermValues>,
    /// `phi(s, a)`.
    pub potential: f64,
}

impl StepRewards {
    /// Computes `r_i`, the terms and `phi` for vehicles applying `actions`, writing into `self`.
    /// Vehicles flagged in `humans` (empty: none) are no players: `phi` leaves out their own
    /// terms and the pairs of two humans.
    pub fn compute(
        &mut self,
        base: &PaperReward,
        pair: &dyn PairReward,
        vehicles: &[Vehicle],
        actions: &[f64],
        humans: &[bool],
    ) {
        let human = |i: usize| humans.get(i).copied().unwrap_or(false);
        let n = vehicles.len();
        let w_comfort = base.weights[1];
        self.reward.clear();
        self.terms.clear();
        self.potential = 0.0;
        for (i, (veh, &u)) in vehicles.iter().zip(actions).enumerate() {
            let (speed, comfort) = base.self_terms(veh, u);
            let r = base.speed_weight_of(veh) * speed + w_comfort * comfort;
            self.reward.push(r);
            self.terms.push(TermValues {
                speed,
                comfort,
                ttc: 0.0,
                conflict: 0.0,
            });
            if !human(i) {
                self.potential += r;
            }
        }
        let symmetric = pair.is_symmetric();
        for i in 0..n {
            for j in 0..i {
                let ij = pair.pair(i, j, &vehicles[i], &vehicles[j]);
                let ji = if symmetric {
                    ij
                } else {
                    pair.pair(j, i, &vehicles[j], &vehicles[i])
                };
                self.reward[i] += ij.reward;
                self.reward[j] += ji.reward;
                self.terms[i].ttc += ij.ttc;
                self.terms[i].conflict += ij.conflict;
                self.terms[j].ttc += ji.ttc;
                self.terms[j].conflict += ji.conflict;
                if !(human(i) && human(j)) {
                    self.potential += ij.reward; // Theorem 3: pairs j < i, r_ij
                }
            }
        }
    }

    /// The ego's (player 0's) `r_0` and terms alone, bit for bit as [`StepRewards::compute`]
    /// gives them (the same pairs added in the same order); `phi` is NaN, as it needs every
    /// pair.
    pub fn compute_ego(
        &mut self,
        base: &PaperReward,
        pair: &dyn PairReward,
        vehicles: &[Vehicle],
        actions: &[f64],
    ) {
        let ego = &vehicles[0];
        let (speed, comfort) = base.self_terms(ego, actions[0]);
        let mut reward = base.speed_weight_of(ego) * speed + base.weights[1] * comfort;
        let mut terms = TermValues {
            speed,
            comfort,
            ttc: 0.0,
            conflict: 0.0,
        };
        let symmetric = pair.is_symmetric();
        for (i, other) in vehicles.iter().enumerate().skip(1) {
            // `compute` adds `r_0i` as the `ji` of its pair (i, 0).
            let terms_0i = if symmetric {
                pair.pair(i, 0, other, ego)
            } else {
                pair.pair(0, i, ego, other)
            };
            reward += terms_0i.reward;
            terms.ttc += terms_0i.ttc;
            terms.conflict += terms_0i.conflict;
        }
        self.reward.clear();
        self.reward.push(reward);
        self.terms.clear();
        self.terms.push(terms);
        self.potential = f64::NAN;
    }
}

/// Weight of a reward held from step `step + 1` to the last step `steps - 1`:
/// `sum_{k = step + 1}^{steps - 1} gamma^k`. With `sim.absorbing_collision`, a collision at
/// `step` charges every player its reward of that step this many more times (an absorbing
/// crash state), so that ending an episode early never raises a return of negative rewards.
pub fn tail_weight(gamma: f64, step: usize, steps: usize) -> f64 {
    (step + 1..steps).map(|k| gamma.powi(k as i32)).sum()
}
