//! `mpgdrive net inspect`: the command over [`mpgdrive::sumo::inspect`].

use crate::cli::common::{print, usage};
use anyhow::Result;
use clap::{Args, Subcommand};
use mpgdrive::sumo::inspect::{find_merges, proposal};
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `mpgdrive net`.
#[derive(Args)]
pub struct NetArgs {
    #[command(subcommand)]
    command: NetCommand,
}

#[derive(Subcommand)]
enum NetCommand {
    /// List the lanes of a network that end in a merge and propose a commented merge.toml for
    /// each (ramp lanes, target lanes, conflict point at the end of the acceleration lane).
    Inspect {
        /// The network (.net.xml).
        net: PathBuf,
        /// Write the proposal of merge number K (see the list) to this file instead of printing.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Which merge to write with --out (1-based, in the order listed).
        #[arg(long, default_value_t = 1)]
        merge: usize,
    },
}

/// Runs `mpgdrive net ...`.
pub fn run(args: NetArgs) -> Result<ExitCode> {
    let NetCommand::Inspect { net, out, merge } = args.command;
    let merges = find_merges(&net)?;
    if merges.is_empty() {
        return Err(usage(format!(
            "{}: no lane ends beside a lane that goes on (no merge found)",
            net.display()
        )));
    }
    if !(1..=merges.len()).contains(&merge) {
        return Err(usage(format!(
            "--merge {merge}: the network has {} merge(s)",
            merges.len()
        )));
    }
    match out {
        Some(path) => {
            mpgdrive::atomic::write(&path, proposal(&merges[merge - 1], &net))
                .map_err(|e| anyhow::anyhow!("writing {}: {e}", path.display()))?;
            eprintln!(
                "net: merge {merge} of {} written to {}",
                merges.len(),
                path.display()
            );
        }
        None => {
            for (k, m) in merges.iter().enumerate() {
                print(&format!(
                    "# Merge {} of {}: `{}` ends at position {:.1} m (along the lanes) beside `{}`\n{}",
                    k + 1,
                    merges.len(),
                    m.ramp_lanes.last().map_or("", String::as_str),
                    m.lane_end,
                    m.target_lane,
                    proposal(m, &net)
                ))?;
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}
