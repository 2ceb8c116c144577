//! `point-springs generate`: write a procedural surface with exact normals as PLY.

use std::fmt;
use std::path::PathBuf;

use bevy_point_springs::core::PointCloud;
use bevy_point_springs::core::cloud::knn::KnnIndex;
use bevy_point_springs::core::cloud::shapes::{self, HAT_DEFAULT_RIM, PAPER_SPHERE_POINTS};
use clap::ValueEnum;
use serde::Serialize;

use crate::args::PlyFlag;
use crate::failure::Failure;
use crate::report::{Report, emit};

/// Arguments of `generate`.
#[derive(Debug, clap::Args)]
pub struct Args {
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
    #[command(flatten)]
    ply: PlyFlag,
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

/// What `generate` reports (as text only: the command has no `--json`).
#[derive(Debug, Serialize)]
struct GenerateReport {
    /// Points written.
    points: usize,
    /// The PLY file written.
    output: String,
}

impl fmt::Display for GenerateReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "{} points → {}", self.points, self.output)
    }
}

impl Report for GenerateReport {}

/// Runs `generate`.
pub fn run(args: &Args) -> Result<(), Failure> {
    let mut cloud = generate(args)?;
    if let Some(sigma) = args.noise {
        if !(sigma >= 0.0 && sigma.is_finite()) {
            return Err(Failure::bad_input(format!(
                "--noise must be a finite number of spacings, 0 or more, got {sigma}"
            )));
        }
        let spacing = cloud
            .spacing(&KnnIndex::build(cloud.positions()))
            .map_or(0.0, |s| s.mean);
        cloud = shapes::with_noise(&cloud, sigma * spacing, args.seed);
    }
    args.ply.write(&args.output, &cloud)?;
    let report = GenerateReport {
        points: cloud.len(),
        output: args.output.display().to_string(),
    };
    emit(&report, false)
}

/// Checks a positive finite value of the option `--name`.
fn positive(name: &str, v: f32) -> Result<(), Failure> {
    if v > 0.0 && v.is_finite() {
        Ok(())
    } else {
        Err(Failure::bad_input(format!(
            "--{name} must be a positive finite number, got {v}"
        )))
    }
}

/// The noiseless surface `args` ask for; out-of-range options are bad input.
fn generate(args: &Args) -> Result<PointCloud, Failure> {
    let Args {
        shape,
        points,
        radius,
        rim,
        size,
        spacing,
        uneven,
        seed,
        ..
    } = *args;
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
