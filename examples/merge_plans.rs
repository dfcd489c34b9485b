//! Where should the ego merge in the paper's scenarios, given the other players' policy? For
//! each described state of a scenario ([`Preset::described_states`]) and each policy seed, runs
//! the shared policy's own episode and the episodes in which the ego alone drives an open-loop
//! two-phase plan (track `v1` until `t1`, then `v2`; `u = v_track - v` clipped to [-3, 2]
//! m/s^2) while every other player keeps the policy. In a potential game a unilateral
//! deviation changes the potential as it changes the deviating player's return, so the best
//! collision-free plan's slot is where a best response to the others merges.
//!
//! ```sh
//! cargo run --release --example merge_plans -- PRESET STATES [CONFIG] [POLICY_DIR]
//! ```
//! `PRESET` is 1, 2, or `2late` (scenario 2 with the ego farther back, see [`late_states`]).
//! Prints, per seed: the policy's slots, the best plan's slots, and in how many states the best
//! plan's potential beats the policy's. Deterministic.

use mpgdrive::config::Config;
use mpgdrive::engine::rollout::{Actor, Recording, RolloutOptions, rollout};
use mpgdrive::eval::study::{Rules, load_policies};
use mpgdrive::policy::drive::{Others, policy_rollout};
use mpgdrive::policy::network::PolicyNet;
use mpgdrive::policy::observation::PolicyActor;
use mpgdrive::world::drivers::Driver;
use mpgdrive::world::neighbors::Neighbors;
use mpgdrive::world::sampler::scenario_rng;
use mpgdrive::world::scenarios::{Preset, PresetState};
use mpgdrive::world::state::Scene;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Mutex;

/// An open-loop plan: track `v1` until `t1` seconds, then `v2`.
#[derive(Debug, Clone, Copy)]
struct Plan {
    v1: f64,
    t1: f64,
    v2: f64,
}

/// Every player on the shared policy, the ego (scene `b`) replaced by plan `b` while on the ramp.
struct EgoPlans {
    policy: PolicyActor<PolicyNet>,
    plans: Vec<Plan>,
    dt: f64,
}

impl Actor for EgoPlans {
    fn act(&mut self, step: usize, scenes: &[Scene], neighbors: &[Neighbors], out: &mut [f64]) {
        self.policy.act(step, scenes, neighbors, out);
        let n = scenes.first().map_or(0, Scene::len);
        let t = step as f64 * self.dt;
        for (b, scene) in scenes.iter().enumerate() {
            let (ego, p) = (scene.ego(), self.plans[b]);
            if ego.on_ramp {
                let target = if t < p.t1 { p.v1 } else { p.v2 };
                out[b * n] = (target - ego.v).clamp(-3.0, 2.0);
            }
        }
    }
}

/// `n` states of scenario 2's description ([`Preset::draw_state`]) with the ego's distance to
/// `x_c` stretched from 20-40 m to 40-120 m, kept only where "5" would reach `x_c` before the
/// ego at the initial speeds (the paper's "the ego waits for 5 to pass" read literally):
/// streams 0, 1, ... of seed 22, rejected until `n` are kept.
fn late_states(n: usize) -> Vec<PresetState> {
    (0u64..)
        .map(|k| {
            let mut s = Preset::Two.draw_state(&mut scenario_rng(22, k));
            s.ego_before = 40.0 + (s.ego_before - 20.0) * 4.0;
            s
        })
        .filter(|s| (s.ego_before + s.gap_behind) / s.follower_speed < s.ego_before / s.ego_speed)
        .take(n)
        .collect()
}

fn slot(between: Option<[usize; 2]>) -> String {
    between.map_or("never".into(), |[a, b]| format!("{a}-{b}"))
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let preset = match args.get(1).map(String::as_str) {
        Some("1") => Preset::One,
        Some("2") | Some("2late") => Preset::Two,
        _ => anyhow::bail!("usage: merge_plans PRESET(1|2|2late) STATES [CONFIG] [POLICY_DIR]"),
    };
    let n: usize = args.get(2).map_or(Ok(40), |s| s.parse())?;
    let config = Config::load(Path::new(
        args.get(3).map_or("configs/paper.toml", String::as_str),
    ))?;
    let nets = load_policies(
        Path::new(args.get(4).map_or("policies/mpg", String::as_str)),
        &config,
        Rules::Same,
    )?;
    let mut plans = Vec::new();
    for v1 in [0.0, 2.0, 4.0, 6.0, 8.0, 10.0, 12.0, 14.0] {
        for t1 in [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0] {
            for v2 in [10.0, 13.0, 16.0, 19.0] {
                plans.push(Plan { v1, t1, v2 });
            }
        }
    }
    let opts = RolloutOptions {
        threads: 1, // plan `b` is scene `b` of the actor's batch: one chunk
        recording: Recording::Full,
        ..RolloutOptions::from_config(&config)
    };
    let states = match args[1].as_str() {
        "2late" => late_states(n),
        _ => preset.described_states(n),
    };
    for (net, side) in &nets {
        let scenes: Vec<Scene> = states.iter().map(|s| s.scene(&config)).collect();
        let own = policy_rollout(&config, net, Others::SameNetwork, &scenes, 2, Recording::Full)?;
        let (mut policy_slots, mut best_slots) = (BTreeMap::new(), BTreeMap::new());
        let mut beaten = 0;
        for (scene, own) in scenes.iter().zip(&own) {
            let batch = vec![scene.clone(); plans.len()];
            let cell = Mutex::new(Some(net.try_clone()?));
            let outcomes = rollout(&config, &opts, &batch, || EgoPlans {
                policy: PolicyActor::new(
                    &config,
                    cell.lock().expect("lock").take().expect("one actor"),
                    Driver::Idm,
                    true,
                ),
                plans: plans.clone(),
                dt: config.sim.dt,
            });
            // Best potential per slot among collision-free plans.
            let mut by_slot: BTreeMap<String, f64> = BTreeMap::new();
            for o in outcomes.iter().filter(|o| o.collision.is_none()) {
                let e = by_slot
                    .entry(slot(o.merged_between()))
                    .or_insert(f64::NEG_INFINITY);
                *e = e.max(o.potential_return);
            }
            let best = by_slot
                .iter()
                .max_by(|a, b| a.1.total_cmp(b.1))
                .map_or("none".to_string(), |(k, _)| k.clone());
            let own_slot = if own.collision.is_some() {
                "collision".into()
            } else {
                slot(own.merged_between())
            };
            *policy_slots.entry(own_slot).or_insert(0) += 1;
            *best_slots.entry(best.clone()).or_insert(0) += 1;
            let best_value = by_slot.values().cloned().fold(f64::NEG_INFINITY, f64::max);
            if best_value > own.potential_return {
                beaten += 1;
            }
            let fmt: Vec<String> = by_slot.iter().map(|(k, v)| format!("{k}:{v:.0}")).collect();
            eprintln!(
                "seed {} | policy {} {:.0} | {}",
                side.seed,
                slot(own.merged_between()),
                own.potential_return,
                fmt.join(" ")
            );
        }
        println!(
            "scenario {} seed {}: policy slots {policy_slots:?}; best plan slots {best_slots:?}; a plan beats the policy in {beaten} of {n}",
            preset.number(),
            side.seed
        );
    }
    Ok(())
}
