//! Surfaces out of every camera's view (feature `render`): each frame, a drawn surface's
//! bounding sphere is tested against the frusta of the active cameras and the result put
//! in [`SurfaceInView`]. A surface out of view keeps simulating but skips the transfer (and
//! so the surfel upload) until it is seen again.
//!
//! The sphere holds the simulation points with a margin: the dense points lie between and
//! around them (within about a spacing), and the surfel discs reach a little further. What
//! is drawn is the dense surface as last transferred, which lags behind the simulation
//! points once the transfer stops: a surface counts as out of view only when that drawn
//! shape is out of view too (its sphere is measured once per transfer, and only then).

use bevy::camera::primitives::{Frustum, Sphere};
use bevy::camera::visibility::VisibilitySystems;
use bevy::math::Vec3A;
use bevy::prelude::*;

use super::PointSpringsSystems;
use super::components::{DenseSurface, SimulationPoints, SurfaceInView, SurfaceNetwork};
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

/// The sphere, in the surface's own coordinates, around the dense surface as drawn (as of
/// its `revision`).
#[derive(Component, Debug, Clone, Copy)]
pub(crate) struct DrawnBounds {
    revision: u64,
    center: Vec3,
    radius: f32,
}

/// The sphere around the points `points()` yields (in the surface's coordinates), widened
/// by `margin`.
fn local_sphere<I: ExactSizeIterator<Item = Vec3>>(
    points: impl Fn() -> I,
    margin: f32,
) -> (Vec3, f32) {
    let n = points().len().max(1) as f32;
    let center = points().sum::<Vec3>() / n;
    let radius = points().map(|p| p.distance(center)).fold(0.0, f32::max);
    (center, radius + margin)
}

/// A local sphere placed in the world by `transform` (its largest scale, mirrored or not).
fn world_sphere((center, radius): (Vec3, f32), transform: &GlobalTransform) -> Sphere {
    Sphere {
        center: Vec3A::from(transform.transform_point(center)),
        radius: transform.scale().abs().max_element() * radius,
    }
}

/// What [`update_in_view`] reads of a drawn surface.
type ViewParts = (
    Entity,
    &'static SimulationPoints,
    &'static SurfaceNetwork,
    &'static DenseSurface,
    &'static GlobalTransform,
    &'static mut SurfaceInView,
    Option<&'static mut DrawnBounds>,
);

/// Each drawn surface is in view when the sphere around its simulation points, or the one
/// around its dense surface as drawn, meets the frustum of an active camera.
fn update_in_view(
    mut commands: Commands,
    cameras: Query<(&Camera, &Frustum)>,
    mut surfaces: Query<ViewParts, With<SurfelRender>>,
) {
    let seen_by_any = |sphere: &Sphere| {
        cameras
            .iter()
            .any(|(camera, frustum)| camera.is_active && frustum.intersects_sphere(sphere, true))
    };
    for (entity, points, network, dense, transform, mut in_view, drawn) in &mut surfaces {
        let n = points.len().max(1) as f32;
        let margin = MARGIN_SPACINGS * (network.report.area / n).sqrt();
        let simulated = local_sphere(|| points.iter_positions(), margin);
        let mut seen = seen_by_any(&world_sphere(simulated, transform));
        if !seen {
            let revision = dense.revision();
            let bounds = match drawn {
                Some(bounds) if bounds.revision == revision => *bounds,
                stale => {
                    let (center, radius) =
                        local_sphere(|| dense.positions().iter().copied(), margin);
                    let bounds = DrawnBounds {
                        revision,
                        center,
                        radius,
                    };
                    match stale {
                        Some(mut old) => *old = bounds,
                        None => {
                            commands.entity(entity).insert(bounds);
                        }
                    }
                    bounds
                }
            };
            seen = seen_by_any(&world_sphere((bounds.center, bounds.radius), transform));
        }
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
    use crate::core::solver::PointState;

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
                    DenseSurface(prepared.dense.clone()),
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
        // Its simulation points went behind the camera but its dense surface, not transferred
        // since, is still drawn ahead: in view (until a transfer moves the drawing too).
        let behind: Vec<Vec3> = prepared
            .solver
            .points
            .iter_positions()
            .map(|p| p + Vec3::Z * 10.0)
            .collect();
        let lagging = app
            .world_mut()
            .spawn((
                SimulationPoints(PointState::new(&behind).unwrap()),
                SurfaceNetwork(network.clone()),
                DenseSurface(prepared.dense.clone()),
                GlobalTransform::from_translation(Vec3::new(0.0, 0.0, -5.0)),
                SurfaceInView(false),
                SurfelRender::default(),
            ))
            .id();
        app.update();
        let in_view = |app: &App, e: Entity| app.world().get::<SurfaceInView>(e).unwrap().0;
        assert!(in_view(&app, lagging), "the drawn surface is ahead");
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
