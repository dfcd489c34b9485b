//! Non-learning drivers: IDM behind the leader a driver follows, and constant speed.

use crate::config::Config;
use crate::num::Num;
use crate::world::geometry::Road;
use crate::world::idm::{idm_accel, idm_v0};
use crate::world::merge_gate::{GateRules, STOP_MARGIN};
use crate::world::neighbors::Neighbors;
use crate::world::rules::WorldRules;
use crate::world::safety::{Neighbor, feasible_interval_after};
use crate::world::state::Scene;
use crate::world::step::neighbor_of;

/// A non-learning driver.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Driver {
    /// Intelligent Driver Model: behind the same-lane leader; on the ramp also behind the
    /// nearest leader by distance to the conflict point (the vehicle it will merge behind),
    /// whichever asks for less acceleration; in the target lane, a driver who yields
    /// ([`yields_to`]) also behind the ramp vehicle it makes room for (as if it were
    /// [`yield_length`] long), when braking at `sim.b_safe` or less does it ([`makes_room`]);
    /// a driver too close for that drives on past it.
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
            let behind_by = |leader: Option<usize>, length: f64| {
                let leader = neighbor_of(scene, leader, me);
                idm_accel(&me.x, &me.v, &leader, length, &config.idm, v0.as_ref())
            };
            let behind = |leader: Option<usize>| behind_by(leader, config.vehicle.length);
            let lane = behind(n.lane_leader);
            // IDM behind a missing leader is the free-road acceleration, the largest: alone on
            // the ramp (the paper's ego) only the nearest leader counts.
            if me.on_ramp {
                lane.min(behind(n.leader))
            } else if let Some(j) = yields_to(&Road::new(config), scene, i, n.leader) {
                let room = behind_by(Some(j), yield_length(config));
                if makes_room(room, config.sim.b_safe) {
                    lane.min(room)
                } else {
                    lane
                }
            } else {
                lane
            }
        }
    }
}

/// The length a yielding driver gives the ramp vehicle it makes room for: its own plus
/// `sim.safety_gap`, so that even stopped behind it (IDM's `s0`) it leaves more than the entry
/// rule's clearance.
pub fn yield_length(config: &Config) -> f64 {
    config.vehicle.length + config.sim.safety_gap
}

/// Whether a yielding driver whose IDM acceleration behind the ramp vehicle would be `room`
/// makes room for it: only when that asks no harder braking than `sim.b_safe` (SUMO's drivers
/// cooperate within their comfortable deceleration). One already too close drives on past it,
/// rather than stop beside it and block its entry.
pub fn makes_room(room: f64, b_safe: f64) -> bool {
    room >= -b_safe
}

/// The ramp vehicle a human target-lane driver `i` makes room for, as SUMO's drivers do for a
/// vehicle that signals: its nearest leader (any lane), when that is a ramp vehicle in the merge
/// zone and `i` is a yielding human ([`Scene::is_yielding`], `traffic.cooperation`).
pub fn yields_to(road: &Road, scene: &Scene, i: usize, leader: Option<usize>) -> Option<usize> {
    let j = leader?;
    let other = &scene.vehicles[j];
    let yields =
        scene.is_yielding(i) && !scene.vehicles[i].on_ramp && other.on_ramp && road.in_yield_zone(other.x);
    yields.then_some(j)
}

/// The ramp vehicle a policy-driven target-lane player `i` makes room for under
/// `sim.players_make_room` ([`crate::world::step::applied_action_with`]): the first ramp
/// vehicle ahead of it in the yield zone, whatever target-lane vehicles are in between. With
/// its nearest leader only, the followers of a car too close to make room saw the ramp vehicle
/// only once it had passed (`i80_merge`, the game: 9.6 m/s against 10.2). A human driver
/// yields by its own rule ([`yields_to`]).
pub fn player_makes_room_for(road: &Road, scene: &Scene, i: usize) -> Option<usize> {
    let me = &scene.vehicles[i];
    if scene.is_human(i) || me.on_ramp {
        return None;
    }
    (scene.vehicles.iter().enumerate())
        .filter(|&(j, r)| r.on_ramp && r.x > me.x && road.in_yield_zone(r.x) && !scene.gives_way(j))
        .min_by(|(_, p), (_, q)| p.x.total_cmp(&q.x))
        .map(|(j, _)| j)
}

/// How a player at `(x, v)` makes room for ramp vehicle `ramp` (`sim.players_make_room`).
#[derive(Debug, Clone, PartialEq)]
pub struct Room<T> {
    /// The largest action (m/s^2) it takes: the projection's bound behind the ramp vehicle (TTC
    /// and time gap, as behind a leader) and, under the entry rule, [`secure_gap_bound`] too, so
    /// that the room it makes is a gap the entry rule lets the ramp vehicle into; under the entry
    /// rule never below `-b_safe`, where the projection's TTC alone asks more (a player closing
    /// on a slow ramp vehicle brakes at `b_safe` towards the secure gap). With the projection's
    /// bound alone a player at 27 m/s behind one at 25 m/s may keep 33 m (beyond the clearance)
    /// where the entry asks 40 m.
    pub bound: T,
    /// The bound whose feasibility decides whether it makes room at all ([`makes_room`]). Under
    /// the entry rule: the larger of the secure gap's behind the ramp vehicle as it is and behind
    /// it stopped at the ramp's end (where it is at the latest, waiting): a player that can still
    /// stop behind the ramp's end at `b_safe` makes room for a ramp vehicle however hard that one
    /// brakes. Judged by the ramp vehicle as it is, a player 80 m behind at 19 m/s gave up as
    /// soon as the vehicle braked for the lane's end, and the players passed a stopped ramp
    /// vehicle 1.4 s apart for 15 s (`acc60-v20`, the game). Else the projection's bound.
    pub reach: T,
}

/// How a player at `(x, v)` makes room for ramp vehicle `ramp` ([`Room`]).
pub fn make_room_bound<T: Num>(x: &T, v: &T, ramp: &Neighbor<T>, rules: &WorldRules) -> Room<T> {
    let absent = Neighbor {
        x: x.full(0.0),
        v: v.full(0.0),
        present: x.full(0.0),
    };
    let (_, room) = feasible_interval_after(x, v, ramp, &ramp.v, &absent, &rules.projection());
    match rules.gate.reaction_time {
        Some(t_r) => {
            let gate = &rules.gate;
            let secure = secure_gap_bound(x, v, &ramp.x, &ramp.v, t_r, gate);
            let end = x.full(gate.conflict_point - STOP_MARGIN);
            let at_end = secure_gap_bound(x, v, &end, &x.full(0.0), t_r, gate);
            Room {
                bound: room.min(&secure).max(&x.full(-gate.b_safe)),
                reach: secure.max(&at_end),
            }
        }
        None => Room {
            bound: room.clone(),
            reach: room,
        },
    }
}

/// The largest action (m/s^2) of a target-lane vehicle at `(x, v)` after which, one step on,
/// it is still a human driver's secure gap ([`crate::world::merge_gate::secure_gap`], reaction
/// time `t_r`, braking `rules.b_safe`) behind a vehicle at `(x_r, v_r)` keeping its speed:
/// the gap the entry rule asks of a new follower. Positions after this step do not depend on
/// the action (eq. 1), so with `D` the bumper gap (less `rules.clearance`) after two steps of
/// the ramp vehicle and one of the follower, the next speed `v'` must satisfy
/// `D - v' dt >= v' t_r + (v'^2 - v_r^2) / (2 b)`, that is
/// `v' <= -b k + sqrt((b k)^2 + 2 b D + v_r^2)` with `k = t_r + dt`. A gap too short for any
/// speed (root argument below 1) gives a bound below `-b k`, which no driver that brakes at
/// most `b_safe` meets ([`makes_room`] then declines).
pub fn secure_gap_bound<T: Num>(x: &T, v: &T, x_r: &T, v_r: &T, t_r: f64, rules: &GateRules) -> T {
    let (b, dt) = (rules.b_safe, rules.dt);
    let k = t_r + dt;
    let gap = x_r
        .add(&v_r.mul_c(2.0 * dt))
        .sub(&x.add(&v.mul_c(dt)))
        .add_c(-rules.clearance);
    let root = gap.mul_c(2.0 * b).add(&v_r.square()).add_c((b * k) * (b * k));
    let v_next = root.max(&root.full(1.0)).sqrt().add_c(-b * k);
    v_next.sub(v).mul_c(1.0 / dt)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::merge_gate::{GateRules, lane_change_is_safe};
    use crate::world::neighbors::find_neighbors;
    use crate::world::state::test_car as at;

    fn traffic_config() -> Config {
        let text =
            std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/configs/traffic.toml")).unwrap();
        Config::parse(&text, "traffic.toml").unwrap()
    }

    /// The IDM acceleration of human 1 behind ramp vehicle 0, yielding or not.
    fn accel(config: &Config, ramp: (f64, f64), human: (f64, f64), yields: bool) -> f64 {
        let scene = Scene {
            vehicles: vec![at(ramp.0, ramp.1, true), at(human.0, human.1, false)],
            humans: vec![false, true],
            yields: vec![yields; 2],
            gives_way: Vec::new(),
            zips: Vec::new(),
            excess: Vec::new(),
            v_desired: None,
        };
        let (mut order, mut nb) = (Vec::new(), Vec::new());
        find_neighbors(&scene, &mut order, &mut nb);
        driver_accel(config, Driver::Idm, &scene, 1, &nb[1])
    }

    #[test]
    fn a_yielding_driver_makes_room_for_a_ramp_vehicle_in_the_merge_zone_ahead() {
        // configs/traffic.toml: x_c 180, merge zone 40 m, IDM v0 15, T 1.5 s, s0 2 m, a 1, b 1.5.
        let config = traffic_config();
        // Free road at 10 m/s: 1 - (10/15)^4 = 0.802469.
        let free = 1.0 - (10.0f64 / 15.0).powi(4);
        assert!((accel(&config, (150.0, 10.0), (130.0, 10.0), false) - free).abs() < 1e-12);
        // Yielding, behind the ramp vehicle at 150 as if it were 7 m long: gap 13 m, s* = 2 +
        // 10 * 1.5 = 17 m, so 1 - 0.197531 - (17/13)^2 = -0.907590.
        let room = 1.0 - (10.0f64 / 15.0).powi(4) - (17.0f64 / 13.0).powi(2);
        assert!((accel(&config, (150.0, 10.0), (130.0, 10.0), true) - room).abs() < 1e-12);
        assert!((room + 0.907590).abs() < 1e-6);
        // Not for a ramp vehicle before the yield zone (scenario.yield_zone 120 m: 60 m), nor
        // one behind it; for one in it before the merge zone, yes.
        assert!((accel(&config, (59.0, 10.0), (39.0, 10.0), true) - free).abs() < 1e-12);
        assert!((accel(&config, (61.0, 10.0), (41.0, 10.0), true) - room).abs() < 1e-12);
        assert!((accel(&config, (150.0, 10.0), (155.0, 10.0), true) - free).abs() < 1e-12);
        // Never harder than b_safe (4 m/s^2): 7.5 m behind a stopped ramp vehicle at 10 m/s it
        // would need far more (gap 0.5 m against s* = 2 + 15 + 10 * 10 / (2 sqrt 1.5) = 57.8 m),
        // so it drives on past it, at the free-road acceleration.
        assert!((accel(&config, (140.5, 0.0), (133.0, 10.0), true) - free).abs() < 1e-12);
        assert!(!makes_room(-4.01, config.sim.b_safe) && makes_room(-4.0, config.sim.b_safe));
    }

    #[test]
    fn a_player_makes_room_for_the_first_ramp_vehicle_ahead_in_the_merge_zone() {
        // configs/traffic.toml: x_c 180, merge zone from 140 m, clearance 7 m, time gap 1 s,
        // tau_s 3 s, dt 0.1 s, b_safe 4. Ramp vehicle R at 164.8 m, 4 m/s; target-lane car T at
        // 150 m and player P at 130 m, both at 10 m/s.
        use crate::world::rules::WorldRules;
        use crate::world::step::applied_action;
        let mut config = traffic_config();
        let scene = Scene::new(vec![
            at(164.8, 4.0, true),
            at(150.0, 10.0, false),
            at(130.0, 10.0, false),
        ]);
        let (mut order, mut nb) = (Vec::new(), Vec::new());
        find_neighbors(&scene, &mut order, &mut nb);
        let act = |config: &Config, scene: &Scene, i: usize| {
            applied_action(&WorldRules::new(config), true, scene, i, &nb[i], 0.0)
        };
        let road = Road::new(&config);
        assert_eq!(player_makes_room_for(&road, &scene, 2), Some(0));
        // P behind R: one step on the gap less the clearance is 164.8 + 0.4 - 131 - 7 = 27.2 m,
        // so v' <= (4 + 27.2 / 3) / (1 + 1 / 3) = 9.8: a = -2, within b_safe. Behind T alone
        // (13 m) it could keep its speed.
        config.sim.players_make_room = true;
        assert!(
            (act(&config, &scene, 2) + 2.0).abs() < 1e-9,
            "{}",
            act(&config, &scene, 2)
        );
        // T is too close to R to make room (v' <= (4 + 7.2 / 3) * 0.75 = 4.8: a = -52), and to
        // stop behind the ramp's end at b_safe (v' <= -4.4 + sqrt(4.4^2 + 8 * 21.9) = 9.55: a =
        // -4.5): it drives on past it.
        assert_eq!(act(&config, &scene, 1), 0.0);
        // A human driver yields by its own rule only; without the setting nobody does.
        let human = Scene {
            humans: vec![false, false, true],
            ..scene.clone()
        };
        assert_eq!(player_makes_room_for(&road, &human, 2), None);
        // Nor does a player for a ramp vehicle that gives way to it (a junction's minor road).
        let minor = Scene {
            gives_way: vec![true, false, false],
            ..scene.clone()
        };
        assert_eq!(player_makes_room_for(&road, &minor, 2), None);
        assert_eq!(act(&config, &minor, 2), 0.0);
        config.sim.players_make_room = false;
        assert_eq!(act(&config, &scene, 2), 0.0);
    }

    #[test]
    fn a_player_follows_a_ramp_vehicle_ahead_that_takes_its_turn_at_a_zipper() {
        // The scene above (x_c 180, clearance 7 m, time gap 1 s, tau_s 3 s, dt 0.1 s): ramp
        // vehicle R at 164.8 m, 4 m/s; T at 150 m and P at 130 m, both at 10 m/s; no room made.
        use crate::world::rules::WorldRules;
        use crate::world::step::applied_action;
        let mut config = traffic_config();
        config.sim.players_make_room = false;
        let scene = Scene::new(vec![
            at(164.8, 4.0, true),
            at(150.0, 10.0, false),
            at(130.0, 10.0, false),
        ]);
        let zipper = Scene {
            zips: vec![true, false, false],
            ..scene.clone()
        };
        let (mut order, mut nb) = (Vec::new(), Vec::new());
        find_neighbors(&scene, &mut order, &mut nb);
        let act =
            |scene: &Scene, i: usize| applied_action(&WorldRules::new(&config), true, scene, i, &nb[i], 0.0);
        assert_eq!((act(&scene, 1), act(&scene, 2)), (0.0, 0.0));
        // R takes its turn: T, 7.2 m behind it one step on (less the clearance), brakes as behind
        // a leader, v' <= (4 + 7.2 / 3) * 0.75 = 4.8, a = -52, at g; P keeps the projection's
        // gap behind R (the first of them ahead, past T): v' <= (4 + 27.2 / 3) * 0.75 = 9.8.
        assert_eq!(act(&zipper, 1), -config.vehicle.max_accel);
        assert!((act(&zipper, 2) + 2.0).abs() < 1e-9, "{}", act(&zipper, 2));
    }

    #[test]
    fn a_player_makes_the_room_the_entry_rule_asks_of_a_new_follower() {
        // configs/traffic.toml: clearance 7 m, dt 0.1 s, reaction time 1 s, b_safe 4. Player P
        // at 0 m, 27 m/s, behind ramp vehicle R at 50 m, 25 m/s: after two steps of R and one
        // of P the gap is 50 + 5 - 2.7 - 7 = 45.3 m, so v' <= -4.4 + sqrt(4.4^2 + 8 * 45.3 +
        // 25^2) = 27.329482 and a <= 3.294816.
        use crate::world::rules::WorldRules;
        let rules = WorldRules::new(&traffic_config());
        let gate = &rules.gate;
        let bound = secure_gap_bound(&0.0, &27.0, &50.0, &25.0, 1.0, gate);
        assert!((bound - 3.294_816).abs() < 1e-6, "{bound}");
        // Independently: at that action, the step after next leaves exactly the secure gap.
        let v_next = 27.0 + bound * gate.dt;
        let gap = (50.0 + 2.0 * 25.0 * gate.dt) - (27.0 * gate.dt + v_next * gate.dt) - gate.clearance;
        let secure = crate::world::merge_gate::secure_gap(v_next, 25.0, 1.0, gate.b_safe);
        assert!((gap - secure).abs() < 1e-9, "{gap} {secure}");
        // The projection's bound (TTC 3 s, 1 s time gap) is far looser here, (25 + 42.8 / 3)
        // * 0.75 = 29.45 m/s, a <= 24.5: the bound kept is the entry's. 10 m closer, the entry's
        // gap asks a <= -9.57, more than b_safe; P still makes room, braking at b_safe, for it can
        // stop behind the ramp's end, 180 m on (test above).
        let ramp = Neighbor {
            x: 50.0,
            v: 25.0,
            present: 1.0,
        };
        assert_eq!(make_room_bound(&0.0, &27.0, &ramp, &rules).bound, bound);
        let close = make_room_bound(&0.0, &27.0, &Neighbor { x: 40.0, ..ramp }, &rules);
        assert!(makes_room(close.reach, gate.b_safe));
        assert_eq!(close.bound, -gate.b_safe);
        let entry = secure_gap_bound(&0.0, &27.0, &40.0, &25.0, 1.0, gate);
        assert!((entry + 9.57).abs() < 0.01, "{entry}");
    }

    #[test]
    fn a_player_that_can_stop_behind_the_ramps_end_makes_room_however_hard_the_ramp_vehicle_brakes() {
        // configs/traffic.toml: the ramp ends at x_c = 180 m (a stopped vehicle's centre at
        // 179.9), clearance 7 m, reaction time 1 s, b_safe 4, dt 0.1. Ramp vehicle R at 150 m
        // braking through 4 m/s; player P at 90 m, 19 m/s. Behind R as it is, the secure gap
        // (150 + 0.8 - 91.9 - 7 = 51.9 m) asks v' <= -4.4 + sqrt(4.4^2 + 8 * 51.9 + 16) =
        // 16.826 (a = -21.74); behind R stopped at the ramp's end (179.9 - 91.9 - 7 = 81 m),
        // v' <= -4.4 + sqrt(4.4^2 + 8 * 81) = 21.433 (a = 24.33). P can stop there, so it makes
        // room, braking at b_safe.
        use crate::world::rules::WorldRules;
        let rules = WorldRules::new(&traffic_config());
        let ramp = Neighbor {
            x: 150.0,
            v: 4.0,
            present: 1.0,
        };
        let room = make_room_bound(&90.0, &19.0, &ramp, &rules);
        assert!((room.reach - 24.333_118).abs() < 1e-5, "{}", room.reach);
        assert!(makes_room(room.reach, rules.gate.b_safe));
        assert_eq!(room.bound, -rules.gate.b_safe);
        // 30 m further on it can do neither (-88.9 behind R, -27.3 behind the end): it drives on.
        let late = make_room_bound(&120.0, &19.0, &ramp, &rules);
        assert!((late.reach + 27.273_127).abs() < 1e-5, "{}", late.reach);
        assert!(!makes_room(late.reach, rules.gate.b_safe));
    }

    #[test]
    fn gaps_to_a_vehicle_longer_than_the_worlds_car_are_its_bumper_gaps() {
        // A 16.5 m truck (excess (16.5 - 5) / 2 = 5.75 m). The entry rule: stopped 9 m behind a
        // ramp vehicle stopped at the ramp's end, a car leaves a 4 m bumper gap and the ramp
        // vehicle may enter (test below); the truck's rear is 5.75 m further ahead (-1.75 m).
        // 20 m behind, its bumper gap is 20 - 2.5 - 8.25 = 9.25 m, 2.25 m beyond the clearance.
        use crate::world::rules::WorldRules;
        use crate::world::step::applied_action;
        let config = traffic_config();
        let truck = |scene: Scene, k: usize| {
            let mut excess = vec![0.0; scene.len()];
            excess[k] = 5.75;
            Scene { excess, ..scene }
        };
        let gate = GateRules::new(&config);
        let behind = |d: f64| Scene::new(vec![at(179.9, 0.0, true), at(179.9 - d, 0.0, false)]);
        assert!(lane_change_is_safe(&behind(9.0), 0, &gate));
        assert!(!lane_change_is_safe(&truck(behind(9.0), 1), 0, &gate));
        assert!(lane_change_is_safe(&truck(behind(20.0), 1), 0, &gate));
        // The projection: player P at 130 m behind T at 150 m, both at 10 m/s (clearance 7 m,
        // tau_s 3 s, time gap 1 s). Behind a car the gap one step on is 13 m, v' <= (10 + 13 /
        // 3) * 0.75 = 10.75, and P keeps its speed; behind the truck it is 7.25 m, v' <= (10 +
        // 7.25 / 3) * 0.75 = 9.3125, a = -6.875.
        let lane = Scene::new(vec![at(150.0, 10.0, false), at(130.0, 10.0, false)]);
        let (mut order, mut nb) = (Vec::new(), Vec::new());
        find_neighbors(&lane, &mut order, &mut nb);
        let act = |scene: &Scene| applied_action(&WorldRules::new(&config), true, scene, 1, &nb[1], 0.0);
        assert_eq!(act(&lane), 0.0);
        assert!(
            (act(&truck(lane.clone(), 0)) + 6.875).abs() < 1e-9,
            "{}",
            act(&truck(lane.clone(), 0))
        );
    }

    #[test]
    fn a_yielding_driver_stopped_behind_a_waiting_ramp_vehicle_leaves_it_room_to_enter() {
        // Stopped 9 m behind a ramp vehicle waiting at the ramp's end (179.9 m): IDM's s0 = 2 m
        // behind a 7 m vehicle, so it stays (1 - 0 - (2/2)^2 = 0) and the bumper gap, 4 m, leaves
        // 2 m beyond the entry rule's 7 m clearance: the ramp vehicle may enter.
        let config = traffic_config();
        assert_eq!(accel(&config, (179.9, 0.0), (170.9, 0.0), true), 0.0);
        let scene = Scene::new(vec![at(179.9, 0.0, true), at(170.9, 0.0, false)]);
        assert!(lane_change_is_safe(&scene, 0, &GateRules::new(&config)));
        let closer = Scene::new(vec![at(179.9, 0.0, true), at(172.9, 0.0, false)]);
        assert!(!lane_change_is_safe(&closer, 0, &GateRules::new(&config)));
    }
}
