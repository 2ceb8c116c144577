//! The baselines `point-springs-bench` and the criterion benches time bevy_point_springs
//! against: the straightforward and the literal versions of what the library does faster.
//! Not for use in a game (they are slow on purpose); `tests/baselines.rs` checks that the
//! library gives their answers, so the timings compare like with like.

pub mod baselines;
