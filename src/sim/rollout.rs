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
//!    ([`tail_weight`]).
//!
//! Scenarios are split into contiguous chunks, one worker thread per chunk, each with its own
//! actor; the results do not depend on the number of threads.

use crate::config::Config;
use crate::game::reward::{PairReward, PaperReward, StepRewards, TermValues};
use crate::sim::dynamics::{Axles, Kinematics, bicycle_step};
use crate::sim::geometry::{Footprint, Road, boxes_overlap};
use crate::sim::idm::idm_accel;
use crate::sim::merge_gate::{GateRules, gate_holds, stop_bound};
use crate::sim::neighbors::{Neighbors, find_neighbors};
use crate::sim::safety::{Neighbor, clip_action, feasible_interval, project_feasible};
use crate::sim::state::{Scene, Vehicle};

/// What a rollout keeps besides the per-episode outcome.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Recording {
    /// Returns, events and ego statistics only.
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

/// A non-learning driver.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Driver {
    /// Intelligent Driver Model: behind the same-lane leader, or on the ramp behind the nearest
    /// leader by distance to the conflict point.
    Idm,
    /// Zero acceleration.
    ConstSpeed,
}

/// Supplies raw accelerations for every player of every scenario of a chunk.
pub trait Actor {
    /// Writes the raw acceleration of player `i` of scene `b` into `out[b * n + i]` (`n`
    /// players per scene). `neighbors` is laid out the same way.
    fn act(&mut self, step: usize, scenes: &[Scene], neighbors: &[Neighbors], out: &mut [f64]);
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

/// The leader a driver follows: same lane, or on the ramp the nearest by distance to `x_c`.
pub fn driving_leader(vehicle: &Vehicle, n: &Neighbors) -> Option<usize> {
    if vehicle.on_ramp { n.leader } else { n.lane_leader }
}

/// A neighbour of `scene` as the generic equations take it (absent: far ahead, same speed).
pub fn neighbor_of(scene: &Scene, who: Option<usize>, me: &Vehicle) -> Neighbor<f64> {
    match who {
        Some(j) => Neighbor {
            x: scene.vehicles[j].x,
            v: scene.vehicles[j].v,
            present: 1.0,
        },
        None => Neighbor {
            x: me.x,
            v: me.v,
            present: 0.0,
        },
    }
}

/// Acceleration of a non-learning driver.
pub fn driver_accel(config: &Config, driver: Driver, scene: &Scene, i: usize, n: &Neighbors) -> f64 {
    match driver {
        Driver::ConstSpeed => 0.0,
        Driver::Idm => {
            let me = &scene.vehicles[i];
            let leader = neighbor_of(scene, driving_leader(me, n), me);
            idm_accel(&me.x, &me.v, &leader, config.vehicle.length, &config.idm)
        }
    }
}

impl Actor for DriverActor {
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
    /// Sum of the ego's speed over the steps.
    pub sum_speed: f64,
    /// Sum of `|u|` of the ego's applied acceleration.
    pub sum_abs_accel: f64,
    /// Sum of `|u_t - u_{t-1}| / dt` over steps after the first.
    pub sum_abs_jerk: f64,
    /// Steps counted in the sums.
    pub steps: usize,
    last_accel: f64,
}

impl Default for EgoStats {
    fn default() -> Self {
        EgoStats {
            min_distance: f64::INFINITY,
            sum_speed: 0.0,
            sum_abs_accel: 0.0,
            sum_abs_jerk: 0.0,
            steps: 0,
            last_accel: 0.0,
        }
    }
}

impl EgoStats {
    /// Adds one step: the ego is `scene.vehicles[0]`, the distance runs over the others.
    pub fn update(&mut self, scene: &Scene, ego_accel: f64, dt: f64) {
        let ego = scene.ego();
        for other in &scene.vehicles[1..] {
            let d = (other.x - ego.x).hypot(other.y - ego.y);
            self.min_distance = self.min_distance.min(d);
        }
        self.sum_speed += ego.v;
        self.sum_abs_accel += ego_accel.abs();
        if self.steps > 0 {
            self.sum_abs_jerk += (ego_accel - self.last_accel).abs() / dt;
        }
        self.last_accel = ego_accel;
        self.steps += 1;
    }
}

/// Everything recorded step by step (with [`Recording::Full`]); `n` players per row.
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
    /// First collision, if any.
    pub collision: Option<Collision>,
    /// First step at whose end the ego had passed the conflict point.
    pub ego_merged_at: Option<usize>,
    /// Discounted return `J_i = sum_t gamma^t r_i` per player.
    pub returns: Vec<f64>,
    /// Discounted potential `sum_t gamma^t phi`.
    pub potential_return: f64,
    /// Ego statistics.
    pub ego: EgoStats,
    /// Final state.
    pub final_scene: Scene,
    /// Step-by-step record ([`Recording::Full`] only).
    pub trajectory: Option<Trajectory>,
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
    let road = Road::new(config);
    let veh = &config.vehicle;
    let axles = Axles {
        l_f: veh.l_f,
        l_r: veh.l_r,
    };
    let dt = config.sim.dt;
    let n = initial[0].len();
    let full = opts.recording == Recording::Full;

    let mut scenes = initial.to_vec();
    let mut outcomes: Vec<EpisodeOutcome> = initial
        .iter()
        .map(|s| EpisodeOutcome {
            steps: 0,
            collision: None,
            ego_merged_at: None,
            returns: vec![0.0; n],
            potential_return: 0.0,
            ego: EgoStats::default(),
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
            for i in 0..n {
                applied[i] = applied_action(
                    config,
                    opts.feasibility,
                    scene,
                    i,
                    &neighbors[b * n + i],
                    raw[b * n + i],
                );
            }
            rewards.compute(&base, pair, &scene.vehicles, &applied);
            for (ret, r) in out.returns.iter_mut().zip(&rewards.reward) {
                *ret += discount * r;
            }
            out.potential_return += discount * rewards.potential;
            out.ego.update(scene, applied[0], dt);
            for (v, &u) in scene.vehicles.iter_mut().zip(&applied) {
                *v = advance(v, u, &road, axles, dt);
            }
            out.steps = step + 1;
            if out.ego_merged_at.is_none() && !scene.ego().on_ramp {
                out.ego_merged_at = Some(step);
            }
            if out.collision.is_none() {
                out.collision =
                    first_collision(scene, veh.length, veh.width).map(|(a, b)| Collision { step, a, b });
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

/// A vehicle after one step of eq. (1) with acceleration `u` and zero steering; a ramp
/// vehicle whose `x` reaches `x_c` joins the target lane (its lateral position follows the
/// lane geometry). One step for the rollout and the NGSIM replay.
pub fn advance(v: &Vehicle, u: f64, road: &Road, axles: Axles, dt: f64) -> Vehicle {
    let k = bicycle_step(
        &Kinematics {
            x: v.x,
            y: v.y,
            v: v.v,
            phi: v.phi,
        },
        &u,
        &0.0,
        axles,
        dt,
    );
    let on_ramp = road.still_on_ramp(v.on_ramp, k.x);
    Vehicle {
        x: k.x,
        y: road.lane_y(on_ramp),
        v: k.v,
        phi: k.phi,
        on_ramp,
    }
}

/// Weight of a reward held from step `step + 1` to the last step `steps - 1`:
/// `sum_{k = step + 1}^{steps - 1} gamma^k`. With `sim.absorbing_collision`, a collision at
/// `step` charges every player its reward of that step this many more times (an absorbing
/// crash state), so that ending an episode early never raises a return of negative rewards.
pub fn tail_weight(gamma: f64, step: usize, steps: usize) -> f64 {
    (step + 1..steps).map(|k| gamma.powi(k as i32)).sum()
}

/// The acceleration player `i` of `scene` applies for the raw action `raw`: when `feasibility`
/// is on, projected onto its feasible interval in the target lane, or held by the merge gate
/// on the ramp (`sim.merge_gate`, [`crate::sim::merge_gate`]); then clipped to
/// `[-g, g]` and the speed bounds (Section V-ii). One function for the internal simulator and
/// the SUMO co-simulation.
pub fn applied_action(
    config: &Config,
    feasibility: bool,
    scene: &Scene,
    i: usize,
    nb: &Neighbors,
    raw: f64,
) -> f64 {
    let veh = &config.vehicle;
    let dt = config.sim.dt;
    let me = &scene.vehicles[i];
    let mut a = raw;
    if feasibility && !me.on_ramp {
        let lead = neighbor_of(scene, nb.lane_leader, me);
        let follow = neighbor_of(scene, nb.lane_follower, me);
        let clearance = veh.length + config.sim.safety_gap;
        let (lo, hi) = feasible_interval(&me.x, &me.v, &lead, &follow, clearance, dt, config.sim.tau_s);
        a = project_feasible(&a, &lo, &hi);
    }
    let rules = GateRules::new(config);
    if feasibility && config.sim.merge_gate && gate_holds(scene, i, &rules) {
        a = a.min(stop_bound(&me.x, &me.v, &rules));
    }
    clip_action(&a, &me.v, veh.max_accel, veh.v_min, veh.v_max, dt)
}

/// The first overlapping pair `(a, b)`, `a < b`, in index order.
pub fn first_collision(scene: &Scene, length: f64, width: f64) -> Option<(usize, usize)> {
    let fp = |v: &Vehicle| Footprint {
        x: v.x,
        y: v.y,
        phi: v.phi,
        length,
        width,
    };
    let veh = &scene.vehicles;
    let diagonal = length.hypot(width); // centres farther apart than this cannot overlap
    (0..veh.len()).find_map(|a| {
        ((a + 1)..veh.len())
            .find(|&b| (veh[a].x - veh[b].x).abs() < diagonal && boxes_overlap(&fp(&veh[a]), &fp(&veh[b])))
            .map(|b| (a, b))
    })
}
