//! `mpgdrive eval`: the statistical study (Tables II and III).

use crate::cli::common::{Common, outln};
use anyhow::{Context, Result};
use clap::Args;
use mpgdrive::eval::study::{Rules, Surrounding, evaluate, load_policies};
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
    let start = Instant::now();
    let study = evaluate(config, &policies, &ne_policies, &args.surrounding, common.threads)?;
    let wall = start.elapsed().as_secs_f64();
    if let Some(path) = args.episodes {
        mpgdrive::atomic::write(&path, study.episodes_csv())
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    if args.json {
        outln!(
            "{}",
            serde_json::to_string_pretty(&study).context("serialising the study")?
        );
    } else {
        outln!("{}", study.markdown());
        outln!(
            "({} policies x {} kinds x {} scenarios in {wall:.2} s)",
            policies.len(),
            args.surrounding.len(),
            config.eval.test_scenarios
        );
    }
    Ok(ExitCode::SUCCESS)
}
