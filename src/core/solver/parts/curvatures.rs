//! Bending from each point's curvature: a plate's energy on a shape operator fitted to the
//! point's neighbourhood, so that it converges on uneven networks where hinges do not.
//!
//! A hinge's dihedral angle is the jump of the piecewise flat surface's normal across an
//! edge. On an uneven mesh the flat triangles' normals are off the smooth surface's by as
//! much as the jump itself, so Σ 3|ē|²/Ā·θ² depends on how the mesh is cut: §3's uneven
//! networks and a regular lattice of the same surface bend differently (5–13 % apart in
//! `point-springs-bench convergence`, with no sign of closing as points are added). This
//! part measures the curvature where it is smooth instead: at each point p, a quadric
//! h(u) = a·u₁ + b·u₂ + ½(c·u₁² + 2d·u₁u₂ + e·u₂²) fitted by least squares to its
//! neighbours' heights hⱼ = n·(xⱼ − p) over its tangent plane, the neighbours' tangent
//! coordinates uⱼ taken once from the rest shape. The fit is exact for any quadric, so its
//! Hessian S = [[c, d], [d, e]] is the shape operator to first order on any mesh; a normal
//! tilted off the true one only adds a linear term, which a and b take. The fit is linear in
//! the heights: S = Σⱼ wⱼ·hⱼ with weights wⱼ (three numbers each) fixed at rest.
//!
//! With the rest curvature S̄ (the same fit on the rest shape, so curved rest shapes keep
//! their shape) and ΔS = S − S̄, a point stores a plate's energy over its area A:
//! E = ½·D·A·(ν·(tr ΔS)² + (1 − ν)·ΔS:ΔS) = ½·ΔSᵀ·K·ΔS with ΔS = (Δc, Δd, Δe) and
//! K = D·A·[[1, 0, ν], [0, 2(1 − ν), 0], [ν, 0, 1]]. Its normal n is the unit area vector of
//! its fan of triangles (p, rⱼ, rⱼ₊₁) over its ring. The force is the energy's exact
//! gradient, through the normal too, so it keeps momentum and angular momentum and a rigid
//! motion costs nothing. Damping dissipates ½·β·Ṡᵀ·K·Ṡ (Ṡ with the normal held). Implicit
//! Euler takes the Gauss–Newton block JᵀKJ with the normal held (J: S's derivative), positive
//! semi-definite.
//!
//! Left alone, the fit lets a network wrinkle in the patterns a least-squares quadric does
//! not see (its residual), and an uneven network bends about 10 % too easily. Each point's
//! residual heights r = (I − ΦP)·h therefore bear ½·γ·D·A/ℓ⁴·Σⱼ(rⱼ − r̄ⱼ)² (see
//! [`CURVATURE_STABILISATION`]), which vanishes as the network is refined; points on a
//! boundary, whose fits are one-sided, bear none.
//!
//! A point whose fan collapses while running (its area vector shorter than
//! [`DEGENERATE_FAN`] of the fan's size) exerts no force that step.

use std::sync::Arc;

use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};

use super::{PointState, Soa3, non_negative};
use crate::core::solver::SolverError;

/// The fewest neighbours a fit takes: five unknowns and one to spare, so that noise does not
/// pass through the fit unfiltered. A ring with fewer borrows its neighbours' rings.
pub const MIN_FIT_POINTS: usize = 6;

/// How many neighbours a fit that borrows its ring's rings takes: the ring, then the nearest
/// (at rest) of the ring's rings' points, this many in all. About a third of a §3 network's
/// points have rings of four or five; fitted over all of their rings' rings (about 17
/// points) they bent at a wider scale than their six-ring neighbours and the coarse spheres
/// of `bench convergence` were up to 6.9 % stiff. Measured there (2026-12-04), the largest
/// error from 5 % to 50 % of the points over the four problems: 7 points 6.5 % (soft),
/// 9: 5.0 %, 11: 4.4 %, 12: 4.0 %, 13: 4.5 %, all of them: 6.9 % (stiff).
pub const WIDE_FIT_POINTS: usize = 12;

/// A fit whose normal equations have a pivot below this share of their largest diagonal
/// entry (neighbours on one line, say) is refused.
pub const FIT_CONDITION: f64 = 1.0e-6;

/// A fan's area vector shorter than this share of Σ|aⱼ|·|bⱼ| over its triangles counts as
/// collapsed: refused at rest, without force while running.
pub const DEGENERATE_FAN: f32 = 1.0e-6;

/// One point's curvature bending as it is given and read back.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CurvatureSpec {
    /// The point.
    pub point: u32,
    /// Its ring, counter-clockwise around its normal: the fan (point, rⱼ, rⱼ₊₁) gives the
    /// normal.
    pub fan: Vec<u32>,
    /// Whether the fan closes (rₙ₋₁, r₀) too; open at a boundary.
    pub closed: bool,
    /// The neighbours the quadric is fitted to (the ring, and more where it is short).
    pub fit: Vec<u32>,
    /// Each fitted neighbour's weights: (c, d, e) = Σⱼ wⱼ·hⱼ.
    pub weights: Vec<[f32; 3]>,
    /// The rest curvature S̄ = (c̄, d̄, ē), 1/m.
    pub rest: [f32; 3],
    /// The area the point stands for, m².
    pub area: f32,
    /// The flexural rigidity D, N·m.
    pub modulus: f32,
    /// Poisson's ratio ν of the bending, in (−1, ½].
    pub poisson: f32,
    /// The damping time β, s.
    pub damping: f32,
}

impl CurvatureSpec {
    /// This spec with its weights and rest curvature measured at `rest` (one position per
    /// point) from its point, fan and fitted neighbours; `None` when they are out of range,
    /// the fan has (almost) no area there or the neighbours admit no fit (see
    /// [`fit_weights`]).
    pub fn measured(mut self, rest: &[Vec3]) -> Option<Self> {
        let at = |i: u32| rest.get(i as usize).copied();
        let centre = at(self.point)?;
        let fan: Option<Vec<(Vec3, Vec3)>> = fan_pairs(&self.fan, self.closed)
            .map(|(a, b)| Some((at(a)?, at(b)?)))
            .collect();
        let (normal, _) = fan_normal(centre, fan?.into_iter())?;
        let neighbours: Option<Vec<Vec3>> = self.fit.iter().map(|&j| at(j)).collect();
        let neighbours = neighbours?;
        self.weights = fit_weights(centre, normal, &neighbours)?;
        self.rest = [0, 1, 2].map(|k| {
            neighbours
                .iter()
                .zip(&self.weights)
                .map(|(p, w)| w[k] * normal.dot(*p - centre))
                .sum()
        });
        Some(self)
    }
}

/// The unit area vector of the fan (centre, rⱼ, rⱼ₊₁), and the area vector's length; `None`
/// when it is collapsed (see [`DEGENERATE_FAN`]) or not finite.
fn fan_normal(centre: Vec3, ring: impl Iterator<Item = (Vec3, Vec3)>) -> Option<(Vec3, f32)> {
    let (mut sum, mut size) = (Vec3::ZERO, 0.0f32);
    for (a, b) in ring {
        let (a, b) = (a - centre, b - centre);
        sum += a.cross(b);
        size += a.length() * b.length();
    }
    let len = sum.length();
    (len.is_finite() && size.is_finite() && len > DEGENERATE_FAN * size).then(|| (sum / len, len))
}

/// The pairs of consecutive ring members of a fan.
fn fan_pairs(fan: &[u32], closed: bool) -> impl Iterator<Item = (u32, u32)> + '_ {
    let wrap = (closed && fan.len() > 2).then(|| (fan[fan.len() - 1], fan[0]));
    fan.windows(2).map(|w| (w[0], w[1])).chain(wrap)
}

/// The fit's weights for a point at `centre` with unit normal `normal` and neighbours at
/// `neighbours` (see the module docs): the rows of the least-squares fit that give the
/// quadric's Hessian (c, d, e). `None` with fewer than five neighbours or when they do not
/// span the plane ([`FIT_CONDITION`]).
pub fn fit_weights(centre: Vec3, normal: Vec3, neighbours: &[Vec3]) -> Option<Vec<[f32; 3]>> {
    let (p, _) = full_fit(centre, normal, neighbours)?;
    Some(
        p.iter()
            .map(|w| [w[2], w[3], w[4]].map(|x| x as f32))
            .collect(),
    )
}

/// The whole least-squares fit: each neighbour's column of P (the five coefficients'
/// weights) and its row of Φ, both in metres.
#[allow(clippy::type_complexity)]
fn full_fit(
    centre: Vec3,
    normal: Vec3,
    neighbours: &[Vec3],
) -> Option<(Vec<[f64; 5]>, Vec<[f64; 5]>)> {
    if neighbours.len() < 5 {
        return None;
    }
    let n = normal.as_dvec3().normalize_or_zero();
    if n == DVec3::ZERO {
        return None;
    }
    let t1 = n.any_orthonormal_vector();
    let t2 = n.cross(t1);
    let uv: Vec<(f64, f64)> = neighbours
        .iter()
        .map(|p| {
            let d = (*p - centre).as_dvec3();
            (t1.dot(d), t2.dot(d))
        })
        .collect();
    // Scale the coordinates to about 1 so that the normal equations are well balanced.
    let scale = (uv.iter().map(|(u, v)| u * u + v * v).sum::<f64>() / uv.len() as f64).sqrt();
    if !(scale.is_finite() && scale > 0.0) {
        return None;
    }
    let rows: Vec<[f64; 5]> = uv
        .iter()
        .map(|(u, v)| {
            let (u, v) = (u / scale, v / scale);
            [u, v, 0.5 * u * u, u * v, 0.5 * v * v]
        })
        .collect();
    // Normal equations ΦᵀΦ, factored by Cholesky.
    let mut a = [[0.0f64; 5]; 5];
    for r in &rows {
        for i in 0..5 {
            for j in 0..5 {
                a[i][j] += r[i] * r[j];
            }
        }
    }
    let largest = (0..5).map(|i| a[i][i]).fold(0.0, f64::max);
    let mut l = [[0.0f64; 5]; 5];
    for i in 0..5 {
        for j in 0..=i {
            let s = a[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>();
            if i == j {
                if s.partial_cmp(&(FIT_CONDITION * largest)) != Some(std::cmp::Ordering::Greater) {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    let solve = |b: [f64; 5]| {
        let mut y = [0.0; 5];
        for i in 0..5 {
            y[i] = (b[i] - (0..i).map(|k| l[i][k] * y[k]).sum::<f64>()) / l[i][i];
        }
        let mut x = [0.0; 5];
        for i in (0..5).rev() {
            x[i] = (y[i] - (i + 1..5).map(|k| l[k][i] * x[k]).sum::<f64>()) / l[i][i];
        }
        x
    };
    // Linear coefficients in the scaled coordinates are scale times those in metres,
    // second derivatives scale² times.
    let degree = [1, 1, 2, 2, 2];
    let p: Vec<[f64; 5]> = rows
        .iter()
        .map(|r| {
            let x = solve(*r);
            [0, 1, 2, 3, 4].map(|k| x[k] / scale.powi(degree[k]))
        })
        .collect();
    let phi: Vec<[f64; 5]> = rows
        .iter()
        .map(|r| [0, 1, 2, 3, 4].map(|k| r[k] * scale.powi(degree[k])))
        .collect();
    p.iter()
        .flatten()
        .all(|c| c.is_finite())
        .then_some((p, phi))
}

/// γ of the fit's residual stabilisation: each point's neighbours' heights off its fitted
/// quadric bear the energy ½·γ·D·A/ℓ⁴·Σⱼ(rⱼ − r̄ⱼ)² (ℓ² the mean square of their tangent
/// distances). Without it a network's heights can wrinkle in the patterns a least-squares
/// quadric does not see, and an uneven network bends 10–12 % too easily (a pinned plate
/// against Navier's series); a smooth surface's residual is of third order in ℓ, so the
/// term vanishes as the network is refined.
///
/// A point whose fan is open (on a boundary) bears none. Its fit is one-sided, so it
/// extrapolates, and a smooth surface's residual there is not small: stabilised too, a
/// narrow cantilever clamped at one end (`tests/bending.rs`, five rows, two of them edges)
/// sagged 7.4 % less at 75 points than at 638; without it, 2.1 % less (and a pinned plate
/// on 740 uneven points 0.5 % under Navier's series instead of 0.8 %). A boundary point's
/// heights are in its interior neighbours' fits, which stabilise them.
pub const CURVATURE_STABILISATION: f32 = 30.0;

/// The most neighbours a fit may take: a point's implicit matrix has about n²/2 entries
/// and a product keeps its n heights on the stack. The network's fits have 6 to
/// [`WIDE_FIT_POINTS`] (all of the rings' rings where those admit none, the nearest this
/// many of them); a spec with more is refused.
pub const MAX_FIT_POINTS: usize = 64;

/// The fitted height Φⱼ·coefficients at one neighbour.
#[inline]
fn fitted(row: &[f32; 5], coef: &[f64; 5]) -> f64 {
    row.iter().zip(coef).map(|(r, c)| f64::from(*r) * c).sum()
}

/// K·s for the plate's form K = k·[[1, 0, ν], [0, 2(1 − ν), 0], [ν, 0, 1]].
#[inline]
fn form<T>(k: T, nu: T, s: [T; 3]) -> [T; 3]
where
    T: Copy + std::ops::Mul<Output = T> + std::ops::Add<Output = T> + std::ops::Sub<Output = T>,
    T: From<f32>,
{
    let two: T = 2.0f32.into();
    let one: T = 1.0f32.into();
    [
        k * (s[0] + nu * s[2]),
        k * two * (one - nu) * s[1],
        k * (nu * s[0] + s[2]),
    ]
}

#[inline]
fn dot3<T: Copy + std::ops::Mul<Output = T> + std::ops::Add<Output = T>>(
    a: [T; 3],
    b: [T; 3],
) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The curvature bending of a surface (see the module docs), part of
/// [`Springs`](super::Springs).
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Curvatures {
    pub(crate) point: Vec<u32>,
    fan_start: Vec<u32>,
    fan: Vec<u32>,
    closed: Vec<bool>,
    fit_start: Vec<u32>,
    pub(crate) fit: Vec<u32>,
    weights: Vec<[f32; 3]>,
    rest: Vec<[f32; 3]>,
    area: Vec<f32>,
    modulus: Vec<f32>,
    poisson: Vec<f32>,
    damping: Vec<f32>,
    /// The rest residual of each fitted neighbour's height.
    rest_residual: Vec<f32>,
    /// The stabilisation's stiffness over the modulus, γ·A/ℓ⁴, per point.
    hourglass: Vec<f32>,
    /// What [`Self::new`] computes once and nothing changes afterwards, shared between
    /// copies: a copy of a surface's springs (a bake taken off the tick) does not copy it.
    fixed: Arc<FixedTables>,
}

/// The larger tables of [`Curvatures`] that are fixed once it is built.
#[derive(Debug, Clone, Default, PartialEq)]
struct FixedTables {
    /// Per fitted neighbour: the fit's residual projector's row I − ΦP over the point's
    /// neighbours is built from `p_full` and `phi`.
    p_full: Vec<[f32; 5]>,
    phi: Vec<[f32; 5]>,
    /// Per fitted neighbour, the implicit product's two rows in f64: [wⱼ, Pⱼ] (its height's
    /// share of the curvature and of the fit's coefficients) and [wⱼ, Φⱼ] (the curvature's
    /// and the fitted height's share of its force), so that a product is two 8-wide passes.
    gather_row: Vec<[f64; 8]>,
    scatter_row: Vec<[f64; 8]>,
    /// Per point, the implicit step's matrix over its stencil per unit of modulus: with
    /// M = A·WᵀK̂W + (γ·A/ℓ⁴)·(I − ΦP) over its n neighbours' heights (K̂: the plate's form
    /// of unit stiffness), its pairs' entries in [`Curvatures::pairs`]'s order (Mₐ_b for
    /// a < b, then each neighbour's with the centre, minus M's column sums: n·(n + 1)/2
    /// from `pair_start`), and its diagonal entries (each Mⱼⱼ, then the centre's 1ᵀM1:
    /// n + 1 from `fit_start[c] + c`). They depend on the rest shape alone (the modulus
    /// scales them), so the preconditioner reads its blocks rather than computing them
    /// every step.
    pair_values: Vec<f64>,
    pair_start: Vec<u32>,
    diagonal_values: Vec<f64>,
}

/// One point's curvature in an implicit step (see [`Curvatures::linearised`]).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct CurvatureBlock {
    /// The normal held (zero where the fan collapsed).
    pub normal: DVec3,
    /// h·β + h²: the block is `scale`·JᵀKJ.
    pub scale: f64,
}

impl Curvatures {
    /// The part from its specs over `rest` (one position per point): points in range and
    /// distinct within a spec, weights one per fitted neighbour and finite, the numbers
    /// finite, area, modulus and damping not negative, ν in (−1, ½], and every fan open at
    /// rest.
    pub(crate) fn new(specs: &[CurvatureSpec], rest: &[Vec3]) -> Result<Self, SolverError> {
        let points = rest.len();
        let mut part = Self {
            fan_start: vec![0],
            fit_start: vec![0],
            ..Self::default()
        };
        let mut fixed = FixedTables {
            pair_start: vec![0],
            ..FixedTables::default()
        };
        for (at, s) in specs.iter().enumerate() {
            let bad = |what| SolverError::InvalidCurvature { point: at, what };
            let in_range = |i: &u32| (*i as usize) < points && *i != s.point;
            if (s.point as usize) >= points
                || !s.fan.iter().all(in_range)
                || !s.fit.iter().all(in_range)
            {
                return Err(bad("its points must be in range and not the point itself"));
            }
            if s.fan.len() < 2 || s.fit.len() != s.weights.len() || s.fit.is_empty() {
                return Err(bad(
                    "it needs a fan of two or more and one weight per fitted neighbour",
                ));
            }
            if s.fit.len() > MAX_FIT_POINTS {
                return Err(bad("it fits more neighbours than MAX_FIT_POINTS"));
            }
            let finite = s
                .weights
                .iter()
                .flatten()
                .chain(&s.rest)
                .all(|w| w.is_finite());
            let numbers = [s.area, s.modulus, s.damping].into_iter().all(non_negative);
            if !(finite && numbers && s.poisson > -1.0 && s.poisson <= 0.5) {
                return Err(bad(
                    "weights and rest curvature must be finite, area, modulus and damping not negative, Poisson's ratio in (−1, ½]",
                ));
            }
            let at_rest = |i: u32| rest[i as usize];
            let pairs = fan_pairs(&s.fan, s.closed).map(|(a, b)| (at_rest(a), at_rest(b)));
            if fan_normal(at_rest(s.point), pairs).is_none() {
                return Err(bad("its fan has (almost) no area at rest"));
            }
            // The residual stabilisation, from the rest shape.
            let centre = at_rest(s.point);
            let pairs = fan_pairs(&s.fan, s.closed).map(|(a, b)| (at_rest(a), at_rest(b)));
            let (normal, _) =
                fan_normal(centre, pairs).ok_or(bad("its fan has (almost) no area at rest"))?;
            let neighbours: Vec<Vec3> = s.fit.iter().map(|&j| at_rest(j)).collect();
            let (pf, phi) = full_fit(centre, normal, &neighbours)
                .ok_or(bad("its neighbours admit no quadric fit at rest"))?;
            let heights: Vec<f64> = neighbours
                .iter()
                .map(|q| f64::from(normal.dot(*q - centre)))
                .collect();
            let coef: [f64; 5] =
                [0, 1, 2, 3, 4].map(|k| pf.iter().zip(&heights).map(|(w, h)| w[k] * h).sum());
            for (row, h) in phi.iter().zip(&heights) {
                let fitted: f64 = (0..5).map(|k| row[k] * coef[k]).sum();
                part.rest_residual.push((h - fitted) as f32);
            }
            let l2 = phi.iter().map(|r| r[0] * r[0] + r[1] * r[1]).sum::<f64>() / phi.len() as f64;
            // Only where the fan closes: a boundary point's fit is one-sided (see
            // [`CURVATURE_STABILISATION`]).
            let hourglass = if s.closed {
                f64::from(CURVATURE_STABILISATION * s.area) / (l2 * l2)
            } else {
                0.0
            };
            part.hourglass.push(hourglass as f32);
            // Stored in f32; the products' and the matrix's constants from the stored values,
            // so that they are the force's own.
            let pf: Vec<[f32; 5]> = pf.iter().map(|w| w.map(|x| x as f32)).collect();
            let phi: Vec<[f32; 5]> = phi.iter().map(|w| w.map(|x| x as f32)).collect();
            let hourglass = f64::from(hourglass as f32);
            let (area, nu) = (f64::from(s.area), f64::from(s.poisson));
            // Mₐ_b for a ≤ b (with Φₐ·P_b: I − ΦP is symmetric but for the rounding).
            let m = s.fit.len();
            let entry = |a: usize, b: usize| {
                let kw = form(area, nu, s.weights[a].map(f64::from));
                let identity = if a == b { 1.0 } else { 0.0 };
                dot3(s.weights[b].map(f64::from), kw)
                    + hourglass * (identity - fitted(&phi[a], &pf[b].map(f64::from)))
            };
            let mut column_sums = vec![0.0f64; m];
            let mut all = 0.0;
            for a in 0..m {
                let diagonal = entry(a, a);
                fixed.diagonal_values.push(diagonal);
                column_sums[a] += diagonal;
                all += diagonal;
                for b in a + 1..m {
                    let e = entry(a, b);
                    fixed.pair_values.push(e);
                    column_sums[a] += e;
                    column_sums[b] += e;
                    all += 2.0 * e;
                }
            }
            fixed.diagonal_values.push(all);
            fixed.pair_values.extend(column_sums.iter().map(|s| -s));
            fixed.pair_start.push(fixed.pair_values.len() as u32);
            for ((w, q), r) in s.weights.iter().zip(&pf).zip(&phi) {
                let mut gather = [0.0f64; 8];
                let mut scatter = [0.0f64; 8];
                for k in 0..3 {
                    gather[k] = f64::from(w[k]);
                    scatter[k] = f64::from(w[k]);
                }
                for k in 0..5 {
                    gather[3 + k] = f64::from(q[k]);
                    scatter[3 + k] = f64::from(r[k]);
                }
                fixed.gather_row.push(gather);
                fixed.scatter_row.push(scatter);
            }
            fixed.p_full.extend(pf);
            fixed.phi.extend(phi);
            part.point.push(s.point);
            part.fan.extend_from_slice(&s.fan);
            part.fan_start.push(part.fan.len() as u32);
            part.closed.push(s.closed);
            part.fit.extend_from_slice(&s.fit);
            part.weights.extend_from_slice(&s.weights);
            part.fit_start.push(part.fit.len() as u32);
            part.rest.push(s.rest);
            part.area.push(s.area);
            part.modulus.push(s.modulus);
            part.poisson.push(s.poisson);
            part.damping.push(s.damping);
        }
        part.fixed = Arc::new(fixed);
        Ok(part)
    }

    /// Number of points with curvature bending.
    pub(crate) fn len(&self) -> usize {
        self.point.len()
    }

    fn fan_of(&self, c: usize) -> &[u32] {
        &self.fan[self.fan_start[c] as usize..self.fan_start[c + 1] as usize]
    }

    fn fit_of(&self, c: usize) -> (&[u32], &[[f32; 3]]) {
        let r = self.fit_start[c] as usize..self.fit_start[c + 1] as usize;
        (&self.fit[r.clone()], &self.weights[r])
    }

    /// The fit's residual r = (I − ΦP)·h for point `c`'s heights `h` (one per fitted
    /// neighbour).
    fn residual(&self, c: usize, h: &[f64]) -> Vec<f64> {
        let r = self.fit_start[c] as usize..self.fit_start[c + 1] as usize;
        let (pf, phi) = (&self.fixed.p_full[r.clone()], &self.fixed.phi[r]);
        let coef: [f64; 5] =
            [0, 1, 2, 3, 4].map(|k| pf.iter().zip(h).map(|(w, h)| f64::from(w[k]) * h).sum());
        phi.iter()
            .zip(h)
            .map(|(row, h)| h - (0..5).map(|k| f64::from(row[k]) * coef[k]).sum::<f64>())
            .collect()
    }

    fn rest_residual_of(&self, c: usize) -> &[f32] {
        &self.rest_residual[self.fit_start[c] as usize..self.fit_start[c + 1] as usize]
    }

    /// The stabilisation's stiffness γ·D·A/ℓ⁴.
    fn stab_stiffness(&self, c: usize) -> f32 {
        self.hourglass[c] * self.modulus[c]
    }

    /// The residual projector's entries (I − ΦP)ⱼᵢ of point `c`, row by row.
    fn projector(&self, c: usize) -> Vec<Vec<f64>> {
        let n = self.fit_of(c).0.len();
        let mut rows = vec![vec![0.0; n]; n];
        for i in 0..n {
            let mut e = vec![0.0; n];
            e[i] = 1.0;
            // (I − ΦP) is symmetric: its column i is its row i.
            rows[i] = self.residual(c, &e);
        }
        rows
    }

    /// The stiffness k = D·A of K.
    fn stiffness(&self, c: usize) -> f32 {
        self.modulus[c] * self.area[c]
    }

    /// Every point's spec, in the order given.
    pub(crate) fn iter(&self) -> impl ExactSizeIterator<Item = CurvatureSpec> + '_ {
        (0..self.len()).map(|c| {
            let (fit, weights) = self.fit_of(c);
            CurvatureSpec {
                point: self.point[c],
                fan: self.fan_of(c).to_vec(),
                closed: self.closed[c],
                fit: fit.to_vec(),
                weights: weights.to_vec(),
                rest: self.rest[c],
                area: self.area[c],
                modulus: self.modulus[c],
                poisson: self.poisson[c],
                damping: self.damping[c],
            }
        })
    }

    /// Point `c`'s normal and its fan's area-vector length at `x`.
    fn normal(&self, c: usize, x: &Soa3) -> Option<(Vec3, f32)> {
        let centre = x.get(self.point[c] as usize);
        let pairs = fan_pairs(self.fan_of(c), self.closed[c])
            .map(|(a, b)| (x.get(a as usize), x.get(b as usize)));
        fan_normal(centre, pairs)
    }

    /// The fitted curvature S at `x` with normal `n`.
    fn curvature(&self, c: usize, x: &Soa3, n: Vec3) -> [f32; 3] {
        let p = x.get(self.point[c] as usize);
        let (fit, weights) = self.fit_of(c);
        let mut s = [0.0f32; 3];
        for (&j, w) in fit.iter().zip(weights) {
            let h = n.dot(x.get(j as usize) - p);
            for k in 0..3 {
                s[k] += w[k] * h;
            }
        }
        s
    }

    /// ΔS = S − S̄ at `points`, or `None` where the fan collapsed.
    pub(crate) fn bend(&self, c: usize, points: &PointState) -> Option<[f32; 3]> {
        let (n, _) = self.normal(c, &points.x)?;
        let s = self.curvature(c, &points.x, n);
        Some([0, 1, 2].map(|k| s[k] - self.rest[c][k]))
    }

    /// Adds the bending forces at `points` to `f` (the energy's gradient and the damping
    /// −β·JᵀKJ·v), and writes each point's normal into `normals` (zero where its fan
    /// collapsed) for an implicit step at the same state ([`Self::linearised`]).
    pub(crate) fn accumulate(&self, points: &PointState, f: &mut Soa3, normals: &mut Vec<Vec3>) {
        normals.clear();
        normals.resize(self.len(), Vec3::ZERO);
        let (x, v) = (&points.x, &points.v);
        for (c, out) in normals.iter_mut().enumerate() {
            let Some((n, len)) = self.normal(c, x) else {
                continue;
            };
            *out = n;
            let p = self.point[c] as usize;
            let (fit, weights) = self.fit_of(c);
            let range = self.fit_start[c] as usize..self.fit_start[c + 1] as usize;
            let (pf, phi) = (
                &self.fixed.p_full[range.clone()],
                &self.fixed.phi[range.clone()],
            );
            let rest_residual = &self.rest_residual[range];
            let kh = self.stab_stiffness(c);
            // One pass for the neighbours' offsets (kept), the curvature S, its rate and the
            // fit's coefficients.
            let (xp, vp) = (x.get(p), v.get(p));
            let mut offsets = [Vec3::ZERO; MAX_FIT_POINTS];
            let (mut s, mut rate, mut coef) = ([0.0f32; 3], [0.0f32; 3], [0.0f64; 5]);
            for (((&j, w), q), d) in fit.iter().zip(weights).zip(pf).zip(&mut offsets) {
                *d = x.get(j as usize) - xp;
                let (h, r) = (n.dot(*d), n.dot(v.get(j as usize) - vp));
                for k in 0..3 {
                    s[k] += w[k] * h;
                    rate[k] += w[k] * r;
                }
                if kh > 0.0 {
                    for (c, q) in coef.iter_mut().zip(q) {
                        *c += f64::from(*q) * f64::from(h);
                    }
                }
            }
            let ds = [0, 1, 2].map(|k| s[k] - self.rest[c][k]);
            let (k, nu) = (self.stiffness(c), self.poisson[c]);
            let elastic = form(k, nu, ds);
            let damping = form(k * self.damping[c], nu, rate);
            let stress = [0, 1, 2].map(|i| elastic[i] + damping[i]);
            // Along the held normal: −Σⱼ (wⱼ·t)·n on each neighbour, the opposite on p.
            let mut on_p = 0.0f32;
            // ∂E/∂n = Σⱼ (wⱼ·K·ΔS)·(xⱼ − p), the elastic part only.
            let mut de_dn = Vec3::ZERO;
            for ((((&j, w), row), r0), d) in fit
                .iter()
                .zip(weights)
                .zip(phi)
                .zip(rest_residual)
                .zip(&offsets)
            {
                // The stabilisation's k_h·(rⱼ − r̄ⱼ).
                let s = if kh > 0.0 {
                    kh * ((f64::from(n.dot(*d)) - fitted(row, &coef)) as f32 - r0)
                } else {
                    0.0
                };
                let j = j as usize;
                let g = dot3(*w, stress) + s;
                f.set(j, f.get(j) - g * n);
                on_p += g;
                de_dn += (dot3(*w, elastic) + s) * *d;
            }
            // Through the normal: ∂E/∂N = (I − nnᵀ)·∂E/∂n / |N|, and N = Σ aⱼ × bⱼ.
            let w_hat = (de_dn - de_dn.dot(n) * n) / len;
            let mut on_p_vec = on_p * n;
            for (a, b) in fan_pairs(self.fan_of(c), self.closed[c]) {
                let (a, b) = (a as usize, b as usize);
                let (ra, rb) = (x.get(a) - xp, x.get(b) - xp);
                let (ga, gb) = (rb.cross(w_hat), w_hat.cross(ra));
                f.set(a, f.get(a) - ga);
                f.set(b, f.get(b) - gb);
                on_p_vec += ga + gb;
            }
            f.set(p, f.get(p) + on_p_vec);
        }
    }

    /// The bending energy Σ ½·ΔSᵀ·K·ΔS at `points`.
    pub(crate) fn energy(&self, points: &PointState) -> f64 {
        (0..self.len())
            .filter_map(|c| {
                let ds = self.bend(c, points)?.map(f64::from);
                let k = f64::from(self.stiffness(c));
                let kh = f64::from(self.stab_stiffness(c));
                let stab = if kh > 0.0 {
                    let (n, _) = self.normal(c, &points.x)?;
                    let xp = points.x.get(self.point[c] as usize);
                    let h: Vec<f64> = self
                        .fit_of(c)
                        .0
                        .iter()
                        .map(|&j| f64::from(n.dot(points.x.get(j as usize) - xp)))
                        .collect();
                    0.5 * kh
                        * self
                            .residual(c, &h)
                            .iter()
                            .zip(self.rest_residual_of(c))
                            .map(|(r, r0)| (r - f64::from(*r0)).powi(2))
                            .sum::<f64>()
                } else {
                    0.0
                };
                Some(0.5 * dot3(ds, form(k, f64::from(self.poisson[c]), ds)) + stab)
            })
            .sum()
    }

    /// The linearised part for an implicit step of length `step` from the normals
    /// [`Self::accumulate`] wrote.
    pub(crate) fn linearised(&self, normals: &[Vec3], step: f64, out: &mut Vec<CurvatureBlock>) {
        out.clear();
        out.extend(normals.iter().enumerate().map(|(c, n)| CurvatureBlock {
            normal: n.as_dvec3(),
            scale: step * f64::from(self.damping[c]) + step * step,
        }));
    }

    /// y += (k·JᵀKJ + kₕ·Jₕᵀ(I − ΦP)Jₕ)·p for point `c` held along `n` (Jₕ: its
    /// neighbours' heights; K the plate's form of stiffness k): the implicit step's block
    /// of one point, in two passes over its neighbours.
    fn add_block(&self, c: usize, n: DVec3, k: f64, kh: f64, p: &[DVec3], y: &mut [DVec3]) {
        let at = self.point[c] as usize;
        let centre = p[at];
        let range = self.fit_start[c] as usize..self.fit_start[c + 1] as usize;
        let fit = &self.fit[range.clone()];
        let (gather, scatter) = (
            &self.fixed.gather_row[range.clone()],
            &self.fixed.scatter_row[range],
        );
        // Pass 1: the curvature change J·p and the fit's coefficients P·Jₕ·p together; the
        // heights are kept for pass 2 (a fit has at most MAX_FIT_POINTS).
        let mut heights = [0.0f64; MAX_FIT_POINTS];
        let mut sums = [0.0f64; 8];
        for (i, (&j, row)) in fit.iter().zip(gather).enumerate() {
            let h = n.dot(p[j as usize] - centre);
            heights[i] = h;
            for (s, r) in sums.iter_mut().zip(row) {
                *s += r * h;
            }
        }
        let t = form(k, f64::from(self.poisson[c]), [sums[0], sums[1], sums[2]]);
        // Pass 2: each neighbour's share along n, wⱼ·K·s + kₕ·(hⱼ − Φⱼ·coefficients).
        let mut u = [0.0f64; 8];
        u[..3].copy_from_slice(&t);
        for (u, c) in u[3..].iter_mut().zip(&sums[3..]) {
            *u = -kh * c;
        }
        let mut on_p = 0.0;
        for (i, (&j, row)) in fit.iter().zip(scatter).enumerate() {
            let h = heights[i];
            let g = row.iter().zip(&u).map(|(r, u)| r * u).sum::<f64>() + kh * h;
            y[j as usize] += g * n;
            on_p += g;
        }
        y[at] -= on_p * n;
    }

    /// The points' stencils as they stand (each point, where its fitted neighbours start,
    /// and the neighbours): what the preconditioner's pattern depends on.
    pub(crate) fn topology(&self) -> (&[u32], &[u32], &[u32]) {
        (&self.point, &self.fit_start, &self.fit)
    }

    /// Point `c`'s stencil: its fitted neighbours, then the point itself.
    pub(crate) fn stencil(&self, c: usize) -> impl Iterator<Item = u32> + '_ {
        let (fit, _) = self.fit_of(c);
        fit.iter().copied().chain(std::iter::once(self.point[c]))
    }

    /// The length of point `c`'s stencil.
    pub(crate) fn stencil_len(&self, c: usize) -> usize {
        (self.fit_start[c + 1] - self.fit_start[c]) as usize + 1
    }

    /// Point `c`'s block of the implicit step's matrix off its diagonal, at `scale`
    /// ([`CurvatureBlock::scale`]): `f(a, b, m)` for every pair a < b of its stencil's
    /// positions ([`Self::stencil`]), in order, where the block between the two points is
    /// m·nnᵀ. Neighbours a, b: wₐᵀKw_b − kₕ·Φₐ·P_b (the projector's I − ΦP off its
    /// diagonal); the point itself (position last) moves all heights by −1, so its column
    /// is minus the sum of the neighbours' columns.
    pub(crate) fn pairs(&self, c: usize, scale: f64, mut f: impl FnMut(usize, usize, f64)) {
        let m = self.stencil_len(c) - 1;
        let factor = scale * self.modulus(c);
        let mut values = self.pair_values(c).iter();
        for a in 0..m {
            for (b, e) in (a + 1..m).zip(values.by_ref()) {
                f(a, b, factor * e);
            }
        }
        for (b, e) in values.enumerate() {
            f(b, m, factor * e);
        }
    }

    /// Point `c`'s diagonal entries of the implicit step's matrix at `scale` (see
    /// [`Self::pairs`]): `f(point, m)` for each point of its stencil, the block there being
    /// m·nnᵀ.
    pub(crate) fn diagonal_entries(&self, c: usize, scale: f64, mut f: impl FnMut(u32, f64)) {
        let factor = scale * self.modulus(c);
        let range = self.fit_start[c] as usize + c..self.fit_start[c + 1] as usize + c + 1;
        for (j, e) in self.stencil(c).zip(&self.fixed.diagonal_values[range]) {
            f(j, factor * e);
        }
    }

    /// Point `c`'s bending damping β (s): its damping block is β times its stiffness one.
    pub(crate) fn damping_rate(&self, c: usize) -> f64 {
        f64::from(self.damping[c])
    }

    /// Point `c`'s pairs' entries per unit of modulus, in [`Self::pairs`]'s order.
    pub(crate) fn pair_values(&self, c: usize) -> &[f64] {
        &self.fixed.pair_values
            [self.fixed.pair_start[c] as usize..self.fixed.pair_start[c + 1] as usize]
    }

    /// Point `c`'s flexural rigidity D, which scales its matrix.
    pub(crate) fn modulus(&self, c: usize) -> f64 {
        f64::from(self.modulus[c])
    }

    /// y += Σ scale·(JᵀKJ + stabilisation)·p over the points (the implicit step's matrix).
    pub(crate) fn apply(&self, blocks: &[CurvatureBlock], p: &[DVec3], y: &mut [DVec3]) {
        for (c, b) in blocks.iter().enumerate() {
            if b.normal == DVec3::ZERO {
                continue;
            }
            let k = f64::from(self.stiffness(c)) * b.scale;
            let kh = f64::from(self.stab_stiffness(c)) * b.scale;
            self.add_block(c, b.normal, k, kh, p, y);
        }
    }

    /// rhs −= h²·JᵀKJ·v₀ (the right-hand side's h²·∂f/∂x·v₀).
    pub(crate) fn add_rhs(
        &self,
        blocks: &[CurvatureBlock],
        v: &[DVec3],
        step: f64,
        rhs: &mut [DVec3],
    ) {
        for (c, b) in blocks.iter().enumerate() {
            if b.normal == DVec3::ZERO {
                continue;
            }
            let k = -f64::from(self.stiffness(c)) * step * step;
            let kh = -f64::from(self.stab_stiffness(c)) * step * step;
            self.add_block(c, b.normal, k, kh, v, rhs);
        }
    }

    /// Each point's diagonal block of Σ scale·JᵀKJ: `add(point, n, s)` for the block s·nnᵀ.
    pub(crate) fn diagonal(
        &self,
        blocks: &[CurvatureBlock],
        mut add: impl FnMut(usize, DVec3, f64),
    ) {
        for (c, b) in blocks.iter().enumerate() {
            if b.normal == DVec3::ZERO {
                continue;
            }
            let factor = b.scale * self.modulus(c);
            let range = self.fit_start[c] as usize + c..self.fit_start[c + 1] as usize + c + 1;
            let stencil = self.stencil(c);
            for (j, e) in stencil.zip(&self.fixed.diagonal_values[range]) {
                add(j as usize, b.normal, factor * e);
            }
        }
    }

    /// Adds each point's Gershgorin row bound of JᵀKJ to `stiff` and of β·JᵀKJ to `damp`;
    /// returns the smallest β (∞ with none), the time constant for explicit Euler.
    pub(crate) fn stability_rows(&self, stiff: &mut [f64], damp: &mut [f64]) -> f64 {
        let mut ratio = f64::INFINITY;
        for c in 0..self.len() {
            let (fit, weights) = self.fit_of(c);
            let mut coefficients: Vec<(usize, [f64; 3])> = fit
                .iter()
                .zip(weights)
                .map(|(&j, w)| (j as usize, w.map(f64::from)))
                .collect();
            let centre = coefficients.iter().fold([0.0; 3], |acc, (_, w)| {
                [acc[0] - w[0], acc[1] - w[1], acc[2] - w[2]]
            });
            coefficients.push((self.point[c] as usize, centre));
            let (k, nu) = (f64::from(self.stiffness(c)), f64::from(self.poisson[c]));
            let beta = f64::from(self.damping[c]);
            for (i, wi) in &coefficients {
                let kwi = form(k, nu, *wi);
                let row: f64 = coefficients
                    .iter()
                    .map(|(_, wj)| dot3(kwi, *wj).abs())
                    .sum();
                stiff[*i] += row;
                damp[*i] += beta * row;
            }
            let kh = f64::from(self.stab_stiffness(c));
            if kh > 0.0 {
                // Row j of k·Jₕᵀ(I − ΦP)Jₕ: its neighbours' entries and the centre's (−Σᵢ).
                let projector = self.projector(c);
                let mut centre_row = 0.0;
                for (row, &j) in projector.iter().zip(fit) {
                    let to_centre = row.iter().sum::<f64>().abs();
                    let sum: f64 = row.iter().map(|e| e.abs()).sum::<f64>() + to_centre;
                    stiff[j as usize] += kh * sum;
                    centre_row += to_centre;
                }
                let all = projector.iter().flatten().sum::<f64>().abs();
                stiff[self.point[c] as usize] += kh * (centre_row + all);
            }
            if k > 0.0 {
                ratio = ratio.min(beta);
            }
        }
        ratio
    }

    /// Sets every point's rest curvature, modulus and damping from its index (see
    /// [`Springs::set_curvature_parameters`](super::Springs::set_curvature_parameters)).
    pub(crate) fn set_parameters(
        &mut self,
        mut of: impl FnMut(usize) -> [f32; 5],
    ) -> Result<(), SolverError> {
        let values: Vec<[f32; 5]> = (0..self.len()).map(&mut of).collect();
        if let Some(point) = values.iter().position(|v| {
            !(v[..3].iter().all(|c| c.is_finite()) && non_negative(v[3]) && non_negative(v[4]))
        }) {
            return Err(SolverError::InvalidCurvature {
                point,
                what: "rest curvature must be finite, modulus and damping finite and not negative",
            });
        }
        for (c, v) in values.into_iter().enumerate() {
            self.rest[c] = [v[0], v[1], v[2]];
            self.modulus[c] = v[3];
            self.damping[c] = v[4];
        }
        Ok(())
    }

    /// Every point's rest residual heights (the stabilisation's), one per fitted
    /// neighbour, point after point.
    pub(crate) fn rest_residuals(&self) -> &[f32] {
        &self.rest_residual
    }

    /// Sets the rest residual heights ([`Self::rest_residuals`]' layout); refused, nothing
    /// changed, when their number differs or one is not finite.
    pub(crate) fn set_rest_residuals(&mut self, residuals: &[f32]) -> Result<(), SolverError> {
        if residuals.len() != self.rest_residual.len() {
            return Err(SolverError::InvalidConfig(
                "the rest residual heights do not match the curvature bending's fits",
            ));
        }
        if !residuals.iter().all(|r| r.is_finite()) {
            return Err(SolverError::InvalidConfig(
                "the rest residual heights must be finite",
            ));
        }
        self.rest_residual.copy_from_slice(residuals);
        Ok(())
    }

    /// Sets every rest curvature, and every rest residual height, to those at `points` (a
    /// bake); refused, nothing changed, where a fan has collapsed there.
    pub(crate) fn set_rest_shape(&mut self, points: &PointState) -> Result<(), SolverError> {
        let mut rest = Vec::with_capacity(self.len());
        for c in 0..self.len() {
            let (n, _) = self
                .normal(c, &points.x)
                .ok_or(SolverError::InvalidCurvature {
                    point: c,
                    what: "its fan in the new rest shape has (almost) no area",
                })?;
            rest.push(self.curvature(c, &points.x, n));
        }
        self.rest = rest;
        // The residual heights' rest too, or the stabilisation would pull the new shape back.
        for c in 0..self.len() {
            if let Some((n, _)) = self.normal(c, &points.x) {
                let residual = self.residual_at(c, &points.x, n);
                let range = self.fit_start[c] as usize..self.fit_start[c + 1] as usize;
                for (rest, r) in self.rest_residual[range].iter_mut().zip(&residual) {
                    *rest = *r as f32;
                }
            }
        }
        Ok(())
    }

    /// Point `c`'s residual heights off its fitted quadric at `x` with normal `n` (one per
    /// fitted neighbour).
    fn residual_at(&self, c: usize, x: &Soa3, n: Vec3) -> Vec<f64> {
        let xp = x.get(self.point[c] as usize);
        let heights: Vec<f64> = self
            .fit_of(c)
            .0
            .iter()
            .map(|&j| f64::from(n.dot(x.get(j as usize) - xp)))
            .collect();
        self.residual(c, &heights)
    }

    /// Plastic flow on the rest curvatures after a step: a point bent by more than
    /// `yield_angle`/√A (the bend that turns its normal by about `yield_angle` across its
    /// own size) moves its rest curvature `fraction` of the way to where the bend would be
    /// that, and its rest residual heights (the stabilisation's) the same share of the way
    /// to the present ones, so that the whole bent shape is kept. Returns how many points
    /// flowed.
    pub(crate) fn flow(&mut self, points: &PointState, yield_angle: f32, fraction: f32) -> usize {
        let mut flowed = 0;
        for c in 0..self.len() {
            let Some(ds) = self.bend(c, points) else {
                continue;
            };
            let size = dot3(ds, ds).sqrt();
            let limit = yield_angle / self.area[c].sqrt().max(f32::MIN_POSITIVE);
            if size.partial_cmp(&limit) != Some(std::cmp::Ordering::Greater) {
                continue;
            }
            let excess = fraction * (1.0 - limit / size);
            for (rest, d) in self.rest[c].iter_mut().zip(ds) {
                *rest += excess * d;
            }
            if let Some((n, _)) = self.normal(c, &points.x) {
                let residual = self.residual_at(c, &points.x, n);
                let range = self.fit_start[c] as usize..self.fit_start[c + 1] as usize;
                for (rest, r) in self.rest_residual[range].iter_mut().zip(&residual) {
                    *rest += excess * (*r as f32 - *rest);
                }
            }
            flowed += 1;
        }
        flowed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A jittered patch of `rings` rings around the origin on the surface z = f(x, y), each
    /// point's fit over its six nearest neighbours.
    fn patch(f: impl Fn(f32, f32) -> f32) -> Vec<Vec3> {
        let mut pts = vec![Vec3::new(0.0, 0.0, f(0.0, 0.0))];
        let mut seed = 7u32;
        let mut jitter = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1u32 << 24) as f32 - 0.5
        };
        for i in 0..7 {
            let angle = i as f32 * 0.9 + 0.3 * jitter();
            let r = 0.1 * (1.0 + 0.4 * jitter());
            let (x, y) = (r * angle.cos(), r * angle.sin());
            pts.push(Vec3::new(x, y, f(x, y)));
        }
        pts
    }

    #[test]
    fn the_fit_is_exact_for_a_quadric_on_uneven_neighbours() {
        let (c, d, e) = (2.0f32, -0.7f32, 0.5f32);
        // The exact check: untilted quadric, any tangent basis: trace and determinant.
        let flat = |x: f32, y: f32| 0.5 * (c * x * x + 2.0 * d * x * y + e * y * y);
        let pts = patch(flat);
        let w = fit_weights(pts[0], Vec3::Z, &pts[1..]).unwrap();
        let s: [f32; 3] = [0, 1, 2].map(|k| pts[1..].iter().zip(&w).map(|(p, w)| w[k] * p.z).sum());
        let trace = s[0] + s[2];
        let det = s[0] * s[2] - s[1] * s[1];
        assert!((trace - (c + e)).abs() < 1e-3, "{trace}");
        assert!((det - (c * e - d * d)).abs() < 1e-3, "{det}");
    }

    /// A closed fan around point 0 of [`patch`], fitted to all its neighbours.
    fn spec(pts: &[Vec3]) -> CurvatureSpec {
        let fit: Vec<u32> = (1..pts.len() as u32).collect();
        let weights = fit_weights(pts[0], Vec3::Z, &pts[1..]).unwrap();
        CurvatureSpec {
            point: 0,
            fan: fit.clone(),
            closed: true,
            fit,
            weights,
            rest: [0.0; 3],
            area: 0.03,
            modulus: 2.0,
            poisson: 0.3,
            damping: 0.0,
        }
    }

    #[test]
    fn the_force_is_minus_the_energy_gradient_and_keeps_both_momenta() {
        let rest = patch(|_, _| 0.0);
        let part = Curvatures::new(&[spec(&rest)], &rest).unwrap();
        let bent: Vec<Vec3> = rest
            .iter()
            .map(|p| *p + Vec3::new(0.01 * p.y, 0.0, 3.0 * p.x * p.x - p.x * p.y + 0.02))
            .collect();
        let state = |x: &[Vec3]| PointState::new(x).unwrap();
        let mut f = Soa3::zeros(bent.len());
        let mut normals = Vec::new();
        part.accumulate(&state(&bent), &mut f, &mut normals);
        let e0 = part.energy(&state(&bent));
        assert!(e0 > 0.0);
        let h = 1e-4f32;
        for i in 0..bent.len() {
            for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
                let (mut plus, mut minus) = (bent.clone(), bent.clone());
                plus[i] += axis * h;
                minus[i] -= axis * h;
                let numeric =
                    (part.energy(&state(&plus)) - part.energy(&state(&minus))) / f64::from(2.0 * h);
                let force = f64::from(f.get(i).dot(axis));
                assert!(
                    (numeric + force).abs() < 2e-3 * (1.0 + numeric.abs()),
                    "point {i} {axis}: −∂E/∂x {} against {force}",
                    -numeric
                );
            }
        }
        let (mut total, mut torque) = (Vec3::ZERO, Vec3::ZERO);
        for (i, p) in bent.iter().enumerate() {
            total += f.get(i);
            torque += p.cross(f.get(i));
        }
        assert!(total.length() < 1e-4, "{total}");
        assert!(torque.length() < 1e-4, "{torque}");
        // A rigid motion of the rest shape costs nothing.
        let turn = glam::Quat::from_rotation_y(0.7);
        let moved: Vec<Vec3> = rest.iter().map(|p| turn * *p + Vec3::ONE).collect();
        assert!(part.energy(&state(&moved)) < 1e-10);
    }

    #[test]
    fn the_implicit_blocks_are_the_stiffness_at_rest() {
        // At rest ΔS = 0, so the energy's Hessian is exactly JᵀKJ: its columns are minus the
        // force's derivatives. The matrix product, its diagonal blocks and the right-hand side
        // (−h²·JᵀKJ·v) are checked against them.
        let rest: Vec<Vec3> = patch(|x, y| 0.8 * x * x - 0.3 * x * y + 0.2 * y * y);
        let mut s = spec(&rest);
        s.rest = [0.0; 3];
        let s = s.measured(&rest).unwrap();
        let part = Curvatures::new(&[s], &rest).unwrap();
        let n = rest.len();
        let force = |x: &[Vec3]| {
            let mut f = Soa3::zeros(n);
            part.accumulate(&PointState::new(x).unwrap(), &mut f, &mut Vec::new());
            (0..n).map(|i| f.get(i).as_dvec3()).collect::<Vec<_>>()
        };
        assert!(force(&rest).iter().all(|f| f.length() < 1e-5));
        let mut normals = Vec::new();
        let mut f = Soa3::zeros(n);
        part.accumulate(&PointState::new(&rest).unwrap(), &mut f, &mut normals);
        let mut blocks = Vec::new();
        part.linearised(&normals, 1.0, &mut blocks);
        let mut diagonal = vec![DVec3::ZERO; n];
        part.diagonal(&blocks, |i, normal, scale| {
            diagonal[i] += scale * normal * normal;
        });
        let h = 1e-3f32;
        for k in 0..3 * n {
            let (i, axis) = (k / 3, Vec3::AXES[k % 3]);
            let (mut plus, mut minus) = (rest.clone(), rest.clone());
            plus[i] += axis * h;
            minus[i] -= axis * h;
            let (fp, fm) = (force(&plus), force(&minus));
            let mut e = vec![DVec3::ZERO; n];
            e[i] = axis.as_dvec3();
            let mut column = vec![DVec3::ZERO; n];
            part.apply(&blocks, &e, &mut column);
            for j in 0..n {
                let numeric = -(fp[j] - fm[j]) / f64::from(2.0 * h);
                assert!(
                    (numeric - column[j]).length() < 2e-2 * (1.0 + numeric.length()),
                    "column {k}, point {j}: {numeric} against {}",
                    column[j]
                );
            }
            // The preconditioner's diagonal and off-diagonal blocks m·nnᵀ are the product's
            // (to the f32 rounding of the stored fit, by which I − ΦP is not exactly
            // symmetric: the blocks take Φₐ·P_b for a < b on both sides of the diagonal).
            let (d, c) = (diagonal[i][k % 3], column[i][k % 3]);
            assert!((d - c).abs() < 1e-6 * (1.0 + c.abs()), "{d} against {c}");
            let stencil: Vec<usize> = part.stencil(0).map(|j| j as usize).collect();
            let normal = blocks[0].normal;
            part.pairs(0, blocks[0].scale, |a, b, m| {
                for (row, col) in [(stencil[a], stencil[b]), (stencil[b], stencil[a])] {
                    if col == i {
                        let entry = m * normal * normal[k % 3];
                        assert!(
                            (entry - column[row]).length() < 1e-5 * (1.0 + entry.length()),
                            "pair ({a}, {b}): {entry} against {}",
                            column[row]
                        );
                    }
                }
            });
            // The right-hand side at step 1 is −JᵀKJ·v for the velocity e.
            let mut rhs = vec![DVec3::ZERO; n];
            part.add_rhs(&blocks, &e, 1.0, &mut rhs);
            for j in 0..n {
                assert!((rhs[j] + column[j]).length() < 1e-9);
            }
        }
    }

    #[test]
    fn only_a_closed_fan_is_stabilised() {
        let rest = patch(|_, _| 0.0);
        let closed = Curvatures::new(&[spec(&rest)], &rest).unwrap();
        assert!(closed.stab_stiffness(0) > 0.0);
        let open = Curvatures::new(
            &[CurvatureSpec {
                closed: false,
                ..spec(&rest)
            }],
            &rest,
        )
        .unwrap();
        assert_eq!(open.stab_stiffness(0), 0.0);
        // A height its quadric cannot fit costs the open fan's point nothing beyond its
        // curvature's energy, and the closed fan's point more.
        let mut bumped = rest.clone();
        bumped[3].z += 0.002;
        let energy = |part: &Curvatures, x: &[Vec3]| part.energy(&PointState::new(x).unwrap());
        let curvature_only = |part: &Curvatures| {
            let ds = part.bend(0, &PointState::new(&bumped).unwrap()).unwrap();
            0.5 * f64::from(dot3(ds, form(part.stiffness(0), part.poisson[0], ds)))
        };
        let (e, k) = (energy(&open, &bumped), curvature_only(&open));
        assert!((e - k).abs() <= 1e-6 * k, "{e} {k}");
        assert!(energy(&closed, &bumped) > 1.5 * curvature_only(&closed));
    }

    #[test]
    fn bad_specs_are_refused() {
        let rest = patch(|_, _| 0.0);
        let good = spec(&rest);
        for bad in [
            CurvatureSpec {
                poisson: 0.7,
                ..good.clone()
            },
            CurvatureSpec {
                fit: vec![1, 2, 99],
                ..good.clone()
            },
            CurvatureSpec {
                weights: vec![[f32::NAN; 3]; good.fit.len()],
                ..good.clone()
            },
            CurvatureSpec {
                fan: vec![1, 0],
                ..good.clone()
            },
        ] {
            assert!(Curvatures::new(&[bad], &rest).is_err());
        }
        // A fit wider than MAX_FIT_POINTS would cost its square in memory: refused.
        let wide = CurvatureSpec {
            fit: vec![1; MAX_FIT_POINTS + 1],
            weights: vec![[0.0; 3]; MAX_FIT_POINTS + 1],
            ..good.clone()
        };
        assert!(matches!(
            Curvatures::new(&[wide], &rest),
            Err(SolverError::InvalidCurvature { what, .. }) if what.contains("MAX_FIT_POINTS")
        ));
        // Neighbours on one line are no fit; a collapsed fan no normal.
        let line: Vec<Vec3> = (1..8).map(|i| Vec3::X * i as f32).collect();
        assert!(fit_weights(Vec3::ZERO, Vec3::Z, &line).is_none());
        let flat: Vec<Vec3> = rest.iter().map(|p| Vec3::new(p.x, 0.0, 0.0)).collect();
        assert!(Curvatures::new(std::slice::from_ref(&good), &flat).is_err());
        // Rest residual heights (a snapshot's) of the wrong number, or not finite: refused,
        // nothing changed.
        let mut part = Curvatures::new(&[good], &rest).unwrap();
        let kept = part.rest_residuals().to_vec();
        let mut nan = kept.clone();
        nan[0] = f32::NAN;
        for bad in [&kept[1..], &nan[..]] {
            assert!(matches!(
                part.set_rest_residuals(bad),
                Err(SolverError::InvalidConfig(_))
            ));
            assert_eq!(part.rest_residuals(), &kept[..]);
        }
    }
}
