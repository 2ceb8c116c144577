//! `point-springs-bench`: timings of the library's stages against straightforward or literal
//! implementations, both measured in the same run (ratios, not absolute times, are what
//! carry over between machines), and the speed-against-error report.
//!
//! ```text
//! point-springs-bench cloth-grid [--size N] [--steps S] [--integrator I] [--repeat R]
//!                        [--no-reference] [--json]
//! point-springs-bench transfer [--points N] [--sim M] [--sim-source sphere|simplify] [-k K]
//!                        [--bandwidth H] [--repeat R] [--no-literal] [--threads T] [--json]
//! point-springs-bench plugin [SCENE.ron] [--dense N] [--sim M] [--ticks T] [--block B]
//!                        [--single-threaded] [--json]
//! point-springs-bench network FILE... [--levels 1,5,20,50] [-k K] [--denoise auto|on|off]
//!                        [--format F] [--ignore-faces] [--json]
//! point-springs-bench report [--quick] [--scenes S,...] [-o DIR] [--assets DIR]
//! point-springs-bench (crowd|table1|convergence|scale|solvers) ... (see --help)
//! ```
//!
//! Run it from the repository root (`cargo run --release -p point-springs-bench -- …`): the
//! scenes are read from `assets/` there unless `--assets` says otherwise. It is the
//! workspace's `bench/` crate, apart from the `point-springs` tool so the tool's `--help`
//! and build carry none of this; it shares the tool's `failure.rs`, `flags.rs` and
//! `report.rs` (by path) so both print and fail the same way. The baselines it times the
//! library against are this crate's library ([`point_springs_bench::baselines`]).

mod args;
mod chart;
mod cloth;
mod convergence;
mod crowd;
#[path = "../../src/bin/point-springs/failure.rs"]
#[allow(
    dead_code,
    reason = "shared with the tool; no benchmark fails as unstable"
)]
mod failure;
#[path = "../../src/bin/point-springs/flags.rs"]
mod flags;
mod network;
mod plugin;
mod poke;
#[path = "../../src/bin/point-springs/report.rs"]
mod report;
mod scale;
mod solvers;
mod speed_error;
mod table1;
mod transfer;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// The command line.
#[derive(Parser)]
#[command(
    name = "point-springs-bench",
    version,
    about = "Benchmarks of bevy_point_springs, and its speed-against-error report"
)]
struct Cli {
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
    Plugin(plugin::Args),
    /// A crowd of small surfaces in the plugin at default settings: --surfaces gas-filled
    /// spheres (of --dense points simplified to --sim), falling under gravity and poked;
    /// milliseconds per tick for all of them, with sub-steps, CG iterations and guard trips.
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
    Report(speed_error::Args),
    /// Implicit Euler's two solvers side by side: conjugate gradient and the prefactored
    /// local/global iterations at several counts, on the scenes of `report` at one level;
    /// ms per step and each dense surface's distance from the CG run's at the end.
    Solvers(solvers::Args),
}

fn main() -> ExitCode {
    let result = match Cli::parse().case {
        Case::ClothGrid(args) => cloth::run(&args),
        Case::Transfer(args) => transfer::run(&args),
        Case::Plugin(args) => plugin::run(&args),
        Case::Crowd(args) => crowd::run(&args),
        Case::Network(args) => network::run(&args),
        Case::Table1(args) => table1::run(&args),
        Case::Scale(args) => scale::run(&args),
        Case::Convergence(args) => convergence::run(&args),
        Case::Report(args) => speed_error::run(&args),
        Case::Solvers(args) => solvers::run(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(failure) => failure.exit(),
    }
}
