//! One training epoch of the paper's study: `configs/paper.toml`, 5 MPG seeds trained side by
//! side (one stacked rollout of 5 x 64 scenarios x 300 steps, back-propagation, one Adam step
//! each, then the probe rollouts), no screening, one libtorch thread as configured.
//! Reported per epoch; divide by 5 for the time per seed-epoch.
//!
//! `cargo bench --bench train_epoch` (or `make bench`).

use criterion::{Criterion, criterion_group, criterion_main};
use mpgdrive::config::Config;
use mpgdrive::train::{Mode, TrainRun, train_all};
use std::path::Path;
use std::sync::atomic::AtomicBool;

fn bench(c: &mut Criterion) {
    let mut config = Config::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/paper.toml")).unwrap();
    config.train.epochs = 1;
    config.train.init_candidates = 1;
    let dir = std::env::temp_dir().join(format!("mpgdrive-bench-train-{}", std::process::id()));
    let runs: Vec<TrainRun> = (0..5)
        .map(|seed| TrainRun {
            mode: Mode::Mpg,
            seed,
            out: dir.join(format!("seed{seed}")),
            resume: false,
            command: "bench".into(),
        })
        .collect();
    let stop = AtomicBool::new(false);
    let mut group = c.benchmark_group("train_epoch");
    group.sample_size(10);
    group.bench_function("paper_5_seeds", |b| {
        b.iter(|| train_all(&config, &runs, &stop, &mut |_, _| {}).unwrap())
    });
    group.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, bench);
criterion_main!(benches);
