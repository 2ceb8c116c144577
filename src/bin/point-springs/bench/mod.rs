//! `point-springs bench`: timings of the core stages against straightforward or literal
//! implementations, both measured in the same run (ratios, not absolute times, are what
//! carry over between machines).

mod cloth;
mod convergence;
#[cfg(feature = "plugin")]
mod crowd;
mod network;
#[cfg(feature = "plugin")]
mod plugin;
mod poke;
mod report;
mod scale;
mod solvers;
mod table1;
mod transfer;

use clap::Subcommand;

use crate::failure::Failure;
pub use poke::{POKED_SPHERE_DT, poked_sphere};

/// Arguments of `bench`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The benchmark.
    #[command(subcommand)]
    case: Case,
}

/// The benchmarks.
#[derive(Debug, Subcommand)]
enum Case {
    /// The standard CPU cloth benchmark: a 32×32 grid with 5826 springs hanging from two
    /// corners, symplectic Euler at dt = 1/960 for 1000 steps, timed against the
    /// straightforward loop over the springs in the same run (one thread).
    ClothGrid(cloth::Args),
    /// Displacement transfer (§5): the precomputed coefficients against the paper's literal
    /// per-frame method (k-NN search, 3×3 solve and PCA normals per dense point), both
    /// parallel, timed in the same run; positions and normals are compared with the exact
    /// answer for a known smooth deformation (a bulge over the upper half of the sphere).
    Transfer(transfer::Args),
    /// The Bevy plugin headless (one fixed tick per update): milliseconds per tick split
    /// into forces, stepping and transfer, the surfel upload's packing, and the same work
    /// done by the core alone in the same run. Without SCENE: a generated sphere (of
    /// --dense points, --sim simulation points) in a cup with a sustained poke.
    #[cfg(feature = "plugin")]
    Plugin(plugin::Args),
    /// A crowd of small surfaces in the plugin at default settings: --surfaces gas-filled
    /// spheres (of --dense points simplified to --sim), falling under gravity and poked;
    /// milliseconds per tick for all of them, with sub-steps, CG iterations and guard trips.
    #[cfg(feature = "plugin")]
    Crowd(crowd::Args),
    /// Whether the spring network is watertight: each cloud simplified to several fractions
    /// of its points, with the network's closedness, Euler characteristic, boundary loops,
    /// fold-overs, crossings and the time of each stage (a Markdown table, or JSON).
    Network(network::Args),
    /// The paper's Table 1 measured here: the 3203-point sphere of Fig. 5 at 85, 273 and
    /// 338 simulation points, poked, with each integrator; ms per step including the
    /// transfer of positions and normals to every dense point, beside the paper's seconds.
    Table1(table1::Args),
    /// Whether a coarse network models the same surface as a fine one: a sheet and the hat
    /// sagging under gravity and the sphere pressed by a fixed force, at several levels,
    /// with the material per spring and as a sheet's moduli, run to equilibrium; the sag
    /// against the finest level's, and a chart (SVG and PNG).
    Convergence(convergence::Args),
    /// How preparation (by stage), a step, the transfer and memory grow with the dense and
    /// simulation point counts (the generated sphere of Fig. 5, pressed for a few steps).
    Scale(scale::Args),
    /// Speed against error: four scenes (the sphere poked and held, the hat and a sheet
    /// sagging, the kitten scan pulled) at several levels with each integrator and step,
    /// timed per step and per 60 Hz frame, their dense surfaces compared with a
    /// full-resolution reference; writes report.md, report.csv, a chart per scene with its
    /// Pareto front, and summary.json (with the paper's Table 1).
    Report(report::Args),
    /// Implicit Euler's two solvers side by side: conjugate gradient and the prefactored
    /// local/global iterations at several counts, on the scenes of `report` at one level;
    /// ms per step and each dense surface's distance from the CG run's at the end.
    Solvers(solvers::Args),
}

/// Runs `bench`.
pub fn run(args: Args) -> Result<(), Failure> {
    match args.case {
        Case::ClothGrid(args) => cloth::run(&args),
        Case::Transfer(args) => transfer::run(&args),
        #[cfg(feature = "plugin")]
        Case::Plugin(args) => plugin::run(&args),
        #[cfg(feature = "plugin")]
        Case::Crowd(args) => crowd::run(&args),
        Case::Network(args) => network::run(&args),
        Case::Table1(args) => table1::run(&args),
        Case::Scale(args) => scale::run(&args),
        Case::Convergence(args) => convergence::run(&args),
        Case::Report(args) => report::run(&args),
        Case::Solvers(args) => solvers::run(&args),
    }
}
