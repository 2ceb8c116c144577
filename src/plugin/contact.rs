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
//! 4. adds each impulse over the tick to the point's [`SurfaceForces`] and applies the
//!    opposite impulse to the dynamic body at the contact point, so rapier's step and the
//!    surface's step both see it in this tick.
//!
//! The plugin keeps rapier's `TimestepMode::Fixed` step equal to the tick, so that
//! both step the same time. A surface's [`SurfaceContacts`] reports what touched it.

use std::collections::HashMap;
use std::sync::Arc;

use bevy::ecs::schedule::{InternedScheduleLabel, ScheduleLabel};
use bevy::prelude::*;
use bevy_rapier3d::plugin::{DefaultRapierContext, PhysicsSet, RapierConfiguration};
use bevy_rapier3d::prelude::{CollisionGroups, TimestepMode, WriteRapierContext};
use bevy_rapier3d::rapier::dynamics::RigidBodyHandle;
use bevy_rapier3d::rapier::geometry::{ColliderHandle, InteractionGroups};

use crate::core::network::SpringNetwork;
use crate::core::solver::contact::{
    BodyState, ContactImpulse, ContactParams, DEFAULT_DEPTH_RECOVERY, DEFAULT_FRICTION,
    DEFAULT_RADIUS_SCALE, PointGrid, Proximity, point_radii, resolve, step_masses,
};

use super::PointSpringsSystems;
use super::components::{
    SimulationPoints, SurfaceForces, SurfaceMasses, SurfaceNetwork, SurfaceSettings,
    SurfaceSprings, SurfaceStatus, SurfaceStepper,
};

/// Distances below this count as zero when a contact normal is taken from them.
const NORMAL_EPSILON: f32 = 1e-7;

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
                ),
            );
    }
}

/// How a surface meets rigid bodies. Optional: a surface without it uses the defaults. Put
/// bevy_rapier3d's [`CollisionGroups`] on the surface's entity to choose what it touches.
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
}

impl Default for SurfaceContact {
    fn default() -> Self {
        Self {
            enabled: true,
            friction: DEFAULT_FRICTION,
            depth_recovery: DEFAULT_DEPTH_RECOVERY,
            radius_scale: DEFAULT_RADIUS_SCALE,
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

/// A collider as the contacts of one tick see it.
struct NearCollider {
    handle: ColliderHandle,
    /// The body whose velocity and mass the collider has (none: a fixed collider).
    body: Option<RigidBodyHandle>,
    /// Bounds at the start of the tick, grown by the body's motion over the tick.
    min: Vec3,
    max: Vec3,
    groups: InteractionGroups,
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

/// The contacts of one tick; see the [module documentation](self).
#[allow(clippy::type_complexity)]
pub fn surface_contacts(
    time: Res<Time>,
    mut rapier: WriteRapierContext,
    configuration: Query<&RapierConfiguration, With<DefaultRapierContext>>,
    mut surfaces: Query<(
        Entity,
        &SimulationPoints,
        &SurfaceMasses,
        &SurfaceSprings,
        &SurfaceNetwork,
        &SurfaceStepper,
        &mut SurfaceForces,
        &GlobalTransform,
        &SurfaceStatus,
        &SurfaceSettings,
        Option<Ref<SurfaceContact>>,
        Option<&CollisionGroups>,
        Option<&mut SurfaceContacts>,
    )>,
    mut diagnostics: ResMut<ContactDiagnostics>,
    mut commands: Commands,
) {
    let started = std::time::Instant::now();
    let dt = time.delta_secs();
    let Ok(mut context) = rapier.single_mut() else {
        return;
    };
    if dt <= 0.0 {
        return;
    }
    let gravity = configuration.single().map_or(Vec3::ZERO, |c| c.gravity);
    let colliders = list_colliders(&context, dt);
    let mut touching = 0;
    let mut bodies: HashMap<RigidBodyHandle, BodyState> = HashMap::new();
    for (
        entity,
        points,
        masses,
        springs,
        network,
        stepper,
        mut forces,
        place,
        status,
        settings,
        contact,
        groups,
        report,
    ) in &mut surfaces
    {
        if !status.is_ready() || settings.paused {
            continue;
        }
        // Settings out of range are said once, when they are set.
        let newly_set = contact.as_ref().is_some_and(|c| c.is_changed());
        let contact = contact.map_or_else(SurfaceContact::default, |c| *c);
        let mut inserted = None;
        let report = match report {
            Some(report) => report.into_inner(),
            None => inserted.insert(SurfaceContacts::default()),
        };
        report.refresh_radii(&network.0, contact.radius_scale);
        report.colliders_near = 0;
        report.touching = 0;
        report.impulse = Vec3::ZERO;
        if contact.enabled && points.len() == report.radii.len() {
            let frame = SurfaceFrame::new(place, stepper.config().gravity, dt);
            let surface = SurfaceView {
                points,
                masses,
                springs,
                stepper,
                radii: &report.radii,
                frame,
            };
            let groups = groups.map_or(InteractionGroups::all(), |g| (*g).into());
            let params = contact.params();
            if let Err(e) = params.validate() {
                if newly_set {
                    error!("point-springs surface {entity}: contacts off: {e}");
                }
            } else {
                let touched = touch(
                    &surface,
                    &colliders,
                    groups,
                    &mut context,
                    &mut bodies,
                    gravity,
                    dt,
                    &params,
                );
                report.colliders_near = touched.near;
                for c in &touched.impulses {
                    // Over the tick, in the surface's coordinates; in range by construction.
                    let force = frame.to_local * (c.impulse / dt);
                    if forces.add(c.point, force).is_ok() {
                        report.impulse += c.impulse;
                    }
                }
                report.touching = touched.impulses.len();
                report.total_impulse += report.impulse;
            }
        }
        touching += report.touching;
        if let Some(fresh) = inserted {
            commands.entity(entity).insert(fresh);
        }
    }
    *diagnostics = ContactDiagnostics {
        colliders: colliders.len(),
        touching,
        time: started.elapsed(),
    };
}

/// How a surface's coordinates map to the world for one tick.
#[derive(Clone, Copy)]
struct SurfaceFrame {
    place: bevy::math::Affine3A,
    /// World vectors into the surface's coordinates (forces and impulses).
    to_local: Mat3,
    /// The surface's gravity over one tick, in world coordinates.
    gravity_dt: Vec3,
    /// How much the frame scales lengths (radii).
    scale: f32,
}

impl SurfaceFrame {
    fn new(place: &GlobalTransform, gravity: Vec3, dt: f32) -> Self {
        let place = place.affine();
        let linear = Mat3::from(place.matrix3);
        let scale = linear.determinant().abs().cbrt();
        Self {
            place,
            to_local: linear.inverse(),
            gravity_dt: linear * gravity * dt,
            scale,
        }
    }
}

/// The parts of a surface the contacts read.
struct SurfaceView<'a> {
    points: &'a SimulationPoints,
    masses: &'a SurfaceMasses,
    springs: &'a SurfaceSprings,
    stepper: &'a SurfaceStepper,
    radii: &'a [f32],
    frame: SurfaceFrame,
}

impl SurfaceView<'_> {
    /// How much the surface's own forces change point `i`'s velocity over the tick (in its
    /// coordinates), with the point as heavy as its `step_mass` ([`step_masses`]): springs,
    /// gravity, drag, anchors and pressure, when the tick's forces have been accumulated;
    /// gravity alone otherwise.
    fn own_dv(&self, i: usize, step_mass: f32, dt: f32) -> Vec3 {
        if self.masses.is_pinned(i) || step_mass <= 0.0 {
            return Vec3::ZERO;
        }
        match self.stepper.own_force(i) {
            Some(f) => f * (dt / step_mass),
            None => self.stepper.config().gravity * dt,
        }
    }
}

/// What touching one surface gave.
struct Touched {
    near: usize,
    impulses: Vec<ContactImpulse>,
}

/// Rapier's colliders this tick: sensors and disabled ones left out, bounds swept.
fn list_colliders(
    context: &bevy_rapier3d::prelude::RapierContextMut<'_>,
    dt: f32,
) -> Vec<NearCollider> {
    let bodies = &context.rigidbody_set.bodies;
    context
        .colliders
        .colliders
        .iter()
        .filter(|(_, c)| c.is_enabled() && !c.is_sensor())
        .map(|(handle, c)| {
            let aabb = c.compute_aabb();
            let (min, max) = (aabb.mins, aabb.maxs);
            let body = c.parent().filter(|h| bodies.get(*h).is_some());
            // Grow the bounds by how far any of their points may move in the tick.
            let reach = body.and_then(|h| bodies.get(h)).map_or(0.0, |b| {
                let half_diagonal = 0.5 * (max - min).length();
                let spin = b.angvel().length()
                    * (half_diagonal + (b.center_of_mass() - 0.5 * (min + max)).length());
                (b.linvel().length() + spin) * dt
            });
            NearCollider {
                handle,
                body,
                min: min - Vec3::splat(reach),
                max: max + Vec3::splat(reach),
                groups: c.collision_groups(),
            }
        })
        .collect()
}

/// The contacts of one surface with every collider near it.
#[allow(clippy::too_many_arguments)]
fn touch(
    surface: &SurfaceView<'_>,
    colliders: &[NearCollider],
    groups: InteractionGroups,
    context: &mut bevy_rapier3d::prelude::RapierContextMut<'_>,
    bodies: &mut HashMap<RigidBodyHandle, BodyState>,
    gravity: Vec3,
    dt: f32,
    params: &ContactParams,
) -> Touched {
    let frame = surface.frame;
    // The surface's bounds over the tick, in world coordinates: one pass over the points.
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    let mut reach = 0.0_f32;
    for i in 0..surface.points.len() {
        let p = frame.place.transform_point3(surface.points.position(i));
        lo = lo.min(p);
        hi = hi.max(p);
        let v = frame.place.transform_vector3(surface.points.velocity(i)) + frame.gravity_dt;
        reach = reach.max(surface.radii[i] * frame.scale + v.length() * dt);
    }
    lo -= Vec3::splat(reach);
    hi += Vec3::splat(reach);
    let near: Vec<&NearCollider> = colliders
        .iter()
        .filter(|c| c.groups.test_and(groups))
        .filter(|c| c.min.cmple(hi).all() && c.max.cmpge(lo).all())
        .collect();
    let mut touched = Touched {
        near: near.len(),
        impulses: Vec::new(),
    };
    if near.is_empty() {
        return touched;
    }
    // The points in world coordinates: where they are, how fast they will go without
    // contacts, how far they reach.
    let step_mass = step_masses(
        surface.masses.masses(),
        surface.springs.iter().map(|(_, s)| s),
        dt,
    );
    let world: Vec<(Vec3, Vec3, f32)> = (0..surface.points.len())
        .map(|i| {
            let p = frame.place.transform_point3(surface.points.position(i));
            let own = surface.own_dv(i, step_mass[i], dt);
            let v = frame
                .place
                .transform_vector3(surface.points.velocity(i) + own);
            let radius = surface.radii[i] * frame.scale;
            (p, v, radius)
        })
        .collect();
    // The points in cells about twice the farthest reach wide.
    let max_reach = world
        .iter()
        .map(|(_, v, r)| r + v.length() * dt)
        .fold(0.0, f32::max);
    let positions: Vec<Vec3> = world.iter().map(|w| w.0).collect();
    let grid = PointGrid::new(&positions, 2.0 * max_reach);
    let mut candidates = Vec::new();
    // Proximities grouped by the body they touch (fixed colliders each on their own).
    let mut by_body: Vec<(Option<RigidBodyHandle>, Vec3, Vec<Proximity>)> = Vec::new();
    for c in near {
        let Some(collider) = context.colliders.colliders.get(c.handle) else {
            continue;
        };
        let (shape, pose) = (collider.shape(), *collider.position());
        let mut found = Vec::new();
        candidates.clear();
        let reach = Vec3::splat(max_reach);
        grid.near(c.min - reach, c.max + reach, |i| candidates.push(i));
        for &i in &candidates {
            let (p, velocity, radius) = world[i];
            let margin = Vec3::splat(radius + velocity.length() * dt);
            if (p + margin).cmplt(c.min).any() || (p - margin).cmpgt(c.max).any() {
                continue;
            }
            let projection = shape.project_point(&pose, p, true);
            let offset = p - projection.point;
            let distance = offset.length();
            let normal = if distance > NORMAL_EPSILON {
                if projection.is_inside {
                    -offset / distance
                } else {
                    offset / distance
                }
            } else {
                // On the shape's surface: push away from its centre.
                (p - pose.translation).normalize_or(Vec3::Y)
            };
            let gap = if projection.is_inside {
                -distance - radius
            } else {
                distance - radius
            };
            let mass = step_mass[i];
            let inv_mass = if surface.masses.is_pinned(i) || mass <= 0.0 {
                0.0
            } else {
                1.0 / mass
            };
            found.push(Proximity {
                point: i,
                at: projection.point,
                normal,
                gap,
                velocity,
                inv_mass,
            });
        }
        if found.is_empty() {
            continue;
        }
        match by_body
            .iter_mut()
            .find(|(b, _, _)| c.body.is_some() && *b == c.body)
        {
            Some((_, _, list)) => list.append(&mut found),
            None => by_body.push((c.body, pose.translation, found)),
        }
    }
    let rigid_bodies = &mut context.rigidbody_set.bodies;
    for (handle, center, mut proximities) in by_body {
        let rigid = handle.and_then(|h| rigid_bodies.get(h));
        let mut state = match (handle, rigid) {
            (Some(h), Some(b)) => *bodies
                .entry(h)
                .or_insert_with(|| body_state(b, gravity, dt)),
            _ => BodyState::immovable(Vec3::ZERO, Vec3::ZERO, center),
        };
        let Ok(impulses) = resolve(&mut state, &mut proximities, dt, params) else {
            continue;
        };
        if let (Some(h), Some(rigid)) = (handle, handle.and_then(|h| rigid_bodies.get_mut(h))) {
            bodies.insert(h, state);
            if rigid.is_dynamic() {
                for c in &impulses {
                    rigid.apply_impulse_at_point(-c.impulse, c.at, true);
                }
            }
        }
        touched.impulses.extend(impulses);
    }
    touched
}

/// A rapier body as contacts see it: its velocity at the end of the tick without contacts
/// (gravity included unless it sleeps), and its inverse mass and inertia if dynamic.
fn body_state(
    body: &bevy_rapier3d::rapier::dynamics::RigidBody,
    gravity: Vec3,
    dt: f32,
) -> BodyState {
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
