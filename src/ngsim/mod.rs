//! NGSIM I-80 naturalistic data: loading both official layouts (feet to metres at the
//! boundary), processing (Savitzky-Golay smoothing, recomputed speed and acceleration,
//! reassigned lanes), merge-scenario extraction, replay against the human drivers (Table IV),
//! and synthetic files in the official layouts for tests and benchmarks.

pub mod config;
pub mod load;
pub mod process;
pub mod replay;
pub mod scenario;
pub mod smooth;
pub mod synth;
