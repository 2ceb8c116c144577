//! Baking (issue 17): the current shape of a surface becomes its rest shape.

use super::*;
use std::sync::Arc;

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
/// positions, normals, spring rest lengths and masses (each point's share of the dense
/// area grown or shrunk with its triangles' areas, see [`SpringNetwork::reshaped`])
/// measured anew; the springs and masses set from them
/// (stiffness, damping, plasticity, pins and anchors kept), every velocity zero, a gas's
/// rest volume the current one; the dense surface's rest positions and normals its
/// deformed ones, with the transfer computed anew. Run without forces afterwards, nothing
/// moves. On an error nothing is changed. [`BakeJob`] does the same away from the parts.
pub fn bake(parts: BakeParts<'_>, density: f32) -> Result<SpringNetwork, PrepareError> {
    let BakeParts {
        network,
        points,
        springs,
        masses,
        pressure,
        dense,
    } = parts;
    let job = BakeJob::new(
        Arc::new(network.clone()),
        points,
        springs,
        masses,
        pressure.as_deref(),
        dense,
        density,
    );
    let baked = job.run()?;
    // Everything is checked: nothing changes unless every part could be rebuilt.
    *points = baked.points;
    *springs = baked.springs;
    *masses = baked.masses;
    if let (Some(gas), Some(new)) = (pressure, baked.pressure) {
        *gas = new;
    }
    *dense = baked.dense;
    Ok(baked.network)
}

/// A [`bake`] taken from a running surface, to be done on another thread
/// ([`Self::run`]) while the surface runs on: copies of its simulation's parts (O(simulation
/// points)) and the dense surface's [`DenseJob`] (which shares, not copies, its transfer).
#[derive(Debug, Clone)]
pub struct BakeJob {
    network: Arc<SpringNetwork>,
    points: PointState,
    springs: Springs,
    masses: Masses,
    pressure: Option<Pressure>,
    dense: DenseJob,
    density: f32,
}

/// What a [`BakeJob`] made: the parts to put in place of the surface's.
#[derive(Debug)]
pub struct Baked {
    /// The network at rest in the baked shape.
    pub network: SpringNetwork,
    /// The simulation points in the baked shape, still.
    pub points: PointState,
    /// Springs at rest in the baked shape.
    pub springs: Springs,
    /// Masses measured anew (pins kept).
    pub masses: Masses,
    /// A gas at rest at its baked volume.
    pub pressure: Option<Pressure>,
    /// The dense surface at rest in its baked shape.
    pub dense: DenseCloud,
}

impl BakeJob {
    /// The bake of a surface's current shape (the parts as in [`BakeParts`]).
    pub fn new(
        network: Arc<SpringNetwork>,
        points: &PointState,
        springs: &Springs,
        masses: &Masses,
        pressure: Option<&Pressure>,
        dense: &DenseCloud,
        density: f32,
    ) -> Self {
        Self {
            network,
            points: points.clone(),
            springs: springs.clone(),
            masses: masses.clone(),
            pressure: pressure.cloned(),
            dense: dense.job(points),
            density,
        }
    }

    /// Measures the baked rest shape and builds every part anew.
    pub fn run(self) -> Result<Baked, PrepareError> {
        let Self {
            network,
            mut points,
            mut springs,
            masses,
            pressure,
            dense,
            density,
        } = self;
        let network = network.reshaped(&points.positions(), density)?;
        springs.set_rest_lengths(|i| network.rest_length(i))?;
        // Rest angles and rest curvatures (and their fits' residual heights) measured anew.
        if !springs.hinges().is_empty() || springs.curvature_count() > 0 {
            springs.set_rest_angles(&points)?;
        }
        let mut new_masses = Masses::new(&network.masses)?;
        for i in (0..masses.len()).filter(|&i| masses.is_pinned(i)) {
            new_masses.set_pinned(i, true)?;
        }
        let pressure = match pressure {
            Some(gas) => Some(Pressure::new(
                network.triangles.clone(),
                &points,
                gas.stiffness,
            )?),
            None => None,
        };
        let dense = dense.rebased()?;
        points.stop();
        Ok(Baked {
            network,
            points,
            springs,
            masses: new_masses,
            pressure,
            dense,
        })
    }
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
