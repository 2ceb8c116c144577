//! `point-springs-bench solvers`: implicit Euler solved by conjugate gradient against the
//! prefactored local/global solver (`ImplicitSolver::LocalGlobal`) at several iteration
//! counts, on the scenes of `point-springs-bench report` at one level and step: the milliseconds per
//! step of each, and how far each one's dense surface ends from the CG run's (the RMS and
//! largest distance over the bounding box's diagonal), all measured in one run.

use std::fmt;
use std::path::PathBuf;

use bevy_point_springs::core::solver::{ImplicitSolver, Integrator, MAX_LOCAL_GLOBAL_ITERATIONS};
use serde::Serialize;

use crate::args::BendingArg;
use crate::failure::Failure;
use crate::flags::JsonFlag;
use crate::report::Report;
use crate::speed_error::measure::{error, run_scene};
use crate::speed_error::scenes::ReportScene;

/// Arguments of `point-springs-bench solvers`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scenes, comma-separated (all four when not given).
    #[arg(long, value_enum, value_delimiter = ',', num_args = 1..)]
    scenes: Vec<ReportScene>,
    /// Fraction of the dense points kept as simulation points.
    #[arg(long, default_value_t = 1.0)]
    fraction: f32,
    /// Local/global iterations per step, comma-separated: a row each.
    #[arg(long, value_delimiter = ',', default_values_t = [1, 2, 4])]
    iterations: Vec<u32>,
    /// Steps per second.
    #[arg(long, default_value_t = 60.0)]
    rate: f32,
    /// Simulated seconds.
    #[arg(long, default_value_t = 3.0)]
    seconds: f32,
    /// How the scenes bend.
    #[arg(long, value_enum, default_value_t = BendingArg::Curvature)]
    bending: BendingArg,
    /// The folder holding `kitten.off`.
    #[arg(long, default_value = "assets")]
    assets: PathBuf,
    #[command(flatten)]
    json: JsonFlag,
}

/// One scene run with one solver.
#[derive(Debug, Serialize)]
struct Row {
    /// The scene.
    scene: ReportScene,
    /// Simulation points.
    sim_points: usize,
    /// Springs.
    springs: usize,
    /// "cg", or "local-global ×N".
    solver: String,
    /// Milliseconds per step.
    ms_step: f64,
    /// Whether the run stayed finite, with no guard trip and nothing thrown.
    stable: bool,
    /// RMS distance of its dense surface from the CG run's at the end, % of the diagonal.
    rms_vs_cg_percent: Option<f64>,
    /// Largest distance from the CG run's, % of the diagonal.
    max_vs_cg_percent: Option<f64>,
    /// The largest speed at the end over the diagonal, 1/s: small when settled.
    residual_speed: f32,
}

/// What `point-springs-bench solvers` reports.
#[derive(Debug, Serialize)]
struct SolversReport {
    /// "solvers".
    benchmark: &'static str,
    /// Fraction of the dense points simulated.
    fraction: f32,
    /// Step, s.
    dt: f32,
    /// Simulated seconds.
    seconds: f32,
    /// The rows, per scene CG first.
    rows: Vec<Row>,
}

impl fmt::Display for SolversReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "Implicit Euler solvers — bench report's scenes at {:.0} % of the points, dt 1/{:.0}, {} s",
            self.fraction * 100.0,
            1.0 / self.dt,
            self.seconds
        )?;
        writeln!(f)?;
        writeln!(
            f,
            "| scene | simulation points | springs | solver | ms per step | vs CG: RMS % | max % | speed at end, diagonals/s |"
        )?;
        writeln!(f, "|---|---|---|---|---|---|---|---|")?;
        let percent = |v: Option<f64>| v.map_or("–".to_owned(), |v| format!("{v:.3}"));
        for r in &self.rows {
            writeln!(
                f,
                "| {} | {} | {} | {}{} | {:.3} | {} | {} | {:.2e} |",
                r.scene.name(),
                r.sim_points,
                r.springs,
                r.solver,
                if r.stable { "" } else { " (unstable)" },
                r.ms_step,
                percent(r.rms_vs_cg_percent),
                percent(r.max_vs_cg_percent),
                r.residual_speed
            )?;
        }
        Ok(())
    }
}

impl Report for SolversReport {}

/// Runs `point-springs-bench solvers`.
pub fn run(args: &Args) -> Result<(), Failure> {
    if !(args.fraction > 0.0 && args.fraction <= 1.0) {
        return Err(Failure::bad_input("--fraction must be in (0, 1]"));
    }
    if !(args.rate >= 1.0 && args.rate <= 10_000.0) {
        return Err(Failure::bad_input("--rate must be between 1 and 10000"));
    }
    if !(args.seconds > 0.0 && args.seconds <= 60.0) {
        return Err(Failure::bad_input("--seconds must be in (0, 60]"));
    }
    if let Some(&bad) = args
        .iterations
        .iter()
        .find(|&&i| !(1..=MAX_LOCAL_GLOBAL_ITERATIONS).contains(&i))
    {
        return Err(Failure::bad_input(format!(
            "--iterations {bad}: each must be between 1 and {MAX_LOCAL_GLOBAL_ITERATIONS}"
        )));
    }
    let dt = 1.0 / args.rate;
    let mut rows = Vec::new();
    for scene in ReportScene::ALL
        .into_iter()
        .filter(|s| args.scenes.is_empty() || args.scenes.contains(s))
    {
        let cloud = scene.cloud(&args.assets)?;
        let diagonal = cloud
            .bounds()
            .map(|b| b.diagonal())
            .filter(|d| *d > 0.0)
            .ok_or_else(|| Failure::bad_input(format!("the {} cloud is empty", scene.name())))?;
        let base = scene.scene(
            &cloud,
            args.fraction,
            args.bending.into(),
            Integrator::ImplicitEuler,
            dt,
            args.seconds,
        );
        let solvers = std::iter::once(ImplicitSolver::ConjugateGradient).chain(
            args.iterations
                .iter()
                .map(|&iterations| ImplicitSolver::LocalGlobal { iterations }),
        );
        let mut reference = None;
        for solver in solvers {
            let mut config = base.clone();
            config.solver.implicit_solver = solver;
            let outcome = run_scene(&config, &cloud, diagonal)?;
            let against = match (&outcome.surface, &reference) {
                (Some(s), Some(r)) => Some(error(s, r, diagonal)),
                _ => None,
            };
            rows.push(Row {
                scene,
                sim_points: outcome.sim_points,
                springs: outcome.springs,
                solver: match solver {
                    ImplicitSolver::LocalGlobal { iterations } => {
                        format!("local-global ×{iterations}")
                    }
                    ImplicitSolver::ConjugateGradient => "cg".to_owned(),
                },
                ms_step: outcome.ms_step,
                stable: outcome.stable,
                rms_vs_cg_percent: against.map(|e| e.rms * 100.0),
                max_vs_cg_percent: against.map(|e| e.max * 100.0),
                residual_speed: outcome.residual_speed,
            });
            if solver == ImplicitSolver::ConjugateGradient {
                reference = outcome.surface;
            }
        }
    }
    args.json.emit(&SolversReport {
        benchmark: "solvers",
        fraction: args.fraction,
        dt,
        seconds: args.seconds,
        rows,
    })
}
