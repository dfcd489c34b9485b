//! `mpgdrive check-mpg`: Definition 3 checked numerically.

use crate::cli::common::{Common, outln, progress_bar, usage};
use anyhow::{Context, Result};
use clap::Args;
use mpgdrive::eval::mpg_check::{CheckReport, CheckSettings, check_mpg, evaluations};
use mpgdrive::game::PaperReward;
use std::process::ExitCode;

/// Arguments of `mpgdrive check-mpg`.
#[derive(Args)]
pub struct CheckMpgArgs {
    #[command(flatten)]
    common: Common,
    /// Theorem setting (f64): feasibility projection and collision termination off; the entry
    /// rule's decisions replayed from the base run for every player but the deviating one.
    #[arg(long)]
    exact: bool,
    /// Random joint policies K.
    #[arg(long, default_value_t = 4)]
    policies: usize,
    /// Initial states M.
    #[arg(long, default_value_t = 16)]
    states: usize,
    /// Relative gap above which the game is flagged as not an MPG.
    #[arg(long, default_value_t = 1e-9)]
    tolerance: f64,
    /// Print JSON.
    #[arg(long)]
    json: bool,
}

/// Runs `mpgdrive check-mpg`.
pub fn run(args: CheckMpgArgs) -> Result<ExitCode> {
    let common = args.common.settings()?;
    let config = &common.config;
    if args.policies == 0 || args.states == 0 {
        return Err(usage("--policies and --states must be at least 1"));
    }
    if !(args.tolerance.is_finite() && args.tolerance >= 0.0) {
        return Err(usage(format!(
            "--tolerance {} must be a finite non-negative number",
            args.tolerance
        )));
    }
    let settings = CheckSettings {
        policies: args.policies,
        states: args.states,
        seed: common.seed,
        exact: args.exact,
        tolerance: args.tolerance,
        threads: common.threads,
    };
    let bar = progress_bar(
        evaluations(config, &settings) as u64,
        "check-mpg {bar:30} {pos}/{len} rollouts, ETA {eta}",
    )?;
    let report = check_mpg(config, &settings, &PaperReward::new(config), &mut || bar.inc(1));
    bar.finish_and_clear();
    if args.json {
        outln!(
            "{}",
            serde_json::to_string_pretty(&report).context("serialising the report")?
        );
    } else {
        print_table(&report)?;
    }
    // In the Theorem setting a gap is a failed check; otherwise it is a finding.
    Ok(if args.exact && !report.is_potential_game {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}

fn print_table(report: &CheckReport) -> Result<()> {
    outln!(
        "check-mpg ({} setting: feasibility {}, collision termination {}), K = {}, M = {}, seed {}",
        report.setting,
        report.feasibility,
        report.terminate_on_collision,
        report.policies,
        report.states,
        report.seed
    );
    outln!("| player | max rel. gap | max abs. gap | min abs. Delta J |\n|---|---|---|---|");
    for p in &report.players {
        outln!(
            "| {} | {:.3e} | {:.3e} | {:.3e} |",
            p.label,
            p.max_relative_gap,
            p.max_absolute_gap,
            p.min_abs_delta_j
        );
    }
    outln!(
        "largest relative gap {:.3e}: {}",
        report.max_relative_gap,
        if report.is_potential_game {
            "within tolerance, an MPG".to_string()
        } else {
            format!("above {:.1e}", report.tolerance)
        }
    );
    Ok(())
}
