//! The transfer on the GPU against the CPU's, read back from the GPU through Bevy's
//! `Readback`: two surfaces in one batch (the paper's sphere, closed, and the hat, whose rim
//! is cut), deformed by a twist and a bulge, drawn by the compute pass of
//! `surfel_transfer.wgsl`, compared record by record with the CPU transfer and
//! `pack_surfels`. Needs a Vulkan adapter: on a machine without a GPU, Mesa's lavapipe
//! (`mesa-vulkan-drivers`, which `.ci/run` installs).

use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use bevy::app::ScheduleRunnerPlugin;
use bevy::camera::RenderTarget;
use bevy::ecs::system::RunSystemOnce;
use bevy::mesh::MeshTag;
use bevy::prelude::*;
use bevy::render::RenderPlugin;
use bevy::render::gpu_readback::{Readback, ReadbackComplete};
use bevy::render::storage::ShaderBuffer;
use bevy::window::ExitCondition;
use bevy::winit::WinitPlugin;
use bevy_point_springs::core::cloud::io::read_cloud;
use bevy_point_springs::core::cloud::surfels::{
    SURFEL_BYTES, SurfelShape, compare_records, pack_surfels,
};
use bevy_point_springs::core::pipeline::DenseCloud;
use bevy_point_springs::core::pipeline::SurfaceConfig;
use bevy_point_springs::core::simplify::SimplifyConfig;
use bevy_point_springs::plugin::TransferTiming;
use bevy_point_springs::plugin::components::SurfaceRunSettings;
use bevy_point_springs::plugin::render::SurfelRenderPlugin;
use bevy_point_springs::plugin::render::{
    SurfelMaterial, SurfelRender, SurfelSlot, TransferDevice,
};
use bevy_point_springs::prelude::*;

/// A hang guard, not a speed check.
const TIMEOUT: Duration = Duration::from_secs(300);

fn asset(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets")
        .join(name)
}

/// A headless app with the renderer (no window) and one camera, drawing nothing but
/// prepasses, that sees the surfaces (so that they are transferred).
fn gpu_app() -> App {
    let mut app = App::new();
    app.add_plugins((
        DefaultPlugins
            .set(WindowPlugin {
                primary_window: None,
                exit_condition: ExitCondition::DontExit,
                ..default()
            })
            .set(RenderPlugin {
                synchronous_pipeline_compilation: true,
                ..default()
            })
            .disable::<WinitPlugin>(),
        ScheduleRunnerPlugin::default(),
        PointSpringsPlugin::default(),
        SurfelRenderPlugin,
    ));
    app.world_mut().spawn((
        Camera3d::default(),
        RenderTarget::None {
            size: UVec2::new(64, 64),
        },
        Transform::from_xyz(0.0, 0.5, 6.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    app.finish();
    app.cleanup();
    app
}

/// A surface drawn from the GPU, held still so that only the test moves its points.
fn spawn(app: &mut App, cloud: bevy_point_springs::core::PointCloud, target: usize) -> Entity {
    let config = SurfaceConfig {
        simplify: SimplifyConfig {
            target: Some(target),
            ..default()
        },
        ..default()
    };
    app.world_mut()
        .spawn((
            DeformableSurface::cloud(cloud, config),
            SurfelRender {
                device: TransferDevice::Gpu,
                ..default()
            },
            SurfaceRunSettings {
                transfer: TransferTiming::PerFrame,
                paused: true,
                ..default()
            },
        ))
        .id()
}

fn update_until(app: &mut App, what: &str, done: impl Fn(&mut App) -> bool) {
    let deadline = Instant::now() + TIMEOUT;
    while !done(app) {
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        app.update();
    }
}

/// A smooth, non-affine deformation: a twist about y growing with height, and a bulge.
fn deform(p: Vec3) -> Vec3 {
    let turn = Quat::from_rotation_y(0.6 * p.y);
    turn * (p * (1.0 + 0.15 * p.x * p.x)) + Vec3::new(0.1, -0.05, 0.2)
}

/// Moves every simulation point of `surfaces` by `to`.
fn move_points(app: &mut App, surfaces: &[Entity], to: impl Fn(Vec3) -> Vec3) {
    for &e in surfaces {
        let mut points = app.world_mut().get_mut::<SimulationPoints>(e).unwrap();
        for i in 0..points.len() {
            let p = points.position(i);
            points.set_position(i, to(p)).unwrap();
        }
    }
}

/// The batch's buffer as the GPU holds it after a few more frames (for the upload, the
/// pipelines and the pass; the readback's copy runs after the frame's compute pass).
fn read_back(app: &mut App, surface: Entity) -> Vec<u8> {
    for _ in 0..5 {
        app.update();
    }
    let buffer: Handle<ShaderBuffer> = app
        .world()
        .get::<MeshMaterial3d<SurfelMaterial>>(surface)
        .and_then(|m| app.world().resource::<Assets<SurfelMaterial>>().get(&m.0))
        .map(|m| m.extension.surfels.clone())
        .unwrap();
    let read: Arc<Mutex<Option<Vec<u8>>>> = Arc::default();
    let sink = read.clone();
    let reader = app
        .world_mut()
        .spawn(Readback::buffer(buffer))
        .observe(move |event: On<ReadbackComplete>| {
            *sink.lock().unwrap() = Some(event.data.clone());
        })
        .id();
    update_until(app, "the readback", |_| read.lock().unwrap().is_some());
    app.world_mut().despawn(reader);
    read.lock().unwrap().take().unwrap()
}

/// Each surface's records in `gpu` against the CPU transfer and packing of its points.
fn check_against_cpu(app: &App, surfaces: &[Entity], gpu: &[u8]) {
    for &e in surfaces {
        let world = app.world();
        let first = world.get::<MeshTag>(e).unwrap().0 as usize;
        let points = world.get::<SimulationPoints>(e).unwrap().0.clone();
        let mut dense = DenseCloud::clone(world.get::<DenseSurface>(e).unwrap());
        let render = world.get::<SurfelRender>(e).unwrap();
        let rest = dense.transfer();
        let shape = SurfelShape::at_rest(
            rest.rest_positions(),
            rest.rest_normals(),
            render.radius_scale,
        );
        dense.follow(&points).unwrap();
        let mut cpu = Vec::new();
        pack_surfels(dense.positions(), dense.normals(), &shape, &mut cpu);
        let at = first * SURFEL_BYTES;
        let drawn = &gpu[at..at + cpu.len()];
        let d = compare_records(drawn, &cpu);
        let extent = dense
            .positions()
            .iter()
            .fold(0.0f32, |m, p| m.max(p.length()));
        println!(
            "surface {e}: {} dense points, {} edge surfels; largest differences: position \
             {:.2e} (of {extent:.2}), normal {:.2e}, radius {:.2e} relative; {} edge words \
             more than a step apart ({} differ at all)",
            dense.len(),
            d.edges,
            d.position,
            d.normal,
            d.radius,
            d.edge_words_apart,
            d.edge_words_differ
        );
        // The CPU moved the points: the comparison is of a deformed surface.
        assert!(dense.max_displacement() > 0.1);
        assert!(d.position <= 1e-5 * extent.max(1.0), "{d:?}");
        assert!(d.normal <= 1e-4, "{d:?}");
        assert!(d.radius <= 1e-4, "{d:?}");
        assert_eq!(d.records, dense.len());
        assert_eq!(d.edge_words_apart, 0, "{d:?}");
    }
}

/// Surfels of `surface` in `gpu` that are cut along an edge.
fn cut_surfels(app: &App, surface: Entity, gpu: &[u8]) -> usize {
    let first = app.world().get::<MeshTag>(surface).unwrap().0 as usize;
    let n = app.world().get::<DenseSurface>(surface).unwrap().len();
    gpu[first * SURFEL_BYTES..(first + n) * SURFEL_BYTES]
        .chunks_exact(SURFEL_BYTES)
        .filter(|r| r[28..32] != [0; 4])
        .count()
}

#[test]
fn the_gpu_transfer_draws_what_the_cpu_transfer_packs() {
    let mut app = gpu_app();
    let sphere = read_cloud(&asset("sphere3203.ply"), None).unwrap();
    let hat = read_cloud(&asset("hat3000.ply"), None).unwrap();
    let surfaces = [spawn(&mut app, sphere, 338), spawn(&mut app, hat, 300)];
    update_until(&mut app, "preparation and slots", |app| {
        surfaces.iter().all(|&e| {
            app.world().get::<SurfelSlot>(e).is_some()
                && app
                    .world()
                    .get::<SurfaceStatus>(e)
                    .is_some_and(|s| s.is_ready())
        })
    });
    for &e in &surfaces {
        assert!(app.world().get::<SurfelSlot>(e).unwrap().on_gpu());
    }
    move_points(&mut app, &surfaces, deform);
    let gpu = read_back(&mut app, surfaces[0]);
    check_against_cpu(&app, &surfaces, &gpu);
    // The hat's rim is cut, the sphere is not.
    assert_eq!(cut_surfels(&app, surfaces[0], &gpu), 0);
    assert!(cut_surfels(&app, surfaces[1], &gpu) > 50);

    // Pins change the transfer's rows (the dense points by pinned points follow the pins
    // alone): the GPU gets the new coefficients, and draws what the CPU does.
    for &e in &surfaces {
        app.world_mut()
            .run_system_once(move |mut pins: SurfacePins| {
                pins.pin_where(e, |i| i % 3 == 0).unwrap();
            })
            .unwrap();
    }
    move_points(&mut app, &surfaces, |p| {
        p + Vec3::new(0.0, 0.1 * p.x * p.x, 0.0)
    });
    let pinned = read_back(&mut app, surfaces[0]);
    assert_ne!(pinned, gpu);
    check_against_cpu(&app, &surfaces, &pinned);
}
