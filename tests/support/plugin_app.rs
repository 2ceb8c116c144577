//! The headless plugin app of `tests/plugin.rs`: `MinimalPlugins` + `AssetPlugin` +
//! `PointSpringsPlugin`, with `TimeUpdateStrategy::ManualDuration` so that one `update()` is
//! one fixed tick; waiting for preparation; and (feature `render`) a mouse driven the way
//! Bevy's picking reads it. Included by path: Cargo does not build files in a folder under
//! `tests/` as tests of their own.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use bevy::ecs::system::RunSystemOnce;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_point_springs::core::cloud::shapes;
use bevy_point_springs::core::network::SpringNetwork;
use bevy_point_springs::core::pipeline::SurfaceConfig;
use bevy_point_springs::core::simplify::SimplifyConfig;
use bevy_point_springs::plugin::{SurfaceMasses, SurfaceNetwork};
use bevy_point_springs::prelude::*;

/// Fixed tick of the tests that do not follow a scene.
pub const TICK: Duration = Duration::from_micros(15_625);

/// Upper bound on waiting for background work (a hang guard, not a speed check).
pub const SETTLE_TIMEOUT: Duration = Duration::from_secs(120);

pub fn assets_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("assets")
}

/// A headless app reading files from `assets` and ticking `tick` per update.
pub fn create_app(assets: &Path, tick: Duration) -> App {
    create_app_with(assets, tick, |_| {})
}

/// [`create_app`] with more plugins, added by `extra` before the app is finished.
pub fn create_app_with(assets: &Path, tick: Duration, extra: impl FnOnce(&mut App)) -> App {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        AssetPlugin {
            file_path: assets.display().to_string(),
            ..default()
        },
        PointSpringsPlugin::default(),
    ))
    .insert_resource(TimeUpdateStrategy::ManualDuration(tick))
    .insert_resource(Time::<Fixed>::from_duration(tick));
    extra(&mut app);
    app.finish();
    app.cleanup();
    // The first update only starts the clock.
    app.update();
    app
}

pub fn status(app: &App, e: Entity) -> SurfaceStatus {
    app.world().get::<SurfaceStatus>(e).cloned().unwrap()
}

/// Updates until every surface has left loading and preparation behind.
pub fn settle(app: &mut App, surfaces: &[Entity]) {
    let deadline = Instant::now() + SETTLE_TIMEOUT;
    let busy = |app: &App| {
        surfaces.iter().any(|&e| {
            matches!(
                app.world().get::<SurfaceStatus>(e),
                Some(SurfaceStatus::Pending | SurfaceStatus::Loading | SurfaceStatus::Preparing)
            )
        })
    };
    while busy(app) {
        assert!(Instant::now() < deadline, "surfaces did not settle");
        app.update();
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// [`settle`], with every surface paused until all are ready: none steps while another
/// prepares (for as many ticks as that happens to take), so that each run begins alike.
#[allow(dead_code)] // not every test file that includes this uses it
pub fn settle_together(app: &mut App, surfaces: &[Entity]) {
    let pause = |app: &mut App, paused: bool| {
        for &e in surfaces {
            let mut settings = app.world_mut().get_mut::<SurfaceRunSettings>(e).unwrap();
            settings.paused = paused;
        }
    };
    pause(app, true);
    settle(app, surfaces);
    pause(app, false);
}

/// A floating surface (no gravity) from a cloud in memory.
pub fn floating(points: usize, sim: usize) -> DeformableSurface {
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(sim),
        solver: SolverConfig {
            gravity: Vec3::ZERO,
            ..default()
        },
        ..default()
    };
    DeformableSurface::cloud(shapes::fibonacci_sphere(points, 1.0), config)
}

/// Σ m·v of `e`'s simulation points in world coordinates: measured, not reported.
#[allow(dead_code)] // `tests/meet.rs` and `tests/contact.rs` use it
pub fn momentum(app: &App, e: Entity) -> Vec3 {
    let place = app.world().get::<GlobalTransform>(e).unwrap();
    let masses = app.world().get::<SurfaceMasses>(e).unwrap();
    let points = app.world().get::<SimulationPoints>(e).unwrap();
    (0..points.len())
        .map(|i| masses.mass(i) * place.affine().transform_vector3(points.velocity(i)))
        .sum()
}

pub fn centroid(points: &SimulationPoints) -> Vec3 {
    points.iter_positions().sum::<Vec3>() / points.len() as f32
}

/// The mouse's ray from `camera`, straight down from `from`, as Bevy would build it from
/// the cursor.
#[cfg(feature = "render")]
pub fn aim_mouse(app: &mut App, camera: Entity, from: Vec3) {
    use bevy::math::Ray3d;
    use bevy::picking::backend::ray::{RayId, RayMap};
    use bevy::picking::pointer::PointerId;

    let ray = Ray3d::new(from, -Dir3::Y);
    let mut rays = app.world_mut().resource_mut::<RayMap>();
    rays.map.clear();
    rays.map.insert(RayId::new(camera, PointerId::Mouse), ray);
}

/// The mouse in the middle of a 1280×720 window.
#[cfg(feature = "render")]
pub fn mouse_location() -> bevy::picking::pointer::Location {
    use bevy::camera::NormalizedRenderTarget;
    use bevy::picking::pointer::Location;

    Location {
        target: NormalizedRenderTarget::None {
            width: 1280,
            height: 720,
        },
        position: Vec2::new(640.0, 360.0),
    }
}

/// What Bevy's picking writes when the primary button is pressed over `target` at `hit`.
#[cfg(feature = "render")]
pub fn press_mouse(app: &mut App, hit: &bevy::picking::backend::HitData, target: Entity) {
    use bevy::picking::pointer::{PointerButton, PointerId};
    use bevy::picking::prelude::{Pointer, Press};

    app.world_mut().write_message(Pointer::new(
        PointerId::Mouse,
        mouse_location(),
        Press {
            button: PointerButton::Primary,
            hit: hit.clone(),
            count: 1,
        },
        target,
    ));
}

/// What Bevy's input writes when the primary button is released.
#[cfg(feature = "render")]
pub fn release_mouse(app: &mut App) {
    use bevy::picking::pointer::{PointerAction, PointerButton, PointerId, PointerInput};

    app.world_mut().write_message(PointerInput::new(
        PointerId::Mouse,
        mouse_location(),
        PointerAction::Release(PointerButton::Primary),
    ));
}

/// Wind from +X on every point of surfaces marked `Windy`.
#[derive(Component)]
pub struct Windy;

/// A steady wind on every [`Windy`] surface (a game's own force system).
pub fn wind(mut surfaces: Query<&mut SurfaceForces, With<Windy>>) {
    for mut forces in &mut surfaces {
        for i in 0..forces.len() {
            forces.add(i, Vec3::X * 0.05).unwrap();
        }
    }
}

/// The simulation point of `surface` nearest to `p`, and its position.
pub fn nearest_point(app: &App, surface: Entity, p: Vec3) -> (usize, Vec3) {
    let points = app.world().get::<SimulationPoints>(surface).unwrap();
    points
        .iter_positions()
        .enumerate()
        .min_by(|a, b| a.1.distance(p).total_cmp(&b.1.distance(p)))
        .unwrap()
}

/// Holds still (pins where they are, with `SurfacePins`, as a game would) the simulation
/// points of `e` whose rest position `held` accepts; returns how many.
pub fn hold(
    app: &mut App,
    e: Entity,
    held: impl Fn(Vec3) -> bool + Send + Sync + 'static,
) -> usize {
    let rest = network_of(app, e);
    app.world_mut()
        .run_system_once(move |mut pins: SurfacePins| {
            pins.pin_where(e, |i| held(rest.positions[i])).unwrap()
        })
        .unwrap()
}

/// `e`'s spring network at rest (its `Arc`: the same one until `e` is prepared again or baked).
pub fn network_of(app: &App, e: Entity) -> Arc<SpringNetwork> {
    app.world()
        .get::<SurfaceNetwork>(e)
        .unwrap()
        .shared()
        .clone()
}
