//! `mpgdrive batch`: every (route file, controller, seed) as its own cosim worker.

use crate::cli::common::{PolicyPair, SeedChoice, deployed_policy, print, progress_bar, usage};
use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use mpgdrive::batch::runner::{BatchEnd, BatchSettings, combos, run_batch};
use mpgdrive::config::Config;
use mpgdrive::policy::Mode;
use mpgdrive::sumo::{ControllerKind, MergeGeometry};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// Arguments of `mpgdrive batch`.
#[derive(Args)]
pub struct BatchArgs {
    /// Configuration file (TOML) passed to every run (as cosim's).
    #[arg(long, default_value = "configs/traffic.toml")]
    config: PathBuf,
    /// Base SUMO configuration (its route files are replaced by each run's).
    #[arg(long)]
    sumocfg: PathBuf,
    /// Route files: a glob pattern (quote it), for example 'routes/*.rou.xml'.
    #[arg(long)]
    routes: String,
    /// Controllers, comma-separated: mpg, sarl, sumo.
    #[arg(long, value_delimiter = ',', default_value = "mpg,sarl,sumo")]
    controllers: Vec<String>,
    #[command(flatten)]
    policies: PolicyPair,
    #[command(flatten)]
    deploy: SeedChoice,
    /// Merge geometry (default: merge.toml beside the .sumocfg).
    #[arg(long)]
    merge: Option<PathBuf>,
    /// SUMO seeds, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0")]
    seeds: Vec<u64>,
    /// Simulated duration of each run (s).
    #[arg(long, default_value_t = 900.0)]
    end: f64,
    /// The merge gate as a shield in every run (`cosim --gate`): true or false (the learned
    /// policy alone); default as cosim's.
    #[arg(long, action = clap::ArgAction::Set)]
    gate: Option<bool>,
    /// Worker processes at a time (default: the number of cores).
    #[arg(long)]
    jobs: Option<usize>,
    /// Output directory: runs/, logs/, work/, summary.csv, summary.md.
    #[arg(long)]
    out: PathBuf,
    /// Skip runs whose result is already in --out (failed runs run again).
    #[arg(long)]
    resume: bool,
    /// Run only shard K of N (1-based), a deterministic 1/N of the combinations.
    #[arg(long, value_name = "K/N")]
    shard: Option<String>,
    /// Kill a run after this many seconds.
    #[arg(long)]
    timeout: Option<f64>,
}

/// Runs `mpgdrive batch`.
pub fn run(args: BatchArgs) -> Result<ExitCode> {
    let kinds = parse_controllers(&args.controllers)?;
    let shard = parse_shard(args.shard.as_deref())?;
    let routes = find_routes(&args.routes)?;
    let config = check_inputs(&args, &kinds)?;
    let routes = routes.iter().map(|r| absolute(r)).collect::<Result<Vec<_>>>()?;
    let todo = combos(&routes, &args.controllers, &args.seeds, shard);
    let jobs = match args.jobs {
        Some(0) => return Err(usage("--jobs must be at least 1")),
        Some(n) => n,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    let settings = BatchSettings {
        exe: std::env::current_exe().context("locating the mpgdrive binary")?,
        common_args: worker_args(&args, &config)?,
        out: args.out.clone(),
        jobs,
        resume: args.resume,
        timeout: args.timeout.map(std::time::Duration::from_secs_f64),
    };
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst))
        .context("installing the Ctrl-C handler")?;
    let bar = progress_bar(
        todo.len() as u64,
        "batch {bar:30} {pos}/{len} runs {msg} ETA {eta}",
    )?;
    let mut failed_now = 0;
    let mut vehicle_seconds = 0.0;
    let started = std::time::Instant::now();
    let end = run_batch(&settings, &todo, &stop, &mut |r| {
        failed_now += usize::from(r.status != "ok");
        vehicle_seconds += r.metrics.as_ref().map_or(0.0, |m| m.vehicle_seconds);
        bar.set_message(format!("({failed_now} failed)"));
        bar.inc(1);
    })
    .with_context(|| format!("batch in {}", args.out.display()))?;
    bar.finish_and_clear();
    let failed = match end {
        BatchEnd::Stopped => {
            eprintln!(
                "batch stopped: finished runs are in {}; rerun with --resume",
                args.out.display()
            );
            return Ok(ExitCode::from(130));
        }
        BatchEnd::Done { failed } => failed,
    };
    let wall = started.elapsed().as_secs_f64();
    eprintln!(
        "batch: {} runs in {wall:.1} s with {jobs} jobs: {:.0} simulated vehicle-seconds per wall second",
        todo.len(),
        vehicle_seconds / wall
    );
    let summary = args.out.join("summary.md");
    print(&std::fs::read_to_string(&summary).context("reading summary.md")?)?;
    if failed > 0 {
        eprintln!("{failed} runs failed: see {}", summary.display());
        Ok(ExitCode::from(1))
    } else {
        Ok(ExitCode::SUCCESS)
    }
}

/// `--controllers`, one line for an unknown name (as every other bad input gets).
fn parse_controllers(names: &[String]) -> Result<Vec<ControllerKind>> {
    names
        .iter()
        .map(|c| {
            ControllerKind::from_str(c, false).map_err(|_| {
                usage(format!(
                    "--controllers: unknown controller `{c}` (mpg, sarl, sumo)"
                ))
            })
        })
        .collect()
}

/// `--shard K/N` (1-based); the whole batch when not given.
fn parse_shard(shard: Option<&str>) -> Result<(usize, usize)> {
    let Some(s) = shard else {
        return Ok((1, 1));
    };
    let parsed = s
        .split_once('/')
        .and_then(|(k, n)| Some((k.parse::<usize>().ok()?, n.parse::<usize>().ok()?)));
    match parsed {
        Some((k, n)) if n >= 1 && (1..=n).contains(&k) => Ok((k, n)),
        _ => Err(usage(format!("--shard {s}: expected K/N with 1 <= K <= N"))),
    }
}

/// The route files `--routes` matches (at least one).
fn find_routes(pattern: &str) -> Result<Vec<PathBuf>> {
    let routes: Vec<PathBuf> = glob::glob(pattern)
        .map_err(|e| usage(format!("--routes {pattern}: {e}")))?
        .filter_map(Result::ok)
        .collect();
    if routes.is_empty() {
        return Err(usage(format!("--routes {pattern}: no file matches")));
    }
    Ok(routes)
}

/// What every worker would refuse is refused here, before any run: the SUMO configuration, the
/// configuration, the duration, the geometry against its network, the policies. A route file
/// a worker's cosim refuses is a failed run, recorded with its message.
fn check_inputs(args: &BatchArgs, kinds: &[ControllerKind]) -> Result<Config> {
    let config = check_run(&args.sumocfg, &args.config, args.end)?;
    let files = mpgdrive::sumo::inputs::config_files(&args.sumocfg)?;
    let merge = args
        .merge
        .clone()
        .unwrap_or_else(|| args.sumocfg.with_file_name("merge.toml"));
    for geometry in MergeGeometry::load_all(&merge)? {
        mpgdrive::sumo::inputs::check_geometry(&geometry, &merge, &files.net)?;
    }
    for mode in kinds.iter().filter_map(|k| k.mode()) {
        deployed_policy(&args.policies.of(mode, &config)?, &args.deploy, &config)?;
    }
    Ok(config)
}

/// What every worker's run needs: the SUMO configuration exists, the configuration loads, the
/// duration is a positive number of seconds. Returns the configuration.
pub(crate) fn check_run(sumocfg: &Path, config: &Path, end: f64) -> Result<Config> {
    if !sumocfg.is_file() {
        return Err(usage(format!("--sumocfg {}: no such file", sumocfg.display())));
    }
    let config = Config::load(&crate::cli::bundled::resolve(config)?)?;
    if !(end.is_finite() && end > 0.0) {
        return Err(usage(format!(
            "--end {end}: must be a positive number of seconds"
        )));
    }
    Ok(config)
}

/// `path` made absolute (the workers run in their own directories).
pub(crate) fn absolute(path: &Path) -> Result<PathBuf> {
    std::fs::canonicalize(path).with_context(|| format!("{}", path.display()))
}

/// The `mpgdrive cosim` arguments every worker of a batch shares (absolute paths): the
/// configuration, the SUMO configuration, the policies (`--policy` or `--sarl-policy` with a
/// path), the duration and how a directory's seeds deploy.
pub(crate) fn cosim_args(
    config: &Path,
    sumocfg: &Path,
    policies: &[(&str, PathBuf)],
    deploy: &SeedChoice,
    end: f64,
) -> Result<Vec<String>> {
    let abs = |p: &Path| -> Result<String> { Ok(absolute(p)?.display().to_string()) };
    let mut common = vec![
        "cosim".to_string(),
        "--config".into(),
        abs(&crate::cli::bundled::resolve(config)?)?,
        "--sumocfg".into(),
        abs(sumocfg)?,
    ];
    for (flag, path) in policies {
        common.extend([flag.to_string(), abs(path)?]);
    }
    common.extend(["--end".into(), end.to_string()]);
    if let Some(seed) = deploy.policy_seed {
        common.extend(["--policy-seed".into(), seed.to_string()]);
    }
    common.extend(["--ensemble".into(), deploy.ensemble.name().into()]);
    Ok(common)
}

/// The `mpgdrive cosim` arguments every worker shares.
fn worker_args(args: &BatchArgs, config: &Config) -> Result<Vec<String>> {
    let policies = [
        ("--policy", args.policies.of(Mode::Mpg, config)?),
        ("--sarl-policy", args.policies.of(Mode::Sarl, config)?),
    ];
    let mut common = cosim_args(&args.config, &args.sumocfg, &policies, &args.deploy, args.end)?;
    if let Some(gate) = args.gate {
        common.extend(["--gate".into(), gate.to_string()]);
    }
    if let Some(m) = &args.merge {
        common.extend(["--merge".into(), absolute(m)?.display().to_string()]);
    }
    Ok(common)
}
