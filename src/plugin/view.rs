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

#[cfg(test)]
mod tests {
    use std::ops::ControlFlow;
    use std::sync::Arc;

    use bevy::math::primitives::ViewFrustum;

    use super::*;
    use crate::core::cloud::shapes::fibonacci_sphere;
    use crate::core::pipeline::{SurfaceConfig, prepare_surface};
    use crate::core::simplify::SimplifyConfig;

    /// A camera at the origin looking down −Z (60° vertical field, 16:9), as Bevy builds its
    /// frustum (reverse-z, infinite far).
    fn camera() -> (Camera, Frustum) {
        let clip_from_view =
            Mat4::perspective_infinite_reverse_rh(60f32.to_radians(), 16.0 / 9.0, 0.1);
        let view_from_world = Mat4::look_at_rh(Vec3::ZERO, Vec3::NEG_Z, Vec3::Y);
        let frustum = ViewFrustum::from_clip_from_world(&(clip_from_view * view_from_world));
        (Camera::default(), Frustum(frustum))
    }

    #[test]
    fn only_surfaces_a_camera_sees_are_in_view() {
        let config = SurfaceConfig {
            simplify: SimplifyConfig::target(60),
            ..SurfaceConfig::default()
        };
        let unit_sphere = fibonacci_sphere(600, 1.0);
        let prepared =
            prepare_surface(unit_sphere, &config, &mut |_| ControlFlow::Continue(())).unwrap();
        let network = Arc::new(prepared.network);
        let mut app = App::new();
        app.add_systems(Update, update_in_view);
        let camera = app.world_mut().spawn(camera()).id();
        // At depth 5 the view is ±2.89 high and ±5.13 wide; the spheres are 1 wide, their
        // bounds 1.92 (two spacings of 60 points added).
        let cases = [
            ("ahead", Vec3::new(0.0, 0.0, -5.0), true),
            ("behind", Vec3::new(0.0, 0.0, 5.0), false),
            ("far to the side", Vec3::new(20.0, 0.0, -5.0), false),
            (
                "centre outside, rim inside",
                Vec3::new(5.8, 0.0, -5.0),
                true,
            ),
            ("above", Vec3::new(0.0, 6.0, -5.0), false),
        ];
        let surfaces: Vec<Entity> = cases
            .iter()
            .map(|&(_, at, seen)| {
                let entity = app.world_mut().spawn((
                    SimulationPoints(prepared.solver.points.clone()),
                    SurfaceNetwork(network.clone()),
                    GlobalTransform::from_translation(at),
                    SurfaceInView(!seen),
                    SurfelRender::default(),
                ));
                entity.id()
            })
            .collect();
        // Not drawn by the plugin: the game decides, the plugin leaves it alone.
        let own = app
            .world_mut()
            .spawn((
                SimulationPoints(prepared.solver.points.clone()),
                SurfaceNetwork(network.clone()),
                GlobalTransform::from_translation(Vec3::new(0.0, 0.0, 5.0)),
                SurfaceInView(true),
            ))
            .id();
        app.update();
        let in_view = |app: &App, e: Entity| app.world().get::<SurfaceInView>(e).unwrap().0;
        for (&(what, _, seen), &e) in cases.iter().zip(&surfaces) {
            assert_eq!(in_view(&app, e), seen, "{what}");
        }
        assert!(in_view(&app, own));
        // An inactive camera sees nothing.
        app.world_mut().get_mut::<Camera>(camera).unwrap().is_active = false;
        app.update();
        assert!(surfaces.iter().all(|&e| !in_view(&app, e)));
    }
}
