//! `point-springs`: the headless command-line tool.
//!
//! ```text
//! point-springs info FILE [--format F] [--json]
//! point-springs normals FILE -o OUT.ply [-k K] [--format F] [--ascii] [--reestimate] [--json]
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
use bevy_point_springs::core::normals::{DEFAULT_NORMAL_K, NormalSource, ensure_normals};
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
    about = "Point-sampled surfaces: inspect, prepare and (soon) simulate them"
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
    }
}

fn print_json(value: &impl Serialize) -> Result<(), Failure> {
    let text = serde_json::to_string_pretty(value).map_err(Failure::other)?;
    println!("{text}");
    Ok(())
}
