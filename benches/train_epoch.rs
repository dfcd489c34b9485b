//! Training epochs of the paper's study: `configs/paper.toml` (two threads, one shard each), 5
//! MPG seeds side by side (stacked rollouts of `train.batch` scenarios x 300 steps per seed,
//! back-propagation, one Adam step each, then the probe rollouts), no screening. One
//! iteration is a whole 3-epoch run (set-up and the first epoch's memory growth included); the
//! throughput is in seed-epochs per second.
//!
//! `cargo bench --bench train_epoch` (or `make bench`).

use criterion::{Criterion, criterion_group, criterion_main};
use mpgdrive::config::Config;
use mpgdrive::train::{Mode, TrainRun, train_all};
use std::path::Path;
use std::sync::atomic::AtomicBool;

const EPOCHS: usize = 3;
const SEEDS: u64 = 5;

fn bench(c: &mut Criterion) {
    let mut config = Config::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/paper.toml")).unwrap();
    config.train.epochs = EPOCHS;
    config.train.init_candidates = 1;
    let dir = std::env::temp_dir().join(format!("mpgdrive-bench-train-{}", std::process::id()));
    let runs: Vec<TrainRun> = (0..SEEDS)
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
    group.throughput(criterion::Throughput::Elements(SEEDS * EPOCHS as u64));
    group.bench_function("paper_5_seeds", |b| {
        b.iter(|| train_all(&config, &runs, &stop, &mut |_, _| {}).unwrap())
    });
    group.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, bench);
criterion_main!(benches);
