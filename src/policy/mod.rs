//! Policies: the Table I observation builder, the shared network and policy files.

pub mod drive;
pub mod ensemble;
pub mod file;
pub mod kernels;
pub mod mode;
pub mod network;
pub mod observation;

pub use ensemble::{Combine, PolicyEnsemble};
pub use mode::Mode;
pub use network::{NetSpec, PolicyNet};
pub use observation::{BatchPolicy, LinearPolicy, PolicyActor, obs_dim};
