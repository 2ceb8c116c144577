//! Failures and the exit codes they map to: 2 for bad input (an unreadable or malformed
//! file, a bad argument), 1 for any other failure (e.g. the output cannot be written).

use std::fmt::Display;
use std::process::ExitCode;

/// Exit code for bad input.
const EXIT_BAD_INPUT: u8 = 2;
/// Exit code for other failures.
const EXIT_FAILURE: u8 = 1;

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

    /// Prints the message to standard error and gives the exit code.
    pub fn exit(self) -> ExitCode {
        eprintln!("point-springs: {}", self.message);
        ExitCode::from(self.code)
    }
}
