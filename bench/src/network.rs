//! `point-springs-bench network`: is the spring network watertight? Each cloud simplified to
//! several fractions of its points, with the network's closedness, Euler characteristic,
//! boundary, checks and the time of each stage, as a Markdown table or JSON.

use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Instant;

use bevy_point_springs::core::PointCloud;
use bevy_point_springs::core::cloud::io::{CloudFormat, read_cloud};
use bevy_point_springs::core::cloud::knn::KnnIndex;
use bevy_point_springs::core::network::{DenseSupport, NetworkConfig, build_network_over};
use bevy_point_springs::core::normals::denoise::noise_level;
use bevy_point_springs::core::normals::{DEFAULT_NORMAL_K, ensure_normals};
use bevy_point_springs::core::simplify::{
    DEFAULT_SIMPLIFY_K, MIN_SIMULATION_POINTS, SimplifyConfig, simplify,
};
use serde::Serialize;

use crate::failure::Failure;
use crate::flags::DenoiseArg;
use crate::report::print_json;

/// Arguments of `point-springs-bench network`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The clouds (.ply .xyz .pwn .off .obj).
    #[arg(required = true)]
    files: Vec<PathBuf>,
    /// Fractions of each cloud's points to keep, in percent.
    #[arg(long, value_delimiter = ',', default_values_t = [1.0, 5.0, 20.0, 50.0])]
    levels: Vec<f64>,
    /// Neighbours per ring (the paper's k).
    #[arg(short, default_value_t = DEFAULT_SIMPLIFY_K)]
    k: usize,
    /// Decide on local plane fits: when the cloud measures noisy, always or never.
    #[arg(long, value_enum, default_value_t = DenoiseArg::Auto)]
    denoise: DenoiseArg,
    /// Read every file as this format instead of the one its extension names.
    #[arg(long)]
    format: Option<CloudFormat>,
    /// Leave out a mesh file's faces: treat its vertices as a bare point cloud (normals
    /// estimated by PCA unless the file has its own).
    #[arg(long)]
    ignore_faces: bool,
    /// Print JSON instead of a Markdown table.
    #[arg(long)]
    json: bool,
}

/// One cloud at one level: a line of the table (its [`Display`](fmt::Display)) or an
/// object of the JSON array.
#[derive(Debug, Serialize)]
struct Row {
    /// The cloud's file name.
    cloud: String,
    /// Its points.
    points: usize,
    /// The level: the percentage of its points kept.
    level_percent: f64,
    /// Simulation points.
    sim_points: usize,
    /// Of `sim_points`, those the network added to fill holes (fans and refinement).
    added_points: usize,
    /// The cloud's noise level, in spacings.
    noise_level: f32,
    /// Whether the decisions were made on local plane fits.
    denoised: bool,
    /// Whether the network is watertight.
    closed: bool,
    /// V − E + F.
    euler_characteristic: i64,
    /// Connected components.
    components: usize,
    /// Boundary loops.
    boundary_loops: usize,
    /// Boundary points.
    boundary_points: usize,
    /// Fold-overs (a check: always 0).
    fold_overs: usize,
    /// Crossing springs (a check: always 0).
    crossings: usize,
    /// Non-manifold edges (a check: always 0).
    non_manifold_edges: usize,
    /// Points without a triangle.
    points_without_triangle: usize,
    /// Triangles closing holes.
    closing_triangles: usize,
    /// Faces the file had (as triangles), used unless `--ignore-faces`.
    faces: usize,
    /// Whether the network is the fine mesh (the file's, or the dense points' network)
    /// collapsed onto the simulation points.
    collapsed: bool,
    /// Σm.
    total_mass: f32,
    /// Time of measuring the noise level (once per cloud), s.
    noise_seconds: f64,
    /// Time of the simplification, s.
    simplify_seconds: f64,
    /// Time of the network, s.
    network_seconds: f64,
}

impl fmt::Display for Row {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "| {} | {} | {}% | {} | {} | {:.2}{} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.4} | {:.2} | {:.2} | {:.3} |",
            self.cloud,
            self.points,
            self.level_percent,
            self.sim_points,
            self.added_points,
            self.noise_level,
            if self.denoised { " (fits)" } else { "" },
            if self.closed { "yes" } else { "no" },
            self.euler_characteristic,
            self.components,
            self.boundary_loops,
            self.boundary_points,
            self.fold_overs,
            self.crossings,
            self.non_manifold_edges,
            self.points_without_triangle,
            self.closing_triangles,
            self.faces,
            if self.collapsed { "yes" } else { "no" },
            self.total_mass,
            self.noise_seconds,
            self.simplify_seconds,
            self.network_seconds
        )
    }
}

/// The table's heading: its first two lines.
const HEADING: &str = "| cloud | points | level | sim | added | noise | closed | χ | comp. | loops | boundary pts | fold-overs | crossings | non-manifold | no triangle | closing tris | faces | collapsed | Σm | noise s | simplify s | network s |
|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|
";

/// One line of the table: a level measured, or one the simplification refused (a line of
/// the text only).
#[derive(Debug)]
enum Entry {
    /// The level's row.
    Row(Row),
    /// The level the simplification refused, and why.
    Refused {
        /// The cloud's file name.
        cloud: String,
        /// Its points.
        points: usize,
        /// The level, percent.
        level: f64,
        /// The simplification's error.
        error: String,
    },
}

impl fmt::Display for Entry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Row(row) => row.fmt(f),
            Self::Refused {
                cloud,
                points,
                level,
                error,
            } => writeln!(f, "| {cloud} | {points} | {level}% | {error} |"),
        }
    }
}

/// A cloud read, with normals, and its noise level measured.
struct Cloud {
    /// Its file name.
    name: String,
    /// The points, with normals, and faces unless `--ignore-faces`.
    cloud: PointCloud,
    /// Its noise level, in spacings.
    noise_level: f32,
    /// Time of measuring it, s.
    noise_seconds: f64,
}

/// Runs `point-springs-bench network`: the table's lines are printed as they are measured (a long run
/// shows its progress); the JSON array of the rows at the end.
pub fn run(args: &Args) -> Result<(), Failure> {
    if let Some(l) = args.levels.iter().find(|l| !(**l > 0.0 && **l <= 100.0)) {
        return Err(Failure::bad_input(format!(
            "--levels are percentages in (0, 100], got {l}"
        )));
    }
    let mut rows = Vec::new();
    if !args.json {
        print!("{HEADING}");
    }
    for file in &args.files {
        let cloud = read(args, file)?;
        for &level in &args.levels {
            let entry = measure(args, &cloud, level)?;
            if !args.json {
                print!("{entry}");
            }
            if let Entry::Row(row) = entry {
                rows.push(row);
            }
        }
    }
    if args.json {
        print_json(&rows)?;
    }
    Ok(())
}

/// Reads `file`, gives it normals and measures its noise level.
fn read(args: &Args, file: &Path) -> Result<Cloud, Failure> {
    let mut cloud = read_cloud(file, args.format).map_err(Failure::bad_input)?;
    if args.ignore_faces {
        let (positions, normals) = cloud.into_parts();
        cloud = PointCloud::new(positions, normals).map_err(Failure::bad_input)?;
    }
    ensure_normals(&mut cloud, DEFAULT_NORMAL_K).map_err(Failure::bad_input)?;
    let positions = cloud.positions();
    let start = Instant::now();
    let noise_level = noise_level(positions, &KnnIndex::build(positions));
    let noise_seconds = start.elapsed().as_secs_f64();
    let name = file.file_name().map_or_else(
        || file.display().to_string(),
        |n| n.to_string_lossy().into(),
    );
    Ok(Cloud {
        name,
        cloud,
        noise_level,
        noise_seconds,
    })
}

/// Simplifies `c` to `level` percent of its points and builds the network: the table's
/// line.
fn measure(args: &Args, c: &Cloud, level: f64) -> Result<Entry, Failure> {
    let cloud = &c.cloud;
    let (positions, normals) = (cloud.positions(), cloud.normals().unwrap_or_default());
    let faces = cloud.faces();
    let target =
        ((positions.len() as f64 * level / 100.0).round() as usize).max(MIN_SIMULATION_POINTS);
    let config = SimplifyConfig {
        k: args.k,
        denoise: args.denoise.into(),
        ..SimplifyConfig::target(target)
    };
    let start = Instant::now();
    let kept = match simplify(positions, normals, &config) {
        Ok(kept) => kept,
        Err(e) => {
            return Ok(Entry::Refused {
                cloud: c.name.clone(),
                points: positions.len(),
                level,
                error: e.to_string(),
            });
        }
    };
    let simplify_seconds = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let (p, n) = kept.gather(positions, normals);
    let dense = DenseSupport::new(
        positions,
        normals,
        kept.noise_level,
        kept.projected.is_some(),
    )
    .with_triangles(faces);
    let net = build_network_over(
        &p,
        &n,
        &NetworkConfig {
            k: args.k,
            ..NetworkConfig::default()
        },
        Some(&dense),
    )
    .map_err(Failure::bad_input)?;
    let network_seconds = start.elapsed().as_secs_f64();
    let r = net.report;
    Ok(Entry::Row(Row {
        cloud: c.name.clone(),
        points: positions.len(),
        level_percent: level,
        sim_points: r.points,
        added_points: r.filling_points,
        noise_level: c.noise_level,
        denoised: kept.projected.is_some(),
        closed: r.closed,
        euler_characteristic: r.euler_characteristic,
        components: r.components,
        boundary_loops: r.boundary_loops,
        boundary_points: r.boundary_points,
        fold_overs: r.fold_overs,
        crossings: r.crossings,
        non_manifold_edges: r.non_manifold_edges,
        points_without_triangle: r.isolated_points,
        closing_triangles: r.closing_triangles,
        faces: faces.len(),
        collapsed: r.collapsed_from_dense,
        total_mass: r.total_mass,
        noise_seconds: c.noise_seconds,
        simplify_seconds,
        network_seconds,
    }))
}
