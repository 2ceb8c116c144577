//! Scene files: a deformation set up and run without code (serde + RON), shared by the
//! command-line tool, the plugin and the examples.
//!
//! A scene names a dense cloud (a file, relative to the scene file), how to get its normals,
//! how to simplify it, the material, gravity, the integrator and its step, the pins (points
//! inside spheres or boxes held in place), the pulls and pokes (anchor springs from the
//! simulation points near a position to a target, active over a range of steps, optionally
//! moving), the number of steps, and how to carry the motion back to the dense points.
//!
//! The settings are the core's own types: [`NormalsSpec`], [`SimplifyConfig`],
//! [`SpringMaterial`], [`SolverConfig`], [`TransferConfig`] and [`ResampleConfig`], every
//! field optional:
//!
//! ```
//! use bevy_point_springs::core::scene::Scene;
//!
//! let scene = Scene::from_ron(r#"(
//!     cloud: "sphere3203.ply",
//!     simplify: (target: Some(338)),
//!     material: (stretch_stiffness: 50.0, bend_stiffness: 10.0),
//!     solver: (integrator: ImplicitEuler, gravity: (0.0, 0.0, 0.0), drag: 2.0),
//!     dt: 0.016666668,
//!     steps: 180,
//!     pins: [Sphere(centre: (0.0, -1.0, 0.0), radius: 0.3)],
//!     pulls: [(at: (0.0, 1.0, 0.0), radius: Some(0.25), to: (0.0, 0.6, 0.0), stiffness: 400.0)],
//! )"#).unwrap();
//! assert_eq!(scene.steps, 180);
//! assert_eq!(scene.simplify.k, 12); // the default
//! ```
//!
//! Instead of a target, a scene may ask for its level by error: `error_budget: Some(0.01)`
//! chooses the coarsest level predicted to keep the deformed surface within 1 % of the
//! bounding box's diagonal (RMS) of the full resolution's ([`Scene::choose_level`]).
//!
//! [`Scene::prepare`] loads the cloud and prepares it with the one pipeline
//! ([`prepare_surface_holding`]: normals, §3 simplification keeping points along the edges
//! of the pinned regions, §4 network, §5 transfer coefficients), pins the pinned points and
//! sets up the [`Timeline`] of pulls, giving a [`SceneRun`];
//! [`SceneRun::run`] steps it (resampling where the scene asks for it);
//! [`SceneRun::deformed`] transfers the motion to the dense points:
//!
//! ```
//! use bevy_point_springs::core::scene::Scene;
//! use bevy_point_springs::prelude::*;
//! use bevy_point_springs::core::cloud::io::{PlyEncoding, write_ply};
//!
//! let (scene, base) = Scene::load("assets/scenes/hat.ron".as_ref()).unwrap();
//! let mut run = scene.prepare(&base).unwrap(); // normals, §3, §4, §5 coefficients
//! run.run(&mut |_step| {}).unwrap(); // 300 implicit Euler steps, resampling every 30
//! assert!(run.resampled().inserted > 0); // the stretched crown got new points
//! let deformed = run.deformed().unwrap(); // §5 transfer and normals
//! let out = std::env::temp_dir().join("hat.ply");
//! write_ply(&out, &deformed.cloud, PlyEncoding::BinaryLittleEndian).unwrap();
//! ```

mod budget;
mod run;
mod snapshot;
mod timeline;

pub use budget::{BUDGET_LADDER, LevelChoice, LevelEstimate, level_target};
pub use run::{Deformed, SceneRun};
pub use snapshot::{SNAPSHOT_MAGIC, Snapshot, SnapshotError};
pub use timeline::{Timeline, TimelineState};

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::core::PointCloud;
use crate::core::cloud::io::{LoadError, read_cloud};
use crate::core::cloud::knn::KnnIndex;
use crate::core::pipeline::{
    NormalsSpec, PrepareError, PreparedSurface, Progress, SurfaceConfig, prepare_surface_holding,
};
use crate::core::simplify::SimplifyConfig;
use crate::core::solver::{
    Anchor, AnchorId, Anchors, Masses, PointState, Solver, SolverConfig, SolverError,
    SpringMaterial, StepReport,
};
use crate::core::transfer::resample::{ResampleConfig, ResampleError, ResampleReport};
use crate::core::transfer::{TransferConfig, TransferError};

/// Most steps a scene may ask for.
pub const MAX_SCENE_STEPS: usize = 10_000_000;

/// Largest scene file read (scenes are a few hundred bytes).
pub const MAX_SCENE_BYTES: u64 = 1 << 20;

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

/// A scene. See the module docs for the file format.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// The dense cloud file, relative to the scene file (.ply .xyz .pwn .off .obj).
    pub cloud: PathBuf,
    /// Where its normals come from.
    #[serde(default)]
    pub normals: NormalsSpec,
    /// §3 settings: `(target: Some(338))`, `(max_diameter: Some(0.1))`, `k`, and `denoise:
    /// Auto / On / Off` for noisy scans.
    #[serde(default)]
    pub simplify: SimplifyConfig,
    /// Density, spring stiffness and damping.
    #[serde(default)]
    pub material: SpringMaterial,
    /// Integrator, gravity (standard gravity unless the scene says otherwise), drag,
    /// sub-steps.
    #[serde(default)]
    pub solver: SolverConfig,
    /// §5 settings.
    #[serde(default)]
    pub transfer: TransferConfig,
    /// Resampling where the surface stretches (none by default).
    #[serde(default)]
    pub resample: Option<ResampleConfig>,
    /// Gas pressure stiffness inside a closed surface (none by default; see
    /// [`SurfaceConfig::pressure`]).
    #[serde(default)]
    pub pressure: Option<f32>,
    /// Step length, s (the fixed tick a plugin app should run at).
    pub dt: f32,
    /// Steps the scene's timeline lasts (and `point-springs run` runs).
    pub steps: usize,
    /// Regions whose simulation points are held in place.
    #[serde(default)]
    pub pins: Vec<Region>,
    /// Pulls and pokes.
    #[serde(default)]
    pub pulls: Vec<Pull>,
    /// The largest RMS error of the deformed surface, over the bounding box's diagonal, that
    /// the simplification may cost: when given, the level is chosen by
    /// [`Scene::choose_level`] when the scene is prepared (the scene runs at a few coarse
    /// levels first), and `simplify`'s target and diameter are not used.
    #[serde(default)]
    pub error_budget: Option<f32>,
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
        /// The scene file (or `<string>`).
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
    /// The surface could not be prepared.
    #[error(transparent)]
    Prepare(#[from] PrepareError),
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

    /// Parses a scene from RON text read from `path` (named in errors).
    pub fn parse(text: &str, path: &Path) -> Result<Self, SceneError> {
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

    /// The surface settings of the scene, for
    /// [`prepare_surface`](crate::core::pipeline::prepare_surface).
    pub fn surface_config(&self) -> SurfaceConfig {
        SurfaceConfig {
            normals: self.normals,
            simplify: self.simplify,
            material: self.material,
            solver: self.solver,
            transfer: self.transfer,
            resample: self.resample,
            pressure: self.pressure,
        }
    }

    /// Takes the surface settings of `config` (normals, simplification, material, solver,
    /// transfer, resampling, pressure); the cloud, step, pins and pulls stay.
    pub fn set_surface_config(&mut self, config: &SurfaceConfig) {
        let SurfaceConfig {
            normals,
            simplify,
            material,
            solver,
            transfer,
            resample,
            pressure,
        } = *config;
        self.normals = normals;
        self.simplify = simplify;
        self.material = material;
        self.solver = solver;
        self.transfer = transfer;
        self.resample = resample;
        self.pressure = pressure;
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
        if let Some(budget) = self.error_budget {
            if !budget::valid_budget(budget) {
                return Err(invalid(format!(
                    "error_budget must be in (0, 1), got {budget}"
                )));
            }
        } else if self.simplify.target.is_none() && self.simplify.max_diameter.is_none() {
            return Err(invalid(
                "simplify needs a target or a max_diameter (or both), or the scene an error_budget",
            ));
        }
        if let Err(PrepareError::Invalid(message)) = self.surface_config().validate() {
            return Err(invalid(message));
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
        Ok(())
    }

    /// Loads the cloud (relative to `base`) and prepares the scene ([`Self::prepare_cloud`]).
    pub fn prepare(&self, base: &Path) -> Result<SceneRun, SceneError> {
        self.validate()?;
        self.prepare_run(read_cloud(&base.join(&self.cloud), None)?)
    }

    /// Prepares the scene on a cloud already loaded ([`Self::prepare_cloud`], without progress)
    /// as a run: generated clouds and clouds read elsewhere run like a scene's own file.
    pub fn prepare_run(&self, cloud: PointCloud) -> Result<SceneRun, SceneError> {
        self.validate()?;
        let (scene, _) = self.resolve_budget(&cloud)?;
        let rest = cloud.clone();
        let (surface, timeline) = scene.prepare_cloud(cloud, &mut |_| ControlFlow::Continue(()))?;
        Ok(SceneRun::new(scene, rest, surface, timeline))
    }

    /// Prepares the scene on a cloud already loaded: the surface ([`prepare_surface_holding`]
    /// with the pins' regions, reporting to `progress`), its pins, and the timeline of its
    /// pulls. A scene with an error budget chooses its level first
    /// ([`Self::resolve_budget`]).
    pub fn prepare_cloud(
        &self,
        cloud: PointCloud,
        progress: &mut dyn FnMut(Progress) -> ControlFlow<()>,
    ) -> Result<(PreparedSurface, Timeline), SceneError> {
        let surface = self.prepare_unpinned(cloud, progress)?;
        self.pin_prepared(surface)
    }

    /// The first half of [`Self::prepare_cloud`]: the surface prepared for the scene's pins
    /// (§3 keeps their edges) but not pinned yet, which is what a
    /// [prepared file](crate::core::pipeline::prepared) holds.
    pub fn prepare_unpinned(
        &self,
        cloud: PointCloud,
        progress: &mut dyn FnMut(Progress) -> ControlFlow<()>,
    ) -> Result<PreparedSurface, SceneError> {
        self.validate()?;
        if self.error_budget.is_some() {
            let (scene, _) = self.resolve_budget(&cloud)?;
            return scene.prepare_unpinned(cloud, progress);
        }
        let pins = &self.pins;
        let held = |p: Vec3| pins.iter().any(|r| r.contains(p));
        Ok(prepare_surface_holding(
            cloud,
            &self.surface_config(),
            &held,
            progress,
        )?)
    }

    /// The second half of [`Self::prepare_cloud`]: pins the points of a surface prepared by
    /// [`Self::prepare_unpinned`] (or read from its prepared file) and makes the timeline of
    /// the scene's pulls.
    pub fn pin_prepared(
        &self,
        mut surface: PreparedSurface,
    ) -> Result<(PreparedSurface, Timeline), SceneError> {
        let pins = &self.pins;
        let held = |p: Vec3| pins.iter().any(|r| r.contains(p));
        let solver = &mut surface.solver;
        pin_regions(
            &self.pins,
            &surface.network.positions,
            &mut solver.masses,
            &mut solver.points,
        )?;
        surface.dense.hold_where(&surface.solver.masses, held)?;
        let timeline = Timeline::new(self, &surface.network.positions);
        Ok((surface, timeline))
    }
}

/// Pins the points at `rest` inside each region (their velocities zeroed). Returns how
/// many points are pinned; a region holding none is an error.
pub fn pin_regions(
    regions: &[Region],
    rest: &[Vec3],
    masses: &mut Masses,
    points: &mut PointState,
) -> Result<usize, SceneError> {
    for (i, region) in regions.iter().enumerate() {
        let inside: Vec<usize> = (0..rest.len())
            .filter(|&j| region.contains(rest[j]))
            .collect();
        if inside.is_empty() {
            return Err(SceneError::EmptyPin(i));
        }
        for j in inside {
            masses.set_pinned(j, true)?;
            points.set_velocity(j, Vec3::ZERO)?;
        }
    }
    Ok(masses.pinned())
}

#[cfg(test)]
mod tests {
    use super::*;

    const MINIMAL: &str = r#"(cloud: "a.ply", simplify: (target: Some(50)), dt: 0.01, steps: 10)"#;

    #[test]
    fn a_surface_config_goes_in_and_comes_out_and_a_timeline_restarts() {
        let mut s = Scene::from_ron(
            r#"(cloud: "a.ply", simplify: (target: Some(50)), dt: 0.01, steps: 10,
                pulls: [(at: (1.0, 0.0, 0.0), to: (1.0, 0.0, 0.0), to_end: Some((2.0, 0.0, 0.0)),
                         start: 2, stiffness: 10.0, damping: 0.0)])"#,
        )
        .unwrap();
        let mut config = s.surface_config();
        config.simplify.target = Some(80);
        config.material.creep_rate = 3.0;
        s.set_surface_config(&config);
        assert_eq!(s.surface_config(), config);
        assert_eq!(s.pulls.len(), 1, "pulls stay");

        let rest = [Vec3::X, Vec3::Y, Vec3::NEG_X];
        let mut timeline = Timeline::new(&s, &rest);
        let mut anchors = Anchors::default();
        let game = anchors
            .add(
                Anchor {
                    point: 1,
                    target: Vec3::Y,
                    stiffness: 1.0,
                    damping: 0.0,
                },
                rest.len(),
            )
            .unwrap();
        let run = |timeline: &mut Timeline, anchors: &mut Anchors| {
            for _ in 0..5 {
                timeline.advance(anchors, &rest).unwrap();
            }
            anchors
                .live()
                .map(|a| (a.point, a.target))
                .collect::<Vec<_>>()
        };
        let first = run(&mut timeline, &mut anchors);
        assert_eq!(first.len(), 2, "the pull's anchor and the game's");
        timeline.restart(&mut anchors);
        assert_eq!(timeline.step(), 0);
        assert_eq!(anchors.live().count(), 1, "the game's anchor stays");
        assert!(anchors.get(game).is_some());
        let again = run(&mut timeline, &mut anchors);
        let sorted = |mut v: Vec<(u32, Vec3)>| {
            v.sort_by_key(|a| a.0);
            v
        };
        assert_eq!(
            sorted(again),
            sorted(first),
            "the same pull, from the start"
        );
    }

    #[test]
    fn defaults_fill_the_rest() {
        let s = Scene::from_ron(MINIMAL).unwrap();
        assert_eq!(s.solver, SolverConfig::default());
        assert_eq!(s.solver.gravity, crate::core::solver::STANDARD_GRAVITY);
        assert_eq!(s.transfer, TransferConfig::default());
        assert!(s.pins.is_empty() && s.pulls.is_empty() && s.resample.is_none());
        // Round trip.
        let text = ron::to_string(&s).unwrap();
        assert_eq!(Scene::from_ron(&text).unwrap(), s);
        // Noisy scans are decided on local fits unless a scene says otherwise.
        assert_eq!(
            s.simplify.denoise,
            crate::core::normals::denoise::Denoise::Auto
        );
        let off = Scene::from_ron(
            r#"(cloud: "a.ply", simplify: (target: Some(50), denoise: Off), dt: 0.01, steps: 10)"#,
        )
        .unwrap();
        assert_eq!(
            off.simplify.denoise,
            crate::core::normals::denoise::Denoise::Off
        );
        // A material is per spring unless it says it is a sheet's.
        assert_eq!(
            s.material.units,
            crate::core::solver::MaterialUnits::PerSpring
        );
        let sheet = Scene::from_ron(
            r#"(cloud: "a.ply", simplify: (target: Some(50)), dt: 0.01, steps: 10,
                material: (units: Sheet, stretch_stiffness: 200.0, stretch_damping: 0.1))"#,
        )
        .unwrap();
        assert_eq!(
            sheet.material.units,
            crate::core::solver::MaterialUnits::Sheet
        );
        assert_eq!(sheet.material.stretch_stiffness, 200.0);
    }

    #[test]
    fn mistakes_are_named() {
        let cases = [
            (
                r#"(cloud: "a.ply", simplify: (target: None), dt: 0.01, steps: 10)"#,
                "simplify needs",
            ),
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
                    solver: (drag: -2.0))"#,
                "solver: invalid solver setting: drag",
            ),
            (
                r#"(cloud: "a.ply", simplify: (target: Some(5)), dt: 0.1, steps: 5,
                    material: (bend_damping: -2.0))"#,
                "material.bend_damping",
            ),
            (
                r#"(cloud: "a.ply", simplify: (target: Some(5)), dt: 0.1, steps: 5,
                    resample: Some((interval: 0)))"#,
                "resample: invalid resampling setting: the interval",
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
