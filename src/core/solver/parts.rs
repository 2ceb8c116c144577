//! The pieces of a surface's dynamic state, each its own type so that a caller (the Bevy
//! layer keeps each in its own component) can read or change one without the others:
//! [`PointState`] (positions and velocities), [`Masses`] (and pins), [`Springs`],
//! [`Anchors`] (eq 5) and [`ExternalForces`]. A [`Stepper`](super::Stepper) advances them.
//!
//! Changes that alter the stable step (masses, pins, springs, anchor stiffness) give the
//! piece a new *revision*, a number unique across all pieces of the process, so that a
//! stepper knows when its stability estimate is stale without being told.

use std::sync::atomic::{AtomicU64, Ordering};

use glam::Vec3;

mod anchors;
mod couplings;
mod curvatures;
mod hinges;
mod pressure;

pub use anchors::Anchors;
pub use couplings::CouplingSpec;
pub(crate) use couplings::{COUPLED_PAIRS, CouplingBlock, Couplings};
pub use curvatures::{
    CURVATURE_STABILISATION, CurvatureSpec, DEGENERATE_FAN, FIT_CONDITION, MAX_FIT_POINTS,
    MIN_FIT_POINTS, WIDE_FIT_POINTS, fit_weights,
};
pub(crate) use curvatures::{CurvatureBlock, Curvatures};
pub(crate) use hinges::HingeBlock;
pub use hinges::{DEGENERATE_HEIGHT, HingeGeometry, HingeSpec, Hinges, angle_difference};
pub use pressure::Pressure;

use super::contact::{CarriedPoint, StepBody, StepContact};
use super::spring_layout::SpringLayout;
use super::{Anchor, AnchorId, Plasticity, STATE_LIMIT, SolverError, SpringSpec};

/// A fresh revision number (never 0, never repeated in a process).
pub(crate) fn next_revision() -> u64 {
    static NEXT: AtomicU64 = AtomicU64::new(1);
    NEXT.fetch_add(1, Ordering::Relaxed)
}

/// Whether a vector is finite and within [`STATE_LIMIT`].
pub(crate) fn check_vector(index: usize, v: Vec3, what: &'static str) -> Result<(), SolverError> {
    if v.is_finite() && v.abs().max_element() <= STATE_LIMIT {
        Ok(())
    } else {
        Err(SolverError::InvalidVector { index, what })
    }
}

/// Whether a parameter is finite and not negative.
pub(crate) fn non_negative(v: f32) -> bool {
    v.is_finite() && v >= 0.0
}

fn check_index(index: usize, points: usize) -> Result<(), SolverError> {
    if index < points {
        Ok(())
    } else {
        Err(SolverError::PointOutOfRange { index, points })
    }
}

/// Positions, velocities or forces as three coordinate arrays.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Soa3 {
    pub x: Vec<f32>,
    pub y: Vec<f32>,
    pub z: Vec<f32>,
}

impl Soa3 {
    pub fn zeros(n: usize) -> Self {
        Self {
            x: vec![0.0; n],
            y: vec![0.0; n],
            z: vec![0.0; n],
        }
    }

    pub fn from_vec3(v: &[Vec3]) -> Self {
        Self {
            x: v.iter().map(|p| p.x).collect(),
            y: v.iter().map(|p| p.y).collect(),
            z: v.iter().map(|p| p.z).collect(),
        }
    }

    pub fn len(&self) -> usize {
        self.x.len()
    }

    pub fn get(&self, i: usize) -> Vec3 {
        Vec3::new(self.x[i], self.y[i], self.z[i])
    }

    pub fn set(&mut self, i: usize, v: Vec3) {
        self.x[i] = v.x;
        self.y[i] = v.y;
        self.z[i] = v.z;
    }

    pub fn fill(&mut self, v: Vec3) {
        self.x.fill(v.x);
        self.y.fill(v.y);
        self.z.fill(v.z);
    }

    pub fn copy_from(&mut self, other: &Soa3) {
        self.x.copy_from_slice(&other.x);
        self.y.copy_from_slice(&other.y);
        self.z.copy_from_slice(&other.z);
    }

    pub fn to_vec3(&self) -> Vec<Vec3> {
        (0..self.len()).map(|i| self.get(i)).collect()
    }

    /// Components that are not finite or exceed [`STATE_LIMIT`] (counting keeps the loop
    /// branch-free, so it vectorises).
    pub fn count_insane(&self) -> usize {
        self.count_beyond(STATE_LIMIT)
    }

    /// Components that are not finite or whose magnitude passes `limit`.
    pub fn count_beyond(&self, limit: f32) -> usize {
        [&self.x, &self.y, &self.z]
            .iter()
            .map(|c| {
                c.iter()
                    .map(|&v| usize::from(!within(v, limit)))
                    .sum::<usize>()
            })
            .sum()
    }
}

/// Whether a state component is finite and within [`STATE_LIMIT`] (false for NaN).
#[inline(always)]
pub(crate) fn sane(v: f32) -> bool {
    within(v, STATE_LIMIT)
}

/// Whether `v` is finite and its magnitude at most `limit` (false for NaN).
#[inline(always)]
pub(crate) fn within(v: f32, limit: f32) -> bool {
    v.abs() <= limit
}

/// The points' positions and velocities (each stored as three coordinate arrays).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointState {
    pub(crate) x: Soa3,
    pub(crate) v: Soa3,
}

impl PointState {
    /// Points at `positions`, at rest. Every position must be finite and within
    /// [`STATE_LIMIT`].
    pub fn new(positions: &[Vec3]) -> Result<Self, SolverError> {
        for (i, p) in positions.iter().enumerate() {
            check_vector(i, *p, "position")?;
        }
        Ok(Self {
            x: Soa3::from_vec3(positions),
            v: Soa3::zeros(positions.len()),
        })
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.x.len() == 0
    }

    /// Position of point `i` (panics past the end, like a slice).
    pub fn position(&self, i: usize) -> Vec3 {
        self.x.get(i)
    }

    /// Velocity of point `i` (panics past the end, like a slice).
    pub fn velocity(&self, i: usize) -> Vec3 {
        self.v.get(i)
    }

    /// All positions, gathered.
    pub fn positions(&self) -> Vec<Vec3> {
        self.x.to_vec3()
    }

    /// All velocities, gathered.
    pub fn velocities(&self) -> Vec<Vec3> {
        self.v.to_vec3()
    }

    /// Positions as three coordinate slices (no copy).
    pub fn position_arrays(&self) -> [&[f32]; 3] {
        [&self.x.x, &self.x.y, &self.x.z]
    }

    /// Every position, in order, without gathering them into a vector first.
    pub fn iter_positions(&self) -> impl ExactSizeIterator<Item = Vec3> + '_ {
        (0..self.len()).map(|i| self.x.get(i))
    }

    /// Moves point `i` (teleport; its velocity is kept).
    pub fn set_position(&mut self, i: usize, p: Vec3) -> Result<(), SolverError> {
        check_index(i, self.len())?;
        check_vector(i, p, "position")?;
        self.x.set(i, p);
        Ok(())
    }

    /// Sets point `i`'s velocity. A pinned point given a velocity moves with it, unaffected
    /// by forces (a kinematic point).
    pub fn set_velocity(&mut self, i: usize, v: Vec3) -> Result<(), SolverError> {
        check_index(i, self.len())?;
        check_vector(i, v, "velocity")?;
        self.v.set(i, v);
        Ok(())
    }

    /// Every velocity to zero.
    pub fn stop(&mut self) {
        self.v.fill(Vec3::ZERO);
    }

    /// The fastest point's speed.
    pub fn max_speed(&self) -> f32 {
        (0..self.len())
            .map(|i| self.v.get(i).length_squared())
            .fold(0.0, f32::max)
            .sqrt()
    }
}

/// Each point's mass, and which points are pinned (held where they are: their inverse mass
/// is zero, so no force moves them).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Masses {
    pub(crate) mass: Vec<f32>,
    pub(crate) inv_mass: Vec<f32>,
    pub(crate) revision: u64,
}

impl Masses {
    /// Free points of the given masses, each positive and finite.
    pub fn new(masses: &[f32]) -> Result<Self, SolverError> {
        for (index, &mass) in masses.iter().enumerate() {
            if !(mass.is_finite() && mass > 0.0) {
                return Err(SolverError::InvalidMass { index, mass });
            }
        }
        Ok(Self {
            mass: masses.to_vec(),
            inv_mass: masses.iter().map(|m| 1.0 / m).collect(),
            revision: next_revision(),
        })
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.mass.len()
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.mass.is_empty()
    }

    /// Mass of point `i`.
    pub fn mass(&self, i: usize) -> f32 {
        self.mass[i]
    }

    /// Every mass.
    pub fn masses(&self) -> &[f32] {
        &self.mass
    }

    /// The sum of all masses.
    pub fn total(&self) -> f64 {
        self.mass.iter().map(|&m| f64::from(m)).sum()
    }

    /// Whether point `i` is pinned.
    pub fn is_pinned(&self, i: usize) -> bool {
        self.inv_mass[i] == 0.0
    }

    /// Number of pinned points.
    pub fn pinned(&self) -> usize {
        self.inv_mass.iter().filter(|&&w| w == 0.0).count()
    }

    /// Pins point `i` (no force moves it; a velocity it has carries it along, so zero it
    /// to hold the point still) or frees it again.
    pub fn set_pinned(&mut self, i: usize, pinned: bool) -> Result<(), SolverError> {
        check_index(i, self.len())?;
        self.inv_mass[i] = if pinned { 0.0 } else { 1.0 / self.mass[i] };
        self.revision = next_revision();
        Ok(())
    }
}

/// Pins the points `held` picks (by index) where they are and stops them: a pinned point
/// keeps the velocity it has, so pinning a moving point alone leaves it drifting. Returns
/// how many were pinned; an index outside either array is refused before anything changes.
pub fn hold_still(
    masses: &mut Masses,
    points: &mut PointState,
    held: impl Fn(usize) -> bool,
) -> Result<usize, SolverError> {
    let n = masses.len();
    if n > points.len() {
        return Err(SolverError::PointOutOfRange {
            index: n - 1,
            points: points.len(),
        });
    }
    let picked: Vec<usize> = (0..n).filter(|&i| held(i)).collect();
    for &i in &picked {
        masses.set_pinned(i, true)?;
        points.v.set(i, Vec3::ZERO);
    }
    Ok(picked.len())
}

/// The springs (eq 2–3), stored in the order the force kernels want (see the `spring_layout`
/// module); [`Springs::iter`] gives them back. They hold the surface's [`Hinges`] too (none
/// unless set), so that bending goes wherever the springs go, and the couplings that make
/// their stretch springs a membrane (none unless set; see [`CouplingSpec`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Springs {
    pub(crate) layout: SpringLayout,
    pub(crate) revision: u64,
    plasticity: Plasticity,
    pub(crate) hinges: Hinges,
    pub(crate) couplings: Couplings,
    pub(crate) curvatures: Curvatures,
}

impl Springs {
    /// Lays out `springs` between `points` points: endpoints distinct and in range; rest
    /// length, stiffness and damping finite and not negative.
    pub fn new(springs: &[SpringSpec], points: usize) -> Result<Self, SolverError> {
        for (spring, s) in springs.iter().enumerate() {
            if s.a == s.b || s.a as usize >= points || s.b as usize >= points {
                return Err(SolverError::InvalidSpringEnds {
                    spring,
                    a: s.a,
                    b: s.b,
                    points,
                });
            }
            for (what, value) in [
                ("rest length", s.rest_length),
                ("stiffness", s.stiffness),
                ("damping", s.damping),
            ] {
                if !non_negative(value) {
                    return Err(SolverError::InvalidSpringParameter {
                        spring,
                        what,
                        value,
                    });
                }
            }
        }
        Ok(Self {
            layout: SpringLayout::new(springs),
            revision: next_revision(),
            plasticity: Plasticity::ELASTIC,
            hinges: Hinges::default(),
            couplings: Couplings::default(),
            curvatures: Curvatures::default(),
        })
    }

    /// The couplings between the edge springs of each triangle (none unless set), their
    /// springs named by the index they were given at.
    pub fn couplings(&self) -> Vec<CouplingSpec> {
        self.couplings.iter(&self.layout).collect()
    }

    /// Replaces the couplings (refused, nothing changed, when a triangle's springs are not
    /// three distinct springs of these or a coupling is not finite).
    pub fn set_couplings(&mut self, couplings: &[CouplingSpec]) -> Result<(), SolverError> {
        self.couplings = Couplings::new(couplings, &self.layout)?;
        self.revision = next_revision();
        Ok(())
    }

    /// The curvature bending of each point that has it (none unless set; see
    /// [`CurvatureSpec`]).
    pub fn curvatures(&self) -> Vec<CurvatureSpec> {
        self.curvatures.iter().collect()
    }

    /// Replaces the curvature bending (refused, nothing changed, when a spec is bad or its
    /// fan has no area at `rest`, the points' rest positions).
    pub fn set_curvatures(
        &mut self,
        curvatures: &[CurvatureSpec],
        rest: &[Vec3],
    ) -> Result<(), SolverError> {
        self.curvatures = Curvatures::new(curvatures, rest)?;
        self.revision = next_revision();
        Ok(())
    }

    /// Number of points with curvature bending.
    pub fn curvature_count(&self) -> usize {
        self.curvatures.len()
    }

    /// Sets every curvature-bending point's rest curvature, modulus and damping from its
    /// index (`of(index)` gives `[c̄, d̄, ē, modulus, damping]`; refused, nothing changed,
    /// when one is not finite or the modulus or damping is negative).
    pub fn set_curvature_parameters(
        &mut self,
        of: impl FnMut(usize) -> [f32; 5],
    ) -> Result<(), SolverError> {
        self.curvatures.set_parameters(of)?;
        self.revision = next_revision();
        Ok(())
    }

    /// Every curvature-bending point's rest residual heights off its fitted quadric (the
    /// stabilisation's; bakes and plastic flow move them), one per fitted neighbour, point
    /// after point in the order given.
    pub fn curvature_rest_residuals(&self) -> &[f32] {
        self.curvatures.rest_residuals()
    }

    /// Sets the rest residual heights ([`Self::curvature_rest_residuals`]' layout);
    /// refused, nothing changed, when their number differs or one is not finite.
    pub fn set_curvature_rest_residuals(&mut self, residuals: &[f32]) -> Result<(), SolverError> {
        self.curvatures.set_rest_residuals(residuals)?;
        self.revision = next_revision();
        Ok(())
    }

    /// The hinges (bending; none unless set).
    pub fn hinges(&self) -> &Hinges {
        &self.hinges
    }

    /// Replaces the hinges (their points must be below the number of points the springs'
    /// owner has: [`Solver::set_hinges`](super::Solver::set_hinges) checks that).
    pub fn set_hinges(&mut self, hinges: Hinges) {
        self.hinges = hinges;
        self.revision = next_revision();
    }

    /// Sets every hinge's rest angle, stiffness and damping from its index (see
    /// [`Hinges::set_parameters`]).
    pub fn set_hinge_parameters(
        &mut self,
        of: impl FnMut(usize) -> [f32; 3],
    ) -> Result<(), SolverError> {
        self.hinges.set_parameters(of)?;
        self.revision = next_revision();
        Ok(())
    }

    /// Sets every hinge's rest angle to its angle at `points`, and every curvature-bending
    /// point's rest curvature to its curvature there (a bake; see [`Hinges::set_rest_shape`]);
    /// refused, nothing changed, where a hinge's triangle or a point's fan has collapsed.
    pub fn set_rest_angles(&mut self, points: &PointState) -> Result<(), SolverError> {
        let mut curvatures = self.curvatures.clone();
        curvatures.set_rest_shape(points)?;
        self.hinges.set_rest_shape(points)?;
        self.curvatures = curvatures;
        self.revision = next_revision();
        Ok(())
    }

    /// Number of springs.
    pub fn len(&self) -> usize {
        self.layout.real()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Springs that take the vectorised run loop (the rest take the scalar loop).
    pub fn in_runs(&self) -> usize {
        self.layout.in_runs()
    }

    /// Every spring with the index it was given at as `(index, spring)`, in storage order.
    pub fn iter(&self) -> impl Iterator<Item = (usize, SpringSpec)> + '_ {
        let l = &self.layout;
        (0..l.len())
            .filter(|&s| !l.is_padding(s))
            .map(|s| (l.order[s] as usize, l.spec(s)))
    }

    /// Sets the stiffness and damping of every spring from its index: `of(index)` gives
    /// `(stiffness, damping)`, each finite and not negative (others are refused, nothing
    /// changed).
    pub fn set_parameters(
        &mut self,
        mut of: impl FnMut(usize) -> (f32, f32),
    ) -> Result<(), SolverError> {
        let values = self.by_index(["stiffness", "damping"], |i| {
            let (k, kd) = of(i);
            [k, kd]
        })?;
        for (s, v) in values.into_iter().enumerate() {
            if let Some([k, kd]) = v {
                self.layout.k[s] = k;
                self.layout.kd[s] = kd;
            }
        }
        self.revision = next_revision();
        Ok(())
    }

    /// `of(index)` for every spring in storage order (`None` for padding), each of the `N`
    /// numbers, named by `names`, checked finite and not negative.
    fn by_index<const N: usize>(
        &self,
        names: [&'static str; N],
        mut of: impl FnMut(usize) -> [f32; N],
    ) -> Result<Vec<Option<[f32; N]>>, SolverError> {
        let l = &self.layout;
        (0..l.len())
            .map(|s| {
                if l.is_padding(s) {
                    return Ok(None);
                }
                let index = l.order[s] as usize;
                let values = of(index);
                for (what, value) in names.into_iter().zip(values) {
                    if !non_negative(value) {
                        return Err(SolverError::InvalidSpringParameter {
                            spring: index,
                            what,
                            value,
                        });
                    }
                }
                Ok(Some(values))
            })
            .collect()
    }

    /// Potential energy ½k(|l| − l⁰)² of the springs at `points`, with their couplings'
    /// (the hinges' is [`Hinges::energy`]).
    pub fn energy(&self, points: &PointState) -> f64 {
        self.layout.energy(&points.x) + self.couplings.energy(&self.layout, points)
    }

    /// Sets every spring's rest length from its index (`of(index)`, finite and not
    /// negative; others are refused, nothing changed), keeping stiffness, damping and
    /// plasticity: baking a shape.
    pub fn set_rest_lengths(
        &mut self,
        mut of: impl FnMut(usize) -> f32,
    ) -> Result<(), SolverError> {
        let values = self.by_index(["rest length"], |i| [of(i)])?;
        for (s, v) in values.into_iter().enumerate() {
            if let Some([rest]) = v {
                self.layout.rest[s] = rest;
            }
        }
        self.revision = next_revision();
        Ok(())
    }

    /// How the springs yield ([`Plasticity::ELASTIC`] unless set).
    pub fn plasticity(&self) -> Plasticity {
        self.plasticity
    }

    /// Sets how the springs yield (refused, nothing changed, when a number is negative or
    /// not finite).
    pub fn set_plasticity(&mut self, plasticity: Plasticity) -> Result<(), SolverError> {
        plasticity.validate()?;
        self.plasticity = plasticity;
        Ok(())
    }

    /// Plastic flow after a step of `dt` seconds: each spring strained beyond the yield
    /// strain moves its rest length [`Plasticity::fraction`] of the way to the length at
    /// which its strain would be the yield strain, and each hinge bent past the yield angle
    /// its rest angle likewise. Nothing happens to an elastic material. Returns how many
    /// springs and hinges flowed. (The stable-step estimate does not depend on rest lengths
    /// or angles, so it stays valid.)
    pub fn flow(&mut self, points: &PointState, dt: f32) -> usize {
        let p = self.plasticity;
        if p.is_elastic() || dt.is_nan() || dt <= 0.0 {
            return 0;
        }
        let fraction = p.fraction(dt);
        let hinges = self.hinges.flow(points, p.yield_angle, fraction)
            + self.curvatures.flow(points, p.yield_angle, fraction);
        let (x, l) = (&points.x, &mut self.layout);
        let mut flowed = 0;
        for s in 0..l.len() {
            if l.is_padding(s) {
                continue;
            }
            let (a, b) = (l.a[s] as usize, l.b[s] as usize);
            let d = Vec3::new(x.x[b] - x.x[a], x.y[b] - x.y[a], x.z[b] - x.z[a]);
            let (length, rest) = (d.length(), l.rest[s]);
            if !(length.is_finite() && rest > 0.0) {
                continue;
            }
            let strain = (length - rest) / rest;
            if strain.abs() <= p.yield_strain {
                continue;
            }
            // Compression beyond yield means yield_strain < |strain| ≤ 1, so the divisor
            // stays positive.
            let at_yield = length / (1.0 + p.yield_strain.copysign(strain));
            l.rest[s] = rest + fraction * (at_yield - rest);
            flowed += 1;
        }
        flowed + hinges
    }
}

/// A force on each point from outside the surface (contacts, wind, a game's own systems),
/// added after the surface's own forces, and the contacts to solve within the step
/// ([`StepContact`]). Both stay until changed or cleared.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ExternalForces {
    pub(crate) f: Soa3,
    /// Whether any force may be non-zero (all zero skips the pass).
    pub(crate) any: bool,
    /// Contacts the step solves with the springs.
    pub(crate) contacts: Vec<StepContact>,
    /// The bodies the contacts' and carried points' `body` indices name.
    pub(crate) bodies: Vec<StepBody>,
    /// Pinned points carried by bodies the step solves with the surface.
    pub(crate) carried: Vec<CarriedPoint>,
}

impl ExternalForces {
    /// No force on `points` points.
    pub fn zeros(points: usize) -> Self {
        Self {
            f: Soa3::zeros(points),
            any: false,
            contacts: Vec::new(),
            bodies: Vec::new(),
            carried: Vec::new(),
        }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.f.len()
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.f.len() == 0
    }

    /// The force on point `i`.
    pub fn get(&self, i: usize) -> Vec3 {
        self.f.get(i)
    }

    /// Sets the force on point `i` (finite and within [`STATE_LIMIT`]).
    pub fn set(&mut self, i: usize, f: Vec3) -> Result<(), SolverError> {
        check_index(i, self.len())?;
        check_vector(i, f, "external force")?;
        self.f.set(i, f);
        self.any = true;
        Ok(())
    }

    /// Adds `f` to the force on point `i`; the sum must stay finite and within
    /// [`STATE_LIMIT`] (otherwise nothing changes).
    pub fn add(&mut self, i: usize, f: Vec3) -> Result<(), SolverError> {
        check_index(i, self.len())?;
        self.set(i, self.f.get(i) + f)
    }

    /// Adds a contact for the step to solve ([`StepContact`]): its normal is made unit
    /// length; refused when its point is out of range or a number is not finite (or the
    /// normal is zero, or the friction negative).
    pub fn add_contact(&mut self, contact: StepContact) -> Result<(), SolverError> {
        let point = contact.point as usize;
        check_index(point, self.len())?;
        let normal = contact.normal.normalize_or_zero();
        if normal == Vec3::ZERO || !contact.normal.is_finite() {
            return Err(SolverError::InvalidVector {
                index: point,
                what: "contact normal",
            });
        }
        check_vector(point, contact.body_velocity, "contact body velocity")?;
        check_vector(point, contact.arm, "contact arm")?;
        if contact
            .body
            .is_some_and(|b| b as usize >= self.bodies.len())
        {
            return Err(SolverError::InvalidContact {
                point,
                what: "body index",
            });
        }
        if !(contact.min_speed.is_finite() && contact.min_speed.abs() <= STATE_LIMIT) {
            return Err(SolverError::InvalidContact {
                point,
                what: "least normal speed",
            });
        }
        if !non_negative(contact.friction) {
            return Err(SolverError::InvalidContact {
                point,
                what: "friction",
            });
        }
        if !(non_negative(contact.recover) && contact.recover <= STATE_LIMIT) {
            return Err(SolverError::InvalidContact {
                point,
                what: "overlap to recover",
            });
        }
        self.contacts.push(StepContact { normal, ..contact });
        Ok(())
    }

    /// The contacts the step will solve, in the order they were added.
    pub fn contacts(&self) -> &[StepContact] {
        &self.contacts
    }

    /// Adds a body the step solves with the surface ([`StepBody`]); returns its index for
    /// the contacts' `body`. Refused when a number is not finite.
    pub fn add_body(&mut self, body: StepBody) -> Result<u32, SolverError> {
        let index = u32::try_from(self.bodies.len()).map_err(|_| SolverError::InvalidContact {
            point: 0,
            what: "body count",
        })?;
        if !body.is_finite() {
            return Err(SolverError::InvalidContact {
                point: 0,
                what: "body",
            });
        }
        self.bodies.push(body);
        Ok(index)
    }

    /// The bodies the step will solve with the surface, in the order they were added.
    pub fn bodies(&self) -> &[StepBody] {
        &self.bodies
    }

    /// Adds a pinned point carried by one of the bodies ([`CarriedPoint`]): an implicit
    /// step (conjugate gradient) solves the body's velocity with the surface's and moves
    /// the point with it. Refused when the point or the body is out of range or the arm is
    /// not finite.
    pub fn add_carried(&mut self, carried: CarriedPoint) -> Result<(), SolverError> {
        let point = carried.point as usize;
        check_index(point, self.len())?;
        check_vector(point, carried.arm, "carried point's arm")?;
        if carried.body as usize >= self.bodies.len() {
            return Err(SolverError::InvalidContact {
                point,
                what: "body index",
            });
        }
        self.carried.push(carried);
        Ok(())
    }

    /// The carried points, in the order they were added.
    pub fn carried(&self) -> &[CarriedPoint] {
        &self.carried
    }

    /// Sets every force to zero and drops the contacts and their bodies.
    pub fn clear(&mut self) {
        if self.any {
            self.f.fill(Vec3::ZERO);
            self.any = false;
        }
        self.contacts.clear();
        self.bodies.clear();
        self.carried.clear();
    }

    /// Whether every force is zero and no contact is waiting (cheap when none was set
    /// since the last clear).
    pub fn is_zero(&self) -> bool {
        self.contacts.is_empty()
            && self.carried.is_empty()
            && (!self.any || (0..self.len()).all(|i| self.f.get(i) == Vec3::ZERO))
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A regular tetrahedron around the origin, faces counter-clockwise from outside.
    pub(crate) fn tetrahedron() -> (PointState, Vec<[u32; 3]>) {
        let p = [
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(1.0, -1.0, -1.0),
            Vec3::new(-1.0, 1.0, -1.0),
            Vec3::new(-1.0, -1.0, 1.0),
        ];
        let faces = vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]];
        (PointState::new(&p).unwrap(), faces)
    }

    #[test]
    fn hold_still_pins_and_stops_what_it_picks() {
        let (mut points, _) = tetrahedron();
        for i in 0..4 {
            points.set_velocity(i, Vec3::new(0.0, -0.16, 0.0)).unwrap();
        }
        let mut masses = Masses::new(&[1.0; 4]).unwrap();
        assert_eq!(hold_still(&mut masses, &mut points, |i| i < 2).unwrap(), 2);
        assert!(masses.is_pinned(0) && masses.is_pinned(1) && !masses.is_pinned(2));
        assert_eq!(points.velocity(1), Vec3::ZERO);
        assert_eq!(points.velocity(2), Vec3::new(0.0, -0.16, 0.0));
        // More masses than points: refused, nothing changed.
        let mut more = Masses::new(&[1.0; 5]).unwrap();
        assert!(matches!(
            hold_still(&mut more, &mut points, |_| true),
            Err(SolverError::PointOutOfRange {
                index: 4,
                points: 4
            })
        ));
        assert_eq!(more.pinned(), 0);
    }
}
