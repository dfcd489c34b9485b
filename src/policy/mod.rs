//! Policies: the Table I observation builder and the batched policy interface.

pub mod observation;

pub use observation::{BatchPolicy, LinearPolicy, PolicyActor, obs_dim};
