//! The libsumo FFI layer: SUMO's errors come back as typed errors with SUMO's message, one
//! simulation per process, and a new simulation after close works.
#![cfg(feature = "sumo")]

use mpgdrive::sumo::{Backend, NewVehicle, Sumo, SumoError};
use std::sync::Mutex;

/// libsumo holds one simulation per process; tests of this file take turns.
static SUMO: Mutex<()> = Mutex::new(());

fn args(cfg: &str) -> Vec<String> {
    [
        "sumo",
        "-c",
        cfg,
        "--no-warnings",
        "true",
        "--no-step-log",
        "true",
    ]
    .iter()
    .map(|s| s.to_string())
    .chain(["--tripinfo-output", "/dev/null", "--device.ssm.file", "/dev/null"].map(String::from))
    .collect()
}

const MERGE: &str = "sumo_nets/single_lane_merge/merge.sumocfg";

#[test]
fn unknown_vehicle_gives_sumos_message() {
    let _turn = SUMO.lock().unwrap_or_else(|e| e.into_inner());
    let sumo = Sumo::start(Backend::Libsumo, &args(MERGE)).expect("start");
    match sumo.vehicle("no-such-car") {
        Err(SumoError::Sumo { call, message }) => {
            assert_eq!(call, "vehicle state");
            assert!(message.contains("no-such-car"), "{message}");
            assert!(message.contains("not known"), "{message}");
        }
        other => panic!("expected SUMO's error, got {other:?}"),
    }
}

#[test]
fn a_second_start_is_refused_and_a_start_after_close_works() {
    let _turn = SUMO.lock().unwrap_or_else(|e| e.into_inner());
    let mut first = Sumo::start(Backend::Libsumo, &args(MERGE)).expect("start");
    assert!(matches!(
        Sumo::start(Backend::Libsumo, &args(MERGE)),
        Err(SumoError::AlreadyRunning)
    ));
    first.step().expect("step");
    assert!((first.time().unwrap() - 0.1).abs() < 1e-9);
    first.close().expect("close");
    // A fresh simulation starts at time 0 and runs.
    let mut second = Sumo::start(Backend::Libsumo, &args(MERGE)).expect("start after close");
    assert_eq!(second.time().unwrap(), 0.0);
    for _ in 0..20 {
        second.step().expect("step");
    }
    assert!((second.time().unwrap() - 2.0).abs() < 1e-9);
}

#[test]
fn a_bad_configuration_is_an_error_not_a_panic() {
    let _turn = SUMO.lock().unwrap_or_else(|e| e.into_inner());
    let err = Sumo::start(Backend::Libsumo, &args("sumo_nets/no/such.sumocfg")).err();
    assert!(
        matches!(err, Some(SumoError::Sumo { call: "start", .. })),
        "{err:?}"
    );
    // The failed start left nothing running.
    drop(Sumo::start(Backend::Libsumo, &args(MERGE)).expect("start after a failed start"));
}

#[test]
fn an_added_vehicle_drives_at_the_commanded_speed() {
    let _turn = SUMO.lock().unwrap_or_else(|e| e.into_inner());
    let mut sumo = Sumo::start(Backend::Libsumo, &args(MERGE)).expect("start");
    sumo.add_route("test_route", &["main", "merge", "out"]).unwrap();
    sumo.add_vehicle(&NewVehicle {
        id: "probe",
        route: "test_route",
        vtype: "ctrl",
        lane: "0",
        pos: "105",
        speed: "10",
    })
    .unwrap();
    sumo.step().unwrap();
    let s = sumo.vehicle("probe").unwrap();
    assert_eq!(sumo.lane_id("probe").unwrap(), "main_0");
    assert_eq!(sumo.type_id("probe").unwrap(), "ctrl");
    // Front bumper at lane position 105 on a lane starting at x = -200.
    assert!(
        (s.lane_pos - 105.0).abs() < 1e-9 && (s.x + 95.0).abs() < 1e-9,
        "{s:?}"
    );
    sumo.set_speed_mode("probe", 0).unwrap();
    sumo.set_color("probe", [220, 20, 20]).unwrap();
    assert!(sumo.set_color("nobody", [0, 0, 0]).is_err());
    sumo.set_speed("probe", 12.0).unwrap();
    sumo.step().unwrap();
    let t = sumo.vehicle("probe").unwrap();
    assert!((t.speed - 12.0).abs() < 1e-9, "{t:?}");
    assert!((t.accel - 20.0).abs() < 1e-6, "(12 - 10) / 0.1 = 20 m/s^2: {t:?}");
}

#[test]
fn libtraci_runs_sumo_in_another_process_with_the_same_calls() {
    // The --gui path: the same shim over libtraci, here with the headless binary.
    let _turn = SUMO.lock().unwrap_or_else(|e| e.into_inner());
    let mut sumo = Sumo::start(Backend::Traci, &args(MERGE)).expect("start sumo through libtraci");
    assert_eq!(sumo.backend_name(), "traci");
    for _ in 0..10 {
        sumo.step().unwrap();
    }
    assert!((sumo.time().unwrap() - 1.0).abs() < 1e-9);
    match sumo.vehicle("no-such-car") {
        Err(SumoError::Sumo { message, .. }) => assert!(message.contains("no-such-car"), "{message}"),
        other => panic!("expected SUMO's error, got {other:?}"),
    }
    sumo.close().expect("close");
}
