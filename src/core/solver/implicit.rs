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
//! Ko 2002). The preconditioner inverts each point's 3×3 diagonal block. Fixed points are
//! filtered out (their Δv is zero). The solve starts from the previous step's Δv when that
//! leaves a smaller residual than starting from zero.
//!
//! Gas pressure enters through its stiffness along the volume's gradient g: the force's
//! Jacobian −c·ggᵀ (c = κ·V₀/V², see `Pressure::linearised`) is a dense but rank-one term,
//! kept as g and h²c beside the sparse blocks and applied as h²c·g(g·p) in each product; its
//! diagonal blocks join the preconditioner. The pressure times the volume's Hessian is
//! indefinite and left out (Gauss–Newton), so the matrix stays positive definite.

use glam::{DMat3, DVec3};

use super::parts::PointState;
use super::springs::{COINCIDENT_DISTANCE, SpringLayout};
use super::stepper::{Model, Stepper};
use super::{DampingModel, SolverConfig};

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
    fn scaled_identity(s: f64) -> Self {
        Self {
            xx: s,
            yy: s,
            zz: s,
            ..Self::default()
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

    fn scale(self, s: f64) -> Self {
        Self {
            xx: self.xx * s,
            yy: self.yy * s,
            zz: self.zz * s,
            xy: self.xy * s,
            xz: self.xz * s,
            yz: self.yz * s,
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
    diag: Vec<Sym3>,
    diag_inv: Vec<Sym3>,
    blocks: Vec<Sym3>,
    /// The volume's gradient at each point, for the gas's rank-one term.
    gas: Vec<DVec3>,
}

impl Scratch {
    pub fn reset_warm_start(&mut self) {
        self.dv.iter_mut().for_each(|d| *d = DVec3::ZERO);
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
        self.diag.resize(n, Sym3::default());
        self.diag_inv.resize(n, Sym3::default());
        self.blocks.resize(springs, Sym3::default());
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

/// The system's matrix: diagonal blocks, one off-diagonal block per spring, and the gas's
/// rank-one term `scale`·ggᵀ (scale 0 without gas).
struct System<'a> {
    diag: &'a [Sym3],
    blocks: &'a [Sym3],
    a_end: &'a [u32],
    b_end: &'a [u32],
    fixed: &'a [bool],
    gas: &'a [DVec3],
    gas_scale: f64,
}

impl System<'_> {
    /// y = A·p (fixed rows zero).
    fn apply(&self, p: &[DVec3], y: &mut [DVec3]) {
        for i in 0..p.len() {
            y[i] = self.diag[i].mul(p[i]);
        }
        for (s, c) in self.blocks.iter().enumerate() {
            let (a, b) = (self.a_end[s] as usize, self.b_end[s] as usize);
            y[a] -= c.mul(p[b]);
            y[b] -= c.mul(p[a]);
        }
        if self.gas_scale > 0.0 {
            // p is zero at fixed points, so g·p sums the free ones.
            let along = self.gas_scale * dot(self.gas, p);
            for (yi, g) in y.iter_mut().zip(self.gas) {
                *yi += along * *g;
            }
        }
        for (yi, &f) in y.iter_mut().zip(self.fixed) {
            if f {
                *yi = DVec3::ZERO;
            }
        }
    }
}

impl Stepper {
    /// One implicit Euler step of length `h` from the forces in `fa` and `fb`.
    pub(super) fn implicit_step(
        &mut self,
        points: &mut PointState,
        model: Model<'_>,
        h: f32,
    ) -> CgOutcome {
        let n = points.len();
        let layout = &model.springs.layout;
        let springs = layout.len();
        let config = *self.config();
        let mut scratch = std::mem::take(&mut self.implicit);
        scratch.resize(n, springs);
        let h = f64::from(h);
        let h2 = h * h;
        let fixed: Vec<bool> = model.masses.inv_mass.iter().map(|&w| w == 0.0).collect();
        let drag = f64::from(config.drag);
        let axial = config.damping_model == DampingModel::Axial;
        let pos = |i: usize| points.x.get(i).as_dvec3();
        let vel = |i: usize| points.v.get(i).as_dvec3();

        // Right-hand side h·f₀ and the diagonal: M + h·μ·M.
        for i in 0..n {
            let f = DVec3::new(
                f64::from(self.fa.x[i] + self.fb.x[i]),
                f64::from(self.fa.y[i] + self.fb.y[i]),
                f64::from(self.fa.z[i] + self.fb.z[i]),
            );
            scratch.rhs[i] = h * f;
            let m = f64::from(model.masses.mass[i]);
            scratch.diag[i] = Sym3::scaled_identity(m * (1.0 + h * drag));
        }
        for a in model.anchors.live() {
            let i = a.point as usize;
            let (k, kd) = (f64::from(a.stiffness), f64::from(a.damping));
            scratch.diag[i] = scratch.diag[i].add(Sym3::scaled_identity(h * kd + h2 * k));
            scratch.rhs[i] -= h2 * k * vel(i);
        }
        for s in 0..springs {
            let (a, b) = (layout.a[s] as usize, layout.b[s] as usize);
            let k = f64::from(layout.k[s]);
            let kd = f64::from(layout.kd[s]);
            let rest = f64::from(layout.rest[s]);
            let d = pos(b) - pos(a);
            let len = d.length();
            let (stiffness, damping) = if len > f64::from(COINCIDENT_DISTANCE) {
                let u = d / len;
                let transverse = k * (1.0 - rest / len).max(0.0);
                let stiffness = Sym3::outer_plus_identity(u, k - transverse, transverse);
                let damping = if axial {
                    Sym3::outer_plus_identity(u, kd, 0.0)
                } else {
                    Sym3::scaled_identity(kd)
                };
                (stiffness, damping)
            } else {
                (Sym3::scaled_identity(k), Sym3::scaled_identity(kd))
            };
            let c = damping.scale(h).add(stiffness.scale(h2));
            scratch.blocks[s] = c;
            scratch.diag[a] = scratch.diag[a].add(c);
            scratch.diag[b] = scratch.diag[b].add(c);
            let kdv = h2 * stiffness.mul(vel(b) - vel(a));
            scratch.rhs[a] += kdv;
            scratch.rhs[b] -= kdv;
        }
        // The gas: h²c·ggᵀ in the matrix (its diagonal blocks in the preconditioner too), and
        // its part of h²·∂f/∂x·v₀ on the right-hand side.
        let gas_scale = match model.pressure {
            Some(gas) => h2 * gas.linearised(points, &mut scratch.gas),
            None => {
                scratch.gas.clear();
                scratch.gas.resize(n, DVec3::ZERO);
                0.0
            }
        };
        if gas_scale > 0.0 {
            let rate: f64 = (0..n)
                .filter(|&i| !fixed[i])
                .map(|i| scratch.gas[i].dot(vel(i)))
                .sum();
            for i in 0..n {
                let g = scratch.gas[i];
                scratch.rhs[i] -= gas_scale * rate * g;
                scratch.diag[i] = scratch.diag[i].add(Sym3::outer_plus_identity(g, gas_scale, 0.0));
            }
        }
        for (i, &fixed) in fixed.iter().enumerate() {
            if fixed {
                scratch.rhs[i] = DVec3::ZERO;
                scratch.diag_inv[i] = Sym3::default();
                scratch.dv[i] = DVec3::ZERO;
            } else {
                scratch.diag_inv[i] = scratch.diag[i].inverse();
            }
        }

        let outcome = conjugate_gradient(&config, layout, &mut scratch, &fixed, gas_scale);

        for (i, dv) in scratch.dv.iter().enumerate() {
            if fixed[i] {
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
        self.implicit = scratch;
        outcome
    }
}

/// Solves the step's system by preconditioned conjugate gradient, from the warm start.
fn conjugate_gradient(
    config: &SolverConfig,
    layout: &SpringLayout,
    s: &mut Scratch,
    fixed: &[bool],
    gas_scale: f64,
) -> CgOutcome {
    let b_norm = dot(&s.rhs, &s.rhs).sqrt();
    if b_norm == 0.0 || !b_norm.is_finite() {
        s.reset_warm_start();
        return CgOutcome {
            iterations: 0,
            converged: b_norm == 0.0,
        };
    }
    let tolerance = f64::from(config.cg_tolerance) * b_norm;
    let gas = std::mem::take(&mut s.gas);
    let outcome = solve(config, layout, s, fixed, &gas, gas_scale, tolerance, b_norm);
    s.gas = gas;
    outcome
}

/// The iterations of [`conjugate_gradient`] (gas gradient taken out of the scratch).
#[allow(clippy::too_many_arguments)]
fn solve(
    config: &SolverConfig,
    layout: &SpringLayout,
    s: &mut Scratch,
    fixed: &[bool],
    gas: &[DVec3],
    gas_scale: f64,
    tolerance: f64,
    b_norm: f64,
) -> CgOutcome {
    let diag = std::mem::take(&mut s.diag);
    let blocks = std::mem::take(&mut s.blocks);
    let system = System {
        diag: &diag,
        blocks: &blocks,
        a_end: &layout.a,
        b_end: &layout.b,
        fixed,
        gas,
        gas_scale,
    };
    let outcome = iterate(config, &system, s, tolerance, b_norm);
    s.diag = diag;
    s.blocks = blocks;
    outcome
}

/// Preconditioned conjugate gradient on `system` from the warm start in `s.dv`.
fn iterate(
    config: &SolverConfig,
    system: &System<'_>,
    s: &mut Scratch,
    tolerance: f64,
    b_norm: f64,
) -> CgOutcome {
    // r = b − A·dv from the warm start; keep it only if it beats starting from zero.
    system.apply(&s.dv, &mut s.q);
    for i in 0..s.r.len() {
        s.r[i] = s.rhs[i] - s.q[i];
    }
    let warm_start_helps = dot(&s.r, &s.r).sqrt() < b_norm;
    if !warm_start_helps {
        s.reset_warm_start();
        s.r.copy_from_slice(&s.rhs);
    }
    for i in 0..s.z.len() {
        s.z[i] = s.diag_inv[i].mul(s.r[i]);
    }
    s.p.copy_from_slice(&s.z);
    let mut rz = dot(&s.r, &s.z);
    let mut iterations = 0;
    let mut converged = dot(&s.r, &s.r).sqrt() <= tolerance;
    while !converged && iterations < config.cg_max_iterations {
        system.apply(&s.p, &mut s.q);
        let pq = dot(&s.p, &s.q);
        let descends = pq > 0.0;
        if !descends {
            break;
        }
        let alpha = rz / pq;
        for i in 0..s.dv.len() {
            s.dv[i] += alpha * s.p[i];
            s.r[i] -= alpha * s.q[i];
        }
        iterations += 1;
        if dot(&s.r, &s.r).sqrt() <= tolerance {
            converged = true;
            break;
        }
        for i in 0..s.z.len() {
            s.z[i] = s.diag_inv[i].mul(s.r[i]);
        }
        let rz_new = dot(&s.r, &s.z);
        let beta = rz_new / rz;
        rz = rz_new;
        for i in 0..s.p.len() {
            s.p[i] = s.z[i] + beta * s.p[i];
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

    #[test]
    fn sym3_inverse_round_trips() {
        let m = Sym3::outer_plus_identity(DVec3::new(0.6, 0.0, 0.8), 3.0, 2.0);
        let inv = m.inverse();
        let v = DVec3::new(1.0, -2.0, 0.5);
        assert!((m.mul(inv.mul(v)) - v).length() < 1e-12);
    }
}
