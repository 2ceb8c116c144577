//! The headless app of the contact tests and the contact bench: `MinimalPlugins` +
//! `TransformPlugin` + `PointSpringsPlugin` + rapier in the fixed schedule +
//! `SurfaceContactPlugin`, with `TimeUpdateStrategy::ManualDuration` so that one `update()`
//! is one fixed tick; and [`pin`], to hold a surface's points once it is prepared.
//! Included by path (`#[path = ...] mod rapier_app;`): Cargo does not build files in a
//! folder under `tests/` as tests of their own.

use std::time::Duration;

use bevy::ecs::system::RunSystemOnce;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_point_springs::plugin::{SurfaceContactPlugin, SurfaceNetwork};
use bevy_point_springs::prelude::*;
use bevy_rapier3d::prelude::*;

/// The tick: 60 Hz, a game's default.
pub const TICK: Duration = Duration::from_micros(16_667);

/// The app, finished and updated once (its plugins' start-up systems have run).
pub fn create_app() -> App {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        TransformPlugin,
        PointSpringsPlugin::default(),
        RapierPhysicsPlugin::<NoUserData>::default().in_fixed_schedule(),
        SurfaceContactPlugin::default(),
    ))
    .insert_resource(TimeUpdateStrategy::ManualDuration(TICK))
    .insert_resource(Time::<Fixed>::from_duration(TICK));
    app.finish();
    app.cleanup();
    app.update();
    app
}

/// Pins, where they are and at rest ([`hold_still`]), the points whose rest position `held`
/// picks.
#[allow(dead_code)] // not every test file that includes this pins
pub fn pin(app: &mut App, surface: Entity, held: impl Fn(Vec3) -> bool + Send + Sync + 'static) {
    let rest = app
        .world()
        .get::<SurfaceNetwork>(surface)
        .unwrap()
        .shared()
        .clone();
    app.world_mut()
        .run_system_once(move |mut pins: SurfacePins| {
            pins.pin_where(surface, |i| held(rest.positions[i]))
                .unwrap();
        })
        .unwrap();
}
