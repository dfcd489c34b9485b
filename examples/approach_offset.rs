//! Did gradient play stop where the potential stops rising? For each traffic policy seed, its
//! own test states (`eval`'s, mixed surroundings as sampled and human-only) rolled out with a
//! constant offset (m/s^2) added to the raw action of every policy-driven ramp vehicle before
//! the merge zone, every other action the policy's. Prints, per offset and column, the mean
//! discounted potential (what training ascends), the ego's return, the step it merged and the
//! collisions and failures over the seeds. An offset that raises the potential of a converged
//! policy is a direction the training's gradient did not see. Last, the potential's
//! derivative along the offset at 0, by central differences (`H`), with the entry rule's
//! decisions live and with them frozen as the offset-0 run took them (replayed, as
//! `check-mpg` replays them): the second is what the pathwise gradient (BPTT) sees, which
//! holds every discrete decision fixed; their difference is the jumps of the discrete entry
//! (a ramp vehicle that arrives earlier catches a gap it would otherwise wait for).
//! Deterministic.
//!
//! ```sh
//! cargo run --release --example approach_offset -- [CONFIG] [POLICY_DIR] [EPISODES] [OFFSET ...]
//! ```
//! (defaults `configs/traffic.toml`, `policies/traffic/mpg`, 200 episodes per seed and column,
//! offsets -0.5 0 0.5 1 2).

use mpgdrive::config::Config;
use mpgdrive::engine::outcome::EpisodeOutcome;
use mpgdrive::engine::rollout::{Actor, EntryDecision, Recording, RolloutOptions, rollout};
use mpgdrive::eval::study::{Rules, load_policies};
use mpgdrive::policy::network::PolicyNet;
use mpgdrive::policy::observation::PolicyActor;
use mpgdrive::world::drivers::Driver;
use mpgdrive::world::neighbors::Neighbors;
use mpgdrive::world::sampler::{Purpose, purpose_seed, sample_scenes};
use mpgdrive::world::state::Scene;
use std::path::Path;
use std::sync::{Arc, Mutex};

/// Worker threads of each rollout.
const THREADS: usize = 2;

/// The offset step (m/s^2) of the central differences.
const H: f64 = 0.1;

/// Every scene's entry decisions, `[scene][step * players + player]`.
type EntryLog = Vec<Vec<EntryDecision>>;

/// What a run does with the entry rule's decisions (one worker thread: `b` is the scene).
#[derive(Clone)]
enum Entries {
    /// Decide live.
    Live,
    /// Decide live and record them.
    Record(Arc<Mutex<EntryLog>>),
    /// Replay a recorded run's.
    Replay(Arc<EntryLog>),
}

/// The shared policy for every player, `offset` added to the raw action of the policy-driven
/// ramp vehicles still short of `until` (the merge zone's start).
struct Offset {
    policy: PolicyActor<PolicyNet>,
    offset: f64,
    until: f64,
    entries: Entries,
    players: usize,
}

impl Actor for Offset {
    fn act(&mut self, step: usize, scenes: &[Scene], neighbors: &[Neighbors], out: &mut [f64]) {
        self.policy.act(step, scenes, neighbors, out);
        for (b, scene) in scenes.iter().enumerate() {
            let n = scene.len();
            for (i, v) in scene.vehicles.iter().enumerate() {
                if !scene.is_human(i) && v.on_ramp && v.x < self.until {
                    out[b * n + i] += self.offset;
                }
            }
        }
    }

    fn entry(&mut self, step: usize, b: usize, i: usize, live: EntryDecision) -> EntryDecision {
        let at = step * self.players + i;
        match &self.entries {
            Entries::Live => live,
            Entries::Record(log) => {
                log.lock().expect("lock")[b][at] = live;
                live
            }
            Entries::Replay(log) => log[b][at],
        }
    }
}

/// Rolls `scenes` out with every player on `net`, `offset` added before `until`.
fn run(
    config: &Config,
    net: &PolicyNet,
    scenes: &[Scene],
    (offset, until): (f64, f64),
    entries: Entries,
) -> anyhow::Result<Vec<EpisodeOutcome>> {
    let threads = if matches!(entries, Entries::Live) {
        THREADS
    } else {
        1
    };
    let opts = RolloutOptions {
        threads,
        recording: Recording::Summary,
        ..RolloutOptions::from_config(config)
    };
    let players = scenes.first().map_or(0, Scene::len);
    anyhow::ensure!(scenes.iter().all(|s| s.len() == players), "scenes of one size");
    let pool = Mutex::new(
        (0..threads)
            .map(|_| net.try_clone())
            .collect::<Result<Vec<_>, _>>()?,
    );
    Ok(rollout(config, &opts, scenes, || Offset {
        policy: PolicyActor::new(
            config,
            pool.lock().expect("lock").pop().expect("a network per thread"),
            Driver::Idm,
            true,
        ),
        offset,
        until,
        entries: entries.clone(),
        players,
    }))
}

/// The mean discounted potential of `outcomes`.
fn mean_potential(outcomes: &[EpisodeOutcome]) -> f64 {
    outcomes.iter().map(|o| o.potential_return).sum::<f64>() / outcomes.len() as f64
}

/// Each seed's test states, in mixed surroundings as sampled or with every vehicle but the ego
/// a human driver.
fn test_scenes(config: &Config, seed: u64, episodes: usize, human_only: bool) -> Vec<Scene> {
    let mut scenes = sample_scenes(config, purpose_seed(seed, Purpose::Test), 0, episodes);
    if human_only {
        for s in &mut scenes {
            s.humans = (0..s.len()).map(|i| i > 0).collect();
        }
    }
    scenes
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let config = Config::load(Path::new(
        args.get(1).map_or("configs/traffic.toml", String::as_str),
    ))?;
    let policies = args.get(2).map_or("policies/traffic/mpg", String::as_str);
    let episodes: usize = args.get(3).map_or(Ok(200), |a| a.parse())?;
    let offsets: Vec<f64> = match args.get(4..) {
        Some(v) if !v.is_empty() => v.iter().map(|a| a.parse()).collect::<Result<_, _>>()?,
        _ => vec![-0.5, 0.0, 0.5, 1.0, 2.0],
    };
    let nets = load_policies(Path::new(policies), &config, Rules::Same)?;
    let until = config.scenario.conflict_point - config.scenario.merge_zone;
    println!(
        "offset (m/s^2) | surroundings | potential | ego's return | ego merged at step | collisions | failures"
    );
    println!("---|---|---|---|---|---|---");
    for &offset in &offsets {
        for human_only in [false, true] {
            let [mut potential, mut ego, mut merged, mut collisions, mut failures] = [0.0; 5];
            for (net, side) in &nets {
                let scenes = test_scenes(&config, side.seed, episodes, human_only);
                for o in &run(&config, net, &scenes, (offset, until), Entries::Live)? {
                    potential += o.potential_return;
                    ego += o.returns[0];
                    merged += o.ego_merged_at.unwrap_or(o.steps) as f64;
                    collisions += f64::from(u8::from(o.collision.is_some()));
                    failures += f64::from(u8::from(o.collision.is_none() && o.final_scene.ego().on_ramp));
                }
            }
            let total = (episodes * nets.len()) as f64;
            println!(
                "{offset} | {} | {:.0} | {:.0} | {:.1} | {collisions} | {failures}",
                if human_only { "human-only" } else { "mixed" },
                potential / total,
                ego / total,
                merged / total,
            );
        }
    }
    println!();
    println!(
        "surroundings | seed | d potential / d offset, entry live | with the entry frozen as at offset 0"
    );
    println!("---|---|---|---");
    for human_only in [false, true] {
        for (net, side) in &nets {
            let scenes = test_scenes(&config, side.seed, episodes, human_only);
            let log = Arc::new(Mutex::new(vec![
                vec![
                    EntryDecision::default();
                    config.n_steps() * scenes[0].len()
                ];
                scenes.len()
            ]));
            run(
                &config,
                net,
                &scenes,
                (0.0, until),
                Entries::Record(Arc::clone(&log)),
            )?;
            let log = Arc::new(std::mem::take(&mut *log.lock().expect("lock")));
            let slope = |entries: &dyn Fn() -> Entries| -> anyhow::Result<f64> {
                let up = mean_potential(&run(&config, net, &scenes, (H, until), entries())?);
                let down = mean_potential(&run(&config, net, &scenes, (-H, until), entries())?);
                Ok((up - down) / (2.0 * H))
            };
            println!(
                "{} | {} | {:.0} | {:.0}",
                if human_only { "human-only" } else { "mixed" },
                side.seed,
                slope(&|| Entries::Live)?,
                slope(&|| Entries::Replay(Arc::clone(&log)))?,
            );
        }
    }
    Ok(())
}
