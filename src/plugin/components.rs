//! The components of a deformable surface. One entity per surface; each component holds
//! whole arrays (never an entity per point), so the spring loop reads contiguous memory.
//!
//! A game spawns a [`DeformableSurface`]; once it is prepared the plugin adds the rest:
//!
//! | component | holds | a game may |
//! |---|---|---|
//! | [`SimulationPoints`] | positions and velocities of the simulation points | read them; move or push a point |
//! | [`SurfaceMasses`] | masses and pins | pin or free a point |
//! | [`SurfaceSprings`] | stretch and bend springs: ends, rest lengths, stiffness, damping | read them |
//! | [`SurfaceAnchors`] | anchor springs to world points (eq 5): pokes, drags, grabs ([`GrabMessage`](super::GrabMessage)) | add, move, remove |
//! | [`SurfaceAttachments`](super::SurfaceAttachments) | sets of points tied to other entities' transforms (added by the game) | attach, retarget, detach; read the pulls |
//! | [`SurfaceMeeting`](super::SurfaceMeeting) | whether and how the surface meets other surfaces and itself (added by the game) | set it |
//! | [`SurfaceMeetingReport`](super::SurfaceMeetingReport) | what touched it last tick (added with `SurfaceMeeting`) | read it |
//! | [`SurfaceForces`] | a force per point, cleared after each tick | add to it in [`PointSpringsSystems::Forces`](super::PointSpringsSystems::Forces) |
//! | [`SurfaceStepper`] | integrator settings, force buffers, running totals | change the integrator, gravity, drag |
//! | [`SurfaceMaterial`] | density, spring stiffness and damping | change it (the springs follow) |
//! | [`SurfaceNetwork`] | the simulation points' rest positions, rings and springs | read them |
//! | [`DenseSurface`] | rest cloud, transfer coefficients, deformed positions and normals | read them (drawing, export) |
//! | [`SceneTimeline`] | a scene's pulls on their schedule (scenes only) | read its step |

use std::path::PathBuf;
use std::sync::Arc;

use bevy::ecs::query::QueryData;
use bevy::prelude::*;
use bevy::reflect::reflect_remote;

use crate::core::PointCloud;
use crate::core::network::SpringNetwork;
use crate::core::pipeline::prepared::PreparedFileError;
use crate::core::pipeline::{DenseCloud, Stage, SurfaceConfig};
use crate::core::scene::{Scene, Timeline};
use crate::core::solver::{
    Anchors, BendingModel, ExternalForces, Masses, MaterialUnits, PointState, Pressure,
    SolverConfig, SolverError, SpringMaterial, Springs, StepParts, Stepper,
};

use super::assets::{CloudAsset, SceneAsset};
use super::health::SurfaceHealth;

/// Where a surface's dense cloud comes from.
#[derive(Debug, Clone)]
pub enum SurfaceSource {
    /// A scene file (`.ron`, loaded with the asset server): its cloud, settings, pins and
    /// pulls.
    Scene(Handle<SceneAsset>),
    /// A cloud file loaded with the asset server (`.ply .xyz .pwn .off .obj`), prepared
    /// with the surface's [`SurfaceConfig`].
    CloudAsset(Handle<CloudAsset>),
    /// A cloud in memory, prepared with the surface's [`SurfaceConfig`].
    Cloud(Arc<PointCloud>),
    /// A scene and its cloud in memory (a scene made by code, or read without the asset
    /// server).
    SceneData(Arc<(Scene, PointCloud)>),
}

/// A deformable point-sampled surface: spawn one, and the plugin prepares it in the
/// background (normals, §3 simplification, §4 springs, §5 transfer) and simulates it on the
/// fixed tick. [`SurfaceStatus`] tells how far it is.
///
/// ```no_run
/// use bevy::prelude::*;
/// use bevy_point_springs::prelude::*;
///
/// fn spawn(mut commands: Commands, assets: Res<AssetServer>) {
///     // A whole scene: cloud, settings, pins and pulls on their schedule.
///     commands.spawn(DeformableSurface::scene(assets.load("scenes/hat.ron")));
///     // A cloud file with settings of your own.
///     let config = SurfaceConfig::default();
///     commands.spawn((
///         DeformableSurface::cloud_asset(assets.load("kitten.off"), config),
///         Transform::from_xyz(3.0, 0.0, 0.0),
///     ));
/// }
/// ```
#[derive(Component, Debug, Clone)]
#[require(
    SurfaceStatus,
    SurfaceHealth,
    PreviousTick,
    SurfaceRunSettings,
    SurfaceSleep,
    SurfaceWork,
    SurfaceTimings,
    SurfaceInView,
    Transform
)]
pub struct DeformableSurface {
    /// Where the dense cloud comes from.
    pub source: SurfaceSource,
    /// How it is prepared (a scene's own settings replace it once the scene has loaded), and
    /// the material and solver settings it starts with. Once it is ready, those run-time
    /// settings are owned by [`SurfaceMaterial`] and [`SurfaceStepper`]: change them there
    /// (a [`PrepareAgain`](super::PrepareAgain) keeps them too).
    pub config: SurfaceConfig,
    /// A file that keeps the preparation (see [`Self::with_prepared_file`]).
    pub prepared_file: Option<PathBuf>,
}

impl DeformableSurface {
    /// A surface from a scene file.
    pub fn scene(scene: Handle<SceneAsset>) -> Self {
        Self {
            source: SurfaceSource::Scene(scene),
            config: SurfaceConfig::default(),
            prepared_file: None,
        }
    }

    /// A surface from a cloud file.
    pub fn cloud_asset(cloud: Handle<CloudAsset>, config: SurfaceConfig) -> Self {
        Self {
            source: SurfaceSource::CloudAsset(cloud),
            config,
            prepared_file: None,
        }
    }

    /// A surface from a cloud in memory.
    pub fn cloud(cloud: PointCloud, config: SurfaceConfig) -> Self {
        Self {
            source: SurfaceSource::Cloud(Arc::new(cloud)),
            config,
            prepared_file: None,
        }
    }

    /// A surface from a scene and its cloud in memory.
    pub fn scene_data(scene: Scene, cloud: PointCloud) -> Self {
        Self {
            config: scene.surface_config(),
            source: SurfaceSource::SceneData(Arc::new((scene, cloud))),
            prepared_file: None,
        }
    }

    /// Keeps the surface's preparation in `path` (a path of the file system; `.psprep` by
    /// custom): where the file holds the preparation of this very source (the cloud, bit for
    /// bit, with these settings, and a scene's pins and pulls) by this version of the
    /// plugin, the surface is read from it instead of being prepared, in a small part of the
    /// time; otherwise it is prepared and the file written (again), and the reason it was
    /// not used is logged. [`PreparedFileOutcome`] says which happened. `point-springs
    /// prepare` writes such files ahead of time.
    pub fn with_prepared_file(mut self, path: impl Into<PathBuf>) -> Self {
        self.prepared_file = Some(path.into());
        self
    }
}

/// What became of a surface's [prepared file](DeformableSurface::with_prepared_file) at its
/// last preparation (inserted with the prepared surface).
#[derive(Component, Debug, Clone)]
pub enum PreparedFileOutcome {
    /// The surface was read from the file: nothing was prepared.
    Read,
    /// The surface was prepared and the file written: there was none, or it was refused
    /// (`refused` says why: another source or version, or a damaged file).
    Written {
        /// Why the file there was not used (none: there was no file).
        refused: Option<Arc<PreparedFileError>>,
    },
    /// The surface was prepared, but the file could not be written.
    NotWritten {
        /// Why the file there was not used (none: there was no file).
        refused: Option<Arc<PreparedFileError>>,
        /// Why it could not be written.
        error: Arc<PreparedFileError>,
    },
}

/// Where a [`DeformableSurface`] is: the plugin's report (read it, or observe
/// [`SurfaceReady`](super::SurfaceReady) and [`SurfaceFailed`](super::SurfaceFailed)). To
/// prepare a surface again, insert [`PrepareAgain`](super::PrepareAgain); a prepared
/// surface whose status a game sets back to `Pending` gets a warning and runs on.
#[derive(Component, Debug, Clone, Default, PartialEq, Reflect)]
#[reflect(Component, Debug, Default)]
pub enum SurfaceStatus {
    /// Not looked at yet.
    #[default]
    Pending,
    /// Waiting for the asset server (the scene or cloud file).
    Loading,
    /// Being prepared on the async compute pool (see [`PreparationProgress`]).
    Preparing,
    /// Prepared and simulating.
    Ready,
    /// Loading, preparing or simulating failed, for this reason (also sent as
    /// [`SurfaceFailed`](super::SurfaceFailed)). Other surfaces are not affected.
    Failed(super::SurfaceError),
}

impl SurfaceStatus {
    /// Whether the surface is simulating.
    pub fn is_ready(&self) -> bool {
        matches!(self, Self::Ready)
    }
}

/// How far the preparation of a surface is (present while [`SurfaceStatus::Preparing`]).
#[derive(Component, Debug, Clone, Copy, PartialEq, Reflect)]
#[reflect(Component, Debug)]
pub struct PreparationProgress {
    /// The stage under way: "normals", "simplify", "network" or "transfer".
    pub stage: &'static str,
    /// How far the whole preparation is, from 0 to 1.
    pub fraction: f32,
}

impl PreparationProgress {
    pub(crate) fn at(stage: Stage, fraction: f32) -> Self {
        Self {
            stage: stage.name(),
            fraction,
        }
    }
}

/// When the dense surface follows the simulation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Reflect)]
pub enum TransferTiming {
    /// After every fixed tick that moved the simulation points: the drawn surface is the
    /// simulation's state after the last tick (it moves in steps when frames outnumber
    /// ticks, or do not line up with them).
    EveryTick,
    /// Once per rendered frame (in `PostUpdate`), if a tick moved the points: cheaper when
    /// ticks outnumber frames. Resampling still happens on its tick.
    PerFrame,
    /// Once per rendered frame, at the frame's time between the last two ticks: the
    /// simulation points' positions at the start and the end of the last tick blended by
    /// `Time<Fixed>::overstep_fraction()`, then transferred, so that the surface moves
    /// smoothly at any frame rate (the drawn surface is then up to a tick behind the
    /// simulation, as interpolated rigid bodies are). The transfer is linear in the
    /// points' positions, so the drawn positions are exactly the blend of the two ticks'.
    /// The default.
    #[default]
    Interpolated,
}

/// A surface's simulation points where the last tick started, for
/// [`TransferTiming::Interpolated`] (kept only for surfaces drawn that way).
#[derive(Component, Debug, Clone, Default)]
pub struct PreviousTick {
    /// The positions at the start of the last tick (the surface's own coordinates); empty
    /// until a tick has run.
    pub(crate) positions: Vec<Vec3>,
    /// The blend drawn this frame, kept to save an allocation a frame.
    pub(crate) blend: Option<PointState>,
}

impl PreviousTick {
    /// The positions at the start of the last tick (empty until a tick has run).
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }
}

/// How a prepared surface runs: when its dense surface follows, whether it is paused, when
/// it sleeps. (How it is prepared, and the material and solver it starts with, are the
/// [`SurfaceConfig`] of its [`DeformableSurface`].)
#[derive(Component, Debug, Clone, Copy, PartialEq, Default, Reflect)]
#[reflect(Component, Debug, Default)]
pub struct SurfaceRunSettings {
    /// When the dense surface follows the simulation.
    pub transfer: TransferTiming,
    /// Whether the simulation is held (no forces, no steps).
    pub paused: bool,
    /// When the surface goes to sleep (see [`SurfaceSleep`]).
    pub sleep: SleepSettings,
}

/// Speed below which a surface's simulation points count as still, by default (metres per
/// second, in the surface's own units).
pub const DEFAULT_SLEEP_SPEED: f32 = 0.002;

/// How long a surface stays still before it sleeps, by default (seconds).
pub const DEFAULT_SLEEP_AFTER: f32 = 1.0;

/// When a surface goes to sleep: its fastest simulation point has stayed below `speed` for
/// `after` seconds, with no anchor on it (no grab, no active pull), no force from the game
/// or from contacts, and its scene timeline (if any) finished.
#[derive(Debug, Clone, Copy, PartialEq, Reflect)]
pub struct SleepSettings {
    /// Speed below which the points count as still; 0 never sleeps.
    pub speed: f32,
    /// Seconds still before sleeping.
    pub after: f32,
}

impl Default for SleepSettings {
    fn default() -> Self {
        Self {
            speed: DEFAULT_SLEEP_SPEED,
            after: DEFAULT_SLEEP_AFTER,
        }
    }
}

/// Whether a surface sleeps. A sleeping surface costs nothing per tick: no forces, no step,
/// no transfer, no upload. It wakes on the tick something acts on it: a grab or any other
/// anchor, a force from the game or a contact in [`SurfaceForces`], or a change of its
/// material, its run settings or its solver settings ([`SurfaceStepper::set_config`]).
#[derive(Component, Debug, Clone, Copy, PartialEq, Default, Reflect)]
#[reflect(Component, Debug, Default)]
pub struct SurfaceSleep {
    /// Asleep now.
    pub asleep: bool,
    /// Seconds the surface has been still so far (awake).
    pub still_for: f32,
    /// Something acted on the surface this tick.
    #[reflect(ignore)]
    pub(crate) acted: bool,
}

impl SurfaceSleep {
    /// Wakes the surface: something acted on it this tick, and its stillness starts again.
    pub(crate) fn wake(&mut self) {
        *self = Self {
            acted: true,
            ..Self::default()
        };
    }
}

/// The work a surface's ticks have done so far, counted (not timed): what sleeping saves.
#[derive(Component, Debug, Clone, Copy, PartialEq, Eq, Default, Reflect)]
#[reflect(Component, Debug, Default)]
pub struct SurfaceWork {
    /// Steps taken.
    pub steps: u64,
    /// Spring evaluations: springs times sub-steps, summed over steps.
    pub springs_evaluated: u64,
    /// Dense points carried by the transfer, summed over the frames computed.
    pub points_transferred: u64,
}

/// How long the latest work on a surface took, in milliseconds of this machine's wall
/// clock (what the panel shows). Forces and step are 0 while the surface is paused or
/// asleep, the transfer 0 while it is out of view (and only the check that nothing moved
/// when nothing did), the upload 0 in a frame that uploaded nothing of its batch.
#[derive(Component, Debug, Clone, Copy, PartialEq, Default, Reflect)]
#[reflect(Component, Debug, Default)]
pub struct SurfaceTimings {
    /// Accumulating the surface's own forces, the last tick.
    pub forces_ms: f32,
    /// The step (all its sub-steps) and plastic flow, the last tick.
    pub step_ms: f32,
    /// Resampling and the transfer to the dense points, the last time it ran.
    pub transfer_ms: f32,
    /// Copying the dense points into the surfel buffer, the last frame (feature `render`).
    pub upload_ms: f32,
    /// Modelling requests ([`ModelMessage`](super::ModelMessage)) on the tick, the last
    /// tick: a reset, or taking a bake or export to the background and putting its result
    /// in place.
    pub model_ms: f32,
}

impl SurfaceTimings {
    /// Forces, step, transfer and modelling requests: the surface's share of a tick.
    pub fn tick_ms(&self) -> f32 {
        self.forces_ms + self.step_ms + self.transfer_ms + self.model_ms
    }
}

/// Whether a camera sees the surface. A surface out of view keeps simulating but skips the
/// transfer (so its surfels stop changing) until it is seen again, when the transfer
/// catches up from the current state in the same frame. For surfaces drawn by
/// [`SurfelRenderPlugin`](super::render) (those with `SurfelRender`) the plugin sets it
/// every frame from the active cameras' frusta and the surface's bounds; any other surface
/// counts as seen unless a game says otherwise.
#[derive(Component, Debug, Clone, Copy, PartialEq, Eq, Reflect, Deref)]
#[reflect(Component, Debug, Default)]
pub struct SurfaceInView(pub bool);

impl Default for SurfaceInView {
    fn default() -> Self {
        Self(true)
    }
}

/// A paused surface with this component takes one step on the next tick (transfer
/// included); the plugin then removes the component. A running surface ignores it.
#[derive(Component, Debug, Clone, Copy, Default, Reflect)]
#[reflect(Component, Debug, Default)]
pub struct StepOnce;

/// The simulation points' positions and velocities (in the surface's own coordinates).
#[derive(Component, Debug, Clone, Default, Deref, DerefMut)]
pub struct SimulationPoints(pub PointState);

/// The simulation points' masses (each a share of the dense surface's area times the
/// density: see [`SpringNetwork::share_dense_area`](crate::core::network::SpringNetwork::share_dense_area))
/// and which of them are pinned. Pin and free points with [`SurfacePins`](super::SurfacePins),
/// which also stops them.
#[derive(Component, Debug, Clone, Default, Deref)]
pub struct SurfaceMasses(pub(crate) Masses);

/// The stretch and bend springs (eq 2–3).
#[derive(Component, Debug, Clone, Default, Deref)]
pub struct SurfaceSprings(pub(crate) Springs);

/// Anchor springs from simulation points to points in the surface's coordinates (eq 5):
/// pokes, drags, soft pins. Add, move and remove them at any time.
#[derive(Component, Debug, Clone, Default, Deref, DerefMut)]
pub struct SurfaceAnchors(pub Anchors);

/// A force on each simulation point from the game (wind, magnets, contacts): add to it
/// from a system in [`PointSpringsSystems::Forces`](super::PointSpringsSystems::Forces).
/// The step adds it to the surface's own forces, then clears it.
#[derive(Component, Debug, Clone, Default, Deref, DerefMut)]
pub struct SurfaceForces(pub ExternalForces);

/// Gas inside a closed surface ([`SurfaceConfig::pressure`]).
#[derive(Component, Debug, Clone, Deref, DerefMut)]
pub struct SurfacePressure(pub Pressure);

/// The integrator's settings, force buffers and running totals. Read them through
/// [`Stepper`]'s methods; change the settings with [`SurfaceStepper::set_config`] (the
/// force buffers and totals are the plugin's). The second field is set when the settings
/// changed, so that a sleeping surface wakes on the next tick.
#[derive(Component, Debug, Clone, Default, Deref)]
pub struct SurfaceStepper(#[deref] pub(crate) Stepper, pub(crate) bool);

impl SurfaceStepper {
    /// Changes the solver settings (integrator, gravity, drag, sub-steps, …) from the next
    /// step on, and wakes the surface if it sleeps; refused, with nothing changed, when they
    /// do not validate.
    pub fn set_config(&mut self, config: SolverConfig) -> Result<(), SolverError> {
        let before = *self.0.config();
        self.0.set_config(config)?;
        self.1 |= *self.0.config() != before;
        Ok(())
    }
}

/// The surface's material ([`SpringMaterial`]: density, spring stiffness and damping,
/// plasticity). Changing it sets every spring's stiffness, damping and plasticity anew (the
/// masses stay those of the density it was prepared with).
#[derive(Component, Debug, Clone, Copy, PartialEq, Reflect, Deref, DerefMut)]
#[reflect(Component, Debug)]
pub struct SurfaceMaterial(#[reflect(remote = SpringMaterialReflect)] pub SpringMaterial);

/// How [`SpringMaterial`] (a core type, which knows nothing of Bevy) is reflected; the
/// fields are checked against it when this compiles.
#[reflect_remote(SpringMaterial)]
#[derive(Debug)]
pub struct SpringMaterialReflect {
    /// Mass per unit area ρ.
    pub density: f32,
    /// Per spring, or a sheet's moduli and damping ratios.
    #[reflect(remote = MaterialUnitsReflect)]
    pub units: MaterialUnits,
    /// Stiffness of stretch springs.
    pub stretch_stiffness: f32,
    /// Stiffness of bend springs.
    pub bend_stiffness: f32,
    /// Damping of stretch springs.
    pub stretch_damping: f32,
    /// Damping of bend springs.
    pub bend_damping: f32,
    /// The paper's bend springs, or hinges.
    #[reflect(remote = BendingModelReflect)]
    pub bending: BendingModel,
    /// Flexural rigidity of the hinges, N·m.
    pub bending_modulus: f32,
    /// Damping time of the hinges, s.
    pub bending_damping: f32,
    /// Strain borne elastically before the rest lengths creep.
    pub yield_strain: f32,
    /// Bend borne elastically before the hinges' rest angles creep, radians.
    pub yield_angle: f32,
    /// How fast the strain beyond yield becomes the rest length, per second (0: elastic).
    pub creep_rate: f32,
}

/// How [`BendingModel`] is reflected.
#[reflect_remote(BendingModel)]
#[derive(Debug)]
pub enum BendingModelReflect {
    /// The paper's bend springs.
    Springs,
    /// Hinges (discrete shells).
    Hinges,
    /// Each point's fitted curvature.
    Curvature,
}

/// How [`MaterialUnits`] is reflected.
#[reflect_remote(MaterialUnits)]
#[derive(Debug)]
pub enum MaterialUnitsReflect {
    /// The paper's per-spring stiffness and damping.
    PerSpring,
    /// A sheet's moduli and damping ratios.
    Sheet,
}

/// The simulation points at rest: positions, normals, rings, springs and masses as §3–§4
/// built them.
#[derive(Component, Debug, Clone, Deref)]
pub struct SurfaceNetwork(pub(crate) Arc<SpringNetwork>);

impl SurfaceNetwork {
    /// The network, shared (cloning the `Arc` is cheap: hand it to a task or keep it as the
    /// rest state to compare with).
    pub fn shared(&self) -> &Arc<SpringNetwork> {
        &self.0
    }
}

/// The dense surface: its rest cloud and transfer coefficients, and its deformed positions
/// and normals (in the surface's own coordinates), updated as the simulation moves.
#[derive(Component, Debug, Clone, Deref)]
pub struct DenseSurface(pub(crate) DenseCloud);

/// On a surface whose transfer runs on the GPU (the renderer adds it, see
/// `SurfelRender::device`): the simulation points to draw this frame, which the transfer
/// systems hand over instead of transferring on the CPU. [`DenseSurface`] then keeps the
/// dense surface as the CPU last computed it; the plugin brings it up to date where it
/// reads it (saving a game, picking, export), as
/// [`DenseCloud::follow`](crate::core::pipeline::DenseCloud::follow) does.
#[derive(Component, Debug, Clone, Default)]
pub struct GpuTransferInput {
    /// The simulation points' positions to draw (the surface's own coordinates; w = 0).
    pub(crate) positions: Vec<[f32; 4]>,
    /// Bumped each time they change.
    pub(crate) revision: u64,
}

impl GpuTransferInput {
    /// Takes `points`' positions to draw; returns whether they changed.
    pub(crate) fn set(&mut self, points: &PointState) -> bool {
        let same = self.positions.len() == points.len()
            && points.iter_positions().zip(&self.positions).all(|(p, q)| {
                p.to_array().map(f32::to_bits) == [q[0], q[1], q[2]].map(f32::to_bits)
            });
        if same {
            return false;
        }
        self.positions.clear();
        self.positions
            .extend(points.iter_positions().map(|p| [p.x, p.y, p.z, 0.0]));
        self.revision += 1;
        true
    }

    /// The positions to draw, w = 0.
    pub fn positions(&self) -> &[[f32; 4]] {
        &self.positions
    }

    /// Bumped each time the positions change.
    pub fn revision(&self) -> u64 {
        self.revision
    }
}

/// A scene's pulls and pokes on their schedule (surfaces spawned from scenes). Read it
/// (`Deref`); the plugin drives it, and `ModelMessage::Reset` starts it again.
#[derive(Component, Debug, Clone, Deref)]
pub struct SceneTimeline(pub(crate) Timeline);

/// The read-only parts of a surface a step needs, as one query item.
#[derive(QueryData)]
pub(crate) struct StepPartsQuery {
    masses: &'static SurfaceMasses,
    springs: &'static SurfaceSprings,
    anchors: &'static SurfaceAnchors,
    pressure: Option<&'static SurfacePressure>,
    network: &'static SurfaceNetwork,
}

impl StepPartsQueryItem<'_, '_> {
    /// The parts as the core's [`StepParts`].
    pub(crate) fn step_parts(&self) -> StepParts<'_> {
        StepParts {
            masses: self.masses,
            springs: self.springs,
            anchors: self.anchors,
            pressure: self.pressure.map(|p| &p.0),
            rest: Some(&self.network.positions),
        }
    }
}
