//! Flags that several commands share, each defined once and flattened into the commands'
//! own `Args`, and the value types and parsers of their options (those `point-springs-bench`
//! shares too are in [`crate::flags`]).

use std::path::{Path, PathBuf};

use bevy_point_springs::core::PointCloud;
use bevy_point_springs::core::cloud::io::{CloudFormat, PlyEncoding, read_cloud, write_ply};
use glam::Vec3;

use crate::failure::Failure;

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
