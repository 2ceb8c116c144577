//! `point-springs`: the headless command-line tool.
//!
//! ```text
//! point-springs info FILE [--format F] [--json]
//! point-springs normals FILE -o OUT.ply [-k K] [--format F] [--ascii] [--reestimate] [--json]
//! point-springs simplify FILE (--target N | --max-diameter D) [-k K] [--density RHO]
//!                        [-o OUT.ply] [--format F] [--ascii] [--json]
//! point-springs bench cloth-grid [--size N] [--steps S] [--integrator I] [--repeat R]
//!                        [--no-reference] [--json]
//! ```
//!
//! Exit codes: 0 success, 2 bad input (unreadable or malformed file, bad arguments),
//! 1 any other failure (e.g. the output cannot be written).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use bevy_point_springs::core::PointCloud;
use bevy_point_springs::core::io::{CloudFormat, PlyEncoding, read_cloud, write_ply};
use bevy_point_springs::core::knn::KnnIndex;
use bevy_point_springs::core::network::{DEFAULT_DENSITY, NetworkConfig, build_network};
use bevy_point_springs::core::normals::{DEFAULT_NORMAL_K, NormalSource, ensure_normals};
use bevy_point_springs::core::simplify::{
    DEFAULT_SIMPLIFY_K, SimplifyConfig, SimplifyProgress, StopReason, simplify_with_progress,
};
use bevy_point_springs::core::solver::cloth::{
    CLOTH_DT, CLOTH_SIZE, CLOTH_STEPS, ReferenceCloth, cloth_grid, max_sag,
};
use bevy_point_springs::core::solver::{Integrator, SubstepPolicy};
use clap::{Parser, Subcommand};
use serde::Serialize;

/// Exit code for bad input.
const EXIT_BAD_INPUT: u8 = 2;
/// Exit code for other failures.
const EXIT_FAILURE: u8 = 1;

#[derive(Parser)]
#[command(
    name = "point-springs",
    version,
    about = "Point-sampled surfaces: inspect, prepare and simulate them"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Summarise a point cloud: count, normals, bounds, spacing.
    Info {
        /// The cloud (.ply .xyz .pwn .off .obj).
        file: PathBuf,
        /// Read as this format instead of the one the extension names.
        #[arg(long)]
        format: Option<CloudFormat>,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Give a cloud oriented normals (PCA + propagation when it has none) and write it as PLY.
    Normals {
        /// The cloud (.ply .xyz .pwn .off .obj).
        file: PathBuf,
        /// Output PLY file.
        #[arg(short, long)]
        output: PathBuf,
        /// Neighbours per PCA fit.
        #[arg(short, default_value_t = DEFAULT_NORMAL_K)]
        k: usize,
        /// Read as this format instead of the one the extension names.
        #[arg(long)]
        format: Option<CloudFormat>,
        /// Estimate normals even when the file has usable ones.
        #[arg(long)]
        reestimate: bool,
        /// Write ASCII PLY instead of binary little-endian.
        #[arg(long)]
        ascii: bool,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Choose simulation points (§3 tangent-plane Delaunay simplification) and build their
    /// spring network (§4); normals are estimated first when the file has none.
    #[command(group(clap::ArgGroup::new("stop").required(true).multiple(true).args(["target", "max_diameter"])))]
    Simplify {
        /// The cloud (.ply .xyz .pwn .off .obj).
        file: PathBuf,
        /// Stop when this many simulation points remain.
        #[arg(long)]
        target: Option<usize>,
        /// Stop when every region R is at least this wide (the paper's threshold on d).
        #[arg(long)]
        max_diameter: Option<f32>,
        /// Neighbours per point for the local Delaunay rings (the paper's k, 10–20).
        #[arg(short, default_value_t = DEFAULT_SIMPLIFY_K)]
        k: usize,
        /// Surface density ρ (mass per unit area) for the masses m = ρ·area(R)/3.
        #[arg(long, default_value_t = DEFAULT_DENSITY)]
        density: f32,
        /// Write the simulation points with their normals to this PLY file.
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// Read as this format instead of the one the extension names.
        #[arg(long)]
        format: Option<CloudFormat>,
        /// Write ASCII PLY instead of binary little-endian.
        #[arg(long)]
        ascii: bool,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Time the solver on standard networks.
    Bench {
        #[command(subcommand)]
        case: BenchCase,
    },
}

#[derive(Subcommand)]
enum BenchCase {
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
        /// Timed runs of each; the fastest counts.
        #[arg(long, default_value_t = 3)]
        repeat: usize,
        /// Skip the straightforward reference loop.
        #[arg(long)]
        no_reference: bool,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
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

#[derive(Serialize)]
struct SimplifyReport {
    input: String,
    output: Option<String>,
    input_points: usize,
    normals: &'static str,
    k: usize,
    density: f32,
    sim_points: usize,
    duplicates_removed: usize,
    stop: &'static str,
    stretch_springs: usize,
    bend_springs: usize,
    boundary_points: usize,
    boundary_loops: usize,
    components: usize,
    total_mass: f32,
    area: f32,
    min_diameter: Option<f32>,
    max_diameter: Option<f32>,
    fallback_springs: usize,
    simplify_seconds: f64,
    network_seconds: f64,
    seconds: f64,
}

#[derive(Serialize)]
struct Info {
    file: String,
    format: String,
    points: usize,
    has_normals: bool,
    normals_usable: bool,
    bbox_min: [f32; 3],
    bbox_max: [f32; 3],
    bbox_diagonal: f32,
    mean_spacing: Option<f32>,
    min_spacing: Option<f32>,
    max_spacing: Option<f32>,
}

#[derive(Serialize)]
struct NormalsReport {
    input: String,
    output: String,
    points: usize,
    normals: &'static str,
    components: Option<usize>,
    flipped: Option<usize>,
    degenerate: Option<usize>,
    seconds: f64,
}

/// A failure and the exit code it maps to.
struct Failure {
    message: String,
    code: u8,
}

impl Failure {
    fn bad_input(e: impl std::fmt::Display) -> Self {
        Self {
            message: e.to_string(),
            code: EXIT_BAD_INPUT,
        }
    }

    fn other(e: impl std::fmt::Display) -> Self {
        Self {
            message: e.to_string(),
            code: EXIT_FAILURE,
        }
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            eprintln!("point-springs: {}", f.message);
            ExitCode::from(f.code)
        }
    }
}

fn format_of(file: &std::path::Path, format: Option<CloudFormat>) -> String {
    format
        .or_else(|| CloudFormat::from_path(file))
        .map_or_else(|| "unknown".into(), |f| f.to_string())
}

fn load(file: &std::path::Path, format: Option<CloudFormat>) -> Result<PointCloud, Failure> {
    read_cloud(file, format).map_err(Failure::bad_input)
}

fn run(command: Command) -> Result<(), Failure> {
    match command {
        Command::Bench { case } => bench(case),
        Command::Info { file, format, json } => {
            let cloud = load(&file, format)?;
            let bounds = cloud
                .bounds()
                .ok_or_else(|| Failure::bad_input("empty cloud"))?;
            let spacing = cloud.spacing(&KnnIndex::build(cloud.positions()));
            let info = Info {
                file: file.display().to_string(),
                format: format_of(&file, format),
                points: cloud.len(),
                has_normals: cloud.normals().is_some(),
                normals_usable: cloud.has_usable_normals(),
                bbox_min: bounds.min.to_array(),
                bbox_max: bounds.max.to_array(),
                bbox_diagonal: bounds.diagonal(),
                mean_spacing: spacing.map(|s| s.mean),
                min_spacing: spacing.map(|s| s.min),
                max_spacing: spacing.map(|s| s.max),
            };
            if json {
                print_json(&info)
            } else {
                println!("file          {}", info.file);
                println!("format        {}", info.format);
                println!("points        {}", info.points);
                let normals = match (info.has_normals, info.normals_usable) {
                    (false, _) => "none (estimate with `point-springs normals`)",
                    (true, false) => "present but some are zero (will be estimated)",
                    (true, true) => "yes",
                };
                println!("normals       {normals}");
                println!("bbox min      {:?}", info.bbox_min);
                println!("bbox max      {:?}", info.bbox_max);
                println!("bbox diagonal {}", info.bbox_diagonal);
                if let Some(s) = spacing {
                    println!(
                        "spacing       mean {} (min {}, max {})",
                        s.mean, s.min, s.max
                    );
                }
                Ok(())
            }
        }
        Command::Normals {
            file,
            output,
            k,
            format,
            reestimate,
            ascii,
            json,
        } => {
            let start = Instant::now();
            let mut cloud = load(&file, format)?;
            if reestimate {
                let (positions, _) = cloud.into_parts();
                cloud = PointCloud::new(positions, None).map_err(Failure::bad_input)?;
            }
            let source = ensure_normals(&mut cloud, k).map_err(Failure::bad_input)?;
            let encoding = if ascii {
                PlyEncoding::Ascii
            } else {
                PlyEncoding::BinaryLittleEndian
            };
            write_ply(&output, &cloud, encoding).map_err(Failure::other)?;
            let report = match source {
                NormalSource::File => None,
                NormalSource::Estimated(r) => Some(r),
            };
            let out = NormalsReport {
                input: file.display().to_string(),
                output: output.display().to_string(),
                points: cloud.len(),
                normals: if report.is_some() {
                    "estimated"
                } else {
                    "file"
                },
                components: report.map(|r| r.components),
                flipped: report.map(|r| r.flipped),
                degenerate: report.map(|r| r.degenerate),
                seconds: start.elapsed().as_secs_f64(),
            };
            if json {
                print_json(&out)
            } else {
                match report {
                    Some(r) => println!(
                        "{}: {} points, normals estimated (k = {k}): {} component(s), {} flipped, {} degenerate, {:.3} s → {}",
                        out.input,
                        out.points,
                        r.components,
                        r.flipped,
                        r.degenerate,
                        out.seconds,
                        out.output
                    ),
                    None => println!(
                        "{}: {} points, the file's own normals kept → {}",
                        out.input, out.points, out.output
                    ),
                }
                Ok(())
            }
        }
        Command::Simplify {
            file,
            target,
            max_diameter,
            k,
            density,
            output,
            format,
            ascii,
            json,
        } => {
            let start = Instant::now();
            let mut cloud = load(&file, format)?;
            let source =
                ensure_normals(&mut cloud, DEFAULT_NORMAL_K).map_err(Failure::bad_input)?;
            let config = SimplifyConfig {
                k,
                target,
                max_diameter,
            };
            let network_config = NetworkConfig { k, density };
            // Check the network's settings before the long part.
            if !(density > 0.0 && density.is_finite()) {
                return Err(Failure::bad_input(format!(
                    "the density must be a positive finite number, got {density}"
                )));
            }
            let simplify_start = Instant::now();
            let normals = cloud.normals().unwrap_or_default();
            let kept =
                simplify_with_progress(cloud.positions(), normals, &config, &mut show_progress)
                    .map_err(Failure::bad_input)?;
            if std::io::IsTerminal::is_terminal(&std::io::stderr()) {
                eprintln!();
            }
            let simplify_seconds = simplify_start.elapsed().as_secs_f64();
            let network_start = Instant::now();
            let (positions, normals) = kept.gather(cloud.positions(), normals);
            let network =
                build_network(&positions, &normals, &network_config).map_err(Failure::bad_input)?;
            let network_seconds = network_start.elapsed().as_secs_f64();
            if let Some(path) = &output {
                let sim = PointCloud::new(positions, Some(normals)).map_err(Failure::other)?;
                let encoding = if ascii {
                    PlyEncoding::Ascii
                } else {
                    PlyEncoding::BinaryLittleEndian
                };
                write_ply(path, &sim, encoding).map_err(Failure::other)?;
            }
            let r = network.report;
            let finite = |v: f32| v.is_finite().then_some(v);
            let report = SimplifyReport {
                input: file.display().to_string(),
                output: output.as_ref().map(|p| p.display().to_string()),
                input_points: cloud.len(),
                normals: match source {
                    NormalSource::File => "file",
                    NormalSource::Estimated(_) => "estimated",
                },
                k,
                density,
                sim_points: r.points,
                duplicates_removed: kept.duplicates_removed,
                stop: match kept.stop {
                    StopReason::TargetReached => "target",
                    StopReason::ThresholdReached => "max-diameter",
                    StopReason::NothingRemovable => "nothing-removable",
                },
                stretch_springs: r.stretch_springs,
                bend_springs: r.bend_springs,
                boundary_points: r.boundary_points,
                boundary_loops: r.boundary_loops,
                components: r.components,
                total_mass: r.total_mass,
                area: r.area,
                min_diameter: finite(r.min_diameter),
                max_diameter: finite(r.max_diameter),
                fallback_springs: r.fallback_springs,
                simplify_seconds,
                network_seconds,
                seconds: start.elapsed().as_secs_f64(),
            };
            if json {
                print_json(&report)
            } else {
                println!(
                    "input         {} ({} points, normals: {})",
                    report.input, report.input_points, report.normals
                );
                println!(
                    "simulation    {} points (stopped by {}; {} duplicates removed)",
                    report.sim_points, report.stop, report.duplicates_removed
                );
                println!(
                    "springs       {} stretch, {} bend",
                    report.stretch_springs, report.bend_springs
                );
                println!(
                    "boundary      {} points in {} loop(s); {} component(s)",
                    report.boundary_points, report.boundary_loops, report.components
                );
                println!(
                    "mass          {} (ρ = {density}, area {})",
                    report.total_mass, report.area
                );
                println!("region d      {} .. {}", r.min_diameter, r.max_diameter);
                println!(
                    "time          {:.3} s (simplify {:.3} s, network {:.3} s)",
                    report.seconds, simplify_seconds, network_seconds
                );
                if let Some(out) = &report.output {
                    println!("written       {out}");
                }
                Ok(())
            }
        }
    }
}

/// Times `steps` steps of `step`, `repeat` times from a fresh state; the fastest run's
/// microseconds per step.
fn time_steps<S>(
    repeat: usize,
    steps: usize,
    mut fresh: impl FnMut() -> S,
    mut step: impl FnMut(&mut S),
) -> (f64, S) {
    let mut best = f64::INFINITY;
    let mut last = fresh();
    for _ in 0..repeat.max(1) {
        let mut state = fresh();
        let start = Instant::now();
        for _ in 0..steps {
            step(&mut state);
        }
        best = best.min(start.elapsed().as_secs_f64() * 1e6 / steps.max(1) as f64);
        last = state;
    }
    (best, last)
}

fn bench(case: BenchCase) -> Result<(), Failure> {
    let BenchCase::ClothGrid {
        size,
        steps,
        integrator,
        repeat,
        no_reference,
        json,
    } = case;
    let grid = cloth_grid(size).map_err(Failure::bad_input)?;
    let solver = grid
        .solver_with(integrator, SubstepPolicy::Unchecked)
        .map_err(Failure::bad_input)?;
    let (us_per_step, solver) = time_steps(
        repeat,
        steps,
        || solver.clone(),
        |s| {
            // The step is valid by construction; a guard trip shows in `finite` and the
            // diagnostics.
            let _ = s.step(CLOTH_DT);
        },
    );
    let positions = solver.positions();
    let sag = max_sag(&grid.positions, &positions);
    let diagnostics = solver.diagnostics();
    let reference = (!no_reference).then(|| {
        time_steps(
            repeat,
            steps,
            || ReferenceCloth::new(&grid),
            |r| r.step(CLOTH_DT),
        )
    });
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

/// Prints simplification progress on one terminal line (only when stderr is a terminal).
fn show_progress(p: SimplifyProgress) {
    use std::io::{IsTerminal, Write};
    let mut err = std::io::stderr();
    if err.is_terminal() {
        let target = p.target.map_or_else(String::new, |t| format!(" → {t}"));
        let _ = write!(
            err,
            "\rsimplify: {} points{target}, last d = {:.4}   ",
            p.points, p.last_diameter
        );
        let _ = err.flush();
    }
}

fn print_json(value: &impl Serialize) -> Result<(), Failure> {
    let text = serde_json::to_string_pretty(value).map_err(Failure::other)?;
    println!("{text}");
    Ok(())
}
