//! The implicit step's preconditioner: symmetric block Gauss–Seidel,
//!
//! ```text
//! P = (D + L)·D⁻¹·(D + Lᵀ),   z = P⁻¹·r = (D + Lᵀ)⁻¹·D·(D + L)⁻¹·r,
//! ```
//!
//! with D the points' 3×3 diagonal blocks and L the strictly lower 3×3 blocks of the step's
//! sparse matrix (the springs' −C between their ends, each hinge's s·∇ᵢθ∇ⱼθᵀ between its
//! corners, each coupled triangle's h²·Cᵢⱼ·(±uᵢ)(±uⱼ)ᵀ between its corners, on its edges'
//! blocks, each curvature stencil's m·nnᵀ on the pairs its springs join; the gas's dense
//! rank-one term only on the diagonal). One forward and one
//! backward sweep over the blocks, in point order, so the result does not depend on threads.
//! P is symmetric positive definite whenever D is, which any step's matrix gives.
//!
//! Against block Jacobi (D alone) on the generated poked sphere at 2000 simulation points
//! (60 steps, instructions counted by callgrind, 2026-12-03) it takes 10.0 iterations a step
//! for 20.4 with bend springs and 18.6 for 49.7 with hinges, but a sweep costs about as much
//! as a product with the matrix: 3 % more instructions with bend springs, 24 % fewer with
//! hinges; at the paper's 338 points 12–15 % more. So a solve on bend springs starts with
//! block Jacobi and turns to this after `JACOBI_ITERATIONS`; one on hinges or curvature
//! starts with this (see `iterate`). Over-relaxation (SSOR, ω 1.2 to 1.6) took as many
//! iterations or more.
//!
//! A curvature stencil couples every pair of its points, about 50 pairs a point; only those
//! its springs already join enter L (an incomplete factorisation's pattern). On the poked
//! sphere at 2000 points (`bench plugin`, 2026-12-04) they cut a solve from 34.5 to 20.6
//! iterations; every pair (the pattern grown to hold them) 20.1, for sweeps that cost more
//! than the iterations saved.

use glam::{DMat3, DVec3};

use super::{Sym3, System};
use crate::core::solver::parts::COUPLED_PAIRS;

/// The widest curvature stencil whose pairs join the sweeps (wider ones, only from custom
/// specs, keep their diagonal blocks alone, so the pattern's bookkeeping stays bounded).
const MAX_COUPLED_STENCIL: usize = 49;

/// The pairs of corners (j, m), j < m, of a hinge: each couples its two points.
const HINGE_PAIRS: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];

/// The strictly lower 3×3 blocks of the step's matrix by rows (row i: columns j < i,
/// ascending), where each spring and hinge adds to them, and the sweeps' buffers. The
/// pattern is rebuilt only when the springs' ends or the hinges' corners change.
#[derive(Debug, Clone, Default)]
pub(crate) struct GaussSeidel {
    /// The topology the pattern was built for: the points, the springs' ends, the hinges'
    /// corners.
    points: usize,
    a_end: Vec<u32>,
    b_end: Vec<u32>,
    hinge_ends: Vec<[u32; 4]>,
    /// The curvature bending's stencils (`Curvatures::topology`).
    curvature_point: Vec<u32>,
    curvature_start: Vec<u32>,
    curvature_fit: Vec<u32>,
    /// Where each row's blocks start in `column` and `block` (one more than the rows).
    row_start: Vec<u32>,
    column: Vec<u32>,
    block: Vec<DMat3>,
    /// The block each spring adds to, and each hinge's pairs ([`HINGE_PAIRS`]).
    spring_slot: Vec<u32>,
    hinge_slot: Vec<[u32; 6]>,
    /// Per curvature stencil (from `curvature_coupled_start`), its pairs that a spring or a
    /// hinge couples: the block each adds to and where its entry is in
    /// `Curvatures::pair_values`.
    curvature_coupled: Vec<(u32, u32)>,
    curvature_coupled_start: Vec<u32>,
    /// Whether the blocks hold this step's matrix.
    assembled: bool,
    /// The forward sweep's result, and the backward sweep's sums.
    forward: Vec<DVec3>,
    pushed: Vec<DVec3>,
}

impl GaussSeidel {
    fn same_topology(&self, n: usize, system: &System<'_>) -> bool {
        let springs = system.blocks.len();
        let hinges = system.hinges.len();
        self.points == n
            && self.a_end[..] == system.a_end[..springs]
            && self.b_end[..] == system.b_end[..springs]
            && self.hinge_ends[..] == system.hinge_ends[..hinges]
            && (
                &self.curvature_point[..],
                &self.curvature_start[..],
                &self.curvature_fit[..],
            ) == system.curvatures.topology()
    }

    /// The pattern for the system's topology: every pair of points a spring or a hinge
    /// couples, once. Curvature bending couples every pair of a point's stencil; only the
    /// pairs already in this pattern (the stencil's springs) get its blocks, as in an
    /// incomplete factorisation: the sweeps stay as cheap as the springs make them.
    fn build(&mut self, n: usize, system: &System<'_>) {
        let springs = system.blocks.len();
        self.points = n;
        self.a_end = system.a_end[..springs].to_vec();
        self.b_end = system.b_end[..springs].to_vec();
        self.hinge_ends = system.hinge_ends[..system.hinges.len()].to_vec();
        let mut rows: Vec<Vec<u32>> = vec![Vec::new(); n];
        let lower = |i: u32, j: u32| if i > j { (i, j) } else { (j, i) };
        let pairs = (0..springs).map(|s| (self.a_end[s], self.b_end[s])).chain(
            self.hinge_ends
                .iter()
                .flat_map(|e| HINGE_PAIRS.into_iter().map(move |(j, m)| (e[j], e[m]))),
        );
        for (i, j) in pairs {
            let (row, col) = lower(i, j);
            rows[row as usize].push(col);
        }
        self.row_start.clear();
        self.column.clear();
        self.row_start.push(0);
        for row in &mut rows {
            row.sort_unstable();
            row.dedup();
            self.column.extend_from_slice(row);
            self.row_start.push(self.column.len() as u32);
        }
        let find = |i: u32, j: u32| {
            let (row, col) = lower(i, j);
            let start = self.row_start[row as usize] as usize;
            let end = self.row_start[row as usize + 1] as usize;
            let at = self.column[start..end].binary_search(&col).ok()?;
            Some((start + at) as u32)
        };
        // Every spring's and hinge's pair was put in its row above, so the search finds it.
        let slot = |i: u32, j: u32| find(i, j).unwrap_or(0);
        let curvatures = system.curvatures;
        let mut coupled = Vec::new();
        let mut coupled_start = vec![0];
        for c in 0..curvatures.len() {
            let stencil: Vec<u32> = curvatures.stencil(c).collect();
            if stencil.len() <= MAX_COUPLED_STENCIL {
                let mut at = 0;
                curvatures.pairs(c, 1.0, |a, b, _| {
                    if let Some(slot) = find(stencil[a], stencil[b]) {
                        coupled.push((slot, at));
                    }
                    at += 1;
                });
            }
            coupled_start.push(coupled.len() as u32);
        }
        let (point, start, fit) = curvatures.topology();
        self.curvature_point = point.to_vec();
        self.curvature_start = start.to_vec();
        self.curvature_fit = fit.to_vec();
        self.curvature_coupled = coupled;
        self.curvature_coupled_start = coupled_start;
        self.spring_slot = (0..springs)
            .map(|s| slot(self.a_end[s], self.b_end[s]))
            .collect();
        self.hinge_slot = self
            .hinge_ends
            .iter()
            .map(|e| HINGE_PAIRS.map(|(j, m)| slot(e[j], e[m])))
            .collect();
        self.block.clear();
        self.block.resize(self.column.len(), DMat3::ZERO);
        self.forward.resize(n, DVec3::ZERO);
        self.pushed.resize(n, DVec3::ZERO);
    }

    /// Marks the blocks as not this step's (a new step's matrix).
    pub(crate) fn invalidate(&mut self) {
        self.assembled = false;
    }

    /// Whether [`Self::assemble`] filled the blocks since the last [`Self::invalidate`].
    pub(crate) fn is_assembled(&self) -> bool {
        self.assembled
    }

    /// Fills the blocks from the step's `system` of `n` points.
    pub(crate) fn assemble(&mut self, n: usize, system: &System<'_>) {
        self.assembled = true;
        if !self.same_topology(n, system) {
            self.build(n, system);
        }
        self.block.fill(DMat3::ZERO);
        for (c, &slot) in system.blocks.iter().zip(&self.spring_slot) {
            // −C = −(along·ûûᵀ + across·I), symmetric.
            let u = c.u * c.along;
            let outer = DMat3::from_cols(u * c.u.x, u * c.u.y, u * c.u.z);
            self.block[slot as usize] -= outer + DMat3::from_diagonal(DVec3::splat(c.across));
        }
        for ((hinge, ends), slots) in system
            .hinges
            .iter()
            .zip(&self.hinge_ends)
            .zip(&self.hinge_slot)
        {
            for ((j, m), &slot) in HINGE_PAIRS.into_iter().zip(slots) {
                // Row max, column min: s·∇_row θ·∇_col θᵀ.
                let (row, col) = if ends[j] > ends[m] { (j, m) } else { (m, j) };
                let g = hinge.gradient[row] * hinge.scale;
                let c = hinge.gradient[col];
                self.block[slot as usize] += DMat3::from_cols(g * c.x, g * c.y, g * c.z);
            }
        }
        self.add_couplings(system);
        self.add_curvatures(system);
    }

    /// Adds each curvature stencil's blocks m·nnᵀ on the pattern's pairs
    /// (`Curvatures::pairs`).
    fn add_curvatures(&mut self, system: &System<'_>) {
        let curvatures = system.curvatures;
        let starts = self.curvature_coupled_start.windows(2);
        for ((c, held), range) in system.curvature_blocks.iter().enumerate().zip(starts) {
            let n = held.normal;
            if n == DVec3::ZERO {
                continue;
            }
            let outer = DMat3::from_cols(n * n.x, n * n.y, n * n.z);
            let (factor, values) = (
                held.scale * curvatures.modulus(c),
                curvatures.pair_values(c),
            );
            for &(slot, at) in &self.curvature_coupled[range[0] as usize..range[1] as usize] {
                self.block[slot as usize] += outer * (factor * values[at as usize]);
            }
        }
    }

    /// Adds the couplings' off-diagonal blocks h²·Cᵢⱼ·(±uᵢ)(±uⱼ)ᵀ between the corners of
    /// each coupled triangle: every pair of its corners is one of its edges, whose spring's
    /// slot holds the block.
    fn add_couplings(&mut self, system: &System<'_>) {
        for (coupling, springs) in system.couplings.iter().zip(system.coupling_springs) {
            let ends = springs.map(|s| [system.a_end[s as usize], system.b_end[s as usize]]);
            for (&(i, j), &c) in COUPLED_PAIRS.iter().zip(&coupling.scaled) {
                for (p, sign_p) in ends[i].into_iter().zip([1.0, -1.0]) {
                    for (q, sign_q) in ends[j].into_iter().zip([1.0, -1.0]) {
                        let edge =
                            (0..3).find(|&e| p != q && (ends[e] == [p, q] || ends[e] == [q, p]));
                        let Some(edge) = edge else {
                            continue;
                        };
                        // Row max, column min.
                        let (row, col) = if p > q {
                            (coupling.u[i], coupling.u[j])
                        } else {
                            (coupling.u[j], coupling.u[i])
                        };
                        let g = row * (c * sign_p * sign_q);
                        let slot = self.spring_slot[springs[edge] as usize] as usize;
                        self.block[slot] += DMat3::from_cols(g * col.x, g * col.y, g * col.z);
                    }
                }
            }
        }
    }

    /// z = P⁻¹·r (see the module docs) with the diagonal blocks' inverses `diag_inv` (zero
    /// at fixed points, whose z is then zero); returns r·z.
    pub(crate) fn precondition(&mut self, diag_inv: &[Sym3], r: &[DVec3], z: &mut [DVec3]) -> f64 {
        let n = r.len();
        // (D + L)·y = r, row by row.
        for i in 0..n {
            let (start, end) = (self.row_start[i] as usize, self.row_start[i + 1] as usize);
            let mut sum = r[i];
            for (b, &j) in self.block[start..end].iter().zip(&self.column[start..end]) {
                sum -= *b * self.forward[j as usize];
            }
            self.forward[i] = diag_inv[i].mul(sum);
        }
        // (D + Lᵀ)·z = D·y, from the last row up, each row's z pushed to the rows above.
        self.pushed[..n].fill(DVec3::ZERO);
        let mut rz = 0.0;
        for i in (0..n).rev() {
            let zi = self.forward[i] - diag_inv[i].mul(self.pushed[i]);
            z[i] = zi;
            rz += r[i].dot(zi);
            let (start, end) = (self.row_start[i] as usize, self.row_start[i + 1] as usize);
            for (b, &j) in self.block[start..end].iter().zip(&self.column[start..end]) {
                self.pushed[j as usize] +=
                    DVec3::new(b.x_axis.dot(zi), b.y_axis.dot(zi), b.z_axis.dot(zi));
            }
        }
        rz
    }
}
