//! Failures and the exit codes they map to: 2 for bad input (an unreadable or malformed
//! file, a bad argument), 3 for a simulation that could not be kept finite, 1 for any other
//! failure (e.g. the output cannot be written).

use std::fmt::Display;
use std::process::ExitCode;

/// Exit code for bad input.
const EXIT_BAD_INPUT: u8 = 2;
/// Exit code for other failures.
const EXIT_FAILURE: u8 = 1;
/// Exit code for a simulation the guard had to step in for.
const EXIT_UNSTABLE: u8 = 3;

/// A failure and the exit code it maps to.
#[derive(Debug)]
pub struct Failure {
    /// What went wrong, for standard error.
    message: String,
    /// The process's exit code.
    code: u8,
}

impl Failure {
    /// Bad input: an unreadable or malformed file, a bad argument (exit code 2).
    pub fn bad_input(e: impl Display) -> Self {
        Self {
            message: e.to_string(),
            code: EXIT_BAD_INPUT,
        }
    }

    /// Any other failure, e.g. an output that cannot be written (exit code 1).
    pub fn other(e: impl Display) -> Self {
        Self {
            message: e.to_string(),
            code: EXIT_FAILURE,
        }
    }

    /// A simulation that went unstable: the guard restored its state at least once (exit
    /// code 3).
    pub fn unstable(e: impl Display) -> Self {
        Self {
            message: e.to_string(),
            code: EXIT_UNSTABLE,
        }
    }

    /// Prints the message to standard error and gives the exit code.
    pub fn exit(self) -> ExitCode {
        eprintln!("{}: {}", env!("CARGO_BIN_NAME"), self.message);
        ExitCode::from(self.code)
    }
}
