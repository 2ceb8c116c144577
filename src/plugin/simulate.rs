//! The systems of a tick, in the chained sets of
//! [`PointSpringsSystems`](super::PointSpringsSystems):
//!
//! * `Forces`: scene timelines move their anchors, material changes reach the springs, then
//!   each surface's own forces (springs, gravity, drag, anchors, pressure) are accumulated.
//!   A game's systems in this set add to [`SurfaceForces`].
//! * `Integrate`: sleeping surfaces that something acted on wake
//!   ([`sleep`](super::sleep)); the game's forces are added and each awake surface takes
//!   one step of the tick's length (sub-stepped where an explicit integrator needs it); the
//!   game's forces are then cleared; springs of a plastic material flow; surfaces that
//!   stayed still go to sleep.
//! * `Transfer`: resampling when due, then the dense surface follows the simulation points
//!   — skipped when they did not move, and deferred to the frame with
//!   [`TransferTiming::PerFrame`].
//!
//! Surfaces are independent, so the per-surface work of `Forces` and `Integrate` runs in
//! parallel over surfaces on Bevy's compute pool; a large dense surface splits its transfer
//! over the same pool.

use bevy::prelude::*;
use bevy::tasks::ComputeTaskPool;

use crate::core::pipeline::DenseCloud;
use crate::core::solver::{PointState, SpringMaterial};
use crate::core::transfer::TransferError;

use super::components::{
    DenseSurface, ModelQuery, SceneTimeline, SimulationPoints, SurfaceAnchors, SurfaceForces,
    SurfaceMaterial, SurfaceNetwork, SurfaceSettings, SurfaceSleep, SurfaceSprings, SurfaceStatus,
    SurfaceStepper, SurfaceWork, TransferTiming,
};

/// Dense surfaces up to this many points follow the simulation on the calling thread
/// (handing the work to other threads costs more than it saves).
pub const PARALLEL_TRANSFER_POINTS: usize = 16_384;

/// Whether a surface steps this tick.
fn running(status: &SurfaceStatus, settings: &SurfaceSettings) -> bool {
    status.is_ready() && !settings.paused
}

/// Marks a surface failed and says why in the log.
fn fail(entity: Entity, status: &mut SurfaceStatus, what: &str, error: impl std::fmt::Display) {
    error!("point-springs surface {entity}: {what}: {error}");
    *status = SurfaceStatus::Failed(format!("{what}: {error}"));
}

/// Scene pulls and pokes act on their schedule.
pub(crate) fn drive_timelines(
    mut surfaces: Query<(
        Entity,
        &mut SceneTimeline,
        &mut SurfaceAnchors,
        &SurfaceNetwork,
        &mut SurfaceStatus,
        &SurfaceSettings,
    )>,
) {
    for (entity, mut timeline, mut anchors, network, mut status, settings) in &mut surfaces {
        if !running(&status, settings) || timeline.finished() {
            continue;
        }
        if let Err(e) = timeline.advance(&mut anchors, &network.positions) {
            fail(entity, &mut status, "scene timeline", e);
        }
    }
}

/// A changed material sets the stiffness, damping and plasticity of every spring.
pub(crate) fn apply_materials(
    mut surfaces: Query<
        (
            Entity,
            &SurfaceMaterial,
            &SurfaceNetwork,
            &mut SurfaceSprings,
        ),
        Changed<SurfaceMaterial>,
    >,
) {
    for (entity, material, network, mut springs) in &mut surfaces {
        let material: SpringMaterial = material.0;
        let stretch = network.stretch.len();
        let applied = springs
            .set_parameters(|i| material.parameters(i, stretch))
            .and_then(|()| springs.set_plasticity(material.plasticity()));
        if let Err(e) = applied {
            // Refused: the springs keep their old parameters and the surface runs on.
            error!("point-springs surface {entity}: material not applied: {e}");
        }
    }
}

/// Each surface's own forces at the state the tick starts from.
pub(crate) fn accumulate_forces(
    mut surfaces: Query<(
        Entity,
        &SimulationPoints,
        ModelQuery,
        &mut SurfaceStepper,
        &mut SurfaceStatus,
        &SurfaceSettings,
        &SurfaceSleep,
    )>,
) {
    surfaces.par_iter_mut().for_each(
        |(entity, points, parts, mut stepper, mut status, settings, sleep)| {
            if !running(&status, settings) || sleep.asleep {
                return;
            }
            if let Err(e) = stepper.accumulate_forces(points, parts.model()) {
                fail(entity, &mut status, "forces", e);
            }
        },
    );
}

/// What [`integrate`] reads and changes of a surface.
type StepParts = (
    Entity,
    &'static mut SimulationPoints,
    ModelQuery,
    &'static mut SurfaceForces,
    &'static mut SurfaceStepper,
    &'static mut SurfaceStatus,
    &'static SurfaceSettings,
    &'static SurfaceSleep,
    &'static mut SurfaceWork,
);

/// Each surface steps by the tick's length with the game's forces added; the game's forces
/// are then cleared. The work is counted in [`SurfaceWork`].
pub(crate) fn integrate(time: Res<Time>, mut surfaces: Query<StepParts>) {
    let dt = time.delta_secs();
    surfaces.par_iter_mut().for_each(
        |(
            entity,
            mut points,
            parts,
            mut forces,
            mut stepper,
            mut status,
            settings,
            sleep,
            mut work,
        )| {
            if !running(&status, settings) || sleep.asleep {
                return;
            }
            match stepper.advance(&mut points, parts.model(), &forces, dt) {
                Ok(report) => {
                    work.steps += 1;
                    work.springs_evaluated +=
                        u64::from(report.substeps) * parts.model().springs.len() as u64;
                }
                Err(e) => fail(entity, &mut status, "step", e),
            }
            forces.clear();
        },
    );
}

/// Plastic flow after each step of a surface whose material yields (rest lengths creep
/// towards the strain beyond yield; see [`Springs::flow`](crate::core::solver::Springs::flow)).
pub(crate) fn plastic_flow(
    time: Res<Time>,
    mut surfaces: Query<(
        &SimulationPoints,
        &mut SurfaceSprings,
        &SurfaceStatus,
        &SurfaceSettings,
        &SurfaceSleep,
    )>,
) {
    let dt = time.delta_secs();
    surfaces
        .par_iter_mut()
        .for_each(|(points, mut springs, status, settings, sleep)| {
            if running(status, settings) && !sleep.asleep && !springs.plasticity().is_elastic() {
                springs.flow(points, dt);
            }
        });
}

/// Resampling when due, then (every tick) the transfer.
pub(crate) fn transfer_tick(
    mut surfaces: Query<(
        Entity,
        &SimulationPoints,
        &SurfaceStepper,
        &mut DenseSurface,
        &mut SurfaceStatus,
        &SurfaceSettings,
        &mut SurfaceWork,
    )>,
) {
    for (entity, points, stepper, mut dense, mut status, settings, mut work) in &mut surfaces {
        if !status.is_ready() {
            continue;
        }
        let steps = stepper.diagnostics().steps;
        if let Err(e) = dense.maintain(points, steps) {
            fail(entity, &mut status, "resampling", e);
            continue;
        }
        if settings.transfer == TransferTiming::EveryTick {
            follow_counted(entity, &mut dense, points, &mut status, &mut work);
        }
    }
}

/// [`follow`], counting the dense points carried in `work`; a failure fails the surface.
fn follow_counted(
    entity: Entity,
    dense: &mut DenseCloud,
    points: &PointState,
    status: &mut SurfaceStatus,
    work: &mut SurfaceWork,
) {
    match follow(dense, points) {
        Ok(true) => work.points_transferred += dense.len() as u64,
        Ok(false) => {}
        Err(e) => fail(entity, status, "transfer", e),
    }
}

/// The transfer of surfaces that follow once per rendered frame.
pub(crate) fn transfer_frame(
    mut surfaces: Query<(
        Entity,
        &SimulationPoints,
        &mut DenseSurface,
        &mut SurfaceStatus,
        &SurfaceSettings,
        &mut SurfaceWork,
    )>,
) {
    for (entity, points, mut dense, mut status, settings, mut work) in &mut surfaces {
        if status.is_ready() && settings.transfer == TransferTiming::PerFrame {
            follow_counted(entity, &mut dense, points, &mut status, &mut work);
        }
    }
}

/// Carries the simulation points' state to the dense points, on Bevy's compute pool when
/// the surface is large. Returns whether anything was computed (false: the points did not
/// move since the last frame).
pub fn follow(dense: &mut DenseCloud, points: &PointState) -> Result<bool, TransferError> {
    if !dense.begin_frame(points)? {
        return Ok(false);
    }
    let parts = dense.frame_parts();
    let n = parts.positions.len();
    let pool = ComputeTaskPool::get();
    // The calling thread works on the scope's tasks too, so even a one-thread pool halves
    // the work.
    if n <= PARALLEL_TRANSFER_POINTS {
        parts
            .transfer
            .frame_rows(parts.input, 0, parts.positions, parts.normals)?;
    } else {
        // A few pieces per thread, so that a thread busy elsewhere delays little.
        let chunk = n.div_ceil(4 * (pool.thread_num() + 1)).max(1024);
        let (transfer, input) = (parts.transfer, parts.input);
        let results = pool.scope(|scope| {
            let pieces = parts
                .positions
                .chunks_mut(chunk)
                .zip(parts.normals.chunks_mut(chunk));
            for (i, (positions, normals)) in pieces.enumerate() {
                scope.spawn(
                    async move { transfer.frame_rows(input, i * chunk, positions, normals) },
                );
            }
        });
        results.into_iter().collect::<Result<(), _>>()?;
    }
    dense.finish_frame();
    Ok(true)
}
