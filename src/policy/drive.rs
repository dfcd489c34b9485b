//! Driving scenarios with trained networks in the scalar engine.

use crate::config::Config;
use crate::engine::outcome::EpisodeOutcome;
use crate::engine::rollout::{Recording, RolloutOptions, rollout};
use crate::policy::ensemble::PolicyEnsemble;
use crate::policy::network::PolicyNet;
use crate::policy::observation::PolicyActor;
use crate::world::drivers::Driver;
use crate::world::state::Scene;
use std::sync::Mutex;

/// Who drives the players other than the ego.
#[derive(Debug, Clone, Copy)]
pub enum Others<'a> {
    /// The ego's network too (parameter sharing).
    SameNetwork,
    /// Another network.
    Network(&'a PolicyNet),
    /// A non-learning driver.
    Driver(Driver),
}

/// `n` copies of `net` on the plain-Rust forward pass ([`PolicyEnsemble`] of one member).
fn copies(net: &PolicyNet, n: usize) -> Result<Vec<PolicyEnsemble>, tch::TchError> {
    (0..n)
        .map(|_| net.try_clone().map(PolicyEnsemble::from))
        .collect()
}

/// Rolls `scenes` out with the network driving the ego and `others` the other players,
/// keeping what `recording` says. Each worker thread gets its own copies of the networks, run
/// by the plain-Rust forward pass of deployment (the same actions as libtorch's within 1e-5
/// m/s^2, and the same bits whatever the batch or the processor).
pub fn policy_rollout(
    config: &Config,
    net: &PolicyNet,
    others: Others,
    scenes: &[Scene],
    threads: usize,
    recording: Recording,
) -> Result<Vec<EpisodeOutcome>, tch::TchError> {
    let threads = threads.clamp(1, scenes.len().max(1));
    let second: Vec<Option<PolicyEnsemble>> = match others {
        Others::Network(o) => copies(o, threads)?.into_iter().map(Some).collect(),
        _ => (0..threads).map(|_| None).collect(),
    };
    let pool = Mutex::new(copies(net, threads)?.into_iter().zip(second).collect::<Vec<_>>());
    // Resolved here: the closure runs on worker threads and may not hold a network reference.
    let driver = match others {
        Others::Driver(d) => Some(d),
        _ => None,
    };
    let opts = RolloutOptions {
        threads,
        recording,
        ..RolloutOptions::from_config(config)
    };
    Ok(rollout(config, &opts, scenes, || {
        let (ego, second) = pool
            .lock()
            .expect("pool lock")
            .pop()
            .expect("networks for each thread");
        match (driver, second) {
            (Some(d), _) => PolicyActor::new(config, ego, d, false),
            (None, Some(o)) => PolicyActor::with_others_policy(config, ego, o),
            (None, None) => PolicyActor::new(config, ego, Driver::Idm, true),
        }
    }))
}
