//! Contacts solved within the implicit step ([`StepContact`], [`StepBody`]): the filtered
//! solve with an active set, and the rounds that solve a moving body's velocity with the
//! surface's (see `docs/ARCHITECTURE.md`, "Contacts solved in the step").

use glam::{DVec3, Vec3};

use super::{CgOutcome, ExternalForces, PointState, Scratch, System, iterate};
use crate::core::solver::contact::{StepBody, StepContact, step};
use crate::core::solver::stepper::StepParts;
use crate::core::solver::{Masses, SolverConfig};

mod coupled;
mod friction;
mod pinch;

pub(super) use coupled::{Pair, Resist};

/// Most solves one step makes to settle which contacts hold their points (a contact that
/// would pull its point is let go; a point let go that passes its body is held again).
const CONTACT_PASSES: u32 = 4;

/// Most rounds of solving the moving bodies' velocities with the surface ([`StepBody`]).
pub(super) const BODY_ROUNDS: u32 = 3;

/// A moving body whose velocity is within this (m/s, rad/s) of what the surface's pushes
/// give it needs no further round.
pub(super) const BODY_SPEED_SLACK: f64 = 1e-3;

/// Gauss–Seidel passes over a body's pinches when it is moved out of its overlaps.
const PINCH_MOVE_PASSES: u32 = 4;

/// The active set's hysteresis (m/s): a held contact lets go only when its pull would
/// change its point's velocity by more than this, and a contact let go holds again only
/// when its point passes its body by more than this. Without it, points just touching the
/// floor beside a resting crate let go and held again every tick, which took seven solves
/// a tick instead of one or two (measured 2026-12-07).
const ACTIVE_SET_SLACK: f64 = 1e-4;

/// The contacts of one implicit step ([`StepContact`]), one per point: while a contact holds
/// its point, the point's velocity along the normal is prescribed (the least the contact
/// allows) and the solve finds the rest, the point's neighbours moving with it; the push
/// that took is read back from the residual, λ = n̂·(A·Δv − b)ᵢ. A contact that pulls
/// (λ < 0) lets go and the step is solved again, as is one whose point, let go, passes the
/// body: an active set over at most [`CONTACT_PASSES`] solves, each warm-started from the
/// last. Friction follows at the velocity level, capped by μ·λ/m.
///
/// A point pressed by a moving body against something immovable (a cloth between a crate
/// and the floor: [`step::with_pinches`]) is a pinch: while the immovable contact holds the
/// point, the body cannot move it, so the body is held off the point instead, as off a
/// rigid obstacle moving with the point — Gauss–Seidel impulses on the body's velocity
/// ([`Contacts::pinch`], warm-started from the last step), their opposites pushing the
/// point into what holds it. Holding the point against the body instead, as one contact a
/// point allows, let a heavy crate press the cloth through the floor.
pub(super) struct Contacts<'a> {
    contacts: &'a [StepContact],
    /// The step's length.
    h: f64,
    /// The contacts kept, as indices into `contacts`.
    kept: Vec<usize>,
    /// Each kept contact's partner on its point (see [`step::with_pinches`]), and whether
    /// the two are a pinch (a moving body's contact and an immovable one pressing the point
    /// from opposite sides; else both hold the point, each along its normal).
    partner: Vec<Option<usize>>,
    pinch_pair: Vec<bool>,
    /// Each pinch's push on its point (N·s), normal and friction, while its partner holds
    /// the point; what of it the right-hand side has.
    pinch: Vec<(f64, DVec3)>,
    pinch_rhs: Vec<DVec3>,
    /// Whether each kept contact holds its point.
    holds: Vec<bool>,
    /// The push λ along the normal each kept contact gave in the last solve (N·s; 0 when it
    /// did not hold).
    push: Vec<f64>,
    /// Each kept contact's point's velocity at the step's start.
    v0: Vec<DVec3>,
    /// The bodies that move ([`StepBody`]).
    bodies: &'a [StepBody],
    /// Each body's velocity now, less its guess: linear, angular.
    shift: Vec<(DVec3, DVec3)>,
    /// Each body's estimate of how the surface's pushes change with its velocity (linear,
    /// angular; see [`Contacts::move_bodies`]) and the last round's velocity and pushes.
    secant: Vec<Option<Secant>>,
}

/// What one round of a moving body left for the next: how the pushes on the surface change
/// with the body's velocity, as estimated so far, and the velocity and pushes of the round.
#[derive(Debug, Clone, Copy)]
pub(super) struct Secant {
    pub(super) resist: Resist,
    pub(super) shift: Pair,
    pub(super) impulse: Pair,
}

/// A second filter axis beside unit `n` for the unit normal `m`: their cosine c, the unit
/// e ⊥ n in their plane, and the sine (m = c·n + sin·e). Kept contacts' normals are never
/// within [`step::PAIR_COSINE`] of each other, so the sine is not small.
fn second_axis(n: DVec3, m: DVec3) -> (f64, DVec3, f64) {
    let c = n.dot(m);
    let across = m - n * c;
    let sin = across.length();
    (c, across / sin, sin)
}

impl<'a> Contacts<'a> {
    pub(super) fn new(
        external: &'a ExternalForces,
        points: &PointState,
        model: StepParts<'_>,
        h: f64,
    ) -> Self {
        let contacts = &external.contacts[..];
        let kept = if contacts.is_empty() {
            Vec::new()
        } else {
            step::with_pinches(contacts, points, model.masses)
        };
        let v0 = kept
            .iter()
            .map(|&k| points.v.get(contacts[k].point as usize).as_dvec3())
            .collect();
        let point = |k: usize| contacts[kept[k]].point;
        let partner: Vec<Option<usize>> = (0..kept.len())
            .map(|k| {
                [k.wrapping_sub(1), k + 1]
                    .into_iter()
                    .find(|&j| j < kept.len() && point(j) == point(k))
            })
            .collect();
        let pinch_pair = (0..kept.len())
            .map(|k| {
                partner[k].is_some_and(|j| {
                    let (a, b) = (&contacts[kept[k]], &contacts[kept[j]]);
                    a.body.is_some() != b.body.is_some()
                        && a.normal.dot(b.normal) < step::PINCH_COSINE
                })
            })
            .collect();
        Self {
            contacts,
            h,
            holds: vec![false; kept.len()],
            push: vec![0.0; kept.len()],
            partner,
            pinch_pair,
            pinch: vec![(0.0, DVec3::ZERO); kept.len()],
            pinch_rhs: vec![DVec3::ZERO; kept.len()],
            kept,
            v0,
            bodies: &external.bodies,
            shift: vec![(DVec3::ZERO, DVec3::ZERO); external.bodies.len()],
            secant: vec![None; external.bodies.len()],
        }
    }

    /// The first guess of which contacts hold: those whose point a contact held at the end
    /// of the last step (a surface at rest keeps its contacts), none whose point had a
    /// contact that did not hold, and, for points new to contact, those whose point, moved
    /// by the step's right-hand side over its own part of the matrix (the explicit
    /// estimate, which overshoots), would end below its least normal speed.
    fn guess(&mut self, s: &Scratch, own: &[f64]) {
        for k in 0..self.kept.len() {
            let (i, n, min_speed) = self.get(k);
            let own = own[i];
            let estimate = if own > 0.0 {
                s.rhs[i] / own
            } else {
                DVec3::ZERO
            };
            // A moving body's contact beside an immovable one on the point remembers apart.
            let by_body = self.contacts[self.kept[k]].body.is_some() && self.partner[k].is_some();
            self.holds[k] = if s.touched[i] {
                if by_body {
                    s.held_by_body[i]
                } else {
                    s.held[i]
                }
            } else {
                n.dot(self.v0[k] + estimate) < min_speed - step::SPEED_SLACK
            };
        }
        // Pinches start from their last step's pushes.
        for k in 0..self.kept.len() {
            if self.is_pinch(k) {
                let c = &self.contacts[self.kept[k]];
                let key = self.bodies.get(c.body.unwrap_or(0) as usize).map(|b| b.key);
                if let Some(&(_, _, push)) = key.and_then(|key| {
                    s.pinched
                        .iter()
                        .find(|(b, point, _)| *b == key && *point == c.point)
                }) {
                    self.pinch[k] = push;
                }
            }
        }
    }

    /// Whether kept contact `k` is a pinch now: a moving body's contact whose point its
    /// immovable partner holds.
    fn is_pinch(&self, k: usize) -> bool {
        self.pinch_pair[k]
            && self.contacts[self.kept[k]].body.is_some()
            && self.partner[k].is_some_and(|j| self.holds[j])
    }

    /// Whether kept contact `k` holds its point in the solve's filter (a pinch holds its
    /// body instead).
    fn filtered(&self, k: usize) -> bool {
        self.holds[k] && !self.is_pinch(k)
    }

    /// The other contact that holds `k`'s point in the filter with it, if any (two normals
    /// at one point).
    fn filtered_with(&self, k: usize) -> Option<usize> {
        self.partner[k].filter(|&j| !self.pinch_pair[k] && self.filtered(j) && self.filtered(k))
    }

    /// Remembers which points a contact held in the last solve, for the next step's guess,
    /// and the pinches' pushes by body and point.
    pub(super) fn remember(&self, s: &mut Scratch) {
        if !self.is_empty() || s.touched.iter().any(|&h| h) {
            s.held.fill(false);
            s.held_by_body.fill(false);
            s.touched.fill(false);
            for k in 0..self.kept.len() {
                let i = self.get(k).0;
                s.touched[i] = true;
                if self.contacts[self.kept[k]].body.is_some() && self.partner[k].is_some() {
                    s.held_by_body[i] = self.holds[k];
                } else {
                    s.held[i] = self.push[k] != 0.0;
                }
            }
        }
        s.pinched.clear();
        for k in 0..self.kept.len() {
            let c = &self.contacts[self.kept[k]];
            let body = c.body.and_then(|b| self.bodies.get(b as usize));
            if let (true, Some(body)) = (self.is_pinch(k), body) {
                s.pinched.push((body.key, c.point, self.pinch[k]));
            }
        }
    }

    pub(super) fn is_empty(&self) -> bool {
        self.kept.is_empty()
    }

    /// Kept contact `k`: its point, unit normal and the least normal speed.
    fn get(&self, k: usize) -> (usize, DVec3, f64) {
        let c = &self.contacts[self.kept[k]];
        let n = c.normal.as_dvec3();
        let shift = self.body_shift(c);
        let out = self.recovery_speed(c);
        (
            c.point as usize,
            n,
            f64::from(c.min_speed) + n.dot(shift) + out,
        )
    }

    /// The speed along its normal that moves contact `c`'s point out of its overlap over the
    /// step ([`StepContact::recover`]): the solve moves it (its neighbours following, as its
    /// springs pull them), and [`Contacts::recover`] takes that speed back once the step has
    /// moved the points, so it ends as a move, not as kinetic energy.
    fn recovery_speed(&self, c: &StepContact) -> f64 {
        f64::from(c.recover) / self.h
    }

    /// How much faster contact `c`'s body now moves where it touches than at its guess.
    fn body_shift(&self, c: &StepContact) -> DVec3 {
        match c.body.and_then(|b| self.shift.get(b as usize)) {
            Some((linear, angular)) => *linear + angular.cross(c.arm.as_dvec3()),
            None => DVec3::ZERO,
        }
    }

    /// The normal velocity change kept contact `k` asks of its point.
    fn asked(&self, k: usize) -> f64 {
        let (_, n, min_speed) = self.get(k);
        min_speed - n.dot(self.v0[k])
    }

    /// Sets the filter's normals and, on each held point, Δv's part along its normal, or
    /// along both where two contacts hold it (a pinch holds the body, not the point).
    fn hold(&self, s: &mut Scratch) {
        s.normal.fill(DVec3::ZERO);
        s.normal2.fill(DVec3::ZERO);
        for k in 0..self.kept.len() {
            if !self.filtered(k) {
                continue;
            }
            let (i, n, _) = self.get(k);
            match self.filtered_with(k) {
                Some(j) if j < k => {}
                Some(j) => {
                    // n·Δv = a₁ and m·Δv = a₂, m = c·n + sin·e: Δv's part along e is
                    // (a₂ − c·a₁)/sin.
                    let m = self.get(j).1;
                    let (c, e, sin) = second_axis(n, m);
                    s.normal[i] = n;
                    s.normal2[i] = e;
                    let (a1, a2) = (self.asked(k), self.asked(j));
                    let dv = s.dv[i];
                    s.dv[i] += n * (a1 - n.dot(dv)) + e * ((a2 - c * a1) / sin - e.dot(dv));
                }
                None => {
                    s.normal[i] = n;
                    let along = n.dot(s.dv[i]);
                    s.dv[i] += n * (self.asked(k) - along);
                }
            }
        }
    }

    /// The solve: passes of the filtered PCG until no contact changes.
    pub(super) fn solve(
        &mut self,
        config: &SolverConfig,
        system: &System<'_>,
        s: &mut Scratch,
        b_norm: f64,
    ) -> CgOutcome {
        // The scale of the residual: the right-hand side, or what the contacts ask.
        let asked = (0..self.kept.len())
            .map(|k| (system.own[self.get(k).0] * self.asked(k)).powi(2))
            .sum::<f64>()
            .sqrt();
        let scale = b_norm.max(asked);
        self.guess(s, system.own);
        self.pinches_to_rhs(s);
        let tolerance = f64::from(config.cg_tolerance) * scale;
        let mut outcome = CgOutcome {
            iterations: 0,
            converged: true,
        };
        for round in 0..BODY_ROUNDS {
            for _ in 0..CONTACT_PASSES {
                self.hold(s);
                let pass = iterate(config, system, s, tolerance, scale, true);
                outcome.iterations += pass.iterations;
                outcome.converged = pass.converged;
                if !s.dv.iter().all(|d| d.is_finite()) {
                    s.normal.fill(DVec3::ZERO);
                    s.normal2.fill(DVec3::ZERO);
                    return outcome;
                }
                system.apply(&s.dv, &mut s.q);
                if !self.settle(s, system.own) {
                    break;
                }
            }
            if round + 1 == BODY_ROUNDS {
                break;
            }
            let moved = self.move_bodies(s);
            if self.pinch(s, system.own) && !moved {
                // A pinch's push goes onto its point along its holder's normal, which the
                // filter holds: the solve's Δv stands, only the holders' pushes change.
                self.read_pushes(s);
            }
            if !moved {
                break;
            }
        }
        s.normal.fill(DVec3::ZERO);
        s.normal2.fill(DVec3::ZERO);
        // Remember how the surface resisted each body, for its next step's first round.
        let last = std::mem::take(&mut s.resisted);
        for (body, secant) in self.bodies.iter().zip(&self.secant) {
            let resist = secant
                .map(|secant| secant.resist)
                .or_else(|| last.iter().find(|(key, _)| *key == body.key).map(|r| r.1));
            if let Some(resist) = resist {
                s.resisted.push((body.key, resist));
            }
        }
        outcome
    }

    /// One quasi-Newton step of each moving body towards the velocity the surface's pushes
    /// give it ([`StepBody`]); returns whether any moved. The pushes J on the surface change
    /// with the body's velocity V (linear and angular, a 6-vector) as J(V) = J₀ + C·V while
    /// the same contacts hold (the step is linear), and the body's own velocity is
    /// V = V₀ − W·J(V): the step solves (I + W·C)·δ = −(V − V₀ + W·J). C ([`Resist`])
    /// starts as the held points' step masses along their normals, a turn's part and a
    /// shift's coupled (more than the surface resists: the rounds fall short rather than
    /// overshoot), and each later round corrects it by Broyden's update from the change it
    /// saw, which along one direction of push is exact.
    fn move_bodies(&mut self, s: &Scratch) -> bool {
        if self.bodies.is_empty() {
            return false;
        }
        let count = self.bodies.len();
        // Per body: the pushes' linear and angular impulse, and the held points' masses
        // along their normals; and the pinches' impulse apart (set by `pinch`, not a
        // function of the body's velocity here).
        let mut impulse = vec![(DVec3::ZERO, DVec3::ZERO); count];
        let mut pinched = vec![(DVec3::ZERO, DVec3::ZERO); count];
        let mut resist = vec![Resist::default(); count];
        for k in 0..self.kept.len() {
            let c = &self.contacts[self.kept[k]];
            let Some(b) = c.body.map(|b| b as usize).filter(|&b| b < count) else {
                continue;
            };
            let arm = c.arm.as_dvec3();
            if self.is_pinch(k) {
                let j = self.pinch_impulse(k);
                pinched[b].0 += j;
                pinched[b].1 += arm.cross(j);
                continue;
            }
            if self.push[k] == 0.0 {
                continue;
            }
            let (i, n, _) = self.get(k);
            let j = n * self.push[k];
            impulse[b].0 += j;
            impulse[b].1 += arm.cross(j);
            resist[b].add(n, arm, n.dot(s.diag[i].mul(n)));
        }
        let mut moved = false;
        for b in 0..count {
            let body = &self.bodies[b];
            let (inv_mass, inv_inertia) = (body.inv_mass.as_dmat3(), body.inv_inertia.as_dmat3());
            // The body takes the opposite of what the surface took.
            let linear = body.linear.as_dvec3() - inv_mass * (impulse[b].0 + pinched[b].0);
            let angular = body.angular.as_dvec3() - inv_inertia * (impulse[b].1 + pinched[b].1);
            let (shift_linear, shift_angular) = self.shift[b];
            let miss_linear = body.guess_linear.as_dvec3() + shift_linear - linear;
            let miss_angular = body.guess_angular.as_dvec3() + shift_angular - angular;
            if miss_linear.length() < BODY_SPEED_SLACK && miss_angular.length() < BODY_SPEED_SLACK {
                continue;
            }
            // C = dJ/dV, from the last round's change where there was one (none where only
            // pinches touch the body: `pinch` holds it).
            let regular = !resist[b].is_empty();
            let resist = match self.secant[b] {
                _ if !regular => resist[b],
                // The body's resistance found last step, where it has one.
                None => s
                    .resisted
                    .iter()
                    .find(|(key, _)| *key == body.key)
                    .map_or(resist[b], |(_, r)| *r),
                Some(last) => last.resist.broyden(
                    (shift_linear - last.shift.0, shift_angular - last.shift.1),
                    (impulse[b].0 - last.impulse.0, impulse[b].1 - last.impulse.1),
                ),
            };
            self.secant[b] = Some(Secant {
                resist,
                shift: self.shift[b],
                impulse: impulse[b],
            });
            if let Some((step_linear, step_angular)) =
                resist.step((inv_mass, inv_inertia), (miss_linear, miss_angular))
            {
                self.shift[b] = (shift_linear + step_linear, shift_angular + step_angular);
                // Only a body the solve holds points to needs the surface solved again (a
                // body held off pinches alone moves no point).
                moved |= regular;
            }
        }
        moved
    }

    /// Reads each held contact's push from `s.q` = A·Δv and lets go of those that pull;
    /// holds again each point let go that passes its body. Returns whether any changed.
    fn settle(&mut self, s: &Scratch, own: &[f64]) -> bool {
        // Every push is read before any contact lets go (two contacts may share a point).
        self.read_pushes(s);
        let mut changed = false;
        for k in 0..self.kept.len() {
            if self.is_pinch(k) {
                continue;
            }
            let (i, n, min_speed) = self.get(k);
            if self.holds[k] {
                if self.push[k] < -ACTIVE_SET_SLACK * own[i] {
                    self.holds[k] = false;
                    changed = true;
                }
            } else if n.dot(self.v0[k] + s.dv[i]) < min_speed - ACTIVE_SET_SLACK {
                self.holds[k] = true;
                changed = true;
            }
        }
        changed
    }

    /// Reads each held contact's push from the residual, `s.q` = A·Δv less the
    /// right-hand side (a pinch's is its body's, found by `pinch`).
    fn read_pushes(&mut self, s: &Scratch) {
        for k in 0..self.kept.len() {
            if self.is_pinch(k) {
                // Its push is the body's, found by `pinch`.
                continue;
            }
            if !self.holds[k] {
                self.push[k] = 0.0;
                continue;
            }
            let (i, n, _) = self.get(k);
            let residual = s.q[i] - s.rhs[i];
            // Where two contacts hold the point, the residual is λ₁·n₁ + λ₂·n₂.
            self.push[k] = match self.filtered_with(k) {
                Some(j) => {
                    let (first, second) = if k < j { (k, j) } else { (j, k) };
                    let (n1, n2) = (self.get(first).1, self.get(second).1);
                    let (c, e, sin) = second_axis(n1, n2);
                    let second_push = e.dot(residual) / sin;
                    if k == second {
                        second_push
                    } else {
                        n1.dot(residual) - c * second_push
                    }
                }
                None => n.dot(residual),
            };
        }
    }

    /// Friction on the points the last solve held (against a moving body, with the body's
    /// answer: [`Contacts::body_friction`]), and each contact's impulse added to `impulses`
    /// (one per contact handed in); returns whether any contact held.
    pub(super) fn slide(
        &mut self,
        s: &mut Scratch,
        points: &PointState,
        impulses: &mut [Vec3],
    ) -> bool {
        let mut held = false;
        for k in 0..self.kept.len() {
            if self.is_pinch(k) {
                // The body took the opposite of all of it; the point, what its holder's
                // normal carries (in the solve), and the holder the rest (below).
                let j = self.pinch_impulse(k);
                held |= j != DVec3::ZERO;
                if let Some(out) = impulses.get_mut(self.kept[k]) {
                    *out += j.as_vec3();
                }
                continue;
            }
            // What holds a pinched point takes what of the pinch passes through it (see
            // `pinch`).
            let passed = self.partner[k]
                .filter(|&j| self.is_pinch(j))
                .map_or(DVec3::ZERO, |j| -self.pinch_passed(j));
            if let Some(out) = impulses.get_mut(self.kept[k]) {
                *out += passed.as_vec3();
            }
            let push = self.push[k];
            if push == 0.0 {
                continue;
            }
            held = true;
            let c = &self.contacts[self.kept[k]];
            let (i, n, _) = self.get(k);
            if self.rubs_body(k) {
                // Its friction is found with the body's answer (below).
                if let Some(out) = impulses.get_mut(self.kept[k]) {
                    *out += (n * push).as_vec3();
                }
                continue;
            }
            let mass = s.own[i];
            let relative = points.v.get(i).as_dvec3() + s.dv[i] - c.body_velocity.as_dvec3();
            let mut slide = step::friction_dv(relative, n, f64::from(c.friction), push / mass);
            // Not into the other contact that holds the point.
            if let Some(j) = self.filtered_with(k) {
                let other = self.get(j).1;
                let into = other.dot(slide);
                if into < 0.0 {
                    slide -= other * into;
                }
            }
            s.dv[i] += slide;
            if let Some(out) = impulses.get_mut(self.kept[k]) {
                *out += (n * push + slide * mass).as_vec3();
            }
        }
        self.body_friction(&mut s.dv, &s.own, impulses);
        held
    }

    /// After the step has moved the points (`points` at their new places and velocities):
    /// each held point that the solve moved out of its overlap at its recovery speed
    /// ([`Contacts::recovery_speed`]) gives that speed back, so the overlap ends as a move
    /// (a share of it, [`StepContact::recover`]) and not as kinetic energy. A pinch moves
    /// its body instead (its point cannot give way): each body's translation out of its
    /// pinches is found by Gauss–Seidel passes and written to `moves` (one per body, the
    /// surface's coordinates). The speed a point gives back comes off its contact's impulse
    /// in `impulses` (its mass times it), so a body given the opposite of the impulse takes
    /// no speed from the overlap either: momentum stays what the points measure.
    pub(super) fn recover(
        &self,
        points: &mut PointState,
        masses: &Masses,
        impulses: &mut [Vec3],
        moves: &mut [Vec3],
    ) {
        let mut pinched = Vec::new();
        for k in 0..self.kept.len() {
            let c = &self.contacts[self.kept[k]];
            if c.recover <= 0.0 {
                continue;
            }
            let i = c.point as usize;
            if self.is_pinch(k) {
                pinched.push((c.body.unwrap_or(0) as usize, c.normal, c.recover));
            } else if self.push[k] > 0.0 {
                // Held: it left its body at least at the recovery speed; take that back.
                let body = (c.body_velocity.as_dvec3() + self.body_shift(c)).as_vec3();
                let leaving = (points.v.get(i) - body).dot(c.normal);
                let back = leaving.min(self.recovery_speed(c) as f32).max(0.0);
                points.v.set(i, points.v.get(i) - c.normal * back);
                if let Some(out) = impulses.get_mut(self.kept[k]) {
                    *out -= c.normal * (back * masses.mass(i));
                }
            }
        }
        for _ in 0..PINCH_MOVE_PASSES {
            for &(b, n, out) in &pinched {
                if let Some(d) = moves.get_mut(b) {
                    // Moving the body by d opens the gap by −n·d.
                    let short = out + n.dot(*d);
                    if short > 0.0 {
                        *d -= n * short;
                    }
                }
            }
        }
    }
}
