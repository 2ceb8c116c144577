//! The headless plugin: `MinimalPlugins` + `AssetPlugin` + `PointSpringsPlugin`, with
//! `TimeUpdateStrategy::ManualDuration` so that one `update()` is one fixed tick.

use std::time::Duration;

use bevy::ecs::schedule::SingleThreadedExecutor;
use bevy::ecs::system::RunSystemOnce;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_point_springs::core::PointCloud;
use bevy_point_springs::core::cloud::io::read_cloud;
use bevy_point_springs::core::cloud::shapes;
use bevy_point_springs::core::pipeline::DenseCloud;
use bevy_point_springs::core::pipeline::SurfaceConfig;
use bevy_point_springs::core::scene::Scene;
use bevy_point_springs::core::simplify::SimplifyConfig;
use bevy_point_springs::core::solver::SpringMaterial;
use bevy_point_springs::plugin::PreparedFileOutcome;
#[cfg(feature = "render")]
use bevy_point_springs::plugin::pick::{PointerGrabs, SurfacePickingPlugin};
use bevy_point_springs::plugin::{
    Grabs, PreparationProgress, PreviousTick, SceneTimeline, SurfaceAnchors, SurfaceNetwork,
    SurfaceSleep, SurfaceSprings, SurfaceStepper, TransferTiming, WorldSurfaceError,
};
use bevy_point_springs::prelude::*;

#[path = "support/plugin_app.rs"]
mod plugin_app;
use plugin_app::*;

#[derive(Resource, Default)]
struct Order(Vec<&'static str>);

#[test]
fn sets_run_in_order_on_the_fixed_tick() {
    let mut app = create_app(&assets_dir(), TICK);
    app.init_resource::<Order>();
    let mark = |name: &'static str| move |mut order: ResMut<Order>| order.0.push(name);
    app.add_systems(
        FixedUpdate,
        (
            mark("transfer").in_set(PointSpringsSystems::Transfer),
            mark("integrate").in_set(PointSpringsSystems::Integrate),
            mark("forces").in_set(PointSpringsSystems::Forces),
        ),
    )
    .add_systems(
        PreUpdate,
        mark("prepare").in_set(PointSpringsSystems::Prepare),
    );
    for _ in 0..3 {
        app.update();
    }
    let order = &app.world().resource::<Order>().0;
    assert_eq!(order.len(), 12, "{order:?}");
    for frame in order.chunks(4) {
        assert_eq!(frame, ["prepare", "forces", "integrate", "transfer"]);
    }
}

/// Runs a shipped scene in the ECS until its last step; returns the dense surface and the
/// scene.
fn run_scene_in_ecs(name: &str) -> (DenseCloud, Scene, App, Entity) {
    run_scene_in_ecs_with(name, false)
}

/// [`run_scene_in_ecs`], with the fixed schedule on the single-threaded executor when asked.
fn run_scene_in_ecs_with(name: &str, single_threaded: bool) -> (DenseCloud, Scene, App, Entity) {
    run_scene_in_ecs_through(name, single_threaded, None)
}

/// [`run_scene_in_ecs_with`], the surface kept in a prepared file when one is given.
fn run_scene_in_ecs_through(
    name: &str,
    single_threaded: bool,
    prepared_file: Option<&std::path::Path>,
) -> (DenseCloud, Scene, App, Entity) {
    let (scene, _) = Scene::load(&assets_dir().join("scenes").join(name)).unwrap();
    let tick = Duration::from_secs_f64(f64::from(scene.dt));
    let mut app = create_app_with(&assets_dir(), tick, |app| {
        if single_threaded {
            app.edit_schedule(FixedUpdate, |schedule| {
                schedule.set_executor(SingleThreadedExecutor::new());
            });
        }
    });
    let handle = app
        .world()
        .resource::<AssetServer>()
        .load(format!("scenes/{name}"));
    // The dense surface as the last tick left it (drawn a tick behind, as by default, it
    // would be the second-last's).
    let entity = app
        .world_mut()
        .spawn((
            DeformableSurface {
                prepared_file: prepared_file.map(|p| p.to_owned()),
                ..DeformableSurface::scene(handle)
            },
            SurfaceRunSettings {
                transfer: TransferTiming::EveryTick,
                ..default()
            },
        ))
        .id();
    settle(&mut app, &[entity]);
    assert_eq!(status(&app, entity), SurfaceStatus::Ready, "{name}");
    // The tick the plugin steps by is the scene's step, to the bit.
    let fixed = app
        .world()
        .resource::<Time<Fixed>>()
        .timestep()
        .as_secs_f32();
    assert_eq!(fixed.to_bits(), scene.dt.to_bits());
    let steps = |app: &App| {
        app.world()
            .get::<SurfaceStepper>(entity)
            .unwrap()
            .diagnostics()
            .steps
    };
    while steps(&app) < scene.steps as u64 {
        app.update();
    }
    assert_eq!(steps(&app), scene.steps as u64, "one step per tick");
    assert!(app.world().get::<SceneTimeline>(entity).unwrap().finished());
    let dense = DenseCloud::clone(app.world().get::<DenseSurface>(entity).unwrap());
    (dense, scene, app, entity)
}

fn bits(v: &[Vec3]) -> Vec<[u32; 3]> {
    v.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
}

/// The ECS run of a scene gives, bit for bit, the dense surface of the core's headless run
/// (the one `point-springs run` writes); returns the largest displacement at the end.
fn ecs_matches_the_headless_run(name: &str) -> f32 {
    let (dense, scene, _, _) = run_scene_in_ecs(name);
    let mut run = scene.prepare(&assets_dir().join("scenes")).unwrap();
    run.run(&mut |_| {}).unwrap();
    let deformed = run.deformed().unwrap();
    assert_eq!(dense.len(), deformed.cloud.len(), "{name}: resampled alike");
    assert!(
        bits(dense.positions()) == bits(deformed.cloud.positions()),
        "{name}: positions differ"
    );
    assert!(
        bits(dense.normals()) == bits(deformed.cloud.normals().unwrap()),
        "{name}: normals differ"
    );
    dense.max_displacement()
}

#[test]
fn sphere_poke_runs_bit_for_bit_like_the_headless_run() {
    // Poked, let go, round again.
    let left = ecs_matches_the_headless_run("sphere_poke.ron");
    assert!(left < 0.05, "dent left {left}");
}

#[test]
fn the_prefactored_solver_runs_bit_for_bit_like_the_headless_run() {
    // The same poke with implicit Euler solved by local/global iterations over one
    // factorised matrix: the factor and its solves give the same bits in the ECS.
    let left = ecs_matches_the_headless_run("sphere_poke_local_global.ron");
    assert!(left < 0.05, "dent left {left}");
}

#[test]
fn hat_runs_bit_for_bit_like_the_headless_run() {
    let crown = ecs_matches_the_headless_run("hat.ron");
    assert!(crown > 0.7, "crown {crown}");
}

/// Bevy's multi-threaded and single-threaded executors give the same bits (the systems of
/// one surface are chained; surfaces run side by side but share nothing).
#[test]
fn both_executors_give_the_same_bits() {
    let (multi, ..) = run_scene_in_ecs_with("hat.ron", false);
    let (single, ..) = run_scene_in_ecs_with("hat.ron", true);
    assert_eq!(multi.len(), single.len());
    assert!(bits(multi.positions()) == bits(single.positions()));
    assert!(bits(multi.normals()) == bits(single.normals()));
}

/// The same, against the PLY file the command-line tool writes.
#[cfg(feature = "cli")]
#[test]
fn hat_matches_the_file_point_springs_run_writes() {
    let (dense, ..) = run_scene_in_ecs("hat.ron");
    let out = std::env::temp_dir().join(format!("bps-plugin-hat-{}.ply", std::process::id()));
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_point-springs"))
        .args(["run", "assets/scenes/hat.ron", "-o"])
        .arg(&out)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    assert!(status.status.success(), "{status:?}");
    let written = read_cloud(&out, None).unwrap();
    assert!(bits(dense.positions()) == bits(written.positions()));
    assert!(bits(dense.normals()) == bits(written.normals().unwrap()));
}

#[test]
fn a_game_system_in_the_force_set_moves_the_surface() {
    let mut app = create_app(&assets_dir(), TICK);
    app.add_systems(FixedUpdate, wind.in_set(PointSpringsSystems::Forces));
    let blown = app.world_mut().spawn((floating(1500, 150), Windy)).id();
    let still = app.world_mut().spawn(floating(1500, 150)).id();
    settle(&mut app, &[blown, still]);
    let start = |e| centroid(app.world().get::<SimulationPoints>(e).unwrap());
    let (b0, s0) = (start(blown), start(still));
    let still_revision = app.world().get::<DenseSurface>(still).unwrap().revision();
    for _ in 0..30 {
        app.update();
    }
    let now = |e| centroid(app.world().get::<SimulationPoints>(e).unwrap());
    let moved = now(blown) - b0;
    assert!(
        moved.x > 1e-3 && moved.y.abs() < 1e-4,
        "blown surface moved {moved}"
    );
    assert_eq!(now(still), s0, "the surface without wind stays put");
    // Nothing moved it, so its dense surface was not transferred again.
    let revision = app.world().get::<DenseSurface>(still).unwrap().revision();
    assert_eq!(revision, still_revision);
    // The game's forces are cleared after each tick.
    let forces = app.world().get::<SurfaceForces>(blown).unwrap();
    assert_eq!(forces.get(0), Vec3::ZERO);
    // The dense surface followed the wind.
    let dense = app.world().get::<DenseSurface>(blown).unwrap();
    // (Against the motion since rest: the blown surface may be ready, and blown, a few
    // updates before the other one.)
    let shift = dense.positions()[0] - dense.transfer().rest_positions()[0];
    let network = app.world().get::<SurfaceNetwork>(blown).unwrap().shared();
    let rest = network.positions.iter().sum::<Vec3>() / network.len() as f32;
    let since_rest = now(blown) - rest;
    assert!(
        (shift.x - since_rest.x).abs() < 0.2 * since_rest.x,
        "{shift} vs {since_rest}"
    );
}

#[test]
fn ten_surfaces_run_at_once() {
    let mut app = create_app(&assets_dir(), TICK);
    let surfaces: Vec<Entity> = (0..10)
        .map(|i| {
            let config = SurfaceConfig {
                simplify: SimplifyConfig::target(100 + 10 * i),
                ..default()
            };
            let cloud = shapes::fibonacci_sphere(800 + 50 * i, 1.0);
            app.world_mut()
                .spawn(DeformableSurface::cloud(cloud, config))
                .id()
        })
        .collect();
    settle(&mut app, &surfaces);
    let starts: Vec<Vec3> = surfaces
        .iter()
        .map(|&e| centroid(app.world().get::<SimulationPoints>(e).unwrap()))
        .collect();
    for _ in 0..20 {
        app.update();
    }
    for (i, (&e, start)) in surfaces.iter().zip(starts).enumerate() {
        assert_eq!(status(&app, e), SurfaceStatus::Ready, "surface {i}");
        let points = app.world().get::<SimulationPoints>(e).unwrap();
        assert_eq!(points.len(), 100 + 10 * i);
        // Falling under gravity, all of them.
        let fall = start.y - centroid(points).y;
        assert!(fall > 0.01 && fall.is_finite(), "surface {i} fell {fall}");
    }
}

#[test]
fn dense_points_by_pins_a_game_sets_hold_exactly() {
    let mut app = create_app(&assets_dir(), TICK);
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(150),
        ..default()
    };
    let sphere = DeformableSurface::cloud(shapes::fibonacci_sphere(2000, 1.0), config);
    let e = app.world_mut().spawn(sphere).id();
    settle(&mut app, &[e]);
    // A few ticks of falling first: the pins are set on a moving surface, where it is.
    for _ in 0..5 {
        app.update();
    }
    let rest = app
        .world()
        .get::<SurfaceNetwork>(e)
        .unwrap()
        .positions
        .clone();
    hold(&mut app, e, |p| p.y > 0.7);
    app.update();
    let held_at = app
        .world()
        .get::<DenseSurface>(e)
        .unwrap()
        .positions()
        .to_vec();
    for _ in 0..60 {
        app.update();
    }
    let dense = app.world().get::<DenseSurface>(e).unwrap();
    let held = dense.transfer().report().held;
    assert!(held > 0);
    // The dense points by the pins (nearest a pinned point at rest) stay where the pins
    // caught them, bit for bit; the rest hangs below them.
    let nearest = |p: Vec3| {
        (0..rest.len())
            .min_by(|&a, &b| rest[a].distance(p).total_cmp(&rest[b].distance(p)))
            .unwrap()
    };
    let (mut counted, mut sag) = (0, 0.0f32);
    for (i, (&now, &then)) in dense.positions().iter().zip(&held_at).enumerate() {
        if rest[nearest(dense.transfer().rest_positions()[i])].y > 0.7 {
            counted += 1;
            assert_eq!(now, then, "dense point {i} by the pins moved");
        } else {
            sag = sag.max(then.y - now.y);
        }
    }
    // (A few more are held: those almost as near a pin as a free point.)
    assert!(counted > 0 && counted <= held, "{counted} of {held}");
    assert!(sag > 1e-3, "the free part sagged {sag}");
}

#[test]
fn despawning_while_preparing_or_simulating_is_clean() {
    let mut app = create_app(&assets_dir(), TICK);
    // Big enough that its preparation is still under way a few frames later.
    let big = app.world_mut().spawn(floating(60_000, 2000)).id();
    let small = app.world_mut().spawn(floating(1000, 100)).id();
    app.update();
    app.update();
    assert_eq!(status(&app, big), SurfaceStatus::Preparing);
    let progress = *app.world().get::<PreparationProgress>(big).unwrap();
    assert!((0.0..=1.0).contains(&progress.fraction), "{progress:?}");
    app.world_mut().despawn(big);
    settle(&mut app, &[small]);
    assert_eq!(status(&app, small), SurfaceStatus::Ready);
    // While simulating.
    app.update();
    app.world_mut().despawn(small);
    for _ in 0..5 {
        app.update();
    }
    // A surface spawned afterwards is prepared and runs as usual.
    let later = app.world_mut().spawn(floating(1000, 100)).id();
    settle(&mut app, &[later]);
    assert_eq!(status(&app, later), SurfaceStatus::Ready);
}

/// The lifecycle events an app saw, in order.
#[derive(Resource, Default)]
struct Lifecycle {
    ready: Vec<SurfaceReady>,
    failed: Vec<SurfaceFailed>,
}

fn watch_lifecycle(app: &mut App) {
    app.init_resource::<Lifecycle>()
        .add_observer(|ready: On<SurfaceReady>, mut seen: ResMut<Lifecycle>| {
            seen.ready.push(ready.event().clone());
        })
        .add_observer(|failed: On<SurfaceFailed>, mut seen: ResMut<Lifecycle>| {
            seen.failed.push(failed.event().clone());
        });
}

#[test]
fn bad_inputs_fail_their_surface_only() {
    let dir = std::env::temp_dir().join(format!("bps-plugin-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let write = |name: &str, text: &str| std::fs::write(dir.join(name), text).unwrap();
    write(
        "missing.ron",
        r#"(cloud: "nowhere.ply", simplify: (target: Some(50)), dt: 0.01, steps: 10)"#,
    );
    write("nan.xyz", "0 0 0\n1 0 0\nnan 1 0\n0 1 1\n");
    write("broken.ron", "(cloud: \"nan.xyz\",\n  steps: ten)");
    let mut app = create_app(&dir, TICK);
    let server = app.world().resource::<AssetServer>().clone();
    let missing = app
        .world_mut()
        .spawn(DeformableSurface::scene(server.load("missing.ron")))
        .id();
    let broken = app
        .world_mut()
        .spawn(DeformableSurface::scene(server.load("broken.ron")))
        .id();
    let nan = app
        .world_mut()
        .spawn(DeformableSurface::cloud_asset(
            server.load("nan.xyz"),
            SurfaceConfig::default(),
        ))
        .id();
    let two = PointCloud::new(vec![Vec3::ZERO, Vec3::X], None).unwrap();
    let two = app
        .world_mut()
        .spawn(DeformableSurface::cloud(two, SurfaceConfig::default()))
        .id();
    // Collinear points: no tangent plane, nothing §3 can simplify.
    let line: Vec<Vec3> = (0..200).map(|i| Vec3::X * i as f32 * 0.01).collect();
    let normals = vec![Vec3::Y; line.len()];
    let line = PointCloud::new(line, Some(normals)).unwrap();
    let line = app
        .world_mut()
        .spawn(DeformableSurface::cloud(line, SurfaceConfig::default()))
        .id();
    // A scan in georeferenced coordinates: f32 cannot resolve its detail out there.
    let far = shapes::fibonacci_sphere(500, 1.0);
    let far_points: Vec<Vec3> = far.positions().iter().map(|p| *p + Vec3::X * 1e6).collect();
    let far = PointCloud::new(far_points, far.normals().map(<[Vec3]>::to_vec)).unwrap();
    let far = app
        .world_mut()
        .spawn(DeformableSurface::cloud(far, SurfaceConfig::default()))
        .id();
    let good = app.world_mut().spawn(floating(1000, 100)).id();
    watch_lifecycle(&mut app);
    let all = [missing, broken, nan, two, line, far, good];
    settle(&mut app, &all);
    let expect = [
        (missing, "nowhere.ply"),
        (broken, "broken.ron"),
        (nan, "not finite"),
        (two, "at least"),
        (line, "surface"),
    ];
    for (entity, needle) in expect {
        match status(&app, entity) {
            SurfaceStatus::Failed(error) => {
                let message = error.to_string();
                assert!(message.contains(needle), "{needle}: {message}");
            }
            other => panic!("{needle}: expected a failure, got {other:?}"),
        }
    }
    // Each failure was sent once, as an event carrying the status's typed error.
    let seen = app.world().resource::<Lifecycle>();
    for entity in [missing, broken, nan, two, line, far] {
        let events: Vec<_> = seen.failed.iter().filter(|f| f.entity == entity).collect();
        assert_eq!(events.len(), 1, "{entity}: {events:?}");
        assert!(!events[0].still_running);
        assert_eq!(
            SurfaceStatus::Failed(events[0].error.clone()),
            status(&app, entity)
        );
        let file = matches!(events[0].error, SurfaceError::Load(_));
        assert_eq!(file, [missing, broken, nan].contains(&entity), "{entity}");
    }
    let far_error = &seen.failed.iter().find(|f| f.entity == far).unwrap().error;
    assert!(
        matches!(
            far_error,
            SurfaceError::Prepare(PrepareError::Precision { magnitude, .. }) if *magnitude > 9e5
        ),
        "{far_error:?}"
    );
    for entity in [two, line] {
        let error = &seen
            .failed
            .iter()
            .find(|f| f.entity == entity)
            .unwrap()
            .error;
        assert!(matches!(error, SurfaceError::Prepare(_)), "{error:?}");
    }
    assert_eq!(
        seen.ready,
        [SurfaceReady {
            entity: good,
            again: false
        }]
    );
    // The good one runs, and the app keeps going.
    assert_eq!(status(&app, good), SurfaceStatus::Ready);
    for _ in 0..5 {
        app.update();
    }
    assert_eq!(status(&app, good), SurfaceStatus::Ready);
}

#[test]
fn an_interpolated_surface_is_drawn_between_its_last_two_ticks() {
    // One and a half ticks per update: the frames fall half-way between ticks and on them.
    let mut app = create_app(&assets_dir(), TICK);
    app.insert_resource(TimeUpdateStrategy::ManualDuration(TICK * 3 / 2));
    // Drawn between ticks by default.
    let surface = app.world_mut().spawn((floating(1200, 120), Windy)).id();
    assert_eq!(
        app.world()
            .get::<SurfaceRunSettings>(surface)
            .unwrap()
            .transfer,
        TransferTiming::Interpolated
    );
    app.add_systems(FixedUpdate, wind.in_set(PointSpringsSystems::Forces));
    settle(&mut app, &[surface]);
    let mut fractions = Vec::new();
    for _ in 0..8 {
        app.update();
        let along = app.world().resource::<Time<Fixed>>().overstep_fraction();
        fractions.push(along);
        let world = app.world();
        let previous = world
            .get::<PreviousTick>(surface)
            .unwrap()
            .positions()
            .to_vec();
        let points = world.get::<SimulationPoints>(surface).unwrap();
        let dense = world.get::<DenseSurface>(surface).unwrap();
        assert_eq!(previous.len(), points.len());
        // The dense surface at each of the two ticks, by the same transfer.
        let at = |positions: &[Vec3]| -> Vec<Vec3> {
            let mut cloud = DenseCloud::clone(dense);
            let state = bevy_point_springs::core::solver::PointState::new(positions).unwrap();
            cloud.follow(&state).unwrap();
            cloud.positions().to_vec()
        };
        let (from, to) = (at(&previous), at(&points.positions()));
        let moved = from
            .iter()
            .zip(&to)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0_f32, f32::max);
        assert!(
            moved > 1e-5,
            "the wind moves the surface each tick: {moved}"
        );
        // Drawn: the blend of the two ticks' dense surfaces, to f32 rounding.
        let worst = dense
            .positions()
            .iter()
            .zip(from.iter().zip(&to))
            .map(|(drawn, (a, b))| drawn.distance(a.lerp(*b, along)))
            .fold(0.0_f32, f32::max);
        assert!(worst < 1e-5, "{worst} off the blend at {along}");
    }
    // Half-way between ticks and on them, in turn.
    assert!(
        fractions.iter().any(|&f| (f - 0.5).abs() < 1e-3),
        "{fractions:?}"
    );
    assert!(fractions.iter().any(|&f| f < 1e-3), "{fractions:?}");
}

#[test]
fn transfer_once_per_frame_when_asked() {
    // Three ticks per update.
    let mut app = create_app(&assets_dir(), TICK);
    app.insert_resource(TimeUpdateStrategy::ManualDuration(TICK * 3));
    let every_tick = app
        .world_mut()
        .spawn((
            floating(1200, 120),
            SurfaceRunSettings {
                transfer: TransferTiming::EveryTick,
                ..default()
            },
        ))
        .id();
    let per_frame = app
        .world_mut()
        .spawn((
            floating(1200, 120),
            SurfaceRunSettings {
                transfer: TransferTiming::PerFrame,
                ..default()
            },
        ))
        .id();
    app.add_systems(FixedUpdate, wind.in_set(PointSpringsSystems::Forces));
    app.world_mut().entity_mut(every_tick).insert(Windy);
    app.world_mut().entity_mut(per_frame).insert(Windy);
    settle(&mut app, &[every_tick, per_frame]);
    let revision = |app: &App, e| app.world().get::<DenseSurface>(e).unwrap().revision();
    let (a0, b0) = (revision(&app, every_tick), revision(&app, per_frame));
    for _ in 0..4 {
        app.update();
    }
    assert_eq!(
        revision(&app, every_tick) - a0,
        12,
        "three transfers per update"
    );
    assert_eq!(revision(&app, per_frame) - b0, 4, "one transfer per update");
    // After the frame, both dense surfaces follow their simulation's latest state exactly:
    // asked to follow it again, there is nothing to do.
    for e in [every_tick, per_frame] {
        let mut dense = DenseCloud::clone(app.world().get::<DenseSurface>(e).unwrap());
        let points = app.world().get::<SimulationPoints>(e).unwrap();
        assert!(!dense.follow(points).unwrap());
    }
}

#[test]
fn a_material_changed_through_reflection_reaches_the_springs() {
    use bevy::reflect::GetPath;
    let mut app = create_app(&assets_dir(), TICK);
    let e = app.world_mut().spawn(floating(1000, 100)).id();
    settle(&mut app, &[e]);
    let stretch_count = app.world().get::<SurfaceNetwork>(e).unwrap().stretch.len();
    // An inspector edits the component by path, as reflection sees it.
    {
        let mut material = app.world_mut().get_mut::<SurfaceMaterial>(e).unwrap();
        *material.path_mut::<f32>(".0.stretch_stiffness").unwrap() = 500.0;
    }
    app.update();
    let springs = app.world().get::<SurfaceSprings>(e).unwrap();
    let stiffness: Vec<(usize, f32)> = springs.iter().map(|(i, s)| (i, s.stiffness)).collect();
    let bend = SpringMaterial::default().bend_stiffness;
    assert!(stiffness.iter().all(|&(i, k)| if i < stretch_count {
        k == 500.0
    } else {
        k == bend
    }));
    assert_eq!(status(&app, e), SurfaceStatus::Ready);
}

#[test]
fn a_grab_dents_the_sphere_and_it_recovers_after_release() {
    let mut app = create_app(&assets_dir(), TICK);
    let sphere = app.world_mut().spawn(floating(1500, 150)).id();
    settle(&mut app, &[sphere]);
    let (top, top_rest) = nearest_point(&app, sphere, Vec3::Y);
    let (bottom, bottom_rest) = nearest_point(&app, sphere, -Vec3::Y);
    let y = |app: &App, i: usize| {
        app.world()
            .get::<SimulationPoints>(sphere)
            .unwrap()
            .position(i)
            .y
    };
    // One grab holds the bottom where it is; another presses the top in by 0.3.
    app.world_mut().write_message(GrabMessage::Start {
        key: 1,
        surface: sphere,
        at: bottom_rest,
    });
    app.world_mut().write_message(GrabMessage::Start {
        key: 2,
        surface: sphere,
        at: top_rest,
    });
    app.update();
    let grabs = app.world().resource::<Grabs>();
    assert_eq!(grabs.len(), 2);
    let (held_by, held) = grabs.get(2).unwrap();
    assert_eq!(held_by, sphere);
    // The default radius (1.5 mean springs) holds a small patch, not one point.
    assert!((2..30).contains(&held), "{held} points held");
    assert_eq!(
        app.world().get::<SurfaceAnchors>(sphere).unwrap().len(),
        grabs.get(1).unwrap().1 + held
    );
    app.world_mut().write_message(GrabMessage::Move {
        key: 2,
        target: top_rest - Vec3::Y * 0.3,
    });
    for _ in 0..120 {
        app.update();
    }
    let dent = top_rest.y - y(&app, top);
    assert!(dent > 0.15, "the top went in by {dent}");
    assert!(
        (y(&app, bottom) - bottom_rest.y).abs() < 0.05,
        "the bottom is held"
    );
    // The dense surface followed.
    let dense = app.world().get::<DenseSurface>(sphere).unwrap();
    let top_dense = dense
        .positions()
        .iter()
        .map(|p| p.y)
        .fold(f32::MIN, f32::max);
    assert!(top_dense < 1.0 - 0.1, "dense top at {top_dense}");

    // Release the top: its anchors go, and the springs push the dent out again.
    app.world_mut().write_message(GrabMessage::End { key: 2 });
    app.update();
    assert_eq!(app.world().resource::<Grabs>().len(), 1);
    assert_eq!(
        app.world().get::<SurfaceAnchors>(sphere).unwrap().len(),
        app.world().resource::<Grabs>().get(1).unwrap().1
    );
    for _ in 0..600 {
        app.update();
    }
    let left = top_rest.y - y(&app, top);
    println!("grab: {held} points held, dent {dent:.3}, {left:.4} left after 600 ticks");
    assert!(left.abs() < 0.2 * dent, "{left} of a {dent} dent is left");
    // Messages for nothing are ignored: a drag after release, an entity that is no surface.
    let stranger = app.world_mut().spawn_empty().id();
    app.world_mut().write_message(GrabMessage::Move {
        key: 2,
        target: Vec3::ZERO,
    });
    app.world_mut().write_message(GrabMessage::Start {
        key: 3,
        surface: stranger,
        at: Vec3::ZERO,
    });
    app.world_mut().write_message(GrabMessage::Start {
        key: 4,
        surface: sphere,
        at: Vec3::NAN,
    });
    app.update();
    assert_eq!(app.world().resource::<Grabs>().len(), 1);
    assert!(status(&app, sphere).is_ready());
}

/// The pointer path (feature `render`): the surfel picking backend answers a ray with the
/// surface under it; a press on the surface starts a grab, the pointer's ray drags it on the
/// plane facing the camera, and a release anywhere ends it. Bevy builds rays only for a
/// window's cursor, so the test fills the `RayMap` itself and writes the `Pointer<Press>` and
/// `PointerInput` messages that Bevy's picking would (it does not run Bevy's hover step).
#[cfg(feature = "render")]
#[test]
fn a_pointer_press_drag_and_release_grab_the_surface() {
    use bevy::ecs::message::Messages;
    use bevy::picking::backend::PointerHits;
    use bevy::picking::pointer::PointerId;

    let mut app = create_app_with(&assets_dir(), TICK, |app| {
        app.add_plugins(SurfacePickingPlugin);
    });
    let sphere = app
        .world_mut()
        .spawn((floating(1500, 150), GlobalTransform::default()))
        .id();
    settle(&mut app, &[sphere]);
    // Hold the bottom still, from code.
    let (_, bottom) = nearest_point(&app, sphere, -Vec3::Y);
    app.world_mut().write_message(GrabMessage::Start {
        key: 99,
        surface: sphere,
        at: bottom,
    });
    // A camera above, looking down; the mouse's ray through the top of the sphere.
    let eye = Vec3::Y * 5.0;
    let camera = app
        .world_mut()
        .spawn(GlobalTransform::from(
            Transform::from_translation(eye).looking_at(Vec3::ZERO, Vec3::Z),
        ))
        .id();
    aim_mouse(&mut app, camera, eye);
    app.update();
    let hits = app.world().resource::<Messages<PointerHits>>();
    let hits: Vec<PointerHits> = hits.iter_current_update_messages().cloned().collect();
    assert_eq!(hits.len(), 1, "one ray, one report");
    let (entity, hit) = hits[0].picks[0].clone();
    assert_eq!(entity, sphere);
    let at = hit.position.unwrap();
    assert!(
        (at.y - 1.0).abs() < 0.05 && at.x.abs() < 1e-4,
        "hit at {at}"
    );
    assert!((hit.depth - (5.0 - at.y)).abs() < 1e-4);
    assert!(hit.normal.unwrap().y > 0.9, "facing the camera");
    // A ray that misses the sphere reports nothing.
    aim_mouse(&mut app, camera, eye + Vec3::X * 1.5);
    app.update();
    let missed = app.world().resource::<Messages<PointerHits>>();
    assert_eq!(missed.iter_current_update_messages().count(), 0);

    // Press on the top: a grab starts there.
    aim_mouse(&mut app, camera, eye);
    press_mouse(&mut app, &hit, sphere);
    app.update();
    assert!(
        app.world()
            .resource::<PointerGrabs>()
            .holds(PointerId::Mouse)
    );
    let (held_by, held) = app.world().resource::<Grabs>().get(0).unwrap();
    assert_eq!(held_by, sphere);
    assert!(held >= 2, "{held}");
    // Drag: the pointer's ray moves 0.3 along x; the target follows it on the plane y = hit.
    aim_mouse(&mut app, camera, eye + Vec3::X * 0.3);
    for _ in 0..120 {
        app.update();
    }
    let (top, _) = nearest_point(&app, sphere, Vec3::new(0.3, 1.0, 0.0));
    let moved = app
        .world()
        .get::<SimulationPoints>(sphere)
        .unwrap()
        .position(top);
    println!(
        "pointer: hit {at}, depth {}, {held} points held, top dragged to {moved}",
        hit.depth
    );
    assert!(moved.x > 0.2, "the top followed the drag to {moved}");
    // Release anywhere: the grab ends; the bottom's grab from code stays.
    release_mouse(&mut app);
    app.update();
    assert!(
        !app.world()
            .resource::<PointerGrabs>()
            .holds(PointerId::Mouse)
    );
    let grabs = app.world().resource::<Grabs>();
    assert_eq!((grabs.len(), grabs.get(0)), (1, None));
}

/// The prepared file a surface went through.
fn file_outcome(app: &App, e: Entity) -> PreparedFileOutcome {
    app.world().get::<PreparedFileOutcome>(e).cloned().unwrap()
}

#[test]
fn a_surface_is_read_from_its_prepared_file_and_runs_as_if_prepared() {
    use bevy_point_springs::core::pipeline::prepared::PreparedFileError;
    let dir = std::env::temp_dir().join(format!("bps-prepared-plugin-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("kitten.psprep");
    let kitten = read_cloud(&assets_dir().join("kitten.off"), None).unwrap();
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(300),
        ..SurfaceConfig::default()
    };
    // A fresh app: the kitten falls for half a second; the state as bits.
    let run = |cloud: &bevy_point_springs::core::PointCloud| {
        let mut app = create_app(&assets_dir(), TICK);
        let surface = DeformableSurface::cloud(cloud.clone(), config).with_prepared_file(&file);
        let e = app.world_mut().spawn(surface).id();
        settle(&mut app, &[e]);
        assert_eq!(status(&app, e), SurfaceStatus::Ready);
        for _ in 0..30 {
            app.update();
        }
        let world = app.world();
        let points = bits(&world.get::<SimulationPoints>(e).unwrap().positions());
        let dense = bits(world.get::<DenseSurface>(e).unwrap().positions());
        (file_outcome(&app, e), points, dense)
    };
    // No file yet: prepared, and the file written.
    let (first, points, dense) = run(&kitten);
    assert!(
        matches!(first, PreparedFileOutcome::Written { refused: None }),
        "{first:?}"
    );
    // The file there: read, and the run the same to the bit.
    let (second, points_again, dense_again) = run(&kitten);
    assert!(matches!(second, PreparedFileOutcome::Read), "{second:?}");
    assert!(points_again == points && dense_again == dense);
    // Another cloud (one coordinate one float step off): refused, prepared, written anew.
    let (mut positions, normals) = kitten.clone().into_parts();
    positions[0].y = f32::from_bits(positions[0].y.to_bits() + 1);
    let nudged = bevy_point_springs::core::PointCloud::new(positions, normals).unwrap();
    let (third, ..) = run(&nudged);
    match third {
        PreparedFileOutcome::Written {
            refused: Some(why), ..
        } => assert!(
            matches!(*why, PreparedFileError::OtherSource { .. }),
            "{why}"
        ),
        other => panic!("expected a refusal, got {other:?}"),
    }
    // A damaged file: refused, and the surface prepared all the same.
    std::fs::write(&file, b"PSPREP\x00\x01 but nothing else").unwrap();
    let (fourth, points_damaged, _) = run(&kitten);
    match fourth {
        PreparedFileOutcome::Written {
            refused: Some(why), ..
        } => assert!(matches!(*why, PreparedFileError::Damaged(_)), "{why}"),
        other => panic!("expected a refusal, got {other:?}"),
    }
    assert!(points_damaged == points);
    // A file that cannot be written: the surface runs, and the outcome says why.
    {
        let mut app = create_app(&assets_dir(), TICK);
        let surface = DeformableSurface::cloud(kitten.clone(), config)
            .with_prepared_file(dir.join("no such folder").join("k.psprep"));
        let e = app.world_mut().spawn(surface).id();
        settle(&mut app, &[e]);
        assert_eq!(status(&app, e), SurfaceStatus::Ready);
        let outcome = file_outcome(&app, e);
        assert!(
            matches!(
                outcome,
                PreparedFileOutcome::NotWritten { refused: None, .. }
            ),
            "{outcome:?}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_scene_read_from_its_prepared_file_runs_bit_for_bit_as_prepared() {
    let dir = std::env::temp_dir().join(format!("bps-prepared-scene-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("hat.psprep");
    let (prepared, ..) = run_scene_in_ecs("hat.ron");
    let (written, _, app, e) = run_scene_in_ecs_through("hat.ron", false, Some(&file));
    assert!(matches!(
        file_outcome(&app, e),
        PreparedFileOutcome::Written { refused: None }
    ));
    let (read, _, app, e) = run_scene_in_ecs_through("hat.ron", false, Some(&file));
    assert!(matches!(file_outcome(&app, e), PreparedFileOutcome::Read));
    for dense in [&written, &read] {
        assert!(bits(dense.positions()) == bits(prepared.positions()));
        assert!(bits(dense.normals()) == bits(prepared.normals()));
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Issue 37: `Changed<DenseSurface>` means the drawn surface changed: it does not fire on
/// the ticks and frames of a surface at rest, and does on those of one being pulled.
#[test]
fn changed_dense_surface_fires_only_when_the_drawn_surface_moves() {
    #[derive(Resource, Default)]
    struct Changes(usize);
    let mut app = create_app(&assets_dir(), TICK);
    app.init_resource::<Changes>().add_systems(
        Last,
        |changed: Query<(), Changed<DenseSurface>>, mut changes: ResMut<Changes>| {
            changes.0 += changed.iter().count();
        },
    );
    let sphere = app.world_mut().spawn(floating(1000, 100)).id();
    settle(&mut app, &[sphere]);
    // Asleep: nothing moves any more.
    let sleep_ticks =
        (bevy_point_springs::plugin::DEFAULT_SLEEP_AFTER / TICK.as_secs_f32()).ceil() as usize;
    for _ in 0..sleep_ticks + 2 {
        app.update();
    }
    assert!(app.world().get::<SurfaceSleep>(sphere).unwrap().asleep);
    assert!(
        app.world().resource::<Changes>().0 > 0,
        "never seen changed"
    );
    app.world_mut().resource_mut::<Changes>().0 = 0;
    let revision = app.world().get::<DenseSurface>(sphere).unwrap().revision();
    for _ in 0..30 {
        app.update();
    }
    assert_eq!(app.world().resource::<Changes>().0, 0);
    assert_eq!(
        app.world().get::<DenseSurface>(sphere).unwrap().revision(),
        revision
    );
    // Pulled: it changes as it moves.
    let (_, top) = nearest_point(&app, sphere, Vec3::Y);
    app.world_mut().write_message(GrabMessage::Start {
        key: 1,
        surface: sphere,
        at: top,
    });
    app.update();
    app.world_mut().write_message(GrabMessage::Move {
        key: 1,
        target: top + Vec3::Y * 0.2,
    });
    for _ in 0..10 {
        app.update();
    }
    let changes = app.world().resource::<Changes>().0;
    assert!(changes >= 9, "{changes} changes in 11 updates");
    assert!(app.world().get::<DenseSurface>(sphere).unwrap().revision() > revision);
}

/// Issue 37: `WorldSurfaces` speaks world coordinates. A world force on a surface turned a
/// quarter turn about Z and scaled twice moves it along the world's X (its own −Y), and
/// the points and dense surface it reads are the local ones placed by the transform.
#[test]
fn world_space_pushes_and_reads_follow_the_surface_transform() {
    #[derive(Resource)]
    struct Pushed(Entity);
    let mut app = create_app(&assets_dir(), TICK);
    // Headless apps have no transform propagation: the global transform is set as well.
    let placed = Transform::from_xyz(5.0, 0.0, 0.0)
        .with_rotation(Quat::from_rotation_z(std::f32::consts::FRAC_PI_2))
        .with_scale(Vec3::splat(2.0));
    let sphere = app
        .world_mut()
        .spawn((floating(1000, 100), placed, GlobalTransform::from(placed)))
        .id();
    settle(&mut app, &[sphere]);
    let world_points = |app: &mut App| {
        app.world_mut()
            .run_system_once(move |surfaces: WorldSurfaces| surfaces.points(sphere))
            .unwrap()
            .unwrap()
    };
    let mean = |points: &[Vec3]| points.iter().sum::<Vec3>() / points.len() as f32;
    let local = app
        .world()
        .get::<SimulationPoints>(sphere)
        .unwrap()
        .0
        .clone();
    let before = world_points(&mut app);
    for (w, l) in before.iter().zip(local.iter_positions()) {
        assert!(w.distance(placed.transform_point(l)) < 1e-5);
    }
    assert!(mean(&before).distance(Vec3::new(5.0, 0.0, 0.0)) < 0.05);
    // Dense positions and normals: placed, and the normals still outward and unit.
    let (dense, normals) = app
        .world_mut()
        .run_system_once(move |surfaces: WorldSurfaces| surfaces.dense(sphere))
        .unwrap()
        .unwrap();
    let centre = mean(&dense);
    for (p, n) in dense.iter().zip(&normals) {
        assert!((n.length() - 1.0).abs() < 1e-4);
        assert!(n.dot(*p - centre) > 0.0, "a normal turned inward");
    }
    app.insert_resource(Pushed(sphere)).add_systems(
        FixedUpdate,
        (|mut surfaces: WorldSurfaces, pushed: Res<Pushed>| {
            surfaces.push_all(pushed.0, Vec3::X * 0.5).unwrap();
        })
        .in_set(PointSpringsSystems::Forces),
    );
    for _ in 0..30 {
        app.update();
    }
    let moved = mean(&world_points(&mut app)) - mean(&before);
    assert!(moved.x > 0.01, "{moved}");
    assert!(
        moved.y.abs() < 0.01 * moved.x && moved.z.abs() < 0.01 * moved.x,
        "{moved}"
    );
    // Bad input is refused, not applied.
    let stranger = app.world_mut().spawn_empty().id();
    let refused = app
        .world_mut()
        .run_system_once(move |mut surfaces: WorldSurfaces| {
            (
                surfaces.push_all(stranger, Vec3::X),
                surfaces.push_near(sphere, Vec3::ZERO, f32::NAN, Vec3::X),
            )
        })
        .unwrap();
    assert_eq!(refused.0, Err(WorldSurfaceError::NotASurface(stranger)));
    assert!(matches!(
        refused.1,
        Err(WorldSurfaceError::NotFinite { .. })
    ));
}

/// Issue 37: one pin that stops the point. A point pinned while its surface falls stays
/// where it was pinned, still; freed, it falls again. Bad indices are refused.
#[test]
fn a_pinned_point_stays_put_and_falls_again_when_freed() {
    let mut app = create_app(&assets_dir(), TICK);
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(100),
        ..default()
    };
    let sphere = app
        .world_mut()
        .spawn(DeformableSurface::cloud(
            shapes::fibonacci_sphere(1000, 1.0),
            config,
        ))
        .id();
    settle(&mut app, &[sphere]);
    for _ in 0..10 {
        app.update();
    }
    let point = |app: &App, i: usize| {
        let points = app.world().get::<SimulationPoints>(sphere).unwrap();
        (points.position(i), points.velocities()[i])
    };
    let (top, _) = nearest_point(&app, sphere, Vec3::Y * 2.0);
    let (_, falling) = point(&app, top);
    assert!(falling.y < -0.1, "not falling: {falling}");
    app.world_mut()
        .run_system_once(move |mut pins: SurfacePins| pins.pin(sphere, top))
        .unwrap()
        .unwrap();
    let (held, still) = point(&app, top);
    assert_eq!(still, Vec3::ZERO);
    for _ in 0..20 {
        app.update();
        assert_eq!(point(&app, top), (held, Vec3::ZERO));
    }
    app.world_mut()
        .run_system_once(move |mut pins: SurfacePins| {
            assert_eq!(pins.is_pinned(sphere, top), Some(true));
            pins.free(sphere, top)
        })
        .unwrap()
        .unwrap();
    for _ in 0..10 {
        app.update();
    }
    assert!(point(&app, top).0.y < held.y - 0.01, "did not fall again");
    let refused = app
        .world_mut()
        .run_system_once(move |mut pins: SurfacePins| pins.pin(sphere, 100_000))
        .unwrap();
    assert!(
        matches!(
            refused,
            Err(WorldSurfaceError::PointOutOfRange { index: 100_000, .. })
        ),
        "{refused:?}"
    );
    // An entity that is no surface, and a rule that picks nothing.
    let nowhere = app.world_mut().spawn_empty().id();
    let (refused, none) = app
        .world_mut()
        .run_system_once(move |mut pins: SurfacePins| {
            (
                pins.pin_where(nowhere, |_| true),
                pins.pin_where(sphere, |_| false),
            )
        })
        .unwrap();
    assert_eq!(refused, Err(WorldSurfaceError::NotASurface(nowhere)));
    assert_eq!(none, Ok(0));
}

/// Issue 37: pins declared before the first tick. An observer of `SurfaceReady` runs as
/// the preparation is put in, before any tick: the points it pins never move, even on a
/// surface that falls from the first tick on.
#[test]
fn points_pinned_when_the_surface_is_ready_never_move() {
    let mut app = create_app(&assets_dir(), TICK);
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(100),
        ..default()
    };
    let sphere = app
        .world_mut()
        .spawn(DeformableSurface::cloud(
            shapes::fibonacci_sphere(1000, 1.0),
            config,
        ))
        .observe(|ready: On<SurfaceReady>, mut pins: SurfacePins| {
            let held = pins.pin_near(ready.entity, Vec3::Y, 0.3).unwrap();
            assert!(held > 0);
        })
        .id();
    settle(&mut app, &[sphere]);
    let rest = app
        .world()
        .get::<SurfaceNetwork>(sphere)
        .unwrap()
        .positions
        .clone();
    let held: Vec<usize> = (0..rest.len())
        .filter(|&i| rest[i].distance(Vec3::Y) <= 0.3)
        .collect();
    assert!(!held.is_empty());
    for _ in 0..30 {
        app.update();
    }
    let points = app.world().get::<SimulationPoints>(sphere).unwrap();
    let work = app
        .world()
        .get::<bevy_point_springs::plugin::SurfaceWork>(sphere);
    assert!(work.unwrap().steps >= 30);
    for &i in &held {
        assert_eq!(points.position(i), rest[i], "pinned point {i} moved");
    }
    let lowest = points
        .iter_positions()
        .map(|p| p.y)
        .fold(f32::MAX, f32::min);
    assert!(lowest < -1.05, "the rest did not hang down: {lowest}");
}

/// Issue 64: gravity is the world's by default. A sphere turned upside down falls along its
/// own +Y (the world's −Y), and with `SurfaceGravity::Own` it rises (falls along its own
/// −Y).
#[test]
fn a_turned_surface_falls_down_unless_its_gravity_is_its_own() {
    let mut app = create_app(&assets_dir(), TICK);
    let flipped = Transform::from_rotation(Quat::from_rotation_x(std::f32::consts::PI));
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(100),
        ..default()
    };
    let surface = || DeformableSurface::cloud(shapes::fibonacci_sphere(1000, 1.0), config);
    let with = app
        .world_mut()
        .spawn((surface(), flipped, GlobalTransform::from(flipped)))
        .id();
    let without = app
        .world_mut()
        .spawn((
            surface(),
            flipped,
            GlobalTransform::from(flipped),
            SurfaceGravity::Own,
        ))
        .id();
    settle(&mut app, &[with, without]);
    let world_centre = |app: &App, e: Entity| {
        let points = app.world().get::<SimulationPoints>(e).unwrap();
        flipped.transform_point(centroid(points))
    };
    let start = [world_centre(&app, with), world_centre(&app, without)];
    for _ in 0..20 {
        app.update();
    }
    let fell = start[0].y - world_centre(&app, with).y;
    let rose = world_centre(&app, without).y - start[1].y;
    assert!(fell > 0.05, "fell {fell}");
    assert!(rose > 0.05, "rose {rose}");
    let stepper = app.world().get::<SurfaceStepper>(with).unwrap();
    // The setting stays the world's; the step's is turned into the surface's coordinates.
    assert_eq!(stepper.config().gravity, Vec3::NEG_Y * 9.81);
    let own = stepper.gravity();
    assert!(own.distance(Vec3::Y * 9.81) < 1e-4, "{own}");
}
