//! `point-springs bench network`: is the spring network watertight? Each cloud simplified to
//! several fractions of its points, with the network's closedness, Euler characteristic,
//! boundary, checks and the time of each stage, as a Markdown table or JSON.

use std::path::PathBuf;
use std::time::Instant;

use bevy_point_springs::core::PointCloud;
use bevy_point_springs::core::cloud::io::CloudFormat;
use bevy_point_springs::core::cloud::knn::KnnIndex;
use bevy_point_springs::core::network::{DenseSupport, NetworkConfig, build_network_over};
use bevy_point_springs::core::normals::denoise::noise_level;
use bevy_point_springs::core::normals::{DEFAULT_NORMAL_K, ensure_normals};
use bevy_point_springs::core::simplify::{
    DEFAULT_SIMPLIFY_K, MIN_SIMULATION_POINTS, SimplifyConfig, simplify,
};
use serde::Serialize;

use crate::{DenoiseArg, Failure, load, print_json};

/// Arguments of `bench network`.
#[derive(clap::Args)]
pub struct NetworkArgs {
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

/// One cloud at one level.
#[derive(Serialize)]
struct Row {
    cloud: String,
    points: usize,
    level_percent: f64,
    sim_points: usize,
    /// Of `sim_points`, those the network added to fill holes (fans and refinement).
    added_points: usize,
    noise_level: f32,
    denoised: bool,
    closed: bool,
    euler_characteristic: i64,
    components: usize,
    boundary_loops: usize,
    boundary_points: usize,
    fold_overs: usize,
    crossings: usize,
    non_manifold_edges: usize,
    points_without_triangle: usize,
    closing_triangles: usize,
    /// Faces the file had (as triangles), used unless `--ignore-faces`.
    faces: usize,
    /// Whether the network is the fine mesh (the file's, or the dense points' network)
    /// collapsed onto the simulation points.
    collapsed: bool,
    total_mass: f32,
    noise_seconds: f64,
    simplify_seconds: f64,
    network_seconds: f64,
}

/// Runs `bench network`.
pub fn bench_network(args: &NetworkArgs) -> Result<(), Failure> {
    if let Some(l) = args.levels.iter().find(|l| !(**l > 0.0 && **l <= 100.0)) {
        return Err(Failure::bad_input(format!(
            "--levels are percentages in (0, 100], got {l}"
        )));
    }
    let mut rows = Vec::new();
    if !args.json {
        println!(
            "| cloud | points | level | sim | added | noise | closed | χ | comp. | loops | boundary pts | fold-overs | crossings | non-manifold | no triangle | closing tris | faces | collapsed | Σm | noise s | simplify s | network s |"
        );
        println!(
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
        );
    }
    for file in &args.files {
        let mut cloud = load(file, args.format)?;
        if args.ignore_faces {
            let (positions, normals) = cloud.into_parts();
            cloud = PointCloud::new(positions, normals).map_err(Failure::bad_input)?;
        }
        ensure_normals(&mut cloud, DEFAULT_NORMAL_K).map_err(Failure::bad_input)?;
        let (positions, normals) = (cloud.positions(), cloud.normals().unwrap_or_default());
        let faces = cloud.faces();
        let start = Instant::now();
        let measured = noise_level(positions, &KnnIndex::build(positions));
        let noise_seconds = start.elapsed().as_secs_f64();
        let name = file.file_name().map_or_else(
            || file.display().to_string(),
            |n| n.to_string_lossy().into(),
        );
        for &level in &args.levels {
            let target = ((positions.len() as f64 * level / 100.0).round() as usize)
                .max(MIN_SIMULATION_POINTS);
            let config = SimplifyConfig {
                k: args.k,
                denoise: args.denoise.into(),
                ..SimplifyConfig::target(target)
            };
            let start = Instant::now();
            let kept = match simplify(positions, normals, &config) {
                Ok(kept) => kept,
                Err(e) => {
                    if !args.json {
                        println!("| {name} | {} | {level}% | {e} |", positions.len());
                    }
                    continue;
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
            let row = Row {
                cloud: name.clone(),
                points: positions.len(),
                level_percent: level,
                sim_points: r.points,
                added_points: r.filling_points,
                noise_level: measured,
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
                noise_seconds,
                simplify_seconds,
                network_seconds,
            };
            if !args.json {
                println!(
                    "| {} | {} | {}% | {} | {} | {:.2}{} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.4} | {:.2} | {:.2} | {:.3} |",
                    row.cloud,
                    row.points,
                    row.level_percent,
                    row.sim_points,
                    row.added_points,
                    row.noise_level,
                    if row.denoised { " (fits)" } else { "" },
                    if row.closed { "yes" } else { "no" },
                    row.euler_characteristic,
                    row.components,
                    row.boundary_loops,
                    row.boundary_points,
                    row.fold_overs,
                    row.crossings,
                    row.non_manifold_edges,
                    row.points_without_triangle,
                    row.closing_triangles,
                    row.faces,
                    if row.collapsed { "yes" } else { "no" },
                    row.total_mass,
                    row.noise_seconds,
                    row.simplify_seconds,
                    row.network_seconds
                );
            }
            rows.push(row);
        }
    }
    if args.json {
        print_json(&rows)?;
    }
    Ok(())
}
