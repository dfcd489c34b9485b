//! Configuration: TOML files (`configs/*.toml`) parsed into serde structs with
//! `deny_unknown_fields`, then validated into a [`Config`] before any work starts.
//!
//! Every quantity is in SI units (m, s, m/s, m/s^2). `configs/paper.toml` documents, value by
//! value, which numbers come from the paper and which are our choice.

use serde::{Deserialize, Serialize};
use std::path::Path;

/// A configuration problem, naming the key at fault.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("cannot read config {path}")]
    Read {
        /// The file.
        path: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The TOML did not parse or did not match the schema (unknown key, wrong type).
    #[error("config {path}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// What the parser said, including the key and line.
        message: String,
    },
    /// A value is out of range, not finite, or inconsistent with another.
    #[error("config key `{key}`: {message}")]
    Invalid {
        /// Dotted key, for example `scenario.conflict_point`.
        key: String,
        /// What is wrong.
        message: String,
    },
}

/// Road geometry of the forced merge (Section V).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ScenarioConfig {
    /// Longitudinal position of the merging conflict point `x_c` (m).
    pub conflict_point: f64,
    /// Length of the simulated road; positions beyond it are still simulated (m).
    pub road_length: f64,
    /// Lane width (m); the ramp centre line is one lane width to the right of the target lane.
    pub lane_width: f64,
    /// Number of target-lane players ahead of the ego by distance to the conflict point.
    pub n_leaders: usize,
    /// Number of target-lane players behind the ego by distance to the conflict point.
    pub n_followers: usize,
    /// Which world episodes start in: the paper's one ego and its players, or merge traffic
    /// (`[traffic]`). Default `paper`.
    #[serde(default)]
    pub kind: ScenarioKind,
    /// Ramp vehicles change to the target lane at the first step the lane change is safe
    /// ([`crate::world::merge_gate::lane_change_is_safe`]) from this distance before `x_c` on,
    /// and at the ramp's end (`x_c`, or the acceleration lane's end) at the latest (m; ours).
    /// Default 0: at `x_c` only, as the paper.
    #[serde(default)]
    pub merge_zone: f64,
    /// From this distance before `x_c` on, the drivers who make room for a ramp vehicle
    /// (`sim.players_make_room`, `traffic.cooperation`) make room for it (m; ours), as SUMO's
    /// drivers slow for a vehicle that signals before it can change lanes: a gap opened only once
    /// the ramp vehicle is in the merge zone is opened too late for a slow one beside a platoon.
    /// Default (and at least) `merge_zone`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub yield_zone: Option<f64>,
    /// The ramp goes on this far past `x_c` as an acceleration lane (m; ours): a ramp vehicle
    /// without a safe gap by `x_c` stays on it, changes lanes at the first safe gap, and joins
    /// the target lane at its end at the latest (where the merge gate, when on, holds it).
    /// Default 0: the ramp ends at `x_c`, as the paper.
    #[serde(default)]
    pub accel_lane: f64,
    /// How a ramp vehicle enters the target lane. Default `conflict_point`, the paper's.
    #[serde(default)]
    pub entry: Entry,
}

/// In which order the feasibility projection settles the players of a step.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum ProjectionOrder {
    /// The paper's reading: every vehicle at once, each assuming its neighbours keep their
    /// speed. A leader pushed on by its follower's bound and that follower held back by its
    /// leader's both correct the same closing speed, so together they overshoot, and the pair
    /// can alternate from step to step (chatter).
    #[default]
    Simultaneous,
    /// Ours: front to back, each vehicle's leader bound reading its leader's speed after this
    /// step, already settled. A closing speed is corrected once.
    Sequential,
    /// Ours: every vehicle at once, as the paper's, but a leader and its follower that are
    /// both projected share the correction of their pair: each takes `sim.shared_correction`
    /// of what its bound asks beyond keeping its speed (at 0.5 a closing speed is corrected
    /// once, in one pass; above it the pair's alternation decays).
    Shared,
}

/// How a ramp vehicle enters the target lane.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Entry {
    /// The paper's: it joins the target lane when its `x` reaches the ramp's end (`x_c`, or
    /// the acceleration lane's end), whatever is beside it.
    #[default]
    ConflictPoint,
    /// The entry rule ([`crate::world::merge_gate`], "Entry rule"): it joins the target lane
    /// only into a gap a human follower absorbs; without one it stops at the ramp's end and
    /// waits. Nothing forces an entry.
    Gap,
}

/// The world an episode starts in.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum ScenarioKind {
    /// The paper's: one ramp ego and `n_leaders + n_followers` target-lane players, Table I
    /// observations (with the one-hot agent index).
    #[default]
    Paper,
    /// Merge traffic: streams on the ramp and the target lane (`[traffic]`), several ramp
    /// vehicles, a share of IDM drivers; the traffic observation (no agent index).
    Traffic,
}

/// Merge traffic (`scenario.kind = "traffic"`): how many vehicles an episode holds and the
/// ranges its demand and driver mix are drawn from.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TrafficConfig {
    /// Ramp vehicles per episode (the ego is one of them).
    pub ramp_vehicles: usize,
    /// Target-lane vehicles per episode.
    pub target_vehicles: usize,
    /// Range of the target lane's flow (veh/h).
    pub lane_flow: [f64; 2],
    /// Range of the ramp's flow (veh/h).
    pub ramp_flow: [f64; 2],
    /// Range of the share of human (IDM) drivers among the vehicles other than the ego.
    pub human_share: [f64; 2],
    /// Share of the target-lane vehicles placed ahead of the conflict point.
    pub ahead_share: f64,
    /// Range of the share of human drivers that make room for a ramp vehicle in the merge zone
    /// just ahead of them, as SUMO's drivers do for one that signals (IDM behind it, when
    /// braking at `sim.b_safe` or less does it); the others never do. Drawn per episode;
    /// `[0, 0]` (the default): none.
    #[serde(default)]
    pub cooperation: [f64; 2],
    /// Range of each episode's desired speed `v_d` (m/s): the reward tracks it, and the
    /// sampled speeds and IDM's `v0` scale by `v_d / reward.v_desired`, so one policy drives
    /// roads of different speed limits. None: `reward.v_desired` in every episode.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub desired_speed: Option<[f64; 2]>,
}

/// Vehicle body and kinematic-bicycle parameters (eq. 1).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct VehicleConfig {
    /// Bounding-box length (m).
    pub length: f64,
    /// Bounding-box width (m).
    pub width: f64,
    /// Distance from the centre of mass to the front axle `l_f` (m).
    pub l_f: f64,
    /// Distance from the centre of mass to the rear axle `l_r` (m).
    pub l_r: f64,
    /// Lowest speed (m/s).
    pub v_min: f64,
    /// Highest speed (m/s).
    pub v_max: f64,
    /// Action bound `g`: accelerations lie in `[-g, g]` (m/s^2).
    pub max_accel: f64,
}

/// Time discretisation and the episode rules.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SimConfig {
    /// Time step `Delta t` (s).
    pub dt: f64,
    /// Episode horizon `T` (s).
    pub horizon: f64,
    /// Discount factor per step.
    pub gamma: f64,
    /// Project target-lane actions onto the TTC-feasible interval (Section V-ii).
    pub feasibility: bool,
    /// TTC safety threshold `tau_s` of the feasibility projection (s).
    pub tau_s: f64,
    /// Standstill clearance kept by the feasibility projection (m): its TTC uses the gap
    /// `|x_i - x_j| - length - safety_gap`, so a platoon held at TTC = tau_s settles this far
    /// apart instead of bumper to bumper.
    pub safety_gap: f64,
    /// Time gap the feasibility projection keeps on top of the clearance (s): its TTC uses
    /// the gap less `time_headway` times the follower's speed, so a vehicle settles behind a
    /// leader at `safety_gap + time_headway * v` (SUMO's and IDM's car following keep such a
    /// gap). 0 when absent: the paper's TTC rule alone, which at equal speeds lets a vehicle
    /// follow `safety_gap` behind its leader at any speed.
    #[serde(default)]
    pub time_headway: f64,
    /// In which order the feasibility projection settles the players of a step (`feasibility`).
    /// Simultaneous when absent (files written before it existed).
    #[serde(default)]
    pub projection_order: ProjectionOrder,
    /// With `projection_order = "shared"`: the share of its bound's correction each end of a
    /// projected pair takes, in [0.5, 1] (ours; 0.5 when absent: the closing speed corrected
    /// once). 1 corrects it from both ends, as the simultaneous order does; in between, the
    /// pair overshoots by `2 share - 1` of it and an alternation decays by that factor a step.
    #[serde(default = "default_shared_correction")]
    pub shared_correction: f64,
    /// With `feasibility`: also hold a ramp vehicle able to stop before `x_c` while entering
    /// the target lane is not safe (the merge gate, [`crate::world::merge_gate`]). Off when
    /// absent (files written before it existed).
    #[serde(default)]
    pub merge_gate: bool,
    /// Largest braking a merge may ask of the new follower or of the merging vehicle (m/s^2).
    #[serde(default = "default_b_safe")]
    pub b_safe: f64,
    /// Braking (m/s^2) of the stopping bound with which the entry rule holds a ramp vehicle at
    /// its lane's end ([`crate::world::merge_gate::lane_end_bound`]): the vehicle may drive on
    /// as long as it can still stop there braking this hard. `vehicle.max_accel` (`g`, the
    /// latest stop the road allows) when absent; `b_safe` stops it as a human driver would
    /// (docs/experiments.md, "Where a held ramp vehicle stops").
    #[serde(default)]
    pub lane_end_brake: Option<f64>,
    /// Reaction time of a human follower in the entry rule (`scenario.entry = "gap"`, s):
    /// the follower goes on at its speed this long before it brakes at `b_safe`.
    #[serde(default = "default_reaction_time")]
    pub reaction_time: f64,
    /// With `feasibility`: also project (and gate) the players a non-learning driver drives
    /// (IDM, constant speed). Off: only policy-driven players follow the feasibility rules and
    /// the others drive by their own rule, as the paper's surrounding players do. On when
    /// absent (files written before it existed).
    #[serde(default = "yes")]
    pub project_non_learning: bool,
    /// With `feasibility`: a policy-driven target-lane player keeps the projection's gap behind
    /// the first ramp vehicle ahead of it in the merge zone too, when that asks no harder
    /// braking than `b_safe` ([`crate::world::step::applied_action_with`]): it
    /// makes room for a vehicle that signals, as SUMO's drivers and the cooperative human
    /// drivers of `traffic.cooperation` do. Off when absent (the paper's players).
    #[serde(default)]
    pub players_make_room: bool,
    /// With `feasibility`: a target-lane vehicle's immediate leader and follower of Section
    /// V-ii are the nearest vehicles ahead and behind by longitudinal position in either lane
    /// (as Table I orders them), so that it keeps the TTC above `tau_s` to a ramp vehicle too;
    /// its same-lane ones still bind ([`crate::world::step::applied_action_with`]). Off when
    /// absent: same-lane neighbours only.
    #[serde(default)]
    pub feasibility_across_lanes: bool,
    /// End the episode for everyone at the first collision.
    pub terminate_on_collision: bool,
    /// With termination: charge each player its collision-step reward for every remaining
    /// step (an absorbing crash state), so that crashing early never pays.
    pub absorbing_collision: bool,
}

/// Reward terms of Section V-iii and their weights.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RewardConfig {
    /// Desired speed `v_d` of the speed-tracking term (m/s).
    pub v_desired: f64,
    /// Relative-speed threshold `v_c` of the same-lane TTC term (m/s).
    pub v_c: f64,
    /// `epsilon` guarding the denominators (and the arrival-time divisions).
    pub epsilon: f64,
    /// Weight `omega_11` of speed tracking `-(v - v_d)^2`.
    pub w_speed: f64,
    /// Weight `omega_12` of comfort `-u^2`.
    pub w_comfort: f64,
    /// Weight `omega_21` of the same-lane pairwise TTC term.
    pub w_ttc: f64,
    /// Weight `omega_22` of the different-lane time-gap-to-conflict-point term (eq. 28).
    pub w_conflict: f64,
    /// Weight `omega_{i,11}` of speed tracking for a vehicle on the ramp (ours; default
    /// `w_speed`). The paper's weights may differ per vehicle `i`; a self term weighted by the
    /// vehicle's own lane is still a function of its own state, so the game stays an MPG.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub w_speed_ramp: Option<f64>,
    /// A different-lane pair's conflict term ends once either vehicle has passed `x_c` (ours;
    /// default false: the paper's `T = |x - x_c| / (v + eps)` on both sides of `x_c`).
    #[serde(default)]
    pub conflict_ends_at_x_c: bool,
    /// With `conflict_ends_at_x_c`, how far past `x_c` (m) the first vehicle must be before
    /// the pair's term ends (ours; default 0). Until then `|x - x_c|` still counts it, so a
    /// vehicle reaching `x_c` just behind another, bodies overlapping, is still penalised.
    #[serde(default)]
    pub conflict_clearance: f64,
    /// The conflict term's times to `x_c` are signed, `T = (x_c - x) / (v + eps)`, negative
    /// once a vehicle has passed (ours; default false: the paper's `|x - x_c|`). `T_i - T_j`
    /// is then the pair's time headway at `x_c` on both sides of it, so a ramp vehicle that
    /// follows a passed one is no longer taken to meet it a second time.
    #[serde(default)]
    pub conflict_signed_time: bool,
}

/// How the different-lane conflict term (eq. 28) reads a vehicle's time to the conflict point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ConflictForm {
    /// The paper's `T = |x - x_c| / (v + eps)` on both sides of `x_c`.
    Paper,
    /// The paper's times until either vehicle is this far (m) past `x_c`, then no term
    /// (`conflict_ends_at_x_c`, `conflict_clearance`).
    EndsPast(f64),
    /// Signed times, `T = (x_c - x) / (v + eps)` (`conflict_signed_time`).
    Signed,
}

impl RewardConfig {
    /// The speed-tracking weight of a vehicle on the ramp (`w_speed_ramp`, else `w_speed`).
    pub fn speed_weight_on_ramp(&self) -> f64 {
        self.w_speed_ramp.unwrap_or(self.w_speed)
    }

    /// The conflict term's form these keys select.
    pub fn conflict_form(&self) -> ConflictForm {
        if self.conflict_signed_time {
            ConflictForm::Signed
        } else if self.conflict_ends_at_x_c {
            ConflictForm::EndsPast(self.conflict_clearance)
        } else {
            ConflictForm::Paper
        }
    }
}

/// Intelligent Driver Model parameters (Treiber, Hennecke and Helbing 2000).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct IdmConfig {
    /// Desired speed `v0` (m/s).
    pub v0: f64,
    /// Safe time headway `T` (s).
    pub time_headway: f64,
    /// Minimum standstill gap `s0` (m).
    pub min_gap: f64,
    /// Maximum acceleration `a` (m/s^2).
    pub accel: f64,
    /// Comfortable deceleration `b` (m/s^2).
    pub decel: f64,
    /// Acceleration exponent `delta` (a multiple of 0.5).
    pub delta: f64,
}

/// Stratified initial-state sampling (Section V-iv).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SamplingConfig {
    /// Range of the ego's initial longitudinal position `[min, max]` (m).
    pub ego_position: [f64; 2],
    /// Range of the ego's initial speed (m/s).
    pub ego_speed: [f64; 2],
    /// Range of the target-lane players' initial speeds (m/s).
    pub speed: [f64; 2],
    /// Range of the centre-to-centre headway between successive vehicles (m).
    pub headway: [f64; 2],
    /// Lowest initial TTC between every successive leader and follower (s).
    pub min_ttc: f64,
    /// Strata over (ego position, ego speed): scenario `k` is drawn in stratum `k mod (n_p * n_v)`.
    pub strata: [usize; 2],
}

/// Evaluation settings shared by later commands.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct EvalConfig {
    /// Training/evaluation seeds (one policy per seed).
    pub seeds: Vec<u64>,
    /// Number of test scenarios per seed.
    pub test_scenarios: usize,
}

/// Training (Algorithm 1) settings.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TrainConfig {
    /// Width of each hidden layer of the shared network.
    pub hidden: usize,
    /// Gradient-ascent epochs (one minibatch each).
    pub epochs: usize,
    /// Initial states per minibatch.
    pub batch: usize,
    /// Adam step size at the first epoch.
    pub learning_rate: f64,
    /// Adam step size at the last epoch; it decays exponentially in between.
    pub learning_rate_final: f64,
    /// Epochs (from 0, ascending) at which the step size warms up again: each starts a new
    /// decay from `learning_rate` to `learning_rate_final` by the epoch before the next one
    /// (or the last), and Adam's moments restart with it (none when absent).
    #[serde(default)]
    pub learning_rate_restarts: Vec<usize>,
    /// Largest gradient norm (clipped above).
    pub grad_clip: f64,
    /// Fixed probe initial states for the curves (disjoint from training).
    pub probe_scenarios: usize,
    /// Epochs between checkpoints.
    pub checkpoint_every: usize,
    /// Threads running the shards of every minibatch and probe set
    /// ([`crate::train::SHARDS`], so more are not used), each with one libtorch thread. A
    /// run's result does not depend on it.
    pub threads: usize,
    /// Initialisations screened before training (1: none; the run's own seed).
    #[serde(default = "one")]
    pub init_candidates: usize,
    /// Epochs each screened initialisation trains before the best probe objective is kept.
    #[serde(default)]
    pub screen_epochs: usize,
    /// Extra training states with the ego close to the merge (none when absent).
    #[serde(default)]
    pub near_merge: Option<NearMergeConfig>,
    /// Share of every training minibatch and of the probe set drawn from the descriptions of
    /// the paper's two specific scenarios, alternately ([`crate::world::scenarios::Preset::draw_state`],
    /// from the set's own random streams); 0 when absent.
    #[serde(default)]
    pub scenario_share: f64,
    /// Share of the probe set (the curves' and the initialisation screening's states) drawn
    /// from the same descriptions; `scenario_share` when absent. The probe can then judge a
    /// policy on the scenario families without training on them.
    #[serde(default)]
    pub probe_scenario_share: Option<f64>,
    /// The first epoch whose minibatches hold `scenario_share` (0: every epoch; the
    /// initialisation screening's epochs count as epochs from 0).
    #[serde(default)]
    pub scenario_from: usize,
    /// The training rewards' `epsilon` starts here and decays geometrically to
    /// `reward.epsilon` over the first `train.continuation.epochs` epochs (none when absent).
    #[serde(default)]
    pub continuation: Option<ContinuationConfig>,
    /// The training world's `sim.shared_correction` starts at `start` and moves linearly to
    /// the configured one between two epochs (none when absent).
    #[serde(default)]
    pub correction_continuation: Option<CorrectionContinuation>,
}

/// A continuation of the shared projection's correction (ours): training starts in a world
/// whose projected pairs each take `start` of their correction (1: the simultaneous order's
/// double push) and moves to the configured `sim.shared_correction` from epoch `epochs[0]` to
/// epoch `epochs[1]`; the probe, screening, checkpoints' curves and every evaluation use the
/// configured world, which is the one the policy ends its training in.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CorrectionContinuation {
    /// `sim.shared_correction` of the first epochs, in [0.5, 1].
    pub start: f64,
    /// The epochs at which the move to the configured value begins and ends.
    pub epochs: [usize; 2],
}

/// A continuation of the pair terms' cap (graduated non-convexity): every pair penalty of
/// the TTC and conflict terms is at most `1 / epsilon`, the height of the ridge between two
/// merge slots of the ego. Training starts with the ridges low (`epsilon_start` above
/// `reward.epsilon`) and raises them to the configured game's over `epochs`; the probe,
/// screening and every evaluation use the configured reward.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ContinuationConfig {
    /// `epsilon` of the first epoch, at least `reward.epsilon`.
    pub epsilon_start: f64,
    /// Epochs over which it decays to `reward.epsilon` (at least 1).
    pub epochs: usize,
}

/// A share of every training minibatch drawn with a slow ego close to `x_c`, where followers
/// pass beside it: the states in which an ego that reaches `x_c` late must still wait are
/// rare under the stratified sampling. Probe and test states keep the stratified sampling
/// ([`crate::world::sampler::sample_training_scenes`]).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct NearMergeConfig {
    /// Share of each minibatch, in `[0, 1]`: its last `round(share * batch)` states.
    pub share: f64,
    /// Range of these states' initial ego position (m); the players are placed around the
    /// ego as in the stratified sampling.
    pub ego_position: [f64; 2],
    /// Range of their initial ego speed (m/s).
    pub ego_speed: [f64; 2],
}

fn one() -> usize {
    1
}

/// MOBIL's safe braking (Kesting, Treiber and Helbing 2007).
fn yes() -> bool {
    true
}

fn default_b_safe() -> f64 {
    4.0
}

fn default_shared_correction() -> f64 {
    0.5
}

/// SUMO's default driver reaction time (Krauss's `tau`).
fn default_reaction_time() -> f64 {
    1.0
}

/// Reads a TOML file into `T` (unknown keys refused when `T` says so).
pub fn load_toml<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, ConfigError> {
    let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
        path: path.display().to_string(),
        source,
    })?;
    parse_toml(&text, &path.display().to_string())
}

/// Parses TOML text into `T`; errors name `origin` and the line.
pub fn parse_toml<T: serde::de::DeserializeOwned>(text: &str, origin: &str) -> Result<T, ConfigError> {
    toml::from_str(text).map_err(|e| {
        let line = e
            .span()
            .map(|s| text[..s.start.min(text.len())].matches('\n').count() + 1);
        // The line itself (without its comment) names the key a type error is about.
        let quoted = |l: usize| {
            let source = text.lines().nth(l - 1).unwrap_or("");
            let code = source.split(" #").next().unwrap_or(source).trim();
            if code.is_empty() || code.len() > 80 {
                String::new()
            } else {
                format!(" (`{code}`)")
            }
        };
        ConfigError::Parse {
            path: origin.to_string(),
            message: match line {
                Some(l) => format!("line {l}{}: {}", quoted(l), e.message()),
                None => e.message().to_string(),
            },
        }
    })
}

/// The whole configuration (one TOML file).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Config {
    /// Seed of every random stream not given on the command line.
    pub seed: u64,
    /// Road geometry.
    pub scenario: ScenarioConfig,
    /// Vehicles.
    pub vehicle: VehicleConfig,
    /// Simulation.
    pub sim: SimConfig,
    /// Rewards.
    pub reward: RewardConfig,
    /// IDM drivers.
    pub idm: IdmConfig,
    /// Initial states.
    pub sampling: SamplingConfig,
    /// Evaluation.
    pub eval: EvalConfig,
    /// Training.
    pub train: TrainConfig,
    /// Merge traffic, required when `scenario.kind = "traffic"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub traffic: Option<TrafficConfig>,
}

impl Config {
    /// Reads, parses and validates a TOML configuration file.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let config: Config = load_toml(path)?;
        config.validate()?;
        Ok(config)
    }

    /// Parses and validates TOML text; `origin` names it in messages.
    pub fn parse(text: &str, origin: &str) -> Result<Self, ConfigError> {
        let config: Config = parse_toml(text, origin)?;
        config.validate()?;
        Ok(config)
    }

    /// This configuration at another conflict point: a network's or a dataset's `x_c`, whose
    /// file validated it. The one way the world's geometry enters a configuration (the SUMO
    /// controller, the NGSIM replay and the synthetic NGSIM files). The training road's
    /// acceleration lane (`scenario.accel_lane`) goes with it: there the network's or the
    /// data's own lanes say where the ramp ends.
    pub fn at_conflict_point(&self, conflict_point: f64) -> Config {
        let mut c = self.clone();
        c.scenario.conflict_point = conflict_point;
        c.scenario.accel_lane = 0.0;
        c
    }

    /// Total number of vehicles `N` of an episode: the ego, leaders and followers, or the
    /// traffic's ramp and target-lane vehicles.
    pub fn n_agents(&self) -> usize {
        match (&self.scenario.kind, &self.traffic) {
            (ScenarioKind::Traffic, Some(t)) => t.ramp_vehicles + t.target_vehicles,
            _ => 1 + self.scenario.n_leaders + self.scenario.n_followers,
        }
    }

    /// Number of simulation steps in an episode, `round(T / dt)`.
    pub fn n_steps(&self) -> usize {
        (self.sim.horizon / self.sim.dt).round() as usize
    }

    /// Checks ranges and consistency; the first problem found is returned.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let s = &self.scenario;
        let v = &self.vehicle;
        let m = &self.sim;
        let r = &self.reward;
        let i = &self.idm;
        let p = &self.sampling;
        positive("scenario.road_length", s.road_length)?;
        positive("scenario.lane_width", s.lane_width)?;
        non_negative("scenario.merge_zone", s.merge_zone)?;
        if let Some(zone) = s.yield_zone {
            non_negative("scenario.yield_zone", zone)?;
        }
        non_negative("scenario.accel_lane", s.accel_lane)?;
        finite("scenario.conflict_point", s.conflict_point)?;
        check(
            "scenario.conflict_point",
            s.conflict_point > 0.0 && s.conflict_point < s.road_length,
            format!(
                "{} must lie inside the road (0, {})",
                s.conflict_point, s.road_length
            ),
        )?;
        check(
            "scenario.n_leaders",
            s.n_leaders <= 16,
            "must be at most 16".into(),
        )?;
        check(
            "scenario.n_followers",
            s.n_followers <= 16,
            "must be at most 16".into(),
        )?;
        positive("vehicle.length", v.length)?;
        positive("vehicle.width", v.width)?;
        check(
            "vehicle.width",
            v.width < s.lane_width,
            format!("{} must be narrower than the lane ({})", v.width, s.lane_width),
        )?;
        positive("vehicle.l_f", v.l_f)?;
        positive("vehicle.l_r", v.l_r)?;
        non_negative("vehicle.v_min", v.v_min)?;
        positive("vehicle.v_max", v.v_max)?;
        check(
            "vehicle.v_max",
            v.v_max > v.v_min,
            format!("{} must exceed vehicle.v_min ({})", v.v_max, v.v_min),
        )?;
        positive("vehicle.max_accel", v.max_accel)?;
        positive("sim.dt", m.dt)?;
        positive("sim.horizon", m.horizon)?;
        check(
            "sim.horizon",
            m.horizon >= m.dt,
            format!("{} must be at least one step (sim.dt = {})", m.horizon, m.dt),
        )?;
        finite("sim.gamma", m.gamma)?;
        check(
            "sim.gamma",
            m.gamma > 0.0 && m.gamma <= 1.0,
            "must lie in (0, 1]".into(),
        )?;
        positive("sim.tau_s", m.tau_s)?;
        non_negative("sim.safety_gap", m.safety_gap)?;
        non_negative("sim.time_headway", m.time_headway)?;
        positive("sim.b_safe", m.b_safe)?;
        within("sim.shared_correction", m.shared_correction, 0.5, 1.0)?;
        non_negative("sim.reaction_time", m.reaction_time)?;
        if let Some(b) = m.lane_end_brake {
            check(
                "sim.lane_end_brake",
                b > 0.0 && b <= v.max_accel,
                format!("{b} must lie in (0, vehicle.max_accel = {}]", v.max_accel),
            )?;
        }
        non_negative("reward.v_desired", r.v_desired)?;
        positive("reward.v_c", r.v_c)?;
        positive("reward.epsilon", r.epsilon)?;
        non_negative("reward.conflict_clearance", r.conflict_clearance)?;
        check(
            "reward.conflict_signed_time",
            !(r.conflict_signed_time && r.conflict_ends_at_x_c),
            "and reward.conflict_ends_at_x_c exclude each other (choose one form of the conflict term)"
                .into(),
        )?;
        for (key, w) in [
            ("reward.w_speed", r.w_speed),
            ("reward.w_comfort", r.w_comfort),
            ("reward.w_ttc", r.w_ttc),
            ("reward.w_conflict", r.w_conflict),
            ("reward.w_speed_ramp", r.speed_weight_on_ramp()),
        ] {
            non_negative(key, w)?;
        }
        for (key, x) in [
            ("idm.v0", i.v0),
            ("idm.time_headway", i.time_headway),
            ("idm.accel", i.accel),
            ("idm.decel", i.decel),
            ("idm.delta", i.delta),
        ] {
            positive(key, x)?;
        }
        non_negative("idm.min_gap", i.min_gap)?;
        check(
            "idm.delta",
            (i.delta * 2.0).fract() == 0.0 && i.delta <= 16.0,
            format!("{} must be a multiple of 0.5 up to 16", i.delta),
        )?;
        range("sampling.ego_position", p.ego_position, 0.0, s.conflict_point)?;
        range("sampling.ego_speed", p.ego_speed, v.v_min, v.v_max)?;
        range("sampling.speed", p.speed, v.v_min, v.v_max)?;
        range("sampling.headway", p.headway, v.length, f64::INFINITY)?;
        positive("sampling.min_ttc", p.min_ttc)?;
        check(
            "sampling.strata",
            p.strata[0] >= 1 && p.strata[1] >= 1,
            "both counts must be at least 1".into(),
        )?;
        self.validate_traffic()?;
        let t = &self.train;
        for (key, n) in [
            ("train.hidden", t.hidden),
            ("train.epochs", t.epochs),
            ("train.batch", t.batch),
            ("train.probe_scenarios", t.probe_scenarios),
            ("train.checkpoint_every", t.checkpoint_every),
            ("train.threads", t.threads),
            ("train.init_candidates", t.init_candidates),
        ] {
            check(key, n >= 1, "must be at least 1".into())?;
        }
        positive("train.learning_rate", t.learning_rate)?;
        positive("train.learning_rate_final", t.learning_rate_final)?;
        positive("train.grad_clip", t.grad_clip)?;
        check(
            "train.learning_rate_restarts",
            t.learning_rate_restarts.windows(2).all(|w| w[0] < w[1])
                && t.learning_rate_restarts
                    .iter()
                    .all(|&r| (1..t.epochs).contains(&r)),
            format!(
                "{:?} must be ascending epochs in [1, train.epochs) ({})",
                t.learning_rate_restarts, t.epochs
            ),
        )?;
        check(
            "train.screen_epochs",
            self.train.init_candidates == 1 || (1..=self.train.epochs).contains(&self.train.screen_epochs),
            format!(
                "{} must lie in [1, train.epochs] when several initialisations are screened",
                self.train.screen_epochs
            ),
        )?;
        finite("train.scenario_share", t.scenario_share)?;
        let near_share = t.near_merge.as_ref().map_or(0.0, |n| n.share);
        check(
            "train.scenario_share",
            t.scenario_share >= 0.0 && t.scenario_share + near_share.max(0.0) <= 1.0,
            format!(
                "{} must lie in [0, 1 - train.near_merge.share] ({near_share})",
                t.scenario_share
            ),
        )?;
        if let Some(share) = t.probe_scenario_share {
            within("train.probe_scenario_share", share, 0.0, 1.0)?;
        }
        for (key, share) in [
            ("train.scenario_share", t.scenario_share),
            (
                "train.probe_scenario_share",
                t.probe_scenario_share.unwrap_or(0.0),
            ),
        ] {
            check(
                key,
                share == 0.0 || s.kind != ScenarioKind::Traffic,
                "applies to the paper's scenario only (scenario.kind = \"paper\")".into(),
            )?;
        }
        check(
            "train.scenario_from",
            t.scenario_from < t.epochs,
            format!("{} must be below train.epochs ({})", t.scenario_from, t.epochs),
        )?;
        if let Some(c) = &t.continuation {
            finite("train.continuation.epsilon_start", c.epsilon_start)?;
            check(
                "train.continuation.epsilon_start",
                c.epsilon_start >= self.reward.epsilon,
                format!(
                    "{} must be at least reward.epsilon ({})",
                    c.epsilon_start, self.reward.epsilon
                ),
            )?;
            check(
                "train.continuation.epochs",
                c.epochs >= 1,
                "must be at least 1".into(),
            )?;
        }
        if let Some(c) = &t.correction_continuation {
            within("train.correction_continuation.start", c.start, 0.5, 1.0)?;
            check(
                "train.correction_continuation.epochs",
                c.epochs[0] <= c.epochs[1] && c.epochs[1] <= t.epochs,
                format!(
                    "{:?} must be ordered and at most train.epochs ({})",
                    c.epochs, t.epochs
                ),
            )?;
            check(
                "train.correction_continuation",
                self.sim.projection_order == ProjectionOrder::Shared,
                "needs sim.projection_order = \"shared\"".into(),
            )?;
        }
        if let Some(n) = &t.near_merge {
            finite("train.near_merge.share", n.share)?;
            within("train.near_merge.share", n.share, 0.0, 1.0)?;
            range(
                "train.near_merge.ego_position",
                n.ego_position,
                0.0,
                s.conflict_point,
            )?;
            range("train.near_merge.ego_speed", n.ego_speed, v.v_min, v.v_max)?;
            check(
                "train.near_merge",
                s.kind != ScenarioKind::Traffic,
                "applies to the paper's scenario only (scenario.kind = \"paper\")".into(),
            )?;
        }
        check(
            "eval.seeds",
            !self.eval.seeds.is_empty(),
            "needs at least one seed".into(),
        )?;
        check(
            "eval.test_scenarios",
            self.eval.test_scenarios >= 1,
            "must be at least 1".into(),
        )?;
        Ok(())
    }
}

impl Config {
    fn validate_traffic(&self) -> Result<(), ConfigError> {
        let Some(t) = &self.traffic else {
            return check(
                "traffic",
                self.scenario.kind == ScenarioKind::Paper,
                "scenario.kind = \"traffic\" needs a [traffic] section".into(),
            );
        };
        check(
            "traffic.ramp_vehicles",
            (1..=8).contains(&t.ramp_vehicles),
            "must lie in [1, 8]".into(),
        )?;
        check(
            "traffic.target_vehicles",
            (1..=32).contains(&t.target_vehicles),
            "must lie in [1, 32]".into(),
        )?;
        range("traffic.lane_flow", t.lane_flow, 1.0, 4000.0)?;
        range("traffic.ramp_flow", t.ramp_flow, 1.0, 4000.0)?;
        range("traffic.human_share", t.human_share, 0.0, 1.0)?;
        range("traffic.cooperation", t.cooperation, 0.0, 1.0)?;
        if let Some(d) = t.desired_speed {
            range("traffic.desired_speed", d, 1.0, self.vehicle.v_max)?;
        }
        finite("traffic.ahead_share", t.ahead_share)?;
        within("traffic.ahead_share", t.ahead_share, 0.0, 1.0)
    }
}

pub(crate) fn check(key: &str, ok: bool, message: String) -> Result<(), ConfigError> {
    if ok {
        Ok(())
    } else {
        Err(ConfigError::Invalid {
            key: key.to_string(),
            message,
        })
    }
}

pub(crate) fn finite(key: &str, x: f64) -> Result<(), ConfigError> {
    check(key, x.is_finite(), format!("{x} is not a finite number"))
}

pub(crate) fn positive(key: &str, x: f64) -> Result<(), ConfigError> {
    finite(key, x)?;
    check(key, x > 0.0, format!("{x} must be positive"))
}

pub(crate) fn non_negative(key: &str, x: f64) -> Result<(), ConfigError> {
    finite(key, x)?;
    check(key, x >= 0.0, format!("{x} must not be negative"))
}

/// `[min, max]` with `lo <= min <= max <= hi`, all finite.
/// `x` in `[lo, hi]` (NaN is not).
fn within(key: &str, x: f64, lo: f64, hi: f64) -> Result<(), ConfigError> {
    check(
        key,
        (lo..=hi).contains(&x),
        format!("{x} must lie in [{lo}, {hi}]"),
    )
}

fn range(key: &str, r: [f64; 2], lo: f64, hi: f64) -> Result<(), ConfigError> {
    finite(key, r[0])?;
    finite(key, r[1])?;
    check(
        key,
        r[0] <= r[1],
        format!("minimum {} exceeds maximum {}", r[0], r[1]),
    )?;
    check(
        key,
        r[0] >= lo && r[1] <= hi,
        format!("[{}, {}] must lie within [{lo}, {hi}]", r[0], r[1]),
    )
}
