//! One preparation pipeline for every caller (the command-line tool, the benches and the
//! Bevy plugin): a dense cloud and a [`SurfaceConfig`] in, a [`PreparedSurface`] out —
//! normals, §3 simplification, §4 network and masses (shares of the dense surface's area,
//! so that the total does not depend on the level), the solver, the §5 transfer
//! coefficients — with progress reports and a way to stop early. No clock is read here:
//! callers that want timings measure around the call.
//!
//! The [`DenseCloud`] of a prepared surface follows the simulation: each frame it carries
//! the simulation points' motion to every dense point (positions and normals), and every
//! [`ResampleConfig::interval`] steps it inserts points where the surface stretched.
//!
//! ```
//! use std::ops::ControlFlow;
//! use bevy_point_springs::core::pipeline::{SurfaceConfig, prepare_surface};
//! use bevy_point_springs::core::cloud::shapes::fibonacci_sphere;
//! use bevy_point_springs::core::simplify::SimplifyConfig;
//!
//! let config = SurfaceConfig {
//!     simplify: SimplifyConfig::target(200),
//!     ..SurfaceConfig::default()
//! };
//! let mut stages = Vec::new();
//! let mut surface = prepare_surface(fibonacci_sphere(2000, 1.0), &config, &mut |p| {
//!     stages.push(p.stage);
//!     ControlFlow::Continue(())
//! })
//! .unwrap();
//! assert_eq!(surface.solver.len(), 200);
//! surface.solver.step(1.0 / 60.0).unwrap(); // falls under gravity
//! assert!(surface.dense.follow(&surface.solver.points).unwrap()); // moved: transferred
//! assert!(!surface.dense.follow(&surface.solver.points).unwrap()); // same state: skipped
//! ```

mod bake;
mod dense;
pub mod prepared;

pub use bake::{BakeJob, BakeParts, Baked, bake};
pub use dense::{DenseCloud, DenseJob, DenseRest, DenseState, ExportError, FrameParts};

use std::ops::ControlFlow;

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::core::PointCloud;
use crate::core::cloud::{Aabb, CloudError};
use crate::core::network::{
    DenseSupport, NetworkConfig, NetworkError, SpringNetwork, build_network_over, dense_areas_after,
};
use crate::core::normals::pca_normals_of;
use crate::core::normals::{DEFAULT_NORMAL_K, NormalSource, NormalsError, ensure_normals};
use crate::core::simplify::{SimplifyConfig, SimplifyError, pinned_edge, simplify_keeping};
use crate::core::solver::{
    PointState, Pressure, Solver, SolverConfig, SolverError, SpringMaterial,
};
use crate::core::transfer::resample::{ResampleConfig, ResampleError, ResampleReport, Resampler};
use crate::core::transfer::{
    FrameInput, NormalUpdate, Pins, Transfer, TransferConfig, TransferError,
};

/// Where the normals of the dense cloud come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum NormalsSpec {
    /// The cloud's own normals, estimated (PCA over `k` neighbours) when it has none.
    FileOrEstimate(usize),
    /// Always estimated, PCA over `k` neighbours.
    Estimate(usize),
}

impl Default for NormalsSpec {
    fn default() -> Self {
        Self::FileOrEstimate(DEFAULT_NORMAL_K)
    }
}

/// Everything about a deformable surface but its cloud: how to prepare it and how it
/// behaves. Scene files hold the same settings (see [`crate::core::scene`]).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SurfaceConfig {
    /// Where the dense normals come from.
    pub normals: NormalsSpec,
    /// §3: how many simulation points, and whether a noisy cloud is decided on local fits.
    pub simplify: SimplifyConfig,
    /// Density, spring stiffness and damping.
    pub material: SpringMaterial,
    /// Integrator, gravity, drag, sub-steps.
    pub solver: SolverConfig,
    /// §5: how the dense points follow.
    pub transfer: TransferConfig,
    /// Resampling where the surface stretches (none by default).
    pub resample: Option<ResampleConfig>,
    /// Gas pressure stiffness κ (force per unit area) inside a closed surface, so that it
    /// springs back from a dent like a ball (none by default; see [`Pressure`]).
    pub pressure: Option<f32>,
}

impl SurfaceConfig {
    /// Checks the settings that no later stage checks before it starts work.
    pub fn validate(&self) -> Result<(), PrepareError> {
        let invalid = |what: &str| Err(PrepareError::Invalid(what.to_owned()));
        match self.normals {
            NormalsSpec::FileOrEstimate(k) | NormalsSpec::Estimate(k) if k < 3 => {
                return invalid("normals need k of at least 3");
            }
            _ => {}
        }
        if let NormalUpdate::Pca(k) = self.transfer.normals
            && k < 3
        {
            return invalid("PCA normals need k of at least 3");
        }
        if let Some(Err(e)) = self.resample.map(|r| r.validate()) {
            return Err(PrepareError::Invalid(format!("resample: {e}")));
        }
        if let Err(e) = self.solver.validate() {
            return Err(PrepareError::Invalid(format!("solver: {e}")));
        }
        if self.pressure.is_some_and(|k| !(k.is_finite() && k >= 0.0)) {
            return invalid("pressure must be finite and not negative");
        }
        self.material.check().map_err(PrepareError::Invalid)?;
        Ok(())
    }
}

/// A stage of [`prepare_surface`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Stage {
    /// Estimating (or normalising) the dense normals.
    Normals,
    /// §3: choosing the simulation points.
    Simplify,
    /// §4: springs and masses.
    Network,
    /// The solver and the §5 transfer coefficients.
    Transfer,
}

impl Stage {
    /// A short name for displays.
    pub fn name(self) -> &'static str {
        match self {
            Self::Normals => "normals",
            Self::Simplify => "simplify",
            Self::Network => "network",
            Self::Transfer => "transfer",
        }
    }
}

/// Where a preparation stands.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress {
    /// The stage under way.
    pub stage: Stage,
    /// How far the whole preparation is, from 0 to 1 (stages weighted by their usual
    /// share of the time).
    pub fraction: f32,
}

/// Share of the preparation's time each stage starts at. Measured once (release, this
/// project's 2-core machine): §3 took from 0–5 % to 88–96 % of the time on the
/// 3203-point sphere (simplified to 338) and on a 10⁵-point one (to 2000), the 5 % being
/// normal estimation for a cloud without normals.
fn stage_start(stage: Stage) -> f32 {
    match stage {
        Stage::Normals => 0.0,
        Stage::Simplify => 0.05,
        Stage::Network => 0.9,
        Stage::Transfer => 0.93,
    }
}

/// Why a surface could not be prepared.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PrepareError {
    /// A setting out of range.
    #[error("invalid surface settings: {0}")]
    Invalid(String),
    /// The cloud is not valid.
    #[error(transparent)]
    Cloud(#[from] CloudError),
    /// Normals could not be estimated.
    #[error(transparent)]
    Normals(#[from] NormalsError),
    /// Simplification failed.
    #[error(transparent)]
    Simplify(#[from] SimplifyError),
    /// The network could not be built.
    #[error(transparent)]
    Network(#[from] NetworkError),
    /// The solver refused.
    #[error(transparent)]
    Solver(#[from] SolverError),
    /// The transfer could not be built.
    #[error(transparent)]
    Transfer(#[from] TransferError),
    /// The cloud lies so far from the origin, for its size, that `f32` coordinates cannot
    /// resolve its detail (a georeferenced scan, say): see [`check_precision`].
    #[error(
        "the cloud's coordinates reach {magnitude:.4e}, where f32 resolves only {resolution:.2e}, \
         more than 1/{} of its point spacing (about {spacing:.2e}); translate it towards the \
         origin",
        1.0 / PRECISION_FRACTION
    )]
    Precision {
        /// The largest absolute coordinate.
        magnitude: f32,
        /// The step between neighbouring `f32` values there.
        resolution: f32,
        /// The spacing estimate: the bounding box's diagonal over √n.
        spacing: f32,
    },
    /// The progress callback asked to stop.
    #[error("preparation was cancelled")]
    Cancelled,
}

/// The largest step between neighbouring coordinates, as a fraction of the point spacing,
/// that [`check_precision`] accepts: 1/32 keeps the rounding of every position and of every
/// displacement below 3 % of the spacing.
pub const PRECISION_FRACTION: f32 = 1.0 / 32.0;

/// Refuses a cloud whose coordinates are too large for its size to be resolved in `f32`:
/// where the step between neighbouring `f32` values at its largest coordinate exceeds
/// [`PRECISION_FRACTION`] of its point spacing (estimated as its bounding box's diagonal
/// over √n, exact within a factor of two on surfaces). A unit sphere of 800 points is
/// refused from about 3·10^4 away from the origin; one of radius 10^6 centred on it is
/// accepted.
pub fn check_precision(cloud: &PointCloud) -> Result<(), PrepareError> {
    let Some(Aabb { min: lo, max: hi }) = cloud.bounds() else {
        return Ok(());
    };
    let magnitude = lo.abs().max(hi.abs()).max_element();
    let spacing = (hi - lo).length() / (cloud.len() as f32).sqrt();
    // The gap to the next f32 above the largest coordinate (finite: PointCloud checks).
    let resolution = f32::from_bits(magnitude.to_bits().saturating_add(1)) - magnitude;
    // A cloud of one point, or of identical ones, has no spacing: later stages name that.
    if spacing > 0.0 && resolution > PRECISION_FRACTION * spacing {
        return Err(PrepareError::Precision {
            magnitude,
            resolution,
            spacing,
        });
    }
    Ok(())
}

/// A surface ready to simulate: its network at rest, the solver over it and the dense
/// cloud that follows it.
#[derive(Debug, Clone)]
pub struct PreparedSurface {
    /// The settings it was prepared with.
    pub config: SurfaceConfig,
    /// Where the dense normals came from.
    pub normal_source: NormalSource,
    /// The simulation points' springs and masses at rest.
    pub network: SpringNetwork,
    /// The dynamic state (pins and anchors none yet).
    pub solver: Solver,
    /// The dense surface and its transfer.
    pub dense: DenseCloud,
}

/// Prepares `cloud` as `config` says, calling `progress` along the way (about a hundred
/// times in simplification, at each stage's start otherwise); when `progress` answers
/// [`ControlFlow::Break`] the preparation stops with [`PrepareError::Cancelled`].
pub fn prepare_surface(
    cloud: PointCloud,
    config: &SurfaceConfig,
    progress: &mut dyn FnMut(Progress) -> ControlFlow<()>,
) -> Result<PreparedSurface, PrepareError> {
    prepare_surface_holding(cloud, config, &|_| false, progress)
}

/// [`prepare_surface`] for a surface whose dense points at the rest positions `held` picks
/// will be pinned: §3 keeps points along the edge of the held region ([`pinned_edge`]), so
/// that the simulation points hold the surface where the dense points are held. Pinning
/// them is the caller's (a scene's pins:
/// [`Scene::prepare_cloud`](crate::core::scene::Scene::prepare_cloud)).
pub fn prepare_surface_holding(
    mut cloud: PointCloud,
    config: &SurfaceConfig,
    held: &dyn Fn(Vec3) -> bool,
    progress: &mut dyn FnMut(Progress) -> ControlFlow<()>,
) -> Result<PreparedSurface, PrepareError> {
    config.validate()?;
    check_precision(&cloud)?;
    let mut report = |stage: Stage, within: f32| {
        let (start, end) = (stage_start(stage), next_start(stage));
        let fraction = start + (end - start) * within.clamp(0.0, 1.0);
        match progress(Progress { stage, fraction }) {
            ControlFlow::Continue(()) => Ok(()),
            ControlFlow::Break(()) => Err(PrepareError::Cancelled),
        }
    };

    report(Stage::Normals, 0.0)?;
    let normal_source = match config.normals {
        NormalsSpec::FileOrEstimate(k) => ensure_normals(&mut cloud, k)?,
        NormalsSpec::Estimate(k) => {
            let faces = cloud.faces().to_vec();
            let (positions, _) = cloud.into_parts();
            cloud = PointCloud::new(positions, None)?.with_faces(faces)?;
            ensure_normals(&mut cloud, k)?
        }
    };
    let (positions, normals) = (cloud.positions(), cloud.normals().unwrap_or_default());

    report(Stage::Simplify, 0.0)?;
    let n = positions.len();
    let floor = config.simplify.target.unwrap_or(0).min(n);
    let mut cancelled = false;
    let held: Vec<bool> = positions.iter().map(|&p| held(p)).collect();
    let keep = pinned_edge(positions, &held, &config.simplify);
    let kept = simplify_keeping(positions, normals, &config.simplify, &keep, &mut |p| {
        let within = p.removed as f32 / n.saturating_sub(floor).max(1) as f32;
        match report(Stage::Simplify, within) {
            Ok(()) => ControlFlow::Continue(()),
            Err(_) => {
                cancelled = true;
                ControlFlow::Break(())
            }
        }
    });
    let kept = match kept {
        Err(SimplifyError::Cancelled) if cancelled => return Err(PrepareError::Cancelled),
        other => other?,
    };
    let (sim_p, sim_n) = kept.gather(positions, normals);

    report(Stage::Network, 0.0)?;
    let mut network = build_network_over(
        &sim_p,
        &sim_n,
        &NetworkConfig {
            k: config.simplify.k,
            density: config.material.density,
        },
        Some(
            &DenseSupport::new(
                positions,
                normals,
                kept.noise_level,
                kept.projected.is_some(),
            )
            .with_triangles(cloud.faces()),
        ),
    )?;
    let areas = dense_areas_after(&kept, positions, normals, cloud.faces(), config.simplify.k)?;
    network.share_dense_area(positions, normals, &areas, config.material.density)?;

    report(Stage::Transfer, 0.0)?;
    let transfer = Transfer::new(positions, normals, &network.positions, config.transfer)?;
    let prepared = PreparedSurface::from_parts(*config, normal_source, network, transfer)?;
    report(Stage::Transfer, 1.0)?;
    Ok(prepared)
}

impl PreparedSurface {
    /// The surface from its prepared parts (the pipeline's last step, and what a
    /// [prepared file](prepared) holds): the solver over `network` with `config`'s material
    /// and settings (gas inside where `config` asks), and the dense cloud following it by
    /// `transfer`.
    pub fn from_parts(
        config: SurfaceConfig,
        normal_source: NormalSource,
        network: SpringNetwork,
        transfer: Transfer,
    ) -> Result<Self, PrepareError> {
        if transfer.simulation_rest() != network.positions.as_slice() {
            return Err(PrepareError::Invalid(
                "the transfer follows other simulation points than the network's".into(),
            ));
        }
        let mut solver = Solver::from_network(&network, &config.material, config.solver)?;
        if let Some(stiffness) = config.pressure {
            let open = network.report.boundary_points;
            if open > 0 {
                return Err(PrepareError::Invalid(format!(
                    "pressure needs a closed surface, but the network has {open} boundary points"
                )));
            }
            solver.pressure = Some(Pressure::new(
                network.triangles.clone(),
                &solver.points,
                stiffness,
            )?);
        }
        let dense = DenseCloud::new(transfer, config.resample);
        Ok(Self {
            config,
            normal_source,
            network,
            solver,
            dense,
        })
    }
}

/// Where the stage after `stage` starts (1 after the last).
fn next_start(stage: Stage) -> f32 {
    match stage {
        Stage::Normals => stage_start(Stage::Simplify),
        Stage::Simplify => stage_start(Stage::Network),
        Stage::Network => stage_start(Stage::Transfer),
        Stage::Transfer => 1.0,
    }
}
