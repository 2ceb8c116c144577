//! The benchmarks' own flag values.

use bevy_point_springs::core::solver::BendingModel;
use clap::ValueEnum;

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
