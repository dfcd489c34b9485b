//! SUMO co-simulation: a C++ shim over libsumo/libtraci (`shim.h`, `shim.cpp`, bindings made by
//! `build.rs`), a safe single-simulation handle, merge geometry per network, and the co-sim
//! controller that lets a trained policy drive ramp vehicles and their players in SUMO traffic.
//!
//! The FFI parts need the `sumo` cargo feature (on by default).

pub mod build;
#[cfg(feature = "sumo")]
pub mod controller;
#[cfg(feature = "sumo")]
pub mod cosim;
#[cfg(feature = "sumo")]
mod ffi;
pub mod geometry;
#[cfg(feature = "sumo")]
pub mod handle;
pub mod inputs;
pub mod inspect;
pub mod kind;
pub mod positions;
pub mod profile;
pub mod ssm;

#[cfg(feature = "sumo")]
pub use controller::{ControlModes, Controller, EgoRecord};
pub use geometry::MergeGeometry;
#[cfg(feature = "sumo")]
pub use handle::{Backend, Collision, NewVehicle, Sumo, VehicleState};
pub use kind::ControllerKind;
pub use positions::{CrossingLane, LanePositions};

/// Errors of the SUMO layer.
#[derive(Debug, thiserror::Error)]
pub enum SumoError {
    /// SUMO (or the shim) refused a call; `message` is SUMO's own.
    #[error("SUMO error in {call}: {message}")]
    Sumo {
        /// The call that failed.
        call: &'static str,
        /// SUMO's message.
        message: String,
    },
    /// libsumo holds one simulation per process.
    #[error("a SUMO simulation is already running in this process (libsumo allows one at a time)")]
    AlreadyRunning,
    /// A string with an interior NUL cannot cross to C++.
    #[error("id or argument contains a NUL byte: {0:?}")]
    Nul(String),
}
