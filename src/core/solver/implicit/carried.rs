//! Pinned points carried by bodies the step solves with the surface ([`CarriedPoint`]):
//! attachments to dynamic bodies, solved implicitly. A body's velocity at the end of the
//! step is an unknown beside the surface's; each round moves its carried points with its
//! current velocity, solves the surface, reads what held them (the pinned rows of
//! A·Δv − b) and takes a quasi-Newton step towards the velocity those pulls would give the
//! body, as the contacts' moving bodies do (`contacts.rs`). Without it a light body under a
//! stiff surface swings further each tick: the surface's pull follows the body's velocity
//! one tick late, and the loop's gain, W·C (the body's inverse mass times the carried
//! points' step masses), passes 2 (a 1 kg body under a 1 kg sheet did, at 60 Hz).

use glam::{DVec3, Vec3};

use super::Scratch;
use super::contacts::{BODY_SPEED_SLACK, Resist, Secant};
use crate::core::solver::contact::{CarriedPoint, StepBody};
use crate::core::solver::{Masses, PointState};

/// The bodies carrying pinned points in one step, and how far each has moved from its
/// guess so far.
pub(super) struct Carried<'a> {
    carried: &'a [CarriedPoint],
    bodies: &'a [StepBody],
    /// Each body's velocity now, less its guess: linear, angular.
    shift: Vec<(DVec3, DVec3)>,
    secant: Vec<Option<Secant>>,
    /// Each carried point's velocity at the start of the step.
    start: Vec<Vec3>,
}

impl<'a> Carried<'a> {
    pub(super) fn new(
        carried: &'a [CarriedPoint],
        bodies: &'a [StepBody],
        points: &PointState,
    ) -> Self {
        Self {
            carried,
            bodies,
            shift: vec![(DVec3::ZERO, DVec3::ZERO); bodies.len()],
            secant: vec![None; bodies.len()],
            start: carried
                .iter()
                .map(|c| points.v.get(c.point as usize))
                .collect(),
        }
    }

    /// Adds to `out` the momentum the rounds gave each carried point by moving it with its
    /// body, m·(v − v_start): part of what held it (the step's pinned rows leave it out,
    /// their Δv being zero).
    pub(super) fn add_moved(&self, points: &PointState, masses: &Masses, out: &mut [Vec3]) {
        for (c, start) in self.carried.iter().zip(&self.start) {
            let i = c.point as usize;
            if let Some(j) = out.get_mut(i).filter(|_| masses.is_pinned(i)) {
                *j += (points.v.get(i) - *start) * masses.mass(i);
            }
        }
    }

    pub(super) fn is_empty(&self) -> bool {
        self.carried.is_empty()
    }

    /// One quasi-Newton step of each carrying body, from what held its points in the last
    /// solve (`held`, one per point, zero at free points, [`Self::add_moved`] included);
    /// each carried point's velocity in `points` moves with its body. Returns whether any
    /// body moved.
    pub(super) fn step(&mut self, s: &Scratch, held: &[Vec3], points: &mut PointState) -> bool {
        let count = self.bodies.len();
        let mut impulse = vec![(DVec3::ZERO, DVec3::ZERO); count];
        let mut resist = vec![Resist::default(); count];
        for c in self.carried {
            let (i, b) = (c.point as usize, c.body as usize);
            let Some(j) = held.get(i).filter(|_| b < count) else {
                continue;
            };
            let (j, arm) = (j.as_dvec3(), c.arm.as_dvec3());
            impulse[b].0 += j;
            impulse[b].1 += arm.cross(j);
            // The point's step mass, as a first guess of how much the surface resists it
            // (more than it does: its neighbours among the carried points move with it).
            let mass = s.diag.get(i).map_or(0.0, |d| d.trace() / 3.0);
            resist[b].add_carried(arm, mass);
        }
        let mut moved = vec![None; count];
        for b in 0..count {
            if impulse[b] == (DVec3::ZERO, DVec3::ZERO) && resist[b].is_empty() {
                continue;
            }
            let body = &self.bodies[b];
            let (inv_mass, inv_inertia) = (body.inv_mass.as_dmat3(), body.inv_inertia.as_dmat3());
            // The body takes the opposite of what held its points.
            let linear = body.linear.as_dvec3() - inv_mass * impulse[b].0;
            let angular = body.angular.as_dvec3() - inv_inertia * impulse[b].1;
            let (shift_linear, shift_angular) = self.shift[b];
            let miss_linear = body.guess_linear.as_dvec3() + shift_linear - linear;
            let miss_angular = body.guess_angular.as_dvec3() + shift_angular - angular;
            if miss_linear.length() < BODY_SPEED_SLACK && miss_angular.length() < BODY_SPEED_SLACK {
                continue;
            }
            let resist = match self.secant[b] {
                None => resist[b],
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
                moved[b] = Some((step_linear, step_angular));
            }
        }
        let mut any = false;
        for c in self.carried {
            let Some((linear, angular)) = moved.get(c.body as usize).copied().flatten() else {
                continue;
            };
            let i = c.point as usize;
            let v = points.v.get(i).as_dvec3() + linear + angular.cross(c.arm.as_dvec3());
            points.v.set(i, v.as_vec3());
            any = true;
        }
        any
    }
}
