//! The transfer's transpose: forces given on the dense surface, carried to the simulation
//! points.

use glam::Vec3;

use super::{NeighbourIndex, Neighbours, Transfer, TransferError, row_stride};

impl Transfer {
    /// The forces on the simulation points that do the same work as `dense_forces` (one per
    /// dense point) on every displacement the transfer can draw: a dense point's force goes
    /// to the simulation points it follows with the coefficients its fitted displacement
    /// reads them with (the transpose of the value map, u(p) = Σⱼ cⱼuⱼ), so
    /// Σᵢ fᵢ·u(pᵢ) = Σⱼ Fⱼ·uⱼ for any simulation displacements u. As the coefficients of a row
    /// sum to 1, the total force is kept (`ΣF = Σf`); the torque is kept only where the fit
    /// reproduces the rest surface. This is how a load defined on the dense surface (a
    /// pressure over a disc, a pull at a dense point) reaches the simulation the same way at
    /// every simulation level.
    ///
    /// Written into `simulation_forces` (one per simulation point, overwritten). Lengths that
    /// do not match and a non-finite force are typed errors.
    pub fn spread_forces(
        &self,
        dense_forces: &[Vec3],
        simulation_forces: &mut [Vec3],
    ) -> Result<(), TransferError> {
        for (which, expected, found) in [
            ("dense", self.len(), dense_forces.len()),
            ("simulation", self.sim_rest.len(), simulation_forces.len()),
        ] {
            if found != expected {
                return Err(TransferError::ForceCount {
                    which,
                    expected,
                    found,
                });
            }
        }
        if let Some(i) = dense_forces.iter().position(|f| !f.is_finite()) {
            return Err(TransferError::InvalidForce(i));
        }
        simulation_forces.fill(Vec3::ZERO);
        match &self.neighbours {
            Neighbours::Narrow(n) => self.spread(n, dense_forces, simulation_forces),
            Neighbours::Wide(n) => self.spread(n, dense_forces, simulation_forces),
        }
        Ok(())
    }

    /// [`Self::spread_forces`] over one neighbour layout (lengths checked).
    fn spread<I: NeighbourIndex>(&self, neighbours: &[I], dense: &[Vec3], out: &mut [Vec3]) {
        let k = self.k;
        let m = k - 1;
        for (i, &f) in dense.iter().enumerate() {
            if f == Vec3::ZERO {
                continue;
            }
            let (anchor, others) = neighbours[i * k..(i + 1) * k].split_at(1);
            let values = &self.coefficients[i * row_stride(k)..][..m];
            // u = u_a + Σ cⱼ(uⱼ − u_a): the anchor reads 1 − Σcⱼ of f, each other cⱼ.
            let mut anchor_share = f;
            for (j, &c) in others.iter().zip(values) {
                out[j.get()] += f * c;
                anchor_share -= f * c;
            }
            out[anchor[0].get()] += anchor_share;
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::{Quat, Vec3};

    use crate::core::cloud::shapes::{fibonacci_sphere, hat};
    use crate::core::transfer::{Transfer, TransferConfig, TransferError};

    /// Deterministic pseudo-random vectors in [−1, 1]³.
    fn noise(n: usize, seed: u32) -> Vec<Vec3> {
        let mut s = seed.wrapping_mul(2_654_435_761).max(1);
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s as f32 / u32::MAX as f32 * 2.0 - 1.0
        };
        (0..n).map(|_| Vec3::new(next(), next(), next())).collect()
    }

    #[test]
    fn spread_forces_do_the_same_work_and_keep_the_total() {
        for (dense, sim) in [
            (fibonacci_sphere(1500, 1.0), fibonacci_sphere(120, 1.0)),
            (hat(1200, 1.0, -0.2), hat(90, 1.0, -0.2)),
        ] {
            let sim_rest = sim.positions().to_vec();
            let (p, n) = (dense.positions(), dense.normals().unwrap());
            let transfer = Transfer::new(p, n, &sim_rest, TransferConfig::default()).unwrap();
            let f = noise(p.len(), 7);
            let mut spread = vec![Vec3::ZERO; sim_rest.len()];
            transfer.spread_forces(&f, &mut spread).unwrap();
            let total: Vec3 = f.iter().sum();
            let carried: Vec3 = spread.iter().sum();
            assert!(total.distance(carried) < 1e-3, "{total} against {carried}");
            // Virtual work, for a rotation (affine) and for noise (any displacement).
            let turn = Quat::from_rotation_z(0.3);
            for u in [
                sim_rest.iter().map(|&s| turn * s - s).collect::<Vec<_>>(),
                noise(sim_rest.len(), 11),
            ] {
                let (moved, _) = transfer.deform(&u).unwrap();
                let dense_work: f32 = (0..p.len()).map(|i| f[i].dot(moved[i] - p[i])).sum();
                let sim_work: f32 = spread.iter().zip(&u).map(|(a, b)| a.dot(*b)).sum();
                assert!(
                    (dense_work - sim_work).abs() < 1e-3 * dense_work.abs().max(1.0),
                    "{dense_work} against {sim_work}"
                );
            }
        }
    }

    #[test]
    fn spread_forces_refuses_wrong_lengths_and_non_finite_forces() {
        let dense = fibonacci_sphere(200, 1.0);
        let sim_rest = fibonacci_sphere(30, 1.0).positions().to_vec();
        let (p, n) = (dense.positions(), dense.normals().unwrap());
        let transfer = Transfer::new(p, n, &sim_rest, TransferConfig::default()).unwrap();
        let mut out = vec![Vec3::ZERO; 30];
        assert_eq!(
            transfer.spread_forces(&[Vec3::X; 199], &mut out),
            Err(TransferError::ForceCount {
                which: "dense",
                expected: 200,
                found: 199
            })
        );
        assert_eq!(
            transfer.spread_forces(&[Vec3::X; 200], &mut out[..29]),
            Err(TransferError::ForceCount {
                which: "simulation",
                expected: 30,
                found: 29
            })
        );
        let mut forces = [Vec3::X; 200];
        forces[17].y = f32::NAN;
        assert_eq!(
            transfer.spread_forces(&forces, &mut out),
            Err(TransferError::InvalidForce(17))
        );
        forces[17] = Vec3::splat(f32::INFINITY);
        assert_eq!(
            transfer.spread_forces(&forces, &mut out),
            Err(TransferError::InvalidForce(17))
        );
    }
}
