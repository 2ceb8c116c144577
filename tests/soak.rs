//! The soak: the paper's sphere (gas inside) and the hat (under gravity) stepped a million
//! times each with random pokes, drags and releases, the dense surface following every step.
//! Finite throughout, energy bounded, total mass conserved, memory flat.
//!
//! Ignored by default (about three minutes per surface in a release build). Run it with
//! `cargo test --release --no-default-features --test soak -- --ignored --nocapture`;
//! `SOAK_STEPS` changes the step count, `SOAK_SECONDS` stops each surface after that many
//! seconds of wall time instead (CI runs it so, with a time bound).
//!
//! With the `rapier` feature it also holds the ECS soak (`support/ecs_soak.rs`): the plugin
//! and rapier under churn for `SOAK_TICKS` ticks (or `SOAK_SECONDS`).

use std::time::{Duration, Instant};

#[cfg(feature = "rapier")]
#[path = "support/rapier_app.rs"]
mod rapier_app;

#[cfg(feature = "rapier")]
#[path = "support/ecs_soak.rs"]
mod ecs_soak;

use bevy_point_springs::core::scene::{Scene, SceneRun};
use bevy_point_springs::core::solver::{Anchor, AnchorId, STANDARD_GRAVITY};
use glam::Vec3;
use rand::{RngExt, SeedableRng};

/// Steps per surface unless `SOAK_STEPS` says otherwise.
const STEPS: u64 = 1_000_000;

/// The most anchors held at once.
const MAX_ANCHORS: usize = 3;

/// Stiffness of every poke and drag, N/m.
const ANCHOR_STIFFNESS: f32 = 300.0;

/// How far from its rest position a poke or drag takes its point at most.
const REACH: f32 = 0.4;

/// Steps between two events at most (an event: a poke, a drag's start, a release).
const EVENT_GAP: u64 = 120;

/// Resident memory of this process, bytes (Linux's `/proc/self/statm`; 0 elsewhere).
fn resident_bytes() -> u64 {
    std::fs::read_to_string("/proc/self/statm")
        .ok()
        .and_then(|s| s.split_whitespace().nth(1)?.parse::<u64>().ok())
        .map_or(0, |pages| pages * 4096)
}

/// What one surface's soak measured.
#[derive(Debug)]
struct Soak {
    steps: u64,
    events: u64,
    energy_min: f64,
    energy_max: f64,
    bound: f64,
    resident_start: u64,
    resident_end: u64,
    seconds: f64,
}

/// A held point: its anchor, its rest position, and the drag it follows (a target moving
/// from `from` to `to` until step `until`).
struct Held {
    id: AnchorId,
    rest: Vec3,
    from: Vec3,
    to: Vec3,
    start: u64,
    until: u64,
}

fn soak(name: &str, mut run: SceneRun, steps: u64, wall: Option<Duration>, seed: u64) -> Soak {
    let dt = run.scene.dt;
    let mut rng = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(seed);
    let rest = run.surface.network.positions.clone();
    let mass = run.solver().masses.total();
    let pinned = run.solver().masses.pinned();
    // The bound: the rest state's energy, plus gravity's over the whole diagonal, plus
    // every anchor stretched across the diagonal ten times over. A blow-up is orders larger.
    let diagonal = {
        let (lo, hi) = rest
            .iter()
            .fold((rest[0], rest[0]), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
        f64::from((hi - lo).length())
    };
    let e0 = run.solver().energy().total();
    let gravity = f64::from(run.solver().config().gravity.length());
    let bound = e0.abs()
        + mass * gravity * diagonal
        + 10.0 * MAX_ANCHORS as f64 * 0.5 * f64::from(ANCHOR_STIFFNESS) * diagonal * diagonal;
    let (mut energy_min, mut energy_max) = (e0, e0);
    let mut held: Vec<Held> = Vec::new();
    let mut next_event = 0u64;
    let mut events = 0u64;
    // Warm up: the first frames allocate the transfer's buffers.
    run.surface
        .dense
        .follow(&run.surface.solver.points)
        .unwrap();
    // Memory is measured from a quarter of the run on: the process's memory is shared with
    // the plugin's soak, which CI runs at once on the other thread and which grows to its
    // working size in its first seconds (2000 ticks; with the fitted curvature the default,
    // 4.8 MiB of that landed in this soak's window when it was measured from step 0, while
    // this soak alone grew 0.2 MiB).
    let mut resident_start = resident_bytes();
    let mut warm = false;
    let start = Instant::now();
    let mut step = 0u64;
    while step < steps && wall.is_none_or(|w| start.elapsed() < w) {
        if !warm && (step >= steps / 4 || wall.is_some_and(|w| start.elapsed() >= w / 4)) {
            resident_start = resident_bytes();
            warm = true;
        }
        if step == next_event {
            events += 1;
            let solver = &mut run.surface.solver;
            if held.len() == MAX_ANCHORS || (!held.is_empty() && rng.random::<f32>() < 0.4) {
                // Release one.
                let h = held.swap_remove(rng.random_range(0..held.len()));
                solver.remove_anchor(h.id).expect("a held anchor");
            } else {
                // Poke or drag a free point somewhere within reach of its rest position.
                let mut random_offset = || {
                    let v = Vec3::new(
                        rng.random_range(-1.0f32..1.0),
                        rng.random_range(-1.0f32..1.0),
                        rng.random_range(-1.0f32..1.0),
                    );
                    v.clamp_length_max(1.0) * REACH
                };
                let (from, to) = (random_offset(), random_offset());
                let point = loop {
                    let i = rng.random_range(0..rest.len());
                    if !solver.masses.is_pinned(i) {
                        break i;
                    }
                };
                let drag = rng.random::<f32>() < 0.5;
                let target = rest[point] + from;
                let id = solver
                    .add_anchor(Anchor {
                        point: point as u32,
                        target,
                        stiffness: ANCHOR_STIFFNESS,
                        damping: 1.0,
                    })
                    .unwrap();
                held.push(Held {
                    id,
                    rest: rest[point],
                    from,
                    to: if drag { to } else { from },
                    start: step,
                    until: step + rng.random_range(30..EVENT_GAP),
                });
            }
            next_event = step + rng.random_range(10..EVENT_GAP);
        }
        for h in &held {
            let t = (step - h.start) as f32 / (h.until - h.start) as f32;
            let target = h.rest + h.from.lerp(h.to, t.min(1.0));
            run.surface.solver.set_anchor_target(h.id, target).unwrap();
        }
        let report = run.surface.solver.step(dt).unwrap();
        assert!(
            !report.recovered,
            "{name}: the guard restored step {step}: {:?}",
            report.instability
        );
        run.surface
            .dense
            .follow(&run.surface.solver.points)
            .unwrap();
        let e = run.solver().energy().total();
        energy_min = energy_min.min(e);
        energy_max = energy_max.max(e);
        assert!(
            e.is_finite() && e.abs() <= bound,
            "{name}: energy {e} at step {step}, bound {bound}"
        );
        step += 1;
    }
    let seconds = start.elapsed().as_secs_f64();
    let solver = run.solver();
    assert_eq!(
        solver.diagnostics().guard_trips,
        0,
        "{name}: the guard tripped"
    );
    let mass_end = solver.masses.total();
    assert_eq!(mass.to_bits(), mass_end.to_bits(), "{name}: mass changed");
    assert_eq!(solver.masses.pinned(), pinned, "{name}: pins changed");
    let dense = &run.surface.dense;
    assert!(dense.positions().iter().all(|p| p.is_finite()));
    assert!(dense.max_displacement() < 10.0 * diagonal as f32);
    Soak {
        steps: step,
        events,
        energy_min,
        energy_max,
        bound,
        resident_start,
        resident_end: resident_bytes(),
        seconds,
    }
}

fn prepared(file: &str, gravity: bool) -> SceneRun {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets/scenes")
        .join(file);
    let (mut scene, base) = Scene::load(&path).unwrap();
    // The scene's own pulls are replaced by the soak's random ones; resampling is off (it
    // grows the dense cloud by design, up to its cap).
    scene.pulls.clear();
    scene.resample = None;
    if gravity {
        scene.solver.gravity = Vec3::NEG_Y * STANDARD_GRAVITY;
    }
    scene.prepare(&base).unwrap()
}

#[test]
#[ignore = "a million steps per surface: minutes; CI runs it time-bounded"]
fn a_million_steps_of_random_pokes_drags_and_releases() {
    let steps = std::env::var("SOAK_STEPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(STEPS);
    let wall = std::env::var("SOAK_SECONDS")
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
        .map(Duration::from_secs_f64);
    for (name, file, gravity, seed) in [
        ("sphere (gas)", "sphere_poke.ron", false, 1),
        ("hat (gravity)", "hat.ron", true, 2),
    ] {
        let s = soak(name, prepared(file, gravity), steps, wall, seed);
        let mib = |b: u64| b as f64 / (1024.0 * 1024.0);
        println!(
            "{name}: {} steps in {:.1} s ({:.1} µs/step), {} events, energy {:.4e} to {:.4e} \
             (bound {:.4e}), resident {:.1} MiB after a quarter of the run, {:.1} MiB at the end",
            s.steps,
            s.seconds,
            s.seconds * 1e6 / s.steps.max(1) as f64,
            s.events,
            s.energy_min,
            s.energy_max,
            s.bound,
            mib(s.resident_start),
            mib(s.resident_end),
        );
        // Memory flat: under 4 MiB of growth over the whole run.
        assert!(
            s.resident_end <= s.resident_start + 4 * 1024 * 1024,
            "{name}: resident memory grew from {} to {} bytes",
            s.resident_start,
            s.resident_end
        );
    }
}
