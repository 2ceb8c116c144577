//! Implicit Euler: backward Euler linearised once per step (Baraff & Witkin 1998),
//!
//! ```text
//! (M − h·∂f/∂v − h²·∂f/∂x) Δv = h·(f₀ + h·∂f/∂x·v₀),   v₁ = v₀ + Δv,   x₁ = x₀ + h·v₁
//! ```
//!
//! solved by preconditioned conjugate gradient in `f64`. Each spring contributes one
//! symmetric 3×3 block C = h·D + h²·K to its two diagonal blocks and, negated, to the two
//! off-diagonal ones; K = k·l̂l̂ᵀ + k·max(0, 1 − l⁰/|l|)·(I − l̂l̂ᵀ) drops the negative
//! transverse stiffness of compressed springs so the matrix stays positive definite (Choi &
//! Ko 2002). Every such block is a·l̂l̂ᵀ + b·I, so it is kept as two numbers and the direction,
//! and the product with the matrix takes each spring once, on the difference of its ends:
//! A·p = M'·p + Σ (eₐ − e_b)·C·(pₐ − p_b), half the work of applying the block to both ends
//! with the diagonal kept apart. The preconditioner is block Jacobi (each point's whole 3×3
//! diagonal block inverted) for the first `JACOBI_ITERATIONS` iterations, then symmetric
//! block Gauss–Seidel over the same blocks (`sweeps`), restarting the search directions
//! from the iterate. Fixed points are filtered out (their Δv is zero). The solve
//! starts from the previous step's Δv when that leaves a smaller residual than starting
//! from zero, and stops at a residual of [`SolverConfig::cg_tolerance`] times the
//! right-hand side's.
//!
//! Gas pressure enters through its stiffness along the volume's gradient g: the force's
//! Jacobian −c·ggᵀ (c = κ·V₀/V², see `Pressure::linearised`) is a dense but rank-one term,
//! kept as g and h²c beside the sparse blocks and applied as h²c·g(g·p) in each product; its
//! diagonal blocks join the preconditioner. The pressure times the volume's Hessian is
//! indefinite and left out (Gauss–Newton), so the matrix stays positive definite.

use glam::{DMat3, DVec3, Vec3};

use super::parts::{
    CouplingBlock, CurvatureBlock, Curvatures, ExternalForces, HingeBlock, PointState, Springs,
};
use super::spring_layout::COINCIDENT_DISTANCE;
use super::stepper::{StepParts, Stepper};
use super::{DampingModel, SolverConfig};

mod carried;
mod contacts;
mod sweeps;

use carried::Carried;
use contacts::{BODY_ROUNDS, Contacts};

/// A symmetric 3×3 matrix.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Sym3 {
    xx: f64,
    yy: f64,
    zz: f64,
    xy: f64,
    xz: f64,
    yz: f64,
}

impl Sym3 {
    /// The sum of the diagonal.
    fn trace(&self) -> f64 {
        self.xx + self.yy + self.zz
    }

    fn scaled_identity(s: f64) -> Self {
        Self {
            xx: s,
            yy: s,
            zz: s,
            ..Self::default()
        }
    }

    /// s·(uwᵀ + wuᵀ).
    fn symmetric_outer(u: DVec3, w: DVec3, s: f64) -> Self {
        Self {
            xx: 2.0 * s * u.x * w.x,
            yy: 2.0 * s * u.y * w.y,
            zz: 2.0 * s * u.z * w.z,
            xy: s * (u.x * w.y + u.y * w.x),
            xz: s * (u.x * w.z + u.z * w.x),
            yz: s * (u.y * w.z + u.z * w.y),
        }
    }

    /// s·uuᵀ + t·I.
    fn outer_plus_identity(u: DVec3, s: f64, t: f64) -> Self {
        Self {
            xx: s * u.x * u.x + t,
            yy: s * u.y * u.y + t,
            zz: s * u.z * u.z + t,
            xy: s * u.x * u.y,
            xz: s * u.x * u.z,
            yz: s * u.y * u.z,
        }
    }

    fn add(self, o: Self) -> Self {
        Self {
            xx: self.xx + o.xx,
            yy: self.yy + o.yy,
            zz: self.zz + o.zz,
            xy: self.xy + o.xy,
            xz: self.xz + o.xz,
            yz: self.yz + o.yz,
        }
    }

    fn mul(&self, v: DVec3) -> DVec3 {
        DVec3::new(
            self.xx * v.x + self.xy * v.y + self.xz * v.z,
            self.xy * v.x + self.yy * v.y + self.yz * v.z,
            self.xz * v.x + self.yz * v.y + self.zz * v.z,
        )
    }

    /// The inverse, or the inverse of the diagonal when the block is singular.
    fn inverse(&self) -> Self {
        let m = DMat3::from_cols(
            DVec3::new(self.xx, self.xy, self.xz),
            DVec3::new(self.xy, self.yy, self.yz),
            DVec3::new(self.xz, self.yz, self.zz),
        );
        let det = m.determinant();
        if det.is_finite() && det > f64::MIN_POSITIVE {
            let i = m.inverse();
            Self {
                xx: i.x_axis.x,
                yy: i.y_axis.y,
                zz: i.z_axis.z,
                xy: i.y_axis.x,
                xz: i.z_axis.x,
                yz: i.z_axis.y,
            }
        } else {
            let r = |d: f64| if d > 0.0 { 1.0 / d } else { 0.0 };
            Self {
                xx: r(self.xx),
                yy: r(self.yy),
                zz: r(self.zz),
                ..Self::default()
            }
        }
    }
}

/// One spring's block of the step's matrix, C = h·D + h²·K = `along`·ûûᵀ + `across`·I.
#[derive(Debug, Clone, Copy, Default)]
struct SpringBlock {
    /// The spring's unit direction (any unit vector for coincident ends: the block is then
    /// isotropic).
    u: DVec3,
    along: f64,
    across: f64,
}

impl SpringBlock {
    /// C·d.
    #[inline(always)]
    fn mul(&self, d: DVec3) -> DVec3 {
        self.u * (self.along * self.u.dot(d)) + d * self.across
    }

    fn sym3(&self) -> Sym3 {
        Sym3::outer_plus_identity(self.u, self.along, self.across)
    }
}

/// Buffers kept between implicit steps.
#[derive(Debug, Clone, Default)]
pub(crate) struct Scratch {
    /// The last Δv (the warm start).
    dv: Vec<DVec3>,
    rhs: Vec<DVec3>,
    r: Vec<DVec3>,
    z: Vec<DVec3>,
    p: Vec<DVec3>,
    q: Vec<DVec3>,
    /// Each point's own isotropic part of the matrix: mass, drag and anchors.
    own: Vec<f64>,
    /// Each point's whole 3×3 diagonal block, and its inverse (the preconditioner).
    diag: Vec<Sym3>,
    diag_inv: Vec<Sym3>,
    blocks: Vec<SpringBlock>,
    fixed: Vec<bool>,
    /// The right-hand side's rows of the fixed points before they were zeroed (what the
    /// step's forces ask of them; see [`Stepper::pin_impulses`]).
    pin_rhs: Vec<DVec3>,
    /// The volume's gradient at each point, for the gas's rank-one term.
    gas: Vec<DVec3>,
    /// Each hinge's gradient and scale.
    hinges: Vec<HingeBlock>,
    /// Each coupled triangle's edge directions and scaled couplings.
    couplings: Vec<CouplingBlock>,
    /// Each curvature-bending point's held normal and scale.
    curvatures: Vec<CurvatureBlock>,
    /// The velocities at the start of the step (curvature bending's right-hand side).
    velocities: Vec<DVec3>,
    /// Each point's contact normal while a contact holds it in the solve (zero: free), and
    /// a second axis where two contacts hold it (unit, ⊥ the first; zero: none).
    normal: Vec<DVec3>,
    normal2: Vec<DVec3>,
    /// Whether a contact held each point at the end of the last step (the next step's
    /// first guess), and whether a moving body's contact beside an immovable one did.
    held: Vec<bool>,
    held_by_body: Vec<bool>,
    /// Whether each point had a contact in the last step, held or not.
    touched: Vec<bool>,
    /// How the surface's pushes changed with each moving body's velocity in the last step,
    /// by the body's key ([`StepBody::key`]).
    resisted: Vec<(u64, contacts::Resist)>,
    /// Each pinch's push at the end of the last step (a moving body on a point something
    /// immovable holds), by the body's key and the point: the next step's first guess.
    pinched: Vec<(u64, u32, (f64, DVec3))>,
    /// The preconditioner's blocks and buffers.
    sweeps: sweeps::GaussSeidel,
}

impl Scratch {
    pub fn reset_warm_start(&mut self) {
        self.pinched.clear();
        self.dv.iter_mut().for_each(|d| *d = DVec3::ZERO);
        self.held.iter_mut().for_each(|h| *h = false);
        self.held_by_body.iter_mut().for_each(|h| *h = false);
        self.touched.iter_mut().for_each(|h| *h = false);
    }

    /// The points a contact held at the end of the last step, and those that had a contact
    /// then, held or not; each ascending.
    pub fn held(&self) -> (Vec<u32>, Vec<u32>) {
        let list = |flags: &[bool]| {
            (0..flags.len())
                .filter(|&i| flags[i])
                .map(|i| i as u32)
                .collect()
        };
        (list(&self.held), list(&self.touched))
    }

    /// Replaces what [`Self::held`] gave (a snapshot's; in range).
    pub fn set_held(&mut self, held: &[u32], touched: &[u32]) {
        self.held_by_body.fill(false);
        self.pinched.clear();
        for (flags, set) in [(&mut self.held, held), (&mut self.touched, touched)] {
            flags.fill(false);
            for &i in set {
                let i = i as usize;
                if i >= flags.len() {
                    flags.resize(i + 1, false);
                }
                flags[i] = true;
            }
        }
    }

    /// The last Δv, the next solve's start.
    pub fn warm_start(&self) -> &[DVec3] {
        &self.dv
    }

    /// Replaces the warm start (a snapshot's).
    pub fn set_warm_start(&mut self, dv: &[DVec3]) {
        self.dv.clear();
        self.dv.extend_from_slice(dv);
    }

    fn resize(&mut self, n: usize, springs: usize) {
        for v in [
            &mut self.dv,
            &mut self.rhs,
            &mut self.r,
            &mut self.z,
            &mut self.p,
            &mut self.q,
        ] {
            v.resize(n, DVec3::ZERO);
        }
        self.own.resize(n, 0.0);
        self.normal.clear();
        self.normal.resize(n, DVec3::ZERO);
        self.normal2.clear();
        self.normal2.resize(n, DVec3::ZERO);
        self.held.resize(n, false);
        self.held_by_body.resize(n, false);
        self.touched.resize(n, false);
        self.diag.resize(n, Sym3::default());
        self.diag_inv.resize(n, Sym3::default());
        self.fixed.resize(n, false);
        self.pin_rhs.resize(n, DVec3::ZERO);
        self.blocks.resize(springs, SpringBlock::default());
    }
}

/// How one conjugate-gradient solve went.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct CgOutcome {
    pub iterations: u32,
    pub converged: bool,
}

fn dot(a: &[DVec3], b: &[DVec3]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x.dot(*y)).sum()
}

/// The system's matrix in the springs' own form, A = M' + Σₛ (eₐ − e_b)·Cₛ·(eₐ − e_b)ᵀ +
/// `gas_scale`·ggᵀ: each point's isotropic part M' (mass, drag, anchors), one block per
/// spring applied once to the difference of its ends (half the work of applying it to both
/// ends and keeping its diagonal apart), and the gas's rank-one term (scale 0 without gas).
struct System<'a> {
    own: &'a [f64],
    blocks: &'a [SpringBlock],
    a_end: &'a [u32],
    b_end: &'a [u32],
    fixed: &'a [bool],
    gas: &'a [DVec3],
    gas_scale: f64,
    hinges: &'a [HingeBlock],
    hinge_ends: &'a [[u32; 4]],
    couplings: &'a [CouplingBlock],
    coupling_springs: &'a [[u32; 3]],
    curvatures: &'a Curvatures,
    curvature_blocks: &'a [CurvatureBlock],
}

impl System<'_> {
    /// Whether the step bends on hinges or curvature: a matrix whose block Jacobi
    /// preconditioner leaves a solve 1.4–2.5 times the iterations of symmetric Gauss–Seidel
    /// (see [`JACOBI_ITERATIONS`]).
    fn bends(&self) -> bool {
        !self.hinges.is_empty() || !self.curvature_blocks.is_empty()
    }

    /// y = A·p (fixed rows zero; p is zero at fixed points), and returns p·y.
    fn apply(&self, p: &[DVec3], y: &mut [DVec3]) -> f64 {
        self.apply_rows::<false>(p, y)
    }

    /// y = A·p, the fixed rows zero unless `FIXED_ROWS` (p is zero at fixed points), and
    /// returns p·y over the free rows.
    fn apply_rows<const FIXED_ROWS: bool>(&self, p: &[DVec3], y: &mut [DVec3]) -> f64 {
        let n = p.len();
        let (own, y) = (&self.own[..n], &mut y[..n]);
        for i in 0..n {
            y[i] = p[i] * own[i];
        }
        let springs = self.blocks.len();
        let (a_end, b_end) = (&self.a_end[..springs], &self.b_end[..springs]);
        for (s, c) in self.blocks.iter().enumerate() {
            let (a, b) = (a_end[s] as usize, b_end[s] as usize);
            let w = c.mul(p[a] - p[b]);
            y[a] += w;
            y[b] -= w;
        }
        for (block, springs) in self.couplings.iter().zip(self.coupling_springs) {
            // h²·JᵀCJ·p over the triangle's three edges.
            let ends = springs.map(|s| (a_end[s as usize] as usize, b_end[s as usize] as usize));
            let rates = [0, 1, 2].map(|i| block.u[i].dot(p[ends[i].0] - p[ends[i].1]));
            let w = block.weights(rates);
            for ((u, (a, b)), w) in block.u.iter().zip(ends).zip(w) {
                y[a] += w * *u;
                y[b] -= w * *u;
            }
        }
        self.curvatures.apply(self.curvature_blocks, p, y);
        for (block, ends) in self.hinges.iter().zip(self.hinge_ends) {
            // s·∇θ(∇θ·p) on the hinge's four points.
            let ends = ends.map(|i| i as usize);
            let g = &block.gradient;
            let t = block.scale
                * (g[0].dot(p[ends[0]])
                    + g[1].dot(p[ends[1]])
                    + g[2].dot(p[ends[2]])
                    + g[3].dot(p[ends[3]]));
            for j in 0..4 {
                y[ends[j]] += t * g[j];
            }
        }
        let along = if self.gas_scale > 0.0 {
            // p is zero at fixed points, so g·p sums the free ones.
            self.gas_scale * dot(self.gas, p)
        } else {
            0.0
        };
        let mut py = 0.0;
        for i in 0..n {
            if self.fixed[i] {
                y[i] = if FIXED_ROWS {
                    y[i] + along * self.gas[i]
                } else {
                    DVec3::ZERO
                };
            } else {
                if along != 0.0 {
                    y[i] += along * self.gas[i];
                }
                py += p[i].dot(y[i]);
            }
        }
        py
    }
}

impl Stepper {
    /// One implicit Euler step of length `h` from the forces in `fa` and `fb`.
    pub(super) fn implicit_step(
        &mut self,
        points: &mut PointState,
        model: StepParts<'_>,
        external: &ExternalForces,
        h: f32,
    ) -> CgOutcome {
        let n = points.len();
        let layout = &model.springs.layout;
        let config = self.step_config();
        let mut scratch = std::mem::take(&mut self.implicit);
        scratch.resize(n, layout.len());
        let h = f64::from(h);
        let forces = Forces {
            fa: &self.fa,
            fb: &self.fb,
            hinge_gradients: &self.hinge_gradients,
            curvature_normals: &self.curvature_normals,
        };
        let mut gas_scale = assemble(&mut scratch, forces, points, model, &config, h);
        let mut contacts = Contacts::new(external, points, model, h);
        let mut outcome = conjugate_gradient(
            &config,
            model.springs,
            &mut scratch,
            gas_scale,
            &mut contacts,
        );
        // Bodies carrying pinned points: rounds of the body's velocity and the surface's.
        let mut carried = Carried::new(&external.carried, &external.bodies, points);
        if !carried.is_empty() {
            let mut held = vec![Vec3::ZERO; n];
            for _ in 0..BODY_ROUNDS {
                held.fill(Vec3::ZERO);
                pin_impulses(model.springs, &mut scratch, gas_scale, &mut held);
                carried.add_moved(points, model.masses, &mut held);
                if !carried.step(&scratch, &held, points) {
                    break;
                }
                gas_scale = assemble(&mut scratch, forces, points, model, &config, h);
                let again = conjugate_gradient(
                    &config,
                    model.springs,
                    &mut scratch,
                    gas_scale,
                    &mut contacts,
                );
                outcome.iterations += again.iterations;
                outcome.converged = again.converged;
            }
        }
        let held = contacts.slide(&mut scratch, points, &mut self.contact_impulses);
        contacts.remember(&mut scratch);
        if config.damping_model == DampingModel::Axial && !held {
            keep_momenta(&mut scratch, points, model, external, &config, h);
        }
        if self.measures_pins() {
            pin_impulses(
                model.springs,
                &mut scratch,
                gas_scale,
                &mut self.pin_impulses,
            );
            carried.add_moved(points, model.masses, &mut self.pin_impulses);
        }

        for (i, dv) in scratch.dv.iter().enumerate() {
            if scratch.fixed[i] {
                continue;
            }
            let v = (points.v.get(i).as_dvec3() + *dv).as_vec3();
            points.v.set(i, v);
        }
        let hf = h as f32;
        for i in 0..n {
            let x = points.x.get(i) + points.v.get(i) * hf;
            points.x.set(i, x);
        }
        contacts.recover(
            points,
            model.masses,
            &mut self.contact_impulses,
            &mut self.body_moves,
        );
        self.implicit = scratch;
        outcome
    }
}

/// What phase 1 left at the state a step starts from: the forces on the springs' two ends
/// and each hinge's gradient.
#[derive(Clone, Copy)]
struct Forces<'a> {
    fa: &'a super::parts::Soa3,
    fb: &'a super::parts::Soa3,
    hinge_gradients: &'a [[Vec3; 4]],
    curvature_normals: &'a [Vec3],
}

/// Builds the step's system in `s`: the right-hand side h·(f₀ + h·∂f/∂x·v₀) from the forces
/// `fa` + `fb`, each point's own part, the springs' blocks, the gas's gradient and the
/// preconditioner; returns the gas's rank-one scale (0 without gas).
fn assemble(
    s: &mut Scratch,
    Forces {
        fa,
        fb,
        hinge_gradients,
        curvature_normals,
    }: Forces<'_>,
    points: &PointState,
    model: StepParts<'_>,
    config: &SolverConfig,
    h: f64,
) -> f64 {
    let n = points.len();
    let h2 = h * h;
    let drag = f64::from(config.drag);
    let axial = config.damping_model == DampingModel::Axial;
    let vel = |i: usize| points.v.get(i).as_dvec3();

    // Right-hand side h·f₀ and each point's own part: M + h·μ·M and the anchors.
    for i in 0..n {
        let f = (fa.get(i) + fb.get(i)).as_dvec3();
        s.rhs[i] = h * f;
        s.own[i] = f64::from(model.masses.mass[i]) * (1.0 + h * drag);
        s.fixed[i] = model.masses.inv_mass[i] == 0.0;
    }
    for a in model.anchors.live() {
        let i = a.point as usize;
        let (k, kd) = (f64::from(a.stiffness), f64::from(a.damping));
        s.own[i] += h * kd + h2 * k;
        s.rhs[i] -= h2 * k * vel(i);
    }
    // The diagonal blocks start as the own parts; each spring adds its block to both ends.
    let mut diag = std::mem::take(&mut s.diag);
    for (d, &own) in diag.iter_mut().zip(&s.own) {
        *d = Sym3::scaled_identity(own);
    }
    let layout = &model.springs.layout;
    for (sp, block) in s.blocks.iter_mut().enumerate() {
        let (a, b) = (layout.a[sp] as usize, layout.b[sp] as usize);
        let k = f64::from(layout.k[sp]);
        let kd = f64::from(layout.kd[sp]);
        let d = (points.x.get(b) - points.x.get(a)).as_dvec3();
        let len = d.length();
        // K = (k − t)·ûûᵀ + t·I, t = k·max(0, 1 − l⁰/l): a compressed spring's negative
        // transverse stiffness dropped; coincident ends: K = k·I, D = k_d·I.
        let (u, transverse, damp_along, damp_across) = if len > f64::from(COINCIDENT_DISTANCE) {
            let inv_len = 1.0 / len;
            let transverse = k * (1.0 - f64::from(layout.rest[sp]) * inv_len).max(0.0);
            let (along, across) = if axial { (kd, 0.0) } else { (0.0, kd) };
            (d * inv_len, transverse, along, across)
        } else {
            (DVec3::X, k, 0.0, kd)
        };
        *block = SpringBlock {
            u,
            along: h * damp_along + h2 * (k - transverse),
            across: h * damp_across + h2 * transverse,
        };
        let c = block.sym3();
        diag[a] = diag[a].add(c);
        diag[b] = diag[b].add(c);
        // h²·K·(v_b − v_a) towards a, its opposite towards b.
        let stiffness = SpringBlock {
            u,
            along: k - transverse,
            across: transverse,
        };
        let kdv = h2 * stiffness.mul(vel(b) - vel(a));
        s.rhs[a] += kdv;
        s.rhs[b] -= kdv;
    }
    // The couplings: h²·JᵀCJ in the matrix (its diagonal blocks at the corner each pair of
    // edges shares), and −h²·JᵀCJ·v₀ on the right-hand side.
    let couplings = &model.springs.couplings;
    couplings.linearised(layout, points, h, &mut s.couplings);
    for (block, ends) in s.couplings.iter().zip(couplings.ends(layout)) {
        let rates = [0, 1, 2].map(|i| block.u[i].dot(vel(ends[i][0]) - vel(ends[i][1])));
        let w = block.weights(rates);
        for ((u, [a, b]), w) in block.u.iter().zip(ends).zip(w) {
            s.rhs[a] -= w * *u;
            s.rhs[b] += w * *u;
        }
        for (i, j, c, [sign_i, sign_j], corner) in block.corners(ends) {
            let outer = Sym3::symmetric_outer(block.u[i], block.u[j], c * sign_i * sign_j);
            diag[corner] = diag[corner].add(outer);
        }
    }
    // The gas: h²c·ggᵀ in the matrix (its diagonal blocks in the preconditioner too), and
    // its part of h²·∂f/∂x·v₀ on the right-hand side.
    let gas_scale = match model.pressure {
        Some(gas) => h2 * gas.linearised(points, &mut s.gas),
        None => {
            s.gas.clear();
            s.gas.resize(n, DVec3::ZERO);
            0.0
        }
    };
    // The hinges: s·∇θ∇θᵀ in the matrix, −h²·2k·∇θ(∇θ·v₀) on the right-hand side.
    let hinges = &model.springs.hinges;
    hinges.linearised(hinge_gradients, points, h, &mut s.hinges);
    for (block, ends) in s.hinges.iter().zip(&hinges.ends) {
        for (&i, &g) in ends.iter().zip(&block.gradient) {
            let i = i as usize;
            s.rhs[i] -= block.rhs * g;
            diag[i] = diag[i].add(Sym3::outer_plus_identity(g, block.scale, 0.0));
        }
    }
    // Curvature bending: scale·JᵀKJ in the matrix (its diagonal blocks too), and
    // −h²·JᵀKJ·v₀ on the right-hand side.
    let curvatures = &model.springs.curvatures;
    curvatures.linearised(curvature_normals, h, &mut s.curvatures);
    if !s.curvatures.is_empty() {
        s.velocities.clear();
        s.velocities.extend((0..n).map(vel));
        curvatures.add_rhs(&s.curvatures, &s.velocities, h, &mut s.rhs);
        curvatures.diagonal(&s.curvatures, |i, normal, scale| {
            diag[i] = diag[i].add(Sym3::outer_plus_identity(normal, scale, 0.0));
        });
    }
    if gas_scale > 0.0 {
        let rate: f64 = (0..n)
            .filter(|&i| !s.fixed[i])
            .map(|i| s.gas[i].dot(vel(i)))
            .sum();
        for (i, d) in diag.iter_mut().enumerate() {
            let g = s.gas[i];
            s.rhs[i] -= gas_scale * rate * g;
            *d = d.add(Sym3::outer_plus_identity(g, gas_scale, 0.0));
        }
    }
    for (i, d) in diag.iter().enumerate() {
        if s.fixed[i] {
            s.pin_rhs[i] = s.rhs[i];
            s.rhs[i] = DVec3::ZERO;
            s.diag_inv[i] = Sym3::default();
            s.dv[i] = DVec3::ZERO;
        } else {
            s.diag_inv[i] = d.inverse();
        }
    }
    s.diag = diag;
    gas_scale
}

/// Below this share of its trace an axis of the inertia tensor counts as empty (the points
/// on one line turn about it with no inertia, and no torque can act about it).
const FLAT_INERTIA: f64 = 1e-12;

/// Makes the step's internal impulses sum to no force and no torque, as the internal forces
/// themselves do (springs and their axial damping are central; hinges and the gas depend only
/// on the shape): backward Euler, linearised and solved to a tolerance, does not, and a free
/// surface turning at ω loses about (h·ω)² of its spin a step to the linearisation alone
/// (8.8 % over 5 s at 1 rad/s and 60 Hz, measured). Each point's internal impulse is read
/// from the solved Δv as Jᵢ = m'ᵢ·Δvᵢ − h·f_ext,ᵢ (m' the point's own part of the matrix:
/// mass, drag and anchors; f_ext gravity, drag, the anchors and the external forces, at the
/// start of the step), and a rigid motion u + ω×(x − c), weighted by m', is added to Δv so
/// that ΣJ = 0 and Σ(x − c)×J = 0. Then L changes only by the external torque. Not with a
/// fixed point (it takes the impulses the surface gives it) nor with eq 3's damping (whose
/// relative velocity damps rotation on purpose).
fn keep_momenta(
    s: &mut Scratch,
    points: &PointState,
    model: StepParts<'_>,
    external: &ExternalForces,
    config: &SolverConfig,
    h: f64,
) {
    let n = points.len();
    if s.fixed.iter().any(|&f| f) {
        return;
    }
    // h·f_ext at the start of the step, less the anchors' h²·k·v₀ that the matrix carries.
    let gravity = config.gravity.as_dvec3();
    let drag = f64::from(config.drag);
    // Kept in the solve's spent search-direction buffer: no allocation a step.
    let pushed = &mut s.q;
    for (i, p) in pushed.iter_mut().enumerate().take(n) {
        let m = f64::from(model.masses.mass[i]);
        let v = points.v.get(i).as_dvec3();
        let e = if external.any {
            external.f.get(i).as_dvec3()
        } else {
            DVec3::ZERO
        };
        *p = h * (m * (gravity - drag * v) + e);
    }
    for a in model.anchors.live() {
        let i = a.point as usize;
        let (x, v) = (points.x.get(i), points.v.get(i));
        let f = a.stiffness * (a.target - x) - a.damping * v;
        pushed[i] += h * f.as_dvec3() - h * h * f64::from(a.stiffness) * v.as_dvec3();
    }
    let (mut weight, mut centre, mut sum) = (0.0, DVec3::ZERO, DVec3::ZERO);
    for i in 0..n {
        let x = points.x.get(i).as_dvec3();
        weight += s.own[i];
        centre += s.own[i] * x;
        sum += s.own[i] * s.dv[i] - s.q[i];
    }
    if weight <= 0.0 || !weight.is_finite() {
        return;
    }
    centre /= weight;
    let (mut torque, mut inertia) = (DVec3::ZERO, DMat3::ZERO);
    for i in 0..n {
        let r = points.x.get(i).as_dvec3() - centre;
        torque += r.cross(s.own[i] * s.dv[i] - s.q[i]);
        inertia += point_inertia(s.own[i], r);
    }
    let spin = cancelling_spin(inertia, torque);
    let shift = -sum / weight;
    if !(shift.is_finite() && spin.is_finite()) {
        return;
    }
    for i in 0..n {
        let r = points.x.get(i).as_dvec3() - centre;
        s.dv[i] += shift + spin.cross(r);
    }
}

/// The inertia tensor of mass `m` at `r` from the centre.
pub(super) fn point_inertia(m: f64, r: DVec3) -> DMat3 {
    m * (DMat3::from_diagonal(DVec3::splat(r.length_squared())) - outer(r, r))
}

/// The spin whose angular momentum cancels `torque` (an impulse's moment) for a body of
/// `inertia`, regularised by [`FLAT_INERTIA`] of its trace so that a flat or linear body
/// still inverts; none for a body without inertia.
pub(super) fn cancelling_spin(inertia: DMat3, torque: DVec3) -> DVec3 {
    let trace = inertia.x_axis.x + inertia.y_axis.y + inertia.z_axis.z;
    if trace > 0.0 {
        let regularised = inertia + DMat3::from_diagonal(DVec3::splat(FLAT_INERTIA * trace));
        -(regularised.inverse() * torque)
    } else {
        DVec3::ZERO
    }
}

fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// Solves the step's system by preconditioned conjugate gradient, from the warm start, with
/// the points the `contacts` hold held.
fn conjugate_gradient(
    config: &SolverConfig,
    springs: &Springs,
    s: &mut Scratch,
    gas_scale: f64,
    contacts: &mut Contacts<'_>,
) -> CgOutcome {
    let b_norm = dot(&s.rhs, &s.rhs).sqrt();
    if !b_norm.is_finite() || (b_norm == 0.0 && contacts.is_empty()) {
        s.reset_warm_start();
        return CgOutcome {
            iterations: 0,
            converged: b_norm == 0.0,
        };
    }
    with_system(springs, s, gas_scale, |system, s| {
        s.sweeps.invalidate();
        if contacts.is_empty() {
            let tolerance = f64::from(config.cg_tolerance) * b_norm;
            iterate(config, system, s, tolerance, b_norm, false)
        } else {
            contacts.solve(config, system, s, b_norm)
        }
    })
}

/// Adds to `out` what held each fixed point in the solved step: its row of A·Δv − b (Δv is
/// zero there), the impulse m·Δv − h·f_end the point took besides the step's forces.
fn pin_impulses(springs: &Springs, s: &mut Scratch, gas_scale: f64, out: &mut [Vec3]) {
    if !s.fixed.iter().any(|&f| f) {
        return;
    }
    with_system(springs, s, gas_scale, |system, s| {
        let dv = std::mem::take(&mut s.dv);
        system.apply_rows::<true>(&dv, &mut s.q);
        s.dv = dv;
        for (i, j) in out.iter_mut().enumerate() {
            if system.fixed[i] {
                *j += (s.q[i] - s.pin_rhs[i]).as_vec3();
            }
        }
    });
}

/// Runs `f` with the step's matrix assembled in `s` ([`System`]), the parts it borrows taken
/// out of `s` meanwhile (read them through the system).
fn with_system<R>(
    springs: &Springs,
    s: &mut Scratch,
    gas_scale: f64,
    f: impl FnOnce(&System<'_>, &mut Scratch) -> R,
) -> R {
    let own = std::mem::take(&mut s.own);
    let blocks = std::mem::take(&mut s.blocks);
    let fixed = std::mem::take(&mut s.fixed);
    let gas = std::mem::take(&mut s.gas);
    let hinges = std::mem::take(&mut s.hinges);
    let couplings = std::mem::take(&mut s.couplings);
    let curvature_blocks = std::mem::take(&mut s.curvatures);
    let layout = &springs.layout;
    let system = System {
        own: &own,
        blocks: &blocks,
        a_end: &layout.a,
        b_end: &layout.b,
        fixed: &fixed,
        gas: &gas,
        gas_scale,
        hinges: &hinges,
        hinge_ends: &springs.hinges.ends,
        couplings: &couplings,
        coupling_springs: &springs.couplings.springs,
        curvatures: &springs.curvatures,
        curvature_blocks: &curvature_blocks,
    };
    let out = f(&system, s);
    s.own = own;
    s.blocks = blocks;
    s.fixed = fixed;
    s.gas = gas;
    s.hinges = hinges;
    s.couplings = couplings;
    s.curvatures = curvature_blocks;
    out
}

/// Iterations of block-Jacobi conjugate gradient before a solve restarts with symmetric
/// Gauss–Seidel (`sweeps`), where the bending is the paper's bend springs. Easy solves (the
/// paper's sphere takes about nine a step) never pay for the Gauss–Seidel blocks, which cost
/// more than the iterations they save there; hard ones (fine or uneven networks) get the
/// stronger preconditioner. Measured by callgrind on the poked sphere (2026-12-03),
/// instructions against block Jacobi alone: at 338 points unchanged; at 2000 points with
/// bend springs +8 % (+6 % after 8, +5 % after 16, +3 % with Gauss–Seidel throughout), with
/// hinges −18 % (−20 %, −15 %, −24 % throughout). So hinges and curvature bending
/// ([`System::bends`]) take Gauss–Seidel from the start: `bench plugin --dense 100000
/// --sim 2000` (2026-12-04, one run each) 26.2 → 18.5 CG iterations a step with hinges, and
/// with curvature 20.6 → 12.3 (34.5 before its stencils joined the sweeps).
const JACOBI_ITERATIONS: u32 = 12;

/// z = P⁻¹·r in `s`: symmetric Gauss–Seidel, or block Jacobi (each point's whole 3×3
/// diagonal block inverted); returns r·z.
fn precondition(s: &mut Scratch, gauss_seidel: bool) -> f64 {
    if gauss_seidel {
        return s.sweeps.precondition(&s.diag_inv, &s.r, &mut s.z);
    }
    let mut rz = 0.0;
    for ((z, r), d) in s.z.iter_mut().zip(&s.r).zip(&s.diag_inv) {
        *z = d.mul(*r);
        rz += r.dot(*z);
    }
    rz
}

/// Removes from each vector its part along its point's contact normal, and along its second
/// axis where it has one (Baraff & Witkin 1998's filter S = I − n̂n̂ᵀ − êêᵀ; zero axes leave
/// the vector alone).
fn filter(normal: &[DVec3], normal2: &[DVec3], v: &mut [DVec3]) {
    for ((v, n), e) in v.iter_mut().zip(normal).zip(normal2) {
        *v -= *n * n.dot(*v) + *e * e.dot(*v);
    }
}

/// Preconditioned conjugate gradient on `system` from the warm start in `s.dv`. `filtered`:
/// the points with a contact normal in `s.normal` keep the part of `s.dv` along it
/// (Baraff & Witkin 1998's modified PCG: the residual and every search direction are
/// filtered), and the warm start is kept as it is.
fn iterate(
    config: &SolverConfig,
    system: &System<'_>,
    s: &mut Scratch,
    tolerance: f64,
    b_norm: f64,
    filtered: bool,
) -> CgOutcome {
    // r = b − A·dv from the warm start; keep it only if it beats starting from zero.
    system.apply(&s.dv, &mut s.q);
    for i in 0..s.r.len() {
        s.r[i] = s.rhs[i] - s.q[i];
    }
    if filtered {
        filter(&s.normal, &s.normal2, &mut s.r);
    } else if dot(&s.r, &s.r).sqrt() >= b_norm {
        s.reset_warm_start();
        s.r.copy_from_slice(&s.rhs);
    }
    // Block Jacobi first; a solve that takes more than JACOBI_ITERATIONS restarts with
    // symmetric Gauss–Seidel (and an earlier pass's Gauss–Seidel is kept). Bending stiff
    // enough to need it (hinges, curvature) gets Gauss–Seidel from the start.
    let mut gauss_seidel = s.sweeps.is_assembled();
    if !gauss_seidel && system.bends() {
        s.sweeps.assemble(s.r.len(), system);
        gauss_seidel = true;
    }
    let mut rz = precondition(s, gauss_seidel);
    if filtered {
        filter(&s.normal, &s.normal2, &mut s.z);
    }
    s.p.copy_from_slice(&s.z);
    let mut iterations = 0;
    let mut converged = dot(&s.r, &s.r).sqrt() <= tolerance;
    while !converged && iterations < config.cg_max_iterations {
        // p is filtered, so p·(S·A·p) = p·A·p.
        let pq = system.apply(&s.p, &mut s.q);
        if filtered {
            filter(&s.normal, &s.normal2, &mut s.q);
        }
        let descends = pq > 0.0;
        if !descends {
            break;
        }
        let alpha = rz / pq;
        let mut rr = 0.0;
        for (((dv, r), p), q) in s.dv.iter_mut().zip(&mut s.r).zip(&s.p).zip(&s.q) {
            *dv += alpha * *p;
            *r -= alpha * *q;
            rr += r.dot(*r);
        }
        iterations += 1;
        if rr.sqrt() <= tolerance {
            converged = true;
            break;
        }
        let restart = !gauss_seidel && iterations == JACOBI_ITERATIONS;
        if restart {
            s.sweeps.assemble(s.r.len(), system);
            gauss_seidel = true;
        }
        let rz_new = precondition(s, gauss_seidel);
        if filtered {
            filter(&s.normal, &s.normal2, &mut s.z);
        }
        // A new preconditioner starts the search directions again from the iterate.
        let beta = if restart { 0.0 } else { rz_new / rz };
        rz = rz_new;
        for (p, z) in s.p.iter_mut().zip(&s.z) {
            *p = *z + beta * *p;
        }
    }
    if s.dv.iter().any(|d| !d.is_finite()) {
        s.reset_warm_start();
        converged = false;
    }
    CgOutcome {
        iterations,
        converged,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use glam::Vec3;

    use crate::core::solver::parts::{
        Anchors, HingeGeometry, HingeSpec, Hinges, Masses, Pressure, Springs,
    };
    use crate::core::solver::{Anchor, CouplingSpec, SpringSpec};

    /// The dense 3n×3n matrix of implicit Euler's step written out from its definition
    /// (M + h·μ·M, anchors, h·D + h²·K of each spring on its two ends and negated between
    /// them (D = k_d·I, or k_d·ûûᵀ along the spring), the gas's h²c·ggᵀ, each hinge's
    /// (h·c + h²·2k)·∇θ∇θᵀ, with `couplings` each coupling's h²·Cᵢⱼ·(gᵢgⱼᵀ + gⱼgᵢᵀ) (gᵢ:
    /// edge i's direction on its a end, negated on its b end); fixed rows and columns zero),
    /// entry (3i + r, 3j + c).
    fn reference_matrix(
        points: &PointState,
        model: StepParts<'_>,
        config: &SolverConfig,
        h: f64,
        (gas, gas_scale): (&[DVec3], f64),
        couplings: Coupled,
    ) -> Vec<Vec<f64>> {
        let n = points.len();
        let mut m = vec![vec![0.0; 3 * n]; 3 * n];
        let mut add = |i: usize, j: usize, block: DMat3, sign: f64| {
            for r in 0..3 {
                for c in 0..3 {
                    m[3 * i + r][3 * j + c] += sign * block.col(c)[r];
                }
            }
        };
        for i in 0..n {
            let own = f64::from(model.masses.mass[i]) * (1.0 + h * f64::from(config.drag));
            add(i, i, DMat3::IDENTITY * own, 1.0);
        }
        for a in model.anchors.live() {
            let k = h * f64::from(a.damping) + h * h * f64::from(a.stiffness);
            add(a.point as usize, a.point as usize, DMat3::IDENTITY * k, 1.0);
        }
        for s in model.springs.iter().map(|(_, s)| s) {
            let (a, b) = (s.a as usize, s.b as usize);
            let d = (points.position(b) - points.position(a)).as_dvec3();
            let (len, k) = (d.length(), f64::from(s.stiffness));
            let u = d / len;
            let uu = DMat3::from_cols(u * u.x, u * u.y, u * u.z);
            let transverse = k * (1.0 - f64::from(s.rest_length) / len).max(0.0);
            let stiffness = uu * k + (DMat3::IDENTITY - uu) * transverse;
            let damping = match config.damping_model {
                DampingModel::Relative => DMat3::IDENTITY,
                DampingModel::Axial => uu,
            } * f64::from(s.damping);
            let c = damping * h + stiffness * (h * h);
            add(a, a, c, 1.0);
            add(b, b, c, 1.0);
            add(a, b, c, -1.0);
            add(b, a, c, -1.0);
        }
        for i in 0..n {
            for j in 0..n {
                let (gi, gj) = (gas[i], gas[j]);
                add(
                    i,
                    j,
                    DMat3::from_cols(gi * gj.x, gi * gj.y, gi * gj.z),
                    gas_scale,
                );
            }
        }
        // Each hinge: (h·c + h²·2k)·∇θ∇θᵀ over its four points.
        for spec in model.springs.hinges().iter() {
            let ends = [spec.edge[0], spec.edge[1], spec.wings[0], spec.wings[1]];
            let g = HingeGeometry::at(ends.map(|i| points.position(i as usize))).unwrap();
            let scale = h * f64::from(spec.damping) + h * h * 2.0 * f64::from(spec.stiffness);
            for (j, &a) in ends.iter().enumerate() {
                for (l, &b) in ends.iter().enumerate() {
                    let (ga, gb) = (g.gradient[j].as_dvec3(), g.gradient[l].as_dvec3());
                    let block = DMat3::from_cols(ga * gb.x, ga * gb.y, ga * gb.z);
                    add(a as usize, b as usize, block, scale);
                }
            }
        }
        let specs: Vec<SpringSpec> = {
            let mut by_index = vec![None; model.springs.len()];
            for (i, spec) in model.springs.iter() {
                by_index[i] = Some(spec);
            }
            by_index.into_iter().map(Option::unwrap).collect()
        };
        for coupling in model
            .springs
            .couplings()
            .iter()
            .filter(|_| couplings != Coupled::Not)
        {
            let edge = |e: usize| {
                let s = specs[coupling.springs[e] as usize];
                let d = (points.position(s.b as usize) - points.position(s.a as usize)).as_dvec3();
                (s.a as usize, s.b as usize, d.normalize())
            };
            for (&(i, j), &c) in [(0, 1), (1, 2), (2, 0)].iter().zip(&coupling.coupling) {
                let ((ai, bi, ui), (aj, bj, uj)) = (edge(i), edge(j));
                let c = h * h * f64::from(c);
                for (p, sp, u, q, sq, w) in [
                    (ai, 1.0, ui, aj, 1.0, uj),
                    (bi, -1.0, ui, aj, 1.0, uj),
                    (ai, 1.0, ui, bj, -1.0, uj),
                    (bi, -1.0, ui, bj, -1.0, uj),
                ] {
                    let block = DMat3::from_cols(u * w.x, u * w.y, u * w.z);
                    add(p, q, block, c * sp * sq);
                    add(q, p, block.transpose(), c * sp * sq);
                }
            }
        }
        for i in (0..n).filter(|&i| model.masses.inv_mass[i] == 0.0) {
            for k in 0..3 * n {
                m[3 * i..3 * i + 3].iter_mut().for_each(|row| row[k] = 0.0);
                m[k][3 * i..3 * i + 3].iter_mut().for_each(|e| *e = 0.0);
            }
        }
        m
    }

    /// Which of the couplings' entries [`reference_matrix`] writes.
    #[derive(Clone, Copy, PartialEq)]
    enum Coupled {
        Not,
        All,
    }

    #[test]
    fn the_springs_own_form_applies_the_whole_matrix_and_the_solve_meets_its_tolerance() {
        // A gas-filled tetrahedron with an apex point: one spring compressed (its transverse
        // stiffness dropped), one stretched, an anchor, one point fixed.
        let x = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.1, 0.0),
            Vec3::new(0.2, 1.0, 0.1),
            Vec3::new(0.3, 0.2, 1.1),
            Vec3::new(0.5, 0.5, 1.6),
        ];
        let mut points = PointState::new(&x).unwrap();
        for (i, v) in [(1, Vec3::X), (2, Vec3::new(0.0, -0.5, 0.3)), (4, Vec3::Z)] {
            points.set_velocity(i, v).unwrap();
        }
        let edges = [
            (0, 1),
            (0, 2),
            (0, 3),
            (1, 2),
            (1, 3),
            (2, 3),
            (3, 4),
            (2, 4),
        ];
        let specs: Vec<SpringSpec> = edges
            .iter()
            .enumerate()
            .map(|(s, &(a, b))| {
                let length = x[a as usize].distance(x[b as usize]);
                SpringSpec {
                    a,
                    b,
                    rest_length: length * [1.3, 0.8, 1.0][s % 3],
                    stiffness: 500.0 + 100.0 * s as f32,
                    damping: 2.0 + s as f32,
                }
            })
            .collect();
        let mut springs = Springs::new(&specs, x.len()).unwrap();
        // Two hinges, one bent off its rest angle and one at a point the gas leaves out.
        let hinge = |edge, wings, rest_angle, stiffness| HingeSpec {
            edge,
            wings,
            rest_angle,
            stiffness,
            damping: 0.05 * stiffness,
        };
        let hinges = [
            hinge([0, 1], [3, 2], 0.3, 4.0),
            hinge([2, 3], [1, 4], -0.2, 9.0),
        ];
        springs.set_hinges(Hinges::new(&hinges, &x).unwrap());
        // Couplings of both signs on the triangles (1, 2, 3) and (2, 3, 4).
        springs
            .set_couplings(&[
                CouplingSpec {
                    springs: [3, 5, 4],
                    coupling: [40.0, -30.0, 25.0],
                },
                CouplingSpec {
                    springs: [5, 6, 7],
                    coupling: [-20.0, 15.0, 35.0],
                },
            ])
            .unwrap();
        let mut masses = Masses::new(&[0.5, 1.0, 2.0, 0.7, 0.3]).unwrap();
        masses.set_pinned(0, true).unwrap();
        let mut anchors = Anchors::default();
        let anchor = Anchor {
            point: 4,
            target: Vec3::ONE,
            stiffness: 80.0,
            damping: 1.5,
        };
        anchors.add(anchor, x.len()).unwrap();
        let gas = Pressure::new(
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
            &points,
            50.0,
        )
        .unwrap();
        let model = StepParts {
            masses: &masses,
            springs: &springs,
            anchors: &anchors,
            pressure: Some(&gas),
            rest: None,
        };
        for damping_model in [DampingModel::Relative, DampingModel::Axial] {
            let config = SolverConfig {
                damping_model,
                drag: 0.3,
                ..SolverConfig::default()
            };
            let mut stepper = Stepper::new(config, x.len()).unwrap();
            stepper.accumulate_forces(&points, model).unwrap();
            let mut s = Scratch::default();
            s.resize(x.len(), springs.len());
            let h = 1.0 / 30.0;
            let forces = Forces {
                fa: &stepper.fa,
                fb: &stepper.fb,
                hinge_gradients: &stepper.hinge_gradients,
                curvature_normals: &stepper.curvature_normals,
            };
            let gas_scale = assemble(&mut s, forces, &points, model, &config, h);
            assert!(gas_scale > 0.0);
            let system = System {
                own: &s.own,
                blocks: &s.blocks,
                a_end: &springs.layout.a,
                b_end: &springs.layout.b,
                fixed: &s.fixed,
                gas: &s.gas,
                gas_scale,
                hinges: &s.hinges,
                hinge_ends: &springs.hinges.ends,
                couplings: &s.couplings,
                coupling_springs: &springs.couplings.springs,
                curvatures: &springs.curvatures,
                curvature_blocks: &s.curvatures,
            };
            let gas = (s.gas.as_slice(), gas_scale);
            let reference = reference_matrix(&points, model, &config, h, gas, Coupled::All);
            // The preconditioner has the whole matrix's blocks.
            let preconditioned = &reference;
            let n = x.len();
            // Column by column: A·e_k against the written-out matrix.
            for k in (0..3 * n).filter(|k| k / 3 != 0) {
                let mut e = vec![DVec3::ZERO; n];
                e[k / 3][k % 3] = 1.0;
                let mut y = vec![DVec3::ZERO; n];
                let ey = system.apply(&e, &mut y);
                assert!(
                    (ey - reference[k][k]).abs() < 1e-12,
                    "{damping_model:?} {k}"
                );
                for (i, yi) in y.iter().enumerate() {
                    for r in 0..3 {
                        let want = reference[3 * i + r][k];
                        assert!(
                            (yi[r] - want).abs() < 1e-9 * (1.0 + want.abs()),
                            "{k} {i} {r}"
                        );
                    }
                }
            }
            // The right-hand side h·(f₀ + h·∂f/∂x·v₀) depends on v₀ as −(A − M)·v₀ does (the
            // damping in f₀, the stiffness in the second term): against the same state at rest.
            let mut still = points.clone();
            for i in 0..n {
                still.set_velocity(i, Vec3::ZERO).unwrap();
            }
            let mut at_rest = Stepper::new(config, n).unwrap();
            at_rest.accumulate_forces(&still, model).unwrap();
            let mut s0 = Scratch::default();
            s0.resize(n, springs.len());
            let forces0 = Forces {
                fa: &at_rest.fa,
                fb: &at_rest.fb,
                hinge_gradients: &at_rest.hinge_gradients,
                curvature_normals: &at_rest.curvature_normals,
            };
            assemble(&mut s0, forces0, &still, model, &config, h);
            for i in 1..n {
                for r in 0..3 {
                    let row = 3 * i + r;
                    let mass = f64::from(model.masses.mass[i]);
                    let av: f64 = (0..3 * n)
                        .map(|c| {
                            let m = if c == row { mass } else { 0.0 };
                            (reference[row][c] - m) * f64::from(points.velocity(c / 3)[c % 3])
                        })
                        .sum();
                    let change = s.rhs[i][r] - s0.rhs[i][r];
                    assert!(
                        // f₀ is summed in f32.
                        (change + av).abs() < 1e-4 * (1.0 + av.abs()),
                        "{damping_model:?} row {row}: {change} against {}",
                        -av
                    );
                }
            }
            // The preconditioner inverts the written-out diagonal blocks.
            for i in 1..n {
                let block = DMat3::from_cols_array_2d(
                    &[0, 1, 2].map(|c| [0, 1, 2].map(|r| preconditioned[3 * i + r][3 * i + c])),
                );
                let back = block
                    * DMat3::from_cols_array_2d(&[0, 1, 2].map(|c| {
                        let v = s.diag_inv[i].mul(DVec3::AXES[c]);
                        [v.x, v.y, v.z]
                    }));
                assert!(back.abs_diff_eq(DMat3::IDENTITY, 1e-9), "{i}: {back}");
            }
            // The preconditioner is (D + L)·D⁻¹·(D + Lᵀ) of the written-out matrix: D its
            // diagonal blocks (the gas's included), L its strictly lower blocks without the
            // gas's dense term. Checked on the free points' rows: (D + L)·D⁻¹·(D + Lᵀ)·z = r.
            let sparse = reference_matrix(&points, model, &config, h, (&s.gas, 0.0), Coupled::All);
            s.sweeps.assemble(n, &system);
            let r: Vec<DVec3> = (0..n)
                .map(|i| DVec3::new(1.0 + i as f64, -0.5 * i as f64, 0.25))
                .collect();
            let mut z = vec![DVec3::ZERO; n];
            let rz = s.sweeps.precondition(&s.diag_inv, &r, &mut z);
            assert_eq!(z[0], DVec3::ZERO, "the fixed point's z is zero");
            assert!((rz - dot(&r[1..], &z[1..])).abs() < 1e-12 * (1.0 + rz.abs()));
            let block = |m: &[Vec<f64>], i: usize, j: usize| {
                DMat3::from_cols_array_2d(
                    &[0, 1, 2].map(|c| [0, 1, 2].map(|r| m[3 * i + r][3 * j + c])),
                )
            };
            // w = (D + Lᵀ)·z, then u = D⁻¹·w, then (D + L)·u.
            let w: Vec<DVec3> = (0..n)
                .map(|i| {
                    let upper: DVec3 = (i + 1..n).map(|j| block(&sparse, i, j) * z[j]).sum();
                    block(preconditioned, i, i) * z[i] + upper
                })
                .collect();
            let u: Vec<DVec3> = (0..n).map(|i| s.diag_inv[i].mul(w[i])).collect();
            for i in 1..n {
                let lower: DVec3 = (1..i).map(|j| block(&sparse, i, j) * u[j]).sum();
                let back = block(preconditioned, i, i) * u[i] + lower;
                assert!(
                    (back - r[i]).length() < 1e-9 * r[i].length(),
                    "{i}: {back} vs {}",
                    r[i]
                );
            }
            // The solve meets its tolerance on the written-out system.
            let none = ExternalForces::zeros(points.len());
            let mut contacts = Contacts::new(&none, &points, model, 1.0 / 60.0);
            let outcome = conjugate_gradient(&config, &springs, &mut s, gas_scale, &mut contacts);
            assert!(outcome.converged);
            let b_norm = dot(&s.rhs, &s.rhs).sqrt();
            // Rows of the fixed point 0 are zero on both sides.
            let mut residual = 0.0;
            for (row, entries) in reference.iter().enumerate().skip(3) {
                let ax: f64 = entries
                    .iter()
                    .enumerate()
                    .map(|(c, e)| e * s.dv[c / 3][c % 3])
                    .sum();
                residual += (s.rhs[row / 3][row % 3] - ax).powi(2);
            }
            assert!(
                residual.sqrt() <= f64::from(config.cg_tolerance) * b_norm * 1.0001,
                "{} against {b_norm}",
                residual.sqrt()
            );
            assert_eq!(s.dv[0], DVec3::ZERO, "the fixed point does not move");
        }
    }

    #[test]
    fn sym3_inverse_round_trips() {
        let m = Sym3::outer_plus_identity(DVec3::new(0.6, 0.0, 0.8), 3.0, 2.0);
        let inv = m.inverse();
        let v = DVec3::new(1.0, -2.0, 0.5);
        assert!((m.mul(inv.mul(v)) - v).length() < 1e-12);
    }
}
