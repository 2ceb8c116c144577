//! Gas pressure inside a closed surface: the force that pushes a poked sphere back out.

use glam::{DVec3, Vec3};

use super::*;

/// Gas inside a closed surface: the over-pressure ΔP = κ·(V₀/V − 1) of an ideal gas kept at
/// one temperature (κ is the outside pressure) pushes every triangle of the surface outward
/// with ΔP times its area, a third to each corner. A shell of springs alone keeps any
/// shape its springs' lengths allow — a dent pushed through stays, as a ping-pong ball's
/// does — while a closed surface with pressure springs back, like a ball.
#[derive(Debug, Clone, PartialEq)]
pub struct Pressure {
    triangles: Vec<[u32; 3]>,
    /// Where volumes are measured from (the rest centroid), for precision.
    origin: Vec3,
    rest_volume: f64,
    /// κ, force per unit area.
    pub stiffness: f32,
    pub(crate) revision: u64,
}

impl Pressure {
    /// Gas of stiffness κ (finite, not negative) filling the closed surface of
    /// `triangles` (counter-clockwise seen from outside) over points at rest at `rest`.
    pub fn new(
        triangles: Vec<[u32; 3]>,
        rest: &PointState,
        stiffness: f32,
    ) -> Result<Self, SolverError> {
        if !non_negative(stiffness) {
            return Err(SolverError::InvalidConfig(
                "the pressure stiffness must be finite and not negative",
            ));
        }
        let n = rest.len();
        if let Some(t) = triangles
            .iter()
            .find(|t| t.iter().any(|&i| i as usize >= n))
        {
            return Err(SolverError::PointOutOfRange {
                index: t.iter().copied().max().unwrap_or(0) as usize,
                points: n,
            });
        }
        let origin = if n == 0 {
            Vec3::ZERO
        } else {
            rest.iter_positions().sum::<Vec3>() / n as f32
        };
        let mut pressure = Self {
            triangles,
            origin,
            rest_volume: 0.0,
            stiffness,
            revision: next_revision(),
        };
        pressure.rest_volume = pressure.volume(rest);
        if !(pressure.rest_volume > 0.0 && pressure.rest_volume.is_finite()) {
            return Err(SolverError::InvalidConfig(
                "pressure needs a closed surface enclosing a positive volume",
            ));
        }
        Ok(pressure)
    }

    /// The enclosed volume at `points`.
    pub fn volume(&self, points: &PointState) -> f64 {
        let o = self.origin.as_dvec3();
        let at = |i: u32| points.position(i as usize).as_dvec3() - o;
        self.triangles
            .iter()
            .map(|&[a, b, c]| at(a).dot(at(b).cross(at(c))))
            .sum::<f64>()
            / 6.0
    }

    /// The enclosed volume at rest.
    pub fn rest_volume(&self) -> f64 {
        self.rest_volume
    }

    /// The over-pressure at `points`.
    pub fn over_pressure(&self, points: &PointState) -> f64 {
        let v = self.volume(points).max(self.rest_volume * 1e-3);
        f64::from(self.stiffness) * (self.rest_volume / v - 1.0)
    }

    /// Adds the pressure forces at `points` to `f`.
    pub(crate) fn accumulate(&self, points: &PointState, f: &mut Soa3) {
        if self.stiffness == 0.0 {
            return;
        }
        let dp = self.over_pressure(points) as f32;
        for &[a, b, c] in &self.triangles {
            let (a, b, c) = (a as usize, b as usize, c as usize);
            let (xa, xb, xc) = (points.position(a), points.position(b), points.position(c));
            // A third of ΔP times the area vector ½(b − a) × (c − a).
            let share = (xb - xa).cross(xc - xa) * (dp / 6.0);
            for i in [a, b, c] {
                f.set(i, f.get(i) + share);
            }
        }
    }

    /// The linearised gas for an implicit step: writes the enclosed volume's gradient at
    /// each point (the area-vector form of [`Self::accumulate`], a third of each triangle's
    /// area vector to each corner) into `grad` and returns c = −dΔP/dV = κ·V₀/V², so that
    /// the force's Jacobian is −c·ggᵀ plus ΔP times the volume's Hessian (indefinite, left
    /// out to keep the step's matrix positive definite).
    pub(crate) fn linearised(&self, points: &PointState, grad: &mut Vec<DVec3>) -> f64 {
        grad.clear();
        grad.resize(points.len(), DVec3::ZERO);
        if self.stiffness == 0.0 {
            return 0.0;
        }
        for &[a, b, c] in &self.triangles {
            let (a, b, c) = (a as usize, b as usize, c as usize);
            let (xa, xb, xc) = (
                points.position(a).as_dvec3(),
                points.position(b).as_dvec3(),
                points.position(c).as_dvec3(),
            );
            let share = (xb - xa).cross(xc - xa) / 6.0;
            for i in [a, b, c] {
                grad[i] += share;
            }
        }
        let v = self.volume(points).max(self.rest_volume * 1e-3);
        f64::from(self.stiffness) * self.rest_volume / (v * v)
    }

    /// An upper bound on the gas's contribution to the largest squared angular frequency
    /// (1/s²) at `points` with `masses`: c·Σᵢ|gᵢ|²/mᵢ, the rank-one term's one eigenvalue
    /// (g the volume's gradient, c = κ·V₀/V²), plus |ΔP| times a Gershgorin bound of the volume's Hessian
    /// (each triangle's longest edge over 3, per corner, over the corner's mass). Free
    /// points only.
    pub fn stiffness_bound(&self, points: &PointState, masses: &Masses) -> f64 {
        if self.stiffness == 0.0 || points.is_empty() {
            return 0.0;
        }
        let mut grad = Vec::new();
        let c = self.linearised(points, &mut grad);
        let free = |i: usize| !masses.is_pinned(i);
        let inv = |i: usize| 1.0 / f64::from(masses.mass(i));
        let rank_one: f64 = (0..points.len())
            .filter(|&i| free(i))
            .map(|i| grad[i].length_squared() * inv(i))
            .sum::<f64>()
            * c;
        let mut row = vec![0.0f64; points.len()];
        for &[a, b, c] in &self.triangles {
            let (a, b, c) = (a as usize, b as usize, c as usize);
            let p = |i: usize| points.position(i).as_dvec3();
            let longest = (p(b) - p(a))
                .length()
                .max((p(c) - p(b)).length())
                .max((p(a) - p(c)).length());
            for i in [a, b, c] {
                row[i] += longest / 3.0;
            }
        }
        let hessian = (0..points.len())
            .filter(|&i| free(i))
            .map(|i| row[i] * inv(i))
            .fold(0.0, f64::max)
            * self.over_pressure(points).abs();
        rank_one + hessian
    }

    /// The gas's potential energy at `points`: κ·(V − V₀) − κ·V₀·ln(V/V₀).
    pub fn energy(&self, points: &PointState) -> f64 {
        let (v, v0) = (self.volume(points), self.rest_volume);
        let k = f64::from(self.stiffness);
        if v <= 0.0 {
            return f64::INFINITY;
        }
        k * (v - v0) - k * v0 * (v / v0).ln()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::solver::parts::tests::tetrahedron;

    #[test]
    fn pressure_pushes_along_the_volume_gradient() {
        let (mut points, faces) = tetrahedron();
        let gas = Pressure::new(faces.clone(), &points, 10.0).unwrap();
        // The tetrahedron inscribed in the cube [-1, 1]³ holds a third of it.
        assert!((gas.rest_volume() - 8.0 / 3.0).abs() < 1e-9);
        // At rest: no over-pressure, no force.
        let mut f = Soa3::zeros(4);
        gas.accumulate(&points, &mut f);
        assert!(f.to_vec3().iter().all(|v| v.length() < 1e-6));
        // Squeezed: the force on a corner is ΔP times dV/dx (checked by finite differences).
        points.set_position(0, Vec3::splat(0.5)).unwrap();
        let mut f = Soa3::zeros(4);
        gas.accumulate(&points, &mut f);
        let dp = gas.over_pressure(&points);
        assert!(dp > 0.0);
        let h = 1e-3;
        for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
            let (mut plus, mut minus) = (points.clone(), points.clone());
            plus.set_position(0, Vec3::splat(0.5) + axis * h).unwrap();
            minus.set_position(0, Vec3::splat(0.5) - axis * h).unwrap();
            let grad = (gas.volume(&plus) - gas.volume(&minus)) / (2.0 * f64::from(h));
            let along = f64::from(f.get(0).dot(axis));
            assert!(
                (along - dp * grad).abs() < 1e-3 * dp.abs().max(1.0),
                "{along} vs {}",
                dp * grad
            );
        }
        // Inside out is no volume at all: refused.
        let inverted: Vec<[u32; 3]> = faces.iter().map(|&[a, b, c]| [a, c, b]).collect();
        let (rest, _) = tetrahedron();
        assert!(Pressure::new(inverted, &rest, 10.0).is_err());
    }
}
