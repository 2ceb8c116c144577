//! What a solver says: its typed errors, each step's report, diagnostics, energy and the
//! stability limit.

use super::*;

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
    /// A contact for the step ([`StepContact`](super::contact::StepContact)) with a number
    /// that is not finite or out of range.
    #[error("contact on point {point}: {what} is not finite, or out of range")]
    InvalidContact {
        /// The point the contact is on.
        point: usize,
        /// Which of the contact's numbers.
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
    /// A hinge names a point twice or out of range, has a bad number, or its rest shape has a
    /// triangle of (almost) no area.
    #[error("hinge {hinge}: {what}")]
    InvalidHinge {
        /// The hinge's index.
        hinge: usize,
        /// What is wrong.
        what: &'static str,
    },
    /// A point's curvature bending names points out of range, has weights or numbers that
    /// are not valid, or a fan with no area at rest.
    #[error("curvature bending {point}: {what}")]
    InvalidCurvature {
        /// The spec's index.
        point: usize,
        /// What is wrong.
        what: &'static str,
    },
    /// A triangle's coupling names springs that are not three distinct ones of the surface,
    /// or a coupling that is not finite.
    #[error("coupling of triangle {triangle}: {what}")]
    InvalidCoupling {
        /// The triangle's index among the couplings.
        triangle: usize,
        /// What is wrong.
        what: &'static str,
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
    /// A plasticity setting is negative or not finite.
    #[error("the {what} must be finite and not negative, got {value}")]
    InvalidPlasticity {
        /// Which setting.
        what: &'static str,
        /// The value given.
        value: f32,
    },
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

/// Why a step's new state was refused (the guard restored the state from before it), or
/// why a step ran above its stable step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Instability {
    /// A coordinate or velocity became non-finite or passed [`STATE_LIMIT`].
    NonFinite,
    /// A point went faster than the runaway speed ([`SolverConfig::runaway_speed`]).
    Runaway,
    /// An explicit step needed more sub-steps than [`SubstepPolicy::Auto`] allows, so it ran
    /// above its stable step (the state may still be finite).
    SubstepLimit,
}

impl Instability {
    /// What it means, in a few words.
    pub fn describe(self) -> &'static str {
        match self {
            Self::NonFinite => "the state became non-finite",
            Self::Runaway => "a point ran away (faster than the runaway speed)",
            Self::SubstepLimit => "the step needed more sub-steps than allowed",
        }
    }
}

impl std::fmt::Display for Instability {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.describe())
    }
}

/// What one [`Solver::step`] did.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct StepReport {
    /// Sub-steps taken (0 for a zero-length step).
    pub substeps: u32,
    /// Length of each sub-step.
    pub substep_dt: f32,
    /// The sub-step count hit [`SubstepPolicy::Auto`]'s cap: the step ran above the stable
    /// step.
    pub limited: bool,
    /// Conjugate-gradient iterations (implicit Euler), summed over sub-steps; with
    /// [`ImplicitSolver::LocalGlobal`](super::ImplicitSolver::LocalGlobal), its local/global
    /// iterations.
    pub cg_iterations: u32,
    /// Whether every conjugate-gradient solve reached its tolerance.
    pub cg_converged: bool,
    /// The guard found a bad state and restored the one from before the step.
    pub recovered: bool,
    /// Whether the state is finite after the step (always true with the guard on).
    pub finite: bool,
    /// Springs whose rest length crept after the step (plastic flow; 0 for an elastic
    /// material or a step taken through [`Stepper::advance`](super::Stepper::advance) alone).
    pub flowed_springs: usize,
    /// What went wrong, if anything: the guard's reason when it restored the state
    /// ([`Self::recovered`]), else [`Instability::SubstepLimit`] when [`Self::limited`].
    pub instability: Option<Instability>,
    /// The step was taken again with implicit Euler after the explicit one failed
    /// ([`InstabilityResponse::FallBackToImplicit`]); every later step is implicit too.
    pub fell_back: bool,
}

/// Running totals over a solver's life.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct Diagnostics {
    /// Steps taken.
    pub steps: u64,
    /// Sub-steps taken.
    pub substeps: u64,
    /// Steps whose sub-step count hit the cap.
    pub limited_steps: u64,
    /// Conjugate-gradient iterations (or local/global ones, see
    /// [`StepReport::cg_iterations`]).
    pub cg_iterations: u64,
    /// Implicit solves that stopped at the iteration cap.
    pub cg_unconverged: u64,
    /// Times the guard restored the state.
    pub guard_trips: u64,
    /// Simulated time, s.
    pub time: f64,
    /// The last step's report.
    pub last: StepReport,
    /// An explicit integrator failed and handed over to implicit Euler: every step since
    /// is implicit ([`InstabilityResponse::FallBackToImplicit`]).
    pub fell_back: bool,
}

/// Energies of the current state (f64 sums).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Energy {
    /// ½Σm|v|² over free points.
    pub kinetic: f64,
    /// ½Σk(|l| − l⁰)² over springs.
    pub spring: f64,
    /// Σk(θ − θ̄)² over hinges (see [`Hinges`]).
    pub bending: f64,
    /// −Σm g·x over free points (zero at the origin).
    pub gravity: f64,
    /// ½Σk_r|target − x|² over anchors.
    pub anchor: f64,
    /// The enclosed gas's (see [`Pressure`]).
    pub pressure: f64,
}

impl Energy {
    /// The sum of all six.
    pub fn total(&self) -> f64 {
        self.kinetic + self.spring + self.bending + self.gravity + self.anchor + self.pressure
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
    /// The estimate with `omega2` more squared angular frequency (1/s²), such as a gas's
    /// (the largest eigenvalues add up at most: Weyl), and the same damping; `drag` is the
    /// solver's drag rate μ.
    pub fn with_stiffness(&self, omega2: f64, drag: f64) -> Self {
        if omega2.is_nan() || omega2 <= 0.0 {
            return *self;
        }
        Self::from_rates(
            f64::from(self.omega2_max) + omega2,
            f64::from(self.gamma_max),
            f64::from(self.damping_ratio_min),
            drag,
        )
    }

    /// The estimate from its bounds: the largest squared angular frequency `omega2`, the
    /// largest damping rate `gamma` (drag included), the smallest damping ratio `ratio` and
    /// the drag rate `drag` (see the module docs of `solver`).
    pub(crate) fn from_rates(omega2: f64, gamma: f64, ratio: f64, drag: f64) -> Self {
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
        Self {
            omega2_max: omega2 as f32,
            gamma_max: gamma as f32,
            damping_ratio_min: ratio as f32,
            symplectic_dt: symplectic as f32,
            explicit_dt: oscillation.min(overdamping) as f32,
        }
    }

    /// The stable step of `integrator` (∞ for implicit Euler).
    pub fn dt(&self, integrator: Integrator) -> f32 {
        match integrator {
            Integrator::ExplicitEuler => self.explicit_dt,
            Integrator::SymplecticEuler => self.symplectic_dt,
            Integrator::ImplicitEuler => f32::INFINITY,
        }
    }
}
