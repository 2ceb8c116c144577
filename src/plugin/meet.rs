//! Deformable surfaces touching each other (issue 35, item 1), with or without rapier: put
//! [`SurfaceMeeting`] on each surface that should meet others.
//!
//! Each tick, after the surfaces' own forces and before their steps ([`meet_surfaces`]):
//!
//! 1. each meeting surface's bounds, swept over the tick by its fastest point, are compared
//!    pair by pair (with the groups' filter); two far-apart surfaces cost that test alone;
//! 2. for a pair whose bounds meet, the points of both in world coordinates, each with the
//!    velocity its own forces give it over the tick (as heavy as its step mass), and the
//!    second's points bucketed in a grid;
//! 3. each point of the second is a small body (its sphere, its step mass) that the first's
//!    points near it push and are pushed by, resolved as rigid contacts are
//!    ([`resolve`]): the speculative sweep (a point still apart is stopped only where the
//!    gap would close within the tick), a share of an overlap pushed out, Coulomb friction;
//! 4. each impulse goes to both surfaces' [`SurfaceForces`] as equal
//!    and opposite forces over the tick, so momentum is exchanged exactly.
//!
//! The contacts are estimated before the step from the points' step masses (as
//! [`ContactSolve::Estimated`](super::ContactSolve) does for rigid bodies), not solved
//! with the springs; see `docs/ARCHITECTURE.md`, "Surfaces meeting surfaces".

use std::sync::Arc;

use bevy::prelude::*;

use crate::core::network::SpringNetwork;
use crate::core::solver::contact::{
    BodyState, ContactParams, DEFAULT_DEPTH_RECOVERY, DEFAULT_FRICTION, DEFAULT_RADIUS_SCALE,
    PointGrid, Proximity, group_step_masses, point_radii, resolve,
};

use super::components::{
    SimulationPoints, StepOnce, SurfaceForces, SurfaceMasses, SurfaceNetwork, SurfaceSettings,
    SurfaceSprings, SurfaceStatus, SurfaceStepper,
};
use super::simulate::running;

/// Every group: the default membership and filter.
pub const ALL_GROUPS: u32 = u32::MAX;

/// How a surface meets other surfaces (opt-in: surfaces without it pass through each other),
/// and what touched it. Two surfaces meet when each one's `groups` share a bit with the
/// other's `filter`.
#[derive(Component, Debug, Clone, Reflect)]
#[reflect(Component, Debug, Default)]
pub struct SurfaceMeeting {
    /// Whether the surface meets others at all.
    pub enabled: bool,
    /// The groups the surface belongs to (bits).
    pub groups: u32,
    /// The groups it meets (bits).
    pub filter: u32,
    /// Coulomb friction coefficient μ between this surface and another (the pair uses the
    /// smaller of theirs).
    pub friction: f32,
    /// Fraction of an overlap pushed out per tick, in [0, 1] (the pair uses the smaller).
    pub depth_recovery: f32,
    /// Radius of each simulation point's sphere, as a share of the mean rest length of its
    /// stretch springs.
    pub radius_scale: f32,
    /// Surfaces whose bounds met this one's last tick.
    #[reflect(ignore)]
    near: usize,
    /// This surface's points that took an impulse from another surface last tick.
    #[reflect(ignore)]
    touching: usize,
    /// Impulse on this surface from others last tick (world, N·s).
    #[reflect(ignore)]
    impulse: Vec3,
    /// Impulse on this surface from others since it was prepared (world, N·s).
    #[reflect(ignore)]
    total_impulse: Vec3,
    /// The sphere radii.
    #[reflect(ignore)]
    radii: PointRadii,
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
            near: 0,
            touching: 0,
            impulse: Vec3::ZERO,
            total_impulse: Vec3::ZERO,
            radii: PointRadii::default(),
        }
    }
}

impl SurfaceMeeting {
    /// Surfaces whose bounds met this one's last tick.
    pub fn near(&self) -> usize {
        self.near
    }

    /// This surface's points that took an impulse from another surface last tick.
    pub fn touching(&self) -> usize {
        self.touching
    }

    /// The impulse other surfaces gave this one last tick (world, N·s).
    pub fn impulse(&self) -> Vec3 {
        self.impulse
    }

    /// The impulse other surfaces gave this one since it was prepared (world, N·s).
    pub fn total_impulse(&self) -> Vec3 {
        self.total_impulse
    }

    fn meets(&self, other: &Self) -> bool {
        self.enabled
            && other.enabled
            && self.groups & other.filter != 0
            && other.groups & self.filter != 0
    }

    fn refresh_radii(&mut self, network: &Arc<SpringNetwork>) {
        if self.radii.refresh(network, self.radius_scale.max(0.0)) {
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
    /// Whether each point is pinned.
    pinned: Vec<bool>,
}

/// What [`meet_surfaces`] reads and changes of a surface.
type MeetParts = (
    Entity,
    &'static mut SurfaceMeeting,
    (&'static SimulationPoints, &'static SurfaceMasses),
    (&'static SurfaceSprings, &'static SurfaceNetwork),
    &'static SurfaceStepper,
    &'static mut SurfaceForces,
    Option<&'static GlobalTransform>,
    (
        &'static SurfaceStatus,
        &'static SurfaceSettings,
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
        mut meeting,
        (points, masses),
        (_, network),
        stepper,
        _,
        place,
        (status, settings, once),
    ) in &mut surfaces
    {
        let meeting = meeting.bypass_change_detection();
        meeting.near = 0;
        meeting.touching = 0;
        meeting.impulse = Vec3::ZERO;
        if !meeting.enabled || !running(status, settings, once) {
            continue;
        }
        meeting.refresh_radii(&network.0);
        if meeting.radii.get().len() != points.len() {
            continue;
        }
        let side = Side::new(points, masses, stepper, place, meeting.radii.get(), dt);
        sides.push((entity, side));
    }
    if sides.len() < 2 {
        return;
    }
    for i in 0..sides.len() {
        for j in i + 1..sides.len() {
            let (a, b) = (&sides[i], &sides[j]);
            let Ok([first, second]) = surfaces.get_many_mut([a.0, b.0]) else {
                continue;
            };
            let (mut first, mut second) = (Pair::of(first), Pair::of(second));
            if !first.meeting.meets(second.meeting) || !a.1.overlaps(&b.1) {
                continue;
            }
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
        let gravity = linear * stepper.config().gravity * dt;
        let (mut at, mut start, mut push, mut radius) = (
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
        );
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        let mut reach = 0.0_f32;
        for (i, &r) in radii.iter().enumerate().take(n) {
            let p = place.transform_point3(points.position(i));
            let v = linear * points.velocity(i);
            let f = stepper
                .own_force(i)
                .map_or(stepper.config().gravity * masses.mass(i), |f| f);
            let r = r * scale;
            lo = lo.min(p);
            hi = hi.max(p);
            reach = reach.max(r + (v + gravity).length() * dt);
            at.push(p);
            start.push(v);
            push.push(linear * f * dt);
            radius.push(r);
        }
        Self {
            at,
            start,
            push,
            reach,
            radius,
            lo: lo - Vec3::splat(reach),
            hi: hi + Vec3::splat(reach),
            to_local: linear.inverse(),
            pinned: (0..n).map(|i| masses.is_pinned(i)).collect(),
        }
    }

    /// Point `i`'s velocity at the end of the tick under its surface's own forces, the
    /// point as heavy as `step_mass` (a pinned point keeps its velocity).
    fn predicted(&self, i: usize, step_mass: f32) -> Vec3 {
        if self.pinned[i] || step_mass <= 0.0 {
            self.start[i]
        } else {
            self.start[i] + self.push[i] / step_mass
        }
    }

    /// Point `i`'s inverse mass within the step.
    fn inv_mass(&self, i: usize, step_mass: f32) -> f32 {
        if self.pinned[i] || step_mass <= 0.0 {
            0.0
        } else {
            1.0 / step_mass
        }
    }

    fn overlaps(&self, other: &Side) -> bool {
        self.lo.cmple(other.hi).all() && other.lo.cmple(self.hi).all()
    }
}

/// What one surface of a pair reads and changes.
struct Pair<'a> {
    meeting: &'a mut SurfaceMeeting,
    masses: &'a SurfaceMasses,
    springs: &'a SurfaceSprings,
    forces: Mut<'a, SurfaceForces>,
}

impl<'a> Pair<'a> {
    fn of(item: bevy::ecs::query::QueryItem<'a, 'a, MeetParts>) -> Self {
        let (_, meeting, (_, masses), (springs, _), _, forces, _, _) = item;
        Self {
            meeting: meeting.into_inner(),
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
    first.meeting.near += 1;
    second.meeting.near += 1;
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
    let mut va: Vec<Vec3> = (0..a.at.len()).map(|i| a.predicted(i, step_a[i])).collect();
    let (mut on_a, mut on_b) = (Vec::new(), Vec::new());
    for (k, near) in pairs {
        let inv_b = b.inv_mass(k, step_b[k]);
        let mut body = BodyState {
            linear: b.predicted(k, step_b[k]),
            angular: Vec3::ZERO,
            center: b.at[k],
            inv_mass: Vec3::splat(inv_b),
            inv_inertia: Mat3::ZERO,
        };
        let mut proximities: Vec<Proximity> = near
            .iter()
            .filter_map(|&i| {
                let d = a.at[i] - b.at[k];
                let length = d.length();
                let normal = if length > f32::EPSILON {
                    d / length
                } else {
                    (va[i] - body.linear).normalize_or(Vec3::Y)
                };
                let inv_a = a.inv_mass(i, step_a[i]);
                (inv_a > 0.0 || inv_b > 0.0).then_some(Proximity {
                    point: i,
                    at: b.at[k] + normal * b.radius[k],
                    normal,
                    gap: length - a.radius[i] - b.radius[k],
                    velocity: va[i],
                    inv_mass: inv_a,
                })
            })
            .collect();
        let Ok(impulses) = resolve(&mut body, &mut proximities, dt, &params) else {
            continue;
        };
        for c in impulses {
            if !c.impulse.is_finite() {
                continue;
            }
            let inv_a = proximities
                .iter()
                .find(|p| p.point == c.point)
                .map_or(0.0, |p| p.inv_mass);
            va[c.point] += c.impulse * inv_a;
            on_a.push((c.point, c.impulse));
            on_b.push((k, -c.impulse));
        }
    }
    record(first, a, &on_a, dt);
    record(second, b, &on_b, dt);
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
    pair.meeting.touching += touched.iter().filter(|&&t| t).count();
    pair.meeting.impulse += total;
    pair.meeting.total_impulse += total;
}
