//! What contacts between rapier bodies and surfaces cost per tick, headless, in three scenes:
//!
//! * `playground`: a sphere (338 simulation points) and the hat (300) held by its rim, side
//!   by side, as the `playground` example had them until 2026-12-05 (it now drops the hat
//!   on the sphere: `hat on sphere` below), with 12 balls resting on them and on the floor;
//! * `sheet+50`: a 10 m sheet of 10^4 simulation points, edges held, 50 balls resting on it;
//! * `sheet+far`: the same sheet with the 50 balls 100 m away (near no surface);
//! * `crates on cloth`: a 1.2 m cloth (350 simulation points) lying on the floor, three
//!   1 kg crates dropped on it one above the other and two beside them: the points the
//!   floor holds under them stand in rapier's step as fixed balls (decision 0034);
//! * `spheres 100 m apart`: two of the playground's spheres floating 100 m apart, without
//!   [`SurfaceMeeting`], with it but no self-contact, and with both (what surfaces that
//!   meet nothing pay for meeting);
//! * `hat on sphere`: the paper's hat resting on a sphere of gas (the `playground`'s
//!   surfaces), the same three ways (without meeting the hat falls through, so compare the
//!   whole ticks only as the cost of the meeting);
//! * `cloth on ball`: a 2 m cloth draped over a ball of gas, its sides folded onto
//!   themselves (the self-contact test's scene), the same three ways;
//!
//! and the last three once more with the meeting's contacts only estimated
//! (`SurfaceMeeting::in_step` off).
//!
//! Each scene settles for [`SETTLE_TICKS`], then [`MEASURED_TICKS`] ticks are timed: the
//! contact system alone (its own clock, [`ContactDiagnostics`]) and the whole tick
//! (`App::update`: contacts, rapier, springs, transfer). Medians over ticks; compare the two
//! columns of one run, not runs on different machines.
//!
//! Each scene runs twice: contacts solved in the surfaces' steps ([`ContactSolve::InStep`],
//! the default) and estimated before them.
//!
//! `cargo bench --features rapier --bench contact [-- NAME]` (only the scenes whose name has
//! NAME in it).

use std::path::Path;
use std::time::{Duration, Instant};

use bevy::prelude::*;
use bevy_point_springs::core::cloud::io::read_cloud;
use bevy_point_springs::core::cloud::shapes;
use bevy_point_springs::core::pipeline::SurfaceConfig;
use bevy_point_springs::core::simplify::SimplifyConfig;
use bevy_point_springs::core::solver::Integrator;
use bevy_point_springs::core::solver::{BendingModel, MaterialUnits, SpringMaterial};
use bevy_point_springs::plugin::{BodySupports, SleepSettings};
use bevy_point_springs::plugin::{
    ContactDiagnostics, ContactSolve, SurfaceMeetingReport, SurfaceStepper,
};
use bevy_point_springs::prelude::*;
use bevy_rapier3d::prelude::*;

#[path = "../../tests/support/rapier_app.rs"]
mod rapier_app;
use rapier_app::{create_app, pin};

/// Ticks before timing: the balls fall and come to rest.
const SETTLE_TICKS: usize = 240;

/// Ticks timed.
const MEASURED_TICKS: usize = 240;

/// Radius of the sheet scenes' balls, metres.
const SHEET_BALL_RADIUS: f32 = 0.3;

fn main() {
    println!(
        "| scene | simulation points | balls | colliders | points touching | touching surfaces / themselves | CG iterations / tick | contacts µs/tick | whole tick µs | contacts share |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    // Scene names asked for after `--` (cargo passes `--bench` too).
    let asked: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let wanted = |name: &str| asked.is_empty() || asked.iter().any(|a| name.contains(a));
    for solve in [ContactSolve::InStep, ContactSolve::Estimated] {
        if wanted("playground") {
            playground(solve);
        }
        if wanted("sheet+50") {
            sheet(false, solve);
        }
        if wanted("sheet+far") {
            sheet(true, solve);
        }
        if wanted("crates on cloth") {
            crates_on_cloth(solve);
        }
    }
    for meet in [Meet::No, Meet::Others, Meet::AndSelf, Meet::Estimated] {
        if wanted("spheres 100 m apart") {
            spheres_apart(meet);
        }
        if wanted("hat on sphere") {
            hat_on_sphere(meet);
        }
        if wanted("cloth on ball") {
            cloth_on_ball(meet);
        }
    }
}

/// The playground's sphere: its cloud and settings (gas inside), floating when `gravity`
/// is zero.
fn playground_sphere(gravity: Vec3) -> (bevy_point_springs::core::PointCloud, SurfaceConfig) {
    // The repository's assets (this crate is its `bench/` folder).
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets");
    let cloud = read_cloud(&assets.join("sphere3203.ply"), None).unwrap();
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(338),
        material: SpringMaterial {
            stretch_stiffness: 60.0,
            bend_stiffness: 60.0,
            stretch_damping: 0.6,
            bend_damping: 0.3,
            ..default()
        },
        pressure: Some(1000.0),
        solver: SolverConfig {
            integrator: Integrator::ImplicitEuler,
            drag: 2.0,
            gravity,
            ..default()
        },
        ..default()
    };
    (cloud, config)
}

/// Whether the scene's surfaces meet each other: not at all, each other only, or each other
/// and themselves.
#[derive(Clone, Copy)]
enum Meet {
    No,
    Others,
    AndSelf,
    Estimated,
}

/// The scene's meeting, and its name in the table.
fn meeting(meet: Meet) -> (Option<SurfaceMeeting>, &'static str) {
    match meet {
        Meet::No => (None, "not meeting"),
        Meet::Others => (
            Some(SurfaceMeeting {
                self_contact: false,
                ..default()
            }),
            "meeting",
        ),
        Meet::AndSelf => (Some(SurfaceMeeting::default()), "meeting and self-contact"),
        Meet::Estimated => (
            Some(SurfaceMeeting {
                in_step: false,
                ..default()
            }),
            "meeting and self-contact, estimated",
        ),
    }
}

/// Two of the playground's spheres floating 100 m apart.
fn spheres_apart(meet: Meet) {
    let (meeting, name) = meeting(meet);
    let mut app = create_app();
    for x in [0.0, 100.0] {
        let (cloud, config) = playground_sphere(Vec3::ZERO);
        let mut e = app.world_mut().spawn((
            DeformableSurface::cloud(cloud, config),
            Transform::from_xyz(x, 1.0, 0.0),
            awake(),
        ));
        if let Some(m) = meeting.clone() {
            e.insert(m);
        }
    }
    settle(&mut app);
    measure(&mut app, &format!("spheres 100 m apart, {name}"), 0);
}

/// The paper's hat (turned over, 300 simulation points) dropped onto the playground's
/// sphere (its lower half held).
fn hat_on_sphere(meet: Meet) {
    let (meeting, name) = meeting(meet);
    let mut app = create_app();
    let (cloud, config) = playground_sphere(Vec3::ZERO);
    let sphere = app
        .world_mut()
        .spawn((
            DeformableSurface::cloud(cloud, config),
            Transform::from_xyz(0.0, 1.0, 0.0),
            awake(),
        ))
        .id();
    let turn = Quat::from_rotation_x(std::f32::consts::PI);
    let hat_config = SurfaceConfig {
        simplify: SimplifyConfig::target(300),
        solver: SolverConfig {
            integrator: Integrator::ImplicitEuler,
            drag: 1.0,
            ..default()
        },
        ..default()
    };
    let hat = app
        .world_mut()
        .spawn((
            DeformableSurface::cloud(shapes::hat(3000, 1.0, -0.2), hat_config),
            Transform::from_xyz(0.0, 1.5, 0.0).with_rotation(turn),
            awake(),
        ))
        .id();
    if let Some(m) = meeting {
        for e in [sphere, hat] {
            app.world_mut().entity_mut(e).insert(m.clone());
        }
    }
    settle(&mut app);
    pin(&mut app, sphere, |p| p.y < 0.0);
    measure(&mut app, &format!("hat on sphere, {name}"), 0);
}

/// A 2 m square of cloth (600 simulation points) dropped on a ball of gas of radius 0.5
/// (its lower half held): it drapes over the ball and its sides fold onto themselves (the
/// self-contact test's scene, `tests/meet.rs`).
fn cloth_on_ball(meet: Meet) {
    let (meeting, name) = meeting(meet);
    let mut app = create_app();
    let (_, mut config) = playground_sphere(Vec3::ZERO);
    config.simplify = SimplifyConfig::target(300);
    let cloud = shapes::fibonacci_sphere(3000, 0.5);
    let ball = app
        .world_mut()
        .spawn((DeformableSurface::cloud(cloud, config), awake()))
        .id();
    let cloth_config = SurfaceConfig {
        simplify: SimplifyConfig::target(600),
        material: SpringMaterial {
            units: MaterialUnits::Sheet,
            stretch_stiffness: 300.0,
            stretch_damping: 0.2,
            bending: BendingModel::Hinges,
            bending_modulus: 1e-3,
            density: 0.3,
            ..default()
        },
        solver: SolverConfig {
            integrator: Integrator::ImplicitEuler,
            drag: 1.0,
            gravity: Vec3::new(0.0, 0.0, -9.81),
            ..default()
        },
        ..default()
    };
    let cloth = app
        .world_mut()
        .spawn((
            DeformableSurface::cloud(shapes::square_sheet(2.0, 0.05), cloth_config),
            Transform::from_xyz(0.0, 0.0, 0.8),
            awake(),
        ))
        .id();
    if let Some(m) = meeting {
        for e in [ball, cloth] {
            app.world_mut().entity_mut(e).insert(m.clone());
        }
    }
    settle(&mut app);
    pin(&mut app, ball, |p| p.z < 0.0);
    measure(&mut app, &format!("cloth on ball, {name}"), 0);
}

/// How the surfaces' contacts reach their steps, and its name in the table.
fn contact(solve: ContactSolve) -> (SurfaceContact, &'static str) {
    let name = match solve {
        ContactSolve::InStep => "in the step",
        ContactSolve::Estimated => "estimated",
    };
    (SurfaceContact { solve, ..default() }, name)
}

fn ball(at: Vec3, radius: f32) -> impl Bundle {
    (
        RigidBody::Dynamic,
        Collider::ball(radius),
        ColliderMassProperties::Density(20.0),
        Transform::from_translation(at),
    )
}

/// Updates until every surface is ready.
fn settle(app: &mut App) {
    let deadline = Instant::now() + Duration::from_secs(600);
    loop {
        let mut statuses = app.world_mut().query::<&SurfaceStatus>();
        let all: Vec<SurfaceStatus> = statuses.iter(app.world()).cloned().collect();
        if let Some(failed) = all.iter().find(|s| matches!(s, SurfaceStatus::Failed(_))) {
            panic!("{failed:?}");
        }
        if all.iter().all(SurfaceStatus::is_ready) {
            return;
        }
        assert!(Instant::now() < deadline, "surfaces not ready");
        app.update();
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// Settles, times, prints one row.
fn measure(app: &mut App, scene: &str, balls: usize) {
    for _ in 0..SETTLE_TICKS {
        app.update();
    }
    let mut contacts = Vec::with_capacity(MEASURED_TICKS);
    let mut whole = Vec::with_capacity(MEASURED_TICKS);
    let mut touching = 0;
    let mut colliders = 0;
    let (mut met, mut own) = (0, 0);
    let mut reports = app.world_mut().query::<&SurfaceMeetingReport>();
    let mut steppers = app.world_mut().query::<&SurfaceStepper>();
    let iterations = |app: &App, steppers: &mut QueryState<&SurfaceStepper>| -> u64 {
        steppers
            .iter(app.world())
            .map(|s| s.diagnostics().cg_iterations)
            .sum()
    };
    let iterations_before = iterations(app, &mut steppers);
    for _ in 0..MEASURED_TICKS {
        let start = Instant::now();
        app.update();
        whole.push(start.elapsed());
        let d = *app.world().resource::<ContactDiagnostics>();
        contacts.push(d.time);
        touching += d.touching;
        colliders = d.colliders;
        for r in reports.iter(app.world()) {
            met += r.touching();
            own += r.self_touching();
        }
    }
    let mut points = app.world_mut().query::<&SimulationPoints>();
    let points: usize = points.iter(app.world()).map(|p| p.len()).sum();
    let (c, w) = (median(&mut contacts), median(&mut whole));
    let cg = (iterations(app, &mut steppers) - iterations_before) / MEASURED_TICKS as u64;
    println!(
        "| {scene} | {points} | {balls} | {colliders} | {} | {} / {} | {cg} | {:.0} | {:.0} | {:.1} % |",
        touching / MEASURED_TICKS,
        met / MEASURED_TICKS,
        own / MEASURED_TICKS,
        c.as_secs_f64() * 1e6,
        w.as_secs_f64() * 1e6,
        100.0 * c.as_secs_f64() / w.as_secs_f64()
    );
}

fn median(times: &mut [Duration]) -> Duration {
    times.sort();
    times[times.len() / 2]
}

fn playground(solve: ContactSolve) {
    let (contact, name) = contact(solve);
    let mut app = create_app();
    // The repository's assets (this crate is its `bench/` folder).
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets");
    let sphere = read_cloud(&assets.join("sphere3203.ply"), None).unwrap();
    let hat = read_cloud(&assets.join("hat3000.ply"), None).unwrap();
    let solver = SolverConfig {
        integrator: Integrator::ImplicitEuler,
        drag: 2.0,
        ..default()
    };
    let sphere_config = SurfaceConfig {
        simplify: SimplifyConfig::target(338),
        material: SpringMaterial {
            stretch_stiffness: 60.0,
            bend_stiffness: 60.0,
            stretch_damping: 0.6,
            bend_damping: 0.3,
            ..default()
        },
        pressure: Some(1000.0),
        solver,
        ..default()
    };
    let hat_config = SurfaceConfig {
        simplify: SimplifyConfig::target(300),
        solver,
        ..default()
    };
    let (sphere_at, hat_at) = (Vec3::new(-1.3, 1.0, 0.0), Vec3::new(1.3, 1.0, 0.0));
    app.world_mut().spawn((
        DeformableSurface::cloud(sphere, sphere_config),
        Transform::from_translation(sphere_at),
        awake(),
        contact,
    ));
    let hat = app
        .world_mut()
        .spawn((
            DeformableSurface::cloud(hat, hat_config),
            Transform::from_translation(hat_at),
            awake(),
            contact,
        ))
        .id();
    app.world_mut().spawn((
        Collider::cuboid(5.0, 0.1, 5.0),
        Transform::from_xyz(0.0, -0.1, 0.0),
    ));
    settle(&mut app);
    pin(&mut app, hat, |p| p.y >= -0.3);
    // Twelve balls: four on the sphere, four in the hat, four on the floor.
    for (i, x) in [-1.3, 1.3, 3.0].into_iter().enumerate() {
        for k in 0..4 {
            let a = k as f32 * std::f32::consts::FRAC_PI_2 + i as f32;
            let at = Vec3::new(x + 0.2 * a.cos(), 2.5 + 0.4 * k as f32, 0.2 * a.sin());
            app.world_mut().spawn(ball(at, 0.16));
        }
    }
    measure(&mut app, &format!("playground, {name}"), 12);
}

/// A crate's half side, metres.
const CRATE_HALF: f32 = 0.1;

/// The `crates on cloth` scene; see the module documentation.
fn crates_on_cloth(solve: ContactSolve) {
    let (contact, name) = contact(solve);
    let mut app = create_app();
    let side = 1.2;
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(350),
        ..default()
    };
    // Lying flat: the sheet's XY plane turned onto the floor, its points' spheres just off
    // it (as in `tests/contact_scenes.rs`).
    let turn = Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2);
    app.world_mut().spawn((
        DeformableSurface::cloud(shapes::square_sheet(side, 0.02 * side), config),
        Transform::from_xyz(0.0, 0.03 * side, 0.0).with_rotation(turn),
        awake(),
        contact,
    ));
    app.world_mut().spawn((
        Collider::cuboid(5.0, 0.1, 5.0),
        Transform::from_xyz(0.0, -0.1, 0.0),
    ));
    settle(&mut app);
    let stack = (0..3).map(|k| Vec3::new(0.05, 0.5 + 0.3 * k as f32, -0.03));
    let beside = [Vec3::new(-0.35, 0.5, 0.3), Vec3::new(0.35, 0.5, -0.3)];
    for at in stack.chain(beside) {
        app.world_mut().spawn((
            RigidBody::Dynamic,
            Collider::cuboid(CRATE_HALF, CRATE_HALF, CRATE_HALF),
            ColliderMassProperties::Mass(1.0),
            Transform::from_translation(at).with_rotation(Quat::from_rotation_y(0.3)),
        ));
    }
    measure(&mut app, &format!("crates on cloth, {name}"), 5);
    let balls = app.world().resource::<BodySupports>().len();
    println!("(crates on cloth, {name}: {balls} points standing as balls in rapier's step)");
}

/// Settings that never let a surface sleep: the bench times a whole awake tick against the
/// contacts' share of it, as it did before surfaces could sleep (a sheet with no ball near
/// would otherwise fall asleep once it settled).
fn awake() -> SurfaceRunSettings {
    SurfaceRunSettings {
        sleep: SleepSettings {
            speed: 0.0,
            ..default()
        },
        ..default()
    }
}

fn sheet(far: bool, solve: ContactSolve) {
    let (contact, name) = contact(solve);
    let mut app = create_app();
    // 10 m square, 4·10^4 dense points, 10^4 simulation points (about 0.1 apart), lying
    // flat (the sheet's +z normal turned to +y), edges held.
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(10_000),
        solver: SolverConfig {
            integrator: Integrator::ImplicitEuler,
            drag: 2.0,
            ..default()
        },
        ..default()
    };
    let sheet = app
        .world_mut()
        .spawn((
            DeformableSurface::cloud(shapes::square_sheet(10.0, 0.05), config),
            Transform::from_rotation(Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2)),
            awake(),
            contact,
        ))
        .id();
    settle(&mut app);
    pin(&mut app, sheet, |p| p.x.abs().max(p.y.abs()) > 4.9);
    let shift = if far { Vec3::X * 100.0 } else { Vec3::ZERO };
    for i in 0..10 {
        for k in 0..5 {
            let at = Vec3::new(-4.0 + 0.9 * i as f32, 0.5, -3.6 + 1.8 * k as f32);
            app.world_mut().spawn(ball(at + shift, SHEET_BALL_RADIUS));
        }
    }
    let scene = if far { "sheet+far" } else { "sheet+50" };
    measure(&mut app, &format!("{scene}, {name}"), 50);
}
