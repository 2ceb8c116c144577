//! The straightforward integration of the standard cloth benchmark
//! ([`cloth_grid`]): an array of `Vec3`, one loop over the springs in build order, one over
//! the particles. The benchmark (`point-springs-bench cloth-grid`, `benches/solver.rs`) and
//! `tests/baselines.rs` compare the library's [`Solver`](bevy_point_springs::core::solver::Solver)
//! against it.

use bevy_point_springs::core::solver::SpringSpec;
#[cfg(doc)]
use bevy_point_springs::core::solver::cloth::cloth_grid;
use bevy_point_springs::core::solver::cloth::{CLOTH_GRAVITY, CLOTH_MASS, ClothGrid};
use glam::Vec3;

/// The straightforward integration of a [`ClothGrid`]: one loop over the springs, one over
/// the particles.
#[derive(Debug, Clone)]
pub struct ReferenceCloth {
    springs: Vec<SpringSpec>,
    fixed: Vec<bool>,
    /// Positions.
    pub x: Vec<Vec3>,
    /// Velocities.
    pub v: Vec<Vec3>,
    f: Vec<Vec3>,
}

impl ReferenceCloth {
    /// The grid at rest.
    pub fn new(grid: &ClothGrid) -> Self {
        let n = grid.positions.len();
        let mut fixed = vec![false; n];
        for i in grid.fixed {
            fixed[i as usize] = true;
        }
        Self {
            springs: grid.springs.clone(),
            fixed,
            x: grid.positions.clone(),
            v: vec![Vec3::ZERO; n],
            f: vec![Vec3::ZERO; n],
        }
    }

    /// One symplectic Euler step.
    pub fn step(&mut self, dt: f32) {
        self.f.fill(Vec3::ZERO);
        for s in &self.springs {
            let (a, b) = (s.a as usize, s.b as usize);
            let d = self.x[b] - self.x[a];
            let len = d.length();
            let dir = d / len;
            let dv = self.v[b] - self.v[a];
            let f = dir * (s.stiffness * (len - s.rest_length) + s.damping * dir.dot(dv));
            self.f[a] += f;
            self.f[b] -= f;
        }
        let g = Vec3::new(0.0, CLOTH_GRAVITY, 0.0);
        for i in 0..self.x.len() {
            if self.fixed[i] {
                continue;
            }
            let a = self.f[i] / CLOTH_MASS + g;
            self.v[i] += a * dt;
            self.x[i] += self.v[i] * dt;
        }
    }
}

/// The largest drop of any particle below its start height.
pub fn max_sag(start: &[Vec3], now: &[Vec3]) -> f32 {
    start
        .iter()
        .zip(now)
        .map(|(s, p)| s.y - p.y)
        .fold(0.0, f32::max)
}
