//! `mpgdrive ngsim prepare|eval|synth`: the commands over [`mpgdrive::ngsim`].

use crate::cli::common::{PolicyPair, print, usage};
use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use mpgdrive::atomic;
use mpgdrive::config::Config;
use mpgdrive::ngsim::config::NgsimConfig;
use mpgdrive::ngsim::load::load;
use mpgdrive::ngsim::process::{Prepared, prepare};
use mpgdrive::ngsim::replay::study;
use mpgdrive::ngsim::scenario::{MergeScenario, extract};
use mpgdrive::ngsim::synth::{Layout, generate};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `mpgdrive ngsim`.
#[derive(Args)]
pub struct NgsimArgs {
    #[command(subcommand)]
    command: NgsimCommand,
}

#[derive(Args)]
struct Input {
    /// An NGSIM trajectory file: FHWA text (trajectories-0400-0415.txt) or the
    /// data.transportation.gov CSV.
    #[arg(long)]
    input: PathBuf,
    /// NGSIM settings: location, smoothing, lanes, merge scenarios.
    #[arg(long, default_value = "configs/ngsim.toml")]
    ngsim: PathBuf,
}

#[derive(Subcommand)]
enum NgsimCommand {
    /// Load, smooth, recompute speed and acceleration, reassign lanes; write
    /// trajectories.csv and summary.json.
    Prepare(PrepareArgs),
    /// Extract the merge scenarios and replay them with the human, single-agent and MARL egos
    /// (Table IV): table4.md, table4.json, episodes.csv, scenarios.csv.
    Eval(EvalArgs),
    /// Write a synthetic NGSIM file (internal-simulator merges with measurement noise) in an
    /// official layout, for trying the pipeline and for benchmarks.
    Synth(SynthArgs),
}

#[derive(Args)]
struct PrepareArgs {
    #[command(flatten)]
    input: Input,
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
}

#[derive(Args)]
struct EvalArgs {
    #[command(flatten)]
    input: Input,
    /// Paper configuration (vehicle limits, dt, horizon, feasibility rules).
    #[arg(long, default_value = "configs/paper.toml")]
    config: PathBuf,
    #[command(flatten)]
    policies: PolicyPair,
    /// Output directory.
    #[arg(long, default_value = "results/ngsim")]
    out: PathBuf,
    /// Print JSON instead of Markdown.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct SynthArgs {
    /// Paper configuration.
    #[arg(long, default_value = "configs/paper.toml")]
    config: PathBuf,
    /// NGSIM settings (lanes, conflict point).
    #[arg(long, default_value = "configs/ngsim.toml")]
    ngsim: PathBuf,
    /// Merge episodes (each 30 s: the ego, 8 players, 5 background vehicles).
    #[arg(long, default_value_t = 20)]
    episodes: usize,
    /// Seed of the initial states and the noise.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Standard deviation of the position noise (m).
    #[arg(long, default_value_t = 0.3)]
    noise: f64,
    /// text (FHWA) or csv (data.transportation.gov).
    #[arg(long, value_enum, default_value_t = Layout::Text)]
    layout: Layout,
    /// Output file.
    #[arg(long)]
    out: PathBuf,
}

fn load_prepared(input: &Input) -> Result<(NgsimConfig, Prepared)> {
    let ngsim = NgsimConfig::load(&crate::cli::bundled::resolve(&input.ngsim)?)?;
    let data = load(&input.input, &ngsim.location)?;
    let prepared = prepare(&data, &ngsim)?;
    for w in &prepared.summary.warnings {
        eprintln!("warning: {}: {w}", input.input.display());
    }
    Ok((ngsim, prepared))
}

fn write(dir: &Path, name: &str, text: impl AsRef<[u8]>) -> Result<()> {
    let path = dir.join(name);
    atomic::write(&path, text).with_context(|| format!("writing {}", path.display()))
}

/// Runs `mpgdrive ngsim ...`.
pub fn run(args: NgsimArgs) -> Result<ExitCode> {
    match args.command {
        NgsimCommand::Prepare(args) => prepare_cmd(args)?,
        NgsimCommand::Eval(args) => eval(args)?,
        NgsimCommand::Synth(args) => synth(args)?,
    }
    Ok(ExitCode::SUCCESS)
}

fn prepare_cmd(args: PrepareArgs) -> Result<()> {
    let (input, out) = (&args.input, &args.out);
    let t0 = Instant::now();
    let (_, prepared) = load_prepared(input)?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    write(out, "trajectories.csv", prepared.csv())?;
    let summary = serde_json::to_string_pretty(&prepared.summary)?;
    write(out, "summary.json", &summary)?;
    print(&summary)?;
    eprintln!(
        "prepared {} in {:.1} s: {}",
        input.input.display(),
        t0.elapsed().as_secs_f64(),
        out.display()
    );
    Ok(())
}

fn eval(args: EvalArgs) -> Result<()> {
    let config = Config::load(&crate::cli::bundled::resolve(&args.config)?)?;
    let [mut mpg, mut sarl] = args.policies.load(&config)?;
    let (ngsim, prepared) = load_prepared(&args.input)?;
    let s = &config.scenario;
    let extraction = extract(&prepared, &ngsim, s.n_leaders, s.n_followers);
    let result = study(
        &config,
        &ngsim,
        &prepared,
        &extraction.scenarios,
        &mut sarl,
        &mut mpg,
    );
    let out = &args.out;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let counts = format!(
        "{} scenarios replayed of {} available ({} merging vehicles seen past the start or already merged, {} whose record ends before it; {} vehicles, {} rows, {} skipped)",
        extraction.scenarios.len(),
        extraction.available,
        extraction.late,
        extraction.short,
        prepared.summary.vehicles,
        prepared.summary.rows,
        prepared.summary.rows_skipped
    );
    let table = if extraction.scenarios.is_empty() {
        format!(
            "No merge scenario: no vehicle enters on the on-ramp (lane {}) and ends in lane {} ({} ramp vehicles).\n",
            ngsim.lanes.ramp_lane(),
            ngsim.lanes.target_lane(),
            prepared.summary.ramp_vehicles
        )
    } else {
        result.markdown()
    };
    let markdown = format!(
        "Comparative results on the naturalistic dataset ({})\n\n{table}\n{counts}\n",
        args.input.input.display()
    );
    let report = serde_json::json!({
        "input": args.input.input,
        "policy_seeds": {
            "mpg": mpg.iter().map(|(_, s)| s.seed).collect::<Vec<_>>(),
            "sarl": sarl.iter().map(|(_, s)| s.seed).collect::<Vec<_>>(),
        },
        "ngsim": ngsim,
        "prepare": prepared.summary,
        "extraction": extraction,
        "columns": result.columns,
    });
    let report = serde_json::to_string_pretty(&report)?;
    write(out, "table4.md", &markdown)?;
    write(out, "table4.json", &report)?;
    write(out, "episodes.csv", result.episodes_csv())?;
    write(
        out,
        "scenarios.csv",
        scenarios_csv(&prepared, &extraction.scenarios),
    )?;
    print(if args.json { &report } else { &markdown })?;
    eprintln!("results in {}", out.display());
    Ok(())
}

/// One row per replayed scenario: the ego's id, the start frame and the players' slots and ids.
fn scenarios_csv(prepared: &Prepared, scenarios: &[MergeScenario]) -> String {
    let mut csv = String::from("scenario,ego_id,start_frame,players\n");
    for (i, sc) in scenarios.iter().enumerate() {
        let players: Vec<String> = sc
            .players
            .iter()
            .map(|&(j, slot)| format!("{slot}:{}", prepared.tracks[j].id))
            .collect();
        csv.push_str(&format!(
            "{i},{},{},{}\n",
            prepared.tracks[sc.ego].id,
            sc.start_frame,
            players.join(" ")
        ));
    }
    csv
}

fn synth(args: SynthArgs) -> Result<()> {
    let config = Config::load(&crate::cli::bundled::resolve(&args.config)?)?;
    let ngsim = NgsimConfig::load(&crate::cli::bundled::resolve(&args.ngsim)?)?;
    let (noise, seed, out) = (args.noise, args.seed, &args.out);
    if !(noise.is_finite() && noise >= 0.0) {
        return Err(usage(format!(
            "--noise {noise}: must be a non-negative number of metres"
        )));
    }
    if args.episodes == 0 {
        return Err(usage("--episodes must be at least 1"));
    }
    let synthetic = generate(&config, &ngsim, args.episodes, seed, noise, args.layout);
    atomic::write(out, &synthetic.text).with_context(|| format!("writing {}", out.display()))?;
    eprintln!(
        "{}: {} merge episodes, {} vehicles, {} bytes (seed {seed}, noise {noise} m)",
        out.display(),
        synthetic.episodes.len(),
        synthetic.truth.len(),
        synthetic.text.len()
    );
    Ok(())
}
