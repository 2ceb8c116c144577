//! Snapshots of a running scene: everything the run has changed since its preparation,
//! saved to a file and restored onto the same scene prepared again, so that the run goes on
//! bit for bit as if it had never stopped.
//!
//! A snapshot holds the scene itself, the solver's [`SolverState`], the timeline's
//! [`TimelineState`], the dense surface's [`DenseState`] and what resampling did. It does
//! not hold what preparation gives (the network, the springs' ends, the transfer's
//! coefficients for the original dense points): preparation is deterministic, so preparing
//! the scene again gives them to the bit (`tests/determinism.rs`). A surface baked since
//! its preparation has a new rest state, which a snapshot does not hold.
//!
//! The file: the 8 bytes [`SNAPSHOT_MAGIC`] (whose last byte is the format's version), then
//! the snapshot in postcard's binary serde encoding, floats as their exact bits.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::timeline::TimelineState;
use super::{Scene, SceneError, SceneRun};
use crate::core::PointCloud;
use crate::core::cloud::io::{TaggedError, decode_tagged, encode_tagged, write_atomically};
use crate::core::pipeline::DenseState;
use crate::core::solver::{SolverError, SolverState};
use crate::core::transfer::TransferError;
use crate::core::transfer::resample::ResampleReport;

/// The first bytes of a snapshot file: a name and the format's version (2: the solver's
/// settings gained `implicit_solver`; version 1 files are refused as foreign).
pub const SNAPSHOT_MAGIC: &[u8; 8] = b"PSSNAP\x00\x02";

/// A running scene's state (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Snapshot {
    /// The scene as it runs (with its level chosen, when it asked by an error budget).
    pub scene: Scene,
    /// The scene file it was loaded from, when there was one (absolute): `run --resume`
    /// finds the scene's cloud through it.
    pub scene_file: Option<PathBuf>,
    /// The solver's state.
    pub solver: SolverState,
    /// The timeline's state.
    pub timeline: TimelineState,
    /// The dense surface's state.
    pub dense: DenseState,
    /// What resampling did so far.
    pub resampled: ResampleReport,
}

/// Why a snapshot could not be written, read or restored.
#[derive(Debug, thiserror::Error)]
pub enum SnapshotError {
    /// The file could not be written or read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
    /// The file does not start with [`SNAPSHOT_MAGIC`].
    #[error("not a snapshot of this version (it does not start with {SNAPSHOT_MAGIC:?})")]
    NotASnapshot,
    /// The bytes after the magic do not decode.
    #[error("the snapshot is damaged: {0}")]
    Damaged(String),
    /// A file that is not a snapshot, or a damaged one.
    #[error("{path}: {source}")]
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong with it ([`Self::NotASnapshot`] or [`Self::Damaged`]).
        source: Box<SnapshotError>,
    },
    /// The snapshot was taken of another scene than the one it is restored onto.
    #[error("the snapshot was taken of another scene (its settings differ)")]
    OtherScene,
    /// The solver refused the state.
    #[error("the snapshot's solver state does not fit: {0}")]
    Solver(#[from] SolverError),
    /// The dense surface refused the state.
    #[error(transparent)]
    Transfer(#[from] TransferError),
    /// The timeline refused the state, or the scene could not be prepared again.
    #[error(transparent)]
    Scene(#[from] SceneError),
}

impl Snapshot {
    /// The file's bytes: [`SNAPSHOT_MAGIC`], then the snapshot.
    pub fn to_bytes(&self) -> Vec<u8> {
        encode_tagged(self, SNAPSHOT_MAGIC)
    }

    /// Decodes a snapshot file's bytes. Anything but a whole snapshot of this version is an
    /// error; the decoder allocates no more than the bytes can fill.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, SnapshotError> {
        decode_tagged(bytes, SNAPSHOT_MAGIC).map_err(|e| match e {
            TaggedError::Foreign => SnapshotError::NotASnapshot,
            TaggedError::Damaged(why) => SnapshotError::Damaged(why),
        })
    }

    /// Writes the snapshot to `path` through a temporary file renamed into place: a failed
    /// write never leaves a truncated snapshot, and the previous one stays until then.
    pub fn write(&self, path: &Path) -> Result<(), SnapshotError> {
        let bytes = self.to_bytes();
        write_atomically(path, |out| out.write_all(&bytes)).map_err(|e| SnapshotError::Io {
            path: path.to_owned(),
            source: e.source,
        })
    }

    /// Reads a snapshot file.
    pub fn read(path: &Path) -> Result<Self, SnapshotError> {
        let bytes = std::fs::read(path).map_err(|source| SnapshotError::Io {
            path: path.to_owned(),
            source,
        })?;
        Self::from_bytes(&bytes).map_err(|e| SnapshotError::File {
            path: path.to_owned(),
            source: Box::new(e),
        })
    }

    /// Prepares the snapshot's scene on `cloud` (its dense cloud, loaded) and restores the
    /// snapshot onto it: the run goes on from the step the snapshot was taken at.
    pub fn resume(&self, cloud: PointCloud) -> Result<SceneRun, SnapshotError> {
        let mut run = self.scene.prepare_run(cloud)?;
        run.restore(self)?;
        Ok(run)
    }

    /// [`Self::resume`] with the cloud loaded from the scene file's folder.
    pub fn resume_from_file(&self) -> Result<SceneRun, SnapshotError> {
        let file = self.scene_file.as_ref().ok_or_else(|| {
            SnapshotError::Scene(SceneError::Invalid(
                "the snapshot does not name its scene file".to_owned(),
            ))
        })?;
        let base = file.parent().unwrap_or(Path::new("."));
        let cloud = crate::core::cloud::io::read_cloud(&base.join(&self.scene.cloud), None)
            .map_err(SceneError::from)?;
        self.resume(cloud)
    }
}

impl SceneRun {
    /// The run's state now (see [`Snapshot`]); `scene_file` is left empty.
    pub fn snapshot(&self) -> Snapshot {
        Snapshot {
            scene: self.scene.clone(),
            scene_file: None,
            solver: self.surface.solver.state(),
            timeline: self.timeline.state(),
            dense: self.surface.dense.state(),
            resampled: self.resampled,
        }
    }

    /// Restores `snapshot` onto this run, which must be its scene freshly prepared (no step
    /// taken, no point inserted). Refused, with nothing changed, when the snapshot is of
    /// another scene or does not fit the surface.
    pub fn restore(&mut self, snapshot: &Snapshot) -> Result<(), SnapshotError> {
        if snapshot.scene != self.scene {
            return Err(SnapshotError::OtherScene);
        }
        // Each part checks its piece before changing anything; trial copies of the small
        // parts, and the dense surface last (it checks everything before it changes), keep
        // the whole restore all or nothing.
        let mut solver = self.surface.solver.clone();
        solver.restore(&snapshot.solver)?;
        let mut timeline = self.timeline.clone();
        timeline.restore(&snapshot.timeline)?;
        for (pull, held) in snapshot.timeline.anchors.iter().enumerate() {
            if held.iter().any(|id| solver.anchors.get(*id).is_none()) {
                return Err(SnapshotError::Scene(SceneError::Invalid(format!(
                    "pull {pull} holds an anchor the snapshot's solver does not have"
                ))));
            }
        }
        self.surface.dense.restore(&snapshot.dense)?;
        self.surface.dense.hold(&solver.masses)?;
        self.surface.solver = solver;
        self.timeline = timeline;
        self.resampled = snapshot.resampled;
        Ok(())
    }
}
