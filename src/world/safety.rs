//! Time to collision and the feasibility projection of Section V-ii.
//!
//! The feasibility TTC uses the gap `d = |x_i - x_j| - clearance`, where the clearance is the
//! vehicle length plus `sim.safety_gap`. With the centre-to-centre distance, "TTC >= tau_s"
//! still lets a follower close to a centre distance near zero as its closing speed vanishes,
//! so the boxes overlap (measured: `tests/rollout.rs`,
//! `feasibility_holds_ttc_at_tau_behind_a_steady_leader`); with the bumper gap alone, the gap
//! shrinks by at most a factor `1 - dt / tau_s` per step but a platoon of players held at its
//! bounds settles bumper to bumper (about 0.05 m) and then touches, because every vehicle is
//! projected at once assuming its neighbours keep their speed. The safety gap keeps that
//! platoon `safety_gap` apart. The reward terms keep the paper's centre-to-centre `|x_i - x_j|`.
//!
//! **Both lanes.** The paper defines the feasible set for target-lane vehicles; ours applies the
//! same interval on the ramp, towards a vehicle's ramp leader and follower, so that a ramp queue
//! (merge traffic) keeps its TTC as the target lane does. A lone ramp vehicle (the paper's ego)
//! has no same-lane neighbour, so its interval is unbounded and nothing changes for it.
//!
//! **Feasible interval.** For a vehicle `i` with immediate same-lane leader `L` and
//! follower `F`, the action `a` is feasible when, one step later (neighbours keeping their
//! speed), `TTC(i, L) >= tau_s` and `TTC(F, i) >= tau_s`. Positions after one step do not
//! depend on `a` (eq. 1 moves `x` with the current speed), so each condition is a bound on the
//! next speed `v' = v + a dt`:
//!
//! ```text
//! d_L' = (x_L + v_L dt) - (x + v dt) - clearance    v' <= v_L + d_L' / tau_s   ->  a <= hi
//! d_F' = (x + v dt) - (x_F + v_F dt) - clearance    v' >= v_F - d_F' / tau_s   ->  a >= lo
//! ```
//!
//! With `sim.time_headway = h > 0` (ours; 0 in the paper's setting) each gap also loses `h`
//! times the pair's follower's speed: the vehicle's own next speed towards its leader,
//! `v' <= v_L + (d_L' - h v') / tau_s`, that is `v' <= (v_L + d_L' / tau_s) / (1 + h /
//! tau_s)`, and the follower's current speed, `d_F' - h v_F`, towards its follower. At equal
//! speeds a vehicle then settles `safety_gap + h v` behind its leader, the gap SUMO's and IDM's
//! car following keep, instead of `safety_gap` at any speed. (With the current speed in the
//! leader bound instead of the next, a vehicle held at it alternated its speed from step to
//! step: measured jerks of about 50 m/s^3 in the traffic study.)
//!
//! A missing neighbour gives no bound. The applied action is `min(max(a, lo), hi)`, then
//! clipped to `[-g, g]`, then to the speed bounds `[v_min, v_max]`.
//!
//! **Order** (`sim.projection_order`). Simultaneous (the paper's reading): every vehicle is
//! projected at once, each assuming its neighbours keep their speed. When a follower closes on
//! its leader, the leader's follower bound pushes it on and the follower's leader bound holds
//! it back, each by the whole closing speed: together they overshoot, the bounds come free,
//! the policies' actions close the gap again, and the pair alternates from step to step
//! (measured: the paper's scenario 1, ego and player 5 at about +2 / -0.5 m/s^2 every other
//! step for 20 s). Sequential (ours): front to back, each vehicle's leader bound reads its
//! leader's speed after this step, already settled ([`feasible_interval_after`]); the
//! closing speed is corrected once.
//! Shared (ours): at once, as the paper's, but where a leader and its follower are both
//! projected each takes a share `s` (`sim.shared_correction`) of what its bound asks beyond
//! keeping its speed ([`share_bounds`]). With `time_headway = 0` the leader's push `lo > 0` and
//! the follower's hold `hi = -lo` are the same closing speed seen from both ends, so at
//! `s = 0.5` the halves add up to it once, in one pass, which the training's gradient follows
//! exactly. Above 0.5 the pair overshoots: the excess becomes `1 - 2 s` times itself a step,
//! so it flips and decays (halving at 0.75); at 1 this is the simultaneous order's 2-cycle.
//!
//! **Empty interval** (`lo > hi`: no action keeps both TTCs): the leader bound wins. The
//! vehicle applies `hi`, the largest action that keeps its TTC to its leader (clipped to
//! `[-g, g]`, so at worst full braking), and the follower, which controls its own distance,
//! is left to react. A vehicle is responsible for what is in front of it.

use crate::num::Num;

/// Stand-in for "no bound" in the generic code (m/s^2).
pub const NO_BOUND: f64 = 1.0e9;

/// Time to collision `d / dv`; infinite when `dv <= 0` (the gap is not closing).
pub fn ttc(distance: f64, closing_speed: f64) -> f64 {
    if closing_speed <= 0.0 {
        f64::INFINITY
    } else {
        distance / closing_speed
    }
}

/// A neighbour as the feasibility bounds see it: position, speed and a presence mask.
#[derive(Debug, Clone)]
pub struct Neighbor<T> {
    /// Longitudinal position (m).
    pub x: T,
    /// Speed (m/s).
    pub v: T,
    /// 1.0 when the neighbour exists, else 0.0.
    pub present: T,
}

/// What the feasibility projection keeps between a vehicle and its same-lane neighbours.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projection {
    /// Subtracted from centre distances: vehicle length plus `sim.safety_gap` (m).
    pub clearance: f64,
    /// Also subtracted, times the follower's speed: `sim.time_headway` (s).
    pub time_headway: f64,
    /// Time step (s).
    pub dt: f64,
    /// Time-to-collision threshold `tau_s` (s).
    pub tau_s: f64,
}

/// The feasible acceleration interval `(lo, hi)` of a vehicle at `(x, v)` whose gaps are
/// measured as `|x_i - x_j| - clearance`, less the time headway's share; see the module docs.
/// Without a neighbour the bound is `-NO_BOUND` or `NO_BOUND`.
pub fn feasible_interval<T: Num>(
    x: &T,
    v: &T,
    leader: &Neighbor<T>,
    follower: &Neighbor<T>,
    p: &Projection,
) -> (T, T) {
    feasible_interval_after(x, v, leader, &leader.v, follower, p)
}

/// [`feasible_interval`] with the leader's speed after this step given (`leader_next`, its
/// settled action's, in the sequential order) instead of its current speed. Its position
/// after the step does not depend on it (eq. 1 moves `x` with the current speed).
pub fn feasible_interval_after<T: Num>(
    x: &T,
    v: &T,
    leader: &Neighbor<T>,
    leader_next: &T,
    follower: &Neighbor<T>,
    p: &Projection,
) -> (T, T) {
    let (dt, tau_s) = (p.dt, p.tau_s);
    let x_next = x.add(&v.mul_c(dt));
    let d_lead = leader.x.add(&leader.v.mul_c(dt)).sub(&x_next).add_c(-p.clearance);
    let mut v_hi = leader_next.add(&d_lead.mul_c(1.0 / tau_s));
    let mut d_follow = x_next
        .sub(&follower.x.add(&follower.v.mul_c(dt)))
        .add_c(-p.clearance);
    // Skipped at 0 so that the paper's rule keeps its operations (and bits).
    if p.time_headway > 0.0 {
        v_hi = v_hi.mul_c(1.0 / (1.0 + p.time_headway / tau_s));
        d_follow = d_follow.sub(&follower.v.mul_c(p.time_headway));
    }
    let hi = v_hi.sub(v).mul_c(1.0 / dt);
    let lo = follower
        .v
        .sub(&d_follow.mul_c(1.0 / tau_s))
        .sub(v)
        .mul_c(1.0 / dt);
    (
        T::select(&follower.present, &lo, &lo.full(-NO_BOUND)),
        T::select(&leader.present, &hi, &hi.full(NO_BOUND)),
    )
}

/// The shared projection order's bounds: where the follower is projected too
/// (`follower_shares` 1), a push `lo > 0` is scaled to `share` of it; where the leader is
/// (`leader_shares` 1), a hold `hi < 0` is. The rest is the neighbour's own bound's (all of
/// it at `share = 0.5`).
pub fn share_bounds<T: Num>(lo: &T, hi: &T, [follower_shares, leader_shares]: [&T; 2], share: f64) -> (T, T) {
    let push = lo.clamp_c(0.0, NO_BOUND);
    let hold = hi.clamp_c(-NO_BOUND, 0.0);
    (
        T::select(follower_shares, &lo.sub(&push.mul_c(1.0 - share)), lo),
        T::select(leader_shares, &hi.sub(&hold.mul_c(1.0 - share)), hi),
    )
}

/// Projects `a` onto `[lo, hi]` (the upper bound wins when the interval is empty).
pub fn project_feasible<T: Num>(a: &T, lo: &T, hi: &T) -> T {
    a.max(lo).min(hi)
}

/// Clips an action to `[-g, g]` and then to what keeps the next speed in `[v_min, v_max]`.
pub fn clip_action<T: Num>(a: &T, v: &T, max_accel: f64, v_min: f64, v_max: f64, dt: f64) -> T {
    let lo = v.full(v_min).sub(v).mul_c(1.0 / dt);
    let hi = v.full(v_max).sub(v).mul_c(1.0 / dt);
    a.clamp_c(-max_accel, max_accel).max(&lo).min(&hi)
}
