//! The penetration study (`mpgdrive study`): SUMO's outputs read into its quantities (hand
//! computed from written files), the rows and the share from which the game beats SUMO's
//! drivers, and a short study in SUMO on a network built here, where at a share of 0 nobody is
//! controlled and the game's figures are SUMO's drivers' exactly.

mod common;

use common::fresh_dir;
use mpgdrive::batch::penetration::{
    Conflicts, Quantity, Spread, StudyRun, Trips, apart, break_even, markdown, merge_cost_removed, rows,
};

#[test]
fn trips_count_every_vehicle_with_its_insertion_delay() {
    let dir = fresh_dir("study-trips");
    let path = dir.join("tripinfo.xml");
    std::fs::write(
        &path,
        r#"<tripinfos>
    <tripinfo id="a" depart="1.00" departDelay="1.00" arrival="50.00" duration="49.00" routeLength="1000.00" timeLoss="2.00" vType="human"/>
    <tripinfo id="b" depart="3.00" departDelay="0.00" arrival="60.00" duration="57.00" routeLength="500.00" timeLoss="4.00" vType="ctrl"/>
    <tripinfo id="c" depart="80.00" departDelay="6.00" arrival="-1.00" duration="20.00" routeLength="250.00" timeLoss="3.00" vType="human" vaporized="end"/>
</tripinfos>"#,
    )
    .unwrap();
    let trips = Trips::read(&path, &["ctrl".to_string()]).unwrap();
    // Losses with delays: a 3, b 4, c 9; the non-controllable a and c: 12 over 2.
    assert_eq!((trips.vehicles, trips.arrived, trips.uncontrolled), (3, 2, 2));
    assert!((trips.time_loss - 16.0).abs() < 1e-12);
    assert!((trips.uncontrolled_time_loss - 12.0).abs() < 1e-12);
    assert!((trips.vehicle_km - 1.75).abs() < 1e-12);
    let run = StudyRun {
        share: 0.3,
        seed: 0,
        game: true,
        duration: 100.0,
        trips,
        conflicts: Conflicts { all: 7, severe: 0 },
        ego_speed: None,
        controlled_collisions: 0,
    };
    assert!((Quantity::TimeLoss.of(&run).unwrap() - 16.0 / 3.0).abs() < 1e-12);
    assert!((Quantity::UncontrolledTimeLoss.of(&run).unwrap() - 6.0).abs() < 1e-12);
    assert!((Quantity::Throughput.of(&run).unwrap() - 72.0).abs() < 1e-9); // 2 in 100 s
    assert!((Quantity::Conflicts.of(&run).unwrap() - 4.0).abs() < 1e-12); // 7 over 1.75 km
    assert_eq!(Quantity::EgoSpeed.of(&run), None);
    std::fs::write(
        &path,
        "<tripinfos><tripinfo id=\"a\" timeLoss=\"x\"/></tripinfos>",
    )
    .unwrap();
    let err = Trips::read(&path, &[]).unwrap_err().to_string();
    assert!(err.contains("timeLoss"), "{err}");
}

#[test]
fn conflicts_below_a_ttc_of_one_and_a_half_seconds_are_severe() {
    let dir = fresh_dir("study-ssm");
    let path = dir.join("ssm.xml");
    std::fs::write(
        &path,
        r#"<SSMLog>
    <conflict begin="1" end="5" ego="a" foe="b"><minTTC time="3" value="2.22"/><maxDRAC time="3" value="0.5"/></conflict>
    <conflict begin="6" end="9" ego="b" foe="a"><minTTC time="7" value="1.20"/></conflict>
    <conflict begin="9" end="10" ego="c" foe="d"><minTTC time="9" value="NA"/><maxDRAC time="9" value="3.4"/></conflict>
</SSMLog>"#,
    )
    .unwrap();
    assert_eq!(Conflicts::read(&path).unwrap(), Conflicts { all: 3, severe: 1 });
}

/// Runs at shares 0, 0.1, 0.3 and 0.5 with the game's time losses `game` (per vehicle) and
/// SUMO's drivers' at 10 s each, two seeds each (the second 1 s more on both sides).
fn study(game: [f64; 4]) -> Vec<StudyRun> {
    let run = |share: f64, seed: u64, is_game: bool, loss: f64| StudyRun {
        share,
        seed,
        game: is_game,
        duration: 100.0,
        trips: Trips {
            vehicles: 10,
            arrived: 10,
            time_loss: 10.0 * (loss + seed as f64),
            uncontrolled: 10,
            uncontrolled_time_loss: 10.0 * (loss + seed as f64),
            vehicle_km: 1.0,
        },
        conflicts: Conflicts::default(),
        ego_speed: None,
        controlled_collisions: usize::from(is_game),
    };
    [0.0, 0.1, 0.3, 0.5]
        .iter()
        .zip(game)
        .flat_map(|(&share, g)| {
            (0..2).flat_map(move |seed| [run(share, seed, true, g), run(share, seed, false, 10.0)])
        })
        .collect()
}

#[test]
fn the_game_beats_its_drivers_from_the_share_on_which_it_stays_below() {
    let r = rows(&study([10.0, 11.0, 9.0, 8.0]));
    assert_eq!(r.len(), 4);
    let loss = r[2].game[&Quantity::TimeLoss];
    // Seeds 9 and 10 s: mean 9.5, sample sd sqrt(0.5).
    assert!((loss.mean - 9.5).abs() < 1e-12 && (loss.sd - 0.5f64.sqrt()).abs() < 1e-12 && loss.runs == 2);
    assert!((r[2].ratio(Quantity::TimeLoss).unwrap() - 9.5 / 10.5).abs() < 1e-12);
    assert_eq!((r[2].seeds, r[2].controlled_collisions), (2, 2));
    assert_eq!(break_even(&r), Some(0.3));
    // Below at 10%, above at 30%: from 50% on.
    assert_eq!(break_even(&rows(&study([10.0, 9.0, 11.0, 8.0]))), Some(0.5));
    assert_eq!(break_even(&rows(&study([10.0, 9.0, 9.0, 10.5]))), None);
}

#[test]
fn the_game_beats_its_drivers_only_where_it_is_below_them_on_every_seed() {
    let mut runs = study([10.0, 11.0, 9.0, 8.0]);
    // At 30%, seed 0's game 7 s against SUMO's drivers' 10 s, seed 1's 11.5 s against 11 s:
    // the mean is below (9.25 against 10.5 s), one seed is not.
    for r in runs.iter_mut().filter(|r| r.share == 0.3 && r.game) {
        r.trips.time_loss = if r.seed == 0 { 70.0 } else { 115.0 };
    }
    let r = rows(&runs);
    assert!((r[2].ratio(Quantity::TimeLoss).unwrap() - 9.25 / 10.5).abs() < 1e-12);
    assert_eq!((r[2].seeds_below, r[3].seeds_below, r[1].seeds_below), (1, 2, 0));
    assert_eq!(break_even(&r), Some(0.5));
    let md = markdown(&r, None);
    assert!(md.contains("| 1 of 2 | 0.881 |"), "{md}");
    assert!(
        md.contains("on every seed from a controllable share of 50% on"),
        "{md}"
    );
}

#[test]
fn the_merge_costs_what_the_streams_lose_together_beyond_what_they_lose_apart() {
    let trips = |vehicles, time_loss| Trips {
        vehicles,
        time_loss,
        ..Trips::default()
    };
    // 2 ramp vehicles losing 6 s in all, 3 freeway vehicles losing 9 s: 3 s per vehicle.
    assert_eq!(apart(&trips(2, 6.0), &trips(3, 9.0)), Some(3.0));
    assert_eq!(apart(&trips(0, 0.0), &trips(0, 0.0)), None);
    // At 30% the game loses 9.5 s and SUMO's drivers 10.5 s (over two seeds); apart 6.5 s: the
    // merge costs 4 s, of which the game saves 1 s, a quarter.
    let r = rows(&study([10.0, 11.0, 9.0, 8.0]));
    assert!((merge_cost_removed(&r[2], 6.5).unwrap() - 0.25).abs() < 1e-12);
    assert_eq!(
        merge_cost_removed(&r[2], 10.5),
        None,
        "a merge that costs nothing"
    );
    let md = markdown(&r, Some(Spread::of(&[6.0, 7.0])));
    // SUMO's drivers at share 0: 10.5 s; apart 6.5 s, 0.619 times theirs.
    assert!(
        md.contains("lose 6.50 ± 0.71 s per vehicle: 0.619 times SUMO's drivers' 10.50 s"),
        "{md}"
    );
    assert!(md.contains("| 30% | 25.0% |"), "{md}");
    // Apart 10.45 s against SUMO's drivers' 10.5 s at 30%: a cost of 0.05 s, under 1% of their
    // time loss, is no denominator (the game "saved" 2,000% of it), and at share 0 it says so.
    assert_eq!(merge_cost_removed(&r[2], 10.45), None);
    let md = markdown(&r, Some(Spread::of(&[10.4, 10.5])));
    assert!(
        md.contains("too little here to say what part of it the game saves"),
        "{md}"
    );
    assert!(
        !md.contains("| 30% |  |") && !md.contains("over the merge's cost"),
        "{md}"
    );
}

/// A one-lane 30 m/s freeway with a 150 m acceleration lane, 900 + 400 veh/h for 120 s, built
/// with `net build` in `dir/net`; its .sumocfg.
#[cfg(feature = "sumo")]
fn merge_net(dir: &std::path::Path) -> std::path::PathBuf {
    let net = dir.join("net");
    let out = common::bin()
        .args(["net", "build", "--form", "acceleration", "--accel-lane", "150"])
        .args(["--speed", "30", "--lane-flow", "900", "--ramp-flow", "400"])
        .args(["--duration", "120", "--out"])
        .arg(&net)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    net.join("merge.sumocfg")
}

/// `mpgdrive study ARGS --sumocfg SUMOCFG --out OUT`.
#[cfg(feature = "sumo")]
fn study_run(args: &[&str], sumocfg: &std::path::Path, out: &std::path::Path) -> std::process::Output {
    common::bin()
        .arg("study")
        .args(args)
        .arg("--sumocfg")
        .arg(sumocfg)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

/// A study at shares 0 and 1, seed 0, 120 s, on `sumocfg` into `out`, which must succeed.
#[cfg(feature = "sumo")]
fn short_study(sumocfg: &std::path::Path, out: &std::path::Path) {
    let run = study_run(&["--shares", "0,1", "--seeds", "0", "--end", "120"], sumocfg, out);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
}

/// `study FLAG VALUE` on `sumocfg` is refused with exit code 2 and `message`, before anything
/// is written to `out`.
#[cfg(feature = "sumo")]
fn refused(flag: &str, value: &str, sumocfg: &std::path::Path, out: &std::path::Path, message: &str) {
    let run = study_run(&[flag, value], sumocfg, out);
    assert_eq!(run.status.code(), Some(2));
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(err.contains(message), "{err}");
    assert!(!out.exists());
}

#[cfg(feature = "sumo")]
#[test]
fn a_short_study_in_sumo_reads_its_drivers_exactly_where_nobody_is_controlled() {
    use common::bin;
    let dir = fresh_dir("study-sumo");
    let sumocfg = merge_net(&dir);
    let study = dir.join("study");
    short_study(&sumocfg, &study);
    let csv = std::fs::read_to_string(study.join("study.csv")).unwrap();
    let value = |share: &str, quantity: &str, side: &str| -> f64 {
        let line = csv
            .lines()
            .find(|l| l.starts_with(&format!("{share},{quantity},{side},")))
            .unwrap_or_else(|| panic!("no {share} {quantity} {side} in\n{csv}"));
        line.split(',').nth(3).unwrap().parse().unwrap()
    };
    for q in ["TimeLoss", "Throughput", "Conflicts"] {
        assert_eq!(value("0", q, "game"), value("0", q, "sumo"), "{q} at share 0");
    }
    // At a share of 1 every vehicle is controllable: the ramp's egos drive, none is left over.
    assert!(value("1", "EgoSpeed", "game") > 0.0);
    assert!(!csv.contains("1,UncontrolledTimeLoss"));
    let md = std::fs::read_to_string(study.join("study.md")).unwrap();
    assert!(md.contains("| 100% | 1 |"), "{md}");
    // The streams apart: the ramp's and the freeway's vehicles of the share-0 routes, each in a
    // run of its own; their time loss per vehicle, read here from SUMO's files.
    let tripinfo = |dir: &str| -> Vec<f64> {
        let work = study.join(dir).join("work");
        let run = std::fs::read_dir(&work)
            .unwrap()
            .map(|e| e.unwrap().path())
            .find(|p| p.to_string_lossy().ends_with("__sumo__s0"))
            .unwrap();
        let text = std::fs::read_to_string(run.join("tripinfo-sumo.xml")).unwrap();
        let doc = roxmltree::Document::parse(&text).unwrap();
        doc.descendants()
            .filter(|n| n.has_tag_name("tripinfo"))
            .map(|n| {
                let num = |k: &str| n.attribute(k).unwrap().parse::<f64>().unwrap();
                num("timeLoss") + num("departDelay").max(0.0)
            })
            .collect()
    };
    let (ramp, freeway, both) = (
        tripinfo("apart/ramp"),
        tripinfo("apart/freeway"),
        tripinfo("share_000.0"),
    );
    assert!(!ramp.is_empty() && !freeway.is_empty());
    assert_eq!(ramp.len() + freeway.len(), both.len());
    let apart = (ramp.iter().sum::<f64>() + freeway.iter().sum::<f64>()) / both.len() as f64;
    assert!(
        (value("0", "TimeLoss", "apart") - apart).abs() < 1e-5,
        "{apart}\n{csv}"
    );
    assert!(
        md.contains(&format!("lose {apart:.2} ± 0.00 s per vehicle")),
        "{md}"
    );
    assert!(study.join("study.png").is_file());
    // At a share of 1 every vehicle is controllable: the controllable players are every
    // player, and the game drives exactly as with `players = "all"`.
    let routes: Vec<_> = std::fs::read_dir(study.join("share_100.0/routes"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "xml"))
        .collect();
    let controllable = study.join("merge.toml");
    let all = dir.join("merge_all.toml");
    let text = std::fs::read_to_string(&controllable).unwrap();
    std::fs::write(
        &all,
        text.replace("players = \"controllable\"", "players = \"all\""),
    )
    .unwrap();
    let game = |merge: &std::path::Path| {
        let out = bin()
            .args([
                "cosim",
                "--controllers",
                "mpg",
                "--end",
                "120",
                "--no-diagrams",
                "--json",
                "--sumocfg",
            ])
            .arg(&sumocfg)
            .arg("--route-files")
            .arg(&routes[0])
            .arg("--merge")
            .arg(merge)
            .arg("--out")
            .arg(dir.join("game"))
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        (
            v[0]["summary"].clone(),
            v[0]["speed_overrides"].clone(),
            v[0]["vehicle_seconds"].clone(),
        )
    };
    let driven = game(&controllable);
    assert!(driven.0["episodes"].as_u64().unwrap() > 0);
    assert_eq!(driven, game(&all));
    // A share outside [0, 1], or two shares within 0.05% (one folder), is refused before
    // anything runs.
    for (shares, message) in [
        ("0,1.5", "--shares: 1.5"),
        (
            "0.3,0.3004",
            "--shares: 0.3 and 0.3004 would share the folder share_030.0",
        ),
    ] {
        refused("--shares", shares, &sumocfg, &dir.join("bad"), message);
    }
}

#[cfg(feature = "sumo")]
#[test]
fn the_capacity_sweep_finds_where_a_one_lane_merge_stops_taking_more_vehicles() {
    let dir = fresh_dir("study-capacity");
    let sumocfg = merge_net(&dir);
    let study = dir.join("study");
    let args = [
        "--capacity",
        "0.5,1,5",
        "--shares",
        "0",
        "--seeds",
        "0",
        "--end",
        "120",
    ];
    let out = study_run(&args, &sumocfg, &study);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let md = std::fs::read_to_string(study.join("study.md")).unwrap();
    // About 1,100 veh/h at demand 1 pass; 6,750 veh/h at demand 5 are far beyond what one freeway
    // lane and a ramp take (SUMO's drivers: about 2,000 veh/h a lane), so most of that step's
    // extra vehicles wait to enter: broken down at 5, and the study runs at 1.2 x 5.
    assert!(md.contains("The merge breaks down at demand 5 "), "{md}");
    assert!(md.contains("The game by share, at demand 6"), "{md}");
    assert!(study.join("capacity/demand_0.5/routes").is_dir());
    // A single demand cannot show a breakdown; a repeated one is refused too.
    for (capacity, message) in [
        ("1", "--capacity needs at least two demands"),
        ("1,2,1", "--capacity: demand 1 is given twice"),
        ("1,-2", "--capacity -2: must be a positive number"),
    ] {
        refused("--capacity", capacity, &sumocfg, &dir.join("bad"), message);
    }
    // A configuration that scales its demand itself would scale the study's route files again.
    let scaled = sumocfg.with_file_name("scaled.sumocfg");
    let text = std::fs::read_to_string(&sumocfg).unwrap();
    std::fs::write(
        &scaled,
        text.replace("</configuration>", "<scale value=\"0.5\"/></configuration>"),
    )
    .unwrap();
    refused(
        "--capacity",
        "1,2",
        &scaled,
        &dir.join("bad"),
        "sets scale 0.5: SUMO would scale",
    );
}

#[cfg(feature = "sumo")]
#[test]
fn a_study_runs_on_a_route_file_of_explicit_trips() {
    let dir = fresh_dir("study-explicit");
    let sumocfg = merge_net(&dir);
    // The network's flows written out as explicit trips (as randomTrips.py would give them)
    // become its route file.
    let trips = dir.join("trips");
    let out = common::bin()
        .args(["routes", "--duration", "120", "--base"])
        .arg(dir.join("net/merge.rou.xml"))
        .arg("--out")
        .arg(&trips)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    std::fs::copy(
        trips.join("merge_d1.00_s0.rou.xml"),
        dir.join("net/merge.rou.xml"),
    )
    .unwrap();
    let study = dir.join("study");
    short_study(&sumocfg, &study);
    let md = std::fs::read_to_string(study.join("study.md")).unwrap();
    assert!(
        md.contains("| 100% | 1 |") && md.contains("## The merge's own cost"),
        "{md}"
    );
}
