//! `mpgdrive merge`: batch shards into one summary.

use crate::cli::common::{print, usage};
use anyhow::{Context, Result};
use clap::Args;
use mpgdrive::batch::summary::merge;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `mpgdrive merge`.
#[derive(Args)]
pub struct MergeArgs {
    /// Batch output directories (shards).
    #[arg(required = true)]
    dirs: Vec<PathBuf>,
    /// Where to write the merged results and summary.
    #[arg(long)]
    out: PathBuf,
}

/// Runs `mpgdrive merge`.
pub fn run(args: MergeArgs) -> Result<ExitCode> {
    let results = merge(&args.dirs, &args.out).map_err(usage)?;
    print(&std::fs::read_to_string(args.out.join("summary.md")).context("reading summary.md")?)?;
    let failed = results.iter().filter(|r| r.status != "ok").count();
    Ok(if failed > 0 {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}
