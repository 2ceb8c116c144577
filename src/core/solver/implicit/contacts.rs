//! Contacts solved within the implicit step ([`StepContact`], [`StepBody`]): the filtered
//! solve with an active set, and the rounds that solve a moving body's velocity with the
//! surface's (see `docs/ARCHITECTURE.md`, "Contacts solved in the step").

use glam::{DMat3, DVec3};

use super::{CgOutcome, ExternalForces, PointState, Scratch, System, iterate, outer};
use crate::core::solver::SolverConfig;
use crate::core::solver::contact::{StepBody, StepContact, step};
use crate::core::solver::stepper::StepParts;

/// Most solves one step makes to settle which contacts hold their points (a contact that
/// would pull its point is let go; a point let go that passes its body is held again).
const CONTACT_PASSES: u32 = 4;

/// Most rounds of solving the moving bodies' velocities with the surface ([`StepBody`]).
pub(super) const BODY_ROUNDS: u32 = 3;

/// A moving body whose velocity is within this (m/s, rad/s) of what the surface's pushes
/// give it needs no further round.
pub(super) const BODY_SPEED_SLACK: f64 = 1e-3;

/// The contacts of one implicit step ([`StepContact`]), one per point: while a contact holds
/// its point, the point's velocity along the normal is prescribed (the least the contact
/// allows) and the solve finds the rest, the point's neighbours moving with it; the push
/// that took is read back from the residual, λ = n̂·(A·Δv − b)ᵢ. A contact that pulls
/// (λ < 0) lets go and the step is solved again, as is one whose point, let go, passes the
/// body: an active set over at most [`CONTACT_PASSES`] solves, each warm-started from the
/// last. Friction follows at the velocity level, capped by μ·λ/m.
pub(super) struct Contacts<'a> {
    contacts: &'a [StepContact],
    /// The contacts kept, as indices into `contacts`.
    kept: Vec<usize>,
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
    pub(super) resist: (DMat3, DMat3),
    pub(super) shift: (DVec3, DVec3),
    pub(super) impulse: (DVec3, DVec3),
}

/// Broyden's update of `c` (how y changes with x) from a step `dx` that changed y by `dy`.
pub(super) fn broyden(c: DMat3, dx: DVec3, dy: DVec3) -> DMat3 {
    let length = dx.length_squared();
    if length > 0.0 && length.is_finite() {
        c + outer(dy - c * dx, dx) / length
    } else {
        c
    }
}

impl<'a> Contacts<'a> {
    pub(super) fn new(
        external: &'a ExternalForces,
        points: &PointState,
        model: StepParts<'_>,
    ) -> Self {
        let contacts = &external.contacts[..];
        let kept = if contacts.is_empty() {
            Vec::new()
        } else {
            step::one_per_point(contacts, points, model.masses)
        };
        let v0 = kept
            .iter()
            .map(|&k| points.v.get(contacts[k].point as usize).as_dvec3())
            .collect();
        Self {
            contacts,
            holds: vec![false; kept.len()],
            push: vec![0.0; kept.len()],
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
            self.holds[k] = if s.touched[i] {
                s.held[i]
            } else {
                n.dot(self.v0[k] + estimate) < min_speed - step::SPEED_SLACK
            };
        }
    }

    /// Remembers which points a contact held in the last solve, for the next step's guess.
    pub(super) fn remember(&self, s: &mut Scratch) {
        if !self.is_empty() || s.touched.iter().any(|&h| h) {
            s.held.fill(false);
            s.touched.fill(false);
            for k in 0..self.kept.len() {
                let i = self.get(k).0;
                s.touched[i] = true;
                s.held[i] = self.push[k] != 0.0;
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
        (c.point as usize, n, f64::from(c.min_speed) + n.dot(shift))
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

    /// Sets the filter's normals and, on each held point, Δv's part along its normal.
    fn hold(&self, s: &mut Scratch) {
        s.normal.fill(DVec3::ZERO);
        for k in 0..self.kept.len() {
            if self.holds[k] {
                let (i, n, _) = self.get(k);
                s.normal[i] = n;
                let along = n.dot(s.dv[i]);
                s.dv[i] += n * (self.asked(k) - along);
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
                    return outcome;
                }
                system.apply(&s.dv, &mut s.q);
                if !self.settle(s) {
                    break;
                }
            }
            if round + 1 == BODY_ROUNDS || !self.move_bodies(s) {
                break;
            }
        }
        s.normal.fill(DVec3::ZERO);
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
    /// with the body's velocity V as J(V) = J₀ + C·V while the same contacts hold (the step
    /// is linear), and the body's own velocity is V = V₀ − W·J(V): the step solves
    /// (I + W·C)·δ = −(V − V₀ + W·J). C starts as the held points' step masses along their
    /// normals (more than the surface resists: the rounds fall short rather than overshoot)
    /// and each later round corrects it by Broyden's update from the change it saw, which
    /// along one direction of push is exact.
    fn move_bodies(&mut self, s: &Scratch) -> bool {
        if self.bodies.is_empty() {
            return false;
        }
        let count = self.bodies.len();
        // Per body: the pushes' linear and angular impulse, and the held points' masses
        // along their normals, as linear and angular 3×3 sums.
        let mut impulse = vec![(DVec3::ZERO, DVec3::ZERO); count];
        let mut resist = vec![(DMat3::ZERO, DMat3::ZERO); count];
        for k in 0..self.kept.len() {
            let c = &self.contacts[self.kept[k]];
            let Some(b) = c.body.map(|b| b as usize).filter(|&b| b < count) else {
                continue;
            };
            if self.push[k] == 0.0 {
                continue;
            }
            let (i, n, _) = self.get(k);
            let arm = c.arm.as_dvec3();
            let j = n * self.push[k];
            impulse[b].0 += j;
            impulse[b].1 += arm.cross(j);
            let d = &s.diag[i];
            let mass = n.dot(d.mul(n));
            let turn = arm.cross(n);
            resist[b].0 += outer(n, n) * mass;
            resist[b].1 += outer(turn, turn) * mass;
        }
        let mut moved = false;
        for b in 0..count {
            let body = &self.bodies[b];
            let (inv_mass, inv_inertia) = (body.inv_mass.as_dmat3(), body.inv_inertia.as_dmat3());
            // The body takes the opposite of what the surface took.
            let linear = body.linear.as_dvec3() - inv_mass * impulse[b].0;
            let angular = body.angular.as_dvec3() - inv_inertia * impulse[b].1;
            let (shift_linear, shift_angular) = self.shift[b];
            let miss_linear = body.guess_linear.as_dvec3() + shift_linear - linear;
            let miss_angular = body.guess_angular.as_dvec3() + shift_angular - angular;
            if miss_linear.length() < BODY_SPEED_SLACK && miss_angular.length() < BODY_SPEED_SLACK {
                continue;
            }
            // C = dJ/dV, from the last round's change where there was one.
            let resist = match self.secant[b] {
                // The body's resistance found last step, where it has one.
                None => s
                    .resisted
                    .iter()
                    .find(|(key, _)| *key == body.key)
                    .map_or(resist[b], |(_, r)| *r),
                Some(last) => (
                    broyden(
                        last.resist.0,
                        shift_linear - last.shift.0,
                        impulse[b].0 - last.impulse.0,
                    ),
                    broyden(
                        last.resist.1,
                        shift_angular - last.shift.1,
                        impulse[b].1 - last.impulse.1,
                    ),
                ),
            };
            self.secant[b] = Some(Secant {
                resist,
                shift: self.shift[b],
                impulse: impulse[b],
            });
            let step_linear = -((DMat3::IDENTITY + inv_mass * resist.0).inverse() * miss_linear);
            let step_angular =
                -((DMat3::IDENTITY + inv_inertia * resist.1).inverse() * miss_angular);
            if step_linear.is_finite() && step_angular.is_finite() {
                self.shift[b] = (shift_linear + step_linear, shift_angular + step_angular);
                moved = true;
            }
        }
        moved
    }

    /// Reads each held contact's push from `s.q` = A·Δv and lets go of those that pull;
    /// holds again each point let go that passes its body. Returns whether any changed.
    fn settle(&mut self, s: &Scratch) -> bool {
        let mut changed = false;
        for k in 0..self.kept.len() {
            let (i, n, min_speed) = self.get(k);
            if self.holds[k] {
                let push = n.dot(s.q[i] - s.rhs[i]);
                self.push[k] = push;
                if push < 0.0 {
                    self.holds[k] = false;
                    changed = true;
                }
            } else {
                self.push[k] = 0.0;
                if n.dot(self.v0[k] + s.dv[i]) < min_speed - step::SPEED_SLACK {
                    self.holds[k] = true;
                    changed = true;
                }
            }
        }
        changed
    }

    /// Friction on the points the last solve held, and each contact's impulse added to
    /// `impulses` (one per contact handed in); returns whether any contact held.
    pub(super) fn slide(
        &self,
        s: &mut Scratch,
        points: &PointState,
        impulses: &mut [glam::Vec3],
    ) -> bool {
        let mut held = false;
        for k in 0..self.kept.len() {
            let push = self.push[k];
            if push == 0.0 {
                continue;
            }
            held = true;
            let c = &self.contacts[self.kept[k]];
            let (i, n, _) = self.get(k);
            let mass = s.own[i];
            let body_velocity = c.body_velocity.as_dvec3() + self.body_shift(c);
            let relative = points.v.get(i).as_dvec3() + s.dv[i] - body_velocity;
            let slide = step::friction_dv(relative, n, f64::from(c.friction), push / mass);
            s.dv[i] += slide;
            if let Some(out) = impulses.get_mut(self.kept[k]) {
                *out += (n * push + slide * mass).as_vec3();
            }
        }
        held
    }
}
