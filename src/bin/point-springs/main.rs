//! `point-springs`: the headless command-line tool.
//!
//! ```text
//! point-springs info FILE [--format F] [--json]
//! point-springs normals FILE -o OUT.ply [-k K] [--format F] [--reestimate] [--ascii] [--json]
//! point-springs simplify FILE (--target N | --max-diameter D) [-k K] [--density RHO]
//!                        [--denoise auto|on|off] [-o OUT.ply] [--format F] [--ascii] [--json]
//! point-springs prepare FILE [--settings SURFACE.ron] [--target N] [-o OUT.psprep] [--json]
//! point-springs run SCENE.ron [-o DEFORMED.ply] [--png PICTURE.png] [--view X,Y,Z] [--up X,Y,Z]
//!                        [--ascii] [--json]
//! point-springs render FILE... -o PICTURE.png [--view X,Y,Z] [--up X,Y,Z] [--width W]
//!                        [--height H] [--format F]
//! point-springs generate (sphere|hat|sheet|letter-b) -o OUT.ply [--points N] [--radius R]
//!                        [--rim Y] [--size S] [--spacing H] [--uneven U] [--noise SIGMA]
//!                        [--seed S] [--ascii]
//! ```
//!
//! Exit codes: 0 success, 2 bad input (unreadable or malformed file, bad arguments),
//! 1 any other failure (e.g. the output cannot be written).
//!
//! One module per command, each with its own `Args` and its report; the flags several
//! commands share are in [`args`] and [`flags`], failures and exit codes in [`failure`].
//! The benchmarks and the report are a tool of their own, `point-springs-bench` (the
//! workspace's `bench/` crate), which shares `failure.rs`, `flags.rs` and `report.rs`.

mod args;
mod failure;
mod flags;
mod generate;
mod info;
mod normals;
mod picture;
mod prepare;
mod render;
mod report;
mod run;
mod simplify;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// The command line.
#[derive(Parser)]
#[command(
    name = "point-springs",
    version,
    about = "Point-sampled surfaces: inspect, prepare and simulate them"
)]
struct Cli {
    /// What to do.
    #[command(subcommand)]
    command: Command,
}

/// The commands.
#[derive(Subcommand)]
enum Command {
    /// Summarise a point cloud: count, normals, bounds, spacing.
    Info(info::Args),
    /// Give a cloud oriented normals (PCA + propagation when it has none) and write it as PLY.
    Normals(normals::Args),
    /// Choose simulation points (§3 tangent-plane Delaunay simplification) and build their
    /// spring network (§4); normals are estimated first when the file has none.
    Simplify(simplify::Args),
    /// Prepare a cloud once (normals, simplification, springs, transfer) and save the result
    /// as a prepared file, which the plugin reads instead of preparing again.
    Prepare(prepare::Args),
    /// Run a scene file headless: load, simplify, simulate, transfer the motion back to
    /// every dense point; write the deformed surface (positions and normals).
    Run(run::Args),
    /// Draw clouds as lit discs to a PNG (orthographic, no GPU needed); several clouds are
    /// drawn side by side at one scale.
    Render(render::Args),
    /// Write a procedural surface with exact normals as PLY.
    Generate(generate::Args),
}

fn main() -> ExitCode {
    let result = match Cli::parse().command {
        Command::Info(args) => info::run(&args),
        Command::Normals(args) => normals::run(&args),
        Command::Simplify(args) => simplify::run(&args),
        Command::Prepare(args) => prepare::run(&args),
        Command::Run(args) => run::run(&args),
        Command::Render(args) => render::run(&args),
        Command::Generate(args) => generate::run(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(failure) => failure.exit(),
    }
}
