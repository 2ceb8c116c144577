//! Surfel drawing (feature `render`): each point of a [`DenseSurface`] becomes a small disc
//! facing along its normal, and all discs of a surface form one mesh (one draw call, lit by
//! Bevy's PBR pipeline through the surfel normals).

use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, PrimitiveTopology};
use bevy::prelude::*;

use super::{DenseSurface, SurfaceStatus};
use crate::core::knn::KnnIndex;

/// Rim vertices of each surfel disc.
pub const SURFEL_SIDES: usize = 6;

/// Neighbours whose farthest sets a surfel's size.
pub const SURFEL_NEIGHBOURS: usize = 6;

/// Default surfel radius as a multiple of the distance to the point's
/// [`SURFEL_NEIGHBOURS`]-th nearest neighbour: discs then overlap their neighbours' even where
/// the sampling is uneven (a latitude-longitude scan is dense along rows, sparse across), so
/// the surface reads as closed.
pub const DEFAULT_SURFEL_SCALE: f32 = 0.75;

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
    /// Disc radius as a multiple of the distance to the [`SURFEL_NEIGHBOURS`]-th neighbour.
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

/// Builds the surfel mesh of points with unit normals: one `SURFEL_SIDES`-gon per point, of
/// the point's radius, in the plane perpendicular to its normal.
pub fn surfel_mesh(positions: &[Vec3], normals: &[Vec3], radii: &[f32]) -> Mesh {
    let per_point = SURFEL_SIDES + 1;
    let mut vertex_positions = Vec::with_capacity(positions.len() * per_point);
    let mut vertex_normals = Vec::with_capacity(positions.len() * per_point);
    let mut indices = Vec::with_capacity(positions.len() * SURFEL_SIDES * 3);
    let rim: Vec<(f32, f32)> = (0..SURFEL_SIDES)
        .map(|s| (s as f32 * std::f32::consts::TAU / SURFEL_SIDES as f32).sin_cos())
        .collect();
    for ((&p, &n), &radius) in positions.iter().zip(normals).zip(radii) {
        let n = n.normalize_or(Vec3::Z);
        let (t1, t2) = n.any_orthonormal_pair();
        let base = vertex_positions.len() as u32;
        vertex_positions.push(p.to_array());
        for &(s, c) in &rim {
            vertex_positions.push((p + (t1 * c + t2 * s) * radius).to_array());
        }
        vertex_normals.extend(std::iter::repeat_n(n.to_array(), per_point));
        for s in 0..SURFEL_SIDES as u32 {
            let next = (s + 1) % SURFEL_SIDES as u32;
            indices.extend([base, base + 1 + s, base + 1 + next]);
        }
    }
    Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vertex_positions)
    .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, vertex_normals)
    .with_inserted_indices(Indices::U32(indices))
}

/// Each point's surfel radius: `scale` times the distance to its [`SURFEL_NEIGHBOURS`]-th
/// nearest neighbour (or to its farthest one in a smaller cloud; 1 for a lone point).
pub fn surfel_radii(positions: &[Vec3], scale: f32) -> Vec<f32> {
    let graph = KnnIndex::build(positions).knn_graph(positions, SURFEL_NEIGHBOURS);
    (0..positions.len())
        .map(|i| {
            let far = graph.neighbour_dist2(i).last().map_or(1.0, |d2| d2.sqrt());
            scale * far
        })
        .collect()
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
        let mesh = surfel_mesh(cloud.positions(), normals, &radii);
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn surfels_face_their_normals() {
        let mesh = surfel_mesh(&[Vec3::ZERO, Vec3::X], &[Vec3::Y, Vec3::Z], &[0.5, 0.5]);
        let Some(bevy::mesh::VertexAttributeValues::Float32x3(pos)) =
            mesh.attribute(Mesh::ATTRIBUTE_POSITION)
        else {
            panic!("no positions");
        };
        assert_eq!(pos.len(), 2 * (SURFEL_SIDES + 1));
        // First disc lies in the plane y = 0 at distance 0.5 from its centre.
        for v in &pos[1..=SURFEL_SIDES] {
            assert!(v[1].abs() < 1e-6);
            assert!((Vec3::from_array(*v).length() - 0.5).abs() < 1e-5);
        }
        assert_eq!(mesh.indices().map(Indices::len), Some(2 * SURFEL_SIDES * 3));
    }

    #[test]
    fn radii_follow_local_spacing() {
        // A dense row and a sparse one: each point's disc scales with its own neighbourhood.
        let mut pts: Vec<Vec3> = (0..20)
            .map(|i| Vec3::new(i as f32 * 0.1, 0.0, 0.0))
            .collect();
        pts.extend((0..20).map(|i| Vec3::new(i as f32 * 1.0, 50.0, 0.0)));
        let r = surfel_radii(&pts, 1.0);
        assert!((r[10] - 0.3).abs() < 1e-4, "{}", r[10]);
        assert!((r[30] - 3.0).abs() < 1e-3, "{}", r[30]);
        assert_eq!(surfel_radii(&[Vec3::ZERO], 0.5), vec![0.5]);
    }
}
