//! `mpgdrive routes`, `batch` and `merge` end to end on the paper's single-lane merge: a small
//! batch and its summary, a killed batch resumed to the same summary, two shards merged to the
//! same summary (also when both write into one folder at once), and a malformed route file
//! recorded as a failed run.
#![cfg(feature = "sumo")]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

const CFG: &str = "sumo_nets/single_lane_merge/merge.sumocfg";

mod common;

use common::bin;

fn fresh(name: &str) -> PathBuf {
    common::fresh_dir(&format!("batch-{name}"))
}

/// Two route files (demand 0.5 and 1.0 of the base, 60 s of departures).
fn route_files(name: &str) -> PathBuf {
    let dir = fresh(name);
    let out = bin()
        .args([
            "routes",
            "--base",
            "sumo_nets/single_lane_merge/merge.rou.xml",
            "--scales",
            "0.5,1.0",
        ])
        .args(["--duration", "60", "--controllable-share", "1.0", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    dir
}

fn batch(routes: &Path, out: &Path, extra: &[&str]) -> Command {
    batch_of(routes, out, "sumo,sarl", extra)
}

fn batch_of(routes: &Path, out: &Path, controllers: &str, extra: &[&str]) -> Command {
    let mut c = bin();
    c.args([
        "batch",
        "--sumocfg",
        CFG,
        "--controllers",
        controllers,
        "--end",
        "90",
        "--routes",
    ])
    .arg(format!("{}/*.rou.xml", routes.display()))
    .arg("--out")
    .arg(out)
    .args(extra);
    c
}

fn run(mut c: Command) -> Output {
    let out = c.output().unwrap();
    assert!(!String::from_utf8_lossy(&out.stderr).contains("panicked"));
    out
}

fn summary(dir: &Path) -> String {
    std::fs::read_to_string(dir.join("summary.csv")).unwrap()
}

#[test]
fn zero_jobs_is_refused_before_any_output() {
    let routes = route_files("zero-jobs-routes");
    let out = fresh("zero-jobs");
    let o = run(batch(&routes, &out, &["--jobs", "0"]));
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--jobs must be at least 1"));
    assert!(
        std::fs::read_dir(&out).unwrap().next().is_none(),
        "nothing written"
    );
}

#[test]
fn a_small_batch_runs_every_combination_and_summarises_them() {
    let routes = route_files("small-routes");
    let out = fresh("small");
    let o = run(batch(&routes, &out, &["--jobs", "2"]));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let runs: Vec<_> = std::fs::read_dir(out.join("runs")).unwrap().collect();
    assert_eq!(runs.len(), 4, "2 route files x 2 controllers x 1 seed");
    let csv = summary(&out);
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    let keys: Vec<String> = rows
        .iter()
        .map(|r| r.split(',').take(3).collect::<Vec<_>>().join(","))
        .collect();
    assert_eq!(keys, ["sarl,0.50,1", "sarl,1.00,1", "sumo,0.50,1", "sumo,1.00,1"]);
    // The summary's egos equal those of the run files.
    let result: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("runs/merge_d1.00_s0__sumo__s0.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(result["status"], "ok");
    assert!(result["sumo_version"].as_str().unwrap().starts_with("SUMO 1."));
    let egos = result["metrics"]["egos"].as_u64().unwrap();
    assert!(egos > 0);
    assert!(
        rows[3].starts_with(&format!("sumo,1.00,1,{egos},")),
        "{}",
        rows[3]
    );
    assert!(out.join("logs/merge_d1.00_s0__sumo__s0.log").is_file());
    // Two demand levels: the charts against demand, none against the controllable share.
    for metric in ["speed", "time_loss", "conflict_share", "collision_rate"] {
        assert!(
            out.join(format!("batch_demand_{metric}.png")).is_file(),
            "{metric}"
        );
        assert!(
            !out.join(format!("batch_share_{metric}.png")).exists(),
            "{metric}"
        );
    }
}

#[test]
fn one_policy_seed_drives_every_run_when_asked() {
    let routes = route_files("seed-routes");
    let (mean, one) = (fresh("seed-mean"), fresh("seed-one"));
    for (out, extra) in [(&mean, &[][..]), (&one, &["--policy-seed", "3"][..])] {
        let o = run(batch_of(&routes, out, "sarl", extra));
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let result = |dir: &Path| -> serde_json::Value {
        let text = std::fs::read_to_string(dir.join("runs/merge_d1.00_s0__sarl__s0.json")).unwrap();
        serde_json::from_str(&text).unwrap()
    };
    let (m, o) = (result(&mean), result(&one));
    let command = |r: &serde_json::Value| {
        r["command"]
            .as_array()
            .unwrap()
            .iter()
            .map(|a| a.as_str().unwrap().to_owned())
            .collect::<Vec<_>>()
            .join(" ")
    };
    assert!(command(&o).contains("--policy-seed 3"), "{}", command(&o));
    assert!(!command(&m).contains("--policy-seed"), "{}", command(&m));
    // The same egos, driven by seed 3 alone or by the mean of the five seeds.
    assert_eq!(m["metrics"]["egos"], o["metrics"]["egos"]);
    assert_ne!(m["metrics"]["mean_speed"], o["metrics"]["mean_speed"], "{m} {o}");
    // A seed the directory does not hold is refused before any run.
    let bad = fresh("seed-bad");
    let o = run(batch_of(&routes, &bad, "sarl", &["--policy-seed", "9"]));
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no policy of seed 9"));
}

#[test]
fn a_killed_batch_resumes_to_the_summary_of_an_uninterrupted_one() {
    let routes = route_files("resume-routes");
    let whole = fresh("whole");
    assert!(run(batch(&routes, &whole, &["--jobs", "1"])).status.success());
    let cut = fresh("cut");
    let mut child = batch(&routes, &cut, &["--jobs", "1"]).spawn().unwrap();
    let started = Instant::now();
    while std::fs::read_dir(cut.join("runs")).map_or(0, |d| d.count()) < 1 {
        assert!(started.elapsed() < Duration::from_secs(60), "no run finished");
        std::thread::sleep(Duration::from_millis(10));
    }
    child.kill().unwrap(); // SIGKILL: no chance to tidy up
    child.wait().unwrap();
    let finished = std::fs::read_dir(cut.join("runs")).unwrap().count();
    assert!(finished < 4, "killed before the end ({finished} runs)");
    assert!(!cut.join("summary.csv").exists());
    let o = run(batch(&routes, &cut, &["--jobs", "1", "--resume"]));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(summary(&cut), summary(&whole));
}

#[test]
fn two_shards_merge_to_the_summary_of_one_run() {
    let routes = route_files("shard-routes");
    let whole = fresh("shard-whole");
    assert!(run(batch(&routes, &whole, &["--jobs", "2"])).status.success());
    let (a, b) = (fresh("shard-a"), fresh("shard-b"));
    assert!(run(batch(&routes, &a, &["--shard", "1/2"])).status.success());
    assert!(run(batch(&routes, &b, &["--shard", "2/2"])).status.success());
    let runs = |d: &Path| std::fs::read_dir(d.join("runs")).unwrap().count();
    assert_eq!((runs(&a), runs(&b)), (2, 2));
    let merged = fresh("shard-merged");
    let o = run({
        let mut c = bin();
        c.arg("merge").arg(&a).arg(&b).arg("--out").arg(&merged);
        c
    });
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(summary(&merged), summary(&whole));

    // Both shards at once into one shared folder (as cluster tasks on a shared file system):
    // distinct run names and write-then-rename keep every file whole.
    let shared = fresh("shard-shared");
    let mut children: Vec<_> = ["1/2", "2/2"]
        .iter()
        .map(|k| batch(&routes, &shared, &["--shard", k]).spawn().unwrap())
        .collect();
    for child in &mut children {
        assert!(child.wait().unwrap().success());
    }
    assert_eq!(runs(&shared), 4);
    for entry in std::fs::read_dir(shared.join("runs")).unwrap() {
        let text = std::fs::read_to_string(entry.unwrap().path()).unwrap();
        let run: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(run["status"], "ok");
    }
    for dir in [shared.clone(), shared.join("runs")] {
        for entry in std::fs::read_dir(dir).unwrap() {
            let name = entry.unwrap().file_name();
            assert!(
                !name.to_string_lossy().contains(".tmp."),
                "temporary file left: {name:?}"
            );
        }
    }
    let merged = fresh("shard-shared-merged");
    let o = run({
        let mut c = bin();
        c.arg("merge").arg(&shared).arg("--out").arg(&merged);
        c
    });
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(summary(&merged), summary(&whole));
}

#[test]
fn a_malformed_route_file_is_a_failed_run_and_the_others_complete() {
    let routes = route_files("bad-routes");
    std::fs::write(
        routes.join("broken.rou.xml"),
        "<routes>\n  <vehicle id=\"x\" depart=\"0\" route=\"nowhere\"/>\n",
    )
    .unwrap();
    let out = fresh("bad");
    let o = run(batch_of(&routes, &out, "sumo", &["--jobs", "2"]));
    assert_eq!(o.status.code(), Some(1), "{}", String::from_utf8_lossy(&o.stderr));
    let broken: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("runs/broken__sumo__s0.json")).unwrap())
            .unwrap();
    assert_eq!(broken["status"], "failed");
    let error = broken["error"].as_str().unwrap();
    // Checked by the worker before SUMO starts.
    assert!(
        error.contains("broken.rou.xml") && error.contains("not well-formed XML"),
        "{error}"
    );
    let md = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(md.contains("3 runs: 2 ok, 1 failed."), "{md}");
}

#[test]
fn a_run_over_its_timeout_is_killed_and_recorded() {
    let routes = route_files("timeout-routes");
    let out = fresh("timeout");
    // A 90 s run takes well over 10 ms of wall time (SUMO alone starts in about 80 ms).
    let o = run(batch_of(
        &routes,
        &out,
        "sumo",
        &["--jobs", "2", "--timeout", "0.01"],
    ));
    assert_eq!(o.status.code(), Some(1));
    for key in ["merge_d0.50_s0__sumo__s0", "merge_d1.00_s0__sumo__s0"] {
        let r: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join(format!("runs/{key}.json"))).unwrap())
                .unwrap();
        assert_eq!(r["status"], "failed");
        assert!(r["error"].as_str().unwrap().starts_with("timed out"), "{r}");
    }
}
