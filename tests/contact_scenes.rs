//! Contact that holds (issue 64), tried as a game would: crates dropped on a cloth lying on
//! the floor, crates stacked on it, a crate pinched between a ball of gas and the floor, a
//! crate dropped on a scanned ball of gas. Each scene is measured tick by tick
//! (`support/contact_scenes.rs`): the mechanical energy of crates and points, speeds, how
//! low the points go and how close the crates come to the floor.
#![cfg(feature = "rapier")]

use bevy::prelude::*;

#[path = "support/rapier_app.rs"]
mod rapier_app;
#[path = "support/contact_scenes.rs"]
mod scenes;

use bevy_point_springs::plugin::{BodySupports, ContactSolve, SurfaceContact};
use scenes::{CRATE_SIDE, FLOOR_TOP, Scene};

/// Ticks a second.
const HZ: usize = 60;

/// What a scene's crates and points did after they were dropped.
struct Seen {
    /// How far the energy rose above its value at the drop, J, and that value.
    rise: f64,
    start: f64,
    /// Each crate's fastest speed, and the speed of its fall (what falling from its start
    /// to the lowest it went gives).
    crates: Vec<(f32, f32)>,
    /// The fastest point and crate after 3 s.
    points_late: f32,
    crate_late: f32,
    /// The lowest point's centre and the lowest crate corner above the floor, ever.
    lowest_point: f32,
    lowest_corner: f32,
}

impl Seen {
    fn of(scene: &Scene) -> Self {
        let (points_late, crate_late) = scene.fastest_after(3 * HZ);
        let (lowest_point, lowest_corner) = scene.lowest_after(0);
        Self {
            rise: scene.energy_rise(0),
            start: scene.ticks[0].energy,
            crates: (0..scene.crates.len())
                .map(|k| scene.crate_speeds(k, 0))
                .collect(),
            points_late,
            crate_late,
            lowest_point,
            lowest_corner,
        }
    }

    fn print(&self, what: &str) {
        println!(
            "{what}: energy rose {:.4} J over {:.3} J; crates fastest (of their fall) {:.3?} \
             m/s; after 3 s points {:.4} m/s, crates {:.4} m/s; lowest point {:.4} m, lowest \
             crate corner {:.4} m",
            self.rise,
            self.start,
            self.crates,
            self.points_late,
            self.crate_late,
            self.lowest_point,
            self.lowest_corner
        );
    }

    /// The acceptance's energy: never more than 1 % above its start, no crate faster than
    /// 1.1 times its fall.
    fn assert_no_energy_gained(&self, what: &str) {
        assert!(
            self.rise <= 0.01 * self.start,
            "{what}: energy rose {}",
            self.rise
        );
        for (k, (fastest, fall)) in self.crates.iter().enumerate() {
            assert!(
                *fastest <= 1.1 * fall,
                "{what}: crate {k} at {fastest} of {fall}"
            );
        }
    }
}

/// Crates of `masses` dropped from 1 m onto a 1.2 m cloth (350 simulation points) lying on
/// the floor, stacked one above the other (a crate's side apart), measured for `seconds`
/// after the drop; and the cloth's thickness.
fn crates_on_cloth(masses: &[f32], seconds: usize) -> (Scene, f32) {
    crates_on_cloth_solved(masses, seconds, DEFAULT_SOLVER_ITERATIONS)
}

/// rapier's default `num_solver_iterations`.
const DEFAULT_SOLVER_ITERATIONS: usize = 4;

/// As `crates_on_cloth`, with rapier's solver at `iterations`.
fn crates_on_cloth_solved(masses: &[f32], seconds: usize, iterations: usize) -> (Scene, f32) {
    let mut scene = Scene::new();
    scene.solver_iterations(iterations);
    let cloth = scene.cloth(1.2, 350);
    scene.run(HZ);
    let thickness = 2.0 * scene.mean_radius(cloth);
    for (k, &mass) in masses.iter().enumerate() {
        let above = FLOOR_TOP + thickness + 1.0 + (k as f32 + 0.5) * CRATE_SIDE * 1.5;
        let at = Vec3::new(0.05, above, -0.03);
        scene.drop_crate(at, Quat::from_rotation_y(0.3), mass);
    }
    scene.ticks.clear();
    scene.run(seconds * HZ);
    (scene, thickness)
}

#[test]
fn crates_dropped_on_a_cloth_on_the_floor_come_to_rest_on_it() {
    // Issue 64: a 1 kg crate still moved at 0.3 m/s and the cloth at 1.2 m/s after 4 s; a
    // 5 kg crate pressed the cloth 3 cm into the floor and reached the floor through it.
    // Now the crate is held off the points the floor holds (a pinch), and those points stand
    // in rapier's step as fixed balls (decision 0034). Measured 2026-12-07: 1 kg and 5 kg
    // both below 0.1 mm/s after 3 s (crate and points), energy never above its start, the
    // lowest corner 0.0736 m (1 kg) and 0.0820 m (5 kg) up over a 0.0752 m thick cloth.
    for mass in [1.0, 5.0] {
        let (scene, thickness) = crates_on_cloth(&[mass], 10);
        let seen = Seen::of(&scene);
        let what = format!("a {mass} kg crate on a cloth");
        seen.print(&what);
        seen.assert_no_energy_gained(&what);
        assert!(seen.crate_late < 0.01, "{what}: {}", seen.crate_late);
        assert!(seen.points_late < 0.01, "{what}: {}", seen.points_late);
        assert!(
            seen.lowest_point > FLOOR_TOP,
            "{what}: {}",
            seen.lowest_point
        );
        // Contacts are the points' spheres: a corner over the gap between two of them
        // dips into the cloth's thickness by a few millimetres, never through it.
        assert!(
            seen.lowest_corner > 0.85 * thickness,
            "{what}: {} of {thickness}",
            seen.lowest_corner
        );
    }
}

#[test]
fn three_crates_stacked_on_a_cloth_stay_stacked() {
    // Before the cloth's held points stood in rapier's step as fixed balls (decision 0034),
    // rapier's impulse between two crates came after the surface's step: the lower crate
    // was pressed through the cloth to the floor and the stack fell (its crates ended side
    // by side, 0.18 m up). Measured 2026-12-07: stacked 0.189, 0.388 and 0.588 m up, the
    // energy never above its start; the stack rocks on the balls after the landing and is
    // below 1 cm/s (crates and points) from 3.4 s after the drop, 2.9 s after landing
    // (rapier alone, the crates dropped on its floor: 2 s), and asleep after it. Without
    // the cloth the balls go and the stack falls to the floor.
    let (scene, thickness) = crates_on_cloth(&[1.0, 1.0, 1.0], 10);
    let seen = Seen::of(&scene);
    seen.print("three crates stacked on a cloth");
    seen.assert_no_energy_gained("three crates stacked on a cloth");
    let last = scene.ticks.last().unwrap();
    let rested = rested_from(&scene);
    println!(
        "the crates' heights at the end: {:.3?}; below 1 cm/s from {:.2} s",
        last.crate_height,
        rested as f32 / HZ as f32
    );
    assert_stacked(last, thickness);
    assert!(
        seen.lowest_corner > 0.85 * thickness,
        "{} of {thickness}",
        seen.lowest_corner
    );
    // At rest for the last 5 s.
    assert!(rested <= 5 * HZ, "at rest only from tick {rested}");
    let mut scene = scene;
    let balls = scene.app.world().resource::<BodySupports>().len();
    assert!(balls > 0, "no ball under the stack");
    let cloth = scene.surfaces.remove(0);
    scene.app.world_mut().despawn(cloth);
    scene.run(HZ / 2);
    assert!(scene.app.world().resource::<BodySupports>().is_empty());
    let fell = scene.ticks.last().unwrap().crate_height[0];
    println!("{balls} balls under the stack; the cloth gone, the lowest crate at {fell:.3} m");
    assert!(
        (fell - (FLOOR_TOP + 0.5 * CRATE_SIDE)).abs() < 0.01,
        "the lowest crate at {fell}"
    );
}

/// Each crate on the one below (a crate's side apart), the lowest on the cloth of
/// `thickness` (and the balls' slop, rapier's allowed error, under it): within 2 cm.
fn assert_stacked(last: &scenes::Tick, thickness: f32) {
    for k in 0..3 {
        let expected = FLOOR_TOP + thickness + (k as f32 + 0.5) * CRATE_SIDE;
        assert!(
            (last.crate_height[k] - expected).abs() < 0.02,
            "crate {k} at {} instead of {expected}",
            last.crate_height[k]
        );
    }
}

/// The first tick after which every crate and point stays below 1 cm/s.
fn rested_from(scene: &Scene) -> usize {
    let fastest = |t: &scenes::Tick| t.crate_speed.iter().copied().fold(t.point_speed, f32::max);
    scene
        .ticks
        .iter()
        .rposition(|t| fastest(t) >= 0.01)
        .map_or(0, |k| k + 1)
}

#[test]
fn three_crates_stacked_on_a_cloth_rest_within_2_s_at_8_solver_iterations() {
    // The stack above rocks on the balls under the lowest crate until 3.4 s after the drop:
    // rapier's default 4 iterations meet 14 ball contacts under it. Measured 2026-12-07:
    // at 8 iterations (what the README advises for stacks) below 1 cm/s from 0.93 s, at 16
    // from 0.65 s, the heights as at 4.
    let (scene, thickness) = crates_on_cloth_solved(&[1.0, 1.0, 1.0], 3, 8);
    let seen = Seen::of(&scene);
    seen.print("three crates stacked on a cloth, 8 solver iterations");
    seen.assert_no_energy_gained("three crates stacked on a cloth, 8 solver iterations");
    let rested = rested_from(&scene);
    println!("below 1 cm/s from {:.2} s", rested as f32 / HZ as f32);
    assert!(rested <= 2 * HZ, "at rest only from tick {rested}");
    assert_stacked(scene.ticks.last().unwrap(), thickness);
}

/// A 1 kg crate dropped, its bottom `height` above `2·radius` over the floor and `x` to the
/// side of the middle of the ball (of that radius) that `spawn` makes, after the ball has
/// settled on the floor for 2 s; the scene after `seconds` more, measured from the drop.
fn crate_on_ball(
    spawn: impl FnOnce(&mut Scene) -> Entity,
    (radius, x, height): (f32, f32, f32),
    seconds: usize,
) -> Scene {
    let at = Vec3::new(x, FLOOR_TOP + 2.0 * radius + height + 0.5 * CRATE_SIDE, 0.0);
    let mut scene = Scene::new();
    spawn(&mut scene);
    scene.run(2 * HZ);
    scene.drop_crate(at, Quat::IDENTITY, 1.0);
    scene.ticks.clear();
    scene.run(seconds * HZ);
    scene
}

/// A crate of 1 kg dropped from `height` above the top of a ball of gas (radius 0.5, the
/// playground's material) lying on the floor, 0.45 m to its side: it slides down the ball
/// into the gap between it and the floor.
fn crate_pinched(height: f32, seconds: usize) -> Seen {
    let radius = 0.5;
    let scene = crate_on_ball(
        |scene| scene.gas_ball(0.0, 0.02, radius),
        (radius, 0.45, height),
        seconds,
    );
    let seen = Seen::of(&scene);
    let points = scene.fastest_after(0).0;
    println!("points fastest {points:.3} m/s");
    seen.print(&format!("a crate pinched from {height} m"));
    assert!(
        points < 2.0 * seen.crates[0].1,
        "a point at {points} m/s, twice the crate's fall {}",
        seen.crates[0].1
    );
    seen
}

#[test]
fn a_crate_pinched_between_a_ball_of_gas_and_the_floor_is_not_launched() {
    // Issue 64: at two drop heights of seven the scan's points reached 350–880 m/s and the
    // crate was shot away at ~400 m/s.
    for height in [0.2, 1.0] {
        let seen = crate_pinched(height, 5);
        let what = format!("a crate pinched from {height} m");
        seen.assert_no_energy_gained(&what);
        let (fastest, fall) = seen.crates[0];
        assert!(fastest <= fall, "{what}: the crate at {fastest} of {fall}");
    }
}

#[test]
#[ignore = "fails today: its landing gains energy, and the crate creeps at 5 cm/s (issue 64, items 3, 4)"]
fn a_crate_dropped_on_a_scanned_ball_of_gas_comes_to_rest() {
    // On the default material the ball is a trampoline, and a crate cannot rest on it: it
    // dents the top 0.43 m, is thrown back up at about 0.6 of its landing speed, and tips
    // over. A 0.2 m cube on a soft bed of modulus k (pressure per sink) tips when
    // k·a⁴/12 < m·g·h (a its side, h its centre's height): k below about 7400 N/m³ for this
    // crate, and the default ball's is about 1600 (a 0.16 m sink under 250 Pa). This ball
    // is firm and damped enough to hold the crate up. Measured 2026-12-08, once friction
    // took the body's answer into account (decision 0036): the crate stays on the ball's
    // top, within 0.1 m of where it landed. The landing still raises the energy, by at most
    // 5.8 J over its 29.06 J start, within 0.25 s: friction after the solve kicks a stiff
    // point alone. After 3 s the crate moves at 5 cm/s and the points at 4.5 cm/s. Before,
    // friction spun the crate, the scene gained 29 J, and the crate slid off.
    let radius = 0.5;
    let firm = bevy_point_springs::core::solver::SpringMaterial {
        stretch_stiffness: 5000.0,
        stretch_damping: 10.0,
        ..default()
    };
    let mut scene = Scene::new();
    let ball = scene.scan_ball(0.02, radius, firm, 4000.0);
    scene.run(2 * HZ);
    let top = scene.top_near(ball, (0.0, 0.0), 0.5 * CRATE_SIDE);
    let at = Vec3::new(0.0, top + 0.1 + 0.5 * CRATE_SIDE, 0.0);
    let crate_ = scene.drop_crate(at, Quat::IDENTITY, 1.0);
    scene.ticks.clear();
    let mut path = Vec::new();
    let mut rolled = Vec::new();
    for _ in 0..10 {
        scene.run(HZ / 2);
        path.push(
            scene
                .app
                .world()
                .get::<Transform>(crate_.entity)
                .unwrap()
                .translation,
        );
        rolled.push(centre(&scene, ball));
    }
    let seen = Seen::of(&scene);
    let energy: Vec<f64> = scene
        .ticks
        .iter()
        .step_by(HZ / 4)
        .map(|t| t.energy)
        .collect();
    println!("energy every 0.25 s {energy:.2?}");
    seen.print("a crate dropped 0.1 m on a firm scanned ball");
    println!(
        "the ball's top {top:.4} m; the crate's middle every 0.5 s: {:.3?}",
        path.iter().map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>()
    );
    println!(
        "the ball's centre every 0.5 s: {:.3?}",
        rolled.iter().map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>()
    );
    seen.assert_no_energy_gained("a crate on a firm scanned ball");
    assert!(seen.crate_late < 0.01 && seen.points_late < 0.01);
}

/// The centre of `surface`'s simulation points, world coordinates.
fn centre(scene: &Scene, surface: Entity) -> Vec3 {
    use bevy_point_springs::plugin::SimulationPoints;
    let world = scene.app.world();
    let points = world.get::<SimulationPoints>(surface).unwrap();
    let place = world.get::<GlobalTransform>(surface).unwrap();
    let n = points.len();
    (0..n)
        .map(|i| place.transform_point(points.position(i)))
        .sum::<Vec3>()
        / n as f32
}

#[test]
#[ignore = "fails today: the upper ball rolls off the lower (issue 64, item 2)"]
fn a_ball_of_gas_resting_on_another_on_the_floor() {
    // The acceptance: at rest within 3 s, creeping under 1 mm over the last second.
    // Measured 2026-12-07: the upper ball (dropped 2 cm onto the lower, 5 cm to its side)
    // rolls off onto the floor and still creeps 45 mm in the sixth second; the energy never
    // rose above its start.
    let radius = 0.5;
    let mut scene = Scene::new();
    let lower = scene.gas_ball(0.0, 0.02, radius);
    let upper = scene.gas_ball(0.05, 0.04 + 2.0 * radius, radius);
    scene.ticks.clear();
    scene.run(5 * HZ);
    let before = centre(&scene, upper);
    scene.run(HZ);
    let after = centre(&scene, upper);
    let energy: Vec<f64> = scene.ticks.iter().step_by(HZ).map(|t| t.energy).collect();
    let (points_late, _) = scene.fastest_after(5 * HZ);
    let (points_ever, _) = scene.fastest_after(0);
    let (lowest, _) = scene.lowest_after(0);
    println!(
        "two balls: energy each second {energy:.3?} J, rose {:.4} J; fastest point {points_ever:.3} m/s \
         (the upper ball's bottom falling to the floor: {:.3}); in the last second {points_late:.4} m/s; lowest point \
         {lowest:.4} m; the upper ball's centre {before:.4} → {after:.4}, crept {:.2} mm; lower \
         ball's centre {:.4}",
        scene.energy_rise(0),
        (2.0 * scenes::G * (0.04 + 2.0 * radius)).sqrt(),
        1000.0 * before.distance(after),
        centre(&scene, lower)
    );
    assert!(scene.energy_rise(0) <= 0.01 * scene.ticks[0].energy);
    assert!(
        before.distance(after) < 1e-3,
        "crept {}",
        before.distance(after)
    );
}

#[test]
#[ignore = "fails today: estimated contacts do not hold a cloth lying on the floor (issue 64, item 3)"]
fn a_cloth_lying_on_the_floor_with_estimated_contacts_keeps_still() {
    // `ContactSolve::Estimated` gives each point an impulse before the step, as heavy as
    // its step mass with the springs to neighbours that do not touch. A point next to one
    // hovering a few millimetres up counts those springs and is pushed up far harder than
    // it pressed down. Measured 2026-12-07, 1 s after the switch from the default: points
    // at 0.17 m/s and 0.51 J before it, then up to 10 m/s and 5 to 78 J (friction and
    // overlap recovery off changed nothing). Each point as heavy as its own mass instead
    // held the cloth still (0.40 J), but a crate dropped on it then pressed it through the
    // floor: a point between a body and the floor is estimated against each in turn.
    let mut scene = Scene::new();
    let cloth = scene.cloth(1.2, 350);
    scene
        .app
        .world_mut()
        .entity_mut(cloth)
        .insert(SurfaceContact {
            solve: ContactSolve::Estimated,
            ..default()
        });
    scene.ticks.clear();
    scene.run(3 * HZ);
    let start = scene.ticks[0].energy;
    let most = scene.ticks.iter().map(|t| t.energy).fold(start, f64::max);
    let late = scene.fastest_after(2 * HZ).0;
    println!(
        "a cloth on the floor, estimated: energy {start:.3} J, at most {most:.3} J; points after 2 s {late:.4} m/s"
    );
    assert!(
        most <= start * 1.01,
        "the energy rose from {start} to {most} J"
    );
    assert!(late < 0.01, "points at {late} m/s after 2 s");
}
