//! Dynamics: the forces of eq 2–6 and integrators that stay stable on hard cases.
//!
//! A [`Solver`] holds one surface's state as a structure of arrays — positions, velocities,
//! forces (each as separate x, y, z arrays), masses and inverse masses — and its springs as
//! index pairs with rest length, stiffness and damping (see [`SpringSpec`]).
//!
//! **Forces.** Hooke springs (eq 2); spring damping on the full relative velocity (eq 3,
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
//! step, Baraff & Witkin 1998, solved by conjugate gradient with a block-Jacobi
//! preconditioner, warm-started from the previous step; the stiffness of compressed springs
//! is clamped so the system stays positive definite).
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

mod implicit;
mod parts;
mod springs;
mod stepper;

pub mod contact;

use glam::Vec3;

use crate::core::network::SpringNetwork;

use parts::non_negative;
pub use parts::{Anchors, ExternalForces, Masses, PointState, Pressure, Springs, hold_still};
pub use springs::{COINCIDENT_DISTANCE, SpringSpec};
pub use stepper::{Model, Stepper};

/// Largest magnitude a coordinate or velocity component may reach before the guard treats
/// the state as runaway: the coordinate limit of every input
/// ([`MAX_ABS_COORDINATE`](crate::core::cloud::MAX_ABS_COORDINATE)), so squared distances stay
/// finite in `f32`.
pub const STATE_LIMIT: f32 = crate::core::cloud::MAX_ABS_COORDINATE;

/// Default fraction of the estimated stable step that an explicit sub-step may take.
pub const DEFAULT_STABILITY_MARGIN: f32 = 0.9;

/// Default cap on sub-steps per step.
pub const DEFAULT_MAX_SUBSTEPS: u32 = 256;

/// Default relative residual at which conjugate gradient stops.
pub const DEFAULT_CG_TOLERANCE: f32 = 1.0e-5;

/// Default cap on conjugate-gradient iterations per implicit step.
pub const DEFAULT_CG_MAX_ITERATIONS: u32 = 300;

/// Largest number of points a solver takes (indices are 32-bit).
pub const MAX_POINTS: usize = u32::MAX as usize;

/// Standard gravity, m/s², along −Y (Bevy's up is +Y).
pub const STANDARD_GRAVITY: Vec3 = Vec3::new(0.0, -9.81, 0.0);

/// How a solver advances time.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
pub enum Integrator {
    /// Forward Euler, the paper's choice: x += v·h, v += a·h, both from the old state. First
    /// order; amplifies undamped oscillation at any step, so it needs spring damping.
    ExplicitEuler,
    /// Semi-implicit Euler: v += a·h, then x += v·h. First order, symplectic: without
    /// damping its energy oscillates but does not grow (below the stable step).
    #[default]
    SymplecticEuler,
    /// Linearised backward Euler solved by preconditioned conjugate gradient. First order,
    /// stable at any step; adds numerical damping at large steps.
    ImplicitEuler,
}

impl Integrator {
    /// Every integrator.
    pub const ALL: [Integrator; 3] = [
        Self::ExplicitEuler,
        Self::SymplecticEuler,
        Self::ImplicitEuler,
    ];

    /// The name used in scene files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::ExplicitEuler => "explicit-euler",
            Self::SymplecticEuler => "symplectic-euler",
            Self::ImplicitEuler => "implicit-euler",
        }
    }

    /// Whether the scheme has a stable-step limit.
    pub fn is_explicit(self) -> bool {
        !matches!(self, Self::ImplicitEuler)
    }
}

impl std::fmt::Display for Integrator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// An integrator name that is not one of [`Integrator::ALL`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown integrator {0:?} (expected explicit-euler, symplectic-euler or implicit-euler)")]
pub struct UnknownIntegrator(pub String);

impl std::str::FromStr for Integrator {
    type Err = UnknownIntegrator;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|i| i.name() == s)
            .ok_or_else(|| UnknownIntegrator(s.to_owned()))
    }
}

/// Which velocity the spring damping acts on.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
pub enum DampingModel {
    /// The paper's eq 3: k_d·(v_b − v_a), the whole relative velocity (also damps sliding
    /// and bending motion across the spring).
    #[default]
    Relative,
    /// Along the spring only: k_d·((v_b − v_a)·l̂)·l̂, as most cloth codes do.
    Axial,
}

/// What an explicit integrator does with a step longer than its stable step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum SubstepPolicy {
    /// Split the step into equal sub-steps, at most `max_substeps`; beyond that the step is
    /// taken in `max_substeps` pieces and the report says it was limited. Where no step is
    /// stable (explicit Euler with an undamped spring and no drag) the step is refused as
    /// with [`SubstepPolicy::Refuse`].
    Auto {
        /// Cap on sub-steps per step.
        max_substeps: u32,
    },
    /// Return [`SolverError::StepTooLarge`] instead of sub-stepping.
    Refuse,
    /// Take the step as given (fixed-protocol benchmarks); the guard still watches.
    Unchecked,
}

impl Default for SubstepPolicy {
    fn default() -> Self {
        Self::Auto {
            max_substeps: DEFAULT_MAX_SUBSTEPS,
        }
    }
}

/// A solver's settings. In a scene file: `solver: (integrator: ImplicitEuler, drag: 4.0)`,
/// every field optional.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SolverConfig {
    /// Time integration scheme.
    pub integrator: Integrator,
    /// How spring damping acts.
    pub damping_model: DampingModel,
    /// Gravitational acceleration (eq 4).
    pub gravity: Vec3,
    /// Viscous drag rate μ (1/s): force −μ·m·v on every point.
    pub drag: f32,
    /// What explicit schemes do beyond their stable step.
    pub substeps: SubstepPolicy,
    /// Fraction of the estimated stable step an explicit sub-step may take, in (0, 1].
    pub stability_margin: f32,
    /// Conjugate gradient stops at this residual relative to the right-hand side.
    pub cg_tolerance: f32,
    /// Conjugate gradient iterations per implicit step, at most.
    pub cg_max_iterations: u32,
    /// Whether to check the state after each step and restore it when it went bad.
    pub guard: bool,
}

impl Default for SolverConfig {
    fn default() -> Self {
        Self {
            integrator: Integrator::default(),
            damping_model: DampingModel::default(),
            gravity: STANDARD_GRAVITY,
            drag: 0.0,
            substeps: SubstepPolicy::default(),
            stability_margin: DEFAULT_STABILITY_MARGIN,
            cg_tolerance: DEFAULT_CG_TOLERANCE,
            cg_max_iterations: DEFAULT_CG_MAX_ITERATIONS,
            guard: true,
        }
    }
}

impl SolverConfig {
    /// Checks the settings.
    pub fn validate(&self) -> Result<(), SolverError> {
        if !self.gravity.is_finite() {
            return Err(SolverError::InvalidConfig("gravity must be finite"));
        }
        if !non_negative(self.drag) {
            return Err(SolverError::InvalidConfig(
                "drag must be finite and not negative",
            ));
        }
        if !(self.stability_margin > 0.0 && self.stability_margin <= 1.0) {
            return Err(SolverError::InvalidConfig(
                "the stability margin must be in (0, 1]",
            ));
        }
        if !(self.cg_tolerance > 0.0 && self.cg_tolerance < 1.0) {
            return Err(SolverError::InvalidConfig(
                "the CG tolerance must be in (0, 1)",
            ));
        }
        if self.cg_max_iterations == 0 {
            return Err(SolverError::InvalidConfig(
                "CG needs at least one iteration",
            ));
        }
        if self.substeps == (SubstepPolicy::Auto { max_substeps: 0 }) {
            return Err(SolverError::InvalidConfig("at least one sub-step per step"));
        }
        Ok(())
    }
}

/// A surface's material: its density (the masses of eq 1) and the stiffness and damping of
/// the two kinds of spring of a [`SpringNetwork`]. In a scene file:
/// `material: (density: 1.0, stretch_stiffness: 60.0, bend_stiffness: 20.0)`, every field
/// optional.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SpringMaterial {
    /// Mass per unit area ρ (eq 1).
    pub density: f32,
    /// Stiffness of stretch springs (point to ring vertex).
    pub stretch_stiffness: f32,
    /// Stiffness of bend springs (ring vertex r to r + 2).
    pub bend_stiffness: f32,
    /// Damping of stretch springs.
    pub stretch_damping: f32,
    /// Damping of bend springs.
    pub bend_damping: f32,
}

impl SpringMaterial {
    /// The network's stretch springs, then its bend springs, with this material's
    /// stiffness and damping (the order [`Self::parameters`] numbers them in).
    pub fn springs(&self, network: &SpringNetwork) -> Vec<SpringSpec> {
        let spec = |s: &crate::core::network::Spring, k: f32, kd: f32| SpringSpec {
            a: s.a,
            b: s.b,
            rest_length: s.rest_length,
            stiffness: k,
            damping: kd,
        };
        let stretch = network
            .stretch
            .iter()
            .map(|s| spec(s, self.stretch_stiffness, self.stretch_damping));
        let bend = network
            .bend
            .iter()
            .map(|s| spec(s, self.bend_stiffness, self.bend_damping));
        stretch.chain(bend).collect()
    }

    /// Stiffness and damping of spring `index` of [`Self::springs`] on a network with
    /// `stretch` stretch springs: for [`Springs::set_parameters`] when the material
    /// changes.
    pub fn parameters(&self, index: usize, stretch: usize) -> (f32, f32) {
        if index < stretch {
            (self.stretch_stiffness, self.stretch_damping)
        } else {
            (self.bend_stiffness, self.bend_damping)
        }
    }
}

impl Default for SpringMaterial {
    fn default() -> Self {
        Self {
            density: crate::core::network::DEFAULT_DENSITY,
            stretch_stiffness: 200.0,
            bend_stiffness: 20.0,
            stretch_damping: 2.0,
            bend_damping: 0.2,
        }
    }
}

/// A spring from a point to a world position (eq 5): F = k·(target − x) − k_d·v. Pins, pokes
/// and drags are anchors; move a drag with [`Solver::set_anchor_target`].
#[derive(Debug, Clone, Copy, PartialEq)]
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
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct AnchorId {
    pub(crate) slot: u32,
    pub(crate) generation: u32,
}

/// Why a solver could not be built or stepped.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolverError {
    /// Positions and masses differ in length.
    #[error("{positions} positions but {masses} masses")]
    LengthMismatch {
        /// Number of positions.
        positions: usize,
        /// Number of masses.
        masses: usize,
    },
    /// Two parts of one surface disagree on the number of points.
    #[error("{expected} points but {found} {what}")]
    PointCountMismatch {
        /// Which part disagrees.
        what: &'static str,
        /// Number of points.
        expected: usize,
        /// The part's count.
        found: usize,
    },
    /// More points than 32-bit indices reach.
    #[error("a solver takes at most {MAX_POINTS} points, got {0}")]
    TooManyPoints(usize),
    /// A position, velocity or force is not finite (or beyond [`STATE_LIMIT`]).
    #[error("point {index}: {what} is not finite or beyond ±{STATE_LIMIT:e}")]
    InvalidVector {
        /// The point.
        index: usize,
        /// Which quantity.
        what: &'static str,
    },
    /// A mass is not positive and finite.
    #[error("point {index}: mass {mass} is not positive and finite")]
    InvalidMass {
        /// The point.
        index: usize,
        /// The mass given.
        mass: f32,
    },
    /// A point index past the end.
    #[error("point index {index} out of range ({points} points)")]
    PointOutOfRange {
        /// The index.
        index: usize,
        /// Number of points.
        points: usize,
    },
    /// A spring's endpoint is out of range or equal to the other endpoint.
    #[error("spring {spring}: endpoints {a} and {b} must be distinct points below {points}")]
    InvalidSpringEnds {
        /// The spring's index.
        spring: usize,
        /// First endpoint.
        a: u32,
        /// Second endpoint.
        b: u32,
        /// Number of points.
        points: usize,
    },
    /// A spring's rest length, stiffness or damping is negative or not finite.
    #[error("spring {spring}: {what} {value} must be finite and not negative")]
    InvalidSpringParameter {
        /// The spring's index.
        spring: usize,
        /// Which parameter.
        what: &'static str,
        /// Its value.
        value: f32,
    },
    /// An anchor's stiffness or damping is negative or not finite, or its target not finite.
    #[error("anchor on point {point}: {what} must be finite (and not negative)")]
    InvalidAnchor {
        /// The anchored point.
        point: u32,
        /// What is wrong.
        what: &'static str,
    },
    /// The anchor was removed (or belongs to another solver).
    #[error("no such anchor")]
    UnknownAnchor,
    /// A setting out of range.
    #[error("invalid solver setting: {0}")]
    InvalidConfig(&'static str),
    /// The time step is negative or not finite.
    #[error("the time step must be finite and not negative, got {0}")]
    InvalidTimeStep(f32),
    /// The step exceeds the explicit integrator's stable step and sub-stepping is off.
    #[error(
        "a step of {dt} s exceeds the stable step of {integrator} ({stable_dt:e} s){hint}; \
         take shorter steps, allow sub-steps, add damping or use implicit-euler",
        hint = if *stable_dt == 0.0 { ": explicit Euler amplifies every undamped oscillation" } else { "" }
    )]
    StepTooLarge {
        /// The step asked for.
        dt: f32,
        /// The largest stable step (with the margin).
        stable_dt: f32,
        /// The integrator.
        integrator: Integrator,
    },
}

/// What one [`Solver::step`] did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepReport {
    /// Sub-steps taken (0 for a zero-length step).
    pub substeps: u32,
    /// Length of each sub-step.
    pub substep_dt: f32,
    /// The sub-step count hit [`SubstepPolicy::Auto`]'s cap: the step ran above the stable
    /// step.
    pub limited: bool,
    /// Conjugate-gradient iterations (implicit Euler), summed over sub-steps.
    pub cg_iterations: u32,
    /// Whether every conjugate-gradient solve reached its tolerance.
    pub cg_converged: bool,
    /// The guard found a bad state and restored the one from before the step.
    pub recovered: bool,
    /// Whether the state is finite after the step (always true with the guard on).
    pub finite: bool,
}

/// Running totals over a solver's life.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Diagnostics {
    /// Steps taken.
    pub steps: u64,
    /// Sub-steps taken.
    pub substeps: u64,
    /// Steps whose sub-step count hit the cap.
    pub limited_steps: u64,
    /// Conjugate-gradient iterations.
    pub cg_iterations: u64,
    /// Implicit solves that stopped at the iteration cap.
    pub cg_unconverged: u64,
    /// Times the guard restored the state.
    pub guard_trips: u64,
    /// Simulated time, s.
    pub time: f64,
    /// The last step's report.
    pub last: StepReport,
}

/// Energies of the current state (f64 sums).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Energy {
    /// ½Σm|v|² over free points.
    pub kinetic: f64,
    /// ½Σk(|l| − l⁰)² over springs.
    pub spring: f64,
    /// −Σm g·x over free points (zero at the origin).
    pub gravity: f64,
    /// ½Σk_r|target − x|² over anchors.
    pub anchor: f64,
    /// The enclosed gas's (see [`Pressure`]).
    pub pressure: f64,
}

impl Energy {
    /// The sum of all five.
    pub fn total(&self) -> f64 {
        self.kinetic + self.spring + self.gravity + self.anchor + self.pressure
    }
}

/// The stability estimate of a solver's current network (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stability {
    /// Upper bound on the largest squared angular frequency, 1/s².
    pub omega2_max: f32,
    /// Upper bound on the largest damping rate, 1/s.
    pub gamma_max: f32,
    /// Smallest k_d/k over springs and anchors, s (∞ when there are none).
    pub damping_ratio_min: f32,
    /// Largest stable step of symplectic Euler, without the margin (∞ if unbounded).
    pub symplectic_dt: f32,
    /// Largest stable step of explicit Euler, without the margin (0 when some spring or
    /// anchor has no damping and there is no drag: no step is stable).
    pub explicit_dt: f32,
}

impl Stability {
    /// The stable step of `integrator` (∞ for implicit Euler).
    pub fn dt(&self, integrator: Integrator) -> f32 {
        match integrator {
            Integrator::ExplicitEuler => self.explicit_dt,
            Integrator::SymplecticEuler => self.symplectic_dt,
            Integrator::ImplicitEuler => f32::INFINITY,
        }
    }
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
        let stepper = Stepper::new(config, n)?;
        Ok(Self {
            points: PointState::new(positions)?,
            masses: Masses::new(masses)?,
            springs: Springs::new(springs, n)?,
            anchors: Anchors::default(),
            external: ExternalForces::zeros(n),
            pressure: None,
            stepper,
        })
    }

    /// A solver over a [`SpringNetwork`]: its rest positions and masses, stretch and bend
    /// springs with the material's stiffness and damping.
    pub fn from_network(
        network: &SpringNetwork,
        material: &SpringMaterial,
        config: SolverConfig,
    ) -> Result<Self, SolverError> {
        Self::new(
            &network.positions,
            &network.masses,
            &material.springs(network),
            config,
        )
    }

    /// The read-only parts a step needs.
    pub fn model(&self) -> Model<'_> {
        Model {
            masses: &self.masses,
            springs: &self.springs,
            anchors: &self.anchors,
            pressure: self.pressure.as_ref(),
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

    /// Sets every external force to zero.
    pub fn clear_external_forces(&mut self) {
        self.external.clear();
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
        let model = Model {
            masses: &self.masses,
            springs: &self.springs,
            anchors: &self.anchors,
            pressure: self.pressure.as_ref(),
        };
        self.stepper.stability(model)
    }

    /// Advances the state by `dt` seconds: [`Stepper::accumulate_forces`], then
    /// [`Stepper::advance`].
    pub fn step(&mut self, dt: f32) -> Result<StepReport, SolverError> {
        let model = Model {
            masses: &self.masses,
            springs: &self.springs,
            anchors: &self.anchors,
            pressure: self.pressure.as_ref(),
        };
        self.stepper.accumulate_forces(&self.points, model)?;
        self.stepper
            .advance(&mut self.points, model, &self.external, dt)
    }

    /// Kinetic, spring, gravitational and anchor energy of the current state.
    pub fn energy(&self) -> Energy {
        self.stepper.energy(&self.points, self.model())
    }
}
