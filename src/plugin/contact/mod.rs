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
//! 4. for a dynamic body, adds each impulse over the tick to the point's [`SurfaceForces`]
//!    and applies the opposite impulse to the body at the contact point, so rapier's step
//!    and the surface's step both see it in this tick; for a body nothing moves (a fixed
//!    collider, a kinematic body), hands the contact to the surface's step instead
//!    ([`ContactSolve::InStep`], the default), which solves it with the springs; a system
//!    after the step adds what those contacts gave to the surface's report.
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

mod bodies;
mod colliders;
mod surface;
mod system;
mod touch;

use std::sync::Arc;

use bevy::ecs::schedule::{InternedScheduleLabel, ScheduleLabel};
use bevy::prelude::*;
use bevy_rapier3d::plugin::PhysicsSet;
use bevy_rapier3d::prelude::TimestepMode;

use crate::core::network::SpringNetwork;
use crate::core::solver::contact::{
    ContactParams, DEFAULT_DEPTH_RECOVERY, DEFAULT_FRICTION, DEFAULT_RADIUS_SCALE, point_radii,
};

use super::PointSpringsSystems;

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
            .add_systems(
                self.schedule,
                (
                    keep_rapier_on_the_tick.before(PhysicsSet::SyncBackend),
                    surface_contacts
                        .in_set(PointSpringsSystems::Forces)
                        .after(super::simulate::accumulate_forces)
                        .after(PhysicsSet::SyncBackend)
                        .before(PhysicsSet::StepSimulation),
                    system::record_step_contacts
                        .after(PointSpringsSystems::Integrate)
                        .before(PointSpringsSystems::Transfer),
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
    /// Fraction of an overlap pushed out per tick, in [0, 1].
    pub depth_recovery: f32,
    /// Radius of each simulation point's sphere, as a share of the mean rest length of its
    /// stretch springs.
    pub radius_scale: f32,
    /// How contacts with bodies nothing moves (fixed colliders, kinematic bodies) reach the
    /// surface's step. Contacts with dynamic bodies are always estimated.
    pub solve: ContactSolve,
}

/// How a contact with a body that nothing moves (the ground, a wall, a kinematic paddle)
/// reaches a surface's step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Reflect)]
#[reflect(Debug, Default, PartialEq)]
pub enum ContactSolve {
    /// Solved within the step, with the springs ([`StepContact`]): the point's velocity
    /// along the normal is held to what the contact allows and its neighbours are solved
    /// with it, so a pushed patch moves as far as the body and no further.
    ///
    /// [`StepContact`]: crate::core::solver::contact::StepContact
    #[default]
    InStep,
    /// An impulse before the step, estimated from each point's step mass (the way of every
    /// contact with a dynamic body): a patch pushed as a whole is over-pushed.
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
    radii: Vec<f32>,
    /// The network and scale the radii were computed for.
    #[reflect(ignore)]
    radii_of: Option<(Arc<SpringNetwork>, u32)>,
}

impl SurfaceContacts {
    /// The simulation points' sphere radii, in the surface's coordinates.
    pub fn radii(&self) -> &[f32] {
        &self.radii
    }

    /// Recomputes the radii when the network or the scale changed (a surface prepared
    /// again, a setting changed).
    fn refresh_radii(&mut self, network: &Arc<SpringNetwork>, scale: f32) {
        let current = matches!(&self.radii_of,
            Some((n, s)) if Arc::ptr_eq(n, network) && *s == scale.to_bits());
        if !current {
            self.radii = point_radii(network, scale);
            self.radii_of = Some((Arc::clone(network), scale.to_bits()));
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
