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
//! use bevy_point_springs::core::shapes::fibonacci_sphere;
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
mod springs;

pub mod cloth;

use glam::Vec3;

use crate::core::network::SpringNetwork;

use springs::SpringLayout;
pub use springs::{COINCIDENT_DISTANCE, SpringSpec};

/// Largest magnitude a coordinate or velocity component may reach before the guard treats
/// the state as runaway (squared distances must stay finite in `f32`).
pub const STATE_LIMIT: f32 = 1.0e15;

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

/// Positions, velocities or forces as three coordinate arrays.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Soa3 {
    pub x: Vec<f32>,
    pub y: Vec<f32>,
    pub z: Vec<f32>,
}

impl Soa3 {
    fn zeros(n: usize) -> Self {
        Self {
            x: vec![0.0; n],
            y: vec![0.0; n],
            z: vec![0.0; n],
        }
    }

    fn from_vec3(v: &[Vec3]) -> Self {
        Self {
            x: v.iter().map(|p| p.x).collect(),
            y: v.iter().map(|p| p.y).collect(),
            z: v.iter().map(|p| p.z).collect(),
        }
    }

    fn get(&self, i: usize) -> Vec3 {
        Vec3::new(self.x[i], self.y[i], self.z[i])
    }

    fn set(&mut self, i: usize, v: Vec3) {
        self.x[i] = v.x;
        self.y[i] = v.y;
        self.z[i] = v.z;
    }

    fn fill(&mut self, v: Vec3) {
        self.x.fill(v.x);
        self.y.fill(v.y);
        self.z.fill(v.z);
    }

    fn copy_from(&mut self, other: &Soa3) {
        self.x.copy_from_slice(&other.x);
        self.y.copy_from_slice(&other.y);
        self.z.copy_from_slice(&other.z);
    }

    fn to_vec3(&self) -> Vec<Vec3> {
        (0..self.x.len()).map(|i| self.get(i)).collect()
    }

    /// Components that are not finite or exceed [`STATE_LIMIT`] (counting keeps the loop
    /// branch-free, so it vectorises).
    fn count_insane(&self) -> usize {
        [&self.x, &self.y, &self.z]
            .iter()
            .map(|c| c.iter().map(|&v| usize::from(!sane(v))).sum::<usize>())
            .sum()
    }
}

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
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
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

/// A solver's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
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

/// Stiffness and damping for the two kinds of spring of a [`SpringNetwork`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpringMaterial {
    /// Stiffness of stretch springs (point to ring vertex).
    pub stretch_stiffness: f32,
    /// Stiffness of bend springs (ring vertex r to r + 2).
    pub bend_stiffness: f32,
    /// Damping of stretch springs.
    pub stretch_damping: f32,
    /// Damping of bend springs.
    pub bend_damping: f32,
}

impl Default for SpringMaterial {
    fn default() -> Self {
        Self {
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
    slot: u32,
    generation: u32,
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
}

impl Energy {
    /// The sum of all four.
    pub fn total(&self) -> f64 {
        self.kinetic + self.spring + self.gravity + self.anchor
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

#[derive(Debug, Clone)]
struct AnchorSlot {
    generation: u32,
    anchor: Option<Anchor>,
}

/// One deformable surface's dynamic state and the machinery to advance it.
#[derive(Debug, Clone)]
pub struct Solver {
    config: SolverConfig,
    x: Soa3,
    v: Soa3,
    /// Force accumulators: spring forces on `a` ends plus every per-point force, and spring
    /// forces on `b` ends (see `springs`).
    fa: Soa3,
    fb: Soa3,
    external: Soa3,
    mass: Vec<f32>,
    inv_mass: Vec<f32>,
    springs: SpringLayout,
    anchors: Vec<AnchorSlot>,
    free_slots: Vec<u32>,
    stability: Option<Stability>,
    /// Where explicit steps write the new state (see [`Solver::integrate`]).
    spare_x: Soa3,
    spare_v: Soa3,
    /// The state before the step, when the guard needs a copy.
    snapshot: Option<(Soa3, Soa3)>,
    implicit: implicit::Scratch,
    diagnostics: Diagnostics,
}

fn check_vector(index: usize, v: Vec3, what: &'static str) -> Result<(), SolverError> {
    if v.is_finite() && v.abs().max_element() <= STATE_LIMIT {
        Ok(())
    } else {
        Err(SolverError::InvalidVector { index, what })
    }
}

fn non_negative(v: f32) -> bool {
    v.is_finite() && v >= 0.0
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
        check_config(&config)?;
        for (i, p) in positions.iter().enumerate() {
            check_vector(i, *p, "position")?;
        }
        for (index, &mass) in masses.iter().enumerate() {
            if !(mass.is_finite() && mass > 0.0) {
                return Err(SolverError::InvalidMass { index, mass });
            }
        }
        for (spring, s) in springs.iter().enumerate() {
            if s.a == s.b || s.a as usize >= n || s.b as usize >= n {
                return Err(SolverError::InvalidSpringEnds {
                    spring,
                    a: s.a,
                    b: s.b,
                    points: n,
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
            config,
            x: Soa3::from_vec3(positions),
            v: Soa3::zeros(n),
            fa: Soa3::zeros(n),
            fb: Soa3::zeros(n),
            external: Soa3::zeros(n),
            mass: masses.to_vec(),
            inv_mass: masses.iter().map(|m| 1.0 / m).collect(),
            springs: SpringLayout::new(springs),
            anchors: Vec::new(),
            free_slots: Vec::new(),
            stability: None,
            spare_x: Soa3::zeros(n),
            spare_v: Soa3::zeros(n),
            snapshot: None,
            implicit: implicit::Scratch::default(),
            diagnostics: Diagnostics::default(),
        })
    }

    /// A solver over a [`SpringNetwork`]: its rest positions and masses, stretch and bend
    /// springs with the material's stiffness and damping.
    pub fn from_network(
        network: &SpringNetwork,
        material: &SpringMaterial,
        config: SolverConfig,
    ) -> Result<Self, SolverError> {
        let spec = |s: &crate::core::network::Spring, k: f32, kd: f32| SpringSpec {
            a: s.a,
            b: s.b,
            rest_length: s.rest_length,
            stiffness: k,
            damping: kd,
        };
        let springs: Vec<SpringSpec> = network
            .stretch
            .iter()
            .map(|s| spec(s, material.stretch_stiffness, material.stretch_damping))
            .chain(
                network
                    .bend
                    .iter()
                    .map(|s| spec(s, material.bend_stiffness, material.bend_damping)),
            )
            .collect();
        Self::new(&network.positions, &network.masses, &springs, config)
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.mass.len()
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.mass.is_empty()
    }

    /// Number of springs.
    pub fn spring_count(&self) -> usize {
        self.springs.real()
    }

    /// Springs that take the vectorised run loop (the rest take the scalar loop).
    pub fn springs_in_runs(&self) -> usize {
        self.springs.in_runs()
    }

    /// The springs, in the solver's internal order.
    pub fn springs(&self) -> impl Iterator<Item = SpringSpec> + '_ {
        (0..self.springs.len())
            .filter(|&s| !self.springs.is_padding(s))
            .map(|s| self.springs.spec(s))
    }

    /// The settings.
    pub fn config(&self) -> &SolverConfig {
        &self.config
    }

    /// Replaces the settings.
    pub fn set_config(&mut self, config: SolverConfig) -> Result<(), SolverError> {
        check_config(&config)?;
        if config.integrator != self.config.integrator {
            self.implicit = implicit::Scratch::default();
        }
        self.config = config;
        self.stability = None;
        Ok(())
    }

    /// Switches the integrator.
    pub fn set_integrator(&mut self, integrator: Integrator) {
        let config = SolverConfig {
            integrator,
            ..self.config
        };
        // Only the integrator changes: nothing to validate.
        self.config = config;
        self.implicit = implicit::Scratch::default();
    }

    /// Running totals.
    pub fn diagnostics(&self) -> &Diagnostics {
        &self.diagnostics
    }

    /// Position of point `i`.
    pub fn position(&self, i: usize) -> Vec3 {
        self.x.get(i)
    }

    /// Velocity of point `i`.
    pub fn velocity(&self, i: usize) -> Vec3 {
        self.v.get(i)
    }

    /// All positions.
    pub fn positions(&self) -> Vec<Vec3> {
        self.x.to_vec3()
    }

    /// All velocities.
    pub fn velocities(&self) -> Vec<Vec3> {
        self.v.to_vec3()
    }

    /// Positions as three coordinate slices (no copy).
    pub fn position_arrays(&self) -> [&[f32]; 3] {
        [&self.x.x, &self.x.y, &self.x.z]
    }

    /// Mass of point `i`.
    pub fn mass(&self, i: usize) -> f32 {
        self.mass[i]
    }

    fn check_index(&self, index: usize) -> Result<(), SolverError> {
        if index < self.len() {
            Ok(())
        } else {
            Err(SolverError::PointOutOfRange {
                index,
                points: self.len(),
            })
        }
    }

    /// Moves point `i` (teleport; its velocity is kept).
    pub fn set_position(&mut self, i: usize, p: Vec3) -> Result<(), SolverError> {
        self.check_index(i)?;
        check_vector(i, p, "position")?;
        self.x.set(i, p);
        Ok(())
    }

    /// Sets point `i`'s velocity. A fixed point given a velocity moves with it, unaffected by
    /// forces (a kinematic point).
    pub fn set_velocity(&mut self, i: usize, v: Vec3) -> Result<(), SolverError> {
        self.check_index(i)?;
        check_vector(i, v, "velocity")?;
        self.v.set(i, v);
        Ok(())
    }

    /// Whether point `i` is fixed.
    pub fn is_fixed(&self, i: usize) -> bool {
        self.inv_mass[i] == 0.0
    }

    /// Fixes point `i` in place (its velocity is zeroed; no force or gravity moves it) or
    /// frees it again.
    pub fn set_fixed(&mut self, i: usize, fixed: bool) -> Result<(), SolverError> {
        self.check_index(i)?;
        if fixed {
            self.inv_mass[i] = 0.0;
            self.v.set(i, Vec3::ZERO);
        } else {
            self.inv_mass[i] = 1.0 / self.mass[i];
        }
        self.stability = None;
        Ok(())
    }

    /// The external force on point `i` (what contacts fill).
    pub fn external_force(&self, i: usize) -> Vec3 {
        self.external.get(i)
    }

    /// Sets the external force on point `i`; it stays until changed.
    pub fn set_external_force(&mut self, i: usize, f: Vec3) -> Result<(), SolverError> {
        self.check_index(i)?;
        check_vector(i, f, "external force")?;
        self.external.set(i, f);
        Ok(())
    }

    /// Sets every external force to zero.
    pub fn clear_external_forces(&mut self) {
        self.external.fill(Vec3::ZERO);
    }

    fn check_anchor(&self, a: &Anchor) -> Result<(), SolverError> {
        self.check_index(a.point as usize)?;
        let bad = |what| SolverError::InvalidAnchor {
            point: a.point,
            what,
        };
        if check_vector(a.point as usize, a.target, "anchor target").is_err() {
            return Err(bad("target"));
        }
        if !non_negative(a.stiffness) {
            return Err(bad("stiffness"));
        }
        if !non_negative(a.damping) {
            return Err(bad("damping"));
        }
        Ok(())
    }

    /// Adds an anchor spring (eq 5).
    pub fn add_anchor(&mut self, anchor: Anchor) -> Result<AnchorId, SolverError> {
        self.check_anchor(&anchor)?;
        self.stability = None;
        if let Some(slot) = self.free_slots.pop() {
            let s = &mut self.anchors[slot as usize];
            s.anchor = Some(anchor);
            return Ok(AnchorId {
                slot,
                generation: s.generation,
            });
        }
        let slot = u32::try_from(self.anchors.len())
            .map_err(|_| SolverError::InvalidConfig("too many anchors"))?;
        self.anchors.push(AnchorSlot {
            generation: 0,
            anchor: Some(anchor),
        });
        Ok(AnchorId {
            slot,
            generation: 0,
        })
    }

    fn slot(&self, id: AnchorId) -> Option<&AnchorSlot> {
        self.anchors
            .get(id.slot as usize)
            .filter(|s| s.generation == id.generation && s.anchor.is_some())
    }

    /// The anchor behind `id`, if it still exists.
    pub fn anchor(&self, id: AnchorId) -> Option<&Anchor> {
        self.slot(id).and_then(|s| s.anchor.as_ref())
    }

    /// Every live anchor.
    pub fn anchors(&self) -> impl Iterator<Item = (AnchorId, &Anchor)> + '_ {
        self.anchors.iter().enumerate().filter_map(|(slot, s)| {
            s.anchor.as_ref().map(|a| {
                (
                    AnchorId {
                        slot: slot as u32,
                        generation: s.generation,
                    },
                    a,
                )
            })
        })
    }

    /// Removes an anchor, returning it.
    pub fn remove_anchor(&mut self, id: AnchorId) -> Option<Anchor> {
        self.slot(id)?;
        let s = &mut self.anchors[id.slot as usize];
        let anchor = s.anchor.take();
        s.generation = s.generation.wrapping_add(1);
        self.free_slots.push(id.slot);
        self.stability = None;
        anchor
    }

    /// Moves an anchor's target (a drag).
    pub fn set_anchor_target(&mut self, id: AnchorId, target: Vec3) -> Result<(), SolverError> {
        let point = self.anchor(id).ok_or(SolverError::UnknownAnchor)?.point;
        check_vector(point as usize, target, "anchor target").map_err(|_| {
            SolverError::InvalidAnchor {
                point,
                what: "target",
            }
        })?;
        if let Some(a) = self.anchors[id.slot as usize].anchor.as_mut() {
            a.target = target;
        }
        Ok(())
    }

    /// Replaces an anchor's settings.
    pub fn set_anchor(&mut self, id: AnchorId, anchor: Anchor) -> Result<(), SolverError> {
        self.anchor(id).ok_or(SolverError::UnknownAnchor)?;
        self.check_anchor(&anchor)?;
        self.anchors[id.slot as usize].anchor = Some(anchor);
        self.stability = None;
        Ok(())
    }

    /// Removes every anchor (handles become invalid).
    pub fn clear_anchors(&mut self) {
        let ids: Vec<AnchorId> = self.anchors().map(|(id, _)| id).collect();
        for id in ids {
            self.remove_anchor(id);
        }
    }

    fn live_anchors(&self) -> impl Iterator<Item = &Anchor> + '_ {
        self.anchors.iter().filter_map(|s| s.anchor.as_ref())
    }

    /// The stable-step estimate for the current network, masses, anchors and drag.
    pub fn stability(&mut self) -> Stability {
        if let Some(s) = self.stability {
            return s;
        }
        let s = self.estimate_stability();
        self.stability = Some(s);
        s
    }

    fn estimate_stability(&self) -> Stability {
        let n = self.len();
        let mut stiff = vec![0.0f64; n];
        let mut damp = vec![0.0f64; n];
        let mut ratio = f64::INFINITY;
        let free = |i: usize| self.inv_mass[i] > 0.0;
        for s in 0..self.springs.len() {
            let (a, b) = (self.springs.a[s] as usize, self.springs.b[s] as usize);
            let (k, kd) = (f64::from(self.springs.k[s]), f64::from(self.springs.kd[s]));
            for i in [a, b] {
                stiff[i] += 2.0 * k;
                damp[i] += 2.0 * kd;
            }
            if k > 0.0 && (free(a) || free(b)) {
                ratio = ratio.min(kd / k);
            }
        }
        for a in self.live_anchors() {
            let i = a.point as usize;
            stiff[i] += f64::from(a.stiffness);
            damp[i] += f64::from(a.damping);
            if a.stiffness > 0.0 && free(i) {
                ratio = ratio.min(f64::from(a.damping) / f64::from(a.stiffness));
            }
        }
        if self.config.damping_model == DampingModel::Axial && omega2_from(&stiff) > 0.0 {
            // Axial damping leaves motion across a spring undamped, and a stretched spring
            // resists that motion with k·(1 − l⁰/|l|): for explicit Euler those modes are
            // undamped oscillations, which only drag keeps stable.
            ratio = 0.0;
        }
        let (mut omega2, mut gamma) = (0.0f64, 0.0f64);
        for i in 0..n {
            let inv = f64::from(self.inv_mass[i]);
            omega2 = omega2.max(stiff[i] * inv);
            gamma = gamma.max(damp[i] * inv);
        }
        let drag = f64::from(self.config.drag);
        gamma += drag;
        let symplectic = if omega2 == 0.0 && gamma == 0.0 {
            f64::INFINITY
        } else {
            4.0 / (gamma + (gamma * gamma + 4.0 * omega2).sqrt())
        };
        let oscillation = if omega2 > 0.0 {
            ratio.min(f64::MAX) + drag / omega2
        } else {
            f64::INFINITY
        };
        let overdamping = if gamma > 0.0 {
            2.0 / gamma
        } else {
            f64::INFINITY
        };
        Stability {
            omega2_max: omega2 as f32,
            gamma_max: gamma as f32,
            damping_ratio_min: ratio as f32,
            symplectic_dt: symplectic as f32,
            explicit_dt: oscillation.min(overdamping) as f32,
        }
    }

    /// Sub-steps for a step of `dt` under the current policy.
    fn plan(&mut self, dt: f32) -> Result<(u32, bool), SolverError> {
        let integrator = self.config.integrator;
        if !integrator.is_explicit() || self.config.substeps == SubstepPolicy::Unchecked {
            return Ok((1, false));
        }
        let stable = self.stability().dt(integrator) * self.config.stability_margin;
        if dt <= stable {
            return Ok((1, false));
        }
        let needed = f64::from(dt) / f64::from(stable);
        match self.config.substeps {
            SubstepPolicy::Refuse => Err(SolverError::StepTooLarge {
                dt,
                stable_dt: stable,
                integrator,
            }),
            // No number of sub-steps helps: say so instead of burning them.
            SubstepPolicy::Auto { .. } if stable == 0.0 => Err(SolverError::StepTooLarge {
                dt,
                stable_dt: stable,
                integrator,
            }),
            SubstepPolicy::Auto { max_substeps } => {
                if needed > f64::from(max_substeps) {
                    Ok((max_substeps, true))
                } else {
                    Ok((needed.ceil() as u32, false))
                }
            }
            SubstepPolicy::Unchecked => Ok((1, false)),
        }
    }

    /// Advances the state by `dt` seconds.
    pub fn step(&mut self, dt: f32) -> Result<StepReport, SolverError> {
        if !(dt.is_finite() && dt >= 0.0) {
            return Err(SolverError::InvalidTimeStep(dt));
        }
        if dt == 0.0 || self.is_empty() {
            let report = StepReport {
                cg_converged: true,
                finite: true,
                ..StepReport::default()
            };
            self.diagnostics.last = report;
            return Ok(report);
        }
        let (substeps, limited) = self.plan(dt)?;
        let integrator = self.config.integrator;
        // The guard's way back: an explicit single step writes the new state beside the old
        // one and swaps, so the old state is still there (no copy); anything else copies.
        let swap_restores = integrator.is_explicit() && substeps == 1;
        if self.config.guard && !swap_restores {
            let (x, v) = self
                .snapshot
                .get_or_insert_with(|| (self.x.clone(), self.v.clone()));
            x.copy_from(&self.x);
            v.copy_from(&self.v);
        }
        let h = dt / substeps as f32;
        let mut report = StepReport {
            substeps,
            substep_dt: h,
            limited,
            cg_converged: true,
            ..StepReport::default()
        };
        let mut insane = 0;
        for _ in 0..substeps {
            insane = match integrator {
                Integrator::ExplicitEuler => {
                    self.compute_forces();
                    self.integrate::<false>(h)
                }
                Integrator::SymplecticEuler => {
                    self.compute_forces();
                    self.integrate::<true>(h)
                }
                Integrator::ImplicitEuler => {
                    let cg = self.implicit_step(h);
                    report.cg_iterations += cg.iterations;
                    report.cg_converged &= cg.converged;
                    self.x.count_insane() + self.v.count_insane()
                }
            };
        }
        report.finite = insane == 0;
        if !report.finite && self.config.guard {
            if swap_restores {
                std::mem::swap(&mut self.x, &mut self.spare_x);
                std::mem::swap(&mut self.v, &mut self.spare_v);
            } else if let Some((x, v)) = &self.snapshot {
                self.x.copy_from(x);
                self.v.copy_from(v);
            }
            self.implicit.reset_warm_start();
            report.recovered = true;
            report.finite = true;
        }
        let d = &mut self.diagnostics;
        d.steps += 1;
        d.substeps += u64::from(substeps);
        d.limited_steps += u64::from(limited);
        d.cg_iterations += u64::from(report.cg_iterations);
        d.cg_unconverged += u64::from(!report.cg_converged);
        d.guard_trips += u64::from(report.recovered);
        d.time += f64::from(dt);
        d.last = report;
        Ok(report)
    }

    /// Every force at the current state: `fa` gets m·(g − μ·v) + external + anchors + the
    /// springs' forces on their `a` ends, `fb` the springs' forces on their `b` ends.
    fn compute_forces(&mut self) {
        let g = self.config.gravity;
        let mu = self.config.drag;
        base_forces(
            &mut self.fa.x,
            &self.v.x,
            &self.external.x,
            &self.mass,
            g.x,
            mu,
        );
        base_forces(
            &mut self.fa.y,
            &self.v.y,
            &self.external.y,
            &self.mass,
            g.y,
            mu,
        );
        base_forces(
            &mut self.fa.z,
            &self.v.z,
            &self.external.z,
            &self.mass,
            g.z,
            mu,
        );
        self.fb.fill(Vec3::ZERO);
        match self.config.damping_model {
            DampingModel::Relative => {
                self.springs
                    .accumulate::<false>(&self.x, &self.v, &mut self.fa, &mut self.fb);
            }
            DampingModel::Axial => {
                self.springs
                    .accumulate::<true>(&self.x, &self.v, &mut self.fa, &mut self.fb);
            }
        }
        for slot in &self.anchors {
            let Some(a) = &slot.anchor else { continue };
            let i = a.point as usize;
            let f = a.stiffness * (a.target - self.x.get(i)) - a.damping * self.v.get(i);
            self.fa.set(i, self.fa.get(i) + f);
        }
    }

    /// One explicit step of length `h` from the forces in `fa` and `fb`: symplectic Euler
    /// (v += a·h, then x += v·h) or forward Euler (x += v·h and v += a·h from the same old
    /// state). The new state is written to the spare buffers, which then change places with
    /// the current ones. Returns the number of insane components in the new state.
    fn integrate<const SYMPLECTIC: bool>(&mut self, h: f32) -> usize {
        let inv = &self.inv_mass;
        let mut insane = 0;
        for (x, v, fa, fb, x_out, v_out) in [
            (
                &self.x.x,
                &self.v.x,
                &self.fa.x,
                &self.fb.x,
                &mut self.spare_x.x,
                &mut self.spare_v.x,
            ),
            (
                &self.x.y,
                &self.v.y,
                &self.fa.y,
                &self.fb.y,
                &mut self.spare_x.y,
                &mut self.spare_v.y,
            ),
            (
                &self.x.z,
                &self.v.z,
                &self.fa.z,
                &self.fb.z,
                &mut self.spare_x.z,
                &mut self.spare_v.z,
            ),
        ] {
            insane += pulp::Arch::new().dispatch(IntegrateAxis::<SYMPLECTIC> {
                x,
                v,
                fa,
                fb,
                inv,
                h,
                x_out,
                v_out,
            });
        }
        std::mem::swap(&mut self.x, &mut self.spare_x);
        std::mem::swap(&mut self.v, &mut self.spare_v);
        insane as usize
    }

    /// Kinetic, spring, gravitational and anchor energy of the current state.
    pub fn energy(&self) -> Energy {
        let mut e = Energy {
            spring: self.springs.energy(&self.x),
            ..Energy::default()
        };
        let g = self.config.gravity.as_dvec3();
        for i in 0..self.len() {
            if self.inv_mass[i] == 0.0 {
                continue;
            }
            let m = f64::from(self.mass[i]);
            e.kinetic += 0.5 * m * self.v.get(i).as_dvec3().length_squared();
            e.gravity -= m * g.dot(self.x.get(i).as_dvec3());
        }
        for a in self.live_anchors() {
            let d = (a.target - self.x.get(a.point as usize)).as_dvec3();
            e.anchor += 0.5 * f64::from(a.stiffness) * d.length_squared();
        }
        e
    }
}

/// [`integrate_axis`]'s arguments, handed to [`pulp`] so that the loop is compiled for the
/// widest vector unit the processor has (see the spring kernel's `Accumulate`).
struct IntegrateAxis<'a, const SYMPLECTIC: bool> {
    x: &'a [f32],
    v: &'a [f32],
    fa: &'a [f32],
    fb: &'a [f32],
    inv: &'a [f32],
    h: f32,
    x_out: &'a mut [f32],
    v_out: &'a mut [f32],
}

impl<const SYMPLECTIC: bool> pulp::WithSimd for IntegrateAxis<'_, SYMPLECTIC> {
    type Output = u32;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> u32 {
        integrate_axis::<SYMPLECTIC>(
            self.x, self.v, self.fa, self.fb, self.inv, self.h, self.x_out, self.v_out,
        )
    }
}

/// One axis of an explicit step (see [`Solver::integrate`]); counts new components that are
/// not finite or beyond [`STATE_LIMIT`] (branch-free, so the loop vectorises).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn integrate_axis<const SYMPLECTIC: bool>(
    x: &[f32],
    v: &[f32],
    fa: &[f32],
    fb: &[f32],
    inv: &[f32],
    h: f32,
    x_out: &mut [f32],
    v_out: &mut [f32],
) -> u32 {
    let n = x.len();
    let (v, fa, fb, inv) = (&v[..n], &fa[..n], &fb[..n], &inv[..n]);
    let (x_out, v_out) = (&mut x_out[..n], &mut v_out[..n]);
    let mut insane = 0u32;
    for i in 0..n {
        let dv = inv[i] * (fa[i] + fb[i]) * h;
        let vn = v[i] + dv;
        let xn = x[i] + if SYMPLECTIC { vn } else { v[i] } * h;
        v_out[i] = vn;
        x_out[i] = xn;
        insane += u32::from(!sane(xn)) + u32::from(!sane(vn));
    }
    insane
}

/// Whether a state component is finite and within [`STATE_LIMIT`] (false for NaN).
#[inline(always)]
fn sane(v: f32) -> bool {
    v.abs() <= STATE_LIMIT
}

/// One axis of m·(g − μ·v) + external.
fn base_forces(fa: &mut [f32], v: &[f32], ext: &[f32], m: &[f32], g: f32, mu: f32) {
    let n = fa.len();
    let (v, ext, m) = (&v[..n], &ext[..n], &m[..n]);
    for i in 0..n {
        fa[i] = m[i] * (g - mu * v[i]) + ext[i];
    }
}

/// Whether any point has stiffness at all (the sums are never negative).
fn omega2_from(stiff: &[f64]) -> f64 {
    stiff.iter().copied().fold(0.0, f64::max)
}

fn check_config(c: &SolverConfig) -> Result<(), SolverError> {
    if !c.gravity.is_finite() {
        return Err(SolverError::InvalidConfig("gravity must be finite"));
    }
    if !non_negative(c.drag) {
        return Err(SolverError::InvalidConfig(
            "drag must be finite and not negative",
        ));
    }
    if !(c.stability_margin > 0.0 && c.stability_margin <= 1.0) {
        return Err(SolverError::InvalidConfig(
            "the stability margin must be in (0, 1]",
        ));
    }
    if !(c.cg_tolerance > 0.0 && c.cg_tolerance < 1.0) {
        return Err(SolverError::InvalidConfig(
            "the CG tolerance must be in (0, 1)",
        ));
    }
    if c.cg_max_iterations == 0 {
        return Err(SolverError::InvalidConfig(
            "CG needs at least one iteration",
        ));
    }
    if c.substeps == (SubstepPolicy::Auto { max_substeps: 0 }) {
        return Err(SolverError::InvalidConfig("at least one sub-step per step"));
    }
    Ok(())
}
