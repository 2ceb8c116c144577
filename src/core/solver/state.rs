//! A solver's running state, taken out and put back: what a snapshot holds so that a run
//! restored from it continues bit for bit.

use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};

use super::parts::{Anchors, ExternalForces, Masses, PointState};
use super::{Anchor, Diagnostics, Solver, SolverError};

/// Everything a run changes in a [`Solver`]: positions and velocities, masses and pins,
/// every spring's rest length (plastic flow moves it), stiffness and damping (a material
/// edit moves them), the anchors with their ids, the external forces, the gas's stiffness,
/// and what the stepper carries between steps (its running totals and the implicit solve's
/// warm start). Not held: the settings and the springs' ends, which the surface's
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
}

impl Solver {
    /// The running state (see [`SolverState`]).
    pub fn state(&self) -> SolverState {
        let n = self.points.len();
        let mut springs = vec![[0.0; 3]; self.springs.len()];
        for (i, s) in self.springs.iter() {
            springs[i] = [s.rest_length, s.stiffness, s.damping];
        }
        let (anchor_slots, free_anchor_slots) = self.anchors.slots();
        let (diagnostics, warm_start) = self.stepper.carried();
        SolverState {
            positions: self.points.positions(),
            velocities: self.points.velocities(),
            masses: self.masses.masses().to_vec(),
            pinned: (0..n)
                .filter(|&i| self.masses.is_pinned(i))
                .map(|i| i as u32)
                .collect(),
            springs,
            anchor_slots,
            free_anchor_slots,
            external: (0..self.external.len())
                .map(|i| self.external.get(i))
                .collect(),
            pressure: self
                .pressure
                .as_ref()
                .map(|p| (p.stiffness, p.rest_volume())),
            diagnostics,
            warm_start,
        }
    }

    /// Puts `state` back: afterwards the solver steps exactly as the one `state` was taken
    /// from. A state of another surface (another count of points or springs, gas where there
    /// is none or of another rest volume) or with bad values (non-finite, a mass not
    /// positive, an index out of range) is refused with nothing changed.
    pub fn restore(&mut self, state: &SolverState) -> Result<(), SolverError> {
        let n = self.points.len();
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
        if state.springs.len() != self.springs.len() {
            return Err(mismatch(
                "snapshot springs",
                state.springs.len(),
                self.springs.len(),
            ));
        }
        if !state.warm_start.is_empty() && state.warm_start.len() != n {
            return Err(mismatch("snapshot warm start", state.warm_start.len(), n));
        }
        match (&self.pressure, state.pressure) {
            (None, None) => {}
            (Some(p), Some((_, volume))) if p.rest_volume().to_bits() == volume.to_bits() => {}
            _ => {
                return Err(SolverError::InvalidConfig(
                    "the snapshot's gas does not match the surface's",
                ));
            }
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
        let mut springs = self.springs.clone();
        springs.set_rest_lengths(|i| state.springs[i][0])?;
        springs.set_parameters(|i| (state.springs[i][1], state.springs[i][2]))?;
        let anchors = Anchors::from_slots(&state.anchor_slots, &state.free_anchor_slots, n)?;
        let mut external = ExternalForces::zeros(n);
        for (i, f) in state.external.iter().enumerate() {
            external.set(i, *f)?;
        }
        if let (Some(p), Some((stiffness, _))) = (&mut self.pressure, state.pressure) {
            if !(stiffness.is_finite() && stiffness >= 0.0) {
                return Err(SolverError::InvalidConfig(
                    "the snapshot's gas stiffness must be finite and not negative",
                ));
            }
            p.stiffness = stiffness;
            p.revision = super::parts::next_revision();
        }
        self.points = points;
        self.masses = masses;
        self.springs = springs;
        self.anchors = anchors;
        self.external = external;
        self.stepper
            .set_carried(state.diagnostics, &state.warm_start);
        Ok(())
    }
}
