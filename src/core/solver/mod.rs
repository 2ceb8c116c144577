//! Dynamics: the forces of eq 2–6 and integrators that stay stable on hard cases.
//!
//! A [`Solver`] holds one surface's state as a structure of arrays — positions, velocities,
//! forces (each as separate x, y, z arrays), masses and inverse masses — and its springs as
//! index pairs with rest length, stiffness and damping (see [`SpringSpec`]).
//!
//! **Forces.** Hooke springs (eq 2), coupled within each triangle where they are a sheet's
//! membrane ([`CouplingSpec`]); spring damping on the full relative velocity (eq 3,
//! [`DampingModel::Relative`]) or along the spring ([`DampingModel::Axial`], the form of the
//! common cloth benchmarks); gravity (eq 4) as m·g on every free point; anchor springs to world
//! points (eq 5: pins, pokes and drags, added, moved and removed while running, see
//! [`Anchor`]); viscous drag −μ·m·v; and an external force per point that contacts fill
//! ([`Solver::set_external_force`]). A spring whose endpoints coincide pushes them apart
//! along +X (its direction is undefined; see [`COINCIDENT_DISTANCE`]); zero rest lengths are
//! allowed. Fixed points ([`Solver::set_fixed`]) neither move nor feel gravity.
//!
//! **Integrators** ([`Integrator`]), chosen per solver:
//! explicit Euler (the paper's: x += v·h and v += a·h from the same old state), symplectic
//! Euler (v += a·h, then x += v·h) and implicit Euler (backward Euler linearised once per
//! step, Baraff & Witkin 1998, solved by conjugate gradient preconditioned by block
//! Jacobi, then by symmetric block Gauss–Seidel where a solve is hard, warm-started from
//! the previous step; the stiffness of compressed springs is clamped so the system stays
//! positive definite).
//!
//! **Stability.** Each explicit scheme knows its stable step ([`Solver::stability`]): with
//! ω²_max ≤ maxᵢ (2Σⱼkᵢⱼ + k_anchor)/mᵢ (Gershgorin) and γ_max ≤ maxᵢ (2Σⱼk_dᵢⱼ + k_d,anchor)/mᵢ + μ,
//! symplectic Euler needs h²ω² + 2hγ < 4, and explicit Euler, which amplifies every undamped
//! mode, needs h < γ/ω² for every mode: h < β_min + μ/ω²_max with β_min the smallest k_d/k of
//! any spring, and hγ < 2. (With [`DampingModel::Axial`] motion across a stretched spring is
//! undamped, so β_min = 0 and only drag makes explicit Euler stable: use eq 3 damping with
//! it, as the paper does.) A step longer than that is split into equal sub-steps, or refused
//! ([`SubstepPolicy`]). Implicit Euler takes any step.
//!
//! **Guard.** After each step the state is checked; a non-finite or runaway value (beyond
//! [`STATE_LIMIT`]) restores the state from before the step, and the [`StepReport`] and
//! [`Diagnostics`] say so.
//!
//! A sphere simplified to 338 simulation points, poked inward for one second:
//!
//! ```
//! use bevy_point_springs::core::network::{NetworkConfig, build_network};
//! use bevy_point_springs::core::cloud::shapes::fibonacci_sphere;
//! use bevy_point_springs::core::simplify::{SimplifyConfig, simplify};
//! use bevy_point_springs::prelude::*;
//! use bevy_point_springs::core::solver::{Anchor, Integrator, Solver, SpringMaterial};
//! use glam::Vec3;
//!
//! let dense = fibonacci_sphere(3203, 1.0);
//! let (p, n) = (dense.positions(), dense.normals().unwrap());
//! let kept = simplify(p, n, &SimplifyConfig::target(338)).unwrap();
//! let (sim_p, sim_n) = kept.gather(p, n);
//! let network = build_network(&sim_p, &sim_n, &NetworkConfig::default()).unwrap();
//! let config = SolverConfig {
//!     integrator: Integrator::ImplicitEuler,
//!     gravity: Vec3::ZERO,
//!     ..SolverConfig::default()
//! };
//! let mut solver = Solver::from_network(&network, &SpringMaterial::default(), config).unwrap();
//! // Hold the bottom, poke the top inward (eq 5), run one second at 60 Hz.
//! let height = |i: &usize| solver.position(*i).y;
//! let bottom = (0..solver.len()).min_by(|a, b| height(a).total_cmp(&height(b))).unwrap();
//! let top = (0..solver.len()).max_by(|a, b| height(a).total_cmp(&height(b))).unwrap();
//! solver.set_fixed(bottom, true).unwrap();
//! let target = solver.position(top) - Vec3::Y * 0.3;
//! let poke = solver
//!     .add_anchor(Anchor { point: top as u32, target, stiffness: 50.0, damping: 1.0 })
//!     .unwrap();
//! for _ in 0..60 {
//!     let report = solver.step(1.0 / 60.0).unwrap();
//!     assert!(report.finite);
//! }
//! solver.remove_anchor(poke);
//! assert!(solver.position(top).y < 0.9); // dented
//! assert_eq!(solver.position(bottom), network.positions[bottom]); // held
//! ```

mod config;
mod implicit;
mod parts;
mod prefactored;
mod report;
mod spring_layout;
mod state;
mod stepper;

pub mod cloth;
pub mod contact;
pub mod membrane;

use glam::Vec3;

use crate::core::network::SpringNetwork;

pub use config::{
    BendingModel, CURVATURE_POISSON_RATIO, DEFAULT_BENDING_DAMPING, DEFAULT_BENDING_MODULUS,
    DEFAULT_LOCAL_GLOBAL_ITERATIONS, DEFAULT_YIELD_ANGLE, DEFAULT_YIELD_STRAIN, DampingModel,
    HINGE_PLATE_FACTOR, HINGE_POISSON_RATIO, ImplicitSolver, InstabilityResponse, Integrator,
    MAX_LOCAL_GLOBAL_ITERATIONS, MaterialUnits, Plasticity, RUNAWAY_DIAGONALS_PER_SECOND,
    RUNAWAY_MIN_SPEED, SHEET_LATTICE_FACTOR, SolverConfig, SpringMaterial, SubstepPolicy,
    UnknownIntegrator,
};
use parts::non_negative;
pub use parts::{
    Anchors, CURVATURE_STABILISATION, CouplingSpec, CurvatureSpec, DEGENERATE_FAN,
    DEGENERATE_HEIGHT, ExternalForces, FIT_CONDITION, HingeGeometry, HingeSpec, Hinges,
    MAX_FIT_POINTS, MIN_FIT_POINTS, Masses, PointState, Pressure, Springs, WIDE_FIT_POINTS,
    angle_difference, fit_weights, hold_still,
};
pub use report::{Diagnostics, Energy, Instability, SolverError, Stability, StepReport};
pub use spring_layout::{COINCIDENT_DISTANCE, SpringSpec};
pub use state::{SolverState, StateParts, StatePartsMut};
pub use stepper::{StepParts, Stepper};

/// Largest magnitude a coordinate or velocity component may reach before the guard treats
/// the state as runaway: the coordinate limit of every input
/// ([`MAX_ABS_COORDINATE`](crate::core::cloud::MAX_ABS_COORDINATE)), so squared distances stay
/// finite in `f32`.
pub const STATE_LIMIT: f32 = crate::core::cloud::MAX_ABS_COORDINATE;

/// Default fraction of the estimated stable step that an explicit sub-step may take.
pub const DEFAULT_STABILITY_MARGIN: f32 = 0.9;

/// Default cap on sub-steps per step.
pub const DEFAULT_MAX_SUBSTEPS: u32 = 256;

/// Default relative residual at which conjugate gradient stops. An inexact solve changes
/// how a step moves, never where a surface comes to rest (at rest the right-hand side is
/// zero); on a gas-filled sphere poked and let go, 10⁻⁴ kept the shape within 6·10⁻⁵ of the
/// radius of a 10⁻⁹ solve's over four seconds, in two thirds of 10⁻⁵'s iterations
/// (docs/PERFORMANCE.md).
pub const DEFAULT_CG_TOLERANCE: f32 = 1.0e-4;

/// Default cap on conjugate-gradient iterations per implicit step.
pub const DEFAULT_CG_MAX_ITERATIONS: u32 = 300;

/// Largest number of points a solver takes (indices are 32-bit).
pub const MAX_POINTS: usize = u32::MAX as usize;

/// Standard gravity, m/s², along −Y (Bevy's up is +Y).
pub const STANDARD_GRAVITY: Vec3 = Vec3::new(0.0, -9.81, 0.0);

/// The diagonal of the bounding box of `positions` (0 for none).
pub(crate) fn rest_diagonal(positions: &[Vec3]) -> f32 {
    let (lo, hi) = positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    if positions.is_empty() {
        0.0
    } else {
        (hi - lo).length()
    }
}

/// A spring from a point to a world position (eq 5): F = k·(target − x) − k_d·v. Pins, pokes
/// and drags are anchors; move a drag with [`Solver::set_anchor_target`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Anchor {
    /// The point held.
    pub point: u32,
    /// Where it is pulled to.
    pub target: Vec3,
    /// Spring constant k_r (eq 5).
    pub stiffness: f32,
    /// Damping on the point's velocity.
    pub damping: f32,
}

/// A handle to an anchor, valid until the anchor is removed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub struct AnchorId {
    pub(crate) slot: u32,
    pub(crate) generation: u32,
}

/// One deformable surface's dynamic state and the machinery to advance it: its
/// [`PointState`], [`Masses`], [`Springs`], [`Anchors`], [`ExternalForces`] and
/// [`Stepper`], kept together. Each part is public, so a caller can also keep them apart
/// (as the Bevy layer does, one component each) and step them with the same code.
#[derive(Debug, Clone)]
pub struct Solver {
    /// Positions and velocities.
    pub points: PointState,
    /// Masses and pins.
    pub masses: Masses,
    /// Springs.
    pub springs: Springs,
    /// Anchor springs (eq 5).
    pub anchors: Anchors,
    /// Forces from outside the surface (contacts fill them); they stay until changed.
    pub external: ExternalForces,
    /// Gas inside a closed surface, if any.
    pub pressure: Option<Pressure>,
    /// Settings, force buffers and running totals.
    pub stepper: Stepper,
    /// Where the points rest ([`InstabilityResponse::ResetToRest`] puts them back there).
    rest: Vec<Vec3>,
}

impl Solver {
    /// A solver over points at `positions` (at rest) with `masses`, joined by `springs`.
    pub fn new(
        positions: &[Vec3],
        masses: &[f32],
        springs: &[SpringSpec],
        config: SolverConfig,
    ) -> Result<Self, SolverError> {
        let n = positions.len();
        if masses.len() != n {
            return Err(SolverError::LengthMismatch {
                positions: n,
                masses: masses.len(),
            });
        }
        if n > MAX_POINTS {
            return Err(SolverError::TooManyPoints(n));
        }
        let mut stepper = Stepper::new(config, n)?;
        let points = PointState::new(positions)?;
        stepper.set_rest_diagonal(rest_diagonal(positions));
        Ok(Self {
            points,
            masses: Masses::new(masses)?,
            springs: Springs::new(springs, n)?,
            anchors: Anchors::default(),
            external: ExternalForces::zeros(n),
            pressure: None,
            stepper,
            rest: positions.to_vec(),
        })
    }

    /// Where the points rest (their positions when the solver was made, or the last bake's).
    pub fn rest_positions(&self) -> &[Vec3] {
        &self.rest
    }

    /// Makes `positions` the rest positions (one per point) that
    /// [`InstabilityResponse::ResetToRest`] returns to.
    pub fn set_rest_positions(&mut self, positions: &[Vec3]) -> Result<(), SolverError> {
        if positions.len() != self.len() {
            return Err(SolverError::PointCountMismatch {
                what: "rest positions",
                expected: self.len(),
                found: positions.len(),
            });
        }
        self.rest = positions.to_vec();
        Ok(())
    }

    /// A solver over a [`SpringNetwork`]: its rest positions and masses, and the springs and
    /// hinges of the material's bending model with its stiffness and damping, and the
    /// couplings of a sheet's membrane ([`SpringMaterial::springs`],
    /// [`SpringMaterial::hinges`], [`SpringMaterial::couplings`]).
    pub fn from_network(
        network: &SpringNetwork,
        material: &SpringMaterial,
        config: SolverConfig,
    ) -> Result<Self, SolverError> {
        let mut solver = Self::new(
            &network.positions,
            &network.masses,
            &material.springs(network),
            config,
        )?;
        solver.springs.set_plasticity(material.plasticity())?;
        let hinges = material.hinges(network);
        if !hinges.is_empty() {
            solver.set_hinges(&hinges)?;
        }
        let couplings = material.couplings(network);
        if !couplings.is_empty() {
            solver.springs.set_couplings(&couplings)?;
        }
        let curvatures = material.curvatures(network);
        if !curvatures.is_empty() {
            solver
                .springs
                .set_curvatures(&curvatures, &network.positions)?;
        }
        Ok(solver)
    }

    /// Gives the surface these hinges (bending; see [`Hinges`]), their rest shape measured at
    /// the rest positions; refused, nothing changed, as [`Hinges::new`] refuses.
    pub fn set_hinges(&mut self, hinges: &[HingeSpec]) -> Result<(), SolverError> {
        let hinges = Hinges::new(hinges, &self.rest)?;
        self.springs.set_hinges(hinges);
        Ok(())
    }

    /// Number of hinges.
    pub fn hinge_count(&self) -> usize {
        self.springs.hinges().len()
    }

    /// Number of points bending on their fitted curvature.
    pub fn curvature_count(&self) -> usize {
        self.springs.curvature_count()
    }

    /// The read-only parts a step needs.
    pub fn step_parts(&self) -> StepParts<'_> {
        StepParts {
            masses: &self.masses,
            springs: &self.springs,
            anchors: &self.anchors,
            pressure: self.pressure.as_ref(),
            rest: Some(&self.rest),
        }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Number of springs.
    pub fn spring_count(&self) -> usize {
        self.springs.len()
    }

    /// Springs that take the vectorised run loop (the rest take the scalar loop).
    pub fn springs_in_runs(&self) -> usize {
        self.springs.in_runs()
    }

    /// The springs, in the solver's internal order.
    pub fn springs(&self) -> impl Iterator<Item = SpringSpec> + '_ {
        self.springs.iter().map(|(_, s)| s)
    }

    /// The settings.
    pub fn config(&self) -> &SolverConfig {
        self.stepper.config()
    }

    /// Replaces the settings.
    pub fn set_config(&mut self, config: SolverConfig) -> Result<(), SolverError> {
        self.stepper.set_config(config)
    }

    /// Switches the integrator.
    pub fn set_integrator(&mut self, integrator: Integrator) {
        let config = SolverConfig {
            integrator,
            ..*self.stepper.config()
        };
        // Only the integrator changes, and a valid config stays valid.
        let _ = self.stepper.set_config(config);
    }

    /// Running totals.
    pub fn diagnostics(&self) -> &Diagnostics {
        self.stepper.diagnostics()
    }

    /// Position of point `i`.
    pub fn position(&self, i: usize) -> Vec3 {
        self.points.position(i)
    }

    /// Velocity of point `i`.
    pub fn velocity(&self, i: usize) -> Vec3 {
        self.points.velocity(i)
    }

    /// All positions.
    pub fn positions(&self) -> Vec<Vec3> {
        self.points.positions()
    }

    /// All velocities.
    pub fn velocities(&self) -> Vec<Vec3> {
        self.points.velocities()
    }

    /// Positions as three coordinate slices (no copy).
    pub fn position_arrays(&self) -> [&[f32]; 3] {
        self.points.position_arrays()
    }

    /// Mass of point `i`.
    pub fn mass(&self, i: usize) -> f32 {
        self.masses.mass(i)
    }

    /// Moves point `i` (teleport; its velocity is kept).
    pub fn set_position(&mut self, i: usize, p: Vec3) -> Result<(), SolverError> {
        self.points.set_position(i, p)
    }

    /// Sets point `i`'s velocity. A fixed point given a velocity moves with it, unaffected by
    /// forces (a kinematic point).
    pub fn set_velocity(&mut self, i: usize, v: Vec3) -> Result<(), SolverError> {
        self.points.set_velocity(i, v)
    }

    /// Whether point `i` is fixed.
    pub fn is_fixed(&self, i: usize) -> bool {
        self.masses.is_pinned(i)
    }

    /// Fixes point `i` in place (its velocity is zeroed; no force or gravity moves it) or
    /// frees it again.
    pub fn set_fixed(&mut self, i: usize, fixed: bool) -> Result<(), SolverError> {
        self.masses.set_pinned(i, fixed)?;
        if fixed {
            self.points.set_velocity(i, Vec3::ZERO)?;
        }
        Ok(())
    }

    /// The external force on point `i` (what contacts fill).
    pub fn external_force(&self, i: usize) -> Vec3 {
        self.external.get(i)
    }

    /// Sets the external force on point `i`; it stays until changed.
    pub fn set_external_force(&mut self, i: usize, f: Vec3) -> Result<(), SolverError> {
        self.external.set(i, f)
    }

    /// Sets every external force to zero and drops the contacts.
    pub fn clear_external_forces(&mut self) {
        self.external.clear();
    }

    /// Adds a contact for the steps to solve ([`contact::StepContact`]); it stays until
    /// [`Solver::clear_external_forces`].
    pub fn add_contact(&mut self, contact: contact::StepContact) -> Result<(), SolverError> {
        self.external.add_contact(contact)
    }

    /// The impulse each contact gave its point in the last step (N·s), in the order they
    /// were added.
    pub fn contact_impulses(&self) -> &[Vec3] {
        self.stepper.contact_impulses()
    }

    /// Whether each step measures what holds the pinned points
    /// ([`Stepper::set_measure_pins`]).
    pub fn set_measure_pins(&mut self, on: bool) {
        self.stepper.set_measure_pins(on);
    }

    /// The impulse that held each pinned point in the last step (N·s; see
    /// [`Stepper::pin_impulses`]).
    pub fn pin_impulses(&self) -> &[Vec3] {
        self.stepper.pin_impulses()
    }

    /// Adds an anchor spring (eq 5).
    pub fn add_anchor(&mut self, anchor: Anchor) -> Result<AnchorId, SolverError> {
        self.anchors.add(anchor, self.points.len())
    }

    /// The anchor behind `id`, if it still exists.
    pub fn anchor(&self, id: AnchorId) -> Option<&Anchor> {
        self.anchors.get(id)
    }

    /// Every live anchor.
    pub fn anchors(&self) -> impl Iterator<Item = (AnchorId, &Anchor)> + '_ {
        self.anchors.iter()
    }

    /// Removes an anchor, returning it.
    pub fn remove_anchor(&mut self, id: AnchorId) -> Option<Anchor> {
        self.anchors.remove(id)
    }

    /// Moves an anchor's target (a drag).
    pub fn set_anchor_target(&mut self, id: AnchorId, target: Vec3) -> Result<(), SolverError> {
        self.anchors.set_target(id, target)
    }

    /// Replaces an anchor's settings.
    pub fn set_anchor(&mut self, id: AnchorId, anchor: Anchor) -> Result<(), SolverError> {
        self.anchors.set(id, anchor, self.points.len())
    }

    /// Removes every anchor (handles become invalid).
    pub fn clear_anchors(&mut self) {
        self.anchors.clear();
    }

    /// The stable-step estimate for the current network, masses, anchors and drag.
    pub fn stability(&mut self) -> Stability {
        let model = StepParts {
            masses: &self.masses,
            springs: &self.springs,
            anchors: &self.anchors,
            pressure: self.pressure.as_ref(),
            rest: Some(&self.rest),
        };
        self.stepper.stability(model)
    }

    /// Advances the state by `dt` seconds: [`Stepper::accumulate_forces`], then
    /// [`Stepper::advance`].
    pub fn step(&mut self, dt: f32) -> Result<StepReport, SolverError> {
        let model = StepParts {
            masses: &self.masses,
            springs: &self.springs,
            anchors: &self.anchors,
            pressure: self.pressure.as_ref(),
            rest: Some(&self.rest),
        };
        self.stepper.accumulate_forces(&self.points, model)?;
        let mut report = self
            .stepper
            .advance(&mut self.points, model, &self.external, dt)?;
        report.flowed_springs = self.springs.flow(&self.points, dt);
        Ok(report)
    }

    /// Kinetic, spring, gravitational and anchor energy of the current state.
    pub fn energy(&self) -> Energy {
        self.stepper.energy(&self.points, self.step_parts())
    }
}
