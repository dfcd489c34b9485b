//! A corpus of bad inputs across every command, tried as a new user would: each is refused
//! with exit code 2 and one clear message naming the problem, without a panic, and writes
//! nothing (its output folder does not appear).

mod common;

use common::{bin, fresh_dir};
use std::path::Path;

/// One bad input: files to write into the case's folder, the command line (`{D}` is the
/// case's folder), and what the message must say.
struct Case {
    name: &'static str,
    files: Vec<(&'static str, String)>,
    args: Vec<&'static str>,
    needle: &'static str,
}

fn read(path: &str) -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(path)).unwrap()
}

fn smoke() -> String {
    read("configs/smoke.toml")
}

/// The smoke configuration with `line` added at the top of its `[train]` table.
fn smoke_train(line: &str) -> String {
    smoke().replace("[train]\n", &format!("[train]\n{line}\n"))
}

/// The smoke configuration with one line's value replaced (the line starting with `key =`).
fn smoke_with(key: &str, value: &str) -> String {
    let text = smoke();
    let mut found = false;
    let out: Vec<String> = text
        .lines()
        .map(|l| {
            if l.starts_with(&format!("{key} ")) || l.starts_with(&format!("{key}=")) {
                found = true;
                format!("{key} = {value}")
            } else {
                l.to_string()
            }
        })
        .collect();
    assert!(found, "smoke.toml has no `{key}`");
    out.join("\n") + "\n"
}

fn merge_with(from: &str, to: &str) -> String {
    let text = read("sumo_nets/single_lane_merge/merge.toml");
    assert!(text.contains(from), "{from}");
    text.replacen(from, to, 1)
}

const CFG: &str = "sumo_nets/single_lane_merge/merge.sumocfg";
const NET: &str = "sumo_nets/single_lane_merge/merge.net.xml";

fn sumocfg(body: &str) -> String {
    let net = std::fs::canonicalize(Path::new(env!("CARGO_MANIFEST_DIR")).join(NET)).unwrap();
    format!(
        "<configuration><input><net-file value=\"{}\"/>{body}</input></configuration>\n",
        net.display()
    )
}

fn cases() -> Vec<Case> {
    let c = |name, files: Vec<(&'static str, String)>, args: Vec<&'static str>, needle| Case {
        name,
        files,
        args,
        needle,
    };
    // A command reading one configuration file, `{D}/c.toml`, holding `text`.
    let with_config =
        |name, args: Vec<&'static str>, text: String, needle| c(name, vec![("c.toml", text)], args, needle);
    let traffic_eval = |name, text: String, needle| {
        let args = vec![
            "eval",
            "--config",
            "{D}/c.toml",
            "--policy",
            "policies/traffic/mpg",
        ];
        with_config(name, args, text, needle)
    };
    let demo = |name, text: String, needle| {
        with_config(
            name,
            vec!["demo", "--scenarios", "2", "--config", "{D}/c.toml"],
            text,
            needle,
        )
    };
    let train = |name, text: String, needle| {
        let args = vec![
            "train",
            "--config",
            "{D}/c.toml",
            "--seeds",
            "0",
            "--out",
            "{D}/out",
        ];
        with_config(name, args, text, needle)
    };
    let cosim = |name, files: Vec<(&'static str, String)>, extra: Vec<&'static str>, needle| {
        let mut args = vec!["cosim", "--controllers", "sumo", "--end", "5", "--out", "{D}/out"];
        args.extend(extra);
        c(name, files, args, needle)
    };
    let cosim_merge = |name, text: String, needle| {
        cosim(
            name,
            vec![("m.toml", text)],
            vec!["--sumocfg", CFG, "--merge", "{D}/m.toml"],
            needle,
        )
    };
    let routes = |name, extra: Vec<&'static str>, needle| {
        let mut args = vec!["routes", "--duration", "60", "--out", "{D}/out"];
        args.extend(extra);
        c(name, Vec::new(), args, needle)
    };
    // A base route file written into the case's folder, with the I-80 geometry.
    let routes_base = |name, text: String, needle| {
        c(
            name,
            vec![("b.rou.xml", text)],
            vec![
                "routes",
                "--base",
                "{D}/b.rou.xml",
                "--merge",
                "sumo_nets/i80_merge/merge.toml",
                "--out",
                "{D}/out",
            ],
            needle,
        )
    };
    let batch = |name, files: Vec<(&'static str, String)>, extra: Vec<&'static str>, needle| {
        let mut args = vec!["batch", "--controllers", "sumo", "--end", "5", "--out", "{D}/out"];
        args.extend(extra);
        c(name, files, args, needle)
    };
    let report = |name, files: Vec<(&'static str, String)>, extra: Vec<&'static str>, needle| {
        let mut args = vec!["report", "--config", "configs/smoke.toml", "--out", "{D}/out"];
        args.extend(extra);
        c(name, files, args, needle)
    };
    let ngsim = |name, files: Vec<(&'static str, String)>, extra: Vec<&'static str>, needle| {
        let mut args = vec!["ngsim"];
        args.extend(extra);
        c(name, files, args, needle)
    };
    let garbage_rows = "this is not\nan NGSIM file\n".to_string();
    vec![
        // Configuration files (through demo and train).
        demo("unknown key", smoke() + "bogus = 1\n", "bogus"),
        demo("NaN step", smoke_with("dt", "nan"), "dt"),
        demo("negative step", smoke_with("dt", "-0.1"), "dt"),
        demo("zero horizon", smoke_with("horizon", "0.0"), "horizon"),
        demo("discount above 1", smoke_with("gamma", "1.5"), "gamma"),
        demo("negative TTC threshold", smoke_with("tau_s", "-1.0"), "tau_s"),
        demo(
            "NaN projection time gap",
            smoke().replacen("safety_gap = 2.0", "safety_gap = 2.0\ntime_headway = nan", 1),
            "sim.time_headway",
        ),
        demo(
            "NaN lane-end braking",
            smoke().replacen("b_safe = 4.0", "b_safe = 4.0\nlane_end_brake = nan", 1),
            "sim.lane_end_brake",
        ),
        demo(
            "lane-end braking beyond g",
            smoke().replacen("b_safe = 4.0", "b_safe = 4.0\nlane_end_brake = 12.0", 1),
            "sim.lane_end_brake",
        ),
        demo(
            "shared correction below half",
            smoke_with("shared_correction", "0.3"),
            "sim.shared_correction",
        ),
        demo("inverted speed limits", smoke_with("v_max", "-1.0"), "v_max"),
        demo(
            "inverted headway range",
            smoke_with("headway", "[30.0, 7.0]"),
            "headway",
        ),
        demo(
            "conflict point off the road",
            smoke_with("conflict_point", "-5.0"),
            "conflict_point",
        ),
        demo(
            "two forms of the conflict term",
            smoke().replacen(
                "w_conflict = 5.0",
                "w_conflict = 5.0\nconflict_ends_at_x_c = true\nconflict_signed_time = true",
                1,
            ),
            "reward.conflict_signed_time",
        ),
        demo("a string for a number", smoke_with("dt", "\"fast\""), "dt"),
        demo("not TOML", "this is = = not toml\n".into(), "c.toml"),
        demo("empty strata", smoke_with("strata", "[0, 4]"), "strata"),
        demo(
            "infinite acceleration",
            smoke_with("max_accel", "inf"),
            "max_accel",
        ),
        demo("zero vehicle length", smoke_with("length", "0.0"), "length"),
        c(
            "missing config",
            Vec::new(),
            vec!["demo", "--config", "{D}/nowhere.toml"],
            "nowhere.toml",
        ),
        train("zero batch", smoke_with("batch", "0"), "batch"),
        train(
            "zero checkpoint period",
            smoke_with("checkpoint_every", "0"),
            "checkpoint_every",
        ),
        train(
            "zero probe set",
            smoke_with("probe_scenarios", "0"),
            "probe_scenarios",
        ),
        train(
            "negative learning rate",
            smoke_with("learning_rate", "-0.01"),
            "learning_rate",
        ),
        train("zero gradient clip", smoke_with("grad_clip", "0.0"), "grad_clip"),
        train(
            "a near-merge share above 1",
            smoke()
                + "\n[train.near_merge]\nshare = 1.5\nego_position = [150.0, 178.0]\nego_speed = [0.0, 8.0]\n",
            "train.near_merge.share",
        ),
        train(
            "a near-merge ego beyond the conflict point",
            smoke()
                + "\n[train.near_merge]\nshare = 0.2\nego_position = [150.0, 250.0]\nego_speed = [0.0, 8.0]\n",
            "train.near_merge.ego_position",
        ),
        train(
            "a NaN scenario share",
            smoke_train("scenario_share = nan"),
            "train.scenario_share",
        ),
        train(
            "a probe scenario share above 1",
            smoke_train("probe_scenario_share = 1.5"),
            "train.probe_scenario_share",
        ),
        train(
            "scenario states from an epoch training never reaches",
            smoke_train("scenario_from = 100000"),
            "train.scenario_from",
        ),
        train(
            "a step-size restart at the run's last epoch",
            smoke_train("learning_rate_restarts = [15]"),
            "train.learning_rate_restarts",
        ),
        train(
            "step-size restarts out of order",
            smoke_train("learning_rate_restarts = [8, 4]"),
            "train.learning_rate_restarts",
        ),
        train(
            "a NaN probe scenario share",
            smoke_train("probe_scenario_share = nan"),
            "train.probe_scenario_share",
        ),
        train(
            "scenario and near-merge shares above 1 together",
            smoke_train("scenario_share = 0.8")
                + "\n[train.near_merge]\nshare = 0.25\nego_position = [150.0, 178.0]\nego_speed = [0.0, 8.0]\n",
            "train.scenario_share",
        ),
        train(
            "a continuation that starts below the reward's epsilon",
            smoke() + "\n[train.continuation]\nepsilon_start = 0.001\nepochs = 5\n",
            "train.continuation.epsilon_start",
        ),
        train(
            "a continuation over no epochs",
            smoke() + "\n[train.continuation]\nepsilon_start = 1.0\nepochs = 0\n",
            "train.continuation.epochs",
        ),
        train("zero hidden width", smoke_with("hidden", "0"), "hidden"),
        train("zero epochs", smoke_with("epochs", "0"), "epochs"),
        train("zero threads", smoke_with("threads", "0"), "threads"),
        // Command-line numbers and policies.
        c(
            "zero threads on the command line",
            Vec::new(),
            vec!["demo", "--threads", "0"],
            "--threads",
        ),
        c(
            "a missing policy",
            Vec::new(),
            vec!["eval", "--config", "configs/smoke.toml", "--policy", "{D}/none"],
            "none",
        ),
        c(
            "a policy sidecar that is not JSON",
            vec![("p.json", "{not json".into()), ("p.safetensors", "x".into())],
            vec!["eval", "--config", "configs/smoke.toml", "--policy", "{D}/p.json"],
            "p.json",
        ),
        c(
            "a policy trained with another step",
            vec![(
                "c.toml",
                read("configs/paper.toml").replace("dt = 0.1 ", "dt = 0.2 "),
            )],
            vec!["eval", "--config", "{D}/c.toml", "--policy", "policies/mpg"],
            "sim.dt",
        ),
        traffic_eval(
            "a traffic world without its [traffic] section",
            smoke_with("n_followers", "4\nkind = \"traffic\""),
            "needs a [traffic] section",
        ),
        traffic_eval(
            "a traffic human share above 1",
            read("configs/traffic.toml").replace("human_share = [0.0, 1.0]", "human_share = [0.0, 1.6]"),
            "traffic.human_share",
        ),
        c(
            "a Table I policy for a traffic world",
            Vec::new(),
            vec![
                "eval",
                "--config",
                "configs/traffic.toml",
                "--policy",
                "policies/mpg",
            ],
            "observation layout version 2",
        ),
        c(
            "an empty policy folder",
            vec![("pol/readme.txt", "nothing".into())],
            vec!["eval", "--config", "configs/smoke.toml", "--policy", "{D}/pol"],
            "no policy",
        ),
        c(
            "scenario policy missing",
            Vec::new(),
            vec![
                "scenario", "--preset", "1", "--policy", "{D}/none", "--out", "{D}/out",
            ],
            "none",
        ),
        c(
            "a policy seed that is not there",
            Vec::new(),
            vec![
                "scenario",
                "--preset",
                "1",
                "--policy-seed",
                "99",
                "--out",
                "{D}/out",
            ],
            "seed 99",
        ),
        // Co-simulation inputs.
        cosim(
            "missing sumocfg",
            Vec::new(),
            vec!["--sumocfg", "{D}/none.sumocfg"],
            "none.sumocfg",
        ),
        cosim(
            "garbage sumocfg",
            vec![("g.sumocfg", "garbage\n".into())],
            vec!["--sumocfg", "{D}/g.sumocfg"],
            "not well-formed XML",
        ),
        cosim(
            "a route file as sumocfg",
            vec![("r.sumocfg", "<routes/>\n".into())],
            vec!["--sumocfg", "{D}/r.sumocfg"],
            "not a SUMO configuration",
        ),
        cosim(
            "sumocfg without a network",
            vec![("n.sumocfg", "<configuration><input/></configuration>\n".into())],
            vec![
                "--sumocfg",
                "{D}/n.sumocfg",
                "--merge",
                "sumo_nets/single_lane_merge/merge.toml",
            ],
            "names no network",
        ),
        cosim(
            "a step length that is not a positive number",
            vec![
                (
                    "s.sumocfg",
                    sumocfg("").replace("</input>", "</input><time><step-length value=\"-0.5\"/></time>"),
                ),
                ("merge.toml", read("sumo_nets/single_lane_merge/merge.toml")),
            ],
            vec!["--sumocfg", "{D}/s.sumocfg"],
            "step-length \"-0.5\" is not a positive number",
        ),
        cosim(
            "a begin that is not a time",
            vec![
                (
                    "s.sumocfg",
                    sumocfg("").replace("</input>", "</input><time><begin value=\"6 am\"/></time>"),
                ),
                ("merge.toml", read("sumo_nets/single_lane_merge/merge.toml")),
            ],
            vec!["--sumocfg", "{D}/s.sumocfg"],
            "begin \"6 am\" is not a time of 0 s or later",
        ),
        cosim_merge(
            "merge.toml unknown key",
            merge_with("players", "playrs"),
            "playrs",
        ),
        cosim_merge(
            "merge.toml negative desired speed",
            merge_with("\nplayers = ", "\ndesired_speed = -5.0\nplayers = "),
            "desired_speed",
        ),
        cosim_merge(
            "merge.toml lane not in the network",
            merge_with("\"merge_1\"", "\"merge_7\""),
            "merge_7",
        ),
        cosim_merge(
            "conflict point beyond the network",
            merge_with("conflict_point = 180.0", "conflict_point = 99999.0"),
            "99999",
        ),
        cosim_merge(
            "control zone after the conflict point",
            merge_with("control_from = 80.0", "control_from = 200.0"),
            "control_from",
        ),
        cosim_merge(
            "no ramp lanes",
            merge_with("ramp_lanes = [", "ramp_lanes = [] #"),
            "ramp_lanes",
        ),
        cosim_merge(
            "NaN conflict point",
            merge_with("conflict_point = 180.0", "conflict_point = nan"),
            "conflict_point",
        ),
        cosim(
            "a route file that is not XML",
            vec![("r.rou.xml", "not xml".into())],
            vec!["--sumocfg", CFG, "--route-files", "{D}/r.rou.xml"],
            "not well-formed XML",
        ),
        cosim(
            "a route nobody defines",
            vec![(
                "r.rou.xml",
                "<routes><vehicle id=\"v\" depart=\"0\" route=\"r9\"/></routes>".into(),
            )],
            vec!["--sumocfg", CFG, "--route-files", "{D}/r.rou.xml"],
            "r9",
        ),
        cosim(
            "a flow from an edge the network does not have",
            vec![(
                "r.rou.xml",
                "<routes><flow id=\"f\" begin=\"0\" end=\"60\" vehsPerHour=\"600\" from=\"no_such_edge\" to=\"out\"/></routes>"
                    .into(),
            )],
            vec!["--sumocfg", CFG, "--route-files", "{D}/r.rou.xml"],
            "no_such_edge",
        ),
        cosim(
            "a trip against the direction of travel",
            vec![(
                "r.rou.xml",
                "<routes><trip id=\"t\" depart=\"0\" from=\"out\" to=\"ramp\"/></routes>".into(),
            )],
            vec!["--sumocfg", CFG, "--route-files", "{D}/r.rou.xml"],
            "no route leads from edge `out` to edge `ramp`",
        ),
        cosim(
            "a route whose edges are not connected",
            vec![(
                "r.rou.xml",
                "<routes><route id=\"r\" edges=\"ramp main\"/><vehicle id=\"v\" depart=\"0\" route=\"r\"/></routes>"
                    .into(),
            )],
            vec!["--sumocfg", CFG, "--route-files", "{D}/r.rou.xml"],
            "edge `ramp` does not lead to `main`",
        ),
        cosim(
            "a vehicle type nobody defines",
            vec![(
                "r.rou.xml",
                "<routes><trip id=\"t\" type=\"nope\" depart=\"0\" from=\"main\" to=\"out\"/></routes>".into(),
            )],
            vec!["--sumocfg", CFG, "--route-files", "{D}/r.rou.xml"],
            "vehicle type `nope`",
        ),
        c(
            "zero duration",
            Vec::new(),
            vec!["cosim", "--sumocfg", CFG, "--end=0", "--out", "{D}/out"],
            "--end",
        ),
        c(
            "NaN duration",
            Vec::new(),
            vec!["cosim", "--sumocfg", CFG, "--end=nan", "--out", "{D}/out"],
            "--end",
        ),
        c(
            "cosim policy missing",
            Vec::new(),
            vec![
                "cosim",
                "--sumocfg",
                CFG,
                "--controllers",
                "mpg",
                "--policy",
                "{D}/none",
                "--out",
                "{D}/out",
            ],
            "none",
        ),
        // Route generation.
        routes("missing base", vec!["--base", "{D}/none.rou.xml"], "none.rou.xml"),
        routes_base("base not XML", "<routes".into(), "b.rou.xml"),
        routes_base(
            "base with a NaN begin",
            read("sumo_nets/i80_merge/i80.rou.xml").replacen("begin=\"0\"", "begin=\"NaN\"", 1),
            "begin=\"NaN\"",
        ),
        routes("scales not numbers", vec!["--scales", "a,b"], "--scales"),
        routes("negative scale", vec!["--scales=-1"], "scales"),
        routes("absurd scale", vec!["--scales", "1e300"], "vehicles"),
        routes(
            "controllable share above 1",
            vec!["--controllable-share", "1.5"],
            "--controllable-share",
        ),
        routes("negative ramp share", vec!["--ramp-share=-0.1"], "--ramp-share"),
        c(
            "zero route duration",
            Vec::new(),
            vec!["routes", "--duration", "0", "--out", "{D}/out"],
            "--duration",
        ),
        c(
            "routes merge.toml missing",
            Vec::new(),
            vec!["routes", "--merge", "{D}/none.toml", "--out", "{D}/out"],
            "none.toml",
        ),
        // Batches.
        batch(
            "routes matching nothing",
            Vec::new(),
            vec!["--sumocfg", CFG, "--routes", "{D}/*.rou.xml"],
            "no file matches",
        ),
        batch(
            "zero jobs",
            Vec::new(),
            vec![
                "--sumocfg",
                CFG,
                "--routes",
                "sumo_nets/single_lane_merge/*.rou.xml",
                "--jobs",
                "0",
            ],
            "--jobs",
        ),
        batch(
            "a shard beyond the count",
            Vec::new(),
            vec![
                "--sumocfg",
                CFG,
                "--routes",
                "sumo_nets/single_lane_merge/*.rou.xml",
                "--shard",
                "3/2",
            ],
            "--shard",
        ),
        batch(
            "an unknown controller",
            Vec::new(),
            vec![
                "--sumocfg",
                CFG,
                "--routes",
                "sumo_nets/single_lane_merge/*.rou.xml",
                "--controllers",
                "foo",
            ],
            "foo",
        ),
        batch(
            "batch sumocfg missing",
            Vec::new(),
            vec![
                "--sumocfg",
                "{D}/none.sumocfg",
                "--routes",
                "sumo_nets/single_lane_merge/*.rou.xml",
            ],
            "none.sumocfg",
        ),
        batch(
            "batch conflict point beyond the network",
            vec![(
                "m.toml",
                merge_with("conflict_point = 180.0", "conflict_point = 99999.0"),
            )],
            vec![
                "--sumocfg",
                CFG,
                "--routes",
                "sumo_nets/single_lane_merge/*.rou.xml",
                "--merge",
                "{D}/m.toml",
            ],
            "99999",
        ),
        c(
            "merge of a folder without runs",
            vec![("x/readme", "x".into())],
            vec!["merge", "--out", "{D}/out", "{D}/x"],
            "no result files",
        ),
        // Reports.
        report(
            "batch folder without a summary",
            Vec::new(),
            vec!["--batch", "{D}"],
            "no summary.md",
        ),
        report(
            "a cosim folder whose JSON is broken",
            vec![
                ("cs/cosim.md", "| a |\n".into()),
                ("cs/cosim.json", "{oops".into()),
            ],
            vec!["--cosim", "{D}/cs"],
            "not valid JSON",
        ),
        report(
            "a policy that is not a folder",
            Vec::new(),
            vec!["--policy", "policies/mpg/seed0.json"],
            "directory",
        ),
        // Networks.
        c(
            "net inspect of a missing file",
            Vec::new(),
            vec!["net", "inspect", "{D}/none.net.xml"],
            "none.net.xml",
        ),
        c(
            "net inspect of a file that is not a network",
            vec![("r.net.xml", "<routes/>".into())],
            vec!["net", "inspect", "{D}/r.net.xml"],
            "not a SUMO network",
        ),
        // NGSIM.
        ngsim(
            "prepare input missing",
            Vec::new(),
            vec!["prepare", "--input", "{D}/none.txt", "--out", "{D}/out"],
            "none.txt",
        ),
        ngsim(
            "prepare input with no valid row",
            vec![("t.txt", garbage_rows.clone())],
            vec!["prepare", "--input", "{D}/t.txt", "--out", "{D}/out"],
            "t.txt",
        ),
        ngsim(
            "ngsim settings with an unknown key",
            vec![
                ("n.toml", read("configs/ngsim.toml") + "bogus = 1\n"),
                ("t.txt", garbage_rows.clone()),
            ],
            vec![
                "prepare",
                "--input",
                "{D}/t.txt",
                "--ngsim",
                "{D}/n.toml",
                "--out",
                "{D}/out",
            ],
            "bogus",
        ),
        ngsim(
            "eval input missing",
            Vec::new(),
            vec![
                "eval",
                "--input",
                "{D}/none.txt",
                "--config",
                "configs/paper.toml",
                "--out",
                "{D}/out",
            ],
            "none.txt",
        ),
    ]
}

/// What is wrong with how `case` (run in `dir`) was refused, if anything.
fn check(case: &Case, dir: &Path) -> Option<String> {
    std::fs::create_dir_all(dir).unwrap();
    for (name, text) in &case.files {
        let path = dir.join(name);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, text).unwrap();
    }
    let d = dir.display().to_string();
    let args: Vec<String> = case.args.iter().map(|a| a.replace("{D}", &d)).collect();
    let out = bin().args(&args).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    let problems: Vec<&str> = [
        (out.status.code() != Some(2), "exit code is not 2"),
        (
            !stderr.contains(case.needle),
            "the message does not name the problem",
        ),
        (stderr.trim_end().lines().count() != 1, "not one line"),
        (stderr.contains("panicked"), "panicked"),
        (dir.join("out").exists(), "wrote its output folder"),
    ]
    .into_iter()
    .filter_map(|(bad, what)| bad.then_some(what))
    .collect();
    (!problems.is_empty()).then(|| {
        format!(
            "{} ({:?}): {}; exit {:?}, stderr {stderr:?}",
            case.name,
            case.args,
            problems.join(", "),
            out.status.code()
        )
    })
}

#[test]
fn every_bad_input_is_refused_with_one_message_and_writes_nothing() {
    let cases = cases();
    assert!(cases.len() >= 60, "{} cases", cases.len());
    let base = fresh_dir("bad-inputs");
    // Four at a time: most of each case is the process starting.
    let failures: Vec<String> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..4)
            .map(|w| {
                let (cases, base) = (&cases, &base);
                s.spawn(move || {
                    (w..cases.len())
                        .step_by(4)
                        .filter_map(|k| check(&cases[k], &base.join(format!("case{k}"))))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        workers.into_iter().flat_map(|h| h.join().unwrap()).collect()
    });
    assert!(
        failures.is_empty(),
        "{} of {} cases:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}
