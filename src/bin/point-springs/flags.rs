//! The flags `point-springs` and `point-springs-bench` both use (the bench includes this
//! file, with `failure.rs` and `report.rs`, by path).

use bevy_point_springs::core::normals::denoise::Denoise;
use clap::ValueEnum;

use crate::failure::Failure;
use crate::report::{Report, emit};

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
