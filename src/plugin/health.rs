//! How a surface's steps go: a surface whose guard restored its state, whose explicit step
//! ran out of sub-steps, or whose points ran away says so in [`SurfaceHealth`], once in the
//! log, and once as a [`SurfaceUnstable`] event to observers; what happens to its points is
//! the solver's [`InstabilityResponse`](crate::core::solver::InstabilityResponse) (by
//! default an explicit integrator hands over to implicit Euler, which freezes the points
//! where they were when it fails itself).
//!
//! `watch_health` runs in the `Integrate` set right after the step.

use bevy::prelude::*;

use crate::core::solver::Instability;

use super::components::{SurfaceStatus, SurfaceStepper};

/// Clean steps after which a surface's trouble counts as over (one second at 60 Hz).
pub const STABLE_STEPS_TO_RECOVER: u32 = 60;

/// How a surface's steps have gone. A game reads [`Self::trouble`] (or observes
/// [`SurfaceUnstable`]) to learn that a surface needed the guard.
#[derive(Component, Debug, Clone, Default, PartialEq, Reflect)]
#[reflect(Component, Debug, Default)]
pub struct SurfaceHealth {
    /// Why the latest step of the trouble under way was refused or ran above its stable
    /// step; `None` once [`STABLE_STEPS_TO_RECOVER`] steps in a row went well.
    #[reflect(ignore)]
    pub trouble: Option<Instability>,
    /// Steps that were refused or limited since the surface was prepared.
    pub troubled_steps: u64,
    /// Times trouble began (each reported once).
    pub episodes: u32,
    /// The explicit integrator handed over to implicit Euler.
    pub fell_back: bool,
    /// Clean steps since the last troubled one.
    clean_steps: u32,
    /// The stepper's step count when last looked at.
    seen_steps: u64,
}

impl SurfaceHealth {
    /// Whether no trouble is under way.
    pub fn is_stable(&self) -> bool {
        self.trouble.is_none()
    }
}

/// Sent to observers (and of the surface's entity) when a surface's trouble begins: its
/// guard restored the state, its explicit step ran out of sub-steps, or a point ran away.
#[derive(EntityEvent, Debug, Clone, Copy, PartialEq)]
pub struct SurfaceUnstable {
    /// The surface.
    pub entity: Entity,
    /// Why.
    pub reason: Instability,
    /// Whether implicit Euler took over from the explicit integrator.
    pub fell_back: bool,
}

/// After each step: each surface that stepped updates its health; trouble that begins is
/// logged and sent once, its end logged once.
pub(crate) fn watch_health(
    mut commands: Commands,
    mut surfaces: Query<(Entity, &SurfaceStepper, &SurfaceStatus, &mut SurfaceHealth)>,
) {
    for (entity, stepper, status, mut health) in &mut surfaces {
        let d = stepper.diagnostics();
        if !status.is_ready() || d.steps == health.seen_steps {
            continue;
        }
        health.seen_steps = d.steps;
        match d.last.instability {
            Some(reason) => {
                health.troubled_steps += 1;
                health.clean_steps = 0;
                health.fell_back = d.fell_back;
                if health.trouble.is_none() {
                    health.episodes += 1;
                    let what = if d.last.fell_back {
                        "; implicit Euler takes over"
                    } else if d.last.recovered {
                        "; its points are held (the guard restored the state)"
                    } else {
                        ""
                    };
                    warn!("point-springs surface {entity}: unstable: {reason}{what}");
                    commands.trigger(SurfaceUnstable {
                        entity,
                        reason,
                        fell_back: d.last.fell_back,
                    });
                }
                health.trouble = Some(reason);
            }
            None if health.trouble.is_some() => {
                health.clean_steps += 1;
                if health.clean_steps >= STABLE_STEPS_TO_RECOVER {
                    health.trouble = None;
                    info!("point-springs surface {entity}: stable again");
                }
            }
            None => {}
        }
    }
}
