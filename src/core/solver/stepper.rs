//! The [`Stepper`]: what advances a surface's [`PointState`] in time, in two phases that a
//! caller may run apart (the Bevy layer runs them in two system sets):
//!
//! 1. [`Stepper::accumulate_forces`]: the surface's own forces at the current state —
//!    gravity (eq 4), viscous drag, springs (eq 2–3), anchors (eq 5), gas pressure;
//! 2. [`Stepper::advance`]: adds the [`ExternalForces`] and integrates one step, split into
//!    sub-steps when an explicit scheme needs them (each later sub-step computes its forces
//!    anew).
//!
//! [`Solver::step`](super::Solver::step) runs both, so a surface stepped through its parts
//! and one stepped as a [`Solver`](super::Solver) give the same bits.

use glam::{Mat3, Vec3};

use super::parts::{
    Anchors, ExternalForces, Masses, PointState, Pressure, Soa3, Springs, sane, within,
};
use super::{
    DampingModel, Diagnostics, Energy, ImplicitSolver, Instability, InstabilityResponse,
    Integrator, RUNAWAY_DIAGONALS_PER_SECOND, RUNAWAY_MIN_SPEED, STATE_LIMIT, SolverConfig,
    SolverError, Stability, StepReport, SubstepPolicy,
};
use super::{implicit, prefactored};

/// The parts of a surface a step reads but does not change.
#[derive(Debug, Clone, Copy)]
pub struct StepParts<'a> {
    /// Masses and pins.
    pub masses: &'a Masses,
    /// Springs.
    pub springs: &'a Springs,
    /// Anchor springs.
    pub anchors: &'a Anchors,
    /// Gas inside a closed surface, if any.
    pub pressure: Option<&'a Pressure>,
    /// The points' rest positions, for [`InstabilityResponse::ResetToRest`] (without them
    /// that response freezes).
    pub rest: Option<&'a [Vec3]>,
}

impl StepParts<'_> {
    /// Revisions of the parts the stable step depends on.
    fn revisions(&self) -> [u64; 3] {
        [
            self.masses.revision,
            self.springs.revision,
            self.anchors.revision,
        ]
    }

    fn len(&self) -> usize {
        self.masses.len()
    }
}

/// Settings, force buffers, scratch space and running totals of one surface's time
/// stepping.
#[derive(Debug, Clone, Default)]
pub struct Stepper {
    config: SolverConfig,
    /// Force accumulators: spring forces on `a` ends plus every per-point force, and spring
    /// forces on `b` ends (see `springs`).
    pub(crate) fa: Soa3,
    pub(crate) fb: Soa3,
    /// Each hinge's ∇θ at the state of the forces, for an implicit step.
    pub(crate) hinge_gradients: Vec<[Vec3; 4]>,
    /// Each curvature-bending point's normal at the state of the forces, for an implicit
    /// step.
    pub(crate) curvature_normals: Vec<Vec3>,
    /// Whether `fa` and `fb` hold the forces at the current state (phase 1 ran).
    forces_ready: bool,
    /// Where explicit steps write the new state (see [`Stepper::integrate`]).
    spare_x: Soa3,
    spare_v: Soa3,
    /// The state before the step, when the guard needs a copy.
    snapshot: Option<(Soa3, Soa3)>,
    pub(crate) implicit: implicit::Scratch,
    /// The prefactored matrix of [`ImplicitSolver::LocalGlobal`] steps and their scratch.
    pub(crate) prefactored: prefactored::Scratch,
    /// The stability estimate and the revisions of the parts it was made for.
    stability: Option<(Stability, [u64; 3])>,
    diagnostics: Diagnostics,
    /// The rest bounding box's diagonal, the unit of the default runaway speed (∞: none).
    rest_diagonal: f32,
    /// The impulse each contact handed to the last step gave its point (N·s).
    pub(crate) contact_impulses: Vec<Vec3>,
    /// Whether steps measure what holds their pinned points ([`Stepper::pin_impulses`]).
    measure_pins: bool,
    /// The impulse that held each pinned point during the last step (N·s; zero where free).
    pub(crate) pin_impulses: Vec<Vec3>,
    /// How the world's vectors turn into the stepper's coordinates for gravity (none: they
    /// are the same): see [`Stepper::gravity`].
    gravity_frame: Option<Mat3>,
    /// How far the last step moved each of its bodies out of the points they pinch (the
    /// surface's coordinates; see [`Stepper::body_moves`]).
    pub(crate) body_moves: Vec<Vec3>,
}

impl Stepper {
    /// A stepper with `config` for `points` points.
    pub fn new(config: SolverConfig, points: usize) -> Result<Self, SolverError> {
        config.validate()?;
        Ok(Self {
            config,
            fa: Soa3::zeros(points),
            fb: Soa3::zeros(points),
            spare_x: Soa3::zeros(points),
            spare_v: Soa3::zeros(points),
            rest_diagonal: f32::INFINITY,
            ..Self::default()
        })
    }

    /// Sets the size the default runaway speed is measured in: the diagonal of the points'
    /// bounding box at rest.
    pub(crate) fn set_rest_diagonal(&mut self, diagonal: f32) {
        self.rest_diagonal = if diagonal > 0.0 && diagonal.is_finite() {
            diagonal
        } else {
            f32::INFINITY
        };
    }

    /// The speed (any velocity component) past which a point counts as run away.
    pub fn runaway_speed(&self) -> f32 {
        self.config
            .runaway_speed
            .unwrap_or((RUNAWAY_DIAGONALS_PER_SECOND * self.rest_diagonal).max(RUNAWAY_MIN_SPEED))
            .min(STATE_LIMIT)
    }

    /// The integrator the next step uses: the configured one, or implicit Euler after a
    /// fall-back ([`InstabilityResponse::FallBackToImplicit`]).
    pub fn integrator(&self) -> Integrator {
        if self.diagnostics.fell_back {
            Integrator::ImplicitEuler
        } else {
            self.config.integrator
        }
    }

    /// The settings.
    pub fn config(&self) -> &SolverConfig {
        &self.config
    }

    /// Replaces the settings.
    pub fn set_config(&mut self, config: SolverConfig) -> Result<(), SolverError> {
        config.validate()?;
        if config.integrator != self.config.integrator {
            self.implicit = implicit::Scratch::default();
            // A new choice of integrator starts over from a fall-back.
            self.diagnostics.fell_back = false;
        }
        self.config = config;
        self.stability = None;
        Ok(())
    }

    /// Sets gravity (eq 4, [`SolverConfig::gravity`], in the world's coordinates) alone,
    /// keeping the other settings and what the stepper has measured of them (gravity does
    /// not change the stable step); a value that is not finite is refused.
    pub fn set_gravity(&mut self, gravity: Vec3) -> Result<(), SolverError> {
        if !gravity.is_finite() {
            return Err(SolverError::InvalidConfig("gravity must be finite"));
        }
        self.config.gravity = gravity;
        Ok(())
    }

    /// The gravity each step applies, in the stepper's own coordinates:
    /// [`SolverConfig::gravity`] (the world's) turned by the gravity frame
    /// ([`Stepper::set_gravity_frame`]), or as it is without one. The core and the tool
    /// have no world, so there the two are the same; the plugin sets each surface's frame
    /// from its transform, so that a surface however turned falls the world's way.
    pub fn gravity(&self) -> Vec3 {
        match self.gravity_frame {
            Some(frame) => frame * self.config.gravity,
            None => self.config.gravity,
        }
    }

    /// Sets how the world's vectors map into the stepper's coordinates (the inverse of the
    /// linear part of its placement in the world; none: the same coordinates), for
    /// [`Stepper::gravity`]. A frame with a number that is not finite is refused.
    pub fn set_gravity_frame(&mut self, frame: Option<Mat3>) -> Result<(), SolverError> {
        if frame.is_some_and(|f| !f.is_finite()) {
            return Err(SolverError::InvalidConfig(
                "the gravity frame must be finite",
            ));
        }
        self.gravity_frame = frame;
        Ok(())
    }

    /// The gravity frame ([`Stepper::set_gravity_frame`]).
    pub fn gravity_frame(&self) -> Option<Mat3> {
        self.gravity_frame
    }

    /// The settings a step uses: [`Stepper::config`] with gravity in the stepper's own
    /// coordinates ([`Stepper::gravity`]).
    pub(crate) fn step_config(&self) -> SolverConfig {
        SolverConfig {
            gravity: self.gravity(),
            ..self.config
        }
    }

    /// Running totals.
    pub fn diagnostics(&self) -> &Diagnostics {
        &self.diagnostics
    }

    /// What the stepper carries from one step to the next: its running totals, the
    /// implicit solve's warm start (empty before the first implicit step) and the points
    /// contacts held at its end and had contacts then.
    pub(crate) fn carried(&self) -> (Diagnostics, Vec<glam::DVec3>, (Vec<u32>, Vec<u32>)) {
        (
            self.diagnostics,
            self.implicit.warm_start().to_vec(),
            self.implicit.held(),
        )
    }

    /// Restores what [`Self::carried`] gave.
    pub(crate) fn set_carried(
        &mut self,
        diagnostics: Diagnostics,
        warm_start: &[glam::DVec3],
        (held, touched): (&[u32], &[u32]),
    ) {
        self.diagnostics = diagnostics;
        self.implicit.set_warm_start(warm_start);
        self.implicit.set_held(held, touched);
        self.forces_ready = false;
    }

    /// The stable-step estimate for the model (cached until one of its parts changes).
    pub fn stability(&mut self, model: StepParts<'_>) -> Stability {
        let revisions = model.revisions();
        match self.stability {
            Some((s, r)) if r == revisions => s,
            _ => {
                let s = estimate_stability(&self.config, model);
                self.stability = Some((s, revisions));
                s
            }
        }
    }

    /// The stable-step estimate at `points`: [`Self::stability`] with a gas's stiffness at
    /// the current volume added ([`Pressure::stiffness_bound`]).
    pub fn stability_at(&mut self, points: &PointState, model: StepParts<'_>) -> Stability {
        let springs = self.stability(model);
        match model.pressure {
            Some(gas) => springs.with_stiffness(
                gas.stiffness_bound(points, model.masses),
                f64::from(self.config.drag),
            ),
            None => springs,
        }
    }

    fn check_sizes(&self, points: &PointState, model: StepParts<'_>) -> Result<(), SolverError> {
        let n = points.len();
        for (what, found) in [("masses", model.len()), ("force buffers", self.fa.len())] {
            if found != n {
                return Err(SolverError::PointCountMismatch {
                    what,
                    expected: n,
                    found,
                });
            }
        }
        Ok(())
    }

    /// Phase 1: the surface's own forces at the current state — m·(g − μ·v), springs and
    /// anchors — into the force buffers. [`Stepper::advance`] adds the external forces and
    /// integrates.
    pub fn accumulate_forces(
        &mut self,
        points: &PointState,
        model: StepParts<'_>,
    ) -> Result<(), SolverError> {
        self.check_sizes(points, model)?;
        self.compute_internal(points, model);
        self.forces_ready = true;
        Ok(())
    }

    /// The surface's own force on point `i` (springs, gravity, drag, anchors, pressure) at
    /// the state of the last [`Stepper::accumulate_forces`], if it has run since the last
    /// step.
    pub fn own_force(&self, i: usize) -> Option<Vec3> {
        (self.forces_ready && i < self.fa.len()).then(|| self.fa.get(i) + self.fb.get(i))
    }

    pub(super) fn compute_internal(&mut self, points: &PointState, model: StepParts<'_>) {
        let g = self.gravity();
        let mu = self.config.drag;
        let (v, m) = (&points.v, &model.masses.mass);
        base_forces(&mut self.fa.x, &v.x, m, g.x, mu);
        base_forces(&mut self.fa.y, &v.y, m, g.y, mu);
        base_forces(&mut self.fa.z, &v.z, m, g.z, mu);
        self.fb.fill(Vec3::ZERO);
        let layout = &model.springs.layout;
        match self.config.damping_model {
            DampingModel::Relative => {
                layout.accumulate::<false>(&points.x, v, &mut self.fa, &mut self.fb);
            }
            DampingModel::Axial => {
                layout.accumulate::<true>(&points.x, v, &mut self.fa, &mut self.fb);
            }
        }
        model
            .springs
            .hinges
            .accumulate(points, &mut self.fa, &mut self.hinge_gradients);
        model
            .springs
            .couplings
            .accumulate(layout, points, &mut self.fa);
        model
            .springs
            .curvatures
            .accumulate(points, &mut self.fa, &mut self.curvature_normals);
        for a in model.anchors.live() {
            let i = a.point as usize;
            let f = a.stiffness * (a.target - points.x.get(i)) - a.damping * points.v.get(i);
            self.fa.set(i, self.fa.get(i) + f);
        }
        if let Some(pressure) = model.pressure {
            pressure.accumulate(points, &mut self.fa);
        }
    }

    pub(super) fn add_external(&mut self, external: &ExternalForces) {
        if !external.any {
            return;
        }
        let e = &external.f;
        for (f, e) in [
            (&mut self.fa.x, &e.x),
            (&mut self.fa.y, &e.y),
            (&mut self.fa.z, &e.z),
        ] {
            for (f, e) in f.iter_mut().zip(e) {
                *f += e;
            }
        }
    }

    /// Sub-steps for a step of `dt` of `integrator` under the current policy.
    fn plan(
        &mut self,
        points: &PointState,
        model: StepParts<'_>,
        integrator: Integrator,
        dt: f32,
    ) -> Result<(u32, bool), SolverError> {
        if !integrator.is_explicit() || self.config.substeps == SubstepPolicy::Unchecked {
            return Ok((1, false));
        }
        let stable = self.stability_at(points, model).dt(integrator) * self.config.stability_margin;
        if dt <= stable {
            return Ok((1, false));
        }
        let refuse = Err(SolverError::StepTooLarge {
            dt,
            stable_dt: stable,
            integrator,
        });
        match self.config.substeps {
            SubstepPolicy::Refuse => refuse,
            // No number of sub-steps helps: say so instead of burning them.
            SubstepPolicy::Auto { .. } if stable == 0.0 => refuse,
            SubstepPolicy::Auto { max_substeps } => {
                let needed = f64::from(dt) / f64::from(stable);
                if needed > f64::from(max_substeps) {
                    Ok((max_substeps, true))
                } else {
                    Ok((needed.ceil() as u32, false))
                }
            }
            SubstepPolicy::Unchecked => Ok((1, false)),
        }
    }

    /// Phase 2: adds the external forces to the forces of phase 1 (computing those first
    /// if phase 1 has not run since the last step) and advances the state by `dt` seconds.
    pub fn advance(
        &mut self,
        points: &mut PointState,
        model: StepParts<'_>,
        external: &ExternalForces,
        dt: f32,
    ) -> Result<StepReport, SolverError> {
        if !(dt.is_finite() && dt >= 0.0) {
            return Err(SolverError::InvalidTimeStep(dt));
        }
        self.check_sizes(points, model)?;
        if external.len() != points.len() {
            return Err(SolverError::PointCountMismatch {
                what: "external forces",
                expected: points.len(),
                found: external.len(),
            });
        }
        let fresh = std::mem::take(&mut self.forces_ready);
        if dt == 0.0 || points.is_empty() {
            let report = StepReport {
                cg_converged: true,
                finite: true,
                ..StepReport::default()
            };
            self.diagnostics.last = report;
            return Ok(report);
        }
        let falls_back = self.config.on_instability == InstabilityResponse::FallBackToImplicit;
        let integrator = self.integrator();
        let auto = matches!(self.config.substeps, SubstepPolicy::Auto { .. });
        let mut planned = match self.plan(points, model, integrator, dt) {
            // No explicit step is stable (explicit Euler without damping): fall back.
            Err(SolverError::StepTooLarge { .. }) if falls_back && auto => (1, true),
            other => other?,
        };
        // Beyond the sub-step cap the explicit step would run above its stable step: hand
        // over to implicit Euler before wasting the sub-steps.
        let hands_over = planned.1 && falls_back;
        let step_with = if hands_over {
            planned = (1, false);
            self.fall_back();
            Integrator::ImplicitEuler
        } else {
            integrator
        };
        let mut report = self.take_step(points, model, external, dt, step_with, planned, fresh);
        if hands_over {
            report.fell_back = true;
            report.instability = report.instability.or(Some(Instability::SubstepLimit));
        }
        if report.recovered && integrator.is_explicit() && falls_back && !report.fell_back {
            // The explicit step went bad: take it again, implicitly, from the restored state.
            let first = report.instability;
            self.fall_back();
            planned = (1, false);
            let again = self.take_step(
                points,
                model,
                external,
                dt,
                Integrator::ImplicitEuler,
                planned,
                false,
            );
            report = StepReport {
                fell_back: true,
                instability: again.instability.or(first),
                substeps: report.substeps + again.substeps,
                ..again
            };
        }
        if report.recovered {
            self.respond(points, model);
        }
        let d = &mut self.diagnostics;
        d.steps += 1;
        d.substeps += u64::from(report.substeps);
        d.limited_steps += u64::from(report.limited);
        d.cg_iterations += u64::from(report.cg_iterations);
        d.cg_unconverged += u64::from(!report.cg_converged);
        d.guard_trips += u64::from(report.recovered);
        d.time += f64::from(dt);
        d.last = report;
        Ok(report)
    }

    /// From now on every step is implicit.
    fn fall_back(&mut self) {
        if !self.diagnostics.fell_back {
            self.diagnostics.fell_back = true;
            self.implicit = implicit::Scratch::default();
        }
    }

    /// After the guard restored the state: the points stop there, or at rest
    /// ([`InstabilityResponse`]).
    fn respond(&mut self, points: &mut PointState, model: StepParts<'_>) {
        let rest = model
            .rest
            .filter(|r| r.len() == points.len())
            .filter(|_| self.config.on_instability == InstabilityResponse::ResetToRest);
        for i in 0..points.len() {
            if model.masses.is_pinned(i) {
                continue;
            }
            if let Some(rest) = rest {
                points.x.set(i, rest[i]);
            }
            points.v.set(i, Vec3::ZERO);
        }
        self.implicit.reset_warm_start();
    }

    /// One step of `integrator` in the `planned` sub-steps, guarded.
    #[allow(clippy::too_many_arguments)]
    fn take_step(
        &mut self,
        points: &mut PointState,
        model: StepParts<'_>,
        external: &ExternalForces,
        dt: f32,
        integrator: Integrator,
        (substeps, limited): (u32, bool),
        fresh: bool,
    ) -> StepReport {
        // The guard's way back: an explicit single step writes the new state beside the old
        // one and swaps, so the old state is still there (no copy); anything else copies.
        let swap_restores = integrator.is_explicit() && substeps == 1;
        if self.config.guard && !swap_restores {
            let (x, v) = self
                .snapshot
                .get_or_insert_with(|| (points.x.clone(), points.v.clone()));
            x.copy_from(&points.x);
            v.copy_from(&points.v);
        }
        self.contact_impulses.clear();
        self.contact_impulses
            .resize(external.contacts.len(), Vec3::ZERO);
        self.body_moves.clear();
        self.body_moves.resize(external.bodies.len(), Vec3::ZERO);
        self.pin_impulses.clear();
        if self.measure_pins {
            self.pin_impulses.resize(points.len(), Vec3::ZERO);
        }
        let h = dt / substeps as f32;
        let speed = self.runaway_speed();
        let mut report = StepReport {
            substeps,
            substep_dt: h,
            limited,
            cg_converged: true,
            instability: limited.then_some(Instability::SubstepLimit),
            ..StepReport::default()
        };
        let mut insane = 0;
        for substep in 0..substeps {
            if substep > 0 || !fresh {
                self.compute_internal(points, model);
            }
            self.add_external(external);
            insane = match integrator {
                Integrator::ExplicitEuler => {
                    self.add_pin_forces(model.masses, h);
                    let insane = self.integrate::<false>(points, model.masses, h, speed);
                    self.project_contacts(points, model, external, h, insane)
                }
                Integrator::SymplecticEuler => {
                    self.add_pin_forces(model.masses, h);
                    let insane = self.integrate::<true>(points, model.masses, h, speed);
                    self.project_contacts(points, model, external, h, insane)
                }
                Integrator::ImplicitEuler => {
                    let local_global = match self.config.implicit_solver {
                        ImplicitSolver::LocalGlobal { iterations } => {
                            self.local_global_step(points, model, external, h, iterations)
                        }
                        ImplicitSolver::ConjugateGradient => None,
                    };
                    if let Some(iterations) = local_global {
                        report.cg_iterations += iterations;
                    } else {
                        let cg = self.implicit_step(points, model, external, h);
                        report.cg_iterations += cg.iterations;
                        report.cg_converged &= cg.converged;
                    }
                    points.x.count_insane() + points.v.count_beyond(speed)
                }
            };
            if insane > 0 {
                break;
            }
        }
        report.finite = insane == 0;
        if !report.finite {
            let non_finite = points.x.count_insane() + points.v.count_insane() > 0;
            report.instability = Some(if non_finite {
                Instability::NonFinite
            } else {
                Instability::Runaway
            });
        }
        if !report.finite && self.config.guard {
            if swap_restores {
                std::mem::swap(&mut points.x, &mut self.spare_x);
                std::mem::swap(&mut points.v, &mut self.spare_v);
            } else if let Some((x, v)) = &self.snapshot {
                points.x.copy_from(x);
                points.v.copy_from(v);
            }
            self.implicit.reset_warm_start();
            // The step did not happen: neither did its contacts, nor its pins' pulls, nor
            // its bodies' moves.
            self.contact_impulses.fill(Vec3::ZERO);
            self.pin_impulses.fill(Vec3::ZERO);
            self.body_moves.fill(Vec3::ZERO);
            report.recovered = true;
            report.finite = true;
        }
        report
    }

    /// After an explicit step that left `insane` components: the contacts handed in move
    /// their points ([`contact::step::project`](super::contact::step::project)); returns
    /// `insane` again (a state the guard will restore is left alone).
    fn project_contacts(
        &mut self,
        points: &mut PointState,
        model: StepParts<'_>,
        external: &ExternalForces,
        h: f32,
        insane: usize,
    ) -> usize {
        if insane == 0 && !external.contacts.is_empty() {
            super::contact::step::project(
                points,
                model.masses,
                &external.contacts,
                h,
                &mut self.contact_impulses,
            );
        }
        insane
    }

    /// The impulse each contact handed to the last step ([`ExternalForces::add_contact`])
    /// gave its point, N·s, in the order they were added (zero for one that did not touch,
    /// or that another contact of its point stood in for).
    pub fn contact_impulses(&self) -> &[Vec3] {
        &self.contact_impulses
    }

    /// Forgets the last step's contact impulses and body moves (once a caller has read
    /// them).
    pub fn clear_contact_impulses(&mut self) {
        self.contact_impulses.clear();
        self.body_moves.clear();
    }

    /// How far the last step moved each body it solved with the surface
    /// ([`ExternalForces::add_body`], in that order; the surface's coordinates) out of the
    /// points it pinches against something immovable: those points cannot give way, so the
    /// body's overlap with them is moved out of the body, by position (the caller moves
    /// it; its velocity keeps nothing of it). Zero where it pinches nothing, and when the
    /// guard undid the step.
    pub fn body_moves(&self) -> &[Vec3] {
        &self.body_moves
    }

    /// Whether each step measures what holds its pinned points ([`Stepper::pin_impulses`]).
    /// Off by default: an implicit step pays one more product with its matrix for it.
    pub fn set_measure_pins(&mut self, on: bool) {
        self.measure_pins = on;
        if !on {
            self.pin_impulses.clear();
        }
    }

    /// Whether steps measure what holds their pinned points.
    pub fn measures_pins(&self) -> bool {
        self.measure_pins
    }

    /// The impulse (N·s, the surface's coordinates) that whatever holds each pinned point
    /// gave it during the last step: what it took to keep the point on its prescribed path
    /// against the springs, gravity and every other force of the step (its opposite is
    /// what the surface pulled on the holder with). Zero at free points; empty unless
    /// [`Stepper::set_measure_pins`] is on, and zero when the guard undid the step. With
    /// implicit Euler solved by conjugate gradient it is the pinned rows of A·Δv − b, so
    /// that the surface's momentum changes by exactly these impulses and the external
    /// forces' (to the solve's tolerance); with an explicit integrator −h·f at each
    /// sub-step; with local/global iterations −h·f at the last iterate.
    pub fn pin_impulses(&self) -> &[Vec3] {
        &self.pin_impulses
    }

    /// Subtracts h·f from each pinned point's impulse, `f` the forces in `fa` and `fb`.
    pub(crate) fn add_pin_forces(&mut self, masses: &Masses, h: f32) {
        if !self.measure_pins {
            return;
        }
        for (i, j) in self.pin_impulses.iter_mut().enumerate() {
            if masses.inv_mass[i] == 0.0 {
                *j -= (self.fa.get(i) + self.fb.get(i)) * h;
            }
        }
    }

    /// One explicit step of length `h` from the forces in `fa` and `fb`: symplectic Euler
    /// (v += a·h, then x += v·h) or forward Euler (x += v·h and v += a·h from the same old
    /// state). The new state is written to the spare buffers, which then change places with
    /// the current ones. Returns the number of insane components in the new state.
    fn integrate<const SYMPLECTIC: bool>(
        &mut self,
        points: &mut PointState,
        masses: &Masses,
        h: f32,
        speed: f32,
    ) -> usize {
        let inv = &masses.inv_mass;
        let mut insane = 0;
        let (x, v) = (&points.x, &points.v);
        for (x, v, fa, fb, x_out, v_out) in [
            (
                &x.x,
                &v.x,
                &self.fa.x,
                &self.fb.x,
                &mut self.spare_x.x,
                &mut self.spare_v.x,
            ),
            (
                &x.y,
                &v.y,
                &self.fa.y,
                &self.fb.y,
                &mut self.spare_x.y,
                &mut self.spare_v.y,
            ),
            (
                &x.z,
                &v.z,
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
                speed,
                x_out,
                v_out,
            });
        }
        std::mem::swap(&mut points.x, &mut self.spare_x);
        std::mem::swap(&mut points.v, &mut self.spare_v);
        insane as usize
    }

    /// Kinetic, spring, gravitational and anchor energy of `points`.
    pub fn energy(&self, points: &PointState, model: StepParts<'_>) -> Energy {
        let mut e = Energy {
            spring: model.springs.energy(points),
            bending: model.springs.hinges.energy(points) + model.springs.curvatures.energy(points),
            ..Energy::default()
        };
        let g = self.gravity().as_dvec3();
        let masses = model.masses;
        for i in 0..points.len() {
            if masses.is_pinned(i) {
                continue;
            }
            let m = f64::from(masses.mass(i));
            e.kinetic += 0.5 * m * points.velocity(i).as_dvec3().length_squared();
            e.gravity -= m * g.dot(points.position(i).as_dvec3());
        }
        for a in model.anchors.live() {
            let d = (a.target - points.position(a.point as usize)).as_dvec3();
            e.anchor += 0.5 * f64::from(a.stiffness) * d.length_squared();
        }
        if let Some(pressure) = model.pressure {
            e.pressure = pressure.energy(points);
        }
        e
    }
}

/// The stable-step estimate (see the module docs of `solver`).
fn estimate_stability(config: &SolverConfig, model: StepParts<'_>) -> Stability {
    let n = model.len();
    let (masses, layout) = (model.masses, &model.springs.layout);
    let mut stiff = vec![0.0f64; n];
    let mut damp = vec![0.0f64; n];
    let mut ratio = f64::INFINITY;
    let free = |i: usize| !masses.is_pinned(i);
    for s in 0..layout.len() {
        let (a, b) = (layout.a[s] as usize, layout.b[s] as usize);
        let (k, kd) = (f64::from(layout.k[s]), f64::from(layout.kd[s]));
        for i in [a, b] {
            stiff[i] += 2.0 * k;
            damp[i] += 2.0 * kd;
        }
        if k > 0.0 && (free(a) || free(b)) {
            ratio = ratio.min(kd / k);
        }
    }
    ratio = ratio.min(model.springs.hinges.stability_rows(&mut stiff, &mut damp));
    ratio = ratio.min(
        model
            .springs
            .curvatures
            .stability_rows(&mut stiff, &mut damp),
    );
    model.springs.couplings.stability_rows(layout, &mut stiff);
    for a in model.anchors.live() {
        let i = a.point as usize;
        stiff[i] += f64::from(a.stiffness);
        damp[i] += f64::from(a.damping);
        if a.stiffness > 0.0 && free(i) {
            ratio = ratio.min(f64::from(a.damping) / f64::from(a.stiffness));
        }
    }
    let any_stiffness = stiff.iter().any(|&s| s > 0.0);
    if config.damping_model == DampingModel::Axial && any_stiffness {
        // Axial damping leaves motion across a spring undamped, and a stretched spring
        // resists that motion with k·(1 − l⁰/|l|): for explicit Euler those modes are
        // undamped oscillations, which only drag keeps stable.
        ratio = 0.0;
    }
    let (mut omega2, mut gamma) = (0.0f64, 0.0f64);
    for i in 0..n {
        let inv = f64::from(masses.inv_mass[i]);
        omega2 = omega2.max(stiff[i] * inv);
        gamma = gamma.max(damp[i] * inv);
    }
    let drag = f64::from(config.drag);
    Stability::from_rates(omega2, gamma + drag, ratio, drag)
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
    speed: f32,
    x_out: &'a mut [f32],
    v_out: &'a mut [f32],
}

impl<const SYMPLECTIC: bool> pulp::WithSimd for IntegrateAxis<'_, SYMPLECTIC> {
    type Output = u32;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> u32 {
        integrate_axis::<SYMPLECTIC>(
            self.x, self.v, self.fa, self.fb, self.inv, self.h, self.speed, self.x_out, self.v_out,
        )
    }
}

/// One axis of an explicit step (see [`Stepper::integrate`]); counts new components that
/// are not finite, positions beyond the state limit and velocities beyond `speed`
/// (branch-free, so the loop vectorises).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn integrate_axis<const SYMPLECTIC: bool>(
    x: &[f32],
    v: &[f32],
    fa: &[f32],
    fb: &[f32],
    inv: &[f32],
    h: f32,
    speed: f32,
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
        insane += u32::from(!sane(xn)) + u32::from(!within(vn, speed));
    }
    insane
}

/// One axis of m·(g − μ·v).
fn base_forces(fa: &mut [f32], v: &[f32], m: &[f32], g: f32, mu: f32) {
    let n = fa.len();
    let (v, m) = (&v[..n], &m[..n]);
    for i in 0..n {
        fa[i] = m[i] * (g - mu * v[i]);
    }
}
