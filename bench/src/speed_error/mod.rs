//! `point-springs-bench report`: speed against error. Four fixed scenes (see
//! [`scenes::ReportScene`]), each at several simplification levels (every dense point a
//! simulation point, down to about 2 %), with each integrator and a few steps, run for the
//! same simulated time; per configuration the milliseconds per step and per 60 Hz frame and
//! the dense surface's error against the reference (every dense point simulated, implicit
//! Euler at a small step, the same time). Writes `report.md`, `report.csv`, one chart per
//! scene (error over milliseconds per frame, the Pareto front marked) and `summary.json`
//! (the paper's Table 1 measured here, and per scene the fastest configuration at about
//! 10 % of the points that keeps the RMS error under 1 %).

pub(super) mod measure;
mod output;
pub(super) mod scenes;

use std::path::PathBuf;
use std::time::Instant;

use bevy_point_springs::core::scene::{LevelChoice, Scene};
use bevy_point_springs::core::solver::{BendingModel, Integrator};
use indicatif::{ProgressBar, ProgressStyle};

use crate::args::BendingArg;
use crate::failure::Failure;
use measure::{Error, Outcome, error, run_scene};
use scenes::ReportScene;

/// The RMS error, over the diagonal, a good configuration stays under.
pub const RMS_GOAL: f64 = 0.01;

/// The level the summary looks at (a fraction of the dense points).
pub const SUMMARY_FRACTION: f32 = 0.1;

/// The speed-up over the full-resolution frame the summary asks of it.
pub const SPEEDUP_GOAL: f64 = 10.0;

/// The scene `summary.json`'s Table 1 runs, relative to `--assets`.
const TABLE1_SCENE: &str = "scenes/sphere_poke.ron";

/// What a full report runs, and what `--quick` runs.
#[derive(Debug, Clone)]
struct Plan {
    /// Fractions of the dense points kept as simulation points (1.0 first).
    fractions: Vec<f32>,
    /// Steps, s.
    dts: Vec<f32>,
    /// The reference's step, s.
    reference_dt: f32,
    /// Simulated time of every run, s.
    seconds: f32,
    /// Steps timed per Table 1 row.
    table1_steps: usize,
    /// Runs per Table 1 row (the median's).
    table1_repeats: usize,
    /// How the scenes bend.
    bending: BendingModel,
}

impl Plan {
    fn new(quick: bool, bending: BendingModel) -> Self {
        if quick {
            Self {
                fractions: vec![1.0, 0.1, 0.02],
                dts: vec![1.0 / 60.0],
                reference_dt: 1.0 / 240.0,
                seconds: 3.0,
                table1_steps: 30,
                table1_repeats: 1,
                bending,
            }
        } else {
            Self {
                fractions: vec![1.0, 0.5, 0.2, 0.1, 0.05, 0.02],
                dts: vec![1.0 / 60.0, 1.0 / 240.0],
                reference_dt: 1.0 / 480.0,
                seconds: 5.0,
                table1_steps: 150,
                table1_repeats: 5,
                bending,
            }
        }
    }

    /// Runs per scene: the reference, every configuration, the error budget's estimate and
    /// its chosen level.
    fn runs_per_scene(&self) -> usize {
        3 + self.fractions.len() * self.dts.len() * Integrator::ALL.len()
    }
}

/// Arguments of `point-springs-bench report`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A short report (3 levels, one step, 3 s per run; under two minutes in a release
    /// build), for CI.
    #[arg(long)]
    quick: bool,
    /// The folder the report's files go to (made when missing).
    #[arg(short = 'o', long, default_value = "report")]
    out: PathBuf,
    /// The folder holding `kitten.off` and `scenes/sphere_poke.ron`.
    #[arg(long, default_value = "assets")]
    assets: PathBuf,
    /// How the scenes bend: the paper's bend springs (the default: with them every
    /// integrator runs at every level; a plate's bending stiffens the explicit schemes'
    /// stable step as the spacing to the −4th), hinges, or each point's fitted curvature
    /// (the library's default model).
    #[arg(long, value_enum, default_value_t = BendingArg::Springs)]
    bending: BendingArg,
    /// The scenes to run, comma-separated (all four when not given): a quick look at one
    /// scene, or one scene's figures after a change.
    #[arg(long, value_enum, value_delimiter = ',', num_args = 1..)]
    scenes: Vec<ReportScene>,
}

/// One configuration's row.
#[derive(Debug, Clone)]
pub struct Row {
    /// The scene.
    pub scene: ReportScene,
    /// The integrator.
    pub integrator: Integrator,
    /// The step, s.
    pub dt: f32,
    /// Fraction of the dense points asked for as simulation points.
    pub fraction: f32,
    /// Dense points.
    pub dense_points: usize,
    /// What the run measured.
    pub outcome: Outcome,
    /// Its error (none when it was not stable).
    pub error: Option<Error>,
    /// The same integrator and step with every dense point simulated: its ms per frame over
    /// this one's.
    pub speedup: f64,
    /// On its scene's Pareto front of error against ms per frame.
    pub pareto: bool,
}

impl Row {
    /// "integrator, dt 1/N".
    pub fn config(&self) -> String {
        format!("{}, dt 1/{:.0}", self.integrator, 1.0 / self.dt)
    }
}

/// A scene's reference run.
#[derive(Debug, Clone)]
pub struct Reference {
    /// The scene.
    pub scene: ReportScene,
    /// Dense points.
    pub dense_points: usize,
    /// The bounding box's diagonal of the dense cloud.
    pub diagonal: f32,
    /// What the run measured.
    pub outcome: Outcome,
}

/// A scene's level chosen for the error budget [`RMS_GOAL`], and how its estimate fared.
#[derive(Debug, Clone)]
pub struct Budget {
    /// The scene.
    pub scene: ReportScene,
    /// The choice (implicit Euler at the plan's first step).
    pub choice: LevelChoice,
    /// Seconds the estimate took.
    pub estimate_s: f64,
    /// The chosen level's measured RMS error (none when it was not stable).
    pub measured: Option<f64>,
    /// At each level of the report: the fraction, the predicted RMS error and the measured
    /// one (implicit Euler at the plan's first step).
    pub levels: Vec<(f32, f64, Option<f64>)>,
}

/// Runs `point-springs-bench report`.
pub fn run(args: &Args) -> Result<(), Failure> {
    let plan = Plan::new(args.quick, args.bending.into());
    let bending = plan.bending;
    let table1_path = args.assets.join(TABLE1_SCENE);
    let (table1_scene, table1_base) = Scene::load(&table1_path).map_err(|e| {
        Failure::bad_input(format!(
            "{e} (give --assets, or run from the repository root)"
        ))
    })?;
    let scenes: Vec<ReportScene> = ReportScene::ALL
        .into_iter()
        .filter(|s| args.scenes.is_empty() || args.scenes.contains(s))
        .collect();
    let clouds = scenes
        .iter()
        .map(|s| s.cloud(&args.assets))
        .collect::<Result<Vec<_>, _>>()?;
    std::fs::create_dir_all(&args.out)
        .map_err(|e| Failure::other(format!("{}: {e}", args.out.display())))?;
    let total = scenes.len() * plan.runs_per_scene() + 1;
    let bar = ProgressBar::new(total as u64).with_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} runs, {elapsed} [{msg}]")
            .map_err(Failure::other)?,
    );
    let mut references = Vec::new();
    let mut rows = Vec::new();
    let mut budgets = Vec::new();
    for (&scene, cloud) in scenes.iter().zip(&clouds) {
        let diagonal = cloud
            .bounds()
            .map(|b| b.diagonal())
            .filter(|d| *d > 0.0)
            .ok_or_else(|| Failure::bad_input(format!("the {} cloud is empty", scene.name())))?;
        bar.set_message(format!("{} reference", scene.name()));
        let config = scene.scene(
            cloud,
            1.0,
            bending,
            Integrator::ImplicitEuler,
            plan.reference_dt,
            plan.seconds,
        );
        let outcome = run_scene(&config, cloud, diagonal)?;
        bar.inc(1);
        let Some(reference) = outcome.surface.clone() else {
            return Err(Failure::other(format!(
                "the {} reference was not stable: {}",
                scene.name(),
                outcome.failure.as_deref().unwrap_or("?")
            )));
        };
        for &fraction in &plan.fractions {
            for &dt in &plan.dts {
                for integrator in Integrator::ALL {
                    bar.set_message(format!(
                        "{}, {:.0} %, {integrator}, dt 1/{:.0}",
                        scene.name(),
                        fraction * 100.0,
                        1.0 / dt
                    ));
                    let config =
                        scene.scene(cloud, fraction, bending, integrator, dt, plan.seconds);
                    let outcome = run_scene(&config, cloud, diagonal)?;
                    let error = outcome
                        .surface
                        .as_ref()
                        .map(|s| error(s, &reference, diagonal));
                    rows.push(Row {
                        scene,
                        integrator,
                        dt,
                        fraction,
                        dense_points: cloud.len(),
                        outcome,
                        error,
                        speedup: 1.0,
                        pareto: false,
                    });
                    bar.inc(1);
                }
            }
        }
        bar.set_message(format!("{} error budget", scene.name()));
        budgets.push(budget(
            scene, cloud, &plan, diagonal, &reference, &rows, &bar,
        )?);
        references.push(Reference {
            scene,
            dense_points: cloud.len(),
            diagonal,
            outcome,
        });
    }
    bar.set_message("Table 1");
    let table1 = crate::table1::measure_sizes(
        &table1_scene,
        &table1_base,
        plan.table1_steps,
        plan.table1_repeats,
    )?;
    bar.inc(1);
    bar.finish_and_clear();
    mark_speedups(&mut rows);
    mark_pareto(&mut rows);
    let report = output::Report {
        quick: args.quick,
        bending,
        scenes,
        seconds: plan.seconds,
        reference_dt: plan.reference_dt,
        threads: rayon::current_num_threads(),
        references,
        rows,
        budgets,
        table1,
    };
    let written = report.write(&args.out)?;
    for path in written {
        println!("{}", path.display());
    }
    Ok(())
}

/// Chooses `scene`'s level for [`RMS_GOAL`] (implicit Euler at the plan's first step) and
/// measures the chosen level against the reference; the predictions at the report's levels
/// beside their measured errors.
fn budget(
    scene: ReportScene,
    cloud: &bevy_point_springs::core::PointCloud,
    plan: &Plan,
    diagonal: f32,
    reference: &measure::Surface,
    rows: &[Row],
    bar: &ProgressBar,
) -> Result<Budget, Failure> {
    let dt = plan.dts[0];
    let config = |fraction| {
        scene.scene(
            cloud,
            fraction,
            plan.bending,
            Integrator::ImplicitEuler,
            dt,
            plan.seconds,
        )
    };
    let start = Instant::now();
    let choice = config(1.0)
        .choose_level(cloud, RMS_GOAL as f32)
        .map_err(Failure::other)?;
    let estimate_s = start.elapsed().as_secs_f64();
    bar.inc(1);
    let outcome = run_scene(&config(choice.fraction), cloud, diagonal)?;
    bar.inc(1);
    let measured = outcome
        .surface
        .as_ref()
        .map(|s| error(s, reference, diagonal).rms);
    let levels = rows
        .iter()
        .filter(|r| r.scene == scene && r.integrator == Integrator::ImplicitEuler && r.dt == dt)
        .map(|r| {
            (
                r.fraction,
                f64::from(choice.predict(r.fraction)),
                r.error.map(|e| e.rms),
            )
        })
        .collect();
    Ok(Budget {
        scene,
        choice,
        estimate_s,
        measured,
        levels,
    })
}

/// Sets each row's speed-up over the full-resolution row of its scene, integrator and step.
fn mark_speedups(rows: &mut [Row]) {
    let full: Vec<(ReportScene, Integrator, u32, f64)> = rows
        .iter()
        .filter(|r| r.fraction >= 1.0)
        .map(|r| (r.scene, r.integrator, r.dt.to_bits(), r.outcome.ms_frame()))
        .collect();
    for r in rows.iter_mut() {
        if let Some(&(.., ms)) = full
            .iter()
            .find(|f| (f.0, f.1, f.2) == (r.scene, r.integrator, r.dt.to_bits()))
        {
            r.speedup = ms / r.outcome.ms_frame().max(f64::MIN_POSITIVE);
        }
    }
}

/// Marks, per scene, the stable rows that no other stable row beats in both error and ms
/// per frame.
fn mark_pareto(rows: &mut [Row]) {
    let points: Vec<Option<(ReportScene, f64, f64)>> = rows
        .iter()
        .map(|r| r.error.map(|e| (r.scene, r.outcome.ms_frame(), e.rms)))
        .collect();
    for (i, r) in rows.iter_mut().enumerate() {
        let Some((scene, ms, rms)) = points[i] else {
            continue;
        };
        r.pareto = !points.iter().enumerate().any(|(j, p)| {
            j != i
                && p.is_some_and(|(s, m, e)| {
                    s == scene && m <= ms && e <= rms && (m < ms || e < rms)
                })
        });
    }
}
