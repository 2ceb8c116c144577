//! Deformable surfaces touching each other (issue 35, item 1), with or without rapier: put
//! [`SurfaceMeeting`] on each surface that should meet others.
//!
//! Each tick, after the surfaces' own forces and before their steps ([`meet_surfaces`]):
//!
//! 1. each meeting surface's bounds, swept over the tick by its fastest point, are sorted
//!    and swept along x ([`overlapping_pairs`]), and the pairs whose bounds overlap are
//!    filtered by their groups (and rapier's `CollisionGroups`); two far-apart surfaces
//!    cost that test alone, and many surfaces a sort and the pairs that overlap along x;
//! 2. for a pair whose bounds meet, the points of both in world coordinates, each with the
//!    velocity its own forces give it over the tick (as heavy as its step mass), and the
//!    second's points bucketed in a grid;
//! 3. each point of the second is a small body (its sphere, its step mass) that the first's
//!    points near it push and are pushed by, resolved as rigid contacts are
//!    ([`resolve_in_passes`]): the speculative sweep (a point still apart is stopped only where the
//!    gap would close within the tick), a share of an overlap pushed out, Coulomb friction;
//! 4. each impulse goes to both surfaces' [`SurfaceForces`] as equal
//!    and opposite forces over the tick, so momentum is exchanged exactly; each surface's
//!    [`SurfaceMeetingReport`] says what touched it.
//!
//! A surface with [`SurfaceMeeting::self_contact`] also meets itself, before it meets the
//! others (`own.rs`): its points against its own points more than
//! [`SurfaceMeeting::self_rings`] springs apart on its network, and each point against the
//! triangles near it, in the same way.
//!
//! With [`SurfaceMeeting::in_step`] (the default) each touching point is then handed to its
//! surface's step as well, which holds it to what the estimate allowed with its springs
//! solved; what the two steps of a pair add is shared out between its points the next tick
//! ([`record_meeting_contacts`]). See `docs/ARCHITECTURE.md`, "Surfaces meeting surfaces".

mod own;

use std::sync::Arc;

use bevy::prelude::*;

use crate::core::network::SpringNetwork;
use crate::core::solver::contact::{
    BodyState, ContactParams, DEFAULT_DEPTH_RECOVERY, DEFAULT_FRICTION, DEFAULT_RADIUS_SCALE,
    DEFAULT_SELF_CONTACT_RINGS, PointGrid, Proximity, StepContact, Untangled, group_step_masses,
    overlapping_pairs, point_radii, resolve_in_passes, step_masses, untangle,
};

use super::components::{
    SimulationPoints, StepOnce, SurfaceForces, SurfaceMasses, SurfaceNetwork, SurfaceRunSettings,
    SurfaceSprings, SurfaceStatus, SurfaceStepper,
};
use super::simulate::running;

/// A contact handed to the step: its point, and the surface (this one in self-contact)
/// and points that pushed it, with their weights (summing to 1; unused ones 0).
#[derive(Debug, Clone, Copy)]
struct Link {
    point: u32,
    other: Entity,
    with: [(u32, f32); 3],
}

/// What one contact found by the estimate hands to the step: the point, the normal (world),
/// the other side's point and how far the pair is to be moved apart out of an overlap
/// (world, by position: half by each side's step).
#[derive(Debug, Clone, Copy)]
struct Touch {
    point: usize,
    other: usize,
    normal: Vec3,
    recover: f32,
}

/// Gauss–Seidel passes over the contacts between two surfaces, and over a surface's own,
/// each tick: a point pushed by a later contact may close on an earlier one again, and a
/// second pass stops it.
const CONTACT_PASSES: usize = 2;

/// Every group: the default membership and filter.
pub const ALL_GROUPS: u32 = u32::MAX;

/// How a surface meets other surfaces and itself (opt-in: surfaces without it pass through
/// each other and through themselves). Two surfaces meet when each one's `groups` share a
/// bit with the other's `filter`, and, with the `rapier` feature, when their rapier
/// `CollisionGroups` (where they have them) allow it as they would for two colliders: one
/// `CollisionGroups` on a surface then chooses both the bodies and the surfaces it
/// touches. What touched the surface is in its [`SurfaceMeetingReport`], added with this.
#[derive(Component, Debug, Clone, Reflect)]
#[reflect(Component, Debug, Default)]
#[require(SurfaceMeetingReport)]
pub struct SurfaceMeeting {
    /// Whether the surface meets others (and itself) at all.
    pub enabled: bool,
    /// The groups the surface belongs to (bits).
    pub groups: u32,
    /// The groups it meets (bits).
    pub filter: u32,
    /// Coulomb friction coefficient μ between this surface and another (the pair uses the
    /// smaller of theirs), and between its own parts.
    pub friction: f32,
    /// Fraction of an overlap pushed out per tick, in [0, 1] (the pair uses the smaller).
    pub depth_recovery: f32,
    /// Radius of each simulation point's sphere, as a share of the mean rest length of its
    /// stretch springs.
    pub radius_scale: f32,
    /// Whether the surface meets itself too: its points against its own points more than
    /// `self_rings` springs apart (a sheet folding onto itself, a hat pulled through its
    /// own rim).
    pub self_contact: bool,
    /// In self-contact, points this many stretch springs apart or fewer (and points whose
    /// spheres overlap at rest) do not touch each other.
    pub self_rings: u32,
    /// Whether the contacts are also handed to the surface's step, which holds each
    /// touching point to what its contact allows with its springs solved (the default);
    /// off, they are only estimated before the step, which costs less (no active set in the
    /// step) but lets a fast cloth through another or itself. A pair hands its contacts to
    /// the steps when both surfaces do.
    pub in_step: bool,
}

impl Default for SurfaceMeeting {
    fn default() -> Self {
        Self {
            enabled: true,
            groups: ALL_GROUPS,
            filter: ALL_GROUPS,
            friction: DEFAULT_FRICTION,
            depth_recovery: DEFAULT_DEPTH_RECOVERY,
            radius_scale: DEFAULT_RADIUS_SCALE,
            self_contact: true,
            self_rings: DEFAULT_SELF_CONTACT_RINGS,
            in_step: true,
        }
    }
}

impl SurfaceMeeting {
    /// Whether this surface and `other` meet: both enabled, and each one's groups in the
    /// other's filter, both by their own settings and by rapier's `CollisionGroups` where
    /// a surface has them (read this tick into `mine` and `theirs`; a surface without them
    /// is in every group and meets every group, as in rapier).
    fn meets(
        &self,
        mine: &SurfaceMeetingReport,
        other: &Self,
        theirs: &SurfaceMeetingReport,
    ) -> bool {
        let own = |m: &Self| GroupBits {
            groups: m.groups,
            filter: m.filter,
        };
        self.enabled
            && other.enabled
            && own(self).allow(&own(other))
            && mine.collision_groups.allow(&theirs.collision_groups)
    }
}

/// A surface's groups and the groups it meets, as bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct GroupBits {
    groups: u32,
    filter: u32,
}

impl Default for GroupBits {
    /// In every group, meeting every group.
    fn default() -> Self {
        Self {
            groups: ALL_GROUPS,
            filter: ALL_GROUPS,
        }
    }
}

impl GroupBits {
    /// Whether each side's groups share a bit with the other's filter.
    fn allow(&self, other: &Self) -> bool {
        self.groups & other.filter != 0 && other.groups & self.filter != 0
    }
}

/// Reads each meeting surface's rapier [`CollisionGroups`] for this tick's meeting: they
/// choose which surfaces meet as they choose which colliders touch, on top of
/// [`SurfaceMeeting::groups`] and [`SurfaceMeeting::filter`].
///
/// [`CollisionGroups`]: bevy_rapier3d::prelude::CollisionGroups
#[cfg(feature = "rapier")]
pub fn read_collision_groups(
    mut surfaces: Query<(
        Option<&bevy_rapier3d::prelude::CollisionGroups>,
        &mut SurfaceMeetingReport,
    )>,
) {
    for (groups, mut report) in &mut surfaces {
        report.bypass_change_detection().collision_groups =
            groups.map_or_else(GroupBits::default, |g| GroupBits {
                groups: g.memberships.bits(),
                filter: g.filters.bits(),
            });
    }
}

/// What touched a meeting surface ([`SurfaceMeeting`]), kept by the plugin each tick.
#[derive(Component, Debug, Clone, Default, Reflect)]
#[reflect(Component, Debug, Default)]
pub struct SurfaceMeetingReport {
    /// The memberships and filters of the surface's rapier `CollisionGroups` this tick (every
    /// group without them, or without the `rapier` feature).
    #[reflect(ignore)]
    collision_groups: GroupBits,
    /// Surfaces whose bounds met this one's last tick.
    near: usize,
    /// This surface's points that took an impulse from another surface last tick.
    touching: usize,
    /// This surface's points that touched its own points last tick.
    self_touching: usize,
    /// Impulse on this surface from others last tick (world, N·s).
    impulse: Vec3,
    /// Impulse on this surface from others since it was prepared (world, N·s).
    total_impulse: Vec3,
    /// The sphere radii.
    #[reflect(ignore)]
    radii: PointRadii,
    /// The pairs self-contact leaves out.
    #[reflect(ignore)]
    neighbours: own::Neighbours,
    /// The contacts handed to this tick's step start at this index of its
    /// [`SurfaceForces`]' contacts.
    #[reflect(ignore)]
    contacts_from: usize,
    /// For each contact handed to the step, what pushed its point.
    #[reflect(ignore)]
    links: Vec<Link>,
    /// The stepper's step count when the step's contacts were last read.
    #[reflect(ignore)]
    steps_read: u64,
    /// Impulses (world, N·s) this surface's points owe for what the steps added at the
    /// contacts with other surfaces last tick, taken this tick; and those at its own.
    #[reflect(ignore)]
    owed: Vec<(u32, Vec3)>,
    #[reflect(ignore)]
    owed_self: Vec<(u32, Vec3)>,
    /// With self-contact: where the points were when this tick's step began, and the
    /// stepper's step count then ([`untangle_surfaces`]).
    #[reflect(ignore)]
    start: (Vec<Vec3>, u64),
    /// What the fail-safe against crossing itself did last tick.
    #[reflect(ignore)]
    untangled: Untangled,
}

impl SurfaceMeetingReport {
    /// Surfaces whose bounds met this one's last tick.
    pub fn near(&self) -> usize {
        self.near
    }

    /// This surface's points that took an impulse from another surface last tick.
    pub fn touching(&self) -> usize {
        self.touching
    }

    /// This surface's points that touched its own points last tick (self-contact).
    pub fn self_touching(&self) -> usize {
        self.self_touching
    }

    /// The impulse other surfaces gave this one last tick (world, N·s).
    pub fn impulse(&self) -> Vec3 {
        self.impulse
    }

    /// The impulse other surfaces gave this one since it was prepared (world, N·s).
    pub fn total_impulse(&self) -> Vec3 {
        self.total_impulse
    }

    /// What the fail-safe against the surface passing through itself did last tick
    /// ([`untangle`]): the crossings the step made (none, nearly always: self-contact's
    /// contacts keep its folds apart) and the points moved back to undo them.
    pub fn untangled(&self) -> Untangled {
        self.untangled
    }

    fn refresh_radii(&mut self, network: &Arc<SpringNetwork>, scale: f32) {
        if self.radii.refresh(network, scale.max(0.0)) {
            self.total_impulse = Vec3::ZERO;
        }
    }
}

/// Each simulation point's sphere radius ([`point_radii`]), kept until the network (a
/// surface prepared again) or the scale changes.
#[derive(Debug, Clone, Default)]
pub(crate) struct PointRadii {
    radii: Vec<f32>,
    of: Option<(Arc<SpringNetwork>, u32)>,
}

impl PointRadii {
    /// Computes the radii again where the network or the scale changed; returns whether
    /// it did.
    pub(crate) fn refresh(&mut self, network: &Arc<SpringNetwork>, scale: f32) -> bool {
        let current = matches!(&self.of,
            Some((n, s)) if Arc::ptr_eq(n, network) && *s == scale.to_bits());
        if !current {
            self.radii = point_radii(network, scale);
            self.of = Some((Arc::clone(network), scale.to_bits()));
        }
        !current
    }

    /// The radii, in the surface's coordinates.
    pub(crate) fn get(&self) -> &[f32] {
        &self.radii
    }
}

/// One meeting surface's points this tick, in world coordinates.
struct Side {
    /// World positions.
    at: Vec<Vec3>,
    /// Velocities now (world).
    start: Vec<Vec3>,
    /// The surface's own forces on each point over the tick (world, N·s): springs,
    /// gravity, drag, anchors, pressure.
    push: Vec<Vec3>,
    /// Gravity's velocity change over the tick (world).
    fall: Vec3,
    /// How far each point goes over the tick at its velocity now with gravity's (world):
    /// what self-contact looks within (the sweep then stops it exactly).
    motion: Vec<f32>,
    /// Each point's own mass.
    mass: Vec<f32>,
    /// How far a point may go in the tick, plus its sphere (world): its speed now and
    /// gravity's over the tick.
    reach: f32,
    /// Sphere radii (world).
    radius: Vec<f32>,
    /// Bounds, swept over the tick by the fastest point and the largest sphere.
    lo: Vec3,
    hi: Vec3,
    /// World vectors into the surface's coordinates.
    to_local: Mat3,
    /// The surface's scale (world lengths per local length).
    scale: f32,
    /// Whether each point is pinned.
    pinned: Vec<bool>,
}

/// What [`meet_surfaces`] reads and changes of a surface.
type MeetParts = (
    Entity,
    (&'static SurfaceMeeting, &'static mut SurfaceMeetingReport),
    (&'static SimulationPoints, &'static SurfaceMasses),
    (&'static SurfaceSprings, &'static SurfaceNetwork),
    &'static SurfaceStepper,
    &'static mut SurfaceForces,
    Option<&'static GlobalTransform>,
    (
        &'static SurfaceStatus,
        &'static SurfaceRunSettings,
        Has<StepOnce>,
    ),
);

/// Surfaces meeting surfaces this tick; see the [module documentation](self).
pub fn meet_surfaces(time: Res<Time>, mut surfaces: Query<MeetParts>) {
    let dt = time.delta_secs();
    if dt <= 0.0 {
        return;
    }
    // Each meeting surface that steps this tick, in world coordinates.
    let mut sides: Vec<(Entity, Side)> = Vec::new();
    for (
        entity,
        (meeting, mut report),
        (points, masses),
        (_, network),
        stepper,
        mut forces,
        place,
        (status, settings, once),
    ) in &mut surfaces
    {
        let report = report.bypass_change_detection();
        report.near = 0;
        report.touching = 0;
        report.self_touching = 0;
        report.impulse = Vec3::ZERO;
        report.links.clear();
        report.contacts_from = forces.contacts().len();
        let (owed, owed_self) = (
            std::mem::take(&mut report.owed),
            std::mem::take(&mut report.owed_self),
        );
        report.untangled = Untangled::default();
        if !meeting.enabled || !running(status, settings, once) {
            report.start.0.clear();
            continue;
        }
        if meeting.self_contact {
            report.start.0.clear();
            report.start.0.extend(points.iter_positions());
            report.start.1 = stepper.diagnostics().steps;
        }
        // What the steps added at the contacts last tick, owed back (counted in the report
        // when the steps made it).
        let to_local = place.map_or(Mat3::IDENTITY, |p| Mat3::from(p.affine().matrix3).inverse());
        for (i, j) in owed.into_iter().chain(owed_self) {
            let _ = forces.add(i as usize, to_local * (j / dt));
        }
        report.refresh_radii(&network.0, meeting.radius_scale);
        if report.radii.get().len() != points.len() {
            continue;
        }
        let side = Side::new(points, masses, stepper, place, report.radii.get(), dt);
        if meeting.self_contact {
            let radii = report.radii.get();
            report
                .neighbours
                .refresh(&network.0, meeting.self_rings, radii);
        }
        sides.push((entity, side));
    }
    for (entity, side) in &sides {
        if let Ok(item) = surfaces.get_mut(*entity)
            && item.1.0.self_contact
        {
            own::meet_itself(&mut Pair::of(item), side, dt);
        }
    }
    if sides.len() < 2 {
        return;
    }
    // The pairs whose swept bounds overlap, found by sorting and sweeping them along x:
    // surfaces far apart along x are not even compared.
    let bounds: Vec<(Vec3, Vec3)> = sides.iter().map(|(_, s)| (s.lo, s.hi)).collect();
    for (i, j) in overlapping_pairs(&bounds) {
        let (a, b) = (&sides[i], &sides[j]);
        let Ok([first, second]) = surfaces.get_many_mut([a.0, b.0]) else {
            continue;
        };
        let (mut first, mut second) = (Pair::of(first), Pair::of(second));
        if first
            .meeting
            .meets(first.report, second.meeting, second.report)
        {
            meet_pair(&mut first, &a.1, &mut second, &b.1, dt);
        }
    }
}

impl Side {
    fn new(
        points: &SimulationPoints,
        masses: &SurfaceMasses,
        stepper: &SurfaceStepper,
        place: Option<&GlobalTransform>,
        radii: &[f32],
        dt: f32,
    ) -> Self {
        let place = place.map_or(bevy::math::Affine3A::IDENTITY, GlobalTransform::affine);
        let linear = Mat3::from(place.matrix3);
        let scale = linear.determinant().abs().cbrt();
        let n = points.len();
        let gravity = linear * stepper.gravity() * dt;
        let (mut at, mut start, mut push, mut radius) = (
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
        );
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        let mut reach = 0.0_f32;
        let mut motions = Vec::with_capacity(n);
        for (i, &r) in radii.iter().enumerate().take(n) {
            let p = place.transform_point3(points.position(i));
            let v = linear * points.velocity(i);
            let f = stepper
                .own_force(i)
                .map_or(stepper.gravity() * masses.mass(i), |f| f);
            let r = r * scale;
            lo = lo.min(p);
            hi = hi.max(p);
            let motion = (v + gravity).length() * dt;
            reach = reach.max(r + motion);
            motions.push(motion);
            at.push(p);
            start.push(v);
            push.push(linear * f * dt);
            radius.push(r);
        }
        Self {
            at,
            start,
            push,
            fall: gravity,
            motion: motions,
            mass: masses.masses().to_vec(),
            reach,
            radius,
            lo: lo - Vec3::splat(reach),
            hi: hi + Vec3::splat(reach),
            to_local: linear.inverse(),
            scale,
            pinned: (0..n).map(|i| masses.is_pinned(i)).collect(),
        }
    }

    /// Point `i`'s velocity at the end of the tick under its surface's own forces:
    /// gravity's full change, the rest (springs, drag, pressure) as an implicit step
    /// changes it, the point as heavy as its full `step_mass` ([`step_masses`]; a pinned
    /// point keeps its velocity). Divided by the point's own mass instead, a strained
    /// spring's force predicts explicit Euler's step, which on a light point held by stiff
    /// springs is many times too large: two cloths meeting at 5 m/s were thrown apart at
    /// 20 m/s.
    fn predicted(&self, i: usize, step_mass: f32) -> Vec3 {
        if self.pinned[i] || step_mass <= 0.0 {
            self.start[i]
        } else {
            let own = self.mass.get(i).copied().unwrap_or(0.0);
            self.start[i] + self.fall + (self.push[i] - self.fall * own) / step_mass
        }
    }

    /// Every point's full step mass ([`step_masses`]) for [`Self::predicted`].
    fn full_step_masses(&self, springs: &SurfaceSprings, dt: f32) -> Vec<f32> {
        step_masses(&self.mass, springs.iter().map(|(_, s)| s), dt)
    }

    /// Point `i`'s inverse mass within the step.
    fn inv_mass(&self, i: usize, step_mass: f32) -> f32 {
        if self.pinned[i] || step_mass <= 0.0 {
            0.0
        } else {
            1.0 / step_mass
        }
    }
}

/// What one surface of a pair reads and changes.
struct Pair<'a> {
    entity: Entity,
    meeting: &'a SurfaceMeeting,
    report: &'a mut SurfaceMeetingReport,
    masses: &'a SurfaceMasses,
    springs: &'a SurfaceSprings,
    forces: Mut<'a, SurfaceForces>,
}

impl<'a> Pair<'a> {
    fn of(item: bevy::ecs::query::QueryItem<'a, 'a, MeetParts>) -> Self {
        let (entity, (meeting, report), (_, masses), (springs, _), _, forces, _, _) = item;
        Self {
            entity,
            meeting,
            report: report.into_inner(),
            masses,
            springs,
            forces,
        }
    }
}

/// The contacts between two surfaces whose bounds meet: the second's points are bodies the
/// first's points push, resolved in turn; both take the impulses as forces over the tick.
fn meet_pair(first: &mut Pair<'_>, a: &Side, second: &mut Pair<'_>, b: &Side, dt: f32) {
    let params = ContactParams {
        friction: first.meeting.friction.min(second.meeting.friction),
        depth_recovery: first
            .meeting
            .depth_recovery
            .min(second.meeting.depth_recovery),
    };
    if params.validate().is_err() {
        return;
    }
    first.report.near += 1;
    second.report.near += 1;
    // Pairs within reach over the tick: a's points near each of b's.
    let (reach_a, reach_b) = (a.reach, b.reach);
    let grid = PointGrid::new(&a.at, (reach_a + reach_b).max(f32::EPSILON));
    let mut pairs: Vec<(usize, Vec<usize>)> = Vec::new();
    let (mut touching_a, mut touching_b) = (vec![false; a.at.len()], vec![false; b.at.len()]);
    for (k, &pb) in b.at.iter().enumerate() {
        let margin = Vec3::splat(reach_b);
        if !((a.lo - margin).cmple(pb).all() && pb.cmple(a.hi + margin).all()) {
            continue;
        }
        let mut near = Vec::new();
        let r = Vec3::splat(reach_a + reach_b);
        grid.near(pb - r, pb + r, |i| {
            if a.at[i].distance(pb) - a.radius[i] - b.radius[k] <= reach_a + reach_b {
                near.push(i);
            }
        });
        if !near.is_empty() {
            touching_b[k] = true;
            for &i in &near {
                touching_a[i] = true;
            }
            pairs.push((k, near));
        }
    }
    if pairs.is_empty() {
        return;
    }
    // The touching points' masses within the step (their springs to points that do not
    // touch), and the velocities the surfaces' own forces give them as that heavy.
    let step_a = group_step_masses(
        first.masses.masses(),
        first.springs.iter().map(|(_, s)| s),
        &touching_a,
        dt,
    );
    let step_b = group_step_masses(
        second.masses.masses(),
        second.springs.iter().map(|(_, s)| s),
        &touching_b,
        dt,
    );
    let full_a = a.full_step_masses(first.springs, dt);
    let full_b = b.full_step_masses(second.springs, dt);
    let mut va: Vec<Vec3> = (0..a.at.len()).map(|i| a.predicted(i, full_a[i])).collect();
    let mut vb: Vec<Vec3> = (0..b.at.len()).map(|k| b.predicted(k, full_b[k])).collect();
    let (mut on_a, mut on_b) = (Vec::new(), Vec::new());
    let mut touches: Vec<Touch> = Vec::new();
    for _ in 0..CONTACT_PASSES {
        for (k, near) in &pairs {
            let k = *k;
            let body = Sphere {
                at: b.at[k],
                radius: b.radius[k],
                inv_mass: b.inv_mass(k, step_b[k]),
            };
            let spheres = (&a.at[..], &a.radius[..]);
            let inv_a = |i: usize| a.inv_mass(i, step_a[i]);
            let pushed = push_apart(
                &body, &mut vb[k], near, spheres, &mut va, &inv_a, dt, &params,
            );
            for (i, impulse, normal, recover) in pushed {
                on_a.push((i, impulse));
                on_b.push((k, -impulse));
                touches.push(Touch {
                    point: i,
                    other: k,
                    normal,
                    recover,
                });
            }
        }
    }
    touches.sort_unstable_by_key(|t| (t.point, t.other));
    touches.dedup_by_key(|t| (t.point, t.other));
    let (entity_a, entity_b) = (first.entity, second.entity);
    if !(first.meeting.in_step && second.meeting.in_step) {
        touches.clear();
    }
    for t in &touches {
        let (i, k) = (t.point, t.other);
        hand_to_step(
            first,
            a,
            (i, va[i]),
            (t.normal, 0.5 * t.recover),
            (entity_b, one(k), vb[k]),
            &params,
        );
        hand_to_step(
            second,
            b,
            (k, vb[k]),
            (-t.normal, 0.5 * t.recover),
            (entity_a, one(i), va[i]),
            &params,
        );
    }
    record(first, a, &on_a, dt);
    record(second, b, &on_b, dt);
}

/// One point, weight 1, as what pushed a contact ([`Link::with`]).
fn one(point: usize) -> [(u32, f32); 3] {
    [(point as u32, 1.0), (0, 0.0), (0, 0.0)]
}

/// A point as a small body the points near it push ([`push_apart`]).
struct Sphere {
    at: Vec3,
    radius: f32,
    inv_mass: f32,
}

/// Resolves the contacts of the point `body` (its velocity `velocity`) with the points
/// `near` of a side (`spheres`: every point's place and radius; `v`, `inv_mass`: their
/// velocities and inverse masses), in the order they happen ([`resolve_in_passes`]); both
/// velocities take the impulses. Returns each impulse on a near point, with its normal and
/// how far the pair is to be moved apart out of an overlap.
#[allow(clippy::too_many_arguments)]
fn push_apart(
    body: &Sphere,
    velocity: &mut Vec3,
    near: &[usize],
    (at, radius): (&[Vec3], &[f32]),
    v: &mut [Vec3],
    inv_mass: &dyn Fn(usize) -> f32,
    dt: f32,
    params: &ContactParams,
) -> Vec<(usize, Vec3, Vec3, f32)> {
    let mut state = BodyState {
        linear: *velocity,
        angular: Vec3::ZERO,
        center: body.at,
        inv_mass: Vec3::splat(body.inv_mass),
        inv_inertia: Mat3::ZERO,
    };
    let mut proximities: Vec<Proximity> = near
        .iter()
        .filter_map(|&i| {
            let d = at[i] - body.at;
            let length = d.length();
            let normal = if length > f32::EPSILON {
                d / length
            } else {
                (v[i] - state.linear).normalize_or(Vec3::Y)
            };
            let inv = inv_mass(i);
            (inv > 0.0 || body.inv_mass > 0.0).then_some(Proximity {
                point: i,
                at: body.at + normal * body.radius,
                normal,
                gap: length - radius[i] - body.radius,
                velocity: v[i],
                inv_mass: inv,
            })
        })
        .collect();
    let Ok(impulses) = resolve_in_passes(&mut state, &mut proximities, dt, params, 1) else {
        return Vec::new();
    };
    *velocity = state.linear;
    impulses
        .into_iter()
        .filter(|c| c.impulse.is_finite())
        .map(|c| {
            v[c.point] += c.impulse * inv_mass(c.point);
            let normal = proximities
                .iter()
                .find(|p| p.point == c.point)
                .map_or(Vec3::ZERO, |p| p.normal);
            (c.point, c.impulse, normal, c.moved.length())
        })
        .collect()
}

/// Hands the step the contact of `side`'s point (`own`: its index and the velocity the
/// estimate left it with, world) with what pushed it (`other`: its surface, its points
/// with their weights, and its velocity there): the step keeps the point's velocity along
/// `normal` (world, from the other side towards this point) at least the estimate's, with
/// the springs solved with it, so a point whose springs took part of its estimated push is
/// pushed the rest of the way, and moves the point `recover` (world) out of an overlap by
/// position. What the two steps add at a pair's contacts is shared out between its points
/// the next tick ([`record_meeting_contacts`]).
fn hand_to_step(
    pair: &mut Pair<'_>,
    side: &Side,
    own: (usize, Vec3),
    (normal, recover): (Vec3, f32),
    other: (Entity, [(u32, f32); 3], Vec3),
    params: &ContactParams,
) {
    let (point, velocity) = own;
    let local_normal = (side.to_local * normal).normalize_or_zero();
    let Ok(index) = u32::try_from(point) else {
        return;
    };
    if local_normal == Vec3::ZERO || side.pinned[point] {
        return;
    }
    let contact = StepContact {
        point: index,
        normal: local_normal,
        min_speed: (side.to_local * velocity).dot(local_normal),
        body_velocity: side.to_local * other.2,
        friction: params.friction,
        body: None,
        arm: Vec3::ZERO,
        recover: (recover / side.scale).max(0.0),
    };
    if pair.forces.add_contact(contact).is_ok() {
        pair.report.links.push(Link {
            point: index,
            other: other.0,
            with: other.1,
        });
    }
}

/// After the step: what it added at each meeting contact (world). The two steps of a
/// pair's points each push their own point out of the other's way (`X` and `X'`, the
/// springs solved with them); their sum, which no opposite force met, is taken back from
/// both points, half each, the next tick, so that the pair exchanges `(X − X')/2` each way
/// and momentum is kept exactly, a tick late. (Giving each point the opposite of the
/// other's push instead counts both pushes twice: a cloth thrown at a drum at 5 m/s
/// bounced back at 2.5.) Counted in the report of a surface met by another. A surface
/// that did not step this tick added nothing.
pub fn record_meeting_contacts(
    mut surfaces: Query<(
        Entity,
        &mut SurfaceMeetingReport,
        &SurfaceStepper,
        Option<&GlobalTransform>,
    )>,
) {
    // To whom, which point, how much, whether between two surfaces, whether to count it
    // in the report of the surface it is owed to.
    let mut owed: Vec<(Entity, u32, Vec3, bool, bool)> = Vec::new();
    for (entity, mut report, stepper, place) in &mut surfaces {
        let report = report.bypass_change_detection();
        let steps = stepper.diagnostics().steps;
        let stepped = std::mem::replace(&mut report.steps_read, steps) != steps;
        let links = std::mem::take(&mut report.links);
        if !stepped || links.is_empty() {
            continue;
        }
        let linear = place.map_or(Mat3::IDENTITY, |p| Mat3::from(p.affine().matrix3));
        let added = stepper
            .contact_impulses()
            .get(report.contacts_from..)
            .unwrap_or(&[]);
        for (link, j) in links.into_iter().zip(added) {
            let world = linear * *j;
            if *j == Vec3::ZERO || !world.is_finite() {
                continue;
            }
            let met = link.other != entity;
            if met {
                // Counted when made, with this surface's share of what it owes back; the
                // other surface counts the other share.
                report.impulse += 0.5 * world;
                report.total_impulse += 0.5 * world;
            }
            owed.push((entity, link.point, -0.5 * world, met, false));
            for (point, weight) in link.with.into_iter().filter(|w| w.1 > 0.0) {
                owed.push((link.other, point, -0.5 * weight * world, met, met));
            }
        }
    }
    for (to, point, j, met, count) in owed {
        if let Ok((_, mut report, _, _)) = surfaces.get_mut(to) {
            let report = report.bypass_change_detection();
            if met {
                report.owed.push((point, j));
            } else {
                report.owed_self.push((point, j));
            }
            if count {
                report.impulse += j;
                report.total_impulse += j;
            }
        }
    }
}

/// After the step: each surface meeting itself that stepped is checked for crossings of
/// its network the step made, and those are undone ([`untangle`]: the points of each move
/// as one zone from where they began, at their mean velocity).
pub fn untangle_surfaces(
    time: Res<Time>,
    mut surfaces: Query<(
        &SurfaceMeeting,
        &mut SurfaceMeetingReport,
        &mut SimulationPoints,
        &SurfaceMasses,
        &SurfaceNetwork,
        &SurfaceStepper,
    )>,
) {
    let dt = time.delta_secs();
    for (meeting, mut report, mut points, masses, network, stepper) in &mut surfaces {
        let report = report.bypass_change_detection();
        let stepped = stepper.diagnostics().steps != report.start.1;
        if !(meeting.enabled && meeting.self_contact) || report.start.0.is_empty() || !stepped {
            continue;
        }
        let start = std::mem::take(&mut report.start.0);
        // Read first (no change is marked unless a point moves back).
        let crossed = {
            let now: Vec<Vec3> = points.iter_positions().collect();
            !crate::core::network::crossings(&now, &network.triangles).is_empty()
        };
        if crossed {
            report.untangled = untangle(&start, &mut points, masses, &network.triangles, dt);
        }
        report.start.0 = start;
    }
}

/// Adds each impulse over the tick to its point's force (in the surface's coordinates) and
/// to the surface's report.
fn record(pair: &mut Pair<'_>, side: &Side, impulses: &[(usize, Vec3)], dt: f32) {
    let mut touched = vec![false; side.at.len()];
    let mut total = Vec3::ZERO;
    for &(i, j) in impulses {
        if pair.forces.add(i, side.to_local * (j / dt)).is_ok() {
            total += j;
            touched[i] = true;
        }
    }
    pair.report.touching += touched.iter().filter(|&&t| t).count();
    pair.report.impulse += total;
    pair.report.total_impulse += total;
}
