//! One preparation pipeline for every caller (the command-line tool, the benches and the
//! Bevy plugin): a dense cloud and a [`SurfaceConfig`] in, a [`PreparedSurface`] out —
//! normals, §3 simplification, §4 network and masses, the solver, the §5 transfer
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

use std::ops::ControlFlow;

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::core::PointCloud;
use crate::core::cloud::CloudError;
use crate::core::network::{
    DenseSupport, NetworkConfig, NetworkError, SpringNetwork, build_network_over,
};
use crate::core::normals::pca_normals_of;
use crate::core::normals::{DEFAULT_NORMAL_K, NormalSource, NormalsError, ensure_normals};
use crate::core::simplify::{SimplifyConfig, SimplifyError, simplify_with_progress};
use crate::core::solver::{
    PointState, Pressure, Solver, SolverConfig, SolverError, SpringMaterial,
};
use crate::core::transfer::resample::{ResampleConfig, ResampleError, ResampleReport, Resampler};
use crate::core::transfer::{FrameInput, NormalUpdate, Transfer, TransferConfig, TransferError};

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
        let m = &self.material;
        if !(m.density > 0.0 && m.density.is_finite()) {
            return invalid("material.density must be positive and finite");
        }
        for (name, v) in [
            ("stretch_stiffness", m.stretch_stiffness),
            ("bend_stiffness", m.bend_stiffness),
            ("stretch_damping", m.stretch_damping),
            ("bend_damping", m.bend_damping),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(PrepareError::Invalid(format!(
                    "material.{name} must be finite and not negative, got {v}"
                )));
            }
        }
        if let Err(e) = m.plasticity().validate() {
            return Err(PrepareError::Invalid(format!("material: {e}")));
        }
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
    /// The progress callback asked to stop.
    #[error("preparation was cancelled")]
    Cancelled,
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
    mut cloud: PointCloud,
    config: &SurfaceConfig,
    progress: &mut dyn FnMut(Progress) -> ControlFlow<()>,
) -> Result<PreparedSurface, PrepareError> {
    config.validate()?;
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
    let kept = simplify_with_progress(positions, normals, &config.simplify, &mut |p| {
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
    let network = build_network_over(
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

    report(Stage::Transfer, 0.0)?;
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
    let transfer = Transfer::new(positions, normals, &network.positions, config.transfer)?;
    let dense = DenseCloud::new(transfer, config.resample);
    report(Stage::Transfer, 1.0)?;
    Ok(PreparedSurface {
        config: *config,
        normal_source,
        network,
        solver,
        dense,
    })
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

/// The dense surface of a running simulation: its rest points and transfer coefficients
/// (inside the [`Transfer`]), its deformed positions and normals, and the resampling that
/// keeps it dense where it stretches.
#[derive(Debug, Clone)]
pub struct DenseCloud {
    transfer: Transfer,
    resample: Option<ResampleConfig>,
    resampler: Option<Resampler>,
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    input: FrameInput,
    /// Whether `positions` and `normals` follow the positions in `input`.
    fresh: bool,
    /// Bumped each time the positions or normals change.
    revision: u64,
    /// Points inserted by resampling so far.
    inserted: usize,
    /// The step count resampling last looked at (a paused surface is not checked again).
    maintained_at: u64,
}

/// The pieces of a frame, for callers that split its rows over threads of their own
/// (see [`DenseCloud::frame_parts`]).
#[derive(Debug)]
pub struct FrameParts<'a> {
    /// The coefficients.
    pub transfer: &'a Transfer,
    /// The simulation state the frame follows.
    pub input: &'a FrameInput,
    /// Where the deformed positions go.
    pub positions: &'a mut [Vec3],
    /// Where the deformed normals go.
    pub normals: &'a mut [Vec3],
}

impl DenseCloud {
    /// The dense surface at rest, following the transfer's simulation points;
    /// `resample` says whether and how it resamples.
    pub fn new(transfer: Transfer, resample: Option<ResampleConfig>) -> Self {
        Self {
            positions: transfer.rest_positions().to_vec(),
            normals: transfer.rest_normals().to_vec(),
            resampler: resample.map(|_| Resampler::new(&transfer)),
            transfer,
            resample,
            input: FrameInput::default(),
            fresh: false,
            revision: 1,
            inserted: 0,
            maintained_at: 0,
        }
    }

    /// Number of dense points (resampled ones included).
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// The transfer coefficients (and the rest points and normals).
    pub fn transfer(&self) -> &Transfer {
        &self.transfer
    }

    /// The deformed positions as of the last frame (the rest positions before the first).
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// The deformed unit normals as of the last frame.
    pub fn normals(&self) -> &[Vec3] {
        &self.normals
    }

    /// Changes each time the positions or normals do (for uploads).
    pub fn revision(&self) -> u64 {
        self.revision
    }

    /// Points resampling has inserted so far.
    pub fn inserted(&self) -> usize {
        self.inserted
    }

    /// The largest distance of a dense point from its rest position.
    pub fn max_displacement(&self) -> f32 {
        self.positions
            .iter()
            .zip(self.transfer.rest_positions())
            .map(|(p, r)| p.distance(*r))
            .fold(0.0, f32::max)
    }

    /// The deformed surface as a cloud.
    pub fn to_cloud(&self) -> Result<PointCloud, CloudError> {
        PointCloud::new(self.positions.clone(), Some(self.normals.clone()))
    }

    /// Resamples when it is due: resampling is on and `steps` (the simulation steps taken
    /// so far) is a positive multiple of its interval not looked at before. Inserted points follow the
    /// simulation from the next frame on.
    pub fn maintain(
        &mut self,
        sim: &PointState,
        steps: u64,
    ) -> Result<ResampleReport, ResampleError> {
        let (Some(config), Some(resampler)) = (self.resample, self.resampler.as_mut()) else {
            return Ok(ResampleReport::default());
        };
        if steps == self.maintained_at || !steps.is_multiple_of(u64::from(config.interval.max(1))) {
            return Ok(ResampleReport::default());
        }
        self.maintained_at = steps;
        let rest = self.transfer.simulation_rest();
        let displacements: Vec<Vec3> = sim
            .iter_positions()
            .zip(rest)
            .map(|(p, r)| p - *r)
            .collect();
        let report = resampler.resample(&mut self.transfer, &displacements, &config)?;
        if report.inserted > 0 {
            self.inserted += report.inserted;
            let added = &self.transfer.rest_positions()[self.positions.len()..];
            self.positions.extend_from_slice(added);
            let added = &self.transfer.rest_normals()[self.normals.len()..];
            self.normals.extend_from_slice(added);
            self.fresh = false;
        }
        Ok(report)
    }

    /// Loads the simulation state `sim` for the next frame. Returns false, and the frame
    /// need not run, when the dense surface already follows exactly this state.
    pub fn begin_frame(&mut self, sim: &PointState) -> Result<bool, TransferError> {
        if self.fresh && same_positions(&self.input, sim) {
            return Ok(false);
        }
        self.input
            .set_positions(&self.transfer, sim.position_arrays())?;
        self.fresh = false;
        Ok(true)
    }

    /// The pieces of the frame [`Self::begin_frame`] loaded, to compute its rows in chunks
    /// ([`Transfer::frame_rows`]); call [`Self::finish_frame`] afterwards.
    pub fn frame_parts(&mut self) -> FrameParts<'_> {
        FrameParts {
            transfer: &self.transfer,
            input: &self.input,
            positions: &mut self.positions,
            normals: &mut self.normals,
        }
    }

    /// Completes a frame whose rows were computed through [`Self::frame_parts`]: PCA
    /// normals where the settings ask for them, and a new revision.
    pub fn finish_frame(&mut self) {
        if let NormalUpdate::Pca(k) = self.transfer.config().normals {
            self.normals = pca_normals_of(&self.positions, &self.normals, k);
        }
        self.fresh = true;
        self.revision += 1;
    }

    /// Carries the simulation state `sim` to every dense point (the whole frame, on
    /// rayon's pool when it is large). Returns whether anything was computed: false when
    /// the dense surface already follows this state.
    pub fn follow(&mut self, sim: &PointState) -> Result<bool, TransferError> {
        if !self.begin_frame(sim)? {
            return Ok(false);
        }
        self.transfer
            .apply_frame(&self.input, &mut self.positions, &mut self.normals)?;
        self.finish_frame();
        Ok(true)
    }
}

/// Whether the frame input holds exactly the positions of `sim` (bit for bit).
fn same_positions(input: &FrameInput, sim: &PointState) -> bool {
    let [x, y, z] = sim.position_arrays();
    let current = input.current();
    current.len() == x.len()
        && current.iter().enumerate().all(|(i, c)| {
            c.x.to_bits() == x[i].to_bits()
                && c.y.to_bits() == y[i].to_bits()
                && c.z.to_bits() == z[i].to_bits()
        })
}
