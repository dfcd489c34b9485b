//! The forced-merge world: geometry, vehicle state, kinematic-bicycle dynamics (eq. 1), the TTC
//! feasibility projection and the merge gate, collisions, the initial-state sampler, non-learning drivers and the
//! batched rollout loop.

pub mod dynamics;
pub mod geometry;
pub mod idm;
pub mod merge_gate;
pub mod neighbors;
pub mod rollout;
pub mod safety;
pub mod sampler;
pub mod state;
pub mod tensor;

pub use rollout::{Actor, Driver, EpisodeOutcome, Recording, RolloutOptions, Trajectory};
pub use state::{Scene, Vehicle};
