//! Is the learned merge the potential's best? For each of the paper's two scenarios and each
//! policy seed, compares the discounted potential of the shared policy's own episode with the
//! episodes in which the ego alone drives open loop, tracking a fixed speed until it merges
//! (`u = v_track - v`, clipped to [-3, 2] m/s^2), while every other player keeps the policy.
//!
//! ```sh
//! cargo run --release --example merge_alternatives -- [CONFIG] [POLICY_DIR] [STATE]
//! ```
//! (defaults `configs/paper.toml` and `policies/mpg`). `STATE`, seven numbers, replaces the
//! two presets by one state of their pattern (`world::scenarios::PresetState`: the ego's
//! distance to x_c and speed, the gaps to "4" and "5", the leaders' and the followers' speed,
//! the headway). A collision-free alternative with a higher potential than the policy's episode
//! is a better joint outcome that gradient play did not find from this state (Algorithm 1
//! ascends the potential). Last, whom each seed's ego merges between in its first 300 test
//! episodes (`eval`'s states). Deterministic.

use mpgdrive::config::Config;
use mpgdrive::engine::outcome::EpisodeOutcome;
use mpgdrive::engine::rollout::{Actor, Recording, RolloutOptions, rollout};
use mpgdrive::eval::study::{Rules, load_policies};
use mpgdrive::game::PaperReward;
use mpgdrive::policy::drive::{Others, policy_rollout};
use mpgdrive::policy::network::PolicyNet;
use mpgdrive::policy::observation::PolicyActor;
use mpgdrive::world::drivers::Driver;
use mpgdrive::world::neighbors::Neighbors;
use mpgdrive::world::sampler::{Purpose, purpose_seed, sample_scenes};
use mpgdrive::world::scenarios::{Preset, PresetState};
use mpgdrive::world::state::Scene;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Mutex;

/// Speeds the open-loop ego tracks (m/s); `None` is the policy's own episode.
const TRACKED: [Option<f64>; 8] = [
    None,
    Some(9.0),
    Some(10.0),
    Some(11.0),
    Some(12.0),
    Some(14.0),
    Some(15.0),
    Some(17.0),
];

/// Test episodes per seed whose merge order is counted.
const TEST_EPISODES: usize = 300;

/// Every player on the shared policy, the ego replaced by a speed tracker while on the ramp.
struct EgoTracks {
    policy: PolicyActor<PolicyNet>,
    speed: Option<f64>,
}

impl Actor for EgoTracks {
    fn act(&mut self, step: usize, scenes: &[Scene], neighbors: &[Neighbors], out: &mut [f64]) {
        self.policy.act(step, scenes, neighbors, out);
        let n = scenes.first().map_or(0, Scene::len);
        for (b, scene) in scenes.iter().enumerate() {
            let ego = scene.ego();
            if let (Some(v), true) = (self.speed, ego.on_ramp) {
                out[b * n] = (v - ego.v).clamp(-3.0, 2.0);
            }
        }
    }
}

/// The discounted potential's four weighted terms summed over the players, each pair once
/// (`speed, comfort, TTC, conflict`): the recorded steps only, so after a collision they leave
/// out the absorbing tail that the potential holds.
fn potential_terms(config: &Config, outcome: &EpisodeOutcome) -> [f64; 4] {
    let (r, reward) = (&config.reward, PaperReward::new(config));
    let n = outcome.final_scene.len();
    let trajectory = outcome.trajectory.as_ref().expect("recorded");
    let mut sums = [0.0; 4];
    for (k, (t, v)) in trajectory.terms.iter().zip(&trajectory.states).enumerate() {
        let discount = config.sim.gamma.powi((k / n) as i32);
        let w_speed = reward.speed_weight_of(v);
        // Pair terms are logged for both players of a pair: half each.
        let weighted = [
            w_speed * t.speed,
            r.w_comfort * t.comfort,
            r.w_ttc * t.ttc / 2.0,
            r.w_conflict * t.conflict / 2.0,
        ];
        for (s, w) in sums.iter_mut().zip(weighted) {
            *s += discount * w;
        }
    }
    sums
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let config_path = args.get(1).map_or("configs/paper.toml", String::as_str);
    let policies = args.get(2).map_or("policies/mpg", String::as_str);
    let config = Config::load(Path::new(config_path))?;
    let nets = load_policies(Path::new(policies), &config, Rules::Same)?;
    let opts = RolloutOptions {
        threads: 1,
        recording: Recording::Full,
        ..RolloutOptions::from_config(&config)
    };
    println!(
        "scenario | seed | ego drives | potential | its speed | comfort | TTC | conflict terms | ego's return | merged between | collision"
    );
    let scenes: Vec<(String, Scene)> = match args.get(3..) {
        Some(v) if !v.is_empty() => {
            let v: Vec<f64> = v.iter().map(|a| a.parse()).collect::<Result<_, _>>()?;
            anyhow::ensure!(v.len() == 7, "STATE is seven numbers, got {}", v.len());
            let state = PresetState {
                ego_before: v[0],
                ego_speed: v[1],
                gap_ahead: v[2],
                gap_behind: v[3],
                leader_speed: v[4],
                follower_speed: v[5],
                headway: v[6],
            };
            vec![("state".into(), state.scene(&config))]
        }
        _ => [Preset::One, Preset::Two]
            .map(|p| (p.number().to_string(), p.scene(&config)))
            .into(),
    };
    for (name, scene) in &scenes {
        for (net, side) in &nets {
            let seed = side.seed;
            for speed in TRACKED {
                let cell = Mutex::new(Some(net.try_clone()?));
                let outcome = rollout(&config, &opts, std::slice::from_ref(scene), || EgoTracks {
                    policy: PolicyActor::new(
                        &config,
                        cell.lock().expect("lock").take().expect("one actor"),
                        Driver::Idm,
                        true,
                    ),
                    speed,
                })
                .remove(0);
                let between = outcome
                    .merged_between()
                    .map_or("never".into(), |[a, b]| format!("{a} and {b}"));
                let [speed_term, comfort, ttc, conflict] = potential_terms(&config, &outcome);
                println!(
                    "{name} | {seed} | {} | {:.0} | {speed_term:.0} | {comfort:.0} | {ttc:.0} | {conflict:.0} | {:.0} | {between} | {}",
                    speed.map_or("the policy".into(), |v| format!("tracks {v} m/s")),
                    outcome.potential_return,
                    outcome.returns[0],
                    if outcome.collision.is_some() { "yes" } else { "no" }
                );
            }
        }
    }
    for (net, side) in &nets {
        let tests = sample_scenes(&config, purpose_seed(side.seed, Purpose::Test), 0, TEST_EPISODES);
        let outcomes = policy_rollout(&config, net, Others::SameNetwork, &tests, 2, Recording::Full)?;
        let mut merged: BTreeMap<String, usize> = BTreeMap::new();
        for o in &outcomes {
            let key = o
                .merged_between()
                .map_or("never".into(), |[a, b]| format!("{a} and {b}"));
            *merged.entry(key).or_default() += 1;
        }
        println!(
            "seed {}, {TEST_EPISODES} test episodes, merged between: {merged:?}",
            side.seed
        );
    }
    Ok(())
}
