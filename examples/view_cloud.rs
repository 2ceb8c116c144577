//! View a point cloud as lit surfels, prepared as a deformable surface at rest.
//!
//! ```sh
//! cargo run --release --features render --example view_cloud -- [FILE] [--screenshot shot.png --frames 60]
//! ```
//!
//! Without FILE it shows `assets/half.xyz` (a scanned half sphere without normals: they are
//! estimated and oriented in the background by the plugin's preparation). A FILE is read
//! through the asset server, so give its path relative to `assets/`. Nothing pulls on the
//! surface and there is no gravity, so it stays at rest; G shows the simulation points
//! §3 chose and the springs §4 built between them.

mod utils;

use bevy::prelude::*;
use bevy_point_springs::prelude::*;
use utils::{DemoArgs, DemoPlugin, spawn_camera_and_light};

fn main() -> AppExit {
    let args = DemoArgs::from_env();
    App::new()
        .add_plugins(DemoPlugin {
            title: "bevy_point_springs — view_cloud",
            args,
            panel: false,
        })
        .add_systems(Startup, setup)
        .add_systems(Update, frame_the_surface)
        .run()
}

fn setup(mut commands: Commands, args: Res<DemoArgs>, assets: Res<AssetServer>) {
    let file = args
        .file
        .as_ref()
        .map_or_else(|| "half.xyz".to_owned(), |f| f.display().to_string());
    let config = SurfaceConfig {
        solver: SolverConfig {
            gravity: Vec3::ZERO,
            ..default()
        },
        ..default()
    };
    commands.spawn((
        DeformableSurface::cloud_asset(assets.load(file), config),
        SurfelRender::default(),
    ));
    spawn_camera_and_light(&mut commands, Vec3::ZERO, 3.0, 0.5, 0.45);
}

/// Once the surface is prepared, aims the camera at it.
fn frame_the_surface(
    surfaces: Query<&DenseSurface, Added<DenseSurface>>,
    mut cameras: Query<(&mut Transform, &mut utils::OrbitCamera)>,
) {
    for dense in &surfaces {
        let rest = dense.transfer().rest_positions();
        let lo = rest.iter().copied().fold(Vec3::splat(f32::MAX), Vec3::min);
        let hi = rest.iter().copied().fold(Vec3::splat(f32::MIN), Vec3::max);
        for (mut transform, mut orbit) in &mut cameras {
            orbit.target = (lo + hi) * 0.5;
            orbit.distance = (hi - lo).length() * 1.3;
            *transform = orbit.transform();
        }
    }
}
