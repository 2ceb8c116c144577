//! View a point cloud as lit surfels.
//!
//! ```sh
//! cargo run --release --features render --example view_cloud -- [FILE] [--screenshot shot.png --frames 60]
//! ```
//!
//! Without FILE it shows `assets/half.xyz` (a scanned half sphere without normals: they are
//! estimated and oriented in the background by the plugin) beside `assets/sphere926.pwn`.

mod utils;

use bevy::prelude::*;
use bevy_point_springs::core::PointCloud;
use bevy_point_springs::core::io::read_cloud;
use bevy_point_springs::prelude::*;
use utils::{DemoArgs, DemoPlugin, spawn_camera_and_light};

fn main() -> AppExit {
    let args = DemoArgs::from_env();
    App::new()
        .add_plugins((
            DemoPlugin {
                title: "bevy_point_springs — view_cloud",
                args,
            },
            PointSpringsPlugin::default(),
            SurfelRenderPlugin,
        ))
        .add_systems(Startup, setup)
        .run()
}

fn load(path: &std::path::Path) -> PointCloud {
    read_cloud(path, None).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(2)
    })
}

fn setup(mut commands: Commands, args: Res<DemoArgs>) {
    let assets = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
    let clouds: Vec<(PointCloud, Color)> = match &args.file {
        Some(file) => vec![(load(file), Color::srgb(0.85, 0.62, 0.38))],
        None => {
            // Half sphere (radius ≈ 0.49), scaled to the sphere926 (radius 10) for the picture.
            let half = load(&assets.join("half.xyz"));
            let scaled: Vec<Vec3> = half.positions().iter().map(|p| *p * 20.0).collect();
            vec![
                (
                    PointCloud::new(scaled, None).unwrap_or_default(),
                    Color::srgb(0.85, 0.62, 0.38),
                ),
                (
                    load(&assets.join("sphere926.pwn")),
                    Color::srgb(0.45, 0.65, 0.85),
                ),
            ]
        }
    };
    // Lay the clouds side by side along x.
    let mut x = 0.0;
    let mut all = Vec::new();
    for (cloud, color) in clouds {
        let Some(bounds) = cloud.bounds() else {
            continue;
        };
        let offset = Vec3::new(x - bounds.min.x, 0.0, 0.0)
            - Vec3::new(0.0, bounds.center().y, bounds.center().z);
        x += (bounds.max.x - bounds.min.x) * 1.25;
        all.push(bounds.min + offset);
        all.push(bounds.max + offset);
        commands.spawn((
            DenseSurface::new(cloud),
            SurfelRender { color, ..default() },
            Transform::from_translation(offset),
        ));
    }
    let lo = all.iter().copied().fold(Vec3::splat(f32::MAX), Vec3::min);
    let hi = all.iter().copied().fold(Vec3::splat(f32::MIN), Vec3::max);
    spawn_camera_and_light(&mut commands, (lo + hi) * 0.5, (hi - lo).length());
}
