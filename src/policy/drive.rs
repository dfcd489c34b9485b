//! Driving scenarios with a trained network in the scalar engine.

use crate::config::Config;
use crate::policy::network::PolicyNet;
use crate::policy::observation::PolicyActor;
use crate::sim::rollout::{Driver, EpisodeOutcome, RolloutOptions, rollout};
use crate::sim::state::Scene;
use std::sync::Mutex;

/// Rolls `scenes` out with the network driving the ego (and every player when `all_players`),
/// the rest driven by `others`. Each worker thread gets its own copy of the network.
pub fn policy_rollout(
    config: &Config,
    net: &PolicyNet,
    all_players: bool,
    others: Driver,
    scenes: &[Scene],
    threads: usize,
) -> Result<Vec<EpisodeOutcome>, tch::TchError> {
    let threads = threads.clamp(1, scenes.len().max(1));
    let pool = Mutex::new(
        (0..threads)
            .map(|_| net.try_clone())
            .collect::<Result<Vec<_>, _>>()?,
    );
    let opts = RolloutOptions {
        threads,
        ..RolloutOptions::from_config(config)
    };
    Ok(rollout(config, &opts, scenes, || {
        let copy = pool
            .lock()
            .expect("pool lock")
            .pop()
            .expect("one network per thread");
        PolicyActor::new(config, copy, others, all_players)
    }))
}
