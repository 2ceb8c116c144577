//! The plugin's modelling tools, headless (issue 17): plastic materials, baking and export
//! through `ModelMessage`, and sleeping surfaces.

use bevy::prelude::*;
use bevy_point_springs::core::cloud::io::read_cloud;
use bevy_point_springs::core::pipeline::DenseCloud;
use bevy_point_springs::core::pipeline::NormalsSpec;
use bevy_point_springs::core::solver::BendingModel;
use bevy_point_springs::core::solver::{Masses, Springs};
use bevy_point_springs::plugin::DEFAULT_SLEEP_AFTER;
#[cfg(feature = "egui")]
use bevy_point_springs::plugin::panel::PointSpringsPanelPlugin;
use bevy_point_springs::plugin::{
    Grabs, PreparationProgress, PrepareAgainFailed, SaveGameError, SleepSettings, StepOnce,
    SurfaceInView, SurfaceMasses, SurfaceNetwork, SurfaceRunSettings, SurfaceSleep, SurfaceSprings,
    SurfaceStepper, SurfaceTimings, SurfaceWork,
};
use bevy_point_springs::prelude::*;

#[allow(dead_code)] // each test file uses some of the helpers
#[path = "support/plugin_app.rs"]
mod plugin_app;
use plugin_app::*;

/// A floating sphere (1500 dense, 150 simulation points) made plastic while it runs (yield
/// 5 %, creep 5 per second: the material system hands the springs their yield), its bottom
/// held (key 2), its top grabbed (key 1) and that grab moved `pull` up. Returns the sphere
/// and its top and bottom points.
fn plastic_sphere_pulled_up(app: &mut App, pull: f32) -> (Entity, usize, usize) {
    let sphere = app.world_mut().spawn(floating(1500, 150)).id();
    settle(app, &[sphere]);
    let mut material = app.world_mut().get_mut::<SurfaceMaterial>(sphere).unwrap();
    material.yield_strain = 0.05;
    material.creep_rate = 5.0;
    let (top, top_rest) = nearest_point(app, sphere, Vec3::Y);
    let (bottom, bottom_rest) = nearest_point(app, sphere, Vec3::NEG_Y);
    for (key, at) in [(1, top_rest), (2, bottom_rest)] {
        app.world_mut().write_message(GrabMessage::Start {
            key,
            surface: sphere,
            at,
        });
    }
    app.update();
    app.world_mut().write_message(GrabMessage::Move {
        key: 1,
        target: top_rest + Vec3::Y * pull,
    });
    (sphere, top, bottom)
}

#[test]
fn a_plastic_material_keeps_what_a_grab_pulled_out() {
    let mut app = create_app(&assets_dir(), TICK);
    let pull = 0.4;
    let (sphere, top, bottom) = plastic_sphere_pulled_up(&mut app, pull);
    // How far apart the pulled and the held point are: the sphere's shape, whatever rigid
    // motion the grabs leave it (damping that leaves rigid motion alone keeps a drift or a
    // spin).
    let apart = |app: &App| {
        let points = app.world().get::<SimulationPoints>(sphere).unwrap();
        points.position(top).distance(points.position(bottom))
    };
    let at_rest = apart(&app);
    for _ in 0..120 {
        app.update();
    }
    for key in [1, 2] {
        app.world_mut().write_message(GrabMessage::End { key });
    }
    for _ in 0..300 {
        app.update();
    }
    let kept = apart(&app) - at_rest;
    println!("plastic grab: {kept:.3} of a {pull} pull kept 300 ticks after release");
    // Measured at the default settings: 0.337 kept on hinges (2026-12-03), 0.312 on the
    // fitted curvature, the default since 2026-12-04 (its flow moves the rest curvature and
    // the stabilisation's rest residuals, a little less of the shape than the hinges' rest
    // angles held); the same sphere elastic (no creep) springs back to within 0.001.
    assert!(kept > 0.7 * pull, "only {kept} of a {pull} pull was kept");
    assert!(status(&app, sphere).is_ready());
}

#[test]
fn a_baked_surface_keeps_its_shape_and_exports() {
    let mut app = create_app(&assets_dir(), TICK);
    let sphere = app.world_mut().spawn(floating(1500, 150)).id();
    settle(&mut app, &[sphere]);
    let (_, top_rest) = nearest_point(&app, sphere, Vec3::Y);
    let (_, bottom_rest) = nearest_point(&app, sphere, -Vec3::Y);
    // Hold the bottom, pull the top out, let go of both and bake on the next tick.
    for (key, at) in [(1, bottom_rest), (2, top_rest)] {
        app.world_mut().write_message(GrabMessage::Start {
            key,
            surface: sphere,
            at,
        });
    }
    app.update();
    app.world_mut().write_message(GrabMessage::Move {
        key: 2,
        target: top_rest + Vec3::Y * 0.3,
    });
    for _ in 0..60 {
        app.update();
    }
    app.world_mut().write_message(GrabMessage::End { key: 1 });
    app.world_mut().write_message(GrabMessage::End { key: 2 });
    app.update();
    app.world_mut()
        .write_message(ModelMessage::Bake { surface: sphere });
    let bake_outcome = outcomes_of(&mut app, 1);
    assert_eq!(bake_outcome.len(), 1);
    assert_eq!(bake_outcome[0].result, Ok(()));
    let baked = app
        .world()
        .get::<SimulationPoints>(sphere)
        .unwrap()
        .positions();
    // Nothing moves from the baked shape.
    for _ in 0..30 {
        app.update();
        let points = app.world().get::<SimulationPoints>(sphere).unwrap();
        let fastest = points
            .velocities()
            .iter()
            .map(|v| v.length())
            .fold(0.0, f32::max);
        assert_eq!(fastest, 0.0);
    }
    assert!(
        app.world()
            .get::<SimulationPoints>(sphere)
            .unwrap()
            .positions()
            == baked
    );
    let top = baked.iter().map(|p| p.y).fold(f32::MIN, f32::max);
    assert!(top > 1.1, "the baked top is at {top}");
    // Export, and read it back; an export nowhere fails and the surface runs on.
    let dir = std::env::temp_dir().join(format!("point-springs-plugin-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("baked.ply");
    for path in [path.clone(), dir.join("missing").join("baked.ply")] {
        app.world_mut().write_message(ModelMessage::Export {
            surface: sphere,
            path,
        });
    }
    let exported = outcomes_of(&mut app, 2);
    let written = |outcome: &ModelOutcome| matches!(&outcome.request, ModelMessage::Export { path: to, .. } if *to == path);
    let (good, bad): (Vec<_>, Vec<_>) = exported.iter().partition(|o| written(o));
    assert_eq!(good[0].result, Ok(()));
    assert!(
        matches!(bad[0].result, Err(ModelError::Export(_))),
        "{:?}",
        bad[0].result
    );
    // A request for an entity that is no surface is refused, and nothing else happens.
    let stranger = app.world_mut().spawn_empty().id();
    app.world_mut()
        .write_message(ModelMessage::Bake { surface: stranger });
    app.update();
    let refused = outcomes(&mut app);
    assert_eq!(refused[0].result, Err(ModelError::NotASurface(stranger)));
    let back = read_cloud(&path, None).unwrap();
    let dense = app.world().get::<DenseSurface>(sphere).unwrap();
    assert!(back.positions() == dense.positions());
    assert!(back.normals().unwrap() == dense.normals());
    assert!(status(&app, sphere).is_ready());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_hundred_sleeping_surfaces_cost_nothing_and_a_grab_wakes_one() {
    let mut app = create_app(&assets_dir(), TICK);
    app.add_systems(FixedUpdate, wind.in_set(PointSpringsSystems::Forces));
    let blown = app.world_mut().spawn((floating(1500, 150), Windy)).id();
    let still: Vec<Entity> = (0..100)
        .map(|_| app.world_mut().spawn(floating(300, 40)).id())
        .collect();
    let mut all = still.clone();
    all.push(blown);
    settle(&mut app, &all);
    // Left alone, they sleep after the sleep time; the blown one stays awake.
    let sleep_ticks = (DEFAULT_SLEEP_AFTER / TICK.as_secs_f32()).ceil() as usize;
    for _ in 0..sleep_ticks + 2 {
        app.update();
    }
    let asleep = |app: &App, e: Entity| app.world().get::<SurfaceSleep>(e).unwrap().asleep;
    assert!(still.iter().all(|&e| asleep(&app, e)));
    assert!(!asleep(&app, blown));
    let work = |app: &App, e: Entity| *app.world().get::<SurfaceWork>(e).unwrap();
    let before: Vec<SurfaceWork> = all.iter().map(|&e| work(&app, e)).collect();
    for _ in 0..60 {
        app.update();
    }
    let spent = |i: usize, e: Entity| {
        let (a, b) = (work(&app, e), before[i]);
        (a.springs_evaluated - b.springs_evaluated) + (a.points_transferred - b.points_transferred)
    };
    let sleeping: u64 = still.iter().enumerate().map(|(i, &e)| spent(i, e)).sum();
    let awake = spent(100, blown);
    println!("60 ticks: 100 sleeping surfaces {sleeping} springs + points, one awake {awake}");
    assert!(awake > 0);
    assert!((sleeping as f64) < 0.02 * awake as f64);
    // A grab wakes a sleeping surface on the next tick.
    let (_, top) = nearest_point(&app, still[7], Vec3::Y);
    app.world_mut().write_message(GrabMessage::Start {
        key: 1,
        surface: still[7],
        at: top,
    });
    let steps = work(&app, still[7]).steps;
    app.update();
    assert!(!asleep(&app, still[7]));
    assert_eq!(work(&app, still[7]).steps, steps + 1);
    assert!(asleep(&app, still[8]));
    // So does a change of its solver settings: given gravity, a sleeping one falls.
    let mut stepper = app.world_mut().get_mut::<SurfaceStepper>(still[9]).unwrap();
    let config = SolverConfig {
        gravity: Vec3::new(0.0, -9.81, 0.0),
        ..*stepper.config()
    };
    stepper.set_config(config).unwrap();
    let steps = work(&app, still[9]).steps;
    for _ in 0..10 {
        app.update();
    }
    assert!(!asleep(&app, still[9]));
    assert_eq!(work(&app, still[9]).steps, steps + 10);
    let speed = app
        .world()
        .get::<SimulationPoints>(still[9])
        .unwrap()
        .max_speed();
    assert!(speed > 0.5, "{speed}");
    assert!(asleep(&app, still[10]));
}

/// Updates until `n` modelling outcomes came (bakes and exports finish in the background),
/// and returns them.
fn outcomes_of(app: &mut App, n: usize) -> Vec<ModelOutcome> {
    let deadline = std::time::Instant::now() + SETTLE_TIMEOUT;
    let mut all = Vec::new();
    while all.len() < n {
        assert!(std::time::Instant::now() < deadline, "{all:?}");
        app.update();
        all.extend(outcomes(app));
    }
    all
}

/// The modelling outcomes sent since the last call.
fn outcomes(app: &mut App) -> Vec<ModelOutcome> {
    app.world_mut()
        .resource_mut::<Messages<ModelOutcome>>()
        .drain()
        .collect()
}

#[test]
fn a_paused_surface_steps_once_on_request_and_resets_to_rest() {
    let mut app = create_app(&assets_dir(), TICK);
    // Plastic and pulled, so that rest lengths flow for the reset to undo; held, so that
    // it keeps moving.
    let (sphere, ..) = plastic_sphere_pulled_up(&mut app, 0.4);
    for _ in 0..60 {
        app.update();
    }
    let timings = *app.world().get::<SurfaceTimings>(sphere).unwrap();
    println!("one tick of 150 points, pulled: {timings:?}");
    assert!(timings.forces_ms > 0.0 && timings.step_ms > 0.0 && timings.transfer_ms > 0.0);
    let steps = |app: &App| app.world().get::<SurfaceWork>(sphere).unwrap().steps;
    app.world_mut()
        .get_mut::<SurfaceRunSettings>(sphere)
        .unwrap()
        .paused = true;
    app.update();
    let paused_at = steps(&app);
    app.update();
    assert_eq!(steps(&app), paused_at, "a paused surface stepped");
    app.world_mut().entity_mut(sphere).insert(StepOnce);
    app.update();
    assert_eq!(steps(&app), paused_at + 1, "StepOnce is one step");
    assert!(app.world().get::<StepOnce>(sphere).is_none());
    app.update();
    assert_eq!(
        steps(&app),
        paused_at + 1,
        "StepOnce stepped more than once"
    );

    let energy = |app: &App| {
        let world = app.world();
        let springs = world.get::<SurfaceSprings>(sphere).unwrap();
        springs.energy(world.get::<SimulationPoints>(sphere).unwrap())
    };
    let strained = energy(&app);
    assert!(strained > 0.0);
    let flowed = |app: &App| {
        let world = app.world();
        let network = world.get::<SurfaceNetwork>(sphere).unwrap();
        let springs = world.get::<SurfaceSprings>(sphere).unwrap();
        springs
            .iter()
            .filter(|(i, spec)| spec.rest_length != network.rest_length(*i))
            .count()
    };
    let crept = flowed(&app);
    println!("{crept} springs crept under the pull");
    assert!(
        crept > 0,
        "no spring flowed: the reset would have nothing to undo"
    );
    app.world_mut()
        .write_message(ModelMessage::Reset { surface: sphere });
    app.update();
    assert_eq!(outcomes(&mut app)[0].result, Ok(()));
    let world = app.world();
    let points = world.get::<SimulationPoints>(sphere).unwrap();
    let network = world.get::<SurfaceNetwork>(sphere).unwrap();
    assert_eq!(points.positions(), network.positions);
    assert_eq!(points.max_speed(), 0.0);
    assert_eq!(flowed(&app), 0);
    // Rest lengths back from their plastic flow: no spring is stretched (but for rounding:
    // lengths are measured in f32).
    let left = energy(&app);
    println!("spring energy {strained:.3e} before the reset, {left:.3e} after");
    assert!(left < 1e-6 * strained);
}

#[test]
fn a_surface_out_of_view_simulates_without_transfer() {
    let mut app = create_app(&assets_dir(), TICK);
    app.add_systems(FixedUpdate, wind.in_set(PointSpringsSystems::Forces));
    let sphere = app.world_mut().spawn((floating(1500, 150), Windy)).id();
    settle(&mut app, &[sphere]);
    app.update();
    let work = |app: &App| *app.world().get::<SurfaceWork>(sphere).unwrap();
    let dense = |app: &App| app.world().get::<DenseSurface>(sphere).unwrap().positions()[0];
    app.world_mut()
        .entity_mut(sphere)
        .insert(SurfaceInView(false));
    let (before, at) = (work(&app), dense(&app));
    for _ in 0..30 {
        app.update();
    }
    let hidden = work(&app);
    assert_eq!(hidden.steps, before.steps + 30);
    assert_eq!(hidden.points_transferred, before.points_transferred);
    assert_eq!(dense(&app), at, "the dense surface moved out of view");
    // Seen again: the transfer catches up on the next tick.
    app.world_mut()
        .entity_mut(sphere)
        .insert(SurfaceInView(true));
    app.update();
    assert_eq!(
        work(&app).points_transferred,
        hidden.points_transferred + 1500
    );
    assert_ne!(dense(&app), at);
}

#[test]
fn a_status_set_back_to_pending_prepares_nothing_and_the_surface_runs_on() {
    // `SurfaceStatus` is the plugin's report; `PrepareAgain` is the one way to prepare
    // again. A game that writes `Pending` on a ready surface gets a warning, not a second
    // preparation: the same network, the steps going on.
    let mut app = create_app(&assets_dir(), TICK);
    // Never asleep, so that it steps every tick.
    let awake = SurfaceRunSettings {
        sleep: SleepSettings {
            speed: 0.0,
            ..default()
        },
        ..default()
    };
    let sphere = app.world_mut().spawn((floating(1500, 100), awake)).id();
    settle(&mut app, &[sphere]);
    let network = |app: &App| network_of(app, sphere);
    let steps = |app: &App| app.world().get::<SurfaceWork>(sphere).unwrap().steps;
    let before = network(&app);
    *app.world_mut().get_mut::<SurfaceStatus>(sphere).unwrap() = SurfaceStatus::Pending;
    let at = steps(&app);
    for _ in 0..5 {
        app.update();
    }
    assert!(status(&app, sphere).is_ready());
    assert!(app.world().get::<PreparationProgress>(sphere).is_none());
    assert!(std::sync::Arc::ptr_eq(&before, &network(&app)));
    assert!(steps(&app) >= at + 4, "{} steps after {at}", steps(&app));
}

#[test]
fn preparing_again_keeps_the_old_surface_running_until_the_new_one_is_ready() {
    let mut app = create_app(&assets_dir(), TICK);
    app.add_systems(FixedUpdate, wind.in_set(PointSpringsSystems::Forces));
    let sphere = app.world_mut().spawn((floating(3000, 150), Windy)).id();
    settle(&mut app, &[sphere]);
    #[derive(Resource, Default)]
    struct Seen(Vec<SurfaceReady>, Vec<SurfaceFailed>);
    app.init_resource::<Seen>();
    app.world_mut()
        .entity_mut(sphere)
        .observe(|ready: On<SurfaceReady>, mut seen: ResMut<Seen>| {
            seen.0.push(ready.event().clone());
        })
        .observe(|failed: On<SurfaceFailed>, mut seen: ResMut<Seen>| {
            seen.1.push(failed.event().clone());
        });
    let points = |app: &App| app.world().get::<SimulationPoints>(sphere).unwrap().len();
    let steps = |app: &App| app.world().get::<SurfaceWork>(sphere).unwrap().steps;
    assert_eq!(points(&app), 150);
    // Held while it is prepared again: the grab goes with the old simulation's anchors.
    let (_, top) = nearest_point(&app, sphere, Vec3::Y);
    app.world_mut().write_message(GrabMessage::Start {
        key: 5,
        surface: sphere,
        at: top,
    });
    app.update();
    assert!(app.world().resource::<Grabs>().get(5).is_some());
    // A run-time material: preparing again keeps it (the component is its one owner).
    app.world_mut()
        .get_mut::<SurfaceMaterial>(sphere)
        .unwrap()
        .yield_strain = 0.07;
    let mut config = app.world().get::<DeformableSurface>(sphere).unwrap().config;
    config.simplify.target = Some(400);
    app.world_mut()
        .entity_mut(sphere)
        .insert(PrepareAgain(config));
    app.update();
    assert!(app.world().get::<PreparationProgress>(sphere).is_some());
    // Changed while the preparation runs: the new simulation takes the material and the
    // solver settings as they are when it lands.
    app.world_mut()
        .get_mut::<SurfaceMaterial>(sphere)
        .unwrap()
        .creep_rate = 0.5;
    let mut solver = *app.world().get::<SurfaceStepper>(sphere).unwrap().config();
    solver.drag = 0.75;
    app.world_mut()
        .get_mut::<SurfaceStepper>(sphere)
        .unwrap()
        .set_config(solver)
        .unwrap();
    let started = steps(&app);
    let deadline = std::time::Instant::now() + SETTLE_TIMEOUT;
    while app.world().get::<PreparationProgress>(sphere).is_some() {
        assert!(std::time::Instant::now() < deadline, "never prepared");
        assert!(status(&app, sphere).is_ready());
        app.update();
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    println!(
        "prepared again to {} points while the old one took {} steps",
        points(&app),
        steps(&app) - started
    );
    assert!(
        steps(&app) > started,
        "the old surface stopped while preparing"
    );
    assert!(app.world().resource::<Grabs>().get(5).is_none());
    assert!(points(&app) >= 400, "{} points", points(&app));
    assert!(status(&app, sphere).is_ready());
    let material = app.world().get::<SurfaceMaterial>(sphere).unwrap();
    assert_eq!(material.yield_strain, 0.07);
    assert_eq!(material.creep_rate, 0.5);
    let stepper = app.world().get::<SurfaceStepper>(sphere).unwrap();
    assert_eq!(stepper.config().drag, 0.75);
    let ready = SurfaceReady {
        entity: sphere,
        again: true,
    };
    assert_eq!(app.world().resource::<Seen>().0, [ready]);

    // Settings that cannot work: the surface runs on as it was, and says why.
    config.normals = NormalsSpec::Estimate(2);
    app.world_mut()
        .entity_mut(sphere)
        .insert(PrepareAgain(config));
    let before = points(&app);
    while app.world().get::<PrepareAgainFailed>(sphere).is_none() {
        assert!(std::time::Instant::now() < deadline, "never failed");
        app.update();
    }
    assert_eq!(points(&app), before);
    assert!(status(&app, sphere).is_ready());
    let why = app
        .world()
        .get::<PrepareAgainFailed>(sphere)
        .unwrap()
        .0
        .clone();
    let failed = &app.world().resource::<Seen>().1;
    assert_eq!(failed.len(), 1);
    assert!(failed[0].still_running);
    assert_eq!(failed[0].error, why);
    assert!(matches!(why, SurfaceError::Prepare(_)), "{why:?}");
    // The surface's settings are those it runs with, not those that failed.
    let kept = app.world().get::<DeformableSurface>(sphere).unwrap().config;
    assert_eq!(kept.simplify.target, Some(400));
    assert_ne!(kept.normals, NormalsSpec::Estimate(2));
    let steps_then = steps(&app);
    app.update();
    assert_eq!(steps(&app), steps_then + 1);
}

/// The live panel, headless: bevy_egui runs its pass on a context of its own (no window, no
/// renderer), and the panel draws the selected surface every frame.
#[cfg(feature = "egui")]
#[test]
fn an_open_panel_draws_and_leaves_a_sleeping_surface_asleep() {
    use bevy_egui::{EguiPlugin, EguiRenderOutput, PrimaryEguiContext};

    let mut app = create_app_with(&assets_dir(), TICK, |app| {
        // What the renderer's plugins would otherwise bring: the asset stores egui loads
        // its shader and font texture into.
        app.init_asset::<bevy::shader::Shader>()
            .init_asset::<Image>()
            .add_plugins((
                bevy::input::InputPlugin,
                // Window messages, no window.
                bevy::window::WindowPlugin {
                    primary_window: None,
                    exit_condition: bevy::window::ExitCondition::DontExit,
                    ..default()
                },
                EguiPlugin::default(),
                PointSpringsPanelPlugin,
            ));
    });
    let context = app.world_mut().spawn(PrimaryEguiContext).id();
    let sphere = app.world_mut().spawn(floating(1500, 150)).id();
    settle(&mut app, &[sphere]);
    let sleep_ticks = (DEFAULT_SLEEP_AFTER / TICK.as_secs_f32()).ceil() as usize;
    for _ in 0..sleep_ticks + 2 {
        app.update();
    }
    let asleep = |app: &App| app.world().get::<SurfaceSleep>(sphere).unwrap().asleep;
    assert!(asleep(&app));
    let work = *app.world().get::<SurfaceWork>(sphere).unwrap();
    for _ in 0..60 {
        app.update();
    }
    assert_eq!(
        app.world().resource::<SurfacePanel>().selected,
        Some(sphere)
    );
    let drawn = &app
        .world()
        .get::<EguiRenderOutput>(context)
        .unwrap()
        .paint_jobs;
    assert!(!drawn.is_empty(), "the panel drew nothing");
    assert!(asleep(&app), "the open panel woke the surface");
    assert_eq!(*app.world().get::<SurfaceWork>(sphere).unwrap(), work);
}

/// The saved-game outcomes sent since the last call.
fn saved_outcomes(app: &mut App) -> Vec<SaveGameOutcome> {
    app.world_mut()
        .resource_mut::<Messages<SaveGameOutcome>>()
        .drain()
        .collect()
}

/// A gas-filled sphere (1500 dense, 150 simulation points) named "sphere"; ready.
fn named_gas_sphere(app: &mut App) -> Entity {
    named_gas_sphere_bending(app, BendingModel::Springs)
}

/// [`named_gas_sphere`] bending as `bending` says.
fn named_gas_sphere_bending(app: &mut App, bending: BendingModel) -> Entity {
    let mut surface = floating(1500, 150);
    surface.config.pressure = Some(200.0);
    surface.config.material.bending = bending;
    let sphere = app
        .world_mut()
        .spawn((surface, SaveName("sphere".into())))
        .id();
    settle(app, &[sphere]);
    sphere
}

/// A fresh app with [`named_gas_sphere_bending`] in it, the saved game at `file` loaded into
/// it (which must succeed).
fn loaded_in_a_fresh_app(file: &std::path::Path, bending: BendingModel) -> (App, Entity) {
    let mut fresh = create_app(&assets_dir(), TICK);
    let again = named_gas_sphere_bending(&mut fresh, bending);
    fresh.world_mut().write_message(SaveGameMessage::Load {
        path: file.to_path_buf(),
    });
    fresh.update();
    assert_eq!(
        saved_outcomes(&mut fresh)[0].result,
        Ok(vec!["sphere".to_owned()])
    );
    (fresh, again)
}

/// Vectors as bits.
type Bits = Vec<[u32; 3]>;

/// Everything that moves, as bits: simulation positions and velocities, dense positions.
fn moving_bits(app: &App, e: Entity) -> (Bits, Bits, Bits) {
    let bits = |v: Vec<Vec3>| v.iter().map(|p| p.to_array().map(f32::to_bits)).collect();
    let points = app.world().get::<SimulationPoints>(e).unwrap();
    let dense = app.world().get::<DenseSurface>(e).unwrap();
    (
        bits(points.positions()),
        bits(points.velocities()),
        bits(dense.positions().to_vec()),
    )
}

#[test]
fn a_sculpted_and_baked_surface_on_hinges_goes_on_bit_for_bit_from_a_saved_game() {
    let dir = std::env::temp_dir().join(format!("point-springs-hinges-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("hinges.save");
    let mut app = create_app(&assets_dir(), TICK);
    let sphere = named_gas_sphere_bending(&mut app, BendingModel::Hinges);
    let hinges = |app: &App, e| {
        let springs = app.world().get::<SurfaceSprings>(e).unwrap();
        springs
            .hinges()
            .iter()
            .map(|h| h.rest_angle.to_bits())
            .collect::<Vec<_>>()
    };
    let prepared = hinges(&app, sphere);
    assert!(prepared.len() > 300);
    // Plastic bending: a grab bends the top past the yield angle, then the shape is baked.
    let mut material = app.world_mut().get_mut::<SurfaceMaterial>(sphere).unwrap();
    material.yield_angle = 0.02;
    material.creep_rate = 5.0;
    let (_, top) = nearest_point(&app, sphere, Vec3::Y);
    app.world_mut().write_message(GrabMessage::Start {
        key: 1,
        surface: sphere,
        at: top,
    });
    for i in 0..30 {
        app.world_mut().write_message(GrabMessage::Move {
            key: 1,
            target: top + Vec3::Y * (0.01 * i as f32),
        });
        app.update();
    }
    assert!(hinges(&app, sphere) != prepared, "no rest angle flowed");
    app.world_mut()
        .write_message(ModelMessage::Bake { surface: sphere });
    assert_eq!(outcomes_of(&mut app, 1)[0].result, Ok(()));
    app.world_mut()
        .write_message(SaveGameMessage::Save { path: file.clone() });
    app.update();
    assert_eq!(
        saved_outcomes(&mut app)[0].result,
        Ok(vec!["sphere".to_owned()])
    );
    let (mut fresh, again) = loaded_in_a_fresh_app(&file, BendingModel::Hinges);
    assert_eq!(hinges(&app, sphere), hinges(&fresh, again));
    // Both go on, the grab held and then let go: the same bits each tick.
    for i in 0..40 {
        for a in [&mut app, &mut fresh] {
            if i == 20 {
                a.world_mut().write_message(GrabMessage::End { key: 1 });
            }
            a.update();
        }
        assert!(
            moving_bits(&app, sphere) == moving_bits(&fresh, again),
            "tick {i} after the load"
        );
    }
    // A saved game of bend springs does not fit a surface on hinges: a typed error.
    let mut springs = create_app(&assets_dir(), TICK);
    named_gas_sphere(&mut springs);
    springs
        .world_mut()
        .write_message(SaveGameMessage::Load { path: file });
    springs.update();
    let result = saved_outcomes(&mut springs).remove(0).result;
    assert!(result.is_err(), "{result:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_saved_game_goes_on_bit_for_bit_in_a_fresh_app() {
    let dir = std::env::temp_dir().join(format!("point-springs-save-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("game.save");
    // The first game: a plastic, gas-filled sphere pinned at the bottom, sculpted by a grab,
    // baked, grabbed again (held while saving).
    let mut app = create_app(&assets_dir(), TICK);
    let sphere = named_gas_sphere(&mut app);
    hold(&mut app, sphere, |p| p.y < -0.8);
    let mut material = app.world_mut().get_mut::<SurfaceMaterial>(sphere).unwrap();
    material.yield_strain = 0.05;
    material.creep_rate = 5.0;
    let (_, top_rest) = nearest_point(&app, sphere, Vec3::Y);
    let grab = |app: &mut App, key, at| {
        app.world_mut().write_message(GrabMessage::Start {
            key,
            surface: sphere,
            at,
        })
    };
    let pull = |app: &mut App, key, target| {
        app.world_mut()
            .write_message(GrabMessage::Move { key, target })
    };
    grab(&mut app, 1, top_rest);
    app.update();
    for i in 0..40 {
        pull(&mut app, 1, top_rest + Vec3::new(0.0, 0.01 * i as f32, 0.0));
        app.update();
    }
    app.world_mut().write_message(GrabMessage::End { key: 1 });
    app.world_mut()
        .write_message(ModelMessage::Bake { surface: sphere });
    assert_eq!(outcomes_of(&mut app, 1)[0].result, Ok(()));
    let (_, side) = nearest_point(&app, sphere, Vec3::X);
    let side = app
        .world()
        .get::<Transform>(sphere)
        .unwrap()
        .transform_point(side);
    grab(&mut app, 7, side);
    app.update();
    pull(&mut app, 7, side + Vec3::X * 0.2);
    app.world_mut()
        .write_message(SaveGameMessage::Save { path: file.clone() });
    app.update();
    let saved = saved_outcomes(&mut app);
    assert_eq!(saved[0].result, Ok(vec!["sphere".to_owned()]));
    // The same game, loaded into a fresh app once its sphere is ready.
    let (mut fresh, again) = loaded_in_a_fresh_app(&file, BendingModel::Springs);
    // The simulation alike; the dense surfaces from the next tick on (the game's is drawn
    // between its last two ticks, the loaded one where its points are until it has a tick
    // of its own).
    let (first, loaded) = (moving_bits(&app, sphere), moving_bits(&fresh, again));
    assert_eq!((first.0, first.1), (loaded.0, loaded.1));
    // Both go on, the grab (key 7) dragged further, then let go: the same bits each tick.
    for i in 0..60 {
        for (a, e) in [(&mut app, sphere), (&mut fresh, again)] {
            match i {
                40 => a.world_mut().write_message(GrabMessage::End { key: 7 }),
                _ => pull(a, 7, side + Vec3::X * (0.2 + 0.005 * i as f32)),
            };
            a.update();
            assert!(status(a, e).is_ready());
        }
        assert!(
            moving_bits(&app, sphere) == moving_bits(&fresh, again),
            "tick {i} after the load"
        );
    }
    let baked = |app: &App, e| {
        app.world()
            .get::<bevy_point_springs::plugin::SurfaceBaked>(e)
            .is_some()
    };
    assert!(baked(&app, sphere) && baked(&fresh, again));
    // Bad files: typed errors, the game unchanged.
    let before = moving_bits(&fresh, again);
    let bytes = std::fs::read(&file).unwrap();
    let cases: [(&str, Vec<u8>); 3] = [
        ("foreign", b"ply\nformat ascii 1.0\n".to_vec()),
        ("cut", bytes[..bytes.len() / 2].to_vec()),
        ("empty", Vec::new()),
    ];
    for (name, content) in cases {
        let path = dir.join(name);
        std::fs::write(&path, content).unwrap();
        fresh
            .world_mut()
            .write_message(SaveGameMessage::Load { path });
        fresh.world_mut().resource_mut::<Time<Virtual>>().pause();
        fresh.update();
        fresh.world_mut().resource_mut::<Time<Virtual>>().unpause();
        let result = saved_outcomes(&mut fresh).remove(0).result;
        assert!(
            matches!(
                result,
                Err(SaveGameError::NotASavedGame | SaveGameError::Damaged(_))
            ),
            "{name}: {result:?}"
        );
        assert_eq!(moving_bits(&fresh, again), before, "{name}");
    }
    // A game of another surface (no surface of its name here), a missing file.
    fresh
        .world_mut()
        .entity_mut(again)
        .insert(SaveName("other".into()));
    fresh
        .world_mut()
        .write_message(SaveGameMessage::Load { path: file.clone() });
    fresh.world_mut().write_message(SaveGameMessage::Load {
        path: dir.join("missing"),
    });
    fresh.update();
    let results: Vec<_> = saved_outcomes(&mut fresh)
        .into_iter()
        .map(|o| o.result)
        .collect();
    assert_eq!(results[0], Err(SaveGameError::NoSurface("sphere".into())));
    assert!(matches!(results[1], Err(SaveGameError::Io { .. })));
    // A surface of another size under the saved name: refused after reading, nothing of
    // either surface changed.
    let mut other = floating(1200, 100);
    other.config.pressure = Some(200.0);
    let smaller = fresh
        .world_mut()
        .spawn((other, SaveName("sphere".into())))
        .id();
    settle(&mut fresh, &[smaller]);
    fresh.update();
    let before = (moving_bits(&fresh, again), moving_bits(&fresh, smaller));
    fresh
        .world_mut()
        .write_message(SaveGameMessage::Load { path: file.clone() });
    fresh.world_mut().resource_mut::<Time<Virtual>>().pause();
    fresh.update();
    let result = saved_outcomes(&mut fresh).remove(0).result;
    assert!(
        matches!(&result, Err(SaveGameError::DoesNotFit { name, .. }) if name == "sphere"),
        "{result:?}"
    );
    assert!(before == (moving_bits(&fresh, again), moving_bits(&fresh, smaller)));
    std::fs::remove_dir_all(&dir).ok();
}

/// Issue 37: a bake runs off the tick. On a surface of 10^5 dense points the tick spends
/// well under a millisecond on it (taking the job, putting the result in), while the same
/// bake done on the tick, as before, takes far longer.
#[test]
fn a_bake_of_a_hundred_thousand_points_does_not_hold_up_the_tick() {
    const DENSE: usize = 100_000;
    let mut app = create_app(&assets_dir(), TICK);
    let sphere = app.world_mut().spawn(floating(DENSE, 1000)).id();
    settle(&mut app, &[sphere]);
    assert_eq!(
        app.world().get::<DenseSurface>(sphere).unwrap().len(),
        DENSE
    );
    // Squeeze it a little, so that the bake has a new shape to measure.
    let (_, top) = nearest_point(&app, sphere, Vec3::Y);
    app.world_mut().write_message(GrabMessage::Start {
        key: 1,
        surface: sphere,
        at: top,
    });
    app.update();
    app.world_mut().write_message(GrabMessage::Move {
        key: 1,
        target: top - Vec3::Y * 0.2,
    });
    for _ in 0..10 {
        app.update();
    }
    // The same bake on the tick, as it was done before, on copies.
    let on_tick_ms = {
        let world = app.world();
        let network = world
            .get::<SurfaceNetwork>(sphere)
            .unwrap()
            .shared()
            .clone();
        let mut points = world.get::<SimulationPoints>(sphere).unwrap().0.clone();
        let mut springs = Springs::clone(world.get::<SurfaceSprings>(sphere).unwrap());
        let mut masses = Masses::clone(world.get::<SurfaceMasses>(sphere).unwrap());
        let mut dense = DenseCloud::clone(world.get::<DenseSurface>(sphere).unwrap());
        let density = world.get::<SurfaceMaterial>(sphere).unwrap().density;
        let start = std::time::Instant::now();
        let parts = bevy_point_springs::core::pipeline::BakeParts {
            network: &network,
            points: &mut points,
            springs: &mut springs,
            masses: &mut masses,
            pressure: None,
            dense: &mut dense,
        };
        bevy_point_springs::core::pipeline::bake(parts, density).unwrap();
        start.elapsed().as_secs_f32() * 1e3
    };
    // Three bakes, one after the other. The tests of this file run at once on two cores, so
    // one tick may be preempted: every bake's worst tick must be a small share of the bake,
    // and at least one bake must cost no tick more than 1 ms.
    let mut worst = Vec::new();
    for _ in 0..3 {
        app.world_mut()
            .write_message(ModelMessage::Bake { surface: sphere });
        let deadline = std::time::Instant::now() + SETTLE_TIMEOUT;
        let mut worst_ms = 0.0f32;
        let mut ticks = 0;
        let outcome = loop {
            assert!(std::time::Instant::now() < deadline, "no outcome");
            app.update();
            ticks += 1;
            let timings = app.world().get::<SurfaceTimings>(sphere).unwrap();
            worst_ms = worst_ms.max(timings.model_ms);
            if let Some(outcome) = outcomes(&mut app).pop() {
                break outcome;
            }
        };
        println!(
            "bake of {DENSE} dense points: {ticks} ticks, at most {worst_ms:.3} ms of a tick; \
             on the tick it took {on_tick_ms:.1} ms"
        );
        assert_eq!(outcome.result, Ok(()));
        assert!(ticks > 1, "the bake was done within the tick that read it");
        assert!(
            worst_ms * 10.0 < on_tick_ms,
            "a tick spent {worst_ms} ms on a bake that takes {on_tick_ms} ms"
        );
        worst.push(worst_ms);
    }
    let best = worst.iter().copied().fold(f32::MAX, f32::min);
    assert!(best < 1.0, "every bake cost a tick over 1 ms: {worst:?}");
    // What the test guards against: on the tick, the bake would lengthen it far more.
    assert!(on_tick_ms > 5.0, "{on_tick_ms} ms");
}

/// A saved game loaded onto a surface while a bake of it runs drops the bake: the bake was
/// taken from the state the load replaced, and must not overwrite the loaded one.
#[test]
fn a_load_drops_a_bake_under_way() {
    let dir = std::env::temp_dir().join(format!("point-springs-superseded-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("game.save");
    let mut app = create_app(&assets_dir(), TICK);
    let sphere = named_gas_sphere(&mut app);
    app.update();
    app.world_mut()
        .write_message(SaveGameMessage::Save { path: file.clone() });
    app.update();
    assert!(saved_outcomes(&mut app)[0].result.is_ok());
    let saved = app
        .world()
        .get::<SimulationPoints>(sphere)
        .unwrap()
        .positions();
    // Squeezed out of that shape, then baked and loaded in the same frame.
    let (_, top) = nearest_point(&app, sphere, Vec3::Y);
    app.world_mut().write_message(GrabMessage::Start {
        key: 3,
        surface: sphere,
        at: top,
    });
    app.update();
    app.world_mut().write_message(GrabMessage::Move {
        key: 3,
        target: top - Vec3::Y * 0.3,
    });
    for _ in 0..20 {
        app.update();
    }
    app.world_mut().write_message(GrabMessage::End { key: 3 });
    app.world_mut()
        .write_message(ModelMessage::Bake { surface: sphere });
    app.world_mut()
        .write_message(SaveGameMessage::Load { path: file.clone() });
    app.update();
    assert!(saved_outcomes(&mut app)[0].result.is_ok());
    let outcome = outcomes_of(&mut app, 1);
    assert_eq!(outcome[0].result, Err(ModelError::Superseded(sphere)));
    // The loaded shape runs on, not the squeezed one the bake measured.
    assert!(
        app.world()
            .get::<bevy_point_springs::plugin::SurfaceBaked>(sphere)
            .is_none()
    );
    let now = app
        .world()
        .get::<SimulationPoints>(sphere)
        .unwrap()
        .positions();
    let apart = now
        .iter()
        .zip(&saved)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f32::max);
    assert!(apart < 0.05, "{apart} from the loaded shape");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_reset_drops_a_bake_under_way_and_a_despawn_still_answers_it() {
    let mut app = create_app(&assets_dir(), TICK);
    // Large enough that its bake (the transfer refitted over 20 000 dense points) is still
    // running when the tick that started it ends.
    let sphere = app.world_mut().spawn(floating(20_000, 300)).id();
    settle(&mut app, &[sphere]);
    let network = |app: &App| network_of(app, sphere);
    let before = network(&app);
    // A bake, then a reset in the same tick: the later request wins.
    app.world_mut()
        .write_message(ModelMessage::Bake { surface: sphere });
    app.world_mut()
        .write_message(ModelMessage::Reset { surface: sphere });
    let all = outcomes_of(&mut app, 2);
    let of = |bake: bool| {
        all.iter()
            .find(|o| matches!(o.request, ModelMessage::Bake { .. }) == bake)
            .unwrap()
            .result
            .clone()
    };
    assert_eq!(of(false), Ok(()));
    assert_eq!(of(true), Err(ModelError::Superseded(sphere)));
    assert!(std::sync::Arc::ptr_eq(&before, &network(&app)));
    assert!(
        app.world()
            .get::<bevy_point_springs::plugin::SurfaceBaked>(sphere)
            .is_none()
    );

    // A bake under way when its surface is despawned: the request is answered all the same.
    app.world_mut()
        .write_message(ModelMessage::Bake { surface: sphere });
    app.update();
    assert!(
        outcomes(&mut app).is_empty(),
        "the bake finished in its own tick"
    );
    app.world_mut().despawn(sphere);
    app.update();
    let answered = outcomes(&mut app);
    assert_eq!(answered.len(), 1, "{answered:?}");
    assert_eq!(answered[0].request, ModelMessage::Bake { surface: sphere });
    assert_eq!(answered[0].result, Err(ModelError::Despawned(sphere)));
}
