//! The two rollout engines over the world and the game: the scalar `f64` loop (evaluation,
//! replay of the paper's tables, the MPG check) and the batched tensor loop (training), with
//! one set of equations for both.

pub mod dual;
pub mod outcome;
pub mod rollout;
pub mod tape;
pub mod tensor;

pub use outcome::{EpisodeOutcome, Trajectory};
pub use rollout::{Actor, Recording, RolloutOptions};
