//! The deployment's forward pass: the five members of a traffic set acting on 25 vehicles (about
//! the controlled vehicles of one co-simulation step on `i80_merge`), with the ensemble's plain
//! Rust pass against libtorch's forward pass of each member; and one network on an evaluation's
//! batch (250 scenes x 9 players per thread).
//!
//! `cargo bench --bench ensemble` (or `make bench`).

use criterion::{Criterion, criterion_group, criterion_main};
use mpgdrive::policy::network::{NetSpec, PolicyNet};
use mpgdrive::policy::observation::Layout;
use mpgdrive::policy::{Combine, PolicyEnsemble};
use tch::Tensor;

const MEMBERS: i64 = 5;
const ROWS: usize = 25;

fn bench(c: &mut Criterion) {
    let spec = NetSpec::new(Layout::Traffic, 64, 9.81);
    let nets = || (0..MEMBERS).map(|k| PolicyNet::seeded(spec.clone(), k));
    let obs: Vec<f32> = (0..ROWS * spec.obs_dim)
        .map(|k| (k as f32 * 0.37) % 40.0)
        .collect();
    let mut group = c.benchmark_group("ensemble_5x25");
    let mut ensemble = PolicyEnsemble::new(nets().collect(), Combine::Median).unwrap();
    let mut out = vec![0.0f32; ROWS];
    group.bench_function("plain_rust", |b| {
        b.iter(|| ensemble.actions(&obs, ROWS, &mut out))
    });
    let members: Vec<PolicyNet> = nets().collect();
    let input = Tensor::from_slice(&obs).reshape([ROWS as i64, spec.obs_dim as i64]);
    group.bench_function("libtorch_each_member", |b| {
        b.iter(|| {
            tch::no_grad(|| {
                for net in &members {
                    let _ = Vec::<f32>::try_from(net.forward(&input)).unwrap();
                }
            })
        })
    });
    group.finish();
    // An evaluation's batch: one network on 250 scenes x 9 players.
    const EVAL_ROWS: usize = 2250;
    let obs: Vec<f32> = (0..EVAL_ROWS * spec.obs_dim)
        .map(|k| (k as f32 * 0.37) % 40.0)
        .collect();
    let mut one = PolicyEnsemble::from(PolicyNet::seeded(spec.clone(), 0));
    let mut out = vec![0.0f32; EVAL_ROWS];
    c.bench_function("network_2250_rows", |b| {
        b.iter(|| one.actions(&obs, EVAL_ROWS, &mut out))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
