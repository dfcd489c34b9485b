//! `mpgdrive scenario`: the paper's specific scenarios, run with the shared policy and drawn.

use crate::cli::common::{pick_policy, print};
use anyhow::{Context, Result};
use clap::Args;
use mpgdrive::atomic;
use mpgdrive::config::Config;
use mpgdrive::engine::rollout::Recording;
use mpgdrive::eval::EpisodeMetrics;
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
    let (files, summary) = scenario(
        &config,
        preset,
        &crate::cli::bundled::resolve(&args.policy)?,
        args.policy_seed,
        &args.out,
    )?;
    let mut text = summary;
    for f in files {
        text += &format!("\n  {}", f.display());
    }
    print(&text)?;
    Ok(ExitCode::SUCCESS)
}
