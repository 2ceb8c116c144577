//! The Bevy layer: gathers ECS data, calls [`crate::core`], schedules.
//!
//! One entity per deformable surface; components hold whole arrays, not one entity per point.
//! The simulation runs on Bevy's fixed tick in the chained sets of [`PointSpringsSystems`]:
//! `Prepare → Forces → Integrate → Writeback`. Today `Prepare` gives new surfaces oriented
//! normals — estimated on Bevy's async compute pool, so a large cloud never stalls a frame —
//! and the later sets are configured (so user systems can be ordered against them) and will be
//! filled by the spring network and the solver.

#[cfg(feature = "render")]
pub mod render;

use bevy::prelude::*;
use bevy::tasks::{AsyncComputeTaskPool, Task, block_on, poll_once};

use crate::core::PointCloud;
use crate::core::normals::{
    DEFAULT_NORMAL_K, NormalSource, NormalsError, OrientationReport, ensure_normals,
    estimate_normals,
};

/// The plugin. Add it to an [`App`] next to `DefaultPlugins` or `MinimalPlugins`.
#[derive(Debug, Clone, Copy)]
pub struct PointSpringsPlugin {
    /// Neighbours used to estimate normals for surfaces whose cloud has none.
    pub normal_k: usize,
}

impl Default for PointSpringsPlugin {
    fn default() -> Self {
        Self {
            normal_k: DEFAULT_NORMAL_K,
        }
    }
}

/// The plugin's settings, as a resource.
#[derive(Resource, Debug, Clone, Copy, Reflect)]
#[reflect(Resource, Debug)]
pub struct PointSpringsConfig {
    /// Neighbours used to estimate normals for surfaces whose cloud has none.
    pub normal_k: usize,
}

/// The chained system sets of one simulation tick, run in [`FixedUpdate`].
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PointSpringsSystems {
    /// New or changed surfaces are made ready (normals now; simplification and springs later).
    Prepare,
    /// Spring, damping, gravity, anchor, drag and contact forces.
    Forces,
    /// Time integration.
    Integrate,
    /// Results copied where other systems read them.
    Writeback,
}

/// A dense point-sampled surface: the cloud as loaded (or generated).
///
/// Spawn one per surface; [`SurfaceStatus`] comes with it and tells when it is ready.
#[derive(Component, Debug, Clone, Default, Reflect)]
#[reflect(Component, Debug, Default)]
#[require(SurfaceStatus)]
pub struct DenseSurface {
    /// The points and normals. Missing normals are estimated in the background once the
    /// plugin sees the surface (see [`SurfaceStatus`]).
    #[reflect(ignore)]
    pub cloud: PointCloud,
}

impl DenseSurface {
    /// Wraps a cloud.
    pub fn new(cloud: PointCloud) -> Self {
        Self { cloud }
    }
}

/// Where a [`DenseSurface`] is in its preparation. Set it back to `Pending` after replacing
/// the cloud to prepare the surface again.
#[derive(Component, Debug, Clone, Default, PartialEq, Eq, Reflect)]
#[reflect(Component, Debug, Default)]
pub enum SurfaceStatus {
    /// Not prepared yet.
    #[default]
    Pending,
    /// Normals are being estimated on the async compute pool.
    Preparing,
    /// Prepared; `normals_estimated` tells whether normals were estimated (true) or the
    /// cloud's own (false).
    Ready {
        /// Whether normals were estimated.
        normals_estimated: bool,
    },
    /// Preparation failed; the message says why.
    Failed(String),
}

impl Plugin for PointSpringsPlugin {
    fn build(&self, app: &mut App) {
        app.insert_resource(PointSpringsConfig {
            normal_k: self.normal_k,
        })
        .register_type::<PointSpringsConfig>()
        .register_type::<DenseSurface>()
        .register_type::<SurfaceStatus>()
        .configure_sets(
            FixedUpdate,
            (
                PointSpringsSystems::Prepare,
                PointSpringsSystems::Forces,
                PointSpringsSystems::Integrate,
                PointSpringsSystems::Writeback,
            )
                .chain(),
        )
        .add_systems(
            FixedUpdate,
            (start_preparation, finish_preparation)
                .chain()
                .in_set(PointSpringsSystems::Prepare),
        );
    }
}

/// Normal estimation under way for a surface.
#[derive(Component)]
struct NormalsTask(Task<Result<(Vec<Vec3>, OrientationReport), NormalsError>>);

/// Starts preparing pending surfaces: their own normals are kept (normalised) at once; clouds
/// without usable normals get an estimation task on the async compute pool.
fn start_preparation(
    mut commands: Commands,
    config: Res<PointSpringsConfig>,
    mut surfaces: Query<(Entity, &mut DenseSurface, &mut SurfaceStatus)>,
) {
    for (entity, mut surface, mut status) in &mut surfaces {
        if *status != SurfaceStatus::Pending {
            continue;
        }
        let cloud = &mut surface.cloud;
        if cloud.has_usable_normals() {
            // Only normalises the cloud's own normals: cheap, done at once.
            *status = match ensure_normals(cloud, config.normal_k) {
                Ok(source) => SurfaceStatus::Ready {
                    normals_estimated: source != NormalSource::File,
                },
                Err(e) => SurfaceStatus::Failed(e.to_string()),
            };
            continue;
        }
        let positions = cloud.positions().to_vec();
        let k = config.normal_k;
        let task =
            AsyncComputeTaskPool::get().spawn(async move { estimate_normals(&positions, k) });
        commands.entity(entity).insert(NormalsTask(task));
        *status = SurfaceStatus::Preparing;
    }
}

/// Collects finished normal estimations.
fn finish_preparation(
    mut commands: Commands,
    mut surfaces: Query<(
        Entity,
        &mut DenseSurface,
        &mut SurfaceStatus,
        &mut NormalsTask,
    )>,
) {
    for (entity, mut surface, mut status, mut task) in &mut surfaces {
        let Some(result) = block_on(poll_once(&mut task.0)) else {
            continue;
        };
        commands.entity(entity).remove::<NormalsTask>();
        *status = match result.map_err(|e| e.to_string()).and_then(|(normals, _)| {
            surface
                .cloud
                .set_normals(normals)
                .map_err(|e| e.to_string())
        }) {
            Ok(()) => SurfaceStatus::Ready {
                normals_estimated: true,
            },
            Err(message) => SurfaceStatus::Failed(message),
        };
    }
}
