//! The paper's Fig. 6: the lower part of a sphere, its middle pulled into a hat.
//!
//! ```sh
//! cargo run --release --features render --example hat
//! cargo run --release --features render --example hat -- --screenshot hat.png --frames 300
//! # the same hat bending on hinges, with the hinges drawn (green at rest, red bent)
//! cargo run --release --features render --example hat -- scenes/hat_hinges.ron --gizmos
//! ```
//!
//! The scene (`assets/scenes/hat.ron`) is loaded through the asset server and followed
//! step by step: the 3000-point cap below y = -0.2 of a unit sphere is simplified to 300
//! simulation points, its rim is held, and the points within 0.3 of its bottom pole are
//! pulled 0.9 further down over 200 steps and held there: the middle rises into a crown
//! (the hat hangs upside down, as in the paper's figure), finished by step 300. The
//! stretched crown is resampled so that it shows no holes. Right-drag orbits, the wheel
//! zooms, G shows the simulation points and springs, Space pauses, R starts again.

mod utils;

use bevy::prelude::*;
use bevy_point_springs::prelude::*;
use utils::{DemoArgs, DemoPlugin, prop_material, spawn_camera_and_light};

fn main() -> AppExit {
    App::new()
        .add_plugins(DemoPlugin {
            title: "bevy_point_springs — hat",
            args: DemoArgs::from_env(),
            panel: false,
        })
        .add_systems(Startup, setup)
        .run()
}

fn setup(
    mut commands: Commands,
    args: Res<DemoArgs>,
    assets: Res<AssetServer>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    commands.spawn((
        // Another scene of the same hat (`scenes/hat_hinges.ron`) when one is given.
        DeformableSurface::scene(match &args.file {
            Some(scene) => assets.load(scene.clone()),
            None => assets.load("scenes/hat.ron"),
        }),
        SurfelRender {
            color: Color::srgb(0.55, 0.42, 0.75),
            ..default()
        },
    ));
    // The ring that holds the rim (the scene pins the band above y = -0.3).
    commands.spawn((
        Mesh3d(meshes.add(Torus::new(0.93, 1.03))),
        MeshMaterial3d(materials.add(prop_material())),
        Transform::from_xyz(0.0, -0.22, 0.0),
    ));
    spawn_camera_and_light(&mut commands, Vec3::new(0.0, -0.9, 0.0), 4.4, 0.6, 0.15);
}
