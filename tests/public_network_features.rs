//! What public networks hold that `mpgdrive net build`'s do not, built here with netconvert:
//! sidewalks and bicycle lanes beside every road (city networks, `--sidewalks.guess`,
//! `--bikelanes.guess`), a signal where the ramp joins (ramp metering, `--tls.set`), and
//! vehicle types that keep SUMO's default `minGap` (2.5 m, where ours keep 2), and a ramp fed
//! by a collector road that an off-ramp of the same freeway also joins (SUMO's own
//! `tools/game/ramp` network), an on-ramp that joins on the freeway's inner side, and what
//! osmWebWizard writes (a gzip-compressed network, trips without a controllable type, a
//! configuration without a step length that asks for SUMO's verbose output), on-ramps that
//! join at zipper nodes, where SUMO's drivers merge by arrival, trucks, and stop signs. A lane
//! closed to cars is neither a ramp nor a target lane, and a freeway lane is no ramp lane; the
//! merge `net inspect` proposes drives in `cosim`, at a signal too, where no driven vehicle
//! passes a red light, and at a stop sign, where every one stands at its line.
#![cfg(feature = "sumo")]

mod common;

use common::{bin, controlled_collisions, finished_egos, fresh_dir};
use mpgdrive::sumo::inspect::find_merges;
use std::path::Path;
use std::process::Command;

/// A two-lane road at 13.9 m/s joined by a one-lane ramp at a junction `M`, built with
/// netconvert and `options` into `dir/net.net.xml`, with a sumocfg and 300 s of flows (1,200
/// veh/h on the road, 400 on the ramp of type `ctrl`; SUMO's default `minGap`).
fn build(dir: &Path, options: &[&str]) {
    std::fs::write(
        dir.join("m.nod.xml"),
        r#"<nodes><node id="A" x="0" y="0"/><node id="M" x="600" y="0"/><node id="B" x="1400" y="0"/><node id="R" x="200" y="-150"/></nodes>"#,
    )
    .unwrap();
    std::fs::write(
        dir.join("m.edg.xml"),
        r#"<edges><edge id="fw_in" from="A" to="M" numLanes="2" speed="13.9" priority="3"/>
        <edge id="fw_out" from="M" to="B" numLanes="2" speed="13.9" priority="3"/>
        <edge id="ramp" from="R" to="M" numLanes="1" speed="11.1" priority="1"/></edges>"#,
    )
    .unwrap();
    let out = Command::new("netconvert")
        .current_dir(dir)
        .args(["-n", "m.nod.xml", "-e", "m.edg.xml", "-o", "net.net.xml"])
        .args(options)
        .output()
        .expect("netconvert (SUMO's network builder) is installed with SUMO");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    std::fs::write(
        dir.join("m.rou.xml"),
        r#"<routes><vType id="car" length="5" accel="2.6" decel="4.5" sigma="0.5"/>
        <vType id="ctrl" length="5" accel="2.6" decel="4.5" sigma="0.5"/>
        <flow id="f" type="car" from="fw_in" to="fw_out" begin="0" end="300" vehsPerHour="1200" departLane="best" departSpeed="max"/>
        <flow id="r" type="ctrl" from="ramp" to="fw_out" begin="0" end="300" vehsPerHour="400" departSpeed="max"/></routes>"#,
    )
    .unwrap();
    std::fs::write(
        dir.join("merge.sumocfg"),
        r#"<configuration><input><net-file value="net.net.xml"/><route-files value="m.rou.xml"/></input>
        <time><step-length value="0.1"/></time></configuration>"#,
    )
    .unwrap();
}

/// `mpgdrive ARGS` run in `dir`.
fn mpgdrive_in(dir: &Path, args: &[&str]) -> std::process::Output {
    bin().current_dir(dir).args(args).output().unwrap()
}

/// That at least `egos` of a run's egos finished and no vehicle the policy drove collided.
fn drove_safely(run: &serde_json::Value, egos: usize) {
    assert!(finished_egos(run) >= egos, "{} egos finished", finished_egos(run));
    assert_eq!(controlled_collisions(run), 0);
}

/// `dir/net.net.xml`, built by netconvert from plain `nodes` and `edges` and, unless empty,
/// the connections `links` (from edge, lane, to edge, lane).
fn netconvert(dir: &Path, nodes: &str, edges: &str, links: &[(&str, u32, &str, u32)]) {
    std::fs::write(dir.join("n.nod.xml"), format!("<nodes>{nodes}</nodes>")).unwrap();
    std::fs::write(dir.join("n.edg.xml"), format!("<edges>{edges}</edges>")).unwrap();
    let mut args = vec!["-n", "n.nod.xml", "-e", "n.edg.xml", "-o", "net.net.xml"];
    if !links.is_empty() {
        let links: String = (links.iter())
            .map(|(a, i, b, j)| format!(r#"<connection from="{a}" to="{b}" fromLane="{i}" toLane="{j}"/>"#))
            .collect();
        std::fs::write(
            dir.join("n.con.xml"),
            format!("<connections>{links}</connections>"),
        )
        .unwrap();
        args.extend(["-x", "n.con.xml"]);
    }
    let out = Command::new("netconvert")
        .current_dir(dir)
        .args(&args)
        .output()
        .expect("netconvert (SUMO's network builder) is installed with SUMO");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

/// The game for 600 s in `dir`: `net inspect` with `inspect` (its arguments after the network),
/// `routes` from the base file `base` at demand `scale` with a `share` of the ramp's and the
/// road's vehicles controllable, for SUMO seed `seed`, then [`drive`]: the run. `outputs` goes
/// into the configuration's `<output>` (SUMO's own records, for checks of their own).
fn game(
    dir: &Path,
    base: &str,
    (scale, share, seed): (f64, f64, u64),
    inspect: &[&str],
    outputs: &str,
) -> serde_json::Value {
    let stem = base.trim_end_matches(".rou.xml");
    std::fs::write(
        dir.join("merge.sumocfg"),
        format!(
            r#"<configuration><input><net-file value="net.net.xml"/><route-files value="r/{stem}_d{scale:.2}_m{share:.2}_s{seed}.rou.xml"/></input>
            <output>{outputs}</output><time><step-length value="0.1"/></time></configuration>"#
        ),
    )
    .unwrap();
    let out = mpgdrive_in(
        dir,
        &[&["net", "inspect", "net.net.xml", "--out", "merge.toml"], inspect].concat(),
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (scale, share, seed) = (scale.to_string(), share.to_string(), seed.to_string());
    let shares = [
        "--controllable-share",
        &share,
        "--mainline-controllable-share",
        &share,
    ];
    let routes = [
        &["routes", "--base", base, "--scales", &scale][..],
        &shares,
        &["--seeds", &seed, "--duration", "600", "--out", "r"],
    ];
    let out = mpgdrive_in(dir, &routes.concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    drive(dir, "mpg", &["--end", "600", "--seed", &seed]).remove(0)
}

/// [`game`] with 30% of the vehicles controllable, SUMO seed 1.
fn game_at_30_percent(dir: &Path, base: &str, scale: f64, inspect: &[&str]) -> serde_json::Value {
    game(dir, base, (scale, 0.3, 1), inspect, "")
}

/// `mpgdrive net inspect` in `dir`, writing `merge.toml` (its `players` set to `players`),
/// then [`drive`].
fn inspect_and_drive(dir: &Path, players: &str, controllers: &str, args: &[&str]) -> Vec<serde_json::Value> {
    let out = mpgdrive_in(dir, &["net", "inspect", "net.net.xml", "--out", "merge.toml"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let toml = std::fs::read_to_string(dir.join("merge.toml")).unwrap();
    let toml = toml.replace(r#"players = "controllable""#, &format!("players = \"{players}\""));
    std::fs::write(dir.join("merge.toml"), toml).unwrap();
    drive(dir, controllers, args)
}

/// `cosim` of `controllers` in `dir` (`merge.sumocfg`, `merge.toml`) with `args` (for 200 s
/// unless they set `--end`): the runs.
fn drive(dir: &Path, controllers: &str, args: &[&str]) -> Vec<serde_json::Value> {
    let end: &[&str] = if args.contains(&"--end") {
        &[]
    } else {
        &["--end", "200"]
    };
    let cosim = [
        "cosim",
        "--sumocfg",
        "merge.sumocfg",
        "--controllers",
        controllers,
        "--no-diagrams",
        "--json",
        "--out",
        "results",
    ];
    let out = mpgdrive_in(dir, &[&cosim[..], end, args].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

/// The mean time loss (s) of the road's vehicles (flow `f`) that finished, in a tripinfo file.
fn road_time_loss(tripinfo: &Path) -> f64 {
    let text = std::fs::read_to_string(tripinfo).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    let losses: Vec<f64> = doc
        .descendants()
        .filter(|n| n.has_tag_name("tripinfo") && n.attribute("id").is_some_and(|id| id.starts_with("f.")))
        .map(|n| n.attribute("timeLoss").unwrap().parse().unwrap())
        .collect();
    assert!(losses.len() >= 30, "{} road vehicles finished", losses.len());
    losses.iter().sum::<f64>() / losses.len() as f64
}

#[test]
fn sidewalks_and_bicycle_lanes_are_no_merges_and_the_car_lanes_merge_drives() {
    let dir = fresh_dir("public-sidewalks");
    build(&dir, &["--sidewalks.guess", "--bikelanes.guess"]);
    let run = &inspect_and_drive(&dir, "controllable", "mpg", &[])[0];
    let toml = std::fs::read_to_string(dir.join("merge.toml")).unwrap();
    // The ramp's lane 0 is a sidewalk and lane 1 a bicycle lane, the road's lane 0 a bicycle
    // lane (netconvert guesses no sidewalk at 13.9 m/s): one merge, of the ramp's car lane
    // into the road's right car lane. The proposal's vehicle type is the routes' `ctrl`.
    // (Several merges would be `[[merge]]` tables; one is written in the single form.)
    assert!(!toml.contains("[[merge]]"), "{toml}");
    assert!(toml.contains(r#"ramp_lanes = ["ramp_2"]"#), "{toml}");
    assert!(
        toml.contains(r#"target_lanes = ["fw_in_1", "fw_out_1"]"#),
        "{toml}"
    );
    drove_safely(run, 10);
}

#[test]
fn a_ramp_metered_merge_drives_the_game_as_well_as_sumo_without_passing_a_red_light() {
    let dir = fresh_dir("public-signal");
    build(&dir, &["--tls.set", "M"]);
    // The game (every road vehicle a player), without SUMO's safe speed: nothing but the
    // controller holds a driven vehicle at a red light or keeps SUMO's minGap in the ramp's
    // queue at it.
    let runs = inspect_and_drive(&dir, "all", "mpg,sumo", &["--speed-mode", "0"]);
    let toml = std::fs::read_to_string(dir.join("merge.toml")).unwrap();
    assert!(toml.contains(r#"ramp_lanes = ["ramp_0"]"#), "{toml}");
    let game = &runs[0];
    drove_safely(game, 10);
    assert_eq!(game["red_light_passes"], 0);
    // The light gives each road its turn: players that made room for egos held at theirs
    // lost the road's green time (1.34 times SUMO's drivers' time loss; 1.00 as built).
    let (ours, sumo) = (
        road_time_loss(&dir.join("results/tripinfo-mpg.xml")),
        road_time_loss(&dir.join("results/tripinfo-sumo.xml")),
    );
    assert!(
        ours <= 1.1 * sumo,
        "road time loss {ours:.2} s, SUMO's drivers {sumo:.2} s"
    );
}

/// A freeway (`f1` two lanes, `f2` one, `f3` two with the acceleration lane `f3_0`, `f4` one)
/// whose right lane leaves by an off-ramp `off` that yields into a collector road `col`, which
/// an on-ramp `on` feeds with the right of way; `col` splits into `exit` and `onr`, the ramp
/// into the acceleration lane. Built with netconvert into `dir/net.net.xml`, with a sumocfg and
/// 200 s of routes: `through` the freeway (1,000 veh/h), `onramp` from `on` (400 veh/h) and
/// `offramp` from the freeway through `col` to `exit` (300 veh/h), all of type `car`.
fn build_collector(dir: &Path) {
    let write = |name: &str, text: &str| std::fs::write(dir.join(name), text).unwrap();
    netconvert(
        dir,
        r#"<node id="A" x="0" y="0"/><node id="D" x="500" y="0"/><node id="M" x="900" y="0"/>
        <node id="E" x="1100" y="0"/><node id="B" x="1800" y="0"/><node id="J" x="600" y="-150"/>
        <node id="R" x="300" y="-300"/><node id="K" x="750" y="-150"/><node id="X" x="900" y="-350"/>"#,
        r#"<edge id="f1" from="A" to="D" numLanes="2" speed="30" priority="3"/>
        <edge id="f2" from="D" to="M" numLanes="1" speed="30" priority="3"/>
        <edge id="f3" from="M" to="E" numLanes="2" speed="30" priority="3"/>
        <edge id="f4" from="E" to="B" numLanes="1" speed="30" priority="3"/>
        <edge id="off" from="D" to="J" numLanes="1" speed="15" priority="1"/>
        <edge id="on" from="R" to="J" numLanes="1" speed="15" priority="2"/>
        <edge id="col" from="J" to="K" numLanes="1" speed="15" priority="2"/>
        <edge id="exit" from="K" to="X" numLanes="1" speed="15" priority="1"/>
        <edge id="onr" from="K" to="M" numLanes="1" speed="15" priority="1"/>"#,
        &[
            ("f1", 0, "off", 0),
            ("f1", 1, "f2", 0),
            ("f2", 0, "f3", 1),
            ("onr", 0, "f3", 0),
            ("f3", 1, "f4", 0),
            ("off", 0, "col", 0),
            ("on", 0, "col", 0),
            ("col", 0, "exit", 0),
            ("col", 0, "onr", 0),
        ],
    );
    write(
        "c.rou.xml",
        r#"<routes><vType id="car" length="5" accel="2.6" decel="4.5" sigma="0.5"/>
        <vType id="ctrl" length="5" accel="2.6" decel="4.5" sigma="0.5"/>
        <route id="through" edges="f1 f2 f3 f4"/><route id="onramp" edges="on col onr f3 f4"/>
        <route id="offramp" edges="f1 off col exit"/>
        <flow id="t" type="car" route="through" begin="0" end="200" vehsPerHour="1000" departLane="best" departSpeed="max"/>
        <flow id="r" type="car" route="onramp" begin="0" end="200" vehsPerHour="400" departSpeed="max"/>
        <flow id="x" type="car" route="offramp" begin="0" end="200" vehsPerHour="300" departLane="0" departSpeed="max"/></routes>"#,
    );
    write(
        "merge.sumocfg",
        r#"<configuration><input><net-file value="net.net.xml"/><route-files value="r/c_d1.00_s0.rou.xml"/></input>
        <time><step-length value="0.1"/></time></configuration>"#,
    );
}

#[test]
fn a_ramp_fed_by_a_collector_road_holds_no_freeway_lane_and_only_its_vehicles_are_egos() {
    let dir = fresh_dir("public-collector");
    build_collector(&dir);
    let merges = find_merges(&dir.join("net.net.xml")).unwrap();
    // Where the collector road begins, the on-ramp has the right of way: the ramp is followed
    // back along it, not along the off-ramp into the freeway's right lane.
    let accel = merges
        .iter()
        .find(|m| m.ramp_lanes.last().unwrap() == "f3_0")
        .unwrap();
    assert_eq!(accel.ramp_lanes, ["on_0", "col_0", "onr_0", "f3_0"]);
    assert_eq!(accel.target_lanes, ["f1_1", "f2_0", "f3_1", "f4_0"]);
    // The off-ramp's junction merge into the collector road is one too.
    let junction = merges
        .iter()
        .find(|m| m.ramp_lanes.last().unwrap() == "off_0")
        .unwrap();
    assert_eq!(
        junction.target_lanes[..2],
        ["on_0".to_owned(), "col_0".to_owned()]
    );
    for m in &merges {
        assert!(m.ramp_lanes.iter().all(|l| !m.target_lanes.contains(l)), "{m:?}");
    }
    let out = mpgdrive_in(
        &dir,
        &[
            "net",
            "inspect",
            "net.net.xml",
            "--merge",
            "1",
            "--out",
            "merge.toml",
        ],
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // Every ramp vehicle controllable: the on-ramp's, not the freeway's nor the off-ramp's,
    // which pass the collector road but never reach the acceleration lane.
    let out = mpgdrive_in(
        &dir,
        &[
            "routes",
            "--base",
            "c.rou.xml",
            "--controllable-share",
            "1",
            "--duration",
            "200",
            "--out",
            "r",
        ],
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let routes = std::fs::read_to_string(dir.join("r/c_d1.00_s0.rou.xml")).unwrap();
    let ctrl = |route: &str| {
        routes
            .lines()
            .filter(|l| l.contains(&format!("route=\"{route}\"")) && l.contains("type=\"ctrl\""))
            .count()
    };
    assert!(ctrl("onramp") >= 15, "{routes}");
    assert_eq!((ctrl("through"), ctrl("offramp")), (0, 0));
    let run = drive(&dir, "mpg", &[]);
    drove_safely(&run[0], 10);
}

/// A two-lane freeway at 30 m/s (`in`, `acc` with three lanes, `out`) that a ramp (`ramp`, 20
/// m/s) joins on its inner side: the ramp leads into `acc_2`, which ends beside `acc_1`. Built
/// with netconvert and explicit connections into `dir/net.net.xml`, with a sumocfg and 200 s of
/// flows (2,000 veh/h on the freeway, 400 on the ramp, of type `ctrl`).
fn build_inner(dir: &Path) {
    let write = |name: &str, text: &str| std::fs::write(dir.join(name), text).unwrap();
    netconvert(
        dir,
        r#"<node id="A" x="0" y="0"/><node id="B" x="600" y="0"/><node id="C" x="800" y="0"/>
        <node id="D" x="1400" y="0"/><node id="R" x="150" y="160"/>"#,
        r#"<edge id="in" from="A" to="B" numLanes="2" speed="30"/>
        <edge id="acc" from="B" to="C" numLanes="3" speed="30"/>
        <edge id="out" from="C" to="D" numLanes="2" speed="30"/>
        <edge id="ramp" from="R" to="B" numLanes="1" speed="20"/>"#,
        &[
            ("in", 0, "acc", 0),
            ("in", 1, "acc", 1),
            ("ramp", 0, "acc", 2),
            ("acc", 0, "out", 0),
            ("acc", 1, "out", 1),
        ],
    );
    write(
        "i.rou.xml",
        r#"<routes><vType id="car" length="5" accel="2.6" decel="4.5" sigma="0.5"/>
        <vType id="ctrl" length="5" accel="2.6" decel="4.5" sigma="0.5"/>
        <flow id="f" type="car" from="in" to="out" begin="0" end="200" vehsPerHour="2000" departLane="best" departSpeed="max"/>
        <flow id="r" type="ctrl" from="ramp" to="out" begin="0" end="200" vehsPerHour="400" departSpeed="max"/></routes>"#,
    );
    write(
        "merge.sumocfg",
        r#"<configuration><input><net-file value="net.net.xml"/><route-files value="i.rou.xml"/></input>
        <time><step-length value="0.1"/></time></configuration>"#,
    );
}

#[test]
fn a_ramp_that_joins_on_the_inner_side_merges_into_the_lane_to_its_right() {
    let dir = fresh_dir("public-inner-ramp");
    build_inner(&dir);
    let merges = find_merges(&dir.join("net.net.xml")).unwrap();
    assert_eq!(merges.len(), 1, "{merges:?}");
    assert_eq!(merges[0].ramp_lanes, ["ramp_0", "acc_2"]);
    assert_eq!(merges[0].target_lanes, ["in_1", "acc_1", "out_1"]);
    // With lane-change mode 0 SUMO changes no driven ramp vehicle's lane by itself: an ego that
    // finishes was moved to `acc_1` by the controller, the lane to the right of its own.
    let runs = inspect_and_drive(&dir, "controllable", "mpg", &["--lane-change-mode", "0"]);
    drove_safely(&runs[0], 10);
}

#[test]
fn what_osm_web_wizard_writes_runs_as_it_is() {
    use std::io::Write;
    let dir = fresh_dir("public-osm-wizard");
    build(&dir, &[]);
    // osmWebWizard's files: a gzip-compressed network; trips of one type, no controllable one;
    // a configuration without a step length that asks SUMO for verbose output and statistics.
    let net = std::fs::read(dir.join("net.net.xml")).unwrap();
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    gz.write_all(&net).unwrap();
    std::fs::write(dir.join("osm.net.xml.gz"), gz.finish().unwrap()).unwrap();
    std::fs::remove_file(dir.join("net.net.xml")).unwrap();
    let trips: String = (0..100)
        .map(|k| {
            let from = if k % 4 == 0 { "ramp" } else { "fw_in" };
            format!(
                r#"<trip id="veh{k}" type="veh_passenger" depart="{}.00" departLane="best" from="{from}" to="fw_out"/>"#,
                2 * k
            )
        })
        .collect();
    std::fs::write(
        dir.join("osm.passenger.trips.xml"),
        format!(r#"<routes><vType id="veh_passenger" vClass="passenger"/>{trips}</routes>"#),
    )
    .unwrap();
    std::fs::write(
        dir.join("osm.sumocfg"),
        r#"<configuration><input><net-file value="osm.net.xml.gz"/><route-files value="osm.passenger.trips.xml"/></input>
        <report><verbose value="true"/><duration-log.statistics value="true"/></report></configuration>"#,
    )
    .unwrap();
    let out = mpgdrive_in(&dir, &["net", "inspect", "osm.net.xml.gz", "--out", "merge.toml"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // As they are, its trips hold no vehicle the policy may drive, and cosim says so.
    let out = mpgdrive_in(
        &dir,
        &[
            "cosim",
            "--sumocfg",
            "osm.sumocfg",
            "--end",
            "5",
            "--controllers",
            "mpg",
            "--out",
            "as_is",
        ],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success() && stderr.contains("the policy drives no vehicle"),
        "{stderr}"
    );
    let out = mpgdrive_in(
        &dir,
        &[
            "study",
            "--sumocfg",
            "osm.sumocfg",
            "--shares",
            "1",
            "--seeds",
            "0",
            "--end",
            "200",
            "--out",
            "st",
        ],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("`ctrl` is added as a copy of its first passenger car's vType"),
        "{stderr}"
    );
    // Every ramp trip drawn controllable, and `cosim --json` prints its results alone.
    let routes = dir.join("st/share_100.0/routes/osm.passenger.trips_d1.20_m1.00_s0.rou.xml");
    let out = mpgdrive_in(
        &dir,
        &[
            "cosim",
            "--sumocfg",
            "osm.sumocfg",
            "--route-files",
            routes.to_str().unwrap(),
            "--end",
            "200",
            "--controllers",
            "mpg",
            "--no-diagrams",
            "--json",
            "--out",
            "results",
        ],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("sets no step-length"), "{stderr}");
    let runs: Vec<serde_json::Value> = serde_json::from_slice(&out.stdout).unwrap();
    drove_safely(&runs[0], 15);
}

#[test]
fn at_zipper_junctions_players_let_sumos_drivers_ahead_take_their_turn() {
    // A one-lane road at 30 m/s joined by two one-lane ramps at zipper nodes 400 m apart.
    let dir = fresh_dir("public-zipper");
    let write = |name: &str, text: &str| std::fs::write(dir.join(name), text).unwrap();
    netconvert(
        &dir,
        r#"<node id="a" x="0" y="0"/><node id="j1" x="700" y="0" type="zipper"/><node id="j2" x="1100" y="0" type="zipper"/>
        <node id="d" x="1800" y="0"/><node id="r1" x="400" y="-120"/><node id="r2" x="800" y="-120"/>"#,
        r#"<edge id="e1" from="a" to="j1" numLanes="1" speed="30" priority="3"/>
        <edge id="e2" from="j1" to="j2" numLanes="1" speed="30" priority="3"/><edge id="e3" from="j2" to="d" numLanes="1" speed="30" priority="3"/>
        <edge id="on1" from="r1" to="j1" numLanes="1" speed="20" priority="1"/><edge id="on2" from="r2" to="j2" numLanes="1" speed="20" priority="1"/>"#,
        &[],
    );
    write(
        "z.rou.xml",
        r#"<routes><vType id="car" length="5" minGap="2.5" accel="2.6" decel="4.5" sigma="0.5" speedDev="0.1"/>
        <vType id="ctrl" length="5" minGap="2.5" accel="2.6" decel="4.5" sigma="0.5" speedDev="0.1"/>
        <flow id="main" type="car" begin="0" end="600" vehsPerHour="1100" from="e1" to="e3" departSpeed="max"/>
        <flow id="o1" type="car" begin="0" end="600" vehsPerHour="250" from="on1" to="e3" departSpeed="max"/>
        <flow id="o2" type="car" begin="0" end="600" vehsPerHour="250" from="on2" to="e3" departSpeed="max"/></routes>"#,
    );
    // SUMO seed 1: a player drove on beside SUMO's driver just ahead of it at the first zipper
    // (t = 486 s) and they collided in the junction, before players followed such drivers.
    let run = &game_at_30_percent(&dir, "z.rou.xml", 1.0, &[]);
    drove_safely(run, 15);
}

#[test]
fn gaps_to_trucks_are_their_bumper_gaps() {
    // A two-lane road at 33 m/s joined by a two-lane ramp that drops to one lane into an
    // acceleration lane; 16.5 m trucks among the cars on both.
    let dir = fresh_dir("public-trucks");
    let write = |name: &str, text: &str| std::fs::write(dir.join(name), text).unwrap();
    netconvert(
        &dir,
        r#"<node id="a" x="0" y="0"/><node id="b" x="600" y="0"/><node id="c" x="850" y="0"/><node id="d" x="1500" y="0"/>
        <node id="r0" x="150" y="-160"/><node id="r1" x="420" y="-50"/>"#,
        r#"<edge id="in" from="a" to="b" numLanes="2" speed="33"/><edge id="acc" from="b" to="c" numLanes="3" speed="33"/>
        <edge id="out" from="c" to="d" numLanes="2" speed="33"/><edge id="rampA" from="r0" to="r1" numLanes="2" speed="22"/>
        <edge id="rampB" from="r1" to="b" numLanes="1" speed="22"/>"#,
        &[
            ("rampA", 0, "rampB", 0),
            ("rampA", 1, "rampB", 0),
            ("rampB", 0, "acc", 0),
            ("in", 0, "acc", 1),
            ("in", 1, "acc", 2),
            ("acc", 1, "out", 0),
            ("acc", 2, "out", 1),
        ],
    );
    write(
        "t.rou.xml",
        r#"<routes><vType id="car" length="5" minGap="2.5" accel="2.6" decel="4.5" sigma="0.5" speedDev="0.1"/>
        <vType id="ctrl" length="5" minGap="2.5" accel="2.6" decel="4.5" sigma="0.5" speedDev="0.1"/>
        <vType id="truck" vClass="truck" length="16.5" minGap="2.5" accel="1.1" decel="4.0" sigma="0.5" maxSpeed="25"/>
        <flow id="main" type="car" begin="0" end="600" vehsPerHour="2200" from="in" to="out" departLane="best" departSpeed="max"/>
        <flow id="trk" type="truck" begin="0" end="600" vehsPerHour="500" from="in" to="out" departLane="best" departSpeed="max"/>
        <flow id="onr" type="car" begin="0" end="600" vehsPerHour="500" from="rampA" to="out" departLane="best" departSpeed="max"/>
        <flow id="ontrk" type="truck" begin="0" end="600" vehsPerHour="100" from="rampA" to="out" departLane="best" departSpeed="max"/></routes>"#,
    );
    // SUMO seed 1: a driven car ran into a truck's rear, and a truck into an ego that entered
    // in front of it, while the world took every vehicle for a 5 m car.
    let run = &game_at_30_percent(&dir, "t.rou.xml", 1.2, &["--merge", "1"]);
    drove_safely(run, 20);
}

#[test]
fn egos_wait_for_the_lanes_their_junction_link_crosses() {
    // A three-lane 14 m/s road joined from its left by a one-lane ramp whose only link crosses
    // lanes 2 and 1 into lane 0, as SMARTS's `merge/3lane` map has it; SUMO's drivers on the
    // ramp yield to all three lanes.
    let dir = fresh_dir("public-crossing");
    let write = |name: &str, text: &str| std::fs::write(dir.join(name), text).unwrap();
    netconvert(
        &dir,
        r#"<node id="a" x="0" y="0"/><node id="j" x="400" y="0"/><node id="b" x="800" y="0"/><node id="r" x="100" y="60"/>"#,
        r#"<edge id="in" from="a" to="j" numLanes="3" speed="14" priority="3"/><edge id="out" from="j" to="b" numLanes="3" speed="14" priority="3"/>
        <edge id="ramp" from="r" to="j" numLanes="1" speed="14" priority="1"/>"#,
        &[
            ("in", 0, "out", 0),
            ("in", 1, "out", 1),
            ("in", 2, "out", 2),
            ("ramp", 0, "out", 0),
        ],
    );
    write(
        "x.rou.xml",
        r#"<routes><vType id="car" length="5" minGap="2.5" accel="2.6" decel="4.5" sigma="0.5" speedDev="0.1"/>
        <vType id="ctrl" length="5" minGap="2.5" accel="2.6" decel="4.5" sigma="0.5" speedDev="0.1"/>
        <flow id="main" type="car" begin="0" end="600" vehsPerHour="900" from="in" to="out" departLane="random" departSpeed="max"/>
        <flow id="on" type="car" begin="0" end="600" vehsPerHour="300" from="ramp" to="out" departSpeed="max"/></routes>"#,
    );
    let merges = find_merges(&dir.join("net.net.xml")).unwrap();
    assert_eq!(merges.len(), 1, "{merges:?}");
    assert_eq!(merges[0].target_lanes, ["in_0", "out_0"]);
    // Every vehicle playing, SUMO seed 0: 3 controlled collisions in the junction with lane 1
    // and 2's vehicles before egos waited for them.
    drove_safely(&game(&dir, "x.rou.xml", (1.0, 1.0, 0), &[], ""), 40);
}

/// Each vehicle's samples of SUMO's fcd output `path` on `lane`: (lane position, speed), in time
/// order, and whether it was seen on a lane after them.
fn samples_on(path: &Path, lane: &str) -> std::collections::HashMap<String, (Vec<(f64, f64)>, bool)> {
    let text = std::fs::read_to_string(path).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    let mut seen: std::collections::HashMap<String, (Vec<(f64, f64)>, bool)> = Default::default();
    for v in doc.descendants().filter(|n| n.has_tag_name("vehicle")) {
        let num = |key: &str| v.attribute(key).unwrap().parse::<f64>().unwrap();
        let entry = seen.entry(v.attribute("id").unwrap().to_owned()).or_default();
        match v.attribute("lane") == Some(lane) {
            true => entry.0.push((num("pos"), num("speed"))),
            false => entry.1 |= !entry.0.is_empty(),
        }
    }
    seen.retain(|_, (on, _)| !on.is_empty());
    seen
}

#[test]
fn at_a_stop_sign_every_vehicle_stands_at_its_line_before_it_goes_on() {
    // A one-lane 20 m/s road joined by a one-lane ramp at an all-way stop (netconvert's
    // `allway_stop`: SUMO's `w` links, a stop sign on every approach), 30% of the vehicles
    // controllable: egos stop at the ramp's line and players at the road's.
    let dir = fresh_dir("public-stop-sign");
    netconvert(
        &dir,
        r#"<node id="a" x="0" y="0"/><node id="j" x="500" y="0" type="allway_stop"/><node id="b" x="900" y="0"/><node id="r" x="200" y="-100"/>"#,
        r#"<edge id="in" from="a" to="j" numLanes="1" speed="20" priority="3"/><edge id="out" from="j" to="b" numLanes="1" speed="20" priority="3"/>
        <edge id="ramp" from="r" to="j" numLanes="1" speed="14" priority="1"/>"#,
        &[],
    );
    std::fs::write(
        dir.join("s.rou.xml"),
        r#"<routes><vType id="car" length="5" minGap="2.5" accel="2.6" decel="4.5" sigma="0.5"/>
        <vType id="ctrl" length="5" minGap="2.5" accel="2.6" decel="4.5" sigma="0.5"/>
        <flow id="main" type="car" begin="0" end="600" vehsPerHour="500" from="in" to="out" departSpeed="max"/>
        <flow id="on" type="car" begin="0" end="600" vehsPerHour="200" from="ramp" to="out" departSpeed="max"/></routes>"#,
    )
    .unwrap();
    let fcd = r#"<fcd-output value="fcd.xml"/>"#;
    let run = game(&dir, "s.rou.xml", (1.0, 0.3, 1), &[], fcd);
    drove_safely(&run, 5);
    assert_eq!(run["stop_sign_passes"], 0);
    // SUMO's own record: every vehicle that went on from either approach stood (below SUMO's
    // halting speed, 0.1 m/s) within 1 m of the lane's end. Before the fix egos and players
    // ran the signs at up to 20 m/s.
    let net = std::fs::read_to_string(dir.join("net.net.xml")).unwrap();
    for lane in ["ramp_0", "in_0"] {
        let length: f64 = roxmltree::Document::parse(&net)
            .unwrap()
            .descendants()
            .find(|n| n.has_tag_name("lane") && n.attribute("id") == Some(lane))
            .and_then(|n| n.attribute("length")?.parse().ok())
            .unwrap();
        let passed: Vec<_> = samples_on(&dir.join("fcd.xml"), lane)
            .into_iter()
            .filter(|(_, (_, went_on))| *went_on)
            .collect();
        assert!(
            passed.len() >= 20,
            "{} vehicles went on from {lane}",
            passed.len()
        );
        for (id, (on, _)) in passed {
            let stood = on.iter().any(|&(pos, v)| pos >= length - 1.0 && v < 0.1);
            let fastest = on
                .iter()
                .filter(|&&(pos, _)| pos >= length - 1.0)
                .map(|s| s.1)
                .fold(0.0, f64::max);
            assert!(
                stood,
                "{id} went on from {lane} without a stop (up to {fastest} m/s in its last metre)"
            );
        }
    }
}

#[test]
fn a_configuration_that_turns_the_collision_check_off_still_counts_collisions() {
    // Ramp drivers that ignore the road's vehicles at the junction (SUMO's `jmIgnoreFoeProb`)
    // collide with them; a configuration with `collision.action none` hid every one of those
    // collisions from the metrics. It runs as SUMO's default (teleport) does.
    let dir = fresh_dir("public-collision-check");
    netconvert(
        &dir,
        r#"<node id="a" x="0" y="0"/><node id="j" x="600" y="0"/><node id="b" x="1000" y="0"/><node id="r" x="200" y="-150"/>"#,
        r#"<edge id="in" from="a" to="j" numLanes="2" speed="30" priority="3"/><edge id="out" from="j" to="b" numLanes="2" speed="30" priority="3"/>
        <edge id="ramp" from="r" to="j" numLanes="1" speed="20" priority="1"/>"#,
        &[],
    );
    std::fs::write(
        dir.join("c.rou.xml"),
        r#"<routes><vType id="car" length="5" accel="2.6" decel="4.5" sigma="0.5"/>
        <vType id="blind" length="5" accel="2.6" decel="4.5" sigma="0.5" jmIgnoreFoeProb="1" jmIgnoreFoeSpeed="50"/>
        <flow id="f" type="car" from="in" to="out" begin="0" end="300" vehsPerHour="2400" departLane="best" departSpeed="max"/>
        <flow id="r" type="blind" from="ramp" to="out" begin="0" end="300" vehsPerHour="500" departSpeed="max"/></routes>"#,
    )
    .unwrap();
    let out = mpgdrive_in(&dir, &["net", "inspect", "net.net.xml", "--out", "merge.toml"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let collisions = |processing: &str| {
        std::fs::write(
            dir.join("merge.sumocfg"),
            format!(
                r#"<configuration><input><net-file value="net.net.xml"/><route-files value="c.rou.xml"/></input>
                <time><step-length value="0.1"/></time><processing>{processing}</processing></configuration>"#
            ),
        )
        .unwrap();
        drive(&dir, "sumo", &["--end", "300", "--seed", "0"])[0]["collisions"]
            .as_array()
            .unwrap()
            .len()
    };
    let default = collisions("");
    assert!(default > 0, "no collision to count");
    assert_eq!(collisions(r#"<collision.action value="none"/>"#), default);
}

#[test]
fn ssm_collisions_that_sumos_collision_check_does_not_find_are_no_conflicts() {
    // On a curved junction merge SSM's conflict area reaches past the lanes: a ramp vehicle
    // standing at its stop line beside a passing car is an SSM "collision" (type 111, TTC 0),
    // where SUMO's collision check (junctions included) finds no overlap. Before, such an ego
    // was "in a conflict" at TTC 0 and the study counted it severe.
    let dir = fresh_dir("public-ssm-collision");
    let out = bin()
        .args(["net", "build", "--form", "junction", "--curved", "--speed", "30"])
        .args([
            "--lane-flow",
            "600",
            "--ramp-flow",
            "400",
            "--duration",
            "120",
            "--out",
        ])
        .arg(dir.join("net"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let args = [
        "--controllers",
        "sumo",
        "--seed",
        "1",
        "--end",
        "120",
        "--ssm-all",
        "--no-diagrams",
    ];
    let (runs, _) = common::cosim_json(&args, &dir.join("net/merge.sumocfg"), &dir.join("run"));
    let run = &runs[0];
    assert_eq!(run["collisions"].as_array().unwrap().len(), 0);
    // Each vehicle's smallest TTC over its encounters within the thresholds (TTC < 3 s or
    // DRAC > 3 m/s^2), read here from SUMO's file without SSM's collisions.
    let text = std::fs::read_to_string(dir.join("run/ssm-sumo.xml")).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    let (mut inferred, mut expected) = (Vec::new(), std::collections::HashMap::new());
    for c in doc.descendants().filter(|n| n.has_tag_name("conflict")) {
        let ego = c.attribute("ego").unwrap();
        let value = |tag: &str| {
            let n = c.children().find(|n| n.has_tag_name(tag)).unwrap();
            (
                n.attribute("value").unwrap().parse::<f64>().ok(),
                n.attribute("type").unwrap(),
            )
        };
        let (ttc, kind) = value("minTTC");
        let ttc = if kind == "111" {
            inferred.push(ego.to_owned());
            None
        } else {
            ttc
        };
        let drac = value("maxDRAC").0;
        if ttc.is_some_and(|t| t < 3.0) || drac.is_some_and(|d| d > 3.0) {
            let slot = expected.entry(ego.to_owned()).or_insert(None);
            if let Some(t) = ttc {
                *slot = Some(slot.map_or(t, |m: f64| m.min(t)));
            }
        }
    }
    let egos = run["egos"].as_array().unwrap();
    assert!(
        egos.iter()
            .any(|e| inferred.iter().any(|i| e["id"] == i.as_str())),
        "no ramp vehicle in an SSM collision: {inferred:?}"
    );
    for e in egos {
        let id = e["id"].as_str().unwrap();
        assert_eq!(
            e["ssm_min_ttc"].as_f64(),
            expected.get(id).copied().flatten(),
            "{id}"
        );
    }
}
