//! Eq. (1) and the action clipping, against hand-computed kinematics.

use approx::assert_abs_diff_eq;
use mpgdrive::engine::tape::{self, Var};
use mpgdrive::num::Num;
use mpgdrive::world::dynamics::{Axles, Kinematics, bicycle_step, straight_step};
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

#[test]
fn a_straight_step_is_eq_1_without_steering_bit_for_bit() {
    // phi = 0 and delta = 0: beta = atan(0) = 0, cos 0 = 1 and sin 0 = 0, so eq. (1) gives
    // x' = x + v dt and v' = v + u dt to the bit, and y and phi stay (up to a zero's sign).
    let cases = [
        (0.0, 0.0, 0.0),
        (12.3, 17.9, -4.2),
        (179.99, 0.3, 9.81),
        (-55.5, 29.7, -9.81),
        (1e-3, 1e-9, 7e-8),
    ];
    for (x, v, u) in cases {
        let s = Kinematics {
            x,
            y: -3.66,
            v,
            phi: 0.0,
        };
        let (a, b) = (bicycle_step(&s, &u, &0.0, AXLES, 0.1), straight_step(&s, &u, 0.1));
        assert_eq!(
            (a.x.to_bits(), a.v.to_bits()),
            (b.x.to_bits(), b.v.to_bits()),
            "{x} {v} {u}"
        );
        assert_eq!((a.y, a.phi), (b.y, b.phi));
        assert_eq!(b.x, x + v * 0.1);
    }
    // On the training tape: the same values and the same gradients of x, v and u, through two
    // steps (the second step's heading is the first's output).
    let (xs, vs, us): (Vec<f64>, Vec<f64>, Vec<f64>) = (
        cases.iter().map(|c| c.0).collect(),
        cases.iter().map(|c| c.1).collect(),
        cases.iter().map(|c| c.2).collect(),
    );
    let run = |straight: bool| {
        tape::start();
        let (x, v, u) = (
            Var::leaf(xs.clone(), 5, 1),
            Var::leaf(vs.clone(), 5, 1),
            Var::leaf(us.clone(), 5, 1),
        );
        let mut s = Kinematics {
            x: x.clone(),
            y: x.full(-3.66),
            v: v.clone(),
            phi: x.full(0.0),
        };
        for _ in 0..2 {
            s = if straight {
                straight_step(&s, &u, 0.1)
            } else {
                bicycle_step(&s, &u, &u.full(0.0), AXLES, 0.1)
            };
        }
        let out = s.x.mul(&s.v);
        let g = tape::backward(&out, vec![1.0; 5]);
        let bits = |t: &[f64]| t.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        [
            out.values(),
            g.of(&x).unwrap(),
            g.of(&v).unwrap(),
            g.of(&u).unwrap(),
        ]
        .map(bits)
    };
    assert_eq!(run(true), run(false));
}
