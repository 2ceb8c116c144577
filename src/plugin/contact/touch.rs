//! One surface against the colliders near it: each point whose sphere may reach a collider
//! over the tick is measured against the collider's exact shape (parry's point projection),
//! and the proximities found go, grouped by body, to the bodies' side to be resolved.

use bevy::prelude::*;
use bevy_rapier3d::prelude::RapierContextMut;
use bevy_rapier3d::rapier::dynamics::RigidBodyHandle;
use bevy_rapier3d::rapier::geometry::InteractionGroups;
use bevy_rapier3d::rapier::math::Pose;
use bevy_rapier3d::rapier::parry::shape::Shape;

use crate::core::solver::Integrator;
use crate::core::solver::contact::{ContactImpulse, ContactParams, Proximity, SpringIncidence};

use super::ContactSolve;
use super::bodies::{BodyContacts, Held, RigidSide};
use super::colliders::{NearCollider, near_colliders};
use super::surface::{SurfaceView, WorldPoint, WorldPoints};

/// Distances below this count as zero when a contact normal is taken from them.
const NORMAL_EPSILON: f32 = 1e-7;

/// What touching one surface gave.
pub(super) struct Touched {
    /// Colliders near the surface (their swept bounds met the surface's).
    pub(super) near: usize,
    /// The impulse on each point that touched.
    pub(super) impulses: Vec<ContactImpulse>,
    /// The points near a dynamic body, sorted.
    pub(super) near_bodies: Vec<u32>,
    /// The contacts for the surface's step to solve ([`ContactSolve::InStep`]), in world
    /// coordinates.
    pub(super) held: Held,
}

/// The contacts of one surface, of collision `groups`, with every collider near it.
pub(super) fn touch(
    surface: &SurfaceView<'_>,
    colliders: &[NearCollider],
    groups: InteractionGroups,
    rigid: &mut RigidSide<'_>,
    params: &ContactParams,
    solve: ContactSolve,
) -> Touched {
    let dt = rigid.dt;
    let (lo, hi) = surface.swept_bounds(dt);
    let near = near_colliders(colliders, groups, lo, hi);
    let mut touched = Touched {
        near: near.len(),
        impulses: Vec::new(),
        near_bodies: Vec::new(),
        held: Held::default(),
    };
    if near.is_empty() {
        return touched;
    }
    let world = surface.world_points(dt);
    let by_body = proximities_by_body(surface, &world, &near, &rigid.context, dt);
    let bodies = &rigid.context.rigidbody_set.bodies;
    let is_dynamic = |b: &BodyContacts| {
        b.body
            .and_then(|h| bodies.get(h))
            .is_some_and(|b| b.is_dynamic())
    };
    touched.near_bodies = by_body
        .iter()
        .filter(|b| is_dynamic(b))
        .flat_map(|b| b.proximities.iter().map(|p| p.point as u32))
        .collect();
    touched.near_bodies.sort_unstable();
    touched.near_bodies.dedup();

    // Built on the first body that several points touch, once for all of this tick's.
    let incidence = std::cell::OnceCell::new();
    let mut reweigh = |proximities: &mut [Proximity], touching: &[bool]| {
        let incidence = incidence.get_or_init(|| {
            let springs: Vec<_> = surface.springs.iter().map(|(_, s)| s).collect();
            SpringIncidence::new(surface.points.len(), &springs)
        });
        together(surface, incidence, proximities, touching, dt);
    };
    // Dynamic bodies are solved in the step only by implicit Euler (an explicit step's
    // points are as light as their own mass within it: the estimate is better), only where
    // the surface's frame is a turn and a uniform scale (a body's turning is not a turning
    // in a sheared frame), and not while the guard stops the surface's steps (a step
    // undone gives its bodies nothing; the estimate holds them).
    let stepper = surface.stepper;
    let dynamic_in_step = stepper.integrator() == Integrator::ImplicitEuler
        && !stepper.diagnostics().last.recovered
        && surface.frame.is_similarity();
    touched.impulses = rigid.resolve(
        by_body,
        params,
        (solve, dynamic_in_step),
        &mut reweigh,
        &mut touched.held,
    );
    touched
}

/// The points' proximities to each collider in `near`, grouped by the body they touch
/// (fixed colliders each on their own), in the order of `near`.
fn proximities_by_body(
    surface: &SurfaceView<'_>,
    world: &WorldPoints,
    near: &[&NearCollider],
    context: &RapierContextMut<'_>,
    dt: f32,
) -> Vec<BodyContacts> {
    let mut candidates = Vec::new();
    let mut by_body: Vec<BodyContacts> = Vec::new();
    for c in near {
        let Some(collider) = context.colliders.colliders.get(c.handle) else {
            continue;
        };
        let (shape, pose) = (collider.shape(), *collider.position());
        candidates.clear();
        let reach = Vec3::splat(world.max_reach);
        world
            .grid
            .near(c.min - reach, c.max + reach, |i| candidates.push(i));
        let found: Vec<Proximity> = candidates
            .iter()
            .filter_map(|&i| {
                let inv_mass = surface.inv_mass(i, world.step_mass[i]);
                proximity(i, &world.points[i], inv_mass, c, shape, &pose, dt)
            })
            .collect();
        if !found.is_empty() {
            join_body(&mut by_body, c.body, pose.translation, found);
        }
    }
    by_body
}

/// The points that touch one body together move together within the tick: each takes the
/// mass of [`group_step_masses`](crate::core::solver::contact::group_step_masses), without
/// the springs to the others (`touching[k]`: whether `proximities[k]` touches), from the
/// springs' `incidence` (the points' own springs only).
fn together(
    surface: &SurfaceView<'_>,
    incidence: &SpringIncidence,
    proximities: &mut [Proximity],
    touching: &[bool],
    dt: f32,
) {
    let mut touched: Vec<usize> = proximities
        .iter()
        .zip(touching)
        .filter(|(_, t)| **t)
        .map(|(p, _)| p.point)
        .collect();
    touched.sort_unstable();
    let touches = |i: usize| touched.binary_search(&i).is_ok();
    let masses = surface.masses.masses();
    for p in proximities.iter_mut() {
        let Some(&mass) = masses.get(p.point) else {
            continue;
        };
        let step_mass = incidence.group_step_mass(mass, p.point, touches, dt);
        p.inv_mass = surface.inv_mass(p.point, step_mass);
    }
}

/// Point `i`'s proximity to collider `c` (of `shape` at `pose`), or none if its sphere
/// cannot reach the collider's swept bounds over the tick.
fn proximity(
    i: usize,
    point: &WorldPoint,
    inv_mass: f32,
    c: &NearCollider,
    shape: &dyn Shape,
    pose: &Pose,
    dt: f32,
) -> Option<Proximity> {
    let WorldPoint {
        at: p,
        velocity,
        radius,
    } = *point;
    let margin = Vec3::splat(radius + velocity.length() * dt);
    if (p + margin).cmplt(c.min).any() || (p - margin).cmpgt(c.max).any() {
        return None;
    }
    let projection = shape.project_point(pose, p, true);
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
    Some(Proximity {
        point: i,
        at: projection.point,
        normal,
        gap,
        velocity,
        inv_mass,
    })
}

/// Adds `found` to the proximities of `body`, or starts a group for it (a fixed collider,
/// `body` none, always starts its own).
fn join_body(
    by_body: &mut Vec<BodyContacts>,
    body: Option<RigidBodyHandle>,
    center: Vec3,
    mut found: Vec<Proximity>,
) {
    match by_body
        .iter_mut()
        .find(|b| body.is_some() && b.body == body)
    {
        Some(group) => group.proximities.append(&mut found),
        None => by_body.push(BodyContacts {
            body,
            center,
            proximities: found,
        }),
    }
}
