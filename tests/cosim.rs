//! Co-simulation against the internal simulator: the same initial state placed into SUMO
//! (sumo_nets/single_lane_merge) and into the internal simulator, the same policy driving all
//! nine players, gives ego trajectories that agree; and a merge-traffic episode of several
//! egos under the traffic policy agrees vehicle by vehicle.
#![cfg(feature = "sumo")]

mod common;

use common::paper;
use mpgdrive::config::Config;
use mpgdrive::engine::rollout::{Recording, RolloutOptions, rollout};
use mpgdrive::policy::PolicyActor;
use mpgdrive::policy::file::load;
use mpgdrive::policy::observation::Layout;
use mpgdrive::sumo::inputs::check_geometry;
use mpgdrive::sumo::{Backend, ControlModes, Controller, ControllerKind, MergeGeometry, NewVehicle, Sumo};
use mpgdrive::world::drivers::Driver;
use mpgdrive::world::sampler::{Purpose, purpose_seed, sample_scenes};
use mpgdrive::world::state::Scene;
use std::path::Path;
use std::sync::Mutex;

static SUMO: Mutex<()> = Mutex::new(());

const NET: &str = "sumo_nets/single_lane_merge";
const POLICY: &str = "policies/mpg/seed0";
const TRAFFIC_POLICY: &str = "policies/traffic/mpg/seed0";
/// Where `single_lane_merge`'s last edge ends (network x, m): SUMO takes a vehicle off there.
const NET_END: f64 = 600.0;

/// The `maxSpeed` of the network's vehicle types (`merge.rou.xml`), m/s.
const NET_TYPE_MAX_SPEED: f64 = 30.0;

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

/// Every vehicle's centre x per step in SUMO, `policy` driving the vehicles `geometry` gives
/// it (ramp vehicles are of the controllable type).
fn sumo_tracks(
    config: &Config,
    geometry: MergeGeometry,
    policy: &str,
    scene: &Scene,
    steps: usize,
) -> Vec<Vec<f64>> {
    let (net, _) = load(Path::new(policy), Layout::of(config)).unwrap();
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
            vtype: if v.on_ramp { "ctrl" } else { "human" },
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
        // No speed or lane change of SUMO's own before the controller takes over (a vehicle
        // placed on an acceleration lane would change lanes in the first step).
        sumo.set_speed_mode(&id, 0).unwrap();
        sumo.set_lane_change_mode(&id, 0).unwrap();
        sumo.set_speed(&id, v.v).unwrap();
    }
    let positions = check_geometry(
        &geometry,
        Path::new("merge.toml"),
        &Path::new(NET).join("merge.net.xml"),
    )
    .unwrap();
    let mut controller = Controller::new(
        config.clone(),
        geometry,
        positions,
        ControllerKind::Mpg,
        Some(net.into()),
        ControlModes::EXACT,
    );
    let mut tracks = Vec::new();
    for _ in 0..=steps {
        sumo.step().unwrap();
        if tracks.is_empty() {
            assert_eq!(
                sumo.vehicle_ids().unwrap().len(),
                scene.len(),
                "every vehicle inserted at once"
            );
        }
        let xs = (0..scene.len())
            .map(|i| {
                let v = sumo.vehicle(&format!("p{i}")).unwrap();
                v.x - 0.5 * v.length
            })
            .collect();
        tracks.push(xs);
        controller.step(&mut sumo).unwrap();
    }
    tracks
}

/// Every vehicle's centre x per step in the internal simulator, `policy` driving all, and the
/// number of steps the episode ran (it ends at a collision).
fn internal_tracks(config: &Config, policy: &str, scene: &Scene, steps: usize) -> (Vec<Vec<f64>>, usize) {
    let mut config = config.clone();
    config.sim.horizon = steps as f64 * config.sim.dt;
    let (net, _) = load(Path::new(policy), Layout::of(&config)).unwrap();
    let opts = RolloutOptions {
        recording: Recording::Full,
        threads: 1,
        ..RolloutOptions::from_config(&config)
    };
    let slot = Mutex::new(Some(net));
    let out = rollout(&config, &opts, std::slice::from_ref(scene), || {
        PolicyActor::new(&config, slot.lock().unwrap().take().unwrap(), Driver::Idm, true)
    });
    let tracks = out[0]
        .trajectory
        .as_ref()
        .unwrap()
        .states
        .chunks(scene.len())
        .map(|s| s.iter().map(|v| v.x).collect())
        .collect();
    (tracks, out[0].steps)
}

#[test]
fn sumo_and_the_internal_simulator_agree_on_the_ego_trajectory() {
    // The acceptance asks for 0.5 m over 10 s. With the one-step speed lag of the controller
    // (src/sumo/controller.rs) and lanes whose length equals their drawn length, the two agree
    // to rounding from the initial state through the merge at x_c = 180 m until the controller
    // releases the ego 50 m later; from then on SUMO drives it. The rounding is that of two
    // forward passes of one network: libtorch's in the internal simulator, the deployment's
    // plain Rust one in SUMO (actions within 1e-5 m/s^2; measured: at most 6e-6 m here, and
    // 2e-13 m when both used libtorch). A mismatch of the integration or the lanes would be
    // centimetres at least.
    let _turn = SUMO.lock().unwrap_or_else(|e| e.into_inner());
    let config = paper();
    let mut geometry = MergeGeometry::load(&Path::new(NET).join("merge.toml")).unwrap();
    geometry.merge_from = None; // the internal simulator's merge, at x_c
    geometry.control_from = 40.0; // every sampled ego (40-120 m before x_c) starts under control
    let release = geometry.conflict_point + geometry.release_after;
    let steps = 250; // 25 s
    for scene in sample_scenes(&config, purpose_seed(0, Purpose::Test), 0, 3) {
        let internal: Vec<f64> = internal_tracks(&config, POLICY, &scene, steps)
            .0
            .iter()
            .map(|x| x[0])
            .collect();
        let sumo: Vec<f64> = sumo_tracks(&config, geometry.clone(), POLICY, &scene, steps)
            .iter()
            .map(|x| x[0])
            .collect();
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
        assert!(worst < 1e-4, "worst {worst} m");
    }
}

#[test]
fn sumo_and_the_internal_traffic_world_agree_on_a_multi_ego_episode() {
    // Merge traffic: 3 ramp vehicles (each an ego in SUMO) and 10 target-lane vehicles, all on
    // the traffic policy, in SUMO's exact modes. The control zone covers the whole network so
    // that SUMO drives every vehicle by the policy, as the internal world does; the densest
    // demand keeps every vehicle on the network. Acceptance: within 0.5 m over 10 s.
    let _turn = SUMO.lock().unwrap_or_else(|e| e.into_inner());
    let mut config = common::traffic();
    let t = config.traffic.as_mut().unwrap();
    t.lane_flow = [t.lane_flow[1]; 2];
    t.ramp_flow = [t.ramp_flow[1]; 2];
    let mut geometry = MergeGeometry::load(&Path::new(NET).join("merge.toml")).unwrap();
    geometry.control_from = -1000.0;
    geometry.release_after = 1000.0;
    // Under the entry rule the world's ramp ends, and its conflict point is, where the
    // network's acceleration lane ends (x = 200 m), a centre half a length before it: the
    // controller puts it there whatever merge.toml says, so the internal world is set there too.
    config.scenario.conflict_point = 200.0 - 0.5 * config.vehicle.length;
    // Ramp vehicles merge early as the traffic world's do: from merge_zone before x_c.
    geometry.merge_from = Some(config.scenario.conflict_point - config.scenario.merge_zone);
    let steps = 100;
    // The first two episodes that stay on the network (front bumpers short of NET_END), run
    // 10 s without a collision (an internal episode ends at its first one) and include a merge
    // (a ramp vehicle past x_c).
    let episodes: Vec<(Scene, Vec<Vec<f64>>)> = sample_scenes(&config, 5, 0, 60)
        .into_iter()
        .filter(|s| {
            // Each vehicle is placed one step back on its first edge (sumo_tracks), at a speed
            // its vehicle type allows (the network's types drive at most 30 m/s; the traffic
            // world's desired speeds reach 36).
            s.vehicles.iter().all(|v| {
                depart(v.x, v.on_ramp, config.vehicle.length).2 - v.v * config.sim.dt > 0.0
                    && v.v <= NET_TYPE_MAX_SPEED
            })
        })
        .filter_map(|mut s| {
            s.humans.clear();
            let (internal, ran) = internal_tracks(&config, TRAFFIC_POLICY, &s, steps);
            let on_network = internal
                .iter()
                .flatten()
                .all(|&x| x + 0.5 * config.vehicle.length < NET_END - 1.0);
            let merges = |last: &[f64]| {
                last.iter()
                    .zip(&s.vehicles)
                    .any(|(x, v)| v.on_ramp && *x >= config.scenario.conflict_point)
            };
            let kept = ran == steps && on_network && merges(&internal[steps - 1]);
            kept.then_some((s, internal))
        })
        .take(2)
        .collect();
    assert_eq!(episodes.len(), 2);
    for (scene, internal) in &episodes {
        // The policy observes the episode's desired speed in SUMO too (merge.toml's key).
        let geometry = MergeGeometry {
            name: None,
            desired_speed: scene.v_desired,
            ..geometry.clone()
        };
        let sumo = sumo_tracks(&config, geometry, TRAFFIC_POLICY, scene, steps);
        let ran = steps;
        let worst = internal[..ran]
            .iter()
            .zip(&sumo)
            .flat_map(|(a, b)| a.iter().zip(b).map(|(x, y)| (x - y).abs()))
            .fold(0.0, f64::max);
        eprintln!("traffic episode: worst |dx| over 13 vehicles and 10 s = {worst:.3e} m");
        assert!(worst < 0.5, "worst {worst} m");
    }
}
