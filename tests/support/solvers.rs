//! Solvers shared by the solver's tests (`tests/dynamics.rs`, `tests/stability.rs`),
//! included by path: Cargo does not build files in a folder under `tests/` as tests of
//! their own.

use std::f64::consts::PI;

use bevy_point_springs::core::solver::cloth::cloth_grid;
use bevy_point_springs::core::solver::{
    Integrator, Solver, SolverConfig, SpringSpec, SubstepPolicy,
};
use glam::Vec3;

/// A spring between points `a` and `b`.
pub fn spring(a: u32, b: u32, rest_length: f32, stiffness: f32, damping: f32) -> SpringSpec {
    SpringSpec {
        a,
        b,
        rest_length,
        stiffness,
        damping,
    }
}

/// `integrator` without gravity.
pub fn config(integrator: Integrator) -> SolverConfig {
    SolverConfig {
        integrator,
        gravity: Vec3::ZERO,
        ..SolverConfig::default()
    }
}

/// Mass, stiffness (ω₀ = 2π) and damping (γ = k_d/m = 0.5) of the oscillator.
pub const OSC_MASS: f32 = 1.0;
pub const OSC_STIFFNESS: f32 = (4.0 * PI * PI) as f32;
pub const OSC_DAMPING: f32 = 0.5;
pub const OSC_AMPLITUDE: f64 = 0.1;

/// One free point on a spring (rest length 1) to a fixed point, pulled out by the amplitude.
pub fn oscillator(integrator: Integrator) -> Solver {
    let positions = [Vec3::ZERO, Vec3::new(1.0 + OSC_AMPLITUDE as f32, 0.0, 0.0)];
    let springs = [spring(0, 1, 1.0, OSC_STIFFNESS, OSC_DAMPING)];
    let mut s = Solver::new(
        &positions,
        &[OSC_MASS; 2],
        &springs,
        SolverConfig {
            substeps: SubstepPolicy::Unchecked,
            ..config(integrator)
        },
    )
    .unwrap();
    s.set_fixed(0, true).unwrap();
    s
}

/// A solver on the benchmark's `size` × `size` cloth grid, 0.1 kg per point, each spring
/// changed by `spring`, the corner points held when `held`.
pub fn cloth_solver(
    size: usize,
    spring: impl Fn(SpringSpec) -> SpringSpec,
    config: SolverConfig,
    held: bool,
) -> Solver {
    let grid = cloth_grid(size).unwrap();
    let springs: Vec<SpringSpec> = grid.springs.iter().map(|&s| spring(s)).collect();
    let mut s = Solver::new(
        &grid.positions,
        &vec![0.1; grid.positions.len()],
        &springs,
        config,
    )
    .unwrap();
    if held {
        for i in grid.fixed {
            s.set_fixed(i as usize, true).unwrap();
        }
    }
    s
}
