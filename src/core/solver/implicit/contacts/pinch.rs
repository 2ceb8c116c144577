//! Pinches ([`Contacts::pinch`]): a point pressed by a moving body against something
//! immovable holds the body off instead of giving way (see [`Contacts`]).

use glam::DVec3;

use super::super::Scratch;
use super::Contacts;
use crate::core::solver::contact::step;

/// Gauss–Seidel passes over a body's pinches each round ([`Contacts::pinch`]).
const PINCH_PASSES: u32 = 24;

/// A pinch whose push changes its body's velocity where it touches by less than this (m/s)
/// between rounds has settled.
const PINCH_SPEED_SLACK: f64 = 1e-4;

impl Contacts<'_> {
    /// The velocity pinch `k`'s point will end the step with, from the last solve: what
    /// holds it against the body (its partner) then slows its slide by friction, as
    /// [`Contacts::slide`] will.
    pub(super) fn held_point_velocity(&self, k: usize, s: &Scratch, own: &[f64]) -> DVec3 {
        let i = self.contacts[self.kept[k]].point as usize;
        let v = self.v0[k] + s.dv[i];
        let Some(j) = self.partner[k] else {
            return v;
        };
        let (push, mass) = (self.push[j], own[i]);
        if push <= 0.0 || mass <= 0.0 {
            return v;
        }
        let c = &self.contacts[self.kept[j]];
        let (_, n, _) = self.get(j);
        let relative = v - c.body_velocity.as_dvec3();
        v + step::friction_dv(relative, n, f64::from(c.friction), push / mass)
    }

    /// Pinch `k`'s impulse on its point: its push along the normal and its friction.
    pub(super) fn pinch_impulse(&self, k: usize) -> DVec3 {
        let (push, friction) = self.pinch[k];
        self.get(k).1 * push + friction
    }

    /// What of pinch `k`'s impulse the solve carries to the points: its push's part along
    /// the normal of what holds the point (the rest, and its friction, pass through the
    /// point to what holds it: see `pinch`; a light point took the sideways part of a tilted
    /// crate's push alone and shot out at 11 m/s).
    pub(super) fn pinch_push(&self, k: usize) -> DVec3 {
        let push = self.get(k).1 * self.pinch[k].0;
        match self.partner[k] {
            Some(j) => {
                let holder = self.get(j).1;
                holder * holder.dot(push)
            }
            None => push,
        }
    }

    /// What of pinch `k`'s impulse passes through its point to what holds it: its friction
    /// and its push's part across the holder's normal.
    pub(super) fn pinch_passed(&self, k: usize) -> DVec3 {
        self.pinch_impulse(k) - self.pinch_push(k)
    }

    /// Holds each body off the points it pinches (see [`Contacts`]): Gauss–Seidel passes
    /// over its pinches, each pushing the body's velocity where it touches its point (the
    /// point's velocity as it will end the step; the point cannot give way) up to what the
    /// gap allows and no more than needed (a push never pulls), with Coulomb friction
    /// against the slide; the body answers with its own inverse mass and inertia (with the
    /// surface's other contacts' resistance, `(I + W·C)⁻¹·W` from their secant, a crate
    /// landing half on the floor's cloth ran away). The pushes go into the right-hand
    /// side, onto the points. Returns whether a push changed the body's velocity where it
    /// touches by more than [`PINCH_SPEED_SLACK`].
    pub(super) fn pinch(&mut self, s: &mut Scratch, own: &[f64]) -> bool {
        let mut changed = false;
        for b in 0..self.bodies.len() {
            let pinches: Vec<usize> = (0..self.kept.len())
                .filter(|&k| self.is_pinch(k) && self.contacts[self.kept[k]].body == Some(b as u32))
                .collect();
            if pinches.is_empty() {
                continue;
            }
            let body = &self.bodies[b];
            let (inv_mass, inv_inertia) = (body.inv_mass.as_dmat3(), body.inv_inertia.as_dmat3());
            let (mut linear, mut angular) = self.shift[b];
            // How far an impulse of 1 along `d` at `arm` changes the body's velocity there.
            let compliance = |d: DVec3, arm: DVec3| {
                let turn = arm.cross(d);
                d.dot(inv_mass * d) + turn.dot(inv_inertia * turn)
            };
            for _ in 0..PINCH_PASSES {
                for &k in &pinches {
                    let c = &self.contacts[self.kept[k]];
                    let n = self.get(k).1;
                    let arm = c.arm.as_dvec3();
                    let at = |linear: DVec3, angular: DVec3| {
                        c.body_velocity.as_dvec3() + linear + angular.cross(arm)
                    };
                    let allowed = f64::from(c.min_speed) - n.dot(c.body_velocity.as_dvec3());
                    let (push, friction) = self.pinch[k];
                    let point = self.held_point_velocity(k, s, own);
                    let w = compliance(n, arm);
                    if w <= 0.0 || !w.is_finite() {
                        continue;
                    }
                    // Along the normal: the body may come no closer than `allowed`.
                    let closing = n.dot(point - at(linear, angular));
                    let next = (push + (allowed - closing) / w).max(0.0);
                    let j = n * (next - push);
                    linear -= inv_mass * j;
                    angular -= inv_inertia * arm.cross(j);
                    // Across it: Coulomb friction, the body's slide on the point stopped or
                    // slowed by μ times the push (an impulse f on the point moves the
                    // body's velocity there by −w·f). The point does not give way: what
                    // holds it against the body (the floor under a cloth) holds it across
                    // too, by its own friction under the body's push and the point's
                    // weight, so the friction passes through the point to it.
                    let relative = point - at(linear, angular);
                    let slide = relative - n * n.dot(relative);
                    let speed = slide.length();
                    let mut friction_next = friction;
                    if speed > 0.0 {
                        let t = slide / speed;
                        let wt = compliance(t, arm);
                        if wt > 0.0 && wt.is_finite() {
                            friction_next -= t * (speed / wt);
                        }
                    }
                    let cap = f64::from(c.friction) * next;
                    let size = friction_next.length();
                    if size > cap {
                        friction_next *= cap / size;
                    }
                    let jf = friction_next - friction;
                    linear -= inv_mass * jf;
                    angular -= inv_inertia * arm.cross(jf);
                    changed |= (next - push).abs() * w > PINCH_SPEED_SLACK
                        || jf.length() * w > PINCH_SPEED_SLACK;
                    self.pinch[k] = (next, friction_next);
                }
            }
            if linear.is_finite() && angular.is_finite() {
                self.shift[b] = (linear, angular);
            }
        }
        self.pinches_to_rhs(s);
        changed
    }

    /// Puts each pinch's push on its point into the right-hand side (what changed since it
    /// was last put there), and takes out the push of a pinch that no longer is one.
    pub(super) fn pinches_to_rhs(&mut self, s: &mut Scratch) {
        for k in 0..self.kept.len() {
            let now = if self.is_pinch(k) {
                self.pinch_push(k)
            } else {
                self.pinch[k] = (0.0, DVec3::ZERO);
                DVec3::ZERO
            };
            let change = now - self.pinch_rhs[k];
            if change != DVec3::ZERO {
                let i = self.contacts[self.kept[k]].point as usize;
                s.rhs[i] += change;
                self.pinch_rhs[k] = now;
            }
        }
    }
}
