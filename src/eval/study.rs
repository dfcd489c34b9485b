//! The statistical study (Tables II and III): a policy, or one per seed, drives the ego over
//! `eval.test_scenarios` test initial states per seed (drawn from the seed's test stream,
//! disjoint from training and probe states), with the surrounding players driven by the NE
//! policies (the shared MPG policy; for a single-agent ego, the MPG policy of the same seed, as
//! in Table III), IDM or constant speed. Counts are averaged over seeds, so rates can be
//! fractional (15.4/500).

use crate::config::Config;
use crate::engine::outcome::EpisodeOutcome;
use crate::engine::rollout::Recording;
use crate::eval::metrics::{EpisodeMetrics, Summary, distance_cell, mean_defined};
use crate::policy::drive::{Others, policy_rollout};
use crate::policy::file::{self, PolicyError, Sidecar};
use crate::policy::mode::Mode;
use crate::policy::network::PolicyNet;
use crate::policy::observation::Layout;
use crate::world::drivers::Driver;
use crate::world::sampler::{Purpose, purpose_seed, sample_scenes};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// How the surrounding players drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Surrounding {
    /// The same shared policy as the ego (the Nash-equilibrium policies).
    Ne,
    /// Intelligent Driver Model.
    Idm,
    /// Constant speed.
    Const,
}

impl Surrounding {
    /// Column title as in the paper's tables.
    pub fn title(self) -> &'static str {
        match self {
            Surrounding::Ne => "NE",
            Surrounding::Idm => "IDM",
            Surrounding::Const => "Constant speed",
        }
    }
}

/// An evaluation problem.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// A policy file is missing, mismatched or damaged.
    #[error(transparent)]
    Policy(#[from] PolicyError),
    /// The policy directory holds no policy.
    #[error("{0}: no policy (*.json with its .safetensors) found")]
    NoPolicy(PathBuf),
    /// The directory could not be listed.
    #[error("cannot list {path}")]
    List {
        /// The directory.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A single-agent policy against NE players needs the MPG policy of its seed.
    #[error(
        "NE surrounding players for a single-agent policy need the MPG policy of seed {seed}: pass --ne-policy"
    )]
    NeedNePolicy {
        /// The seed without an MPG policy.
        seed: u64,
    },
    /// libtorch failed.
    #[error("libtorch: {0}")]
    Torch(#[from] tch::TchError),
}

/// Which policies a run accepts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rules {
    /// Only policies trained under the run's world rules ([`file::check_rules`]).
    Same,
    /// Any policy of the run's player count (an ablation: the caller warns).
    Any,
}

/// Loads a policy file, or every policy of a directory (checkpoints excluded), sorted by seed,
/// for a run of `config` (its observation layout, and its world rules unless `rules` is
/// [`Rules::Any`]).
pub fn load_policies(
    path: &Path,
    config: &Config,
    rules: Rules,
) -> Result<Vec<(PolicyNet, Sidecar)>, EvalError> {
    let layout = Layout::of(config);
    let load = |p: &Path| -> Result<(PolicyNet, Sidecar), EvalError> {
        let (net, side) = file::load(p, layout)?;
        if rules == Rules::Same {
            file::check_rules(p, &side, config)?;
        }
        Ok((net, side))
    };
    if !path.is_dir() {
        return Ok(vec![load(path)?]);
    }
    let entries = std::fs::read_dir(path).map_err(|source| EvalError::List {
        path: path.into(),
        source,
    })?;
    let mut sidecars: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension().is_some_and(|e| e == "json")
                && p.file_name()
                    .is_some_and(|n| !n.to_string_lossy().contains(".ckpt."))
        })
        .collect();
    sidecars.sort();
    let mut policies = sidecars.iter().map(|p| load(p)).collect::<Result<Vec<_>, _>>()?;
    if policies.is_empty() {
        return Err(EvalError::NoPolicy(path.into()));
    }
    policies.sort_by_key(|(_, side)| side.seed);
    Ok(policies)
}

/// One evaluated episode.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct EpisodeRow {
    /// The policy's training seed.
    pub seed: u64,
    /// Surrounding players.
    pub surrounding: Surrounding,
    /// Test scenario index.
    pub scenario: usize,
    /// Its metrics.
    pub metrics: EpisodeMetrics,
    /// The ego's discounted return `J_0` (its total reward).
    pub ego_return: f64,
    /// The collision that ended the episode, if any.
    pub collision: Option<CollisionRecord>,
}

/// Where an episode's first collision happened: the two players (0 is the ego) and their
/// states at the first overlapping step, for an episode-by-episode analysis of collisions.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CollisionRecord {
    /// Time of the overlap (s).
    pub time: f64,
    /// The two players, lower number first.
    pub players: [usize; 2],
    /// Their positions (m).
    pub x: [f64; 2],
    /// Their speeds (m/s).
    pub v: [f64; 2],
    /// Whether each was still on the ramp.
    pub on_ramp: [bool; 2],
}

impl CollisionRecord {
    /// The record of an outcome that ended with a collision (`dt`: the step, s); `None` when
    /// the episode went on after it (`sim.terminate_on_collision = false`), whose final state
    /// is not the collision's.
    pub fn of(o: &EpisodeOutcome, dt: f64) -> Option<Self> {
        let c = o.collision.filter(|c| c.step + 1 == o.steps)?;
        let veh = &o.final_scene.vehicles;
        let (a, b) = (&veh[c.a], &veh[c.b]);
        Some(CollisionRecord {
            time: (c.step + 1) as f64 * dt,
            players: [c.a, c.b],
            x: [a.x, b.x],
            v: [a.v, b.v],
            on_ramp: [a.on_ramp, b.on_ramp],
        })
    }

    /// CSV header of [`Self::csv`]'s fields.
    pub const CSV: &str = "collision_time,collision_players,collision_x,collision_v,collision_on_ramp";

    /// The record as CSV fields (pairs as `a b`); empty fields for no collision.
    pub fn csv(record: Option<&Self>) -> String {
        record.map_or_else(
            || ",,,,".to_string(),
            |r| {
                format!(
                    "{:.1},{} {},{:.2} {:.2},{:.2} {:.2},{} {}",
                    r.time,
                    r.players[0],
                    r.players[1],
                    r.x[0],
                    r.x[1],
                    r.v[0],
                    r.v[1],
                    u8::from(r.on_ramp[0]),
                    u8::from(r.on_ramp[1])
                )
            },
        )
    }
}

/// Results for one kind of surrounding players.
#[derive(Debug, Clone, Serialize)]
pub struct Column {
    /// Surrounding players.
    pub surrounding: Surrounding,
    /// Per policy seed.
    pub per_seed: Vec<(u64, Summary)>,
    /// Averaged over seeds (counts may be fractional).
    pub mean: MeanSummary,
}

/// A [`Summary`] averaged over seeds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MeanSummary {
    /// Scenarios per seed.
    pub episodes: usize,
    /// Mean ego collisions per seed.
    pub collisions: f64,
    /// Mean failures per seed.
    pub failures: f64,
    /// Mean episodes per seed ended by a collision between other players.
    pub other_collisions: f64,
    /// Mean minimum distance (m).
    pub min_distance: f64,
    /// Mean minimum in-lane distance (m) over the seeds where it is defined.
    pub min_lane_distance: Option<f64>,
    /// Mean ego speed (m/s).
    pub mean_speed: f64,
    /// Mean acceleration magnitude (m/s^2).
    pub mean_abs_accel: f64,
    /// Mean jerk magnitude (m/s^3).
    pub mean_abs_jerk: f64,
}

/// Averages per-seed summaries (counts become fractional means).
pub fn mean_over_seeds(per_seed: &[(u64, Summary)]) -> MeanSummary {
    let k = per_seed.len() as f64;
    let avg = |f: fn(&Summary) -> f64| per_seed.iter().map(|(_, s)| f(s)).sum::<f64>() / k;
    MeanSummary {
        episodes: per_seed[0].1.episodes,
        collisions: avg(|s| s.collisions as f64),
        failures: avg(|s| s.failures as f64),
        other_collisions: avg(|s| s.other_collisions as f64),
        min_distance: avg(|s| s.min_distance),
        min_lane_distance: mean_defined(per_seed.iter().filter_map(|(_, s)| s.min_lane_distance)),
        mean_speed: avg(|s| s.mean_speed),
        mean_abs_accel: avg(|s| s.mean_abs_accel),
        mean_abs_jerk: avg(|s| s.mean_abs_jerk),
    }
}

/// The whole study.
#[derive(Debug, Clone, Serialize)]
pub struct Study {
    /// What the policies learned (from the policy files).
    pub mode: Mode,
    /// Policy seeds.
    pub seeds: Vec<u64>,
    /// One column per kind of surrounding players.
    pub columns: Vec<Column>,
    /// Every episode.
    #[serde(skip)]
    pub episodes: Vec<EpisodeRow>,
}

/// Runs the study. `ne_policies` are the MPG policies that drive the surrounding players in the
/// NE column when the evaluated policy is a single-agent one (matched by seed), as in Table III.
pub fn evaluate(
    config: &Config,
    policies: &[(PolicyNet, Sidecar)],
    ne_policies: &[(PolicyNet, Sidecar)],
    surroundings: &[Surrounding],
    threads: usize,
) -> Result<Study, EvalError> {
    let mut columns = Vec::new();
    let mut episodes = Vec::new();
    for &surrounding in surroundings {
        let mut per_seed = Vec::new();
        for (net, side) in policies {
            let scenes = sample_scenes(
                config,
                purpose_seed(side.seed, Purpose::Test),
                0,
                config.eval.test_scenarios,
            );
            let others = match surrounding {
                Surrounding::Ne if side.mode == Mode::Mpg => Others::SameNetwork,
                Surrounding::Ne => {
                    let ne = ne_policies
                        .iter()
                        .find(|(_, s)| s.seed == side.seed && s.mode == Mode::Mpg);
                    Others::Network(&ne.ok_or(EvalError::NeedNePolicy { seed: side.seed })?.0)
                }
                Surrounding::Idm => Others::Driver(Driver::Idm),
                Surrounding::Const => Others::Driver(Driver::ConstSpeed),
            };
            let outcomes = policy_rollout(config, net, others, &scenes, threads, Recording::Ego)?;
            let metrics: Vec<_> = outcomes.iter().map(EpisodeMetrics::of).collect();
            episodes.extend(
                outcomes
                    .iter()
                    .zip(&metrics)
                    .enumerate()
                    .map(|(scenario, (o, &metrics))| EpisodeRow {
                        seed: side.seed,
                        surrounding,
                        scenario,
                        metrics,
                        ego_return: o.returns[0],
                        collision: CollisionRecord::of(o, config.sim.dt),
                    }),
            );
            per_seed.push((side.seed, Summary::of(&metrics)));
        }
        columns.push(Column {
            surrounding,
            mean: mean_over_seeds(&per_seed),
            per_seed,
        });
    }
    Ok(Study {
        mode: policies[0].1.mode,
        seeds: policies.iter().map(|(_, s)| s.seed).collect(),
        columns,
        episodes,
    })
}

fn count(x: f64) -> String {
    if x.fract() == 0.0 {
        format!("{x:.0}")
    } else {
        format!("{x:.1}")
    }
}

impl Study {
    /// A Markdown table laid out like the paper's Tables II and III.
    pub fn markdown(&self) -> String {
        let title = if self.mode == Mode::Sarl {
            "Single-agent RL"
        } else {
            "MARL with MPGs"
        };
        let head = if self.mode == Mode::Sarl {
            "Surrounding vehicles' policies"
        } else {
            "Selected players' policies"
        };
        let columns: Vec<(&str, MeanSummary)> = self
            .columns
            .iter()
            .map(|c| (c.surrounding.title(), c.mean))
            .collect();
        format!(
            "Statistical results: {title} (policy seeds {:?})\n\n{}",
            self.seeds,
            table(head, &columns, true)
        )
    }

    /// Every episode as CSV.
    pub fn episodes_csv(&self) -> String {
        let mut out = format!(
            "seed,surrounding,scenario,collision,failure,other_collision,{},ego_return,{}\n",
            EpisodeMetrics::CSV_MOTION,
            CollisionRecord::CSV
        );
        for e in &self.episodes {
            let m = &e.metrics;
            out.push_str(&format!(
                "{},{},{},{},{},{},{},{},{}\n",
                e.seed,
                e.surrounding.title().to_lowercase().replace(' ', "_"),
                e.scenario,
                u8::from(m.collision),
                u8::from(m.failure),
                u8::from(m.other_collision),
                m.motion_csv(),
                e.ego_return,
                CollisionRecord::csv(e.collision.as_ref())
            ));
        }
        out
    }
}

/// A Markdown table laid out like the paper's Tables II-IV: one column per `(title, results)`,
/// one row per metric, `head` in the top-left cell. `others` adds our row of collisions between
/// two players other than the ego.
pub fn table(head: &str, columns: &[(&str, MeanSummary)], others: bool) -> String {
    let mut out = format!("| {head} |");
    for (title, _) in columns {
        out.push_str(&format!(" {title} |"));
    }
    out.push_str(&format!("\n|---|{}\n", "---|".repeat(columns.len())));
    let row = |name: &str, f: &dyn Fn(&MeanSummary) -> String| {
        let cells: String = columns.iter().map(|(_, m)| format!(" {} |", f(m))).collect();
        format!("| {name} |{cells}\n")
    };
    out += &row("Collision rate", &|m| {
        format!("{}/{}", count(m.collisions), m.episodes)
    });
    out += &row("Failure rate", &|m| {
        format!("{}/{}", count(m.failures), m.episodes)
    });
    if others {
        out += &row("Collisions between other players (ours)", &|m| {
            format!("{}/{}", count(m.other_collisions), m.episodes)
        });
    }
    out += &row("Average minimum inter-vehicle distance (m)", &|m| {
        format!("{:.4}", m.min_distance)
    });
    out += &row("Average minimum in-lane distance (m)", &|m| {
        distance_cell(m.min_lane_distance)
    });
    out += &row("Average ego vehicle speed (m/s)", &|m| {
        format!("{:.4}", m.mean_speed)
    });
    out += &row("Average acceleration magnitude (m/s^2)", &|m| {
        format!("{:.4}", m.mean_abs_accel)
    });
    out += &row("Average jerk magnitude (m/s^3)", &|m| {
        format!("{:.4}", m.mean_abs_jerk)
    });
    out
}
