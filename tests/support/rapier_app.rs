//! The headless app of the contact tests and the contact bench: `MinimalPlugins` +
//! `TransformPlugin` + `PointSpringsPlugin` + rapier in the fixed schedule +
//! `SurfaceContactPlugin`, with `TimeUpdateStrategy::ManualDuration` so that one `update()`
//! is one fixed tick. Included by path (`#[path = ...] mod rapier_app;`): Cargo does not
//! build files in a folder under `tests/` as tests of their own.

use std::time::Duration;

use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
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
