//! `point-springs render`: draw clouds as lit discs to a PNG, side by side at one scale.

use std::fmt;
use std::path::PathBuf;

use bevy_point_springs::core::PointCloud;
use bevy_point_springs::core::normals::{DEFAULT_NORMAL_K, ensure_normals};
use glam::Vec3;
use serde::Serialize;

use crate::args::{FormatFlag, parse_vec3};
use crate::failure::Failure;
use crate::picture::{self, View};
use crate::report::{Report, emit};

/// Arguments of `render`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The clouds (.ply .xyz .pwn .off .obj); normals are estimated where missing.
    #[arg(required = true)]
    files: Vec<PathBuf>,
    /// The PNG to write.
    #[arg(short, long)]
    output: PathBuf,
    /// Direction from the cloud towards the eye.
    #[arg(long, value_parser = parse_vec3, default_value = "1,0.8,1.6")]
    view: Vec3,
    /// Up on the picture.
    #[arg(long, value_parser = parse_vec3, default_value = "0,1,0")]
    up: Vec3,
    /// Picture width, pixels.
    #[arg(long, default_value_t = 900)]
    width: u32,
    /// Picture height, pixels.
    #[arg(long, default_value_t = 700)]
    height: u32,
    #[command(flatten)]
    format: FormatFlag,
}

/// What `render` reports (as text only: the command has no `--json`).
#[derive(Debug, Serialize)]
struct RenderReport {
    /// Points drawn.
    points: usize,
    /// Clouds drawn, one panel each.
    panels: usize,
    /// The smallest disc radius, pixels.
    disc_px: f32,
    /// The PNG written.
    output: String,
}

impl fmt::Display for RenderReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{} points in {} panel(s), discs of {:.1} px or more → {}",
            self.points, self.panels, self.disc_px, self.output
        )
    }
}

impl Report for RenderReport {}

/// Runs `render`.
pub fn run(args: &Args) -> Result<(), Failure> {
    let view = View::checked(args.view, args.up, (args.width, args.height))?;
    let mut clouds = Vec::with_capacity(args.files.len());
    for file in &args.files {
        let mut cloud = args.format.load(file)?;
        ensure_normals(&mut cloud, DEFAULT_NORMAL_K).map_err(Failure::bad_input)?;
        clouds.push(cloud);
    }
    let refs: Vec<&PointCloud> = clouds.iter().collect();
    let drawn = picture::render(&refs, &view, &args.output).map_err(Failure::other)?;
    let report = RenderReport {
        points: drawn.points,
        panels: refs.len(),
        disc_px: drawn.disc_px,
        output: args.output.display().to_string(),
    };
    emit(&report, false)
}
