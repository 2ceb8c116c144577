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
//!   — skipped when they did not move or no camera sees the surface ([`SurfaceInView`]),
//!   and deferred to the frame with [`TransferTiming::PerFrame`].
//!
//! Each surface's share of the tick is timed in [`SurfaceTimings`]; a paused surface with
//! [`StepOnce`] takes a single step.
//!
//! Surfaces are independent, so the per-surface work of `Forces` and `Integrate` runs in
//! parallel over surfaces on Bevy's compute pool; a large dense surface splits its transfer
//! over the same pool.

use std::time::Instant;

use bevy::prelude::*;
use bevy::tasks::ComputeTaskPool;

use crate::core::pipeline::DenseCloud;
use crate::core::solver::{Masses, PointState, SolverError, SpringMaterial};
use crate::core::transfer::TransferError;

use super::components::{
    DenseSurface, GpuTransferInput, PreviousTick, SceneTimeline, SimulationPoints, StepOnce,
    StepPartsQuery, SurfaceAnchors, SurfaceForces, SurfaceInView, SurfaceMasses, SurfaceMaterial,
    SurfaceNetwork, SurfaceRunSettings, SurfaceSleep, SurfaceSprings, SurfaceStatus,
    SurfaceStepper, SurfaceTimings, SurfaceWork, TransferTiming,
};
use super::lifecycle::SurfaceError;

/// Dense surfaces up to this many points follow the simulation on the calling thread
/// (handing the work to other threads costs more than it saves).
pub(crate) const PARALLEL_TRANSFER_POINTS: usize = 16_384;

/// Whether a surface steps this tick: ready, and not paused unless asked for one step
/// ([`StepOnce`]).
pub(crate) fn running(
    status: &SurfaceStatus,
    settings: &SurfaceRunSettings,
    step_once: bool,
) -> bool {
    status.is_ready() && (!settings.paused || step_once)
}

/// What [`running`] reads besides the status: the settings, and whether one step was asked
/// for.
pub(crate) type Gate = (&'static SurfaceRunSettings, Has<StepOnce>);

/// What [`accumulate_forces`] reads and changes of a surface.
type ForceParts = (
    &'static SimulationPoints,
    StepPartsQuery,
    &'static mut SurfaceStepper,
    &'static mut SurfaceStatus,
    Gate,
    &'static SurfaceSleep,
    &'static mut SurfaceTimings,
);

/// What [`plastic_flow`] reads and changes of a surface.
type FlowParts = (
    &'static SimulationPoints,
    &'static mut SurfaceSprings,
    &'static SurfaceStatus,
    Gate,
    &'static SurfaceSleep,
    &'static mut SurfaceTimings,
);

/// Milliseconds since `start`.
fn ms_since(start: Instant) -> f32 {
    start.elapsed().as_secs_f32() * 1e3
}

/// Marks a surface failed ([`announce_failures`](super::lifecycle::announce_failures) logs
/// it and sends [`SurfaceFailed`](super::SurfaceFailed)).
fn fail(status: &mut SurfaceStatus, error: SurfaceError) {
    *status = SurfaceStatus::Failed(error);
}

/// A solver failure during `during`.
fn solver_failed(during: &'static str, error: SolverError) -> SurfaceError {
    SurfaceError::Solver { during, error }
}

/// A transfer failure during `during`.
fn transfer_failed(during: &'static str, error: TransferError) -> SurfaceError {
    SurfaceError::Transfer { during, error }
}

/// Scene pulls and pokes act on their schedule.
pub(crate) fn drive_timelines(
    mut surfaces: Query<(
        &mut SceneTimeline,
        &mut SurfaceAnchors,
        &SurfaceNetwork,
        &mut SurfaceStatus,
        Gate,
    )>,
) {
    for (mut timeline, mut anchors, network, mut status, (settings, once)) in &mut surfaces {
        if !running(&status, settings, once) || timeline.finished() {
            continue;
        }
        if let Err(e) = timeline.0.advance(&mut anchors, &network.positions) {
            fail(&mut status, solver_failed("scene timeline", e));
        }
    }
}

/// A changed material sets the stiffness, damping and plasticity of every spring, and the
/// couplings of a sheet's membrane.
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
        let specs = material.springs(network);
        let hinges = material.hinges(network);
        let curvatures = material.curvatures(network);
        let bent = springs.curvatures();
        let same_points = curvatures.len() == bent.len()
            && curvatures
                .iter()
                .zip(&bent)
                .all(|(a, b)| a.point == b.point);
        if specs.len() != springs.len() || hinges.len() != springs.hinges().len() || !same_points {
            // Another bending model builds other springs: that takes a new preparation (the
            // panel sends one), until which the surface keeps its springs.
            warn!(
                "point-springs surface {entity}: material not applied until the surface is \
                 prepared again (PrepareAgain): its bending model ({:?}) is not the one it was \
                 prepared with",
                material.bending
            );
            continue;
        }
        let rest: Vec<f32> = springs.hinges().iter().map(|h| h.rest_angle).collect();
        let applied = springs
            .0
            .set_parameters(|i| (specs[i].stiffness, specs[i].damping))
            .and_then(|()| {
                springs
                    .0
                    .set_hinge_parameters(|i| [rest[i], hinges[i].stiffness, hinges[i].damping])
            })
            .and_then(|()| springs.0.set_couplings(&material.couplings(network)))
            .and_then(|()| {
                // New modulus and damping; the rest curvatures as they are (plastic flow).
                springs.0.set_curvature_parameters(|i| {
                    let [c, d, e] = bent[i].rest;
                    [c, d, e, curvatures[i].modulus, curvatures[i].damping]
                })
            })
            .and_then(|()| springs.0.set_plasticity(material.plasticity()));
        if let Err(e) = applied {
            // Refused: the springs keep their old parameters and the surface runs on.
            error!("point-springs surface {entity}: material not applied: {e}");
        }
    }
}

/// Each surface's own forces at the state the tick starts from.
pub(crate) fn accumulate_forces(mut surfaces: Query<ForceParts>) {
    surfaces.par_iter_mut().for_each(
        |(points, parts, mut stepper, mut status, (settings, once), sleep, mut timings)| {
            if !running(&status, settings, once) || sleep.asleep {
                timings.forces_ms = 0.0;
                timings.step_ms = 0.0;
                return;
            }
            let start = Instant::now();
            if let Err(e) = stepper.0.accumulate_forces(points, parts.step_parts()) {
                fail(&mut status, solver_failed("forces", e));
            }
            timings.forces_ms = ms_since(start);
        },
    );
}

/// What [`integrate`] reads and changes of a surface.
type StepParts = (
    &'static mut SimulationPoints,
    StepPartsQuery,
    &'static mut SurfaceForces,
    &'static mut SurfaceStepper,
    &'static mut SurfaceStatus,
    Gate,
    &'static SurfaceSleep,
    (&'static mut SurfaceWork, &'static mut SurfaceTimings),
);

/// Each surface steps by the tick's length with the game's forces added; the game's forces
/// are then cleared. The work is counted in [`SurfaceWork`].
pub(crate) fn integrate(time: Res<Time>, mut surfaces: Query<StepParts>) {
    let dt = time.delta_secs();
    surfaces.par_iter_mut().for_each(
        |(
            mut points,
            parts,
            mut forces,
            mut stepper,
            mut status,
            (settings, once),
            sleep,
            (mut work, mut timings),
        )| {
            if !running(&status, settings, once) || sleep.asleep {
                // A paused surface drops what the game added meanwhile, so that it does not
                // land all at once when the surface runs again (a sleeping one woke
                // already if anything was added).
                if status.is_ready() && !forces.is_zero() {
                    forces.clear();
                }
                return;
            }
            let start = Instant::now();
            match stepper
                .0
                .advance(&mut points, parts.step_parts(), &forces, dt)
            {
                Ok(report) => {
                    work.steps += 1;
                    work.springs_evaluated +=
                        u64::from(report.substeps) * parts.step_parts().springs.len() as u64;
                }
                Err(e) => fail(&mut status, solver_failed("step", e)),
            }
            forces.clear();
            timings.step_ms = ms_since(start);
        },
    );
}

/// Plastic flow after each step of a surface whose material yields (rest lengths creep
/// towards the strain beyond yield; see [`Springs::flow`](crate::core::solver::Springs::flow)).
pub(crate) fn plastic_flow(time: Res<Time>, mut surfaces: Query<FlowParts>) {
    let dt = time.delta_secs();
    surfaces.par_iter_mut().for_each(
        |(points, mut springs, status, (settings, once), sleep, mut timings)| {
            if running(status, settings, once)
                && !sleep.asleep
                && !springs.plasticity().is_elastic()
            {
                let start = Instant::now();
                springs.0.flow(points, dt);
                timings.step_ms += ms_since(start);
            }
        },
    );
}

/// What the transfer systems read and change of a surface.
type TransferParts = (
    (
        &'static SimulationPoints,
        &'static SurfaceMasses,
        &'static mut PreviousTick,
    ),
    &'static SurfaceStepper,
    (
        &'static mut DenseSurface,
        Option<&'static mut GpuTransferInput>,
    ),
    &'static mut SurfaceStatus,
    (&'static SurfaceRunSettings, Ref<'static, SurfaceInView>),
    (&'static mut SurfaceWork, &'static mut SurfaceTimings),
);

/// Resampling when due, then (every tick) the transfer; both wait while the surface is out
/// of view. The dense points by pinned simulation points are held to the pins first
/// ([`DenseCloud::hold`]: nothing to do unless the masses changed).
pub(crate) fn transfer_tick(mut surfaces: Query<TransferParts>) {
    for (
        (points, masses, _),
        stepper,
        (mut dense, gpu),
        mut status,
        (settings, in_view),
        (mut work, mut timings),
    ) in &mut surfaces
    {
        if !status.is_ready() {
            continue;
        }
        if !in_view.0 {
            timings.transfer_ms = 0.0;
            continue;
        }
        let start = Instant::now();
        // Marked changed only where the drawn surface changes (see `follow_counted`).
        let cloud = &mut dense.bypass_change_detection().0;
        let Some(refit) = hold_or_fail(cloud, masses, &mut status) else {
            continue;
        };
        let steps = stepper.diagnostics().steps;
        let inserted = match cloud.maintain(points, steps) {
            Ok(report) => report.inserted > 0,
            Err(e) => {
                fail(&mut status, SurfaceError::Resample(e));
                continue;
            }
        };
        let mut moved = false;
        if settings.transfer == TransferTiming::EveryTick {
            match gpu {
                Some(mut gpu) => {
                    gpu.set(points);
                }
                None => moved = follow_counted(cloud, points, &mut status, &mut work),
            }
        }
        if refit || inserted || moved {
            dense.set_changed();
        }
        timings.transfer_ms = ms_since(start);
    }
}

/// [`DenseCloud::hold`] with `masses`' pins: whether the coefficients were refitted, or
/// `None` when it failed (and failed the surface).
fn hold_or_fail(
    dense: &mut DenseCloud,
    masses: &Masses,
    status: &mut SurfaceStatus,
) -> Option<bool> {
    match dense.hold(masses) {
        Ok(refit) => Some(refit),
        Err(e) => {
            fail(status, transfer_failed("holding the pins", e));
            None
        }
    }
}

/// [`follow`], counting the dense points carried in `work`; a failure fails the surface.
/// Returns whether the dense surface moved: the transfer systems mark [`DenseSurface`]
/// changed only then (or when its coefficients or points changed), so that
/// `Changed<DenseSurface>` means the drawn surface changed.
fn follow_counted(
    dense: &mut DenseCloud,
    points: &PointState,
    status: &mut SurfaceStatus,
    work: &mut SurfaceWork,
) -> bool {
    match follow(dense, points) {
        Ok(true) => {
            work.points_transferred += dense.len() as u64;
            true
        }
        Ok(false) => false,
        Err(e) => {
            fail(status, transfer_failed("transfer", e));
            false
        }
    }
}

/// The transfer of surfaces that follow once per rendered frame (and are in view), and of
/// surfaces just seen again (so that they are not drawn as they were until the next tick).
pub(crate) fn transfer_frame(time: Option<Res<Time<Fixed>>>, mut surfaces: Query<TransferParts>) {
    // Where the frame is between the last tick and the next (1: at the last tick, as
    // without a fixed clock).
    let along = time.map_or(1.0, |t| t.overstep_fraction().clamp(0.0, 1.0));
    for (
        (points, masses, mut previous),
        _,
        (mut dense, gpu),
        mut status,
        (settings, in_view),
        (mut work, mut timings),
    ) in &mut surfaces
    {
        let due = settings.transfer != TransferTiming::EveryTick || in_view.is_changed();
        if status.is_ready() && in_view.0 && due {
            let start = Instant::now();
            let cloud = &mut dense.bypass_change_detection().0;
            let Some(refit) = hold_or_fail(cloud, masses, &mut status) else {
                continue;
            };
            let drawn = if settings.transfer == TransferTiming::Interpolated {
                blend(previous.bypass_change_detection(), points, along)
            } else {
                points
            };
            let moved = match gpu {
                Some(mut gpu) => {
                    gpu.set(drawn);
                    false
                }
                None => follow_counted(cloud, drawn, &mut status, &mut work),
            };
            if refit || moved {
                dense.set_changed();
            }
            timings.transfer_ms = ms_since(start);
        }
    }
}

/// The simulation points `along` the way from where the last tick started to where it
/// ended (kept in `previous`); the points as they are where no tick has run yet or their
/// number changed.
fn blend<'a>(previous: &'a mut PreviousTick, points: &'a PointState, along: f32) -> &'a PointState {
    let PreviousTick { positions, blend } = previous;
    if positions.len() != points.len() || points.is_empty() {
        return points;
    }
    if blend.as_ref().is_none_or(|b| b.len() != points.len()) {
        *blend = PointState::new(positions).ok();
    }
    let Some(blend) = blend.as_mut() else {
        return points;
    };
    for (i, from) in positions.iter().enumerate() {
        let at = from.lerp(points.position(i), along);
        if blend.set_position(i, at).is_err() {
            return points;
        }
    }
    blend
}

/// Keeps, for surfaces drawn between ticks ([`TransferTiming::Interpolated`]), where the
/// simulation points are as the tick starts (after any change the game made since the
/// last one).
pub(crate) fn remember_previous_tick(
    mut surfaces: Query<(
        &SimulationPoints,
        &SurfaceRunSettings,
        &SurfaceStatus,
        &mut PreviousTick,
    )>,
) {
    for (points, settings, status, mut previous) in &mut surfaces {
        let previous = previous.bypass_change_detection();
        if settings.transfer == TransferTiming::Interpolated && status.is_ready() {
            previous.positions.clear();
            previous.positions.extend(points.iter_positions());
        } else if !previous.positions.is_empty() {
            *previous = PreviousTick::default();
        }
    }
}

/// Carries the simulation points' state to the dense points, on Bevy's compute pool when
/// the surface is large (the same rows, to the bit, as the core's `DenseCloud::follow` on
/// rayon). Returns whether anything was computed (false: the points did not
/// move since the last frame).
pub(crate) fn follow(dense: &mut DenseCloud, points: &PointState) -> Result<bool, TransferError> {
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
