//! Surfel drawing (feature `render`): each point of a [`DenseSurface`] becomes a small disc
//! facing along its normal ([`crate::core::surfels`]), and all discs of a surface form one mesh
//! (one draw call, lit by Bevy's PBR pipeline through the surfel normals).

use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, PrimitiveTopology};
use bevy::prelude::*;

use super::{DenseSurface, SurfaceStatus};
use crate::core::surfels::{DEFAULT_SURFEL_SCALE, surfel_geometry, surfel_radii};

/// Adds surfel drawing. Needs Bevy's renderer (`DefaultPlugins`).
#[derive(Debug, Default, Clone, Copy)]
pub struct SurfelRenderPlugin;

impl Plugin for SurfelRenderPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<SurfelRender>()
            .add_systems(PostUpdate, attach_surfel_meshes);
    }
}

/// Draw this [`DenseSurface`] as surfels.
#[derive(Component, Debug, Clone, Reflect)]
#[reflect(Component, Debug)]
#[require(Transform, Visibility)]
pub struct SurfelRender {
    /// Disc radius as a multiple of the distance to the point's
    /// [`SURFEL_NEIGHBOURS`](crate::core::surfels::SURFEL_NEIGHBOURS)-th neighbour.
    pub radius_scale: f32,
    /// Surface colour.
    pub color: Color,
}

impl Default for SurfelRender {
    fn default() -> Self {
        Self {
            radius_scale: DEFAULT_SURFEL_SCALE,
            color: Color::srgb(0.85, 0.62, 0.38),
        }
    }
}

/// Gives ready surfaces that should be drawn their surfel mesh and material.
fn attach_surfel_meshes(
    mut commands: Commands,
    surfaces: Query<(Entity, &DenseSurface, &SurfaceStatus, &SurfelRender), Without<Mesh3d>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    for (entity, surface, status, render) in &surfaces {
        if !matches!(status, SurfaceStatus::Ready { .. }) {
            continue;
        }
        let cloud = &surface.cloud;
        let Some(normals) = cloud.normals() else {
            continue;
        };
        let radii = surfel_radii(cloud.positions(), render.radius_scale);
        let geometry = surfel_geometry(cloud.positions(), normals, &radii);
        let mesh = Mesh::new(
            PrimitiveTopology::TriangleList,
            RenderAssetUsages::default(),
        )
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, geometry.positions)
        .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, geometry.normals)
        .with_inserted_indices(Indices::U32(geometry.indices));
        let material = StandardMaterial {
            base_color: render.color,
            perceptual_roughness: 0.7,
            double_sided: true,
            cull_mode: None,
            ..default()
        };
        commands.entity(entity).insert((
            Mesh3d(meshes.add(mesh)),
            MeshMaterial3d(materials.add(material)),
        ));
    }
}
