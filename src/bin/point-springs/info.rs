//! `point-springs info`: a cloud's point count, normals, bounding box and spacing.

use std::fmt;

use bevy_point_springs::core::cloud::knn::KnnIndex;
use serde::Serialize;

use crate::args::CloudInput;
use crate::failure::Failure;
use crate::flags::JsonFlag;
use crate::report::Report;

/// Arguments of `info`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    input: CloudInput,
    #[command(flatten)]
    json: JsonFlag,
}

/// What `info` reports.
#[derive(Debug, Serialize)]
struct Info {
    /// The file read.
    file: String,
    /// The format it was read as.
    format: String,
    /// Its points.
    points: usize,
    /// Whether it has normals.
    has_normals: bool,
    /// Whether they are all usable (non-zero).
    normals_usable: bool,
    /// The bounding box's lower corner.
    bbox_min: [f32; 3],
    /// Its upper corner.
    bbox_max: [f32; 3],
    /// Its diagonal's length.
    bbox_diagonal: f32,
    /// Mean distance to the nearest few neighbours, over the points.
    mean_spacing: Option<f32>,
    /// The smallest of those distances.
    min_spacing: Option<f32>,
    /// The largest.
    max_spacing: Option<f32>,
}

impl fmt::Display for Info {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "file          {}", self.file)?;
        writeln!(f, "format        {}", self.format)?;
        writeln!(f, "points        {}", self.points)?;
        let normals = match (self.has_normals, self.normals_usable) {
            (false, _) => "none (estimate with `point-springs normals`)",
            (true, false) => "present but some are zero (will be estimated)",
            (true, true) => "yes",
        };
        writeln!(f, "normals       {normals}")?;
        writeln!(f, "bbox min      {:?}", self.bbox_min)?;
        writeln!(f, "bbox max      {:?}", self.bbox_max)?;
        writeln!(f, "bbox diagonal {}", self.bbox_diagonal)?;
        if let (Some(mean), Some(min), Some(max)) =
            (self.mean_spacing, self.min_spacing, self.max_spacing)
        {
            writeln!(f, "spacing       mean {mean} (min {min}, max {max})")?;
        }
        Ok(())
    }
}

impl Report for Info {}

/// Runs `info`.
pub fn run(args: &Args) -> Result<(), Failure> {
    let file = &args.input.file;
    let cloud = args.input.load()?;
    let bounds = cloud
        .bounds()
        .ok_or_else(|| Failure::bad_input("empty cloud"))?;
    let spacing = cloud.spacing(&KnnIndex::build(cloud.positions()));
    let info = Info {
        file: file.display().to_string(),
        format: args.input.format.name_for(file),
        points: cloud.len(),
        has_normals: cloud.normals().is_some(),
        normals_usable: cloud.has_usable_normals(),
        bbox_min: bounds.min.to_array(),
        bbox_max: bounds.max.to_array(),
        bbox_diagonal: bounds.diagonal(),
        mean_spacing: spacing.map(|s| s.mean),
        min_spacing: spacing.map(|s| s.min),
        max_spacing: spacing.map(|s| s.max),
    };
    args.json.emit(&info)
}
