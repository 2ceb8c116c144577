//! Baking (issue 17): the current shape of a prepared surface becomes its rest shape.

use super::*;
use crate::core::solver::Masses;

impl PreparedSurface {
    /// Makes the surface's current shape its rest shape: the network's rest positions,
    /// normals, spring rest lengths and masses (eq 1, from the triangles' current areas)
    /// measured anew; the solver's springs and masses set from them (stiffness, damping,
    /// plasticity, pins and anchors kept), every velocity zero, a gas's rest volume the
    /// current one; the dense surface's rest positions and normals its deformed ones, with
    /// the transfer computed anew. Run without forces afterwards, nothing moves.
    pub fn bake(&mut self) -> Result<(), PrepareError> {
        let positions = self.solver.points.positions();
        let network = self
            .network
            .reshaped(&positions, self.config.material.density)?;
        let stretch = network.stretch.len();
        let rest = |i: usize| match i.checked_sub(stretch) {
            None => network.stretch[i].rest_length,
            Some(b) => network.bend[b].rest_length,
        };
        let mut springs = self.solver.springs.clone();
        springs.set_rest_lengths(rest)?;
        let mut masses = Masses::new(&network.masses)?;
        for i in (0..masses.len()).filter(|&i| self.solver.masses.is_pinned(i)) {
            masses.set_pinned(i, true)?;
        }
        let pressure = match &self.solver.pressure {
            Some(gas) => Some(Pressure::new(
                network.triangles.clone(),
                &self.solver.points,
                gas.stiffness,
            )?),
            None => None,
        };
        let mut dense = self.dense.clone();
        dense.rebase(&self.solver.points)?;
        // Everything is checked: nothing changes unless every part could be rebuilt.
        self.solver.springs = springs;
        self.solver.masses = masses;
        self.solver.pressure = pressure;
        self.solver.points.stop();
        self.network = network;
        self.dense = dense;
        Ok(())
    }
}
