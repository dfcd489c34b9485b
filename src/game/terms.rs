//! The four reward terms of Section V-iii, unweighted, over any [`Num`].
//!
//! Self terms depend on one vehicle; pair terms are symmetric in the two vehicles
//! (`r_ij = r_ji`), which Theorem 2 needs.

use crate::config::ConflictForm;
use crate::num::Num;

/// Speed tracking, `-(v - v_d)^2`.
pub fn speed_tracking<T: Num>(v: &T, v_desired: f64) -> T {
    v.add_c(-v_desired).square().neg()
}

/// Speed tracking towards a desired speed of each vehicle's own (a tensor of them may
/// broadcast over a scene's vehicles), `-(v - v_d)^2`.
pub fn speed_tracking_towards<T: Num>(v: &T, v_desired: &T) -> T {
    v.sub(v_desired).square().neg()
}

/// Ride comfort, `-u^2`.
pub fn comfort<T: Num>(u: &T) -> T {
    u.square().neg()
}

/// Same-lane pairwise TTC term (the paper's piecewise equation):
///
/// ```text
/// -1 / (|x_i - x_j| / v_c + eps)     if |v_i - v_j| <= v_c
/// -1 / (TTC_ij + eps)                otherwise, TTC_ij = |x_i - x_j| / |v_i - v_j|
/// ```
///
/// Both branches are `-1 / (|dx| / max(|dv|, v_c) + eps)`, which is how it is computed (one
/// expression, continuous at `|dv| = v_c`, and with finite gradients everywhere).
pub fn same_lane_ttc<T: Num>(x_i: &T, v_i: &T, x_j: &T, v_j: &T, v_c: f64, eps: f64) -> T {
    let dx = x_i.sub(x_j).abs();
    let dv = v_i.sub(v_j).abs().max(&x_i.full(v_c));
    dx.div(&dv).add_c(eps).recip().neg()
}

/// Time for a vehicle to reach the conflict point, `T_i = |x_i - x_c| / (v_i + eps)`.
pub fn time_to_conflict<T: Num>(x: &T, v: &T, x_c: f64, eps: f64) -> T {
    x.add_c(-x_c).abs().div(&v.add_c(eps))
}

/// [`time_to_conflict`] signed, `(x_c - x) / (v + eps)`: negative once the vehicle has passed
/// the conflict point (`reward.conflict_signed_time`).
pub fn signed_time_to_conflict<T: Num>(x: &T, v: &T, x_c: f64, eps: f64) -> T {
    x.add_c(-x_c).neg().div(&v.add_c(eps))
}

/// Different-lane time-gap-to-conflict-point term, eq. (28):
/// `-1 / (sqrt(T_i T_j) (T_i - T_j)^2 + eps)`, with `T_i T_j + 1e-12` under the root.
pub fn conflict_time_gap<T: Num>(x_i: &T, v_i: &T, x_j: &T, v_j: &T, x_c: f64, eps: f64) -> T {
    let t_i = time_to_conflict(x_i, v_i, x_c, eps);
    let t_j = time_to_conflict(x_j, v_j, x_c, eps);
    time_gap_penalty(&t_i, &t_j, t_i.mul(&t_j), eps)
}

/// Eq. (28) from the two times and `|T_i T_j|`:
/// `-1 / (sqrt(|T_i T_j| + 1e-12) (T_i - T_j)^2 + eps)`.
fn time_gap_penalty<T: Num>(t_i: &T, t_j: &T, product: T, eps: f64) -> T {
    // 1e-12 under the root keeps its derivative finite where a time is 0 (a vehicle at x_c):
    // sqrt'(0) is infinite. It moves the value by less than 1e-12 relative.
    product
        .add_c(1e-12)
        .sqrt()
        .mul(&t_i.sub(t_j).square())
        .add_c(eps)
        .recip()
        .neg()
}

/// [`conflict_time_gap`] until either vehicle is more than `clearance` (m) past the conflict
/// point, 0 from then on (`reward.conflict_ends_at_x_c` and `reward.conflict_clearance`, ours):
/// a vehicle past `x_c` has no conflict there to come, while `|x - x_c|` has its time grow
/// again, so a ramp vehicle still before `x_c` met each target-lane vehicle that had passed
/// once more, at `T_i = T_j`. Within `clearance` of `x_c` that meeting still counts: a vehicle
/// reaching `x_c` just behind another one, bodies overlapping, is still penalised. Still
/// symmetric.
pub fn conflict_time_gap_before<T: Num>(
    [x_i, v_i, x_j, v_j]: [&T; 4],
    x_c: f64,
    clearance: f64,
    eps: f64,
) -> T {
    let passed = x_i.max(x_j).gt_c(x_c + clearance);
    T::select(
        &passed,
        &x_i.full(0.0),
        &conflict_time_gap(x_i, v_i, x_j, v_j, x_c, eps),
    )
}

/// Eq. (28) on signed times to the conflict point, `T = (x_c - x) / (v + eps)`, negative once
/// a vehicle has passed it (`reward.conflict_signed_time`, ours):
/// `-1 / (sqrt(|T_i T_j|) (T_i - T_j)^2 + eps)`. `T_i - T_j` is the pair's time headway at
/// `x_c` whichever side of it each vehicle is, so a ramp vehicle following a passed one by
/// 1.5 s is penalised for 1.5 s, where `|x - x_c|` had them meet at `T_i = T_j`. Symmetric,
/// and equal to [`conflict_time_gap`] while both vehicles are before `x_c`.
pub fn conflict_time_gap_signed<T: Num>(x_i: &T, v_i: &T, x_j: &T, v_j: &T, x_c: f64, eps: f64) -> T {
    let t_i = signed_time_to_conflict(x_i, v_i, x_c, eps);
    let t_j = signed_time_to_conflict(x_j, v_j, x_c, eps);
    time_gap_penalty(&t_i, &t_j, t_i.mul(&t_j).abs(), eps)
}

/// The conflict term of the configured form ([`crate::config::RewardConfig::conflict_form`]).
pub fn conflict_term<T: Num>(
    form: ConflictForm,
    x_i: &T,
    v_i: &T,
    x_j: &T,
    v_j: &T,
    x_c: f64,
    eps: f64,
) -> T {
    match form {
        ConflictForm::Paper => conflict_time_gap(x_i, v_i, x_j, v_j, x_c, eps),
        ConflictForm::EndsPast(clearance) => {
            conflict_time_gap_before([x_i, v_i, x_j, v_j], x_c, clearance, eps)
        }
        ConflictForm::Signed => conflict_time_gap_signed(x_i, v_i, x_j, v_j, x_c, eps),
    }
}
