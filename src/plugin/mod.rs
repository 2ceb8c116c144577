//! The Bevy layer: gathers ECS data, calls [`crate::core`], schedules.
//!
//! One entity per deformable surface; components hold whole arrays, not one entity per point.
//! The simulation runs on Bevy's fixed tick in the chained sets of [`PointSpringsSystems`]:
//! `Prepare → Forces → Integrate → Writeback`. Today `Prepare` gives new surfaces oriented
//! normals; the later sets are configured (so user systems can be ordered against them) and
//! will be filled by the spring network and the solver.

#[cfg(feature = "render")]
pub mod render;

use bevy::prelude::*;

use crate::core::PointCloud;
use crate::core::normals::{DEFAULT_NORMAL_K, NormalSource, ensure_normals};

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
    /// The points and normals. Normals are estimated on the first tick when missing.
    #[reflect(ignore)]
    pub cloud: PointCloud,
}

impl DenseSurface {
    /// Wraps a cloud.
    pub fn new(cloud: PointCloud) -> Self {
        Self { cloud }
    }
}

/// Where a [`DenseSurface`] is in its preparation.
#[derive(Component, Debug, Clone, Default, PartialEq, Eq, Reflect)]
#[reflect(Component, Debug, Default)]
pub enum SurfaceStatus {
    /// Not prepared yet.
    #[default]
    Pending,
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
            prepare_surfaces.in_set(PointSpringsSystems::Prepare),
        );
    }
}

/// Gives pending surfaces oriented normals.
fn prepare_surfaces(
    config: Res<PointSpringsConfig>,
    mut surfaces: Query<(&mut DenseSurface, &mut SurfaceStatus)>,
) {
    for (mut surface, mut status) in &mut surfaces {
        if *status != SurfaceStatus::Pending {
            continue;
        }
        *status = match ensure_normals(&mut surface.cloud, config.normal_k) {
            Ok(source) => SurfaceStatus::Ready {
                normals_estimated: matches!(source, NormalSource::Estimated(_)),
            },
            Err(e) => SurfaceStatus::Failed(e.to_string()),
        };
    }
}
