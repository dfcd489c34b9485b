//! The rollout over `[batch, agents]` tensors, differentiable for training.
//!
//! It runs the same generic equations as the scalar engine ([`crate::engine::rollout`]): eq. (1),
//! the feasibility projection, IDM and the reward terms come from the same functions. The
//! discrete parts carry no gradient and are computed once, on detached values, by the scalar
//! code: who is whose neighbour ([`find_neighbors`]) and which boxes overlap
//! ([`first_collision`]). `tests/tensor.rs` checks that both engines agree.

use crate::config::Config;
use crate::game::reward::{speed_weight, tail_weight};
use crate::game::terms;
use crate::num::Num;
use crate::world::dynamics::{Kinematics, bicycle_step};
use crate::world::idm::{idm_accel, idm_v0};
use crate::world::merge_gate::{gate_holds, stop_bound};
use crate::world::neighbors::find_neighbors;
use crate::world::rules::WorldRules;
use crate::world::safety::{Neighbor, clip_action, feasible_interval, project_feasible};
use crate::world::state::{Scene, Vehicle};
use crate::world::step::first_collision;
use tch::{Kind, Tensor};

/// States of a batch of scenarios, each field `[batch, agents]`.
#[derive(Debug)]
pub struct TensorBatch {
    /// Longitudinal positions (m).
    pub x: Tensor,
    /// Lateral positions (m).
    pub y: Tensor,
    /// Speeds (m/s).
    pub v: Tensor,
    /// Headings (rad).
    pub phi: Tensor,
    /// 1.0 on the ramp, 0.0 in the target lane (no gradient).
    pub on_ramp: Tensor,
    /// 1.0 where a human (IDM) drives the vehicle (merge traffic), else 0.0.
    pub human: Tensor,
    /// Each scene's human flags (as [`Scene::humans`]).
    humans: Vec<Vec<bool>>,
    /// Each scene's own desired speed (as [`Scene::v_desired`]).
    own_desired: Vec<Option<f64>>,
    /// The same states as plain scenes, without gradient: the discrete work (neighbours,
    /// merge gate, collisions) reads them, copied out of the tensors once per step.
    detached: Vec<Scene>,
}

fn to_vec(t: &Tensor) -> Vec<f64> {
    Vec::<f64>::try_from(t.detach().to_kind(Kind::Double).flatten(0, -1)).expect("a CPU tensor")
}

impl TensorBatch {
    /// Tensors of `kind` (f32 for training, f64 where exactness is checked) from scenes.
    pub fn from_scenes(scenes: &[Scene], kind: Kind) -> Self {
        let (b, n) = (scenes.len() as i64, scenes[0].len() as i64);
        let field = |f: fn(&Vehicle) -> f64| {
            let data: Vec<f64> = scenes.iter().flat_map(|s| s.vehicles.iter().map(f)).collect();
            Tensor::from_slice(&data).reshape([b, n]).to_kind(kind)
        };
        TensorBatch {
            x: field(|v| v.x),
            y: field(|v| v.y),
            v: field(|v| v.v),
            phi: field(|v| v.phi),
            on_ramp: field(|v| if v.on_ramp { 1.0 } else { 0.0 }),
            human: human_mask(scenes, kind),
            humans: scenes.iter().map(|s| s.humans.clone()).collect(),
            own_desired: scenes.iter().map(|s| s.v_desired).collect(),
            detached: scenes.to_vec(),
        }
    }

    /// `[batch, 1]`: `f` of each scene's own desired speed ([`Scene::v_desired`]), when any
    /// scene has one; none: every scene keeps the configuration's values.
    pub fn per_scene(&self, f: impl Fn(Option<f64>) -> f64) -> Option<Tensor> {
        self.own_desired.iter().any(Option::is_some).then(|| {
            let data: Vec<f64> = self.own_desired.iter().map(|&d| f(d)).collect();
            Tensor::from_slice(&data)
                .reshape([data.len() as i64, 1])
                .to_kind(self.x.kind())
        })
    }

    /// The next state of `self`: these tensors, the same drivers (the scenes are copied out
    /// of them).
    fn next(&self, x: Tensor, y: Tensor, v: Tensor, phi: Tensor, on_ramp: Tensor) -> Self {
        let mut batch = TensorBatch {
            x,
            y,
            v,
            phi,
            on_ramp,
            human: self.human.shallow_clone(),
            humans: self.humans.clone(),
            own_desired: self.own_desired.clone(),
            detached: Vec::new(),
        };
        batch.detached = batch.copy_scenes();
        batch
    }

    /// The detached states as scenes.
    pub fn scenes(&self) -> &[Scene] {
        &self.detached
    }

    fn copy_scenes(&self) -> Vec<Scene> {
        let n = self.x.size()[1] as usize;
        let (x, y, v, phi, r) = (
            to_vec(&self.x),
            to_vec(&self.y),
            to_vec(&self.v),
            to_vec(&self.phi),
            to_vec(&self.on_ramp),
        );
        (0..x.len() / n)
            .map(|b| Scene {
                vehicles: (b * n..(b + 1) * n)
                    .map(|k| Vehicle {
                        x: x[k],
                        y: y[k],
                        v: v[k],
                        phi: phi[k],
                        on_ramp: r[k] > 0.5,
                    })
                    .collect(),
                humans: self.humans[b].clone(),
                v_desired: self.own_desired[b],
            })
            .collect()
    }
}

/// `[batch, agents]`: 1.0 where a human drives the vehicle.
fn human_mask(scenes: &[Scene], kind: Kind) -> Tensor {
    let n = scenes[0].len();
    let data: Vec<f64> = scenes
        .iter()
        .flat_map(|s| (0..n).map(move |i| f64::from(u8::from(s.is_human(i)))))
        .collect();
    Tensor::from_slice(&data)
        .reshape([scenes.len() as i64, n as i64])
        .to_kind(kind)
}

/// Neighbour indices as `[batch, agents]` tensors (a missing neighbour points at the player
/// itself, with presence 0, as the scalar engine's [`crate::world::step::neighbor_of`] does).
#[derive(Debug)]
pub struct NeighborIndex {
    index: [Tensor; 4],
    present: [Tensor; 4],
}

/// Which neighbour: the four notions of [`crate::world::neighbors::Neighbors`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Which {
    /// Nearest ahead, any lane.
    Leader = 0,
    /// Nearest behind, any lane.
    Follower = 1,
    /// Nearest ahead, same lane.
    LaneLeader = 2,
    /// Nearest behind, same lane.
    LaneFollower = 3,
}

impl NeighborIndex {
    /// Neighbours of the batch's current (detached) state.
    pub fn of(batch: &TensorBatch) -> Self {
        let scenes = batch.scenes();
        let n = scenes[0].len();
        let mut idx = vec![vec![0i64; scenes.len() * n]; 4];
        let mut present = vec![vec![0f64; scenes.len() * n]; 4];
        let (mut order, mut nb) = (Vec::new(), Vec::new());
        for (b, scene) in scenes.iter().enumerate() {
            find_neighbors(scene, &mut order, &mut nb);
            for (i, w) in nb.iter().enumerate() {
                for (k, who) in [w.leader, w.follower, w.lane_leader, w.lane_follower]
                    .into_iter()
                    .enumerate()
                {
                    idx[k][b * n + i] = who.unwrap_or(i) as i64;
                    present[k][b * n + i] = if who.is_some() { 1.0 } else { 0.0 };
                }
            }
        }
        let shape = [scenes.len() as i64, n as i64];
        let kind = batch.x.kind();
        NeighborIndex {
            index: std::array::from_fn(|k| Tensor::from_slice(&idx[k]).reshape(shape)),
            present: std::array::from_fn(|k| Tensor::from_slice(&present[k]).reshape(shape).to_kind(kind)),
        }
    }

    /// The chosen neighbour's position, speed and presence, gathered from the batch.
    pub fn get(&self, batch: &TensorBatch, which: Which) -> Neighbor<Tensor> {
        let k = which as usize;
        Neighbor {
            x: batch.x.gather(1, &self.index[k], false),
            v: batch.v.gather(1, &self.index[k], false),
            present: self.present[k].shallow_clone(),
        }
    }
}

/// IDM accelerations of every player (behind the same-lane leader; on the ramp also behind
/// the nearest leader, whichever asks for less, as [`crate::world::drivers::driver_accel`]).
pub fn idm_actions(config: &Config, batch: &TensorBatch, nb: &NeighborIndex) -> Tensor {
    let v0 = batch.per_scene(|d| idm_v0(config, d));
    let behind = |leader: &Neighbor<Tensor>| {
        idm_accel(
            &batch.x,
            &batch.v,
            leader,
            config.vehicle.length,
            &config.idm,
            v0.as_ref(),
        )
    };
    let lane = behind(&nb.get(batch, Which::LaneLeader));
    let nearest = behind(&nb.get(batch, Which::Leader));
    <Tensor as Num>::select(&batch.on_ramp, &Num::min(&lane, &nearest), &lane)
}

/// Which players a policy drives in a tensor rollout.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Learning {
    /// Every player (the shared policy).
    All,
    /// The ego only (the others on a non-learning driver).
    Ego,
}

/// Applied actions: feasibility projection towards same-lane neighbours and the merge gate for
/// ramp players (when `feasibility`; with `only`, for the players where it is 1), then
/// `[-g, g]` and the speed bounds.
pub fn apply_limits(
    rules: &WorldRules,
    batch: &TensorBatch,
    nb: &NeighborIndex,
    raw: &Tensor,
    feasibility: bool,
    only: Option<&Tensor>,
) -> Tensor {
    let dt = rules.dt;
    let a = if feasibility {
        let lead = nb.get(batch, Which::LaneLeader);
        let follow = nb.get(batch, Which::LaneFollower);
        let (lo, hi) = feasible_interval(
            &batch.x,
            &batch.v,
            &lead,
            &follow,
            rules.clearance(),
            dt,
            rules.tau_s,
        );
        let lane = project_feasible(raw, &lo, &hi);
        if rules.merge_gate || batch.humans.iter().flatten().any(|&h| h) {
            merge_gate(rules, batch, &lane)
        } else {
            lane
        }
    } else {
        raw.shallow_clone()
    };
    let a = match only {
        Some(mask) if feasibility => <Tensor as Num>::select(mask, &a, raw),
        _ => a,
    };
    clip_action(&a, &batch.v, rules.max_accel, rules.v_min, rules.v_max, dt)
}

/// The merge gate on `a`: ramp players it holds get `min(a, stop bound)` (every player with
/// `sim.merge_gate`, else the human drivers only).
fn merge_gate(rules: &WorldRules, batch: &TensorBatch, a: &Tensor) -> Tensor {
    let closed: Vec<f64> = batch
        .scenes()
        .iter()
        .flat_map(|s| {
            (0..s.len()).map(move |i| {
                let gated = rules.merge_gate || s.is_human(i);
                f64::from(u8::from(gated && gate_holds(s, i, &rules.gate)))
            })
        })
        .collect();
    let closed = Tensor::from_slice(&closed)
        .reshape(batch.x.size())
        .to_kind(batch.x.kind());
    let bound = stop_bound(&batch.x, &batch.v, &rules.gate);
    <Tensor as Num>::select(&closed, &Num::min(a, &bound), a)
}

/// The unordered player pairs `i < j` of `n` players, as index tensors, and which pairs each
/// player belongs to: the pair terms are symmetric (Theorem 2), so each is computed once.
#[derive(Debug)]
pub struct Pairs {
    first: Tensor,
    second: Tensor,
    /// `[pairs, n]`: 1 where the pair holds the player.
    incidence: Tensor,
}

impl Pairs {
    /// The pairs of `n` players, `kind` for the incidence matrix.
    pub fn new(n: usize, kind: Kind) -> Self {
        let pairs: Vec<(i64, i64)> = (0..n as i64)
            .flat_map(|i| (i + 1..n as i64).map(move |j| (i, j)))
            .collect();
        let mut incidence = vec![0.0f64; pairs.len() * n];
        for (p, &(i, j)) in pairs.iter().enumerate() {
            incidence[p * n + i as usize] = 1.0;
            incidence[p * n + j as usize] = 1.0;
        }
        let index = |f: fn(&(i64, i64)) -> i64| Tensor::from_slice(&pairs.iter().map(f).collect::<Vec<_>>());
        Pairs {
            first: index(|p| p.0),
            second: index(|p| p.1),
            incidence: Tensor::from_slice(&incidence)
                .reshape([pairs.len() as i64, n as i64])
                .to_kind(kind),
        }
    }
}

/// Rewards `r_i` (`[batch, agents]`) and potential `phi` (`[batch]`) of the paper's reward.
pub fn rewards(config: &Config, pairs: &Pairs, batch: &TensorBatch, u: &Tensor) -> (Tensor, Tensor) {
    let r = &config.reward;
    let x_c = config.scenario.conflict_point;
    // A scene's own desired speed comes with its weight factor (`speed_weight`).
    let v_d = batch.per_scene(|d| d.unwrap_or(r.v_desired));
    let weight = batch.per_scene(|d| r.w_speed * d.map_or(1.0, |d| speed_weight(r.v_desired, d)));
    let speed = match (v_d, weight) {
        (Some(v_d), Some(weight)) => terms::speed_tracking_towards(&batch.v, &v_d) * weight,
        _ => terms::speed_tracking(&batch.v, r.v_desired) * r.w_speed,
    };
    let own = speed + terms::comfort(u) * r.w_comfort;
    let ends = |t: &Tensor| (t.index_select(1, &pairs.first), t.index_select(1, &pairs.second));
    let ((xi, xj), (vi, vj), (ri, rj)) = (ends(&batch.x), ends(&batch.v), ends(&batch.on_ramp));
    let same_lane: Tensor = 1.0 - (ri - rj).abs();
    let ttc = terms::same_lane_ttc(&xi, &vi, &xj, &vj, r.v_c, r.epsilon) * r.w_ttc;
    let gap = terms::conflict_time_gap(&xi, &vi, &xj, &vj, x_c, r.epsilon) * r.w_conflict;
    let pair: Tensor = &same_lane * ttc + (1.0 - &same_lane) * gap;
    let reward = &own + pair.matmul(&pairs.incidence);
    // Humans are no players: the potential holds the players' own terms and every pair with
    // at least one player (Theorem 3 over the players; a human's terms are not in any
    // player's reward).
    let (hi, hj) = ends(&batch.human);
    let player = 1.0 - &batch.human;
    let both_human: Tensor = hi * hj;
    let own_players: Tensor = own * player;
    let pairs_with_a_player: Tensor = pair * (1.0 - both_human);
    let potential =
        own_players.sum_dim_intlist(1, false, None) + pairs_with_a_player.sum_dim_intlist(1, false, None);
    (reward, potential)
}

/// Eq. (1) with zero steering, then the merge: a ramp player reaching `x_c`, or merging early
/// ([`WorldRules::merges_early`], on the scenes as they were this step), joins the target
/// lane.
pub fn advance(rules: &WorldRules, batch: &TensorBatch, u: &Tensor) -> TensorBatch {
    let k = Kinematics {
        x: batch.x.shallow_clone(),
        y: batch.y.shallow_clone(),
        v: batch.v.shallow_clone(),
        phi: batch.phi.shallow_clone(),
    };
    let next = bicycle_step(&k, u, &u.zeros_like(), rules.axles, rules.dt);
    let before_conflict = Num::gt(&next.x.full(rules.conflict_point()), &next.x);
    let mut on_ramp = &batch.on_ramp * before_conflict;
    if rules.road.merge_zone > 0.0 {
        let stays: Vec<f64> = batch
            .scenes()
            .iter()
            .flat_map(|s| (0..s.len()).map(move |i| f64::from(u8::from(!rules.merges_early(s, i)))))
            .collect();
        on_ramp *= Tensor::from_slice(&stays)
            .reshape(batch.x.size())
            .to_kind(batch.x.kind());
    }
    batch.next(
        next.x,
        on_ramp.mul_c(-rules.road.lane_width),
        next.v,
        next.phi,
        on_ramp,
    )
}

/// Discounted returns `[batch, agents]` and potential returns `[batch]` of a rollout.
#[derive(Debug)]
pub struct TensorReturns {
    /// `J_i` per scenario and player.
    pub returns: Tensor,
    /// `sum_t gamma^t phi` per scenario.
    pub potential: Tensor,
}

/// What a tensor rollout runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TensorRun {
    /// Tensors' kind (f32 for training, f64 where exactness is checked).
    pub kind: Kind,
    /// Number of steps.
    pub steps: usize,
    /// Apply the feasibility rules (projection and gate).
    pub feasibility: bool,
    /// Stop counting an episode's rewards after its first collision.
    pub terminate_on_collision: bool,
    /// Which players a policy drives.
    pub learning: Learning,
}

/// Runs `run.steps` steps; `act` gives the raw actions of every player from the state and its
/// neighbours. An episode stops counting rewards after its first collision when
/// `terminate_on_collision` (charging the collision step's rewards for the remaining steps
/// with `sim.absorbing_collision`, as the scalar engine does).
// `a = a + b` on purpose: tch's `+=` is an in-place op, which autograd handles less freely.
#[allow(clippy::assign_op_pattern)]
pub fn rollout(
    config: &Config,
    scenes: &[Scene],
    run: &TensorRun,
    mut act: impl FnMut(&TensorBatch, &NeighborIndex, usize) -> Tensor,
) -> TensorReturns {
    let TensorRun {
        kind,
        steps,
        feasibility,
        terminate_on_collision,
        learning,
    } = *run;
    let mut batch = TensorBatch::from_scenes(scenes, kind);
    let (b, n) = (scenes.len() as i64, scenes[0].len() as i64);
    let mut returns = Tensor::zeros([b, n], (kind, tch::Device::Cpu));
    let mut potential = Tensor::zeros([b], (kind, tch::Device::Cpu));
    let mut alive = vec![1.0f64; scenes.len()];
    let mut discount = 1.0;
    let pairs = Pairs::new(scenes[0].len(), kind);
    let rules = WorldRules::new(config);
    let any_human = scenes.iter().any(|s| s.humans.contains(&true));
    // With `sim.project_non_learning` off, the feasibility rules apply to the learning players
    // alone: not to humans, and to the ego alone when only the ego learns.
    let only = (!config.sim.project_non_learning).then(|| {
        let learner = 1.0 - &batch.human;
        match learning {
            Learning::All => learner,
            Learning::Ego => {
                let ego =
                    Tensor::zeros([n], (kind, tch::Device::Cpu)).index_fill(0, &Tensor::from(0i64), 1.0);
                learner * ego.unsqueeze(0).expand([b, n], false)
            }
        }
    });
    for step in 0..steps {
        let nb = NeighborIndex::of(&batch);
        let mut raw = act(&batch, &nb, step);
        if any_human {
            let idm = idm_actions(config, &batch, &nb).to_kind(raw.kind());
            raw = <Tensor as Num>::select(&batch.human.to_kind(raw.kind()), &idm, &raw);
        }
        let u = apply_limits(&rules, &batch, &nb, &raw, feasibility, only.as_ref());
        let (r, phi) = rewards(config, &pairs, &batch, &u);
        let live = Tensor::from_slice(&alive).to_kind(kind);
        returns = returns + &r * live.unsqueeze(1) * discount;
        potential = potential + &phi * &live * discount;
        batch = advance(&rules, &batch, &u);
        if terminate_on_collision {
            let mut crashed = vec![0.0f64; alive.len()];
            for ((a, c), scene) in alive.iter_mut().zip(&mut crashed).zip(batch.scenes()) {
                if *a > 0.0 && first_collision(scene, rules.length, rules.width).is_some() {
                    (*a, *c) = (0.0, 1.0);
                }
            }
            if config.sim.absorbing_collision && crashed.contains(&1.0) {
                let tail =
                    Tensor::from_slice(&crashed).to_kind(kind) * tail_weight(config.sim.gamma, step, steps);
                returns = returns + &r * tail.unsqueeze(1);
                potential = potential + &phi * tail;
            }
        }
        discount *= config.sim.gamma;
    }
    TensorReturns { returns, potential }
}
