//! The Markov potential game: reward terms (Section V-iii), per-agent rewards `r_i`, the
//! potential `phi` of Theorem 3, and the numerical check of Definition 3.

pub mod reward;
pub mod terms;

pub use reward::{PairReward, PairTerms, PaperReward, StepRewards, TermValues};
