//! Flags that several commands share, each defined once and flattened into the commands'
//! own `Args`, and the value types and parsers of their options.

use std::path::{Path, PathBuf};

use bevy_point_springs::core::PointCloud;
use bevy_point_springs::core::cloud::io::{CloudFormat, PlyEncoding, read_cloud, write_ply};
use bevy_point_springs::core::normals::denoise::Denoise;
use bevy_point_springs::core::solver::BendingModel;
use clap::ValueEnum;
use glam::Vec3;

use crate::failure::Failure;
use crate::report::{Report, emit};

/// One cloud to read: `FILE [--format F]`.
#[derive(Debug, clap::Args)]
pub struct CloudInput {
    /// The cloud (.ply .xyz .pwn .off .obj).
    pub file: PathBuf,
    #[command(flatten)]
    pub format: FormatFlag,
}

impl CloudInput {
    /// Reads the cloud; an unreadable or malformed file is bad input.
    pub fn load(&self) -> Result<PointCloud, Failure> {
        self.format.load(&self.file)
    }
}

/// `--format F`: the format of the clouds read.
#[derive(Debug, clap::Args)]
pub struct FormatFlag {
    /// Read as this format instead of the one the extension names.
    #[arg(long)]
    pub format: Option<CloudFormat>,
}

impl FormatFlag {
    /// Reads `file` as this format (or the one its extension names).
    pub fn load(&self, file: &Path) -> Result<PointCloud, Failure> {
        load(file, self.format)
    }

    /// The name of the format `file` is read as ("unknown" when neither this flag nor the
    /// extension names one).
    pub fn name_for(&self, file: &Path) -> String {
        self.format
            .or_else(|| CloudFormat::from_path(file))
            .map_or_else(|| "unknown".into(), |f| f.to_string())
    }
}

/// Reads `file` as `format` (or the one its extension names); failing is bad input.
pub fn load(file: &Path, format: Option<CloudFormat>) -> Result<PointCloud, Failure> {
    read_cloud(file, format).map_err(Failure::bad_input)
}

/// `--ascii`: how PLY files are written.
#[derive(Debug, clap::Args)]
pub struct PlyFlag {
    /// Write ASCII PLY instead of binary little-endian.
    #[arg(long)]
    pub ascii: bool,
}

impl PlyFlag {
    /// The encoding the flag asks for.
    pub fn encoding(&self) -> PlyEncoding {
        if self.ascii {
            PlyEncoding::Ascii
        } else {
            PlyEncoding::BinaryLittleEndian
        }
    }

    /// Writes `cloud` to `path` in this encoding; failing is not bad input.
    pub fn write(&self, path: &Path, cloud: &PointCloud) -> Result<(), Failure> {
        write_ply(path, cloud, self.encoding()).map_err(Failure::other)
    }
}

/// `--json`: how a command prints its report.
#[derive(Debug, clap::Args)]
pub struct JsonFlag {
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

impl JsonFlag {
    /// Prints `report` as the flag asks.
    pub fn emit(&self, report: &impl Report) -> Result<(), Failure> {
        emit(report, self.json)
    }
}

/// `--denoise` values.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum DenoiseArg {
    /// When the cloud measures noisy.
    Auto,
    /// Always.
    On,
    /// Never.
    Off,
}

impl From<DenoiseArg> for Denoise {
    fn from(d: DenoiseArg) -> Self {
        match d {
            DenoiseArg::Auto => Denoise::Auto,
            DenoiseArg::On => Denoise::On,
            DenoiseArg::Off => Denoise::Off,
        }
    }
}

/// Parses "x,y,z".
pub fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let parts: Vec<f32> = s
        .split(',')
        .map(|p| p.trim().parse::<f32>().map_err(|e| format!("{p:?}: {e}")))
        .collect::<Result<_, _>>()?;
    match parts[..] {
        [x, y, z] if x.is_finite() && y.is_finite() && z.is_finite() => Ok(Vec3::new(x, y, z)),
        _ => Err(format!("expected three finite numbers x,y,z, got {s:?}")),
    }
}

/// `--bending` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum BendingArg {
    /// The paper's bend springs.
    Springs,
    /// Hinges (discrete shells).
    Hinges,
    /// Each point's curvature, from a quadric fitted to its neighbours.
    Curvature,
}

impl From<BendingArg> for BendingModel {
    fn from(b: BendingArg) -> Self {
        match b {
            BendingArg::Springs => Self::Springs,
            BendingArg::Hinges => Self::Hinges,
            BendingArg::Curvature => Self::Curvature,
        }
    }
}
