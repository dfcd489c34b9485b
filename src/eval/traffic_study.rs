//! The internal traffic study (`mpgdrive eval` with `scenario.kind = "traffic"`): every
//! controlled vehicle of merge-traffic test episodes, in two kinds of surroundings.
//!
//! - **Human-only**: every vehicle but the ego is a human (IDM) driver; the ego is the one
//!   controlled vehicle.
//! - **Mixed**: the episode's own draw of human drivers (`traffic.human_share`); every other
//!   vehicle, ramp and target lane, is controlled by the shared policy.
//!
//! Per episode: a collision counts when the first collision involves a controlled vehicle; a
//! failure when no collision happened and a controlled ramp vehicle that started where the
//! paper's ego starts (`sampling.ego_position`, 40-120 m before x_c) is still on the ramp at the
//! horizon, the paper's failure for every such vehicle (one that starts farther back, behind a
//! queue, may not reach the merge within the horizon whatever it does); speed, acceleration and
//! jerk are the means over the controlled vehicles of their episode means. Counts are per
//! seed's `eval.test_scenarios` episodes, and every figure is averaged over the policy seeds.

use crate::config::Config;
use crate::engine::outcome::EpisodeOutcome;
use crate::engine::rollout::Recording;
use crate::policy::drive::{Others, policy_rollout};
use crate::policy::file::Sidecar;
use crate::policy::network::PolicyNet;
use crate::world::sampler::{Purpose, purpose_seed, sample_scenes};
use crate::world::state::Scene;
use serde::Serialize;

/// Who surrounds the ego.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Surroundings {
    /// Every other vehicle a human (IDM) driver.
    HumanOnly,
    /// The episode's draw of human drivers; the rest on the shared policy.
    Mixed,
}

impl Surroundings {
    /// Column title.
    pub fn title(self) -> &'static str {
        match self {
            Surroundings::HumanOnly => "Human-only surroundings (ego controlled)",
            Surroundings::Mixed => "Mixed surroundings (every non-human vehicle controlled)",
        }
    }
}

/// One column of the study: means over the policy seeds.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrafficColumn {
    /// The surroundings.
    pub surroundings: Surroundings,
    /// Controlled vehicles per episode, on average.
    pub controlled: f64,
    /// Episodes whose first collision involves a controlled vehicle.
    pub collisions: f64,
    /// Episodes without a collision where a controlled ramp vehicle that started where the
    /// paper's ego starts did not merge.
    pub failures: f64,
    /// Mean speed of the controlled vehicles (m/s).
    pub speed: f64,
    /// Mean acceleration magnitude (m/s^2).
    pub accel: f64,
    /// Mean jerk magnitude (m/s^3).
    pub jerk: f64,
}

/// The study: both columns.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrafficStudy {
    /// Policy seeds.
    pub seeds: Vec<u64>,
    /// Episodes per seed.
    pub episodes: usize,
    /// Human-only, then mixed.
    pub columns: Vec<TrafficColumn>,
}

/// Per-episode figures of the controlled vehicles.
struct EpisodeFigures {
    controlled: usize,
    collision: bool,
    failure: bool,
    speed: f64,
    accel: f64,
    jerk: f64,
}

/// The figures of one episode; a failure counts the controlled ramp vehicles that started at
/// `from` or later.
fn figures(scene: &Scene, o: &EpisodeOutcome, from: f64) -> EpisodeFigures {
    let controlled: Vec<usize> = (0..scene.len()).filter(|&i| !scene.is_human(i)).collect();
    let collision = o
        .collision
        .is_some_and(|c| !scene.is_human(c.a) || !scene.is_human(c.b));
    let failure = o.collision.is_none()
        && controlled
            .iter()
            .any(|&i| o.final_scene.vehicles[i].on_ramp && scene.vehicles[i].x >= from);
    let mean =
        |f: &dyn Fn(usize) -> f64| controlled.iter().map(|&i| f(i)).sum::<f64>() / controlled.len() as f64;
    let per_step = |i: usize, sum: f64| sum / o.vehicles[i].steps.max(1) as f64;
    let per_jerk_step =
        |i: usize| o.vehicles[i].sum_abs_jerk / o.vehicles[i].steps.saturating_sub(1).max(1) as f64;
    EpisodeFigures {
        controlled: controlled.len(),
        collision,
        failure,
        speed: mean(&|i| per_step(i, o.vehicles[i].sum_speed)),
        accel: mean(&|i| per_step(i, o.vehicles[i].sum_abs_accel)),
        jerk: mean(&per_jerk_step),
    }
}

/// Runs the study for every policy (one per seed) on `config`'s test episodes.
pub fn traffic_study(
    config: &Config,
    policies: &[(PolicyNet, Sidecar)],
    threads: usize,
) -> Result<TrafficStudy, tch::TchError> {
    let episodes = config.eval.test_scenarios;
    let mut columns = Vec::new();
    for surroundings in [Surroundings::HumanOnly, Surroundings::Mixed] {
        let mut sums = [0.0f64; 6];
        for (net, side) in policies {
            let mut scenes = sample_scenes(config, purpose_seed(side.seed, Purpose::Test), 0, episodes);
            if surroundings == Surroundings::HumanOnly {
                for s in &mut scenes {
                    s.humans = (0..s.len()).map(|i| i > 0).collect();
                }
            }
            let outcomes = policy_rollout(
                config,
                net,
                Others::SameNetwork,
                &scenes,
                threads,
                Recording::Summary,
            )?;
            let per: Vec<EpisodeFigures> = scenes
                .iter()
                .zip(&outcomes)
                .map(|(s, o)| figures(s, o, config.sampling.ego_position[0]))
                .collect();
            let n = per.len() as f64;
            sums[0] += per.iter().map(|f| f.controlled as f64).sum::<f64>() / n;
            sums[1] += per.iter().filter(|f| f.collision).count() as f64;
            sums[2] += per.iter().filter(|f| f.failure).count() as f64;
            sums[3] += per.iter().map(|f| f.speed).sum::<f64>() / n;
            sums[4] += per.iter().map(|f| f.accel).sum::<f64>() / n;
            sums[5] += per.iter().map(|f| f.jerk).sum::<f64>() / n;
        }
        let k = policies.len().max(1) as f64;
        columns.push(TrafficColumn {
            surroundings,
            controlled: sums[0] / k,
            collisions: sums[1] / k,
            failures: sums[2] / k,
            speed: sums[3] / k,
            accel: sums[4] / k,
            jerk: sums[5] / k,
        });
    }
    Ok(TrafficStudy {
        seeds: policies.iter().map(|(_, s)| s.seed).collect(),
        episodes,
        columns,
    })
}

impl TrafficStudy {
    /// The study as a Markdown table.
    pub fn markdown(&self) -> String {
        let mut out = format!(
            "Traffic study: the controlled vehicles of {} merge-traffic test episodes per seed (policy seeds {:?}), means over seeds\n\n| | {} |\n|---|{}\n",
            self.episodes,
            self.seeds,
            self.columns
                .iter()
                .map(|c| c.surroundings.title())
                .collect::<Vec<_>>()
                .join(" | "),
            "---|".repeat(self.columns.len())
        );
        let row = |name: &str, f: &dyn Fn(&TrafficColumn) -> String| {
            format!(
                "| {name} | {} |\n",
                self.columns.iter().map(f).collect::<Vec<_>>().join(" | ")
            )
        };
        let per = self.episodes;
        out += &row("Controlled vehicles per episode", &|c| {
            format!("{:.2}", c.controlled)
        });
        out += &row("Collisions (episodes)", &|c| format!("{:.1}/{per}", c.collisions));
        out += &row("Failures (episodes)", &|c| format!("{:.1}/{per}", c.failures));
        out += &row("Average speed (m/s)", &|c| format!("{:.4}", c.speed));
        out += &row("Average acceleration magnitude (m/s^2)", &|c| {
            format!("{:.4}", c.accel)
        });
        out += &row("Average jerk magnitude (m/s^3)", &|c| format!("{:.4}", c.jerk));
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::outcome::{Collision, EgoStats};
    use crate::world::state::test_car as car;

    fn outcome(final_scene: Scene, collision: Option<Collision>, speeds: [f64; 3]) -> EpisodeOutcome {
        let vehicles = speeds
            .iter()
            .map(|&v| {
                let mut s = EgoStats::default();
                let scene = Scene::new(vec![car(0.0, v, false), car(50.0, v, false)]);
                for _ in 0..4 {
                    s.update_vehicle(&scene, 0, 1.0, 0.1);
                }
                s
            })
            .collect();
        EpisodeOutcome {
            steps: 4,
            collision,
            others_overlapped: false,
            ego_merged_at: None,
            returns: vec![0.0; 3],
            potential_return: 0.0,
            vehicles,
            final_scene,
            trajectory: None,
        }
    }

    #[test]
    fn figures_count_only_the_controlled_vehicles() {
        // Ego (controlled, merged), a controlled target-lane car, a human ramp car still on the
        // ramp at the end.
        let mut scene = Scene::new(vec![
            car(100.0, 10.0, true),
            car(120.0, 12.0, false),
            car(90.0, 8.0, true),
        ]);
        scene.humans = vec![false, false, true];
        let end = Scene::new(vec![
            car(190.0, 10.0, false),
            car(240.0, 12.0, false),
            car(150.0, 0.0, true),
        ]);
        let f = figures(&scene, &outcome(end.clone(), None, [10.0, 14.0, 2.0]), 60.0);
        // The human's speed and its unmerged state do not count: no failure, mean speed 12.
        assert_eq!(f.controlled, 2);
        assert!(!f.collision && !f.failure);
        assert!((f.speed - 12.0).abs() < 1e-12);
        assert!((f.accel - 1.0).abs() < 1e-12);
        assert!(f.jerk.abs() < 1e-12);
        // A collision between the human and a controlled car counts; one between two humans
        // would not.
        let hit = Some(Collision { step: 2, a: 1, b: 2 });
        assert!(figures(&scene, &outcome(end.clone(), hit, [10.0; 3]), 60.0).collision);
        scene.humans = vec![false, true, true];
        assert!(!figures(&scene, &outcome(end.clone(), hit, [10.0; 3]), 60.0).collision);
        // A controlled ramp car left on the ramp is a failure when it started at 90 m, where
        // the paper's ego may start (from 60 m), and not when it started farther back.
        scene.humans = vec![false, false, false];
        assert!(figures(&scene, &outcome(end.clone(), None, [10.0; 3]), 60.0).failure);
        assert!(!figures(&scene, &outcome(end, None, [10.0; 3]), 95.0).failure);
    }
}
