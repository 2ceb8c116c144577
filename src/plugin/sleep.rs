//! Sleeping surfaces (issue 17): a surface that has stayed still for a while stops costing
//! anything per tick, and wakes on the tick something acts on it. See [`SurfaceSleep`] and
//! [`SleepSettings`](super::components::SleepSettings).
//!
//! `wake_surfaces` runs first in the `Integrate` set, after every system of `Forces` (grabs,
//! timelines, contacts and the game's forces) had its say; `settle_surfaces` runs last,
//! after the step.

use bevy::prelude::*;

use super::components::{
    SceneTimeline, SimulationPoints, StepOnce, SurfaceAnchors, SurfaceForces, SurfaceMaterial,
    SurfaceRunSettings, SurfaceSleep, SurfaceStatus, SurfaceStepper,
};

/// What [`wake_surfaces`] reads of a surface to tell whether something acted on it.
type WakeParts = (
    &'static mut SurfaceSleep,
    &'static SurfaceForces,
    &'static SurfaceAnchors,
    Ref<'static, SurfaceMaterial>,
    Ref<'static, SurfaceRunSettings>,
    &'static mut SurfaceStepper,
    Has<StepOnce>,
);

/// A surface acted on this tick (a force, an anchor, a changed material, run settings or
/// solver settings, a single step asked for) is awake, and its stillness starts again.
pub(crate) fn wake_surfaces(mut surfaces: Query<WakeParts>) {
    for (mut sleep, forces, anchors, material, settings, mut stepper, step_once) in &mut surfaces {
        let solver_changed = std::mem::take(&mut stepper.bypass_change_detection().1);
        let acted = !anchors.is_empty()
            || material.is_changed()
            || settings.is_changed()
            || solver_changed
            || step_once
            || !forces.is_zero();
        if acted {
            sleep.wake();
        }
    }
}

/// After the step: a running surface left alone whose fastest point stays below the sleep
/// speed for the sleep time goes to sleep, its points stopped. A single step asked for
/// ([`StepOnce`]) has been taken.
pub(crate) fn settle_surfaces(
    mut commands: Commands,
    time: Res<Time>,
    single_steps: Query<Entity, With<StepOnce>>,
    mut surfaces: Query<(
        &mut SimulationPoints,
        &mut SurfaceSleep,
        &SurfaceRunSettings,
        &SurfaceStatus,
        Option<&SceneTimeline>,
    )>,
) {
    for entity in &single_steps {
        commands.entity(entity).remove::<StepOnce>();
    }
    let dt = time.delta_secs();
    for (mut points, mut sleep, settings, status, timeline) in &mut surfaces {
        if sleep.asleep || !status.is_ready() || settings.paused {
            continue;
        }
        let rule = settings.sleep;
        let still = !std::mem::take(&mut sleep.acted)
            && rule.speed > 0.0
            && timeline.is_none_or(|t| t.finished())
            && points.max_speed() < rule.speed;
        if !still {
            sleep.still_for = 0.0;
            continue;
        }
        sleep.still_for += dt;
        if sleep.still_for >= rule.after {
            sleep.asleep = true;
            points.stop();
        }
    }
}
