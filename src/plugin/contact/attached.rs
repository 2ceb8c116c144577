//! Attachments to rapier's rigid bodies ([`SurfaceAttachments`]), both ways: a body that
//! rapier moves by velocity carries its attached points along over the tick, and a dynamic
//! body takes the surface's pull at the attached points before rapier steps.

use bevy::prelude::*;
use bevy_rapier3d::prelude::{RapierRigidBodyHandle, ReadRapierContext, WriteRapierContext};
use bevy_rapier3d::rapier::dynamics::RigidBodyType;

use bevy_rapier3d::plugin::{DefaultRapierContext, RapierConfiguration};

use super::bodies::body_state;
use super::surface::SurfaceFrame;
use crate::core::solver::contact::{BodyState, StepBody};
use crate::core::solver::{ImplicitSolver, Integrator};
use crate::plugin::attach::{SurfaceAttachments, TargetMotion};
use crate::plugin::components::SurfaceStepper;

/// Before the attachments move their points: each target whose rigid body rapier moves by
/// velocity (dynamic, or kinematic by velocity) tells how it will move over the tick, so
/// that its points land where the body will be. A body moved by position (kinematic by
/// position, driven through its `Transform`) is where it will be already. A dynamic body is
/// also handed to the step, which solves its velocity with the surface's where the surface
/// steps by implicit Euler with conjugate gradient in a frame that is a turn and a uniform
/// scale (otherwise its pull reaches it a tick late, as an impulse).
pub(crate) fn predict_attached_bodies(
    time: Res<Time>,
    mut surfaces: Query<(&mut SurfaceAttachments, &SurfaceStepper, &GlobalTransform)>,
    handles: Query<&RapierRigidBodyHandle>,
    configuration: Query<&RapierConfiguration, With<DefaultRapierContext>>,
    rapier: ReadRapierContext,
) {
    let Ok(context) = rapier.single() else {
        return;
    };
    let dt = time.delta_secs();
    let gravity = configuration.single().map_or(Vec3::ZERO, |c| c.gravity);
    for (mut attachments, stepper, place) in &mut surfaces {
        let frame = SurfaceFrame::new(place, stepper.gravity(), dt);
        let solved = stepper.integrator() == Integrator::ImplicitEuler
            && stepper.config().implicit_solver == ImplicitSolver::ConjugateGradient
            && frame.is_similarity();
        for a in attachments.bypass_change_detection().live_mut() {
            let body = handles
                .get(a.target)
                .ok()
                .and_then(|h| Some((h.0, context.rigidbody_set.bodies.get(h.0)?)))
                .filter(|(_, body)| {
                    matches!(
                        body.body_type(),
                        RigidBodyType::Dynamic | RigidBodyType::KinematicVelocityBased
                    )
                });
            a.motion = body
                .map(|(_, body)| TargetMotion {
                    linear: body.linvel(),
                    angular: body.angvel(),
                    centre: body.center_of_mass(),
                })
                .filter(|m| m.linear.is_finite() && m.angular.is_finite() && m.centre.is_finite());
            a.carrier = body
                .filter(|(_, body)| solved && a.motion.is_some() && body.is_dynamic())
                .map(|(handle, body)| {
                    let predicted = body_state(body, gravity, dt);
                    let guess = BodyState {
                        linear: body.linvel(),
                        angular: body.angvel(),
                        ..predicted
                    };
                    let (index, generation) = handle.into_raw_parts();
                    let key = (u64::from(index) << 32) | u64::from(generation);
                    frame.body_to_local(&predicted, &guess, key)
                })
                .filter(StepBody::is_finite);
        }
    }
}

/// After the step, before rapier's: each dynamic target takes the surface's pull at its
/// attached points (the opposite of what held them), so that momentum is exchanged exactly.
pub(crate) fn pull_attached_bodies(
    surfaces: Query<&SurfaceAttachments>,
    handles: Query<&RapierRigidBodyHandle>,
    mut rapier: WriteRapierContext,
) {
    let Ok(mut context) = rapier.single_mut() else {
        return;
    };
    for attachments in &surfaces {
        for (target, pulls) in attachments.pulls_on() {
            let Ok(handle) = handles.get(target) else {
                continue;
            };
            let Some(body) = context.rigidbody_set.bodies.get_mut(handle.0) else {
                continue;
            };
            if !body.is_dynamic() {
                continue;
            }
            for &(at, pull) in pulls {
                body.apply_impulse_at_point(pull, at, true);
            }
        }
    }
}
