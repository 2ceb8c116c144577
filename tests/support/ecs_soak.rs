//! The ECS soak (issue 32): the plugin with rapier under churn. Surfaces (some with gas) are
//! spawned and despawned, grabbed, dragged and let go, hit by rapier balls, prepared again,
//! baked, reset, paused and resumed, taken out of view and back, for `SOAK_TICKS` fixed
//! ticks (10⁵ by default) or `SOAK_SECONDS` of wall time. Checked throughout: no panic, every
//! simulation point and ball finite, speeds bounded, no surface failed; at the end, with
//! everything despawned: the entities and rapier bodies released (counted), memory flat.
//! Included by `tests/soak.rs` (feature `rapier`).

use std::time::{Duration, Instant};

use bevy::ecs::system::RunSystemOnce;
use bevy::prelude::*;
use bevy_point_springs::core::cloud::shapes;
use bevy_point_springs::plugin::{
    PrepareAgainFailed, SurfaceHealth, SurfaceInView, SurfaceMasses, SurfaceNetwork,
};
use bevy_point_springs::prelude::*;
use bevy_rapier3d::prelude::*;
use rand::{RngExt, SeedableRng};

use super::rapier_app::create_app;
use super::resident_bytes;

/// Ticks unless `SOAK_TICKS` says otherwise.
const TICKS: u64 = 100_000;

/// Surfaces alive at once, at most.
const MAX_SURFACES: usize = 3;

/// Ticks between two events.
const EVENT_GAP: u64 = 15;

/// A ball is despawned this many ticks after it was dropped.
const BALL_LIFE: u64 = 240;

/// A grab lets go after this many ticks.
const GRAB_LIFE: u64 = 90;

/// Ticks between two checks of every surface and ball.
const CHECK_GAP: u64 = 50;

/// No simulation point or ball may be faster (m/s): the balls fall about 3 m, the grabs
/// drag at under 2 m/s.
const MAX_SPEED: f32 = 50.0;

/// Memory is measured from this tick on (preparation pools, rapier's and Bevy's tables
/// have grown to their working size by then).
const WARM_UP: u64 = 2_000;

/// What the soak did and saw.
#[derive(Debug, Default)]
struct Tally {
    ticks: u64,
    spawned: u64,
    despawned: u64,
    grabs: u64,
    balls: u64,
    prepared_again: u64,
    bakes: u64,
    resets: u64,
    pauses: u64,
    hidden: u64,
    pins: u64,
    saves: u64,
    loads: u64,
    fastest: f32,
    troubled_steps: u64,
    /// Troubled steps of surfaces despawned or prepared again (their health starts over).
    troubled_before: u64,
    failed_requests: u64,
    resident_warm: u64,
    resident_end: u64,
}

/// An active grab: its key, surface, the world point it started at, and when.
struct Grab {
    key: u64,
    surface: Entity,
    at: Vec3,
    since: u64,
}

/// A surface of `points` dense points on a sphere of radius 0.4 at `at`, simplified to
/// `target`, with gas or without.
fn surface(points: usize, target: usize, gas: bool, at: Vec3) -> impl Bundle {
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(target),
        pressure: gas.then_some(300.0),
        ..default()
    };
    (
        DeformableSurface::cloud(shapes::fibonacci_sphere(points, 0.4), config),
        Transform::from_translation(at),
    )
}

fn ball(at: Vec3) -> impl Bundle {
    (
        RigidBody::Dynamic,
        Collider::ball(0.12),
        ColliderMassProperties::Density(300.0),
        Velocity::zero(),
        Transform::from_translation(at),
    )
}

/// Entities in the world, resources (entities too) left out: the plugin inserts some on
/// first use.
fn entities(app: &mut App) -> usize {
    let world = app.world_mut();
    world
        .query_filtered::<Entity, Without<bevy::ecs::resource::IsResource>>()
        .iter(world)
        .count()
}

/// Pins the points of `e`'s top cap (rest y above 0.25) where they are, or frees them where
/// some are pinned.
fn toggle_pins(app: &mut App, e: Entity) {
    let rest = app
        .world()
        .get::<SurfaceNetwork>(e)
        .unwrap()
        .positions
        .clone();
    let pinned = app.world().get::<SurfaceMasses>(e).unwrap().pinned();
    app.world_mut()
        .run_system_once(move |mut pins: SurfacePins| {
            let cap = |i: usize| rest[i].y > 0.25;
            if pinned > 0 {
                for i in 0..rest.len() {
                    pins.free(e, i).unwrap();
                }
            } else if (0..rest.len()).any(cap) {
                pins.pin_where(e, cap).unwrap();
            }
        })
        .unwrap();
}

/// The troubled steps of surface `e` so far (which must not have failed).
fn troubled(app: &App, e: Entity) -> u64 {
    let status = app.world().get::<SurfaceStatus>(e);
    assert!(
        !matches!(status, Some(SurfaceStatus::Failed(_))),
        "surface {e} failed: {status:?}"
    );
    app.world()
        .get::<SurfaceHealth>(e)
        .map_or(0, |h| h.troubled_steps)
}

/// Bakes and resets that failed since the last call (a request for a surface despawned or
/// not ready by then, or despawned while it ran, is refused by design, and not counted), and surfaces whose preparation
/// again failed.
fn failed_requests(app: &mut App) -> u64 {
    let world = app.world_mut();
    let models = world
        .resource_mut::<Messages<ModelOutcome>>()
        .drain()
        // Refusals (not ready, already baking, prepared again or reset meanwhile, despawned
        // meanwhile) are not failures.
        .filter(|o| {
            o.result.as_ref().is_err_and(|e| {
                !matches!(
                    e,
                    ModelError::NotASurface(_)
                        | ModelError::NotReady(_)
                        | ModelError::Busy(_)
                        | ModelError::Superseded(_)
                        | ModelError::Despawned(_)
                )
            })
        })
        .inspect(|o| eprintln!("{o:?}"))
        .count();
    let mut again = world.query_filtered::<Entity, With<PrepareAgainFailed>>();
    (models + again.iter(world).count()) as u64
}

fn ready(app: &App, e: Entity) -> bool {
    app.world()
        .get::<SurfaceStatus>(e)
        .is_some_and(SurfaceStatus::is_ready)
}

/// A world point of `e`'s simulation points, picked by `pick`.
fn point_of(app: &App, e: Entity, pick: usize) -> Option<Vec3> {
    let points = app.world().get::<SimulationPoints>(e)?;
    let transform = app.world().get::<Transform>(e)?;
    (!points.is_empty()).then(|| transform.transform_point(points.position(pick % points.len())))
}

/// Every simulation point and ball finite and slower than [`MAX_SPEED`], no surface
/// failed. Returns the fastest speed seen and the troubled steps so far.
fn check(app: &mut App, tick: u64) -> (f32, u64) {
    let mut fastest = 0.0f32;
    let mut troubled = 0;
    let world = app.world_mut();
    let mut surfaces = world.query::<(
        Entity,
        &SurfaceStatus,
        &SurfaceHealth,
        Option<&SimulationPoints>,
    )>();
    for (e, status, health, points) in surfaces.iter(world) {
        assert!(
            !matches!(status, SurfaceStatus::Failed(_)),
            "tick {tick}: surface {e} failed: {status:?}"
        );
        troubled += health.troubled_steps;
        let Some(points) = points else { continue };
        for i in 0..points.len() {
            let (p, v) = (points.position(i), points.velocity(i));
            assert!(p.is_finite() && v.is_finite(), "tick {tick}: {e} point {i}");
            fastest = fastest.max(v.length());
        }
    }
    let mut balls = world.query::<(&Transform, &Velocity)>();
    for (t, v) in balls.iter(world) {
        assert!(
            t.translation.is_finite() && v.linear.is_finite(),
            "tick {tick}: a ball"
        );
        fastest = fastest.max(v.linear.length());
    }
    assert!(
        fastest < MAX_SPEED,
        "tick {tick}: something moves at {fastest} m/s"
    );
    (fastest, troubled)
}

#[test]
#[ignore = "10⁵ ticks of churn: minutes; CI runs it time-bounded"]
fn the_plugin_under_churn() {
    let ticks = std::env::var("SOAK_TICKS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(TICKS);
    let wall = std::env::var("SOAK_SECONDS")
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
        .map(Duration::from_secs_f64);
    let mut app = create_app();
    app.world_mut().spawn((
        RigidBody::Fixed,
        Collider::cuboid(20.0, 0.5, 20.0),
        Transform::from_xyz(0.0, -1.5, 0.0),
    ));
    app.update();
    let baseline = entities(&mut app);
    let mut rng = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(32);
    let dir = std::env::temp_dir().join(format!("point-springs-soak-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let save = dir.join("soak.save");
    let (mut surfaces, mut balls) = (Vec::<Entity>::new(), Vec::<(Entity, u64)>::new());
    let mut grab: Option<Grab> = None;
    let mut tally = Tally::default();
    let start = Instant::now();
    let mut tick = 0;
    while tick < ticks && wall.is_none_or(|w| start.elapsed() < w) {
        if tick % EVENT_GAP == 0 {
            let target = surfaces
                .get(rng.random_range(0..surfaces.len().max(1)))
                .copied();
            let ready_target = target.filter(|&e| ready(&app, e));
            match rng.random_range(0..12) {
                0 | 1 if surfaces.len() < MAX_SURFACES => {
                    let at = Vec3::new(
                        rng.random_range(-2.0..2.0),
                        rng.random_range(0.0..1.0),
                        rng.random_range(-2.0..2.0),
                    );
                    let (points, target) = (rng.random_range(800..1600), rng.random_range(60..140));
                    let name = SaveName(format!("surface {}", tally.spawned));
                    let e = app
                        .world_mut()
                        .spawn((surface(points, target, rng.random_bool(0.5), at), name))
                        .id();
                    surfaces.push(e);
                    tally.spawned += 1;
                }
                2 if surfaces.len() > 1 => {
                    let e = surfaces.swap_remove(rng.random_range(0..surfaces.len()));
                    tally.troubled_before += troubled(&app, e);
                    app.world_mut().despawn(e);
                    tally.despawned += 1;
                }
                3 if grab.is_none() => {
                    if let Some(e) = ready_target
                        && let Some(at) = point_of(&app, e, rng.random_range(0..1000))
                    {
                        tally.grabs += 1;
                        let key = tally.grabs;
                        app.world_mut().write_message(GrabMessage::Start {
                            key,
                            surface: e,
                            at,
                        });
                        grab = Some(Grab {
                            key,
                            surface: e,
                            at,
                            since: tick,
                        });
                    }
                }
                4 => {
                    if let Some(at) = ready_target.and_then(|e| point_of(&app, e, 0)) {
                        let e = app.world_mut().spawn(ball(at + Vec3::Y * 1.5)).id();
                        balls.push((e, tick));
                        tally.balls += 1;
                    }
                }
                5 => {
                    if let Some(e) = ready_target {
                        let config = SurfaceConfig {
                            simplify: SimplifyConfig::target(rng.random_range(60..140)),
                            ..default()
                        };
                        tally.troubled_before += troubled(&app, e);
                        app.world_mut().entity_mut(e).insert(PrepareAgain(config));
                        tally.prepared_again += 1;
                    }
                }
                6 => {
                    if let Some(surface) = ready_target {
                        app.world_mut()
                            .write_message(ModelMessage::Bake { surface });
                        tally.bakes += 1;
                    }
                }
                7 => {
                    if let Some(surface) = ready_target {
                        app.world_mut()
                            .write_message(ModelMessage::Reset { surface });
                        tally.resets += 1;
                    }
                }
                8 => {
                    if let Some(e) = target {
                        let mut settings =
                            app.world_mut().get_mut::<SurfaceRunSettings>(e).unwrap();
                        settings.paused = !settings.paused;
                        tally.pauses += 1;
                    }
                }
                9 => {
                    if let Some(e) = target {
                        let mut in_view = app.world_mut().get_mut::<SurfaceInView>(e).unwrap();
                        in_view.0 = !in_view.0;
                        tally.hidden += 1;
                    }
                }
                10 => {
                    // Pin the top cap where it is, or free it again.
                    if let Some(e) = ready_target {
                        toggle_pins(&mut app, e);
                        tally.pins += 1;
                    }
                }
                11 => {
                    // Save every surface, or load the last save (refused, and nothing
                    // changed, where a saved surface is gone, not ready or baked since).
                    let message = if rng.random_bool(0.5) {
                        SaveGameMessage::Save { path: save.clone() }
                    } else {
                        SaveGameMessage::Load { path: save.clone() }
                    };
                    app.world_mut().write_message(message);
                }
                _ => {}
            }
        }
        if let Some(g) = &grab {
            let age = tick - g.since;
            let alive = surfaces.contains(&g.surface);
            if age > GRAB_LIFE || !alive {
                app.world_mut()
                    .write_message(GrabMessage::End { key: g.key });
                grab = None;
            } else {
                let swing = (age as f32 * 0.1).sin() * 0.3;
                let target = g.at + Vec3::new(swing, 0.2 * swing.abs(), 0.0);
                app.world_mut()
                    .write_message(GrabMessage::Move { key: g.key, target });
            }
        }
        balls.retain(|&(e, born)| {
            let gone = tick - born > BALL_LIFE;
            if gone {
                app.world_mut().despawn(e);
            }
            !gone
        });
        app.update();
        tally.failed_requests += failed_requests(&mut app);
        for outcome in app
            .world_mut()
            .resource_mut::<Messages<SaveGameOutcome>>()
            .drain()
        {
            match (&outcome.request, outcome.result) {
                (SaveGameMessage::Save { .. }, Ok(_)) => tally.saves += 1,
                (SaveGameMessage::Load { .. }, Ok(_)) => tally.loads += 1,
                (SaveGameMessage::Save { .. }, Err(e)) => panic!("a save failed: {e}"),
                (SaveGameMessage::Load { .. }, Err(_)) => {}
            }
        }
        tick += 1;
        if tick % CHECK_GAP == 0 {
            let (fastest, troubled) = check(&mut app, tick);
            tally.fastest = tally.fastest.max(fastest);
            tally.troubled_steps = troubled;
        }
        if tick == WARM_UP {
            tally.resident_warm = resident_bytes();
        }
    }
    tally.ticks = tick;
    tally.resident_end = resident_bytes();
    // Everything goes: the entities and rapier's bodies are released.
    for e in surfaces.drain(..).chain(balls.drain(..).map(|(e, _)| e)) {
        app.world_mut().despawn(e);
    }
    for _ in 0..5 {
        app.update();
    }
    let left = entities(&mut app);
    let bodies = {
        let world = app.world_mut();
        world
            .query::<&RapierRigidBodySet>()
            .iter(world)
            .map(|s| s.bodies.len())
            .sum::<usize>()
    };
    let mib = |b: u64| b as f64 / (1024.0 * 1024.0);
    println!(
        "ECS soak: {} ticks in {:.1} s; {} surfaces spawned, {} despawned, {} grabs, {} balls, \
         {} prepared again, {} bakes, {} resets, {} pauses, {} hidden, {} pin changes, {} saves, \
         {} loads; fastest {:.2} m/s; \
         {} troubled steps; resident {:.1} MiB after warm-up, {:.1} MiB at the end; \
         entities {baseline} before, {left} after; rapier bodies after: {bodies}",
        tally.ticks,
        start.elapsed().as_secs_f64(),
        tally.spawned,
        tally.despawned,
        tally.grabs,
        tally.balls,
        tally.prepared_again,
        tally.bakes,
        tally.resets,
        tally.pauses,
        tally.hidden,
        tally.pins,
        tally.saves,
        tally.loads,
        tally.fastest,
        tally.troubled_steps,
        mib(tally.resident_warm),
        mib(tally.resident_end),
    );
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(left, baseline, "entities left behind");
    assert_eq!(
        tally.troubled_steps + tally.troubled_before,
        0,
        "a surface's guard stepped in"
    );
    assert_eq!(
        tally.failed_requests, 0,
        "a bake, reset or preparation failed"
    );
    assert_eq!(bodies, 1, "rapier bodies left behind (the floor stays)");
    if tally.ticks > WARM_UP {
        assert!(
            tally.resident_end <= tally.resident_warm + 8 * 1024 * 1024,
            "resident memory grew from {} to {} bytes",
            tally.resident_warm,
            tally.resident_end
        );
    }
}
