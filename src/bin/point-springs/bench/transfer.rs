//! `point-springs bench`: timings of the core stages against straightforward or literal
//! implementations, both measured in the same run (ratios, not absolute times, are what
//! carry over between machines).

use std::time::Instant;

use bevy_point_springs::core::cloud::shapes::fibonacci_sphere;
use bevy_point_springs::core::fixtures::cloth::{
    CLOTH_DT, CLOTH_SIZE, CLOTH_STEPS, ReferenceCloth, cloth_grid, max_sag,
};
use bevy_point_springs::core::fixtures::paper_transfer::literal_transfer;
use bevy_point_springs::core::normals::pca_normals_of;
use bevy_point_springs::core::simplify::{SimplifyConfig, simplify};
use bevy_point_springs::core::solver::{Integrator, Solver, SubstepPolicy};
use bevy_point_springs::core::transfer::{
    DEFAULT_BANDWIDTH, DEFAULT_TRANSFER_K, Transfer, TransferConfig,
};
use clap::{Subcommand, ValueEnum};
use glam::{Mat3, Vec3};
use serde::Serialize;

use crate::{Failure, print_json};

#[derive(Subcommand)]
pub enum BenchCase {
    /// The standard CPU cloth benchmark: a 32×32 grid with 5826 springs hanging from two
    /// corners, symplectic Euler at dt = 1/960 for 1000 steps, timed against the
    /// straightforward loop over the springs in the same run (one thread).
    ClothGrid {
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
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Displacement transfer (§5): the precomputed coefficients against the paper's literal
    /// per-frame method (k-NN search, 3×3 solve and PCA normals per dense point), both
    /// parallel, timed in the same run; positions and normals are compared with the exact
    /// answer for a known smooth deformation (a bulge over the upper half of the sphere).
    Transfer {
        /// Dense points (a Fibonacci sphere of radius 1).
        #[arg(long, default_value_t = 1_000_000)]
        points: usize,
        /// Simulation points.
        #[arg(long, default_value_t = 10_000)]
        sim: usize,
        /// Where the simulation points come from.
        #[arg(long, value_enum, default_value_t = SimSource::Sphere)]
        sim_source: SimSource,
        /// Simulation points each dense point follows.
        #[arg(short, long, default_value_t = DEFAULT_TRANSFER_K)]
        k: usize,
        /// Gaussian bandwidth, a multiple of the farthest neighbour's distance.
        #[arg(long, default_value_t = DEFAULT_BANDWIDTH)]
        bandwidth: f32,
        /// Timed rounds (each times every method); the fastest round of each counts.
        #[arg(long, default_value_t = 5)]
        repeat: usize,
        /// Skip the literal per-frame method.
        #[arg(long)]
        no_literal: bool,
        /// Threads for both methods (default: one per core).
        #[arg(long)]
        threads: Option<usize>,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// The Bevy plugin headless (one fixed tick per update): milliseconds per tick split
    /// into forces, stepping and transfer, the surfel upload's packing, and the same work
    /// done by the core alone in the same run. Without SCENE: a generated sphere (of
    /// --dense points, --sim simulation points) in a cup with a sustained poke.
    #[cfg(feature = "plugin")]
    Plugin(crate::bench_plugin::PluginArgs),
    /// Whether the spring network is watertight: each cloud simplified to several fractions
    /// of its points, with the network's closedness, Euler characteristic, boundary loops,
    /// fold-overs, crossings and the time of each stage (a Markdown table, or JSON).
    Network(crate::bench_network::NetworkArgs),
}

/// Where the transfer benchmark's simulation points come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SimSource {
    /// A Fibonacci sphere of their own (no set-up time on large clouds).
    Sphere,
    /// Chosen from the dense cloud by §3 (slow on large clouds: half a minute for 10^6).
    Simplify,
}

/// Most dense points the transfer benchmark takes.
const MAX_BENCH_POINTS: usize = 20_000_000;

/// Most threads the transfer benchmark accepts.
const MAX_BENCH_THREADS: usize = 256;

/// Amplitude of the benchmark's bulge: u(x) = A·y₊²·x.
const BULGE: f32 = 0.2;

/// Neighbours for PCA normals (the literal method's normal update).
const PCA_K: usize = 10;

struct TransferBench {
    points: usize,
    sim: usize,
    sim_source: SimSource,
    config: TransferConfig,
    repeat: usize,
    no_literal: bool,
}

/// Errors of a deformed surface against the exact one.
#[derive(Serialize, Clone, Copy)]
struct Errors {
    /// Largest distance from the exact deformed position.
    position_max: f32,
    /// Mean distance from it.
    position_mean: f32,
    /// Largest angle from the exact deformed normal, degrees.
    normal_max_deg: f32,
    /// Mean angle from it, degrees.
    normal_mean_deg: f32,
}

#[derive(Serialize)]
struct TransferBenchReport {
    benchmark: &'static str,
    dense_points: usize,
    sim_points: usize,
    sim_source: SimSource,
    k: usize,
    bandwidth: f32,
    threads: usize,
    max_displacement: f32,
    precompute_ms: f64,
    coefficient_mib: f64,
    fits_full: usize,
    fits_plane: usize,
    fits_regularised: usize,
    /// Rows whose fit does not give back the rest surface: a frame computes them from the
    /// displacements and the rest frame.
    fits_residual: usize,
    apply_ms: f64,
    apply_positions_ms: f64,
    errors: Errors,
    errors_pca_normals: Errors,
    literal_ms: Option<f64>,
    literal_errors: Option<Errors>,
    speedup: Option<f64>,
}

/// The benchmark's deformation: x ↦ x + A·y₊²·x, and its Jacobian.
fn bulge(x: Vec3) -> (Vec3, Mat3) {
    let y = x.y.max(0.0);
    let s = 1.0 + BULGE * y * y;
    let jacobian = Mat3::from_cols(Vec3::X * s, Vec3::Y * s + 2.0 * BULGE * y * x, Vec3::Z * s);
    (x * s, jacobian)
}

/// Position and normal errors against the exact bulge of the rest surface.
fn errors(rest: &[Vec3], normals: &[Vec3], positions: &[Vec3], deformed: &[Vec3]) -> Errors {
    let mut e = Errors {
        position_max: 0.0,
        position_mean: 0.0,
        normal_max_deg: 0.0,
        normal_mean_deg: 0.0,
    };
    let (mut sum_p, mut sum_n) = (0.0f64, 0.0f64);
    for i in 0..rest.len() {
        let (exact, jacobian) = bulge(rest[i]);
        let exact_n = (jacobian.inverse().transpose() * normals[i]).normalize();
        let dp = positions[i].distance(exact);
        let dn = deformed[i]
            .dot(exact_n)
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees();
        e.position_max = e.position_max.max(dp);
        e.normal_max_deg = e.normal_max_deg.max(dn);
        sum_p += f64::from(dp);
        sum_n += f64::from(dn);
    }
    let n = rest.len().max(1) as f64;
    e.position_mean = (sum_p / n) as f32;
    e.normal_mean_deg = (sum_n / n) as f32;
    e
}

/// A timed sample lasts about this long.
const SAMPLE_MS: f64 = 5.0;
/// Calls in a sample at most.
const MAX_SAMPLE_CALLS: usize = 10_000;

/// Milliseconds per call of `f`, over `calls` calls.
fn per_call_ms(calls: usize, f: &mut dyn FnMut()) -> f64 {
    let start = Instant::now();
    for _ in 0..calls {
        f();
    }
    start.elapsed().as_secs_f64() * 1e3 / calls as f64
}

/// Calls of `f` that last about [`SAMPLE_MS`] (after one warm-up call).
fn calls_for(f: &mut dyn FnMut()) -> usize {
    f();
    let once = per_call_ms(1, f);
    ((SAMPLE_MS / once.max(1e-6)).ceil() as usize).clamp(1, MAX_SAMPLE_CALLS)
}

fn transfer(b: &TransferBench, json: bool) -> Result<(), Failure> {
    if !(4..=MAX_BENCH_POINTS).contains(&b.points) {
        return Err(Failure::bad_input(format!(
            "--points must be between 4 and {MAX_BENCH_POINTS}"
        )));
    }
    if !(4..=b.points).contains(&b.sim) {
        return Err(Failure::bad_input(
            "--sim must be at least 4 and at most --points",
        ));
    }
    let dense = fibonacci_sphere(b.points, 1.0);
    let (rest, normals) = (dense.positions(), dense.normals().unwrap_or_default());
    let sim: Vec<Vec3> = match b.sim_source {
        SimSource::Sphere => fibonacci_sphere(b.sim, 1.0).positions().to_vec(),
        SimSource::Simplify => {
            let kept = simplify(rest, normals, &SimplifyConfig::target(b.sim))
                .map_err(Failure::bad_input)?;
            kept.gather(rest, normals).0
        }
    };
    let disp: Vec<Vec3> = sim.iter().map(|&s| bulge(s).0 - s).collect();
    let start = Instant::now();
    let t = Transfer::new(rest, normals, &sim, b.config).map_err(Failure::bad_input)?;
    let precompute_ms = start.elapsed().as_secs_f64() * 1e3;
    let mut positions = vec![Vec3::ZERO; rest.len()];
    let mut deformed = vec![Vec3::ZERO; rest.len()];
    let mut literal_out = (Vec::new(), Vec::new());
    // Rounds interleave the methods, so that a machine that slows down or speeds up over
    // the run (other tenants, clock changes) does not tilt the ratio; each round times the
    // cheap methods over enough calls to last a few milliseconds. The fastest round counts.
    // The lengths match by construction: the calls cannot fail.
    let (mut apply_ms, mut apply_positions_ms, mut literal_ms) =
        (f64::INFINITY, f64::INFINITY, f64::INFINITY);
    let calls = calls_for(&mut || {
        let _ = t.apply(&disp, &mut positions, &mut deformed);
    });
    for _ in 0..b.repeat.max(1) {
        apply_ms = apply_ms.min(per_call_ms(calls, &mut || {
            let _ = t.apply(&disp, &mut positions, &mut deformed);
        }));
        apply_positions_ms = apply_positions_ms.min(per_call_ms(calls, &mut || {
            let _ = t.apply_positions(&disp, &mut positions);
        }));
        if !b.no_literal {
            literal_ms = literal_ms.min(per_call_ms(1, &mut || {
                literal_out = literal_transfer(rest, normals, &sim, &disp, b.config, PCA_K);
            }));
        }
    }
    let _ = t.apply(&disp, &mut positions, &mut deformed);
    let errors_gradient = errors(rest, normals, &positions, &deformed);
    let pca = pca_normals_of(&positions, &deformed, PCA_K);
    let errors_pca = errors(rest, normals, &positions, &pca);
    let literal = (!b.no_literal).then(|| {
        (
            literal_ms,
            errors(rest, normals, &literal_out.0, &literal_out.1),
        )
    });
    let fits = t.report();
    let report = TransferBenchReport {
        benchmark: "transfer",
        dense_points: rest.len(),
        sim_points: sim.len(),
        sim_source: b.sim_source,
        k: b.config.k,
        bandwidth: b.config.bandwidth,
        threads: rayon::current_num_threads(),
        max_displacement: disp.iter().map(|d| d.length()).fold(0.0, f32::max),
        precompute_ms,
        coefficient_mib: t.coefficient_bytes() as f64 / f64::from(1u32 << 20),
        fits_full: fits.full,
        fits_plane: fits.plane,
        fits_regularised: fits.regularised,
        fits_residual: fits.residual,
        apply_ms,
        apply_positions_ms,
        errors: errors_gradient,
        errors_pca_normals: errors_pca,
        literal_ms: literal.as_ref().map(|l| l.0),
        literal_errors: literal.as_ref().map(|l| l.1),
        speedup: literal.as_ref().map(|l| l.0 / apply_ms),
    };
    if json {
        return print_json(&report);
    }
    let r = &report;
    println!(
        "transfer      {} dense points follow {} simulation points ({:?}), k = {}, h = {} × reach, {} threads",
        r.dense_points, r.sim_points, r.sim_source, r.k, r.bandwidth, r.threads
    );
    println!(
        "precompute    {:.1} ms, {:.1} MiB of coefficients (fits: {} full, {} plane, {} regularised; {} rows not reproducing the rest surface)",
        r.precompute_ms,
        r.coefficient_mib,
        r.fits_full,
        r.fits_plane,
        r.fits_regularised,
        r.fits_residual
    );
    let show = |name: &str, ms: Option<f64>, e: &Errors| {
        let ms = ms.map_or_else(|| "—".to_owned(), |ms| format!("{ms:.3}"));
        println!(
            "{name:<13} {ms:>9} ms   position error max {:.2e} mean {:.2e}   normal error max {:.3}° mean {:.4}°",
            e.position_max, e.position_mean, e.normal_max_deg, e.normal_mean_deg
        );
    };
    show("precomputed", Some(r.apply_ms), &r.errors);
    println!("  positions only {:.3} ms", r.apply_positions_ms);
    show("  +PCA normals", None, &r.errors_pca_normals);
    if let (Some(ms), Some(e), Some(x)) = (r.literal_ms, &r.literal_errors, r.speedup) {
        show("literal", Some(ms), e);
        println!("speedup       {x:.1}× (literal / precomputed, positions and normals)");
    }
    Ok(())
}

#[derive(Serialize)]
struct ClothBenchReport {
    benchmark: &'static str,
    particles: usize,
    springs: usize,
    springs_in_runs: usize,
    steps: usize,
    dt: f32,
    integrator: String,
    us_per_step: f64,
    max_sag: f32,
    finite: bool,
    cg_iterations: u64,
    reference_us_per_step: Option<f64>,
    reference_max_sag: Option<f32>,
    sag_difference: Option<f32>,
    max_position_difference: Option<f32>,
    speedup: Option<f64>,
}

/// A state that can be stepped and timed.
struct Timed<S, F> {
    fresh: F,
    step: fn(&mut S),
    best: f64,
    last: Option<S>,
}

impl<S, F: FnMut() -> S> Timed<S, F> {
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

/// Runs a benchmark.
pub fn bench(case: BenchCase) -> Result<(), Failure> {
    match case {
        #[cfg(feature = "plugin")]
        BenchCase::Plugin(args) => crate::bench_plugin::bench_plugin(&args),
        BenchCase::Network(args) => crate::bench_network::bench_network(&args),
        BenchCase::ClothGrid {
            size,
            steps,
            integrator,
            repeat,
            no_reference,
            json,
        } => cloth(size, steps, integrator, repeat, no_reference, json),
        BenchCase::Transfer {
            points,
            sim,
            sim_source,
            k,
            bandwidth,
            repeat,
            no_literal,
            threads,
            json,
        } => {
            let mut pool = rayon::ThreadPoolBuilder::new();
            if let Some(threads) = threads {
                if !(1..=MAX_BENCH_THREADS).contains(&threads) {
                    return Err(Failure::bad_input(format!(
                        "--threads must be between 1 and {MAX_BENCH_THREADS}"
                    )));
                }
                pool = pool.num_threads(threads);
            }
            let pool = pool.build().map_err(Failure::other)?;
            let bench = TransferBench {
                points,
                sim,
                sim_source,
                config: TransferConfig {
                    k,
                    bandwidth,
                    ..TransferConfig::default()
                },
                repeat,
                no_literal,
            };
            pool.install(|| transfer(&bench, json))
        }
    }
}

fn cloth(
    size: usize,
    steps: usize,
    integrator: Integrator,
    repeat: usize,
    no_reference: bool,
    json: bool,
) -> Result<(), Failure> {
    let grid = cloth_grid(size).map_err(Failure::bad_input)?;
    let solver = grid
        .solver_with(integrator, SubstepPolicy::Unchecked)
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
    let mut timed_reference = (!no_reference).then(|| {
        Timed::new(
            || ReferenceCloth::new(&grid),
            |r: &mut ReferenceCloth| r.step(CLOTH_DT),
        )
    });
    for _ in 0..repeat.max(1) {
        timed_solver.round(steps);
        if let Some(r) = &mut timed_reference {
            r.round(steps);
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
        steps,
        dt: CLOTH_DT,
        integrator: integrator.to_string(),
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
    if json {
        return print_json(&report);
    }
    println!(
        "cloth-grid    {} particles, {} springs ({} in vectorised runs), {} steps of {:.6} s, {}",
        report.particles,
        report.springs,
        report.springs_in_runs,
        report.steps,
        report.dt,
        report.integrator
    );
    println!(
        "solver        {:.2} µs/step, max sag {:.6}",
        report.us_per_step, report.max_sag
    );
    if let (Some(t), Some(s), Some(d), Some(x)) = (
        report.reference_us_per_step,
        report.reference_max_sag,
        report.speedup,
        report.max_position_difference,
    ) {
        println!("reference     {t:.2} µs/step, max sag {s:.6}");
        println!("speedup       {d:.2}×; final positions differ by at most {x:.2e}");
    }
    Ok(())
}
