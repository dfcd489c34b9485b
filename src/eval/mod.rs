//! Evaluation: per-episode metrics of Section V and their aggregation.

pub mod metrics;

pub use metrics::{EpisodeMetrics, Summary};
