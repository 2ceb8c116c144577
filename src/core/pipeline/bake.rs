//! Baking (issue 17): the current shape of a surface becomes its rest shape.

use super::*;
use crate::core::solver::{Masses, PointState, Springs};

/// The parts of one surface a bake changes: a [`PreparedSurface`]'s, or the Bevy layer's
/// components.
#[derive(Debug)]
pub struct BakeParts<'a> {
    /// The network at rest (replaced by the one [`bake`] returns).
    pub network: &'a SpringNetwork,
    /// The simulation points: their positions are the new rest shape; velocities go to zero.
    pub points: &'a mut PointState,
    /// Rest lengths and hinges' rest angles set anew (stiffness, damping and plasticity
    /// kept).
    pub springs: &'a mut Springs,
    /// Masses set anew (pins kept).
    pub masses: &'a mut Masses,
    /// A gas's rest volume set to the current one.
    pub pressure: Option<&'a mut Pressure>,
    /// The dense surface: its deformed positions and normals become its rest ones.
    pub dense: &'a mut DenseCloud,
}

/// Makes a surface's current shape its rest shape, returning the new network: rest
/// positions, normals, spring rest lengths and masses (eq 1 with `density`, from the
/// triangles' current areas) measured anew; the springs and masses set from them
/// (stiffness, damping, plasticity, pins and anchors kept), every velocity zero, a gas's
/// rest volume the current one; the dense surface's rest positions and normals its
/// deformed ones, with the transfer computed anew. Run without forces afterwards, nothing
/// moves. On an error nothing is changed.
pub fn bake(parts: BakeParts<'_>, density: f32) -> Result<SpringNetwork, PrepareError> {
    let BakeParts {
        network,
        points,
        springs,
        masses,
        pressure,
        dense,
    } = parts;
    let network = network.reshaped(&points.positions(), density)?;
    let mut new_springs = springs.clone();
    new_springs.set_rest_lengths(|i| network.rest_length(i))?;
    // Rest angles and rest curvatures (and their fits' residual heights) measured anew.
    if !new_springs.hinges().is_empty() || new_springs.curvature_count() > 0 {
        new_springs.set_rest_angles(points)?;
    }
    let mut new_masses = Masses::new(&network.masses)?;
    for i in (0..masses.len()).filter(|&i| masses.is_pinned(i)) {
        new_masses.set_pinned(i, true)?;
    }
    let new_pressure = match &pressure {
        Some(gas) => Some(Pressure::new(
            network.triangles.clone(),
            points,
            gas.stiffness,
        )?),
        None => None,
    };
    let mut new_dense = dense.clone();
    new_dense.rebase(points)?;
    // Everything is checked: nothing changes unless every part could be rebuilt.
    *springs = new_springs;
    *masses = new_masses;
    if let (Some(gas), Some(new)) = (pressure, new_pressure) {
        *gas = new;
    }
    *dense = new_dense;
    points.stop();
    Ok(network)
}

impl PreparedSurface {
    /// [`bake`]s the surface with its material's density.
    pub fn bake(&mut self) -> Result<(), PrepareError> {
        let parts = BakeParts {
            network: &self.network,
            points: &mut self.solver.points,
            springs: &mut self.solver.springs,
            masses: &mut self.solver.masses,
            pressure: self.solver.pressure.as_mut(),
            dense: &mut self.dense,
        };
        self.network = bake(parts, self.config.material.density)?;
        self.solver.set_rest_positions(&self.network.positions)?;
        Ok(())
    }
}
