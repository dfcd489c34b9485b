//! Kinematic bicycle model, eq. (1), discretised with step `dt`.

use crate::num::Num;

/// The bicycle state `(x, y, v, phi)` of eq. (1), over any [`Num`].
#[derive(Debug, Clone, PartialEq)]
pub struct Kinematics<T> {
    /// Longitudinal position (m).
    pub x: T,
    /// Lateral position (m).
    pub y: T,
    /// Speed (m/s).
    pub v: T,
    /// Heading (rad).
    pub phi: T,
}

/// Bicycle geometry: distances from the centre of mass to the axles.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Axles {
    /// To the front axle `l_f` (m).
    pub l_f: f64,
    /// To the rear axle `l_r` (m).
    pub l_r: f64,
}

/// One step of eq. (1) with acceleration `u` and front steering angle `delta`:
///
/// ```text
/// beta   = atan(l_r / (l_r + l_f) * tan(delta))
/// x'     = x + v cos(phi + beta) dt
/// y'     = y + v sin(phi + beta) dt
/// v'     = v + u dt
/// phi'   = phi + v / l_r * sin(beta) dt
/// ```
///
/// Speed bounds are not applied here: the rollout projects `u` so that `v'` stays in
/// `[v_min, v_max]` (see [`crate::world::step::applied_action`]).
pub fn bicycle_step<T: Num>(s: &Kinematics<T>, u: &T, delta: &T, axles: Axles, dt: f64) -> Kinematics<T> {
    let beta = delta.tan().mul_c(axles.l_r / (axles.l_r + axles.l_f)).atan();
    let heading = s.phi.add(&beta);
    Kinematics {
        x: s.x.add(&s.v.mul(&heading.cos()).mul_c(dt)),
        y: s.y.add(&s.v.mul(&heading.sin()).mul_c(dt)),
        v: s.v.add(&u.mul_c(dt)),
        phi: s.phi.add(&s.v.mul(&beta.sin()).mul_c(dt / axles.l_r)),
    }
}

/// Eq. (1) with zero steering on a straight heading (`delta = 0`, `phi = 0`, so `beta = 0`):
/// `x' = x + v dt`, `v' = v + u dt`, while `y` and `phi` stay. These are [`bicycle_step`]'s
/// values bit for bit (`cos 0 = 1`, `sin 0 = 0`; its `y'` and `phi'` differ at most in the sign
/// of a zero) without its four trigonometric functions: no vehicle of a rollout steers, and
/// every rollout starts straight.
pub fn straight_step<T: Num + Clone>(s: &Kinematics<T>, u: &T, dt: f64) -> Kinematics<T> {
    Kinematics {
        x: s.x.add(&s.v.mul_c(dt)),
        y: s.y.clone(),
        v: s.v.add(&u.mul_c(dt)),
        phi: s.phi.clone(),
    }
}

/// One step of eq. (1) with zero steering: [`straight_step`] when `straight` (every heading
/// is 0), else [`bicycle_step`]; the same values either way.
pub fn zero_steering_step<T: Num + Clone>(
    s: &Kinematics<T>,
    u: &T,
    straight: bool,
    axles: Axles,
    dt: f64,
) -> Kinematics<T> {
    if straight {
        straight_step(s, u, dt)
    } else {
        bicycle_step(s, u, &u.full(0.0), axles, dt)
    }
}
