//! Non-learning drivers: the Intelligent Driver Model and constant speed.
//!
//! IDM (Treiber, Hennecke and Helbing, 2000):
//!
//! ```text
//! a = a_max [ 1 - (v / v0)^delta - (s* / s)^2 ],   s* = s0 + max(0, v T + v dv / (2 sqrt(a_max b)))
//! ```
//!
//! with `s` the bumper-to-bumper gap to the leader (centre distance minus vehicle length,
//! floored at 0.1 m) and `dv = v - v_leader`. Without a leader only the free-road term acts.
//! The result is clipped to `[-g, g]` by the rollout like every action.

use crate::config::{Config, IdmConfig};
use crate::num::Num;
use crate::world::safety::Neighbor;

/// Smallest gap IDM divides by (m).
pub const MIN_GAP: f64 = 0.1;

/// IDM acceleration of a vehicle at `(x, v)` behind `leader`; `length` is the vehicle length.
/// `v0` replaces `p.v0` when given (a scene's own desired speed, [`idm_v0`]).
pub fn idm_accel<T: Num>(
    x: &T,
    v: &T,
    leader: &Neighbor<T>,
    length: f64,
    p: &IdmConfig,
    v0: Option<&T>,
) -> T {
    let free = match v0 {
        Some(v0) => v.div(v0).abs(),
        None => v.mul_c(1.0 / p.v0).abs(),
    };
    // (v / v0)^delta for a real delta: exp(delta ln(.)) is not in Num; integer deltas are the
    // norm (4), so use repeated products and a square root for a half-integer remainder.
    let free_term = powf(&free, p.delta);
    let gap = leader.x.sub(x).add_c(-length).max(&x.full(MIN_GAP));
    let dv = v.sub(&leader.v);
    let dynamic = v
        .mul_c(p.time_headway)
        .add(&v.mul(&dv).mul_c(1.0 / (2.0 * (p.accel * p.decel).sqrt())));
    let s_star = dynamic.max(&v.full(0.0)).add_c(p.min_gap);
    let interaction = s_star.div(&gap).square().mul(&leader.present);
    free_term.add(&interaction).neg().add_c(1.0).mul_c(p.accel)
}

/// The IDM drivers' `v0` in a scene of desired speed `v_desired` (none: the configuration's
/// `idm.v0`): `idm.v0` scaled by `v_desired / reward.v_desired`, so a faster road scales the
/// drivers' aim with it.
pub fn idm_v0(config: &Config, v_desired: Option<f64>) -> f64 {
    match v_desired {
        Some(v_d) => config.idm.v0 * (v_d / config.reward.v_desired),
        None => config.idm.v0,
    }
}

/// `x^p` for `x >= 0` and `p` a non-negative multiple of 0.5.
fn powf<T: Num>(x: &T, p: f64) -> T {
    let whole = p.floor() as u32;
    let mut out = x.full(1.0);
    for _ in 0..whole {
        out = out.mul(x);
    }
    if p - p.floor() >= 0.25 {
        out = out.mul(&x.sqrt());
    }
    out
}
