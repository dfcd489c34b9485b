//! The merge gate: the feasible set of a ramp vehicle (ours; the paper defines feasible sets
//! for target-lane vehicles only).
//!
//! A ramp vehicle joins the target lane the moment its `x` reaches `x_c`, so a crawl across
//! `x_c` beside a passing car is an immediate overlap that no target-lane projection can undo
//! (most ego collisions of early trained policies were such slow entries; CHANGELOG.md,
//! "Design notes"). The gate extends Section
//! V-ii's feasibility to the ramp: an action is feasible for a ramp vehicle when the vehicle
//! can still stop before `x_c` braking at up to `g`, unless entering is safe. With an
//! acceleration lane (`scenario.accel_lane`) the ramp, and so the stop line, ends that far past
//! `x_c`; "`x_c`" below then reads as the lane's end.
//!
//! **Safe entry** ([`entry_is_safe`]): the gate only binds at the last step the vehicle can
//! still stop, so what it must make safe is the crossing of a vehicle that commits now. That
//! crossing comes at the earliest two steps ahead (the first step an action can move it
//! across) and at the latest when, having just passed the fastest speed `v_stop` from which it
//! could still stop, it brakes at `g`: `2 dt + v_stop / g` (at most `tau_s`). A stopped
//! vehicle at its stop line thus needs the gap of one entry, not a gap lasting `tau_s` (which
//! held egos far longer than SUMO's own drivers wait). At each of these times, with every vehicle at its current speed, its
//! target-lane leader and follower at entry must both have a gap
//! `|x_i - x_j| - clearance` above zero and a closing speed that braking at `b_safe` absorbs
//! within that gap (MOBIL's safety criterion, Kesting, Treiber and Helbing 2007: the new
//! follower must not need to brake harder than `b_safe`; and symmetrically the merging
//! vehicle behind its new leader).
//!
//! **Lane change** ([`lane_change_is_safe`]): inside the merge zone (`scenario.merge_zone`,
//! SUMO's `merge_from`) a ramp vehicle changes lanes at once, as SUMO's drivers do along an
//! acceleration lane, so there is no later crossing to predict: the check is the entry's one
//! step ahead, and it also asks the feasibility projection's time to collision, `tau_s`, of
//! both new pairs, so that a merge never starts inside what the projection would then have to
//! undo (and SUMO's safety measures count as a conflict, TTC < 3 s). Checking up to `tau_s`
//! ahead as at the stop line held egos slower than the target lane until the gap they had
//! drifted past.
//!
//! **Entry rule** (`scenario.entry = "gap"`, [`lane_end_holds`]): part of the world's
//! physics, not a shield, and the same in training, `eval`, `check-mpg` and SUMO. A ramp
//! vehicle enters the target lane only where the lane change above holds and, on top of it,
//! both new gaps are at least a human driver's [`secure_gap`]: the new follower goes on at its
//! speed for its reaction time (`sim.reaction_time`, SUMO's `tau`) before braking at `b_safe`
//! and still stops behind the entering vehicle should that brake at `b_safe` at once (Krauss's
//! safe speed, which SUMO's drivers keep and their lane changes ask for), and the entering
//! vehicle keeps the same gap to its new leader. The ramp ends where it ends: a vehicle
//! without such a gap is held by the stopping bound below at the ramp's end (`x_c`, or the
//! acceleration lane's end) and waits there, as SUMO's drivers wait at the end of an
//! acceleration lane or at a stop line; nothing forces an entry. A vehicle that starts too
//! fast to stop there (an initial state only) brakes at `g` and joins where it ends up.
//!
//! **Stopping bound** ([`stop_bound`]): after this step the vehicle is at `x' = x + v dt`
//! (eq. 1 moves `x` with the current speed) with speed `v' = v + a dt`; from there it stops
//! before `x_s = x_c - 0.1 m` braking at `b` when `v'^2 / (2 b) + v' dt <= x_s - x'`, that is
//! `v' <= -b dt + sqrt((b dt)^2 + 2 b (x_s - x'))`. The bound on `a` follows; the applied
//! action is `min(a, bound)`, then clipped to `[-g, g]` as every action is. The merge gate
//! brakes at `b = g`, and so does the entry rule's lane end unless `sim.lane_end_brake` says
//! otherwise ([`lane_end_bound`]): at `g` a held vehicle may run on to the last metres, and
//! SUMO's driver behind one that did closed in at a time to collision below 1.5 s
//! (`i80_merge`, the game at 30% of the vehicles, demand 1.2); at `b_safe` it stops as a human
//! driver does, but egos then entered slower, and more of them in an SSM conflict, in SUMO
//! (docs/experiments.md, "Where a held ramp vehicle stops"). A vehicle whose
//! bound is below `-g` can no longer stop: it is committed, and the gate lets it go
//! ([`gate_holds`]), because braking would only bring it in slower in front of the same
//! follower. The decision
//! (safe or not) is discrete and carries no gradient; the bound is differentiable in `x` and `v`.

use crate::config::{Config, Entry};
use crate::num::Num;
use crate::world::state::Scene;

/// How far before `x_c` a held vehicle stops (m): the bound only approaches its stop line,
/// so a line at `x_c` itself would be reached by rounding.
pub const STOP_MARGIN: f64 = 0.1;

/// What the gate needs from the configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GateRules {
    /// The stop line's reference: where the ramp ends, `x_c` plus the acceleration lane (m).
    pub conflict_point: f64,
    /// Gap subtracted from centre distances: vehicle length plus the safety gap (m).
    pub clearance: f64,
    /// Largest braking an entry may ask of the new follower or the merging vehicle (m/s^2).
    pub b_safe: f64,
    /// Upper end of the entry-time prediction (s): `tau_s`.
    pub horizon: f64,
    /// Hardest braking the stopping bound may use (m/s^2): the action bound `g`.
    pub brake: f64,
    /// Braking of the entry rule's stop at the lane's end ([`lane_end_bound`], m/s^2):
    /// `sim.lane_end_brake`, `brake` when unset.
    pub lane_end_brake: f64,
    /// Time step (s).
    pub dt: f64,
    /// With the entry rule (`scenario.entry = "gap"`): the human follower's reaction time
    /// (s), and the gaps are judged as a human driver's secure gap (module docs, "Entry
    /// rule"). None: MOBIL's closing-speed criterion.
    pub reaction_time: Option<f64>,
}

impl GateRules {
    /// The configuration's rules.
    pub fn new(config: &Config) -> Self {
        GateRules {
            conflict_point: config.scenario.conflict_point + config.scenario.accel_lane,
            clearance: config.vehicle.length + config.sim.safety_gap,
            b_safe: config.sim.b_safe,
            horizon: config.sim.tau_s,
            brake: config.vehicle.max_accel,
            lane_end_brake: config.sim.lane_end_brake.unwrap_or(config.vehicle.max_accel),
            dt: config.sim.dt,
            reaction_time: (config.scenario.entry == Entry::Gap).then_some(config.sim.reaction_time),
        }
    }
}

/// Whether the gate holds ramp vehicle `i` of `scene`: it is on the ramp, entering is not
/// safe, and it can still stop before the line braking at up to `rules.brake` (past that point
/// it is committed and goes on as its driver says: braking would only bring it in slower, in
/// front of the same follower).
pub fn gate_holds(scene: &Scene, i: usize, rules: &GateRules) -> bool {
    let me = &scene.vehicles[i];
    me.on_ramp && stop_bound(&me.x, &me.v, rules) >= -rules.brake && !entry_is_safe(scene, i, rules)
}

/// Whether a gap of `gap` (m) absorbs a closing speed `closing` (m/s) braking at `b` (m/s^2),
/// with a time to collision `gap / closing` of at least `min_ttc` (s).
fn absorbs(gap: f64, closing: f64, b: f64, min_ttc: f64) -> bool {
    gap > 0.0 && (closing <= 0.0 || (closing * closing <= 2.0 * b * gap && gap >= min_ttc * closing))
}

/// Whether ramp vehicle `i` of `scene` may enter the target lane (module docs). Vehicles
/// still on the ramp do not count as target-lane neighbours.
pub fn entry_is_safe(scene: &Scene, i: usize, rules: &GateRules) -> bool {
    let me = &scene.vehicles[i];
    let v_stop = (me.v + stop_bound(&me.x, &me.v, rules) * rules.dt).max(0.0);
    let t_latest = 2.0 * rules.dt + v_stop / rules.brake;
    let last = (t_latest.min(rules.horizon) / rules.dt).ceil().max(2.0) as usize;
    (2..=last).all(|k| safe_at(scene, i, k as f64 * rules.dt, 0.0, rules))
}

/// Whether ramp vehicle `i` of `scene` may change to the target lane this step, as it does
/// inside the merge zone (module docs, "Lane change"): after the step, every vehicle keeping
/// its speed, both new gaps absorb their closing speeds braking at `b_safe` with a time to
/// collision of at least `tau_s` (`rules.horizon`).
pub fn lane_change_is_safe(scene: &Scene, i: usize, rules: &GateRules) -> bool {
    safe_at(scene, i, rules.dt, rules.horizon, rules)
}

/// Whether vehicle `i`, entering at `t` with its current speed, finds gaps that absorb the
/// closing speeds with a time to collision of at least `min_ttc` (every target-lane vehicle
/// keeping its speed until then); with the entry rule (`rules.reaction_time`), gaps of at least
/// a human driver's secure gap behind and ahead of it too (module docs, "Entry rule"). Gaps are
/// bumper gaps whatever the vehicles' lengths ([`Scene::excess`]).
fn safe_at(scene: &Scene, i: usize, t: f64, min_ttc: f64, rules: &GateRules) -> bool {
    let me = &scene.vehicles[i];
    let x_e = me.x + me.v * t;
    let mut leader: Option<(f64, f64)> = None;
    let mut follower: Option<(f64, f64)> = None;
    for (j, v) in scene.vehicles.iter().enumerate().filter(|(_, v)| !v.on_ramp) {
        let x = v.x + v.v * t;
        let excess = scene.excess(i) + scene.excess(j);
        if x > x_e {
            if leader.is_none_or(|(lx, _)| x - excess < lx) {
                leader = Some((x - excess, v.v));
            }
        } else if follower.is_none_or(|(fx, _)| x + excess > fx) {
            follower = Some((x + excess, v.v));
        }
    }
    // The gap a driver at `v_back` keeps behind one at `v_front` (none without the rule).
    let secure = |v_back: f64, v_front: f64| {
        rules
            .reaction_time
            .map_or(0.0, |t_r| secure_gap(v_back, v_front, t_r, rules.b_safe))
    };
    let ahead_ok = leader.is_none_or(|(x, v)| {
        let gap = x - x_e - rules.clearance;
        absorbs(gap, me.v - v, rules.b_safe, min_ttc) && gap >= secure(me.v, v)
    });
    let behind_ok = follower.is_none_or(|(x, v)| {
        let gap = x_e - x - rules.clearance;
        absorbs(gap, v - me.v, rules.b_safe, min_ttc) && gap >= secure(v, me.v)
    });
    ahead_ok && behind_ok
}

/// A human driver's secure gap (m) behind a leader, as SUMO's Krauss model and its lane
/// changes keep it: driving at `v_back`, it goes on for its reaction time `t_r` before braking
/// at `b`, and still stops behind a leader at `v_front` that brakes at `b` now.
pub fn secure_gap(v_back: f64, v_front: f64, t_r: f64, b: f64) -> f64 {
    (v_back * t_r + (v_back * v_back - v_front * v_front) / (2.0 * b)).max(0.0)
}

/// Whether the ramp's end holds ramp vehicle `i` of `scene` under the entry rule
/// (`scenario.entry = "gap"`, module docs): it is on the ramp and may not enter the target
/// lane now ([`lane_change_is_safe`]). Held, its action is at most [`lane_end_bound`]: the
/// lane ends there, for the policy as for a human driver.
pub fn lane_end_holds(scene: &Scene, i: usize, rules: &GateRules) -> bool {
    rules.reaction_time.is_some() && scene.vehicles[i].on_ramp && !lane_change_is_safe(scene, i, rules)
}

/// The entry rule's bound on a ramp vehicle the ramp's end holds ([`lane_end_holds`]): the
/// largest action that still stops it [`STOP_MARGIN`] before the end braking at
/// `rules.lane_end_brake` (`sim.lane_end_brake`; `g` by default, the latest stop the road
/// allows), and harder (up to `g`, the action's own bound) only when it must (module docs,
/// "Stopping bound").
pub fn lane_end_bound<T: Num>(x: &T, v: &T, rules: &GateRules) -> T {
    stop_bound(
        x,
        v,
        &GateRules {
            brake: rules.lane_end_brake,
            ..*rules
        },
    )
}

/// The largest action that leaves a vehicle at `(x, v)` able to stop [`STOP_MARGIN`] before
/// `x_c` braking at `rules.brake` (module docs). Past that line after this step nothing can
/// stop the entry and the bound is `(0 - v) / dt`, full braking.
pub fn stop_bound<T: Num>(x: &T, v: &T, rules: &GateRules) -> T {
    let (brake, dt) = (rules.brake, rules.dt);
    let room = x
        .add(&v.mul_c(dt))
        .neg()
        .add_c(rules.conflict_point - STOP_MARGIN)
        .max(&x.full(0.0));
    let v_next = room
        .mul_c(2.0 * brake)
        .add_c((brake * dt).powi(2))
        .sqrt()
        .add_c(-brake * dt);
    v_next.sub(v).mul_c(1.0 / dt)
}
