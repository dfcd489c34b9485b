//! The batched rollout loop (scalar `f64` engine).
//!
//! Each step, for every live scenario:
//! 1. neighbours of every player ([`find_neighbors`]);
//! 2. raw actions from the [`Actor`] (policy, IDM, constant speed, ...);
//! 3. target-lane vehicles' actions projected onto the TTC-feasible interval (when enabled),
//!    then every action clipped to `[-g, g]` and to the speed bounds;
//! 4. per-agent rewards, per-term values and the potential at `(s_t, a_t)`;
//! 5. eq. (1) with zero steering; a ramp vehicle whose `x` reaches `x_c` joins the target lane
//!    (its lateral position follows the lane geometry);
//! 6. collisions between bounding boxes at `s_{t+1}`: the first one ends the episode for
//!    everyone (when enabled), after the rewards of step `t` are counted; with
//!    `sim.absorbing_collision` the step-`t` rewards are also charged for every remaining step
//!    ([`tail_weight`]). Two players that no policy drives and that are not the ego (the
//!    study's IDM or constant-speed surrounding players, [`Actor::learning`]) do not react to
//!    each other: their overlap is recorded ([`EpisodeOutcome::others_overlapped`]) and they
//!    drive on, so a study measures the ego against them (Table II's constant-speed column).
//!
//! Scenarios are split into contiguous chunks, one worker thread per chunk, each with its own
//! actor; the results do not depend on the number of threads.

use crate::config::Config;
use crate::engine::outcome::{Collision, EgoStats, EpisodeOutcome, Trajectory};
use crate::game::reward::{PairReward, PaperReward, StepRewards, tail_weight};
use crate::world::drivers::{Driver, driver_accel};
use crate::world::merge_gate::lane_end_holds;
use crate::world::neighbors::{Neighbors, find_neighbors, front_to_back};
use crate::world::rules::WorldRules;
use crate::world::state::Scene;
use crate::world::step::{Projected, Settled, advance, applied_action_with, first_collision_among};

/// What a rollout keeps besides the per-episode outcome.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Recording {
    /// The ego's return and statistics and the events only, what the paper's study reports:
    /// [`EpisodeOutcome::returns`] and [`EpisodeOutcome::vehicles`] hold the ego's alone and
    /// [`EpisodeOutcome::potential_return`] is NaN, so no other player's reward is computed.
    Ego,
    /// Every player's return and statistics, the potential's return and the events.
    Summary,
    /// Also every step's states, actions, terms, rewards and potential.
    Full,
}

/// Rules of a rollout (defaults from the configuration).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RolloutOptions {
    /// What to keep.
    pub recording: Recording,
    /// Worker threads (at least 1).
    pub threads: usize,
    /// Apply the feasibility projection to target-lane vehicles.
    pub feasibility: bool,
    /// End an episode at its first collision.
    pub terminate_on_collision: bool,
    /// Number of steps.
    pub steps: usize,
}

impl RolloutOptions {
    /// The configuration's rules, summary recording, one thread per available core.
    pub fn from_config(config: &Config) -> Self {
        RolloutOptions {
            recording: Recording::Summary,
            threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
            feasibility: config.sim.feasibility,
            terminate_on_collision: config.sim.terminate_on_collision,
            steps: config.n_steps(),
        }
    }
}

/// Supplies raw accelerations for every player of every scenario of a chunk.
pub trait Actor {
    /// Writes the raw acceleration of player `i` of scene `b` into `out[b * n + i]` (`n`
    /// players per scene). `neighbors` is laid out the same way.
    fn act(&mut self, step: usize, scenes: &[Scene], neighbors: &[Neighbors], out: &mut [f64]);

    /// Whether a policy drives player `i` (a learning player). With
    /// `sim.project_non_learning` off, only these follow the feasibility rules.
    fn learning(&self, i: usize) -> bool {
        let _ = i;
        true
    }

    /// The entry rule's decisions for player `i` of scene `b` at `step`, given the world's
    /// (`live`). Every actor keeps the world's; the MPG check replays another run's.
    fn entry(&mut self, step: usize, b: usize, i: usize, live: EntryDecision) -> EntryDecision {
        let _ = (step, b, i);
        live
    }
}

/// The two decisions of the entry rule for a ramp vehicle and a step, both read from the
/// scene at the step's start.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EntryDecision {
    /// It joins the target lane this step before the ramp's end
    /// ([`WorldRules::merges_early`]).
    pub merges: bool,
    /// The ramp's end holds it ([`lane_end_holds`]).
    pub held: bool,
}

/// Fixed drivers: one for the ego, one for every other player.
#[derive(Debug, Clone)]
pub struct DriverActor {
    /// The ego's driver.
    pub ego: Driver,
    /// The other players' driver.
    pub others: Driver,
    config: Config,
}

impl DriverActor {
    /// Drivers for a configuration.
    pub fn new(config: &Config, ego: Driver, others: Driver) -> Self {
        DriverActor {
            ego,
            others,
            config: config.clone(),
        }
    }
}

impl Actor for DriverActor {
    fn learning(&self, _i: usize) -> bool {
        false
    }

    fn act(&mut self, _step: usize, scenes: &[Scene], neighbors: &[Neighbors], out: &mut [f64]) {
        for (b, scene) in scenes.iter().enumerate() {
            let n = scene.len();
            for i in 0..n {
                let driver = if i == 0 { self.ego } else { self.others };
                out[b * n + i] = driver_accel(&self.config, driver, scene, i, &neighbors[b * n + i]);
            }
        }
    }
}

/// Runs every scene for `opts.steps` steps with the paper's reward.
pub fn rollout<A, F>(
    config: &Config,
    opts: &RolloutOptions,
    scenes: &[Scene],
    make_actor: F,
) -> Vec<EpisodeOutcome>
where
    A: Actor,
    F: Fn() -> A + Sync,
{
    let reward = PaperReward::new(config);
    rollout_with_reward(config, opts, scenes, &reward, make_actor)
}

/// Runs every scene for `opts.steps` steps with a given pair reward (self terms as configured).
pub fn rollout_with_reward<A, F>(
    config: &Config,
    opts: &RolloutOptions,
    scenes: &[Scene],
    pair: &dyn PairReward,
    make_actor: F,
) -> Vec<EpisodeOutcome>
where
    A: Actor,
    F: Fn() -> A + Sync,
{
    if scenes.is_empty() {
        return Vec::new();
    }
    let threads = opts.threads.clamp(1, scenes.len());
    let chunk = scenes.len().div_ceil(threads);
    std::thread::scope(|s| {
        let handles: Vec<_> = scenes
            .chunks(chunk)
            .map(|part| {
                let make_actor = &make_actor;
                s.spawn(move || run_chunk(config, opts, part, pair, &mut make_actor()))
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().expect("rollout worker panicked"))
            .collect()
    })
}

fn run_chunk(
    config: &Config,
    opts: &RolloutOptions,
    initial: &[Scene],
    pair: &dyn PairReward,
    actor: &mut impl Actor,
) -> Vec<EpisodeOutcome> {
    let base = PaperReward::new(config);
    let rules = WorldRules::new(config);
    let dt = rules.dt;
    let n = initial[0].len();
    let full = opts.recording == Recording::Full;
    let ego_only = opts.recording == Recording::Ego;
    let kept = if ego_only { 1 } else { n };

    let mut scenes = initial.to_vec();
    let mut outcomes: Vec<EpisodeOutcome> = initial
        .iter()
        .map(|s| EpisodeOutcome {
            steps: 0,
            collision: None,
            others_overlapped: false,
            ego_merged_at: None,
            returns: vec![0.0; kept],
            potential_return: if ego_only { f64::NAN } else { 0.0 },
            vehicles: vec![EgoStats::default(); kept],
            final_scene: s.clone(),
            trajectory: full.then(|| Trajectory {
                states: s.vehicles.clone(),
                ..Default::default()
            }),
        })
        .collect();
    let mut alive = vec![true; scenes.len()];
    let mut neighbors = vec![Neighbors::default(); scenes.len() * n];
    let mut raw = vec![0.0; scenes.len() * n];
    let mut applied = vec![0.0; n];
    let mut merging: Vec<bool> = Vec::with_capacity(n);
    let mut settle_order: Vec<usize> = Vec::with_capacity(n);
    let (mut order, mut scratch) = (Vec::new(), Vec::new());
    let mut rewards = StepRewards::default();
    let mut discount = 1.0;

    for step in 0..opts.steps {
        for (b, scene) in scenes.iter().enumerate() {
            if alive[b] {
                find_neighbors(scene, &mut order, &mut scratch);
                neighbors[b * n..(b + 1) * n].copy_from_slice(&scratch);
            }
        }
        actor.act(step, &scenes, &neighbors, &mut raw);
        for (b, scene) in scenes.iter_mut().enumerate() {
            if !alive[b] {
                continue;
            }
            let out = &mut outcomes[b];
            merging.clear();
            merging.resize(n, false);
            let nb = &neighbors[b * n..(b + 1) * n];
            if rules.sequential() {
                front_to_back(nb, &mut settle_order);
            } else {
                settle_order.clear();
                settle_order.extend(0..n);
            }
            for &i in &settle_order {
                let human = scene.is_human(i);
                if human {
                    raw[b * n + i] = driver_accel(config, Driver::Idm, scene, i, &nb[i]);
                }
                let live = EntryDecision {
                    merges: rules.merges_early(scene, i),
                    held: lane_end_holds(scene, i, &rules.gate),
                };
                let entry = actor.entry(step, b, i, live);
                let projected = |j: usize| {
                    opts.feasibility
                        && (config.sim.project_non_learning || (actor.learning(j) && !scene.is_human(j)))
                };
                merging[i] = entry.merges;
                let settled = Settled {
                    held: Some(entry.held),
                    // The leader was settled before (front to back): its speed after the step.
                    leader_next_v: nb[i]
                        .lane_leader
                        .filter(|_| rules.sequential())
                        .map(|j| scene.vehicles[j].v + applied[j] * dt),
                    projected: Projected {
                        leader: nb[i].lane_leader.is_some_and(projected),
                        follower: nb[i].lane_follower.is_some_and(projected),
                    },
                };
                applied[i] =
                    applied_action_with(&rules, projected(i), scene, i, &nb[i], raw[b * n + i], settled);
            }
            let base = base.in_scene(scene);
            if ego_only {
                rewards.compute_ego(&base, pair, &scene.vehicles, &applied);
            } else {
                rewards.compute(&base, pair, &scene.vehicles, &applied, &scene.humans);
            }
            for (ret, r) in out.returns.iter_mut().zip(&rewards.reward) {
                *ret += discount * r;
            }
            out.potential_return += discount * rewards.potential;
            for (i, stats) in out.vehicles.iter_mut().enumerate() {
                stats.update_vehicle(scene, i, applied[i], dt);
            }
            for ((v, &u), &merges) in scene.vehicles.iter_mut().zip(&applied).zip(&merging) {
                *v = advance(v, u, merges, &rules);
            }
            out.steps = step + 1;
            if out.ego_merged_at.is_none() && !scene.ego().on_ramp {
                out.ego_merged_at = Some(step);
            }
            let counts = |a: usize, b: usize| a == 0 || actor.learning(a) || actor.learning(b);
            if !out.others_overlapped {
                out.others_overlapped =
                    first_collision_among(scene, rules.length, rules.width, |a, b| !counts(a, b)).is_some();
            }
            if out.collision.is_none() {
                out.collision = first_collision_among(scene, rules.length, rules.width, counts)
                    .map(|(a, b)| Collision { step, a, b });
                if out.collision.is_some() && opts.terminate_on_collision {
                    alive[b] = false;
                    if config.sim.absorbing_collision {
                        let tail = tail_weight(config.sim.gamma, step, opts.steps);
                        for (ret, r) in out.returns.iter_mut().zip(&rewards.reward) {
                            *ret += tail * r;
                        }
                        out.potential_return += tail * rewards.potential;
                    }
                }
            }
            if let Some(t) = out.trajectory.as_mut() {
                t.states.extend_from_slice(&scene.vehicles);
                t.raw_actions.extend_from_slice(&raw[b * n..(b + 1) * n]);
                t.actions.extend_from_slice(&applied);
                t.terms.extend_from_slice(&rewards.terms);
                t.rewards.extend_from_slice(&rewards.reward);
                t.potential.push(rewards.potential);
            }
        }
        discount *= config.sim.gamma;
    }
    for (out, scene) in outcomes.iter_mut().zip(scenes) {
        out.final_scene = scene;
    }
    outcomes
}
