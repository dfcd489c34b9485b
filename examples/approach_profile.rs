//! The potential along one direction of the ego's approach in the paper's scenario presets:
//! every player on a seed's shared policy, the ego's action raised by a constant offset `d`
//! (m/s^2) for the first `STEPS` steps while it is on the ramp. Gradient play stops where the
//! potential's derivative along every direction is zero; this shows what that looks like
//! along one. On a coarse grid (`d` in -0.5..2 by 0.05) the least-squares trend and the spread
//! of the slopes between neighbouring points; on a fine grid (-0.01..0.04 by 0.001) the local
//! maxima and where the policy itself (`d = 0`) lies among them.
//!
//! ```sh
//! cargo run --release --example approach_profile -- [CONFIG] [POLICY_DIR] [STEPS]
//! ```
//! (defaults `configs/paper.toml`, `policies/mpg`, 30). Deterministic.

use mpgdrive::config::Config;
use mpgdrive::engine::rollout::{Actor, RolloutOptions, rollout};
use mpgdrive::eval::study::{Rules, load_policies};
use mpgdrive::policy::network::PolicyNet;
use mpgdrive::policy::observation::PolicyActor;
use mpgdrive::world::drivers::Driver;
use mpgdrive::world::neighbors::Neighbors;
use mpgdrive::world::scenarios::Preset;
use mpgdrive::world::state::Scene;
use std::path::Path;
use std::sync::Mutex;

/// Every player on the policy; in scene `b` the ego's action raised by `offsets[b]` for the
/// first `steps` steps while it is on the ramp.
struct Offset {
    policy: PolicyActor<PolicyNet>,
    offsets: Vec<f64>,
    steps: usize,
}

impl Actor for Offset {
    fn act(&mut self, step: usize, scenes: &[Scene], neighbors: &[Neighbors], out: &mut [f64]) {
        self.policy.act(step, scenes, neighbors, out);
        let n = scenes.first().map_or(0, Scene::len);
        for (b, scene) in scenes.iter().enumerate() {
            if step < self.steps && scene.ego().on_ramp {
                out[b * n] += self.offsets[b];
            }
        }
    }
}

/// Least-squares slope of `y` on `x`.
fn trend(x: &[f64], y: &[f64]) -> f64 {
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (mx, my) = (mean(x), mean(y));
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
    sxy / sxx
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let config = Config::load(Path::new(
        args.get(1).map_or("configs/paper.toml", String::as_str),
    ))?;
    let nets = load_policies(
        Path::new(args.get(2).map_or("policies/mpg", String::as_str)),
        &config,
        Rules::Same,
    )?;
    let steps: usize = args.get(3).map_or(Ok(30), |s| s.parse())?;
    let coarse: Vec<f64> = (-10..=40).map(|k| f64::from(k) * 0.05).collect();
    let fine: Vec<f64> = (-10..=40).map(|k| f64::from(k) * 0.001).collect();
    let opts = RolloutOptions {
        threads: 1, // offset `b` is scene `b` of the actor's batch: one chunk
        ..RolloutOptions::from_config(&config)
    };
    println!(
        "scenario | seed | trend (per m/s^2) | slopes between coarse neighbours: sd, share > 0 | fine-grid local maxima | nearest to d = 0 (m/s^2)"
    );
    for preset in [Preset::One, Preset::Two] {
        for (net, side) in &nets {
            let profile = |offsets: &[f64]| -> anyhow::Result<Vec<f64>> {
                let batch = vec![preset.scene(&config); offsets.len()];
                let cell = Mutex::new(Some(net.try_clone()?));
                let outcomes = rollout(&config, &opts, &batch, || Offset {
                    policy: PolicyActor::new(
                        &config,
                        cell.lock().expect("lock").take().expect("one actor"),
                        Driver::Idm,
                        true,
                    ),
                    offsets: offsets.to_vec(),
                    steps,
                });
                Ok(outcomes.iter().map(|o| o.potential_return).collect())
            };
            let (c, f) = (profile(&coarse)?, profile(&fine)?);
            let slopes: Vec<f64> = c.windows(2).map(|w| (w[1] - w[0]) / 0.05).collect();
            let mean = slopes.iter().sum::<f64>() / slopes.len() as f64;
            let sd = (slopes.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / slopes.len() as f64).sqrt();
            let up = slopes.iter().filter(|s| **s > 0.0).count();
            let maxima: Vec<f64> = (1..f.len() - 1)
                .filter(|&k| f[k] > f[k - 1] && f[k] >= f[k + 1])
                .map(|k| fine[k])
                .collect();
            let nearest = maxima.iter().copied().min_by(|a, b| a.abs().total_cmp(&b.abs()));
            println!(
                "{} | {} | {:.0} | {sd:.0}, {up} of {} | {} | {}",
                preset.number(),
                side.seed,
                trend(&coarse, &c),
                slopes.len(),
                maxima.len(),
                nearest.map_or("none".into(), |d| format!("{d:.3}"))
            );
        }
    }
    Ok(())
}
