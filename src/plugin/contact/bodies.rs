//! The rigid bodies' side of one tick: each body's contacts resolved against its state (its
//! velocity at the end of the tick without contacts), which carries over from one surface to
//! the next, and the opposite impulses applied to rapier's dynamic bodies.

use std::collections::HashMap;

use bevy::prelude::*;
use bevy_rapier3d::prelude::RapierContextMut;
use bevy_rapier3d::rapier::dynamics::{RigidBody, RigidBodyHandle};

use super::ContactSolve;
use crate::core::solver::contact::{
    BodyState, ContactImpulse, ContactParams, Proximity, StepContact, resolve, step_contact,
    will_touch,
};

/// Rapier's scene through one tick, and the state each body touched so far is left in.
pub(super) struct RigidSide<'w> {
    pub(super) context: RapierContextMut<'w>,
    /// The bodies touched this tick, as the contacts so far left them.
    pub(super) bodies: HashMap<RigidBodyHandle, BodyState>,
    /// Rapier's gravity.
    pub(super) gravity: Vec3,
    /// The tick.
    pub(super) dt: f32,
}

/// A surface's proximities to one body (or to one fixed collider).
pub(super) struct BodyContacts {
    /// The body (none: a fixed collider).
    pub(super) body: Option<RigidBodyHandle>,
    /// Where a fixed collider is: the centre it turns about, were it to turn.
    pub(super) center: Vec3,
    pub(super) proximities: Vec<Proximity>,
}

impl RigidSide<'_> {
    /// Resolves the contacts of each body in turn; returns the impulses on the surface, body
    /// after body, their opposites owed to the dynamic bodies (`held.owed`, given after the
    /// surface's step). With
    /// [`ContactSolve::InStep`], the contacts go to `held` instead, for the surface's step
    /// to solve: those with bodies nothing moves, and those with dynamic bodies too when
    /// `dynamic_in_step` (the body's estimated state after the contacts is its guess, and
    /// what it takes is applied after the step). `reweigh` sets the proximities' inverse
    /// masses once it is known which of them touch (the points that touch one body together
    /// move together).
    pub(super) fn resolve(
        &mut self,
        by_body: Vec<BodyContacts>,
        params: &ContactParams,
        (solve, dynamic_in_step): (ContactSolve, bool),
        reweigh: &mut dyn FnMut(&mut [Proximity], &[bool]),
        held: &mut Held,
    ) -> Vec<ContactImpulse> {
        let (gravity, dt) = (self.gravity, self.dt);
        let states = &mut self.bodies;
        let rigid_bodies = &mut self.context.rigidbody_set.bodies;
        let mut all = Vec::new();
        for BodyContacts {
            body: handle,
            center,
            mut proximities,
        } in by_body
        {
            let rigid = handle.and_then(|h| rigid_bodies.get(h));
            let mut state = match (handle, rigid) {
                (Some(h), Some(b)) => *states
                    .entry(h)
                    .or_insert_with(|| body_state(b, gravity, dt)),
                _ => BodyState::immovable(Vec3::ZERO, Vec3::ZERO, center),
            };
            // A proximity measured from a bad state (a surface the guard had to stop) takes
            // no part: nothing non-finite reaches rapier.
            proximities.retain(|p| p.velocity.is_finite() && p.gap.is_finite());
            let immovable = rigid.is_none_or(|b| !b.is_dynamic());
            if immovable && solve == ContactSolve::InStep {
                for p in &proximities {
                    if let Some(c) = step_contact(&state, p, dt, params, None) {
                        held.contacts.push(c);
                        held.at.push(p.at);
                    }
                }
                continue;
            }
            let moving_in_step = !immovable && solve == ContactSolve::InStep && dynamic_in_step;
            let touching: Vec<bool> = proximities
                .iter()
                .map(|p| will_touch(&state, p, dt))
                .collect();
            if touching.iter().filter(|t| **t).count() > 1 {
                reweigh(&mut proximities, &touching);
            }
            let predicted = state;
            if let Some(h) = handle {
                // Should the surface not take its step (the guard undoes it), it stood
                // still: the body is stopped as by a surface nothing moves.
                let mut still = predicted;
                let mut rigid_points: Vec<Proximity> = proximities
                    .iter()
                    .map(|p| Proximity {
                        inv_mass: 0.0,
                        ..*p
                    })
                    .collect();
                if let Ok(stopped) = resolve(&mut still, &mut rigid_points, dt, params) {
                    held.if_still.extend(
                        stopped
                            .iter()
                            .filter(|c| c.impulse.is_finite())
                            .map(|c| (h, -c.impulse, c.at)),
                    );
                }
            }
            let Ok(impulses) = resolve(&mut state, &mut proximities, dt, params) else {
                continue;
            };
            if impulses.iter().any(|c| !c.impulse.is_finite()) {
                continue;
            }
            if let (true, Some(h)) = (moving_in_step, handle) {
                // The estimate is the guess; the step solves the rest.
                let index = held.bodies.len() as u32;
                held.bodies.push((h, predicted, state));
                for p in &proximities {
                    if let Some(c) = step_contact(&predicted, p, dt, params, Some(index)) {
                        // At the guess: the body's velocity after the estimate.
                        let at_guess = state.velocity_at(p.at);
                        held.contacts.push(StepContact {
                            min_speed: c.min_speed + (at_guess - c.body_velocity).dot(p.normal),
                            body_velocity: at_guess,
                            ..c
                        });
                        held.at.push(p.at);
                    }
                }
                states.insert(h, state);
                continue;
            }
            if let (Some(h), Some(rigid)) = (handle, handle.and_then(|h| rigid_bodies.get(h))) {
                states.insert(h, state);
                if rigid.is_dynamic() {
                    // Given to the body once the surface has taken the step they went into
                    // (a step the guard undoes gives its bodies nothing).
                    held.owed
                        .extend(impulses.iter().map(|c| (h, -c.impulse, c.at)));
                }
            }
            all.extend(impulses);
        }
        all
    }
}

/// The contacts one surface hands to its step ([`ContactSolve::InStep`]), in world
/// coordinates.
#[derive(Default)]
pub(super) struct Held {
    /// The contacts.
    pub(super) contacts: Vec<StepContact>,
    /// Where each contact touches its body.
    pub(super) at: Vec<Vec3>,
    /// The dynamic bodies the contacts' `body` indices name: each one's handle, its state
    /// without the contacts and its state after the estimated ones (the guess).
    pub(super) bodies: Vec<(RigidBodyHandle, BodyState, BodyState)>,
    /// The estimated impulses' opposites, owed to dynamic bodies once the surface has
    /// stepped with the impulses (world): the body, the impulse, where it acts.
    pub(super) owed: Vec<(RigidBodyHandle, Vec3, Vec3)>,
    /// What each dynamic body takes instead if the surface does not step (the guard undoes
    /// its step): stopped as by a surface nothing moves, at its points' velocities.
    pub(super) if_still: Vec<(RigidBodyHandle, Vec3, Vec3)>,
}

/// A rapier body as contacts see it: its velocity at the end of the tick without contacts
/// (gravity included unless it sleeps), and its inverse mass and inertia if dynamic.
pub(super) fn body_state(body: &RigidBody, gravity: Vec3, dt: f32) -> BodyState {
    let center = body.center_of_mass();
    if !body.is_dynamic() {
        return BodyState::immovable(body.linvel(), body.angvel(), center);
    }
    let fall = if body.is_sleeping() {
        Vec3::ZERO
    } else {
        gravity * body.gravity_scale() * dt
    };
    let props = body.mass_properties();
    let i = props.effective_world_inv_inertia;
    BodyState {
        linear: body.linvel() + fall,
        angular: body.angvel(),
        center,
        inv_mass: props.effective_inv_mass,
        inv_inertia: Mat3::from_cols(
            Vec3::new(i.m11, i.m12, i.m13),
            Vec3::new(i.m12, i.m22, i.m23),
            Vec3::new(i.m13, i.m23, i.m33),
        ),
    }
}
