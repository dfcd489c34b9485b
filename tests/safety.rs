//! TTC, the feasible interval and bounding boxes on worked cases.

use approx::assert_abs_diff_eq;
use mpgdrive::world::geometry::{Footprint, boxes_overlap};
use mpgdrive::world::safety::{
    NO_BOUND, Neighbor, Projection, clip_action, feasible_interval, project_feasible, ttc,
};

/// A 5 m clearance, dt = 0.1 s, tau_s = 3 s, and time headway `h`.
fn rule(h: f64) -> Projection {
    Projection {
        clearance: 5.0,
        time_headway: h,
        dt: 0.1,
        tau_s: 3.0,
    }
}

fn nb(x: f64, v: f64) -> Neighbor<f64> {
    Neighbor { x, v, present: 1.0 }
}

fn none() -> Neighbor<f64> {
    Neighbor {
        x: 0.0,
        v: 0.0,
        present: 0.0,
    }
}

#[test]
fn ttc_is_distance_over_closing_speed_or_infinite() {
    assert_eq!(ttc(10.0, 2.0), 5.0);
    assert_eq!(ttc(10.0, 0.0), f64::INFINITY);
    assert_eq!(ttc(10.0, -1.0), f64::INFINITY);
}

#[test]
fn feasible_interval_worked_case() {
    // 5 m cars. Vehicle at x = 0, 15 m/s; leader at 15 m, 12 m/s; follower at -15 m, 18 m/s;
    // dt = 0.1, tau = 3. After one step the bumper gaps are d_L = 16.2 - 1.5 - 5 = 9.7, so
    // v' <= 12 + 9.7 / 3 and a <= (12 + 3.2333 - 15) / 0.1 = 2.3333; d_F = 1.5 - (-13.2) - 5
    // = 9.7, so a >= (18 - 3.2333 - 15) / 0.1 = -2.3333.
    let (lo, hi) = feasible_interval(&0.0, &15.0, &nb(15.0, 12.0), &nb(-15.0, 18.0), &rule(0.0));
    assert_abs_diff_eq!(hi, 7.0 / 3.0, epsilon = 1e-9);
    assert_abs_diff_eq!(lo, -7.0 / 3.0, epsilon = 1e-9);
    assert_abs_diff_eq!(project_feasible(&5.0, &lo, &hi), 7.0 / 3.0, epsilon = 1e-9);
    assert_abs_diff_eq!(project_feasible(&-5.0, &lo, &hi), -7.0 / 3.0, epsilon = 1e-9);
    assert_eq!(project_feasible(&1.0, &lo, &hi), 1.0);
    // At the upper bound the TTC to the leader is exactly tau after the step.
    let v_next = 15.0 + hi * 0.1;
    assert_abs_diff_eq!(ttc(9.7, v_next - 12.0), 3.0, epsilon = 1e-9);
}

#[test]
fn time_headway_takes_the_followers_speed_off_each_gap() {
    // The worked case above with h = 0.5 s. Towards the leader the vehicle's next speed is
    // the follower's: v' <= 12 + (9.7 - 0.5 v') / 3, so v' <= (12 + 9.7 / 3) / (1 + 0.5 / 3)
    // = 91.4 / 7 and a <= (91.4 / 7 - 15) / 0.1 = -13.6 / 0.7. Towards the follower its
    // speed, 18: the gap is 9.7 - 9 = 0.7, so a >= (18 - 0.7 / 3 - 15) / 0.1 = 83 / 3. The
    // interval is empty: the leader bound wins when projected.
    let (lo, hi) = feasible_interval(&0.0, &15.0, &nb(15.0, 12.0), &nb(-15.0, 18.0), &rule(0.5));
    assert_abs_diff_eq!(hi, -13.6 / 0.7, epsilon = 1e-9);
    assert_abs_diff_eq!(lo, 83.0 / 3.0, epsilon = 1e-9);
    // At equal speeds a vehicle may hold its speed exactly where its gap after the step is
    // the headway's: 10 m/s behind a 10 m/s leader with h = 1 s needs a bumper gap of 10 m
    // (v' <= (10 + 10 / 3) / (4 / 3) = 10); 1 m closer, v' <= (10 + 9 / 3) / (4 / 3) = 9.75.
    let (_, hi) = feasible_interval(&0.0, &10.0, &nb(15.0, 10.0), &none(), &rule(1.0));
    assert_abs_diff_eq!(hi, 0.0, epsilon = 1e-9);
    let (_, closer) = feasible_interval(&0.0, &10.0, &nb(14.0, 10.0), &none(), &rule(1.0));
    assert_abs_diff_eq!(closer, -2.5, epsilon = 1e-9);
    // The bound does not depend on the vehicle's own speed beyond its step: held at it, the
    // next speed is the same from 9 or 11 m/s when the gap after the step is the same.
    let v_next =
        |v: f64, lead_x: f64| v + feasible_interval(&0.0, &v, &nb(lead_x, 10.0), &none(), &rule(1.0)).1 * 0.1;
    assert_abs_diff_eq!(v_next(9.0, 14.9), v_next(11.0, 15.1), epsilon = 1e-9);
}

#[test]
fn missing_neighbours_give_no_bound() {
    let (lo, hi) = feasible_interval(&0.0, &15.0, &none(), &none(), &rule(0.0));
    assert_eq!((lo, hi), (-NO_BOUND, NO_BOUND));
    assert_eq!(project_feasible(&4.0, &lo, &hi), 4.0);
}

#[test]
fn empty_interval_protects_the_front() {
    // Leader 11 m ahead at 10 m/s, follower 11 m behind at 20 m/s, own speed 15 m/s, 5 m
    // cars: both gaps after a step are 5.5 m, so hi = (10 + 5.5 / 3 - 15) / 0.1 = -31.67 and
    // lo = (20 - 5.5 / 3 - 15) / 0.1 = +31.67.
    let (lo, hi) = feasible_interval(&0.0, &15.0, &nb(11.0, 10.0), &nb(-11.0, 20.0), &rule(0.0));
    assert!(lo > hi);
    assert_abs_diff_eq!(hi, -95.0 / 3.0, epsilon = 1e-9);
    let a = project_feasible(&0.0, &lo, &hi);
    assert_eq!(a, hi, "the leader bound wins");
    assert_eq!(
        clip_action(&a, &15.0, 9.81, 0.0, 30.0, 0.1),
        -9.81,
        "then full braking at most"
    );
}

fn fp(x: f64, y: f64, phi: f64) -> Footprint {
    Footprint {
        x,
        y,
        phi,
        length: 5.0,
        width: 2.0,
    }
}

#[test]
fn box_overlap_cases() {
    // Same lane, 5 m boxes: 4.9 m apart overlap, 5.0 m apart only touch.
    assert!(boxes_overlap(&fp(0.0, 0.0, 0.0), &fp(4.9, 0.0, 0.0)));
    assert!(!boxes_overlap(&fp(0.0, 0.0, 0.0), &fp(5.0, 0.0, 0.0)));
    // Side by side: 1.9 m lateral overlap, a lane (3.66 m) apart do not.
    assert!(boxes_overlap(&fp(0.0, 0.0, 0.0), &fp(1.0, 1.9, 0.0)));
    assert!(!boxes_overlap(&fp(0.0, 0.0, 0.0), &fp(0.0, -3.66, 0.0)));
    // A box turned 90 degrees reaches 1 m along x: at 3.4 m it overlaps (2.5 + 1 > 3.4), at 3.6
    // it does not.
    let quarter = std::f64::consts::FRAC_PI_2;
    assert!(boxes_overlap(&fp(0.0, 0.0, 0.0), &fp(3.4, 0.0, quarter)));
    assert!(!boxes_overlap(&fp(0.0, 0.0, 0.0), &fp(3.6, 0.0, quarter)));
    // Rotated 45 degrees: its front corner is at (2.5 cos45 + sin45, 2.5 sin45 - cos45) =
    // (2.4749, 1.0607). An aligned box centred at y = 1.06 with its rear edge at x = 2.45
    // contains that corner; with its rear edge at 2.49 it is beyond the rotated box's reach.
    let eighth = std::f64::consts::FRAC_PI_4;
    assert!(boxes_overlap(&fp(0.0, 0.0, eighth), &fp(4.95, 1.06, 0.0)));
    assert!(!boxes_overlap(&fp(0.0, 0.0, eighth), &fp(4.99, 1.06, 0.0)));
}
