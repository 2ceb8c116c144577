//! Modelling requests (issue 17): bake a surface's current shape into its rest shape,
//! export its deformed dense surface to a PLY file, or reset it to its rest shape. Send a
//! [`ModelMessage`]; it is read at the start of the next tick's
//! [`Forces`](super::PointSpringsSystems::Forces) set, and a [`ModelOutcome`] says how it
//! went (a failure is also logged; the surface runs on unchanged).
//!
//! **Off the tick.** A reset is done there and then. A bake or an export takes what it needs
//! of the surface in O(simulation points) (the dense surface's transfer is shared, not
//! copied) and runs on Bevy's async compute pool while the surface runs on; its outcome
//! comes in a later tick. A finished bake puts the surface in the shape it had when the
//! request was read, still, with that shape as its rest shape: the ticks in between are
//! dropped. A bake whose surface was prepared again, reset, or had a saved game loaded onto
//! it meanwhile is dropped ([`ModelError::Superseded`]: the later request wins), and one
//! surface bakes once at a time ([`ModelError::Busy`]). A despawned surface's work is
//! dropped with it, and each request still gets its outcome ([`ModelError::Despawned`]).
//!
//! ```no_run
//! use bevy::prelude::*;
//! use bevy_point_springs::prelude::*;
//!
//! fn keep_the_shape(mut requests: MessageWriter<ModelMessage>, surface: Single<Entity, With<DeformableSurface>>) {
//!     requests.write(ModelMessage::Bake { surface: *surface });
//!     requests.write(ModelMessage::Export { surface: *surface, path: "sculpted.ply".into() });
//! }
//! ```

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use bevy::ecs::entity::EntityHashMap;
use bevy::prelude::*;
use bevy::tasks::futures::check_ready;
use bevy::tasks::{AsyncComputeTaskPool, Task};

use super::components::{
    DenseSurface, SceneTimeline, SimulationPoints, SurfaceAnchors, SurfaceMasses, SurfaceMaterial,
    SurfaceNetwork, SurfacePressure, SurfaceSleep, SurfaceSprings, SurfaceStatus, SurfaceTimings,
};
use super::prepare::PreparationPool;
use super::save::SurfaceBaked;
use crate::core::cloud::io::PlyEncoding;
use crate::core::network::SpringNetwork;
use crate::core::pipeline::{BakeJob, Baked, ExportError, PrepareError};
use crate::core::solver::SolverError;

/// A modelling request for one surface.
#[derive(Message, Debug, Clone, PartialEq)]
pub enum ModelMessage {
    /// Makes the surface's current shape its rest shape: rest lengths, masses and normals
    /// measured anew, velocities zero, the dense surface's rest shape its deformed one (see
    /// [`bake`](crate::core::pipeline::bake)). Stiffness, plasticity, pins and grabs are kept.
    Bake {
        /// The surface.
        surface: Entity,
    },
    /// Writes the surface's deformed dense surface (positions and normals, in the surface's
    /// own coordinates) to `path` as binary PLY, beside it first and then renamed into
    /// place, so a failure never leaves a truncated file.
    Export {
        /// The surface.
        surface: Entity,
        /// The PLY file to write.
        path: PathBuf,
    },
    /// Puts the surface back in its rest shape (as prepared, or as last baked): points at
    /// their rest positions and still, springs at their rest lengths (plastic flow since
    /// then undone), a scene's timeline started again. Pins, masses and the game's anchors
    /// (grabs) are kept.
    Reset {
        /// The surface.
        surface: Entity,
    },
}

impl ModelMessage {
    /// The surface the request is for.
    pub fn surface(&self) -> Entity {
        match self {
            Self::Bake { surface } | Self::Export { surface, .. } | Self::Reset { surface } => {
                *surface
            }
        }
    }
}

/// How a [`ModelMessage`] went.
#[derive(Message, Debug, Clone, PartialEq)]
pub struct ModelOutcome {
    /// The request.
    pub request: ModelMessage,
    /// `Err` with the reason when it was refused or failed (nothing changed then).
    pub result: Result<(), ModelError>,
}

/// Why a [`ModelMessage`] was refused or failed.
#[derive(Debug, Clone, thiserror::Error)]
pub enum ModelError {
    /// The entity is not a prepared surface.
    #[error("{0} is not a prepared surface")]
    NotASurface(Entity),
    /// The surface is not ready (still preparing, or failed).
    #[error("{0} is not ready")]
    NotReady(Entity),
    /// A bake of the surface is already under way.
    #[error("{0} is already being baked")]
    Busy(Entity),
    /// The surface was prepared again, reset, or had a saved game loaded onto it, while its
    /// bake ran: the bake was dropped.
    #[error("{0} changed while it was being baked: the bake was dropped")]
    Superseded(Entity),
    /// The surface was despawned while its bake or export ran: the work was dropped.
    #[error("{0} was despawned while its bake or export ran: the work was dropped")]
    Despawned(Entity),
    /// No thread pool for the work could be built.
    #[error("no thread pool: {0}")]
    ThreadPool(Arc<rayon::ThreadPoolBuildError>),
    /// The bake could not rebuild the surface.
    #[error(transparent)]
    Bake(PrepareError),
    /// The export could not be written.
    #[error(transparent)]
    Export(Arc<ExportError>),
    /// The reset could not put the surface at rest.
    #[error(transparent)]
    Reset(SolverError),
}

impl PartialEq for ModelError {
    /// The same variant with equal contents; errors held in an `Arc` (which cannot be
    /// compared) equal only themselves.
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (Self::NotASurface(a), Self::NotASurface(b))
            | (Self::NotReady(a), Self::NotReady(b))
            | (Self::Busy(a), Self::Busy(b))
            | (Self::Superseded(a), Self::Superseded(b))
            | (Self::Despawned(a), Self::Despawned(b)) => a == b,
            (Self::ThreadPool(a), Self::ThreadPool(b)) => Arc::ptr_eq(a, b),
            (Self::Bake(a), Self::Bake(b)) => a == b,
            (Self::Export(a), Self::Export(b)) => Arc::ptr_eq(a, b),
            (Self::Reset(a), Self::Reset(b)) => a == b,
            _ => false,
        }
    }
}

/// The parts of a surface a request reads or changes.
type ModelParts = (
    &'static mut SurfaceNetwork,
    &'static mut SimulationPoints,
    &'static mut SurfaceSprings,
    &'static mut SurfaceMasses,
    Option<&'static mut SurfacePressure>,
    &'static mut DenseSurface,
    &'static SurfaceMaterial,
    &'static SurfaceStatus,
    &'static mut SurfaceAnchors,
    Option<&'static mut SceneTimeline>,
    &'static mut SurfaceSleep,
    Option<&'static mut ModelWork>,
);

/// What a background request hands back.
enum Done {
    Baked(Box<Baked>),
    Exported,
}

/// A bake or export under way.
struct Running {
    request: ModelMessage,
    task: Task<Result<Done, ModelError>>,
    /// A bake's: the network it was taken from (the surface must still have it).
    network: Option<Arc<SpringNetwork>>,
    /// A bake's: a saved game was loaded onto the surface meanwhile.
    superseded: bool,
}

/// A surface's bakes and exports under way (dropping it drops them).
#[derive(Component, Default)]
pub(crate) struct ModelWork(Vec<Running>);

impl ModelWork {
    fn baking(&self) -> bool {
        self.0.iter().any(|r| r.network.is_some())
    }

    /// Marks the bakes under way superseded: they were taken from a state since replaced.
    fn supersede_bakes(&mut self) {
        for running in self.0.iter_mut().filter(|r| r.network.is_some()) {
            running.superseded = true;
        }
    }
}

/// A saved game loaded onto `surface` drops the bakes under way on it
/// ([`ModelError::Superseded`]): they were taken from the state the load replaced.
pub(crate) fn supersede_bakes(commands: &mut Commands, surface: Entity) {
    commands
        .entity(surface)
        .queue(|mut entity: EntityWorldMut| {
            if let Some(mut work) = entity.get_mut::<ModelWork>() {
                work.supersede_bakes();
            }
        });
}

/// Reads the tick's modelling requests, in the order they were sent: resets are done,
/// bakes and exports started in the background.
pub(crate) fn apply_model_requests(
    mut requests: MessageReader<ModelMessage>,
    mut outcomes: MessageWriter<ModelOutcome>,
    mut surfaces: Query<ModelParts>,
    pool: Option<Res<PreparationPool>>,
    mut commands: Commands,
    mut timings: Query<&mut SurfaceTimings>,
) {
    for mut timings in &mut timings {
        if timings.model_ms != 0.0 {
            timings.model_ms = 0.0;
        }
    }
    // Work started this tick on surfaces that had none under way (inserted at the end).
    let mut fresh: EntityHashMap<ModelWork> = EntityHashMap::default();
    for request in requests.read() {
        let start = Instant::now();
        let surface = request.surface();
        let started = match PreparationPool::get_or_build(&mut commands, pool.as_deref()) {
            Ok(pool) => carry_out(request, &mut surfaces, &pool, fresh.get_mut(&surface)),
            Err(e) => Err(ModelError::ThreadPool(Arc::new(e))),
        };
        match started {
            Ok(Some(running)) => match surfaces.get_mut(surface).ok().and_then(|p| p.11) {
                Some(mut work) => work.0.push(running),
                None => fresh.entry(surface).or_default().0.push(running),
            },
            Ok(None) => report(&mut outcomes, request.clone(), Ok(())),
            Err(e) => report(&mut outcomes, request.clone(), Err(e)),
        }
        if let Ok(mut timings) = timings.get_mut(surface) {
            timings.model_ms += ms_since(start);
        }
    }
    for (surface, work) in fresh {
        commands.entity(surface).try_insert(work);
    }
}

/// Sends an outcome, logging a failure.
fn report(
    outcomes: &mut MessageWriter<ModelOutcome>,
    request: ModelMessage,
    result: Result<(), ModelError>,
) {
    if let Err(e) = &result {
        error!("point-springs: {request:?} failed: {e}");
    }
    outcomes.write(ModelOutcome { request, result });
}

/// One request on its surface: a reset done, a bake or export started.
fn carry_out(
    request: &ModelMessage,
    surfaces: &mut Query<ModelParts>,
    pool: &PreparationPool,
    fresh: Option<&mut ModelWork>,
) -> Result<Option<Running>, ModelError> {
    let surface = request.surface();
    let Ok((
        network,
        mut points,
        mut springs,
        masses,
        pressure,
        dense,
        material,
        status,
        mut anchors,
        timeline,
        mut sleep,
        work,
    )) = surfaces.get_mut(surface)
    else {
        return Err(ModelError::NotASurface(surface));
    };
    if !status.is_ready() {
        return Err(ModelError::NotReady(surface));
    }
    let pool = pool.0.clone();
    match request {
        ModelMessage::Bake { .. } => {
            if work.is_some_and(|w| w.baking()) || fresh.is_some_and(|w| w.baking()) {
                return Err(ModelError::Busy(surface));
            }
            let job = BakeJob::new(
                network.0.clone(),
                &points,
                &springs,
                &masses,
                pressure.as_deref().map(|p| &p.0),
                &dense,
                material.density,
            );
            let task = AsyncComputeTaskPool::get().spawn(async move {
                pool.install(|| job.run())
                    .map(|baked| Done::Baked(Box::new(baked)))
                    .map_err(ModelError::Bake)
            });
            Ok(Some(Running {
                request: request.clone(),
                task,
                network: Some(network.0.clone()),
                superseded: false,
            }))
        }
        ModelMessage::Export { path, .. } => {
            // The current shape, even where the transfer waited (out of view, per frame).
            let job = dense.job(&points);
            let path = path.clone();
            let task = AsyncComputeTaskPool::get().spawn(async move {
                pool.install(|| job.export(&path, PlyEncoding::BinaryLittleEndian))
                    .map(|()| Done::Exported)
                    .map_err(|e| ModelError::Export(Arc::new(e)))
            });
            Ok(Some(Running {
                request: request.clone(),
                task,
                network: None,
                superseded: false,
            }))
        }
        ModelMessage::Reset { .. } => {
            reset(&network, &mut points, &mut springs).map_err(ModelError::Reset)?;
            // A bake under way was taken from the shape the reset discards: the later
            // request wins.
            if let Some(mut work) = work {
                work.supersede_bakes();
            }
            if let Some(work) = fresh {
                work.supersede_bakes();
            }
            if let Some(mut timeline) = timeline {
                timeline.0.restart(&mut anchors);
            }
            // The rest shape need not be at rest under gravity or pins: awake, it settles.
            sleep.wake();
            Ok(None)
        }
    }
}

/// Puts the points at their rest positions, still, and the springs at rest.
fn reset(
    network: &SurfaceNetwork,
    points: &mut SimulationPoints,
    springs: &mut SurfaceSprings,
) -> Result<(), SolverError> {
    springs.0.set_rest_lengths(|i| network.rest_length(i))?;
    for (i, &p) in network.positions.iter().enumerate() {
        points.set_position(i, p)?;
    }
    points.stop();
    if !springs.hinges().is_empty() {
        // Plastic flow moved the rest angles too: measured again on the rest shape.
        springs.0.set_rest_angles(points)?;
    }
    Ok(())
}

/// Collects finished bakes and exports: a bake's parts go in (if the surface is still the
/// one it was taken from), and the outcome is sent.
pub(crate) fn finish_model_work(
    mut outcomes: MessageWriter<ModelOutcome>,
    mut surfaces: Query<(Entity, ModelParts)>,
    mut commands: Commands,
    mut timings: Query<&mut SurfaceTimings>,
) {
    for (entity, parts) in &mut surfaces {
        let Some(mut work) = parts.11 else {
            continue;
        };
        let start = Instant::now();
        let mut finished = Vec::new();
        work.0
            .retain_mut(|running| match check_ready(&mut running.task) {
                Some(result) => {
                    let from = running.network.take().filter(|_| !running.superseded);
                    finished.push((running.request.clone(), from, result));
                    false
                }
                None => true,
            });
        if work.0.is_empty() {
            commands.entity(entity).try_remove::<ModelWork>();
        }
        if finished.is_empty() {
            continue;
        }
        let (
            mut network,
            mut points,
            mut springs,
            mut masses,
            mut pressure,
            mut dense,
            material,
            status,
            ..,
        ) = parts;
        for (request, from, result) in finished {
            let result = result.and_then(|done| match done {
                Done::Exported => Ok(()),
                Done::Baked(baked) => {
                    let same = from.is_some_and(|from| Arc::ptr_eq(&from, &network.0));
                    if !(same && status.is_ready()) {
                        return Err(ModelError::Superseded(entity));
                    }
                    let Baked {
                        network: new_network,
                        points: new_points,
                        springs: new_springs,
                        masses: new_masses,
                        pressure: new_pressure,
                        dense: new_dense,
                    } = *baked;
                    use std::mem::replace;
                    // The old parts are freed on another thread: freeing a large dense
                    // surface's arrays is not the tick's work either.
                    let old = (
                        replace(&mut network.0, Arc::new(new_network)),
                        replace(&mut points.0, new_points),
                        replace(&mut springs.0, new_springs),
                        replace(&mut masses.0, new_masses),
                        replace(&mut dense.0, new_dense),
                    );
                    AsyncComputeTaskPool::get()
                        .spawn(async move { drop(old) })
                        .detach();
                    if let (Some(gas), Some(new)) = (pressure.as_deref_mut(), new_pressure) {
                        gas.0 = new;
                    }
                    // A saved game carries a baked surface's rest shape.
                    let density = material.density;
                    commands.entity(entity).try_insert(SurfaceBaked { density });
                    Ok(())
                }
            });
            report(&mut outcomes, request, result);
        }
        if let Ok(mut timings) = timings.get_mut(entity) {
            timings.model_ms += ms_since(start);
        }
    }
}

/// A surface despawned with bakes or exports under way: each request still gets its
/// outcome, [`ModelError::Despawned`]. (Work that finished took its entries out first.)
pub(crate) fn report_dropped_work(
    removed: On<Remove, ModelWork>,
    works: Query<&ModelWork>,
    mut outcomes: MessageWriter<ModelOutcome>,
) {
    let surface = removed.entity;
    let Ok(work) = works.get(surface) else {
        return;
    };
    for running in &work.0 {
        let error = ModelError::Despawned(surface);
        report(&mut outcomes, running.request.clone(), Err(error));
    }
}

/// Milliseconds since `start`.
fn ms_since(start: Instant) -> f32 {
    start.elapsed().as_secs_f32() * 1e3
}
