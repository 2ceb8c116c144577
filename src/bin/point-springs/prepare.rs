//! `point-springs prepare`: prepares a cloud once (normals, §3, §4, §5) and writes the
//! result as a prepared file, which the plugin reads instead of preparing again
//! (`DeformableSurface::with_prepared_file`). The file is read back at once, to check it
//! and to time how much faster reading it is than preparing.

use std::fmt;
use std::ops::ControlFlow;
use std::path::PathBuf;
use std::time::Instant;

use bevy_point_springs::core::pipeline::prepared::{
    PREPARED_EXTENSION, SourceFingerprint, read_prepared, write_prepared,
};
use bevy_point_springs::core::pipeline::{SurfaceConfig, prepare_surface};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;

use crate::args::CloudInput;
use crate::failure::Failure;
use crate::flags::JsonFlag;
use crate::report::Report;

/// Steps of the progress bar (the whole preparation).
const BAR_STEPS: u64 = 1000;

/// Arguments of `prepare`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    input: CloudInput,
    /// The surface's settings: a `SurfaceConfig` in RON (the defaults without).
    #[arg(long)]
    settings: Option<PathBuf>,
    /// Simulation points to aim for (instead of the settings' `simplify.target`).
    #[arg(long)]
    target: Option<usize>,
    /// The prepared file (default: the cloud's path with the extension `.psprep`).
    #[arg(short, long)]
    output: Option<PathBuf>,
    #[command(flatten)]
    json: JsonFlag,
}

/// What `prepare` reports.
#[derive(Debug, Serialize)]
struct Prepared {
    /// The cloud prepared.
    file: String,
    /// The prepared file written.
    output: String,
    /// Its size.
    bytes: u64,
    /// The source's fingerprint (first 8 bytes, hexadecimal).
    source: String,
    /// Dense points.
    dense_points: usize,
    /// Simulation points.
    sim_points: usize,
    /// Seconds to read the cloud.
    seconds_read_cloud: f64,
    /// Seconds to fingerprint it with its settings.
    seconds_fingerprint: f64,
    /// Seconds to prepare it.
    seconds_prepare: f64,
    /// Seconds to write the prepared file.
    seconds_write: f64,
    /// Seconds to read the prepared file back (checked) into a surface.
    seconds_read_prepared: f64,
    /// Reading the prepared file and fingerprinting the source, as a share of preparing.
    ready_share: f64,
}

impl fmt::Display for Prepared {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "cloud           {} ({} points)",
            self.file, self.dense_points
        )?;
        writeln!(f, "simulation      {} points", self.sim_points)?;
        writeln!(
            f,
            "prepared file   {} ({:.1} MB, source {})",
            self.output,
            self.bytes as f64 / 1e6,
            self.source
        )?;
        writeln!(f, "prepare         {:.3} s", self.seconds_prepare)?;
        writeln!(
            f,
            "ready from file {:.3} s (read {:.3} s + fingerprint {:.3} s): {:.1} % of preparing",
            self.seconds_read_prepared + self.seconds_fingerprint,
            self.seconds_read_prepared,
            self.seconds_fingerprint,
            100.0 * self.ready_share
        )
    }
}

impl Report for Prepared {}

/// Runs `prepare`.
pub fn run(args: &Args) -> Result<(), Failure> {
    let mut config = match &args.settings {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .map_err(|e| Failure::bad_input(format!("{}: {e}", path.display())))?;
            ron::from_str::<SurfaceConfig>(&text)
                .map_err(|e| Failure::bad_input(format!("{}: {e}", path.display())))?
        }
        None => SurfaceConfig::default(),
    };
    if let Some(target) = args.target {
        config.simplify.target = Some(target);
    }
    config.validate().map_err(Failure::bad_input)?;
    let output = args
        .output
        .clone()
        .unwrap_or_else(|| args.input.file.with_extension(PREPARED_EXTENSION));

    let start = Instant::now();
    let cloud = args.input.load()?;
    let seconds_read_cloud = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let source = SourceFingerprint::of(&cloud, &config);
    let seconds_fingerprint = start.elapsed().as_secs_f64();
    let dense_points = cloud.len();

    let bar = if args.json.json {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(BAR_STEPS).with_style(
            ProgressStyle::with_template("{bar:40} {msg} {elapsed}").map_err(Failure::other)?,
        )
    };
    let start = Instant::now();
    let surface = prepare_surface(cloud, &config, &mut |p| {
        bar.set_message(p.stage.name());
        bar.set_position((p.fraction * BAR_STEPS as f32) as u64);
        ControlFlow::Continue(())
    })
    .map_err(Failure::bad_input)?;
    let seconds_prepare = start.elapsed().as_secs_f64();
    bar.finish_and_clear();

    let start = Instant::now();
    write_prepared(&output, &surface, source).map_err(Failure::other)?;
    let seconds_write = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let again = read_prepared(&output, source).map_err(Failure::other)?;
    let seconds_read_prepared = start.elapsed().as_secs_f64();
    if again.network != surface.network {
        return Err(Failure::other(format!(
            "{}: read back, the network differs",
            output.display()
        )));
    }
    let bytes = std::fs::metadata(&output).map_or(0, |m| m.len());
    let report = Prepared {
        file: args.input.file.display().to_string(),
        output: output.display().to_string(),
        bytes,
        source: source.to_string(),
        dense_points,
        sim_points: surface.network.len(),
        seconds_read_cloud,
        seconds_fingerprint,
        seconds_prepare,
        seconds_write,
        seconds_read_prepared,
        ready_share: (seconds_read_prepared + seconds_fingerprint) / seconds_prepare.max(1e-9),
    };
    args.json.emit(&report)
}
