//! A surface's life as events: [`SurfaceReady`] when a preparation is in, [`SurfaceFailed`]
//! with the typed [`SurfaceError`] when loading, preparing or simulating fails. Observe
//! them on one surface (`commands.entity(e).observe(..)`) or on all
//! (`app.add_observer(..)`), instead of polling [`SurfaceStatus`], which says the same.
//!
//! ```
//! use bevy::prelude::*;
//! use bevy_point_springs::prelude::*;
//!
//! fn too_far(failed: On<SurfaceFailed>) {
//!     if let SurfaceError::Prepare(PrepareError::Precision { magnitude, .. }) = failed.error {
//!         warn!("{} lies {magnitude} m out: move it towards the origin", failed.entity);
//!     }
//! }
//!
//! App::new()
//!     .add_plugins((MinimalPlugins, PointSpringsPlugins::default()))
//!     .add_observer(too_far);
//! ```

use std::sync::Arc;

use bevy::asset::AssetLoadError;
use bevy::prelude::*;

use super::components::SurfaceStatus;
use crate::core::pipeline::PrepareError;
use crate::core::scene::SceneError;
use crate::core::solver::SolverError;
use crate::core::transfer::TransferError;
use crate::core::transfer::resample::ResampleError;

/// Why a surface failed (in [`SurfaceStatus::Failed`] and [`SurfaceFailed`]). Match the
/// variant, and inside it the core's own error ([`PrepareError::Precision`], say).
#[derive(Debug, Clone, thiserror::Error, Reflect)]
#[reflect(opaque, Debug, PartialEq, Clone)]
pub enum SurfaceError {
    /// Loading a file needs Bevy's `AssetPlugin`, and the app has none.
    #[error("loading a file needs Bevy's AssetPlugin")]
    NoAssetPlugin,
    /// The asset server could not load the cloud or scene file.
    #[error("loading: {0}")]
    Load(Arc<AssetLoadError>),
    /// No thread pool for the preparation could be built.
    #[error("no thread pool: {0}")]
    ThreadPool(Arc<rayon::ThreadPoolBuildError>),
    /// The core pipeline refused the cloud or the settings.
    #[error(transparent)]
    Prepare(PrepareError),
    /// A scene's preparation failed (its pins, say); a failure of the pipeline under it is a
    /// [`Self::Prepare`].
    #[error(transparent)]
    Scene(Arc<SceneError>),
    /// The solver failed in a tick (`during`: "forces", "step" or "scene timeline").
    #[error("{during}: {error}")]
    Solver {
        /// The work that failed.
        during: &'static str,
        /// The solver's error.
        error: SolverError,
    },
    /// The displacement transfer failed (`during`: "transfer" or "holding the pins").
    #[error("{during}: {error}")]
    Transfer {
        /// The work that failed.
        during: &'static str,
        /// The transfer's error.
        error: TransferError,
    },
    /// Resampling the dense surface failed.
    #[error("resampling: {0}")]
    Resample(ResampleError),
}

impl PartialEq for SurfaceError {
    /// The same variant with equal errors; errors held in an `Arc` (which cannot be compared)
    /// equal only themselves.
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (Self::NoAssetPlugin, Self::NoAssetPlugin) => true,
            (Self::Load(a), Self::Load(b)) => Arc::ptr_eq(a, b),
            (Self::ThreadPool(a), Self::ThreadPool(b)) => Arc::ptr_eq(a, b),
            (Self::Prepare(a), Self::Prepare(b)) => a == b,
            (Self::Scene(a), Self::Scene(b)) => Arc::ptr_eq(a, b),
            (
                Self::Solver {
                    during: a,
                    error: e,
                },
                Self::Solver {
                    during: b,
                    error: f,
                },
            ) => a == b && e == f,
            (
                Self::Transfer {
                    during: a,
                    error: e,
                },
                Self::Transfer {
                    during: b,
                    error: f,
                },
            ) => a == b && e == f,
            (Self::Resample(a), Self::Resample(b)) => a == b,
            _ => false,
        }
    }
}

impl From<PrepareError> for SurfaceError {
    fn from(error: PrepareError) -> Self {
        Self::Prepare(error)
    }
}

impl From<SceneError> for SurfaceError {
    /// A failure of the pipeline under the scene stays a [`Self::Prepare`].
    fn from(error: SceneError) -> Self {
        match error {
            SceneError::Prepare(e) => Self::Prepare(e),
            other => Self::Scene(Arc::new(other)),
        }
    }
}

/// A surface's preparation is in: its simulation components are there and it runs from
/// the next tick. Triggered for every preparation, a [`PrepareAgain`](super::PrepareAgain)'s
/// included.
#[derive(EntityEvent, Debug, Clone, PartialEq)]
pub struct SurfaceReady {
    /// The surface.
    pub entity: Entity,
    /// Whether it replaced a running simulation (a [`PrepareAgain`](super::PrepareAgain)).
    pub again: bool,
}

/// Loading, preparing or simulating a surface failed. Unless `still_running`, its status
/// is now [`SurfaceStatus::Failed`] with the same error and it is not simulated; other
/// surfaces are not affected.
#[derive(EntityEvent, Debug, Clone, PartialEq)]
pub struct SurfaceFailed {
    /// The surface.
    pub entity: Entity,
    /// Why.
    pub error: SurfaceError,
    /// True when a [`PrepareAgain`](super::PrepareAgain) failed: the old simulation runs on.
    pub still_running: bool,
}

/// Marks a surface whose present failure was announced.
#[derive(Component)]
pub(crate) struct FailureAnnounced;

/// Triggers [`SurfaceFailed`] once for each surface whose status became failed (in a tick
/// system, say, which cannot trigger from its parallel loop), and logs it.
pub(crate) fn announce_failures(
    mut commands: Commands,
    surfaces: Query<(Entity, &SurfaceStatus, Has<FailureAnnounced>), Changed<SurfaceStatus>>,
) {
    for (entity, status, announced) in &surfaces {
        match (status, announced) {
            (SurfaceStatus::Failed(error), false) => {
                error!("point-springs surface {entity}: {error}");
                commands.entity(entity).try_insert(FailureAnnounced);
                commands.trigger(SurfaceFailed {
                    entity,
                    error: error.clone(),
                    still_running: false,
                });
            }
            (SurfaceStatus::Failed(_), true) | (_, false) => {}
            (_, true) => {
                commands.entity(entity).try_remove::<FailureAnnounced>();
            }
        }
    }
}
