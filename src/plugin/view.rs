//! Surfaces out of every camera's view (feature `render`): each frame, a drawn surface's
//! bounding sphere is tested against the frusta of the active cameras and the result put
//! in [`SurfaceInView`]. A surface out of view keeps simulating but skips the transfer (and
//! so the surfel upload) until it is seen again.
//!
//! The sphere holds the simulation points with a margin: the dense points lie between and
//! around them (within about a spacing), and the surfel discs reach a little further.

use bevy::camera::primitives::{Frustum, Sphere};
use bevy::camera::visibility::VisibilitySystems;
use bevy::math::Vec3A;
use bevy::prelude::*;

use super::PointSpringsSystems;
use super::components::{SimulationPoints, SurfaceInView, SurfaceNetwork};
use super::render::SurfelRender;

/// The bounding sphere is widened by this many typical spacings of the simulation points.
const MARGIN_SPACINGS: f32 = 2.0;

/// Sets [`SurfaceInView`] of drawn surfaces from the cameras (added by
/// [`SurfelRenderPlugin`](super::render::SurfelRenderPlugin)).
pub(crate) fn add_systems(app: &mut App) {
    app.add_systems(
        PostUpdate,
        update_in_view
            .after(VisibilitySystems::UpdateFrusta)
            .before(PointSpringsSystems::Transfer),
    );
}

/// The world-space sphere around a surface's simulation points, with the margin.
fn bounds(
    points: &SimulationPoints,
    network: &SurfaceNetwork,
    transform: &GlobalTransform,
) -> Sphere {
    let n = points.len().max(1) as f32;
    let local_center = points.iter_positions().sum::<Vec3>() / n;
    let local_radius = points
        .iter_positions()
        .map(|p| p.distance(local_center))
        .fold(0.0, f32::max);
    let spacing = (network.report.area / n).sqrt();
    let scale = transform.scale().max_element();
    Sphere {
        center: Vec3A::from(transform.transform_point(local_center)),
        radius: scale * (local_radius + MARGIN_SPACINGS * spacing),
    }
}

/// Each drawn surface is in view when its sphere meets the frustum of an active camera.
fn update_in_view(
    cameras: Query<(&Camera, &Frustum)>,
    mut surfaces: Query<
        (
            &SimulationPoints,
            &SurfaceNetwork,
            &GlobalTransform,
            &mut SurfaceInView,
        ),
        With<SurfelRender>,
    >,
) {
    for (points, network, transform, mut in_view) in &mut surfaces {
        let sphere = bounds(points, network, transform);
        let seen = cameras
            .iter()
            .any(|(camera, frustum)| camera.is_active && frustum.intersects_sphere(&sphere, true));
        in_view.set_if_neq(SurfaceInView(seen));
    }
}
