//! What a policy learned: the shared MPG policy or the single-agent baseline. One enum for the
//! command line, training, the policy sidecar (`"mode": "mpg"`) and evaluation.

use serde::{Deserialize, Serialize};

/// What is learned.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// Shared policy for every player, maximising the potential.
    Mpg,
    /// Ego policy only, maximising the ego's return, the others on IDM.
    Sarl,
}

impl Mode {
    /// Lower-case name ("mpg" or "sarl"), as serialized.
    pub fn as_str(self) -> &'static str {
        match self {
            Mode::Mpg => "mpg",
            Mode::Sarl => "sarl",
        }
    }
}
