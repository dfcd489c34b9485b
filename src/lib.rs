//! mpgdrive: a highway forced merge as a Markov potential game.
//!
//! The modules form layers, each using only those below it: [`atomic`] and [`num`] ->
//! [`config`] -> [`world`] -> [`game`] -> [`engine`] -> [`policy`] -> [`eval`] -> [`train`] ->
//! [`render`] -> [`ngsim`] / [`sumo`] / [`report`] -> [`batch`] -> [`exit`].
//! `docs/ARCHITECTURE.md` draws them, maps the paper's equations to the code and follows the
//! data through each command; `tests/architecture.rs` enforces the order. The paper is Yan and
//! Liu, "Markov Potential Game and Multi-Agent Reinforcement Learning for Autonomous Driving".

#![warn(missing_docs)]

pub mod atomic;
pub mod batch;
pub mod config;
pub mod engine;
pub mod eval;
pub mod exit;
pub mod game;
pub mod ngsim;
pub mod num;
pub mod policy;
pub mod render;
pub mod report;
pub mod sumo;
pub mod train;
pub mod world;

pub use config::{Config, ConfigError};

/// Version of this crate, recorded with results.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
