//! The paper's Fig. 5: a point-sampled sphere in a cup, poked by a finger, let go, and
//! springing back.
//!
//! ```sh
//! cargo run --release --features render --example sphere_poke
//! cargo run --release --features render --example sphere_poke -- --screenshot poke.png --frames 150
//! ```
//!
//! The scene (`assets/scenes/sphere_poke.ron`) is loaded through the asset server and
//! followed step by step: the 3203-point sphere is simplified to 338 simulation points,
//! the points within 0.3 of its top are pulled 0.45 inward (deepest at step 150), let go at
//! step 170, and the gas inside pushes the dent back out. Right-drag orbits, the wheel
//! zooms, G shows the simulation points and springs, Space pauses, R starts again.

mod utils;

use bevy::prelude::*;
use bevy_point_springs::plugin::SurfaceAnchors;
use bevy_point_springs::prelude::*;
use utils::{DemoArgs, DemoPlugin, prop_material, spawn_camera_and_light};

fn main() -> AppExit {
    App::new()
        .add_plugins(DemoPlugin {
            title: "bevy_point_springs — sphere_poke",
            args: DemoArgs::from_env(),
            panel: false,
        })
        .add_systems(Startup, setup)
        .add_systems(Update, move_finger)
        .run()
}

/// The finger that pokes: drawn where the scene's pull holds the top of the sphere.
#[derive(Component)]
struct Finger;

/// How far the finger's tip sits above the targets of the points it holds.
const FINGER_TIP: f32 = 0.12;

fn setup(
    mut commands: Commands,
    assets: Res<AssetServer>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    commands.spawn((
        DeformableSurface::scene(assets.load("scenes/sphere_poke.ron")),
        SurfelRender::default(),
    ));
    // The cup: the scene pins every simulation point below y = -0.6.
    commands.spawn((
        Mesh3d(meshes.add(Torus::new(0.62, 0.86))),
        MeshMaterial3d(materials.add(prop_material())),
        Transform::from_xyz(0.0, -0.66, 0.0),
    ));
    commands.spawn((
        Finger,
        Mesh3d(meshes.add(Capsule3d::new(0.12, 0.9))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.9, 0.75, 0.65),
            perceptual_roughness: 0.6,
            ..default()
        })),
        Transform::from_xyz(0.0, 1.0 + FINGER_TIP + 0.57, 0.0),
        Visibility::Hidden,
    ));
    spawn_camera_and_light(&mut commands, Vec3::new(0.0, 0.1, 0.0), 4.0, 0.5, 0.75);
}

/// The finger follows the pull: shown while anchors hold the sphere (the scene's poke, or a
/// mouse grab), at the mean target of the points they hold.
fn move_finger(
    surfaces: Query<(&SurfaceAnchors, &GlobalTransform)>,
    mut fingers: Query<(&mut Transform, &mut Visibility), With<Finger>>,
) {
    let Ok((mut finger, mut visibility)) = fingers.single_mut() else {
        return;
    };
    let Some((anchors, place)) = surfaces.iter().next() else {
        return;
    };
    let targets: Vec<Vec3> = anchors.iter().map(|(_, a)| a.target).collect();
    if targets.is_empty() {
        *visibility = Visibility::Hidden;
        return;
    }
    let mean = targets.iter().sum::<Vec3>() / targets.len() as f32;
    let top = targets.iter().map(|t| t.y).fold(f32::MIN, f32::max);
    let tip = place.transform_point(Vec3::new(mean.x, top, mean.z));
    finger.translation = tip + Vec3::Y * (FINGER_TIP + 0.57);
    *visibility = Visibility::Visible;
}
