//! `point-springs-bench transfer`: displacement transfer (§5) with precomputed coefficients
//! against the paper's literal per-frame method, both timed in the same run and compared
//! with the exact answer for a known smooth deformation.

use std::fmt;
use std::time::Instant;

use bevy_point_springs::core::cloud::shapes::fibonacci_sphere;
use bevy_point_springs::core::normals::pca_normals_of;
use bevy_point_springs::core::simplify::{SimplifyConfig, simplify};
use bevy_point_springs::core::transfer::{
    DEFAULT_BANDWIDTH, DEFAULT_TRANSFER_K, Transfer, TransferConfig,
};
use clap::ValueEnum;
use glam::{Mat3, Vec3};
use point_springs_bench::baselines::paper_transfer::literal_transfer;
use serde::Serialize;

use crate::failure::Failure;
use crate::flags::JsonFlag;
use crate::report::Report;

/// Arguments of `point-springs-bench transfer`.
#[derive(Debug, clap::Args)]
pub struct Args {
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
    #[command(flatten)]
    json: JsonFlag,
}

/// Where the transfer benchmark's simulation points come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
enum SimSource {
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

/// A timed sample lasts about this long.
const SAMPLE_MS: f64 = 5.0;
/// Calls in a sample at most.
const MAX_SAMPLE_CALLS: usize = 10_000;

/// Errors of a deformed surface against the exact one.
#[derive(Debug, Serialize, Clone, Copy)]
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

/// What `point-springs-bench transfer` reports.
#[derive(Debug, Serialize)]
struct TransferBenchReport {
    /// "transfer".
    benchmark: &'static str,
    /// Dense points.
    dense_points: usize,
    /// Simulation points.
    sim_points: usize,
    /// Where they came from.
    sim_source: SimSource,
    /// Simulation points each dense point follows.
    k: usize,
    /// Gaussian bandwidth.
    bandwidth: f32,
    /// Threads of both methods.
    threads: usize,
    /// The bulge's largest displacement of a simulation point.
    max_displacement: f32,
    /// Time of the precomputation, ms.
    precompute_ms: f64,
    /// Size of the coefficients, MiB.
    coefficient_mib: f64,
    /// Rows fitted in full.
    fits_full: usize,
    /// Rows fitted to a plane.
    fits_plane: usize,
    /// Rows fitted with regularisation.
    fits_regularised: usize,
    /// Rows whose fit does not give back the rest surface: a frame computes them from the
    /// displacements and the rest frame.
    fits_residual: usize,
    /// The precomputed transfer of positions and normals, ms per frame.
    apply_ms: f64,
    /// The precomputed transfer of positions only, ms per frame.
    apply_positions_ms: f64,
    /// Bytes a frame of positions and normals reads and writes: neighbour indices and
    /// coefficients, the simulation points' positions, the dense positions and normals.
    frame_bytes: usize,
    /// Those bytes over the frame's time, GB/s (10⁹ bytes per second).
    transfer_gb_s: f64,
    /// A parallel memory copy of the same number of bytes (half read, half written), on
    /// the same threads in the same rounds, GB/s: the machine's ceiling for the transfer.
    memcpy_gb_s: f64,
    /// Its errors.
    errors: Errors,
    /// Its errors with PCA normals of the deformed positions instead.
    errors_pca_normals: Errors,
    /// The literal method, ms per frame.
    literal_ms: Option<f64>,
    /// Its errors.
    literal_errors: Option<Errors>,
    /// Literal time / precomputed time.
    speedup: Option<f64>,
}

/// Writes a method's line: its time (or a dash) and its errors.
fn error_line(f: &mut fmt::Formatter<'_>, name: &str, ms: Option<f64>, e: &Errors) -> fmt::Result {
    let ms = ms.map_or_else(|| "—".to_owned(), |ms| format!("{ms:.3}"));
    writeln!(
        f,
        "{name:<13} {ms:>9} ms   position error max {:.2e} mean {:.2e}   normal error max {:.3}° mean {:.4}°",
        e.position_max, e.position_mean, e.normal_max_deg, e.normal_mean_deg
    )
}

impl fmt::Display for TransferBenchReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "transfer      {} dense points follow {} simulation points ({:?}), k = {}, h = {} × reach, {} threads",
            self.dense_points,
            self.sim_points,
            self.sim_source,
            self.k,
            self.bandwidth,
            self.threads
        )?;
        writeln!(
            f,
            "precompute    {:.1} ms, {:.1} MiB of coefficients (fits: {} full, {} plane, {} regularised; {} rows not reproducing the rest surface)",
            self.precompute_ms,
            self.coefficient_mib,
            self.fits_full,
            self.fits_plane,
            self.fits_regularised,
            self.fits_residual
        )?;
        error_line(f, "precomputed", Some(self.apply_ms), &self.errors)?;
        writeln!(
            f,
            "  throughput   {:.1} GB/s ({:.1} MB read and written per frame), {:.0} % of a {:.1} GB/s memory copy",
            self.transfer_gb_s,
            self.frame_bytes as f64 / 1e6,
            100.0 * self.transfer_gb_s / self.memcpy_gb_s,
            self.memcpy_gb_s
        )?;
        writeln!(f, "  positions only {:.3} ms", self.apply_positions_ms)?;
        error_line(f, "  +PCA normals", None, &self.errors_pca_normals)?;
        if let (Some(ms), Some(e), Some(x)) = (self.literal_ms, &self.literal_errors, self.speedup)
        {
            error_line(f, "literal", Some(ms), e)?;
            writeln!(
                f,
                "speedup       {x:.1}× (literal / precomputed, positions and normals)"
            )?;
        }
        Ok(())
    }
}

impl Report for TransferBenchReport {}

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

/// Runs `point-springs-bench transfer` (on its own thread pool).
pub fn run(args: &Args) -> Result<(), Failure> {
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(threads) = args.threads {
        if !(1..=MAX_BENCH_THREADS).contains(&threads) {
            return Err(Failure::bad_input(format!(
                "--threads must be between 1 and {MAX_BENCH_THREADS}"
            )));
        }
        pool = pool.num_threads(threads);
    }
    let pool = pool.build().map_err(Failure::other)?;
    let report = pool.install(|| measure(args))?;
    args.json.emit(&report)
}

/// The transfer configuration the arguments ask for.
fn config(args: &Args) -> TransferConfig {
    TransferConfig {
        k: args.k,
        bandwidth: args.bandwidth,
        ..TransferConfig::default()
    }
}

/// The simulation points over the dense sphere (`rest` with `normals`).
fn sim_points(args: &Args, rest: &[Vec3], normals: &[Vec3]) -> Result<Vec<Vec3>, Failure> {
    Ok(match args.sim_source {
        SimSource::Sphere => fibonacci_sphere(args.sim, 1.0).positions().to_vec(),
        SimSource::Simplify => {
            let kept = simplify(rest, normals, &SimplifyConfig::target(args.sim))
                .map_err(Failure::bad_input)?;
            kept.gather(rest, normals).0
        }
    })
}

/// Times of the methods, ms per frame (the fastest round of each).
#[derive(Debug, Clone, Copy)]
struct Times {
    /// Precomputed, positions and normals.
    apply: f64,
    /// Precomputed, positions only.
    apply_positions: f64,
    /// Literal (infinite when skipped).
    literal: f64,
    /// A memory copy of the frame's bytes.
    memcpy: f64,
}

/// Bytes moved per frame of positions and normals (see `TransferBenchReport::frame_bytes`).
fn frame_bytes(t: &Transfer, sim: usize) -> usize {
    let written = 2 * size_of::<Vec3>() * t.len();
    // The simulation points' current positions, read as 16-byte vectors.
    t.coefficient_bytes() + 16 * sim + written
}

/// Copies `src` into `dst` in parallel, a few pieces per thread (as the transfer splits).
fn parallel_copy(src: &[u8], dst: &mut [u8]) {
    use rayon::prelude::*;
    let pieces = 4 * rayon::current_num_threads();
    let chunk = src.len().div_ceil(pieces).max(4096);
    dst.par_chunks_mut(chunk)
        .zip(src.par_chunks(chunk))
        .for_each(|(d, s)| d.copy_from_slice(s));
}

/// GB/s of `bytes` moved in `ms` milliseconds.
fn gb_per_s(bytes: usize, ms: f64) -> f64 {
    bytes as f64 / (ms * 1e-3) / 1e9
}

/// Times the methods and measures their errors; the report.
fn measure(args: &Args) -> Result<TransferBenchReport, Failure> {
    if !(4..=MAX_BENCH_POINTS).contains(&args.points) {
        return Err(Failure::bad_input(format!(
            "--points must be between 4 and {MAX_BENCH_POINTS}"
        )));
    }
    if !(4..=args.points).contains(&args.sim) {
        return Err(Failure::bad_input(
            "--sim must be at least 4 and at most --points",
        ));
    }
    let config = config(args);
    let dense = fibonacci_sphere(args.points, 1.0);
    let (rest, normals) = (dense.positions(), dense.normals().unwrap_or_default());
    let sim = sim_points(args, rest, normals)?;
    let disp: Vec<Vec3> = sim.iter().map(|&s| bulge(s).0 - s).collect();
    let start = Instant::now();
    let t = Transfer::new(rest, normals, &sim, config).map_err(Failure::bad_input)?;
    let precompute_ms = start.elapsed().as_secs_f64() * 1e3;
    let mut positions = vec![Vec3::ZERO; rest.len()];
    let mut deformed = vec![Vec3::ZERO; rest.len()];
    let mut literal_out = (Vec::new(), Vec::new());
    // Rounds interleave the methods, so that a machine that slows down or speeds up over
    // the run (other tenants, clock changes) does not tilt the ratio; each round times the
    // cheap methods over enough calls to last a few milliseconds. The fastest round counts.
    // The lengths match by construction: the calls cannot fail.
    let mut times = Times {
        apply: f64::INFINITY,
        apply_positions: f64::INFINITY,
        literal: f64::INFINITY,
        memcpy: f64::INFINITY,
    };
    // The copy moves as many bytes as a frame: half of them read, half written.
    let bytes = frame_bytes(&t, sim.len());
    let copy_src = vec![1u8; bytes / 2];
    let mut copy_dst = vec![0u8; bytes / 2];
    let copy_calls = calls_for(&mut || parallel_copy(&copy_src, &mut copy_dst));
    let calls = calls_for(&mut || {
        let _ = t.apply(&disp, &mut positions, &mut deformed);
    });
    for _ in 0..args.repeat.max(1) {
        times.apply = times.apply.min(per_call_ms(calls, &mut || {
            let _ = t.apply(&disp, &mut positions, &mut deformed);
        }));
        times.apply_positions = times.apply_positions.min(per_call_ms(calls, &mut || {
            let _ = t.apply_positions(&disp, &mut positions);
        }));
        times.memcpy = times.memcpy.min(per_call_ms(copy_calls, &mut || {
            parallel_copy(&copy_src, &mut copy_dst);
        }));
        if !args.no_literal {
            times.literal = times.literal.min(per_call_ms(1, &mut || {
                literal_out = literal_transfer(rest, normals, &sim, &disp, config, PCA_K);
            }));
        }
    }
    let _ = t.apply(&disp, &mut positions, &mut deformed);
    let pca = pca_normals_of(&positions, &deformed, PCA_K);
    let literal = (!args.no_literal).then(|| {
        (
            times.literal,
            errors(rest, normals, &literal_out.0, &literal_out.1),
        )
    });
    let fits = t.report();
    Ok(TransferBenchReport {
        benchmark: "transfer",
        dense_points: rest.len(),
        sim_points: sim.len(),
        sim_source: args.sim_source,
        k: config.k,
        bandwidth: config.bandwidth,
        threads: rayon::current_num_threads(),
        max_displacement: disp.iter().map(|d| d.length()).fold(0.0, f32::max),
        precompute_ms,
        coefficient_mib: t.coefficient_bytes() as f64 / f64::from(1u32 << 20),
        fits_full: fits.full,
        fits_plane: fits.plane,
        fits_regularised: fits.regularised,
        fits_residual: fits.residual,
        apply_ms: times.apply,
        apply_positions_ms: times.apply_positions,
        frame_bytes: bytes,
        transfer_gb_s: gb_per_s(bytes, times.apply),
        memcpy_gb_s: gb_per_s(2 * (bytes / 2), times.memcpy),
        errors: errors(rest, normals, &positions, &deformed),
        errors_pca_normals: errors(rest, normals, &positions, &pca),
        literal_ms: literal.as_ref().map(|l| l.0),
        literal_errors: literal.as_ref().map(|l| l.1),
        speedup: literal.as_ref().map(|l| l.0 / times.apply),
    })
}
