//! A flag on a moving pole, in the wind: a sheet attached by its edge to a rapier body.
//!
//! ```sh
//! cargo run --release --features render,rapier --example flag
//! cargo run --release --features render,rapier --example flag -- --screenshot flag.png --frames 240
//! ```
//!
//! The flag is a 1 m square sheet (its cloud made in memory, 200 simulation points). Its
//! simulation points within 3 cm of its left edge are attached ([`SurfaceAttachments`]) to
//! the pole, a kinematic rapier body that a system drives round a circle before each tick's
//! forces: the edge follows the pole exactly, the springs carry the rest. The wind is a
//! game system in `PointSpringsSystems::Forces`: each simulation point is pushed towards the
//! gusting air's velocity (a drag on its velocity relative to the air), with a flutter across
//! the flag. Left-drag pulls the flag, right-drag orbits, Space pauses, R starts again.

mod utils;

use bevy::prelude::*;
use bevy_point_springs::core::cloud::shapes;
use bevy_point_springs::core::pipeline::SurfaceConfig;
use bevy_point_springs::core::simplify::SimplifyConfig;
use bevy_point_springs::core::solver::MaterialUnits;
use bevy_point_springs::core::solver::{BendingModel, Integrator, SpringMaterial};
use bevy_point_springs::plugin::SurfaceMasses;
use bevy_point_springs::prelude::*;
use bevy_rapier3d::prelude::*;
use utils::{DemoArgs, DemoPlugin, prop_material, spawn_camera_and_light};

/// Side of the flag (m) and the spacing of its cloud.
const FLAG_SIDE: f32 = 1.0;
const FLAG_SPACING: f32 = 0.02;

/// The flag's edge on the pole: its points this close to its left side are attached.
const EDGE: f32 = 0.03;

/// Height of the flag's centre, and the pole's length and radius.
const FLAG_HEIGHT: f32 = 2.2;
const POLE_LENGTH: f32 = 3.0;
const POLE_RADIUS: f32 = 0.03;

/// The circle the pole goes round: radius (m) and angular speed (rad/s).
const CIRCLE: (f32, f32) = (1.2, 0.6);

/// The wind: mean speed along +X (m/s), gusts (a share of it, and their angular
/// frequency), the flutter across the flag (m/s), and how hard the air drags a point
/// (per second: a point's mass times this, times its velocity relative to the air).
const WIND: f32 = 8.0;
const GUSTS: (f32, f32) = (0.35, 1.3);
const FLUTTER: f32 = 2.0;
const AIR_DRAG: f32 = 1.5;

fn main() -> AppExit {
    App::new()
        .add_plugins((
            DemoPlugin {
                title: "bevy_point_springs — flag",
                args: DemoArgs::from_env(),
                panel: false,
            },
            RapierPhysicsPlugin::<NoUserData>::default().in_fixed_schedule(),
        ))
        .add_systems(Startup, setup)
        .add_systems(
            FixedUpdate,
            (
                drive_pole.before(PointSpringsSystems::Forces),
                wind.in_set(PointSpringsSystems::Forces),
            ),
        )
        .run()
}

/// Marks the pole.
#[derive(Component)]
struct Pole;

/// Marks the flag.
#[derive(Component)]
struct Flag;

/// Where the pole stands at `t` seconds: round the circle, its foot on the floor.
fn pole_at(t: f32) -> Vec3 {
    let (radius, speed) = CIRCLE;
    Vec3::new(
        radius * (speed * t).cos() - radius,
        POLE_LENGTH * 0.5,
        radius * (speed * t).sin(),
    )
}

fn setup(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    let pole = commands
        .spawn((
            Pole,
            RigidBody::KinematicPositionBased,
            Collider::cylinder(POLE_LENGTH * 0.5, POLE_RADIUS),
            Mesh3d(meshes.add(Cylinder::new(POLE_RADIUS, POLE_LENGTH))),
            MeshMaterial3d(materials.add(prop_material())),
            Transform::from_translation(pole_at(0.0)),
        ))
        .id();
    // The flag: a sheet in the XY plane, its left edge along the pole.
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(200),
        material: SpringMaterial {
            units: MaterialUnits::Sheet,
            stretch_stiffness: 300.0,
            stretch_damping: 0.2,
            bending: BendingModel::Hinges,
            bending_modulus: 0.002,
            density: 0.3,
            ..default()
        },
        solver: SolverConfig {
            integrator: Integrator::ImplicitEuler,
            drag: 0.2,
            ..default()
        },
        ..default()
    };
    let mut attachments = SurfaceAttachments::default();
    let half = FLAG_SIDE * 0.5;
    attachments.attach(pole, AttachPoints::filter(move |p| p.x < -half + EDGE));
    commands.spawn((
        Name::new("flag"),
        Flag,
        DeformableSurface::cloud(shapes::square_sheet(FLAG_SIDE, FLAG_SPACING), config),
        attachments,
        SurfelRender {
            color: Color::srgb(0.85, 0.25, 0.2),
            ..default()
        },
        // Not touching rapier's bodies: the pole would push the edge it holds.
        SurfaceContact {
            enabled: false,
            ..default()
        },
        // The left edge against the pole.
        Transform::from_xyz(half + POLE_RADIUS, FLAG_HEIGHT, 0.0),
    ));
    // The floor.
    commands.spawn((
        Collider::cuboid(6.0, 0.1, 6.0),
        Mesh3d(meshes.add(Cuboid::new(12.0, 0.2, 12.0))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.24, 0.26, 0.3),
            perceptual_roughness: 0.9,
            ..default()
        })),
        Transform::from_xyz(0.0, -0.1, 0.0),
    ));
    spawn_camera_and_light(&mut commands, Vec3::new(-0.7, 1.9, 0.0), 4.6, 0.25, 0.15);
}

/// The pole round its circle: its `Transform` set to where it will be at the end of the
/// tick, before the tick's forces (rapier moves it there; the flag's edge lands there).
fn drive_pole(
    time: Res<Time>,
    flags: Query<(&SurfaceStatus, &SurfaceRunSettings), With<Flag>>,
    mut poles: Query<&mut Transform, With<Pole>>,
    mut t: Local<f32>,
) {
    let running = flags
        .iter()
        .any(|(status, settings)| status.is_ready() && !settings.paused);
    if !running {
        return;
    }
    *t += time.delta_secs();
    for mut pole in &mut poles {
        pole.translation = pole_at(*t);
    }
}

/// The wind, in each flag's own coordinates: each simulation point dragged towards the
/// air's velocity, the gusts along the wind, the flutter across the flag varying along it.
fn wind(
    time: Res<Time>,
    mut flags: Query<
        (
            &SimulationPoints,
            &SurfaceMasses,
            &GlobalTransform,
            &mut SurfaceForces,
        ),
        With<Flag>,
    >,
) {
    let t = time.elapsed_secs();
    let (share, frequency) = GUSTS;
    for (points, masses, place, mut forces) in &mut flags {
        let to_local = place.affine().inverse();
        for i in 0..points.len() {
            let p = points.position(i);
            let gust = WIND * (1.0 + share * (frequency * t).sin());
            let flutter = FLUTTER * (7.0 * t - 6.0 * p.x).sin();
            let air = to_local.transform_vector3(Vec3::new(gust, 0.0, flutter));
            let force = (air - points.velocity(i)) * masses.mass(i) * AIR_DRAG;
            if let Err(e) = forces.add(i, force) {
                warn!("the wind on point {i}: {e}");
                return;
            }
        }
    }
}
