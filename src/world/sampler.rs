//! Stratified initial states (Section V-iv).
//!
//! Scenario `k` of a seed is drawn from its own random stream (ChaCha8, stream `k` of the seed),
//! so it does not depend on how many scenarios are drawn or in which batch. Its stratum is
//! `k mod (n_p * n_v)`: the ego's position range is cut into `n_p` equal parts and its speed
//! range into `n_v`, and the ego's position and speed are uniform inside the stratum's cell.
//!
//! The target-lane players are then placed outward from the ego: the nearest leader one
//! headway ahead of the ego, each further leader one headway ahead of the previous one, and the
//! followers likewise behind. Headways (centre to centre) are uniform in `sampling.headway`
//! (at least 7 m in the paper's setting). Speeds are uniform in `sampling.speed` restricted so
//! that the TTC between every successive follower and leader (ego included) is at least
//! `sampling.min_ttc`:
//!
//! ```text
//! ahead of a vehicle at speed v_f, headway h:   v_lead   >= v_f - h / min_ttc
//! behind a vehicle at speed v_l, headway h:     v_follow <= v_l + h / min_ttc
//! ```
//!
//! Both ranges are never empty, so no sample is rejected.

use crate::config::{Config, ScenarioKind};
use crate::world::geometry::Road;
use crate::world::scenarios::Preset;
use crate::world::state::{Scene, Vehicle};
use crate::world::traffic::sample_traffic_scene;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// What a set of initial states is for. Each purpose draws from its own seed, so training,
/// probe and test states of one seed are different draws.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Purpose {
    /// Training minibatches.
    Train,
    /// The fixed probe set of the training curves.
    Probe,
    /// Evaluation scenarios.
    Test,
}

/// The seed of the initial states of `purpose` for run seed `seed`.
pub fn purpose_seed(seed: u64, purpose: Purpose) -> u64 {
    let salt: u64 = match purpose {
        Purpose::Train => 0x7472_6169_6e00_0000,
        Purpose::Probe => 0x7072_6f62_6500_0000,
        Purpose::Test => 0x7465_7374_0000_0000,
    };
    seed ^ salt
}

/// The random stream of scenario `index` of `seed`.
pub fn scenario_rng(seed: u64, index: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(index);
    rng
}

/// A standard normal draw from `rng` (Box-Muller, two uniform draws).
pub fn standard_normal(rng: &mut impl Rng) -> f64 {
    let u: f64 = 1.0 - rng.random::<f64>();
    let v: f64 = rng.random();
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// The stratum (position cell, speed cell) of scenario `index`.
pub fn stratum(config: &Config, index: usize) -> (usize, usize) {
    let [np, nv] = config.sampling.strata;
    let s = index % (np * nv);
    (s / nv, s % nv)
}

/// Draws `count` scenarios, indices `first..first + count` of `seed`.
pub fn sample_scenes(config: &Config, seed: u64, first: usize, count: usize) -> Vec<Scene> {
    (first..first + count)
        .map(|k| sample_scene(config, seed, k))
        .collect()
}

/// Training minibatch `epoch` of `seed`: scenarios `epoch * batch..(epoch + 1) * batch`,
/// the last `round(share * batch)` of them drawn near the merge when `train.near_merge` is
/// set: the ego's position and speed stratified in `near_merge`'s ranges instead of
/// `sampling`'s (the same two draws), the players placed around it by the usual rules. The
/// `round(train.scenario_share * batch)` states before those are drawn from the paper's
/// specific scenarios' descriptions ([`family_scene`]) from epoch `train.scenario_from` on.
pub fn sample_training_scenes(config: &Config, seed: u64, epoch: usize) -> Vec<Scene> {
    let batch = config.train.batch;
    let first = epoch * batch;
    let near = config.train.near_merge.as_ref();
    let n_near = share_count(near.map_or(0.0, |n| n.share), batch);
    let share = if epoch >= config.train.scenario_from {
        config.train.scenario_share
    } else {
        0.0
    };
    let n_family = share_count(share, batch - n_near);
    (first..first + batch)
        .map(|k| match near {
            Some(near) if k >= first + batch - n_near => {
                paper_scene(config, seed, k, near.ego_position, near.ego_speed)
            }
            _ if k >= first + batch - n_near - n_family => family_scene(config, seed, k),
            _ => sample_scene(config, seed, k),
        })
        .collect()
}

/// The probe set of `seed`: its first `train.probe_scenarios` scenarios, the last
/// `round(train.probe_scenario_share * count)` of them (`train.scenario_share` when it is
/// not set) drawn from the paper's specific scenarios' descriptions ([`family_scene`]).
pub fn sample_probe_scenes(config: &Config, seed: u64) -> Vec<Scene> {
    let t = &config.train;
    let count = t.probe_scenarios;
    let n_family = share_count(t.probe_scenario_share.unwrap_or(t.scenario_share), count);
    (0..count)
        .map(|k| {
            if k >= count - n_family {
                family_scene(config, seed, k)
            } else {
                sample_scene(config, seed, k)
            }
        })
        .collect()
}

/// `round(share * n)`, at most `n`.
fn share_count(share: f64, n: usize) -> usize {
    ((share * n as f64).round() as usize).min(n)
}

/// Scenario `index` of `seed` drawn from the description of one of the paper's specific
/// scenarios (scenario 1 for even indices, 2 for odd ones) with the scenario's own random
/// stream: other draws than the fixed described sets, which use seeds 1 and 2.
pub fn family_scene(config: &Config, seed: u64, index: usize) -> Scene {
    let preset = match index % 2 {
        0 => Preset::One,
        _ => Preset::Two,
    };
    preset
        .draw_state(&mut scenario_rng(seed, index as u64))
        .scene(config)
}

/// The ego's initial position and speed of scenario `index`: uniform inside its stratum's cell,
/// two draws from `rng`.
pub fn stratified_ego(config: &Config, index: usize, rng: &mut ChaCha8Rng) -> (f64, f64) {
    let p = &config.sampling;
    stratified_point(config, p.ego_position, p.ego_speed, index, rng)
}

/// A position in `position` and a speed in `speed`, each range cut into the configuration's
/// strata, uniform inside the cell of scenario `index`'s stratum: two draws from `rng`.
fn stratified_point(
    config: &Config,
    position: [f64; 2],
    speed: [f64; 2],
    index: usize,
    rng: &mut ChaCha8Rng,
) -> (f64, f64) {
    let p = &config.sampling;
    let (cp, cv) = stratum(config, index);
    let cell = |range: [f64; 2], parts: usize, at: usize, u: f64| {
        let w = (range[1] - range[0]) / parts as f64;
        range[0] + w * (at as f64 + u)
    };
    let x = cell(position, p.strata[0], cp, rng.random::<f64>());
    let v = cell(speed, p.strata[1], cv, rng.random::<f64>());
    (x, v)
}

/// Draws scenario `index` of `seed`: the paper's, or merge traffic
/// ([`crate::world::traffic`]) when the configuration says so.
pub fn sample_scene(config: &Config, seed: u64, index: usize) -> Scene {
    if let (ScenarioKind::Traffic, Some(t)) = (config.scenario.kind, &config.traffic) {
        return sample_traffic_scene(config, t, seed, index);
    }
    let p = &config.sampling;
    paper_scene(config, seed, index, p.ego_position, p.ego_speed)
}

/// Scenario `index` of `seed` in the paper's world, the ego's position and speed stratified
/// in `ego_position` and `ego_speed`.
fn paper_scene(
    config: &Config,
    seed: u64,
    index: usize,
    ego_position: [f64; 2],
    ego_speed: [f64; 2],
) -> Scene {
    let p = &config.sampling;
    let road = Road::new(config);
    let mut rng = scenario_rng(seed, index as u64);
    let (ego_x, ego_v) = stratified_point(config, ego_position, ego_speed, index, &mut rng);
    let uniform = |rng: &mut ChaCha8Rng, lo: f64, hi: f64| lo + (hi - lo) * rng.random::<f64>();

    let target = |x: f64, v: f64| Vehicle {
        x,
        y: road.lane_y(false),
        v,
        phi: 0.0,
        on_ramp: false,
    };
    let n_lead = config.scenario.n_leaders;
    let n_follow = config.scenario.n_followers;
    let mut leaders = Vec::with_capacity(n_lead); // nearest first
    let (mut x, mut v) = (ego_x, ego_v);
    for _ in 0..n_lead {
        let h = uniform(&mut rng, p.headway[0], p.headway[1]);
        let v_lo = (v - h / p.min_ttc).max(p.speed[0]);
        v = uniform(&mut rng, v_lo, p.speed[1].max(v_lo));
        x += h;
        leaders.push(target(x, v));
    }
    let mut followers = Vec::with_capacity(n_follow); // nearest first
    let (mut x, mut v) = (ego_x, ego_v);
    for _ in 0..n_follow {
        let h = uniform(&mut rng, p.headway[0], p.headway[1]);
        let v_hi = (v + h / p.min_ttc).min(p.speed[1]);
        v = uniform(&mut rng, p.speed[0].min(v_hi), v_hi);
        x -= h;
        followers.push(target(x, v));
    }
    let mut vehicles = Vec::with_capacity(config.n_agents());
    vehicles.push(Vehicle {
        x: ego_x,
        y: road.lane_y(true),
        v: ego_v,
        phi: 0.0,
        on_ramp: true,
    });
    vehicles.extend(leaders.into_iter().rev()); // "1" is the front-most leader
    vehicles.extend(followers);
    Scene::new(vehicles)
}
