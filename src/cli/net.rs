//! `mpgdrive net inspect`: the command over [`mpgdrive::sumo::inspect`].

use crate::cli::common::{print, usage};
use anyhow::Result;
use clap::{Args, Subcommand};
use mpgdrive::sumo::build::{BuiltForm, MergeNetwork};
use mpgdrive::sumo::inspect::{find_merges, proposal, proposals};
use mpgdrive::sumo::positions::MergeForm;
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
        /// Write only merge number K with --out (1-based, in the order listed; default: every
        /// merge, as `[[merge]]` tables when there are several).
        #[arg(long)]
        merge: Option<usize>,
    },
    /// Build a merge network with netconvert from a few parameters (for trying the tool, tests
    /// and network families): merge.net.xml, its plain XML, merge.rou.xml (from/to flows, the
    /// ramp's vehicles of the controllable type "ctrl"), merge.sumocfg and the merge.toml that
    /// `net inspect` proposes.
    Build(BuildArgs),
}

/// Arguments of `mpgdrive net build`.
#[derive(Args)]
struct BuildArgs {
    /// The merge form.
    #[arg(long, value_enum, default_value_t = BuiltForm::Junction)]
    form: BuiltForm,
    /// Freeway lanes after the merge.
    #[arg(long, default_value_t = 1)]
    lanes: u32,
    /// Freeway speed limit (m/s).
    #[arg(long, default_value_t = 30.0)]
    speed: f64,
    /// Ramp speed limit (m/s).
    #[arg(long, default_value_t = 20.0)]
    ramp_speed: f64,
    /// Acceleration lane length (m; --form acceleration).
    #[arg(long, default_value_t = 150.0)]
    accel_lane: f64,
    /// Freeway length before the merge (m).
    #[arg(long, default_value_t = 500.0)]
    upstream: f64,
    /// A curved ramp instead of a straight one.
    #[arg(long)]
    curved: bool,
    /// A traffic light where the ramp joins (--form junction; the two roads take turns).
    #[arg(long)]
    signal: bool,
    /// Demand per freeway lane (veh/h).
    #[arg(long, default_value_t = 500.0)]
    lane_flow: f64,
    /// Ramp demand (veh/h).
    #[arg(long, default_value_t = 400.0)]
    ramp_flow: f64,
    /// Demand duration (s).
    #[arg(long, default_value_t = 600.0)]
    duration: f64,
    /// On-ramps along the freeway (a corridor; a lane drop has one).
    #[arg(long, default_value_t = 1)]
    ramps: u32,
    /// Freeway between one merge's end and the next ramp (m).
    #[arg(long, default_value_t = 600.0)]
    spacing: f64,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
}

/// Runs `mpgdrive net build`.
fn build(args: BuildArgs) -> Result<ExitCode> {
    let network = MergeNetwork {
        form: args.form,
        lanes: args.lanes,
        speed: args.speed,
        ramp_speed: args.ramp_speed,
        accel_lane: args.accel_lane,
        upstream: args.upstream,
        curved: args.curved,
        signal: args.signal,
        lane_flow: args.lane_flow,
        ramp_flow: args.ramp_flow,
        duration: args.duration,
        ramps: args.ramps,
        spacing: args.spacing,
    };
    network.validate().map_err(|e| usage(e.to_string()))?;
    let files = network.build(&args.out)?;
    let merges = find_merges(&files.net)?;
    if merges.len() != network.ramps as usize {
        anyhow::bail!(
            "{}: net inspect finds {} merge(s) in the built network, not {}",
            files.net.display(),
            merges.len(),
            network.ramps
        );
    }
    let path = args.out.join("merge.toml");
    mpgdrive::atomic::write(&path, proposals(&merges, &files.net))
        .map_err(|e| anyhow::anyhow!("writing {}: {e}", path.display()))?;
    eprintln!("net: built {} with {}", files.sumocfg.display(), path.display());
    Ok(ExitCode::SUCCESS)
}

/// Runs `mpgdrive net ...`.
pub fn run(args: NetArgs) -> Result<ExitCode> {
    let (net, out, merge) = match args.command {
        NetCommand::Inspect { net, out, merge } => (net, out, merge),
        NetCommand::Build(args) => return build(args),
    };
    let merges = find_merges(&net)?;
    if merges.is_empty() {
        return Err(usage(format!(
            "{}: no lane ends beside a lane that goes on, and none yields at a junction into a lane that another lane leads into (no merge found)",
            net.display()
        )));
    }
    if let Some(k) = merge.filter(|k| !(1..=merges.len()).contains(k)) {
        return Err(usage(format!(
            "--merge {k}: the network has {} merge(s)",
            merges.len()
        )));
    }
    match out {
        Some(path) => {
            let (text, which) = match merge {
                Some(k) => (
                    proposal(&merges[k - 1], &net),
                    format!("merge {k} of {}", merges.len()),
                ),
                None => (proposals(&merges, &net), format!("{} merge(s)", merges.len())),
            };
            mpgdrive::atomic::write(&path, text)
                .map_err(|e| anyhow::anyhow!("writing {}: {e}", path.display()))?;
            eprintln!("net: {which} written to {}", path.display());
        }
        None => {
            for (k, m) in merges.iter().enumerate() {
                print(&format!(
                    "# Merge {} of {}: `{}` ends at position {:.1} m (along the lanes) {} `{}`\n{}",
                    k + 1,
                    merges.len(),
                    m.ramp_lanes.last().map_or("", String::as_str),
                    m.lane_end,
                    match m.form {
                        MergeForm::AccelerationLane => "beside",
                        MergeForm::Junction => "at a junction, leading into",
                    },
                    m.target_lane,
                    proposal(m, &net)
                ))?;
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}
