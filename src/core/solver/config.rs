//! What a solver is told: the integrator, damping model, sub-stepping, and the springs'
//! material, with their checks.

use glam::Vec3;

use super::membrane::{LATTICE_POISSON_RATIO, TRIANGLE_EDGES, triangle_stiffness};

use super::*;

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
    SymplecticEuler,
    /// Linearised backward Euler solved by preconditioned conjugate gradient. First order,
    /// stable at any step; adds numerical damping at large steps. The default: a scan's
    /// network has a stable explicit step set by its lightest point and shortest springs,
    /// which at 60 Hz often needs hundreds of sub-steps (see `docs/ARCHITECTURE.md`).
    #[default]
    ImplicitEuler,
}

/// How an implicit Euler step is solved.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
pub enum ImplicitSolver {
    /// Backward Euler linearised once per step and solved by preconditioned conjugate
    /// gradient to [`SolverConfig::cg_tolerance`]. Carries everything, contacts included;
    /// its iterations grow with the network (on `point-springs-bench scale`'s poked sphere
    /// about 0.47 µs a spring at 10³ simulation points and 1.4–2.3 µs at 10⁴). The default.
    #[default]
    ConjugateGradient,
    /// Backward Euler by `iterations` local/global iterations over one matrix factorised in
    /// advance (Liu et al. 2013, as quasi-Newton: Liu, Bouaziz & Kavan 2017). Every force
    /// takes part; each iteration costs about an explicit step and one sparse solve, and the
    /// matrix is factorised again only when the step length, masses, pins, springs, bending,
    /// anchors (not their targets) or drag change: about 0.35 µs a spring at 10³ and at
    /// 10⁴ points. Not converged, a step is softer and more damped than backward Euler's
    /// in fast motion, most on stiff cloth (the matrix holds each spring's stiffness
    /// across it too, so a cloth of stiff springs falls slowly); at rest it is at the same
    /// equilibrium. Contacts are projected after the step, as the explicit integrators take
    /// them (CG holds them inside its solve). See `docs/ARCHITECTURE.md`.
    LocalGlobal {
        /// Iterations per step, 1 to [`MAX_LOCAL_GLOBAL_ITERATIONS`].
        iterations: u32,
    },
}

/// The local/global iterations a step takes unless told otherwise.
pub const DEFAULT_LOCAL_GLOBAL_ITERATIONS: u32 = 2;

/// The most local/global iterations a step may take (a step's cost grows with them and
/// nothing stops them early).
pub const MAX_LOCAL_GLOBAL_ITERATIONS: u32 = 1000;

impl ImplicitSolver {
    /// The local/global solver with [`DEFAULT_LOCAL_GLOBAL_ITERATIONS`].
    pub const LOCAL_GLOBAL: Self = Self::LocalGlobal {
        iterations: DEFAULT_LOCAL_GLOBAL_ITERATIONS,
    };

    /// The name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::ConjugateGradient => "cg",
            Self::LocalGlobal { .. } => "local-global",
        }
    }
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
    /// The paper's eq 3: k_d·(v_b − v_a), the whole relative velocity. It also damps
    /// sliding and bending motion across the spring, and rigid rotation: a free sphere
    /// spun at 1 rad/s has no spin left after 5 s (`tests/materials.rs`). Kept for the
    /// paper's method (`bench table1` and `bench report` use it) and for explicit Euler,
    /// whose damping time it sets; it also settles a surface faster where that matters
    /// more than its rigid motion.
    Relative,
    /// Along the spring only: k_d·((v_b − v_a)·l̂)·l̂, as most cloth codes do. A central
    /// force, so it leaves rigid motion alone (with implicit Euler the step also keeps the
    /// momenta, see `docs/ARCHITECTURE.md`); bending is damped by the hinges' own damping
    /// ([`SpringMaterial::bending_damping`]) or the bend springs'. With explicit Euler its
    /// stable-step estimate hands over to implicit Euler. The default (see
    /// `docs/ARCHITECTURE.md`, "Bending on hinges").
    #[default]
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

/// What a step does when its new state is bad: not finite, beyond
/// [`STATE_LIMIT`](super::STATE_LIMIT), or a point faster than the runaway speed
/// ([`SolverConfig::runaway_speed`]). In every case the state from before the step is
/// restored first (the guard), and the step's [`StepReport::instability`](super::StepReport)
/// says why.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
pub enum InstabilityResponse {
    /// An explicit integrator hands over to implicit Euler for good and takes the step
    /// again; implicit Euler itself freezes as [`Self::Freeze`] does.
    #[default]
    FallBackToImplicit,
    /// The points stop where they were before the step (velocities zeroed).
    Freeze,
    /// The points go back to their rest positions, stopped (a solver without rest positions
    /// freezes instead).
    ResetToRest,
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
    /// Gravitational acceleration (eq 4), m/s², in the world's coordinates: the plugin turns
    /// it into each surface's own coordinates, so that a surface however turned falls the
    /// world's way (unless it asks for its own frame); the core and the tool have no world,
    /// so there it is the solver's own ([`Stepper::gravity`](super::Stepper::gravity)).
    pub gravity: Vec3,
    /// Viscous drag rate μ (1/s): force −μ·m·v on every point.
    pub drag: f32,
    /// What explicit schemes do beyond their stable step.
    pub substeps: SubstepPolicy,
    /// Fraction of the estimated stable step an explicit sub-step may take, in (0, 1].
    pub stability_margin: f32,
    /// How implicit Euler steps are solved.
    pub implicit_solver: ImplicitSolver,
    /// Conjugate gradient stops at this residual relative to the right-hand side.
    pub cg_tolerance: f32,
    /// Conjugate gradient iterations per implicit step, at most.
    pub cg_max_iterations: u32,
    /// Whether to check the state after each step and restore it when it went bad.
    pub guard: bool,
    /// What the guard does after it restored a bad state.
    pub on_instability: InstabilityResponse,
    /// Speed (any velocity component, units per second) past which a point counts as run
    /// away and the guard steps in. `None`: [`RUNAWAY_DIAGONALS_PER_SECOND`] rest
    /// bounding-box diagonals per second, and at least [`RUNAWAY_MIN_SPEED`].
    pub runaway_speed: Option<f32>,
}

/// The default runaway speed, in rest bounding-box diagonals per second: a point of a unit
/// sphere past 346 m/s. Nothing a game does to a surface moves it that fast, and a network
/// gone unstable passes it within a step or two.
pub const RUNAWAY_DIAGONALS_PER_SECOND: f32 = 100.0;

/// The default runaway speed is never below this (units per second; a kilometre per second
/// in metres), so that a small surface may still fall, or be hit by a fast body.
pub const RUNAWAY_MIN_SPEED: f32 = 1000.0;

impl Default for SolverConfig {
    fn default() -> Self {
        Self {
            integrator: Integrator::default(),
            damping_model: DampingModel::default(),
            gravity: STANDARD_GRAVITY,
            drag: 0.0,
            substeps: SubstepPolicy::default(),
            stability_margin: DEFAULT_STABILITY_MARGIN,
            implicit_solver: ImplicitSolver::default(),
            cg_tolerance: DEFAULT_CG_TOLERANCE,
            cg_max_iterations: DEFAULT_CG_MAX_ITERATIONS,
            guard: true,
            on_instability: InstabilityResponse::default(),
            runaway_speed: None,
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
        if self
            .runaway_speed
            .is_some_and(|v| !(v > 0.0 && v.is_finite()))
        {
            return Err(SolverError::InvalidConfig(
                "the runaway speed must be positive and finite",
            ));
        }
        if self.cg_max_iterations == 0 {
            return Err(SolverError::InvalidConfig(
                "CG needs at least one iteration",
            ));
        }
        if let ImplicitSolver::LocalGlobal { iterations } = self.implicit_solver
            && !(1..=MAX_LOCAL_GLOBAL_ITERATIONS).contains(&iterations)
        {
            return Err(SolverError::InvalidConfig(
                "local/global steps take 1 to 1000 iterations",
            ));
        }
        if self.substeps == (SubstepPolicy::Auto { max_substeps: 0 }) {
            return Err(SolverError::InvalidConfig("at least one sub-step per step"));
        }
        Ok(())
    }
}

/// How a [`SpringMaterial`]'s stiffness and damping numbers are read.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
pub enum MaterialUnits {
    /// The paper's: every stretch spring has the stiffness `stretch_stiffness` (force per
    /// unit of length change) and the damping `stretch_damping` (force per unit of speed),
    /// every bend spring the bend ones. A finer network of the same surface has more,
    /// lighter points with the same springs, so it is a different sheet.
    #[default]
    PerSpring,
    /// A sheet's, so that a coarse and a fine network of one surface model the same sheet:
    /// - `stretch_stiffness` is the sheet's Young's modulus (force per unit width per unit
    ///   strain, N/m), with Poisson's ratio 1/3 (the only one a regular lattice of central
    ///   springs has). The network's triangles are a constant-strain membrane of it on any
    ///   triangulation: each stretch spring gets the diagonal of its triangles' stiffness
    ///   over their edges' length changes, and [`SpringMaterial::couplings`] the rest
    ///   (see [`membrane`](super::membrane)); on a regular lattice the couplings vanish and
    ///   k = √3/2·modulus. A stretch spring on no triangle gets k = 3·modulus·A/L², A an
    ///   equal share of each end's area (its mass over the density) among that end's
    ///   springs of the kind.
    /// - `bend_stiffness` is converted the same way: the modulus the bend springs alone
    ///   would give the sheet in its plane. They resist folding only through the change of
    ///   their length, so it is not a plate's flexural rigidity (`bench convergence`
    ///   measures how far that leaves the sag of a bending sheet from converging).
    /// - `stretch_damping` and `bend_damping` are damping ratios: 1 damps a spring
    ///   critically for its two ends' masses (c = ratio·2·√(k·m₁m₂/(m₁+m₂))).
    Sheet,
}

/// How a surface resists bending.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
pub enum BendingModel {
    /// The paper's bend springs (§4.2): a central spring from ring vertex r to r + 2. It
    /// resists folding only through the change of its length, which is of second order in
    /// the fold angle on flat ground, so finer networks are softer shells; the springs also
    /// stiffen the sheet in its plane. Kept so that the paper's method stays reproducible.
    Springs,
    /// A hinge at every inner edge of the network's mesh (discrete shells, see
    /// [`Hinges`]) with the energy E = k·(θ − θ̄)², k = `bending_modulus`·3|ē|²/(6·Ā) (Ā the
    /// two triangles' rest area): a plate of flexural rigidity `bending_modulus` (N·m) with
    /// the Poisson's ratio [`HINGE_POISSON_RATIO`], on any network spacing. No bend springs:
    /// the stretch springs alone carry the sheet in its plane. On §3's uneven networks it
    /// depends on how the mesh was cut (coarse spheres 8–12 % stiff in `point-springs-bench
    /// convergence`); a tick costs about 0.9 times one on [`Self::Curvature`].
    Hinges,
    /// Each point's curvature, from a quadric fitted to its neighbours (see
    /// [`CurvatureSpec`]), bears a plate's energy ½·D·A·(ν·(tr ΔS)² + (1 − ν)·ΔS:ΔS) of
    /// flexural rigidity `bending_modulus` (N·m) and Poisson's ratio
    /// [`CURVATURE_POISSON_RATIO`], with `bending_damping` as the hinges'. Unlike hinges it
    /// does not depend on how §3 cuts the mesh: a pinned plate on uneven networks sags as
    /// Navier's series says to within 0.5 % at 740 points (hinges: 14–26 % stiff), and
    /// every problem of `point-springs-bench convergence` is within 5 % of its finest level
    /// from 5 % of the points. No bend springs. The default (see `docs/ARCHITECTURE.md`,
    /// "Bending on each point's fitted curvature").
    #[default]
    Curvature,
}

/// The Poisson's ratio of [`BendingModel::Curvature`]: the membrane's (see
/// [`LATTICE_POISSON_RATIO`](super::membrane::LATTICE_POISSON_RATIO)).
pub const CURVATURE_POISSON_RATIO: f32 = 1.0 / 3.0;

/// The 6 of k = D·3|ē|²/(6·Ā) ([`BendingModel::Hinges`]). On a regular triangle lattice bent
/// to principal curvatures κ₁ and κ₂, Σ 3|ē|²/Ā·θ² over the hinges of a unit of area is
/// 3κ₁² + 3κ₂² − 2κ₁κ₂ (measured on lattices of 8100 points to 1 %; the lattice's three-fold
/// symmetry makes it the same in every direction), and a plate of flexural rigidity D and
/// Poisson's ratio ν stores D/2·(κ₁² + κ₂² + 2ν·κ₁κ₂): the hinges are that plate with
/// ν = −1/3. Bent one way only (κ₂ = 0, a wide sheet) it stores D/2·κ², as a plate does; a
/// narrow strip, free to curl across, bends as a beam of rigidity D·(1 − ν²) = 8D/9 per unit
/// width.
pub const HINGE_PLATE_FACTOR: f32 = 6.0;

/// The Poisson's ratio of bending on hinges (see [`HINGE_PLATE_FACTOR`]).
pub const HINGE_POISSON_RATIO: f32 = -1.0 / 3.0;

/// A surface's material: its density (the masses of eq 1), the stiffness and damping of
/// the two kinds of spring of a [`SpringNetwork`], per spring or as a sheet's moduli (see
/// [`MaterialUnits`]), and how it bends ([`BendingModel`]). In a scene file:
/// `material: (density: 1.0, stretch_stiffness: 60.0, bend_stiffness: 20.0)`, or
/// `material: (units: Sheet, stretch_stiffness: 200.0, stretch_damping: 0.1)`, or
/// `material: (units: Sheet, stretch_stiffness: 70.0, bending: Hinges, bending_modulus: 0.3)`,
/// every field optional.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SpringMaterial {
    /// Mass per unit area ρ (eq 1).
    pub density: f32,
    /// How the four numbers below are read: per spring (the paper's) or as a sheet's
    /// moduli and damping ratios.
    pub units: MaterialUnits,
    /// Stiffness of stretch springs (point to ring vertex), or the sheet's Young's modulus.
    pub stretch_stiffness: f32,
    /// Stiffness of bend springs (ring vertex r to r + 2), or their modulus.
    pub bend_stiffness: f32,
    /// Damping of stretch springs, or their damping ratio.
    pub stretch_damping: f32,
    /// Damping of bend springs, or their damping ratio.
    pub bend_damping: f32,
    /// How the surface resists bending: the paper's bend springs, or hinges.
    pub bending: BendingModel,
    /// The flexural rigidity D of [`BendingModel::Hinges`], N·m (for a solid sheet of
    /// Young's modulus E, thickness t and Poisson's ratio ν, D = E·t³/(12·(1 − ν²))).
    pub bending_modulus: f32,
    /// The hinges' damping as a time β (seconds): each dissipates ½·β·2k·θ̇², so a bending
    /// mode of angular frequency ω is damped at the ratio β·ω/2.
    pub bending_damping: f32,
    /// Plasticity: the strain (stretch or compression, relative to the rest length) a spring
    /// bears elastically; beyond it the rest length creeps (see [`Self::creep_rate`]).
    pub yield_strain: f32,
    /// Plasticity: the bend (radians past the rest angle) a hinge bears elastically; beyond
    /// it the rest angle creeps at [`Self::creep_rate`].
    pub yield_angle: f32,
    /// Plasticity: how fast a spring strained beyond [`Self::yield_strain`] takes the excess as
    /// its new rest length, per second (its excess decays as e^(−rate·t)). 0, the default,
    /// keeps the material elastic.
    pub creep_rate: f32,
}

impl SpringMaterial {
    /// Checks every number: the density positive and finite, stiffness and damping finite
    /// and not negative, the plasticity valid. The error names the field.
    pub fn check(&self) -> Result<(), String> {
        if !(self.density > 0.0 && self.density.is_finite()) {
            return Err("material.density must be positive and finite".to_owned());
        }
        for (name, v) in [
            ("stretch_stiffness", self.stretch_stiffness),
            ("bend_stiffness", self.bend_stiffness),
            ("stretch_damping", self.stretch_damping),
            ("bend_damping", self.bend_damping),
            ("bending_modulus", self.bending_modulus),
            ("bending_damping", self.bending_damping),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!(
                    "material.{name} must be finite and not negative, got {v}"
                ));
            }
        }
        self.plasticity()
            .validate()
            .map_err(|e| format!("material: {e}"))
    }

    /// The material's plastic behaviour.
    pub fn plasticity(&self) -> Plasticity {
        Plasticity {
            yield_strain: self.yield_strain,
            yield_angle: self.yield_angle,
            creep_rate: self.creep_rate,
        }
    }

    /// The network's hinges with this material's stiffness and damping, their rest angles
    /// measured on the network's rest shape: one at every inner edge
    /// ([`SpringNetwork::hinge_stencils`]) with [`BendingModel::Hinges`], none with
    /// [`BendingModel::Springs`].
    pub fn hinges(&self, network: &SpringNetwork) -> Vec<HingeSpec> {
        if self.bending != BendingModel::Hinges {
            return Vec::new();
        }
        let at = |i: u32| network.positions[i as usize];
        network
            .hinge_stencils()
            .into_iter()
            .map(|[p0, p1, w1, w2]| {
                let (e, a1, a2) = (at(p1) - at(p0), at(w1) - at(p0), at(w2) - at(p0));
                // Twice the two triangles' area.
                let area2 = e.cross(a1).length() + a2.cross(e).length();
                let weight = if area2 > 0.0 {
                    3.0 * e.length_squared() / (0.5 * area2)
                } else {
                    0.0
                };
                let stiffness = self.bending_modulus * weight / HINGE_PLATE_FACTOR;
                let rest_angle =
                    HingeGeometry::at([at(p0), at(p1), at(w1), at(w2)]).map_or(0.0, |g| g.angle);
                HingeSpec {
                    edge: [p0, p1],
                    wings: [w1, w2],
                    rest_angle,
                    stiffness,
                    damping: self.bending_damping * 2.0 * stiffness,
                }
            })
            .collect()
    }

    /// The network's curvature bending with this material's modulus and damping
    /// ([`BendingModel::Curvature`]; none with another model): one at every point whose ring
    /// gives a normal and a fit, fitted to its ring, or where the ring has fewer than
    /// [`MIN_FIT_POINTS`] or admits no fit, to its ring and the nearest of its ring's rings'
    /// points, [`WIDE_FIT_POINTS`] in all (to all of them if those admit none; never more
    /// than the nearest [`MAX_FIT_POINTS`]). A point with none bears none.
    pub fn curvatures(&self, network: &SpringNetwork) -> Vec<CurvatureSpec> {
        if self.bending != BendingModel::Curvature {
            return Vec::new();
        }
        let areas = network.point_areas();
        let offsets = &network.ring_offsets;
        let ring = |i: usize| -> &[u32] {
            match (offsets.get(i), offsets.get(i + 1)) {
                (Some(&a), Some(&b)) => network
                    .ring_indices
                    .get(a as usize..b as usize)
                    .unwrap_or(&[]),
                _ => &[],
            }
        };
        (0..network.len())
            .filter_map(|i| {
                let fan = ring(i).to_vec();
                let wider = || {
                    let mut fit = fan.clone();
                    for &j in &fan {
                        for &k in ring(j as usize) {
                            if k as usize != i && !fit.contains(&k) {
                                fit.push(k);
                            }
                        }
                    }
                    fit
                };
                let centre = network.positions[i];
                let distance = |j: &u32| network.positions[*j as usize].distance_squared(centre);
                let spec = |mut fit: Vec<u32>| {
                    if fit.len() > MAX_FIT_POINTS {
                        fit.sort_by(|a, b| distance(a).total_cmp(&distance(b)));
                        fit.truncate(MAX_FIT_POINTS);
                    }
                    CurvatureSpec {
                        point: i as u32,
                        fan: fan.clone(),
                        closed: !network.boundary.get(i).copied().unwrap_or(true),
                        fit,
                        weights: Vec::new(),
                        rest: [0.0; 3],
                        area: areas.get(i).copied().unwrap_or(0.0),
                        modulus: self.bending_modulus,
                        poisson: CURVATURE_POISSON_RATIO,
                        damping: self.bending_damping,
                    }
                    .measured(&network.positions)
                };
                // The ring, then the nearest of its rings' points: WIDE_FIT_POINTS in all.
                let nearest = || {
                    let mut fit = wider();
                    fit[fan.len()..].sort_by(|a, b| distance(a).total_cmp(&distance(b)));
                    fit.truncate(WIDE_FIT_POINTS.max(fan.len()));
                    fit
                };
                if fan.len() >= MIN_FIT_POINTS {
                    spec(fan.clone())
                        .or_else(|| spec(nearest()))
                        .or_else(|| spec(wider()))
                } else {
                    spec(nearest()).or_else(|| spec(wider()))
                }
            })
            .collect()
    }

    /// The network's stretch springs, then its bend springs (none with
    /// [`BendingModel::Hinges`]), with this material's stiffness and damping (per spring, or
    /// converted from the sheet's moduli and damping ratios on the network's geometry: see
    /// [`MaterialUnits`]).
    pub fn springs(&self, network: &SpringNetwork) -> Vec<SpringSpec> {
        let no_bend = Vec::new();
        let bend = match self.bending {
            BendingModel::Springs => &network.bend,
            BendingModel::Hinges | BendingModel::Curvature => &no_bend,
        };
        let spec =
            |s: &crate::core::network::Spring, (stiffness, damping): (f32, f32)| SpringSpec {
                a: s.a,
                b: s.b,
                rest_length: s.rest_length,
                stiffness,
                damping,
            };
        match self.units {
            MaterialUnits::PerSpring => {
                let stretch = (self.stretch_stiffness, self.stretch_damping);
                let bend_kd = (self.bend_stiffness, self.bend_damping);
                let stretch = network.stretch.iter().map(|s| spec(s, stretch));
                let bend = bend.iter().map(|s| spec(s, bend_kd));
                stretch.chain(bend).collect()
            }
            MaterialUnits::Sheet => {
                let areas = network.point_areas();
                let mut out = Vec::with_capacity(network.stretch.len() + bend.len());
                for (springs, modulus, ratio) in [
                    (
                        &network.stretch,
                        self.stretch_stiffness,
                        self.stretch_damping,
                    ),
                    (bend, self.bend_stiffness, self.bend_damping),
                ] {
                    let mut degree = vec![0u32; network.len()];
                    for s in springs.iter() {
                        degree[s.a as usize] += 1;
                        degree[s.b as usize] += 1;
                    }
                    // The stretch springs on triangles: the membrane's diagonal.
                    let membrane = if std::ptr::eq(springs, &network.stretch) {
                        self.membrane(network).0
                    } else {
                        Vec::new()
                    };
                    out.extend(springs.iter().enumerate().map(|(i, s)| {
                        let (a, b) = (s.a as usize, s.b as usize);
                        let share = areas[a] / degree[a] as f32 + areas[b] / degree[b] as f32;
                        let k = match membrane.get(i) {
                            Some(&k) if k.is_finite() => k,
                            _ => {
                                SHEET_LATTICE_FACTOR * modulus * share
                                    / (s.rest_length * s.rest_length)
                            }
                        };
                        let (ma, mb) = (network.masses[a], network.masses[b]);
                        let reduced = ma * mb / (ma + mb);
                        spec(s, (k, ratio * 2.0 * (k * reduced).sqrt()))
                    }));
                }
                out
            }
        }
    }
}

impl SpringMaterial {
    /// The couplings between the stretch springs of each of the network's triangles that
    /// make them, with their stiffness from [`Self::springs`], a constant-strain membrane of
    /// the sheet's modulus (Poisson's ratio [`LATTICE_POISSON_RATIO`]; see
    /// [`CouplingSpec`]): with [`MaterialUnits::Sheet`], none per spring. Springs are named
    /// by their index in [`Self::springs`]. A triangle of (almost) no area, or one with an
    /// edge that has no stretch spring, carries none.
    pub fn couplings(&self, network: &SpringNetwork) -> Vec<CouplingSpec> {
        match self.units {
            MaterialUnits::PerSpring => Vec::new(),
            MaterialUnits::Sheet => self.membrane(network).1,
        }
    }

    /// The membrane on the network's triangles: each stretch spring's stiffness, the sum
    /// of its triangles' diagonal entries (NaN for a spring on no triangle), and the
    /// triangles' couplings.
    fn membrane(&self, network: &SpringNetwork) -> (Vec<f32>, Vec<CouplingSpec>) {
        use std::collections::HashMap;
        let key = |a: u32, b: u32| (a.min(b), a.max(b));
        let index: HashMap<(u32, u32), u32> = network
            .stretch
            .iter()
            .enumerate()
            .map(|(i, s)| (key(s.a, s.b), i as u32))
            .collect();
        let mut k = vec![f32::NAN; network.stretch.len()];
        let mut couplings = Vec::new();
        for t in &network.triangles {
            let Some(springs) = TRIANGLE_EDGES
                .iter()
                .map(|&(i, j)| index.get(&key(t[i], t[j])).copied())
                .collect::<Option<Vec<u32>>>()
            else {
                continue;
            };
            let corners = t.map(|i| network.positions[i as usize]);
            let Some(form) =
                triangle_stiffness(corners, self.stretch_stiffness, LATTICE_POISSON_RATIO)
            else {
                continue;
            };
            for (e, &s) in springs.iter().enumerate() {
                let entry = &mut k[s as usize];
                *entry = if entry.is_nan() { 0.0 } else { *entry } + form[e][e];
            }
            couplings.push(CouplingSpec {
                springs: [springs[0], springs[1], springs[2]],
                coupling: [form[0][1], form[1][2], form[2][0]],
            });
        }
        (k, couplings)
    }
}

/// The 3 of k = 3·modulus·A/L² ([`MaterialUnits::Sheet`]): a regular triangle lattice of
/// springs k and spacing h has the Young's modulus 2k/√3 (with Poisson's ratio 1/3), and each
/// of its springs stands for the area h²/(2√3), so k = 3·E·A/L² is that same relation.
pub const SHEET_LATTICE_FACTOR: f32 = 3.0;

impl Default for SpringMaterial {
    fn default() -> Self {
        Self {
            density: crate::core::network::DEFAULT_DENSITY,
            units: MaterialUnits::PerSpring,
            stretch_stiffness: 200.0,
            bend_stiffness: 20.0,
            stretch_damping: 2.0,
            bend_damping: 0.2,
            bending: BendingModel::default(),
            bending_modulus: DEFAULT_BENDING_MODULUS,
            bending_damping: DEFAULT_BENDING_DAMPING,
            yield_strain: DEFAULT_YIELD_STRAIN,
            yield_angle: DEFAULT_YIELD_ANGLE,
            creep_rate: 0.0,
        }
    }
}

/// The default flexural rigidity of [`SpringMaterial`]'s bending (curvature or hinges), N·m:
/// a sheet as stiff in its plane as the default springs (about 200 N/m) and about 4 cm
/// thick, D = E·t²/12, so a unit sphere without gas is a shell of radius 24 times its
/// thickness. Measured on hinges (2026-12-03): a grabbed
/// and released sphere without gas springs back (at 0.01 N·m, a radius 41 times the
/// thickness, it kept a snapped-through dimple, as a ping-pong ball does; at 0.1 the
/// kitten's conjugate-gradient iterations doubled).
pub const DEFAULT_BENDING_MODULUS: f32 = 0.03;

/// The default damping time of [`SpringMaterial`]'s bending, s: a bending mode of 10 rad/s
/// damped at the ratio 0.25, the fastest modes of a fine network overdamped. With axial
/// spring damping the hinges are what damps motion across a sheet: at 0.01 s a 20 m/s ball
/// bounced off a pinned sheet at 8.8 m/s and was thrown 7.5 m/s sideways (0.05: 4.5 and
/// 1.7 m/s; `tests/contact.rs`).
pub const DEFAULT_BENDING_DAMPING: f32 = 0.05;

/// The default yield strain of [`SpringMaterial`]: 10 % (used once a creep rate is set).
pub const DEFAULT_YIELD_STRAIN: f32 = 0.1;

/// The default yield angle of [`SpringMaterial`]'s hinges: 0.1 rad, about 6° (used once a
/// creep rate is set).
pub const DEFAULT_YIELD_ANGLE: f32 = 0.1;

fn default_yield_angle() -> f32 {
    DEFAULT_YIELD_ANGLE
}

/// Plastic flow of springs (§ "modelling" in the README): a spring strained by more than
/// `yield_strain` moves its rest length towards the length at which its strain would be the
/// yield strain, relaxing a fraction 1 − e^(−`creep_rate`·dt) of the way each step. A large
/// pull thus leaves a permanent shape; below yield the surface returns to rest.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Plasticity {
    /// Strain borne elastically, finite and not negative.
    pub yield_strain: f32,
    /// Bend (radians past the rest angle) a hinge bears elastically, finite and not
    /// negative.
    #[serde(default = "default_yield_angle")]
    pub yield_angle: f32,
    /// Relaxation rate of the excess strain, per second, finite and not negative (0: elastic).
    pub creep_rate: f32,
}

impl Plasticity {
    /// No plastic flow.
    pub const ELASTIC: Self = Self {
        yield_strain: DEFAULT_YIELD_STRAIN,
        yield_angle: DEFAULT_YIELD_ANGLE,
        creep_rate: 0.0,
    };

    /// Whether rest lengths never change.
    pub fn is_elastic(&self) -> bool {
        self.creep_rate == 0.0
    }

    /// Checks both numbers are finite and not negative.
    pub fn validate(&self) -> Result<(), SolverError> {
        for (what, value) in [
            ("yield strain", self.yield_strain),
            ("yield angle", self.yield_angle),
            ("creep rate", self.creep_rate),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(SolverError::InvalidPlasticity { what, value });
            }
        }
        Ok(())
    }

    /// The fraction of the excess strain relaxed in a step of `dt` seconds.
    pub fn fraction(&self, dt: f32) -> f32 {
        -(-self.creep_rate * dt).exp_m1()
    }
}

impl Default for Plasticity {
    fn default() -> Self {
        Self::ELASTIC
    }
}
