//! `point-springs-bench scale`: how preparation, a step, the transfer and memory grow with
//! the dense and the simulation point counts. Each configuration is the generated sphere of
//! the paper's Fig. 5 ([`poked_sphere`]) at that size, prepared from scratch, then pressed
//! for a few steps (implicit Euler at 60 Hz, gas inside), each step followed by the transfer
//! of positions and normals to every dense point; the same steps are also taken from the
//! same state by the prefactored local/global solver. `--chart` draws the costs on log-log axes:
//! each preparation stage against the dense points, a step and the transfer against the
//! simulation points.

use std::fmt;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::Instant;

use bevy_point_springs::core::pipeline::{Progress, Stage, prepare_surface};
use bevy_point_springs::core::scene::Timeline;
use bevy_point_springs::core::solver::{DEFAULT_LOCAL_GLOBAL_ITERATIONS, ImplicitSolver};
use serde::Serialize;

use crate::chart::{Chart, Series};
use crate::failure::Failure;
use crate::poke::{POKED_SPHERE_DT, poked_sphere};
use crate::report::print_json;

/// Most dense points `point-springs-bench scale` takes.
const MAX_DENSE: usize = 20_000_000;

/// Most steps timed per configuration.
const MAX_STEPS: usize = 10_000;

/// Arguments of `point-springs-bench scale`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Dense point counts.
    #[arg(long, value_delimiter = ',', default_values_t = [10_000, 100_000, 1_000_000])]
    dense: Vec<usize>,
    /// Simulation point counts (each with every dense count it does not exceed).
    #[arg(long, value_delimiter = ',', default_values_t = [100, 1_000, 10_000])]
    sim: Vec<usize>,
    /// Steps timed per configuration.
    #[arg(long, default_value_t = 20)]
    steps: usize,
    /// Print JSON instead of a Markdown table.
    #[arg(long)]
    json: bool,
    /// Also draw the costs on log-log axes: STEM_prepare.svg/.png (each preparation stage
    /// against the dense points, a line per simulation point count) and STEM_step.svg/.png
    /// (a step and the transfer against the simulation points, a line per dense count).
    #[arg(long, value_name = "STEM")]
    chart: Option<PathBuf>,
}

/// One configuration: a line of the table or an object of the JSON array.
#[derive(Debug, Serialize)]
struct Row {
    /// Dense points.
    dense_points: usize,
    /// Simulation points.
    sim_points: usize,
    /// Springs.
    springs: usize,
    /// The whole preparation, ms.
    prepare_ms: f64,
    /// Of which normals (given with the sphere: checked and normalised), ms.
    normals_ms: f64,
    /// Of which §3, ms.
    simplify_ms: f64,
    /// Of which §4, ms.
    network_ms: f64,
    /// Of which the solver and the §5 coefficients, ms.
    transfer_setup_ms: f64,
    /// A step (the scene's press, then the solver; conjugate gradient), ms.
    step_ms: f64,
    /// The same steps from the same state with the prefactored local/global solver
    /// (`ImplicitSolver::LOCAL_GLOBAL`), ms; its factorisation included.
    step_local_global_ms: f64,
    /// Its first step alone (the factorisation and one step), ms.
    first_local_global_ms: f64,
    /// The transfer of positions and normals to every dense point, ms per step.
    transfer_ms: f64,
    /// The transfer's coefficients, MiB.
    coefficient_mib: f64,
    /// The process's resident memory with this surface prepared and stepped, MiB (Linux:
    /// `VmRSS`; it includes what the allocator keeps from earlier configurations).
    resident_mib: Option<f64>,
    /// The process's peak resident memory so far, MiB (Linux: `VmHWM`): with one
    /// configuration a run, what preparing and stepping it took at most.
    peak_mib: Option<f64>,
}

impl fmt::Display for Row {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "| {} | {} | {} | {:.0} ({:.0} / {:.0} / {:.0} / {:.0}) | {:.3} | {:.3} ({:.1}) | {:.3} | {:.1} |",
            self.dense_points,
            self.sim_points,
            self.springs,
            self.prepare_ms,
            self.normals_ms,
            self.simplify_ms,
            self.network_ms,
            self.transfer_setup_ms,
            self.step_ms,
            self.step_local_global_ms,
            self.first_local_global_ms,
            self.transfer_ms,
            self.coefficient_mib
        )?;
        for mib in [self.resident_mib, self.peak_mib] {
            match mib {
                Some(mib) => write!(f, " {mib:.0} |")?,
                None => write!(f, " — |")?,
            }
        }
        Ok(())
    }
}

/// Runs `point-springs-bench scale`.
pub fn run(args: &Args) -> Result<(), Failure> {
    if args.dense.iter().any(|&n| !(4..=MAX_DENSE).contains(&n)) {
        return Err(Failure::bad_input(format!(
            "--dense counts must be between 4 and {MAX_DENSE}"
        )));
    }
    if args.sim.iter().any(|&m| m < 4) {
        return Err(Failure::bad_input("--sim counts must be at least 4"));
    }
    if !(1..=MAX_STEPS).contains(&args.steps) {
        return Err(Failure::bad_input(format!(
            "--steps must be between 1 and {MAX_STEPS}"
        )));
    }
    let mut rows = Vec::new();
    for &dense in &args.dense {
        for &sim in args.sim.iter().filter(|&&m| m <= dense) {
            eprintln!("bench scale: {dense} dense points, {sim} simulation points");
            rows.push(measure(dense, sim, args.steps)?);
        }
    }
    if let Some(stem) = &args.chart {
        for path in charts(&rows, stem)? {
            eprintln!("bench scale: chart {}", path.display());
        }
    }
    if args.json {
        return print_json(&rows);
    }
    println!(
        "| dense points | simulation points | springs | prepare, ms (normals / §3 / §4 / solver and §5) | step (CG), ms | step (local/global ×{DEFAULT_LOCAL_GLOBAL_ITERATIONS}), ms (first step) | transfer, ms | coefficients, MiB | resident, MiB | peak, MiB |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for row in &rows {
        println!("{row}");
    }
    Ok(())
}

/// A figure of a row, ms.
type Measure = fn(&Row) -> f64;

/// A line per measure (a colour each) and per value of `group` (a dash each), through the
/// rows with that value at x = `x`: "measure, value `unit`".
fn lines(
    rows: &[Row],
    measures: &[(&str, Measure)],
    group: fn(&Row) -> usize,
    x: fn(&Row) -> usize,
    unit: &str,
) -> Vec<Series> {
    let mut values: Vec<usize> = rows.iter().map(group).collect();
    values.sort_unstable();
    values.dedup();
    let mut series = Vec::new();
    for (colour, (what, ms)) in measures.iter().enumerate() {
        for (k, &value) in values.iter().enumerate() {
            let points = rows
                .iter()
                .filter(|r| group(r) == value)
                .map(|r| (x(r) as f64, ms(r)))
                .collect();
            series.push(Series {
                colour: Some(colour),
                dash: (k > 0).then_some(3 * k as u32),
                ..Series::new(format!("{what}, {value} {unit}"), points)
            });
        }
    }
    series
}

/// The two log-log charts of `rows` (see [`Args::chart`]), written next to `stem`.
fn charts(rows: &[Row], stem: &Path) -> Result<Vec<PathBuf>, Failure> {
    let stages: [(&str, Measure); 5] = [
        ("whole", |r| r.prepare_ms),
        ("§3", |r| r.simplify_ms),
        ("§4", |r| r.network_ms),
        ("solver and §5", |r| r.transfer_setup_ms),
        ("normals", |r| r.normals_ms),
    ];
    let prepare = lines(
        rows,
        &stages,
        |r| r.sim_points,
        |r| r.dense_points,
        "simulation points",
    );
    let costs: [(&str, Measure); 3] = [
        ("step (CG)", |r| r.step_ms),
        ("step (local/global)", |r| r.step_local_global_ms),
        ("transfer", |r| r.transfer_ms),
    ];
    let step = lines(
        rows,
        &costs,
        |r| r.dense_points,
        |r| r.sim_points,
        "dense points",
    );
    let chart = |title: &str, x: &str, y: &str, series| Chart {
        title: title.to_owned(),
        x_label: x.to_owned(),
        y_label: y.to_owned(),
        log_x: true,
        log_y: true,
        series,
        marked: None,
        legend_upper: false,
    };
    let name = |suffix: &str| {
        let file = stem
            .file_name()
            .map_or_else(String::new, |f| f.to_string_lossy().into_owned());
        stem.with_file_name(format!("{file}_{suffix}"))
    };
    let mut written = Vec::new();
    written.extend(
        chart(
            "Preparation against the dense points (the generated sphere)",
            "dense points",
            "ms",
            prepare,
        )
        .write(&name("prepare"))?,
    );
    written.extend(
        chart(
            "A step (implicit Euler, 60 Hz) and the transfer against the simulation points",
            "simulation points",
            "ms",
            step,
        )
        .write(&name("step"))?,
    );
    Ok(written)
}

/// Prepares and steps one configuration.
fn measure(dense: usize, sim: usize, steps: usize) -> Result<Row, Failure> {
    let (scene, cloud) = poked_sphere(dense, sim, steps);
    // When each stage started, from the preparation's progress reports.
    let mut started: Vec<(Stage, Instant)> = Vec::new();
    let start = Instant::now();
    let mut surface = prepare_surface(cloud, &scene.surface_config(), &mut |p: Progress| {
        if started.last().is_none_or(|&(stage, _)| stage != p.stage) {
            started.push((p.stage, Instant::now()));
        }
        ControlFlow::Continue(())
    })
    .map_err(Failure::bad_input)?;
    let end = Instant::now();
    let stage_ms = |stage: Stage| {
        let Some(i) = started.iter().position(|&(s, _)| s == stage) else {
            return 0.0;
        };
        let until = started.get(i + 1).map_or(end, |&(_, t)| t);
        (until - started[i].1).as_secs_f64() * 1e3
    };
    let mut local_global = surface.solver.clone();
    let mut config = *local_global.config();
    config.implicit_solver = ImplicitSolver::LOCAL_GLOBAL;
    local_global.set_config(config).map_err(Failure::other)?;
    let mut timeline = Timeline::new(&scene, &surface.network.positions);
    let (mut lg_s, mut first_lg_s) = (0.0, 0.0);
    for step in 0..steps {
        let t = Instant::now();
        timeline
            .advance(&mut local_global.anchors, &surface.network.positions)
            .map_err(Failure::other)?;
        local_global.step(POKED_SPHERE_DT).map_err(Failure::other)?;
        let took = t.elapsed().as_secs_f64();
        lg_s += took;
        if step == 0 {
            first_lg_s = took;
        }
    }
    drop(local_global);
    let mut timeline = Timeline::new(&scene, &surface.network.positions);
    let (mut step_s, mut transfer_s) = (0.0, 0.0);
    for _ in 0..steps {
        let t = Instant::now();
        timeline
            .advance(&mut surface.solver.anchors, &surface.network.positions)
            .map_err(Failure::other)?;
        surface
            .solver
            .step(POKED_SPHERE_DT)
            .map_err(Failure::other)?;
        step_s += t.elapsed().as_secs_f64();
        let t = Instant::now();
        surface
            .dense
            .follow(&surface.solver.points)
            .map_err(Failure::other)?;
        transfer_s += t.elapsed().as_secs_f64();
    }
    let per_step = |s: f64| s * 1e3 / steps as f64;
    Ok(Row {
        dense_points: surface.dense.len(),
        sim_points: surface.solver.points.len(),
        springs: surface.solver.springs.len(),
        prepare_ms: (end - start).as_secs_f64() * 1e3,
        normals_ms: stage_ms(Stage::Normals),
        simplify_ms: stage_ms(Stage::Simplify),
        network_ms: stage_ms(Stage::Network),
        transfer_setup_ms: stage_ms(Stage::Transfer),
        step_ms: per_step(step_s),
        step_local_global_ms: per_step(lg_s),
        first_local_global_ms: first_lg_s * 1e3,
        transfer_ms: per_step(transfer_s),
        coefficient_mib: surface.dense.transfer().coefficient_bytes() as f64
            / f64::from(1u32 << 20),
        resident_mib: status_mib("VmRSS:"),
        peak_mib: status_mib("VmHWM:"),
    })
}

/// A memory figure of the process's status (`field`: "VmRSS:", "VmHWM:"), MiB, where the
/// system says (Linux).
fn status_mib(field: &str) -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(field))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}
