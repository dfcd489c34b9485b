//! One file per command. Each turns its clap arguments into validated settings and calls the
//! library; [`common`] holds what several share.

mod batch;
mod bundled;
mod check_mpg;
mod common;
mod cosim;
mod demo;
mod eval;
mod merge;
mod net;
mod ngsim;
mod report;
mod routes;
mod scenario;
mod study;
mod train;

use anyhow::Result;
use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// The command line.
#[derive(Parser)]
#[command(
    name = "mpgdrive",
    version,
    about = "Game-theoretic forced-merge driving: a Markov potential game, trained and deployed in SUMO"
)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Co-simulate with SUMO: a trained policy drives the ramp egos (and, for mpg, their
    /// players) in SUMO traffic; compares the mpg, sarl and sumo controllers.
    Cosim(cosim::CosimArgs),
    /// Generate SUMO route files for a network from a demand description (scales, ramp share,
    /// controllable share, seeds), with a manifest.
    Routes(routes::RoutesArgs),
    /// Run every (route file, controller, seed) as its own cosim worker, N at a time; resumable,
    /// shardable (--shard K/N).
    Batch(batch::BatchArgs),
    /// Merge batch output directories (shards) into one summary.
    Merge(merge::MergeArgs),
    /// SUMO networks: `net inspect NET.net.xml` finds the merges and proposes a merge.toml.
    Net(net::NetArgs),
    /// NGSIM I-80: prepare (smooth, recompute, reassign lanes), eval (Table IV replay against
    /// the human drivers), synth (synthetic files in the official layouts).
    Ngsim(ngsim::NgsimArgs),
    /// Run one of the paper's specific scenarios with the shared policy and draw it: key
    /// moments (PNG), the episode (GIF), the ego's speed, acceleration and gap.
    Scenario(scenario::ScenarioArgs),
    /// Write a self-contained report folder (report.md, report.html): Tables II and III, the
    /// specific scenarios, training curves, and co-sim and NGSIM results when present.
    Report(report::ReportArgs),
    /// Simulate a batch of merge episodes with non-learning drivers and print the ego metrics.
    Demo(demo::DemoArgs),
    /// Train a policy per seed: the shared MPG policy (Algorithm 1) or the single-agent baseline.
    Train(train::TrainArgs),
    /// The statistical study (Tables II and III): the ego on a policy (or one per seed) against
    /// NE, IDM and constant-speed surrounding players.
    Eval(eval::EvalArgs),
    /// The penetration study: the game against SUMO's drivers as the share of controllable
    /// vehicles grows (time loss of every vehicle, throughput, ego speed, conflicts).
    Study(study::StudyArgs),
    /// Check Definition 3 numerically: Delta J_i against Delta Phi for unilateral deviations.
    CheckMpg(check_mpg::CheckMpgArgs),
}

/// Runs the parsed command.
pub fn run(cli: Cli) -> Result<ExitCode> {
    // Every command runs the policy networks on small batches, from worker threads of its own
    // where it has several (rollout chunks, training shards): one libtorch thread each. With
    // libtorch's default pool inside each worker, `eval` spent a tenth of its time in OpenMP's
    // spin-waits (measured: 4.0 s against 3.4 s, the same tables).
    tch::set_num_threads(1);
    match cli.command {
        Command::Cosim(args) => cosim::run(args),
        Command::Routes(args) => routes::run(args),
        Command::Batch(args) => batch::run(args),
        Command::Merge(args) => merge::run(args),
        Command::Ngsim(args) => ngsim::run(args),
        Command::Net(args) => net::run(args),
        Command::Scenario(args) => scenario::run(args),
        Command::Report(args) => report::run(args),
        Command::Demo(args) => demo::run(args),
        Command::Train(args) => train::run(args),
        Command::Eval(args) => eval::run(args),
        Command::CheckMpg(args) => check_mpg::run(args),
        Command::Study(args) => study::run(args),
    }
}
