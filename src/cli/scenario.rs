//! `mpgdrive scenario`: the paper's specific scenarios, run with the shared policy and drawn.

use crate::cli::common::{pick_policy, print, select_policies};
use anyhow::{Context, Result};
use clap::Args;
use mpgdrive::atomic;
use mpgdrive::config::Config;
use mpgdrive::engine::rollout::Recording;
use mpgdrive::eval::EpisodeMetrics;
use mpgdrive::eval::scenario_sets::{SeedSummary, described, markdown};
use mpgdrive::policy::drive::{Others, policy_rollout};
use mpgdrive::render::episode::render_episode;
use mpgdrive::world::scenarios::Preset;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `mpgdrive scenario`.
#[derive(Args)]
pub struct ScenarioArgs {
    /// Configuration file (TOML).
    #[arg(long, default_value = "configs/paper.toml")]
    config: PathBuf,
    /// The paper's scenario: 1 (leaders accelerate, followers decelerate) or 2 (a large gap
    /// closing fast: wait, then merge).
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=2))]
    preset: u8,
    /// The shared policy driving every player: a file or a directory of seeds.
    #[arg(long, default_value = "policies/mpg")]
    policy: PathBuf,
    /// Which seed's policy to use from a directory (default: the lowest).
    #[arg(long)]
    policy_seed: Option<u64>,
    /// Output directory.
    #[arg(long, default_value = "results/scenarios")]
    out: PathBuf,
    /// Instead of the preset's one state, run this many states drawn from the scenario's
    /// description in the paper, for every seed of the policy directory (or `--policy-seed`'s),
    /// and report the share that ends as the paper's does.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=10_000))]
    states: Option<u64>,
}

/// Runs a preset and draws it; returns the files written and a one-line outcome.
pub fn scenario(
    config: &Config,
    preset: Preset,
    policy: &Path,
    seed: Option<u64>,
    out: &Path,
) -> Result<(Vec<PathBuf>, String)> {
    let net = pick_policy(policy, seed, config)?;
    let scene = preset.scene(config);
    let outcome = policy_rollout(config, &net, Others::SameNetwork, &[scene], 1, Recording::Full)?
        .pop()
        .context("one episode")?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let name = format!("preset{}", preset.number());
    let title = format!("Scenario {}", preset.number());
    let mut files = render_episode(out, &name, &title, config, &outcome)?;
    let metrics = EpisodeMetrics::of(&outcome);
    let dt = config.sim.dt;
    let between = outcome.merged_between();
    let summary = format!(
        "{title}: {}; ego merged at {}, collision {}, mean speed {:.2} m/s, mean |u| {:.3} m/s^2",
        preset.description(),
        outcome.ego_merged_at.map_or("never".to_string(), |m| format!(
            "t = {:.1} s between {} and {}",
            (m + 1) as f64 * dt,
            between.map_or("?".into(), |b| player_or_none(b[0])),
            between.map_or("?".into(), |b| player_or_none(b[1]))
        )),
        outcome.collision.map_or("none".to_string(), |c| format!(
            "players {} and {} at t = {:.1} s",
            c.a,
            c.b,
            (c.step + 1) as f64 * dt
        )),
        metrics.mean_speed,
        metrics.mean_abs_accel
    );
    let json = out.join(format!("{name}.json"));
    let record = serde_json::json!({
        "preset": preset.number(),
        "description": preset.description(),
        "policy": policy,
        "policy_seed": seed,
        "state": preset.state(),
        "initial": preset.scene(config).vehicles.iter().map(|v| [v.x, v.v]).collect::<Vec<_>>(),
        "merged_at_step": outcome.ego_merged_at,
        "merged_between": between,
        "collision": outcome.collision.map(|c| [c.step, c.a, c.b]),
        "metrics": metrics,
        "summary": summary,
    });
    atomic::write(&json, serde_json::to_string_pretty(&record)?)
        .with_context(|| format!("writing {}", json.display()))?;
    files.push(json);
    Ok((files, summary))
}

/// A player number, or "none" for 0.
fn player_or_none(p: usize) -> String {
    if p == 0 { "none".into() } else { p.to_string() }
}

/// Runs `mpgdrive scenario`.
pub fn run(args: ScenarioArgs) -> Result<ExitCode> {
    let config = Config::load(&crate::cli::bundled::resolve(&args.config)?)?;
    let preset = if args.preset == 1 {
        Preset::One
    } else {
        Preset::Two
    };
    let policy = crate::cli::bundled::resolve(&args.policy)?;
    if let Some(n) = args.states {
        return described_states(&config, preset, &policy, args.policy_seed, n as usize, &args.out);
    }
    let (files, summary) = scenario(&config, preset, &policy, args.policy_seed, &args.out)?;
    let mut text = summary;
    for f in files {
        text += &format!("\n  {}", f.display());
    }
    print(&text)?;
    Ok(ExitCode::SUCCESS)
}

/// Each seed's summary of `preset`'s first `n` described states, and the JSON record of every
/// episode.
pub fn described_seeds(
    config: &Config,
    preset: Preset,
    policy: &Path,
    seed: Option<u64>,
    n: usize,
) -> Result<(Vec<SeedSummary>, serde_json::Value)> {
    let mut summaries = Vec::new();
    let mut seeds = Vec::new();
    for (net, sidecar) in select_policies(policy, seed, config)? {
        let episodes = described(config, &net, preset, n, config.train.threads)?;
        summaries.push(SeedSummary::of(sidecar.seed, &episodes));
        seeds.push(serde_json::json!({"policy_seed": sidecar.seed, "episodes": episodes}));
    }
    let record = serde_json::json!({
        "preset": preset.number(),
        "description": preset.description(),
        "paper_outcome": preset.paper_outcome(),
        "policy": policy,
        "states": preset.described_states(n),
        "summaries": summaries,
        "seeds": seeds,
    });
    Ok((summaries, record))
}

/// `scenario --states N`: the described states for each seed, as a table and a JSON record.
fn described_states(
    config: &Config,
    preset: Preset,
    policy: &Path,
    seed: Option<u64>,
    n: usize,
    out: &Path,
) -> Result<ExitCode> {
    let (summaries, record) = described_seeds(config, preset, policy, seed, n)?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let json = out.join(format!("preset{}_states.json", preset.number()));
    atomic::write(&json, serde_json::to_string_pretty(&record)?)
        .with_context(|| format!("writing {}", json.display()))?;
    print(&format!("{}\n{}", markdown(preset, &summaries), json.display()))?;
    Ok(ExitCode::SUCCESS)
}
