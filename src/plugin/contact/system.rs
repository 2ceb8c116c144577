//! The contact system: rapier's colliders listed once per tick, then each ready surface
//! touched by those near it, the impulses added to its forces and written to its report,
//! and the tick's costs summed.

use std::collections::HashMap;

use bevy::ecs::query::QueryData;
use bevy::prelude::*;
use bevy_rapier3d::plugin::{DefaultRapierContext, RapierConfiguration};
use bevy_rapier3d::prelude::{CollisionGroups, RapierContextMut, TimestepMode, WriteRapierContext};
use bevy_rapier3d::rapier::dynamics::{RigidBody, RigidBodyHandle};
use bevy_rapier3d::rapier::geometry::InteractionGroups;

use super::bodies::RigidSide;
use super::colliders::{NearCollider, list_colliders};
use super::surface::{SurfaceFrame, SurfaceView};
use super::touch::{Touched, touch};
use super::{ContactDiagnostics, Link, SurfaceContact, SurfaceContacts};
use crate::core::network::SpringNetwork;
use crate::core::solver::contact::StepContact;
use crate::plugin::components::{
    SimulationPoints, StepOnce, SurfaceForces, SurfaceMasses, SurfaceNetwork, SurfaceRunSettings,
    SurfaceSprings, SurfaceStatus, SurfaceStepper,
};

/// A surface as the contacts read and write it, as one query item.
#[derive(QueryData, Debug)]
#[query_data(mutable)]
pub struct ContactSurface {
    entity: Entity,
    points: &'static mut SimulationPoints,
    masses: &'static SurfaceMasses,
    springs: &'static SurfaceSprings,
    network: &'static SurfaceNetwork,
    stepper: &'static SurfaceStepper,
    forces: &'static mut SurfaceForces,
    place: &'static GlobalTransform,
    status: &'static SurfaceStatus,
    settings: &'static SurfaceRunSettings,
    step_once: Has<StepOnce>,
    contact: Option<Ref<'static, SurfaceContact>>,
    groups: Option<&'static CollisionGroups>,
    report: Option<&'static mut SurfaceContacts>,
}

/// The contacts of one tick; see the [module documentation](super).
pub fn surface_contacts(
    time: Res<Time>,
    mut rapier: WriteRapierContext,
    configuration: Query<&RapierConfiguration, With<DefaultRapierContext>>,
    mut surfaces: Query<ContactSurface>,
    mut diagnostics: ResMut<ContactDiagnostics>,
    supports: Res<super::BodySupports>,
    mut commands: Commands,
) {
    let started = std::time::Instant::now();
    let dt = time.delta_secs();
    let Ok(context) = rapier.single_mut() else {
        return;
    };
    if dt <= 0.0 {
        return;
    }
    let gravity = configuration.single().map_or(Vec3::ZERO, |c| c.gravity);
    let colliders = list_colliders(&context, &supports, dt);
    let mut rigid = RigidSide {
        context,
        bodies: HashMap::new(),
        gravity,
        dt,
    };
    let mut touching = 0;
    for surface in &mut surfaces {
        touching += contact_surface(surface, &colliders, &mut rigid, &mut commands);
    }
    *diagnostics = ContactDiagnostics {
        colliders: colliders.len(),
        touching,
        time: started.elapsed(),
    };
}

/// One surface's contacts this tick, added to its forces and written to its report (given
/// one on its first tick); returns how many of its points took an impulse.
fn contact_surface(
    surface: ContactSurfaceItem<'_, '_>,
    colliders: &[NearCollider],
    rigid: &mut RigidSide<'_>,
    commands: &mut Commands,
) -> usize {
    let ContactSurfaceItem {
        entity,
        mut points,
        masses,
        springs,
        network,
        stepper,
        mut forces,
        place,
        status,
        settings,
        step_once,
        contact,
        groups,
        report,
    } = surface;
    if !status.is_ready() || (settings.paused && !step_once) {
        return 0;
    }
    // Settings out of range are said once, when they are set.
    let newly_set = contact.as_ref().is_some_and(|c| c.is_changed());
    let contact = contact.map_or_else(SurfaceContact::default, |c| *c);
    let mut inserted = None;
    let report = match report {
        Some(report) => report.into_inner(),
        None => inserted.insert(SurfaceContacts::default()),
    };
    report.start_tick(&network.0, contact.radius_scale);
    if contact.enabled && points.len() == report.radii().len() {
        let frame = SurfaceFrame::new(place, stepper.gravity(), rigid.dt);
        let surface = SurfaceView {
            points: &points,
            masses,
            springs,
            stepper,
            radii: report.radii.get(),
            frame,
        };
        let groups = groups.map_or(InteractionGroups::all(), |g| (*g).into());
        let params = contact.params();
        if let Err(e) = params.validate() {
            if newly_set {
                error!("point-springs surface {entity}: contacts off: {e}");
            }
        } else {
            let touched = touch(&surface, colliders, groups, rigid, &params, contact.solve);
            report.record(&touched, frame, rigid.dt, &mut forces);
            report.owed_at_step = stepper.diagnostics().steps;
            move_out(&touched, frame, &mut points);
        }
    }
    let touching = report.touching;
    if let Some(fresh) = inserted {
        commands.entity(entity).insert(fresh);
    }
    touching
}

/// The estimated contacts' overlaps moved out of, by position before the step (the
/// contacts solved in the step move theirs in it): no velocity carries them.
fn move_out(touched: &Touched, frame: SurfaceFrame, points: &mut Mut<'_, SimulationPoints>) {
    if touched.impulses.iter().all(|c| c.moved == Vec3::ZERO) {
        return;
    }
    for c in &touched.impulses {
        if c.moved != Vec3::ZERO {
            let at = points.position(c.point) + frame.to_local * c.moved;
            // In range: a point of this surface; a bad value is refused and left out.
            let _ = points.set_position(c.point, at);
        }
    }
}

impl SurfaceContacts {
    /// Starts a tick: the radii brought up to date, the last tick's counts cleared.
    fn start_tick(&mut self, network: &std::sync::Arc<SpringNetwork>, radius_scale: f32) {
        self.refresh_radii(network, radius_scale);
        self.links.clear();
        self.near_bodies.clear();
        self.bodies.clear();
        self.owed.clear();
        self.if_still.clear();
        self.colliders_near = 0;
        self.touching = 0;
        self.impulse = Vec3::ZERO;
    }

    /// Adds each impulse over the tick to its point's force, in the surface's coordinates
    /// (`frame`), and counts what `touched` gave.
    fn record(
        &mut self,
        touched: &Touched,
        frame: SurfaceFrame,
        dt: f32,
        forces: &mut Mut<'_, SurfaceForces>,
    ) {
        self.colliders_near = touched.near;
        for c in &touched.impulses {
            // Over the tick, in the surface's coordinates; in range by construction.
            let force = frame.to_local * (c.impulse / dt);
            if forces.add(c.point, force).is_ok() {
                self.impulse += c.impulse;
            }
        }
        self.touching = touched.impulses.len();
        self.total_impulse += self.impulse;
        self.owed.clone_from(&touched.held.owed);
        self.if_still.clone_from(&touched.held.if_still);
        self.links.clear();
        self.near_bodies.clone_from(&touched.near_bodies);
        // The game's systems may hand contacts of their own to the step too.
        self.links_from = forces.contacts().len();
        let held = &touched.held;
        let bodies: Vec<Option<u32>> = held
            .bodies
            .iter()
            .map(|(handle, predicted, guess)| {
                let (index, generation) = handle.into_raw_parts();
                let key = (u64::from(index) << 32) | u64::from(generation);
                forces
                    .add_body(frame.body_to_local(predicted, guess, key))
                    .inspect_err(|e| warn!("point-springs: a body left out of the step: {e}"))
                    .ok()
            })
            .collect();
        for (b, index) in bodies.iter().enumerate() {
            if let Some(index) = index {
                self.bodies.push((*index, held.bodies[b].0));
            }
        }
        for (c, at) in held.contacts.iter().zip(&held.at) {
            let (body, link) = match c.body {
                None => (None, None),
                Some(b) => match bodies.get(b as usize).copied().flatten() {
                    Some(index) => (Some(index), Some(held.bodies[b as usize].0)),
                    None => continue,
                },
            };
            let local = StepContact {
                body,
                ..frame.contact_to_local(c)
            };
            // In range by construction; one that is not is left out (and said in the log).
            let still = c.body.is_none() && c.body_velocity == Vec3::ZERO;
            match forces.add_contact(local) {
                Ok(()) => self.links.push(Link {
                    body: link,
                    at: *at,
                    point: c.point,
                    still,
                }),
                Err(e) => warn!("point-springs: a contact left out: {e}"),
            }
        }
    }
}

/// After the step: the impulses of the contacts the step solved ([`ContactSolve::InStep`])
/// added to each surface's report and to the tick's count, in world coordinates, and each
/// dynamic body given the opposite of what the surface took (or, estimated, what it was
/// owed), moved out of the points it pinches
/// ([`Stepper::body_moves`](crate::core::solver::Stepper::body_moves)) and set where the
/// step put it ([`land_where_the_step_put`]). The stepper's record is cleared once read, so
/// a surface that did not step this tick (paused, asleep, undone by the guard) gives
/// nothing.
///
/// [`ContactSolve::InStep`]: super::ContactSolve::InStep
pub(crate) fn record_step_contacts(
    mut surfaces: Query<(
        Entity,
        &mut SurfaceStepper,
        &GlobalTransform,
        &mut SurfaceContacts,
    )>,
    supports: Res<super::BodySupports>,
    mut rapier: WriteRapierContext,
    configuration: Query<&RapierConfiguration, With<DefaultRapierContext>>,
    mode: Option<Res<TimestepMode>>,
    time: Res<Time>,
    mut diagnostics: ResMut<ContactDiagnostics>,
) {
    let Ok(mut context) = rapier.single_mut() else {
        return;
    };
    let gravity = configuration.single().map_or(Vec3::ZERO, |c| c.gravity);
    let lag = integrator_lag(&context, mode.as_deref(), gravity, time.delta_secs());
    // Bodies resting on points that stand as balls in rapier's scene are rapier's to end
    // where its solver puts them: never landed (nor moved out, below).
    let on_balls = supports.bodies_on(&context);
    let mut landed: Vec<RigidBodyHandle> = on_balls.clone();
    for (entity, mut stepper, place, mut report) in &mut surfaces {
        let report = report.bypass_change_detection();
        let last = stepper.diagnostics();
        // Whether the surface took the step this tick's contacts went into.
        let stepped = !last.last.recovered && last.steps != report.owed_at_step;
        let owed = std::mem::take(&mut report.owed);
        let if_still = std::mem::take(&mut report.if_still);
        // The estimated impulses' opposites if the surface took its step with them; if it
        // did not, its bodies are stopped as by a surface that stood still.
        let given = if stepped { owed } else { if_still };
        for (handle, impulse, at) in given {
            if let Some(body) = context.rigidbody_set.bodies.get_mut(handle) {
                body.apply_impulse_at_point(impulse, at, true);
                land_where_the_step_put(body, handle, lag, &mut landed);
            }
        }
        if stepper.contact_impulses().is_empty() {
            continue;
        }
        let linear = Mat3::from(place.affine().matrix3);
        let supported = supports.standing_of(entity);
        let (mut impulse, mut touching) = (Vec3::ZERO, 0);
        // Only the contacts this plugin handed to the step (the game's systems, and
        // surfaces meeting surfaces, hand theirs too).
        let own = report.links_from..report.links_from + report.links.len();
        for (k, j) in stepper.contact_impulses().iter().enumerate() {
            if *j == Vec3::ZERO || !own.contains(&k) {
                continue;
            }
            let world = linear * *j;
            impulse += world;
            touching += 1;
            // A dynamic body solved in the step takes the opposite of what the surface took,
            // except at a point standing as a ball in rapier's scene since its last step:
            // there rapier's step holds the body off it (a ball placed this tick has not
            // held it yet: the step's impulse stops the body as it lands).
            let link = k
                .checked_sub(report.links_from)
                .and_then(|k| report.links.get(k).copied());
            if let Some(Link {
                body: Some(handle),
                at,
                point,
                ..
            }) = link
                && supported.binary_search(&point).is_err()
                && world.is_finite()
                && let Some(body) = context.rigidbody_set.bodies.get_mut(handle)
            {
                body.apply_impulse_at_point(-world, at, true);
            }
        }
        for &(index, handle) in &report.bodies {
            if on_balls.contains(&handle) {
                // Rapier's step holds it off the points standing as balls and ends it
                // where its solver puts it: neither moved out here nor landed.
                continue;
            }
            let moved = stepper.body_moves().get(index as usize).copied();
            let world = linear * moved.unwrap_or(Vec3::ZERO);
            let Some(body) = context.rigidbody_set.bodies.get_mut(handle) else {
                continue;
            };
            if world != Vec3::ZERO && world.is_finite() {
                body.set_translation(body.translation() + world, true);
            }
            if stepped {
                land_where_the_step_put(body, handle, lag, &mut landed);
            }
        }
        stepper.bypass_change_detection().0.clear_contact_impulses();
        if impulse.is_finite() {
            report.impulse += impulse;
            report.total_impulse += impulse;
        }
        report.touching += touching;
        diagnostics.touching += touching;
    }
}

/// How much less far rapier's step moves a body under gravity than the surfaces' steps
/// assume: a surface's step takes a body it touches to move by its velocity at the end of
/// the tick (as its own points do, implicit and symplectic Euler alike), while rapier's
/// solver takes M substeps, each adding its share of gravity before it moves the body, so
/// the body moves (M − 1)/(2M)·g·dt² less far along gravity (0.375·g·dt², 1 mm a tick at
/// 60 Hz with rapier's default 4 substeps): resting on a surface on that velocity, a crate
/// stayed 1 mm off it, reported falling at 6 cm/s (measured 2026-12-07).
fn integrator_lag(
    context: &RapierContextMut<'_>,
    mode: Option<&TimestepMode>,
    gravity: Vec3,
    dt: f32,
) -> Vec3 {
    let solver = context
        .simulation
        .integration_parameters
        .num_solver_iterations;
    let outer = match mode {
        Some(
            TimestepMode::Fixed { substeps, .. }
            | TimestepMode::Variable { substeps, .. }
            | TimestepMode::Interpolated { substeps, .. },
        ) => *substeps,
        None => 1,
    };
    let m = (solver.max(1) * outer.max(1)) as f32;
    gravity * dt * dt * (m - 1.0) / (2.0 * m)
}

/// Moves a dynamic body that a surface's step solved with by rapier's lag behind that step
/// ([`integrator_lag`], times the body's gravity scale), once a tick however many surfaces
/// touched it, so that rapier's step ends it where the surfaces' step put it.
fn land_where_the_step_put(
    body: &mut RigidBody,
    handle: RigidBodyHandle,
    lag: Vec3,
    landed: &mut Vec<RigidBodyHandle>,
) {
    if !body.is_dynamic() || landed.contains(&handle) {
        return;
    }
    landed.push(handle);
    let shift = lag * body.gravity_scale();
    if shift != Vec3::ZERO && shift.is_finite() {
        body.set_translation(body.translation() + shift, true);
    }
}
