//! What `point-springs-bench report` writes: `report.md`, `report.csv`, a chart per scene (SVG and PNG)
//! and `summary.json`, each written to a temporary file and renamed into place.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use bevy_point_springs::core::cloud::io::write_atomically;
use bevy_point_springs::core::solver::BendingModel;
use serde::Serialize;

use super::scenes::ReportScene;
use super::{Budget, RMS_GOAL, Reference, Row, SPEEDUP_GOAL, SUMMARY_FRACTION};
use crate::chart::{Chart, Series};
use crate::failure::Failure;
use crate::table1;

/// The smallest error a chart shows (a run equal to the reference would have none).
const CHART_FLOOR: f64 = 1e-7;

/// Everything one report measured.
#[derive(Debug)]
pub struct Report {
    /// Whether it was `--quick`.
    pub quick: bool,
    /// How the scenes bent.
    pub bending: BendingModel,
    /// The scenes it ran, in the report's order.
    pub scenes: Vec<ReportScene>,
    /// Simulated time of every run, s.
    pub seconds: f32,
    /// The references' step, s.
    pub reference_dt: f32,
    /// Threads of the pool the solver and transfer ran on.
    pub threads: usize,
    /// The reference of each scene.
    pub references: Vec<Reference>,
    /// One row per configuration.
    pub rows: Vec<Row>,
    /// Per scene, the level chosen for the error budget.
    pub budgets: Vec<Budget>,
    /// The paper's Table 1 measured here.
    pub table1: Vec<table1::Row>,
}

/// `summary.json`.
#[derive(Debug, Serialize)]
struct Summary {
    quick: bool,
    /// `springs` or `hinges`.
    bending: &'static str,
    /// The RMS error goal, over the diagonal.
    rms_goal: f64,
    /// The speed-up goal over the full-resolution frame.
    speedup_goal: f64,
    /// The paper's Table 1 measured here.
    table1: Vec<Table1Row>,
    /// Per scene: the fastest configuration at about 10 % of the points under the RMS goal,
    /// or the closest miss.
    best_at_10pct: Vec<Best>,
    /// Per integrator and step at about 10 %: the worst error and speed-up over the scenes.
    every_scene: Vec<EveryScene>,
    /// Per scene: the level an error budget of `rms_goal` chose, and its measured error.
    error_budget: Vec<BudgetRow>,
}

#[derive(Debug, Serialize)]
struct BudgetRow {
    scene: ReportScene,
    budget: f32,
    /// The fraction of the dense points chosen.
    fraction: f32,
    /// Simulation points asked for.
    target: usize,
    /// The predicted RMS error at that level.
    predicted_rms: f32,
    /// Its measured RMS error (null when unstable).
    measured_rms: Option<f64>,
    /// The estimate's shrink factor per doubling.
    shrink: f32,
    /// Seconds the estimate took.
    estimate_s: f64,
    /// At each level of the report: predicted and measured RMS error.
    levels: Vec<BudgetLevel>,
}

#[derive(Debug, Serialize)]
struct BudgetLevel {
    fraction: f32,
    predicted_rms: f64,
    measured_rms: Option<f64>,
}

#[derive(Debug, Serialize)]
struct Table1Row {
    sim_points: usize,
    integrator: String,
    ms_per_step: f64,
    paper_s: f64,
    speedup: f64,
}

#[derive(Debug, Serialize)]
struct Best {
    scene: ReportScene,
    config: String,
    fraction: f32,
    sim_points: usize,
    rms_error: f64,
    ms_frame: f64,
    /// The full-resolution frame (same integrator and step) over this one.
    speedup: f64,
    /// The fastest stable full-resolution frame of the scene (any integrator and step) over
    /// this one.
    speedup_over_fastest_full: f64,
    /// Under the RMS goal and at least the speed-up goal.
    met: bool,
}

#[derive(Debug, Serialize)]
struct EveryScene {
    config: String,
    /// The largest RMS error over the scenes (infinite where one was unstable).
    max_rms_error: f64,
    /// The smallest speed-up over the scenes.
    min_speedup: f64,
    met: bool,
}

impl Report {
    /// Writes every file into `dir`, returning their paths.
    pub fn write(&self, dir: &Path) -> Result<Vec<PathBuf>, Failure> {
        let mut written = Vec::new();
        for &scene in &self.scenes {
            let stem = dir.join(format!("report_{}", scene.name()));
            written.extend(self.chart(scene).write(&stem)?);
        }
        let summary = self.summary();
        let files = [
            ("report.csv", self.csv()),
            ("report.md", self.markdown(&summary)),
            (
                "summary.json",
                serde_json::to_string_pretty(&summary).map_err(Failure::other)? + "\n",
            ),
        ];
        for (name, text) in files {
            let path = dir.join(name);
            write_atomically(&path, |out| out.write_all(text.as_bytes()))
                .map_err(Failure::other)?;
            written.push(path);
        }
        Ok(written)
    }

    /// The rows at the level nearest [`SUMMARY_FRACTION`].
    fn summary_rows(&self) -> impl Iterator<Item = &Row> {
        let level = self
            .rows
            .iter()
            .map(|r| r.fraction)
            .min_by(|a, b| {
                (a - SUMMARY_FRACTION)
                    .abs()
                    .total_cmp(&(b - SUMMARY_FRACTION).abs())
            })
            .unwrap_or(SUMMARY_FRACTION);
        self.rows.iter().filter(move |r| r.fraction == level)
    }

    fn summary(&self) -> Summary {
        let best_at_10pct = self
            .scenes
            .iter()
            .filter_map(|&scene| {
                let rows: Vec<&Row> = self.summary_rows().filter(|r| r.scene == scene).collect();
                let good = rows
                    .iter()
                    .filter(|r| r.error.is_some_and(|e| e.rms < RMS_GOAL))
                    .min_by(|a, b| a.outcome.ms_frame().total_cmp(&b.outcome.ms_frame()));
                let closest = || {
                    rows.iter()
                        .filter(|r| r.error.is_some())
                        .min_by(|a, b| rms(a).total_cmp(&rms(b)))
                };
                let fastest_full = self
                    .rows
                    .iter()
                    .filter(|r| r.scene == scene && r.fraction >= 1.0 && r.outcome.stable)
                    .map(|r| r.outcome.ms_frame())
                    .fold(f64::INFINITY, f64::min);
                good.or_else(closest).map(|r| Best {
                    speedup_over_fastest_full: fastest_full / r.outcome.ms_frame(),
                    scene,
                    config: r.config(),
                    fraction: r.fraction,
                    sim_points: r.outcome.sim_points,
                    rms_error: rms(r),
                    ms_frame: r.outcome.ms_frame(),
                    speedup: r.speedup,
                    met: rms(r) < RMS_GOAL && r.speedup >= SPEEDUP_GOAL,
                })
            })
            .collect();
        let mut every_scene: Vec<EveryScene> = Vec::new();
        for r in self.summary_rows() {
            let config = r.config();
            let at = match every_scene.iter().position(|e| e.config == config) {
                Some(at) => at,
                None => {
                    every_scene.push(EveryScene {
                        config,
                        max_rms_error: 0.0,
                        min_speedup: f64::INFINITY,
                        met: false,
                    });
                    every_scene.len() - 1
                }
            };
            let entry = &mut every_scene[at];
            entry.max_rms_error = entry.max_rms_error.max(rms(r));
            entry.min_speedup = entry.min_speedup.min(r.speedup);
            entry.met = entry.max_rms_error < RMS_GOAL && entry.min_speedup >= SPEEDUP_GOAL;
        }
        Summary {
            quick: self.quick,
            bending: bending_name(self.bending),
            rms_goal: RMS_GOAL,
            speedup_goal: SPEEDUP_GOAL,
            table1: self
                .table1
                .iter()
                .map(|r| Table1Row {
                    sim_points: r.sim_points,
                    integrator: r.integrator.clone(),
                    ms_per_step: r.ms_per_step,
                    paper_s: r.paper_s,
                    speedup: r.speedup,
                })
                .collect(),
            best_at_10pct,
            every_scene,
            error_budget: self
                .budgets
                .iter()
                .map(|b| BudgetRow {
                    scene: b.scene,
                    budget: b.choice.budget,
                    fraction: b.choice.fraction,
                    target: b.choice.target,
                    predicted_rms: b.choice.predicted,
                    measured_rms: b.measured,
                    shrink: b.choice.shrink,
                    estimate_s: b.estimate_s,
                    levels: b
                        .levels
                        .iter()
                        .map(|&(fraction, predicted_rms, measured_rms)| BudgetLevel {
                            fraction,
                            predicted_rms,
                            measured_rms,
                        })
                        .collect(),
                })
                .collect(),
        }
    }

    /// One row per configuration.
    fn csv(&self) -> String {
        let mut text = String::from(
            "scene,integrator,dt,fraction,sim_points,dense_points,springs,substeps,ms_step,ms_transfer,ms_frame,speedup,rms_error,max_error,normal_error_deg,stable,residual_speed,pareto\n",
        );
        for r in &self.rows {
            let o = &r.outcome;
            let e =
                |f: fn(&super::Error) -> f64| r.error.map_or(String::new(), |e| f(&e).to_string());
            let _ = writeln!(
                text,
                "{},{},{},{},{},{},{},{},{:.5},{:.5},{:.5},{:.3},{},{},{},{},{:.3e},{}",
                r.scene.name(),
                r.integrator,
                r.dt,
                r.fraction,
                o.sim_points,
                r.dense_points,
                o.springs,
                o.substeps,
                o.ms_step,
                o.ms_transfer,
                o.ms_frame(),
                r.speedup,
                e(|e| e.rms),
                e(|e| e.max),
                e(|e| e.normal_deg),
                o.stable,
                o.residual_speed,
                r.pareto
            );
        }
        text
    }

    fn markdown(&self, summary: &Summary) -> String {
        let mut t = String::new();
        let _ = writeln!(t, "# Speed against error\n");
        let _ = writeln!(
            t,
            "`point-springs-bench report{}{}`: every run simulates {} s; a frame is 1/60 s of steps \
             and one transfer of positions and normals to every dense point; errors are distances \
             of the dense surface at the end from the reference's (every dense point simulated, \
             implicit Euler at dt 1/{:.0}), over the bounding box's diagonal. {} threads. \
             Times are one run on this machine.\n",
            if self.quick { " --quick" } else { "" },
            match self.bending {
                BendingModel::Springs => "",
                BendingModel::Hinges => " --bending hinges",
                BendingModel::Curvature => " --bending curvature",
            },
            self.seconds,
            1.0 / self.reference_dt,
            self.threads
        );
        let _ = writeln!(
            t,
            "## Summary at about {:.0} % of the points\n",
            SUMMARY_FRACTION * 100.0
        );
        let _ = writeln!(
            t,
            "Per scene, the fastest configuration under {:.0} % RMS error (or the closest miss):\n",
            RMS_GOAL * 100.0
        );
        table_header(
            &mut t,
            &[
                "scene",
                "configuration",
                "simulation points",
                "RMS error",
                "ms per frame",
                "speed-up",
                "over the fastest full frame",
                "goal met",
            ],
        );
        for b in &summary.best_at_10pct {
            let _ = writeln!(
                t,
                "| {} | {} | {} | {:.3} % | {:.3} | {:.1}× | {:.1}× | {} |",
                b.scene.name(),
                b.config,
                b.sim_points,
                b.rms_error * 100.0,
                b.ms_frame,
                b.speedup,
                b.speedup_over_fastest_full,
                yes(b.met)
            );
        }
        let _ = writeln!(
            t,
            "\nEach configuration on every scene (worst RMS error, least speed-up):\n"
        );
        table_header(
            &mut t,
            &[
                "configuration",
                "worst RMS error",
                "least speed-up",
                "goal met",
            ],
        );
        for e in &summary.every_scene {
            let _ = writeln!(
                t,
                "| {} | {:.3} % | {:.1}× | {} |",
                e.config,
                e.max_rms_error * 100.0,
                e.min_speedup,
                yes(e.met)
            );
        }
        self.budget_markdown(&mut t, summary);
        let _ = writeln!(t, "\n## References\n");
        table_header(
            &mut t,
            &[
                "scene",
                "dense points",
                "diagonal",
                "largest displacement",
                "ms per step",
                "residual speed",
            ],
        );
        for r in &self.references {
            let _ = writeln!(
                t,
                "| {} | {} | {:.3} | {:.2} % | {:.3} | {:.1e} /s |",
                r.scene.name(),
                r.dense_points,
                r.diagonal,
                r.outcome.max_displacement * 100.0,
                r.outcome.ms_step,
                r.outcome.residual_speed
            );
        }
        for &scene in &self.scenes {
            let _ = writeln!(t, "\n## {}\n", scene.name());
            let _ = writeln!(t, "![{0}](report_{0}.png)\n", scene.name());
            table_header(
                &mut t,
                &[
                    "level",
                    "simulation points",
                    "integrator",
                    "dt",
                    "sub-steps",
                    "ms per step",
                    "ms transfer",
                    "ms per frame",
                    "speed-up",
                    "RMS error",
                    "max error",
                    "normal error",
                    "stable",
                    "Pareto",
                ],
            );
            for r in self.rows.iter().filter(|r| r.scene == scene) {
                let o = &r.outcome;
                let (rms, max, normal) = r.error.map_or(
                    ("—".to_owned(), "—".to_owned(), "—".to_owned()),
                    |e| {
                        (
                            format!("{:.3} %", e.rms * 100.0),
                            format!("{:.3} %", e.max * 100.0),
                            format!("{:.2}°", e.normal_deg),
                        )
                    },
                );
                let _ = writeln!(
                    t,
                    "| {:.0} % | {} | {} | 1/{:.0} | {} | {:.3} | {:.3} | {:.3} | {:.1}× | {} | {} | {} | {} | {} |",
                    r.fraction * 100.0,
                    o.sim_points,
                    r.integrator,
                    1.0 / r.dt,
                    o.substeps,
                    o.ms_step,
                    o.ms_transfer,
                    o.ms_frame(),
                    r.speedup,
                    rms,
                    max,
                    normal,
                    o.failure
                        .as_deref()
                        .map_or("yes".to_owned(), |f| format!("no: {f}")),
                    if r.pareto { "●" } else { "" }
                );
            }
        }
        let _ = writeln!(
            t,
            "\n## The paper's Table 1\n\nThe 3203-point sphere poked (`assets/scenes/sphere_poke.ron`); a step includes the transfer of positions and normals to every dense point. The paper's times are from a 2 GHz Pentium IV (2007).\n"
        );
        table_header(
            &mut t,
            &[
                "simulation points",
                "integrator",
                "ms per step",
                "paper, s per step",
                "paper / ours",
            ],
        );
        for r in &summary.table1 {
            let _ = writeln!(
                t,
                "| {} | {} | {:.4} | {} | {:.0}× |",
                r.sim_points, r.integrator, r.ms_per_step, r.paper_s, r.speedup
            );
        }
        t
    }

    /// The error budget's section: the level chosen per scene, and predictions against
    /// measurements.
    fn budget_markdown(&self, t: &mut String, summary: &Summary) {
        let _ = writeln!(
            t,
            "\n## Levels chosen from an error budget of {:.0} % RMS\n\nThe successive-level estimate (`Scene::choose_level`: the scene run at 2, 4, 8, … % of the points, the error predicted from the differences between neighbouring levels), implicit Euler:\n",
            RMS_GOAL * 100.0
        );
        table_header(
            t,
            &[
                "scene",
                "chosen level",
                "simulation points",
                "predicted RMS",
                "measured RMS",
                "shrink per doubling",
                "estimate took",
            ],
        );
        for b in &summary.error_budget {
            let _ = writeln!(
                t,
                "| {} | {:.0} % | {} | {:.3} % | {} | {:.2} | {:.2} s |",
                b.scene.name(),
                b.fraction * 100.0,
                b.target,
                b.predicted_rms * 100.0,
                b.measured_rms
                    .map_or("unstable".to_owned(), |m| format!("{:.3} %", m * 100.0)),
                b.shrink,
                b.estimate_s
            );
        }
        let _ = writeln!(
            t,
            "\nPredicted against measured RMS error at the report's levels:\n"
        );
        let fractions: Vec<f32> = summary
            .error_budget
            .first()
            .map(|b| {
                b.levels
                    .iter()
                    .map(|l| l.fraction)
                    .filter(|f| *f < 1.0)
                    .collect()
            })
            .unwrap_or_default();
        let _ = write!(t, "| scene |");
        for f in &fractions {
            let _ = write!(t, " {:.0} % |", f * 100.0);
        }
        let _ = writeln!(t, "\n|---|{}", "---|".repeat(fractions.len()));
        for b in &summary.error_budget {
            let _ = write!(t, "| {} |", b.scene.name());
            for l in b.levels.iter().filter(|l| l.fraction < 1.0) {
                let measured = l
                    .measured_rms
                    .map_or("—".to_owned(), |m| format!("{:.2}", m * 100.0));
                let _ = write!(t, " {:.2} / {measured} % |", l.predicted_rms * 100.0);
            }
            let _ = writeln!(t);
        }
    }

    /// A scene's chart: RMS error over ms per frame, a line per integrator and step through
    /// the levels, its Pareto front ringed.
    fn chart(&self, scene: ReportScene) -> Chart {
        let mut series: Vec<Series> = Vec::new();
        for r in self.rows.iter().filter(|r| r.scene == scene) {
            let Some(e) = r.error else { continue };
            let point = (r.outcome.ms_frame(), e.rms.max(CHART_FLOOR));
            let name = r.config();
            match series.iter_mut().find(|s| s.name == name) {
                Some(s) => s.points.push(point),
                None => series.push(Series::new(name, vec![point])),
            }
        }
        let front = self
            .rows
            .iter()
            .filter(|r| r.scene == scene && r.pareto)
            .filter_map(|r| Some((r.outcome.ms_frame(), r.error?.rms.max(CHART_FLOOR))))
            .collect();
        Chart {
            title: format!(
                "{}: error against time per frame (points: levels)",
                scene.name()
            ),
            x_label: "ms per 60 Hz frame".to_owned(),
            y_label: "RMS error / diagonal".to_owned(),
            log_x: true,
            log_y: true,
            series,
            marked: Some(("Pareto front".to_owned(), front)),
            // Slow and inaccurate, the upper right corner stays empty.
            legend_upper: true,
        }
    }
}

/// Writes a Markdown table's header row and its rule.
fn table_header(t: &mut String, columns: &[&str]) {
    let _ = writeln!(t, "| {} |", columns.join(" | "));
    let _ = writeln!(t, "{}|", "|---".repeat(columns.len()));
}

/// A row's RMS error, infinite when it was not stable.
fn rms(r: &Row) -> f64 {
    r.error.map_or(f64::INFINITY, |e| e.rms)
}

fn yes(b: bool) -> &'static str {
    if b { "yes" } else { "no" }
}

/// The `--bending` value of a model.
fn bending_name(bending: BendingModel) -> &'static str {
    match bending {
        BendingModel::Springs => "springs",
        BendingModel::Hinges => "hinges",
        BendingModel::Curvature => "curvature",
    }
}
