//! Rapier colliders touching deformable surfaces (feature `rapier`): each tick every
//! simulation point near a collider takes a contact force, and the collider's rigid body the
//! equal and opposite impulse.
//!
//! Add [`SurfaceContactPlugin`] next to [`PointSpringsPlugin`](super::PointSpringsPlugin)
//! and bevy_rapier3d's plugin **in the same fixed schedule**:
//!
//! ```no_run
//! use bevy::prelude::*;
//! use bevy_point_springs::prelude::*;
//! use bevy_point_springs::plugin::SurfaceContactPlugin;
//! use bevy_rapier3d::prelude::*;
//!
//! App::new().add_plugins((
//!     DefaultPlugins,
//!     PointSpringsPlugin::default(),
//!     RapierPhysicsPlugin::<NoUserData>::default().in_fixed_schedule(),
//!     SurfaceContactPlugin::default(),
//! ));
//! ```
//!
//! Each tick, after rapier has taken in the scene's changes and before it steps
//! (`PhysicsSet::SyncBackend → contacts → PhysicsSet::StepSimulation`), [`surface_contacts`]:
//!
//! 1. lists rapier's colliders once (sensors and disabled ones left out) with their bounds
//!    swept over the tick by their body's velocity;
//! 2. per surface, skips every collider whose swept bounds miss the surface's bounds or
//!    whose [`CollisionGroups`] the surface's own groups filter out, and stops there when
//!    none is left: a surface nothing is near costs one pass over its points;
//! 3. finds the points inside each remaining collider's bounds, measures each point's
//!    sphere against the collider's exact shape (parry's point projection) and hands the
//!    proximities to [`crate::core::solver::contact::resolve`];
//! 4. hands the contacts to the surface's step ([`ContactSolve::InStep`], the default),
//!    which solves them with the springs (a dynamic body's velocity with the surface's,
//!    from the estimate of step 3 as a first guess); a system after the step, before
//!    rapier's, applies to each dynamic body the opposite of what the surface took, at the
//!    contact points, and adds it to the surface's report. With
//!    [`ContactSolve::Estimated`] (and for dynamic bodies with an explicit integrator), the
//!    estimated impulses go into the points' [`SurfaceForces`] instead and their opposites
//!    to the bodies, so rapier's step and the surface's step both see them in this tick.
//!
//! The same plugin makes attachments ([`SurfaceAttachments`](super::SurfaceAttachments))
//! two-way: a target rapier moves by velocity carries its points along over the tick, and a
//! dynamic target takes the surface's pull at its attached points before rapier steps.
//!
//! The plugin keeps rapier's `TimestepMode::Fixed` step equal to the tick, so that
//! both step the same time. A surface's [`SurfaceContacts`] reports what touched it.
//!
//! The files follow the tick's steps: [`surface_contacts`] (`system.rs`) walks the surfaces,
//! `colliders.rs` lists rapier's colliders and keeps those near a surface, `surface.rs` puts
//! a surface's points in world coordinates, `touch.rs` measures them against each near
//! collider's shape, and `bodies.rs` resolves the contacts per body and hands rapier its
//! share.
//!
//! [`CollisionGroups`]: bevy_rapier3d::prelude::CollisionGroups
//! [`SurfaceForces`]: super::SurfaceForces

mod attached;
mod bodies;
mod colliders;
mod support;
mod surface;
mod system;
mod touch;

use std::sync::Arc;

use bevy::ecs::schedule::{InternedScheduleLabel, ScheduleLabel};
use bevy::prelude::*;
use bevy_rapier3d::plugin::PhysicsSet;
use bevy_rapier3d::prelude::TimestepMode;
use bevy_rapier3d::rapier::dynamics::RigidBodyHandle;

use crate::core::network::SpringNetwork;
use crate::core::solver::contact::{
    ContactParams, DEFAULT_DEPTH_RECOVERY, DEFAULT_FRICTION, DEFAULT_RADIUS_SCALE,
};

use super::PointSpringsSystems;
use super::meet::PointRadii;

pub use support::BodySupports;
pub use system::surface_contacts;

/// Contacts between rapier's colliders and deformable surfaces.
#[derive(Debug, Clone)]
pub struct SurfaceContactPlugin {
    schedule: InternedScheduleLabel,
}

impl SurfaceContactPlugin {
    /// Contacts in `schedule`: the schedule of both [`PointSpringsPlugin`] and rapier's
    /// plugin.
    ///
    /// [`PointSpringsPlugin`]: super::PointSpringsPlugin
    pub fn new(schedule: impl ScheduleLabel) -> Self {
        Self {
            schedule: schedule.intern(),
        }
    }
}

impl Default for SurfaceContactPlugin {
    fn default() -> Self {
        Self::new(FixedUpdate)
    }
}

impl Plugin for SurfaceContactPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<SurfaceContact>()
            .register_type::<ContactSolve>()
            .register_type::<SurfaceContacts>()
            .init_resource::<ContactDiagnostics>()
            .init_resource::<BodySupports>()
            .add_systems(
                self.schedule,
                (
                    keep_rapier_on_the_tick.before(PhysicsSet::SyncBackend),
                    surface_contacts
                        .in_set(PointSpringsSystems::Forces)
                        .after(super::simulate::accumulate_forces)
                        .after(PhysicsSet::SyncBackend)
                        .before(PhysicsSet::StepSimulation),
                    support::support_bodies
                        .after(PointSpringsSystems::Integrate)
                        .before(system::record_step_contacts)
                        .before(PhysicsSet::StepSimulation),
                    system::record_step_contacts
                        .after(PointSpringsSystems::Integrate)
                        .before(PointSpringsSystems::Transfer)
                        .before(PhysicsSet::StepSimulation),
                    attached::predict_attached_bodies
                        .after(PhysicsSet::SyncBackend)
                        .before(crate::plugin::attach::hold_attachments),
                    attached::pull_attached_bodies
                        .after(PointSpringsSystems::Integrate)
                        .before(PhysicsSet::StepSimulation),
                ),
            );
    }
}

/// How a surface meets rigid bodies. Optional: a surface without it uses the defaults. Put
/// bevy_rapier3d's [`CollisionGroups`] on the surface's entity to choose what it touches.
///
/// [`CollisionGroups`]: bevy_rapier3d::prelude::CollisionGroups
#[derive(Component, Debug, Clone, Copy, PartialEq, Reflect)]
#[reflect(Component, Debug, Default)]
pub struct SurfaceContact {
    /// Whether rigid bodies touch this surface at all.
    pub enabled: bool,
    /// Coulomb friction coefficient μ.
    pub friction: f32,
    /// Fraction of an overlap moved out per tick, in [0, 1], by position (never by
    /// velocity).
    pub depth_recovery: f32,
    /// Radius of each simulation point's sphere, as a share of the mean rest length of its
    /// stretch springs.
    pub radius_scale: f32,
    /// How contacts reach the surface's step.
    pub solve: ContactSolve,
}

/// How a contact reaches a surface's step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Reflect)]
#[reflect(Debug, Default, PartialEq)]
pub enum ContactSolve {
    /// Solved within the step, with the springs ([`StepContact`]): the point's velocity
    /// along the normal is held to what the contact allows and its neighbours are solved
    /// with it, so a pushed patch moves as far as the body and no further; a dynamic body's
    /// velocity is solved with the surface's ([`StepBody`]) where the surface steps by
    /// implicit Euler in a frame without shear, and estimated otherwise.
    ///
    /// [`StepContact`]: crate::core::solver::contact::StepContact
    /// [`StepBody`]: crate::core::solver::contact::StepBody
    #[default]
    InStep,
    /// An impulse before the step, estimated from each point's step mass: a patch pushed as
    /// a whole is pushed too far or too little, a ball resting on a surface jitters, and a
    /// cloth lying on a floor flaps and gains energy (a point beside one hovering above the
    /// floor is estimated as heavy as its springs to it make it, and pushed up too hard).
    Estimated,
}

impl Default for SurfaceContact {
    fn default() -> Self {
        Self {
            enabled: true,
            friction: DEFAULT_FRICTION,
            depth_recovery: DEFAULT_DEPTH_RECOVERY,
            radius_scale: DEFAULT_RADIUS_SCALE,
            solve: ContactSolve::default(),
        }
    }
}

impl SurfaceContact {
    fn params(&self) -> ContactParams {
        ContactParams {
            friction: self.friction,
            depth_recovery: self.depth_recovery,
        }
    }
}

/// What touched a surface (added by [`surface_contacts`] to every ready surface): counts
/// and impulses of the last tick and the total since the surface was prepared. Impulses are
/// in world coordinates, N·s, on the surface (its bodies took the opposite).
#[derive(Component, Debug, Clone, Default, Reflect)]
#[reflect(Component, Debug, Default)]
pub struct SurfaceContacts {
    /// Colliders near the surface last tick (their swept bounds met the surface's).
    pub colliders_near: usize,
    /// Simulation points that took a contact impulse last tick.
    pub touching: usize,
    /// Impulse on the surface last tick.
    pub impulse: Vec3,
    /// Impulse on the surface since it was prepared.
    pub total_impulse: Vec3,
    /// The points' sphere radii, in the surface's coordinates.
    #[reflect(ignore)]
    radii: PointRadii,
    /// For each contact handed to the step this tick: what it joins.
    #[reflect(ignore)]
    links: Vec<Link>,
    /// The points near a dynamic body this tick (sorted): those a fixed collider holds are
    /// shown to rapier ([`support`]).
    #[reflect(ignore)]
    pub(super) near_bodies: Vec<u32>,
    /// The dynamic bodies handed to the step this tick: each one's index among the step's
    /// bodies, and its handle.
    #[reflect(ignore)]
    bodies: Vec<(u32, RigidBodyHandle)>,
    /// The estimated impulses' opposites owed to dynamic bodies once the surface steps
    /// (world): the body, the impulse, where it acts; and the surface's step count when
    /// they were found.
    #[reflect(ignore)]
    owed: Vec<(RigidBodyHandle, Vec3, Vec3)>,
    #[reflect(ignore)]
    owed_at_step: u64,
    /// What the dynamic bodies take instead if the surface does not take its step (the
    /// guard undoes it): stopped as by a surface nothing moves (world).
    #[reflect(ignore)]
    if_still: Vec<(RigidBodyHandle, Vec3, Vec3)>,
    /// The index of the first of them among the step's contacts.
    #[reflect(ignore)]
    links_from: usize,
}

/// A contact handed to a surface's step, as the plugin keeps it.
#[derive(Debug, Clone, Copy)]
struct Link {
    /// Its dynamic body, if it has one.
    body: Option<RigidBodyHandle>,
    /// Where it touches the body (world coordinates).
    at: Vec3,
    /// The simulation point.
    point: u32,
    /// Whether what it touches stands still (a fixed collider, or a body at rest).
    still: bool,
}

impl SurfaceContacts {
    /// The points near a dynamic body that a still collider pushed in the step that gave
    /// `impulses` (the step's contact impulses, this plugin's among them), in order.
    fn held_near_bodies<'a>(&'a self, impulses: &'a [Vec3]) -> impl Iterator<Item = u32> + 'a {
        let own = impulses.get(self.links_from..).unwrap_or(&[]);
        own.iter()
            .zip(&self.links)
            .filter(|(j, link)| {
                link.body.is_none()
                    && link.still
                    && **j != Vec3::ZERO
                    && self.near_bodies.binary_search(&link.point).is_ok()
            })
            .map(|(_, link)| link.point)
    }

    /// The simulation points' sphere radii, in the surface's coordinates.
    pub fn radii(&self) -> &[f32] {
        self.radii.get()
    }

    /// Recomputes the radii when the network or the scale changed (a surface prepared
    /// again, a setting changed).
    fn refresh_radii(&mut self, network: &Arc<SpringNetwork>, scale: f32) {
        if self.radii.refresh(network, scale) {
            self.total_impulse = Vec3::ZERO;
        }
    }
}

/// What the contacts of the last tick cost, over every surface.
#[derive(Resource, Debug, Clone, Copy, Default, PartialEq)]
pub struct ContactDiagnostics {
    /// Rapier colliders listed (sensors and disabled ones left out).
    pub colliders: usize,
    /// Simulation points that took a contact impulse.
    pub touching: usize,
    /// Wall time of the contact system.
    pub time: std::time::Duration,
}

/// Keeps rapier's fixed step equal to the tick, so rapier and the surfaces step the same
/// time.
pub(crate) fn keep_rapier_on_the_tick(time: Res<Time>, mode: Option<ResMut<TimestepMode>>) {
    let Some(mut mode) = mode else { return };
    let dt = time.delta_secs();
    if dt <= 0.0 {
        return;
    }
    match *mode {
        TimestepMode::Fixed { dt: step, substeps } if step != dt => {
            *mode = TimestepMode::Fixed { dt, substeps };
        }
        TimestepMode::Fixed { .. } => {}
        _ => *mode = TimestepMode::Fixed { dt, substeps: 1 },
    }
}
