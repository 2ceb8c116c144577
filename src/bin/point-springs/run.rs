//! `point-springs run`: run a scene file headless (load, simplify, simulate, transfer the
//! motion back to every dense point) and write the deformed surface.

use std::fmt;
use std::path::PathBuf;
use std::time::Instant;

use bevy_point_springs::core::scene::{Deformed, Scene, SceneRun};
use glam::Vec3;
use serde::Serialize;

use crate::args::{JsonFlag, PlyFlag, parse_vec3};
use crate::failure::Failure;
use crate::picture::{self, View};
use crate::report::Report;

/// Arguments of `run`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene (.ron); its cloud path is relative to it.
    scene: PathBuf,
    /// Write the deformed dense surface to this PLY file.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Draw the surface at rest and deformed, side by side, to this PNG file.
    #[arg(long)]
    png: Option<PathBuf>,
    /// Direction from the surface towards the eye for --png.
    #[arg(long, value_parser = parse_vec3, default_value = "1,0.8,1.6")]
    view: Vec3,
    /// Up on the picture for --png.
    #[arg(long, value_parser = parse_vec3, default_value = "0,1,0")]
    up: Vec3,
    #[command(flatten)]
    ply: PlyFlag,
    #[command(flatten)]
    json: JsonFlag,
}

/// Size of `run --png` pictures (two panels), pixels.
const PICTURE_WIDTH: u32 = 1400;
/// Their height, pixels.
const PICTURE_HEIGHT: u32 = 700;

/// What `run` reports.
#[derive(Debug, Serialize)]
struct RunReport {
    /// The scene file.
    scene: String,
    /// The PLY file written, if any.
    output: Option<String>,
    /// The PNG file written, if any.
    png: Option<String>,
    /// Dense points at the end (with those resampling added).
    dense_points: usize,
    /// Dense points at rest.
    dense_points_at_rest: usize,
    /// Simulation points.
    sim_points: usize,
    /// Springs the solver steps.
    springs: usize,
    /// Stretch springs.
    stretch_springs: usize,
    /// Bend springs.
    bend_springs: usize,
    /// Simulation points held by pins.
    pinned_points: usize,
    /// Simulation points grabbed by each pull.
    pulled_points: Vec<usize>,
    /// Steps run.
    steps: usize,
    /// The step, s.
    dt: f32,
    /// The integrator.
    integrator: String,
    /// Solver sub-steps.
    substeps: u64,
    /// Conjugate-gradient iterations.
    cg_iterations: u64,
    /// Times the solver's guard restored the state.
    guard_trips: u64,
    /// Steps whose sub-step count hit the cap.
    limited_steps: u64,
    /// Preparation time, ms.
    ms_prepare: f64,
    /// Simulation time per step, ms.
    ms_per_step: f64,
    /// Time of the final transfer, ms.
    ms_transfer: f64,
    /// Time of the resampling over the run, ms.
    ms_resample: f64,
    /// The largest dense point's displacement.
    max_displacement: f32,
    /// The solver's total energy at the end.
    energy_final: f64,
    /// No guard trip, and the energy and the deformed surface finite.
    finite: bool,
    /// Dense points resampling added.
    resampled_points: usize,
}

impl fmt::Display for RunReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "scene         {} ({} steps of {} s, {})",
            self.scene, self.steps, self.dt, self.integrator
        )?;
        writeln!(
            f,
            "surface       {} dense points at rest, {} simulation points, {} springs ({} pinned)",
            self.dense_points_at_rest, self.sim_points, self.springs, self.pinned_points
        )?;
        writeln!(
            f,
            "simulation    {:.3} ms per step ({} sub-steps, {} CG iterations, {} guard trips)",
            self.ms_per_step, self.substeps, self.cg_iterations, self.guard_trips
        )?;
        writeln!(
            f,
            "transfer      {:.2} ms (+ {:.2} ms resampling: {} points added)",
            self.ms_transfer, self.ms_resample, self.resampled_points
        )?;
        writeln!(
            f,
            "result        largest displacement {:.4}, energy {:.4e}, finite: {}",
            self.max_displacement, self.energy_final, self.finite
        )?;
        for out in self.output.iter().chain(&self.png) {
            writeln!(f, "written       {out}")?;
        }
        Ok(())
    }
}

impl Report for RunReport {}

/// How long the stages of `run` took, s.
#[derive(Debug, Clone, Copy)]
struct Seconds {
    /// Loading the cloud and preparing the surface.
    prepare: f64,
    /// Stepping the solver, over the run.
    simulate: f64,
    /// Resampling, over the run.
    resample: f64,
    /// The final transfer.
    transfer: f64,
}

/// Runs `run`.
pub fn run(args: &Args) -> Result<(), Failure> {
    let view = args
        .png
        .as_ref()
        .map(|_| View::checked(args.view, args.up, (PICTURE_WIDTH, PICTURE_HEIGHT)))
        .transpose()?;
    let (scene, base) = Scene::load(&args.scene).map_err(Failure::bad_input)?;
    let start = Instant::now();
    let mut scene_run = scene.prepare(&base).map_err(Failure::bad_input)?;
    let prepare = start.elapsed().as_secs_f64();
    let (simulate, resample) = simulate(&mut scene_run, scene.steps)?;
    let energy = scene_run.solver().energy().total();
    let start = Instant::now();
    let deformed = scene_run.deformed().map_err(Failure::other)?;
    let transfer = start.elapsed().as_secs_f64();
    if let Some(out) = &args.output {
        args.ply.write(out, &deformed.cloud)?;
    }
    if let (Some(path), Some(view)) = (&args.png, &view) {
        picture::render(&[&scene_run.rest, &deformed.cloud], view, path).map_err(Failure::other)?;
    }
    let seconds = Seconds {
        prepare,
        simulate,
        resample,
        transfer,
    };
    let report = report(args, &scene, &scene_run, &deformed, energy, seconds);
    args.json.emit(&report)
}

/// Steps `run` to its end, showing progress on a terminal; the seconds spent stepping and
/// resampling.
fn simulate(run: &mut SceneRun, total: usize) -> Result<(f64, f64), Failure> {
    use std::io::{IsTerminal, Write};
    let tty = std::io::stderr().is_terminal();
    let (mut simulate_seconds, mut resample_seconds) = (0.0, 0.0);
    while !run.finished() {
        let start = Instant::now();
        run.simulate().map_err(Failure::other)?;
        let middle = Instant::now();
        run.maintain().map_err(Failure::other)?;
        simulate_seconds += (middle - start).as_secs_f64();
        resample_seconds += middle.elapsed().as_secs_f64();
        let step = run.step_count();
        if tty && (step.is_multiple_of(10) || step == total) {
            let _ = write!(std::io::stderr(), "\rrun: step {step} of {total}   ");
            let _ = std::io::stderr().flush();
        }
    }
    if tty {
        eprintln!();
    }
    Ok((simulate_seconds, resample_seconds))
}

/// The report of `run`, from the finished run and its final `energy`.
fn report(
    args: &Args,
    scene: &Scene,
    run: &SceneRun,
    deformed: &Deformed,
    energy: f64,
    seconds: Seconds,
) -> RunReport {
    let d = *run.solver().diagnostics();
    let finite = d.guard_trips == 0
        && energy.is_finite()
        && deformed
            .cloud
            .positions()
            .iter()
            .chain(deformed.cloud.normals().unwrap_or_default())
            .all(|v| v.is_finite());
    let r = &run.surface.network.report;
    RunReport {
        scene: args.scene.display().to_string(),
        output: args.output.as_ref().map(|p| p.display().to_string()),
        png: args.png.as_ref().map(|p| p.display().to_string()),
        dense_points: deformed.cloud.len(),
        dense_points_at_rest: run.rest.len(),
        sim_points: r.points,
        springs: run.solver().spring_count(),
        stretch_springs: r.stretch_springs,
        bend_springs: r.bend_springs,
        pinned_points: run.pinned,
        pulled_points: run.timeline.pulled_points(),
        steps: run.step_count(),
        dt: scene.dt,
        integrator: scene.solver.integrator.to_string(),
        substeps: d.substeps,
        cg_iterations: d.cg_iterations,
        guard_trips: d.guard_trips,
        limited_steps: d.limited_steps,
        ms_prepare: seconds.prepare * 1e3,
        ms_per_step: seconds.simulate * 1e3 / run.step_count().max(1) as f64,
        ms_transfer: seconds.transfer * 1e3,
        ms_resample: seconds.resample * 1e3,
        max_displacement: deformed.max_displacement,
        energy_final: energy,
        finite,
        resampled_points: run.resampled().inserted,
    }
}
