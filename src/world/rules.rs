//! The world's rules as one value: the road (conflict point, lane width), the time step, the
//! vehicle's size and limits, the feasibility projection and the merge gate.
//!
//! Built once by [`WorldRules::new`] from a validated [`Config`] whose conflict point already
//! holds any network's or dataset's geometry ([`Config::at_conflict_point`]), then passed down
//! to every step of the scalar rollout, the NGSIM replay and the SUMO co-simulation.

use crate::config::{Config, ProjectionOrder};
use crate::world::dynamics::Axles;
use crate::world::geometry::Road;
use crate::world::merge_gate::{GateRules, lane_change_is_safe};
use crate::world::safety::Projection;
use crate::world::state::Scene;

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
    /// Time gap of the feasibility projection (s; `sim.time_headway`).
    pub time_headway: f64,
    /// The order in which the feasibility projection settles vehicles (`sim.projection_order`).
    pub order: ProjectionOrder,
    /// The share of a projected pair's correction each end takes in the shared order
    /// (`sim.shared_correction`).
    pub shared_correction: f64,
    /// Whether the merge gate holds ramp vehicles when the feasibility rules are on.
    pub merge_gate: bool,
    /// The merge gate's parameters (clearance, braking, horizon).
    pub gate: GateRules,
    /// Whether policy-driven target-lane players make room for a ramp vehicle in the merge
    /// zone ahead of them (`sim.players_make_room`).
    pub players_make_room: bool,
    /// Whether a target-lane vehicle's feasibility also binds towards the nearest ramp
    /// vehicles ahead and behind (`sim.feasibility_across_lanes`).
    pub feasibility_across_lanes: bool,
}

impl WorldRules {
    /// Whether the projection settles vehicles front to back, each leader bound reading the
    /// leader's next speed (`sim.projection_order = "sequential"`).
    pub fn sequential(&self) -> bool {
        self.order == ProjectionOrder::Sequential
    }

    /// Whether a projected leader and follower share their pair's correction
    /// (`sim.projection_order = "shared"`, [`crate::world::safety::share_bounds`]).
    pub fn shared(&self) -> bool {
        self.order == ProjectionOrder::Shared
    }

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
            time_headway: config.sim.time_headway,
            order: config.sim.projection_order,
            shared_correction: config.sim.shared_correction,
            merge_gate: config.sim.merge_gate,
            gate: GateRules::new(config),
            players_make_room: config.sim.players_make_room,
            feasibility_across_lanes: config.sim.feasibility_across_lanes,
        }
    }

    /// Gap subtracted from centre distances: vehicle length plus the safety gap (m).
    pub fn clearance(&self) -> f64 {
        self.gate.clearance
    }

    /// The feasibility projection's parameters.
    pub fn projection(&self) -> Projection {
        Projection {
            clearance: self.clearance(),
            time_headway: self.time_headway,
            dt: self.dt,
            tau_s: self.tau_s,
        }
    }

    /// Conflict point `x_c` (m).
    pub fn conflict_point(&self) -> f64 {
        self.road.conflict_point
    }

    /// Whether ramp vehicle `i` of `scene` joins the target lane this step before reaching
    /// `x_c`: it is inside the merge zone and the lane change is safe
    /// ([`lane_change_is_safe`]; a discrete decision, no gradient, as the gate's).
    pub fn merges_early(&self, scene: &Scene, i: usize) -> bool {
        let me = &scene.vehicles[i];
        me.on_ramp && self.road.in_merge_zone(me.x) && lane_change_is_safe(scene, i, &self.gate)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::state::test_car as at;

    #[test]
    fn ramp_vehicles_merge_early_only_inside_the_zone_and_at_a_safe_gap() {
        let mut config =
            Config::load(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/paper.toml"))
                .unwrap();
        // The paper: at x_c only.
        let alone = Scene::new(vec![at(160.0, 12.0, true)]);
        assert!(!WorldRules::new(&config).merges_early(&alone, 0));
        // A 40 m zone before x_c = 180 m: from 140 m on, with the target lane empty.
        config.scenario.merge_zone = 40.0;
        let rules = WorldRules::new(&config);
        assert!(rules.merges_early(&alone, 0));
        assert!(!rules.merges_early(&Scene::new(vec![at(139.0, 12.0, true)]), 0));
        // A car 6 m behind at the same speed is inside the 7 m clearance (5 m length + 2 m
        // gap): not now; 60 m behind at the same speed: now. A vehicle already in the target
        // lane never merges.
        let close = Scene::new(vec![at(160.0, 12.0, true), at(154.0, 12.0, false)]);
        assert!(!rules.merges_early(&close, 0));
        assert!(!rules.merges_early(&close, 1));
        let far = Scene::new(vec![at(160.0, 12.0, true), at(100.0, 12.0, false)]);
        assert!(rules.merges_early(&far, 0));
    }

    #[test]
    fn an_acceleration_lane_keeps_ramp_vehicles_past_x_c_until_a_gap_or_its_end() {
        use crate::world::merge_gate::{gate_holds, stop_bound};
        use crate::world::step::advance;
        let mut config =
            Config::load(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/paper.toml"))
                .unwrap();
        (config.scenario.merge_zone, config.scenario.accel_lane) = (40.0, 40.0);
        config.sim.merge_gate = true;
        let rules = WorldRules::new(&config);
        assert_eq!(rules.road.ramp_end(), 220.0);
        // A network's or a dataset's geometry replaces the training road's lane.
        assert_eq!(
            WorldRules::new(&config.at_conflict_point(150.0)).road.ramp_end(),
            150.0
        );
        // 10 m past x_c = 180 with a car beside it: no lane change, and it stays on the
        // ramp (y = -3.66) after the step; with the lane free it changes now.
        let beside = Scene::new(vec![at(190.0, 10.0, true), at(192.0, 10.0, false)]);
        assert!(!rules.merges_early(&beside, 0));
        let next = advance(&beside.vehicles[0], 0.0, false, &rules);
        assert!(next.on_ramp && next.y == -3.66 && (next.x - 191.0).abs() < 1e-12);
        assert!(rules.merges_early(&Scene::new(vec![at(190.0, 10.0, true)]), 0));
        // At its end (x 219.5 + 1 m this step) it joins the target lane whatever the gaps.
        assert!(!advance(&at(219.5, 10.0, true), 0.0, false, &rules).on_ramp);
        // The gate's stop line is the lane's end less 0.1 m: from x = 212 at 10 m/s the step
        // leaves 219.9 - 213 = 6.9 m, so v' = -g dt + sqrt((g dt)^2 + 2 g 6.9) = 10.695 m/s
        // and the bound is (v' - 10) / dt = 6.955 m/s^2; the car beside holds it.
        let bound = stop_bound(&212.0, &10.0, &rules.gate);
        assert!((bound - 6.954_875).abs() < 1e-5, "{bound}");
        let held = Scene::new(vec![at(212.0, 10.0, true), at(212.0, 10.0, false)]);
        assert!(gate_holds(&held, 0, &rules.gate));
        // Without the lane the same vehicle is past the line: no room, full braking.
        config.scenario.accel_lane = 0.0;
        let bound = stop_bound(&212.0, &10.0, &WorldRules::new(&config).gate);
        assert!((bound + 100.0).abs() < 1e-9, "{bound}");
    }

    /// The paper's road with a 40 m merge zone and the entry rule (`scenario.entry = "gap"`,
    /// reaction time 1 s, b_safe 4 m/s^2, clearance 7 m, tau_s 3 s, x_c = 180 m).
    fn entry_rule_road() -> WorldRules {
        let mut config =
            Config::load(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/paper.toml"))
                .unwrap();
        config.scenario.merge_zone = 40.0;
        config.scenario.entry = crate::config::Entry::Gap;
        (config.sim.reaction_time, config.sim.b_safe) = (1.0, 4.0);
        WorldRules::new(&config)
    }

    #[test]
    fn the_entry_rule_asks_a_human_followers_secure_gap() {
        use crate::world::merge_gate::secure_gap;
        // 30 m/s behind 10 m/s: 30 * 1 + (900 - 100) / 8 = 130 m; the other way round none.
        assert!((secure_gap(30.0, 10.0, 1.0, 4.0) - 130.0).abs() < 1e-12);
        assert_eq!(secure_gap(10.0, 30.0, 1.0, 4.0), 0.0);
        let rules = entry_rule_road();
        // Ego at 160 m, 10 m/s; follower at 20 m/s. One step on: ego 161, follower x + 2.
        // Secure gap 20 + (400 - 100) / 8 = 57.5 m; MOBIL's own check (closing 10 m/s: 12.5
        // m at 4 m/s^2, TTC 3 s: 30 m) passes from 40 m on.
        let with_follower_at = |x: f64| Scene::new(vec![at(160.0, 10.0, true), at(x, 20.0, false)]);
        // Follower at 95 m: gap 161 - 97 - 7 = 57 m < 57.5; at 94 m: 58 m.
        assert!(!rules.merges_early(&with_follower_at(95.0), 0));
        assert!(rules.merges_early(&with_follower_at(94.0), 0));
        // Without the rule (the paper's entry) MOBIL's check alone: 57 m is ample.
        let mut mobil = rules;
        mobil.gate.reaction_time = None;
        assert!(mobil.merges_early(&with_follower_at(95.0), 0));
        // A new leader the ego would close on: ego 20 m/s behind a 10 m/s leader needs
        // 20 + (400 - 100) / 8 = 57.5 m beyond the clearance.
        let with_leader_at = |x: f64| Scene::new(vec![at(150.0, 20.0, true), at(x, 10.0, false)]);
        // One step on: ego 152, leader x + 1; gap x + 1 - 152 - 7.
        assert!(!rules.merges_early(&with_leader_at(215.0), 0)); // 57 m
        assert!(rules.merges_early(&with_leader_at(216.0), 0)); // 58 m
    }

    #[test]
    fn under_the_entry_rule_the_ramps_end_holds_a_vehicle_until_a_gap_comes() {
        use crate::world::neighbors::find_neighbors;
        use crate::world::step::{advance, applied_action};
        let rules = entry_rule_road();
        // An ego at 170 m and 10 m/s beside a car at 172 m and 10 m/s: it may not enter, it
        // accelerates as hard as it may (raw g), and still stops before x_c - 0.1 = 179.9 m.
        let mut scene = Scene::new(vec![at(170.0, 10.0, true), at(172.0, 10.0, false)]);
        let (mut order, mut nb) = (Vec::new(), Vec::new());
        let mut entered_at = None;
        for step in 0..100 {
            find_neighbors(&scene, &mut order, &mut nb);
            let merges = rules.merges_early(&scene, 0);
            let u = applied_action(&rules, false, &scene, 0, &nb[0], 9.81);
            let beside = scene.vehicles[1];
            scene.vehicles[0] = advance(&scene.vehicles[0], u, merges, &rules);
            scene.vehicles[1] = advance(&beside, 0.0, false, &rules);
            let ego = scene.vehicles[0];
            if ego.on_ramp {
                assert!(ego.x < 179.9 + 1e-9, "step {step}: {ego:?}");
            } else if entered_at.is_none() {
                entered_at = Some((step, scene.vehicles[1].x, ego.x));
            }
        }
        // It enters once the car is ahead by more than the clearance (7 m) plus the rule's
        // gap behind a 10 m/s leader, which it may approach from a standstill: none.
        let (step, leader, ego) = entered_at.expect("the ego entered once the car had passed");
        assert!(
            leader - ego > 7.0,
            "entered {} m behind at step {step}",
            leader - ego
        );
        assert!(step > 5, "held at first");
        // The paper's road forces it in at x_c instead.
        let mut forced = rules;
        forced.gate.reaction_time = None;
        let mut scene = Scene::new(vec![at(179.5, 10.0, true), at(180.0, 10.0, false)]);
        find_neighbors(&scene, &mut order, &mut nb);
        let u = applied_action(&forced, false, &scene, 0, &nb[0], 0.0);
        scene.vehicles[0] = advance(&scene.vehicles[0], u, false, &forced);
        assert!(!scene.vehicles[0].on_ramp);
    }
}
