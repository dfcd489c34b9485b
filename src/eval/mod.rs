//! Evaluation: per-episode metrics of Section V, and the statistical study (Tables II-III).

pub mod metrics;
pub mod study;

pub use metrics::{EpisodeMetrics, Summary};
