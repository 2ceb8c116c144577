//! Rigid bodies and deformable surfaces touching, and surfaces touching each other and
//! themselves: the hat dropped on a sphere on a floor, a sheet dropped on its edge that
//! folds on itself, a 1 kg and a 5 kg crate dropped on a cloth lying on the floor, balls
//! dropped on the hat every second and a half, and the mouse to poke and drag.
//!
//! ```sh
//! cargo run --release --features egui,rapier --example playground
//! cargo run --release --features egui,rapier --example playground -- --screenshot play.png --frames 240
//! ```
//!
//! The sphere (3203 points, 338 simulation points, gas inside) sits on the floor under
//! gravity; the hat's cloud (the cap of a sphere, 300 simulation points), turned over, is
//! dropped onto it from a metre above and rests on it like a cap on a head: both carry
//! [`SurfaceMeeting`], so their points push each other apart. Beside them a 1.4 m sheet
//! (400 simulation points), dropped standing on its edge, buckles and folds on itself; its
//! `SurfaceMeeting` keeps the folds apart. In front, a 1.2 m cloth (350 simulation points)
//! lies on the floor; half a second in, two crates fall on it from a metre up and come to
//! rest on it. All four are [`DeformableSurface`]s; the floor, the crates and the balls
//! are bevy_rapier3d bodies.
//! [`SurfaceContactPlugin`] makes every simulation point a small sphere that rapier's
//! colliders push, and pushes them back. Left-drag pokes and pulls a surface, right-drag
//! orbits, the wheel zooms, G shows the simulation points and springs, Space pauses. Built
//! with the `egui` feature it shows the live panel (figures, plots, settings, bake, export).

mod utils;

use bevy::prelude::*;
use bevy_point_springs::core::cloud::shapes;
use bevy_point_springs::core::pipeline::SurfaceConfig;
use bevy_point_springs::core::simplify::SimplifyConfig;
use bevy_point_springs::core::solver::MaterialUnits;
use bevy_point_springs::core::solver::{BendingModel, DampingModel, Integrator, SpringMaterial};
use bevy_point_springs::prelude::*;
use bevy_rapier3d::prelude::*;
use utils::{DemoArgs, DemoPlugin, spawn_camera_and_light};

/// Ticks between two balls (1.5 s at 60 Hz).
const BALL_INTERVAL: u32 = 90;

/// Balls kept at once; the oldest goes when another comes.
const MAX_BALLS: usize = 12;

/// Radius of a ball, metres.
const BALL_RADIUS: f32 = 0.16;

/// Density of a ball (kg/m³): 0.7 kg, about forty of the hat's simulation points.
const BALL_DENSITY: f32 = 40.0;

/// Mass per unit area of the sphere.
const SPHERE_DENSITY: f32 = 1.0;

/// Height the balls are dropped from.
const DROP_HEIGHT: f32 = 3.4;

/// Where the sphere stands, and how high above it the hat starts (the hat's inside is the
/// sphere's size: it lands this far below).
const SPHERE_AT: Vec3 = Vec3::new(0.0, 1.0, 0.0);
const HAT_DROP: f32 = 1.0;

/// Air drag on the hat (per second), which steadies it as it lands.
const HAT_DRAG: f32 = 1.0;

/// The cloth lying on the floor: its side (m) and where its middle lies.
const CLOTH_SIDE: f32 = 1.2;
const CLOTH_AT: Vec3 = Vec3::new(1.9, 0.04, 0.9);

/// The crates: their side (m), when they fall (ticks) and, for each, its mass (kg) and
/// where it starts.
const CRATE_SIDE: f32 = 0.2;
const CRATE_TICK: u32 = 30;
const CRATES: [(f32, Vec3); 2] = [
    (1.0, Vec3::new(1.6, 1.2, 0.8)),
    (5.0, Vec3::new(2.15, 1.2, 1.0)),
];

/// The sheet: its side (m), where its middle starts (standing on its edge, 0.9 m above
/// the floor, beside the sphere), how far it leans, and its flexural rigidity (N·m): soft
/// enough to fold on itself where it lands (`tests/contact.rs` drops the same sheet).
const SHEET_SIDE: f32 = 1.4;
const SHEET_AT: Vec3 = Vec3::new(-2.0, 1.6, 0.6);
const SHEET_LEAN: f32 = 0.05;
const SHEET_BENDING: f32 = 1e-3;

fn main() -> AppExit {
    App::new()
        .add_plugins((
            DemoPlugin {
                title: "bevy_point_springs — playground",
                args: DemoArgs::from_env(),
                panel: true,
            },
            RapierPhysicsPlugin::<NoUserData>::default().in_fixed_schedule(),
        ))
        .add_systems(Startup, setup)
        .add_systems(FixedUpdate, (drop_balls, drop_crates))
        .run()
}

/// Marks a ball, with the tick it was dropped at.
#[derive(Component)]
struct Ball(u32);

/// The ball's mesh and material, made once.
#[derive(Resource)]
struct BallLook {
    mesh: Handle<Mesh>,
    material: Handle<StandardMaterial>,
}

fn setup(
    mut commands: Commands,
    assets: Res<AssetServer>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    // Both surfaces: implicit Euler at the tick, a little air drag.
    let solver = SolverConfig {
        integrator: Integrator::ImplicitEuler,
        drag: 2.0,
        ..default()
    };
    let sphere = SurfaceConfig {
        simplify: SimplifyConfig::target(338),
        material: SpringMaterial {
            stretch_stiffness: 60.0,
            bend_stiffness: 60.0,
            stretch_damping: 0.6,
            bend_damping: 0.3,
            density: SPHERE_DENSITY,
            ..default()
        },
        pressure: Some(1000.0),
        // Damping on the springs' whole relative velocity (the paper's eq 3): a ball set on
        // the sphere sinks in, bobs once and rests within two seconds. Along the springs
        // only (the default), the dent's up-and-down motion is barely damped and the ball
        // bobs for seven seconds (`tests/contact.rs`).
        solver: SolverConfig {
            damping_model: DampingModel::Relative,
            ..solver
        },
        ..default()
    };
    commands.spawn((
        Name::new("sphere"),
        DeformableSurface::cloud_asset(assets.load("sphere3203.ply"), sphere),
        SurfaceMeeting::default(),
        SurfelRender::default(),
        Transform::from_translation(SPHERE_AT),
    ));
    // The hat turned over, rim down (gravity is the world's, however a surface is turned).
    let turn = Quat::from_rotation_x(std::f32::consts::PI);
    let hat = SurfaceConfig {
        simplify: SimplifyConfig::target(300),
        solver: SolverConfig {
            drag: HAT_DRAG,
            ..solver
        },
        ..default()
    };
    commands.spawn((
        Name::new("hat"),
        DeformableSurface::cloud_asset(assets.load("hat3000.ply"), hat),
        SurfaceMeeting::default(),
        SurfelRender {
            color: Color::srgb(0.55, 0.42, 0.75),
            ..default()
        },
        Transform::from_translation(SPHERE_AT + Vec3::Y * HAT_DROP).with_rotation(turn),
    ));
    // The sheet, standing on its edge: it buckles as it lands and folds on itself
    // (`SurfaceMeeting`'s self-contact keeps its folds from passing through each other).
    let lean = Quat::from_rotation_x(SHEET_LEAN);
    let sheet = SurfaceConfig {
        simplify: SimplifyConfig::target(400),
        material: SpringMaterial {
            units: MaterialUnits::Sheet,
            stretch_stiffness: 300.0,
            stretch_damping: 0.2,
            bending: BendingModel::Hinges,
            bending_modulus: SHEET_BENDING,
            density: 0.3,
            ..default()
        },
        solver: SolverConfig {
            drag: 0.2,
            ..solver
        },
        ..default()
    };
    commands.spawn((
        Name::new("sheet"),
        DeformableSurface::cloud(shapes::square_sheet(SHEET_SIDE, 0.025 * SHEET_SIDE), sheet),
        SurfaceMeeting::default(),
        SurfelRender {
            color: Color::srgb(0.25, 0.6, 0.55),
            ..default()
        },
        Transform::from_translation(SHEET_AT).with_rotation(lean),
    ));
    // The cloth lying on the floor (its cloud's XY plane turned onto it), at the default
    // material, meeting itself.
    let cloth = SurfaceConfig {
        simplify: SimplifyConfig::target(350),
        ..default()
    };
    commands.spawn((
        Name::new("cloth"),
        DeformableSurface::cloud(shapes::square_sheet(CLOTH_SIDE, 0.02 * CLOTH_SIDE), cloth),
        SurfaceMeeting::default(),
        SurfelRender {
            color: Color::srgb(0.8, 0.7, 0.35),
            ..default()
        },
        Transform::from_translation(CLOTH_AT)
            .with_rotation(Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2)),
    ));
    // The floor: a rapier collider and its slab.
    commands.spawn((
        Collider::cuboid(5.0, 0.1, 5.0),
        Mesh3d(meshes.add(Cuboid::new(10.0, 0.2, 10.0))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.24, 0.26, 0.3),
            perceptual_roughness: 0.9,
            ..default()
        })),
        Transform::from_xyz(0.0, -0.1, 0.0),
    ));
    commands.insert_resource(BallLook {
        mesh: meshes.add(Sphere::new(BALL_RADIUS)),
        material: materials.add(StandardMaterial {
            base_color: Color::srgb(0.85, 0.2, 0.2),
            perceptual_roughness: 0.4,
            ..default()
        }),
    });
    spawn_camera_and_light(&mut commands, Vec3::new(0.0, 0.8, 0.0), 6.0, 0.0, 0.6);
}

/// [`CRATE_TICK`] ticks after the surfaces are ready, the crates.
fn drop_crates(
    mut commands: Commands,
    surfaces: Query<&SurfaceStatus>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut tick: Local<u32>,
) {
    if surfaces.is_empty() || !surfaces.iter().all(SurfaceStatus::is_ready) {
        return;
    }
    *tick += 1;
    if *tick != CRATE_TICK {
        return;
    }
    let half = 0.5 * CRATE_SIDE;
    let mesh = meshes.add(Cuboid::new(CRATE_SIDE, CRATE_SIDE, CRATE_SIDE));
    let material = materials.add(StandardMaterial {
        base_color: Color::srgb(0.6, 0.4, 0.2),
        perceptual_roughness: 0.8,
        ..default()
    });
    for (k, (mass, at)) in CRATES.into_iter().enumerate() {
        commands.spawn((
            Name::new(format!("crate {k}")),
            RigidBody::Dynamic,
            Collider::cuboid(half, half, half),
            ColliderMassProperties::Mass(mass),
            Mesh3d(mesh.clone()),
            MeshMaterial3d(material.clone()),
            Transform::from_translation(at).with_rotation(Quat::from_rotation_y(0.3 * k as f32)),
        ));
    }
}

/// Every [`BALL_INTERVAL`] ticks while the surfaces run, a ball over the hat on the sphere,
/// its middle or a little off it; the oldest goes when there are too many.
fn drop_balls(
    mut commands: Commands,
    look: Res<BallLook>,
    surfaces: Query<(&SurfaceStatus, &SurfaceRunSettings)>,
    balls: Query<(Entity, &Ball)>,
    mut tick: Local<u32>,
) {
    let running = !surfaces.is_empty()
        && surfaces
            .iter()
            .all(|(status, settings)| status.is_ready() && !settings.paused);
    if !running {
        return;
    }
    *tick += 1;
    // The first once the hat has landed.
    if !(*tick).is_multiple_of(BALL_INTERVAL) {
        return;
    }
    let n = *tick / BALL_INTERVAL;
    // A walk around the top of the hat, the same on every run.
    let angle = n as f32 * 2.4;
    let offset = Vec3::new(angle.cos(), 0.0, angle.sin()) * (0.15 + 0.25 * (n % 3) as f32);
    commands.spawn((
        Ball(*tick),
        RigidBody::Dynamic,
        Collider::ball(BALL_RADIUS),
        ColliderMassProperties::Density(BALL_DENSITY),
        Mesh3d(look.mesh.clone()),
        MeshMaterial3d(look.material.clone()),
        Transform::from_translation(Vec3::new(SPHERE_AT.x, DROP_HEIGHT, SPHERE_AT.z) + offset),
    ));
    let mut all: Vec<(Entity, u32)> = balls.iter().map(|(e, b)| (e, b.0)).collect();
    if all.len() >= MAX_BALLS {
        all.sort_by_key(|&(_, t)| t);
        commands.entity(all[0].0).despawn();
    }
}
