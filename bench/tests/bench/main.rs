//! The bench crate's tests, in one binary (each test binary links the whole of Bevy):
//! the library against its baselines, and the `point-springs-bench` commands end to end.

mod baselines;
mod commands;
