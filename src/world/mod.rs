//! The forced-merge world: geometry, vehicle state, kinematic-bicycle dynamics (eq. 1), the TTC
//! feasibility projection and the merge gate, collisions, the world's rules as one value, the
//! initial-state samplers (the paper's and merge traffic), the paper's specific scenarios and the
//! non-learning drivers.

pub mod drivers;
pub mod dynamics;
pub mod geometry;
pub mod idm;
pub mod merge_gate;
pub mod neighbors;
pub mod rules;
pub mod safety;
pub mod sampler;
pub mod scenarios;
pub mod state;
pub mod step;
pub mod traffic;

pub use drivers::Driver;
pub use rules::WorldRules;
pub use state::{Scene, Vehicle};
