//! `mpgdrive train`: every requested seed in one stacked training.

use crate::cli::common::{outln, progress_bar};
use anyhow::{Context, Result};
use clap::Args;
use mpgdrive::config::Config;
use mpgdrive::train::{Mode, TrainError, TrainOutcome, TrainRun, train_all};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// Arguments of `mpgdrive train`.
#[derive(Args)]
pub struct TrainArgs {
    /// Configuration file (TOML).
    #[arg(long, default_value = "configs/paper.toml")]
    config: PathBuf,
    /// What to learn: mpg (shared policy, potential) or sarl (ego only, IDM players).
    #[arg(long, value_enum, default_value_t = Mode::Mpg)]
    mode: Mode,
    /// Seeds, comma-separated (default: the configuration's eval.seeds).
    #[arg(long, value_delimiter = ',')]
    seeds: Option<Vec<u64>>,
    /// Output directory: one seedK.safetensors / seedK.json / seedK.curves.csv per seed.
    #[arg(long)]
    out: PathBuf,
    /// Continue from the checkpoints in the output directory.
    #[arg(long)]
    resume: bool,
}

/// Runs `mpgdrive train`.
pub fn run(args: TrainArgs) -> Result<ExitCode> {
    let config = Config::load(&crate::cli::bundled::resolve(&args.config)?)?;
    let seeds = args.seeds.clone().unwrap_or_else(|| config.eval.seeds.clone());
    let command = std::env::args().collect::<Vec<_>>().join(" ");
    // Ctrl-C: finish the current epoch, write a checkpoint, exit 130.
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst))
        .context("installing the Ctrl-C handler")?;
    let runs: Vec<TrainRun> = seeds
        .iter()
        .map(|&seed| TrainRun {
            mode: args.mode,
            seed,
            out: args.out.join(format!("seed{seed}")),
            resume: args.resume,
            command: command.clone(),
        })
        .collect();
    if args.resume {
        warn_missing_checkpoints(&runs);
    }
    let bar = progress_bar(
        config.train.epochs as u64,
        "{prefix} {bar:30} epoch {pos}/{len} {msg} ETA {eta}",
    )?;
    let listed: Vec<String> = seeds.iter().map(u64::to_string).collect();
    bar.set_prefix(format!("{} seeds {}", args.mode.as_str(), listed.join(",")));
    let t = &config.train;
    if t.init_candidates > 1 && !args.resume {
        bar.set_message(format!(
            "screening {} initialisations, {} epochs each",
            t.init_candidates, t.screen_epochs
        ));
    }
    // Every seed (and every screening candidate) trains in one stacked computation.
    let result = train_all(&config, &runs, &stop, &mut |k, r| {
        if k + 1 == runs.len() {
            bar.set_message(format!("objective {:.1}", r.probe_objective));
            bar.set_position(r.epoch as u64);
        }
    });
    bar.finish_and_clear();
    let outcomes = match result {
        Err(e @ TrainError::Interrupted { .. }) => {
            eprintln!("{e}");
            return Ok(ExitCode::from(130));
        }
        other => other?,
    };
    print_outcomes(&runs, &outcomes)?;
    Ok(ExitCode::SUCCESS)
}

/// Says which seeds have no checkpoint to resume from (they train from the start), and which
/// resume from an older checkpoint or without the optimiser state.
fn warn_missing_checkpoints(runs: &[TrainRun]) {
    use mpgdrive::train::checkpoint::{checkpoint_path, latest, moments_path};
    for run in runs {
        let current = checkpoint_path(&run.out);
        let Some(ckpt) = latest(&run.out) else {
            eprintln!(
                "seed {}: no checkpoint {}.json to resume; it trains from the start",
                run.seed,
                current.display()
            );
            continue;
        };
        if ckpt != current {
            eprintln!(
                "seed {}: the write of checkpoint {}.json was cut short; it resumes from the one before, {}.json",
                run.seed,
                current.display(),
                ckpt.display()
            );
        }
        if !moments_path(&ckpt).exists() {
            eprintln!(
                "seed {}: checkpoint {}.json has no optimiser state (an older checkpoint); Adam's moments restart",
                run.seed,
                ckpt.display()
            );
        }
    }
}

fn print_outcomes(runs: &[TrainRun], outcomes: &[TrainOutcome]) -> Result<()> {
    for (run, outcome) in runs.iter().zip(outcomes) {
        if let Some(r) = outcome.records.last() {
            outln!(
                "{} seed {}: {} epochs in {:.1} s, probe objective {:.2}, probe collisions {:.3}, failures {:.3} -> {}",
                run.mode.as_str(),
                run.seed,
                r.epoch,
                r.wall_seconds,
                r.probe_objective,
                r.probe_collision_rate,
                r.probe_failure_rate,
                run.out.display()
            );
        }
        if let Some(s) = &outcome.screening {
            outln!(
                "  initialisation {} kept (probe objectives after {} epochs: {:?})",
                s.chosen,
                s.screen_epochs,
                s.probe_objectives
            );
        }
    }
    Ok(())
}
