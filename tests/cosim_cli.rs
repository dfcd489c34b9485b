//! `mpgdrive cosim` end to end: the three controllers on the paper's merge, bad input refused
//! with one message and exit code 2, and two mpgdrive clients sharing one SUMO.
#![cfg(feature = "sumo")]

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

const CFG: &str = "sumo_nets/single_lane_merge/merge.sumocfg";

mod common;

use common::bin;

fn temp_dir(name: &str) -> PathBuf {
    common::fresh_dir(&format!("cosim-{name}"))
}

/// A plain sumocfg in `dir` over the single-lane network with route file `routes` (relative to
/// `dir`), a 0.1 s step, and the network's merge.toml beside it.
fn plain_sumocfg(dir: &Path, name: &str, routes: &str) -> PathBuf {
    let net = std::fs::canonicalize("sumo_nets/single_lane_merge/merge.net.xml").unwrap();
    let path = dir.join(name);
    std::fs::write(
        &path,
        format!(
            "<configuration><input><net-file value=\"{}\"/><route-files value=\"{routes}\"/></input>\
             <time><step-length value=\"0.1\"/></time></configuration>\n",
            net.display()
        ),
    )
    .unwrap();
    std::fs::copy("sumo_nets/single_lane_merge/merge.toml", dir.join("merge.toml")).unwrap();
    path
}

/// Exit code 2, one line on stderr containing every needle, no panic.
fn assert_rejected(out: &Output, needles: &[&str]) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {stderr}");
    for needle in needles {
        assert!(stderr.contains(needle), "{needle:?} not in {stderr:?}");
    }
    assert_eq!(stderr.trim_end().lines().count(), 1, "one message: {stderr:?}");
    assert!(!stderr.contains("panicked"));
}

#[test]
fn three_controllers_run_side_by_side_and_write_their_results() {
    // A relative --out, as users type it: SUMO alone would resolve its output files against
    // the .sumocfg's folder.
    let relative = format!("target/test-cosim-run-{}", std::process::id());
    let out_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join(&relative);
    let _ = std::fs::remove_dir_all(&out_dir);
    let out = bin()
        .args([
            "cosim",
            "--sumocfg",
            CFG,
            "--end",
            "60",
            "--json",
            "--out",
            &relative,
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let runs: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let names: Vec<&str> = runs
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["controller"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["mpg", "sarl", "sumo"]);
    for r in runs.as_array().unwrap() {
        // 300 ramp vehicles per hour: a 60 s run picks up a few egos.
        assert!(!r["egos"].as_array().unwrap().is_empty(), "{r}");
        assert_eq!(r["seed"], 0);
        assert!(
            r["sumo_version"].as_str().unwrap().starts_with("SUMO 1."),
            "{}",
            r["sumo_version"]
        );
        assert!((r["simulated"].as_f64().unwrap() - 60.0).abs() < 1e-9);
        // From a directory every seed drives, as one policy; SUMO's drivers have none.
        let seeds: &[u64] = if r["controller"] == "sumo" {
            &[]
        } else {
            &[0, 1, 2, 3, 4]
        };
        assert_eq!(r["policy_seeds"], serde_json::json!(seeds), "{}", r["controller"]);
        // The speed profile covers the control zone in 20 m bands without a hole (picked up
        // at 80 m, 117.5 m before the world's x_c: the ramp's end at 200 m less half a length;
        // released 200 m past it, merge.toml's `release_after`), and its step-weighted mean
        // lies within the finished egos' own mean speeds.
        let bands = r["speed_by_position"].as_array().unwrap();
        let num = |b: &serde_json::Value, k: &str| b[k].as_f64().unwrap();
        assert!(!bands.is_empty(), "{r}");
        assert_eq!(num(&bands[0], "from"), -120.0, "{}", r["controller"]);
        assert!(num(bands.last().unwrap(), "to") <= 200.0);
        for pair in bands.windows(2) {
            assert_eq!(num(&pair[0], "to"), num(&pair[1], "from"));
        }
        let steps: f64 = bands.iter().map(|b| num(b, "steps")).sum();
        let mean = bands
            .iter()
            .map(|b| num(b, "mean_speed") * num(b, "steps"))
            .sum::<f64>()
            / steps;
        let own: Vec<f64> = r["egos"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|e| e["finished"] == true)
            .map(|e| e["metrics"]["mean_speed"].as_f64().unwrap())
            .collect();
        let (lo, hi) = own
            .iter()
            .fold((f64::MAX, f64::MIN), |(l, h), &v| (l.min(v), h.max(v)));
        assert!(
            lo - 1e-9 <= mean && mean <= hi + 1e-9,
            "{mean} outside {lo}..{hi}"
        );
        // The target lane's profile covers the same zone, whoever drives: from the pick-up
        // point's band to the release point's ([180, 200)), at speeds a car can have.
        let lane = r["lane_speed_by_position"].as_array().unwrap();
        assert_eq!(num(&lane[0], "from"), -120.0, "{}", r["controller"]);
        assert_eq!(num(lane.last().unwrap(), "to"), 200.0, "{}", r["controller"]);
        assert_eq!(lane.len(), 16);
        assert!(
            lane.iter()
                .all(|b| (0.0..=30.0).contains(&num(b, "mean_speed")) && num(b, "steps") > 0.0)
        );
    }
    let md = std::fs::read_to_string(out_dir.join("cosim.md")).unwrap();
    // Two tables: the egos' and the target lane's.
    let header =
        "| Distance past the conflict point (m) | mpg | sarl | sumo |\n|---|---|---|---|\n| -120 to -100 |";
    assert_eq!(md.matches(header).count(), 2, "{md}");
    for file in [
        "cosim.md",
        "cosim.json",
        "egos.csv",
        "tripinfo-mpg.xml",
        "ssm-sumo.xml",
    ] {
        assert!(out_dir.join(file).is_file(), "{file}");
    }
    let csv = std::fs::read_to_string(out_dir.join("egos.csv")).unwrap();
    assert!(csv.starts_with("controller,seed,id,"));
    for c in ["mpg", "sarl", "sumo"] {
        // SUMO empties a finished run's SSM file when the next run starts: restored.
        let ssm = std::fs::read_to_string(out_dir.join(format!("ssm-{c}.xml"))).unwrap();
        assert!(roxmltree::Document::parse(&ssm).is_ok(), "ssm-{c}.xml: {ssm:?}");
        let png = image::open(out_dir.join(format!("timespace_{c}.png"))).unwrap();
        assert_eq!((png.width(), png.height()), (1600, 900), "{c}");
    }
    // Without the diagrams: the same run writes none.
    let plain = format!("{relative}-plain");
    let out = bin()
        .args([
            "cosim",
            "--sumocfg",
            CFG,
            "--end",
            "20",
            "--controllers",
            "sumo",
            "--no-diagrams",
            "--out",
            &plain,
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let plain = Path::new(env!("CARGO_MANIFEST_DIR")).join(plain);
    assert!(plain.join("cosim.md").is_file() && !plain.join("timespace_sumo.png").exists());
}

#[test]
fn one_seed_drives_alone_and_differently_from_the_median_and_the_mean_of_the_seeds() {
    let dir = temp_dir("seeds");
    let run = |extra: &[&str], name: &str| {
        let args = [&["--controllers", "mpg", "--end", "60", "--no-diagrams"], extra].concat();
        let out = dir.join(name);
        let (runs, _) = common::cosim_json(&args, Path::new(CFG), &out);
        let md = std::fs::read_to_string(out.join("cosim.md")).unwrap();
        (runs[0].clone(), md)
    };
    let (alone, md) = run(&["--policy-seed", "2"], "alone");
    assert_eq!(alone["policy_seeds"], serde_json::json!([2]));
    assert!(md.contains("| Policy (training seeds) | seed 2 |"), "{md}");
    assert_eq!(alone["ensemble"], serde_json::Value::Null);
    let (median, md) = run(&[], "median");
    assert_eq!(median["ensemble"], "median");
    assert!(
        md.contains("| Policy (training seeds) | median of seeds 0, 1, 2, 3, 4 |"),
        "{md}"
    );
    let (mean, md) = run(&["--ensemble", "mean"], "mean");
    assert_eq!(mean["ensemble"], "mean");
    assert!(
        md.contains("| Policy (training seeds) | mean of seeds 0, 1, 2, 3, 4 |"),
        "{md}"
    );
    // The same egos (same routes and SUMO seed), driven by other actions.
    let speeds = |r: &serde_json::Value| -> Vec<f64> {
        r["egos"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e["metrics"]["mean_speed"].as_f64().unwrap())
            .collect()
    };
    let (a, d, m) = (speeds(&alone), speeds(&median), speeds(&mean));
    assert!(
        !a.is_empty() && a.len() == m.len() && d.len() == m.len(),
        "{a:?} {d:?} {m:?}"
    );
    assert!(a.iter().zip(&m).any(|(x, y)| (x - y).abs() > 1e-6), "{a:?} {m:?}");
    assert!(d.iter().zip(&m).any(|(x, y)| (x - y).abs() > 1e-6), "{d:?} {m:?}");
}

#[test]
fn seeds_of_two_network_shapes_are_refused_as_one_policy() {
    use mpgdrive::policy::{NetSpec, PolicyNet, file, observation::Layout};
    let dir = temp_dir("shapes");
    let set = dir.join("set");
    std::fs::create_dir_all(&set).unwrap();
    for ext in ["json", "safetensors"] {
        std::fs::copy(
            format!("policies/traffic/mpg/seed0.{ext}"),
            set.join(format!("seed0.{ext}")),
        )
        .unwrap();
    }
    // Seed 9: the same world and layout, 8 hidden units instead of 64.
    let text = std::fs::read_to_string("policies/traffic/mpg/seed0.json").unwrap();
    let mut side: file::Sidecar = serde_json::from_str(&text).unwrap();
    let narrow = PolicyNet::seeded(NetSpec::new(Layout::Traffic, 8, side.net.action_scale), 9);
    side.seed = 9;
    side.net = narrow.spec.clone();
    file::save(&set.join("seed9"), &narrow, &side).unwrap();
    let out = bin()
        .args(["cosim", "--sumocfg", CFG, "--controllers", "mpg", "--end", "5"])
        .arg("--policy")
        .arg(&set)
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .unwrap();
    assert_rejected(
        &out,
        &["do not fit together", "8 hidden units", "64 hidden units"],
    );
    assert!(!dir.join("out").exists());
    // Either seed alone deploys.
    let (runs, _) = common::cosim_json(
        &[
            "--controllers",
            "mpg",
            "--end",
            "5",
            "--no-diagrams",
            "--policy-seed",
            "9",
            "--policy",
            set.to_str().unwrap(),
        ],
        Path::new(CFG),
        &dir.join("nine"),
    );
    assert_eq!(runs[0]["policy_seeds"], serde_json::json!([9]));
}

#[test]
fn a_lane_that_is_not_in_the_network_is_named_with_the_lanes_that_are() {
    let dir = temp_dir("lane");
    let merge = std::fs::read_to_string("sumo_nets/single_lane_merge/merge.toml")
        .unwrap()
        .replace("\"merge_1\"", "\"merge_7\"");
    let path = dir.join("merge.toml");
    std::fs::write(&path, merge).unwrap();
    let out = bin()
        .args([
            "cosim",
            "--sumocfg",
            CFG,
            "--controllers",
            "sumo",
            "--end",
            "1",
            "--merge",
        ])
        .arg(&path)
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    // The message names the --merge file, not the merge.toml beside the .sumocfg.
    let named = path.display().to_string();
    assert_rejected(&out, &[&named, "merge_7", "target_lanes", "merge_1", "ramp_0"]);
}

#[test]
fn unknown_merge_keys_and_missing_files_are_refused() {
    let dir = temp_dir("keys");
    let path = dir.join("merge.toml");
    std::fs::write(
        &path,
        std::fs::read_to_string("sumo_nets/single_lane_merge/merge.toml").unwrap() + "conflict_pont = 3\n",
    )
    .unwrap();
    let run = |merge: &Path, cfg: &str| {
        bin()
            .args([
                "cosim",
                "--controllers",
                "sumo",
                "--end",
                "1",
                "--sumocfg",
                cfg,
                "--merge",
            ])
            .arg(merge)
            .output()
            .unwrap()
    };
    assert_rejected(&run(&path, CFG), &["conflict_pont"]);
    assert_rejected(&run(&path, "sumo_nets/nowhere.sumocfg"), &["nowhere.sumocfg"]);
}

#[test]
fn route_files_are_checked_before_sumo_starts_and_sumo_names_the_rest() {
    let dir = temp_dir("routes");
    let cfg = plain_sumocfg(&dir, "bad.sumocfg", "bad.rou.xml");
    let run = |routes: &str, out: &str| {
        std::fs::write(dir.join("bad.rou.xml"), routes).unwrap();
        bin()
            .args(["cosim", "--controllers", "sumo", "--end", "5", "--sumocfg"])
            .arg(&cfg)
            .arg("--out")
            .arg(dir.join(out))
            .output()
            .unwrap()
    };
    // Not well-formed, or a route nobody defines: refused by mpgdrive, nothing written.
    let unclosed = run("<routes>\n  <vehicle id=\"x\" depart=\"0\">\n</routes>\n", "a");
    assert_rejected(&unclosed, &["bad.rou.xml", "not well-formed XML"]);
    let unknown = run(
        "<routes><vehicle id=\"x\" depart=\"0\" route=\"r9\"/></routes>\n",
        "b",
    );
    assert_rejected(&unknown, &["bad.rou.xml", "`x` uses route `r9`"]);
    assert!(!dir.join("a").exists() && !dir.join("b").exists());
    // Well-formed, but a vehicle with neither a route nor a trip: SUMO's own message.
    let out = run("<routes><vehicle id=\"x\" depart=\"0\"/></routes>\n", "c");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("SUMO error"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}

#[test]
fn a_bad_configuration_or_a_conflict_point_off_the_network_writes_nothing() {
    let dir = temp_dir("inputs");
    std::fs::write(dir.join("garbage.sumocfg"), "this is not XML\n").unwrap();
    std::fs::write(dir.join("routes.sumocfg"), "<routes/>\n").unwrap();
    let far = std::fs::read_to_string("sumo_nets/single_lane_merge/merge.toml")
        .unwrap()
        .replace("conflict_point = 180.0", "conflict_point = 99999.0");
    assert!(far.contains("99999"));
    std::fs::write(dir.join("far.toml"), far).unwrap();
    let reversed = std::fs::read_to_string("sumo_nets/single_lane_merge/merge.toml")
        .unwrap()
        .replace(
            "[\"main_0\", \"merge_1\", \"out_0\"]",
            "[\"out_0\", \"merge_1\", \"main_0\"]",
        );
    assert!(reversed.contains("\"out_0\", \"merge_1\""));
    std::fs::write(dir.join("reversed.toml"), reversed).unwrap();
    let run = |cfg: &Path, merge: &str, out: &str| {
        bin()
            .args(["cosim", "--controllers", "sumo", "--end", "5", "--sumocfg"])
            .arg(cfg)
            .args(["--merge", merge, "--out"])
            .arg(dir.join(out))
            .output()
            .unwrap()
    };
    let merge = "sumo_nets/single_lane_merge/merge.toml";
    assert_rejected(
        &run(&dir.join("garbage.sumocfg"), merge, "a"),
        &["garbage.sumocfg", "not well-formed XML"],
    );
    assert_rejected(
        &run(&dir.join("routes.sumocfg"), merge, "b"),
        &["not a SUMO configuration"],
    );
    let far = dir.join("far.toml").display().to_string();
    assert_rejected(
        &run(Path::new(CFG), &far, "c"),
        &[
            "far.toml",
            "conflict_point 99999 m is not on the acceleration lane",
        ],
    );
    let reversed = dir.join("reversed.toml").display().to_string();
    assert_rejected(
        &run(Path::new(CFG), &reversed, "d"),
        &[
            "reversed.toml",
            "`out_0` does not lead to `merge_1`",
            "driving order",
        ],
    );
    for out in ["a", "b", "c", "d"] {
        assert!(!dir.join(out).exists(), "{out} written");
    }
}

/// A free TCP port on localhost.
fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

#[test]
fn two_clients_share_one_sumo_and_the_first_detach_leaves_it_running() {
    let port = free_port();
    let mut server = Command::new("sumo")
        .args([
            "-c",
            CFG,
            "--no-step-log",
            "true",
            "--no-warnings",
            "true",
            "--num-clients",
            "2",
        ])
        .args([
            "--remote-port",
            &port.to_string(),
            "--tripinfo-output",
            "/dev/null",
        ])
        .args(["--device.ssm.file", "/dev/null"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("sumo on the PATH");
    let client = |order: &str, end: &str| {
        bin()
            .args([
                "cosim",
                "--sumocfg",
                CFG,
                "--controllers",
                "sumo",
                "--json",
                "--attach",
            ])
            .args([&port.to_string(), "--order", order, "--end", end, "--out"])
            .arg(temp_dir(&format!("attach{order}")))
            .stderr(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .unwrap()
    };
    let first = client("1", "20");
    let second = client("2", "30");
    let first = first.wait_with_output().unwrap();
    let second = second.wait_with_output().unwrap();
    let _ = server.wait();
    for (out, end) in [(&first, 20.0), (&second, 30.0)] {
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let runs: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let simulated = runs[0]["simulated"].as_f64().unwrap();
        assert!(
            (simulated - end).abs() < 1e-9,
            "client ending at {end} saw {simulated}"
        );
    }
}

/// Egos of a `cosim --json` run, without the timings (they differ from run to run).
fn egos_of(out: &Output) -> serde_json::Value {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let runs: serde_json::Value = serde_json::from_slice(&out.stdout).expect("stdout is the JSON alone");
    runs[0]["egos"].clone()
}

#[test]
fn the_gui_run_drives_sumo_gui_exactly_as_the_headless_run() {
    // sumo-gui on a virtual display (xvfb, installed by scripts/setup.sh), through libtraci,
    // and without SUMO_HOME, where sumo-gui 1.15 alone refuses the route file offline.
    let dir = temp_dir("gui");
    let run = |gui: bool| {
        let mut cmd = if gui {
            let mut c = Command::new("xvfb-run");
            c.args(["-a", env!("CARGO_BIN_EXE_mpgdrive")])
                .current_dir(env!("CARGO_MANIFEST_DIR"));
            c
        } else {
            bin()
        };
        cmd.args([
            "cosim",
            "--sumocfg",
            CFG,
            "--controllers",
            "mpg",
            "--end",
            "40",
            "--json",
        ])
        .args(if gui { &["--gui"][..] } else { &[] })
        .arg("--out")
        .arg(dir.join(if gui { "gui" } else { "headless" }))
        .env_remove("SUMO_HOME")
        .output()
        .unwrap()
    };
    let headless = egos_of(&run(false));
    assert!(!headless.as_array().unwrap().is_empty(), "{headless}");
    assert_eq!(egos_of(&run(true)), headless);
}

#[test]
fn a_configuration_without_an_ssm_device_gets_one_for_the_metrics() {
    // A user's plain sumocfg and routes: no SSM device anywhere.
    let dir = temp_dir("no-ssm");
    let routes = std::fs::read_to_string("sumo_nets/single_lane_merge/merge.rou.xml")
        .unwrap()
        .replace("<param key=\"has.ssm.device\" value=\"true\"/>", "");
    assert!(!routes.contains("ssm"));
    std::fs::write(dir.join("r.rou.xml"), routes).unwrap();
    let cfg = plain_sumocfg(&dir, "plain.sumocfg", "r.rou.xml");
    let (runs, stderr) =
        common::cosim_json(&["--controllers", "sumo", "--end", "60"], &cfg, &dir.join("out"));
    assert!(
        stderr.contains("equips no vehicle with the SSM device"),
        "{stderr}"
    );
    let ssm = std::fs::read_to_string(dir.join("out/ssm-sumo.xml")).unwrap();
    assert!(roxmltree::Document::parse(&ssm).is_ok());
    assert!(!runs[0]["egos"].as_array().unwrap().is_empty());
}

#[test]
fn a_configuration_at_another_step_length_runs_at_the_policys() {
    // Flow's benchmarks and many public scenarios step SUMO at 0.2-1 s; the policy acts every
    // sim.dt (0.1 s). Such a configuration runs as the same one at 0.1 s, and says so.
    let dir = temp_dir("step");
    std::fs::copy("sumo_nets/single_lane_merge/merge.rou.xml", dir.join("r.rou.xml")).unwrap();
    let cfg = plain_sumocfg(&dir, "at01.sumocfg", "r.rou.xml");
    let coarse = dir.join("at05.sumocfg");
    let text = std::fs::read_to_string(&cfg).unwrap();
    std::fs::write(&coarse, text.replace("value=\"0.1\"", "value=\"0.5\"")).unwrap();
    let args = ["--controllers", "mpg,sumo", "--end", "60"];
    let (fine, _) = common::cosim_json(&args, &cfg, &dir.join("fine"));
    let (runs, stderr) = common::cosim_json(&args, &coarse, &dir.join("coarse"));
    assert!(
        stderr.contains("sets step-length 0.5 s: SUMO runs at the policy's 0.1 s"),
        "{stderr}"
    );
    for (a, b) in fine.as_array().unwrap().iter().zip(runs.as_array().unwrap()) {
        assert!(!a["egos"].as_array().unwrap().is_empty(), "{a}");
        assert_eq!(a["egos"], b["egos"]);
        assert_eq!(a["mean_time_loss"], b["mean_time_loss"]);
    }
}

#[test]
fn a_configuration_with_the_ballistic_update_or_mesoscopic_runs_in_the_policys_world() {
    // The policy's world moves each vehicle by one speed per step, on lanes. Under SUMO's
    // ballistic update a held ego slid past its stop line into the junction in front of a car
    // (a netconvert junction merge, 2,400 + 500 veh/h: 4 controlled collisions in 300 s), and a
    // mesoscopic run had no SSM output. Either runs as the same configuration without it.
    let dir = temp_dir("dynamics");
    std::fs::copy("sumo_nets/single_lane_merge/merge.rou.xml", dir.join("r.rou.xml")).unwrap();
    let cfg = plain_sumocfg(&dir, "plain.sumocfg", "r.rou.xml");
    let text = std::fs::read_to_string(&cfg).unwrap();
    for (name, option) in [
        (
            "ballistic",
            "<processing><step-method.ballistic value=\"true\"/></processing>",
        ),
        ("meso", "<mesoscopic><mesosim value=\"true\"/></mesoscopic>"),
    ] {
        let other = dir.join(format!("{name}.sumocfg"));
        std::fs::write(
            &other,
            text.replace("</configuration>", &format!("{option}</configuration>")),
        )
        .unwrap();
        let args = ["--controllers", "mpg,sumo", "--end", "60"];
        let (plain, _) = common::cosim_json(&args, &cfg, &dir.join("plain"));
        let (runs, stderr) = common::cosim_json(&args, &other, &dir.join(name));
        assert!(
            stderr.contains("SUMO runs with the policy's world's update"),
            "{stderr}"
        );
        for (a, b) in plain.as_array().unwrap().iter().zip(runs.as_array().unwrap()) {
            assert!(!a["egos"].as_array().unwrap().is_empty(), "{a}");
            assert_eq!(
                (&a["egos"], &a["mean_time_loss"]),
                (&b["egos"], &b["mean_time_loss"]),
                "{name}"
            );
        }
    }
}

#[test]
fn a_configuration_that_begins_later_runs_its_duration_from_its_begin() {
    // Public scenarios begin at the hour they model (6:00 is 21,600 s): the same traffic an hour
    // later, in a configuration that begins at "1:00:00", gives the same run an hour later.
    let dir = temp_dir("begin");
    let routes = std::fs::read_to_string("sumo_nets/single_lane_merge/merge.rou.xml").unwrap();
    std::fs::write(dir.join("r.rou.xml"), &routes).unwrap();
    let later = routes.replace(r#"begin="0" end="300""#, r#"begin="3600" end="3900""#);
    std::fs::write(dir.join("later.rou.xml"), later).unwrap();
    let cfg = plain_sumocfg(&dir, "now.sumocfg", "r.rou.xml");
    let text = std::fs::read_to_string(plain_sumocfg(&dir, "then.sumocfg", "later.rou.xml")).unwrap();
    let then = dir.join("then.sumocfg");
    std::fs::write(&then, text.replace("<time>", "<time><begin value=\"1:00:00\"/>")).unwrap();
    let args = ["--controllers", "mpg,sumo", "--end", "90"];
    let (now, _) = common::cosim_json(&args, &cfg, &dir.join("now"));
    let (later, _) = common::cosim_json(&args, &then, &dir.join("then"));
    for (a, b) in now.as_array().unwrap().iter().zip(later.as_array().unwrap()) {
        assert_eq!((&a["simulated"], &b["simulated"]), (&90.0.into(), &90.0.into()));
        assert_eq!(a["mean_time_loss"], b["mean_time_loss"]);
        let (x, y) = (a["egos"].as_array().unwrap(), b["egos"].as_array().unwrap());
        assert!(
            x.len() >= 5 && x.len() == y.len(),
            "{} and {} egos",
            x.len(),
            y.len()
        );
        for (e, f) in x.iter().zip(y) {
            assert_eq!((&e["id"], &e["metrics"]), (&f["id"], &f["metrics"]));
            let shift = f["start"].as_f64().unwrap() - e["start"].as_f64().unwrap();
            assert!((shift - 3600.0).abs() < 1e-6, "{shift}");
        }
    }
}

#[test]
fn egos_that_signal_their_merge_get_room_from_sumos_drivers() {
    // `single_lane_merge` at demand 1.2 (routes seed 0), ego only, without SUMO's safe speed
    // (docs/experiments.md). Before the entry rule, with lane-change mode 256
    // (egos neither signal nor change lanes on their own) `onramp.17` braked for the lane's end
    // beside the 17 m/s lane and was forced in at x_c in front of a car closing at 8.6 m/s
    // (TTC 1.3 s). Under the entry rule nothing forces an entry: it waits for a gap instead, and
    // no ego has a conflict in either mode. Signalling (257, `cosim`'s default) still pays: that
    // car makes room and `onramp.17` loses less time.
    let dir = temp_dir("signal");
    let routes = dir.join("routes");
    let out = bin()
        .args([
            "routes",
            "--base",
            "sumo_nets/single_lane_merge/merge.rou.xml",
            "--merge",
            "sumo_nets/single_lane_merge/merge.toml",
            "--scales",
            "1.2",
            "--seeds",
            "0",
            "--duration",
            "900",
            "--out",
        ])
        .arg(&routes)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let merge = dir.join("merge.toml");
    let toml = std::fs::read_to_string("sumo_nets/single_lane_merge/merge.toml").unwrap();
    let ego_only: String = toml
        .lines()
        .map(|l| {
            if l.starts_with("players") {
                "players = \"controllable\""
            } else {
                l
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(&merge, ego_only + "\n").unwrap();
    let run = |mode: Option<&str>| {
        let routes = routes.join("merge_d1.20_s0.rou.xml");
        let mut args = vec![
            "--controllers",
            "mpg",
            "--route-files",
            routes.to_str().unwrap(),
            "--merge",
            merge.to_str().unwrap(),
            "--speed-mode",
            "0",
            "--end",
            "200",
            "--no-diagrams",
        ];
        args.extend(mode.map(|m| ["--lane-change-mode", m]).into_iter().flatten());
        let (runs, _) = common::cosim_json(&args, Path::new(CFG), &dir.join(mode.unwrap_or("default")));
        runs[0].clone()
    };
    let in_conflict = |run: &serde_json::Value| -> Vec<String> {
        run["egos"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|e| !e["ssm_min_ttc"].is_null() || !e["ssm_max_drac"].is_null())
            .map(|e| e["id"].as_str().unwrap().to_string())
            .collect()
    };
    let silent = run(Some("256"));
    assert_eq!(silent["shields"]["lane_change_mode"], 256);
    assert_eq!(in_conflict(&silent), Vec::<String>::new());
    let signalling = run(None);
    assert_eq!(signalling["shields"]["lane_change_mode"], 257);
    assert_eq!(signalling["shields"]["speed_mode"], 0);
    assert_eq!(in_conflict(&signalling), Vec::<String>::new());
    assert_eq!(
        signalling["egos"].as_array().unwrap().len(),
        silent["egos"].as_array().unwrap().len(),
        "the same egos"
    );
    let time_loss = |run: &serde_json::Value| {
        let ego = run["egos"]
            .as_array()
            .unwrap()
            .iter()
            .find(|e| e["id"] == "onramp.17");
        let ego = ego.expect("onramp.17 is an ego");
        assert_eq!(ego["finished"], true);
        ego["time_loss"].as_f64().unwrap()
    };
    // Measured: 14.72 s waiting silently, 9.21 s signalling.
    assert!(time_loss(&signalling) + 3.0 < time_loss(&silent));
}

#[test]
fn the_default_speed_mode_follows_what_the_policys_scenes_hold() {
    // A traffic policy's scenes hold every vehicle in the control zone, so the policy drives
    // alone (speed mode 0); a Table I game holds nine players, so SUMO's safe speed (25)
    // guards it against the rest. An explicit --speed-mode wins.
    let dir = std::env::temp_dir().join(format!("mpgdrive-speed-mode-{}", std::process::id()));
    let mode = |extra: &[&str], name: &str| {
        let mut args = vec!["--controllers", "mpg", "--end", "20", "--no-diagrams"];
        args.extend_from_slice(extra);
        let (runs, _) = common::cosim_json(&args, Path::new(CFG), &dir.join(name));
        runs[0]["shields"]["speed_mode"].as_i64().unwrap()
    };
    assert_eq!(mode(&[], "traffic"), 0);
    assert_eq!(
        mode(
            &["--config", "configs/paper.toml", "--policy", "policies/mpg"],
            "table1"
        ),
        25
    );
    assert_eq!(mode(&["--speed-mode", "25"], "shielded"), 25);
    std::fs::remove_dir_all(&dir).ok();
}
