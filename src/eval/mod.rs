//! Evaluation: per-episode metrics of Section V, and the statistical study (Tables II-III), and the numerical check of Definition 3.

pub mod claims;
pub mod metrics;
pub mod mpg_check;
pub mod study;

pub use metrics::{EpisodeMetrics, Summary};
