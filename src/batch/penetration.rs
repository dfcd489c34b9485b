//! The penetration study (`mpgdrive study`): the game against SUMO's drivers as the share of
//! controllable vehicles grows.
//!
//! For each share `p` of all vehicles (ramp and freeway alike), route files of one demand and
//! seed with a share `p` of the controllable type run twice in SUMO: the controllable vehicles
//! playing the game (`cosim`'s mpg controller, `players = "controllable"`), and SUMO's drivers
//! alone on the same routes. Every vehicle counts, read from SUMO's own outputs: tripinfo
//! (written for the unfinished vehicles too) and the SSM device on every vehicle.
//!
//! - **time loss** of a vehicle: SUMO's `timeLoss` plus its `departDelay`, the wait to enter the
//!   network (a vehicle still waiting at the end counts its wait so far);
//! - **throughput**: vehicles that finished their trip, per hour of the run (every route of a
//!   merge network passes the merge);
//! - **conflicts** per vehicle-km: SUMO's SSM conflicts at the thresholds `cosim` sets (TTC < 3 s
//!   or DRAC > 3 m/s^2; not the collisions SSM infers, [`crate::sumo::ssm`]), and the severe
//!   ones (minimum TTC below [`SEVERE_TTC`]), over the distance every vehicle drove
//!   (`routeLength`).
//!
//! The merge's own cost: the same arrivals with the ramp's flows and the freeway's flows in
//! separate runs of SUMO's drivers, where the streams never meet ([`apart`]). Their time loss
//! is what every vehicle would lose if merging cost nothing; the difference to SUMO's drivers
//! with both streams is what the merge costs, and [`merge_cost_removed`] the part of it the
//! game saves.

use crate::batch::summary::mean_sd;
use crate::render::RenderError;
use crate::render::charts::{Panel, Series, panels_png};
use crate::sumo::ssm;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A conflict with a minimum TTC below this (s) is severe.
pub const SEVERE_TTC: f64 = 1.5;

/// Errors reading SUMO's outputs.
#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    /// A file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A file is not what SUMO writes.
    #[error("{path}: {message}")]
    Content {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

fn read(path: &Path) -> Result<String, StudyError> {
    std::fs::read_to_string(path).map_err(|source| StudyError::Io {
        path: path.to_path_buf(),
        source,
    })
}

fn content(path: &Path, message: impl Into<String>) -> StudyError {
    StudyError::Content {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// Every vehicle's trip in one run (SUMO's tripinfo with `write-unfinished`).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Trips {
    /// Vehicles in the file.
    pub vehicles: usize,
    /// Vehicles that finished their trip.
    pub arrived: usize,
    /// Sum of every vehicle's time loss and insertion delay (s).
    pub time_loss: f64,
    /// Vehicles not of a controllable type.
    pub uncontrolled: usize,
    /// Their time loss and insertion delay (s).
    pub uncontrolled_time_loss: f64,
    /// Distance driven by every vehicle (km).
    pub vehicle_km: f64,
}

impl Trips {
    /// Reads a tripinfo file; `controllable` names the controllable vehicle types.
    pub fn read(path: &Path, controllable: &[String]) -> Result<Trips, StudyError> {
        let text = read(path)?;
        let doc = roxmltree::Document::parse(&text).map_err(|e| content(path, e.to_string()))?;
        let mut trips = Trips::default();
        for t in doc.descendants().filter(|n| n.has_tag_name("tripinfo")) {
            let num = |name: &str| {
                t.attribute(name)
                    .and_then(|v| v.parse::<f64>().ok())
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| content(path, format!("a tripinfo without a number `{name}`")))
            };
            let loss = num("timeLoss")? + num("departDelay")?.max(0.0);
            trips.vehicles += 1;
            trips.arrived += usize::from(num("arrival")? >= 0.0);
            trips.time_loss += loss;
            trips.vehicle_km += num("routeLength")?.max(0.0) / 1000.0;
            let vtype = t.attribute("vType").unwrap_or_default();
            if !controllable.iter().any(|c| c == vtype) {
                trips.uncontrolled += 1;
                trips.uncontrolled_time_loss += loss;
            }
        }
        Ok(trips)
    }
}

/// The mean time loss of every vehicle of one seed's arrivals, insertion delay included, when
/// the ramp's flows (`ramp`) and the freeway's flows (`freeway`) run apart; none without
/// vehicles.
pub fn apart(ramp: &Trips, freeway: &Trips) -> Option<f64> {
    let n = ramp.vehicles + freeway.vehicles;
    (n > 0).then(|| (ramp.time_loss + freeway.time_loss) / n as f64)
}

/// Below this share of SUMO's drivers' time loss a merge's cost is too small to divide by: on
/// SUMO's `tools/game/highway` network the merge cost 0.01 s of 50 s per vehicle, and the game
/// "saved" 7,650% of it.
pub const MIN_MERGE_COST: f64 = 0.01;

/// The part of the merge's cost the game saves at `row`'s share: SUMO's drivers' mean time
/// loss of every vehicle less the game's, over SUMO's drivers' less the streams' apart
/// (`apart`, s per vehicle); none where a figure is missing or the merge costs less than
/// [`MIN_MERGE_COST`] of SUMO's drivers' time loss.
pub fn merge_cost_removed(row: &ShareRow, apart: f64) -> Option<f64> {
    let (g, s) = (
        row.game.get(&Quantity::TimeLoss)?.mean,
        row.sumo.get(&Quantity::TimeLoss)?.mean,
    );
    (s - apart > MIN_MERGE_COST * s).then(|| (s - g) / (s - apart))
}

/// SUMO's SSM conflicts of one run.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Conflicts {
    /// Every conflict the SSM devices logged.
    pub all: usize,
    /// Those with a minimum TTC below [`SEVERE_TTC`].
    pub severe: usize,
}

impl Conflicts {
    /// Reads an SSM output file (the conflicts [`ssm::conflicts`] counts).
    pub fn read(path: &Path) -> Result<Conflicts, StudyError> {
        let text = read(path)?;
        let conflicts = ssm::conflicts(&text).map_err(|e| content(path, e.to_string()))?;
        Ok(Conflicts {
            all: conflicts.len(),
            severe: conflicts.iter().filter(|c| c.ttc_below(SEVERE_TTC)).count(),
        })
    }
}

/// One run of the study: a share, a seed, a controller.
#[derive(Debug, Clone, PartialEq)]
pub struct StudyRun {
    /// Share of controllable vehicles.
    pub share: f64,
    /// SUMO seed.
    pub seed: u64,
    /// True for the game (the mpg controller), false for SUMO's drivers alone.
    pub game: bool,
    /// Simulated duration (s).
    pub duration: f64,
    /// Every vehicle's trip.
    pub trips: Trips,
    /// SSM conflicts.
    pub conflicts: Conflicts,
    /// Mean speed of the finished egos (controllable ramp vehicles; m/s), if any.
    pub ego_speed: Option<f64>,
    /// SUMO collisions involving a vehicle the controller drove.
    pub controlled_collisions: usize,
}

/// The study's quantities, each one number per run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Quantity {
    /// Mean time loss of every vehicle, insertion delay included (s).
    TimeLoss,
    /// The same over the vehicles not of a controllable type (s).
    UncontrolledTimeLoss,
    /// Finished trips per hour.
    Throughput,
    /// Mean speed of the finished egos (m/s).
    EgoSpeed,
    /// SSM conflicts per vehicle-km.
    Conflicts,
    /// Severe conflicts per vehicle-km.
    SevereConflicts,
}

impl Quantity {
    /// Every quantity, in the tables' order.
    pub const ALL: [Quantity; 6] = [
        Quantity::TimeLoss,
        Quantity::UncontrolledTimeLoss,
        Quantity::Throughput,
        Quantity::EgoSpeed,
        Quantity::Conflicts,
        Quantity::SevereConflicts,
    ];

    /// Title and unit.
    pub fn label(self) -> (&'static str, &'static str) {
        match self {
            Quantity::TimeLoss => ("Time loss of every vehicle", "s per vehicle"),
            Quantity::UncontrolledTimeLoss => ("Time loss of the non-controllable vehicles", "s per vehicle"),
            Quantity::Throughput => ("Throughput (finished trips)", "veh/h"),
            Quantity::EgoSpeed => ("Mean ego speed", "m/s"),
            Quantity::Conflicts => ("SSM conflicts (TTC < 3 s or DRAC > 3 m/s^2)", "per vehicle-km"),
            Quantity::SevereConflicts => ("Severe conflicts (TTC < 1.5 s)", "per vehicle-km"),
        }
    }

    /// Its value in `run`, when defined.
    pub fn of(self, run: &StudyRun) -> Option<f64> {
        let t = &run.trips;
        let per = |x: f64, n: f64| (n > 0.0).then(|| x / n);
        match self {
            Quantity::TimeLoss => per(t.time_loss, t.vehicles as f64),
            Quantity::UncontrolledTimeLoss => per(t.uncontrolled_time_loss, t.uncontrolled as f64),
            Quantity::Throughput => per(t.arrived as f64 * 3600.0, run.duration),
            Quantity::EgoSpeed => run.ego_speed,
            Quantity::Conflicts => per(run.conflicts.all as f64, t.vehicle_km),
            Quantity::SevereConflicts => per(run.conflicts.severe as f64, t.vehicle_km),
        }
    }
}

/// Mean and sample standard deviation over seeds, with the number of runs that have a value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spread {
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation (0 for one run).
    pub sd: f64,
    /// Runs with a value.
    pub runs: usize,
}

impl Spread {
    /// The mean and sample standard deviation of `xs`.
    pub fn of(xs: &[f64]) -> Spread {
        let (mean, sd) = mean_sd(xs);
        Spread {
            mean,
            sd,
            runs: xs.len(),
        }
    }
}

/// One share's line of the study: each quantity for the game and for SUMO's drivers.
#[derive(Debug, Clone, PartialEq)]
pub struct ShareRow {
    /// Share of controllable vehicles.
    pub share: f64,
    /// The game's quantities.
    pub game: BTreeMap<Quantity, Spread>,
    /// SUMO's drivers' quantities.
    pub sumo: BTreeMap<Quantity, Spread>,
    /// Collisions involving a controlled vehicle, summed over seeds.
    pub controlled_collisions: usize,
    /// Seeds run.
    pub seeds: usize,
    /// Seeds on which the game's time loss of every vehicle is below SUMO's drivers' on the
    /// same arrivals.
    pub seeds_below: usize,
}

impl ShareRow {
    /// The game's mean of `q` over SUMO's drivers', when both are defined and SUMO's is not 0.
    pub fn ratio(&self, q: Quantity) -> Option<f64> {
        let (g, s) = (self.game.get(&q)?, self.sumo.get(&q)?);
        (s.mean != 0.0).then(|| g.mean / s.mean)
    }
}

fn key(x: f64) -> i64 {
    (x * 1e6).round() as i64
}

/// The rows of the study, one per share in increasing order.
pub fn rows(runs: &[StudyRun]) -> Vec<ShareRow> {
    let mut shares: BTreeMap<i64, Vec<&StudyRun>> = BTreeMap::new();
    for r in runs {
        shares.entry(key(r.share)).or_default().push(r);
    }
    shares
        .into_iter()
        .map(|(share, runs)| {
            let spread = |game: bool| {
                Quantity::ALL
                    .iter()
                    .filter_map(|&q| {
                        let xs: Vec<f64> = runs
                            .iter()
                            .filter(|r| r.game == game)
                            .filter_map(|r| q.of(r))
                            .collect();
                        (!xs.is_empty()).then(|| (q, Spread::of(&xs)))
                    })
                    .collect()
            };
            let mut seeds: Vec<u64> = runs.iter().map(|r| r.seed).collect();
            seeds.sort_unstable();
            seeds.dedup();
            let loss = |seed: u64, game: bool| {
                runs.iter()
                    .find(|r| r.seed == seed && r.game == game)
                    .and_then(|r| Quantity::TimeLoss.of(r))
            };
            let seeds_below = seeds
                .iter()
                .filter(|&&seed| matches!((loss(seed, true), loss(seed, false)), (Some(g), Some(s)) if g < s))
                .count();
            ShareRow {
                share: share as f64 / 1e6,
                game: spread(true),
                sumo: spread(false),
                controlled_collisions: runs
                    .iter()
                    .filter(|r| r.game)
                    .map(|r| r.controlled_collisions)
                    .sum(),
                seeds: seeds.len(),
                seeds_below,
            }
        })
        .collect()
}

/// The smallest positive share from which on (at it and every larger share) the game's time
/// loss of every vehicle is below SUMO's drivers' on every seed; none when no share is.
pub fn break_even(rows: &[ShareRow]) -> Option<f64> {
    let below = |r: &ShareRow| r.seeds > 0 && r.seeds_below == r.seeds;
    let positive: Vec<&ShareRow> = rows.iter().filter(|r| r.share > 0.0).collect();
    let last_not = positive.iter().rposition(|r| !below(r));
    let from = last_not.map_or(0, |k| k + 1);
    positive.get(from).map(|r| r.share)
}

fn cell(s: Option<&Spread>, decimals: usize) -> String {
    s.map_or_else(
        || "-".into(),
        |s| format!("{:.*} ± {:.*}", decimals, s.mean, decimals, s.sd),
    )
}

fn decimals(q: Quantity) -> usize {
    match q {
        Quantity::Throughput => 0,
        Quantity::Conflicts | Quantity::SevereConflicts => 4,
        _ => 2,
    }
}

/// The study as Markdown: per share, each quantity for the game and SUMO's drivers (mean ±
/// sample standard deviation over seeds) in two tables (delay and flow; speed, conflicts and
/// collisions), the share from which the game beats SUMO's drivers, and with the streams'
/// time loss apart (over seeds, [`apart`]) the merge's cost and the part of it the game saves.
pub fn markdown(rows: &[ShareRow], apart: Option<Spread>) -> String {
    type Column = (&'static str, fn(&ShareRow) -> String);
    let table = |quantities: &[Quantity], tail: &[Column]| {
        let mut md = String::from("| controllable share | seeds |");
        for q in quantities {
            let (title, unit) = q.label();
            md += &format!(" {title} ({unit}): the game | SUMO's drivers |");
        }
        for (head, _) in tail {
            md += &format!(" {head} |");
        }
        md += &format!(
            "\n|---|---|{}\n",
            "---|---|".repeat(quantities.len()) + &"---|".repeat(tail.len())
        );
        for r in rows {
            md += &format!("| {:.0}% | {} |", r.share * 100.0, r.seeds);
            for &q in quantities {
                md += &format!(
                    " {} | {} |",
                    cell(r.game.get(&q), decimals(q)),
                    cell(r.sumo.get(&q), decimals(q))
                );
            }
            for (_, value) in tail {
                md += &format!(" {} |", value(r));
            }
            md.push('\n');
        }
        md
    };
    let ratio: fn(&ShareRow) -> String = |r| {
        r.ratio(Quantity::TimeLoss)
            .map_or_else(|| "-".into(), |x| format!("{x:.3}"))
    };
    let mut md = table(
        &[
            Quantity::TimeLoss,
            Quantity::UncontrolledTimeLoss,
            Quantity::Throughput,
        ],
        &[
            (
                "seeds on which the game's time loss of every vehicle is below SUMO's drivers'",
                |r| format!("{} of {}", r.seeds_below, r.seeds),
            ),
            ("time loss of every vehicle, the game / SUMO's drivers", ratio),
        ],
    );
    md.push('\n');
    md += &table(
        &[Quantity::EgoSpeed, Quantity::Conflicts, Quantity::SevereConflicts],
        &[("collisions with a controlled vehicle", |r| {
            r.controlled_collisions.to_string()
        })],
    );
    md += &match (break_even(rows), rows.last()) {
        (Some(s), _) => format!(
            "\nThe game's time loss of every vehicle is below SUMO's drivers' on every seed from a controllable share of {:.0}% on.\n",
            s * 100.0
        ),
        (None, Some(last)) => format!(
            "\nThe game does not beat SUMO's drivers on every seed from any share on: at the largest share run ({:.0}%) its time loss of every vehicle is {} times theirs.\n",
            last.share * 100.0,
            ratio(last)
        ),
        (None, None) => String::new(),
    };
    if let (Some(a), Some(sumo)) = (apart, rows.first().and_then(|r| r.sumo.get(&Quantity::TimeLoss))) {
        md += &format!(
            "\n## The merge's own cost\n\nOn the same arrivals, SUMO's drivers with the ramp's flows and the \
             freeway's flows in separate runs (the streams never meet) lose {:.2} ± {:.2} s per vehicle: \
             {:.3} times SUMO's drivers' {:.2} s with both streams at a share of {:.0}%. The difference, \
             {:.2} s per vehicle, is what the merge costs.",
            a.mean,
            a.sd,
            a.mean / sumo.mean,
            sumo.mean,
            rows[0].share * 100.0,
            sumo.mean - a.mean
        );
        if sumo.mean - a.mean <= MIN_MERGE_COST * sumo.mean {
            md += &format!(
                " That is less than {:.0}% of their time loss: too little here to say what part of it the game saves.\n",
                MIN_MERGE_COST * 100.0
            );
            return md;
        }
        md += " The part of it the game saves:\n\n\
               | controllable share | SUMO's drivers' time loss less the game's, over the merge's cost |\n|---|---|\n";
        for r in rows.iter().filter(|r| r.share > 0.0) {
            let cell =
                merge_cost_removed(r, a.mean).map_or_else(|| "-".into(), |x| format!("{:.1}%", x * 100.0));
            md += &format!("| {:.0}% | {cell} |\n", r.share * 100.0);
        }
    }
    md
}

/// The study as CSV: one line per share, quantity and side; the streams' time loss apart, if
/// given, as side `apart` at share 0.
pub fn csv(rows: &[ShareRow], apart: Option<Spread>) -> String {
    let mut out = String::from("share,quantity,side,mean,sd,runs\n");
    if let Some(a) = apart {
        out += &format!(
            "0,{:?},apart,{:.6},{:.6},{}\n",
            Quantity::TimeLoss,
            a.mean,
            a.sd,
            a.runs
        );
    }
    for r in rows {
        for q in Quantity::ALL {
            for (side, map) in [("game", &r.game), ("sumo", &r.sumo)] {
                if let Some(s) = map.get(&q) {
                    out += &format!("{},{q:?},{side},{:.6},{:.6},{}\n", r.share, s.mean, s.sd, s.runs);
                }
            }
        }
    }
    out
}

/// Draws the study into `path`: one panel per quantity against the share, the game and SUMO's
/// drivers, each the mean over seeds with a band of one sample standard deviation; the time
/// loss panel also has the streams' apart, if given.
pub fn plot(rows: &[ShareRow], apart: Option<Spread>, path: &Path) -> Result<(), RenderError> {
    let side = |label: &str, pick: fn(&ShareRow) -> &BTreeMap<Quantity, Spread>, q: Quantity| {
        let points: Vec<(f64, Spread)> = rows
            .iter()
            .filter_map(|r| pick(r).get(&q).map(|s| (r.share * 100.0, *s)))
            .collect();
        Series {
            label: label.into(),
            points: points.iter().map(|(x, s)| (*x, s.mean)).collect(),
            band: points
                .iter()
                .map(|(x, s)| (*x, s.mean - s.sd, s.mean + s.sd))
                .collect(),
        }
    };
    let panels: Vec<(Panel, Vec<Series>)> = Quantity::ALL
        .iter()
        .map(|&q| {
            let (title, unit) = q.label();
            let panel = Panel {
                title: title.into(),
                x_label: "controllable vehicles, % of all".into(),
                y_label: unit.into(),
            };
            let mut series = vec![
                side("the game", |r| &r.game, q),
                side("SUMO's drivers", |r| &r.sumo, q),
            ];
            if let Some(a) = apart.filter(|_| q == Quantity::TimeLoss) {
                let xs: Vec<f64> = rows.iter().map(|r| r.share * 100.0).collect();
                series.push(Series {
                    label: "each stream alone".into(),
                    points: xs.iter().map(|&x| (x, a.mean)).collect(),
                    band: xs.iter().map(|&x| (x, a.mean - a.sd, a.mean + a.sd)).collect(),
                });
            }
            (panel, series)
        })
        .collect();
    panels_png(path, (1000, 1500), &panels)
}
