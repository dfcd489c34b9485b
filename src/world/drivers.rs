//! Non-learning drivers: IDM behind the leader a driver follows, and constant speed.

use crate::config::Config;
use crate::world::idm::idm_accel;
use crate::world::neighbors::Neighbors;
use crate::world::state::{Scene, Vehicle};
use crate::world::step::neighbor_of;

/// A non-learning driver.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Driver {
    /// Intelligent Driver Model: behind the same-lane leader, or on the ramp behind the nearest
    /// leader by distance to the conflict point.
    Idm,
    /// Zero acceleration.
    ConstSpeed,
}

/// The leader a driver follows: same lane, or on the ramp the nearest by distance to `x_c`.
pub fn driving_leader(vehicle: &Vehicle, n: &Neighbors) -> Option<usize> {
    if vehicle.on_ramp { n.leader } else { n.lane_leader }
}

/// Acceleration of a non-learning driver.
pub fn driver_accel(config: &Config, driver: Driver, scene: &Scene, i: usize, n: &Neighbors) -> f64 {
    match driver {
        Driver::ConstSpeed => 0.0,
        Driver::Idm => {
            let me = &scene.vehicles[i];
            let leader = neighbor_of(scene, driving_leader(me, n), me);
            idm_accel(&me.x, &me.v, &leader, config.vehicle.length, &config.idm)
        }
    }
}
