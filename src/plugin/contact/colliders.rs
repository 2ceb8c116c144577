//! Rapier's side of the search: its colliders listed once per tick, each with its bounds
//! swept over the tick by its body's motion, and those near one surface picked out by their
//! bounds and collision groups.

use bevy::prelude::*;
use bevy_rapier3d::prelude::RapierContextMut;
use bevy_rapier3d::rapier::dynamics::RigidBodyHandle;
use bevy_rapier3d::rapier::geometry::{ColliderHandle, InteractionGroups};

use super::BodySupports;

/// A collider as the contacts of one tick see it.
pub(super) struct NearCollider {
    pub(super) handle: ColliderHandle,
    /// The body whose velocity and mass the collider has (none: a fixed collider).
    pub(super) body: Option<RigidBodyHandle>,
    /// Bounds at the start of the tick, grown by the body's motion over the tick.
    pub(super) min: Vec3,
    pub(super) max: Vec3,
    groups: InteractionGroups,
}

/// Rapier's colliders this tick: sensors, disabled ones and the surfaces' own held points
/// ([`BodySupports`]) left out, bounds swept.
pub(super) fn list_colliders(
    context: &RapierContextMut<'_>,
    supports: &BodySupports,
    dt: f32,
) -> Vec<NearCollider> {
    let bodies = &context.rigidbody_set.bodies;
    context
        .colliders
        .colliders
        .iter()
        .filter(|(h, c)| c.is_enabled() && !c.is_sensor() && !supports.is_support(*h))
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

/// The colliders that a surface of collision `groups`, within `lo..hi` over the tick, may
/// touch: their groups and the surface's accept each other and their swept bounds meet.
pub(super) fn near_colliders(
    colliders: &[NearCollider],
    groups: InteractionGroups,
    lo: Vec3,
    hi: Vec3,
) -> Vec<&NearCollider> {
    colliders
        .iter()
        .filter(|c| c.groups.test_and(groups))
        .filter(|c| c.min.cmple(hi).all() && c.max.cmpge(lo).all())
        .collect()
}
