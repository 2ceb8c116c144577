//! The headless plugin: `MinimalPlugins` + `PointSpringsPlugin`, one `update()` = one known step.

use std::time::{Duration, Instant};

use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_point_springs::core::{PointCloud, shapes};
use bevy_point_springs::prelude::*;

/// Fixed tick used by the tests.
const TICK: Duration = Duration::from_micros(15_625);

/// Upper bound on waiting for background preparation (a hang guard, not a speed check).
const SETTLE_TIMEOUT: Duration = Duration::from_secs(60);

fn create_app() -> App {
    let mut app = App::new();
    app.add_plugins((MinimalPlugins, PointSpringsPlugin::default()))
        .insert_resource(TimeUpdateStrategy::ManualDuration(TICK))
        .insert_resource(Time::<Fixed>::from_duration(TICK));
    // The first update only starts the clock.
    app.update();
    app
}

#[derive(Resource, Default)]
struct Order(Vec<&'static str>);

#[test]
fn sets_run_in_order_on_the_fixed_tick() {
    let mut app = create_app();
    app.init_resource::<Order>();
    let mark = |name: &'static str| move |mut order: ResMut<Order>| order.0.push(name);
    app.add_systems(
        FixedUpdate,
        (
            mark("writeback").in_set(PointSpringsSystems::Writeback),
            mark("integrate").in_set(PointSpringsSystems::Integrate),
            mark("forces").in_set(PointSpringsSystems::Forces),
            mark("prepare").in_set(PointSpringsSystems::Prepare),
        ),
    );
    for _ in 0..3 {
        app.update();
    }
    let order = &app.world().resource::<Order>().0;
    assert!(!order.is_empty(), "the fixed tick never ran");
    assert_eq!(order.len() % 4, 0);
    for tick in order.chunks(4) {
        assert_eq!(tick, ["prepare", "forces", "integrate", "writeback"]);
    }
}

#[test]
fn surfaces_get_oriented_normals_and_bad_ones_fail_cleanly() {
    let mut app = create_app();
    let sphere = shapes::fibonacci_sphere(2000, 1.0);
    let bare = PointCloud::new(sphere.positions().to_vec(), None).unwrap();
    let good = app.world_mut().spawn(DenseSurface::new(bare)).id();
    let tiny = PointCloud::new(vec![Vec3::ZERO, Vec3::X], None).unwrap();
    let bad = app.world_mut().spawn(DenseSurface::new(tiny)).id();
    // Normals are estimated on the async compute pool: tick until both surfaces settle.
    let settled = |app: &App| {
        [good, bad].iter().all(|&e| {
            !matches!(
                app.world().get::<SurfaceStatus>(e),
                Some(SurfaceStatus::Pending | SurfaceStatus::Preparing)
            )
        })
    };
    let deadline = Instant::now() + SETTLE_TIMEOUT;
    while !settled(&app) && Instant::now() < deadline {
        app.update();
        std::thread::sleep(Duration::from_millis(1));
    }
    let world = app.world();
    assert_eq!(
        world.get::<SurfaceStatus>(good),
        Some(&SurfaceStatus::Ready {
            normals_estimated: true
        })
    );
    let cloud = &world.get::<DenseSurface>(good).unwrap().cloud;
    let outward = cloud
        .positions()
        .iter()
        .zip(cloud.normals().unwrap())
        .all(|(p, n)| p.dot(*n) > 0.9);
    assert!(outward);
    match world.get::<SurfaceStatus>(bad) {
        Some(SurfaceStatus::Failed(message)) => assert!(message.contains("at least")),
        other => panic!("expected a failure, got {other:?}"),
    }
}

#[test]
fn surfaces_with_normals_are_ready_on_the_first_tick() {
    let mut app = create_app();
    let sphere = shapes::fibonacci_sphere(500, 2.0);
    let entity = app
        .world_mut()
        .spawn(DenseSurface::new(sphere.clone()))
        .id();
    // One fixed tick runs per update with ManualDuration == timestep.
    app.update();
    assert_eq!(
        app.world().get::<SurfaceStatus>(entity),
        Some(&SurfaceStatus::Ready {
            normals_estimated: false
        })
    );
    // The cloud's own normals are kept (normalised), not re-estimated.
    let cloud = &app.world().get::<DenseSurface>(entity).unwrap().cloud;
    assert!(cloud.positions() == sphere.positions());
    let kept = cloud
        .normals()
        .unwrap()
        .iter()
        .zip(sphere.normals().unwrap())
        .all(|(a, b)| a.dot(*b) > 0.999_999);
    assert!(kept);
}
