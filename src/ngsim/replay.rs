//! Replay of a merge scenario (Table IV): the ego starts with the recorded ramp vehicle's
//! position and speed and is driven by the human (the recorded trajectory) or by a policy; the
//! players follow their recorded trajectories.
//!
//! - Positions are centres along the road (`Local_Y` minus half the recorded length); the
//!   lateral position is the lane's (the simulator's `y`: target lane 0, ramp `-w`, lanes to the
//!   left positive), from the reassigned lane.
//! - A policy ego is simulated as in the internal simulator (eq. (1), feasibility projection
//!   and bounds from the paper configuration; it joins the target lane at the conflict point).
//!   It observes the players as Table I says, with the conflict point of `configs/ngsim.toml`.
//! - The human ego is its recorded trajectory; its acceleration is the recomputed one, and it
//!   has merged once its reassigned lane is the target lane.
//! - A player whose record has ended, or has a hole, continues at its last recorded speed.
//! - A collision is an overlap of the ego's box with a player's, each with the recorded length
//!   and width; it ends the episode. Collisions among recorded players are not ours to count.
//! - A policy ego is replayed for the paper's horizon `T`; the human for `T` or until its
//!   record ends.

use crate::config::Config;
use crate::engine::outcome::EgoStats;
use crate::eval::metrics::{EpisodeMetrics, Summary};
use crate::eval::study::{MeanSummary, mean_over_seeds, table};
use crate::ngsim::config::{FRAME_SECONDS, NgsimConfig};
use crate::ngsim::process::{Prepared, Track};
use crate::ngsim::scenario::MergeScenario;
use crate::policy::file::Sidecar;
use crate::policy::network::PolicyNet;
use crate::policy::observation::{BatchPolicy, Frame, Layout, observe};
use crate::world::geometry::{Footprint, boxes_overlap};
use crate::world::neighbors::find_neighbors;
use crate::world::rules::WorldRules;
use crate::world::state::{Scene, Vehicle};
use crate::world::step::{advance, applied_action};
use serde::Serialize;

/// Who drives the ego.
pub enum EgoDriver<'a> {
    /// The recorded human driver.
    Human,
    /// A policy (single-agent or MARL).
    Policy(&'a mut dyn BatchPolicy),
}

/// The result of one replay.
#[derive(Debug, Clone, PartialEq)]
pub struct Replay {
    /// The metrics of `mpgdrive eval`.
    pub metrics: EpisodeMetrics,
    /// Steps replayed.
    pub steps: usize,
    /// The scene at every step, ego first, then the players in the scenario's order.
    pub scenes: Vec<Scene>,
}

/// The paper configuration with the NGSIM conflict point.
pub fn replay_config(config: &Config, ngsim: &NgsimConfig) -> Config {
    config.at_conflict_point(ngsim.merge.conflict_point)
}

/// A recorded vehicle at `frame` (after its record, or in a hole: moved on at its last speed).
fn recorded(t: &Track, frame: u32, ngsim: &NgsimConfig) -> Vehicle {
    let k = t.frames.partition_point(|&f| f <= frame).saturating_sub(1);
    let ahead = f64::from(frame.saturating_sub(t.frames[k])) * FRAME_SECONDS;
    Vehicle {
        x: t.centre(k) + t.speed[k] * ahead,
        y: ngsim.lanes.offset(t.lane[k]),
        v: t.speed[k],
        phi: 0.0,
        on_ramp: t.lane[k] == ngsim.lanes.ramp_lane(),
    }
}

fn footprint(v: &Vehicle, t: &Track) -> Footprint {
    Footprint {
        x: v.x,
        y: v.y,
        phi: v.phi,
        length: t.length,
        width: t.width,
    }
}

/// Replays `scenario`; `config` is the paper configuration with the NGSIM conflict point
/// ([`replay_config`]).
pub fn replay(
    config: &Config,
    ngsim: &NgsimConfig,
    data: &Prepared,
    scenario: &MergeScenario,
    mut driver: EgoDriver,
) -> Replay {
    let ego_track = &data.tracks[scenario.ego];
    let players: Vec<&Track> = scenario.players.iter().map(|&(j, _)| &data.tracks[j]).collect();
    let rules = WorldRules::new(config);
    let dt = rules.dt;
    let start = scenario.start_frame;
    let human = matches!(driver, EgoDriver::Human);
    let steps = if human {
        let last = ego_track.frames[ego_track.frames.len() - 1];
        config.n_steps().min((last - start) as usize)
    } else {
        config.n_steps()
    };
    let scene_at = |step: usize, ego: Vehicle| {
        let frame = start + step as u32;
        let mut vehicles = Vec::with_capacity(players.len() + 1);
        vehicles.push(ego);
        vehicles.extend(players.iter().map(|t| recorded(t, frame, ngsim)));
        Scene::new(vehicles)
    };
    let mut ego = recorded(ego_track, start, ngsim);
    ego.y = rules.road.lane_y(true);
    ego.on_ramp = true;
    let mut scene = scene_at(0, ego);
    let mut scenes = vec![scene.clone()];
    let mut stats = EgoStats::default();
    let (mut order, mut nb) = (Vec::new(), Vec::new());
    let layout = Layout::of(config);
    let frame = Frame::of(config);
    let mut obs = vec![0.0f32; layout.dim()];
    let mut action = [0.0f32];
    let (mut collision, mut merged, mut done) = (false, false, 0);
    for step in 0..steps {
        let accel = match &mut driver {
            EgoDriver::Human => {
                let k = ego_track.frames.partition_point(|&f| f <= start + step as u32) - 1;
                ego_track.accel[k]
            }
            EgoDriver::Policy(policy) => {
                find_neighbors(&scene, &mut order, &mut nb);
                observe(layout, frame, &scene, 0, &nb[0], &mut obs);
                policy.act(&obs, 1, &mut action);
                applied_action(
                    &rules,
                    config.sim.feasibility,
                    &scene,
                    0,
                    &nb[0],
                    f64::from(action[0]),
                )
            }
        };
        stats.update(&scene, accel, dt);
        let ego = if human {
            recorded(ego_track, start + step as u32 + 1, ngsim)
        } else {
            advance(scene.ego(), accel, false, &rules)
        };
        scene = scene_at(step + 1, ego);
        scenes.push(scene.clone());
        done = step + 1;
        merged |= !scene.ego().on_ramp;
        let me = footprint(scene.ego(), ego_track);
        collision = scene.vehicles[1..]
            .iter()
            .zip(&players)
            .any(|(v, t)| boxes_overlap(&me, &footprint(v, t)));
        if collision {
            break;
        }
    }
    Replay {
        metrics: EpisodeMetrics::from_stats(&stats, collision, merged),
        steps: done,
        scenes,
    }
}

/// One replayed episode of the study.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReplayRow {
    /// "human", "sarl" or "mpg".
    pub driver: String,
    /// The policy's training seed (none for the human).
    pub seed: Option<u64>,
    /// Scenario index.
    pub scenario: usize,
    /// The ego's Vehicle_ID.
    pub ego_id: u32,
    /// First frame.
    pub start_frame: u32,
    /// Steps replayed.
    pub steps: usize,
    /// Its metrics.
    pub metrics: EpisodeMetrics,
}

/// The Table IV study: one column per ego driver.
#[derive(Debug, Clone, Serialize)]
pub struct NgsimStudy {
    /// `(column title, results averaged over seeds)`: human, single-agent RL, MARL.
    pub columns: Vec<(String, MeanSummary)>,
    /// Every episode.
    pub episodes: Vec<ReplayRow>,
}

/// Replays every scenario with the human, each single-agent policy and each MARL policy;
/// policy columns are averaged over seeds as in Tables II and III.
pub fn study(
    config: &Config,
    ngsim: &NgsimConfig,
    data: &Prepared,
    scenarios: &[MergeScenario],
    sarl: &mut [(PolicyNet, Sidecar)],
    mpg: &mut [(PolicyNet, Sidecar)],
) -> NgsimStudy {
    let config = replay_config(config, ngsim);
    let mut episodes = Vec::new();
    let mut run = |driver_name: &str, seed: Option<u64>, mut net: Option<&mut PolicyNet>| {
        let metrics: Vec<EpisodeMetrics> = scenarios
            .iter()
            .enumerate()
            .map(|(i, sc)| {
                let driver = match net.as_deref_mut() {
                    Some(n) => EgoDriver::Policy(n),
                    None => EgoDriver::Human,
                };
                let r = replay(&config, ngsim, data, sc, driver);
                episodes.push(ReplayRow {
                    driver: driver_name.to_string(),
                    seed,
                    scenario: i,
                    ego_id: data.tracks[sc.ego].id,
                    start_frame: sc.start_frame,
                    steps: r.steps,
                    metrics: r.metrics,
                });
                r.metrics
            })
            .collect();
        (seed.unwrap_or(0), Summary::of(&metrics))
    };
    let human = vec![run("human", None, None)];
    let mut column = |name: &str, policies: &mut [(PolicyNet, Sidecar)]| -> Vec<(u64, Summary)> {
        policies
            .iter_mut()
            .map(|(net, side)| run(name, Some(side.seed), Some(net)))
            .collect()
    };
    let sarl = column("sarl", sarl);
    let mpg = column("mpg", mpg);
    let mut columns = vec![("Human driver".to_string(), mean_over_seeds(&human))];
    for (title, per_seed) in [("Single-agent RL", &sarl), ("MARL", &mpg)] {
        if !per_seed.is_empty() {
            columns.push((title.to_string(), mean_over_seeds(per_seed)));
        }
    }
    NgsimStudy { columns, episodes }
}

impl NgsimStudy {
    /// A Markdown table laid out like Table IV.
    pub fn markdown(&self) -> String {
        let columns: Vec<(&str, MeanSummary)> = self.columns.iter().map(|(t, m)| (t.as_str(), *m)).collect();
        table("Ego vehicle's policy", &columns, false)
    }

    /// Every episode as CSV.
    pub fn episodes_csv(&self) -> String {
        let mut out = format!(
            "driver,seed,scenario,ego_id,start_frame,steps,collision,failure,{}\n",
            EpisodeMetrics::CSV_MOTION
        );
        for e in &self.episodes {
            out.push_str(&format!(
                "{},{},{},{},{},{},{},{},{}\n",
                e.driver,
                e.seed.map_or(String::new(), |s| s.to_string()),
                e.scenario,
                e.ego_id,
                e.start_frame,
                e.steps,
                u8::from(e.metrics.collision),
                u8::from(e.metrics.failure),
                e.metrics.motion_csv()
            ));
        }
        out
    }
}
