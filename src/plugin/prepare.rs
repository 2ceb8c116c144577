//! Preparation: a new [`DeformableSurface`] is noticed once, its files are awaited from
//! the asset server, and the one core pipeline ([`prepare_surface`], or a scene's
//! [`Scene::prepare_cloud`](crate::core::scene::Scene::prepare_cloud)) runs on Bevy's async
//! compute pool, reporting [`PreparationProgress`]. When it is done the simulation's
//! components are inserted. Despawning the entity drops the task, which tells the
//! pipeline to stop at its next progress report.
//!
//! **Preparing again.** [`PrepareAgain`] is the one way: on a ready surface it prepares it
//! with new settings (the panel's simplification level, say) in the background while the
//! old simulation runs on; the new one replaces it when it is ready, or
//! [`PrepareAgainFailed`] says why not. [`SurfaceStatus`] is the plugin's report: a game
//! that sets a prepared surface's status back to `Pending` gets a warning, and the surface
//! runs on.
//!
//! **Threads.** The pipeline's own parallel loops use rayon. Inside a Bevy app they run in
//! a rayon pool of the plugin's ([`PreparationPool`]) with as many threads as Bevy's async
//! compute pool has, not in rayon's global pool (one thread per core): Bevy's compute pool
//! already keeps every core busy during a frame, so a second pool of that size would
//! take cores from the game's frames while a surface is being prepared.

use std::ops::ControlFlow;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use bevy::asset::LoadState;
use bevy::prelude::*;
use bevy::tasks::futures::check_ready;
use bevy::tasks::{AsyncComputeTaskPool, Task};

use crate::core::PointCloud;
use crate::core::pipeline::prepared::{SourceFingerprint, read_prepared, write_prepared};
use crate::core::pipeline::{PreparedSurface, Progress, Stage, SurfaceConfig, prepare_surface};
use crate::core::scene::{Scene, Timeline};
use crate::core::solver::ExternalForces;

use super::assets::{CloudAsset, SceneAsset};
use super::components::{
    DeformableSurface, DenseSurface, PreparationProgress, PreparedFileOutcome, SceneTimeline,
    SimulationPoints, SurfaceAnchors, SurfaceForces, SurfaceMasses, SurfaceMaterial,
    SurfaceNetwork, SurfacePressure, SurfaceSource, SurfaceSprings, SurfaceStatus, SurfaceStepper,
};
use super::grab::Grabs;
use super::lifecycle::{SurfaceError, SurfaceFailed, SurfaceReady};
use super::save::SurfaceBaked;

/// The rayon pool surfaces are prepared in (see the module docs).
#[derive(Resource, Clone)]
pub struct PreparationPool(pub Arc<rayon::ThreadPool>);

impl std::fmt::Debug for PreparationPool {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_tuple("PreparationPool")
            .field(&self.0.current_num_threads())
            .finish()
    }
}

impl PreparationPool {
    /// A pool with as many threads as Bevy's async compute pool (at least one).
    pub fn matching_async_compute() -> Result<Self, rayon::ThreadPoolBuildError> {
        let threads = AsyncComputeTaskPool::get().thread_num().max(1);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("point-springs prepare {i}"))
            .build()?;
        Ok(Self(Arc::new(pool)))
    }

    /// The app's pool (`pool`), or a new one [matching](Self::matching_async_compute) the
    /// compute pool, made the app's.
    pub(crate) fn get_or_build(
        commands: &mut Commands,
        pool: Option<&Self>,
    ) -> Result<Self, rayon::ThreadPoolBuildError> {
        if let Some(pool) = pool {
            return Ok(pool.clone());
        }
        let pool = Self::matching_async_compute()?;
        commands.insert_resource(pool.clone());
        Ok(pool)
    }
}

/// Prepares a surface again with these settings, from its source: a baked or sculpted
/// shape is not kept. A ready surface keeps its run-time material and solver settings
/// ([`SurfaceMaterial`], [`SurfaceStepper`], their one owner), as they are when the new
/// simulation takes over (changes made meanwhile included): change those there; the
/// settings here give the rest (normals, simplification, network, transfer, gas). On a ready surface the old simulation keeps running until the new
/// one is ready (with [`PreparationProgress`] present meanwhile), and
/// [`DeformableSurface::config`] takes the settings then; a surface being prepared takes
/// the request once it is ready; a pending, loading or failed one starts afresh with these
/// settings. A scene keeps its cloud, pins and pulls and takes these settings; its timeline
/// starts again. The plugin removes the component when it starts the work (or could not).
#[derive(Component, Debug, Clone, PartialEq)]
pub struct PrepareAgain(pub SurfaceConfig);

/// Why the last [`PrepareAgain`] of a ready surface failed; the old simulation ran on.
/// Removed when another starts.
#[derive(Component, Debug, Clone, PartialEq)]
pub struct PrepareAgainFailed(pub SurfaceError);

/// What a finished preparation hands over.
struct Prepared {
    surface: PreparedSurface,
    timeline: Option<Timeline>,
    /// What became of the prepared file, when the surface has one.
    file: Option<PreparedFileOutcome>,
}

impl Prepared {
    /// Takes `config`'s material and solver settings (the running surface's, as they are
    /// now) in place of those it was prepared with. The springs follow the material when
    /// it is inserted ([`apply_materials`](super::simulate::apply_materials) sees it added).
    fn keep_running_settings(&mut self, config: &SurfaceConfig) {
        self.surface.config.material = config.material;
        if let Err(e) = self.surface.solver.set_config(config.solver) {
            warn!("the running solver settings were not kept ({e}); the prepared ones are used");
        }
    }
}

/// Progress shared between a preparation task and the app.
#[derive(Debug, Default)]
struct Shared {
    stage: AtomicU32,
    fraction: AtomicU32,
    cancel: AtomicBool,
}

const STAGES: [Stage; 4] = [
    Stage::Normals,
    Stage::Simplify,
    Stage::Network,
    Stage::Transfer,
];

impl Shared {
    fn report(&self, p: Progress) -> ControlFlow<()> {
        let stage = STAGES.iter().position(|&s| s == p.stage).unwrap_or(0);
        self.stage.store(stage as u32, Ordering::Relaxed);
        self.fraction.store(p.fraction.to_bits(), Ordering::Relaxed);
        if self.cancel.load(Ordering::Relaxed) {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    }

    fn progress(&self) -> PreparationProgress {
        let stage = STAGES[(self.stage.load(Ordering::Relaxed) as usize).min(STAGES.len() - 1)];
        PreparationProgress::at(stage, f32::from_bits(self.fraction.load(Ordering::Relaxed)))
    }
}

/// A surface's preparation under way. Dropping it (the entity despawned, or the component
/// removed) asks the pipeline to stop.
#[derive(Component)]
pub(crate) struct PreparationTask {
    task: Task<Result<Prepared, SurfaceError>>,
    shared: Arc<Shared>,
    /// With [`PrepareAgain`] on a ready surface: the settings it takes when the new
    /// simulation replaces the old one, which runs on meanwhile.
    background: Option<SurfaceConfig>,
}

impl Drop for PreparationTask {
    fn drop(&mut self) {
        self.shared.cancel.store(true, Ordering::Relaxed);
    }
}

/// The cloud (and scene) of a surface, once the asset server has them.
enum Inputs {
    Ready(Box<(PointCloud, Option<Scene>)>),
    Waiting,
    Failed(SurfaceError),
}

fn cloud_from_asset(
    handle: &Handle<CloudAsset>,
    server: Option<&AssetServer>,
    clouds: Option<&Assets<CloudAsset>>,
) -> Inputs {
    if let Some(cloud) = clouds.and_then(|c| c.get(handle)) {
        return Inputs::Ready(Box::new((cloud.0.clone(), None)));
    }
    match server.map(|s| s.load_state(handle)) {
        None => Inputs::Failed(SurfaceError::NoAssetPlugin),
        Some(LoadState::Failed(e)) => Inputs::Failed(SurfaceError::Load(e)),
        Some(_) => Inputs::Waiting,
    }
}

fn inputs(
    source: &SurfaceSource,
    server: Option<&AssetServer>,
    scenes: Option<&Assets<SceneAsset>>,
    clouds: Option<&Assets<CloudAsset>>,
) -> Inputs {
    match source {
        SurfaceSource::Cloud(cloud) => Inputs::Ready(Box::new((PointCloud::clone(cloud), None))),
        SurfaceSource::SceneData(data) => {
            Inputs::Ready(Box::new((data.1.clone(), Some(data.0.clone()))))
        }
        SurfaceSource::CloudAsset(handle) => cloud_from_asset(handle, server, clouds),
        SurfaceSource::Scene(handle) => {
            let Some(scene) = scenes.and_then(|s| s.get(handle)) else {
                return match server.map(|s| s.load_state(handle)) {
                    None => Inputs::Failed(SurfaceError::NoAssetPlugin),
                    Some(LoadState::Failed(e)) => Inputs::Failed(SurfaceError::Load(e)),
                    Some(_) => Inputs::Waiting,
                };
            };
            match cloud_from_asset(&scene.cloud, server, clouds) {
                Inputs::Ready(found) => {
                    Inputs::Ready(Box::new((found.0, Some(scene.scene.clone()))))
                }
                other => other,
            }
        }
    }
}

/// What [`start_preparation`] reads and changes of a surface: with its run-time settings
/// when it runs.
type StartParts = (
    Entity,
    &'static mut DeformableSurface,
    &'static mut SurfaceStatus,
    Option<&'static PrepareAgain>,
    Option<(&'static SurfaceMaterial, &'static SurfaceStepper)>,
    Has<SurfaceNetwork>,
);

/// What [`finish_preparation`] reads and changes of a surface: with its run-time settings
/// when it runs.
type FinishParts = (
    Entity,
    &'static mut PreparationTask,
    &'static mut PreparationProgress,
    &'static mut SurfaceStatus,
    &'static mut DeformableSurface,
    Option<(&'static SurfaceMaterial, &'static SurfaceStepper)>,
);

/// Starts preparing surfaces whose status is `Pending` (or `Loading`, once their files
/// are in).
pub(crate) fn start_preparation(
    mut commands: Commands,
    pool: Option<Res<PreparationPool>>,
    server: Option<Res<AssetServer>>,
    scenes: Option<Res<Assets<SceneAsset>>>,
    clouds: Option<Res<Assets<CloudAsset>>>,
    mut surfaces: Query<StartParts>,
) {
    for (entity, mut surface, mut status, again, running, prepared) in &mut surfaces {
        if *status == SurfaceStatus::Pending && prepared && again.is_none() {
            // The status is the plugin's report: a game that set it back to `Pending` to
            // prepare again is told the one way, and the surface runs on.
            warn!(
                "{entity}: SurfaceStatus is the plugin's report, not a request; insert \
                 PrepareAgain to prepare a surface again (it runs on as it was)"
            );
            *status = SurfaceStatus::Ready;
            continue;
        }
        let background = again.is_some() && status.is_ready();
        // A running surface's material and solver settings are its components' (their one
        // owner): preparing again keeps them.
        let again = again.map(|a| match running.filter(|_| background) {
            Some((material, stepper)) => SurfaceConfig {
                material: material.0,
                solver: *stepper.config(),
                ..a.0
            },
            None => a.0,
        });
        let fresh = match *status {
            SurfaceStatus::Pending | SurfaceStatus::Loading => true,
            SurfaceStatus::Failed(_) => again.is_some(),
            SurfaceStatus::Preparing | SurfaceStatus::Ready => false,
        };
        if !(background || fresh) {
            continue;
        }
        let found = inputs(
            &surface.source,
            server.as_deref(),
            scenes.as_deref(),
            clouds.as_deref(),
        );
        let (cloud, mut scene) = match found {
            Inputs::Ready(found) => *found,
            Inputs::Waiting => {
                if !background {
                    status.set_if_neq(SurfaceStatus::Loading);
                }
                continue;
            }
            Inputs::Failed(error) => {
                refuse(&mut commands, entity, &mut status, background, error);
                continue;
            }
        };
        let pool = match PreparationPool::get_or_build(&mut commands, pool.as_deref()) {
            Ok(pool) => pool,
            Err(e) => {
                let error = SurfaceError::ThreadPool(Arc::new(e));
                refuse(&mut commands, entity, &mut status, background, error);
                continue;
            }
        };
        let mut config = again.unwrap_or(surface.config);
        if let Some(scene) = &mut scene {
            if let Some(again) = &again {
                scene.set_surface_config(again);
            }
            config = scene.surface_config();
        }
        if again.is_some() {
            commands
                .entity(entity)
                .remove::<(PrepareAgain, PrepareAgainFailed)>();
        }
        if !background {
            surface.config = config;
        }
        let shared = Arc::new(Shared::default());
        let task_shared = shared.clone();
        let file = surface.prepared_file.clone();
        let task = AsyncComputeTaskPool::get().spawn(async move {
            pool.0
                .install(|| prepare(cloud, scene, &config, file.as_deref(), &task_shared))
        });
        commands.entity(entity).insert((
            PreparationTask {
                task,
                shared,
                background: background.then_some(config),
            },
            PreparationProgress::at(Stage::Normals, 0.0),
        ));
        if !background {
            *status = SurfaceStatus::Preparing;
        }
    }
}

/// A preparation that could not start: a fresh one fails the surface; one in the background
/// leaves the running surface as it is and says why in [`PrepareAgainFailed`]. The request
/// is dropped either way (it would fail the same way again).
fn refuse(
    commands: &mut Commands,
    entity: Entity,
    status: &mut SurfaceStatus,
    background: bool,
    error: SurfaceError,
) {
    commands.entity(entity).remove::<PrepareAgain>();
    if background {
        failed_again(commands, entity, error);
    } else {
        *status = SurfaceStatus::Failed(error);
    }
}

/// A [`PrepareAgain`] failed: the old simulation runs on; [`PrepareAgainFailed`] and
/// [`SurfaceFailed`] say why.
fn failed_again(commands: &mut Commands, entity: Entity, error: SurfaceError) {
    error!("point-springs surface {entity}: preparing again: {error}");
    commands
        .entity(entity)
        .insert(PrepareAgainFailed(error.clone()));
    commands.trigger(SurfaceFailed {
        entity,
        error,
        still_running: true,
    });
}

/// The job itself: the scene's preparation (pins and timeline included) or the plain
/// pipeline, through the prepared file when the surface has one.
fn prepare(
    cloud: PointCloud,
    scene: Option<Scene>,
    config: &SurfaceConfig,
    file: Option<&Path>,
    shared: &Shared,
) -> Result<Prepared, SurfaceError> {
    let mut progress = |p: Progress| shared.report(p);
    // What the file must have been prepared from: the cloud, the settings, and the scene.
    let source = file.map(|_| {
        let scene_bytes = scene
            .as_ref()
            .and_then(|s| postcard::to_stdvec(s).ok())
            .unwrap_or_default();
        SourceFingerprint::with_extra(&cloud, config, &scene_bytes)
    });
    let mut outcome = None;
    let surface = match (file, source) {
        (Some(path), Some(source)) => match read_prepared(path, source) {
            Ok(surface) => {
                info!("point-springs: {} read, not prepared", path.display());
                outcome = Some(PreparedFileOutcome::Read);
                surface
            }
            Err(refused) => {
                let refused = (!refused.is_missing()).then(|| {
                    warn!(
                        "point-springs: {} not used ({refused}): preparing from the source",
                        path.display()
                    );
                    Arc::new(refused)
                });
                let surface = prepare_unpinned(cloud, scene.as_ref(), config, &mut progress)?;
                outcome = Some(match write_prepared(path, &surface, source) {
                    Ok(()) => PreparedFileOutcome::Written { refused },
                    Err(e) => {
                        warn!("point-springs: cannot keep the preparation: {e}");
                        PreparedFileOutcome::NotWritten {
                            refused,
                            error: Arc::new(e),
                        }
                    }
                });
                surface
            }
        },
        _ => prepare_unpinned(cloud, scene.as_ref(), config, &mut progress)?,
    };
    let (surface, timeline) = match &scene {
        Some(scene) => scene.pin_prepared(surface).map(|(s, t)| (s, Some(t)))?,
        None => (surface, None),
    };
    Ok(Prepared {
        surface,
        timeline,
        file: outcome,
    })
}

/// The surface prepared, before a scene's pins hold it.
fn prepare_unpinned(
    cloud: PointCloud,
    scene: Option<&Scene>,
    config: &SurfaceConfig,
    progress: &mut dyn FnMut(Progress) -> ControlFlow<()>,
) -> Result<PreparedSurface, SurfaceError> {
    Ok(match scene {
        Some(scene) => scene.prepare_unpinned(cloud, progress)?,
        None => prepare_surface(cloud, config, progress)?,
    })
}

/// Reports progress and collects finished preparations: the simulation's components go in,
/// or the status says why it failed.
pub(crate) fn finish_preparation(
    mut commands: Commands,
    mut grabs: ResMut<Grabs>,
    mut surfaces: Query<FinishParts>,
) {
    for (entity, mut task, mut progress, mut status, mut surface, running) in &mut surfaces {
        let expected = if task.background.is_some() {
            SurfaceStatus::Ready
        } else {
            SurfaceStatus::Preparing
        };
        if *status != expected {
            // Set back to Pending (or failed elsewhere) while preparing: drop the job.
            commands
                .entity(entity)
                .remove::<(PreparationTask, PreparationProgress)>();
            continue;
        }
        progress.set_if_neq(task.shared.progress());
        let Some(result) = check_ready(&mut task.task) else {
            continue;
        };
        let mut entity_commands = commands.entity(entity);
        entity_commands.remove::<(PreparationTask, PreparationProgress)>();
        match result {
            Ok(mut prepared) => {
                if let Some(mut config) = task.background {
                    // The material and solver settings as they are now: a game may have
                    // changed them while the preparation ran (their components own them).
                    if let Some((material, stepper)) = running {
                        config.material = material.0;
                        config.solver = *stepper.config();
                        prepared.keep_running_settings(&config);
                    }
                    surface.config = config;
                    // The old anchors go with the old simulation: so do grabs holding them.
                    grabs.forget_surface(entity);
                }
                insert_simulation(&mut entity_commands, prepared);
                *status = SurfaceStatus::Ready;
                commands.trigger(SurfaceReady {
                    entity,
                    again: task.background.is_some(),
                });
            }
            Err(error) if task.background.is_some() => failed_again(&mut commands, entity, error),
            Err(error) => *status = SurfaceStatus::Failed(error),
        }
    }
}

/// Inserts the components of a prepared surface (replacing those of an earlier
/// preparation).
fn insert_simulation(entity: &mut EntityCommands, prepared: Prepared) {
    let PreparedSurface {
        config,
        network,
        solver,
        dense,
        ..
    } = prepared.surface;
    let points = solver.points.len();
    entity.insert((
        SimulationPoints(solver.points),
        SurfaceMasses(solver.masses),
        SurfaceSprings(solver.springs),
        SurfaceAnchors(solver.anchors),
        SurfaceForces(ExternalForces::zeros(points)),
        SurfaceStepper(solver.stepper, false),
        SurfaceMaterial(config.material),
        SurfaceNetwork(Arc::new(network)),
        DenseSurface(dense),
    ));
    match solver.pressure {
        Some(pressure) => entity.insert(SurfacePressure(pressure)),
        None => entity.remove::<SurfacePressure>(),
    };
    match prepared.timeline {
        Some(timeline) => entity.insert(SceneTimeline(timeline)),
        None => entity.remove::<SceneTimeline>(),
    };
    match prepared.file {
        Some(outcome) => entity.insert(outcome),
        None => entity.remove::<PreparedFileOutcome>(),
    };
    entity.remove::<SurfaceBaked>();
}
