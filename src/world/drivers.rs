//! Non-learning drivers: IDM behind the leader a driver follows, and constant speed.

use crate::config::Config;
use crate::world::idm::{idm_accel, idm_v0};
use crate::world::neighbors::Neighbors;
use crate::world::state::Scene;
use crate::world::step::neighbor_of;

/// A non-learning driver.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Driver {
    /// Intelligent Driver Model: behind the same-lane leader; on the ramp also behind the
    /// nearest leader by distance to the conflict point (the vehicle it will merge behind),
    /// whichever asks for less acceleration.
    Idm,
    /// Zero acceleration.
    ConstSpeed,
}

/// Acceleration of a non-learning driver.
pub fn driver_accel(config: &Config, driver: Driver, scene: &Scene, i: usize, n: &Neighbors) -> f64 {
    match driver {
        Driver::ConstSpeed => 0.0,
        Driver::Idm => {
            let me = &scene.vehicles[i];
            let v0 = scene.v_desired.map(|d| idm_v0(config, Some(d)));
            let behind = |leader: Option<usize>| {
                let leader = neighbor_of(scene, leader, me);
                idm_accel(
                    &me.x,
                    &me.v,
                    &leader,
                    config.vehicle.length,
                    &config.idm,
                    v0.as_ref(),
                )
            };
            let lane = behind(n.lane_leader);
            // IDM behind a missing leader is the free-road acceleration, the largest: alone on
            // the ramp (the paper's ego) only the nearest leader counts.
            if me.on_ramp {
                lane.min(behind(n.leader))
            } else {
                lane
            }
        }
    }
}
