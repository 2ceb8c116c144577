//! `point-springs-bench table1`: the paper's Table 1 measured here. The 3203-point sphere
//! of Fig. 5 (the `sphere_poke` scene) simplified to the table's 85, 273 and 338
//! simulation points, poked as in the scene; the time per step includes the transfer to
//! every dense point, positions and normals, as the paper's does. The paper's figures (a
//! 2 GHz Pentium IV, 2007) are printed beside ours. The scene runs with the paper's method
//! whatever its file says: bend springs (`BendingModel::Springs`) and eq 3's damping
//! (`DampingModel::Relative`, which explicit Euler needs: with axial damping it hands over
//! to implicit Euler). Each row is the median of `--repeats` runs, each prepared afresh
//! and timed over the same steps: one run of the same binary varied by 1.5–2× here.

use std::fmt;
use std::path::PathBuf;
use std::time::Instant;

use bevy_point_springs::core::scene::Scene;
use bevy_point_springs::core::solver::{BendingModel, DampingModel, Integrator};
use serde::Serialize;

use crate::failure::Failure;
use crate::flags::JsonFlag;
use crate::report::Report;

/// The paper's Table 1: simulation points and seconds per step on its 2 GHz Pentium IV.
pub const PAPER_TABLE1: [(usize, f64); 3] = [(85, 0.13), (273, 0.25), (338, 0.42)];

/// The scene `point-springs-bench table1` runs unless told otherwise (relative to the repository root).
const DEFAULT_SCENE: &str = "assets/scenes/sphere_poke.ron";

/// Most steps `point-springs-bench table1` takes per row.
const MAX_STEPS: usize = 100_000;

/// Most runs `point-springs-bench table1` takes per row.
const MAX_REPEATS: usize = 100;

/// Arguments of `point-springs-bench table1`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene (by default the paper's sphere poke, `assets/scenes/sphere_poke.ron`).
    #[arg(default_value = DEFAULT_SCENE)]
    scene: PathBuf,
    /// Steps timed per row: the first ones of the scene, while the finger presses in (the
    /// surface moves every step, so every step transfers).
    #[arg(long, default_value_t = 150)]
    steps: usize,
    /// Runs per row, each prepared afresh; a row is the run of median time.
    #[arg(long, default_value_t = 5)]
    repeats: usize,
    #[command(flatten)]
    json: JsonFlag,
}

/// One row: a size of the table with one integrator.
#[derive(Debug, Serialize)]
pub(super) struct Row {
    /// Simulation points asked for (the paper's).
    pub(super) paper_sim_points: usize,
    /// Simulation points the network has.
    pub(super) sim_points: usize,
    /// Dense points.
    pub(super) dense_points: usize,
    /// Springs.
    pub(super) springs: usize,
    /// The integrator.
    pub(super) integrator: String,
    /// Sub-steps per step (the largest over the run).
    pub(super) substeps: u32,
    /// Milliseconds per step: simulation and transfer.
    pub(super) ms_per_step: f64,
    /// Of which the simulation (forces, step, the scene's pull).
    pub(super) ms_simulate: f64,
    /// Of which the transfer of positions and normals to every dense point.
    pub(super) ms_transfer: f64,
    /// Steps whose points moved, so that the transfer ran (all of them, normally).
    pub(super) transfers: usize,
    /// The paper's seconds per step for this size.
    pub(super) paper_s: f64,
    /// The paper's time over ours.
    pub(super) speedup: f64,
}

/// What `point-springs-bench table1` reports.
#[derive(Debug, Serialize)]
struct Table1Report {
    /// "table1".
    benchmark: &'static str,
    /// The scene run.
    scene: String,
    /// Steps timed per row.
    steps: usize,
    /// Runs per row (each row is the run of median time).
    repeats: usize,
    /// Step length, s.
    dt: f32,
    /// One row per size and integrator.
    rows: Vec<Row>,
}

impl fmt::Display for Table1Report {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "Table 1 — {}, {} steps of {:.4} s per row; ours: this machine, the median of {} runs; paper: a 2 GHz Pentium IV (2007)",
            self.scene, self.steps, self.dt, self.repeats
        )?;
        writeln!(f)?;
        writeln!(
            f,
            "| simulation points | dense | integrator | sub-steps | ms per step | simulate | transfer | paper, s per step | paper / ours |"
        )?;
        writeln!(f, "|---|---|---|---|---|---|---|---|---|")?;
        for r in &self.rows {
            writeln!(
                f,
                "| {} | {} | {} | {} | {:.3} | {:.3} | {:.3} | {} | {:.0}× |",
                r.sim_points,
                r.dense_points,
                r.integrator,
                r.substeps,
                r.ms_per_step,
                r.ms_simulate,
                r.ms_transfer,
                r.paper_s,
                r.speedup
            )?;
        }
        Ok(())
    }
}

impl Report for Table1Report {}

/// Runs `point-springs-bench table1`.
pub fn run(args: &Args) -> Result<(), Failure> {
    if !(1..=MAX_STEPS).contains(&args.steps) {
        return Err(Failure::bad_input(format!(
            "--steps must be between 1 and {MAX_STEPS}"
        )));
    }
    if !(1..=MAX_REPEATS).contains(&args.repeats) {
        return Err(Failure::bad_input(format!(
            "--repeats must be between 1 and {MAX_REPEATS}"
        )));
    }
    let (scene, base) = Scene::load(&args.scene).map_err(|e| {
        Failure::bad_input(format!(
            "{e} (give the scene, or run from the repository root)"
        ))
    })?;
    let rows = measure_sizes(&scene, &base, args.steps, args.repeats)?;
    let report = Table1Report {
        benchmark: "table1",
        scene: args.scene.display().to_string(),
        steps: args.steps,
        repeats: args.repeats,
        dt: scene.dt,
        rows,
    };
    args.json.emit(&report)
}

/// Every row of the table: each of the paper's sizes with each integrator, `steps` steps
/// of `scene` timed (at least `steps` in the scene), with the paper's bend springs and
/// damping; each row the run of median time of `repeats` (at least one).
pub(super) fn measure_sizes(
    scene: &Scene,
    base: &std::path::Path,
    steps: usize,
    repeats: usize,
) -> Result<Vec<Row>, Failure> {
    let mut rows = Vec::new();
    for (paper_sim_points, paper_s) in PAPER_TABLE1 {
        for integrator in [
            Integrator::ExplicitEuler,
            Integrator::SymplecticEuler,
            Integrator::ImplicitEuler,
        ] {
            let mut scene = scene.clone();
            scene.simplify.target = Some(paper_sim_points);
            scene.simplify.max_diameter = None;
            scene.solver.integrator = integrator;
            scene.solver.damping_model = DampingModel::Relative;
            scene.material.bending = BendingModel::Springs;
            scene.steps = scene.steps.max(steps);
            let mut runs = (0..repeats.max(1))
                .map(|_| measure(&scene, base, steps, paper_sim_points, paper_s))
                .collect::<Result<Vec<Row>, Failure>>()?;
            runs.sort_by(|a, b| a.ms_per_step.total_cmp(&b.ms_per_step));
            rows.push(runs.swap_remove(runs.len() / 2));
        }
    }
    Ok(rows)
}

/// One row: the scene prepared at one size, `steps` steps timed.
fn measure(
    scene: &Scene,
    base: &std::path::Path,
    steps: usize,
    paper_sim_points: usize,
    paper_s: f64,
) -> Result<Row, Failure> {
    let mut run = scene.prepare(base).map_err(Failure::bad_input)?;
    let (mut simulate, mut transfer) = (0.0f64, 0.0f64);
    let (mut substeps, mut transfers) = (0, 0);
    for _ in 0..steps {
        let start = Instant::now();
        let report = run.step().map_err(Failure::other)?;
        simulate += start.elapsed().as_secs_f64();
        let start = Instant::now();
        let s = &mut run.surface;
        if s.dense.follow(&s.solver.points).map_err(Failure::other)? {
            transfers += 1;
        }
        transfer += start.elapsed().as_secs_f64();
        substeps = substeps.max(report.substeps);
    }
    let per_step = |seconds: f64| seconds * 1e3 / steps as f64;
    let ms_per_step = per_step(simulate + transfer);
    let surface = &run.surface;
    Ok(Row {
        paper_sim_points,
        sim_points: surface.solver.points.len(),
        dense_points: surface.dense.len(),
        springs: surface.solver.springs.len(),
        integrator: format!("{:?}", scene.solver.integrator),
        substeps,
        ms_per_step,
        ms_simulate: per_step(simulate),
        ms_transfer: per_step(transfer),
        transfers,
        paper_s,
        speedup: paper_s * 1e3 / ms_per_step,
    })
}
