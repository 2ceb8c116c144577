//! Modelling requests (issue 17): bake a surface's current shape into its rest shape,
//! export its deformed dense surface to a PLY file, or reset it to its rest shape. Send a [`ModelMessage`]; the request is
//! carried out at the start of the next tick's [`Forces`](super::PointSpringsSystems::Forces)
//! set, and a [`ModelOutcome`] says how it went (a failure is also logged; the surface runs
//! on unchanged).
//!
//! ```no_run
//! use bevy::prelude::*;
//! use bevy_point_springs::prelude::*;
//!
//! fn keep_the_shape(mut requests: MessageWriter<ModelMessage>, surface: Single<Entity, With<DeformableSurface>>) {
//!     requests.write(ModelMessage::Bake { surface: *surface });
//!     requests.write(ModelMessage::Export { surface: *surface, path: "sculpted.ply".into() });
//! }
//! ```

use std::path::PathBuf;

use bevy::prelude::*;

use super::components::{
    DenseSurface, SceneTimeline, SimulationPoints, SurfaceAnchors, SurfaceMasses, SurfaceMaterial,
    SurfaceNetwork, SurfacePressure, SurfaceSleep, SurfaceSprings, SurfaceStatus,
};
use super::save::SurfaceBaked;
use super::simulate::follow;
use crate::core::cloud::io::PlyEncoding;
use crate::core::pipeline::{BakeParts, bake};

/// A modelling request for one surface.
#[derive(Message, Debug, Clone, PartialEq)]
pub enum ModelMessage {
    /// Makes the surface's current shape its rest shape: rest lengths, masses and normals
    /// measured anew, velocities zero, the dense surface's rest shape its deformed one (see
    /// [`bake`]). Stiffness, plasticity, pins and grabs are kept.
    Bake {
        /// The surface.
        surface: Entity,
    },
    /// Writes the surface's deformed dense surface (positions and normals, in the surface's
    /// own coordinates) to `path` as binary PLY, beside it first and then renamed into
    /// place, so a failure never leaves a truncated file.
    Export {
        /// The surface.
        surface: Entity,
        /// The PLY file to write.
        path: PathBuf,
    },
    /// Puts the surface back in its rest shape (as prepared, or as last baked): points at
    /// their rest positions and still, springs at their rest lengths (plastic flow since
    /// then undone), a scene's timeline started again. Pins, masses and the game's anchors
    /// (grabs) are kept.
    Reset {
        /// The surface.
        surface: Entity,
    },
}

impl ModelMessage {
    /// The surface the request is for.
    pub fn surface(&self) -> Entity {
        match self {
            Self::Bake { surface } | Self::Export { surface, .. } | Self::Reset { surface } => {
                *surface
            }
        }
    }
}

/// How a [`ModelMessage`] went.
#[derive(Message, Debug, Clone, PartialEq)]
pub struct ModelOutcome {
    /// The request.
    pub request: ModelMessage,
    /// `Err` with the reason when it was refused or failed (nothing changed then).
    pub result: Result<(), String>,
}

/// The parts of a surface a request reads or changes.
type ModelParts = (
    &'static mut SurfaceNetwork,
    &'static mut SimulationPoints,
    &'static mut SurfaceSprings,
    &'static mut SurfaceMasses,
    Option<&'static mut SurfacePressure>,
    &'static mut DenseSurface,
    &'static SurfaceMaterial,
    &'static SurfaceStatus,
    &'static mut SurfaceAnchors,
    Option<&'static mut SceneTimeline>,
    &'static mut SurfaceSleep,
);

/// Carries out the tick's modelling requests, in the order they were sent.
pub(crate) fn apply_model_requests(
    mut requests: MessageReader<ModelMessage>,
    mut outcomes: MessageWriter<ModelOutcome>,
    mut surfaces: Query<ModelParts>,
    mut commands: Commands,
) {
    for request in requests.read() {
        let result = carry_out(request, &mut surfaces);
        if let Err(e) = &result {
            error!("point-springs: {request:?} failed: {e}");
        }
        // A saved game carries a baked surface's rest shape.
        if result.is_ok()
            && let ModelMessage::Bake { surface } = request
            && let Ok(parts) = surfaces.get(*surface)
        {
            let density = parts.6.0.density;
            commands.entity(*surface).insert(SurfaceBaked { density });
        }
        outcomes.write(ModelOutcome {
            request: request.clone(),
            result,
        });
    }
}

/// One request on its surface.
fn carry_out(request: &ModelMessage, surfaces: &mut Query<ModelParts>) -> Result<(), String> {
    let surface = &request.surface();
    let Ok((
        mut network,
        mut points,
        mut springs,
        mut masses,
        pressure,
        mut dense,
        material,
        status,
        mut anchors,
        timeline,
        mut sleep,
    )) = surfaces.get_mut(*surface)
    else {
        return Err(format!("{surface} is not a prepared surface"));
    };
    if !status.is_ready() {
        return Err(format!("{surface} is not ready ({status:?})"));
    }
    match request {
        ModelMessage::Bake { .. } => {
            let parts = BakeParts {
                network: &network.0,
                points: &mut points.0,
                springs: &mut springs.0,
                masses: &mut masses.0,
                pressure: pressure.map(|p| &mut p.into_inner().0),
                dense: &mut dense.0,
            };
            let baked = bake(parts, material.density).map_err(|e| e.to_string())?;
            network.0 = baked.into();
            Ok(())
        }
        ModelMessage::Export { path, .. } => {
            // The current shape, even where the transfer waited (out of view, per frame).
            follow(&mut dense, &points).map_err(|e| e.to_string())?;
            dense
                .export(path, PlyEncoding::BinaryLittleEndian)
                .map_err(|e| e.to_string())
        }
        ModelMessage::Reset { .. } => {
            springs
                .set_rest_lengths(|i| network.rest_length(i))
                .map_err(|e| e.to_string())?;
            for (i, &p) in network.positions.iter().enumerate() {
                points.set_position(i, p).map_err(|e| e.to_string())?;
            }
            points.stop();
            if !springs.hinges().is_empty() {
                // Plastic flow moved the rest angles too: measured again on the rest shape.
                springs
                    .set_rest_angles(&points)
                    .map_err(|e| e.to_string())?;
            }
            if let Some(mut timeline) = timeline {
                timeline.restart(&mut anchors);
            }
            // The rest shape need not be at rest under gravity or pins: awake, it settles.
            *sleep = SurfaceSleep {
                acted: true,
                ..SurfaceSleep::default()
            };
            Ok(())
        }
    }
}
