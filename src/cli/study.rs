//! `mpgdrive study`: the penetration study ([`mpgdrive::batch::penetration`]). For each share
//! of controllable vehicles, route files (`routes` with that share on the ramp and on the
//! freeway) run as a batch of `cosim` workers, the game and SUMO's drivers alone on the same
//! routes for every seed; SUMO's drivers on each seed's ramp and freeway flows apart (the
//! merge's own cost); then the table, the CSV and the plot.

use crate::cli::batch::{absolute, check_run, cosim_args};
use crate::cli::common::{PolicyPair, SeedChoice, deployed_policy, print, usage};
use anyhow::{Context, Result};
use clap::Args;
use mpgdrive::atomic;
use mpgdrive::batch::capacity::{self, SweepRun};
use mpgdrive::batch::penetration::{self, Conflicts, Spread, StudyRun, Trips};
use mpgdrive::batch::routes::{
    DemandSpec, ManifestEntry, Streams, base_notes, combined_route_files, flows_by_stream, generate,
};
use mpgdrive::batch::runner::{BatchEnd, BatchSettings, Combo, run_batch};
use mpgdrive::config::Config;
use mpgdrive::policy::Mode;
use mpgdrive::sumo::MergeGeometry;
use mpgdrive::sumo::geometry::PlayerControl;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// Arguments of `mpgdrive study`.
#[derive(Args)]
pub struct StudyArgs {
    /// Configuration file (TOML) passed to every run (as cosim's).
    #[arg(long, default_value = "configs/traffic.toml")]
    config: PathBuf,
    /// SUMO configuration of the network; its route files, taken together, are the base demand.
    #[arg(long, default_value = "sumo_nets/i80_merge/i80.sumocfg")]
    sumocfg: PathBuf,
    /// Merge geometry (default: merge.toml beside the .sumocfg). The study sets its `players`
    /// to "controllable": the controllable vehicles play the game.
    #[arg(long)]
    merge: Option<PathBuf>,
    #[command(flatten)]
    policies: PolicyPair,
    #[command(flatten)]
    deploy: SeedChoice,
    /// Shares of controllable vehicles among all vehicles (ramp and freeway alike),
    /// comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0,0.1,0.3,0.5,1")]
    shares: Vec<f64>,
    /// Demand: a multiple of the base route file's flows (default 1.2; with --capacity, 1.2
    /// times the demand at which the merge breaks down, when it does).
    #[arg(long)]
    demand: Option<f64>,
    /// Before the study, the merge's capacity: SUMO's drivers alone at these demands
    /// (multiples of the base route file, comma-separated), the outflow against the inflow and
    /// the demand at which the merge breaks down (capacity/ in --out, a table in study.md).
    #[arg(long, value_delimiter = ',')]
    capacity: Vec<f64>,
    /// Seeds, comma-separated: each gives its own arrivals and SUMO's random seed.
    #[arg(long, value_delimiter = ',', default_value = "0,1,2")]
    seeds: Vec<u64>,
    /// Simulated duration of each run (s), from the configuration's begin; departures span it.
    #[arg(long, default_value_t = 900.0)]
    end: f64,
    /// Worker processes at a time (default: the number of cores).
    #[arg(long)]
    jobs: Option<usize>,
    /// Output directory: study.md, study.csv, study.png, merge.toml, one batch folder per
    /// share (share_<percent>/: routes, runs, SUMO's outputs) and apart/ (SUMO's drivers on the
    /// ramp's and the freeway's flows alone: the merge's own cost).
    #[arg(long)]
    out: PathBuf,
    /// Skip runs whose result is already in --out.
    #[arg(long)]
    resume: bool,
}

/// The controllers of every run: the game, and SUMO's drivers alone.
const CONTROLLERS: [&str; 2] = ["mpg", "sumo"];

/// The study's demand without --demand (a multiple of the base route file).
const DEFAULT_DEMAND: f64 = 1.2;

/// With --capacity and without --demand, the study runs at this multiple of the demand at
/// which the merge breaks down (issue 59: the outflow each controller keeps beyond it).
const STUDY_OVER_BREAKDOWN: f64 = 1.2;

/// Runs `mpgdrive study`.
pub fn run(args: StudyArgs) -> Result<ExitCode> {
    let config = check_inputs(&args)?;
    let merge_path = args
        .merge
        .clone()
        .unwrap_or_else(|| args.sumocfg.with_file_name("merge.toml"));
    let mut merges = MergeGeometry::load_all(&merge_path)?;
    let files = mpgdrive::sumo::inputs::config_files(&args.sumocfg)?;
    if let Some(scale) = files
        .scale
        .as_ref()
        .filter(|s| s.trim().parse::<f64>() != Ok(1.0))
    {
        return Err(usage(format!(
            "--sumocfg {} sets scale {scale}: SUMO would scale the study's route files again; \
             remove it and give the demand with --demand (or --capacity)",
            args.sumocfg.display()
        )));
    }
    for geometry in &merges {
        mpgdrive::sumo::inputs::check_geometry(geometry, &merge_path, &files.net)?;
    }
    let mut base = files.routes.first().cloned().ok_or_else(|| {
        usage(format!(
            "--sumocfg {}: names no route file",
            args.sumocfg.display()
        ))
    })?;
    std::fs::create_dir_all(&args.out).with_context(|| format!("{}", args.out.display()))?;
    // Several route files (vehicle types in one, flows in another) are one demand: the base is
    // all of them, in --out.
    if files.routes.len() > 1 {
        base = args.out.join("base.rou.xml");
        atomic::write(&base, combined_route_files(&files.routes)?)
            .with_context(|| format!("{}", base.display()))?;
    }
    for g in &mut merges {
        g.players = PlayerControl::Controllable;
    }
    let merge = args.out.join("merge.toml");
    atomic::write(&merge, merge_toml(&merges)?).with_context(|| format!("{}", merge.display()))?;
    let controllable: Vec<String> = merges.iter().flat_map(|g| g.controllable_types.clone()).collect();
    let settings = |out: PathBuf| -> Result<BatchSettings> {
        Ok(BatchSettings {
            exe: std::env::current_exe().context("locating the mpgdrive binary")?,
            common_args: worker_args(&args, &config, &merge)?,
            out,
            jobs: args
                .jobs
                .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get())),
            resume: args.resume,
            timeout: None,
        })
    };
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst))
        .context("installing the Ctrl-C handler")?;
    // Every batch of runs of one demand, share and streams: the route files, then the runs.
    let noted = std::cell::Cell::new(false);
    let batch = |dir: &Path,
                 demand: f64,
                 share: f64,
                 controllers: &[&str],
                 streams: Streams|
     -> Result<Option<Vec<(ManifestEntry, Combo)>>> {
        let spec = DemandSpec {
            scales: vec![demand],
            ramp_share: None,
            controllable_shares: vec![share],
            mainline_share: Some(share),
            seeds: args.seeds.clone(),
            begin: files.begin,
            duration: args.end,
            streams,
            loaded: files.additional.clone(),
        };
        let manifest = generate(&base, &merges, &spec, &dir.join("routes"))?;
        if !noted.replace(true) {
            for note in base_notes(&base, &manifest) {
                eprintln!("study: {note}");
            }
        }
        let mut todo = Vec::new();
        for m in &manifest {
            let route = absolute(&dir.join("routes").join(&m.file))?;
            todo.extend(controllers.iter().map(|&c| {
                let combo = Combo {
                    route: route.clone(),
                    controller: c.into(),
                    seed: m.seed,
                };
                (m.clone(), combo)
            }));
        }
        eprintln!(
            "study: demand {demand}, controllable share {:.0}%, {} flows: {} runs",
            share * 100.0,
            streams.name(),
            todo.len()
        );
        let combos: Vec<Combo> = todo.iter().map(|(_, c)| c.clone()).collect();
        match run_batch(&settings(dir.to_path_buf())?, &combos, &stop, &mut |_| {})? {
            BatchEnd::Stopped => {
                eprintln!(
                    "study stopped: finished runs are in {}; rerun with --resume",
                    args.out.display()
                );
                Ok(None)
            }
            BatchEnd::Done { failed: 0 } => Ok(Some(todo)),
            BatchEnd::Done { failed } => Err(usage(format!(
                "{failed} runs failed: see {}",
                dir.join("summary.md").display()
            ))),
        }
    };
    let read = |dir: &Path, share: f64, combo: &Combo| {
        read_run(
            &dir.join("work").join(combo.key()),
            combo,
            share,
            args.end,
            &controllable,
        )
    };
    let mut capacity_md = String::new();
    let mut demand = args.demand.unwrap_or(DEFAULT_DEMAND);
    if !args.capacity.is_empty() {
        let mut sweep = Vec::new();
        for &d in &args.capacity {
            let dir = args.out.join("capacity").join(format!("demand_{d}"));
            let Some(done) = batch(&dir, d, 0.0, &["sumo"], Streams::All)? else {
                return Ok(ExitCode::from(130));
            };
            for (m, combo) in &done {
                sweep.push(SweepRun {
                    demand: d,
                    scheduled: m.vehicles,
                    run: read(&dir, 0.0, combo)?,
                });
            }
        }
        let points = capacity::points(&sweep);
        let found = capacity::capacity(&points);
        if let (None, Some(breakdown)) = (args.demand, found.breakdown) {
            // Rounded to 1e-6 (1.2 x 3.3 is 3.9599999999999995 in f64).
            demand = (STUDY_OVER_BREAKDOWN * breakdown * 1e6).round() / 1e6;
        }
        capacity_md = format!(
            "## The merge's capacity: SUMO's drivers alone\n\n{}\n## The game by share, at demand {demand}\n\n",
            capacity::markdown(&points, &found)
        );
    }
    let mut runs = Vec::new();
    for &share in &args.shares {
        let dir = args.out.join(share_folder(share));
        let Some(done) = batch(&dir, demand, share, &CONTROLLERS, Streams::All)? else {
            return Ok(ExitCode::from(130));
        };
        for (_, combo) in &done {
            runs.push(read(&dir, share, combo)?);
        }
    }
    // The merge's own cost: each seed's ramp and freeway flows in runs of their own, when the
    // base file has both (a ramp flow drives along a ramp of merge.toml).
    let (ramp_flows, freeway_flows) = flows_by_stream(&base, &files.additional, &merges)?;
    let both = ramp_flows > 0 && freeway_flows > 0;
    let mut alone: Vec<(u64, Trips)> = Vec::new();
    for streams in [Streams::Ramp, Streams::Freeway].into_iter().filter(|_| both) {
        let dir = args.out.join("apart").join(streams.name());
        let Some(done) = batch(&dir, demand, 0.0, &["sumo"], streams)? else {
            return Ok(ExitCode::from(130));
        };
        for (_, combo) in &done {
            alone.push((combo.seed, read(&dir, 0.0, combo)?.trips));
        }
    }
    let per_seed: Vec<f64> = args
        .seeds
        .iter()
        .filter_map(|seed| {
            let mut of_seed = alone.iter().filter(|(s, _)| s == seed).map(|(_, t)| t);
            penetration::apart(of_seed.next()?, of_seed.next()?)
        })
        .collect();
    let apart = (!per_seed.is_empty()).then(|| Spread::of(&per_seed));
    let rows = penetration::rows(&runs);
    let command = std::env::args().collect::<Vec<_>>().join(" ");
    let title = format!(
        "Command: `{command}`\n\n`{}`, demand {} x the base route file, seeds {}, {} s runs; \
         the controllable vehicles play the game (mpg policy), the others are SUMO's drivers. \
         Mean ± sample standard deviation over seeds.\n\n",
        args.sumocfg.display(),
        demand,
        args.seeds
            .iter()
            .map(u64::to_string)
            .collect::<Vec<_>>()
            .join(", "),
        args.end
    );
    let mut md = title + &capacity_md + &penetration::markdown(&rows, apart);
    if !both {
        md += &format!(
            "\nThe merge's own cost is not measured: {} has {ramp_flows} flows that drive along a \
             ramp of merge.toml and {freeway_flows} that do not (it runs the two apart).\n",
            base.display()
        );
    }
    atomic::write(&args.out.join("study.md"), &md).context("writing study.md")?;
    atomic::write(&args.out.join("study.csv"), penetration::csv(&rows, apart))
        .context("writing study.csv")?;
    penetration::plot(&rows, apart, &args.out.join("study.png"))?;
    print(&md)?;
    Ok(ExitCode::SUCCESS)
}

/// One run's figures from its worker folder: SUMO's tripinfo and SSM files, and the worker's
/// JSON (ego speed, collisions with a controlled vehicle).
fn read_run(work: &Path, combo: &Combo, share: f64, end: f64, controllable: &[String]) -> Result<StudyRun> {
    let c = &combo.controller;
    let trips = Trips::read(&work.join(format!("tripinfo-{c}.xml")), controllable)?;
    let conflicts = Conflicts::read(&work.join(format!("ssm-{c}.xml")))?;
    let json = work.join("stdout.json");
    let text = std::fs::read_to_string(&json).with_context(|| format!("{}", json.display()))?;
    let value: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("{}", json.display()))?;
    let r = &value[0];
    let egos = r["summary"]["episodes"].as_u64().unwrap_or(0);
    let controlled_collisions = r["collisions"]
        .as_array()
        .map_or(0, |c| c.iter().filter(|e| e["controlled"] == true).count());
    Ok(StudyRun {
        share,
        seed: combo.seed,
        game: c == "mpg",
        duration: end,
        trips,
        conflicts,
        ego_speed: (egos > 0).then(|| r["summary"]["mean_speed"].as_f64()).flatten(),
        controlled_collisions,
    })
}

/// The merge geometries as a merge.toml (one table, or `[[merge]]` tables for several).
fn merge_toml(merges: &[MergeGeometry]) -> Result<String> {
    #[derive(serde::Serialize)]
    struct List<'a> {
        merge: &'a [MergeGeometry],
    }
    Ok(match merges {
        [one] => toml::to_string(one)?,
        all => toml::to_string(&List { merge: all })?,
    })
}

/// What a worker would refuse is refused here, before any run.
fn check_inputs(args: &StudyArgs) -> Result<Config> {
    let config = check_run(&args.sumocfg, &args.config, args.end)?;
    for (flag, d) in
        (args.demand.iter().map(|d| ("--demand", d))).chain(args.capacity.iter().map(|d| ("--capacity", d)))
    {
        if !(d.is_finite() && *d > 0.0) {
            return Err(usage(format!("{flag} {d}: must be a positive number")));
        }
    }
    if let Some((k, d)) = (args.capacity.iter().enumerate()).find(|(k, d)| args.capacity[..*k].contains(d)) {
        return Err(usage(format!("--capacity: demand {d} is given twice (at {k})")));
    }
    if args.capacity.len() == 1 {
        return Err(usage(
            "--capacity needs at least two demands (a breakdown is a rise that stops)",
        ));
    }
    if let Some(s) = args.shares.iter().find(|s| !(0.0..=1.0).contains(*s)) {
        return Err(usage(format!("--shares: {s} is not a share between 0 and 1")));
    }
    if args.shares.is_empty() || args.seeds.is_empty() {
        return Err(usage("--shares and --seeds need at least one value each"));
    }
    for (k, a) in args.shares.iter().enumerate() {
        if let Some(b) = args.shares[..k]
            .iter()
            .find(|b| share_folder(**b) == share_folder(*a))
        {
            return Err(usage(format!(
                "--shares: {b} and {a} would share the folder {} (give shares at least 0.1% apart)",
                share_folder(*a)
            )));
        }
    }
    if args.jobs == Some(0) {
        return Err(usage("--jobs must be at least 1"));
    }
    deployed_policy(&args.policies.of(Mode::Mpg, &config)?, &args.deploy, &config)?;
    Ok(config)
}

/// The folder of a share's runs, in per cent to 0.1: `share_030.0` for 0.3.
fn share_folder(share: f64) -> String {
    format!("share_{:05.1}", share * 100.0)
}

/// The `mpgdrive cosim` arguments every worker shares: the game's policy, the study's merge.toml,
/// SUMO's SSM device on every vehicle.
fn worker_args(args: &StudyArgs, config: &Config, merge: &Path) -> Result<Vec<String>> {
    let policy = [("--policy", args.policies.of(Mode::Mpg, config)?)];
    let mut common = cosim_args(&args.config, &args.sumocfg, &policy, &args.deploy, args.end)?;
    common.extend([
        "--merge".into(),
        absolute(merge)?.display().to_string(),
        "--no-diagrams".into(),
        "--ssm-all".into(),
    ]);
    Ok(common)
}
