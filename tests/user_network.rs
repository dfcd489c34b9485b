//! Bring your own network: a merge network unlike the bundled ones (a one-lane freeway heading
//! south-west, a ramp curving in, junction lanes, the conflict point far from 180 m, a plain
//! sumocfg without the SSM device), built here with netconvert, given only the merge.toml that
//! `mpgdrive net inspect` proposes, runs the three controllers through `mpgdrive cosim`.
#![cfg(feature = "sumo")]

mod common;

use common::{bin, controlled_collisions, fresh_dir};
use std::path::Path;
use std::process::Command;

/// Heading of the freeway (degrees from +x, counter-clockwise): south-west.
const HEADING: f64 = 210.0;

/// Network coordinates of the point `s` metres along the freeway from its start and `d`
/// metres to its left (negative: right).
fn at(s: f64, d: f64) -> (f64, f64) {
    let (sin, cos) = HEADING.to_radians().sin_cos();
    (-300.0 + s * cos - d * sin, 900.0 + s * sin + d * cos)
}

fn point(s: f64, d: f64) -> String {
    let (x, y) = at(s, d);
    format!("{x:.2},{y:.2}")
}

/// Writes the plain XML of the network and its routes into `dir` and builds `user.net.xml`.
fn build_network(dir: &Path) {
    let nodes: String = [
        ("start", 0.0, 0.0),
        ("gore", 300.0, 0.0),
        ("accel_end", 450.0, 0.0),
        ("end", 800.0, 0.0),
        ("ramp_start", 120.0, -160.0),
    ]
    .iter()
    .map(|&(id, s, d)| {
        let (x, y) = at(s, d);
        format!("<node id=\"{id}\" x=\"{x:.2}\" y=\"{y:.2}\" type=\"priority\"/>")
    })
    .collect();
    // The ramp: a cubic Bezier from its start, curving in to run beside the freeway (the
    // acceleration lane's centre is 5.25 m right of the freeway's left edge) for its last 40 m.
    let bezier = |t: f64| {
        let p = [(120.0, -160.0), (160.0, -60.0), (200.0, -5.25), (260.0, -5.25)];
        let m = 1.0 - t;
        let w = [m * m * m, 3.0 * m * m * t, 3.0 * m * t * t, t * t * t];
        (0..4).fold((0.0, 0.0), |(s, d), k| (s + w[k] * p[k].0, d + w[k] * p[k].1))
    };
    let mut shape: Vec<String> = (0..=20)
        .map(|k| bezier(f64::from(k) / 20.0))
        .map(|(s, d)| point(s, d))
        .collect();
    shape.push(point(300.0, -5.25));
    let edges = format!(
        "<edges>\
         <edge id=\"in\" from=\"start\" to=\"gore\" numLanes=\"1\" speed=\"18\" width=\"3.5\"/>\
         <edge id=\"acc\" from=\"gore\" to=\"accel_end\" numLanes=\"2\" speed=\"18\" width=\"3.5\"/>\
         <edge id=\"out\" from=\"accel_end\" to=\"end\" numLanes=\"1\" speed=\"18\" width=\"3.5\"/>\
         <edge id=\"onramp\" from=\"ramp_start\" to=\"gore\" numLanes=\"1\" speed=\"15\" width=\"3.5\" \
         spreadType=\"center\" shape=\"{}\"/></edges>",
        shape.join(" ")
    );
    let connections = "<connections>\
        <connection from=\"in\" to=\"acc\" fromLane=\"0\" toLane=\"1\"/>\
        <connection from=\"onramp\" to=\"acc\" fromLane=\"0\" toLane=\"0\"/>\
        <connection from=\"acc\" to=\"out\" fromLane=\"1\" toLane=\"0\"/></connections>";
    std::fs::write(dir.join("user.nod.xml"), format!("<nodes>{nodes}</nodes>")).unwrap();
    std::fs::write(dir.join("user.edg.xml"), edges).unwrap();
    std::fs::write(dir.join("user.con.xml"), connections).unwrap();
    let out = Command::new("netconvert")
        .current_dir(dir)
        .args([
            "--node-files=user.nod.xml",
            "--edge-files=user.edg.xml",
            "--connection-files=user.con.xml",
            "--output-file=user.net.xml",
            "--no-turnarounds=true",
        ])
        .output()
        .expect("netconvert (SUMO's network builder) is installed with SUMO");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    std::fs::write(
        dir.join("user.rou.xml"),
        "<routes>\
         <vType id=\"car\" length=\"5\" width=\"2\" accel=\"2.6\" decel=\"4.5\" sigma=\"0.5\"/>\
         <vType id=\"ctrl\" length=\"5\" width=\"2\" accel=\"2.6\" decel=\"4.5\" sigma=\"0.5\"/>\
         <route id=\"main\" edges=\"in acc out\"/><route id=\"ramp\" edges=\"onramp acc out\"/>\
         <flow id=\"freeway\" type=\"car\" route=\"main\" begin=\"0\" end=\"600\" vehsPerHour=\"800\" departSpeed=\"max\"/>\
         <flow id=\"merging\" type=\"ctrl\" route=\"ramp\" begin=\"0\" end=\"540\" vehsPerHour=\"360\" departSpeed=\"max\"/>\
         </routes>",
    )
    .unwrap();
    std::fs::write(
        dir.join("user.sumocfg"),
        "<configuration><input><net-file value=\"user.net.xml\"/><route-files value=\"user.rou.xml\"/>\
         </input><time><step-length value=\"0.1\"/></time></configuration>",
    )
    .unwrap();
}

#[test]
fn a_curved_ramp_network_runs_every_controller_with_the_proposed_merge_toml() {
    let dir = fresh_dir("user-network");
    build_network(&dir);
    let net = std::fs::read_to_string(dir.join("user.net.xml")).unwrap();
    assert!(
        net.contains("function=\"internal\""),
        "junction lanes between the listed lanes"
    );
    let inspect = bin()
        .args(["net", "inspect"])
        .arg(dir.join("user.net.xml"))
        .arg("--out")
        .arg(dir.join("merge.toml"))
        .output()
        .unwrap();
    assert!(
        inspect.status.success(),
        "{}",
        String::from_utf8_lossy(&inspect.stderr)
    );
    let merge = mpgdrive::sumo::MergeGeometry::load(&dir.join("merge.toml")).unwrap();
    assert_eq!(merge.ramp_lanes, ["onramp_0", "acc_0"]);
    assert_eq!(merge.target_lanes, ["in_0", "acc_1", "out_0"]);
    // Along the lanes: `in` is about 300 m (less the junction), `acc` about 150 m, and the
    // conflict point 20 m before the acceleration lane's end: far from 180 m and from any
    // network x (the freeway runs towards -x here).
    assert!(
        (420.0..440.0).contains(&merge.conflict_point),
        "conflict point {}",
        merge.conflict_point
    );
    // cosim's defaults (the policy alone, lane-change mode 257). With the proposal's
    // merge_from the egos take the first safe gap on the acceleration lane: SUMO seeds 0-4 all
    // had 0 controlled collisions (the previous traffic policies; seed 0 with the current ones). Merging at x_c only (the previous stop's deployment), 0-2 of
    // the 54 egos per run were rear-ended by a human right after merging.
    let (runs, _) = common::cosim_json(&["--end", "600"], &dir.join("user.sumocfg"), &dir.join("out"));
    let runs = runs.as_array().unwrap();
    assert_eq!(runs.len(), 3);
    for run in runs {
        let c = run["controller"].as_str().unwrap();
        let finished = run["summary"]["episodes"].as_u64().unwrap();
        eprintln!(
            "{c}: {finished} egos, mean speed {:.2} m/s",
            run["summary"]["mean_speed"].as_f64().unwrap()
        );
        assert!(finished >= 30, "{c}: {finished} controlled egos");
        // The traffic policies observe the road's speed: the freeway's 18 m/s limit.
        let expected = if c == "sumo" { None } else { Some(18.0) };
        assert_eq!(run["desired_speed"].as_f64(), expected, "{c}");
        assert_eq!(run["summary"]["collisions"], 0, "{c}");
        assert_eq!(
            controlled_collisions(run),
            0,
            "{c}: collisions involving a controlled vehicle"
        );
        // SSM metrics: cosim equipped every vehicle (the sumocfg has no device) and read the
        // log back; each ego carries its SSM fields.
        let ssm = std::fs::read_to_string(dir.join(format!("out/ssm-{c}.xml"))).unwrap();
        let doc = roxmltree::Document::parse(&ssm).unwrap();
        assert_eq!(doc.root_element().tag_name().name(), "SSMLog", "{c}");
        assert!(ssm.contains("<device.ssm.probability value=\"1\"/>"), "{c}");
        assert!(run["egos"][0].get("ssm_min_ttc").is_some(), "{c}");
    }
}
