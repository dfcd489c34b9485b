//! The world's rules as one value: the road (conflict point, lane width), the time step, the
//! vehicle's size and limits, the feasibility projection and the merge gate.
//!
//! Built once by [`WorldRules::new`] from a validated [`Config`] whose conflict point already
//! holds any network's or dataset's geometry ([`Config::at_conflict_point`]), then passed down
//! to every step of the scalar rollout, the NGSIM replay and the SUMO co-simulation.

use crate::config::Config;
use crate::world::dynamics::Axles;
use crate::world::geometry::Road;
use crate::world::merge_gate::GateRules;

/// Everything a step of the world reads from the configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldRules {
    /// The road: conflict point and lane width.
    pub road: Road,
    /// Time step (s).
    pub dt: f64,
    /// Wheelbase of the bicycle model.
    pub axles: Axles,
    /// Vehicle length (m).
    pub length: f64,
    /// Vehicle width (m).
    pub width: f64,
    /// Action bound `g` (m/s^2).
    pub max_accel: f64,
    /// Lowest speed (m/s).
    pub v_min: f64,
    /// Highest speed (m/s).
    pub v_max: f64,
    /// Time-to-collision horizon `tau_s` of the feasibility projection (s).
    pub tau_s: f64,
    /// Whether the merge gate holds ramp vehicles when the feasibility rules are on.
    pub merge_gate: bool,
    /// The merge gate's parameters (clearance, braking, horizon).
    pub gate: GateRules,
}

impl WorldRules {
    /// The rules of a (validated) configuration.
    pub fn new(config: &Config) -> Self {
        let veh = &config.vehicle;
        WorldRules {
            road: Road::new(config),
            dt: config.sim.dt,
            axles: Axles {
                l_f: veh.l_f,
                l_r: veh.l_r,
            },
            length: veh.length,
            width: veh.width,
            max_accel: veh.max_accel,
            v_min: veh.v_min,
            v_max: veh.v_max,
            tau_s: config.sim.tau_s,
            merge_gate: config.sim.merge_gate,
            gate: GateRules::new(config),
        }
    }

    /// Gap subtracted from centre distances: vehicle length plus the safety gap (m).
    pub fn clearance(&self) -> f64 {
        self.gate.clearance
    }

    /// Conflict point `x_c` (m).
    pub fn conflict_point(&self) -> f64 {
        self.road.conflict_point
    }
}
