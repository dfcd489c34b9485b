//! The `mpgdrive` command line: parses arguments, builds a validated configuration, calls the
//! library and maps errors to one message and an exit code (2 for bad input, 1 otherwise).

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use mpgdrive::config::Config;
use mpgdrive::eval::study::{Rules, Surrounding, evaluate, load_policies};
use mpgdrive::eval::{EpisodeMetrics, Summary};
use mpgdrive::game::PaperReward;
use mpgdrive::game::mpg_check::{CheckSettings, check_mpg, evaluations};
use mpgdrive::sim::Driver;
use mpgdrive::sim::rollout::{DriverActor, RolloutOptions, rollout};
use mpgdrive::sim::sampler::sample_scenes;
use mpgdrive::train::{Mode, TrainError, TrainRun, train_all};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

#[derive(Parser)]
#[command(
    name = "mpgdrive",
    version,
    about = "Game-theoretic forced-merge driving: a Markov potential game, trained and deployed in SUMO"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Args)]
struct Common {
    /// Configuration file (TOML).
    #[arg(long, default_value = "configs/paper.toml")]
    config: PathBuf,
    /// Seed of the initial states (default: the configuration's `seed`).
    #[arg(long)]
    seed: Option<u64>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

/// The two trained policies a comparison needs.
#[derive(Args)]
struct PolicyPair {
    /// MARL policy: a file or a directory of one per seed.
    #[arg(long, default_value = "policies/mpg")]
    policy: PathBuf,
    /// Single-agent policy: a file or a directory of one per seed.
    #[arg(long, default_value = "policies/sarl")]
    sarl_policy: PathBuf,
}

mod batch_cmd;
mod cosim_cmd;
mod net_cmd;
mod ngsim_cmd;
mod report_cmd;

#[derive(Subcommand)]
enum Command {
    /// Co-simulate with SUMO: a trained policy drives the ramp egos (and, for mpg, their
    /// players) in SUMO traffic; compares the mpg, sarl and sumo controllers.
    Cosim(cosim_cmd::CosimArgs),
    /// Generate SUMO route files for a network from a demand description (scales, ramp share,
    /// controllable share, seeds), with a manifest.
    Routes(batch_cmd::RoutesArgs),
    /// Run every (route file, controller, seed) as its own cosim worker, N at a time; resumable,
    /// shardable (--shard K/N).
    Batch(batch_cmd::BatchArgs),
    /// Merge batch output directories (shards) into one summary.
    Merge(batch_cmd::MergeArgs),
    /// SUMO networks: `net inspect NET.net.xml` finds the merges and proposes a merge.toml.
    Net(net_cmd::NetArgs),
    /// NGSIM I-80: prepare (smooth, recompute, reassign lanes), eval (Table IV replay against
    /// the human drivers), synth (synthetic files in the official layouts).
    Ngsim(ngsim_cmd::NgsimArgs),
    /// Run one of the paper's specific scenarios with the shared policy and draw it: key
    /// moments (PNG), the episode (GIF), the ego's speed, acceleration and gap.
    Scenario(report_cmd::ScenarioArgs),
    /// Write a self-contained report folder (report.md, report.html): Tables II and III, the
    /// specific scenarios, training curves, and co-sim and NGSIM results when present.
    Report(report_cmd::ReportArgs),
    /// Simulate a batch of merge episodes with non-learning drivers and print the ego metrics.
    Demo {
        #[command(flatten)]
        common: Common,
        /// Number of scenarios per setting.
        #[arg(long, default_value_t = 100)]
        scenarios: usize,
        /// Print JSON instead of Markdown.
        #[arg(long)]
        json: bool,
    },
    /// Train a policy per seed: the shared MPG policy (Algorithm 1) or the single-agent baseline.
    Train {
        /// Configuration file (TOML).
        #[arg(long, default_value = "configs/paper.toml")]
        config: PathBuf,
        /// What to learn: mpg (shared policy, potential) or sarl (ego only, IDM players).
        #[arg(long, value_enum, default_value_t = ModeArg::Mpg)]
        mode: ModeArg,
        /// Seeds, comma-separated (default: the configuration's eval.seeds).
        #[arg(long, value_delimiter = ',')]
        seeds: Option<Vec<u64>>,
        /// Output directory: one seedK.safetensors / seedK.json / seedK.curves.csv per seed.
        #[arg(long)]
        out: PathBuf,
        /// Continue from the checkpoints in the output directory.
        #[arg(long)]
        resume: bool,
    },
    /// The statistical study (Tables II and III): the ego on a policy (or one per seed) against
    /// NE, IDM and constant-speed surrounding players.
    Eval {
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
        surrounding: Vec<SurroundingArg>,
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
    },
    /// Check Definition 3 numerically: Delta J_i against Delta Phi for unilateral deviations.
    CheckMpg {
        #[command(flatten)]
        common: Common,
        /// Theorem setting: feasibility projection and collision termination off (f64).
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
    },
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum SurroundingArg {
    Ne,
    Idm,
    Const,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum ModeArg {
    Mpg,
    Sarl,
}

/// `println!` that ends the process quietly when stdout is closed (for example `| head`)
/// instead of panicking on the broken pipe.
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        if let Err(e) = writeln!(std::io::stdout().lock(), $($arg)*) {
            if e.kind() == std::io::ErrorKind::BrokenPipe {
                std::process::exit(0);
            }
            return Err(anyhow::Error::new(e).context("writing to stdout"));
        }
    }};
}

/// An error in the user's input, not a failure of the tool (exit code 2).
fn usage(message: impl Into<String>) -> anyhow::Error {
    anyhow::Error::new(mpgdrive::exit::UsageError(message.into()))
}

/// Prints to stdout, ending quietly on a closed pipe.
fn print(text: &str) -> Result<()> {
    outln!("{text}");
    Ok(())
}

/// One policy from a file or a directory of seeds: `seed`, or else the lowest seed.
fn pick_policy(path: &Path, seed: Option<u64>, config: &Config) -> Result<mpgdrive::policy::PolicyNet> {
    let mut policies = load_policies(path, config, Rules::Same)?;
    policies.sort_by_key(|(_, side)| side.seed);
    let index = match seed {
        None => 0,
        Some(s) => policies
            .iter()
            .position(|(_, side)| side.seed == s)
            .ok_or_else(|| usage(format!("{}: no policy of seed {s}", path.display())))?,
    };
    Ok(policies.swap_remove(index).0)
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            // 2 when the input is what is wrong, 1 when the tool failed (src/exit.rs).
            ExitCode::from(mpgdrive::exit::exit_code(e.as_ref()))
        }
    }
}

fn load(common: &Common) -> Result<(Config, u64, usize)> {
    let config = Config::load(&common.config)?;
    let seed = common.seed.unwrap_or(config.seed);
    Ok((config, seed, threads(common.threads)?))
}

/// `--threads`: at least 1; all cores when not given.
fn threads(given: Option<usize>) -> Result<usize> {
    match given {
        Some(0) => Err(usage("--threads must be at least 1")),
        Some(t) => Ok(t),
        None => Ok(std::thread::available_parallelism().map_or(1, |n| n.get())),
    }
}

fn run(cli: Cli) -> Result<ExitCode> {
    match cli.command {
        Command::Cosim(args) => cosim_cmd::run(args),
        Command::Routes(args) => batch_cmd::routes(args),
        Command::Batch(args) => batch_cmd::batch(args),
        Command::Merge(args) => batch_cmd::merge_dirs(args),
        Command::Ngsim(args) => ngsim_cmd::run(args),
        Command::Net(args) => net_cmd::run(args),
        Command::Scenario(args) => report_cmd::run_scenario(args),
        Command::Report(args) => report_cmd::run_report(args),
        Command::Demo {
            common,
            scenarios,
            json,
        } => {
            let (config, seed, threads) = load(&common)?;
            if scenarios == 0 {
                return Err(usage("--scenarios must be at least 1"));
            }
            demo(&config, seed, threads, scenarios, json)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Train {
            config,
            mode,
            seeds,
            out,
            resume,
        } => {
            let config = Config::load(&config)?;
            let mode = match mode {
                ModeArg::Mpg => Mode::Mpg,
                ModeArg::Sarl => Mode::Sarl,
            };
            let seeds = seeds.unwrap_or_else(|| config.eval.seeds.clone());
            let command = std::env::args().collect::<Vec<_>>().join(" ");
            // Ctrl-C: finish the current epoch, write a checkpoint, exit 130.
            let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
            let flag = stop.clone();
            ctrlc::set_handler(move || flag.store(true, std::sync::atomic::Ordering::SeqCst))
                .context("installing the Ctrl-C handler")?;
            let runs: Vec<TrainRun> = seeds
                .iter()
                .map(|&seed| TrainRun {
                    mode,
                    seed,
                    out: out.join(format!("seed{seed}")),
                    resume,
                    command: command.clone(),
                })
                .collect();
            if resume {
                for run in &runs {
                    let ckpt = mpgdrive::train::checkpoint_path(&run.out);
                    if !mpgdrive::policy::file::paths(&ckpt).1.exists() {
                        eprintln!(
                            "seed {}: no checkpoint {}.json to resume; it trains from the start",
                            run.seed,
                            ckpt.display()
                        );
                    }
                }
            }
            let bar = indicatif::ProgressBar::new(config.train.epochs as u64).with_style(
                indicatif::ProgressStyle::with_template(
                    "{prefix} {bar:30} epoch {pos}/{len} {msg} ETA {eta}",
                )
                .context("progress bar template")?,
            );
            let listed: Vec<String> = seeds.iter().map(u64::to_string).collect();
            bar.set_prefix(format!("{} seeds {}", mode.name(), listed.join(",")));
            let t = &config.train;
            if t.init_candidates > 1 && !resume {
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
            for (run, outcome) in runs.iter().zip(&outcomes) {
                if let Some(r) = outcome.records.last() {
                    outln!(
                        "{} seed {}: {} epochs in {:.1} s, probe objective {:.2}, probe collisions {:.3}, failures {:.3} -> {}",
                        mode.name(),
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
            Ok(ExitCode::SUCCESS)
        }
        Command::Eval {
            common,
            policy,
            ne_policy,
            surrounding,
            episodes,
            json,
            allow_policy_mismatch,
        } => {
            let (config, _, threads) = load(&common)?;
            let rules = if allow_policy_mismatch {
                eprintln!("warning: --allow-policy-mismatch: the policies' world rules are not checked");
                Rules::Any
            } else {
                Rules::Same
            };
            let policies = load_policies(&policy, &config, rules)?;
            let ne_policies = match &ne_policy {
                Some(path) => load_policies(path, &config, rules)?,
                None => Vec::new(),
            };
            let kinds: Vec<_> = surrounding
                .iter()
                .map(|s| match s {
                    SurroundingArg::Ne => Surrounding::Ne,
                    SurroundingArg::Idm => Surrounding::Idm,
                    SurroundingArg::Const => Surrounding::Const,
                })
                .collect();
            let start = Instant::now();
            let study = evaluate(&config, &policies, &ne_policies, &kinds, threads)?;
            let wall = start.elapsed().as_secs_f64();
            if let Some(path) = episodes {
                mpgdrive::atomic::write(&path, study.episodes_csv())
                    .with_context(|| format!("cannot write {}", path.display()))?;
            }
            if json {
                outln!(
                    "{}",
                    serde_json::to_string_pretty(&study).context("serialising the study")?
                );
            } else {
                outln!("{}", study.markdown());
                outln!(
                    "({} policies x {} kinds x {} scenarios in {wall:.2} s)",
                    policies.len(),
                    kinds.len(),
                    config.eval.test_scenarios
                );
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::CheckMpg {
            common,
            exact,
            policies,
            states,
            tolerance,
            json,
        } => {
            let (config, seed, threads) = load(&common)?;
            if policies == 0 || states == 0 {
                return Err(usage("--policies and --states must be at least 1"));
            }
            if !(tolerance.is_finite() && tolerance >= 0.0) {
                return Err(usage(format!(
                    "--tolerance {tolerance} must be a finite non-negative number"
                )));
            }
            let settings = CheckSettings {
                policies,
                states,
                seed,
                exact,
                tolerance,
                threads,
            };
            // Drawn on stderr, and hidden when stderr is not a terminal.
            let bar = indicatif::ProgressBar::new(evaluations(&config, &settings) as u64).with_style(
                indicatif::ProgressStyle::with_template("check-mpg {bar:30} {pos}/{len} rollouts, ETA {eta}")
                    .context("progress bar template")?,
            );
            let report = check_mpg(&config, &settings, &PaperReward::new(&config), &mut || bar.inc(1));
            bar.finish_and_clear();
            if json {
                outln!(
                    "{}",
                    serde_json::to_string_pretty(&report).context("serialising the report")?
                );
            } else {
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
            }
            // In the Theorem setting a gap is a failed check; otherwise it is a finding.
            Ok(if exact && !report.is_potential_game {
                ExitCode::from(1)
            } else {
                ExitCode::SUCCESS
            })
        }
    }
}

fn demo(config: &Config, seed: u64, threads: usize, scenarios: usize, json: bool) -> Result<()> {
    let scenes = sample_scenes(config, seed, 0, scenarios);
    let mut opts = RolloutOptions::from_config(config);
    opts.threads = threads;
    let mut results = Vec::new();
    for (name, others) in [("IDM", Driver::Idm), ("Constant speed", Driver::ConstSpeed)] {
        let start = Instant::now();
        let outcomes = rollout(config, &opts, &scenes, || {
            DriverActor::new(config, Driver::Idm, others)
        });
        let wall = start.elapsed().as_secs_f64();
        let metrics: Vec<_> = outcomes.iter().map(EpisodeMetrics::of).collect();
        results.push((name, Summary::of(&metrics), wall));
    }
    if json {
        let v: Vec<_> = results
            .iter()
            .map(|(name, s, wall)| serde_json::json!({"surrounding": name, "summary": s, "wall_seconds": wall}))
            .collect();
        outln!(
            "{}",
            serde_json::to_string_pretty(
                &serde_json::json!({"seed": seed, "scenarios": scenarios, "ego": "IDM", "results": v})
            )?
        );
    } else {
        outln!(
            "mpgdrive demo: {scenarios} forced-merge scenarios (seed {seed}), ego driven by IDM behind its projected leader\n"
        );
        for (name, s, wall) in &results {
            outln!("{}", s.markdown(&format!("Surrounding players: {name}")));
            outln!(
                "({} episodes x {} steps in {:.3} s)\n",
                s.episodes,
                config.n_steps(),
                wall
            );
        }
    }
    Ok(())
}
