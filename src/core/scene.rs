//! Scene files: a deformation set up and run without code (serde + RON), shared by the
//! command-line tool, the plugin and the examples.
//!
//! A scene names a dense cloud (a file, relative to the scene file), how to get its normals,
//! how to simplify it, the material, gravity, the integrator and its step, the pins (points
//! inside spheres or boxes held in place), the pulls and pokes (anchor springs from the
//! simulation points near a position to a target, active over a range of steps, optionally
//! moving), the number of steps, and how to carry the motion back to the dense points.
//!
//! ```
//! use bevy_point_springs::core::scene::Scene;
//!
//! let scene = Scene::from_ron(r#"(
//!     cloud: "sphere3203.ply",
//!     simplify: (target: Some(338)),
//!     material: (stretch_stiffness: 50.0, bend_stiffness: 10.0, drag: 2.0),
//!     integrator: ImplicitEuler,
//!     dt: 0.016666668,
//!     steps: 180,
//!     pins: [Sphere(centre: (0.0, -1.0, 0.0), radius: 0.3)],
//!     pulls: [(at: (0.0, 1.0, 0.0), radius: Some(0.25), to: (0.0, 0.6, 0.0), stiffness: 400.0)],
//! )"#).unwrap();
//! assert_eq!(scene.steps, 180);
//! assert_eq!(scene.simplify.k, 12); // the default
//! ```
//!
//! [`Scene::prepare`] loads and preprocesses everything (normals, §3 simplification, §4
//! network, §5 transfer coefficients) into a [`SceneRun`]; [`SceneRun::run`] steps it;
//! [`SceneRun::deformed`] transfers the motion to the dense points (and resamples where the
//! scene asks for it):
//!
//! ```
//! use bevy_point_springs::core::scene::Scene;
//! use bevy_point_springs::prelude::*;
//!
//! let (scene, base) = Scene::load("assets/scenes/hat.ron".as_ref()).unwrap();
//! let mut run = scene.prepare(&base).unwrap(); // normals, §3, §4, §5 coefficients
//! run.run(&mut |_step| {}).unwrap(); // 300 implicit Euler steps
//! let deformed = run.deformed().unwrap(); // §5 transfer, normals, resampling
//! assert!(deformed.resampled.inserted > 0); // the stretched crown got new points
//! let out = std::env::temp_dir().join("hat.ply");
//! write_ply(&out, &deformed.cloud, PlyEncoding::BinaryLittleEndian).unwrap();
//! ```

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::core::PointCloud;
use crate::core::io::{LoadError, read_cloud};
use crate::core::knn::KnnIndex;
use crate::core::network::{NetworkError, SpringNetwork, build_network};
use crate::core::normals::{DEFAULT_NORMAL_K, NormalsError, ensure_normals};
use crate::core::resample::{
    DEFAULT_MAX_NEW_PER_POINT, DEFAULT_RESAMPLE_FACTOR, DEFAULT_RESAMPLE_PASSES, ResampleConfig,
    ResampleError, ResampleReport, Resampler,
};
use crate::core::simplify::{DEFAULT_SIMPLIFY_K, SimplifyConfig, SimplifyError, simplify};
use crate::core::solver::{
    Anchor, AnchorId, DEFAULT_MAX_SUBSTEPS, DampingModel, Integrator, Solver, SolverConfig,
    SolverError, SpringMaterial, StepReport, SubstepPolicy,
};
use crate::core::transfer::{
    DEFAULT_BANDWIDTH, DEFAULT_TRANSFER_K, Transfer, TransferConfig, TransferError, pca_normals_of,
};

/// Most steps a scene may ask for.
pub const MAX_SCENE_STEPS: usize = 10_000_000;

/// Largest scene file read (scenes are a few hundred bytes).
pub const MAX_SCENE_BYTES: u64 = 1 << 20;

/// Where the normals of the dense cloud come from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum NormalsSpec {
    /// The file's own normals, estimated (PCA over `k` neighbours) when it has none.
    FileOrEstimate(usize),
    /// Always estimated, PCA over `k` neighbours.
    Estimate(usize),
}

impl Default for NormalsSpec {
    fn default() -> Self {
        Self::FileOrEstimate(DEFAULT_NORMAL_K)
    }
}

/// §3 settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimplifySpec {
    /// Stop at this many simulation points.
    pub target: Option<usize>,
    /// Stop when every region is at least this wide.
    pub max_diameter: Option<f32>,
    /// Neighbours per local ring.
    pub k: usize,
}

impl Default for SimplifySpec {
    fn default() -> Self {
        Self {
            target: None,
            max_diameter: None,
            k: DEFAULT_SIMPLIFY_K,
        }
    }
}

/// The surface's material.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MaterialSpec {
    /// Mass per unit area ρ (eq 1).
    pub density: f32,
    /// Stiffness of stretch springs.
    pub stretch_stiffness: f32,
    /// Stiffness of bend springs.
    pub bend_stiffness: f32,
    /// Damping of stretch springs.
    pub stretch_damping: f32,
    /// Damping of bend springs.
    pub bend_damping: f32,
    /// Viscous drag rate μ (1/s).
    pub drag: f32,
    /// How spring damping acts.
    pub damping_model: DampingModel,
}

impl Default for MaterialSpec {
    fn default() -> Self {
        let m = SpringMaterial::default();
        Self {
            density: crate::core::network::DEFAULT_DENSITY,
            stretch_stiffness: m.stretch_stiffness,
            bend_stiffness: m.bend_stiffness,
            stretch_damping: m.stretch_damping,
            bend_damping: m.bend_damping,
            drag: 0.0,
            damping_model: DampingModel::default(),
        }
    }
}

/// A region of space.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Region {
    /// Points within `radius` of `centre`.
    Sphere {
        /// Centre.
        centre: Vec3,
        /// Radius.
        radius: f32,
    },
    /// Points inside the axis-aligned box.
    Box {
        /// Lower corner.
        min: Vec3,
        /// Upper corner.
        max: Vec3,
    },
}

impl Region {
    /// Whether `p` is inside.
    pub fn contains(&self, p: Vec3) -> bool {
        match *self {
            Self::Sphere { centre, radius } => p.distance_squared(centre) <= radius * radius,
            Self::Box { min, max } => p.cmpge(min).all() && p.cmple(max).all(),
        }
    }

    fn valid(&self) -> bool {
        match *self {
            Self::Sphere { centre, radius } => {
                centre.is_finite() && radius.is_finite() && radius > 0.0
            }
            Self::Box { min, max } => min.is_finite() && max.is_finite() && min.cmple(max).all(),
        }
    }
}

/// A pull or poke: anchor springs (eq 5) from the simulation point nearest `at` — or from
/// every simulation point within `radius` of it — towards `to` (each grabbed point keeps
/// its offset from `at`), active from step `start` until step `end`, the target moving in
/// a straight line to `to_end` over that time when given.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pull {
    /// Where to grab (rest state).
    pub at: Vec3,
    /// Grab every simulation point this close to `at` (default: the nearest one only).
    #[serde(default)]
    pub radius: Option<f32>,
    /// Target at the start.
    pub to: Vec3,
    /// Target at the end (default: `to`, a fixed target).
    #[serde(default)]
    pub to_end: Option<Vec3>,
    /// Spring constant k_r per grabbed point.
    pub stiffness: f32,
    /// Damping on the grabbed points' velocities.
    #[serde(default)]
    pub damping: f32,
    /// First step it acts on.
    #[serde(default)]
    pub start: usize,
    /// Step at which it lets go (default: the end of the run).
    #[serde(default)]
    pub end: Option<usize>,
}

/// How the dense surface follows and refreshes its normals.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum NormalUpdate {
    /// From the fitted displacement gradient (exact for affine motion, no search).
    Gradient,
    /// PCA over `k` neighbours of the deformed cloud, the paper's way (slow).
    Pca(usize),
}

/// §5 settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TransferSpec {
    /// Simulation points each dense point follows.
    pub k: usize,
    /// Gaussian bandwidth as a multiple of the farthest neighbour's distance.
    pub bandwidth: f32,
    /// How normals are updated.
    pub normals: NormalUpdate,
}

impl Default for TransferSpec {
    fn default() -> Self {
        Self {
            k: DEFAULT_TRANSFER_K,
            bandwidth: DEFAULT_BANDWIDTH,
            normals: NormalUpdate::Gradient,
        }
    }
}

/// Resampling settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ResampleSpec {
    /// Resample where the spacing grew by more than this factor.
    pub factor: f32,
    /// Passes at most.
    pub max_passes: usize,
    /// New points at most, per dense point.
    pub max_new_per_point: f32,
}

impl Default for ResampleSpec {
    fn default() -> Self {
        Self {
            factor: DEFAULT_RESAMPLE_FACTOR,
            max_passes: DEFAULT_RESAMPLE_PASSES,
            max_new_per_point: DEFAULT_MAX_NEW_PER_POINT,
        }
    }
}

fn no_gravity() -> Vec3 {
    Vec3::ZERO
}

fn default_max_substeps() -> u32 {
    DEFAULT_MAX_SUBSTEPS
}

/// A scene. See the module docs for the file format.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// The dense cloud file, relative to the scene file (.ply .xyz .pwn .off .obj).
    pub cloud: PathBuf,
    /// Where its normals come from.
    #[serde(default)]
    pub normals: NormalsSpec,
    /// §3 settings; at least one stopping rule is needed.
    #[serde(default)]
    pub simplify: SimplifySpec,
    /// Material.
    #[serde(default)]
    pub material: MaterialSpec,
    /// Gravity (default none: modelling scenes usually float).
    #[serde(default = "no_gravity")]
    pub gravity: Vec3,
    /// Integrator.
    #[serde(default)]
    pub integrator: Integrator,
    /// Step length, s.
    pub dt: f32,
    /// Sub-steps an explicit integrator may take per step.
    #[serde(default = "default_max_substeps")]
    pub max_substeps: u32,
    /// Steps to run.
    pub steps: usize,
    /// Regions whose simulation points are held in place.
    #[serde(default)]
    pub pins: Vec<Region>,
    /// Pulls and pokes.
    #[serde(default)]
    pub pulls: Vec<Pull>,
    /// §5 settings.
    #[serde(default)]
    pub transfer: TransferSpec,
    /// Resampling after the run (none by default).
    #[serde(default)]
    pub resample: Option<ResampleSpec>,
}

/// Why a scene could not be loaded, prepared or run.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file could not be read.
    #[error("{path}: {message}")]
    Read {
        /// The scene file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// The scene file is not a valid scene.
    #[error("{path}: {message}")]
    Parse {
        /// The scene file (or "<string>").
        path: PathBuf,
        /// RON's message, with line and column.
        message: String,
    },
    /// A setting out of range.
    #[error("invalid scene: {0}")]
    Invalid(String),
    /// A pin region holds no simulation point.
    #[error("pin {0} holds no simulation point")]
    EmptyPin(usize),
    /// The cloud could not be read.
    #[error(transparent)]
    Cloud(#[from] LoadError),
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
    /// The transfer failed.
    #[error(transparent)]
    Transfer(#[from] TransferError),
    /// Resampling failed.
    #[error(transparent)]
    Resample(#[from] ResampleError),
}

fn invalid(what: impl Into<String>) -> SceneError {
    SceneError::Invalid(what.into())
}

fn finite_non_negative(v: f32) -> bool {
    v.is_finite() && v >= 0.0
}

impl Scene {
    /// Parses a scene from RON text.
    pub fn from_ron(text: &str) -> Result<Self, SceneError> {
        Self::parse(text, Path::new("<string>"))
    }

    fn parse(text: &str, path: &Path) -> Result<Self, SceneError> {
        let scene: Scene = ron::from_str(text).map_err(|e| SceneError::Parse {
            path: path.to_owned(),
            message: e.to_string(),
        })?;
        scene.validate()?;
        Ok(scene)
    }

    /// Reads and checks a scene file; returns it with the folder its cloud path is relative
    /// to.
    pub fn load(path: &Path) -> Result<(Self, PathBuf), SceneError> {
        let read = |message: String| SceneError::Read {
            path: path.to_owned(),
            message,
        };
        let size = std::fs::metadata(path)
            .map_err(|e| read(e.to_string()))?
            .len();
        if size > MAX_SCENE_BYTES {
            return Err(read(format!(
                "{size} bytes is too large for a scene (at most {MAX_SCENE_BYTES})"
            )));
        }
        let text = std::fs::read_to_string(path).map_err(|e| read(e.to_string()))?;
        let scene = Self::parse(&text, path)?;
        let base = path.parent().map(Path::to_owned).unwrap_or_default();
        Ok((scene, base))
    }

    /// Checks every setting.
    pub fn validate(&self) -> Result<(), SceneError> {
        if !(self.dt > 0.0 && self.dt.is_finite()) {
            return Err(invalid(format!(
                "dt must be positive and finite, got {}",
                self.dt
            )));
        }
        if self.steps == 0 || self.steps > MAX_SCENE_STEPS {
            return Err(invalid(format!(
                "steps must be between 1 and {MAX_SCENE_STEPS}, got {}",
                self.steps
            )));
        }
        if self.max_substeps == 0 {
            return Err(invalid("max_substeps must be at least 1"));
        }
        if self.simplify.target.is_none() && self.simplify.max_diameter.is_none() {
            return Err(invalid(
                "simplify needs a target or a max_diameter (or both)",
            ));
        }
        if !self.gravity.is_finite() {
            return Err(invalid("gravity must be finite"));
        }
        let m = &self.material;
        if !(m.density > 0.0 && m.density.is_finite()) {
            return Err(invalid("the density must be positive and finite"));
        }
        for (name, v) in [
            ("stretch_stiffness", m.stretch_stiffness),
            ("bend_stiffness", m.bend_stiffness),
            ("stretch_damping", m.stretch_damping),
            ("bend_damping", m.bend_damping),
            ("drag", m.drag),
        ] {
            if !finite_non_negative(v) {
                return Err(invalid(format!(
                    "material.{name} must be finite and not negative, got {v}"
                )));
            }
        }
        for (i, pin) in self.pins.iter().enumerate() {
            if !pin.valid() {
                return Err(invalid(format!(
                    "pin {i}: a sphere needs a positive radius, a box min <= max, all finite"
                )));
            }
        }
        for (i, pull) in self.pulls.iter().enumerate() {
            let end = pull.end.unwrap_or(self.steps);
            let ok = pull.at.is_finite()
                && pull.to.is_finite()
                && pull.to_end.is_none_or(|t| t.is_finite())
                && pull.radius.is_none_or(|r| r > 0.0 && r.is_finite())
                && finite_non_negative(pull.stiffness)
                && finite_non_negative(pull.damping);
            if !ok {
                return Err(invalid(format!(
                    "pull {i}: positions must be finite, radius positive, stiffness and damping not negative"
                )));
            }
            if pull.start >= end || end > self.steps {
                return Err(invalid(format!(
                    "pull {i}: needs start < end <= steps, got {}..{end} of {}",
                    pull.start, self.steps
                )));
            }
        }
        match self.normals {
            NormalsSpec::FileOrEstimate(k) | NormalsSpec::Estimate(k) if k < 3 => {
                return Err(invalid("normals need k of at least 3"));
            }
            _ => {}
        }
        if let NormalUpdate::Pca(k) = self.transfer.normals
            && k < 3
        {
            return Err(invalid("PCA normals need k of at least 3"));
        }
        Ok(())
    }

    /// Loads the cloud (relative to `base`), gives it normals, simplifies it, builds the
    /// network, the solver (pins applied) and the transfer coefficients.
    pub fn prepare(&self, base: &Path) -> Result<SceneRun, SceneError> {
        self.validate()?;
        let start = Instant::now();
        let mut cloud = read_cloud(&base.join(&self.cloud), None)?;
        match self.normals {
            NormalsSpec::FileOrEstimate(k) => {
                ensure_normals(&mut cloud, k)?;
            }
            NormalsSpec::Estimate(k) => {
                let (positions, _) = cloud.into_parts();
                cloud = PointCloud::new(positions, None).map_err(|e| invalid(e.to_string()))?;
                ensure_normals(&mut cloud, k)?;
            }
        }
        let (positions, normals) = (cloud.positions(), cloud.normals().unwrap_or_default());
        let config = SimplifyConfig {
            k: self.simplify.k,
            target: self.simplify.target,
            max_diameter: self.simplify.max_diameter,
        };
        let kept = simplify(positions, normals, &config)?;
        let (sim_p, sim_n) = kept.gather(positions, normals);
        let network = build_network(
            &sim_p,
            &sim_n,
            &crate::core::network::NetworkConfig {
                k: self.simplify.k,
                density: self.material.density,
            },
        )?;
        let m = &self.material;
        let material = SpringMaterial {
            stretch_stiffness: m.stretch_stiffness,
            bend_stiffness: m.bend_stiffness,
            stretch_damping: m.stretch_damping,
            bend_damping: m.bend_damping,
        };
        let solver_config = SolverConfig {
            integrator: self.integrator,
            damping_model: m.damping_model,
            gravity: self.gravity,
            drag: m.drag,
            substeps: SubstepPolicy::Auto {
                max_substeps: self.max_substeps,
            },
            ..SolverConfig::default()
        };
        let mut solver = Solver::from_network(&network, &material, solver_config)?;
        let mut pinned = 0;
        for (i, pin) in self.pins.iter().enumerate() {
            let inside: Vec<usize> = (0..network.len())
                .filter(|&j| pin.contains(network.positions[j]))
                .collect();
            if inside.is_empty() {
                return Err(SceneError::EmptyPin(i));
            }
            for j in inside {
                if !solver.is_fixed(j) {
                    pinned += 1;
                }
                solver.set_fixed(j, true)?;
            }
        }
        let index = KnnIndex::build(&network.positions);
        let pulls = self
            .pulls
            .iter()
            .map(|pull| {
                let grabbed: Vec<u32> = match pull.radius {
                    Some(r) => (0..network.len() as u32)
                        .filter(|&j| network.positions[j as usize].distance(pull.at) <= r)
                        .collect(),
                    None => Vec::new(),
                };
                // The nearest point at least, however small the radius.
                let grabbed = if grabbed.is_empty() {
                    index
                        .nearest(pull.at, 1)
                        .iter()
                        .map(|nb| nb.index)
                        .collect()
                } else {
                    grabbed
                };
                ActivePull {
                    pull: *pull,
                    end: pull.end.unwrap_or(self.steps),
                    grabbed,
                    anchors: Vec::new(),
                }
            })
            .collect();
        let transfer = Transfer::new(
            positions,
            normals,
            &network.positions,
            TransferConfig {
                k: self.transfer.k,
                bandwidth: self.transfer.bandwidth,
            },
        )?;
        Ok(SceneRun {
            scene: self.clone(),
            dense: cloud,
            network,
            solver,
            transfer,
            pulls,
            pinned,
            step: 0,
            prepare_seconds: start.elapsed().as_secs_f64(),
            simulate_seconds: 0.0,
            substeps: 0,
            guard_trips: 0,
            limited_steps: 0,
            cg_iterations: 0,
            resampler: None,
        })
    }
}

/// A pull's state during a run.
#[derive(Debug, Clone)]
struct ActivePull {
    pull: Pull,
    end: usize,
    grabbed: Vec<u32>,
    anchors: Vec<AnchorId>,
}

/// A prepared scene: the dense cloud, the network, the solver and the transfer.
#[derive(Debug, Clone)]
pub struct SceneRun {
    /// The scene.
    pub scene: Scene,
    /// The dense cloud at rest, with normals.
    pub dense: PointCloud,
    /// The simulation points' network at rest.
    pub network: SpringNetwork,
    /// The solver.
    pub solver: Solver,
    /// The transfer coefficients.
    pub transfer: Transfer,
    pulls: Vec<ActivePull>,
    /// Simulation points held by pins.
    pub pinned: usize,
    /// Steps taken.
    pub step: usize,
    /// Seconds spent preparing (loading, normals, §3, §4, §5 coefficients).
    pub prepare_seconds: f64,
    /// Seconds spent in the solver.
    pub simulate_seconds: f64,
    /// Sub-steps taken.
    pub substeps: u64,
    /// Steps the guard had to restore.
    pub guard_trips: u64,
    /// Steps that hit the sub-step cap.
    pub limited_steps: u64,
    /// Conjugate-gradient iterations.
    pub cg_iterations: u64,
    /// The rest spacing the resampling keeps track of (from the first resampling on).
    resampler: Option<Resampler>,
}

/// The deformed dense surface.
#[derive(Debug, Clone)]
pub struct Deformed {
    /// Positions and normals.
    pub cloud: PointCloud,
    /// Largest displacement of a dense point.
    pub max_displacement: f32,
    /// What resampling did.
    pub resampled: ResampleReport,
    /// Seconds for the transfer and the normals (once).
    pub transfer_seconds: f64,
    /// Seconds for resampling.
    pub resample_seconds: f64,
}

impl SceneRun {
    /// Grabbed simulation points per pull.
    pub fn pulled_points(&self) -> Vec<usize> {
        self.pulls.iter().map(|p| p.grabbed.len()).collect()
    }

    /// Whether all steps are done.
    pub fn finished(&self) -> bool {
        self.step >= self.scene.steps
    }

    /// Takes one step: pulls start, move and let go on schedule.
    pub fn step(&mut self) -> Result<StepReport, SceneError> {
        let step = self.step;
        for active in &mut self.pulls {
            let p = active.pull;
            if step == p.start {
                active.anchors = active
                    .grabbed
                    .iter()
                    .map(|&j| {
                        let offset = self.network.positions[j as usize] - p.at;
                        self.solver.add_anchor(Anchor {
                            point: j,
                            target: p.to + offset,
                            stiffness: p.stiffness,
                            damping: p.damping,
                        })
                    })
                    .collect::<Result<_, _>>()?;
            }
            if step == active.end {
                for id in active.anchors.drain(..) {
                    self.solver.remove_anchor(id);
                }
            }
            if let (Some(to_end), true) = (p.to_end, (p.start..active.end).contains(&step)) {
                let t = (step - p.start) as f32 / (active.end - p.start) as f32;
                let target = p.to.lerp(to_end, t);
                for (&j, &id) in active.grabbed.iter().zip(&active.anchors) {
                    let offset = self.network.positions[j as usize] - p.at;
                    self.solver.set_anchor_target(id, target + offset)?;
                }
            }
        }
        let start = Instant::now();
        let report = self.solver.step(self.scene.dt)?;
        self.simulate_seconds += start.elapsed().as_secs_f64();
        self.substeps += u64::from(report.substeps);
        self.guard_trips += u64::from(report.recovered);
        self.limited_steps += u64::from(report.limited);
        self.cg_iterations += u64::from(report.cg_iterations);
        self.step += 1;
        Ok(report)
    }

    /// Runs the remaining steps, calling `progress` with the step count after each.
    pub fn run(&mut self, progress: &mut dyn FnMut(usize)) -> Result<(), SceneError> {
        while !self.finished() {
            self.step()?;
            progress(self.step);
        }
        Ok(())
    }

    /// Each simulation point's displacement from its rest position.
    pub fn displacements(&self) -> Vec<Vec3> {
        self.solver
            .positions()
            .iter()
            .zip(&self.network.positions)
            .map(|(p, r)| *p - *r)
            .collect()
    }

    /// The deformed dense surface: the transfer of the current displacements, after
    /// resampling when the scene asks for it. Inserted points stay and follow the simulation
    /// from then on; a later call inserts only where the surface has stretched further.
    pub fn deformed(&mut self) -> Result<Deformed, SceneError> {
        let disp = self.displacements();
        let mut resampled = ResampleReport::default();
        let start = Instant::now();
        if let Some(spec) = self.scene.resample {
            let resampler = self
                .resampler
                .get_or_insert_with(|| Resampler::new(&self.transfer));
            resampled = resampler.resample(
                &mut self.transfer,
                &disp,
                &ResampleConfig {
                    factor: spec.factor,
                    max_passes: spec.max_passes,
                    max_new_per_point: spec.max_new_per_point,
                },
            )?;
        }
        let resample_seconds = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let (positions, mut normals) = self.transfer.deform(&disp)?;
        if let NormalUpdate::Pca(k) = self.scene.transfer.normals {
            normals = pca_normals_of(&positions, &normals, k);
        }
        let transfer_seconds = start.elapsed().as_secs_f64();
        let max_displacement = positions
            .iter()
            .zip(self.transfer.rest_positions())
            .map(|(p, r)| p.distance(*r))
            .fold(0.0, f32::max);
        let cloud = PointCloud::new(positions, Some(normals))
            .map_err(|e| invalid(format!("the deformed surface is not valid: {e}")))?;
        Ok(Deformed {
            cloud,
            max_displacement,
            resampled,
            transfer_seconds,
            resample_seconds,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MINIMAL: &str = r#"(cloud: "a.ply", simplify: (target: Some(50)), dt: 0.01, steps: 10)"#;

    #[test]
    fn defaults_fill_the_rest() {
        let s = Scene::from_ron(MINIMAL).unwrap();
        assert_eq!(s.integrator, Integrator::SymplecticEuler);
        assert_eq!(s.gravity, Vec3::ZERO);
        assert_eq!(s.transfer, TransferSpec::default());
        assert!(s.pins.is_empty() && s.pulls.is_empty() && s.resample.is_none());
        // Round trip.
        let text = ron::to_string(&s).unwrap();
        assert_eq!(Scene::from_ron(&text).unwrap(), s);
    }

    #[test]
    fn mistakes_are_named() {
        let cases = [
            (r#"(cloud: "a.ply", dt: 0.01, steps: 10)"#, "simplify needs"),
            (
                r#"(cloud: "a.ply", simplify: (target: Some(5)), dt: 0.0, steps: 10)"#,
                "dt must",
            ),
            (
                r#"(cloud: "a.ply", simplify: (target: Some(5)), dt: 0.1, steps: 0)"#,
                "steps must",
            ),
            (
                r#"(cloud: "a.ply", simplify: (target: Some(5)), dt: 0.1, steps: 5, colour: 3)"#,
                "colour",
            ),
            (
                r#"(cloud: "a.ply", simplify: (targt: Some(5)), dt: 0.1, steps: 5)"#,
                "targt",
            ),
            (
                r#"(cloud: "a.ply", simplify: (target: Some(5)), dt: 0.1, steps: 5,
                    pulls: [(at: (0,0,0), to: (1,0,0), stiffness: 1.0, start: 3, end: Some(9))])"#,
                "pull 0",
            ),
            (
                r#"(cloud: "a.ply", simplify: (target: Some(5)), dt: 0.1, steps: 5,
                    pins: [Sphere(centre: (0,0,0), radius: -1.0)])"#,
                "pin 0",
            ),
            (
                r#"(cloud: "a.ply", simplify: (target: Some(5)), dt: 0.1, steps: 5,
                    material: (drag: -2.0))"#,
                "material.drag",
            ),
        ];
        for (text, needle) in cases {
            let err = Scene::from_ron(text).unwrap_err().to_string();
            assert!(err.contains(needle), "{needle}: {err}");
        }
    }

    #[test]
    fn regions() {
        let s = Region::Sphere {
            centre: Vec3::ZERO,
            radius: 1.0,
        };
        assert!(s.contains(Vec3::X) && !s.contains(Vec3::splat(1.0)));
        let b = Region::Box {
            min: Vec3::ZERO,
            max: Vec3::ONE,
        };
        assert!(b.contains(Vec3::splat(0.5)) && !b.contains(Vec3::new(0.5, 1.5, 0.5)));
    }
}
