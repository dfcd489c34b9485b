//! `mpgdrive eval`: the statistical study (Tables II and III), or with a merge-traffic
//! configuration the traffic study.

use crate::cli::common::{Common, outln, usage};
use anyhow::{Context, Result};
use clap::Args;
use mpgdrive::config::{Config, ScenarioKind};
use mpgdrive::eval::study::{Rules, Surrounding, evaluate, load_policies};
use mpgdrive::eval::traffic_study::traffic_study;
use mpgdrive::policy::PolicyNet;
use mpgdrive::policy::file::Sidecar;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `mpgdrive eval`.
#[derive(Args)]
pub struct EvalArgs {
    #[command(flatten)]
    common: Common,
    /// A policy (BASE, BASE.json or BASE.safetensors) or a directory of one per seed.
    #[arg(long)]
    policy: PathBuf,
    /// MPG policies (file or directory) driving the NE surrounding players when --policy is
    /// a single-agent (sarl) policy; matched by seed.
    #[arg(long)]
    ne_policy: Option<PathBuf>,
    /// Surrounding players, comma-separated: ne, idm, const.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "ne,idm,const")]
    surrounding: Vec<Surrounding>,
    /// Also write every episode's metrics to this CSV file.
    #[arg(long)]
    episodes: Option<PathBuf>,
    /// Print JSON instead of Markdown.
    #[arg(long)]
    json: bool,
    /// Evaluate policies trained under other world rules than --config's (dt, limits,
    /// geometry, feasibility and gate rules, desired speed), with a warning: an ablation.
    #[arg(long)]
    allow_policy_mismatch: bool,
}

/// Runs `mpgdrive eval`.
pub fn run(args: EvalArgs) -> Result<ExitCode> {
    let common = args.common.settings()?;
    let config = &common.config;
    let rules = if args.allow_policy_mismatch {
        eprintln!("warning: --allow-policy-mismatch: the policies' world rules are not checked");
        Rules::Any
    } else {
        Rules::Same
    };
    let policies = load_policies(&args.policy, config, rules)?;
    let ne_policies = match &args.ne_policy {
        Some(path) => load_policies(path, config, rules)?,
        None => Vec::new(),
    };
    let trained_otherwise = policies.iter().chain(&ne_policies).find_map(|(_, side)| {
        mpgdrive::policy::file::reward_difference(side, config).map(|d| (side.seed, d))
    });
    if let Some((seed, difference)) = trained_otherwise {
        eprintln!(
            "warning: the policy of seed {seed} was trained with {difference}: the returns and potentials reported are this run's reward"
        );
    }
    let start = Instant::now();
    if config.scenario.kind == ScenarioKind::Traffic {
        return traffic(&args, config, &policies, common.threads, start);
    }
    let study = evaluate(config, &policies, &ne_policies, &args.surrounding, common.threads)?;
    let wall = start.elapsed().as_secs_f64();
    if let Some(path) = args.episodes {
        mpgdrive::atomic::write(&path, study.episodes_csv())
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    let footer = format!(
        "({} policies x {} kinds x {} scenarios in {wall:.2} s)",
        policies.len(),
        args.surrounding.len(),
        config.eval.test_scenarios
    );
    print_study(args.json, &study, &study.markdown(), &footer)
}

/// Prints a study as JSON, or as Markdown with a footer line.
fn print_study(json: bool, study: &impl serde::Serialize, markdown: &str, footer: &str) -> Result<ExitCode> {
    if json {
        outln!(
            "{}",
            serde_json::to_string_pretty(study).context("serialising the study")?
        );
    } else {
        outln!("{markdown}");
        outln!("{footer}");
    }
    Ok(ExitCode::SUCCESS)
}

/// The traffic study (a merge-traffic configuration): every controlled vehicle, human-only and
/// mixed surroundings.
fn traffic(
    args: &EvalArgs,
    config: &Config,
    policies: &[(PolicyNet, Sidecar)],
    threads: usize,
    start: Instant,
) -> Result<ExitCode> {
    if args.episodes.is_some() || args.ne_policy.is_some() {
        return Err(usage(
            "--episodes and --ne-policy are for the paper's study, not merge traffic",
        ));
    }
    let study = traffic_study(config, policies, threads)?;
    let footer = format!(
        "({} policies x 2 kinds x {} scenarios in {:.2} s)",
        policies.len(),
        config.eval.test_scenarios,
        start.elapsed().as_secs_f64()
    );
    print_study(args.json, &study, &study.markdown(), &footer)
}
