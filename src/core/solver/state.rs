//! A solver's running state, taken out and put back: what a snapshot holds so that a run
//! restored from it continues bit for bit.

use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};

use super::parts::{Anchors, ExternalForces, Masses, PointState, Pressure, Springs};
use super::{Anchor, Diagnostics, Solver, SolverError, Stepper};

/// Everything a run changes in a [`Solver`]: positions and velocities, masses and pins,
/// every spring's rest length (plastic flow moves it), stiffness and damping (a material
/// edit moves them), every hinge's rest angle, stiffness and damping, the anchors with their
/// ids, the external forces, the gas's stiffness, and what the stepper carries between steps
/// (its running totals and the implicit solve's warm start). Not held: the settings and the springs' ends, which the surface's
/// preparation gives again ([`Solver::restore`] checks the counts).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SolverState {
    /// Positions.
    pub positions: Vec<Vec3>,
    /// Velocities.
    pub velocities: Vec<Vec3>,
    /// Masses.
    pub masses: Vec<f32>,
    /// The pinned points, ascending.
    pub pinned: Vec<u32>,
    /// Each spring's `[rest length, stiffness, damping]`, by the index it was given at.
    pub springs: Vec<[f32; 3]>,
    /// Each hinge's `[rest angle, stiffness, damping]` (plastic flow and bakes move the rest
    /// angles), in the order given (empty without hinges).
    #[serde(default)]
    pub hinges: Vec<[f32; 3]>,
    /// Each curvature-bending point's `[c̄, d̄, ē, modulus, damping]` (its rest curvature,
    /// which plastic flow and bakes move, its flexural rigidity and damping time), in the
    /// order given (empty without curvature bending).
    #[serde(default)]
    pub curvatures: Vec<[f32; 5]>,
    /// The curvature bending's rest residual heights, one per fitted neighbour (see
    /// [`Springs::curvature_rest_residuals`]; empty without curvature bending, or from a
    /// snapshot that predates them, which then keeps the surface's own).
    #[serde(default)]
    pub curvature_residuals: Vec<f32>,
    /// Every anchor slot as `(generation, anchor)`.
    pub anchor_slots: Vec<(u32, Option<Anchor>)>,
    /// The empty anchor slots, in the order they will be reused.
    pub free_anchor_slots: Vec<u32>,
    /// External forces (contacts).
    pub external: Vec<Vec3>,
    /// The gas's stiffness κ and its rest volume (which must match the restored surface's).
    pub pressure: Option<(f32, f64)>,
    /// Running totals.
    pub diagnostics: Diagnostics,
    /// The implicit solve's warm start (empty before the first implicit step).
    pub warm_start: Vec<DVec3>,
    /// The points a contact held at the end of the last implicit step, ascending (the next
    /// step's first guess of which contacts hold). Contacts handed to a step are not kept:
    /// the caller hands them in each step.
    #[serde(default)]
    pub held: Vec<u32>,
    /// The points that had a contact in the last implicit step, held or not, ascending.
    #[serde(default)]
    pub touched: Vec<u32>,
}

/// The parts of a solver a [`SolverState`] is taken from: a [`Solver`]'s, or the Bevy
/// layer's components.
#[derive(Debug, Clone, Copy)]
pub struct StateParts<'a> {
    /// Positions and velocities.
    pub points: &'a PointState,
    /// Masses and pins.
    pub masses: &'a Masses,
    /// The springs.
    pub springs: &'a Springs,
    /// The anchors.
    pub anchors: &'a Anchors,
    /// External forces.
    pub external: &'a ExternalForces,
    /// The gas, where there is one.
    pub pressure: Option<&'a Pressure>,
    /// The stepper (its running totals and warm start).
    pub stepper: &'a Stepper,
}

/// The parts of a solver a [`SolverState`] is put back into ([`SolverState::apply`]).
#[derive(Debug)]
pub struct StatePartsMut<'a> {
    /// Positions and velocities.
    pub points: &'a mut PointState,
    /// Masses and pins.
    pub masses: &'a mut Masses,
    /// The springs.
    pub springs: &'a mut Springs,
    /// The anchors.
    pub anchors: &'a mut Anchors,
    /// External forces.
    pub external: &'a mut ExternalForces,
    /// The gas, where there is one.
    pub pressure: Option<&'a mut Pressure>,
    /// The stepper.
    pub stepper: &'a mut Stepper,
}

impl Solver {
    /// The running state (see [`SolverState`]).
    pub fn state(&self) -> SolverState {
        SolverState::capture(StateParts {
            points: &self.points,
            masses: &self.masses,
            springs: &self.springs,
            anchors: &self.anchors,
            external: &self.external,
            pressure: self.pressure.as_ref(),
            stepper: &self.stepper,
        })
    }

    /// Puts `state` back: afterwards the solver steps exactly as the one `state` was taken
    /// from. A state of another surface (another count of points or springs, gas where there
    /// is none or of another rest volume) or with bad values (non-finite, a mass not
    /// positive, an index out of range) is refused with nothing changed.
    pub fn restore(&mut self, state: &SolverState) -> Result<(), SolverError> {
        state.apply(StatePartsMut {
            points: &mut self.points,
            masses: &mut self.masses,
            springs: &mut self.springs,
            anchors: &mut self.anchors,
            external: &mut self.external,
            pressure: self.pressure.as_mut(),
            stepper: &mut self.stepper,
        })
    }
}

impl SolverState {
    /// The running state of `parts`.
    pub fn capture(parts: StateParts<'_>) -> Self {
        let n = parts.points.len();
        let mut springs = vec![[0.0; 3]; parts.springs.len()];
        for (i, s) in parts.springs.iter() {
            springs[i] = [s.rest_length, s.stiffness, s.damping];
        }
        let (anchor_slots, free_anchor_slots) = parts.anchors.slots();
        let (diagnostics, warm_start, (held, touched)) = parts.stepper.carried();
        Self {
            positions: parts.points.positions(),
            velocities: parts.points.velocities(),
            masses: parts.masses.masses().to_vec(),
            pinned: (0..n)
                .filter(|&i| parts.masses.is_pinned(i))
                .map(|i| i as u32)
                .collect(),
            springs,
            hinges: parts
                .springs
                .hinges()
                .iter()
                .map(|h| [h.rest_angle, h.stiffness, h.damping])
                .collect(),
            curvatures: parts
                .springs
                .curvatures()
                .iter()
                .map(|c| [c.rest[0], c.rest[1], c.rest[2], c.modulus, c.damping])
                .collect(),
            curvature_residuals: parts.springs.curvature_rest_residuals().to_vec(),
            anchor_slots,
            free_anchor_slots,
            external: (0..parts.external.len())
                .map(|i| parts.external.get(i))
                .collect(),
            pressure: parts.pressure.map(|p| (p.stiffness, p.rest_volume())),
            diagnostics,
            warm_start,
            held,
            touched,
        }
    }

    /// Puts this state back into `parts` (see [`Solver::restore`]): refused, with nothing
    /// changed, where it does not fit them or holds bad values.
    pub fn apply(&self, parts: StatePartsMut<'_>) -> Result<(), SolverError> {
        let state = self;
        let n = parts.points.len();
        let mismatch =
            |what: &'static str, found: usize, expected: usize| SolverError::PointCountMismatch {
                what,
                expected,
                found,
            };
        for (what, found) in [
            ("snapshot positions", state.positions.len()),
            ("snapshot velocities", state.velocities.len()),
            ("snapshot masses", state.masses.len()),
            ("snapshot external forces", state.external.len()),
        ] {
            if found != n {
                return Err(mismatch(what, found, n));
            }
        }
        if state.springs.len() != parts.springs.len() {
            return Err(mismatch(
                "snapshot springs",
                state.springs.len(),
                parts.springs.len(),
            ));
        }
        let hinges = parts.springs.hinges().len();
        if state.hinges.len() != hinges {
            return Err(SolverError::InvalidConfig(
                "the snapshot's hinges do not match the surface's",
            ));
        }
        if state.curvatures.len() != parts.springs.curvature_count() {
            return Err(SolverError::InvalidConfig(
                "the snapshot's curvature bending does not match the surface's",
            ));
        }
        if !state.warm_start.is_empty() && state.warm_start.len() != n {
            return Err(mismatch("snapshot warm start", state.warm_start.len(), n));
        }
        match (&parts.pressure, state.pressure) {
            (None, None) => {}
            (Some(p), Some((_, volume))) if p.rest_volume().to_bits() == volume.to_bits() => {}
            _ => {
                return Err(SolverError::InvalidConfig(
                    "the snapshot's gas does not match the surface's",
                ));
            }
        }
        if let Some(&i) = state
            .held
            .iter()
            .chain(&state.touched)
            .find(|&&i| i as usize >= n)
        {
            return Err(SolverError::PointOutOfRange {
                index: i as usize,
                points: n,
            });
        }
        if !state.warm_start.iter().all(|d| d.is_finite()) {
            return Err(SolverError::InvalidConfig(
                "the snapshot's warm start is not finite",
            ));
        }
        // Build every part first, so that a refusal changes nothing.
        let mut points = PointState::new(&state.positions)?;
        for (i, v) in state.velocities.iter().enumerate() {
            points.set_velocity(i, *v)?;
        }
        let mut masses = Masses::new(&state.masses)?;
        for &i in &state.pinned {
            masses.set_pinned(i as usize, true)?;
        }
        let mut springs = parts.springs.clone();
        springs.set_rest_lengths(|i| state.springs[i][0])?;
        springs.set_parameters(|i| (state.springs[i][1], state.springs[i][2]))?;
        if hinges > 0 {
            springs.set_hinge_parameters(|i| state.hinges[i])?;
        }
        if !state.curvatures.is_empty() {
            springs.set_curvature_parameters(|i| state.curvatures[i])?;
        }
        if !state.curvature_residuals.is_empty() {
            springs.set_curvature_rest_residuals(&state.curvature_residuals)?;
        }
        let anchors = Anchors::from_slots(&state.anchor_slots, &state.free_anchor_slots, n)?;
        let mut external = ExternalForces::zeros(n);
        for (i, f) in state.external.iter().enumerate() {
            external.set(i, *f)?;
        }
        let stiffness = match state.pressure {
            Some((stiffness, _)) if !(stiffness.is_finite() && stiffness >= 0.0) => {
                return Err(SolverError::InvalidConfig(
                    "the snapshot's gas stiffness must be finite and not negative",
                ));
            }
            pressure => pressure.map(|(stiffness, _)| stiffness),
        };
        if let (Some(p), Some(stiffness)) = (parts.pressure, stiffness) {
            p.stiffness = stiffness;
            p.revision = super::parts::next_revision();
        }
        *parts.points = points;
        *parts.masses = masses;
        *parts.springs = springs;
        *parts.anchors = anchors;
        *parts.external = external;
        parts.stepper.set_carried(
            state.diagnostics,
            &state.warm_start,
            (&state.held, &state.touched),
        );
        Ok(())
    }
}
