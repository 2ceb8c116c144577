//! Contacts between simulation points and rigid bodies: the force each body puts on the
//! points it touches this tick, and the equal and opposite impulse it takes back.
//!
//! Each simulation point is a small sphere (radius from its local spacing). For every point
//! near a body the caller measures, at the start of the tick, the [`Proximity`]: the gap
//! between the point's sphere and the body (negative where they overlap), the contact
//! normal, and the velocities both would have at the end of the tick without the contact
//! (gravity included). [`resolve`] then turns the proximities of one body into impulses:
//!
//! * **Normal:** the impulse that removes the closing speed in one tick (an inelastic
//!   contact), set per contact from the pair's effective mass and the tick. An overlap does
//!   not stay as speed (Baumgarte's push-out did: the speed outlived the overlap as
//!   kinetic energy and fed resting contacts): a fraction
//!   [`ContactParams::depth_recovery`] of it is moved out, by position before the step
//!   ([`ContactImpulse::moved`]) or by the step, whose speed for it is taken back after it
//!   ([`StepContact::recover`]), as split impulses do. Explicit
//!   penalty springs of a fixed stiffness either let a fast body through or blow up at a
//!   game's tick; these do neither.
//! * **Sweep:** a point still apart from the body only takes a force when the gap would close
//!   within the tick at the current closing speed (a speculative contact): the closing speed
//!   is cut to what closes the gap exactly. A body at 20 m/s moves a third of a metre per
//!   60 Hz tick; it is stopped at the surface instead of being found beyond it.
//! * **Friction:** Coulomb's, `|J_t| <= μ J_n`, against the tangential relative velocity,
//!   never more than stops it.
//!
//! The contacts of one body are taken in the order they happen (overlapping first, then by
//! time to touch), each one seeing the body's velocity after the ones before (one
//! Gauss–Seidel pass), so many points touching one light body do not each stop it. The
//! caller adds each impulse divided by the tick to the point's external force (eq 6's
//! accumulator) and applies the opposite impulse to the body, so the momentum the surface
//! receives is exactly the momentum the body loses.

mod broad;
mod grid;
mod neighbours;
pub(crate) mod step;
mod triangle;
mod untangle;

pub use broad::overlapping_pairs;
pub use grid::PointGrid;
pub use neighbours::{DEFAULT_SELF_CONTACT_RINGS, NetworkNeighbours};
pub use triangle::{Stencil, StencilProximity, closest_on_triangle, stencil_impulse};
pub use untangle::{Untangled, ZONE_PASSES, untangle};

use glam::{Mat3, Vec3};

use crate::core::network::SpringNetwork;

/// Default Coulomb friction coefficient μ between a surface and a body.
pub const DEFAULT_FRICTION: f32 = 0.5;

/// Default fraction of an overlap removed per tick.
pub const DEFAULT_DEPTH_RECOVERY: f32 = 0.2;

/// Default radius of a simulation point's sphere, as a share of the mean rest length of its
/// stretch springs: neighbouring spheres touch, so a sheet is one spacing thick.
pub const DEFAULT_RADIUS_SCALE: f32 = 0.5;

/// Closing and sliding speeds below this (m/s) count as none.
const SPEED_EPSILON: f32 = 1e-9;

/// How contacts act.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactParams {
    /// Coulomb friction coefficient μ (0: frictionless).
    pub friction: f32,
    /// Fraction of an overlap moved out per tick, in [0, 1], by position (no speed is left
    /// of it after the tick: no kinetic energy comes of it).
    pub depth_recovery: f32,
}

impl Default for ContactParams {
    fn default() -> Self {
        Self {
            friction: DEFAULT_FRICTION,
            depth_recovery: DEFAULT_DEPTH_RECOVERY,
        }
    }
}

/// Contact settings out of range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ContactError {
    /// Friction negative or not finite.
    #[error("contact friction must be finite and >= 0, got {0}")]
    Friction(f32),
    /// Depth recovery outside [0, 1].
    #[error("contact depth recovery must be in [0, 1], got {0}")]
    DepthRecovery(f32),
    /// The tick is not a positive finite number of seconds.
    #[error("contact tick must be finite and > 0, got {0}")]
    Tick(f32),
}

impl ContactParams {
    /// Checks the settings.
    pub fn validate(&self) -> Result<(), ContactError> {
        if !(self.friction.is_finite() && self.friction >= 0.0) {
            return Err(ContactError::Friction(self.friction));
        }
        if !(0.0..=1.0).contains(&self.depth_recovery) {
            return Err(ContactError::DepthRecovery(self.depth_recovery));
        }
        Ok(())
    }
}

/// A rigid body as contacts see it, in world coordinates. Fixed and kinematic bodies (and
/// colliders without a body) have zero inverse mass and inertia: contacts move them not.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyState {
    /// Linear velocity the body will have at the end of the tick without contacts.
    pub linear: Vec3,
    /// Angular velocity (rad/s).
    pub angular: Vec3,
    /// Centre of mass.
    pub center: Vec3,
    /// Inverse mass per axis (zero on locked axes).
    pub inv_mass: Vec3,
    /// Inverse inertia tensor in world axes.
    pub inv_inertia: Mat3,
}

impl BodyState {
    /// A body that nothing moves (the ground, a wall, a kinematic paddle), moving with
    /// `linear` and `angular` velocity about `center`.
    pub fn immovable(linear: Vec3, angular: Vec3, center: Vec3) -> Self {
        Self {
            linear,
            angular,
            center,
            inv_mass: Vec3::ZERO,
            inv_inertia: Mat3::ZERO,
        }
    }

    /// Velocity of the body's material at `p`.
    pub fn velocity_at(&self, p: Vec3) -> Vec3 {
        self.linear + self.angular.cross(p - self.center)
    }

    /// How much the body's velocity at `at` along `dir` changes per unit impulse there
    /// along `dir`.
    fn inv_mass_along(&self, at: Vec3, dir: Vec3) -> f32 {
        let arm = (at - self.center).cross(dir);
        dir.dot(self.inv_mass * dir) + arm.dot(self.inv_inertia * arm)
    }

    /// Applies an impulse at `at`.
    pub fn apply_impulse(&mut self, at: Vec3, impulse: Vec3) {
        self.linear += self.inv_mass * impulse;
        self.angular += self.inv_inertia * (at - self.center).cross(impulse);
    }
}

/// A simulation point near a body at the start of a tick, in world coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Proximity {
    /// The simulation point's index.
    pub point: usize,
    /// The nearest point of the body's surface.
    pub at: Vec3,
    /// Unit contact normal, from the body towards the point.
    pub normal: Vec3,
    /// Distance from the point's sphere to the body; negative where they overlap.
    pub gap: f32,
    /// The point's velocity at the end of the tick without the contact.
    pub velocity: Vec3,
    /// The point's inverse mass (zero for a pinned point).
    pub inv_mass: f32,
}

/// A contact handed to the step instead of as a force ([`ExternalForces::add_contact`]), in
/// the surface's own coordinates: the step gives the point's velocity along `normal` at
/// least `min_speed` at its end, by the least push along the normal that the springs,
/// solved together with it, allow, and the point slides along the body with Coulomb
/// friction. Unlike an impulse estimated before the step, this moves a pushed patch exactly
/// as far as the body moves it (issue 35): the point's neighbours are solved with it, not
/// guessed.
///
/// With `body` none, the body is one nothing moves (the ground, a wall, a kinematic paddle).
/// With a [`StepBody`] ([`ExternalForces::add_body`]), `min_speed` and `body_velocity` are
/// taken at the body's guessed velocity, and the step solves the body's velocity with the
/// surface's (see [`StepBody`]).
///
/// [`ExternalForces::add_contact`]: super::ExternalForces::add_contact
/// [`ExternalForces::add_body`]: super::ExternalForces::add_body
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepContact {
    /// The simulation point's index.
    pub point: u32,
    /// Unit contact normal, from the body towards the point.
    pub normal: Vec3,
    /// The least velocity along `normal` the point may have at the end of the step: the
    /// body's own along it plus what the gap allows ([`step_contact`]).
    pub min_speed: f32,
    /// The body's velocity where it touches the point (friction acts against the point's
    /// velocity relative to it).
    pub body_velocity: Vec3,
    /// Coulomb friction coefficient μ.
    pub friction: f32,
    /// The body that moves, as its index among the step's bodies; none for one nothing
    /// moves.
    pub body: Option<u32>,
    /// Where the contact is, from the body's centre of mass.
    pub arm: Vec3,
    /// How far the step moves the point (or, where the point is held against something
    /// immovable, the body) out of an overlap along `normal`, m (0: no overlap). The
    /// implicit step moves a held point out at `recover / h` with its springs solved, and
    /// takes that speed back after the step; an explicit step and a pinched body move by
    /// position. No kinetic energy comes of it.
    pub recover: f32,
}

/// A pinned simulation point carried by a body the step solves with the surface
/// ([`StepBody`]): an attachment to a dynamic body. The point's velocity at the start of the
/// step is the body's guess carried to it; each round of the step moves it with the body's
/// velocity (v + ω × arm), and the body takes the opposite of what held the point
/// ([`Stepper::pin_impulses`](crate::core::solver::Stepper::pin_impulses)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CarriedPoint {
    /// The simulation point's index (a pinned one; a free point is left out).
    pub point: u32,
    /// The body carrying it, as its index among the step's bodies.
    pub body: u32,
    /// Where the point is, from the body's centre of mass.
    pub arm: Vec3,
}

/// A body the surface moves and that moves the surface, solved with it within the step, in
/// the surface's own coordinates: its velocity at the end of the step is found with the
/// surface's, by a few rounds of (1) the surface solved with its points held to the body's
/// current velocity, (2) the body's velocity the surface's pushes would give it, and (3) a
/// quasi-Newton step between the two, its Jacobian first from the held points' step masses
/// along their normals, then corrected by Broyden's update from what each round saw. The
/// body takes the exact opposite of what the surface took, whatever the rounds left, so
/// momentum is exchanged exactly.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepBody {
    /// Linear velocity the body will have at the end of the step without the surface.
    pub linear: Vec3,
    /// Angular velocity the body will have at the end of the step without the surface.
    pub angular: Vec3,
    /// The first guess of its linear velocity with the surface (an estimate; the contacts'
    /// `min_speed` and `body_velocity` are taken at it).
    pub guess_linear: Vec3,
    /// The first guess of its angular velocity with the surface.
    pub guess_angular: Vec3,
    /// Its inverse mass, as a matrix (locked axes and the frame's turn included).
    pub inv_mass: Mat3,
    /// Its inverse inertia tensor.
    pub inv_inertia: Mat3,
    /// A number that names the body from one step to the next (rapier's handle), so that
    /// the step starts from how the surface resisted it the step before.
    pub key: u64,
}

impl StepBody {
    /// Whether every number is finite.
    pub fn is_finite(&self) -> bool {
        self.linear.is_finite()
            && self.angular.is_finite()
            && self.guess_linear.is_finite()
            && self.guess_angular.is_finite()
            && self.inv_mass.is_finite()
            && self.inv_inertia.is_finite()
    }
}

/// The contact of `p` with `body` for the step to solve, in world coordinates like `p`, at
/// the body's current velocities: whether it touches is the step's to find, with the
/// springs' forces solved (`None` only for a point index beyond `u32`). `moving`: the
/// body's index among the step's bodies, for a body that moves.
pub fn step_contact(
    body: &BodyState,
    p: &Proximity,
    dt: f32,
    params: &ContactParams,
    moving: Option<u32>,
) -> Option<StepContact> {
    let body_velocity = body.velocity_at(p.at);
    Some(StepContact {
        point: u32::try_from(p.point).ok()?,
        normal: p.normal,
        min_speed: body_velocity.dot(p.normal) + allowed_speed(p, dt),
        body_velocity,
        friction: params.friction,
        body: moving,
        arm: p.at - body.center,
        recover: recovery(p.gap, params),
    })
}

/// How far to move a point out of an overlap of `-gap` this tick (a share of it; none
/// where the gap is open).
pub fn recovery(gap: f32, params: &ContactParams) -> f32 {
    if gap < 0.0 {
        params.depth_recovery * -gap
    } else {
        0.0
    }
}

/// The impulse one contact exchanged this tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactImpulse {
    /// The simulation point's index.
    pub point: usize,
    /// Where it acts on the body.
    pub at: Vec3,
    /// The impulse on the point (the body takes its opposite), N·s, world coordinates.
    pub impulse: Vec3,
    /// How far the point should move out of an overlap (by position, not velocity: see
    /// [`ContactParams::depth_recovery`]), m, world coordinates; zero apart.
    pub moved: Vec3,
}

/// The radius of each simulation point's sphere: `scale` times the mean rest length of its
/// stretch springs (a point without springs takes the network's mean).
pub fn point_radii(network: &SpringNetwork, scale: f32) -> Vec<f32> {
    let n = network.len();
    let mut sum = vec![0.0_f64; n];
    let mut count = vec![0_u32; n];
    for spring in &network.stretch {
        for end in [spring.a as usize, spring.b as usize] {
            if end < n {
                sum[end] += f64::from(spring.rest_length);
                count[end] += 1;
            }
        }
    }
    let total: f64 = sum.iter().sum();
    let springs: u32 = count.iter().sum();
    let mean = if springs > 0 {
        total / f64::from(springs)
    } else {
        0.0
    };
    sum.iter()
        .zip(&count)
        .map(|(&s, &c)| {
            let length = if c > 0 { s / f64::from(c) } else { mean };
            (length * f64::from(scale)) as f32
        })
        .collect()
}

/// The mass each point has within one implicit step of `dt`: its own, plus `dt·Σd +
/// dt²·Σk` over the springs that end at it (the diagonal of implicit Euler's matrix
/// `M + dt·D + dt²·K`). A contact that moves a point within a tick moves its springs'
/// other ends too; taking the point as this much heavier lets the contact feel the
/// surface's stiffness in the same tick, and predicts the point's own velocity change as
/// the implicit step will make it, not the far larger explicit one (which, on a point held
/// by stiff springs, overshoots and feeds energy in).
pub fn step_masses(
    masses: &[f32],
    springs: impl Iterator<Item = crate::core::solver::SpringSpec>,
    dt: f32,
) -> Vec<f32> {
    let mut out = masses.to_vec();
    for s in springs {
        let add = dt * s.damping + dt * dt * s.stiffness;
        for end in [s.a as usize, s.b as usize] {
            if let Some(m) = out.get_mut(end) {
                *m += add;
            }
        }
    }
    out
}

/// [`step_masses`] for points that touch one body together: each touching point's own mass
/// plus `dt·d + dt²·k` of only those of its springs whose other end does not touch too
/// (`touching[i]`). Points pressed together move together, so the springs between them do
/// not resist: counting them, a scan landing flat on a floor took each of its points as
/// up to 200 times heavier than it is (h²Σk/m at 60 Hz) and bounced ten times higher than
/// it fell. A point touching alone keeps its full step mass. Points that do not touch get
/// their own mass.
pub fn group_step_masses(
    masses: &[f32],
    springs: impl Iterator<Item = crate::core::solver::SpringSpec>,
    touching: &[bool],
    dt: f32,
) -> Vec<f32> {
    let mut out = masses.to_vec();
    let touches = |i: usize| touching.get(i).copied().unwrap_or(false);
    for s in springs {
        let (a, b) = (s.a as usize, s.b as usize);
        if touches(a) == touches(b) {
            continue;
        }
        let end = if touches(a) { a } else { b };
        if let Some(m) = out.get_mut(end) {
            *m += dt * s.damping + dt * dt * s.stiffness;
        }
    }
    out
}

/// Each point's springs, in the springs' order, for the step masses of a few points at a
/// time: [`group_step_masses`] passes over every spring, which, once per body touching a
/// large surface, is most of what its contacts cost.
#[derive(Debug, Clone, Default)]
pub struct SpringIncidence {
    /// Where each point's springs start in `ends` (one more entry than points).
    start: Vec<u32>,
    /// Each point's springs: the other end, the damping and the stiffness.
    ends: Vec<(u32, f32, f32)>,
}

impl SpringIncidence {
    /// The incidence of `springs` on `points` points (springs with an end beyond are left
    /// out).
    pub fn new(points: usize, springs: &[crate::core::solver::SpringSpec]) -> Self {
        let in_range = |s: &&crate::core::solver::SpringSpec| {
            (s.a as usize) < points && (s.b as usize) < points
        };
        let mut count = vec![0_u32; points + 1];
        for s in springs.iter().filter(in_range) {
            count[s.a as usize + 1] += 1;
            count[s.b as usize + 1] += 1;
        }
        for i in 0..points {
            count[i + 1] += count[i];
        }
        let mut next = count.clone();
        let mut ends = vec![(0, 0.0, 0.0); count[points] as usize];
        for s in springs.iter().filter(in_range) {
            for (end, other) in [(s.a, s.b), (s.b, s.a)] {
                let slot = &mut next[end as usize];
                ends[*slot as usize] = (other, s.damping, s.stiffness);
                *slot += 1;
            }
        }
        Self { start: count, ends }
    }

    /// Point `i`'s step mass among points that touch one body together
    /// ([`group_step_masses`], the same to the bit): `mass` plus `dt·d + dt²·k` of each of
    /// its springs whose other end does not touch (`touching`), if `i` touches; `mass`
    /// otherwise.
    pub fn group_step_mass(
        &self,
        mass: f32,
        i: usize,
        touching: impl Fn(usize) -> bool,
        dt: f32,
    ) -> f32 {
        let (Some(&from), Some(&to)) = (self.start.get(i), self.start.get(i + 1)) else {
            return mass;
        };
        if !touching(i) {
            return mass;
        }
        let mut m = mass;
        for &(other, damping, stiffness) in &self.ends[from as usize..to as usize] {
            if !touching(other as usize) {
                m += dt * damping + dt * dt * stiffness;
            }
        }
        m
    }
}

/// Resolves the contacts of one body for a tick of `dt` seconds: returns the impulse on each
/// point that touches (points that stay apart are left out; an overlapping point is kept,
/// with how far to move it out, its impulse zero where nothing closes) and applies the
/// opposite impulses to `body`, whose velocities then hold the body's state after the
/// contacts.
///
/// `proximities` is reordered (overlaps first, then by time to touch).
pub fn resolve(
    body: &mut BodyState,
    proximities: &mut [Proximity],
    dt: f32,
    params: &ContactParams,
) -> Result<Vec<ContactImpulse>, ContactError> {
    resolve_in_passes(body, proximities, dt, params, RESOLVE_PASSES)
}

/// [`resolve`] in `passes` Gauss–Seidel passes (at least one). Surfaces meeting surfaces
/// take one per contact pass: their estimate only seeds the steps' contacts, and one pass,
/// each point stopping the other in turn, leaves their folds more room than the converged
/// pushes (a sheet falling onto itself crossed itself at 20 of 240 ticks with six passes,
/// at none with one; measured 2026-12-07).
pub fn resolve_in_passes(
    body: &mut BodyState,
    proximities: &mut [Proximity],
    dt: f32,
    params: &ContactParams,
    passes: usize,
) -> Result<Vec<ContactImpulse>, ContactError> {
    params.validate()?;
    if !(dt.is_finite() && dt > 0.0) {
        return Err(ContactError::Tick(dt));
    }
    let order = |p: &Proximity| {
        let closing = -(p.velocity - body.velocity_at(p.at)).dot(p.normal);
        if p.gap <= 0.0 {
            p.gap
        } else if closing > SPEED_EPSILON {
            p.gap / closing
        } else {
            f32::INFINITY
        }
    };
    proximities.sort_by(|a, b| order(a).total_cmp(&order(b)));
    // Each contact's impulse so far and its point's velocity with it.
    let mut taken = vec![Vec3::ZERO; proximities.len()];
    let mut velocity: Vec<Vec3> = proximities.iter().map(|p| p.velocity).collect();
    for _ in 0..passes.max(1) {
        for (k, p) in proximities.iter().enumerate() {
            let Some(change) = contact_impulse(body, p, velocity[k], taken[k], dt, params) else {
                continue;
            };
            body.apply_impulse(p.at, -change);
            velocity[k] += change * p.inv_mass;
            taken[k] += change;
        }
    }
    // An overlapping point touches even where nothing closes: it is moved out.
    Ok(proximities
        .iter()
        .zip(taken)
        .filter(|(p, j)| *j != Vec3::ZERO || p.gap < 0.0)
        .map(|(p, impulse)| ContactImpulse {
            point: p.point,
            at: p.at,
            impulse,
            moved: p.normal * recovery(p.gap, params),
        })
        .collect())
}

/// Gauss–Seidel passes over one body's contacts in [`resolve`]: each contact's impulse is
/// summed over the passes and never pulls, so a flat face landing on many points at once
/// ends with the pushes spread over them (one pass, the first points in the order stopped
/// the body alone, off its centre, and spun it: a crate dropped flat on a ball turned at
/// 4 rad/s).
const RESOLVE_PASSES: usize = 6;

/// Whether the point of `p` touches `body` this tick (its normal speed at the end of the
/// tick would pass what the gap allows), given the body's current velocities.
pub fn will_touch(body: &BodyState, p: &Proximity, dt: f32) -> bool {
    let normal_speed = (p.velocity - body.velocity_at(p.at)).dot(p.normal);
    normal_speed < allowed_speed(p, dt)
}

/// The least normal speed allowed at the end of the tick: apart, the gap may close but not
/// more; overlapping, none (the overlap is moved out by position: [`recovery`]).
fn allowed_speed(p: &Proximity, dt: f32) -> f32 {
    allowed_closing(p.gap, dt)
}

/// The least normal speed allowed at the end of a tick of `dt` across a `gap`: apart, it
/// may close but not more; overlapping, it may not close further.
pub(crate) fn allowed_closing(gap: f32, dt: f32) -> f32 {
    if gap >= 0.0 { -gap / dt } else { 0.0 }
}

/// The change of one contact's impulse on its point (`taken` so far, the point at
/// `velocity` with it), given the body's current velocities: along the normal, up to what
/// stops the closing the gap does not allow, the sum never pulling; across it, Coulomb
/// friction on the sum. `None` when nothing changes.
fn contact_impulse(
    body: &BodyState,
    p: &Proximity,
    velocity: Vec3,
    taken: Vec3,
    dt: f32,
    params: &ContactParams,
) -> Option<Vec3> {
    let n = p.normal;
    let normal_compliance = p.inv_mass + body.inv_mass_along(p.at, n);
    if normal_compliance <= 0.0 {
        return None; // neither side can move
    }
    let normal_speed = (velocity - body.velocity_at(p.at)).dot(n);
    let pushed = n.dot(taken);
    let push = (pushed + (allowed_speed(p, dt) - normal_speed) / normal_compliance).max(0.0);
    let normal_change = n * (push - pushed);
    // Friction on the velocities the normal change leaves.
    let mut after = *body;
    after.apply_impulse(p.at, -normal_change);
    let relative = velocity + normal_change * p.inv_mass - after.velocity_at(p.at);
    let across = taken - n * pushed;
    let sliding = relative - n * relative.dot(n);
    let slide_speed = sliding.length();
    let mut friction = across;
    if slide_speed > SPEED_EPSILON {
        let t = sliding / slide_speed;
        let compliance = p.inv_mass + body.inv_mass_along(p.at, t);
        if compliance > 0.0 {
            friction -= t * (slide_speed / compliance);
        }
    }
    let cap = params.friction * push;
    if friction.length() > cap {
        friction = friction.normalize_or_zero() * cap;
    }
    let change = normal_change + (friction - across);
    (change != Vec3::ZERO && change.is_finite()).then_some(change)
}

/// Coulomb friction with a contact's normal impulse: the impulse against the `relative`
/// velocity's slide across `normal` that stops the slide, or μ times the normal impulse if
/// less. `compliance(t)` is how far an impulse of 1 along `t` changes the relative velocity.
pub(crate) fn friction_impulse(
    relative: Vec3,
    normal: Vec3,
    normal_impulse: f32,
    friction: f32,
    compliance: impl Fn(Vec3) -> f32,
) -> Vec3 {
    let sliding = relative - normal * relative.dot(normal);
    let slide_speed = sliding.length();
    if friction <= 0.0 || slide_speed <= SPEED_EPSILON {
        return Vec3::ZERO;
    }
    let tangent = sliding / slide_speed;
    let stop = slide_speed / compliance(tangent);
    -tangent * stop.min(friction * normal_impulse)
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f32 = 1.0 / 60.0;

    fn ground() -> BodyState {
        BodyState::immovable(Vec3::ZERO, Vec3::ZERO, Vec3::ZERO)
    }

    fn ball(mass: f32, velocity: Vec3, center: Vec3) -> BodyState {
        let radius = 0.2_f32;
        let inertia = 0.4 * mass * radius * radius;
        BodyState {
            linear: velocity,
            angular: Vec3::ZERO,
            center,
            inv_mass: Vec3::splat(1.0 / mass),
            inv_inertia: Mat3::from_diagonal(Vec3::splat(1.0 / inertia)),
        }
    }

    fn above_ground(point: usize, gap: f32, velocity: Vec3) -> Proximity {
        Proximity {
            point,
            at: Vec3::new(point as f32, 0.0, 0.0),
            normal: Vec3::Y,
            gap,
            velocity,
            inv_mass: 1.0,
        }
    }

    #[test]
    fn a_point_falling_fast_stops_at_the_ground_in_one_tick() {
        // 20 m/s down, 0.1 above: without the contact it would end 0.23 below.
        let mut body = ground();
        let mut p = [above_ground(0, 0.1, Vec3::new(0.0, -20.0, 0.0))];
        let out = resolve(&mut body, &mut p, DT, &ContactParams::default()).unwrap();
        let v = p[0].velocity + out[0].impulse * p[0].inv_mass;
        // It closes the gap exactly and no more.
        assert!((v.y * DT + 0.1).abs() < 1e-5, "{v}");
        assert_eq!(body, ground(), "the ground does not move");
    }

    #[test]
    fn a_point_that_stays_apart_takes_nothing() {
        let mut body = ground();
        let mut p = [
            above_ground(0, 0.1, Vec3::new(0.0, -1.0, 0.0)), // closes 0.017 of 0.1
            above_ground(1, 0.0, Vec3::new(0.0, 1.0, 0.0)),  // leaving
        ];
        let out = resolve(&mut body, &mut p, DT, &ContactParams::default()).unwrap();
        assert!(out.is_empty(), "{out:?}");
    }

    #[test]
    fn an_overlap_is_moved_out_by_its_share_per_tick_without_a_speed() {
        let mut body = ground();
        let params = ContactParams {
            depth_recovery: 0.25,
            ..Default::default()
        };
        // At rest in the ground: no impulse (nothing closes), a quarter moved out.
        let mut p = [above_ground(0, -0.04, Vec3::ZERO)];
        let out = resolve(&mut body, &mut p, DT, &params).unwrap();
        assert_eq!(out[0].impulse, Vec3::ZERO);
        assert!((out[0].moved.y - 0.01).abs() < 1e-6, "{}", out[0].moved);
        // Sinking further: stopped, and moved out by position, not by speed.
        let mut p = [above_ground(0, -0.04, Vec3::new(0.0, -1.0, 0.0))];
        let out = resolve(&mut body, &mut p, DT, &params).unwrap();
        let v = p[0].velocity.y + out[0].impulse.y * p[0].inv_mass;
        assert!(v.abs() < 1e-6, "{v}");
        assert!((out[0].moved.y - 0.01).abs() < 1e-6, "{}", out[0].moved);
    }

    #[test]
    fn friction_is_bounded_by_the_cone_and_never_reverses_a_slide() {
        let mut body = ground();
        // Fast slide, slow press: friction is mu times the normal impulse.
        let mut p = [above_ground(0, 0.0, Vec3::new(5.0, -1.0, 0.0))];
        let out = resolve(&mut body, &mut p, DT, &ContactParams::default()).unwrap();
        let j = out[0].impulse;
        assert!((j.y - 1.0).abs() < 1e-5);
        assert!((j.x + DEFAULT_FRICTION * j.y).abs() < 1e-5, "{j}");
        // Slow slide, hard press: the slide stops, no more.
        let mut p = [above_ground(0, 0.0, Vec3::new(0.1, -5.0, 0.0))];
        let out = resolve(&mut body, &mut p, DT, &ContactParams::default()).unwrap();
        assert!((out[0].impulse.x + 0.1).abs() < 1e-5, "{}", out[0].impulse);
    }

    #[test]
    fn momentum_is_exchanged_exactly_and_many_points_do_not_each_stop_a_light_ball() {
        // A light ball falls on ten heavy points side by side: taken one after the other,
        // the first contacts stop it and the rest see it stopped.
        let mass = 0.1;
        let mut body = ball(mass, Vec3::new(0.0, -3.0, 0.0), Vec3::new(0.0, 0.2, 0.0));
        let mut proximities: Vec<Proximity> = (0..10)
            .map(|i| Proximity {
                point: i,
                at: Vec3::new(0.01 * i as f32, 0.0, 0.0),
                normal: -Vec3::Y,
                gap: 0.0,
                velocity: Vec3::ZERO,
                inv_mass: 0.01, // 100 kg each
            })
            .collect();
        let before = body.linear * mass;
        let out = resolve(&mut body, &mut proximities, DT, &ContactParams::default()).unwrap();
        let on_points: Vec3 = out.iter().map(|c| c.impulse).sum();
        let on_ball = body.linear * mass - before;
        assert!(
            (on_points + on_ball).length() < 1e-5,
            "{on_points} {on_ball}"
        );
        // Stopped, not thrown back up at ten times its speed.
        assert!(body.linear.y.abs() < 0.05, "{}", body.linear);
    }

    #[test]
    fn an_off_centre_push_spins_the_body() {
        let mut body = ball(1.0, Vec3::ZERO, Vec3::ZERO);
        let mut p = [Proximity {
            point: 0,
            at: Vec3::new(0.2, 0.0, 0.0),
            normal: -Vec3::Y,
            gap: 0.0,
            velocity: Vec3::new(0.0, 2.0, 0.0), // pushes up on the right side
            inv_mass: 1.0,
        }];
        resolve(&mut body, &mut p, DT, &ContactParams::default()).unwrap();
        assert!(body.linear.y > 0.0);
        assert!(
            body.angular.z > 0.0,
            "counter-clockwise about +z: {}",
            body.angular
        );
    }

    #[test]
    fn radii_are_half_the_local_spacing() {
        let cloud = crate::core::cloud::shapes::fibonacci_sphere(2000, 1.0);
        let network = crate::core::network::build_network(
            cloud.positions(),
            cloud.normals().unwrap(),
            &Default::default(),
        )
        .unwrap();
        let radii = point_radii(&network, DEFAULT_RADIUS_SCALE);
        // 2000 points on a unit sphere: spacing about sqrt(4 pi / 2000 / 0.866) = 0.085.
        let mean = radii.iter().sum::<f32>() / radii.len() as f32;
        assert!((0.035..0.05).contains(&mean), "{mean}");
        assert!(radii.iter().all(|r| r.is_finite() && *r > 0.0));
    }

    #[test]
    fn step_masses_add_the_springs_of_an_implicit_step() {
        let springs = [(0, 1), (1, 2)].map(|(a, b)| crate::core::solver::SpringSpec {
            a,
            b,
            rest_length: 1.0,
            stiffness: 3600.0,
            damping: 60.0,
        });
        let m = step_masses(&[1.0; 4], springs.into_iter(), 1.0 / 60.0);
        // 1 + dt·60 + dt²·3600 = 3 per spring end.
        assert!(
            (m[0] - 3.0).abs() < 1e-5 && (m[1] - 5.0).abs() < 1e-5,
            "{m:?}"
        );
        assert_eq!(m[3], 1.0);
    }

    #[test]
    fn points_that_touch_together_do_not_count_the_springs_between_them() {
        let spring = |a, b| crate::core::solver::SpringSpec {
            a,
            b,
            rest_length: 1.0,
            stiffness: 3600.0,
            damping: 0.0,
        };
        // A chain 0-1-2: 0 and 1 touch, 2 does not.
        let springs = [spring(0, 1), spring(1, 2)];
        let m = group_step_masses(
            &[1.0; 3],
            springs.into_iter(),
            &[true, true, false],
            1.0 / 60.0,
        );
        assert_eq!(
            m[0], 1.0,
            "its only spring goes to a point that touches too"
        );
        assert!(
            (m[1] - 2.0).abs() < 1e-6,
            "the spring to 2 resists: {}",
            m[1]
        );
        assert_eq!(m[2], 1.0);
        // Alone, 1 feels both springs, as in an implicit step.
        let alone = group_step_masses(
            &[1.0; 3],
            springs.into_iter(),
            &[false, true, false],
            1.0 / 60.0,
        );
        let full = step_masses(&[1.0; 3], springs.into_iter(), 1.0 / 60.0);
        assert!((alone[1] - full[1]).abs() < 1e-6);
    }

    #[test]
    fn bad_settings_are_refused() {
        let mut body = ground();
        let bad = ContactParams {
            friction: f32::NAN,
            ..Default::default()
        };
        assert!(matches!(
            resolve(&mut body, &mut [], DT, &bad),
            Err(ContactError::Friction(_))
        ));
        assert!(matches!(
            resolve(&mut body, &mut [], 0.0, &ContactParams::default()),
            Err(ContactError::Tick(_))
        ));
    }

    #[test]
    fn the_incidence_gives_the_group_step_masses_to_the_bit() {
        // The benchmark cloth (every kind of spring) with a few patches touching.
        let grid = crate::core::solver::cloth::cloth_grid(12).unwrap();
        let n = grid.positions.len();
        let masses: Vec<f32> = (0..n).map(|i| 0.1 + 0.001 * i as f32).collect();
        let incidence = SpringIncidence::new(n, &grid.springs);
        for touching in [
            vec![5_usize],
            vec![40, 41, 52, 53],
            (60..84).collect(),
            (0..n).step_by(7).collect(),
        ] {
            let mut mask = vec![false; n];
            touching.iter().for_each(|&i| mask[i] = true);
            let all = group_step_masses(&masses, grid.springs.iter().copied(), &mask, DT);
            for i in 0..n {
                let one = incidence.group_step_mass(masses[i], i, |j| mask[j], DT);
                assert_eq!(one.to_bits(), all[i].to_bits(), "point {i}");
            }
        }
    }
}
