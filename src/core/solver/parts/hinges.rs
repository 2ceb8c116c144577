//! Hinge bending (discrete shells, Grinspun et al. 2003): an energy on the dihedral angle at
//! every inner edge of the network's triangle mesh, so that a sheet resists folding to first
//! order in the fold angle, with a stiffness that does not depend on the network's spacing.
//!
//! A hinge is the edge p₀→p₁ shared by the triangles (p₀, p₁, w₁) and (p₁, p₀, w₂), both
//! counter-clockwise around the normals. With n₁ = (p₁ − p₀) × (w₁ − p₀), n₂ = (w₂ − p₀) ×
//! (p₁ − p₀) and ê the edge's direction, its signed angle is
//! θ = atan2((n₁ × n₂)·ê, n₁·n₂): zero on a flat sheet, positive where the surface bends away
//! from its normals (every hinge of a sphere with outward normals), in (−π, π]. Its energy is
//! E = k·(θ − θ̄)² with θ̄ the angle at rest, and its damping dissipates ½·c·θ̇². Forces come
//! from θ's exact gradient (Bridson et al. 2003): each wing moves θ along its triangle's
//! normal by 1 over its height, and the edge's ends take the opposite, shared by where the
//! wings' feet fall along the edge. The Jacobian an implicit step uses is the Gauss–Newton
//! term −2k·∇θ∇θᵀ (positive semi-definite; the curvature of θ itself is left out).
//!
//! A hinge whose triangle collapses while running (a height under [`DEGENERATE_HEIGHT`] of its
//! edge) exerts no force that step: its angle is undefined, and its gradient unbounded.

use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};

use super::{PointState, Soa3, non_negative};
use crate::core::solver::SolverError;

/// A triangle's height over its edge, relative to the edge's length, below which a hinge
/// counts as degenerate: refused at rest, without force while running.
pub const DEGENERATE_HEIGHT: f32 = 1.0e-4;

/// One hinge as it is given and read back.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HingeSpec {
    /// The shared edge p₀ → p₁, as the first triangle runs.
    pub edge: [u32; 2],
    /// The far corners w₁ (of (p₀, p₁, w₁)) and w₂ (of (p₁, p₀, w₂)).
    pub wings: [u32; 2],
    /// The angle at rest θ̄, radians in (−π, π].
    pub rest_angle: f32,
    /// k of E = k·(θ − θ̄)², in energy units (N·m), finite and not negative.
    pub stiffness: f32,
    /// c of the dissipation ½·c·θ̇² (N·m·s), finite and not negative.
    pub damping: f32,
}

/// θ and its gradient for the four points of a hinge, p₀, p₁, w₁, w₂ in that order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HingeGeometry {
    /// The signed dihedral angle θ (see the module docs).
    pub angle: f32,
    /// ∂θ/∂p₀, ∂θ/∂p₁, ∂θ/∂w₁, ∂θ/∂w₂ (they sum to zero).
    pub gradient: [Vec3; 4],
}

impl HingeGeometry {
    /// The geometry of the hinge at `x` (p₀, p₁, w₁, w₂), or `None` when either triangle's
    /// height over the edge is below [`DEGENERATE_HEIGHT`] of the edge (or not finite).
    #[inline]
    pub fn at(x: [Vec3; 4]) -> Option<Self> {
        let [p0, p1, w1, w2] = x;
        let e = p1 - p0;
        let e2 = e.length_squared();
        let n1 = e.cross(w1 - p0);
        let n2 = (w2 - p0).cross(e);
        let (m1, m2) = (n1.length_squared(), n2.length_squared());
        // |n| = |e|·height, so the height test is |n|² > (δ·|e|²)².
        let floor = (DEGENERATE_HEIGHT * e2) * (DEGENERATE_HEIGHT * e2);
        if !(e2 > 0.0 && m1 > floor && m2 > floor && m1.is_finite() && m2.is_finite()) {
            return None;
        }
        let len = e2.sqrt();
        let angle = (n1.cross(n2).dot(e) / len).atan2(n1.dot(n2));
        let g1 = n1 * (-len / m1);
        let g2 = n2 * (-len / m2);
        let (a1, a2) = ((w1 - p0).dot(e) / e2, (w2 - p0).dot(e) / e2);
        let gradient = [
            -(1.0 - a1) * g1 - (1.0 - a2) * g2,
            -a1 * g1 - a2 * g2,
            g1,
            g2,
        ];
        Some(Self { angle, gradient })
    }
}

/// θ − θ̄ taken into (−π, π]: a hinge folded past ±180° turns back the short way.
#[inline]
pub fn angle_difference(angle: f32, rest: f32) -> f32 {
    use std::f32::consts::{PI, TAU};
    let d = angle - rest;
    if d > PI {
        d - TAU
    } else if d <= -PI {
        d + TAU
    } else {
        d
    }
}

/// A finite angle taken into [−π, π]: as it is when it lies there (so that a rest angle read
/// back from a snapshot keeps its bits), else wrapped by whole turns.
fn principal(angle: f32) -> f32 {
    use std::f32::consts::{PI, TAU};
    if (-PI..=PI).contains(&angle) {
        angle
    } else {
        (angle + PI).rem_euclid(TAU) - PI
    }
}

/// The hinges of a surface (see the module docs), with their rest angles, stiffness and
/// damping. Part of [`Springs`](super::Springs), so that wherever springs go — the Bevy
/// layer's components, snapshots, bakes, plastic flow — bending goes too.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Hinges {
    /// p₀, p₁, w₁, w₂ of each hinge.
    pub(crate) ends: Vec<[u32; 4]>,
    pub(crate) rest: Vec<f32>,
    pub(crate) k: Vec<f32>,
    pub(crate) c: Vec<f32>,
    /// |∂θ/∂x| at each of the four points in the rest shape, for the stable-step estimate.
    pub(crate) rest_gradient: Vec<[f32; 4]>,
}

impl Hinges {
    /// Hinges from their specs over `points` points at `rest` (one position per point): the
    /// four points of each distinct and in range, the numbers finite and not negative, and
    /// the rest shape not degenerate at any hinge ([`DEGENERATE_HEIGHT`]).
    pub fn new(specs: &[HingeSpec], rest: &[Vec3]) -> Result<Self, SolverError> {
        let points = rest.len();
        let mut hinges = Self::default();
        for (hinge, s) in specs.iter().enumerate() {
            let ends = [s.edge[0], s.edge[1], s.wings[0], s.wings[1]];
            let distinct = (0..4).all(|i| (i + 1..4).all(|j| ends[i] != ends[j]));
            if !distinct || ends.iter().any(|&i| i as usize >= points) {
                return Err(SolverError::InvalidHinge {
                    hinge,
                    what: "its four points must be distinct and in range",
                });
            }
            let numbers = [s.stiffness, s.damping];
            if !(numbers.into_iter().all(non_negative) && s.rest_angle.is_finite()) {
                return Err(SolverError::InvalidHinge {
                    hinge,
                    what: "stiffness and damping must be finite and not negative, the rest angle finite",
                });
            }
            let Some(g) = HingeGeometry::at(ends.map(|i| rest[i as usize])) else {
                return Err(SolverError::InvalidHinge {
                    hinge,
                    what: "a triangle of its rest shape has (almost) no area",
                });
            };
            hinges.ends.push(ends);
            hinges.rest.push(principal(s.rest_angle));
            hinges.k.push(s.stiffness);
            hinges.c.push(s.damping);
            hinges.rest_gradient.push(g.gradient.map(Vec3::length));
        }
        Ok(hinges)
    }

    /// Number of hinges.
    pub fn len(&self) -> usize {
        self.ends.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.ends.is_empty()
    }

    /// Every hinge, in the order given.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = HingeSpec> + '_ {
        (0..self.len()).map(|h| {
            let [p0, p1, w1, w2] = self.ends[h];
            HingeSpec {
                edge: [p0, p1],
                wings: [w1, w2],
                rest_angle: self.rest[h],
                stiffness: self.k[h],
                damping: self.c[h],
            }
        })
    }

    /// The four points of hinge `h` at `points`.
    #[inline]
    fn corners(&self, h: usize, points: &PointState) -> [Vec3; 4] {
        self.ends[h].map(|i| points.position(i as usize))
    }

    /// The current angle of every hinge (0 where degenerate).
    pub fn angles(&self, points: &PointState) -> Vec<f32> {
        (0..self.len())
            .map(|h| HingeGeometry::at(self.corners(h, points)).map_or(0.0, |g| g.angle))
            .collect()
    }

    /// Adds the bending forces −(2k·(θ − θ̄) + c·θ̇)·∇θ at `points` to `f`, and writes each
    /// hinge's ∇θ there into `gradients` (zero where degenerate) for an implicit step at the
    /// same state ([`Self::linearised`]).
    pub(crate) fn accumulate(
        &self,
        points: &PointState,
        f: &mut Soa3,
        gradients: &mut Vec<[Vec3; 4]>,
    ) {
        gradients.clear();
        gradients.resize(self.len(), [Vec3::ZERO; 4]);
        let (x, v) = (&points.x, &points.v);
        for (h, out) in gradients.iter_mut().enumerate() {
            let ends = self.ends[h].map(|i| i as usize);
            let Some(g) = HingeGeometry::at(ends.map(|i| x.get(i))) else {
                continue;
            };
            let rate: f32 = (0..4).map(|j| g.gradient[j].dot(v.get(ends[j]))).sum();
            let torque =
                2.0 * self.k[h] * angle_difference(g.angle, self.rest[h]) + self.c[h] * rate;
            for (&i, &gradient) in ends.iter().zip(&g.gradient) {
                f.set(i, f.get(i) - torque * gradient);
            }
            *out = g.gradient;
        }
    }

    /// The bending energy Σk·(θ − θ̄)² at `points`.
    pub fn energy(&self, points: &PointState) -> f64 {
        (0..self.len())
            .filter_map(|h| {
                let g = HingeGeometry::at(self.corners(h, points))?;
                let d = f64::from(angle_difference(g.angle, self.rest[h]));
                Some(f64::from(self.k[h]) * d * d)
            })
            .sum()
    }

    /// The linearised hinges for an implicit step of length `step` from the gradients
    /// [`Self::accumulate`] wrote at `points`: for each hinge its gradient (in `f64`), the scale
    /// s = h·c + h²·2k of its block s·∇θ∇θᵀ, and h²·2k·(∇θ·v) for the right-hand side (zero
    /// for a degenerate hinge, whose gradient is zero).
    /// The signed lengths of hinge `h`'s rest gradient ∇θ over its four points (edge points
    /// −, wings +: on a flat hinge ∇θ is one direction times these), scaled so that they sum
    /// to zero as ∇θ does; zero for a hinge without a rest gradient.
    pub(crate) fn scalar_gradient(&self, h: usize) -> [f64; 4] {
        let g = self.rest_gradient[h].map(f64::from);
        let (edge, wings) = (g[0] + g[1], g[2] + g[3]);
        if !(edge > 0.0 && wings > 0.0) {
            return [0.0; 4];
        }
        let mean = 0.5 * (edge + wings);
        [
            -g[0] * mean / edge,
            -g[1] * mean / edge,
            g[2] * mean / wings,
            g[3] * mean / wings,
        ]
    }

    pub(crate) fn linearised(
        &self,
        gradients: &[[Vec3; 4]],
        points: &PointState,
        step: f64,
        out: &mut Vec<HingeBlock>,
    ) {
        out.clear();
        out.extend(gradients.iter().enumerate().map(|(h, g)| {
            let gradient = g.map(|g| g.as_dvec3());
            let ends = self.ends[h];
            let rate: f64 = (0..4)
                .map(|j| gradient[j].dot(points.velocity(ends[j] as usize).as_dvec3()))
                .sum();
            let k2 = 2.0 * f64::from(self.k[h]);
            HingeBlock {
                gradient,
                scale: step * f64::from(self.c[h]) + step * step * k2,
                rhs: step * step * k2 * rate,
            }
        }));
    }

    /// Sets every rest angle to the angle at `points` (a bake); refused, nothing changed,
    /// where a hinge's triangle has collapsed there.
    pub fn set_rest_shape(&mut self, points: &PointState) -> Result<(), SolverError> {
        let mut rest = Vec::with_capacity(self.len());
        let mut norms = Vec::with_capacity(self.len());
        for h in 0..self.len() {
            let g =
                HingeGeometry::at(self.corners(h, points)).ok_or(SolverError::InvalidHinge {
                    hinge: h,
                    what: "a triangle of the new rest shape has (almost) no area",
                })?;
            rest.push(g.angle);
            norms.push(g.gradient.map(Vec3::length));
        }
        self.rest = rest;
        self.rest_gradient = norms;
        Ok(())
    }

    /// Sets every hinge's rest angle, stiffness and damping from its index (`of(index)` gives
    /// `[rest angle, stiffness, damping]`; refused, nothing changed, when one is not finite or
    /// the stiffness or damping is negative).
    pub fn set_parameters(
        &mut self,
        mut of: impl FnMut(usize) -> [f32; 3],
    ) -> Result<(), SolverError> {
        let values: Vec<[f32; 3]> = (0..self.len()).map(&mut of).collect();
        if let Some(hinge) = values
            .iter()
            .position(|&[r, k, c]| !(r.is_finite() && non_negative(k) && non_negative(c)))
        {
            return Err(SolverError::InvalidHinge {
                hinge,
                what: "stiffness and damping must be finite and not negative, the rest angle finite",
            });
        }
        for (h, [r, k, c]) in values.into_iter().enumerate() {
            self.rest[h] = principal(r);
            self.k[h] = k;
            self.c[h] = c;
        }
        Ok(())
    }

    /// Plastic flow on the rest angles after a step: a hinge bent more than `yield_angle`
    /// past its rest angle moves the rest angle `fraction` of the way to where the bend would
    /// be the yield angle. Returns how many hinges flowed.
    pub(crate) fn flow(&mut self, points: &PointState, yield_angle: f32, fraction: f32) -> usize {
        let mut flowed = 0;
        for h in 0..self.len() {
            let Some(g) = HingeGeometry::at(self.corners(h, points)) else {
                continue;
            };
            let d = angle_difference(g.angle, self.rest[h]);
            if d.abs() <= yield_angle {
                continue;
            }
            let excess = d - yield_angle.copysign(d);
            self.rest[h] = angle_difference(self.rest[h] + fraction * excess, 0.0);
            flowed += 1;
        }
        flowed
    }

    /// Adds each hinge's Gershgorin row bound of the Gauss–Newton Hessian at rest to `stiff`
    /// (2k·|gᵢ|·Σⱼ|gⱼ|) and of its damping to `damp` (c·|gᵢ|·Σⱼ|gⱼ|); returns the smallest
    /// c/(2k) (∞ with none), the hinges' time constant for explicit Euler.
    pub(crate) fn stability_rows(&self, stiff: &mut [f64], damp: &mut [f64]) -> f64 {
        let mut ratio = f64::INFINITY;
        for h in 0..self.len() {
            let norms = self.rest_gradient[h].map(f64::from);
            let sum: f64 = norms.iter().sum();
            let (k2, c) = (2.0 * f64::from(self.k[h]), f64::from(self.c[h]));
            for (j, &i) in self.ends[h].iter().enumerate() {
                stiff[i as usize] += k2 * norms[j] * sum;
                damp[i as usize] += c * norms[j] * sum;
            }
            if k2 > 0.0 {
                ratio = ratio.min(c / k2);
            }
        }
        ratio
    }
}

/// One hinge's part of an implicit step (see [`Hinges::linearised`]).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct HingeBlock {
    pub gradient: [DVec3; 4],
    pub scale: f64,
    pub rhs: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A hinge over the unit edge along X, wings at ±1 across it, folded by `fold`.
    fn folded(fold: f32) -> [Vec3; 4] {
        let (s, c) = fold.sin_cos();
        [
            Vec3::ZERO,
            Vec3::X,
            Vec3::new(0.3, 1.0, 0.0),
            Vec3::new(0.6, -c, -s),
        ]
    }

    #[test]
    fn the_angle_is_signed_and_its_gradient_is_the_derivative() {
        assert!(HingeGeometry::at(folded(0.0)).unwrap().angle.abs() < 1e-6);
        // Bending the second wing below the first's normal (+Z) bends away from the normals.
        for fold in [0.4f32, -0.9, 2.5, -3.0] {
            let x = folded(fold);
            let g = HingeGeometry::at(x).unwrap();
            assert!((g.angle - fold).abs() < 1e-5, "{} vs {fold}", g.angle);
            let sum: Vec3 = g.gradient.iter().sum();
            assert!(sum.length() < 1e-5);
            let h = 1e-3;
            for j in 0..4 {
                for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
                    let (mut plus, mut minus) = (x, x);
                    plus[j] += axis * h;
                    minus[j] -= axis * h;
                    let numeric = angle_difference(
                        HingeGeometry::at(plus).unwrap().angle,
                        HingeGeometry::at(minus).unwrap().angle,
                    ) / (2.0 * h);
                    let exact = g.gradient[j].dot(axis);
                    assert!(
                        (numeric - exact).abs() < 2e-3,
                        "{j} {axis}: {numeric} vs {exact}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_collapsed_triangle_is_no_hinge_and_a_wrapped_fold_turns_back() {
        let mut x = folded(0.3);
        x[2] = Vec3::new(0.5, 0.0, 0.0);
        assert!(HingeGeometry::at(x).is_none());
        assert!(
            Hinges::new(
                &[HingeSpec {
                    edge: [0, 1],
                    wings: [2, 3],
                    rest_angle: 0.0,
                    stiffness: 1.0,
                    damping: 0.0
                }],
                &x
            )
            .is_err()
        );
        assert_eq!(principal(0.1), 0.1);
        assert!((principal(100.0) - (100.0 - 32.0 * std::f32::consts::PI)).abs() < 1e-4);
        let d = angle_difference(3.0, -3.0);
        assert!((d - (6.0 - std::f32::consts::TAU)).abs() < 1e-6);
    }
}
