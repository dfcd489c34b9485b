//! Co-simulation against the internal simulator: the same initial state placed into SUMO
//! (sumo_nets/single_lane_merge) and into the internal simulator, the same policy driving all
//! nine players, gives ego trajectories that agree.
#![cfg(feature = "sumo")]

mod common;

use common::paper;
use mpgdrive::engine::rollout::{Recording, RolloutOptions, rollout};
use mpgdrive::policy::PolicyActor;
use mpgdrive::policy::file::load;
use mpgdrive::policy::observation::Layout;
use mpgdrive::sumo::{Backend, ControlModes, Controller, ControllerKind, MergeGeometry, NewVehicle, Sumo};
use mpgdrive::world::drivers::Driver;
use mpgdrive::world::sampler::{Purpose, purpose_seed, sample_scenes};
use mpgdrive::world::state::Scene;
use std::path::Path;
use std::sync::Mutex;

static SUMO: Mutex<()> = Mutex::new(());

const NET: &str = "sumo_nets/single_lane_merge";
const POLICY: &str = "policies/mpg/seed0";

/// Where a vehicle whose centre is at `x` departs: (route, lane, position of the front bumper
/// on the route's first edge). Edge starts: main and ramp -200, merge 100, out 200.
fn depart(x: f64, on_ramp: bool, length: f64) -> (&'static str, &'static str, f64) {
    let front = x + 0.5 * length;
    match (on_ramp, front) {
        (true, f) if f < 100.0 => ("r_ramp", "0", f + 200.0),
        (true, f) => ("r_merge", "0", f - 100.0),
        (false, f) if f < 100.0 => ("r_main", "0", f + 200.0),
        (false, f) if f < 200.0 => ("r_merge", "1", f - 100.0),
        (false, f) => ("r_out", "0", f - 200.0),
    }
}

/// Ego centre x per step in SUMO, with the policy driving all nine players.
fn sumo_ego_track(scene: &Scene, steps: usize) -> Vec<f64> {
    let config = paper();
    let geometry = MergeGeometry::load(&Path::new(NET).join("merge.toml")).unwrap();
    let (net, _) = load(Path::new(POLICY), Layout::of(&config)).unwrap();
    let args: Vec<String> = [
        "sumo",
        "-c",
        "sumo_nets/single_lane_merge/merge.sumocfg",
        "--scale",
        "0",
        "--no-step-log",
        "true",
        "--no-warnings",
        "true",
        "--tripinfo-output",
        "/dev/null",
        "--device.ssm.file",
        "/dev/null",
    ]
    .map(String::from)
    .to_vec();
    let mut sumo = Sumo::start(Backend::Libsumo, &args).unwrap();
    for (id, edges) in [
        ("r_main", &["main", "merge", "out"][..]),
        ("r_ramp", &["ramp", "merge", "out"][..]),
        ("r_merge", &["merge", "out"][..]),
        ("r_out", &["out"][..]),
    ] {
        sumo.add_route(id, edges).unwrap();
    }
    for (i, v) in scene.vehicles.iter().enumerate() {
        let (route, lane, pos) = depart(v.x, v.on_ramp, config.vehicle.length);
        let id = format!("p{i}");
        sumo.add_vehicle(&NewVehicle {
            id: &id,
            route,
            vtype: if i == 0 { "ctrl" } else { "human" },
            lane,
            pos: &format!("{pos:.6}"),
            speed: &format!("{:.6}", v.v),
        })
        .unwrap();
        // Insert now, past SUMO's insertion checks (the sampled headways can be shorter than
        // Krauss's safe gap), one step's travel back, and hold the speed through the first step
        // (SUMO moves x' = x + v' dt): after it the vehicle is exactly at the sampled state.
        let first_edge = match route {
            "r_main" => "main",
            "r_ramp" => "ramp",
            "r_merge" => "merge",
            _ => "out",
        };
        sumo.move_to(&id, &format!("{first_edge}_{lane}"), pos - v.v * config.sim.dt)
            .unwrap();
        sumo.set_speed_mode(&id, 0).unwrap();
        sumo.set_speed(&id, v.v).unwrap();
    }
    let mut controller = Controller::new(
        config.clone(),
        geometry,
        ControllerKind::Mpg,
        Some(net),
        ControlModes::EXACT,
    );
    let mut xs = Vec::new();
    for _ in 0..=steps {
        sumo.step().unwrap();
        if xs.is_empty() {
            assert_eq!(
                sumo.vehicle_ids().unwrap().len(),
                9,
                "every player inserted at once"
            );
        }
        let ego = sumo.vehicle("p0").unwrap();
        xs.push(ego.x - 0.5 * ego.length);
        controller.step(&mut sumo).unwrap();
    }
    xs
}

/// Ego centre x per step in the internal simulator.
fn internal_ego_track(scene: &Scene, steps: usize) -> Vec<f64> {
    let mut config = paper();
    config.sim.horizon = steps as f64 * config.sim.dt;
    let (net, _) = load(Path::new(POLICY), Layout::of(&config)).unwrap();
    let opts = RolloutOptions {
        recording: Recording::Full,
        threads: 1,
        ..RolloutOptions::from_config(&config)
    };
    let slot = Mutex::new(Some(net));
    let out = rollout(&config, &opts, std::slice::from_ref(scene), || {
        PolicyActor::new(&config, slot.lock().unwrap().take().unwrap(), Driver::Idm, true)
    });
    let n = config.n_agents();
    out[0]
        .trajectory
        .as_ref()
        .unwrap()
        .states
        .chunks(n)
        .map(|s| s[0].x)
        .collect()
}

#[test]
fn sumo_and_the_internal_simulator_agree_on_the_ego_trajectory() {
    // The acceptance asks for 0.5 m over 10 s. With the one-step speed lag of the controller
    // (src/sumo/controller.rs) and lanes whose length equals their drawn length, the two agree
    // to rounding (measured: about 2e-13 m) from the initial state through the merge at
    // x_c = 180 m until the controller releases the ego 50 m later; from then on SUMO drives it.
    let _turn = SUMO.lock().unwrap_or_else(|e| e.into_inner());
    let config = paper();
    let geometry = MergeGeometry::load(&Path::new(NET).join("merge.toml")).unwrap();
    let release = geometry.conflict_point + geometry.release_after;
    let steps = 250; // 25 s
    for scene in sample_scenes(&config, purpose_seed(0, Purpose::Test), 0, 3) {
        let internal = internal_ego_track(&scene, steps);
        let sumo = sumo_ego_track(&scene, steps);
        let controlled = internal.iter().take_while(|&&x| x < release).count();
        assert!(
            controlled >= 100,
            "at least 10 s under control: {controlled} steps"
        );
        assert!(
            internal[controlled - 1] >= geometry.conflict_point,
            "the comparison includes the merge"
        );
        let worst = internal[..controlled]
            .iter()
            .zip(&sumo)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        eprintln!(
            "ego x0 {:.1}: worst |dx| over {:.1} s = {worst:.3e} m",
            scene.vehicles[0].x,
            controlled as f64 * config.sim.dt
        );
        assert!(worst < 1e-6, "worst {worst} m");
    }
}
