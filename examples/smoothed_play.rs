//! Gradient play on the potential smoothed in the policy's parameters: from one seed's shared
//! policy, each step estimates the gradient of `E[Phi(theta + sigma eps)]` over `PAIRS`
//! antithetic Gaussian perturbations `eps` (every player on the perturbed policy, common
//! training states for all of them, centred ranks as fitness) and takes an Adam step along it.
//! The pathwise gradient that training follows sees the potential at a scale of 1e-5 m/s^2,
//! where a waiting policy sits on a ripple's crest (`approach_profile`); this one sees it at
//! the scale `sigma`. Every 10 steps it prints the probe potential, probe collisions and the
//! number of scenario 1's and 2's described states with the paper's outcome. Measured in
//! docs/experiments.md ("Gradient play smoothed in the parameters").
//!
//! ```sh
//! cargo run --release --example smoothed_play -- SEED [STEPS] [SIGMA] [PAIRS] [LR] [OUT] [SHARE] [PREFIX]
//! ```
//! (defaults 100 steps, sigma 0.02, 16 pairs, learning rate 0.001; `configs/paper.toml`,
//! `policies/mpg`; OUT: where to save the last policy, `-` for nowhere; SHARE: the minibatch's
//! share of scenario states, default 0.25; PREFIX: perturb only the parameters whose names
//! start with it, e.g. `output`, default all). Deterministic.

use mpgdrive::config::Config;
use mpgdrive::engine::outcome::EpisodeOutcome;
use mpgdrive::engine::rollout::{Recording, RolloutOptions, rollout};
use mpgdrive::eval::EpisodeMetrics;
use mpgdrive::eval::scenario_sets::described;
use mpgdrive::eval::study::{Rules, load_policies};
use mpgdrive::policy::file;
use mpgdrive::policy::network::PolicyNet;
use mpgdrive::policy::observation::PolicyActor;
use mpgdrive::train::adam::Adam;
use mpgdrive::train::stacked::StackedNet;
use mpgdrive::world::drivers::Driver;
use mpgdrive::world::sampler::{
    Purpose, purpose_seed, sample_probe_scenes, sample_training_scenes, standard_normal,
};
use mpgdrive::world::scenarios::Preset;
use mpgdrive::world::state::Scene;
use rand::SeedableRng;
use std::path::Path;
use std::sync::Mutex;

const EVERY: usize = 10;

/// The parameters of `net` as flat arrays, in name order.
fn params(net: &PolicyNet) -> (Vec<String>, Vec<Vec<f32>>) {
    let vars = net.vs.variables();
    let mut names: Vec<String> = vars.keys().cloned().collect();
    names.sort();
    let values = names
        .iter()
        .map(|n| Vec::<f32>::try_from(vars[n].detach().flatten(0, -1)).expect("f32"))
        .collect();
    (names, values)
}

/// A network of `template`'s spec holding `values`.
fn with_params(template: &PolicyNet, names: &[String], values: &[Vec<f32>]) -> PolicyNet {
    let net = PolicyNet::new(template.spec.clone());
    let mut vars = net.vs.variables();
    tch::no_grad(|| {
        for (n, v) in names.iter().zip(values) {
            let var = vars.get_mut(n).expect("same spec");
            let shape = var.size();
            var.copy_(&tch::Tensor::from_slice(v).reshape(shape));
        }
    });
    net
}

/// Every net in `nets` driving every player from each of `scenes` (rows member after member,
/// the members split over two threads).
fn outcomes(config: &Config, nets: Vec<PolicyNet>, scenes: &[Scene]) -> Vec<EpisodeOutcome> {
    let opts = RolloutOptions {
        threads: 1,
        recording: Recording::Summary,
        ..RolloutOptions::from_config(config)
    };
    let half = nets.len().div_ceil(2);
    let mut nets = nets;
    let second = nets.split_off(half);
    let run = |part: Vec<PolicyNet>| -> Vec<EpisodeOutcome> {
        if part.is_empty() {
            return Vec::new();
        }
        let members = part.len();
        let batch: Vec<Scene> = (0..members).flat_map(|_| scenes.iter().cloned()).collect();
        let cell = Mutex::new(Some(StackedNet::from_nets(&part)));
        rollout(config, &opts, &batch, || {
            PolicyActor::new(
                config,
                cell.lock().expect("lock").take().expect("one"),
                Driver::Idm,
                true,
            )
        })
    };
    std::thread::scope(|s| {
        let other = s.spawn(|| run(second));
        let mut first = run(nets);
        first.extend(other.join().expect("thread"));
        first
    })
}

fn mean_potential(o: &[EpisodeOutcome]) -> f64 {
    o.iter().map(|o| o.potential_return).sum::<f64>() / o.len() as f64
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let arg = |k: usize, default: &str| args.get(k).cloned().unwrap_or_else(|| default.to_string());
    let seed: u64 = arg(1, "3").parse()?;
    let steps: usize = arg(2, "100").parse()?;
    let sigma: f32 = arg(3, "0.02").parse()?;
    let pairs: usize = arg(4, "16").parse()?;
    let lr: f64 = arg(5, "0.001").parse()?;
    let out = args.get(6).filter(|o| o.as_str() != "-");
    let share: f64 = arg(7, "0.25").parse()?;
    let prefix = arg(8, "");
    let config = Config::load(Path::new("configs/paper.toml"))?;
    let mut train_config = config.clone();
    train_config.train.scenario_share = share;
    let (net, side) = load_policies(Path::new("policies/mpg"), &config, Rules::Same)?
        .into_iter()
        .find(|(_, s)| s.seed == seed)
        .ok_or_else(|| anyhow::anyhow!("no seed {seed}"))?;
    let (names, mut theta) = params(&net);
    let lengths: Vec<usize> = theta.iter().map(Vec::len).collect();
    let mut adam = Adam::new(&lengths);
    let probe = sample_probe_scenes(&config, purpose_seed(seed, Purpose::Probe));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
    println!(
        "step | probe potential | probe collisions | scenario 1 paper's | scenario 2 paper's | minibatch potential"
    );
    for step in 0..=steps {
        let current = with_params(&net, &names, &theta);
        if step % EVERY == 0 {
            let p = outcomes(&config, vec![current.try_clone()?], &probe);
            let collisions = p.iter().filter(|o| EpisodeMetrics::of(o).collision).count();
            let share = |preset| -> anyhow::Result<usize> {
                Ok(described(&config, &current, preset, 40, 2)?
                    .iter()
                    .filter(|e| e.paper_outcome)
                    .count())
            };
            println!(
                "{step} | {:.0} | {collisions} | {} of 40 | {} of 40 |",
                mean_potential(&p),
                share(Preset::One)?,
                share(Preset::Two)?
            );
        }
        if step == steps {
            break;
        }
        let scenes = sample_training_scenes(&train_config, purpose_seed(seed, Purpose::Train), 5000 + step);
        let noise: Vec<Vec<Vec<f32>>> = (0..pairs)
            .map(|_| {
                lengths
                    .iter()
                    .zip(&names)
                    .map(|(&n, name)| {
                        (0..n)
                            .map(|_| {
                                if name.starts_with(&prefix) {
                                    standard_normal(&mut rng) as f32
                                } else {
                                    0.0
                                }
                            })
                            .collect()
                    })
                    .collect()
            })
            .collect();
        let shifted = |eps: &[Vec<f32>], sign: f32| -> Vec<Vec<f32>> {
            theta
                .iter()
                .zip(eps)
                .map(|(t, e)| t.iter().zip(e).map(|(t, e)| t + sign * sigma * e).collect())
                .collect()
        };
        let nets: Vec<PolicyNet> = noise
            .iter()
            .flat_map(|eps| [shifted(eps, 1.0), shifted(eps, -1.0)])
            .map(|v| with_params(&net, &names, &v))
            .collect();
        let o = outcomes(&config, nets, &scenes);
        let values: Vec<f64> = o.chunks(scenes.len()).map(mean_potential).collect();
        // Centred ranks in [-0.5, 0.5] as fitness (OpenAI-ES).
        let mut order: Vec<usize> = (0..values.len()).collect();
        order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
        let mut rank = vec![0f32; values.len()];
        for (r, &k) in order.iter().enumerate() {
            rank[k] = r as f32 / (values.len() - 1) as f32 - 0.5;
        }
        // Descent on minus the smoothed potential.
        let grads: Vec<Vec<f32>> = (0..lengths.len())
            .map(|l| {
                (0..lengths[l])
                    .map(|i| {
                        -noise
                            .iter()
                            .enumerate()
                            .map(|(j, eps)| (rank[2 * j] - rank[2 * j + 1]) * eps[l][i])
                            .sum::<f32>()
                            / (pairs as f32 * sigma)
                    })
                    .collect()
            })
            .collect();
        let mut views: Vec<&mut [f32]> = theta.iter_mut().map(Vec::as_mut_slice).collect();
        let g: Vec<&[f32]> = grads.iter().map(Vec::as_slice).collect();
        adam.step(lr, &mut views, &g);
        eprintln!(
            "{step}: minibatch potential mean {:.0}",
            values.iter().sum::<f64>() / values.len() as f64
        );
    }
    if let Some(out) = out {
        let net = with_params(&net, &names, &theta);
        file::save(Path::new(out), &net, &side)?;
    }
    Ok(())
}
