//! Numerical check of Definition 3 (`mpgdrive check-mpg`).
//!
//! For `K` random joint policies `theta` and, for each player `i`, a unilateral deviation
//! `theta'_i` (only player `i`'s policy changes), it computes over the same `M` initial states
//!
//! ```text
//! Delta J_i  = J_i(theta'_i, theta_-i) - J_i(theta)
//! Delta Phi  = Phi(theta'_i, theta_-i) - Phi(theta)
//! ```
//!
//! and reports, per player, the largest `|Delta J_i - Delta Phi| / |Delta J_i|`.
//!
//! **Which random policies.** Theorems 1-3 rest on other players' trajectories being unchanged
//! when player `i` deviates. That holds when each player's transition depends only on its own
//! action *and* each player's policy reacts only to its own state. The random policies are
//! therefore own-state feedback laws with a time-varying part,
//! `u = g_p tanh(k (v* - v) + A sin(w t + psi))`, with `k, v*, A, w, psi` drawn per player
//! from the check's seed. With the feasibility projection or collision termination on, a
//! player's transition depends on its neighbours and the identity no longer holds exactly: the
//! check then reports the measured gap as a finding; the exact setting turns both off.
//!
//! **The entry rule.** Under `scenario.entry = "gap"` (and an early merge,
//! `scenario.merge_zone`) a ramp vehicle enters the target lane only at a gap, and the ramp's
//! end holds it until one comes: decisions that read the neighbours. They stay on in the exact
//! setting, which instead records every player's decisions in the base run and replays them
//! for every player but the deviating one, who decides live. The others' trajectories are then
//! the base run's, which is all Theorems 1-3 need; the deviating player's may depend on them.
//!
//! In merge traffic (`scenario.kind = "traffic"`) the check runs on traffic episodes, several
//! ramp vehicles and both streams, every vehicle a player (humans too: see [`check_mpg`]).

use crate::config::Config;
use crate::engine::rollout::{Actor, EntryDecision, Recording, RolloutOptions, rollout_with_reward};
use crate::game::reward::PairReward;
use crate::world::neighbors::Neighbors;
use crate::world::sampler::{sample_scenes, scenario_rng};
use crate::world::state::Scene;
use rand::Rng;
use serde::Serialize;
use std::sync::{Arc, Mutex};

/// Amplitude `g_p` of the random policies (m/s^2).
pub const POLICY_ACCEL: f64 = 3.0;

/// Parameters of one player's random own-state policy.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OwnStatePolicy {
    /// Feedback gain `k` on the speed error (per m/s, inside the tanh).
    pub gain: f64,
    /// Target speed `v*` (m/s).
    pub target_speed: f64,
    /// Amplitude `A` of the time-varying part.
    pub amplitude: f64,
    /// Angular frequency `w` (rad/s).
    pub omega: f64,
    /// Phase `psi` (rad).
    pub phase: f64,
}

impl OwnStatePolicy {
    /// Draws a policy.
    pub fn random(rng: &mut impl Rng) -> Self {
        OwnStatePolicy {
            gain: rng.random_range(0.1..1.0),
            target_speed: rng.random_range(5.0..25.0),
            amplitude: rng.random_range(0.0..1.0),
            omega: rng.random_range(0.1..1.0),
            phase: rng.random_range(0.0..std::f64::consts::TAU),
        }
    }

    /// Acceleration at time `t` (s) and own speed `v`.
    pub fn accel(&self, t: f64, v: f64) -> f64 {
        POLICY_ACCEL
            * (self.gain * (self.target_speed - v) + self.amplitude * (self.omega * t + self.phase).sin())
                .tanh()
    }
}

/// Every player driven by its own-state policy.
#[derive(Debug, Clone)]
pub struct JointPolicy {
    /// One policy per player.
    pub players: Vec<OwnStatePolicy>,
    /// Time step (s).
    pub dt: f64,
}

impl Actor for JointPolicy {
    fn act(&mut self, step: usize, scenes: &[Scene], _neighbors: &[Neighbors], out: &mut [f64]) {
        let t = step as f64 * self.dt;
        let n = self.players.len();
        for (b, scene) in scenes.iter().enumerate() {
            for (i, (p, v)) in self.players.iter().zip(&scene.vehicles).enumerate() {
                out[b * n + i] = p.accel(t, v.v);
            }
        }
    }
}

/// Every scene's entry decisions, `[scene][step * players + player]`.
type EntryLog = Vec<Vec<EntryDecision>>;

/// What a run of the exact setting does with the entry rule's decisions.
#[derive(Debug, Clone)]
enum Entries {
    /// Decide live (the configured setting).
    Live,
    /// Decide live and record them (the base run).
    Record(Arc<Mutex<EntryLog>>),
    /// Replay the base run's for every player but `deviator`.
    Replay { log: Arc<EntryLog>, deviator: usize },
}

/// A joint policy on a chunk of the states starting at state `offset`, with its entries.
struct CheckActor {
    policy: JointPolicy,
    entries: Entries,
    offset: usize,
}

impl Actor for CheckActor {
    fn act(&mut self, step: usize, scenes: &[Scene], neighbors: &[Neighbors], out: &mut [f64]) {
        self.policy.act(step, scenes, neighbors, out);
    }

    fn entry(&mut self, step: usize, b: usize, i: usize, live: EntryDecision) -> EntryDecision {
        let at = step * self.policy.players.len() + i;
        match &self.entries {
            Entries::Live => live,
            Entries::Record(log) => {
                let mut log = log.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
                log[self.offset + b][at] = live;
                live
            }
            Entries::Replay { log, deviator } if i != *deviator => log[self.offset + b][at],
            Entries::Replay { .. } => live,
        }
    }
}

/// Settings of a check.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CheckSettings {
    /// Random joint policies `K`.
    pub policies: usize,
    /// Initial states `M`.
    pub states: usize,
    /// Seed of the policies and initial states.
    pub seed: u64,
    /// Theorem setting: feasibility projection, collision termination and early merges off.
    pub exact: bool,
    /// A relative gap above this flags the game as not an MPG.
    pub tolerance: f64,
    /// Worker threads.
    pub threads: usize,
}

/// The gap measured for one player.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct PlayerGap {
    /// Player index (0 = ego).
    pub player: usize,
    /// Label as in the paper's figures.
    pub label: String,
    /// Largest `|Delta J_i - Delta Phi| / |Delta J_i|` over the policies.
    pub max_relative_gap: f64,
    /// Largest `|Delta J_i - Delta Phi|`.
    pub max_absolute_gap: f64,
    /// Smallest `|Delta J_i|` seen (a tiny one would make the relative gap meaningless).
    pub min_abs_delta_j: f64,
}

/// Result of a check.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct CheckReport {
    /// "exact" (Theorem setting) or "configured".
    pub setting: String,
    /// Feasibility projection used.
    pub feasibility: bool,
    /// Collision termination used.
    pub terminate_on_collision: bool,
    /// `K`.
    pub policies: usize,
    /// `M`.
    pub states: usize,
    /// Seed.
    pub seed: u64,
    /// Tolerance on the relative gap.
    pub tolerance: f64,
    /// Per player.
    pub players: Vec<PlayerGap>,
    /// Largest relative gap over players.
    pub max_relative_gap: f64,
    /// True when every player's relative gap is within the tolerance.
    pub is_potential_game: bool,
}

/// Mean returns `J_i` and mean potential return `Phi` of a joint policy over `scenes`. The
/// scenes run in `opts.threads` chunks, each knowing where it starts in the entry log.
fn evaluate(
    config: &Config,
    opts: &RolloutOptions,
    scenes: &[Scene],
    pair: &dyn PairReward,
    policy: &JointPolicy,
    entries: &Entries,
) -> (Vec<f64>, f64) {
    let chunk = scenes
        .len()
        .div_ceil(opts.threads.clamp(1, scenes.len().max(1)))
        .max(1);
    let one = RolloutOptions { threads: 1, ..*opts };
    let outcomes: Vec<_> = std::thread::scope(|s| {
        let handles: Vec<_> = scenes
            .chunks(chunk)
            .enumerate()
            .map(|(k, part)| {
                let one = &one;
                s.spawn(move || {
                    rollout_with_reward(config, one, part, pair, || CheckActor {
                        policy: policy.clone(),
                        entries: entries.clone(),
                        offset: k * chunk,
                    })
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().expect("check worker panicked"))
            .collect()
    });
    let m = outcomes.len() as f64;
    let n = policy.players.len();
    let mut j = vec![0.0; n];
    let mut phi = 0.0;
    for o in &outcomes {
        for (acc, r) in j.iter_mut().zip(&o.returns) {
            *acc += r / m;
        }
        phi += o.potential_return / m;
    }
    (j, phi)
}

/// Number of joint-policy evaluations a check runs, `K (N + 1)`.
pub fn evaluations(config: &Config, settings: &CheckSettings) -> usize {
    settings.policies * (config.n_agents() + 1)
}

/// Runs the check with pair reward `pair` (the paper's, or a test's); `progress` is called
/// after each of the [`evaluations`] joint-policy evaluations.
pub fn check_mpg(
    config: &Config,
    settings: &CheckSettings,
    pair: &dyn PairReward,
    progress: &mut dyn FnMut(),
) -> CheckReport {
    let mut opts = RolloutOptions::from_config(config);
    opts.recording = Recording::Summary;
    opts.threads = settings.threads;
    if settings.exact {
        opts.feasibility = false;
        opts.terminate_on_collision = false;
    }
    let n = config.n_agents();
    let mut scenes = sample_scenes(config, settings.seed, 0, settings.states);
    // In merge traffic every vehicle is a player here: a human's IDM reacts to its
    // neighbours, which Theorems 1-3 exclude, so the check draws own-state policies for all.
    for scene in &mut scenes {
        scene.humans.clear();
    }
    // Policies come from a stream of their own, after the scenario streams.
    let mut rng = scenario_rng(settings.seed, u64::MAX);
    let mut players: Vec<PlayerGap> = (0..n)
        .map(|i| PlayerGap {
            player: i,
            label: crate::world::state::player_label(i),
            max_relative_gap: 0.0,
            max_absolute_gap: 0.0,
            min_abs_delta_j: f64::INFINITY,
        })
        .collect();
    for _ in 0..settings.policies {
        let base = JointPolicy {
            players: (0..n).map(|_| OwnStatePolicy::random(&mut rng)).collect(),
            dt: config.sim.dt,
        };
        let log = settings.exact.then(|| {
            let steps = vec![EntryDecision::default(); opts.steps * n];
            Arc::new(Mutex::new(vec![steps; scenes.len()]))
        });
        let record = log
            .as_ref()
            .map_or(Entries::Live, |l| Entries::Record(Arc::clone(l)));
        let (j0, phi0) = evaluate(config, &opts, &scenes, pair, &base, &record);
        drop(record);
        let log = log.map(|l| {
            Arc::new(
                Arc::into_inner(l)
                    .expect("the base run is over")
                    .into_inner()
                    .unwrap_or_else(std::sync::PoisonError::into_inner),
            )
        });
        progress();
        for (i, gap) in players.iter_mut().enumerate() {
            let mut deviated = base.clone();
            deviated.players[i] = OwnStatePolicy::random(&mut rng);
            let entries = log.as_ref().map_or(Entries::Live, |l| Entries::Replay {
                log: Arc::clone(l),
                deviator: i,
            });
            let (j1, phi1) = evaluate(config, &opts, &scenes, pair, &deviated, &entries);
            progress();
            let delta_j = j1[i] - j0[i];
            let delta_phi = phi1 - phi0;
            let abs_gap = (delta_j - delta_phi).abs();
            gap.max_absolute_gap = gap.max_absolute_gap.max(abs_gap);
            gap.max_relative_gap = gap
                .max_relative_gap
                .max(abs_gap / delta_j.abs().max(f64::MIN_POSITIVE));
            gap.min_abs_delta_j = gap.min_abs_delta_j.min(delta_j.abs());
        }
    }
    let max_relative_gap = players.iter().map(|p| p.max_relative_gap).fold(0.0, f64::max);
    CheckReport {
        setting: if settings.exact { "exact" } else { "configured" }.to_string(),
        feasibility: opts.feasibility,
        terminate_on_collision: opts.terminate_on_collision,
        policies: settings.policies,
        states: settings.states,
        seed: settings.seed,
        tolerance: settings.tolerance,
        players,
        max_relative_gap,
        is_potential_game: max_relative_gap <= settings.tolerance,
    }
}
