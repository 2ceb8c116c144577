//! Points held by something still, shown to rapier: after a surface's step, each of its
//! points that a fixed collider (or a body standing still) pushed this tick and that a
//! dynamic body is near becomes a fixed ball in rapier's scene (the point's sphere, where
//! the step left it, grown by rapier's allowed error), for rapier's step of the same tick. A point the floor holds cannot
//! give way, so to the bodies it is as fixed as the floor: a crate resting on a cloth on
//! the floor, and a crate landing on that crate, are solved by rapier's own solver together
//! (its contacts with the other crate and with the balls in one solve), not a tick apart.
//!
//! The balls are rapier colliders without a body and without an entity of their own: their
//! `user_data` is the surface's entity, so rapier's events and queries name the surface.
//! They take the surface's [`CollisionGroups`] and its contact friction, and the surfaces'
//! own contacts leave them out ([`BodySupports::is_support`]). A ball stays while a
//! dynamic body is near its surface and its point within a quarter of its radius of where
//! it was placed (moved with the point each tick); a surface that does not step keeps its
//! balls where they were; a surface gone, not ready, with contacts off or with its step
//! undone by the guard loses them. See decision 0034.

use std::collections::{BTreeMap, BTreeSet, HashSet};

use bevy::prelude::*;
use bevy_rapier3d::prelude::{CollisionGroups, RapierContextMut, WriteRapierContext};
use bevy_rapier3d::rapier::dynamics::CoefficientCombineRule;
use bevy_rapier3d::rapier::dynamics::RigidBodyHandle;
use bevy_rapier3d::rapier::geometry::{
    ColliderBuilder, ColliderHandle, InteractionGroups, SharedShape,
};

use super::surface::uniform_scale;
use super::{SurfaceContact, SurfaceContacts};
use crate::plugin::components::{SimulationPoints, SurfaceStatus, SurfaceStepper};

/// The balls standing for held points in rapier's scene, by surface and point.
#[derive(Resource, Debug, Default)]
pub struct BodySupports {
    /// Each ball's collider, by its surface and point (ordered: rapier's scene changes in
    /// the same order every run).
    balls: BTreeMap<(Entity, u32), Placed>,
    /// The balls placed this tick for the first time: rapier's step has not held a body
    /// off them yet.
    fresh: BTreeSet<(Entity, u32)>,
    /// The same colliders, to leave them out of the surfaces' contacts.
    handles: HashSet<ColliderHandle>,
    /// Each surface's step count when its balls were last placed.
    placed_at: BTreeMap<Entity, u64>,
}

impl BodySupports {
    /// Whether `handle` is one of the balls (the surfaces' contacts leave them out).
    pub fn is_support(&self, handle: ColliderHandle) -> bool {
        self.handles.contains(&handle)
    }

    /// The dynamic bodies that rest on a ball (touched one in rapier's last step): rapier's
    /// step ends them where its solver puts them, so the surfaces' steps neither move them
    /// out of their points nor land them ([`record_step_contacts`]).
    ///
    /// [`record_step_contacts`]: super::system::record_step_contacts
    pub(super) fn bodies_on(&self, context: &RapierContextMut<'_>) -> Vec<RigidBodyHandle> {
        let colliders = &context.colliders.colliders;
        let mut on: Vec<RigidBodyHandle> = self
            .balls
            .values()
            .flat_map(|placed| {
                context
                    .simulation
                    .narrow_phase
                    .contact_pairs_with(placed.handle)
            })
            .filter(|pair| pair.has_any_active_contact())
            .flat_map(|pair| [pair.collider1, pair.collider2])
            .filter(|h| !self.handles.contains(h))
            .filter_map(|h| colliders.get(h)?.parent())
            .collect();
        on.sort_unstable_by_key(|h| h.into_raw_parts());
        on.dedup();
        on
    }

    /// How many balls stand in rapier's scene now.
    pub fn len(&self) -> usize {
        self.balls.len()
    }

    /// Whether no ball stands in rapier's scene.
    pub fn is_empty(&self) -> bool {
        self.balls.is_empty()
    }

    /// The points of `surface` that stood as balls in rapier's last step already and stand
    /// on, in order: the bodies touching them are rapier's to hold off them.
    pub(super) fn standing_of(&self, surface: Entity) -> Vec<u32> {
        self.balls
            .range((surface, 0)..=(surface, u32::MAX))
            .filter(|(key, _)| !self.fresh.contains(key))
            .map(|((_, point), _)| *point)
            .collect()
    }
}

/// A surface as the supports read it.
type SupportSurface<'a> = (
    Entity,
    &'a SurfaceStepper,
    &'a SimulationPoints,
    &'a GlobalTransform,
    &'a SurfaceContacts,
    &'a SurfaceStatus,
    Option<&'a SurfaceContact>,
    Option<&'a CollisionGroups>,
);

/// After the surfaces' steps, before rapier's: each surface's held points near dynamic
/// bodies placed in rapier's scene as fixed balls; see the [module documentation](self).
pub(crate) fn support_bodies(
    surfaces: Query<SupportSurface<'_>>,
    mut supports: ResMut<BodySupports>,
    mut rapier: WriteRapierContext,
) {
    let Ok(mut context) = rapier.single_mut() else {
        return;
    };
    let mut wanted: BTreeMap<(Entity, u32), Ball> = BTreeMap::new();
    let mut kept: BTreeSet<Entity> = BTreeSet::new();
    // Rapier lets a body sink this far into what holds it before it pushes back: each
    // ball is that much larger than its point's sphere, so that a body resting on it
    // rests on the sphere's surface, as the surface's own contacts see it.
    let slop = context
        .simulation
        .integration_parameters
        .allowed_linear_error()
        .max(0.0);
    for surface in &surfaces {
        let entity = surface.0;
        let steps = surface.1.diagnostics().steps;
        match surface_balls(&surface, &supports, slop) {
            Some(balls) => {
                supports.placed_at.insert(entity, steps);
                wanted.extend(balls.into_iter().map(|(i, ball)| ((entity, i), ball)));
            }
            None => {
                kept.insert(entity);
            }
        }
    }
    let surfaces_now: BTreeSet<Entity> = surfaces.iter().map(|s| s.0).collect();
    supports.placed_at.retain(|e, _| surfaces_now.contains(e));
    let colliders = &mut context.colliders.colliders;
    let islands = &mut context.simulation.islands;
    let bodies = &mut context.rigidbody_set.bodies;
    // Balls no longer wanted go (those of a surface that did not step stay).
    let gone: Vec<(Entity, u32)> = supports
        .balls
        .keys()
        .filter(|key| !wanted.contains_key(key) && !kept.contains(&key.0))
        .copied()
        .collect();
    supports.fresh.clear();
    for key in gone {
        if let Some(placed) = supports.balls.remove(&key) {
            supports.handles.remove(&placed.handle);
            colliders.remove(placed.handle, islands, bodies, true);
        }
    }
    for (key, ball) in wanted {
        match supports
            .balls
            .get(&key)
            .and_then(|p| colliders.get_mut(p.handle))
        {
            Some(collider) => {
                collider.set_translation(ball.at);
                if collider.shape().as_ball().map(|b| b.radius) != Some(ball.radius) {
                    collider.set_shape(SharedShape::ball(ball.radius));
                }
                collider.set_friction(ball.friction);
                collider.set_collision_groups(ball.groups);
            }
            None => {
                let collider = ColliderBuilder::ball(ball.radius)
                    .translation(ball.at)
                    .friction(ball.friction)
                    .friction_combine_rule(CoefficientCombineRule::Average)
                    .restitution(0.0)
                    .collision_groups(ball.groups)
                    .user_data(u128::from(key.0.to_bits()))
                    .build();
                let handle = colliders.insert(collider);
                supports.balls.insert(
                    key,
                    Placed {
                        handle,
                        origin: ball.at,
                    },
                );
                supports.fresh.insert(key);
                supports.handles.insert(handle);
            }
        }
    }
}

/// How far a point standing as a ball may move from where it was first placed and stand
/// on, as a share of its radius: the floor holds it still.
const BALL_DRIFT: f32 = 0.25;

/// One surface's balls this tick, by point (none: it is not ready, its contacts are off, or
/// the guard undid its step); `None` if its balls stay as they are (it did not step).
fn surface_balls(
    (entity, stepper, points, place, report, status, contact, groups): &SupportSurface<'_>,
    supports: &BodySupports,
    slop: f32,
) -> Option<BTreeMap<u32, Ball>> {
    let contact = contact.copied().unwrap_or_default();
    let last = stepper.diagnostics();
    if !status.is_ready() || !contact.enabled || last.last.recovered {
        return Some(BTreeMap::new());
    }
    if supports.placed_at.get(entity) == Some(&last.steps) {
        return None;
    }
    let groups = groups.map_or(InteractionGroups::all(), |g| (*g).into());
    let scale = uniform_scale(Mat3::from(place.affine().matrix3));
    let ball = |i: u32| {
        let radius = report.radii().get(i as usize)? * scale + slop;
        let at = ((i as usize) < points.len())
            .then(|| place.transform_point(points.position(i as usize)))?;
        (at.is_finite() && radius.is_finite() && radius > 0.0).then_some(Ball {
            at,
            radius,
            friction: contact.friction,
            groups,
        })
    };
    // New balls: held up by something still, a dynamic body near.
    let mut balls: BTreeMap<u32, Ball> = report
        .held_near_bodies(stepper.contact_impulses())
        .filter_map(|i| Some((i, ball(i)?)))
        .collect();
    // Standing balls stay while a dynamic body is near the surface and their points stay
    // put (a point held up this tick may rest on the body alone the next).
    if !report.near_bodies.is_empty() {
        for (&(_, i), placed) in supports.balls.range((*entity, 0)..=(*entity, u32::MAX)) {
            if let Some(b) = ball(i)
                && b.at.distance(placed.origin) <= BALL_DRIFT * b.radius
            {
                balls.entry(i).or_insert(b);
            }
        }
    }
    Some(balls)
}

/// A ball in rapier's scene: its collider and where it was first placed.
#[derive(Debug, Clone, Copy)]
struct Placed {
    handle: ColliderHandle,
    origin: Vec3,
}

/// One held point as rapier is to see it.
struct Ball {
    /// Its centre, world coordinates.
    at: Vec3,
    radius: f32,
    friction: f32,
    groups: InteractionGroups,
}
