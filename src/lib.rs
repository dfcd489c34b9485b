//! mpgdrive: a highway forced merge as a Markov potential game.
//!
//! Data flows one way: [`config`] -> [`sim`] / [`game`] (the world and its payoffs) ->
//! [`policy`] -> [`eval`]. See `DESIGN.md` and the paper (Yan and Liu, "Markov Potential Game
//! and Multi-Agent Reinforcement Learning for Autonomous Driving") for the equations.

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
