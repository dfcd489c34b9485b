//! Exit codes, by one rule: an error the user can fix (a bad config, argument, input file,
//! policy or SUMO input) exits with 2; a failure of the tool or the machine (libtorch, a
//! write that failed, a diverged training) exits with 1.
//!
//! Each library error type says which of its variants are the user's to fix
//! ([`UserFacing`]); [`exit_code`] looks for them along an error's chain of causes, so context
//! added on the way up does not change the code.

use std::error::Error;

/// Errors that know whether they are the user's to fix.
pub trait UserFacing {
    /// True when the input (configuration, arguments, files, policy, SUMO's inputs) is what
    /// is wrong, false when the tool or the machine failed.
    fn is_user_error(&self) -> bool;
}

/// An error in the command's arguments or inputs, found by the command itself.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct UsageError(pub String);

impl UserFacing for UsageError {
    fn is_user_error(&self) -> bool {
        true
    }
}

impl UserFacing for crate::config::ConfigError {
    fn is_user_error(&self) -> bool {
        true
    }
}

impl UserFacing for crate::policy::file::PolicyError {
    fn is_user_error(&self) -> bool {
        true // a missing, foreign or mismatched policy file
    }
}

impl UserFacing for crate::policy::ensemble::EnsembleError {
    fn is_user_error(&self) -> bool {
        true // policies of one directory that do not fit together
    }
}

impl UserFacing for crate::eval::study::EvalError {
    fn is_user_error(&self) -> bool {
        use crate::eval::study::EvalError as E;
        match self {
            E::Policy(e) => e.is_user_error(),
            E::NoPolicy(_) | E::List { .. } | E::NeedNePolicy { .. } => true,
            E::Torch(_) => false,
        }
    }
}

impl UserFacing for crate::train::TrainError {
    fn is_user_error(&self) -> bool {
        use crate::train::TrainError as E;
        match self {
            E::Policy(e) => e.is_user_error(),
            E::ForeignCheckpoint { .. } | E::OptimiserState { .. } => true,
            E::Io { .. } | E::Interrupted { .. } | E::Diverged { .. } | E::Torch(_) => false,
        }
    }
}

impl UserFacing for crate::sumo::SumoError {
    fn is_user_error(&self) -> bool {
        use crate::sumo::SumoError as E;
        match self {
            // SUMO's own message names what is wrong in its inputs.
            E::Sumo { .. } | E::Nul(_) => true,
            E::AlreadyRunning => false,
        }
    }
}

#[cfg(feature = "sumo")]
impl UserFacing for crate::sumo::cosim::CosimError {
    fn is_user_error(&self) -> bool {
        use crate::sumo::cosim::CosimError as E;
        match self {
            E::Sumo(e) => e.is_user_error(),
            // An output SUMO did not write comes from the configuration it was given.
            E::Geometry { .. } | E::StepLength { .. } | E::Output { .. } => true,
        }
    }
}

impl UserFacing for crate::sumo::inputs::InputError {
    fn is_user_error(&self) -> bool {
        true // a SUMO input (configuration, network, routes, merge.toml) that does not fit
    }
}

impl UserFacing for crate::ngsim::load::NgsimError {
    fn is_user_error(&self) -> bool {
        true // a missing or malformed data file
    }
}

impl UserFacing for crate::ngsim::smooth::SmoothError {
    fn is_user_error(&self) -> bool {
        true // smoothing parameters from the configuration
    }
}

impl UserFacing for crate::batch::routes::RoutesError {
    fn is_user_error(&self) -> bool {
        true // a missing or malformed base file, or a bad demand description
    }
}

impl UserFacing for crate::render::RenderError {
    fn is_user_error(&self) -> bool {
        false
    }
}

/// The library error `e` is, if it is one.
fn user_facing<'a>(e: &'a (dyn Error + 'static)) -> Option<&'a dyn UserFacing> {
    macro_rules! first_of {
        ($($t:ty),* $(,)?) => {
            None $(.or_else(|| e.downcast_ref::<$t>().map(|x| x as &dyn UserFacing)))*
        };
    }
    #[cfg(feature = "sumo")]
    if let Some(x) = e.downcast_ref::<crate::sumo::cosim::CosimError>() {
        return Some(x);
    }
    first_of!(
        UsageError,
        crate::config::ConfigError,
        crate::policy::file::PolicyError,
        crate::policy::ensemble::EnsembleError,
        crate::eval::study::EvalError,
        crate::train::TrainError,
        crate::sumo::SumoError,
        crate::sumo::inputs::InputError,
        crate::ngsim::load::NgsimError,
        crate::ngsim::smooth::SmoothError,
        crate::batch::routes::RoutesError,
        crate::render::RenderError,
    )
}

/// 2 when the first library error along `e`'s chain of causes is the user's to fix, else 1
/// (also when the chain holds no library error: an I/O error on the way, say).
pub fn exit_code(e: &(dyn Error + 'static)) -> u8 {
    let mut next = Some(e);
    while let Some(cause) = next {
        if let Some(known) = user_facing(cause) {
            return if known.is_user_error() { 2 } else { 1 };
        }
        next = cause.source();
    }
    1
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::policy::file::PolicyError;
    use crate::train::TrainError;

    /// Context added on the way up, as a command adds it.
    #[derive(Debug, thiserror::Error)]
    #[error("while doing something")]
    struct Context(#[source] Box<dyn Error + Send + Sync>);

    #[test]
    fn user_errors_exit_2_and_failures_1_through_any_context() {
        let foreign = TrainError::ForeignCheckpoint {
            path: "x.ckpt".into(),
            message: "seed 1".into(),
        };
        let diverged = TrainError::Diverged {
            seed: 0,
            epoch: 3,
            value: f64::NAN,
        };
        let mismatch = || PolicyError::Mismatch {
            path: "p.json".into(),
            message: "dt".into(),
        };
        assert_eq!(exit_code(&foreign), 2);
        assert_eq!(exit_code(&diverged), 1);
        assert_eq!(exit_code(&TrainError::Policy(mismatch())), 2);
        assert_eq!(exit_code(&Context(Box::new(mismatch()))), 2);
        assert_eq!(exit_code(&Context(Box::new(diverged))), 1);
        assert_eq!(exit_code(&UsageError("--jobs must be at least 1".into())), 2);
        assert_eq!(exit_code(&crate::sumo::SumoError::AlreadyRunning), 1);
        // No library error in the chain: the tool failed.
        let io = std::io::Error::other("disk full");
        assert_eq!(exit_code(&Context(Box::new(io))), 1);
    }
}
