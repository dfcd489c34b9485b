//! Which controller drives the ramp egos in a co-simulation: one of the two learned policies
//! ([`Mode`]) or SUMO's own drivers.

use crate::policy::mode::Mode;
use serde::Serialize;

/// Who drives the egos (and players).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum ControllerKind {
    /// The MARL (MPG) policy drives the ego and the players `merge.toml`'s `players` names.
    Mpg,
    /// The single-agent policy drives the ego only.
    Sarl,
    /// No override: SUMO's own car-following and lane changing (metrics only).
    Sumo,
}

impl ControllerKind {
    /// The name used on the command line and in tables.
    pub fn name(self) -> &'static str {
        match self.mode() {
            Some(mode) => mode.as_str(),
            None => "sumo",
        }
    }

    /// The learned policy this controller deploys (none for SUMO's drivers).
    pub fn mode(self) -> Option<Mode> {
        match self {
            ControllerKind::Mpg => Some(Mode::Mpg),
            ControllerKind::Sarl => Some(Mode::Sarl),
            ControllerKind::Sumo => None,
        }
    }
}
