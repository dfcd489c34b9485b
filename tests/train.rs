//! Training on the smoke setting, policy files, checkpoints and resume.

mod common;

use common::{checkpoint_files, fresh_dir, smoke};
use mpgdrive::policy::file::{self, PolicyError};
use mpgdrive::policy::observation::Layout;
use mpgdrive::policy::{NetSpec, PolicyNet};
use mpgdrive::train::{Mode, TrainRun, curves, train, train_all};
use std::path::PathBuf;
use std::process::Command;
use std::sync::atomic::AtomicBool;
use tch::Tensor;

static NO_STOP: AtomicBool = AtomicBool::new(false);

fn out_dir(name: &str) -> PathBuf {
    fresh_dir(&format!("train-{name}"))
}

/// Mean probe objective of the first and of the last five epochs (single epochs are noisy).
fn first_last(records: &[curves::EpochRecord]) -> (f64, f64) {
    let mean = |r: &[curves::EpochRecord]| r.iter().map(|x| x.probe_objective).sum::<f64>() / r.len() as f64;
    (mean(&records[..5]), mean(&records[records.len() - 5..]))
}

fn run(mode: Mode, dir: &std::path::Path) -> TrainRun {
    TrainRun {
        mode,
        seed: 3,
        out: dir.join("seed3"),
        resume: false,
        command: "test".into(),
    }
}

#[test]
fn mpg_training_improves_the_potential() {
    let config = smoke();
    let dir = out_dir("mpg");
    let records = train(&config, &run(Mode::Mpg, &dir), &NO_STOP, &mut |_| {}).unwrap();
    assert_eq!(records.len(), config.train.epochs);
    let (first, last) = first_last(&records);
    assert!(
        last > first + 0.2 * first.abs(),
        "probe potential {first} -> {last}"
    );
    // The curves on disk are what was returned (printed with full precision but wall time).
    let back = curves::read(&dir.join("seed3.curves.csv")).unwrap();
    assert_eq!(back.len(), records.len());
    assert_eq!(back[4].probe_objective, records[4].probe_objective);
    // The finished policy exists, the checkpoint is gone.
    assert!(dir.join("seed3.safetensors").exists() && dir.join("seed3.json").exists());
    assert!(!dir.join("seed3.ckpt.json").exists());
}

#[test]
fn sarl_training_improves_the_ego_return() {
    let config = smoke();
    let dir = out_dir("sarl");
    // The ego needs time to matter: 10 s instead of the smoke setting's 3 s.
    let mut config = config;
    config.sim.horizon = 10.0;
    config.train.epochs = 20;
    config.train.learning_rate = 0.003;
    config.train.learning_rate_final = 0.003;
    let records = train(&config, &run(Mode::Sarl, &dir), &NO_STOP, &mut |_| {}).unwrap();
    let (first, last) = first_last(&records);
    assert!(last > first, "probe ego return {first} -> {last}");
    let (_, side) = file::load(&dir.join("seed3"), Layout::Table1 { players: 9 }).unwrap();
    assert_eq!(
        (side.mode.as_str(), side.seed, side.epochs),
        ("sarl", 3, config.train.epochs)
    );
}

#[test]
fn training_is_reproducible_for_a_seed() {
    let config = smoke();
    let a = train(&config, &run(Mode::Mpg, &out_dir("rep-a")), &NO_STOP, &mut |_| {}).unwrap();
    let b = train(&config, &run(Mode::Mpg, &out_dir("rep-b")), &NO_STOP, &mut |_| {}).unwrap();
    let key = |r: &Vec<curves::EpochRecord>| {
        r.iter()
            .map(|x| (x.train_objective, x.probe_objective))
            .collect::<Vec<_>>()
    };
    assert_eq!(key(&a), key(&b));
}

#[test]
fn a_seed_learns_the_same_alone_or_beside_other_seeds() {
    // Seeds train side by side in stacked computations; each member's arithmetic is its own,
    // so seed 3 alone (one thread) and seed 3 beside seeds 1 and 4 (two threads, one shard
    // each) give the same bits.
    let mut config = smoke();
    config.train.epochs = 3;
    let alone = out_dir("alone");
    let together = out_dir("together");
    let runs = |dir: &std::path::Path, seeds: &[u64]| -> Vec<TrainRun> {
        seeds
            .iter()
            .map(|&seed| TrainRun {
                seed,
                out: dir.join(format!("seed{seed}")),
                ..run(Mode::Mpg, dir)
            })
            .collect()
    };
    let mut seen = Vec::new();
    let one = train_all(&config, &runs(&alone, &[3]), &NO_STOP, &mut |_, _| {}).unwrap();
    // Two threads, each running one shard of every seed's minibatch and probe set.
    let mut two_workers = config.clone();
    two_workers.train.threads = 2;
    let three = train_all(
        &two_workers,
        &runs(&together, &[1, 3, 4]),
        &NO_STOP,
        &mut |k, r| seen.push((k, r.epoch)),
    )
    .unwrap();
    let key = |r: &[curves::EpochRecord]| {
        r.iter()
            .map(|x| {
                (
                    x.train_objective,
                    x.probe_objective,
                    x.action_msd,
                    x.probe_ego_return,
                )
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(key(&one[0].records), key(&three[1].records));
    let weights = |dir: &std::path::Path| std::fs::read(dir.join("seed3.safetensors")).unwrap();
    assert_eq!(weights(&alone), weights(&together));
    // The other seeds learned something else, and every run reported every epoch.
    assert_ne!(key(&three[0].records), key(&three[1].records));
    assert_eq!(seen.len(), 9);
    for k in 0..3 {
        let epochs: Vec<usize> = seen.iter().filter(|s| s.0 == k).map(|s| s.1).collect();
        assert_eq!(epochs, vec![1, 2, 3], "run {k}");
    }
}

#[test]
fn resume_runs_only_the_epochs_after_the_checkpoint() {
    let mut config = smoke();
    config.train.epochs = 7;
    let dir = out_dir("resume");
    let run7 = run(Mode::Mpg, &dir);
    let full = train(&config, &run7, &NO_STOP, &mut |_| {}).unwrap();
    // Emulate a run interrupted after epoch 5: a checkpoint saying epoch 5 next to the curves.
    let (net, mut side) = file::load(&dir.join("seed3"), Layout::Table1 { players: 9 }).unwrap();
    side.epochs = 5;
    file::save(&dir.join("seed3.ckpt"), &net, &side).unwrap();
    let mut epochs_run = Vec::new();
    let resumed = train(
        &config,
        &TrainRun {
            resume: true,
            ..run7.clone()
        },
        &NO_STOP,
        &mut |r| epochs_run.push(r.epoch),
    )
    .unwrap();
    assert_eq!(epochs_run, vec![6, 7], "only the missing epochs run");
    let key = |r: &[curves::EpochRecord]| {
        r.iter()
            .map(|x| (x.epoch, x.train_objective, x.probe_objective))
            .collect::<Vec<_>>()
    };
    assert_eq!(
        key(&resumed[..5]),
        key(&full[..5]),
        "the first five rows come from the curves file"
    );
    assert!(
        !dir.join("seed3.ckpt.json").exists(),
        "the finished policy supersedes the checkpoint"
    );
    // A checkpoint made with another configuration is refused.
    file::save(&dir.join("seed3.ckpt"), &net, &side).unwrap();
    let mut other = config.clone();
    other.train.learning_rate = 0.5;
    let err = train(&other, &TrainRun { resume: true, ..run7 }, &NO_STOP, &mut |_| {}).unwrap_err();
    assert!(err.to_string().contains("another run"), "{err}");
}

#[test]
fn a_stop_request_ends_with_a_checkpoint_that_resumes_past_a_cut_write() {
    let config = smoke();
    let dir = out_dir("stop");
    let stop = AtomicBool::new(false);
    let mut seen = Vec::new();
    let err = train(&config, &run(Mode::Mpg, &dir), &stop, &mut |r| {
        seen.push(r.epoch);
        if r.epoch == 3 {
            stop.store(true, std::sync::atomic::Ordering::SeqCst); // as the Ctrl-C handler does
        }
    })
    .unwrap_err();
    assert!(
        matches!(err, mpgdrive::train::TrainError::Interrupted { epoch: 3, .. }),
        "{err}"
    );
    assert_eq!(seen, vec![1, 2, 3]);
    let (_, side) = file::load(&dir.join("seed3.ckpt"), Layout::Table1 { players: 9 }).unwrap();
    assert_eq!(side.epochs, 3);
    assert!(
        dir.join("seed3.ckpt.adam.safetensors").exists(),
        "Adam's state kept"
    );
    // The run uninterrupted, for reference.
    let whole = out_dir("stop-whole");
    let uninterrupted = train(&config, &run(Mode::Mpg, &whole), &NO_STOP, &mut |_| {}).unwrap();
    let bytes = |d: &std::path::Path| std::fs::read(d.join("seed3.safetensors")).unwrap();
    // A later checkpoint's write cut short as the writer leaves it: the epoch-3 files kept
    // under `.ckpt.prev` (copies), then new optimiser state and weights renamed over the
    // current ones, the sidecar still epoch 3's. Resuming must start from the kept files.
    for ext in ["safetensors", "adam.safetensors", "json"] {
        let name = |kind: &str| dir.join(format!("seed3.ckpt.{kind}{ext}"));
        std::fs::copy(name(""), name("prev.")).unwrap();
    }
    let replace = |name: &str, contents: &[u8]| {
        let tmp = dir.join("tmp");
        std::fs::write(&tmp, contents).unwrap();
        std::fs::rename(tmp, dir.join(name)).unwrap();
    };
    replace("seed3.ckpt.adam.safetensors", b"a later state");
    replace("seed3.ckpt.safetensors", &bytes(&whole));
    let resumed = train(
        &config,
        &TrainRun {
            resume: true,
            ..run(Mode::Mpg, &dir)
        },
        &NO_STOP,
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(resumed.len(), config.train.epochs);
    let left = checkpoint_files(&dir);
    assert!(left.is_empty(), "removed with the checkpoint: {left:?}");
    // Adam continues with its moments, so the run ends as one never stopped: the same
    // weights, bit for bit, and the same curves.
    assert!(
        bytes(&dir) == bytes(&whole),
        "the resumed weights are the uninterrupted run's"
    );
    let key = |r: &[curves::EpochRecord]| {
        r.iter()
            .map(|x| (x.epoch, x.train_objective, x.probe_objective, x.action_msd))
            .collect::<Vec<_>>()
    };
    assert_eq!(key(&resumed), key(&uninterrupted));
}

fn sample_net() -> PolicyNet {
    PolicyNet::seeded(NetSpec::new(Layout::Table1 { players: 9 }, 8, 9.81), 0)
}

fn sidecar_for(net: &PolicyNet) -> file::Sidecar {
    file::Sidecar {
        format: file::FORMAT.into(),
        obs_layout_version: mpgdrive::policy::observation::OBS_LAYOUT_VERSION,
        net: net.spec.clone(),
        mode: Mode::Mpg,
        seed: 0,
        epochs: 0,
        command: "test".into(),
        code_version: mpgdrive::VERSION.into(),
        config: smoke(),
        metrics: serde_json::Value::Null,
    }
}

#[test]
fn policy_file_round_trip_gives_the_same_actions() {
    let dir = out_dir("roundtrip");
    let net = sample_net();
    file::save(&dir.join("p"), &net, &sidecar_for(&net)).unwrap();
    let (back, side) = file::load(&dir.join("p.json"), Layout::Table1 { players: 9 }).unwrap();
    assert_eq!(side, sidecar_for(&net));
    // Fixed inputs (not libtorch's generator, which other tests seed).
    let obs = Tensor::linspace(-20.0, 50.0, 90, (tch::Kind::Float, tch::Device::Cpu)).reshape([5, 18]);
    let (a, b) = (net.forward(&obs), back.forward(&obs));
    assert_eq!(Vec::<f32>::try_from(a).unwrap(), Vec::<f32>::try_from(b).unwrap());
    // Outputs stay inside [-g, g].
    let big = net.forward(&(obs * 1e4));
    assert!(big.abs().max().double_value(&[]) <= 9.81 + 1e-5);
}

#[test]
fn mismatched_truncated_or_corrupted_policy_files_are_refused() {
    let dir = out_dir("refuse");
    let net = sample_net();
    let base = dir.join("p");
    file::save(&base, &net, &sidecar_for(&net)).unwrap();
    // Another player count.
    assert!(matches!(
        file::load(&base, Layout::Table1 { players: 5 }),
        Err(PolicyError::Mismatch { .. })
    ));
    // A Table I policy where the traffic layout is read (a traffic configuration).
    let err = file::load(&base, Layout::Traffic).unwrap_err();
    assert!(
        err.to_string()
            .contains("observation layout version 2, the configuration's world"),
        "{err}"
    );
    // Another observation layout.
    let mut side = sidecar_for(&net);
    side.obs_layout_version = 99;
    std::fs::write(dir.join("p.json"), serde_json::to_string(&side).unwrap()).unwrap();
    let err = file::load(&base, Layout::Table1 { players: 9 }).unwrap_err();
    assert!(err.to_string().contains("observation layout version 99"), "{err}");
    // Truncated weights.
    file::save(&base, &net, &sidecar_for(&net)).unwrap();
    let weights = std::fs::read(dir.join("p.safetensors")).unwrap();
    std::fs::write(dir.join("p.safetensors"), &weights[..weights.len() / 2]).unwrap();
    assert!(matches!(
        file::load(&base, Layout::Table1 { players: 9 }),
        Err(PolicyError::Weights { .. })
    ));
    // Weights of another network size under a matching sidecar.
    let other = PolicyNet::new(NetSpec::new(Layout::Table1 { players: 9 }, 4, 9.81));
    other.vs.save(dir.join("p.safetensors")).unwrap();
    assert!(matches!(
        file::load(&base, Layout::Table1 { players: 9 }),
        Err(PolicyError::Weights { .. })
    ));
    // A sidecar that is not JSON.
    std::fs::write(dir.join("p.json"), "{not json").unwrap();
    assert!(matches!(
        file::load(&base, Layout::Table1 { players: 9 }),
        Err(PolicyError::Sidecar { .. })
    ));
}

#[test]
fn learning_rate_decays_exponentially_to_its_final_value() {
    let mut t = smoke().train;
    (t.epochs, t.learning_rate, t.learning_rate_final) = (3, 1e-2, 1e-4);
    let lr: Vec<f64> = (0..3).map(|e| mpgdrive::train::learning_rate(&t, e)).collect();
    approx::assert_relative_eq!(lr[0], 1e-2);
    approx::assert_relative_eq!(lr[1], 1e-3, max_relative = 1e-12);
    approx::assert_relative_eq!(lr[2], 1e-4, max_relative = 1e-12);
}

#[test]
fn a_step_size_restart_starts_a_new_cycle_that_resumes_bit_for_bit() {
    // Two cycles, epochs 0-7 and 8-14, each decaying from 0.01 to 0.001.
    let mut config = smoke();
    config.train.learning_rate_restarts = vec![8];
    let lr = |e| mpgdrive::train::learning_rate(&config.train, e);
    approx::assert_relative_eq!(lr(7), 1e-3, max_relative = 1e-12);
    approx::assert_relative_eq!(lr(8), 1e-2);
    approx::assert_relative_eq!(lr(11), 1e-2 * 0.1f64.sqrt(), max_relative = 1e-12);
    approx::assert_relative_eq!(lr(14), 1e-3, max_relative = 1e-12);
    let key = |r: &[curves::EpochRecord]| {
        r.iter()
            .map(|x| (x.epoch, x.train_objective, x.probe_objective))
            .collect::<Vec<_>>()
    };
    let bytes = |d: &std::path::Path| std::fs::read(d.join("seed3.safetensors")).unwrap();
    // The first cycle is a run of 8 epochs.
    let mut short = smoke();
    short.train.epochs = 8;
    let first = train(
        &short,
        &run(Mode::Mpg, &out_dir("cycle-first")),
        &NO_STOP,
        &mut |_| {},
    )
    .unwrap();
    let whole_dir = out_dir("cycle-whole");
    let whole = train(&config, &run(Mode::Mpg, &whole_dir), &NO_STOP, &mut |_| {}).unwrap();
    assert_eq!(key(&whole[..8]), key(&first));
    // The second cycle changes the run (a warm step size and fresh moments).
    let plain_dir = out_dir("cycle-none");
    train(&smoke(), &run(Mode::Mpg, &plain_dir), &NO_STOP, &mut |_| {}).unwrap();
    assert!(
        bytes(&whole_dir) != bytes(&plain_dir),
        "the restart changes the weights"
    );
    // Stopped one epoch into the second cycle (Adam's state holds that one step), then
    // resumed: the uninterrupted run's weights, bit for bit.
    let dir = out_dir("cycle-stop");
    let stop = AtomicBool::new(false);
    let err = train(&config, &run(Mode::Mpg, &dir), &stop, &mut |r| {
        if r.epoch == 9 {
            stop.store(true, std::sync::atomic::Ordering::SeqCst);
        }
    })
    .unwrap_err();
    assert!(
        matches!(err, mpgdrive::train::TrainError::Interrupted { epoch: 9, .. }),
        "{err}"
    );
    let resume = TrainRun {
        resume: true,
        ..run(Mode::Mpg, &dir)
    };
    train(&config, &resume, &NO_STOP, &mut |_| {}).unwrap();
    assert!(bytes(&dir) == bytes(&whole_dir), "resumed across the restart");
}

#[test]
fn the_continuation_decays_epsilon_geometrically_to_the_rewards() {
    let mut config = smoke();
    config.reward.epsilon = 0.02;
    assert_eq!(
        mpgdrive::train::training_epsilon(&config, 0),
        0.02,
        "none configured"
    );
    config.train.continuation = Some(mpgdrive::config::ContinuationConfig {
        epsilon_start: 1.0,
        epochs: 4,
    });
    let eps: Vec<f64> = (0..6)
        .map(|e| mpgdrive::train::training_epsilon(&config, e))
        .collect();
    // 0.02 * 50^(1 - e/4): 1, 50^0.75 * 0.02 = 0.37606, 50^0.5 * 0.02 = 0.14142, 0.05318, then 0.02.
    approx::assert_relative_eq!(eps[0], 1.0, max_relative = 1e-12);
    approx::assert_relative_eq!(eps[1], 0.376_060_309_308_639_7, max_relative = 1e-12);
    approx::assert_relative_eq!(eps[2], 0.141_421_356_237_309_5, max_relative = 1e-12);
    approx::assert_relative_eq!(eps[3], 0.053_182_958_969_449_89, max_relative = 1e-12);
    assert_eq!(eps[4..], [0.02, 0.02]);
}

#[test]
fn the_correction_continuation_holds_its_start_then_moves_linearly_to_the_worlds() {
    let mut config = smoke();
    config.sim.projection_order = mpgdrive::config::ProjectionOrder::Shared;
    config.sim.shared_correction = 0.75;
    assert_eq!(mpgdrive::train::training_shared_correction(&config, 0), 0.75);
    config.train.correction_continuation = Some(mpgdrive::config::CorrectionContinuation {
        start: 1.0,
        epochs: [2, 6],
    });
    // 1 until epoch 2, then 1 - 0.25 (e - 2) / 4: 0.9375, 0.875, 0.8125, and 0.75 from 6 on.
    let share: Vec<f64> = (0..8)
        .map(|e| mpgdrive::train::training_shared_correction(&config, e))
        .collect();
    assert_eq!(share, [1.0, 1.0, 1.0, 0.9375, 0.875, 0.8125, 0.75, 0.75]);
    // Without the shared order there is no correction to move.
    config.sim.projection_order = mpgdrive::config::ProjectionOrder::Simultaneous;
    let refused = config.validate().unwrap_err().to_string();
    assert!(refused.contains("train.correction_continuation"), "{refused}");
}

#[test]
fn a_continuation_changes_only_the_training_rewards_epsilon() {
    let mut config = smoke();
    config.train.epochs = 3;
    let weights = |dir: &std::path::Path| std::fs::read(dir.join("seed3.safetensors")).unwrap();
    let trained = |config: &mpgdrive::config::Config, name: &str| {
        let dir = out_dir(name);
        let records = train(config, &run(Mode::Mpg, &dir), &NO_STOP, &mut |_| {}).unwrap();
        (records, weights(&dir))
    };
    let (plain, plain_weights) = trained(&config, "cont-plain");
    config.train.continuation = Some(mpgdrive::config::ContinuationConfig {
        epsilon_start: config.reward.epsilon,
        epochs: 3,
    });
    let (_, same_weights) = trained(&config, "cont-same");
    assert_eq!(
        plain_weights, same_weights,
        "epsilon_start = epsilon is no continuation"
    );
    config.train.continuation = Some(mpgdrive::config::ContinuationConfig {
        epsilon_start: 5.0,
        epochs: 3,
    });
    let (cont, cont_weights) = trained(&config, "cont-5");
    assert_ne!(plain_weights, cont_weights);
    // The first step's minibatch objective: the same weights and states, every pair penalty
    // -1 / (q + epsilon) less negative with epsilon 5 than with the smoke setting's 0.1.
    assert!(
        cont[0].train_objective > plain[0].train_objective,
        "{} vs {}",
        cont[0].train_objective,
        plain[0].train_objective
    );
}

#[test]
fn screening_keeps_the_initialisation_with_the_best_probe_objective() {
    let mut config = smoke();
    config.train.epochs = 4;
    // Candidate 0 is the run's own initialisation: screened for 2 epochs, its probe objective
    // is the plain run's after epoch 2.
    let plain = train(
        &config,
        &run(Mode::Mpg, &out_dir("screen-plain")),
        &NO_STOP,
        &mut |_| {},
    )
    .unwrap();
    config.train.init_candidates = 3;
    config.train.screen_epochs = 2;
    let dir = out_dir("screen");
    let records = train(&config, &run(Mode::Mpg, &dir), &NO_STOP, &mut |_| {}).unwrap();
    let side: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("seed3.json")).unwrap()).unwrap();
    let s = &side["metrics"]["init_screening"];
    let objectives: Vec<f64> = serde_json::from_value(s["probe_objectives"].clone()).unwrap();
    assert_eq!(objectives.len(), 3);
    assert_eq!(objectives[0], plain[1].probe_objective);
    let best = (0..3).fold(0, |b, c| if objectives[c] > objectives[b] { c } else { b });
    assert_eq!(s["chosen"], best);
    // The kept candidate then trains from scratch: its epoch 2 is its screening result.
    assert_eq!(records[1].probe_objective, objectives[best]);
    assert!(
        objectives.iter().any(|&o| o != objectives[0]),
        "the candidates differ: {objectives:?}"
    );
}

/// The smoke training through the command line, with `env` added; the weights' bytes.
fn trained_bytes(name: &str, env: &[(&str, &str)]) -> Vec<u8> {
    trained_bytes_on(name, SMOKE, env, common::bin())
}

/// The paper's world, tiny (the smoke configuration).
const SMOKE: &str = "configs/smoke.toml";

/// [`trained_bytes_on`] with the binary run by `qemu-x86_64` as processor model `cpu`.
fn trained_bytes_emulated(name: &str, config: &str, cpu: &str) -> Vec<u8> {
    let mut qemu = Command::new("qemu-x86_64");
    qemu.args(["-cpu", cpu, env!("CARGO_BIN_EXE_mpgdrive")]);
    qemu.current_dir(env!("CARGO_MANIFEST_DIR"));
    trained_bytes_on(name, config, &[], qemu)
}

/// `configs/traffic.toml` (the merge-traffic world of `policies/traffic`) made tiny: a 10 s
/// horizon, 16 hidden units, 6 epochs of 8 states, two initialisations screened for 2 epochs.
/// Returns the path it is written to.
fn tiny_traffic_config() -> String {
    let mut text = std::fs::read_to_string("configs/traffic.toml").unwrap();
    for (from, to) in [
        ("horizon = 30.0", "horizon = 10.0"),
        ("hidden = 64", "hidden = 16"),
        ("epochs = 300", "epochs = 6"),
        ("batch = 64", "batch = 8"),
        ("probe_scenarios = 64", "probe_scenarios = 8"),
        ("init_candidates = 4", "init_candidates = 2"),
        ("screen_epochs = 30", "screen_epochs = 2"),
    ] {
        assert_eq!(text.matches(from).count(), 1, "configs/traffic.toml: {from}");
        text = text.replace(from, to);
    }
    let path = out_dir("tiny-traffic").join("traffic.toml");
    std::fs::write(&path, text).unwrap();
    path.to_str().unwrap().to_owned()
}

/// The training of `config` through the command line for seed 0, `mpgdrive` (a command that
/// runs the binary) with `env` added; the weights' bytes.
fn trained_bytes_on(name: &str, config: &str, env: &[(&str, &str)], mut mpgdrive: Command) -> Vec<u8> {
    let dir = out_dir(name);
    let out = mpgdrive
        .args(["train", "--config", config, "--seeds", "0", "--out"])
        .arg(&dir)
        .envs(env.iter().copied())
        .env_remove("MKL_CBWR")
        .env_remove("ATEN_CPU_CAPABILITY")
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    std::fs::read(dir.join("seed0.safetensors")).unwrap()
}

#[test]
fn training_gives_the_same_bytes_on_intel_and_amd_processors() {
    // QEMU's user-mode emulator runs the binary as an Intel Haswell and as an AMD EPYC (both
    // AVX2, no AVX-512), each telling MKL its vendor. Its approximate instructions (reciprocal
    // square root and the like) round otherwise than either vendor's silicon, so a kernel
    // that follows the processor shows here: while Adam's square root was MKL's, the weights
    // differed from this processor's under both models.
    let found = Command::new("qemu-x86_64").arg("--version").output();
    assert!(
        found.is_ok(),
        "qemu-x86_64 is missing: scripts/setup.sh installs it (qemu-user)"
    );
    // The paper's world (smoke) under both models, and the merge-traffic world of
    // `policies/traffic` (its own vehicles, drivers and entry rule) as the Intel one.
    let traffic = tiny_traffic_config();
    let smoke_own = trained_bytes("vendor-own", &[]);
    let traffic_own = trained_bytes_on("vendor-own-traffic", &traffic, &[], common::bin());
    std::thread::scope(|s| {
        let runs = [
            (SMOKE, &smoke_own, "Haswell-noTSX"),
            (SMOKE, &smoke_own, "EPYC-Rome"),
            (traffic.as_str(), &traffic_own, "Haswell-noTSX"),
        ]
        .map(|(config, own, cpu)| {
            let name = format!(
                "vendor-{cpu}-{}",
                if config == SMOKE { "smoke" } else { "traffic" }
            );
            (
                config,
                own,
                cpu,
                s.spawn(move || trained_bytes_emulated(&name, config, cpu)),
            )
        });
        for (config, own, cpu, run) in runs {
            assert!(*own == run.join().unwrap(), "{config}: other weights as {cpu}");
        }
    });
}

#[test]
fn training_gives_the_same_bytes_whichever_vector_instructions_the_processor_offers() {
    // MKL_ENABLE_INSTRUCTIONS=AVX2 makes MKL take the path of a processor without AVX-512;
    // SSE4_2 that of an older one. Pinned (the default), the weights are the same bytes.
    let avx2 = [("MKL_ENABLE_INSTRUCTIONS", "AVX2")];
    let sse = [("MKL_ENABLE_INSTRUCTIONS", "SSE4_2")];
    let own = trained_bytes("pinned-own", &[]);
    assert_eq!(own, trained_bytes("pinned-avx2", &avx2));
    assert_eq!(own, trained_bytes("pinned-sse", &sse));
    // The check can fail: with each library's own kernels, an Intel processor with AVX-512
    // (this one, if it is) trains other weights than its AVX2 path. (MKL takes other paths on
    // other vendors' processors, so there the two may agree.)
    let intel = std::fs::read_to_string("/proc/cpuinfo").is_ok_and(|c| c.contains("GenuineIntel"));
    if intel && std::arch::is_x86_feature_detected!("avx512f") {
        let native = [(mpgdrive::policy::kernels::OPT_OUT, "native")];
        let native_avx2 = [native[0], avx2[0]];
        assert_ne!(
            trained_bytes("native-own", &native),
            trained_bytes("native-avx2", &native_avx2)
        );
    }
}
