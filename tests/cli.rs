//! The binary: bad input gets one clear message and exit code 2; the commands run end to end.

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;

use common::bin;

fn smoke_text() -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/smoke.toml")).unwrap()
}

/// Writes `text` to a fresh temporary config file.
fn temp_config(name: &str, text: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

fn run_with(name: &str, text: &str) -> Output {
    let path = temp_config(name, text);
    bin()
        .args(["demo", "--scenarios", "2", "--config"])
        .arg(&path)
        .output()
        .unwrap()
}

/// Exit code 2, one line on stderr naming `needle`, no panic.
fn assert_rejected(out: &Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {stderr}");
    assert!(stderr.contains(needle), "{needle:?} not in {stderr:?}");
    assert_eq!(stderr.trim_end().lines().count(), 1, "one message: {stderr:?}");
    assert!(!stderr.contains("panicked") && !stderr.contains("backtrace"));
    assert!(out.stdout.is_empty(), "no work done");
}

#[test]
fn unknown_key_is_rejected_by_name() {
    let text = smoke_text().replace("[sim]\n", "[sim]\ntime_step = 0.1\n");
    assert_rejected(&run_with("unknown", &text), "time_step");
}

#[test]
fn nan_is_rejected_by_key() {
    let text = smoke_text().replace("conflict_point = 180.0", "conflict_point = nan");
    assert_rejected(&run_with("nan", &text), "scenario.conflict_point");
}

#[test]
fn negative_time_step_is_rejected_by_key() {
    let text = smoke_text().replace("dt = 0.1 ", "dt = -0.1 ");
    assert_rejected(&run_with("negative", &text), "sim.dt");
}

#[test]
fn training_settings_that_would_panic_or_give_nan_are_rejected_by_key() {
    // Each of these used to panic (a zero checkpoint period or batch), give NaN curves (no
    // probe states) or train nonsense; every one is refused before any work, by its key.
    for (key, line) in [
        ("train.checkpoint_every", "checkpoint_every = 0"),
        ("train.batch", "batch = 0"),
        ("train.probe_scenarios", "probe_scenarios = 0"),
        ("train.hidden", "hidden = 0"),
        ("train.epochs", "epochs = 0"),
        ("train.threads", "threads = 0"),
        ("train.learning_rate", "learning_rate = -0.001"),
        ("train.learning_rate_final", "learning_rate_final = nan"),
        ("train.grad_clip", "grad_clip = 0.0"),
    ] {
        let name = key.split('.').nth(1).unwrap();
        let text = smoke_text();
        let start = text.find(&format!("\n{name} =")).expect(name) + 1;
        let end = start + text[start..].find('\n').unwrap();
        let text = format!("{}{line}{}", &text[..start], &text[end..]);
        assert_rejected(&run_with(name, &text), key);
    }
}

#[test]
fn resume_says_when_there_is_no_checkpoint_or_optimiser_state_and_refuses_foreign_or_corrupt_ones() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli-resume");
    let _ = std::fs::remove_dir_all(&dir);
    let config = temp_config("resume", &smoke_text().replace("epochs = 15 ", "epochs = 2 "));
    let train = |config: &Path| {
        bin()
            .args(["train", "--seeds", "0", "--resume", "--config"])
            .arg(config)
            .arg("--out")
            .arg(&dir)
            .output()
            .unwrap()
    };
    let resumes_saying = |words: &[&str]| {
        let out = train(&config);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{stderr}");
        assert!(words.iter().all(|w| stderr.contains(w)), "{stderr}");
    };
    resumes_saying(&["no checkpoint", "trains from the start"]);
    // A checkpoint of this run without Adam's state (as older versions wrote them): resumed,
    // with a warning that the moments restart.
    let checkpoint = |name: &str| {
        for ext in ["json", "safetensors"] {
            std::fs::copy(
                dir.join(format!("seed0.{ext}")),
                dir.join(format!("seed0.{name}.{ext}")),
            )
            .unwrap();
        }
    };
    checkpoint("ckpt");
    resumes_saying(&["no optimiser state", "moments restart"]);
    // A checkpoint whose write was cut short (the one before kept as `.ckpt.prev`, the same
    // epochs in both sidecars): resumed from the kept one, and said so.
    checkpoint("ckpt");
    checkpoint("ckpt.prev");
    resumes_saying(&["cut short", "seed0.ckpt.prev.json"]);
    // A checkpoint whose optimiser state is corrupted: refused as bad input, naming the file.
    checkpoint("ckpt");
    let state = dir.join("seed0.ckpt.adam.safetensors");
    std::fs::write(&state, b"not a safetensors file").unwrap();
    let out = train(&config);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("seed0.ckpt.adam.safetensors") && stderr.contains("remove it"),
        "{stderr}"
    );
    std::fs::remove_file(&state).unwrap();
    // A checkpoint of this run, resumed under another learning rate: refused as bad input.
    let other = temp_config(
        "resume-other",
        &smoke_text()
            .replace("epochs = 15 ", "epochs = 2 ")
            .replace("learning_rate = 0.01 ", "learning_rate = 0.02 "),
    );
    let out = train(&other);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("made by another run"), "{stderr}");
}

#[test]
fn a_policy_trained_under_other_world_rules_is_refused_by_setting() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli-rules");
    let _ = std::fs::remove_dir_all(&dir);
    let tiny = smoke_text().replace("epochs = 15 ", "epochs = 1 ");
    let out = bin()
        .args(["train", "--seeds", "0", "--config"])
        .arg(temp_config("rules", &tiny))
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let eval = |name: &str, text: String, extra: &[&str]| {
        bin()
            .args(["eval", "--surrounding", "idm", "--config"])
            .arg(temp_config(name, &text))
            .arg("--policy")
            .arg(&dir)
            .args(extra)
            .output()
            .unwrap()
    };
    // Another step, another conflict point, the gate off: each named.
    for (key, from, to) in [
        ("sim.dt", "dt = 0.1 ", "dt = 0.05 "),
        (
            "scenario.conflict_point",
            "conflict_point = 180.0 ",
            "conflict_point = 200.0 ",
        ),
        ("sim.merge_gate", "merge_gate = false ", "merge_gate = true "),
    ] {
        assert!(tiny.contains(from), "{from}");
        assert_rejected(&eval("rules-other", tiny.replace(from, to), &[]), key);
    }
    // The same rules (other training settings) pass; an explicit ablation passes with a warning.
    let out = eval(
        "rules-same",
        tiny.replace("learning_rate = 0.01 ", "learning_rate = 0.02 "),
        &[],
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(!String::from_utf8_lossy(&out.stderr).contains("warning"));
    // Another reward is no world rule: evaluated, with a warning naming the term.
    assert!(tiny.contains("epsilon = 0.1 "));
    let out = eval(
        "rules-reward",
        tiny.replace("epsilon = 0.1 ", "epsilon = 0.05 "),
        &[],
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr
            .contains("warning: the policy of seed 0 was trained with reward.epsilon = 0.1, this run's 0.05"),
        "{stderr}"
    );
    let out = eval(
        "rules-ablation",
        tiny.replace("merge_gate = false ", "merge_gate = true "),
        &["--allow-policy-mismatch"],
    );
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("warning: --allow-policy-mismatch"));
}

#[test]
fn conflict_point_outside_the_road_is_rejected() {
    let text = smoke_text().replace("conflict_point = 180.0", "conflict_point = 450.0");
    assert_rejected(&run_with("outside", &text), "scenario.conflict_point");
}

#[test]
fn inverted_range_is_rejected_by_key() {
    let text = smoke_text().replace("headway = [7.0, 30.0]", "headway = [30.0, 7.0]");
    assert_rejected(&run_with("inverted", &text), "sampling.headway");
}

#[test]
fn missing_config_file_is_rejected() {
    let out = bin()
        .args(["demo", "--config", "no/such/file.toml"])
        .output()
        .unwrap();
    assert_rejected(&out, "no/such/file.toml");
}

#[test]
fn demo_runs_and_prints_the_metrics() {
    let out = bin()
        .args(["demo", "--config", "configs/smoke.toml", "--scenarios", "4"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("| Collision rate |") && stdout.contains("Constant speed"));
}

#[test]
fn check_mpg_exact_json_reports_every_player_below_1e_9() {
    let out = bin()
        .args([
            "check-mpg",
            "--config",
            "configs/smoke.toml",
            "--exact",
            "--json",
            "--policies",
            "2",
            "--states",
            "4",
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let players = v["players"].as_array().unwrap();
    assert_eq!(players.len(), 9);
    for p in players {
        assert!(p["max_relative_gap"].as_f64().unwrap() < 1e-9, "{p}");
    }
    assert_eq!(v["is_potential_game"], true);
    assert_eq!(v["setting"], "exact");
}

#[test]
fn train_then_eval_end_to_end_and_deterministic() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli-train");
    let _ = std::fs::remove_dir_all(&dir);
    let out = bin()
        .args([
            "train",
            "--config",
            "configs/smoke.toml",
            "--seeds",
            "0,1",
            "--out",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for seed in [0, 1] {
        for ext in ["safetensors", "json", "curves.csv"] {
            assert!(dir.join(format!("seed{seed}.{ext}")).exists(), "seed{seed}.{ext}");
        }
    }
    let episodes = dir.join("episodes.csv");
    let eval = |extra: &[&str]| {
        let out = bin()
            .args(["eval", "--config", "configs/smoke.toml", "--policy"])
            .arg(&dir)
            .args(extra)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        out.stdout
    };
    let json: serde_json::Value = serde_json::from_slice(&eval(&["--json"])).unwrap();
    assert_eq!(json["seeds"], serde_json::json!([0, 1]));
    let columns = json["columns"].as_array().unwrap();
    assert_eq!(columns.len(), 3);
    assert_eq!(columns[0]["mean"]["episodes"], 8);
    // Same command, same numbers.
    assert_eq!(eval(&["--json"]), eval(&["--json"]));
    let table = String::from_utf8(eval(&[
        "--surrounding",
        "idm",
        "--episodes",
        episodes.to_str().unwrap(),
    ]))
    .unwrap();
    assert!(table.contains("| Selected players' policies | IDM |"), "{table}");
    let csv = std::fs::read_to_string(&episodes).unwrap();
    assert_eq!(csv.lines().count(), 1 + 2 * 8, "header + 2 seeds x 8 scenarios");
    // A single-agent policy against NE players needs the MPG policies (Table III).
    let sarl = dir.join("sarl");
    let out = bin()
        .args([
            "train",
            "--config",
            "configs/smoke.toml",
            "--mode",
            "sarl",
            "--seeds",
            "0",
            "--out",
        ])
        .arg(&sarl)
        .output()
        .unwrap();
    assert!(out.status.success());
    let sarl_eval = |extra: &[&str]| {
        bin()
            .args([
                "eval",
                "--config",
                "configs/smoke.toml",
                "--surrounding",
                "ne",
                "--policy",
            ])
            .arg(&sarl)
            .args(extra)
            .output()
            .unwrap()
    };
    assert_rejected(&sarl_eval(&[]), "--ne-policy");
    let with_ne = sarl_eval(&["--ne-policy", dir.to_str().unwrap()]);
    assert!(
        with_ne.status.success(),
        "{}",
        String::from_utf8_lossy(&with_ne.stderr)
    );
    assert!(String::from_utf8_lossy(&with_ne.stdout).contains("Single-agent RL"));
    // A policy made for 9 players is refused by a configuration with 5.
    let small = smoke_text()
        .replace("n_leaders = 4", "n_leaders = 2")
        .replace("n_followers = 4", "n_followers = 2");
    let path = temp_config("small", &small);
    let out = bin()
        .args(["eval", "--config"])
        .arg(&path)
        .arg("--policy")
        .arg(&dir)
        .output()
        .unwrap();
    assert_rejected(&out, "made for 9 players");
}

/// The curves' (epoch, train objective, probe objective) rows of a finished run.
fn curve_rows(dir: &Path) -> Vec<String> {
    std::fs::read_to_string(dir.join("seed3.curves.csv"))
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').take(3).collect::<Vec<_>>().join(","))
        .collect()
}

#[test]
fn training_killed_with_sigkill_resumes_from_its_last_checkpoint() {
    let text = smoke_text().replace("epochs = 15 ", "epochs = 60 "); // a checkpoint every 5
    assert!(text.contains("epochs = 60 "));
    let config = temp_config("kill9", &text);
    let base = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli-kill9");
    let _ = std::fs::remove_dir_all(&base);
    let train = |out: &Path, resume: bool| {
        let mut c = bin();
        c.args(["train", "--mode", "mpg", "--seeds", "3", "--config"])
            .arg(&config)
            .arg("--out")
            .arg(out);
        if resume {
            c.arg("--resume");
        }
        c
    };
    let whole = base.join("whole");
    assert!(train(&whole, false).output().unwrap().status.success());

    let cut = base.join("cut");
    let mut child = train(&cut, false)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let ckpt = cut.join("seed3.ckpt.json");
    let started = std::time::Instant::now();
    while !ckpt.is_file() {
        assert!(started.elapsed().as_secs() < 60, "no checkpoint");
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    child.kill().unwrap(); // SIGKILL: no chance to tidy up
    child.wait().unwrap();
    assert!(!cut.join("seed3.json").exists(), "killed before it finished");
    let side: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&ckpt).unwrap()).unwrap();
    let saved = side["epochs"].as_u64().unwrap() as usize;
    assert!(
        saved >= 5 && saved % 5 == 0 && saved < 60,
        "checkpoint at epoch {saved}"
    );

    let resumed = train(&cut, true).output().unwrap();
    assert!(
        resumed.status.success(),
        "{}",
        String::from_utf8_lossy(&resumed.stderr)
    );
    let (whole, cut) = (curve_rows(&whole), curve_rows(&cut));
    assert_eq!(cut.len(), 60, "every epoch in the curves");
    // Nothing up to the checkpoint is lost or redone: those rows are the uninterrupted run's.
    assert_eq!(cut[..saved], whole[..saved]);
    // Wherever the kill fell (even inside a checkpoint's write), the run ends as the
    // uninterrupted one: the same weights, bit for bit, and the same curves.
    let weights = |d: &str| std::fs::read(base.join(d).join("seed3.safetensors")).unwrap();
    assert!(weights("cut") == weights("whole"), "the resumed weights differ");
    assert_eq!(cut, whole);
    let left = common::checkpoint_files(&base.join("cut"));
    assert!(left.is_empty(), "{left:?}");
}
