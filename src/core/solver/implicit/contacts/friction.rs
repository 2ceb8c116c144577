//! Friction between the surface and the moving bodies that touch it, after the solve
//! ([`Contacts::body_friction`]): Gauss–Seidel passes over each body's held contacts, each
//! contact's impulse found with the body's answer to it.
//!
//! Each contact used to stop its point's slide on the body as if the body could not move,
//! and the body took the opposite of all of those impulses at once: a 1 kg crate on a dozen
//! points took a dozen. At its edges, 0.1 m from its centre, its inertia answers an impulse
//! as a 0.4 kg mass would, so it was spun past the points it touched, faster each tick. A
//! crate dropped 0.1 m on a firm gas-filled ball (`tests/contact_scenes.rs`) spun at
//! 2 rad/s within three ticks of landing; the scene gained 29 J over its 5 s, and the crate
//! slid off the ball. With friction off, the landing gained nothing (measured 2026-12-08).
//! See decision 0036.

use glam::{DVec3, Vec3};

use super::Contacts;

/// Gauss–Seidel passes over a body's contacts ([`Contacts::body_friction`]).
const FRICTION_PASSES: u32 = 8;

impl Contacts<'_> {
    /// Whether kept contact `k` is a moving body's contact that is not a pinch (a pinch's
    /// friction is the body's, found by `pinch`).
    pub(super) fn rubs_body(&self, k: usize) -> bool {
        let c = &self.contacts[self.kept[k]];
        c.body.is_some_and(|b| (b as usize) < self.bodies.len()) && !self.is_pinch(k)
    }

    /// Friction between each moving body and the points its contacts held in the last solve
    /// (their pushes along the normals already in `impulses`): Coulomb friction up to μ
    /// times each push, by Gauss–Seidel passes in which an impulse f changes its point's
    /// velocity by f/m (`own`: the point's own mass; the point alone) and the body's by −W·f
    /// at its arm, so that together they stop the slide and no more. Each point's Δv (`dv`),
    /// each body's velocity (its shift) and each contact's impulse in `impulses` take what
    /// friction gave.
    pub(super) fn body_friction(&mut self, dv: &mut [DVec3], own: &[f64], impulses: &mut [Vec3]) {
        for b in 0..self.bodies.len() {
            let mine: Vec<usize> = (0..self.kept.len())
                .filter(|&k| {
                    self.rubs_body(k)
                        && self.push[k] > 0.0
                        && self.contacts[self.kept[k]].body == Some(b as u32)
                })
                .collect();
            if mine.is_empty() {
                continue;
            }
            let body = &self.bodies[b];
            let (inv_mass, inv_inertia) = (body.inv_mass.as_dmat3(), body.inv_inertia.as_dmat3());
            let (mut linear, mut angular) = self.shift[b];
            let mut friction = vec![DVec3::ZERO; mine.len()];
            for _ in 0..FRICTION_PASSES {
                for (f, &k) in friction.iter_mut().zip(&mine) {
                    let c = &self.contacts[self.kept[k]];
                    let (i, n, _) = self.get(k);
                    let arm = c.arm.as_dvec3();
                    let mass = own[i];
                    let cap = f64::from(c.friction) * self.push[k];
                    // Neither a point without mass nor a contact without friction rubs (NaN
                    // included).
                    if !(mass > 0.0 && cap > 0.0) {
                        continue;
                    }
                    let at = c.body_velocity.as_dvec3() + linear + angular.cross(arm);
                    let relative = self.v0[k] + dv[i] - at;
                    let slide = relative - n * n.dot(relative);
                    let speed = slide.length();
                    if speed <= 0.0 {
                        continue;
                    }
                    let t = slide / speed;
                    let turn = arm.cross(t);
                    let give = 1.0 / mass + t.dot(inv_mass * t) + turn.dot(inv_inertia * turn);
                    let mut next = *f - t * (speed / give);
                    let size = next.length();
                    if size > cap {
                        next *= cap / size;
                    }
                    let mut change = next - *f;
                    // Not into the other contact that holds the point.
                    if let Some(j) = self.filtered_with(k) {
                        let other = self.get(j).1;
                        let into = other.dot(change);
                        if into < 0.0 {
                            change -= other * into;
                        }
                    }
                    dv[i] += change / mass;
                    linear -= inv_mass * change;
                    angular -= inv_inertia * arm.cross(change);
                    *f += change;
                }
            }
            if linear.is_finite() && angular.is_finite() {
                self.shift[b] = (linear, angular);
            }
            for (f, &k) in friction.iter().zip(&mine) {
                if let Some(out) = impulses.get_mut(self.kept[k]) {
                    *out += f.as_vec3();
                }
            }
        }
    }
}
