//! `point-springs normals`: give a cloud oriented normals and write it as PLY.

use std::fmt;
use std::path::PathBuf;
use std::time::Instant;

use bevy_point_springs::core::PointCloud;
use bevy_point_springs::core::normals::{DEFAULT_NORMAL_K, NormalSource, ensure_normals};
use serde::Serialize;

use crate::args::{CloudInput, PlyFlag};
use crate::failure::Failure;
use crate::flags::JsonFlag;
use crate::report::Report;

/// Arguments of `normals`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output PLY file.
    #[arg(short, long)]
    output: PathBuf,
    /// Neighbours per PCA fit.
    #[arg(short, default_value_t = DEFAULT_NORMAL_K)]
    k: usize,
    #[command(flatten)]
    input: CloudInput,
    /// Estimate normals even when the file has usable ones.
    #[arg(long)]
    reestimate: bool,
    #[command(flatten)]
    ply: PlyFlag,
    #[command(flatten)]
    json: JsonFlag,
}

/// What `normals` reports.
#[derive(Debug, Serialize)]
struct NormalsReport {
    /// The file read.
    input: String,
    /// The file written.
    output: String,
    /// Its points.
    points: usize,
    /// Where the normals came from: "file" (kept) or "estimated".
    normals: &'static str,
    /// Estimated: connected components of the k-NN graph.
    components: Option<usize>,
    /// Estimated: points whose normal ended up with the opposite sign from PCA's.
    flipped: Option<usize>,
    /// Estimated: points whose neighbourhood had no plane.
    degenerate: Option<usize>,
    /// Time taken, s.
    seconds: f64,
    /// Neighbours per PCA fit (text only).
    #[serde(skip)]
    k: usize,
}

impl fmt::Display for NormalsReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (self.components, self.flipped, self.degenerate) {
            (Some(components), Some(flipped), Some(degenerate)) => writeln!(
                f,
                "{}: {} points, normals estimated (k = {}): {components} component(s), {flipped} flipped, {degenerate} degenerate, {:.3} s → {}",
                self.input, self.points, self.k, self.seconds, self.output
            ),
            _ => writeln!(
                f,
                "{}: {} points, the file's own normals kept → {}",
                self.input, self.points, self.output
            ),
        }
    }
}

impl Report for NormalsReport {}

/// Runs `normals`.
pub fn run(args: &Args) -> Result<(), Failure> {
    let start = Instant::now();
    let mut cloud = args.input.load()?;
    if args.reestimate {
        let (positions, _) = cloud.into_parts();
        cloud = PointCloud::new(positions, None).map_err(Failure::bad_input)?;
    }
    let source = ensure_normals(&mut cloud, args.k).map_err(Failure::bad_input)?;
    args.ply.write(&args.output, &cloud)?;
    let estimated = match source {
        NormalSource::File | NormalSource::Faces => None,
        NormalSource::Estimated(r) | NormalSource::FileReoriented(r) => Some(r),
    };
    let report = NormalsReport {
        input: args.input.file.display().to_string(),
        output: args.output.display().to_string(),
        points: cloud.len(),
        normals: match source {
            NormalSource::File => "file",
            NormalSource::FileReoriented(_) => "file, re-oriented",
            NormalSource::Faces => "faces",
            NormalSource::Estimated(_) => "estimated",
        },
        components: estimated.map(|r| r.components),
        flipped: estimated.map(|r| r.flipped),
        degenerate: estimated.map(|r| r.degenerate),
        seconds: start.elapsed().as_secs_f64(),
        k: args.k,
    };
    args.json.emit(&report)
}
