//! Evaluation: per-episode metrics of Section V, the statistical study (Tables II-III), the
//! internal traffic study, the paper's claims, and the numerical check of Definition 3.

pub mod claims;
pub mod metrics;
pub mod mpg_check;
pub mod scenario_sets;
pub mod study;
pub mod traffic_study;

pub use metrics::{EpisodeMetrics, Summary};
