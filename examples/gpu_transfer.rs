//! Measures the drawn surface's transfer on the CPU against the GPU, headless: a sphere of
//! `--points` dense points following `--simulation` simulation points, moved by a wave each
//! frame, drawn by a camera that renders no colour target (so the frame is the transfer,
//! the upload and the compute pass, not the rasteriser). For each path it prints the
//! milliseconds a frame takes (the update, then waiting for the device to finish its work)
//! and the CPU's share spent transferring and packing; then it reads the GPU's surfels back
//! and compares them with the CPU transfer's.
//!
//! ```text
//! cargo run --release --features render --example gpu_transfer -- --points 1000000 --simulation 10000
//! ```
//!
//! The preparation is kept in a prepared file in the temporary directory (the second path
//! and later runs read it). On a machine without a GPU, Mesa's lavapipe runs the compute
//! pass on the CPU's cores: the numbers then say what the pass costs there, not on a GPU.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use bevy::app::ScheduleRunnerPlugin;
use bevy::camera::RenderTarget;
use bevy::log::LogPlugin;
use bevy::mesh::MeshTag;
use bevy::prelude::*;
use bevy::render::RenderPlugin;
use bevy::render::gpu_readback::{Readback, ReadbackComplete};
use bevy::render::render_resource::PollType;
use bevy::render::renderer::{RenderAdapterInfo, RenderDevice};
use bevy::window::ExitCondition;
use bevy::winit::WinitPlugin;
use bevy_point_springs::core::cloud::shapes::fibonacci_sphere;
use bevy_point_springs::core::cloud::surfels::{
    SURFEL_BYTES, SurfelShape, compare_records, pack_surfels,
};
use bevy_point_springs::core::pipeline::DenseCloud;
use bevy_point_springs::core::pipeline::SurfaceConfig;
use bevy_point_springs::core::simplify::SimplifyConfig;
use bevy_point_springs::plugin::panel::PointSpringsPanelPlugin;
use bevy_point_springs::plugin::pick::SurfacePickingPlugin;
use bevy_point_springs::plugin::render::{SurfelMaterial, SurfelSlot, TransferDevice};
use bevy_point_springs::plugin::{SurfaceNetwork, SurfaceTimings, TransferTiming};
use bevy_point_springs::prelude::*;

/// Frames before the timed ones (pipelines compile, buffers grow).
const WARM_UP_FRAMES: usize = 10;

/// A hang guard for preparation and readback.
const TIMEOUT: Duration = Duration::from_secs(1200);

struct Options {
    points: usize,
    simulation: usize,
    frames: usize,
}

fn options() -> Options {
    let mut o = Options {
        points: 100_000,
        simulation: 2_000,
        frames: 60,
    };
    let args: Vec<String> = std::env::args().skip(1).collect();
    for pair in args.chunks(2) {
        let value = pair
            .get(1)
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("{} needs a number", pair[0]));
        match pair[0].as_str() {
            "--points" => o.points = value,
            "--simulation" => o.simulation = value,
            "--frames" => o.frames = value,
            other => panic!("unknown option {other} (--points N --simulation M --frames F)"),
        }
    }
    o
}

/// A headless app; `log`: whether it sets up logging (only the first app of the process
/// may).
fn app(log: bool) -> App {
    let mut app = App::new();
    let mut plugins = DefaultPlugins.build();
    if !log {
        plugins = plugins.disable::<LogPlugin>();
    }
    // No window: no pointer to grab with, no panel.
    let point_springs = PointSpringsPlugins::default()
        .build()
        .disable::<SurfacePickingPlugin>();
    #[cfg(feature = "egui")]
    let point_springs = point_springs.disable::<PointSpringsPanelPlugin>();
    app.add_plugins((
        plugins
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
        point_springs,
    ))
    .add_systems(Update, wave);
    app.world_mut().spawn((
        Camera3d::default(),
        RenderTarget::None {
            size: UVec2::new(1280, 720),
        },
        Transform::from_xyz(0.0, 0.5, 4.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    app.finish();
    app.cleanup();
    app
}

/// Frames drawn so far, which the wave follows.
#[derive(Resource, Default)]
struct Frame(u32);

/// Moves every simulation point of the (paused) surfaces along its normal by a travelling
/// wave, so that each frame's transfer has new positions to follow.
fn wave(
    frame: Option<ResMut<Frame>>,
    mut surfaces: Query<(&mut SimulationPoints, &SurfaceNetwork)>,
) {
    let Some(mut frame) = frame else {
        return;
    };
    frame.0 += 1;
    let phase = frame.0 as f32 * 0.1;
    for (mut points, network) in &mut surfaces {
        for (i, (&rest, &normal)) in network.positions.iter().zip(&network.normals).enumerate() {
            let lift = 0.05 * (4.0 * rest.y + phase).sin();
            // Finite by construction; a refusal would leave the point where it was.
            let _ = points.set_position(i, rest + normal * lift);
        }
    }
}

fn update_until(app: &mut App, what: &str, done: impl Fn(&mut App) -> bool) {
    let deadline = Instant::now() + TIMEOUT;
    while !done(app) {
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        app.update();
    }
}

/// One path's figures.
struct Run {
    frame_ms: f64,
    transfer_ms: f64,
    upload_ms: f64,
}

fn run(o: &Options, device: TransferDevice, file: &std::path::Path) -> (Run, App, Entity) {
    let mut app = app(device == TransferDevice::Cpu);
    let config = SurfaceConfig {
        simplify: SimplifyConfig {
            target: Some(o.simulation),
            ..default()
        },
        ..default()
    };
    let cloud = fibonacci_sphere(o.points, 1.0);
    let surface = app
        .world_mut()
        .spawn((
            DeformableSurface::cloud(cloud, config).with_prepared_file(file),
            SurfelRender {
                device,
                ..default()
            },
            SurfaceRunSettings {
                transfer: TransferTiming::PerFrame,
                paused: true,
                ..default()
            },
        ))
        .id();
    update_until(&mut app, "preparation", |app| {
        app.world().get::<SurfelSlot>(surface).is_some()
    });
    app.insert_resource(Frame::default());
    let wait = |app: &App| {
        // Pipelined rendering: the previous frame's work is on the device; wait for it.
        let _ = app
            .world()
            .resource::<RenderDevice>()
            .poll(PollType::wait_indefinitely());
    };
    for _ in 0..WARM_UP_FRAMES {
        app.update();
        wait(&app);
    }
    let (mut total, mut transfer, mut upload) = (0.0, 0.0, 0.0);
    for _ in 0..o.frames {
        let start = Instant::now();
        app.update();
        wait(&app);
        total += start.elapsed().as_secs_f64() * 1e3;
        let timings = app.world().get::<SurfaceTimings>(surface).unwrap();
        transfer += f64::from(timings.transfer_ms);
        upload += f64::from(timings.upload_ms);
    }
    let frames = o.frames.max(1) as f64;
    let run = Run {
        frame_ms: total / frames,
        transfer_ms: transfer / frames,
        upload_ms: upload / frames,
    };
    (run, app, surface)
}

/// The GPU's surfels of `surface` against the CPU transfer and packing of the same points.
fn check(app: &mut App, surface: Entity) {
    let buffer = app
        .world()
        .get::<MeshMaterial3d<SurfelMaterial>>(surface)
        .and_then(|m| app.world().resource::<Assets<SurfelMaterial>>().get(&m.0))
        .map(|m| m.extension.surfels.clone())
        .expect("a drawn surface has its batch's material");
    // The wave stops, so that the readback sees the frame the CPU transfers.
    app.world_mut().remove_resource::<Frame>();
    for _ in 0..3 {
        app.update();
    }
    let read: Arc<Mutex<Option<Vec<u8>>>> = Arc::default();
    let sink = read.clone();
    app.world_mut()
        .spawn(Readback::buffer(buffer))
        .observe(move |event: On<ReadbackComplete>| {
            *sink.lock().unwrap() = Some(event.data.clone());
        });
    update_until(app, "the readback", |_| read.lock().unwrap().is_some());
    let gpu = read.lock().unwrap().take().unwrap();
    let world = app.world();
    let first = world.get::<MeshTag>(surface).unwrap().0 as usize;
    let points = world.get::<SimulationPoints>(surface).unwrap().0.clone();
    let mut dense = DenseCloud::clone(world.get::<DenseSurface>(surface).unwrap());
    let scale = world.get::<SurfelRender>(surface).unwrap().radius_scale;
    let rest = dense.transfer();
    let shape = SurfelShape::at_rest(rest.rest_positions(), rest.rest_normals(), scale);
    dense.follow(&points).unwrap();
    let mut cpu = Vec::new();
    pack_surfels(dense.positions(), dense.normals(), &shape, &mut cpu);
    let at = first * SURFEL_BYTES;
    let d = compare_records(&gpu[at..at + cpu.len()], &cpu);
    println!(
        "GPU against CPU over {} surfels: largest differences position {:.2e}, normal {:.2e}, \
         radius {:.2e} relative; edge words: {} of {} cut differ, {} by more than a step",
        d.records, d.position, d.normal, d.radius, d.edge_words_differ, d.edges, d.edge_words_apart
    );
}

fn main() {
    let o = options();
    let file = std::env::temp_dir().join(format!(
        "point-springs-gpu-transfer-{}-{}.psprep",
        o.points, o.simulation
    ));
    let (cpu_run, cpu_app, _) = run(&o, TransferDevice::Cpu, &file);
    let adapter = cpu_app
        .world()
        .get_resource::<RenderAdapterInfo>()
        .map_or("none".to_owned(), |a| {
            format!("{} ({:?}, {})", a.name, a.device_type, a.driver)
        });
    drop(cpu_app);
    let (gpu_run, mut gpu_app, surface) = run(&o, TransferDevice::Gpu, &file);
    println!(
        "{} dense points, {} simulation points, {} frames, adapter {adapter}",
        o.points, o.simulation, o.frames
    );
    for (name, r) in [("CPU", &cpu_run), ("GPU", &gpu_run)] {
        let cpu = r.transfer_ms + r.upload_ms;
        println!(
            "{name} path: {:.2} ms a frame, of which {cpu:.2} ms on the CPU for the surface \
             ({:.0} %: transfer {:.2} ms, packing {:.2} ms)",
            r.frame_ms,
            100.0 * cpu / r.frame_ms.max(1e-9),
            r.transfer_ms,
            r.upload_ms
        );
    }
    check(&mut gpu_app, surface);
}
