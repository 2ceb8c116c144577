//! Attachments ([`SurfaceAttachments`]): simulation points tied to another entity's
//! transform, headless, in the contact tests' app (rapier in the fixed schedule, one
//! `update()` one tick).
#![cfg(feature = "rapier")]

use std::time::{Duration, Instant};

use bevy::prelude::*;
use bevy_point_springs::core::cloud::shapes;
use bevy_point_springs::core::pipeline::SurfaceConfig;
use bevy_point_springs::core::simplify::SimplifyConfig;
use bevy_point_springs::core::solver::{MaterialUnits, SpringMaterial};
use bevy_point_springs::plugin::AttachmentState;
use bevy_point_springs::plugin::{AttachmentError, AttachmentId};
use bevy_point_springs::plugin::{SurfaceMasses, SurfaceNetwork};
use bevy_point_springs::prelude::*;
use bevy_rapier3d::prelude::*;

#[path = "support/rapier_app.rs"]
mod rapier_app;
use rapier_app::TICK;

/// Upper bound on waiting for preparation (a hang guard, not a speed check).
const SETTLE_TIMEOUT: Duration = Duration::from_secs(120);

/// The sheet's simulation points at or above this height are attached (its top edge).
const TOP_EDGE: f32 = 0.45;

/// A 1 m square sheet in the XY plane (1 kg/m²), its own gravity along −Y, no drag (so
/// that gravity is the only force from outside besides the attachment), not touching
/// rapier's bodies.
fn spawn_sheet(app: &mut App) -> Entity {
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(200),
        material: SpringMaterial {
            units: MaterialUnits::Sheet,
            stretch_stiffness: 400.0,
            stretch_damping: 0.2,
            ..default()
        },
        solver: SolverConfig {
            drag: 0.0,
            ..default()
        },
        ..default()
    };
    let sheet = app
        .world_mut()
        .spawn((
            DeformableSurface::cloud(shapes::square_sheet(1.0, 0.025), config),
            SurfaceContact {
                enabled: false,
                ..default()
            },
        ))
        .id();
    let deadline = Instant::now() + SETTLE_TIMEOUT;
    while !status(app, sheet).is_ready() {
        assert!(Instant::now() < deadline, "the sheet did not get ready");
        assert!(
            !matches!(status(app, sheet), SurfaceStatus::Failed(_)),
            "{:?}",
            status(app, sheet)
        );
        app.update();
        std::thread::sleep(Duration::from_millis(1));
    }
    sheet
}

fn status(app: &App, e: Entity) -> SurfaceStatus {
    app.world().get::<SurfaceStatus>(e).unwrap().clone()
}

fn attach(app: &mut App, sheet: Entity, target: Entity, points: AttachPoints) -> AttachmentId {
    let mut attachments = SurfaceAttachments::default();
    let id = attachments.attach(target, points);
    app.world_mut().entity_mut(sheet).insert(attachments);
    id
}

fn attachments(app: &App, sheet: Entity) -> &SurfaceAttachments {
    app.world().get::<SurfaceAttachments>(sheet).unwrap()
}

/// The farthest any held point is from where its target's transform puts it.
fn off_target(app: &App, sheet: Entity, id: AttachmentId) -> f32 {
    let a = attachments(app, sheet);
    let target = a.target(id).unwrap();
    let pose = app.world().get::<Transform>(target).unwrap();
    let points = app.world().get::<SimulationPoints>(sheet).unwrap();
    a.held_points(id)
        .unwrap()
        .iter()
        .zip(a.offsets(id).unwrap())
        .map(|(&i, &offset)| {
            points
                .position(i as usize)
                .distance(pose.transform_point(offset))
        })
        .fold(0.0, f32::max)
}

/// How a kinematic body is driven round its circle.
#[derive(Component, Clone, Copy, PartialEq, Debug)]
enum Circling {
    /// Its `Transform` set to where it is at the end of each tick (a plain entity, or a
    /// rapier body moved by position).
    ByPosition,
    /// Its `Velocity` set each tick (a rapier body moved by velocity).
    ByVelocity,
}

/// Radius (m) and angular speed (rad/s) of the circle; the body turns with it.
const CIRCLE: (f32, f32) = (0.5, 2.0);

fn circle_pose(t: f32) -> Transform {
    let (r, w) = CIRCLE;
    Transform::from_xyz(r * (w * t).cos() - r, 0.0, r * (w * t).sin())
        .with_rotation(Quat::from_rotation_y(-w * t))
}

/// When the bodies started round the circle (the fixed clock's seconds): after the sheet
/// is prepared, which takes as many ticks as the machine's clock gives it.
#[derive(Resource)]
struct CircleStart(f32);

/// Before the tick's forces: bodies going round the circle, where each will be at the
/// tick's end.
fn drive_circles(
    time: Res<Time>,
    start: Option<Res<CircleStart>>,
    mut bodies: Query<(&Circling, &mut Transform, Option<&mut Velocity>)>,
) {
    // Still until they start.
    let Some(start) = start else {
        return;
    };
    let (r, w) = CIRCLE;
    let t = time.elapsed_secs() - start.0;
    for (circling, mut transform, velocity) in &mut bodies {
        match (circling, velocity) {
            (Circling::ByPosition, _) => *transform = circle_pose(t + time.delta_secs()),
            (Circling::ByVelocity, Some(mut v)) => {
                // The velocity at the middle of the tick carries it along the chord.
                let mid = t + 0.5 * time.delta_secs();
                let half = 0.5 * w * time.delta_secs();
                let chord = half.sin() / half;
                v.linear = Vec3::new(-(w * mid).sin(), 0.0, (w * mid).cos()) * r * w * chord;
                v.angular = Vec3::new(0.0, -w, 0.0);
            }
            _ => {}
        }
    }
}

#[test]
fn attached_points_follow_a_body_going_round_a_circle_exactly() {
    let cases: [(&str, Circling, Option<RigidBody>); 3] = [
        ("a plain entity", Circling::ByPosition, None),
        (
            "a kinematic body moved by position",
            Circling::ByPosition,
            Some(RigidBody::KinematicPositionBased),
        ),
        (
            "a kinematic body moved by velocity",
            Circling::ByVelocity,
            Some(RigidBody::KinematicVelocityBased),
        ),
    ];
    for (name, circling, body) in cases {
        let mut app = rapier_app::create_app();
        app.add_systems(
            FixedUpdate,
            drive_circles
                .before(PointSpringsSystems::Forces)
                .before(PhysicsSet::SyncBackend),
        );
        let sheet = spawn_sheet(&mut app);
        let begun = app.world().resource::<Time<Fixed>>().elapsed_secs();
        app.insert_resource(CircleStart(begun));
        let mut pole = app.world_mut().spawn((circle_pose(0.0), circling));
        if let Some(body) = body {
            pole.insert((body, Velocity::zero(), Collider::ball(0.02)));
        }
        let pole = pole.id();
        let id = attach(
            &mut app,
            sheet,
            pole,
            AttachPoints::filter(|p| p.y >= TOP_EDGE),
        );
        let (mut worst, mut centre_moved) = (0.0_f32, 0.0_f32);
        let start = centroid(&app, sheet);
        for tick in 0..120 {
            app.update();
            assert_eq!(
                attachments(&app, sheet).state(id),
                Some(AttachmentState::Holding),
                "{name}"
            );
            if tick > 0 {
                worst = worst.max(off_target(&app, sheet, id));
            }
            centre_moved = centre_moved.max(centroid(&app, sheet).distance(start));
        }
        let held = attachments(&app, sheet).held_points(id).unwrap().len();
        let pole_at = app.world().get::<Transform>(pole).unwrap().translation;
        println!(
            "{name}: {held} points held; the farthest from its target {worst:.2e} m; the sheet's \
             centre moved up to {centre_moved:.3} m; the pole ended at {pole_at}"
        );
        assert!(held >= 5, "{name}: {held}");
        // Exactly: to f32 rounding of positions a metre from the origin (a velocity-driven
        // body's points are carried as rapier integrates it).
        assert!(worst < 1e-5, "{name}: {worst}");
        // The pole went round most of its circle (4 rad in 2 s); the sheet came with it.
        assert!(pole_at.distance(Vec3::ZERO) > 0.3, "{name}: {pole_at}");
        assert!(centre_moved > 0.5, "{name}: {centre_moved}");
        assert!(status(&app, sheet).is_ready(), "{name}");
    }
}

fn centroid(app: &App, sheet: Entity) -> Vec3 {
    let points = app.world().get::<SimulationPoints>(sheet).unwrap();
    points.iter_positions().sum::<Vec3>() / points.len() as f32
}

fn total_mass(app: &App, sheet: Entity) -> f32 {
    app.world().get::<SurfaceMasses>(sheet).unwrap().total() as f32
}

fn momentum(app: &App, sheet: Entity) -> Vec3 {
    let points = app.world().get::<SimulationPoints>(sheet).unwrap();
    let masses = app.world().get::<SurfaceMasses>(sheet).unwrap();
    (0..points.len())
        .map(|i| points.velocity(i) * masses.mass(i))
        .sum()
}

#[test]
fn a_sheet_hanging_from_a_dynamic_body_pulls_it_with_its_weight() {
    let g = Vec3::new(0.0, -9.81, 0.0);
    let mut app = rapier_app::create_app();
    app.world_mut()
        .query::<&mut RapierConfiguration>()
        .single_mut(app.world_mut())
        .unwrap()
        .gravity = g;
    let sheet = spawn_sheet(&mut app);
    // A 1 kg body on a ball joint 0.3 m below a fixed point, beside the sheet's top edge's
    // middle: the sheet hangs from it off the joint's vertical, so the pendulum swings.
    let anchor = app
        .world_mut()
        .spawn((RigidBody::Fixed, Transform::from_xyz(0.25, 0.8, 0.0)))
        .id();
    let joint = SphericalJointBuilder::new().local_anchor2(Vec3::new(0.0, 0.3, 0.0));
    let body = app
        .world_mut()
        .spawn((
            RigidBody::Dynamic,
            Collider::cuboid(0.05, 0.05, 0.05),
            ColliderMassProperties::Mass(1.0),
            ReadMassProperties::default(),
            Velocity::zero(),
            Sleeping::disabled(),
            ImpulseJoint::new(anchor, joint),
            Transform::from_xyz(0.25, 0.5, 0.0),
        ))
        .id();
    let id = attach(
        &mut app,
        sheet,
        body,
        AttachPoints::filter(|p| p.y >= TOP_EDGE),
    );
    // One tick to start holding.
    app.update();
    let body_start = app.world().get::<Transform>(body).unwrap().translation;
    let start_momentum = momentum(&app, sheet);
    let (mut pull, mut time) = (Vec3::ZERO, 0.0);
    for _ in 0..240 {
        app.update();
        pull += attachments(&app, sheet).pull(id).unwrap();
        time += TICK.as_secs_f32();
    }
    let mass = total_mass(&app, sheet);
    let weight = mass * g * time;
    let change = momentum(&app, sheet) - start_momentum;
    let body_moved = app
        .world()
        .get::<Transform>(body)
        .unwrap()
        .translation
        .distance(body_start);
    let body_mass = app.world().get::<ReadMassProperties>(body).unwrap().mass;
    let off_weight = (pull - weight).length() / weight.length();
    // The pull on the body is the weight less what the sheet's momentum gained.
    let off_momentum = (pull - (weight - change)).length() / weight.length();
    println!(
        "sheet {mass:.3} kg on a {body_mass:.2} kg body, {time:.2} s: pull {pull:.3} N·s against \
         the weight's {weight:.3} (off by {off_weight:.2e}); the sheet's momentum changed by \
         {change:.3} (balance off by {off_momentum:.2e}); the body moved {body_moved:.3} m; \
         {} points held",
        attachments(&app, sheet).held_points(id).unwrap().len()
    );
    assert!((0.8..1.2).contains(&mass), "{mass}");
    assert!((body_mass - 1.0).abs() < 1e-3, "{body_mass}");
    assert!(off_weight < 0.02, "{off_weight}");
    assert!(off_momentum < 0.01, "{off_momentum}");
    assert!(
        body_moved > 0.02,
        "the sheet's pull moved the body {body_moved} m"
    );
    assert!(status(&app, sheet).is_ready());
}

#[test]
fn attachments_are_picked_again_after_preparing_again_and_let_go_of_a_despawned_target() {
    let mut app = rapier_app::create_app();
    let sheet = spawn_sheet(&mut app);
    let pole = app.world_mut().spawn(Transform::default()).id();
    let mut attachments_of = SurfaceAttachments::default();
    let top = attachments_of.attach(pole, AttachPoints::filter(|p| p.y >= TOP_EDGE));
    let corner = attachments_of.attach(
        pole,
        AttachPoints::Near {
            centre: Vec3::new(-0.5, -0.5, 0.0),
            radius: 0.1,
        },
    );
    let wrong = attachments_of.attach(pole, AttachPoints::Indices(vec![0, 100_000]));
    app.world_mut().entity_mut(sheet).insert(attachments_of);
    app.update();
    let pinned = |app: &App| app.world().get::<SurfaceMasses>(sheet).unwrap().pinned();
    let a = attachments(&app, sheet);
    let (top_held, corner_held) = (
        a.held_points(top).unwrap().len(),
        a.held_points(corner).unwrap().len(),
    );
    assert_eq!(a.state(top), Some(AttachmentState::Holding));
    assert_eq!(a.state(corner), Some(AttachmentState::Holding));
    let points = app.world().get::<SimulationPoints>(sheet).unwrap().len();
    assert_eq!(
        a.state(wrong),
        Some(AttachmentState::Released(
            AttachmentError::PointOutOfRange {
                index: 100_000,
                points
            }
        ))
    );
    assert!(top_held >= 5 && corner_held >= 1);
    assert_eq!(pinned(&app), top_held + corner_held);

    // Detached: its points are free on the next tick; the other holds on.
    app.world_mut()
        .get_mut::<SurfaceAttachments>(sheet)
        .unwrap()
        .detach(corner);
    app.update();
    assert_eq!(pinned(&app), top_held);
    assert_eq!(attachments(&app, sheet).state(corner), None);

    // Prepared again at another size: picked again on the new network.
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(120),
        ..app.world().get::<DeformableSurface>(sheet).unwrap().config
    };
    app.world_mut()
        .entity_mut(sheet)
        .insert(PrepareAgain(config));
    let before = app
        .world()
        .get::<SurfaceNetwork>(sheet)
        .unwrap()
        .shared()
        .clone();
    let deadline = Instant::now() + SETTLE_TIMEOUT;
    while std::sync::Arc::ptr_eq(
        &before,
        app.world().get::<SurfaceNetwork>(sheet).unwrap().shared(),
    ) {
        assert!(Instant::now() < deadline, "not prepared again");
        app.update();
        std::thread::sleep(Duration::from_millis(1));
    }
    app.update();
    let a = attachments(&app, sheet);
    let again = a.held_points(top).unwrap().len();
    assert_eq!(a.state(top), Some(AttachmentState::Holding));
    assert!(again >= 3 && again < top_held, "{again} of {top_held}");
    assert_eq!(pinned(&app), again);

    // The target despawned: the attachment lets go, its points fall, the app runs on.
    app.world_mut().despawn(pole);
    app.update();
    assert_eq!(
        attachments(&app, sheet).state(top),
        Some(AttachmentState::Released(AttachmentError::TargetGone(pole)))
    );
    assert_eq!(pinned(&app), 0);
    let falling_from = centroid(&app, sheet).y;
    for _ in 0..30 {
        app.update();
    }
    assert!(centroid(&app, sheet).y < falling_from - 0.1);
    assert!(status(&app, sheet).is_ready());
}
