//! Eq. (1) and the action clipping, against hand-computed kinematics.

use approx::assert_abs_diff_eq;
use mpgdrive::world::dynamics::{Axles, Kinematics, bicycle_step};
use mpgdrive::world::safety::clip_action;

const AXLES: Axles = Axles { l_f: 1.2, l_r: 1.6 };

fn state(x: f64, v: f64) -> Kinematics<f64> {
    Kinematics {
        x,
        y: 0.0,
        v,
        phi: 0.0,
    }
}

fn run(mut s: Kinematics<f64>, u: f64, delta: f64, steps: usize) -> Kinematics<f64> {
    for _ in 0..steps {
        s = bicycle_step(&s, &u, &delta, AXLES, 0.1);
    }
    s
}

#[test]
fn constant_speed_20_mps_for_2_s_covers_40_m() {
    let s = run(state(0.0, 20.0), 0.0, 0.0, 20);
    assert_abs_diff_eq!(s.x, 40.0, epsilon = 1e-9);
    assert_abs_diff_eq!(s.v, 20.0, epsilon = 1e-12);
    assert_abs_diff_eq!(s.y, 0.0, epsilon = 1e-12);
}

#[test]
fn constant_acceleration_follows_explicit_euler() {
    // x_n = v0 n dt + u dt^2 n (n - 1) / 2 = 40 + 0.01 * 190 = 41.9 m; v = 20 + 1 * 2 = 22 m/s.
    let s = run(state(0.0, 20.0), 1.0, 0.0, 20);
    assert_abs_diff_eq!(s.x, 41.9, epsilon = 1e-9);
    assert_abs_diff_eq!(s.v, 22.0, epsilon = 1e-9);
}

#[test]
fn steering_turns_heading_as_eq_1_says() {
    // delta = 0.1 rad, v = 10 m/s, l_r / (l_r + l_f) = 1.6 / 2.8:
    // beta = atan(0.5714 tan 0.1) = 0.0572714 rad; one step of 0.1 s gives
    // x = 10 cos(beta) 0.1, y = 10 sin(beta) 0.1, phi = 10 / 1.6 sin(beta) 0.1.
    let s = bicycle_step(&state(0.0, 10.0), &0.0, &0.1, AXLES, 0.1);
    assert_abs_diff_eq!(s.x, 0.998_360_441_644_348_8, epsilon = 1e-12);
    assert_abs_diff_eq!(s.y, 0.057_240_095_734_555_05, epsilon = 1e-12);
    assert_abs_diff_eq!(s.phi, 0.035_775_059_834_096_9, epsilon = 1e-12);
    // The heading then moves the velocity direction: the second step goes along phi + beta.
    let s2 = bicycle_step(&s, &0.0, &0.1, AXLES, 0.1);
    let heading = 0.035_775_059_834_096_9 + 0.057_271_399_090_735_45;
    assert_abs_diff_eq!(s2.y - s.y, 10.0 * f64::sin(heading) * 0.1, epsilon = 1e-12);
}

#[test]
fn speed_is_clipped_at_zero_and_thirty() {
    // At 0.5 m/s full braking would give -0.48 m/s: the action is clipped to -5 m/s^2.
    let a = clip_action(&-9.81, &0.5, 9.81, 0.0, 30.0, 0.1);
    assert_abs_diff_eq!(a, -5.0, epsilon = 1e-12);
    let s = bicycle_step(&state(0.0, 0.5), &a, &0.0, AXLES, 0.1);
    assert_abs_diff_eq!(s.v, 0.0, epsilon = 1e-12);
    // At 29.5 m/s full throttle is clipped to +5 m/s^2, reaching exactly 30 m/s.
    let a = clip_action(&9.81, &29.5, 9.81, 0.0, 30.0, 0.1);
    assert_abs_diff_eq!(a, 5.0, epsilon = 1e-12);
    // Actions beyond g are clipped to g.
    assert_abs_diff_eq!(clip_action(&50.0, &10.0, 9.81, 0.0, 30.0, 0.1), 9.81);
    assert_abs_diff_eq!(clip_action(&-50.0, &10.0, 9.81, 0.0, 30.0, 0.1), -9.81);
}
