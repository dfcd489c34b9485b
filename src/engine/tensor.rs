//! The rollout over `[batch, agents]` arrays ([`Var`]), differentiable for training.
//!
//! It runs the same generic equations as the scalar engine ([`crate::engine::rollout`]): eq. (1),
//! the feasibility projection, IDM and the reward terms come from the same functions. The
//! discrete parts carry no gradient and are computed once, on detached values, by the scalar
//! code: who is whose neighbour ([`find_neighbors`]) and which boxes overlap
//! ([`first_collision_among`]). `tests/tensor.rs` checks that both engines agree, and that the
//! gradients match finite differences.

use crate::config::Config;
use crate::engine::tape::Var;
use crate::game::reward::{speed_weight, tail_weight};
use crate::game::terms;
use crate::num::Num;
use crate::world::drivers::{make_room_bound, makes_room, player_makes_room_for, yield_length, yields_to};
use crate::world::dynamics::{Kinematics, zero_steering_step};
use crate::world::geometry::Road;
use crate::world::idm::{idm_accel, idm_v0};
use crate::world::merge_gate::{gate_holds, lane_end_bound, lane_end_holds, stop_bound};
use crate::world::neighbors::find_neighbors;
use crate::world::rules::WorldRules;
use crate::world::safety::{Neighbor, clip_action, feasible_interval_after, project_feasible, share_bounds};
use crate::world::state::{Scene, Vehicle};
use crate::world::step::first_collision_among;
use std::rc::Rc;

/// States of a batch of scenarios, each field `[batch, agents]`.
#[derive(Debug)]
pub struct TensorBatch {
    /// Longitudinal positions (m).
    pub x: Var,
    /// Lateral positions (m).
    pub y: Var,
    /// Speeds (m/s).
    pub v: Var,
    /// Headings (rad).
    pub phi: Var,
    /// 1.0 on the ramp, 0.0 in the target lane (no gradient).
    pub on_ramp: Var,
    /// 1.0 where a human (IDM) drives the vehicle (merge traffic), else 0.0.
    pub human: Var,
    /// Each scene's human flags (as [`Scene::humans`]).
    humans: Vec<Vec<bool>>,
    /// Each scene's yielding flags (as [`Scene::yields`]).
    yields: Vec<Vec<bool>>,
    /// Each scene's own desired speed (as [`Scene::v_desired`]).
    own_desired: Vec<Option<f64>>,
    /// The same states as plain scenes, without gradient: the discrete work (neighbours,
    /// merge gate, collisions) reads them, copied out of the arrays once per step.
    detached: Vec<Scene>,
}

impl TensorBatch {
    /// Arrays (constants) of the scenes' states.
    pub fn from_scenes(scenes: &[Scene]) -> Self {
        let (b, n) = (scenes.len(), scenes[0].len());
        let field = |f: fn(&Vehicle) -> f64| {
            Var::constant(
                scenes.iter().flat_map(|s| s.vehicles.iter().map(f)).collect(),
                b,
                n,
            )
        };
        TensorBatch {
            x: field(|v| v.x),
            y: field(|v| v.y),
            v: field(|v| v.v),
            phi: field(|v| v.phi),
            on_ramp: field(|v| if v.on_ramp { 1.0 } else { 0.0 }),
            human: human_mask(scenes),
            humans: scenes.iter().map(|s| s.humans.clone()).collect(),
            yields: scenes.iter().map(|s| s.yields.clone()).collect(),
            own_desired: scenes.iter().map(|s| s.v_desired).collect(),
            detached: scenes.to_vec(),
        }
    }

    /// `[batch, 1]`: `f` of each scene's own desired speed ([`Scene::v_desired`]), when any
    /// scene has one; none: every scene keeps the configuration's values.
    pub fn per_scene(&self, f: impl Fn(Option<f64>) -> f64) -> Option<Var> {
        self.own_desired.iter().any(Option::is_some).then(|| {
            let data: Vec<f64> = self.own_desired.iter().map(|&d| f(d)).collect();
            let rows = data.len();
            Var::constant(data, rows, 1)
        })
    }

    /// The next state of `self`: these arrays, the same drivers (the scenes are copied out
    /// of them).
    fn next(&self, x: Var, y: Var, v: Var, phi: Var, on_ramp: Var) -> Self {
        let mut batch = TensorBatch {
            x,
            y,
            v,
            phi,
            on_ramp,
            human: self.human.clone(),
            humans: self.humans.clone(),
            yields: self.yields.clone(),
            own_desired: self.own_desired.clone(),
            detached: Vec::new(),
        };
        batch.detached = batch.copy_scenes();
        batch
    }

    /// The same states as constants: work on it records nothing on the tape.
    fn without_gradient(&self) -> Self {
        TensorBatch {
            x: self.x.detach(),
            y: self.y.detach(),
            v: self.v.detach(),
            phi: self.phi.detach(),
            on_ramp: self.on_ramp.detach(),
            human: self.human.detach(),
            humans: self.humans.clone(),
            yields: self.yields.clone(),
            own_desired: self.own_desired.clone(),
            detached: self.detached.clone(),
        }
    }

    /// Whether a human drives any vehicle of the batch.
    pub fn any_human(&self) -> bool {
        self.humans.iter().flatten().any(|&h| h)
    }

    /// The detached states as scenes.
    pub fn scenes(&self) -> &[Scene] {
        &self.detached
    }

    fn copy_scenes(&self) -> Vec<Scene> {
        let n = self.x.cols();
        let (x, y, v, phi, r) = (
            self.x.values(),
            self.y.values(),
            self.v.values(),
            self.phi.values(),
            self.on_ramp.values(),
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
                yields: self.yields[b].clone(),
                gives_way: Vec::new(),
                zips: Vec::new(),
                excess: Vec::new(),
                v_desired: self.own_desired[b],
            })
            .collect()
    }
}

/// `[batch, agents]`: 1.0 where a human drives the vehicle.
fn human_mask(scenes: &[Scene]) -> Var {
    let n = scenes[0].len();
    let data: Vec<f64> = scenes
        .iter()
        .flat_map(|s| (0..n).map(move |i| f64::from(u8::from(s.is_human(i)))))
        .collect();
    Var::constant(data, scenes.len(), n)
}

/// Neighbour indices of each `[batch, agents]` element (a missing neighbour points at the
/// player itself, with presence 0, as the scalar engine's
/// [`crate::world::step::neighbor_of`] does).
#[derive(Debug)]
pub struct NeighborIndex {
    index: [Rc<[usize]>; 4],
    present: [Var; 4],
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
        let mut idx = vec![vec![0usize; scenes.len() * n]; 4];
        let mut present = vec![vec![0f64; scenes.len() * n]; 4];
        let (mut order, mut nb) = (Vec::new(), Vec::new());
        for (b, scene) in scenes.iter().enumerate() {
            find_neighbors(scene, &mut order, &mut nb);
            for (i, w) in nb.iter().enumerate() {
                for (k, who) in [w.leader, w.follower, w.lane_leader, w.lane_follower]
                    .into_iter()
                    .enumerate()
                {
                    idx[k][b * n + i] = who.unwrap_or(i);
                    present[k][b * n + i] = if who.is_some() { 1.0 } else { 0.0 };
                }
            }
        }
        let mut idx = idx.into_iter();
        let mut present = present.into_iter();
        NeighborIndex {
            index: std::array::from_fn(|_| idx.next().expect("four").into()),
            present: std::array::from_fn(|_| Var::constant(present.next().expect("four"), scenes.len(), n)),
        }
    }

    /// The nearest leader (any lane) of element `k` (`b * agents + i`), if any.
    pub fn leader(&self, k: usize) -> Option<usize> {
        let w = Which::Leader as usize;
        (self.present[w].values()[k] > 0.5).then(|| self.index[w][k])
    }

    /// The chosen neighbour's position, speed and presence, gathered from the batch.
    pub fn get(&self, batch: &TensorBatch, which: Which) -> Neighbor<Var> {
        let k = which as usize;
        Neighbor {
            x: batch.x.gather_cols(&self.index[k]),
            v: batch.v.gather_cols(&self.index[k]),
            present: self.present[k].clone(),
        }
    }
}

/// IDM accelerations of every player (behind the same-lane leader; on the ramp also behind
/// the nearest leader, whichever asks for less, as [`crate::world::drivers::driver_accel`]).
pub fn idm_actions(config: &Config, batch: &TensorBatch, nb: &NeighborIndex) -> Var {
    let v0 = batch.per_scene(|d| idm_v0(config, d));
    let behind = |leader: &Neighbor<Var>, length: f64| {
        idm_accel(&batch.x, &batch.v, leader, length, &config.idm, v0.as_ref())
    };
    let lane = behind(&nb.get(batch, Which::LaneLeader), config.vehicle.length);
    let leader = nb.get(batch, Which::Leader);
    let nearest = behind(&leader, config.vehicle.length);
    let lane = match yielding_mask(config, batch, nb) {
        Some(mask) => {
            let room = behind(&leader, yield_length(config));
            let yields: Vec<f64> = (mask.iter().zip(room.values()))
                .map(|(&m, &r)| f64::from(u8::from(m && makes_room(r, config.sim.b_safe))))
                .collect();
            let yields = Var::constant(yields, room.rows(), room.cols());
            Var::select(&yields, &lane.min(&room), &lane)
        }
        None => lane,
    };
    Var::select(&batch.on_ramp, &lane.min(&nearest), &lane)
}

/// `[batch, agents]`, row-major: where a human target-lane driver may make room for its
/// nearest leader ([`yields_to`]); None when no driver of the batch ever yields.
fn yielding_mask(config: &Config, batch: &TensorBatch, nb: &NeighborIndex) -> Option<Vec<bool>> {
    if !batch.yields.iter().flatten().any(|&y| y) {
        return None;
    }
    let road = Road::new(config);
    let n = batch.x.cols();
    let mut mask = Vec::with_capacity(batch.x.rows() * n);
    for (b, scene) in batch.scenes().iter().enumerate() {
        mask.extend((0..n).map(|i| yields_to(&road, scene, i, nb.leader(b * n + i)).is_some()));
    }
    Some(mask)
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
/// `[-g, g]` and the speed bounds. In the sequential order ([`WorldRules::sequential`]) each
/// leader bound reads the leader's settled next speed: pass `k` settles every player with `k`
/// lane leaders ahead of it, so at most one pass per player, and the passes stop when one
/// changes nothing (then none would). The same actions as the scalar engine's front-to-back
/// order ([`crate::world::neighbors::front_to_back`]).
///
/// The passes run on values only; one recorded pass then reads the leaders' settled actions
/// as constants. Its values are the settled ones (the fixed point passes once more), and its
/// gradient takes the paths of the simultaneous order: through every player's own action and
/// the states, not from a follower's bound into its leader's action. Recording every pass
/// took over twice the training's memory (merge traffic: beyond 18 GB against 8.6 GB).
pub fn apply_limits(
    rules: &WorldRules,
    batch: &TensorBatch,
    nb: &NeighborIndex,
    raw: &Var,
    feasibility: bool,
    only: Option<&Var>,
) -> Var {
    if !(rules.sequential() && feasibility) {
        return limits_once(rules, batch, nb, raw, feasibility, only, None);
    }
    let leaders = &nb.index[Which::LaneLeader as usize];
    let leader_next = |v: &Var, a: &Var| v.add(&a.mul_c(rules.dt)).gather_cols(leaders);
    let values = batch.without_gradient();
    let (raw_values, only_values) = (raw.detach(), only.map(Var::detach));
    let settle = |leader_next: Option<&Var>| {
        limits_once(
            rules,
            &values,
            nb,
            &raw_values,
            feasibility,
            only_values.as_ref(),
            leader_next,
        )
    };
    let mut a = settle(None);
    for _ in 1..batch.x.cols() {
        let settled = settle(Some(&leader_next(&values.v, &a)));
        let unchanged = settled.values() == a.values();
        a = settled;
        if unchanged {
            break;
        }
    }
    let next = leader_next(&batch.v, &a);
    limits_once(rules, batch, nb, raw, feasibility, only, Some(&next))
}

/// One pass of [`apply_limits`], the lane leaders' next speeds given (`leader_next`) or their
/// current speeds.
fn limits_once(
    rules: &WorldRules,
    batch: &TensorBatch,
    nb: &NeighborIndex,
    raw: &Var,
    feasibility: bool,
    only: Option<&Var>,
    leader_next: Option<&Var>,
) -> Var {
    let dt = rules.dt;
    let a = if feasibility {
        let lead = nb.get(batch, Which::LaneLeader);
        let follow = nb.get(batch, Which::LaneFollower);
        let next = leader_next.unwrap_or(&lead.v);
        let (lo, hi) = feasible_interval_after(&batch.x, &batch.v, &lead, next, &follow, &rules.projection());
        let (lo, hi) = if rules.shared() {
            // A neighbour is projected where it is present and (with `only`) where `only` is 1.
            let projected = |which: Which, n: &Neighbor<Var>| match only {
                Some(mask) => mask.gather_cols(&nb.index[which as usize]).mul(&n.present),
                None => n.present.clone(),
            };
            let (f, l) = (
                projected(Which::LaneFollower, &follow),
                projected(Which::LaneLeader, &lead),
            );
            share_bounds(&lo, &hi, [&f, &l], rules.shared_correction)
        } else {
            (lo, hi)
        };
        let (lo, hi) = if rules.feasibility_across_lanes {
            across_lanes(rules, batch, nb, lo, hi)
        } else {
            (lo, hi)
        };
        let lane = project_feasible(raw, &lo, &hi);
        let lane = if rules.players_make_room {
            make_room(rules, batch, &lane)
        } else {
            lane
        };
        if rules.merge_gate || batch.any_human() {
            merge_gate(rules, batch, &lane)
        } else {
            lane
        }
    } else {
        raw.clone()
    };
    let a = match only {
        Some(mask) if feasibility => Var::select(mask, &a, raw),
        _ => a,
    };
    let a = if rules.gate.reaction_time.is_some() {
        hold_at_lane_end(rules, batch, &a)
    } else {
        a
    };
    clip_action(&a, &batch.v, rules.max_accel, rules.v_min, rules.v_max, dt)
}

/// `sim.feasibility_across_lanes` on the interval `(lo, hi)`: for a target-lane vehicle, also
/// the projection's bounds towards its nearest leader and follower where those are on the ramp
/// (as [`crate::world::step::applied_action_with`]).
fn across_lanes(rules: &WorldRules, batch: &TensorBatch, nb: &NeighborIndex, lo: Var, hi: Var) -> (Var, Var) {
    let in_lane = batch.on_ramp.neg().add_c(1.0);
    let ramp = |which: Which| {
        let n = nb.get(batch, which);
        let on_ramp = batch.on_ramp.gather_cols(&nb.index[which as usize]);
        Neighbor {
            present: n.present.mul(&on_ramp).mul(&in_lane),
            ..n
        }
    };
    let (lead, follow) = (ramp(Which::Leader), ramp(Which::Follower));
    let (ramp_lo, ramp_hi) =
        feasible_interval_after(&batch.x, &batch.v, &lead, &lead.v, &follow, &rules.projection());
    (lo.max(&ramp_lo), hi.min(&ramp_hi))
}

/// `sim.players_make_room` on `a`: a player that makes room for the first ramp vehicle ahead of
/// it in the yield zone ([`player_makes_room_for`]) gets `min(a, room)`, `room` being
/// [`crate::world::drivers::Room`]'s bound behind that vehicle, when braking at `sim.b_safe` or
/// less reaches the gap it asks (as
/// [`crate::world::step::applied_action_with`]).
fn make_room(rules: &WorldRules, batch: &TensorBatch, a: &Var) -> Var {
    let (rows, n) = (batch.x.rows(), batch.x.cols());
    let (mut mask, mut index) = (Vec::with_capacity(rows * n), Vec::with_capacity(rows * n));
    for scene in batch.scenes().iter() {
        for i in 0..n {
            let j = player_makes_room_for(&rules.road, scene, i);
            mask.push(j.is_some());
            index.push(j.unwrap_or(i));
        }
    }
    if !mask.contains(&true) {
        return a.clone();
    }
    let index: std::rc::Rc<[usize]> = index.into();
    let ramp = Neighbor {
        x: batch.x.gather_cols(&index),
        v: batch.v.gather_cols(&index),
        present: Var::constant(mask.iter().map(|&m| f64::from(u8::from(m))).collect(), rows, n),
    };
    let room = make_room_bound(&batch.x, &batch.v, &ramp, rules);
    let chosen = (mask.iter().zip(room.reach.values()))
        .map(|(&m, &r)| f64::from(u8::from(m && makes_room(r, rules.gate.b_safe))))
        .collect();
    Var::select(&Var::constant(chosen, rows, n), &a.min(&room.bound), a)
}

/// The merge gate on `a`: ramp players it holds get `min(a, stop bound)` (every player with
/// `sim.merge_gate`, else the human drivers only).
fn merge_gate(rules: &WorldRules, batch: &TensorBatch, a: &Var) -> Var {
    let bound = stop_bound(&batch.x, &batch.v, &rules.gate);
    held_at(batch, a, &bound, |s, i| {
        (rules.merge_gate || s.is_human(i)) && gate_holds(s, i, &rules.gate)
    })
}

/// The entry rule's lane end on `a`: ramp players it holds
/// ([`crate::world::merge_gate::lane_end_holds`]) get `min(a, lane end bound)`, every player.
fn hold_at_lane_end(rules: &WorldRules, batch: &TensorBatch, a: &Var) -> Var {
    let bound = lane_end_bound(&batch.x, &batch.v, &rules.gate);
    held_at(batch, a, &bound, |s, i| lane_end_holds(s, i, &rules.gate))
}

/// `min(a, bound)` for the players `holds` names in their scene, `a` for the others.
fn held_at(batch: &TensorBatch, a: &Var, bound: &Var, holds: impl Fn(&Scene, usize) -> bool) -> Var {
    let held: Vec<f64> = batch
        .scenes()
        .iter()
        .flat_map(|s| (0..s.len()).map(|i| f64::from(u8::from(holds(s, i)))))
        .collect();
    let held = Var::constant(held, batch.x.rows(), batch.x.cols());
    Var::select(&held, &a.min(bound), a)
}

/// The unordered player pairs `i < j` of `n` players: the pair terms are symmetric
/// (Theorem 2), so each is computed once.
#[derive(Debug)]
pub struct Pairs {
    n: usize,
    both: Rc<[(usize, usize)]>,
}

impl Pairs {
    /// The pairs of `n` players.
    pub fn new(n: usize) -> Self {
        Pairs {
            n,
            both: (0..n).flat_map(|i| (i + 1..n).map(move |j| (i, j))).collect(),
        }
    }

    /// `[rows, pairs]`: `f` of the two ends' values of a `[rows, n]` array (no gradient).
    fn of_ends(&self, t: &Var, f: impl Fn(f64, f64) -> f64) -> Vec<f64> {
        let f = &f;
        t.values()
            .chunks(self.n)
            .flat_map(|row| self.both.iter().map(move |&(i, j)| f(row[i], row[j])))
            .collect()
    }
}

/// Rewards `r_i` (`[batch, agents]`) and potential `phi` (`[batch, 1]`) of the paper's reward,
/// each when `sums` asks for it.
pub fn rewards(
    config: &Config,
    pairs: &Pairs,
    batch: &TensorBatch,
    u: &Var,
    sums: Sums,
) -> (Option<Var>, Option<Var>) {
    let r = &config.reward;
    let x_c = config.scenario.conflict_point;
    // A scene's own desired speed comes with its weight factor (`speed_weight`).
    let v_d = batch.per_scene(|d| d.unwrap_or(r.v_desired));
    // Each vehicle's weight by its lane (`w_speed_ramp` on the ramp): one per-scene factor
    // times the lane's weight; with one weight for both lanes, the weight per scene.
    let w_ramp = r.speed_weight_on_ramp();
    let (w, lanes) = if w_ramp == r.w_speed {
        (r.w_speed, None)
    } else {
        (
            1.0,
            Some(batch.on_ramp.mul_c(w_ramp - r.w_speed).add_c(r.w_speed)),
        )
    };
    let weight = batch.per_scene(|d| w * d.map_or(1.0, |d| speed_weight(r.v_desired, d)));
    let speed = match (v_d, weight) {
        (Some(v_d), Some(weight)) => terms::speed_tracking_towards(&batch.v, &v_d).mul(&weight),
        _ => terms::speed_tracking(&batch.v, r.v_desired).mul_c(w),
    };
    let speed = match lanes {
        Some(lanes) => speed.mul(&lanes),
        None => speed,
    };
    let own = speed.add(&terms::comfort(u).mul_c(r.w_comfort));
    let same_lane = pairs.of_ends(&batch.on_ramp, |a, b| f64::from(u8::from(a == b)));
    let np = pairs.both.len();
    let conflict_form = r.conflict_form();
    // Each pair's term in one pass over the pairs (the generic terms on dual numbers).
    let pair = Var::pairwise(&batch.x, &batch.v, &pairs.both, |row, p, [xi, vi, xj, vj]| {
        if same_lane[row * np + p] > 0.5 {
            terms::same_lane_ttc(&xi, &vi, &xj, &vj, r.v_c, r.epsilon).mul_c(r.w_ttc)
        } else {
            terms::conflict_term(conflict_form, &xi, &vi, &xj, &vj, x_c, r.epsilon).mul_c(r.w_conflict)
        }
    });
    let reward = sums
        .returns()
        .then(|| own.add(&pair.pair_sums(&pairs.both, pairs.n)));
    if !sums.potential() {
        return (reward, None);
    }
    // Humans are no players: the potential holds the players' own terms and every pair with
    // at least one player (Theorem 3 over the players; a human's terms are not in any
    // player's reward). Without humans the masks are all ones and are left out (the same
    // values).
    let potential = if batch.any_human() {
        let player = batch.human.neg().add_c(1.0);
        let with_a_player = pairs.of_ends(&batch.human, |a, b| 1.0 - a * b);
        let pairs_with_a_player = pair.mul(&Var::constant(with_a_player, pair.rows(), np));
        own.mul(&player).sum_cols().add(&pairs_with_a_player.sum_cols())
    } else {
        own.sum_cols().add(&pair.sum_cols())
    };
    (reward, Some(potential))
}

/// Eq. (1) with zero steering, then the merge: a ramp player reaching the ramp's end, or merging early
/// ([`WorldRules::merges_early`], on the scenes as they were this step), joins the target
/// lane.
pub fn advance(rules: &WorldRules, batch: &TensorBatch, u: &Var) -> TensorBatch {
    let k = Kinematics {
        x: batch.x.clone(),
        y: batch.y.clone(),
        v: batch.v.clone(),
        phi: batch.phi.clone(),
    };
    let straight = batch.phi.values().iter().all(|&phi| phi == 0.0);
    let next = zero_steering_step(&k, u, straight, rules.axles, rules.dt);
    let ramp_end = rules.road.ramp_end();
    let scenes = batch.scenes();
    let on_ramp: Vec<f64> = batch
        .on_ramp
        .values()
        .iter()
        .zip(next.x.values())
        .enumerate()
        .map(|(k, (&ramp, &x))| {
            let (b, i) = (k / batch.x.cols(), k % batch.x.cols());
            let early = rules.merges_early(&scenes[b], i);
            f64::from(u8::from(ramp > 0.5 && ramp_end > x && !early))
        })
        .collect();
    let on_ramp = Var::constant(on_ramp, batch.x.rows(), batch.x.cols());
    batch.next(
        next.x,
        on_ramp.mul_c(-rules.road.lane_width),
        next.v,
        next.phi,
        on_ramp,
    )
}

/// Discounted returns `[batch, agents]` and potential returns `[batch, 1]` of a rollout, each
/// when its [`TensorRun::sums`] asked for it.
#[derive(Debug)]
pub struct TensorReturns {
    /// `J_i` per scenario and player.
    pub returns: Option<Var>,
    /// `sum_t gamma^t phi` per scenario.
    pub potential: Option<Var>,
}

/// Which discounted sums a tensor rollout computes. Training back-propagates one of them; the
/// other's operations would only lengthen the tape. A sum has the same values whichever else
/// is computed (`tests/tensor.rs`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sums {
    /// The players' returns and the potential.
    Both,
    /// The potential only (the MPG objective).
    Potential,
    /// The players' returns only (the single-agent objective).
    Returns,
}

impl Sums {
    fn returns(self) -> bool {
        self != Sums::Potential
    }

    fn potential(self) -> bool {
        self != Sums::Returns
    }
}

/// What a tensor rollout runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TensorRun {
    /// Number of steps.
    pub steps: usize,
    /// Apply the feasibility rules (projection and gate).
    pub feasibility: bool,
    /// Stop counting an episode's rewards after its first collision.
    pub terminate_on_collision: bool,
    /// Which players a policy drives.
    pub learning: Learning,
    /// Which discounted sums to compute.
    pub sums: Sums,
}

/// Runs `run.steps` steps (on this thread's tape, where they depend on a leaf or a
/// [`Var::recorded`] value); `act` gives the raw actions of every player from the state and
/// its neighbours. An episode stops counting rewards after its first collision when
/// `terminate_on_collision` (charging the collision step's rewards for the remaining steps
/// with `sim.absorbing_collision`, as the scalar engine does).
pub fn rollout(
    config: &Config,
    scenes: &[Scene],
    run: &TensorRun,
    mut act: impl FnMut(&TensorBatch, &NeighborIndex, usize) -> Var,
) -> TensorReturns {
    let TensorRun {
        steps,
        feasibility,
        terminate_on_collision,
        learning,
        sums,
    } = *run;
    let mut batch = TensorBatch::from_scenes(scenes);
    let (b, n) = (scenes.len(), scenes[0].len());
    let mut returns = sums.returns().then(|| Var::constant(vec![0.0; b * n], b, n));
    let mut potential = sums.potential().then(|| Var::constant(vec![0.0; b], b, 1));
    // Adds `weight` (`[batch, 1]`) times a step's value to a sum that is computed.
    let accumulate = |sum: &mut Option<Var>, value: &Option<Var>, weight: &Var| {
        if let (Some(s), Some(v)) = (sum.as_mut(), value) {
            *s = s.add(&v.mul(weight));
        }
    };
    let mut alive = vec![1.0f64; scenes.len()];
    let mut discount = 1.0;
    let pairs = Pairs::new(n);
    let rules = WorldRules::new(config);
    let any_human = batch.any_human();
    // With `sim.project_non_learning` off, the feasibility rules apply to the learning players
    // alone: not to humans, and to the ego alone when only the ego learns. A mask that holds
    // every player changes nothing and is left out (the same values, one operation less).
    let only = (!config.sim.project_non_learning)
        .then(|| {
            let learner = batch.human.neg().add_c(1.0);
            match learning {
                Learning::All => learner,
                Learning::Ego => {
                    let ego = (0..b * n).map(|k| f64::from(u8::from(k % n == 0))).collect();
                    learner.mul(&Var::constant(ego, b, n))
                }
            }
        })
        .filter(|mask| mask.values().iter().any(|&m| m < 0.5));
    for step in 0..steps {
        let nb = NeighborIndex::of(&batch);
        let mut raw = act(&batch, &nb, step);
        if any_human {
            raw = Var::select(&batch.human, &idm_actions(config, &batch, &nb), &raw);
        }
        let u = apply_limits(&rules, &batch, &nb, &raw, feasibility, only.as_ref());
        let (r, phi) = rewards(config, &pairs, &batch, &u, sums);
        let live = Var::constant(alive.iter().map(|a| a * discount).collect(), b, 1);
        accumulate(&mut returns, &r, &live);
        accumulate(&mut potential, &phi, &live);
        batch = advance(&rules, &batch, &u);
        if terminate_on_collision {
            let mut crashed = vec![0.0f64; alive.len()];
            for ((a, c), scene) in alive.iter_mut().zip(&mut crashed).zip(batch.scenes()) {
                // As the scalar engine: players that no policy drives (all but the ego when
                // only the ego learns) drive through each other.
                let counts = |a: usize, _| a == 0 || learning == Learning::All;
                if *a > 0.0 && first_collision_among(scene, rules.length, rules.width, counts).is_some() {
                    (*a, *c) = (0.0, 1.0);
                }
            }
            if config.sim.absorbing_collision && crashed.contains(&1.0) {
                let w = tail_weight(config.sim.gamma, step, steps);
                let tail = Var::constant(crashed.iter().map(|c| c * w).collect(), b, 1);
                accumulate(&mut returns, &r, &tail);
                accumulate(&mut potential, &phi, &tail);
            }
        }
        discount *= config.sim.gamma;
    }
    TensorReturns { returns, potential }
}
