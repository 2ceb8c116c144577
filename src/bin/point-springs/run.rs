//! `point-springs run`: run a scene file headless (load, simplify, simulate, transfer the
//! motion back to every dense point) and write the deformed surface.

use std::fmt;
use std::path::PathBuf;
use std::time::Instant;

use bevy_point_springs::core::scene::{Deformed, Scene, SceneRun, Snapshot};
use glam::Vec3;
use serde::Serialize;

use crate::args::{PlyFlag, parse_vec3};
use crate::failure::Failure;
use crate::flags::JsonFlag;
use crate::picture::{self, View};
use crate::report::Report;

/// Arguments of `run`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene (.ron); its cloud path is relative to it. Optional with --resume (the
    /// snapshot names its scene file); when given there, it must be the snapshot's scene.
    #[arg(required_unless_present = "resume")]
    scene: Option<PathBuf>,
    /// Every N steps, save a snapshot of the running surface to --snapshot (written to a
    /// temporary file and renamed, so a crash never leaves a half-written one).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    snapshot_every: Option<u64>,
    /// Where --snapshot-every writes: by default SCENE's name with `.snapshot` in the
    /// current folder, or the --resume file when resuming.
    #[arg(long, value_name = "FILE")]
    snapshot: Option<PathBuf>,
    /// Go on from a snapshot (`--snapshot-every`): the scene is prepared again and the run
    /// continues bit for bit from the step the snapshot was taken at.
    #[arg(long, value_name = "FILE")]
    resume: Option<PathBuf>,
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
    /// The explicit integrator failed and handed over to implicit Euler.
    fell_back: bool,
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
    /// The step the run went on from, when resumed from a snapshot.
    resumed_at_step: Option<usize>,
    /// Snapshots written over the run.
    snapshots_written: usize,
    /// Where they went.
    snapshot: Option<String>,
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
        if self.fell_back {
            writeln!(
                f,
                "fell back     {} went unstable; implicit-euler took over",
                self.integrator
            )?;
        }
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
        if let Some(step) = self.resumed_at_step {
            writeln!(f, "resumed       from step {step}")?;
        }
        if let Some(snapshot) = &self.snapshot {
            writeln!(
                f,
                "snapshots     {} written to {snapshot}",
                self.snapshots_written
            )?;
        }
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
    let start = Instant::now();
    let (mut scene_run, scene_file) = prepare(args)?;
    let scene = scene_run.scene.clone();
    let resumed_at_step = args.resume.is_some().then(|| scene_run.step_count());
    let prepare = start.elapsed().as_secs_f64();
    let snapshots = args.snapshot_every.map(|every| Snapshots {
        every,
        path: args.snapshot.clone().unwrap_or_else(|| {
            args.resume.clone().unwrap_or_else(|| {
                let stem = scene_file.file_stem().unwrap_or_default();
                PathBuf::from(stem).with_extension("snapshot")
            })
        }),
        scene_file: scene_file.clone(),
        written: 0,
    });
    let (simulate, resample, snapshots) = simulate(&mut scene_run, scene.steps, snapshots)?;
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
    let mut report = report(args, &scene, &scene_run, &deformed, energy, seconds);
    report.scene = scene_file.display().to_string();
    report.resumed_at_step = resumed_at_step;
    let stepped = scene_run.step_count() - resumed_at_step.unwrap_or(0);
    report.ms_per_step = simulate * 1e3 / stepped.max(1) as f64;
    if let Some(s) = &snapshots {
        report.snapshots_written = s.written;
        report.snapshot = Some(s.path.display().to_string());
    }
    args.json.emit(&report)?;
    if !report.finite {
        let last = scene_run.solver().diagnostics().last.instability;
        return Err(Failure::unstable(format!(
            "the scene could not be kept finite: the guard restored the state {} times{}",
            report.guard_trips,
            last.map_or(String::new(), |why| format!(" (last: {why})"))
        )));
    }
    Ok(())
}

/// The run, prepared from the scene or resumed from a snapshot, and the scene file (made
/// absolute, so that a snapshot finds it from anywhere).
fn prepare(args: &Args) -> Result<(SceneRun, PathBuf), Failure> {
    let absolute = |p: &PathBuf| std::path::absolute(p).unwrap_or_else(|_| p.clone());
    let Some(resume) = &args.resume else {
        let file = args
            .scene
            .as_ref()
            .expect("clap requires a scene without --resume");
        let (scene, base) = Scene::load(file).map_err(Failure::bad_input)?;
        let run = scene.prepare(&base).map_err(Failure::bad_input)?;
        return Ok((run, absolute(file)));
    };
    let snapshot = Snapshot::read(resume).map_err(Failure::bad_input)?;
    let file = match &args.scene {
        Some(file) => absolute(file),
        None => snapshot.scene_file.clone().ok_or_else(|| {
            Failure::bad_input(format!(
                "{}: the snapshot does not name its scene file; give the scene",
                resume.display()
            ))
        })?,
    };
    let (scene, base) = Scene::load(&file).map_err(Failure::bad_input)?;
    let cloud = bevy_point_springs::core::cloud::io::read_cloud(&base.join(&scene.cloud), None)
        .map_err(Failure::bad_input)?;
    // The snapshot holds the scene as it ran: a budget resolved to a level.
    let mut as_run = scene.clone();
    if as_run.error_budget.take().is_some() {
        as_run.simplify.target = snapshot.scene.simplify.target;
        as_run.simplify.max_diameter = None;
    }
    if as_run != snapshot.scene {
        return Err(Failure::bad_input(format!(
            "{}: the snapshot was taken of another scene than {}",
            resume.display(),
            file.display()
        )));
    }
    let run = snapshot.resume(cloud).map_err(Failure::bad_input)?;
    Ok((run, file))
}

/// Snapshots to write while simulating.
#[derive(Debug)]
struct Snapshots {
    /// Steps between two.
    every: u64,
    /// The file each replaces.
    path: PathBuf,
    /// The scene file they name.
    scene_file: PathBuf,
    /// How many were written.
    written: usize,
}

/// Steps `run` to its end, showing progress on a terminal and writing `snapshots` when
/// due; the seconds spent stepping and resampling.
fn simulate(
    run: &mut SceneRun,
    total: usize,
    mut snapshots: Option<Snapshots>,
) -> Result<(f64, f64, Option<Snapshots>), Failure> {
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
        if let Some(s) = snapshots
            .as_mut()
            .filter(|s| (step as u64).is_multiple_of(s.every))
        {
            let mut snapshot = run.snapshot();
            snapshot.scene_file = Some(s.scene_file.clone());
            snapshot.write(&s.path).map_err(Failure::other)?;
            s.written += 1;
        }
        if tty && (step.is_multiple_of(10) || step == total) {
            let _ = write!(std::io::stderr(), "\rrun: step {step} of {total}   ");
            let _ = std::io::stderr().flush();
        }
    }
    if tty {
        eprintln!();
    }
    Ok((simulate_seconds, resample_seconds, snapshots))
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
        scene: String::new(),
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
        fell_back: d.fell_back,
        ms_prepare: seconds.prepare * 1e3,
        ms_per_step: seconds.simulate * 1e3 / run.step_count().max(1) as f64,
        ms_transfer: seconds.transfer * 1e3,
        ms_resample: seconds.resample * 1e3,
        max_displacement: deformed.max_displacement,
        energy_final: energy,
        finite,
        resampled_points: run.resampled().inserted,
        resumed_at_step: None,
        snapshots_written: 0,
        snapshot: None,
    }
}
