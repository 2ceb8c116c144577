//! `point-springs`: the headless command-line tool.
//!
//! ```text
//! point-springs info FILE [--format F] [--json]
//! point-springs normals FILE -o OUT.ply [-k K] [--format F] [--ascii] [--reestimate] [--json]
//! point-springs simplify FILE (--target N | --max-diameter D) [-k K] [--density RHO]
//!                        [-o OUT.ply] [--format F] [--ascii] [--json]
//! point-springs bench cloth-grid [--size N] [--steps S] [--integrator I] [--repeat R]
//!                        [--no-reference] [--json]
//! point-springs bench transfer [--points N] [--sim M] [--sim-source sphere|simplify] [-k K]
//!                        [--bandwidth H] [--repeat R] [--no-literal] [--json]
//! point-springs bench plugin [SCENE.ron] [--dense N] [--sim M] [--ticks T] [--block B] [--json]
//! point-springs run SCENE.ron [-o DEFORMED.ply] [--png PICTURE.png] [--view X,Y,Z] [--json]
//! point-springs render FILE -o PICTURE.png [--view X,Y,Z] [--up X,Y,Z] [--width W] [--height H]
//! point-springs generate (sphere|hat|sheet|letter-b) -o OUT.ply [--points N] [--radius R]
//!                        [--rim Y] [--size S] [--spacing H] [--ascii]
//! ```
//!
//! Exit codes: 0 success, 2 bad input (unreadable or malformed file, bad arguments),
//! 1 any other failure (e.g. the output cannot be written).

mod bench;
mod bench_network;
#[cfg(feature = "plugin")]
mod bench_plugin;
mod render;

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use bevy_point_springs::core::PointCloud;
use bevy_point_springs::core::cloud::io::{CloudFormat, PlyEncoding, read_cloud, write_ply};
use bevy_point_springs::core::cloud::knn::KnnIndex;
use bevy_point_springs::core::cloud::shapes::{self, HAT_DEFAULT_RIM, PAPER_SPHERE_POINTS};
use bevy_point_springs::core::network::{
    DEFAULT_DENSITY, DenseSupport, NetworkConfig, build_network_over,
};
use bevy_point_springs::core::normals::denoise::Denoise;
use bevy_point_springs::core::normals::{DEFAULT_NORMAL_K, NormalSource, ensure_normals};
use bevy_point_springs::core::scene::Scene;
use bevy_point_springs::core::simplify::{
    DEFAULT_SIMPLIFY_K, SimplifyConfig, SimplifyProgress, StopReason, simplify_with_progress,
};
use clap::{Parser, Subcommand, ValueEnum};
use glam::Vec3;
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
        /// Decide on the points projected on local plane fits: when the cloud measures noisy
        /// (auto), always (on) or never (off, the paper's method as written).
        #[arg(long, value_enum, default_value_t = DenoiseArg::Auto)]
        denoise: DenoiseArg,
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
    /// Time core stages against straightforward or literal implementations.
    Bench {
        #[command(subcommand)]
        case: bench::BenchCase,
    },
    /// Run a scene file headless: load, simplify, simulate, transfer the motion back to
    /// every dense point; write the deformed surface (positions and normals).
    Run {
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
        /// Write ASCII PLY instead of binary little-endian.
        #[arg(long)]
        ascii: bool,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Draw clouds as lit discs to a PNG (orthographic, no GPU needed); several clouds are
    /// drawn side by side at one scale.
    Render {
        /// The clouds (.ply .xyz .pwn .off .obj); normals are estimated where missing.
        #[arg(required = true)]
        files: Vec<PathBuf>,
        /// The PNG to write.
        #[arg(short, long)]
        output: PathBuf,
        /// Direction from the cloud towards the eye.
        #[arg(long, value_parser = parse_vec3, default_value = "1,0.8,1.6")]
        view: Vec3,
        /// Up on the picture.
        #[arg(long, value_parser = parse_vec3, default_value = "0,1,0")]
        up: Vec3,
        /// Picture width, pixels.
        #[arg(long, default_value_t = 900)]
        width: u32,
        /// Picture height, pixels.
        #[arg(long, default_value_t = 700)]
        height: u32,
        /// Read as this format instead of the one the extension names.
        #[arg(long)]
        format: Option<CloudFormat>,
    },
    /// Write a procedural surface with exact normals as PLY.
    Generate {
        /// Which surface.
        shape: ShapeKind,
        /// The PLY file to write.
        #[arg(short, long)]
        output: PathBuf,
        /// Points (sphere and hat).
        #[arg(long, default_value_t = PAPER_SPHERE_POINTS)]
        points: usize,
        /// Radius (sphere and hat).
        #[arg(long, default_value_t = 1.0)]
        radius: f32,
        /// Height of the hat's rim as a fraction of the radius.
        #[arg(long, default_value_t = HAT_DEFAULT_RIM)]
        rim: f32,
        /// Side of the sheet, height of the letter.
        #[arg(long, default_value_t = 2.0)]
        size: f32,
        /// Point spacing (sheet and letter).
        #[arg(long, default_value_t = 0.04)]
        spacing: f32,
        /// Sphere only: let the density fall smoothly from pole to pole by this ratio (10 for
        /// 10:1), like a scan seen from one side.
        #[arg(long)]
        uneven: Option<f32>,
        /// Add Gaussian noise with this standard deviation, in mean point spacings (a real
        /// scan: 0.1 to 1.5); normals stay those of the noiseless surface.
        #[arg(long)]
        noise: Option<f32>,
        /// Seed for --uneven and --noise.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Write ASCII PLY instead of binary little-endian.
        #[arg(long)]
        ascii: bool,
    },
}

/// `--denoise` values.
#[derive(Debug, Clone, Copy, ValueEnum)]
enum DenoiseArg {
    /// When the cloud measures noisy.
    Auto,
    /// Always.
    On,
    /// Never.
    Off,
}

impl From<DenoiseArg> for Denoise {
    fn from(d: DenoiseArg) -> Self {
        match d {
            DenoiseArg::Auto => Denoise::Auto,
            DenoiseArg::On => Denoise::On,
            DenoiseArg::Off => Denoise::Off,
        }
    }
}

/// Procedural surfaces `generate` writes.
#[derive(Debug, Clone, Copy, ValueEnum)]
enum ShapeKind {
    /// A Fibonacci sphere.
    Sphere,
    /// The lower part of a sphere (open).
    Hat,
    /// A flat square sheet.
    Sheet,
    /// A flat sheet shaped like the letter B.
    LetterB,
}

/// Most points `generate` writes.
const MAX_GENERATED_POINTS: usize = 50_000_000;

/// Parses "x,y,z".
fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let parts: Vec<f32> = s
        .split(',')
        .map(|p| p.trim().parse::<f32>().map_err(|e| format!("{p:?}: {e}")))
        .collect::<Result<_, _>>()?;
    match parts[..] {
        [x, y, z] if x.is_finite() && y.is_finite() && z.is_finite() => Ok(Vec3::new(x, y, z)),
        _ => Err(format!("expected three finite numbers x,y,z, got {s:?}")),
    }
}

#[derive(Serialize)]
struct RunReport {
    scene: String,
    output: Option<String>,
    png: Option<String>,
    dense_points: usize,
    dense_points_at_rest: usize,
    sim_points: usize,
    springs: usize,
    stretch_springs: usize,
    bend_springs: usize,
    pinned_points: usize,
    pulled_points: Vec<usize>,
    steps: usize,
    dt: f32,
    integrator: String,
    substeps: u64,
    cg_iterations: u64,
    guard_trips: u64,
    limited_steps: u64,
    ms_prepare: f64,
    ms_per_step: f64,
    ms_transfer: f64,
    ms_resample: f64,
    max_displacement: f32,
    energy_final: f64,
    finite: bool,
    resampled_points: usize,
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
    noise_level: f32,
    denoised: bool,
    duplicates_removed: usize,
    stop: &'static str,
    stretch_springs: usize,
    bend_springs: usize,
    triangles: usize,
    boundary_points: usize,
    boundary_loops: usize,
    closed: bool,
    euler_characteristic: i64,
    components: usize,
    non_manifold_edges: usize,
    non_manifold_points: usize,
    fold_overs: usize,
    crossings: usize,
    closing_triangles: usize,
    filling_points: usize,
    isolated_points: usize,
    /// Faces the file had (as triangles).
    faces: usize,
    /// Whether the network is a fine mesh (the file's faces, or the dense points' own network)
    /// collapsed onto the simulation points.
    collapsed_from_dense: bool,
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
        Command::Bench { case } => bench::bench(case),
        Command::Run {
            scene,
            output,
            png,
            view,
            up,
            ascii,
            json,
        } => run_scene(&scene, output, png, view, up, ascii, json),
        Command::Render {
            files,
            output,
            view,
            up,
            width,
            height,
            format,
        } => {
            let view = check_view(view, up, (width, height))?;
            let mut clouds = Vec::with_capacity(files.len());
            for file in &files {
                let mut cloud = load(file, format)?;
                ensure_normals(&mut cloud, DEFAULT_NORMAL_K).map_err(Failure::bad_input)?;
                clouds.push(cloud);
            }
            let refs: Vec<&PointCloud> = clouds.iter().collect();
            let drawn = render::render(&refs, &view, &output).map_err(Failure::other)?;
            println!(
                "{} points in {} panel(s), discs of {:.1} px or more → {}",
                drawn.points,
                refs.len(),
                drawn.disc_px,
                output.display()
            );
            Ok(())
        }
        Command::Generate {
            shape,
            output,
            points,
            radius,
            rim,
            size,
            spacing,
            uneven,
            noise,
            seed,
            ascii,
        } => {
            let mut cloud = generate(shape, points, radius, rim, size, spacing, uneven, seed)?;
            if let Some(sigma) = noise {
                if !(sigma >= 0.0 && sigma.is_finite()) {
                    return Err(Failure::bad_input(format!(
                        "--noise must be a finite number of spacings, 0 or more, got {sigma}"
                    )));
                }
                let spacing = cloud
                    .spacing(&KnnIndex::build(cloud.positions()))
                    .map_or(0.0, |s| s.mean);
                cloud = shapes::with_noise(&cloud, sigma * spacing, seed);
            }
            write_ply(&output, &cloud, encoding(ascii)).map_err(Failure::other)?;
            println!("{} points → {}", cloud.len(), output.display());
            Ok(())
        }
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
                NormalSource::File | NormalSource::Faces => None,
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
            denoise,
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
                denoise: denoise.into(),
            };
            let network_config = NetworkConfig { k, density };
            // Check the network's settings before the long part.
            if !(density > 0.0 && density.is_finite()) {
                return Err(Failure::bad_input(format!(
                    "the density must be a positive finite number, got {density}"
                )));
            }
            let simplify_start = Instant::now();
            let dense_normals = cloud.normals().unwrap_or_default();
            let kept = simplify_with_progress(
                cloud.positions(),
                dense_normals,
                &config,
                &mut show_progress,
            )
            .map_err(Failure::bad_input)?;
            if std::io::IsTerminal::is_terminal(&std::io::stderr()) {
                eprintln!();
            }
            let simplify_seconds = simplify_start.elapsed().as_secs_f64();
            let network_start = Instant::now();
            let (positions, normals) = kept.gather(cloud.positions(), dense_normals);
            let dense = DenseSupport::new(
                cloud.positions(),
                dense_normals,
                kept.noise_level,
                kept.projected.is_some(),
            )
            .with_triangles(cloud.faces());
            let network = build_network_over(&positions, &normals, &network_config, Some(&dense))
                .map_err(Failure::bad_input)?;
            let network_seconds = network_start.elapsed().as_secs_f64();
            if let Some(path) = &output {
                // The network's points: the kept ones and any that fill holes.
                let sim = PointCloud::new(network.positions.clone(), Some(network.normals.clone()))
                    .map_err(Failure::other)?;
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
                    NormalSource::Faces => "faces",
                    NormalSource::Estimated(_) => "estimated",
                },
                k,
                density,
                sim_points: r.points,
                noise_level: kept.noise_level,
                denoised: kept.projected.is_some(),
                duplicates_removed: kept.duplicates_removed,
                stop: match kept.stop {
                    StopReason::TargetReached => "target",
                    StopReason::ThresholdReached => "max-diameter",
                    StopReason::NothingRemovable => "nothing-removable",
                    StopReason::Cancelled => "cancelled",
                },
                stretch_springs: r.stretch_springs,
                bend_springs: r.bend_springs,
                triangles: r.triangles,
                boundary_points: r.boundary_points,
                boundary_loops: r.boundary_loops,
                closed: r.closed,
                euler_characteristic: r.euler_characteristic,
                components: r.components,
                non_manifold_edges: r.non_manifold_edges,
                non_manifold_points: r.non_manifold_points,
                fold_overs: r.fold_overs,
                crossings: r.crossings,
                closing_triangles: r.closing_triangles,
                filling_points: r.filling_points,
                isolated_points: r.isolated_points,
                faces: cloud.faces().len(),
                collapsed_from_dense: r.collapsed_from_dense,
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
                    "noise         {:.3} spacings{}",
                    report.noise_level,
                    if report.denoised {
                        "; decided on local plane fits"
                    } else {
                        ""
                    }
                );
                println!(
                    "springs       {} stretch, {} bend",
                    report.stretch_springs, report.bend_springs
                );
                println!(
                    "surface       {}, Euler characteristic {}, {} triangles ({} closing holes, with {} points added from the dense cloud), {} component(s)",
                    if report.closed { "closed" } else { "open" },
                    report.euler_characteristic,
                    report.triangles,
                    report.closing_triangles,
                    report.filling_points,
                    report.components
                );
                if report.collapsed_from_dense {
                    println!(
                        "built from    {} collapsed onto the simulation points (their rings left holes)",
                        if report.faces > 0 {
                            "the file's faces"
                        } else {
                            "the dense points' own network"
                        }
                    );
                }
                println!(
                    "boundary      {} points in {} loop(s)",
                    report.boundary_points, report.boundary_loops
                );
                println!(
                    "checks        {} fold-overs, {} crossing springs, {} non-manifold edges, {} pinched points, {} points without a triangle",
                    report.fold_overs,
                    report.crossings,
                    report.non_manifold_edges,
                    report.non_manifold_points,
                    report.isolated_points
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

fn encoding(ascii: bool) -> PlyEncoding {
    if ascii {
        PlyEncoding::Ascii
    } else {
        PlyEncoding::BinaryLittleEndian
    }
}

/// Size of `run --png` pictures (two panels), pixels.
const PICTURE_WIDTH: u32 = 1400;
const PICTURE_HEIGHT: u32 = 700;

/// Largest picture side, pixels.
const MAX_PICTURE_SIDE: u32 = 8192;

fn check_view(from: Vec3, up: Vec3, size: (u32, u32)) -> Result<render::View, Failure> {
    if !(1..=MAX_PICTURE_SIDE).contains(&size.0) || !(1..=MAX_PICTURE_SIDE).contains(&size.1) {
        return Err(Failure::bad_input(format!(
            "the picture must be between 1 and {MAX_PICTURE_SIDE} pixels on each side"
        )));
    }
    if from.length_squared() == 0.0 || up.cross(from).length_squared() == 0.0 {
        return Err(Failure::bad_input(
            "the view direction must be non-zero and not parallel to up",
        ));
    }
    Ok(render::View { from, up, size })
}

#[allow(clippy::too_many_arguments)]
fn generate(
    shape: ShapeKind,
    points: usize,
    radius: f32,
    rim: f32,
    size: f32,
    spacing: f32,
    uneven: Option<f32>,
    seed: u64,
) -> Result<PointCloud, Failure> {
    let positive = |name: &str, v: f32| {
        if v > 0.0 && v.is_finite() {
            Ok(())
        } else {
            Err(Failure::bad_input(format!(
                "--{name} must be a positive finite number, got {v}"
            )))
        }
    };
    let count = match shape {
        ShapeKind::Sphere | ShapeKind::Hat => {
            positive("radius", radius)?;
            if !(-1.0..=1.0).contains(&rim) {
                return Err(Failure::bad_input("--rim must be between -1 and 1"));
            }
            points as f64
        }
        ShapeKind::Sheet | ShapeKind::LetterB => {
            positive("size", size)?;
            positive("spacing", spacing)?;
            // A triangular lattice holds about 1.155 points per spacing².
            1.155 * f64::from(size / spacing).powi(2)
        }
    };
    if !(4.0..=MAX_GENERATED_POINTS as f64).contains(&count) {
        return Err(Failure::bad_input(format!(
            "that would be about {count:.0} points; generate writes 4 to {MAX_GENERATED_POINTS}"
        )));
    }
    if let Some(ratio) = uneven {
        if !matches!(shape, ShapeKind::Sphere) {
            return Err(Failure::bad_input("--uneven is for the sphere"));
        }
        if !(ratio >= 1.0 && ratio.is_finite()) {
            return Err(Failure::bad_input(format!(
                "--uneven must be a density ratio of 1 or more, got {ratio}"
            )));
        }
        return Ok(shapes::uneven_sphere(points, radius, ratio, seed));
    }
    Ok(match shape {
        ShapeKind::Sphere => shapes::fibonacci_sphere(points, radius),
        ShapeKind::Hat => shapes::hat(points, radius, rim),
        ShapeKind::Sheet => shapes::square_sheet(size, spacing),
        ShapeKind::LetterB => shapes::letter_b(size, spacing),
    })
}

fn run_scene(
    path: &Path,
    output: Option<PathBuf>,
    png: Option<PathBuf>,
    view: Vec3,
    up: Vec3,
    ascii: bool,
    json: bool,
) -> Result<(), Failure> {
    use std::io::{IsTerminal, Write};
    let view = png
        .as_ref()
        .map(|_| check_view(view, up, (PICTURE_WIDTH, PICTURE_HEIGHT)))
        .transpose()?;
    let (scene, base) = Scene::load(path).map_err(Failure::bad_input)?;
    let start = Instant::now();
    let mut run = scene.prepare(&base).map_err(Failure::bad_input)?;
    let prepare_seconds = start.elapsed().as_secs_f64();
    let tty = std::io::stderr().is_terminal();
    let total = scene.steps;
    let (mut simulate_seconds, mut resample_seconds) = (0.0, 0.0);
    while !run.finished() {
        let start = Instant::now();
        run.simulate().map_err(Failure::other)?;
        let middle = Instant::now();
        run.maintain().map_err(Failure::other)?;
        simulate_seconds += (middle - start).as_secs_f64();
        resample_seconds += middle.elapsed().as_secs_f64();
        let step = run.step_count();
        if tty && (step % 10 == 0 || step == total) {
            let _ = write!(std::io::stderr(), "\rrun: step {step} of {total}   ");
            let _ = std::io::stderr().flush();
        }
    }
    if tty {
        eprintln!();
    }
    let energy = run.solver().energy().total();
    let start = Instant::now();
    let deformed = run.deformed().map_err(Failure::other)?;
    let transfer_seconds = start.elapsed().as_secs_f64();
    if let Some(out) = &output {
        write_ply(out, &deformed.cloud, encoding(ascii)).map_err(Failure::other)?;
    }
    if let (Some(picture), Some(view)) = (&png, &view) {
        render::render(&[&run.rest, &deformed.cloud], view, picture).map_err(Failure::other)?;
    }
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
    let report = RunReport {
        scene: path.display().to_string(),
        output: output.as_ref().map(|p| p.display().to_string()),
        png: png.as_ref().map(|p| p.display().to_string()),
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
        ms_prepare: prepare_seconds * 1e3,
        ms_per_step: simulate_seconds * 1e3 / run.step_count().max(1) as f64,
        ms_transfer: transfer_seconds * 1e3,
        ms_resample: resample_seconds * 1e3,
        max_displacement: deformed.max_displacement,
        energy_final: energy,
        finite,
        resampled_points: run.resampled().inserted,
    };
    if json {
        return print_json(&report);
    }
    println!(
        "scene         {} ({} steps of {} s, {})",
        report.scene, report.steps, report.dt, report.integrator
    );
    println!(
        "surface       {} dense points at rest, {} simulation points, {} springs ({} pinned)",
        report.dense_points_at_rest, report.sim_points, report.springs, report.pinned_points
    );
    println!(
        "simulation    {:.3} ms per step ({} sub-steps, {} CG iterations, {} guard trips)",
        report.ms_per_step, report.substeps, report.cg_iterations, report.guard_trips
    );
    println!(
        "transfer      {:.2} ms (+ {:.2} ms resampling: {} points added)",
        report.ms_transfer, report.ms_resample, report.resampled_points
    );
    println!(
        "result        largest displacement {:.4}, energy {:.4e}, finite: {}",
        report.max_displacement, report.energy_final, report.finite
    );
    for out in report.output.iter().chain(&report.png) {
        println!("written       {out}");
    }
    Ok(())
}

/// Prints simplification progress on one terminal line (only when stderr is a terminal).
fn show_progress(p: SimplifyProgress) -> std::ops::ControlFlow<()> {
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
    std::ops::ControlFlow::Continue(())
}

fn print_json(value: &impl Serialize) -> Result<(), Failure> {
    let text = serde_json::to_string_pretty(value).map_err(Failure::other)?;
    println!("{text}");
    Ok(())
}
