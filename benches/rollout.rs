//! No-gradient rollout throughput: 500 scenarios x 300 steps (the paper's T = 30 s at 0.1 s),
//! IDM surrounding players, the ego driven by a fixed batched policy (observation building and
//! the batched forward call included). Reported in agent-steps per second.
//!
//! `cargo bench --bench rollout` (or `make bench`).

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use mpgdrive::config::Config;
use mpgdrive::engine::rollout::{Recording, RolloutOptions, rollout};
use mpgdrive::policy::{LinearPolicy, PolicyActor};
use mpgdrive::world::Driver;
use mpgdrive::world::sampler::sample_scenes;
use std::path::Path;

const SCENARIOS: usize = 500;

fn bench(c: &mut Criterion) {
    let config = Config::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/paper.toml")).unwrap();
    let scenes = sample_scenes(&config, 0, 0, SCENARIOS);
    let agent_steps = (SCENARIOS * config.n_steps() * config.n_agents()) as u64;
    let mut group = c.benchmark_group("rollout_500x300");
    group.sample_size(10);
    group.throughput(Throughput::Elements(agent_steps));
    // Episodes end at their first collision; "all_steps" turns that off so that every episode
    // really runs its 300 steps and the element count is exact.
    for (name, recording, threads, terminate) in [
        ("all_steps_2_threads", Recording::Summary, 2, false),
        ("summary_2_threads", Recording::Summary, 2, true),
        ("summary_1_thread", Recording::Summary, 1, true),
        ("full_record_2_threads", Recording::Full, 2, true),
    ] {
        let opts = RolloutOptions {
            recording,
            threads,
            terminate_on_collision: terminate,
            ..RolloutOptions::from_config(&config)
        };
        group.bench_function(name, |b| {
            b.iter(|| {
                rollout(&config, &opts, &scenes, || {
                    PolicyActor::new(&config, LinearPolicy::speed_keeping(&config), Driver::Idm, false)
                })
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
