//! `mpgdrive routes`, `mpgdrive batch` and `mpgdrive merge`: the commands over
//! [`mpgdrive::batch`].

use anyhow::{Context, Result};
use clap::Args;
use mpgdrive::batch::routes::{DemandSpec, generate};
use mpgdrive::batch::runner::{BatchEnd, BatchSettings, combos, run_batch};
use mpgdrive::batch::summary::merge;
use mpgdrive::sumo::MergeGeometry;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `mpgdrive routes`.
#[derive(Args)]
pub struct RoutesArgs {
    /// Base route file: vehicle types, routes and the flows to scale.
    #[arg(long, default_value = "sumo_nets/i80_merge/i80.rou.xml")]
    base: PathBuf,
    /// Merge geometry of the network (default: merge.toml beside the base file).
    #[arg(long)]
    merge: Option<PathBuf>,
    /// Demand scales: a list (0.8,1.0,1.2) or a range FROM:TO:STEP (0.6:1.3:0.1).
    #[arg(long, default_value = "1.0")]
    scales: String,
    /// Share of all vehicles from the ramp (default: the base file's).
    #[arg(long)]
    ramp_share: Option<f64>,
    /// Shares of ramp vehicles that are controllable, comma-separated (default: the base
    /// file's); several shares give one file each (`_c<share>` in the name).
    #[arg(long, value_delimiter = ',')]
    controllable_share: Vec<f64>,
    /// Seeds of the arrivals, one route file per seed and scale.
    #[arg(long, value_delimiter = ',', default_value = "0")]
    seeds: Vec<u64>,
    /// Departures over this many seconds.
    #[arg(long, default_value_t = 900.0)]
    duration: f64,
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
}

/// Arguments of `mpgdrive batch`.
#[derive(Args)]
pub struct BatchArgs {
    /// Configuration file (TOML) passed to every run.
    #[arg(long, default_value = "configs/paper.toml")]
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
    /// MARL policy (file or directory of seeds).
    #[arg(long, default_value = "policies/mpg")]
    policy: PathBuf,
    /// Single-agent policy (file or directory of seeds).
    #[arg(long, default_value = "policies/sarl")]
    sarl_policy: PathBuf,
    /// Merge geometry (default: merge.toml beside the .sumocfg).
    #[arg(long)]
    merge: Option<PathBuf>,
    /// SUMO seeds, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0")]
    seeds: Vec<u64>,
    /// Simulated duration of each run (s).
    #[arg(long, default_value_t = 900.0)]
    end: f64,
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

fn parse_scales(text: &str) -> Result<Vec<f64>> {
    let bad = || {
        crate::usage(format!(
            "--scales {text}: a list like 0.8,1.0 or a range FROM:TO:STEP"
        ))
    };
    if let [from, to, step] = text.split(':').collect::<Vec<_>>()[..] {
        let (from, to, step): (f64, f64, f64) = (
            from.parse().map_err(|_| bad())?,
            to.parse().map_err(|_| bad())?,
            step.parse().map_err(|_| bad())?,
        );
        if !(step > 0.0 && to >= from) {
            return Err(bad());
        }
        let n = ((to - from) / step + 1e-9).floor() as usize;
        return Ok((0..=n)
            .map(|i| ((from + i as f64 * step) * 1e6).round() / 1e6)
            .collect());
    }
    text.split(',')
        .map(|s| s.trim().parse().map_err(|_| bad()))
        .collect()
}

pub fn routes(args: RoutesArgs) -> Result<ExitCode> {
    if !args.base.is_file() {
        return Err(crate::usage(format!(
            "--base {}: no such route file",
            args.base.display()
        )));
    }
    let merge = args
        .merge
        .clone()
        .unwrap_or_else(|| args.base.with_file_name("merge.toml"));
    let geometry = MergeGeometry::load(&merge)?;
    let spec = DemandSpec {
        scales: parse_scales(&args.scales)?,
        ramp_share: args.ramp_share,
        controllable_shares: args.controllable_share,
        seeds: args.seeds,
        duration: args.duration,
    };
    let manifest = generate(&args.base, &geometry, &spec, &args.out)?;
    for m in &manifest {
        crate::print(&format!(
            "{} (scale {}{}, seed {}): {} vehicles",
            m.file,
            m.scale,
            m.controllable_share
                .map_or(String::new(), |c| format!(", controllable share {c}")),
            m.seed,
            m.vehicles
        ))?;
    }
    Ok(ExitCode::SUCCESS)
}

pub fn batch(args: BatchArgs) -> Result<ExitCode> {
    for c in &args.controllers {
        if !["mpg", "sarl", "sumo"].contains(&c.as_str()) {
            return Err(crate::usage(format!(
                "--controllers: unknown controller `{c}` (mpg, sarl, sumo)"
            )));
        }
    }
    let shard = match &args.shard {
        None => (1, 1),
        Some(s) => {
            let parsed = s
                .split_once('/')
                .and_then(|(k, n)| Some((k.parse::<usize>().ok()?, n.parse::<usize>().ok()?)));
            match parsed {
                Some((k, n)) if n >= 1 && (1..=n).contains(&k) => (k, n),
                _ => {
                    return Err(crate::usage(format!(
                        "--shard {s}: expected K/N with 1 <= K <= N"
                    )));
                }
            }
        }
    };
    let routes: Vec<PathBuf> = glob::glob(&args.routes)
        .map_err(|e| crate::usage(format!("--routes {}: {e}", args.routes)))?
        .filter_map(Result::ok)
        .collect();
    if routes.is_empty() {
        return Err(crate::usage(format!("--routes {}: no file matches", args.routes)));
    }
    if !args.sumocfg.is_file() {
        return Err(crate::usage(format!(
            "--sumocfg {}: no such file",
            args.sumocfg.display()
        )));
    }
    // What every worker would refuse is refused here, before any run: the configuration, the
    // controllers, the SUMO configuration and the geometry against its network, the policies.
    let config = mpgdrive::config::Config::load(&args.config)?;
    if let Some(bad) = args
        .controllers
        .iter()
        .find(|c| !["mpg", "sarl", "sumo"].contains(&c.as_str()))
    {
        return Err(crate::usage(format!(
            "--controllers: unknown controller `{bad}` (mpg, sarl, sumo)"
        )));
    }
    if !(args.end.is_finite() && args.end > 0.0) {
        return Err(crate::usage(format!(
            "--end {}: must be a positive number of seconds",
            args.end
        )));
    }
    let files = mpgdrive::sumo::inputs::config_files(&args.sumocfg)?;
    let merge = args
        .merge
        .clone()
        .unwrap_or_else(|| args.sumocfg.with_file_name("merge.toml"));
    let geometry = MergeGeometry::load(&merge)?;
    mpgdrive::sumo::inputs::check_geometry(&geometry, &merge, &files.net)?;
    for (name, policy) in [("mpg", &args.policy), ("sarl", &args.sarl_policy)] {
        if args.controllers.iter().any(|c| c == name) {
            crate::pick_policy(policy, None, &config)?;
        }
    }
    let abs = |p: &PathBuf| std::fs::canonicalize(p).with_context(|| format!("{}", p.display()));
    let mut common = vec![
        "cosim".to_string(),
        "--config".into(),
        abs(&args.config)?.display().to_string(),
        "--sumocfg".into(),
        abs(&args.sumocfg)?.display().to_string(),
        "--policy".into(),
        abs(&args.policy)?.display().to_string(),
        "--sarl-policy".into(),
        abs(&args.sarl_policy)?.display().to_string(),
        "--end".into(),
        args.end.to_string(),
    ];
    if let Some(m) = &args.merge {
        common.extend(["--merge".into(), abs(m)?.display().to_string()]);
    }
    let routes = routes.iter().map(abs).collect::<Result<Vec<_>>>()?;
    let todo = combos(&routes, &args.controllers, &args.seeds, shard);
    let jobs = match args.jobs {
        Some(0) => return Err(crate::usage("--jobs must be at least 1")),
        Some(n) => n,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    let settings = BatchSettings {
        exe: std::env::current_exe().context("locating the mpgdrive binary")?,
        common_args: common,
        out: args.out.clone(),
        jobs,
        resume: args.resume,
        timeout: args.timeout.map(std::time::Duration::from_secs_f64),
    };
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc::set_handler(move || flag.store(true, std::sync::atomic::Ordering::SeqCst))
        .context("installing the Ctrl-C handler")?;
    let bar = indicatif::ProgressBar::new(todo.len() as u64).with_style(
        indicatif::ProgressStyle::with_template("batch {bar:30} {pos}/{len} runs {msg} ETA {eta}")
            .context("progress bar template")?,
    );
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
    match end {
        BatchEnd::Stopped => {
            eprintln!(
                "batch stopped: finished runs are in {}; rerun with --resume",
                args.out.display()
            );
            Ok(ExitCode::from(130))
        }
        BatchEnd::Done { failed } => {
            let wall = started.elapsed().as_secs_f64();
            eprintln!(
                "batch: {} runs in {wall:.1} s with {jobs} jobs: {:.0} simulated vehicle-seconds per wall second",
                todo.len(),
                vehicle_seconds / wall
            );
            crate::print(
                &std::fs::read_to_string(args.out.join("summary.md")).context("reading summary.md")?,
            )?;
            if failed > 0 {
                eprintln!(
                    "{failed} runs failed: see {}",
                    args.out.join("summary.md").display()
                );
                Ok(ExitCode::from(1))
            } else {
                Ok(ExitCode::SUCCESS)
            }
        }
    }
}

pub fn merge_dirs(args: MergeArgs) -> Result<ExitCode> {
    let results = merge(&args.dirs, &args.out).map_err(crate::usage)?;
    crate::print(&std::fs::read_to_string(args.out.join("summary.md")).context("reading summary.md")?)?;
    let failed = results.iter().filter(|r| r.status != "ok").count();
    Ok(if failed > 0 {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}
