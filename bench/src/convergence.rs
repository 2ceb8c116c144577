//! `point-springs-bench convergence`: does a coarse network model the same surface as a fine
//! one? Four static problems, each prepared at several simplification levels (down from
//! every dense point as a simulation point), with the material per spring (the paper's), as a
//! sheet's moduli (see `MaterialUnits`), as a sheet bending on hinges (see
//! `BendingModel::Hinges`) and as a sheet bending on each point's fitted curvature (see
//! `BendingModel::Curvature`), run to equilibrium. Each load is defined on the dense surface, so
//! every level carries the same one; the sag (the load-weighted mean displacement of the dense
//! points it acts on) and the peak displacement, both measured on the dense surface after the
//! transfer, are compared with the same material's finest level, and the stretch springs'
//! energy at the end with a constant-strain membrane's on the same triangles (how far the
//! springs are from the membrane they stand for). A Markdown table or JSON,
//! the total mass against ρ times the dense area, and a chart (SVG and PNG) of the sag over
//! the level.

use std::fmt;
use std::ops::ControlFlow;
use std::path::PathBuf;

use bevy_point_springs::core::PointCloud;
use bevy_point_springs::core::cloud::shapes::{fibonacci_sphere, hat, square_sheet};
use bevy_point_springs::core::network::SpringNetwork;
use bevy_point_springs::core::pipeline::{PreparedSurface, SurfaceConfig, prepare_surface};
use bevy_point_springs::core::scene::level_target;
use bevy_point_springs::core::simplify::SimplifyConfig;
use bevy_point_springs::core::solver::membrane::{LATTICE_POISSON_RATIO, membrane_energy};
use bevy_point_springs::core::solver::{
    BendingModel, DEFAULT_BENDING_DAMPING, DEFAULT_YIELD_ANGLE, Integrator, MaterialUnits,
    PointState, SolverConfig, SpringMaterial, Springs,
};
use glam::Vec3;
use serde::Serialize;

use crate::chart::{Chart, Series};
use crate::failure::Failure;
use crate::flags::JsonFlag;
use crate::report::Report;

/// Step of the runs to equilibrium, s (implicit Euler: stable, and its numerical damping
/// helps the runs settle).
const DT: f32 = 1.0 / 30.0;

/// Surface density of every problem.
const DENSITY: f32 = 0.2;

/// Gravity's magnitude, m/s².
const GRAVITY: f32 = 9.81;

/// Viscous drag, 1/s.
const DRAG: f32 = 1.0;

/// The per-spring material (the `hat` scene's springs).
const PER_SPRING: SpringMaterial = SpringMaterial {
    density: DENSITY,
    units: MaterialUnits::PerSpring,
    stretch_stiffness: 60.0,
    bend_stiffness: 20.0,
    stretch_damping: 0.6,
    bend_damping: 0.2,
    bending: BendingModel::Springs,
    bending_modulus: HINGE_MODULUS,
    bending_damping: DEFAULT_BENDING_DAMPING,
    yield_strain: 0.1,
    yield_angle: DEFAULT_YIELD_ANGLE,
    creep_rate: 0.0,
};

/// The flexural rigidity of the hinged material, N·m.
const HINGE_MODULUS: f32 = 0.3;

/// The sheet material that equals [`PER_SPRING`] on a regular triangle lattice: stretch
/// modulus 2k/√3, bend modulus 2√3·k_b (bend springs span √3 spacings there).
fn sheet_material() -> SpringMaterial {
    SpringMaterial {
        units: MaterialUnits::Sheet,
        stretch_stiffness: 2.0 * PER_SPRING.stretch_stiffness / 3f32.sqrt(),
        bend_stiffness: 2.0 * 3f32.sqrt() * PER_SPRING.bend_stiffness,
        stretch_damping: 0.3,
        bend_damping: 0.3,
        ..PER_SPRING
    }
}

/// [`sheet_material`]'s stretch springs, bending on hinges of [`HINGE_MODULUS`] instead of bend
/// springs.
fn hinge_material() -> SpringMaterial {
    SpringMaterial {
        bending: BendingModel::Hinges,
        ..sheet_material()
    }
}

/// [`hinge_material`] bending on each point's fitted curvature instead of hinges.
fn curvature_material() -> SpringMaterial {
    SpringMaterial {
        bending: BendingModel::Curvature,
        ..hinge_material()
    }
}

/// The materials compared.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
#[value(rename_all = "snake_case")]
pub enum Material {
    /// The paper's: stiffness per spring, bend springs.
    PerSpring,
    /// A sheet's moduli, bend springs.
    Sheet,
    /// A sheet's stretch modulus, hinges of a flexural rigidity.
    Hinges,
    /// A sheet's stretch modulus, each point's curvature bearing a flexural rigidity.
    Curvature,
}

impl Material {
    fn material(self) -> SpringMaterial {
        match self {
            Self::PerSpring => PER_SPRING,
            Self::Sheet => sheet_material(),
            Self::Hinges => hinge_material(),
            Self::Curvature => curvature_material(),
        }
    }

    fn name(self) -> &'static str {
        match self {
            Self::PerSpring => "per spring",
            Self::Sheet => "sheet",
            Self::Hinges => "hinges",
            Self::Curvature => "curvature",
        }
    }
}

/// Total force of the ball's poke, N.
const BALL_FORCE: f32 = 2.0;

/// Total force of the shell's poke, N.
const SHELL_FORCE: f32 = 0.5;

/// The gas in the ball: its outside pressure κ (see `Pressure`), N/m².
const BALL_GAS: f32 = 100.0;

/// Radius of the poked disc around the sphere's top, as a fraction of its radius.
const POKE_RADIUS: f32 = 0.3;

/// Most steps per run.
const MAX_STEPS: usize = 100_000;

/// Arguments of `point-springs-bench convergence`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Fractions of the dense points kept as simulation points; the largest is the
    /// reference.
    #[arg(long, value_delimiter = ',', default_values_t = [0.02, 0.05, 0.1, 0.2, 0.5, 1.0])]
    fractions: Vec<f32>,
    /// Steps of 1/30 s to equilibrium.
    #[arg(long, default_value_t = 450)]
    steps: usize,
    /// The problems run.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = Problem::ALL)]
    problems: Vec<Problem>,
    /// The materials compared.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [Material::PerSpring, Material::Sheet, Material::Hinges, Material::Curvature])]
    materials: Vec<Material>,
    /// Where the chart goes: this path with `.svg` and `.png`.
    #[arg(long, default_value = "convergence")]
    chart: PathBuf,
    #[command(flatten)]
    json: JsonFlag,
}

/// The problems.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
#[value(rename_all = "snake_case")]
pub enum Problem {
    /// A 2 × 2 square sheet (2887 points), pinned along its whole rim, sagging under gravity.
    Sheet,
    /// The hat of Fig. 6 (3000 points), pinned at its rim, sagging under gravity.
    Hat,
    /// The sphere of Fig. 5 (3203 points) with gas inside, its lower fifth pinned, pressed
    /// on its top by a fixed total force shared evenly by the dense points of a disc and
    /// carried to the simulation points by the transfer's transpose (the same load at every
    /// level): a ball.
    Ball,
    /// The same sphere without gas, pressed more lightly: a shell, which only its bending
    /// keeps from folding in.
    Shell,
}

impl Problem {
    const ALL: [Self; 4] = [Self::Sheet, Self::Hat, Self::Ball, Self::Shell];

    fn cloud(self) -> PointCloud {
        match self {
            Self::Sheet => square_sheet(2.0, 0.04),
            Self::Hat => hat(3000, 1.0, -0.2),
            Self::Ball | Self::Shell => fibonacci_sphere(3203, 1.0),
        }
    }

    /// The direction the load pushes (the sag is measured along it).
    fn load(self) -> Vec3 {
        match self {
            Self::Sheet => Vec3::NEG_Z,
            Self::Hat | Self::Ball | Self::Shell => Vec3::NEG_Y,
        }
    }
}

/// One run.
#[derive(Debug, Serialize)]
struct Row {
    problem: Problem,
    material: Material,
    fraction: f32,
    sim_points: usize,
    dense_points: usize,
    /// Σm / (ρ · the dense surface's area).
    mass_ratio: f32,
    /// The mean displacement along the load of the dense points it acts on, weighted by
    /// their shares of it (every dense point under gravity, the disc's under a poke): the
    /// load's work over its total, the compliance.
    sag: f32,
    /// `sag` over the same material's finest level (set once that level has run).
    relative: f32,
    /// The largest displacement of a dense point along the load: a local figure, which a
    /// coarse network concentrates or spreads.
    peak: f32,
    /// `peak` over the same material's finest level.
    relative_peak: f32,
    /// The largest speed at the end, over `peak` per second: small when settled.
    residual_speed: f32,
    /// The stretch springs' energy at the end, with their couplings (a sheet's), over a
    /// constant-strain membrane's on the same triangles for the same displacement (the
    /// sheet's stretch modulus, Poisson's ratio 1/3; see `membrane`): 1 where the springs
    /// are the membrane they stand for (a sheet's), other where they are not (the paper's,
    /// per spring).
    springs_over_membrane: f32,
}

#[derive(Debug, Serialize)]
struct ConvergenceReport {
    benchmark: &'static str,
    steps: usize,
    dt: f32,
    rows: Vec<Row>,
    chart: [String; 2],
}

impl fmt::Display for ConvergenceReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "Convergence — {} steps of {:.4} s, implicit Euler, to equilibrium; relative: over the same material's finest level",
            self.steps, self.dt
        )?;
        writeln!(f)?;
        writeln!(
            f,
            "| problem | material | simulation points | dense | Σm / ρA | mean sag | relative | peak sag | relative | residual speed | springs / membrane |"
        )?;
        writeln!(f, "|---|---|---|---|---|---|---|---|---|---|---|")?;
        for r in &self.rows {
            writeln!(
                f,
                "| {:?} | {} | {} | {} | {:.4} | {:.4} | {:.3} | {:.4} | {:.3} | {:.1e} | {:.3} |",
                r.problem,
                r.material.name(),
                r.sim_points,
                r.dense_points,
                r.mass_ratio,
                r.sag,
                r.relative,
                r.peak,
                r.relative_peak,
                r.residual_speed,
                r.springs_over_membrane
            )?;
        }
        writeln!(f)?;
        writeln!(f, "chart: {} and {}", self.chart[0], self.chart[1])
    }
}

impl Report for ConvergenceReport {}

/// Runs `point-springs-bench convergence`.
pub fn run(args: &Args) -> Result<(), Failure> {
    if !(1..=MAX_STEPS).contains(&args.steps) {
        return Err(Failure::bad_input(format!(
            "--steps must be between 1 and {MAX_STEPS}"
        )));
    }
    if args.fractions.is_empty() || args.fractions.iter().any(|f| !(*f > 0.0 && *f <= 1.0)) {
        return Err(Failure::bad_input("--fractions must be in (0, 1]"));
    }
    let mut fractions = args.fractions.clone();
    fractions.sort_by(f32::total_cmp);
    fractions.dedup();
    let mut rows = Vec::new();
    let mut series = Vec::new();
    for &problem in &args.problems {
        let cloud = problem.cloud();
        for &material in &args.materials {
            let name = material.name();
            let mut runs = Vec::new();
            for &fraction in &fractions {
                eprintln!("bench convergence: {problem:?}, {name}, {fraction} of the points");
                runs.push(settle(problem, &cloud, material, fraction, args.steps)?);
            }
            let (sag, peak) = runs.last().map_or((1.0, 1.0), |r: &Row| (r.sag, r.peak));
            for r in &mut runs {
                r.relative = r.sag / sag;
                r.relative_peak = r.peak / peak;
            }
            // A colour per problem, a line per material (hinges solid, the fitted curvature in
            // short dashes, springs dotted or in long dashes).
            series.push(Series {
                name: format!("{problem:?}, {name}"),
                points: runs
                    .iter()
                    .map(|r| (r.sim_points as f64, f64::from(r.relative)))
                    .collect(),
                colour: Some(problem as usize),
                dash: match material {
                    Material::PerSpring => Some(3),
                    Material::Sheet => Some(9),
                    Material::Hinges => None,
                    Material::Curvature => Some(5),
                },
            });
            rows.extend(runs);
        }
    }
    let chart = Chart {
        title: "Sag and depth at equilibrium over the simplification level".to_owned(),
        x_label: "simulation points".to_owned(),
        y_label: "over the finest level's".to_owned(),
        log_x: true,
        log_y: false,
        series,
        marked: None,
        legend_upper: false,
    };
    let [svg, png] = chart.write(&args.chart)?;
    let report = ConvergenceReport {
        benchmark: "convergence",
        steps: args.steps,
        dt: DT,
        rows,
        chart: [svg.display().to_string(), png.display().to_string()],
    };
    args.json.emit(&report)
}

/// Prepares `cloud` at `fraction`, loads it as `problem` says and runs it `steps` steps.
fn settle(
    problem: Problem,
    cloud: &PointCloud,
    kind: Material,
    fraction: f32,
    steps: usize,
) -> Result<Row, Failure> {
    let target = level_target(cloud.len(), fraction);
    let gravity = match problem {
        Problem::Sheet | Problem::Hat => problem.load() * GRAVITY,
        Problem::Ball | Problem::Shell => Vec3::ZERO,
    };
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(target),
        material: kind.material(),
        solver: SolverConfig {
            integrator: Integrator::ImplicitEuler,
            gravity,
            drag: DRAG,
            ..SolverConfig::default()
        },
        pressure: (problem == Problem::Ball).then_some(BALL_GAS),
        ..SurfaceConfig::default()
    };
    let mut surface = prepare_surface(cloud.clone(), &config, &mut |_| ControlFlow::Continue(()))
        .map_err(Failure::other)?;
    let shares = load(problem, &mut surface)?;
    for _ in 0..steps {
        surface.solver.step(DT).map_err(Failure::other)?;
    }
    surface
        .dense
        .follow(&surface.solver.points)
        .map_err(Failure::other)?;
    let rest = surface.dense.transfer().rest_positions();
    let along: Vec<f32> = surface
        .dense
        .positions()
        .iter()
        .zip(rest)
        .map(|(p, r)| (*p - *r).dot(problem.load()))
        .collect();
    let peak = along.iter().copied().fold(0.0f32, f32::max);
    let sag = along.iter().zip(&shares).map(|(u, w)| u * w).sum::<f32>();
    let network = &surface.network;
    Ok(Row {
        problem,
        material: kind,
        fraction,
        sim_points: network.len(),
        dense_points: surface.dense.len(),
        mass_ratio: network.report.total_mass / (DENSITY * network.report.dense_area),
        sag,
        relative: 1.0,
        peak,
        relative_peak: 1.0,
        residual_speed: surface.solver.points.max_speed() / peak.max(f32::MIN_POSITIVE),
        springs_over_membrane: springs_over_membrane(
            network,
            kind,
            &surface.solver.points.positions(),
        )?,
    })
}

/// The stretch springs' energy at `positions`, with their couplings, over a membrane's of
/// the sheet's stretch modulus on the network's triangles (see
/// [`Row::springs_over_membrane`]).
fn springs_over_membrane(
    network: &SpringNetwork,
    kind: Material,
    positions: &[Vec3],
) -> Result<f32, Failure> {
    let material = kind.material();
    let specs = material.springs(network);
    let mut stretch =
        Springs::new(&specs[..network.stretch.len()], network.len()).map_err(Failure::other)?;
    stretch
        .set_couplings(&material.couplings(network))
        .map_err(Failure::other)?;
    let points = PointState::new(positions).map_err(Failure::other)?;
    let membrane = membrane_energy(
        &network.triangles,
        &network.positions,
        positions,
        sheet_material().stretch_stiffness,
        LATTICE_POISSON_RATIO,
    );
    Ok((stretch.energy(&points) / membrane) as f32)
}

/// Pins and loads a prepared surface: the sheet and the hat at their rims (the network's
/// boundary points), the ball and the shell below y = −0.6, pressed over the disc at
/// their top. Returns each dense point's share of the load (summing to 1): even over the
/// dense surface under gravity (the clouds are evenly sampled), even over the disc's dense
/// points under a poke.
fn load(problem: Problem, surface: &mut PreparedSurface) -> Result<Vec<f32>, Failure> {
    let network = &surface.network;
    let solver = &mut surface.solver;
    let rest = surface.dense.transfer().rest_positions();
    match problem {
        Problem::Sheet | Problem::Hat => {
            for (i, &rim) in network.boundary.iter().enumerate() {
                if rim {
                    solver.set_fixed(i, true).map_err(Failure::other)?;
                }
            }
            Ok(vec![1.0 / rest.len() as f32; rest.len()])
        }
        Problem::Ball | Problem::Shell => {
            let force = if problem == Problem::Ball {
                BALL_FORCE
            } else {
                SHELL_FORCE
            };
            let under = |p: &Vec3| p.distance(Vec3::Y) < POKE_RADIUS;
            let count = rest.iter().filter(|p| under(p)).count().max(1);
            let shares: Vec<f32> = rest
                .iter()
                .map(|p| if under(p) { 1.0 / count as f32 } else { 0.0 })
                .collect();
            let dense_forces: Vec<Vec3> =
                shares.iter().map(|w| problem.load() * force * w).collect();
            let mut forces = vec![Vec3::ZERO; network.len()];
            surface
                .dense
                .transfer()
                .spread_forces(&dense_forces, &mut forces)
                .map_err(Failure::other)?;

            for (i, f) in forces.into_iter().enumerate() {
                if f != Vec3::ZERO {
                    solver.set_external_force(i, f).map_err(Failure::other)?;
                }
            }
            for i in 0..network.len() {
                if network.positions[i].y < -0.6 {
                    solver.set_fixed(i, true).map_err(Failure::other)?;
                }
            }
            Ok(shares)
        }
    }
}
