//! The NGSIM pipeline end to end on synthetic files in both official layouts (internal-simulator
//! merges with known trajectories plus noise): load, smooth, recompute, reassign lanes,
//! extract, replay; and the real sample through the same steps.

mod common;

use common::{bin, fresh_dir, paper, real_sample};
use mpgdrive::ngsim::config::NgsimConfig;
use mpgdrive::ngsim::load::load;
use mpgdrive::ngsim::process::{Prepared, prepare};
use mpgdrive::ngsim::replay::{EgoDriver, replay, replay_config};
use mpgdrive::ngsim::scenario::extract;
use mpgdrive::ngsim::synth::{Layout, Synthetic, TruePoint, generate};
use mpgdrive::policy::observation::LinearPolicy;
use std::path::Path;

fn ngsim_config() -> NgsimConfig {
    NgsimConfig::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/ngsim.toml")).unwrap()
}

fn rms(errors: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = errors.fold((0.0, 0usize), |(s, n), e| (s + e * e, n + 1));
    (sum / n as f64).sqrt()
}

/// Generates, writes and prepares a synthetic file.
fn pipeline(layout: Layout, name: &str) -> (Synthetic, Prepared) {
    let ngsim = ngsim_config();
    let synthetic = generate(&paper(), &ngsim, 12, 3, 0.3, layout);
    let path = fresh_dir(name).join("trajectories");
    std::fs::write(&path, &synthetic.text).unwrap();
    let data = load(&path, "i-80").unwrap();
    let rows: usize = synthetic.truth.values().map(Vec::len).sum();
    assert_eq!(
        (data.rows, data.skipped, data.vehicles.len()),
        (rows, 0, synthetic.truth.len())
    );
    (synthetic.clone(), prepare(&data, &ngsim).unwrap())
}

fn truth_at(points: &[TruePoint], frame: u32) -> &TruePoint {
    &points[(frame - points[0].frame) as usize]
}

#[test]
fn synthetic_merges_are_smoothed_reassigned_and_extracted_in_both_layouts() {
    let ngsim = ngsim_config();
    for (layout, name) in [(Layout::Text, "synth-text"), (Layout::Csv, "synth-csv")] {
        let (synthetic, prepared) = pipeline(layout, name);
        assert!(
            synthetic.episodes.len() >= 6,
            "{} episodes",
            synthetic.episodes.len()
        );
        // Smoothing: 0.3 m of noise on the positions; the known trajectory comes back.
        let (mut pos_err, mut speed_err, mut lanes_ok, mut rows) = (Vec::new(), Vec::new(), 0, 0);
        for t in &prepared.tracks {
            let truth = &synthetic.truth[&t.id];
            for (k, p) in truth.iter().enumerate() {
                assert_eq!(t.frames[k], p.frame);
                pos_err.push(t.front[k] - p.front);
                speed_err.push(t.speed[k] - p.speed);
                let lane = ngsim.lanes.lane_at(p.lateral, p.front);
                lanes_ok += usize::from(t.lane[k] == lane);
                rows += 1;
            }
        }
        let (pos, speed) = (rms(pos_err.into_iter()), rms(speed_err.into_iter()));
        eprintln!(
            "{name}: position rms error {pos:.3} m, speed rms error {speed:.3} m/s, lanes {lanes_ok}/{rows}"
        );
        assert!(pos < 0.15, "position rms error {pos} m (noise 0.3 m)");
        assert!(speed < 0.5, "speed rms error {speed} m/s");
        assert!(lanes_ok as f64 >= 0.999 * rows as f64, "lanes {lanes_ok}/{rows}");
        assert_eq!(prepared.summary.merging_vehicles, synthetic.episodes.len());

        // Extraction: an ego whose true centre starts before x_c - 60 m gives a scenario whose
        // players are its episode's 8, in the slots their true order at the start frame gives.
        let extraction = extract(&prepared, &ngsim, 4, 4);
        let start_x = ngsim.merge.conflict_point - ngsim.merge.start_distance;
        let half = 2.5;
        let expected: Vec<_> = synthetic
            .episodes
            .iter()
            .filter(|e| synthetic.truth[&e.ids[0]][0].front - half < start_x - 1.0)
            .collect();
        assert!(!expected.is_empty());
        for e in &expected {
            let sc = extraction
                .scenarios
                .iter()
                .find(|s| prepared.tracks[s.ego].id == e.ids[0])
                .unwrap_or_else(|| panic!("no scenario for ego {}", e.ids[0]));
            let ego_x = truth_at(&synthetic.truth[&e.ids[0]], sc.start_frame).front - half;
            // The first frame at or past the start (up to one frame of travel, 2 m at 20 m/s).
            assert!(
                ego_x > start_x - 0.5 && ego_x < start_x + 2.5,
                "start at {ego_x} m"
            );
            let mut by_truth: Vec<(f64, u32)> = e.ids[1..]
                .iter()
                .map(|id| (truth_at(&synthetic.truth[id], sc.start_frame).front - half, *id))
                .collect();
            by_truth.sort_by(|a, b| b.0.total_cmp(&a.0)); // front-most first
            let ahead = by_truth.iter().filter(|p| p.0 > ego_x).count();
            let got: Vec<(u32, usize)> = sc
                .players
                .iter()
                .map(|&(j, s)| (prepared.tracks[j].id, s))
                .collect();
            let want: Vec<(u32, usize)> = by_truth
                .iter()
                .enumerate()
                .map(|(r, p)| {
                    (
                        p.1,
                        if r < ahead {
                            4 - ahead + 1 + r
                        } else {
                            5 + r - ahead
                        },
                    )
                })
                .collect();
            let mut want_sorted = want.clone();
            want_sorted.sort_by_key(|w| w.1);
            assert_eq!(got, want_sorted, "ego {}", e.ids[0]);
        }
        assert_eq!(extraction.scenarios.len(), extraction.available);
    }
}

#[test]
fn replay_follows_the_record_and_drives_a_policy_ego_from_the_human_start() {
    let ngsim = ngsim_config();
    let config = replay_config(&paper(), &ngsim);
    let (synthetic, prepared) = pipeline(Layout::Text, "replay");
    let extraction = extract(&prepared, &ngsim, 4, 4);
    let sc = &extraction.scenarios[0];
    let ego = &prepared.tracks[sc.ego];
    let truth = &synthetic.truth[&ego.id];

    // The human: its smoothed record; metrics from the true trajectory within tolerance.
    let human = replay(&config, &ngsim, &prepared, sc, EgoDriver::Human);
    // Until its record ends (the episode's 30 s began before the scenario's start).
    let steps = (truth[truth.len() - 1].frame - sc.start_frame) as usize;
    assert_eq!(human.steps, steps);
    assert!(!human.metrics.collision && !human.metrics.failure);
    let speeds = (0..steps as u32).map(|s| truth_at(truth, sc.start_frame + s).speed);
    let true_speed = speeds.sum::<f64>() / steps as f64;
    assert!(
        (human.metrics.mean_speed - true_speed).abs() < 0.05,
        "{} vs {true_speed}",
        human.metrics.mean_speed
    );
    // The players are where the record puts them, at every step.
    for (s, scene) in human.scenes.iter().enumerate().step_by(50) {
        for (v, &(j, _)) in scene.vehicles[1..].iter().zip(&sc.players) {
            let p = truth_at(
                &synthetic.truth[&prepared.tracks[j].id],
                sc.start_frame + s as u32,
            );
            assert!(
                (v.x - (p.front - 2.5)).abs() < 0.3,
                "step {s}: {} vs {}",
                v.x,
                p.front - 2.5
            );
        }
    }

    // A policy ego starts from the human's state and then drives itself: a speed keeper
    // (u = g tanh(0.1 (15 - v) + ...)) on an open ramp accelerates towards 15 m/s.
    let mut policy = LinearPolicy::speed_keeping(&config);
    let driven = replay(&config, &ngsim, &prepared, sc, EgoDriver::Policy(&mut policy));
    let (h0, p0) = (human.scenes[0].ego(), driven.scenes[0].ego());
    assert_eq!((h0.x, h0.v), (p0.x, p0.v));
    assert!((p0.x - (truth_at(truth, sc.start_frame).front - 2.5)).abs() < 0.3);
    assert!(driven.steps > 0 && driven.scenes.len() == driven.steps + 1);
    assert!(
        driven.scenes[1..]
            .iter()
            .all(|s| s.vehicles.len() == sc.players.len() + 1)
    );
}

#[test]
fn the_real_sample_prepares_cleanly_and_has_no_merge_scenarios() {
    let Some(path) = real_sample() else {
        return;
    };
    let ngsim = ngsim_config();
    let prepared = prepare(&load(&path, "i-80").unwrap(), &ngsim).unwrap();
    let s = &prepared.summary;
    assert_eq!((s.vehicles, s.rows, s.rows_skipped), (142, 68_339, 0));
    assert_eq!((s.ramp_vehicles, s.merging_vehicles), (0, 0));
    // Lanes from Local_X and 12 ft lanes agree with the recorded lanes 1-3 (measured: all but
    // one row, where the smoothed trace of a car on lane 3's right edge crosses into lane 4).
    assert!(
        s.rows_per_lane.keys().all(|l| (1..=4).contains(l)),
        "{:?}",
        s.rows_per_lane
    );
    assert!(
        s.lane_changed_rows * 1000 < s.rows,
        "{} rows changed lane",
        s.lane_changed_rows
    );
    assert!(extract(&prepared, &ngsim, 4, 4).scenarios.is_empty());
    let out = fresh_dir("real-eval");
    let o = bin()
        .args(["ngsim", "eval", "--input"])
        .arg(&path)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && text.contains("No merge scenario"), "{text}");
}

#[test]
fn ngsim_commands_write_their_outputs_and_refuse_bad_input() {
    let dir = fresh_dir("ngsim-cli");
    let file = dir.join("synthetic.csv");
    let ok = bin()
        .args(["ngsim", "synth", "--episodes", "6", "--layout", "csv", "--out"])
        .arg(&file)
        .output()
        .unwrap();
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let out = dir.join("eval");
    let ok = bin()
        .args(["ngsim", "eval", "--input"])
        .arg(&file)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let table = String::from_utf8_lossy(&ok.stdout);
    assert!(
        table.contains("| Ego vehicle's policy | Human driver | Single-agent RL | MARL |"),
        "{table}"
    );
    for f in ["table4.md", "table4.json", "episodes.csv", "scenarios.csv"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    // 1 human + 5 sarl + 5 mpg replays of each scenario.
    let scenarios = std::fs::read_to_string(out.join("scenarios.csv"))
        .unwrap()
        .lines()
        .count()
        - 1;
    let episodes = std::fs::read_to_string(out.join("episodes.csv"))
        .unwrap()
        .lines()
        .count()
        - 1;
    assert!(
        scenarios > 0 && episodes == 11 * scenarios,
        "{scenarios} scenarios, {episodes} episodes"
    );

    // Bad input: one message, exit code 2, no output written.
    let bad_config = dir.join("bad.toml");
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/ngsim.toml")).unwrap();
    std::fs::write(&bad_config, text.replace("window = 21", "window = 20")).unwrap();
    let empty = dir.join("empty.txt");
    std::fs::write(&empty, "").unwrap();
    let garbage = dir.join("garbage.txt");
    std::fs::write(&garbage, "this is not NGSIM\n").unwrap();
    for (args, input, says) in [
        (
            vec!["--ngsim", bad_config.to_str().unwrap()],
            &file,
            "smoothing.window",
        ),
        (vec![], &empty, "no usable rows"),
        (vec![], &garbage, "18 (FHWA text)"),
        (vec![], &dir.join("absent.txt"), "absent.txt"),
    ] {
        let prep = dir.join("prep");
        let o = bin()
            .args(["ngsim", "prepare", "--input"])
            .arg(input)
            .arg("--out")
            .arg(&prep)
            .args(&args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(says) && !err.contains("panicked"), "{err}");
        assert!(!prep.join("trajectories.csv").exists());
    }
}

#[test]
fn a_file_without_lateral_positions_or_sizes_keeps_its_lanes_and_warns() {
    // A re-extraction that publishes lanes and longitudinal positions only: Local_X (column 5)
    // and v_Length / v_Width (9 and 10) all zero.
    let ngsim = ngsim_config();
    let synthetic = generate(&paper(), &ngsim, 4, 5, 0.3, Layout::Text);
    let text: String = synthetic
        .text
        .lines()
        .map(|line| {
            let mut cols: Vec<&str> = line.split_whitespace().collect();
            for k in [4, 8, 9] {
                cols[k] = "0";
            }
            cols.join(" ") + "\n"
        })
        .collect();
    let dir = fresh_dir("ngsim-degenerate");
    let input = dir.join("trajectories.txt");
    std::fs::write(&input, &text).unwrap();
    let out = bin()
        .args(["ngsim", "prepare", "--input"])
        .arg(&input)
        .arg("--out")
        .arg(dir.join("prepared"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("warning") && stderr.contains("recorded Lane_ID is kept"),
        "{stderr}"
    );
    assert!(stderr.contains("default size"), "{stderr}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("prepared/summary.json")).unwrap()).unwrap();
    assert_eq!(summary["lateral_constant"], true);
    assert_eq!(summary["lane_changed_rows"], 0);
    assert_eq!(summary["default_sizes"], summary["vehicles"]);
    assert_eq!(summary["warnings"].as_array().unwrap().len(), 2);
    // Every row keeps its recorded lane; every (class 2) car is 4.6 x 1.8 m.
    let csv = std::fs::read_to_string(dir.join("prepared/trajectories.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert!(!rows.is_empty());
    for r in &rows {
        assert_eq!(r[col("Lane_ID")], r[col("Recorded_Lane_ID")]);
        assert_eq!(r[col("Class")], "2");
        assert_eq!((r[col("Length_m")], r[col("Width_m")]), ("4.600", "1.800"));
    }
    // The synthetic file's ramp vehicles merge: the recorded lanes still show them.
    let ramp = ngsim.lanes.ramp_lane().to_string();
    assert!(rows.iter().any(|r| r[col("Lane_ID")] == ramp));
}
