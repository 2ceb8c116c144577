//! The standard CPU cloth benchmark network, and the straightforward integration it is
//! measured against.
//!
//! Built exactly as the widely used benchmark builds it: `size × size` particles (32 × 32),
//! particle (x, y) at (0.1·x, 0, 0.1·y); springs from each particle to its horizontal
//! neighbour (x − 1), its horizontal second neighbour (x − 2, bend), both diagonal neighbours
//! in the previous row (shear), its vertical neighbour (y − 1) and its vertical second
//! neighbour (y − 2, bend) — 5826 springs at 32 × 32; every spring of stiffness 1000 and
//! damping 10 along the spring, particle mass 0.1, the two corners of row y = 0 fixed,
//! gravity −9.81 along Y, symplectic Euler at dt = 1/960 for 1000 steps, in `f32`.
//!
//! [`ReferenceCloth`] integrates the same network the straightforward way (an array of
//! `Vec3`, one loop over the springs in build order, one over the particles); the benchmark
//! and the tests compare the [`Solver`] against it.

use glam::Vec3;

use super::{
    DampingModel, Integrator, Solver, SolverConfig, SolverError, SpringSpec, SubstepPolicy,
};

/// Particles per side.
pub const CLOTH_SIZE: usize = 32;
/// Distance between neighbouring particles.
pub const CLOTH_SPACING: f32 = 0.1;
/// Stiffness of every spring.
pub const CLOTH_STIFFNESS: f32 = 1000.0;
/// Damping of every spring (along the spring).
pub const CLOTH_DAMPING: f32 = 10.0;
/// Mass of every particle.
pub const CLOTH_MASS: f32 = 0.1;
/// Gravity along Y.
pub const CLOTH_GRAVITY: f32 = -9.81;
/// Time step.
pub const CLOTH_DT: f32 = 1.0 / 960.0;
/// Steps per run.
pub const CLOTH_STEPS: usize = 1000;
/// Largest side accepted (16.7 million particles).
pub const MAX_CLOTH_SIZE: usize = 4096;

/// The benchmark network.
#[derive(Debug, Clone, PartialEq)]
pub struct ClothGrid {
    /// Particles per side.
    pub size: usize,
    /// Start positions, row y = 0 first.
    pub positions: Vec<Vec3>,
    /// The springs, in build order.
    pub springs: Vec<SpringSpec>,
    /// The two fixed corners of row y = 0.
    pub fixed: [u32; 2],
}

/// Builds the benchmark network with `size` particles per side (at least 2).
pub fn cloth_grid(size: usize) -> Result<ClothGrid, SolverError> {
    if !(2..=MAX_CLOTH_SIZE).contains(&size) {
        return Err(SolverError::InvalidConfig(
            "the cloth grid needs between 2 and 4096 particles per side",
        ));
    }
    let id = |x: usize, y: usize| (y * size + x) as u32;
    let mut positions = Vec::with_capacity(size * size);
    let mut springs = Vec::new();
    for y in 0..size {
        for x in 0..size {
            let p = Vec3::new(CLOTH_SPACING * x as f32, 0.0, CLOTH_SPACING * y as f32);
            positions.push(p);
            let mut link = |ox: usize, oy: usize| {
                let rest = (positions[id(ox, oy) as usize] - p).length();
                springs.push(SpringSpec {
                    a: id(x, y),
                    b: id(ox, oy),
                    rest_length: rest,
                    stiffness: CLOTH_STIFFNESS,
                    damping: CLOTH_DAMPING,
                });
            };
            if x >= 1 {
                link(x - 1, y);
            }
            if x >= 2 {
                link(x - 2, y);
            }
            if y >= 1 {
                if x >= 1 {
                    link(x - 1, y - 1);
                }
                if x + 1 < size {
                    link(x + 1, y - 1);
                }
                link(x, y - 1);
            }
            if y >= 2 {
                link(x, y - 2);
            }
        }
    }
    Ok(ClothGrid {
        size,
        positions,
        springs,
        fixed: [id(0, 0), id(size - 1, 0)],
    })
}

impl ClothGrid {
    /// A [`Solver`] set up as the benchmark prescribes (symplectic Euler, damping along the
    /// springs, the step taken as given).
    pub fn solver(&self) -> Result<Solver, SolverError> {
        self.solver_with(Integrator::SymplecticEuler, SubstepPolicy::Unchecked)
    }

    /// The same network with another integrator and sub-step policy.
    pub fn solver_with(
        &self,
        integrator: Integrator,
        substeps: SubstepPolicy,
    ) -> Result<Solver, SolverError> {
        let config = SolverConfig {
            integrator,
            damping_model: DampingModel::Axial,
            gravity: Vec3::new(0.0, CLOTH_GRAVITY, 0.0),
            drag: 0.0,
            substeps,
            ..SolverConfig::default()
        };
        let masses = vec![CLOTH_MASS; self.positions.len()];
        let mut solver = Solver::new(&self.positions, &masses, &self.springs, config)?;
        for i in self.fixed {
            solver.set_fixed(i as usize, true)?;
        }
        Ok(solver)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_32_grid_has_5826_springs_in_five_families() {
        let grid = cloth_grid(CLOTH_SIZE).unwrap();
        assert_eq!(grid.positions.len(), 1024);
        assert_eq!(grid.springs.len(), 5826);
        assert_eq!(grid.fixed, [0, 31]);
        let solver = grid.solver().unwrap();
        // Every family is a run of consecutive springs: nothing is left to the scalar loop.
        assert_eq!(solver.springs_in_runs(), 5826);
    }

    #[test]
    fn tiny_and_huge_grids_are_refused() {
        assert!(cloth_grid(1).is_err());
        assert!(cloth_grid(MAX_CLOTH_SIZE + 1).is_err());
        assert_eq!(cloth_grid(2).unwrap().springs.len(), 6);
    }
}
