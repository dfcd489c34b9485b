//! `mpgdrive demo`: non-learning drivers on sampled merge scenarios.

use crate::cli::common::{Common, outln, usage};
use anyhow::Result;
use clap::Args;
use mpgdrive::config::Config;
use mpgdrive::engine::rollout::{DriverActor, RolloutOptions, rollout};
use mpgdrive::eval::{EpisodeMetrics, Summary};
use mpgdrive::world::Driver;
use mpgdrive::world::sampler::sample_scenes;
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `mpgdrive demo`.
#[derive(Args)]
pub struct DemoArgs {
    #[command(flatten)]
    common: Common,
    /// Number of scenarios per setting.
    #[arg(long, default_value_t = 100)]
    scenarios: usize,
    /// Print JSON instead of Markdown.
    #[arg(long)]
    json: bool,
}

/// Runs `mpgdrive demo`.
pub fn run(args: DemoArgs) -> Result<ExitCode> {
    let common = args.common.settings()?;
    if args.scenarios == 0 {
        return Err(usage("--scenarios must be at least 1"));
    }
    demo(
        &common.config,
        common.seed,
        common.threads,
        args.scenarios,
        args.json,
    )?;
    Ok(ExitCode::SUCCESS)
}

fn demo(config: &Config, seed: u64, threads: usize, scenarios: usize, json: bool) -> Result<()> {
    let scenes = sample_scenes(config, seed, 0, scenarios);
    let mut opts = RolloutOptions::from_config(config);
    opts.threads = threads;
    let mut results = Vec::new();
    for (name, others) in [("IDM", Driver::Idm), ("Constant speed", Driver::ConstSpeed)] {
        let start = Instant::now();
        let outcomes = rollout(config, &opts, &scenes, || {
            DriverActor::new(config, Driver::Idm, others)
        });
        let wall = start.elapsed().as_secs_f64();
        let metrics: Vec<_> = outcomes.iter().map(EpisodeMetrics::of).collect();
        results.push((name, Summary::of(&metrics), wall));
    }
    if json {
        let v: Vec<_> = results
            .iter()
            .map(|(name, s, wall)| serde_json::json!({"surrounding": name, "summary": s, "wall_seconds": wall}))
            .collect();
        outln!(
            "{}",
            serde_json::to_string_pretty(
                &serde_json::json!({"seed": seed, "scenarios": scenarios, "ego": "IDM", "results": v})
            )?
        );
    } else {
        outln!(
            "mpgdrive demo: {scenarios} forced-merge scenarios (seed {seed}), ego driven by IDM behind its projected leader\n"
        );
        for (name, s, wall) in &results {
            outln!("{}", s.markdown(&format!("Surrounding players: {name}")));
            outln!(
                "({} episodes x {} steps in {:.3} s)\n",
                s.episodes,
                config.n_steps(),
                wall
            );
        }
    }
    Ok(())
}
