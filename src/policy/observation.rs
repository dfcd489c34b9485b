//! Local observation of each player (Table I), one builder for every kind of traffic
//! (internal simulator, NGSIM replay, SUMO co-simulation).
//!
//! | index | feature | definition |
//! |---|---|---|
//! | 0 | position | `x_c - x` (m), signed distance to the conflict point |
//! | 1 | speed | `v` (m/s) |
//! | 2 | leader distance | `x_L - x` (m), nearest player ahead in any lane |
//! | 3 | leader relative speed | `v_L - v` (m/s) |
//! | 4 | leader flag | 1 when there is a leader |
//! | 5 | follower distance | `x - x_F` (m), nearest player behind in any lane |
//! | 6 | follower relative speed | `v_F - v` (m/s) |
//! | 7 | follower flag | 1 when there is a follower |
//! | 8 | lane flag | 1 on the ramp, 0 in the target lane |
//! | 9.. | agent index | one-hot over the `N` players |
//!
//! A missing neighbour reads as [`MISSING_DISTANCE`] away with zero relative speed, and its
//! flag is 0. A neighbour farther than that reads as that far (with its flag and relative
//! speed): training's rollouts almost never go beyond it, so a farther distance is outside
//! what a policy learned (CHANGELOG.md, "Design notes", has the measurements).
//! Values are raw SI numbers here; the policy network normalises them.

use crate::config::{Config, ScenarioKind};
use crate::engine::rollout::Actor;
use crate::num::Num;
use crate::world::drivers::{Driver, driver_accel};
use crate::world::neighbors::Neighbors;
use crate::world::safety::Neighbor;
use crate::world::state::Scene;
use crate::world::step::neighbor_of;
use std::ops::Range;

/// Observation layout version of Table I, stored with policy files; a file of another version
/// is refused. Version 2 caps a present neighbour's distance at [`MISSING_DISTANCE`] (version 1
/// did not). `observation_of_version_2_is_pinned` fails when the features change: bump this
/// with them.
pub const OBS_LAYOUT_VERSION: u32 = 2;
/// Observation layout version of merge traffic ([`Layout::Traffic`]).
pub const TRAFFIC_LAYOUT_VERSION: u32 = 4;
/// Number of features before the one-hot agent index.
pub const N_FEATURES: usize = 9;
/// Number of features of the traffic layout: Table I's nine, the same-lane leader's three and
/// the desired speed.
pub const N_TRAFFIC_FEATURES: usize = 13;
/// Distance reported for a missing neighbour, and the largest reported for a present one (m).
pub const MISSING_DISTANCE: f64 = 100.0;

/// What a policy observes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// Table I: nine features and the one-hot index over `players` players (the paper's
    /// world, version [`OBS_LAYOUT_VERSION`]).
    Table1 {
        /// Number of players `N`.
        players: usize,
    },
    /// Merge traffic (version [`TRAFFIC_LAYOUT_VERSION`]): Table I's nine features, then the
    /// nearest vehicle ahead in the same lane (distance `x_LL - x`, relative speed, flag; as
    /// features 2-4, capped the same way). A ramp vehicle sees the ramp vehicle it queues
    /// behind, a target-lane vehicle the one it follows. Then the scene's desired speed `v_d`
    /// (m/s, [`Scene::desired_speed`]): the road's speed, so one policy drives roads of any
    /// speed limit (version 4; version 3 had no `v_d`). No agent index: any number of
    /// vehicles play, each a player of every ego it meets.
    Traffic,
}

impl Layout {
    /// The layout of a configuration's world (`scenario.kind`).
    pub fn of(config: &Config) -> Self {
        match config.scenario.kind {
            ScenarioKind::Paper => Layout::Table1 {
                players: config.n_agents(),
            },
            ScenarioKind::Traffic => Layout::Traffic,
        }
    }

    /// Version stored with policy files.
    pub fn version(self) -> u32 {
        match self {
            Layout::Table1 { .. } => OBS_LAYOUT_VERSION,
            Layout::Traffic => TRAFFIC_LAYOUT_VERSION,
        }
    }

    /// Number of features before the agent index.
    pub fn features(self) -> usize {
        match self {
            Layout::Table1 { .. } => N_FEATURES,
            Layout::Traffic => N_TRAFFIC_FEATURES,
        }
    }

    /// Length of the one-hot agent index.
    pub fn one_hot(self) -> usize {
        match self {
            Layout::Table1 { players } => players,
            Layout::Traffic => 0,
        }
    }

    /// Observation width.
    pub fn dim(self) -> usize {
        self.features() + self.one_hot()
    }
}

/// Observation width of a configuration's world.
pub fn obs_dim(config: &Config) -> usize {
    Layout::of(config).dim()
}

/// The nine Table I features of a player at `(x, v)`, over any [`Num`].
pub fn features<T: Num>(
    x_c: f64,
    x: &T,
    v: &T,
    on_ramp: &T,
    leader: &Neighbor<T>,
    follower: &Neighbor<T>,
) -> [T; N_FEATURES] {
    let missing = x.full(MISSING_DISTANCE);
    let zero = x.full(0.0);
    let [ld, lv, lp] = ahead_features(x, v, leader);
    [
        x.mul_c(-1.0).add_c(x_c),
        v.mul_c(1.0),
        ld,
        lv,
        lp,
        T::select(&follower.present, &x.sub(&follower.x).min(&missing), &missing),
        T::select(&follower.present, &follower.v.sub(v), &zero),
        follower.present.mul_c(1.0),
        on_ramp.mul_c(1.0),
    ]
}

/// Distance (capped at [`MISSING_DISTANCE`]), relative speed and flag of a neighbour ahead.
pub fn ahead_features<T: Num>(x: &T, v: &T, ahead: &Neighbor<T>) -> [T; 3] {
    let missing = x.full(MISSING_DISTANCE);
    [
        T::select(&ahead.present, &ahead.x.sub(x).min(&missing), &missing),
        T::select(&ahead.present, &ahead.v.sub(v), &x.full(0.0)),
        ahead.present.mul_c(1.0),
    ]
}

/// Where a world's observations are taken: its conflict point and the desired speed of
/// scenes without their own (the configuration's `reward.v_desired`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// Conflict point `x_c` (m).
    pub x_c: f64,
    /// Desired speed of a scene without its own (m/s).
    pub v_desired: f64,
}

impl Frame {
    /// The frame of a configuration's world.
    pub fn of(config: &Config) -> Self {
        Frame {
            x_c: config.scenario.conflict_point,
            v_desired: config.reward.v_desired,
        }
    }
}

/// Writes the observation of player `i` of `scene` into `out` (length [`Layout::dim`]).
pub fn observe(layout: Layout, frame: Frame, scene: &Scene, i: usize, nb: &Neighbors, out: &mut [f32]) {
    observe_as(layout, frame, scene, i, i, nb, out);
}

/// As [`observe`], with the one-hot agent index `agent` instead of `i`: for scenes that hold
/// fewer than `N` players (SUMO traffic, naturalistic data), where vehicle `i` of the scene
/// plays the role of player `agent` (the traffic layout has no index).
pub fn observe_as(
    layout: Layout,
    frame: Frame,
    scene: &Scene,
    i: usize,
    agent: usize,
    nb: &Neighbors,
    out: &mut [f32],
) {
    let me = &scene.vehicles[i];
    let f = features(
        frame.x_c,
        &me.x,
        &me.v,
        &if me.on_ramp { 1.0 } else { 0.0 },
        &neighbor_of(scene, nb.leader, me),
        &neighbor_of(scene, nb.follower, me),
    );
    for (o, v) in out.iter_mut().zip(f) {
        *o = v as f32;
    }
    if layout == Layout::Traffic {
        let lane = ahead_features(&me.x, &me.v, &neighbor_of(scene, nb.lane_leader, me));
        for (o, v) in out[N_FEATURES..].iter_mut().zip(lane) {
            *o = v as f32;
        }
        out[N_FEATURES + 3] = scene.desired_speed(frame.v_desired) as f32;
    }
    let features = layout.features();
    for (k, o) in out[features..].iter_mut().enumerate() {
        *o = if k == agent { 1.0 } else { 0.0 };
    }
}

/// A policy evaluated on many observations at once (one row per controlled player).
pub trait BatchPolicy: Send {
    /// Writes one action (m/s^2) per row of `obs` (`rows x obs_dim`, row-major) into `out`.
    fn act(&mut self, obs: &[f32], rows: usize, out: &mut [f32]);
}

/// `u = g tanh(w . o + b)`: a fixed linear policy, used as a stand-in for a trained network
/// (demo, benchmarks).
#[derive(Debug, Clone, PartialEq)]
pub struct LinearPolicy {
    /// Weights, one per observation entry.
    pub weights: Vec<f32>,
    /// Bias.
    pub bias: f32,
    /// Action scale `g` (m/s^2).
    pub scale: f32,
}

impl LinearPolicy {
    /// Tracks `v_desired` and backs off from a close leader:
    /// `u = g tanh(0.1 (v_d - v) + 0.05 (d_L - 20) + 0.2 dv_L)` (d_L capped by the missing
    /// distance).
    pub fn speed_keeping(config: &Config) -> Self {
        let mut weights = vec![0.0; obs_dim(config)];
        weights[1] = -0.1;
        weights[2] = 0.05;
        weights[3] = 0.2;
        LinearPolicy {
            weights,
            bias: (0.1 * config.reward.v_desired - 0.05 * 20.0) as f32,
            scale: config.vehicle.max_accel as f32,
        }
    }
}

impl BatchPolicy for LinearPolicy {
    fn act(&mut self, obs: &[f32], rows: usize, out: &mut [f32]) {
        let dim = self.weights.len();
        for (r, o) in out.iter_mut().enumerate().take(rows) {
            let row = &obs[r * dim..(r + 1) * dim];
            let z: f32 = row.iter().zip(&self.weights).map(|(a, b)| a * b).sum::<f32>() + self.bias;
            *o = self.scale * z.tanh();
        }
    }
}

/// The ego (and optionally every player) driven by a batched policy, the rest by a
/// non-learning driver.
pub struct PolicyActor<P: BatchPolicy> {
    policy: P,
    config: Config,
    /// Driver of the players the policy does not drive.
    pub others: Driver,
    /// True: the policy drives every player (parameter sharing); false: the ego only.
    pub all_players: bool,
    /// A second policy for every player but the ego (for example the ego on a single-agent
    /// policy among players on the shared MPG policy); replaces `others`.
    others_policy: Option<P>,
    obs: Vec<f32>,
    act: Vec<f32>,
    act_others: Vec<f32>,
}

impl<P: BatchPolicy> PolicyActor<P> {
    /// A policy actor.
    pub fn new(config: &Config, policy: P, others: Driver, all_players: bool) -> Self {
        PolicyActor {
            policy,
            config: config.clone(),
            others,
            all_players,
            others_policy: None,
            obs: Vec::new(),
            act: Vec::new(),
            act_others: Vec::new(),
        }
    }

    /// The ego on `policy`, every other player on `others`.
    pub fn with_others_policy(config: &Config, policy: P, others: P) -> Self {
        PolicyActor {
            others_policy: Some(others),
            ..Self::new(config, policy, Driver::Idm, true)
        }
    }
}

impl<P: BatchPolicy> PolicyActor<P> {
    /// The observations of players `players` of every scene into `self.obs`, scene by scene.
    fn observe_players(&mut self, scenes: &[Scene], neighbors: &[Neighbors], players: Range<usize>) {
        let n = self.config.n_agents();
        let layout = Layout::of(&self.config);
        let (dim, frame) = (layout.dim(), Frame::of(&self.config));
        self.obs.resize(scenes.len() * players.len() * dim, 0.0);
        let mut rows = self.obs.chunks_exact_mut(dim);
        for (b, scene) in scenes.iter().enumerate() {
            for i in players.clone() {
                let row = rows.next().expect("a row per player");
                observe(layout, frame, scene, i, &neighbors[b * n + i], row);
            }
        }
    }
}

impl<P: BatchPolicy> Actor for PolicyActor<P> {
    fn learning(&self, i: usize) -> bool {
        i == 0 || self.all_players || self.others_policy.is_some()
    }

    fn act(&mut self, _step: usize, scenes: &[Scene], neighbors: &[Neighbors], out: &mut [f64]) {
        let n = self.config.n_agents();
        // The players `policy` drives in each scene (0..per_scene); a second policy drives the
        // rest, each network on its own players' rows only.
        let per_scene = if self.all_players && self.others_policy.is_none() {
            n
        } else {
            1
        };
        let rows = scenes.len() * per_scene;
        self.observe_players(scenes, neighbors, 0..per_scene);
        self.act.resize(rows, 0.0);
        self.policy.act(&self.obs, rows, &mut self.act);
        if self.others_policy.is_some() {
            let rows = scenes.len() * (n - 1);
            self.observe_players(scenes, neighbors, 1..n);
            self.act_others.resize(rows, 0.0);
            let others = self.others_policy.as_mut().expect("checked above");
            others.act(&self.obs, rows, &mut self.act_others);
        }
        for (b, scene) in scenes.iter().enumerate() {
            for i in 0..n {
                // A human's raw action is replaced by the rollout (IDM).
                out[b * n + i] = if i < per_scene {
                    f64::from(self.act[b * per_scene + i])
                } else if self.others_policy.is_some() {
                    f64::from(self.act_others[b * (n - 1) + i - 1])
                } else {
                    driver_accel(&self.config, self.others, scene, i, &neighbors[b * n + i])
                };
            }
        }
    }
}

/// The features of every player of a tensor batch, one `[batch, agents]` array each, from
/// the same [`features`] as [`observe`] (differentiable in the states). The one-hot agent
/// index of the Table I layout is not among them: it is each element's column
/// ([`observation_rows`]).
pub fn tensor_features(
    layout: Layout,
    frame: Frame,
    batch: &crate::engine::tensor::TensorBatch,
    nb: &crate::engine::tensor::NeighborIndex,
) -> Vec<crate::engine::tape::Var> {
    use crate::engine::tensor::Which;
    let mut f: Vec<_> = features(
        frame.x_c,
        &batch.x,
        &batch.v,
        &batch.on_ramp,
        &nb.get(batch, Which::Leader),
        &nb.get(batch, Which::Follower),
    )
    .into();
    if layout == Layout::Traffic {
        f.extend(ahead_features(
            &batch.x,
            &batch.v,
            &nb.get(batch, Which::LaneLeader),
        ));
        f.push(match batch.per_scene(|d| d.unwrap_or(frame.v_desired)) {
            Some(v_d) => batch.x.full(0.0).add(&v_d),
            None => batch.x.full(frame.v_desired),
        });
    }
    f
}

/// The observation rows (`[rows * cols, layout.dim()]`, row-major) of `features` (each
/// `[rows, cols]`, as [`tensor_features`] gives them or a selection of their columns): an
/// element's features, then for the Table I layout the one-hot index of its column.
pub fn observation_rows(layout: Layout, features: &[crate::engine::tape::Var]) -> Vec<f32> {
    let (elements, cols, dim) = (features[0].values().len(), features[0].cols(), layout.dim());
    let mut out = vec![0.0f32; elements * dim];
    for (k, row) in out.chunks_mut(dim).enumerate() {
        for (slot, f) in row.iter_mut().zip(features) {
            *slot = f.values()[k] as f32;
        }
        if layout.one_hot() > 0 {
            row[layout.features() + k % cols] = 1.0;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::neighbors::find_neighbors;
    use crate::world::state::Vehicle;

    use crate::world::state::test_car as car;

    /// x_c = 180 m, v_d = 15 m/s.
    fn frame() -> Frame {
        Frame {
            x_c: 180.0,
            v_desired: 15.0,
        }
    }

    /// Every vehicle's observation of a scene of three (x_c = 180 m).
    fn observations(vehicles: Vec<Vehicle>) -> Vec<Vec<f32>> {
        let scene = Scene::new(vehicles);
        let (mut order, mut nb) = (Vec::new(), Vec::new());
        find_neighbors(&scene, &mut order, &mut nb);
        (0..scene.len())
            .map(|i| {
                let layout = Layout::Table1 { players: 3 };
                let mut out = vec![0.0f32; layout.dim()];
                observe(layout, frame(), &scene, i, &nb[i], &mut out);
                out
            })
            .collect()
    }

    #[test]
    fn observation_of_version_2_is_pinned() {
        // Hand-computed Table I observations of a scene with a near and a far neighbour, a
        // missing one, both lanes, and the network's input scales. A change here changes
        // what a trained policy sees: bump OBS_LAYOUT_VERSION and update this test.
        assert_eq!(OBS_LAYOUT_VERSION, 2);
        assert_eq!((N_FEATURES, MISSING_DISTANCE), (9, 100.0));
        let rows = observations(vec![
            car(150.0, 10.0, true),
            car(170.0, 12.0, false),
            car(20.0, 14.0, false),
        ]);
        let expected: [[f32; 12]; 3] = [
            // ego on the ramp: leader 20 m ahead at +2 m/s, follower 130 m back (capped).
            [30.0, 10.0, 20.0, 2.0, 1.0, 100.0, 4.0, 1.0, 1.0, 1.0, 0.0, 0.0],
            // front car: no leader, the ego 20 m behind at -2 m/s.
            [10.0, 12.0, 100.0, 0.0, 0.0, 20.0, -2.0, 1.0, 0.0, 0.0, 1.0, 0.0],
            // rear car: the ego 130 m ahead (capped) at -4 m/s, no follower.
            [160.0, 14.0, 100.0, -4.0, 1.0, 100.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        ];
        for (row, e) in rows.iter().zip(expected) {
            assert_eq!(row.as_slice(), e.as_slice());
        }
        assert_eq!(
            crate::policy::network::OBS_SCALE,
            [0.01, 1.0 / 30.0, 0.01, 0.1, 1.0, 0.01, 0.1, 1.0, 1.0]
        );
    }

    #[test]
    fn traffic_observation_of_version_4_is_pinned() {
        // A queue on the ramp (ego at 150 m behind a ramp car at 165 m) beside a target-lane
        // car at 160 m: the nearest leader is the target-lane car, the same-lane leader the
        // ramp car. Then the scene's desired speed: the frame's 15 m/s, or the scene's own
        // 25 m/s. No agent index. A change here changes what a traffic policy sees: bump
        // TRAFFIC_LAYOUT_VERSION and update this test.
        assert_eq!((TRAFFIC_LAYOUT_VERSION, N_TRAFFIC_FEATURES), (4, 13));
        let mut scene = Scene::new(vec![
            car(150.0, 10.0, true),
            car(165.0, 8.0, true),
            car(160.0, 13.0, false),
        ]);
        let (mut order, mut nb) = (Vec::new(), Vec::new());
        find_neighbors(&scene, &mut order, &mut nb);
        let layout = Layout::Traffic;
        let observe_all = |scene: &Scene| {
            let mut rows = vec![vec![0.0f32; layout.dim()]; 3];
            for (i, row) in rows.iter_mut().enumerate() {
                observe(layout, frame(), scene, i, &nb[i], row);
            }
            rows
        };
        let expected: [[f32; 13]; 3] = [
            [
                30.0, 10.0, 10.0, 3.0, 1.0, 100.0, 0.0, 0.0, 1.0, 15.0, -2.0, 1.0, 15.0,
            ],
            // the ramp car: no leader at all, the target-lane car 5 m behind.
            [
                15.0, 8.0, 100.0, 0.0, 0.0, 5.0, 5.0, 1.0, 1.0, 100.0, 0.0, 0.0, 15.0,
            ],
            // the target-lane car: the ramp car 5 m ahead (any lane), none in its lane.
            [
                20.0, 13.0, 5.0, -5.0, 1.0, 10.0, -3.0, 1.0, 0.0, 100.0, 0.0, 0.0, 15.0,
            ],
        ];
        for (row, e) in observe_all(&scene).iter().zip(expected) {
            assert_eq!(row.as_slice(), e.as_slice());
        }
        scene.v_desired = Some(25.0);
        for (row, e) in observe_all(&scene).iter().zip(expected) {
            assert_eq!(row[..12], e[..12]);
            assert_eq!(row[12], 25.0);
        }
        assert_eq!(
            crate::policy::network::TRAFFIC_SCALE,
            [0.01, 0.1, 1.0, 1.0 / 30.0]
        );
    }

    #[test]
    fn neighbours_beyond_the_missing_distance_read_as_that_far() {
        // A stopped ramp ego at 179.9 m, its nearest player ahead 250 m away at 13 m/s and
        // one 40 m behind at 12 m/s: the leader reads 100 m away, still present, with its
        // relative speed.
        let rows = observations(vec![
            car(179.9, 0.0, true),
            car(429.9, 13.0, false),
            car(139.9, 12.0, false),
        ]);
        let out = &rows[0];
        let expected = [0.1, 0.0, 100.0, 13.0, 1.0, 40.0, 12.0, 1.0, 1.0, 1.0, 0.0, 0.0];
        for (k, (o, e)) in out.iter().zip(expected).enumerate() {
            assert!((f64::from(*o) - e).abs() < 1e-4, "feature {k}: {o} != {e}");
        }
        // The follower sees the ego 40 m ahead; the far leader sees the ego 250 m behind as
        // 100 m, and no leader of its own.
        assert_eq!(&rows[1][2..8], &[100.0, 0.0, 0.0, 100.0, -13.0, 1.0]);
    }
}
