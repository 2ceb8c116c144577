//! `point-springs simplify`: choose simulation points (§3) and build their spring network
//! (§4), reporting the network's counts, checks and masses.

use std::fmt;
use std::path::PathBuf;
use std::time::Instant;

use bevy_point_springs::core::PointCloud;
use bevy_point_springs::core::network::{
    DEFAULT_DENSITY, DenseSupport, NetworkConfig, NetworkReport, SpringNetwork, build_network_over,
    dense_areas_after,
};
use bevy_point_springs::core::normals::{DEFAULT_NORMAL_K, NormalSource, ensure_normals};
use bevy_point_springs::core::simplify::{
    DEFAULT_ROUNDS_ABOVE, DEFAULT_SIMPLIFY_K, Simplification, SimplifyConfig, SimplifyProgress,
    StopReason, simplify_with_progress,
};
use serde::Serialize;

use crate::args::{CloudInput, PlyFlag};
use crate::failure::Failure;
use crate::flags::{DenoiseArg, JsonFlag};
use crate::report::Report;

/// Arguments of `simplify`.
#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("stop").required(true).multiple(true).args(["target", "max_diameter"])))]
pub struct Args {
    /// Stop when this many simulation points remain.
    #[arg(long)]
    target: Option<usize>,
    /// Stop when every region R is at least this wide (the paper's threshold on d).
    #[arg(long)]
    max_diameter: Option<f32>,
    /// While more points than this are left, remove them in parallel rounds (the smallest
    /// regions that do not touch one another together); below, one at a time, as the paper
    /// does.
    #[arg(long, default_value_t = DEFAULT_ROUNDS_ABOVE)]
    rounds_above: usize,
    /// Neighbours per point for the local Delaunay rings (the paper's k, 10–20).
    #[arg(short, default_value_t = DEFAULT_SIMPLIFY_K)]
    k: usize,
    /// Surface density ρ (mass per unit area): each simulation point's mass is ρ times its
    /// share of the dense surface's area, as the simulation prepares it.
    #[arg(long, default_value_t = DEFAULT_DENSITY)]
    density: f32,
    /// Decide on the points projected on local plane fits: when the cloud measures noisy
    /// (auto), always (on) or never (off, the paper's method as written).
    #[arg(long, value_enum, default_value_t = DenoiseArg::Auto)]
    denoise: DenoiseArg,
    /// Write the simulation points with their normals to this PLY file.
    #[arg(short, long)]
    output: Option<PathBuf>,
    // The cloud and --format (listed here so that --format shows after --output).
    #[command(flatten)]
    input: CloudInput,
    #[command(flatten)]
    ply: PlyFlag,
    #[command(flatten)]
    json: JsonFlag,
}

/// What `simplify` reports: the input, the simplification, and the network's counts and
/// checks (see [`NetworkReport`] for each).
#[derive(Debug, Serialize)]
struct SimplifyReport {
    /// The file read.
    input: String,
    /// The PLY file written, if any.
    output: Option<String>,
    /// Points of the file.
    input_points: usize,
    /// Where the dense normals came from: "file", "faces" or "estimated".
    normals: &'static str,
    /// Neighbours per ring.
    k: usize,
    /// Surface density ρ.
    density: f32,
    /// Simulation points (with any the network added to fill holes).
    sim_points: usize,
    /// The cloud's noise level, in spacings.
    noise_level: f32,
    /// Whether the decisions were made on points projected on local plane fits.
    denoised: bool,
    /// Points removed because they coincided with a neighbour.
    duplicates_removed: usize,
    /// What stopped the simplification.
    stop: &'static str,
    /// Stretch springs.
    stretch_springs: usize,
    /// Bend springs.
    bend_springs: usize,
    /// Triangles of the network's mesh.
    triangles: usize,
    /// Boundary points.
    boundary_points: usize,
    /// Boundary loops.
    boundary_loops: usize,
    /// Whether the network is a watertight surface.
    closed: bool,
    /// V − E + F.
    euler_characteristic: i64,
    /// Connected components.
    components: usize,
    /// Non-manifold edges (a check: always 0).
    non_manifold_edges: usize,
    /// Points where the surface pinches.
    non_manifold_points: usize,
    /// Fold-overs (a check: always 0).
    fold_overs: usize,
    /// Crossing springs (a check: always 0).
    crossings: usize,
    /// Triangles closing holes.
    closing_triangles: usize,
    /// Dense points added to fill holes.
    filling_points: usize,
    /// Points without a triangle.
    isolated_points: usize,
    /// Faces the file had (as triangles).
    faces: usize,
    /// Whether the network is a fine mesh (the file's faces, or the dense points' own network)
    /// collapsed onto the simulation points.
    collapsed_from_dense: bool,
    /// Σm: ρ times the dense surface's area.
    total_mass: f32,
    /// The dense surface's area, which the masses share out.
    dense_area: f32,
    /// Σ area(R)/3: the network's own mesh's area (eq 1's).
    area: f32,
    /// Smallest region diameter d, if finite.
    min_diameter: Option<f32>,
    /// Largest region diameter d, if finite.
    max_diameter: Option<f32>,
    /// Springs added to give stragglers enough.
    fallback_springs: usize,
    /// Time of the simplification, s.
    simplify_seconds: f64,
    /// Time of the network, s.
    network_seconds: f64,
    /// Time of the whole command, s.
    seconds: f64,
    /// The smallest and largest region diameters as measured, finite or not (text only).
    #[serde(skip)]
    diameters: (f32, f32),
}

impl fmt::Display for SimplifyReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "input         {} ({} points, normals: {})",
            self.input, self.input_points, self.normals
        )?;
        writeln!(
            f,
            "simulation    {} points (stopped by {}; {} duplicates removed)",
            self.sim_points, self.stop, self.duplicates_removed
        )?;
        writeln!(
            f,
            "noise         {:.3} spacings{}",
            self.noise_level,
            if self.denoised {
                "; decided on local plane fits"
            } else {
                ""
            }
        )?;
        writeln!(
            f,
            "springs       {} stretch, {} bend",
            self.stretch_springs, self.bend_springs
        )?;
        writeln!(
            f,
            "surface       {}, Euler characteristic {}, {} triangles ({} closing holes, with {} points added from the dense cloud), {} component(s)",
            if self.closed { "closed" } else { "open" },
            self.euler_characteristic,
            self.triangles,
            self.closing_triangles,
            self.filling_points,
            self.components
        )?;
        if self.collapsed_from_dense {
            writeln!(
                f,
                "built from    {} collapsed onto the simulation points (their rings left holes)",
                if self.faces > 0 {
                    "the file's faces"
                } else {
                    "the dense points' own network"
                }
            )?;
        }
        writeln!(
            f,
            "boundary      {} points in {} loop(s)",
            self.boundary_points, self.boundary_loops
        )?;
        writeln!(
            f,
            "checks        {} fold-overs, {} crossing springs, {} non-manifold edges, {} pinched points, {} points without a triangle",
            self.fold_overs,
            self.crossings,
            self.non_manifold_edges,
            self.non_manifold_points,
            self.isolated_points
        )?;
        writeln!(
            f,
            "mass          {} (ρ = {} on the dense surface's area {}; the network's mesh: {})",
            self.total_mass, self.density, self.dense_area, self.area
        )?;
        writeln!(
            f,
            "region d      {} .. {}",
            self.diameters.0, self.diameters.1
        )?;
        writeln!(
            f,
            "time          {:.3} s (simplify {:.3} s, network {:.3} s)",
            self.seconds, self.simplify_seconds, self.network_seconds
        )?;
        if let Some(out) = &self.output {
            writeln!(f, "written       {out}")?;
        }
        Ok(())
    }
}

impl Report for SimplifyReport {}

/// Runs `simplify`.
pub fn run(args: &Args) -> Result<(), Failure> {
    let start = Instant::now();
    let mut cloud = args.input.load()?;
    let source = ensure_normals(&mut cloud, DEFAULT_NORMAL_K).map_err(Failure::bad_input)?;
    let config = SimplifyConfig {
        k: args.k,
        target: args.target,
        max_diameter: args.max_diameter,
        denoise: args.denoise.into(),
        rounds_above: args.rounds_above,
    };
    let network_config = NetworkConfig {
        k: args.k,
        density: args.density,
    };
    // Check the network's settings before the long part.
    if !(args.density > 0.0 && args.density.is_finite()) {
        return Err(Failure::bad_input(format!(
            "the density must be a positive finite number, got {}",
            args.density
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
    let network = network_of(&cloud, &kept, &network_config)?;
    let network_seconds = network_start.elapsed().as_secs_f64();
    if let Some(path) = &args.output {
        // The network's points: the kept ones and any that fill holes.
        let sim = PointCloud::new(network.positions.clone(), Some(network.normals.clone()))
            .map_err(Failure::other)?;
        args.ply.write(path, &sim)?;
    }
    let seconds = Seconds {
        simplify: simplify_seconds,
        network: network_seconds,
        total: start.elapsed().as_secs_f64(),
    };
    args.json.emit(&report(
        args,
        &cloud,
        source,
        &kept,
        &network.report,
        seconds,
    ))
}

/// The spring network over the points `kept` of `cloud` (which has normals).
fn network_of(
    cloud: &PointCloud,
    kept: &Simplification,
    config: &NetworkConfig,
) -> Result<SpringNetwork, Failure> {
    let dense_normals = cloud.normals().unwrap_or_default();
    let (positions, normals) = kept.gather(cloud.positions(), dense_normals);
    let dense = DenseSupport::new(
        cloud.positions(),
        dense_normals,
        kept.noise_level,
        kept.projected.is_some(),
    )
    .with_triangles(cloud.faces());
    let mut network = build_network_over(&positions, &normals, config, Some(&dense))
        .map_err(Failure::bad_input)?;
    // The masses as the simulation has them: shares of the dense surface's area.
    let areas = dense_areas_after(
        kept,
        cloud.positions(),
        dense_normals,
        cloud.faces(),
        config.k,
    )
    .map_err(Failure::bad_input)?;
    network
        .share_dense_area(cloud.positions(), dense_normals, &areas, config.density)
        .map_err(Failure::bad_input)?;
    Ok(network)
}

/// How long `simplify` took.
#[derive(Debug, Clone, Copy)]
struct Seconds {
    /// The simplification.
    simplify: f64,
    /// The network.
    network: f64,
    /// The whole command.
    total: f64,
}

/// The report of `simplify`.
fn report(
    args: &Args,
    cloud: &PointCloud,
    source: NormalSource,
    kept: &Simplification,
    r: &NetworkReport,
    seconds: Seconds,
) -> SimplifyReport {
    let finite = |v: f32| v.is_finite().then_some(v);
    SimplifyReport {
        input: args.input.file.display().to_string(),
        output: args.output.as_ref().map(|p| p.display().to_string()),
        input_points: cloud.len(),
        normals: match source {
            NormalSource::File => "file",
            NormalSource::FileReoriented(_) => "file, re-oriented",
            NormalSource::Faces => "faces",
            NormalSource::Estimated(_) => "estimated",
        },
        k: args.k,
        density: args.density,
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
        dense_area: r.dense_area,
        area: r.area,
        min_diameter: finite(r.min_diameter),
        max_diameter: finite(r.max_diameter),
        fallback_springs: r.fallback_springs,
        simplify_seconds: seconds.simplify,
        network_seconds: seconds.network,
        seconds: seconds.total,
        diameters: (r.min_diameter, r.max_diameter),
    }
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
