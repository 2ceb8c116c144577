//! Saved games: every named surface of a running app to a file, and back into an app that
//! prepared the same surfaces (issue 32).
//!
//! A game names the surfaces it saves with [`SaveName`] and sends
//! [`SaveGameMessage::Save`]; to load, it spawns the same surfaces with the same names
//! (the same sources and settings), waits until they are [`SurfaceStatus::Ready`], and sends
//! [`SaveGameMessage::Load`]. Each surface then goes on exactly as the saved one would have,
//! bit for bit: its positions and velocities, masses and pins, springs with their plastic
//! rest lengths and edited stiffness, anchors and grabs, external forces, gas, the stepper's
//! settings, running totals and warm start, sleep, a scene's timeline, the dense surface
//! (deformed points, resampled points, the resampler's spacings) and a baked rest shape.
//! [`SaveGameOutcome`] reports how it went. A file that is not a saved game, is cut short
//! or damaged, or does not fit the app's surfaces is refused with a [`SaveGameError`], and
//! nothing in the app changes.
//!
//! Load a surface at least one tick after it became ready (a load in the frame it became
//! ready is refused as [`SaveGameError::NotReady`]). A save of a surface never baked is
//! refused onto one baked since it was prepared.
//!
//! Not saved: the surface's `Transform`, the game's own settings of a surface
//! ([`SurfaceRunSettings`](super::SurfaceRunSettings), whether it is in view), its
//! [`SurfaceHealth`](super::SurfaceHealth), work counters and timings, dense points a game
//! named held itself ([`DenseCloud::hold_where`](crate::core::pipeline::DenseCloud::hold_where))
//! on a surface never baked, and anything outside the surfaces (rapier bodies, the clock).

use std::collections::HashMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use bevy::prelude::*;
use serde::{Deserialize, Serialize};

use super::components::{
    DenseSurface, GpuTransferInput, SceneTimeline, SimulationPoints, SurfaceAnchors, SurfaceForces,
    SurfaceMasses, SurfaceMaterial, SurfaceNetwork, SurfacePressure, SurfaceSleep, SurfaceSprings,
    SurfaceStatus, SurfaceStepper,
};
use super::grab::{Grabs, HeldGrab};
use crate::core::cloud::io::{TaggedError, decode_tagged, encode_tagged, write_atomically};
use crate::core::network::{RestShape, SpringNetwork};
use crate::core::pipeline::{DenseCloud, DenseRest, DenseState};
use crate::core::scene::{Timeline, TimelineState};
use crate::core::solver::{
    Anchors, ExternalForces, Masses, PointState, Pressure, SolverConfig, SolverState,
    SpringMaterial, Springs, StateParts, StatePartsMut, Stepper,
};

/// The first bytes of a saved game (the format's name and version: 2 since the solver's
/// settings gained `implicit_solver`; version 1 files are refused as foreign).
pub const SAVED_GAME_MAGIC: &[u8; 8] = b"PSGAME2\n";

/// The name a surface is saved and loaded under. Surfaces without one are not saved; a
/// name must be unique among the surfaces saved.
#[derive(Component, Reflect, Debug, Clone, PartialEq, Eq, Hash)]
#[reflect(Component, Debug)]
pub struct SaveName(pub String);

/// Marks a surface baked since it was prepared, with the density it was baked with (a saved
/// game carries its rest shape). Set by [`ModelMessage::Bake`](super::ModelMessage::Bake),
/// removed when the surface is prepared again.
#[derive(Component, Debug, Clone, Copy, PartialEq)]
pub struct SurfaceBaked {
    /// The density the bake measured masses with.
    pub density: f32,
}

/// A request to save or load.
#[derive(Message, Debug, Clone, PartialEq, Eq)]
pub enum SaveGameMessage {
    /// Writes every surface with a [`SaveName`] (and ready) to `path`, through a temporary
    /// file renamed into place.
    Save {
        /// The file.
        path: PathBuf,
    },
    /// Reads `path` and puts each saved surface back onto the ready surface of its name.
    Load {
        /// The file.
        path: PathBuf,
    },
}

/// How a [`SaveGameMessage`] went.
#[derive(Message, Debug, Clone, PartialEq)]
pub struct SaveGameOutcome {
    /// The request.
    pub request: SaveGameMessage,
    /// The names of the surfaces saved or loaded, or why nothing was.
    pub result: Result<Vec<String>, SaveGameError>,
}

/// Why a game could not be saved or loaded (nothing changed).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SaveGameError {
    /// The file could not be read or written.
    #[error("{}: {message}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the system said.
        message: String,
    },
    /// The file does not start as a saved game of this version does.
    #[error("not a saved game of this version")]
    NotASavedGame,
    /// The file is cut short or damaged.
    #[error("the saved game is damaged: {0}")]
    Damaged(String),
    /// Two surfaces to save have the same name.
    #[error("two surfaces are named {0:?}")]
    DuplicateName(String),
    /// A saved surface has no surface of its name in the app.
    #[error("no surface is named {0:?}")]
    NoSurface(String),
    /// The surface of that name is not ready (still preparing, or failed).
    #[error("the surface {0:?} is not ready")]
    NotReady(String),
    /// The saved surface does not fit the surface of its name (other points, springs, gas,
    /// settings), or holds bad values.
    #[error("the saved surface {name:?} does not fit: {reason}")]
    DoesNotFit {
        /// The surface.
        name: String,
        /// Why.
        reason: String,
    },
}

/// One saved surface.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct SavedSurface {
    name: String,
    config: SolverConfig,
    material: SpringMaterial,
    solver: SolverState,
    timeline: Option<TimelineState>,
    dense: DenseState,
    /// The rest shape of the last bake, if any.
    baked: Option<Baked>,
    asleep: bool,
    still_for: f32,
    grabs: Vec<(u64, HeldGrab)>,
}

/// What a bake made of a surface's rest: the network's and the dense surface's, and the
/// density it measured with.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Baked {
    network: RestShape,
    dense: DenseRest,
    density: f32,
}

/// A saved game: its surfaces.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct SavedGame {
    surfaces: Vec<SavedSurface>,
}

impl SavedGame {
    fn to_bytes(&self) -> Vec<u8> {
        encode_tagged(self, SAVED_GAME_MAGIC)
    }

    fn from_bytes(bytes: &[u8]) -> Result<Self, SaveGameError> {
        decode_tagged(bytes, SAVED_GAME_MAGIC).map_err(|e| match e {
            TaggedError::Foreign => SaveGameError::NotASavedGame,
            TaggedError::Damaged(why) => SaveGameError::Damaged(why),
        })
    }
}

/// What a saved game reads of a surface.
type SaveParts = (
    Entity,
    &'static SaveName,
    &'static SurfaceStatus,
    (
        &'static mut SimulationPoints,
        &'static mut SurfaceMasses,
        &'static mut SurfaceSprings,
        &'static mut SurfaceAnchors,
        &'static mut SurfaceForces,
        Option<&'static mut SurfacePressure>,
        &'static mut SurfaceStepper,
    ),
    (
        &'static mut SurfaceNetwork,
        &'static mut DenseSurface,
        Option<&'static mut SceneTimeline>,
        &'static mut SurfaceSleep,
        &'static mut SurfaceMaterial,
        Option<&'static SurfaceBaked>,
    ),
);

/// Surfaces whose transfer runs on the GPU keep no current dense surface on the CPU
/// ([`GpuTransferInput`]): before a save reads it, it is brought up to date (the CPU
/// transfer of the simulation points as they are).
pub(crate) fn catch_up_before_save(
    mut requests: MessageReader<SaveGameMessage>,
    mut surfaces: Query<(Entity, &SimulationPoints, &mut DenseSurface), With<GpuTransferInput>>,
) {
    let saving = requests
        .read()
        .any(|r| matches!(r, SaveGameMessage::Save { .. }));
    if !saving {
        return;
    }
    for (entity, points, mut dense) in &mut surfaces {
        if let Err(e) = super::simulate::follow(&mut dense.0, points) {
            warn!(
                "point-springs: surface {entity}: its dense surface could not be brought up to date for the save: {e}"
            );
        }
    }
}

/// Carries out the frame's save and load requests, in order.
pub(crate) fn apply_saved_games(
    mut requests: MessageReader<SaveGameMessage>,
    mut outcomes: MessageWriter<SaveGameOutcome>,
    mut surfaces: Query<SaveParts>,
    mut grabs: ResMut<Grabs>,
    mut commands: Commands,
) {
    // What loads of this frame made of surfaces' bake marks (the commands that set them
    // apply after this system), for a save after them.
    let mut baked = HashMap::new();
    for request in requests.read() {
        let result = match request {
            SaveGameMessage::Save { path } => save(path, &mut surfaces, &grabs, &baked),
            SaveGameMessage::Load { path } => {
                load(path, &mut surfaces, &mut grabs, &mut commands, &mut baked)
            }
        };
        match &result {
            Ok(names) => info!("point-springs: {request:?}: {} surfaces", names.len()),
            Err(e) => error!("point-springs: {request:?} failed: {e}"),
        }
        outcomes.write(SaveGameOutcome {
            request: request.clone(),
            result,
        });
    }
}

/// Saves the named, ready surfaces to `path`.
fn save(
    path: &Path,
    surfaces: &mut Query<SaveParts>,
    grabs: &Grabs,
    loaded: &HashMap<Entity, Option<f32>>,
) -> Result<Vec<String>, SaveGameError> {
    let mut saved = Vec::new();
    for (entity, name, status, solver, rest) in surfaces.iter() {
        if !status.is_ready() {
            continue;
        }
        let (points, masses, springs, anchors, forces, pressure, stepper) = solver;
        let (network, dense, timeline, sleep, material, baked) = rest;
        let baked = match loaded.get(&entity) {
            Some(density) => *density,
            None => baked.map(|b| b.density),
        };
        if saved.iter().any(|s: &SavedSurface| s.name == name.0) {
            return Err(SaveGameError::DuplicateName(name.0.clone()));
        }
        let state = SolverState::capture(StateParts {
            points,
            masses,
            springs,
            anchors,
            external: forces,
            pressure: pressure.map(|p| &p.0),
            stepper,
        });
        saved.push(SavedSurface {
            name: name.0.clone(),
            config: *stepper.config(),
            material: material.0,
            solver: state,
            timeline: timeline.map(|t| t.state()),
            dense: dense.state(),
            baked: baked.map(|density| Baked {
                network: network.rest_shape(),
                dense: dense.rest(),
                density,
            }),
            asleep: sleep.asleep,
            still_for: sleep.still_for,
            // (An anchor a game removed from a grab is left out.)
            grabs: grabs
                .of_surface(entity)
                .into_iter()
                .map(|(key, held)| (key, held.alive(&anchors.0)))
                .collect(),
        });
    }
    let names = saved.iter().map(|s| s.name.clone()).collect();
    let bytes = SavedGame { surfaces: saved }.to_bytes();
    write_atomically(path, |out| out.write_all(&bytes)).map_err(|e| SaveGameError::Io {
        path: path.to_owned(),
        message: e.source.to_string(),
    })?;
    Ok(names)
}

/// The bytes of the file at `path`, once its first bytes say it is a saved game (a foreign
/// file is not read whole).
fn read_saved_game(path: &Path) -> Result<Vec<u8>, SaveGameError> {
    let io = |e: std::io::Error| SaveGameError::Io {
        path: path.to_owned(),
        message: e.to_string(),
    };
    let mut file = std::fs::File::open(path).map_err(io)?;
    let mut bytes = vec![0; SAVED_GAME_MAGIC.len()];
    match file.read_exact(&mut bytes) {
        Ok(()) if bytes == SAVED_GAME_MAGIC => {}
        Ok(()) => return Err(SaveGameError::NotASavedGame),
        Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => {
            return Err(SaveGameError::NotASavedGame);
        }
        Err(e) => return Err(io(e)),
    }
    file.read_to_end(&mut bytes).map_err(io)?;
    Ok(bytes)
}

/// The parts of one surface a load puts back, built before anything changes.
struct Restored {
    entity: Entity,
    points: PointState,
    masses: Masses,
    springs: Springs,
    anchors: Anchors,
    forces: ExternalForces,
    pressure: Option<Pressure>,
    stepper: Stepper,
    network: Option<Arc<SpringNetwork>>,
    dense: DenseCloud,
    timeline: Option<Timeline>,
    material: SpringMaterial,
    baked: Option<f32>,
    sleep: (bool, f32),
    grabs: Vec<(u64, HeldGrab)>,
}

/// Reads `path` and puts every saved surface back onto the surface of its name: all of them
/// or, on any error, none.
fn load(
    path: &Path,
    surfaces: &mut Query<SaveParts>,
    grabs: &mut Grabs,
    commands: &mut Commands,
    baked_marks: &mut HashMap<Entity, Option<f32>>,
) -> Result<Vec<String>, SaveGameError> {
    let game = SavedGame::from_bytes(&read_saved_game(path)?)?;
    let mut restored = Vec::with_capacity(game.surfaces.len());
    for saved in &game.surfaces {
        if restored
            .iter()
            .any(|r: &(String, Restored)| r.0 == saved.name)
        {
            return Err(SaveGameError::DuplicateName(saved.name.clone()));
        }
        // (entity, ready, prepared this frame, baked with) of the surfaces of its name.
        let named: Vec<(Entity, bool, bool, Option<f32>)> = surfaces
            .iter_mut()
            .filter(|(_, name, ..)| name.0 == saved.name)
            .map(|(e, _, status, _, rest)| {
                (
                    e,
                    status.is_ready(),
                    rest.4.is_added(),
                    rest.5.map(|b| b.density),
                )
            })
            .collect();
        let target = match named.as_slice() {
            [] => return Err(SaveGameError::NoSurface(saved.name.clone())),
            [one] => *one,
            _ => return Err(SaveGameError::DuplicateName(saved.name.clone())),
        };
        // Ready, and ticked since: a surface prepared this frame still has its material's
        // change to apply, which would overwrite the saved springs.
        if !target.1 || target.2 {
            return Err(SaveGameError::NotReady(saved.name.clone()));
        }
        let does_not_fit = |reason: String| SaveGameError::DoesNotFit {
            name: saved.name.clone(),
            reason,
        };
        let was_baked = baked_marks
            .get(&target.0)
            .copied()
            .unwrap_or(target.3)
            .is_some();
        if was_baked && saved.baked.is_none() {
            return Err(does_not_fit(
                "the surface was baked since it was prepared, the saved one was not \
                 (prepare it again first)"
                    .to_owned(),
            ));
        }
        let parts = rebuild(saved, target.0, surfaces).map_err(does_not_fit)?;
        restored.push((saved.name.clone(), parts));
    }
    // A saved grab's key must not be held on a surface this load leaves alone.
    let loaded: Vec<Entity> = restored.iter().map(|(_, r)| r.entity).collect();
    for (name, r) in &restored {
        for (key, _) in &r.grabs {
            if let Some((other, _)) = grabs.get(*key)
                && !loaded.contains(&other)
            {
                return Err(SaveGameError::DoesNotFit {
                    name: name.clone(),
                    reason: format!("grab {key} is held on another surface ({other})"),
                });
            }
        }
    }
    // Everything fits: put it in. Written past change detection (a restored surface must
    // not look acted on: that would wake it), but for the dense surface (to be drawn anew).
    for (_, r) in &mut restored {
        let (_, _, _, solver, rest) = surfaces.get_mut(r.entity).expect("checked above");
        let (mut points, mut masses, mut springs, mut anchors, mut forces, pressure, mut stepper) =
            solver;
        let (mut network, mut dense, timeline, mut sleep, mut material, _) = rest;
        points.bypass_change_detection().0 = std::mem::take(&mut r.points);
        masses.bypass_change_detection().0 = r.masses.clone();
        springs.bypass_change_detection().0 = r.springs.clone();
        anchors.bypass_change_detection().0 = r.anchors.clone();
        forces.bypass_change_detection().0 = r.forces.clone();
        if let (Some(mut p), Some(new)) = (pressure, r.pressure.take()) {
            p.bypass_change_detection().0 = new;
        }
        stepper.bypass_change_detection().0 = r.stepper.clone();
        if let Some(new) = r.network.take() {
            network.bypass_change_detection().0 = new;
        }
        let old = dense.revision();
        dense.0 = r.dense.clone();
        // Uploads and caches that saw the old cloud must see a change.
        dense.0.advance_revision_past(old);
        if let (Some(mut t), Some(new)) = (timeline, r.timeline.take()) {
            t.bypass_change_detection().0 = new;
        }
        let sleep = sleep.bypass_change_detection();
        (sleep.asleep, sleep.still_for) = r.sleep;
        material.bypass_change_detection().0 = r.material;
        match r.baked {
            Some(density) => commands.entity(r.entity).insert(SurfaceBaked { density }),
            None => commands.entity(r.entity).remove::<SurfaceBaked>(),
        };
        baked_marks.insert(r.entity, r.baked);
        super::model::supersede_bakes(commands, r.entity);
        grabs.forget_surface(r.entity);
        for (key, held) in r.grabs.drain(..) {
            grabs.hold(key, r.entity, held);
        }
    }
    Ok(restored.into_iter().map(|(name, _)| name).collect())
}

/// The parts of surface `entity` with `saved` put back (on copies).
fn rebuild(
    saved: &SavedSurface,
    entity: Entity,
    surfaces: &Query<SaveParts>,
) -> Result<Restored, String> {
    let (_, _, _, solver, rest) = surfaces.get(entity).map_err(|e| e.to_string())?;
    let (points, masses, springs, anchors, forces, pressure, stepper) = solver;
    let (network, dense, timeline, _, _, _) = rest;
    let mut r = Restored {
        entity,
        points: points.0.clone(),
        masses: masses.0.clone(),
        springs: springs.0.clone(),
        anchors: anchors.0.clone(),
        forces: forces.0.clone(),
        pressure: pressure.map(|p| p.0.clone()),
        stepper: stepper.0.clone(),
        network: None,
        dense: dense.0.clone(),
        timeline: timeline.map(|t| t.0.clone()),
        material: saved.material,
        baked: saved.baked.as_ref().map(|b| b.density),
        sleep: (saved.asleep, saved.still_for),
        grabs: saved.grabs.clone(),
    };
    // A baked surface: its rest shape first, as the bake made it.
    if let Some(b) = &saved.baked {
        if b.dense.simulation != b.network.positions {
            return Err("its baked rest shapes disagree".to_owned());
        }
        let baked = network
            .with_rest_shape(b.network.clone())
            .map_err(|e| format!("its baked rest shape: {e}"))?;
        if let Some(gas) = &mut r.pressure {
            let at_rest = PointState::new(&baked.positions).map_err(|e| e.to_string())?;
            *gas = Pressure::new(baked.triangles.clone(), &at_rest, gas.stiffness)
                .map_err(|e| e.to_string())?;
        }
        r.dense = dense.with_rest(&b.dense).map_err(|e| e.to_string())?;
        r.network = Some(Arc::new(baked));
    }
    r.stepper
        .set_config(saved.config)
        .map_err(|e| e.to_string())?;
    saved
        .solver
        .apply(StatePartsMut {
            points: &mut r.points,
            masses: &mut r.masses,
            springs: &mut r.springs,
            anchors: &mut r.anchors,
            external: &mut r.forces,
            pressure: r.pressure.as_mut(),
            stepper: &mut r.stepper,
        })
        .map_err(|e| e.to_string())?;
    r.material.check()?;
    // Plastic flow follows the material (a game may have changed it since preparing).
    r.springs
        .set_plasticity(r.material.plasticity())
        .map_err(|e| format!("its material: {e}"))?;
    match (&mut r.timeline, &saved.timeline) {
        (Some(t), Some(state)) => t.restore(state).map_err(|e| e.to_string())?,
        (None, None) => {}
        _ => return Err("a scene's timeline on one side only".to_owned()),
    }
    r.dense.restore(&saved.dense).map_err(|e| e.to_string())?;
    match &saved.baked {
        Some(b) => r.dense.hold_rest(&r.masses, &b.dense),
        None => r.dense.hold(&r.masses).map(|_| ()),
    }
    .map_err(|e| e.to_string())?;
    if !(saved.still_for.is_finite() && saved.still_for >= 0.0) {
        return Err("its time still is not a finite, non-negative number".to_owned());
    }
    for (key, held) in &saved.grabs {
        if held.anchors().any(|id| r.anchors.get(id).is_none()) {
            return Err(format!(
                "grab {key} holds an anchor the surface does not have"
            ));
        }
    }
    Ok(r)
}
