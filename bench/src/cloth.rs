//! `point-springs-bench cloth-grid`: the standard CPU cloth benchmark, the solver timed
//! against the straightforward loop over the springs in the same run.

use std::fmt;
use std::time::Instant;

use bevy_point_springs::core::solver::cloth::{CLOTH_DT, CLOTH_SIZE, CLOTH_STEPS, cloth_grid};
use bevy_point_springs::core::solver::{Integrator, Solver, SubstepPolicy};
use point_springs_bench::baselines::cloth::{ReferenceCloth, max_sag};
use serde::Serialize;

use crate::failure::Failure;
use crate::flags::JsonFlag;
use crate::report::Report;

/// Arguments of `point-springs-bench cloth-grid`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Particles per side.
    #[arg(long, default_value_t = CLOTH_SIZE)]
    size: usize,
    /// Steps per run.
    #[arg(long, default_value_t = CLOTH_STEPS)]
    steps: usize,
    /// Integrator (the benchmark's is symplectic-euler; others take the same dt as
    /// given).
    #[arg(long, default_value_t = Integrator::SymplecticEuler)]
    integrator: Integrator,
    /// Timed runs of each, alternating between the solver and the reference; the
    /// fastest of each counts.
    #[arg(long, default_value_t = 5)]
    repeat: usize,
    /// Skip the straightforward reference loop.
    #[arg(long)]
    no_reference: bool,
    #[command(flatten)]
    json: JsonFlag,
}

/// What `point-springs-bench cloth-grid` reports.
#[derive(Debug, Serialize)]
struct ClothBenchReport {
    /// "cloth-grid".
    benchmark: &'static str,
    /// Particles.
    particles: usize,
    /// Springs.
    springs: usize,
    /// Of those, springs the solver steps in vectorised runs.
    springs_in_runs: usize,
    /// Steps per run.
    steps: usize,
    /// The step, s.
    dt: f32,
    /// The integrator.
    integrator: String,
    /// The solver's fastest run, µs per step.
    us_per_step: f64,
    /// The solver's largest sag at the end.
    max_sag: f32,
    /// No guard trip and every position finite.
    finite: bool,
    /// Conjugate-gradient iterations of the last run.
    cg_iterations: u64,
    /// The reference's fastest run, µs per step.
    reference_us_per_step: Option<f64>,
    /// The reference's largest sag at the end.
    reference_max_sag: Option<f32>,
    /// |solver's sag − reference's|.
    sag_difference: Option<f32>,
    /// The largest distance between their final positions.
    max_position_difference: Option<f32>,
    /// Reference time / solver time.
    speedup: Option<f64>,
}

impl fmt::Display for ClothBenchReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "cloth-grid    {} particles, {} springs ({} in vectorised runs), {} steps of {:.6} s, {}",
            self.particles,
            self.springs,
            self.springs_in_runs,
            self.steps,
            self.dt,
            self.integrator
        )?;
        writeln!(
            f,
            "solver        {:.2} µs/step, max sag {:.6}",
            self.us_per_step, self.max_sag
        )?;
        if let (Some(t), Some(s), Some(d), Some(x)) = (
            self.reference_us_per_step,
            self.reference_max_sag,
            self.speedup,
            self.max_position_difference,
        ) {
            writeln!(f, "reference     {t:.2} µs/step, max sag {s:.6}")?;
            writeln!(
                f,
                "speedup       {d:.2}×; final positions differ by at most {x:.2e}"
            )?;
        }
        Ok(())
    }
}

impl Report for ClothBenchReport {}

/// A state that can be stepped and timed.
struct Timed<S, F> {
    /// Makes a fresh state.
    fresh: F,
    /// Steps a state.
    step: fn(&mut S),
    /// The fastest run so far, µs per step.
    best: f64,
    /// The final state of the last run.
    last: Option<S>,
}

impl<S, F: FnMut() -> S> Timed<S, F> {
    /// Timing of `step` from states `fresh` makes.
    fn new(fresh: F, step: fn(&mut S)) -> Self {
        Self {
            fresh,
            step,
            best: f64::INFINITY,
            last: None,
        }
    }

    /// One timed run of `steps` steps from a fresh state; keeps the fastest microseconds
    /// per step.
    fn round(&mut self, steps: usize) {
        let mut state = (self.fresh)();
        let start = Instant::now();
        for _ in 0..steps {
            (self.step)(&mut state);
        }
        let us = start.elapsed().as_secs_f64() * 1e6 / steps.max(1) as f64;
        self.best = self.best.min(us);
        self.last = Some(state);
    }

    /// The fastest microseconds per step and the final state of the last run.
    fn finish(mut self) -> (f64, S) {
        let last = self.last.take().unwrap_or_else(|| (self.fresh)());
        (self.best, last)
    }
}

/// Runs `point-springs-bench cloth-grid`.
pub fn run(args: &Args) -> Result<(), Failure> {
    let grid = cloth_grid(args.size).map_err(Failure::bad_input)?;
    let solver = grid
        .solver_with(args.integrator, SubstepPolicy::Unchecked)
        .map_err(Failure::bad_input)?;
    // Rounds alternate between the two, so that both see the same machine (the other
    // core's load and the clock drift over seconds here); the fastest round of each counts.
    let mut timed_solver = Timed::new(
        || solver.clone(),
        // The step is valid by construction; a guard trip shows in `finite` and the
        // diagnostics.
        |s: &mut Solver| {
            let _ = s.step(CLOTH_DT);
        },
    );
    let mut timed_reference = (!args.no_reference).then(|| {
        Timed::new(
            || ReferenceCloth::new(&grid),
            |r: &mut ReferenceCloth| r.step(CLOTH_DT),
        )
    });
    for _ in 0..args.repeat.max(1) {
        timed_solver.round(args.steps);
        if let Some(r) = &mut timed_reference {
            r.round(args.steps);
        }
    }
    let (us_per_step, solver) = timed_solver.finish();
    let positions = solver.positions();
    let sag = max_sag(&grid.positions, &positions);
    let diagnostics = solver.diagnostics();
    let reference = timed_reference.map(Timed::finish);
    let reference_sag = reference
        .as_ref()
        .map(|(_, r)| max_sag(&grid.positions, &r.x));
    let report = ClothBenchReport {
        benchmark: "cloth-grid",
        particles: solver.len(),
        springs: solver.spring_count(),
        springs_in_runs: solver.springs_in_runs(),
        steps: args.steps,
        dt: CLOTH_DT,
        integrator: args.integrator.to_string(),
        us_per_step,
        max_sag: sag,
        finite: diagnostics.guard_trips == 0 && positions.iter().all(|p| p.is_finite()),
        cg_iterations: diagnostics.cg_iterations,
        reference_us_per_step: reference.as_ref().map(|(t, _)| *t),
        reference_max_sag: reference_sag,
        sag_difference: reference_sag.map(|r| (r - sag).abs()),
        max_position_difference: reference.as_ref().map(|(_, r)| {
            r.x.iter()
                .zip(&positions)
                .map(|(a, b)| a.distance(*b))
                .fold(0.0, f32::max)
        }),
        speedup: reference.as_ref().map(|(t, _)| t / us_per_step),
    };
    args.json.emit(&report)
}
