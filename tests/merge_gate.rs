//! The merge gate on worked cases: when a ramp vehicle may enter, and the stopping bound.

mod common;

use approx::assert_abs_diff_eq;
use common::{car, scene};
use mpgdrive::world::merge_gate::{
    GateRules, STOP_MARGIN, entry_is_safe, gate_holds, lane_change_is_safe, lane_end_bound, stop_bound,
};
use mpgdrive::world::state::Vehicle;

/// x_c = 180 m, 5 m cars with a 2 m safety gap, b_safe = 4 m/s^2, tau_s = 3 s, braking at up
/// to g = 9.81 m/s^2, dt = 0.1 s.
fn rules() -> GateRules {
    GateRules {
        conflict_point: 180.0,
        clearance: 7.0,
        b_safe: 4.0,
        horizon: 3.0,
        brake: 9.81,
        lane_end_brake: 9.81,
        dt: 0.1,
        reaction_time: None,
    }
}

/// Whether `ego` may enter with `other` as the only other vehicle.
fn safe_beside(ego: Vehicle, other: Vehicle) -> bool {
    entry_is_safe(&scene(vec![ego, other]), 0, &rules())
}

#[test]
fn a_stopped_ego_at_the_line_needs_the_gap_of_one_entry() {
    // Ego stopped at 179.9 m, on its stop line: the fastest speed from which it could still
    // stop is 0, so committing now means crossing within 2 dt = 0.2 s, the only entry checked.
    // A follower at 10 m/s needs a gap of 10^2 / (2 * 4) = 12.5 m beyond the 7 m clearance:
    // its centre at 0.2 s at or behind 179.9 - 19.5 = 160.4 m, so it may start at up to 158.4 m.
    let ego = car(179.9, 0.0, true);
    assert!(safe_beside(ego, car(158.3, 10.0, false)));
    assert!(!safe_beside(ego, car(158.5, 10.0, false)));
    // A follower no faster than the ego asks for no braking: only the clearance counts.
    assert!(safe_beside(ego, car(172.8, 0.0, false)));
    assert!(!safe_beside(ego, car(173.0, 0.0, false)));
}

#[test]
fn entries_are_checked_until_the_latest_crossing_of_a_vehicle_that_commits_now() {
    // Ego stopped at 170 m, 9.9 m before its stop line: it could reach
    // v' = -0.981 + sqrt(0.981^2 + 2 * 9.81 * 9.9) = 12.99 m/s and still stop; committing
    // above that and braking at g, it crosses by 0.2 + 12.99 / 9.81 = 1.52 s, so entries up to
    // the 16th step (1.6 s) count. The 10 m/s follower's centre must stay at or behind
    // 170 - 19.5 = 150.5 m until 1.6 s: it may start at up to 134.5 m.
    let waiting = car(170.0, 0.0, true);
    assert!(safe_beside(waiting, car(134.4, 10.0, false)));
    assert!(!safe_beside(waiting, car(134.6, 10.0, false)));
    // Ego at 176 m and 8 m/s: after the step it is at 176.8 m, 3.1 m before the stop line, and
    // could stop from v' = -0.981 + sqrt(0.981^2 + 2 * 9.81 * 3.1) = 6.88 m/s; the latest
    // crossing is 0.2 + 6.88 / 9.81 = 0.90 s, so entries up to the 10th step (1.0 s, ego at
    // 184 m at its speed) count. Behind a stopped leader it needs 7 + 8^2 / (2 * 4) = 15 m:
    // the leader beyond 199 m.
    let ego = car(176.0, 8.0, true);
    assert!(safe_beside(ego, car(199.1, 0.0, false)));
    assert!(!safe_beside(ego, car(198.9, 0.0, false)));
}

#[test]
fn a_committed_ego_is_not_held() {
    // A car beside the ego makes every entry unsafe. At 170 m and 8.5 m/s the ego can still
    // stop (after the step: 170.85 m, 9.05 m before the line, v' <= 12.4 m/s), so the gate
    // holds it; at 177.2 m (1.85 m before the line after the step, v' <= 5.1 m/s, a <= -34
    // m/s^2 < -g) it cannot, and the gate lets it go.
    let held = scene(vec![car(170.0, 8.5, true), car(170.0, 12.0, false)]);
    assert!(!entry_is_safe(&held, 0, &rules()) && gate_holds(&held, 0, &rules()));
    let committed = scene(vec![car(177.2, 8.5, true), car(177.2, 12.0, false)]);
    assert!(!entry_is_safe(&committed, 0, &rules()) && !gate_holds(&committed, 0, &rules()));
    // A target-lane vehicle is never held.
    assert!(!gate_holds(
        &scene(vec![car(170.0, 8.5, false), car(170.0, 12.0, false)]),
        0,
        &rules()
    ));
}

#[test]
fn a_lane_change_needs_one_steps_gaps_with_tau_s_of_ttc() {
    // Ego at 140 m and 10 m/s (the entry check at the stop line does not apply this far).
    // A leader 19 m ahead at 6 m/s: after the step the gap is 159.6 - 141 - 7 = 11.6 m,
    // closing at 4 m/s: TTC 2.9 s < 3 s, not safe; 20 m ahead: 12.6 / 4 = 3.15 s, safe.
    let ego = car(140.0, 10.0, true);
    let change = |other| lane_change_is_safe(&scene(vec![ego, other]), 0, &rules());
    assert!(!change(car(159.0, 6.0, false)));
    assert!(change(car(160.0, 6.0, false)));
    // A follower at the ego's speed needs the clearance only: 7 m between centres.
    assert!(change(car(132.9, 10.0, false)));
    assert!(!change(car(133.1, 10.0, false)));
    // The same follower 30 m back but at 20 m/s: gap 141 - 112 - 7 = 22 m closing at 10 m/s,
    // TTC 2.2 s: not safe.
    assert!(!change(car(110.0, 20.0, false)));
}

#[test]
fn the_leader_at_entry_needs_the_clearance_and_an_absorbable_closing_speed() {
    let ego = car(179.9, 0.0, true);
    // Pulling away: 8.1 m apart at 0.2 s, more than the 7 m clearance, and growing.
    assert!(safe_beside(ego, car(186.0, 10.0, false)));
    // Stopped 6.9 m ahead (centre to centre): inside the 7 m clearance.
    assert!(!safe_beside(ego, car(186.8, 0.0, false)));
    // An ego at 10 m/s (entry at 0.2 s, x_e = 181.9) behind a stopped car 20 m ahead of that:
    // a 13 m gap absorbs the 12.5 m that stopping from 10 m/s at 4 m/s^2 takes; 12.4 m does not.
    let fast = car(179.9, 10.0, true);
    assert!(safe_beside(fast, car(201.9, 0.0, false)));
    assert!(!safe_beside(fast, car(201.3, 0.0, false)));
}

#[test]
fn only_target_lane_vehicles_count() {
    // A second ramp vehicle right behind does not close the gate; the same car in the lane does.
    let ego = car(179.9, 0.0, true);
    assert!(safe_beside(ego, car(176.0, 10.0, true)));
    assert!(!safe_beside(ego, car(176.0, 10.0, false)));
    assert!(entry_is_safe(&scene(vec![ego]), 0, &rules()));
}

#[test]
fn stop_bound_worked_case_stops_before_the_line() {
    // b = 10 m/s^2, dt = 0.1 s: at 174.9 m and 10 m/s the vehicle is at 175.9 m after the step,
    // 4 m before the stop line at 179.9 m; v' <= -1 + sqrt(1 + 2 * 10 * 4) = 8 m/s, so
    // a <= (8 - 10) / 0.1 = -20 m/s^2.
    let ten = GateRules {
        brake: 10.0,
        ..rules()
    };
    let a = stop_bound(&174.9, &10.0, &ten);
    assert_abs_diff_eq!(a, -20.0, epsilon = 1e-9);
    // Braking at 10 m/s^2 from there stays short of the line (step by step, as eq. 1 moves).
    let (mut x, mut v) = (174.9 + 10.0 * 0.1, 10.0 + a * 0.1);
    while v > 0.0 {
        x += v * 0.1;
        v = (v - 1.0).max(0.0);
    }
    assert!(x < 180.0 - STOP_MARGIN, "stopped at {x}");
    // Already at the line after this step: the bound is a full stop, -v / dt.
    assert_abs_diff_eq!(stop_bound(&179.9, &0.5, &ten), -5.0, epsilon = 1e-9);
}

#[test]
fn a_vehicle_held_at_the_lane_end_stops_there_braking_at_the_lane_end_brake() {
    // At 160 m and 12 m/s it is at 161.2 m after the step, 18.7 m before the stop line at
    // 179.9 m. At 4 m/s^2: v' <= -0.4 + sqrt(0.16 + 2 * 4 * 18.7) = 11.8377 m/s, so
    // a <= (11.8377 - 12) / 0.1 = -1.623 m/s^2; at g (the default) the bound does not bind yet
    // (v' <= -0.981 + sqrt(0.962 + 2 * 9.81 * 18.7) = 18.199 m/s, a <= 61.99 m/s^2).
    let gentle = GateRules {
        lane_end_brake: 4.0,
        ..rules()
    };
    let expected = (-0.4 + (0.16f64 + 8.0 * 18.7).sqrt() - 12.0) / 0.1;
    assert_abs_diff_eq!(lane_end_bound(&160.0, &12.0, &gentle), expected, epsilon = 1e-9);
    assert_abs_diff_eq!(expected, -1.623, epsilon = 1e-3);
    let at_g = (-0.981 + (0.981f64.powi(2) + 2.0 * 9.81 * 18.7).sqrt() - 12.0) / 0.1;
    assert_abs_diff_eq!(lane_end_bound(&160.0, &12.0, &rules()), at_g, epsilon = 1e-9);
    assert_abs_diff_eq!(at_g, 61.99, epsilon = 0.01);
    // Driven at its bound step by step (eq. 1), it never brakes harder than 4 m/s^2 and stops
    // short of the line.
    let (mut x, mut v) = (160.0, 12.0);
    while v > 0.0 {
        let a = lane_end_bound(&x, &v, &gentle).min(0.0);
        assert!(a >= -4.0 - 1e-9, "braked at {a} m/s^2 at {x} m");
        x += v * 0.1;
        v = (v + a * 0.1).max(0.0);
    }
    assert!(x < 180.0 - STOP_MARGIN + 1e-9, "stopped at {x}");
    // Too fast to stop at 4 m/s^2 (16 m/s, 19.9 m before the line after the step, where it
    // needs 32 m): it brakes harder, as it must.
    assert!(lane_end_bound(&158.4, &16.0, &gentle) < -4.0);
}
