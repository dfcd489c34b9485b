//! Policies: the Table I observation builder, the shared network and policy files.

pub mod drive;
pub mod file;
pub mod network;
pub mod observation;

pub use network::{NetSpec, PolicyNet};
pub use observation::{BatchPolicy, LinearPolicy, PolicyActor, obs_dim};
