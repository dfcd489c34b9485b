//! `mpgdrive routes`: route files for a network from a demand description.

use crate::cli::common::{print, usage};
use anyhow::Result;
use clap::Args;
use mpgdrive::batch::routes::{DemandSpec, Streams, base_notes, generate};
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
    /// Share of freeway vehicles of the controllable type (a penetration rate: with
    /// `players = "controllable"` they play the game in `cosim`); default none.
    #[arg(long)]
    mainline_controllable_share: Option<f64>,
    /// Seeds of the arrivals, one route file per seed and scale.
    #[arg(long, value_delimiter = ',', default_value = "0")]
    seeds: Vec<u64>,
    /// Departures from this time (s) on: the begin time of the configuration that runs them
    /// (public scenarios start at the hour they model).
    #[arg(long, default_value_t = 0.0)]
    begin: f64,
    /// Departures over this many seconds (from --begin).
    #[arg(long, default_value_t = 900.0)]
    duration: f64,
    /// Which flows the files carry: all, or the ramp's or the freeway's alone (with the
    /// arrivals they have in the file of all flows; `_ramp` or `_freeway` in the name).
    #[arg(long, value_enum, default_value = "all")]
    streams: StreamChoice,
    /// Files SUMO loads with the route files (a configuration's additional files),
    /// comma-separated: their vehicle types and routes count as the base file's and are not
    /// written again.
    #[arg(long, value_delimiter = ',')]
    additional: Vec<PathBuf>,
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
}

/// `--streams`.
#[derive(Clone, Copy, clap::ValueEnum)]
enum StreamChoice {
    All,
    Ramp,
    Freeway,
}

impl From<StreamChoice> for Streams {
    fn from(c: StreamChoice) -> Streams {
        match c {
            StreamChoice::All => Streams::All,
            StreamChoice::Ramp => Streams::Ramp,
            StreamChoice::Freeway => Streams::Freeway,
        }
    }
}

fn parse_scales(text: &str) -> Result<Vec<f64>> {
    let bad = || {
        usage(format!(
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

/// Runs `mpgdrive routes`.
pub fn run(args: RoutesArgs) -> Result<ExitCode> {
    if !args.base.is_file() {
        return Err(usage(format!(
            "--base {}: no such route file",
            args.base.display()
        )));
    }
    let merge = args
        .merge
        .clone()
        .unwrap_or_else(|| args.base.with_file_name("merge.toml"));
    let merges = MergeGeometry::load_all(&merge)?;
    let spec = DemandSpec {
        scales: parse_scales(&args.scales)?,
        ramp_share: args.ramp_share,
        controllable_shares: args.controllable_share,
        mainline_share: args.mainline_controllable_share,
        seeds: args.seeds,
        begin: args.begin,
        duration: args.duration,
        streams: args.streams.into(),
        loaded: args.additional.clone(),
    };
    let manifest = generate(&args.base, &merges, &spec, &args.out)?;
    for note in base_notes(&args.base, &manifest) {
        eprintln!("routes: {note}");
    }
    for m in &manifest {
        print(&format!(
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
