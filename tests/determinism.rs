//! Determinism: a scene prepared and run twice, and with one and with two threads, gives the
//! same deformed dense surface to the bit (what is and is not deterministic is written in
//! `docs/ARCHITECTURE.md`, "Determinism").

use std::path::Path;

use bevy_point_springs::core::cloud::io::read_cloud;
use bevy_point_springs::core::scene::{Pull, Region, Scene};
use bevy_point_springs::core::simplify::SimplifyConfig;
use bevy_point_springs::core::solver::{Integrator, SolverConfig};
use glam::Vec3;

/// A run's deformed surface, as bits: positions, normals, then the simulation points'
/// positions and velocities and their masses.
type Bits = (
    Vec<[u32; 3]>,
    Vec<[u32; 3]>,
    Vec<[u32; 3]>,
    Vec<[u32; 3]>,
    Vec<u32>,
);

fn bits(v: &[Vec3]) -> Vec<[u32; 3]> {
    v.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
}

/// Prepares and runs `scene` on the cloud at `cloud` inside a rayon pool of `threads`
/// threads (every parallel stage of the core runs in the pool it is called from).
fn run_with_threads(scene: &Scene, cloud: &Path, threads: usize) -> Bits {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let mut run = scene.prepare_run(read_cloud(cloud, None).unwrap()).unwrap();
        run.run(&mut |_| {}).unwrap();
        let deformed = run.deformed().unwrap();
        let solver = run.solver();
        (
            bits(deformed.cloud.positions()),
            bits(deformed.cloud.normals().unwrap()),
            bits(&solver.points.positions()),
            bits(&solver.points.velocities()),
            run.surface
                .network
                .masses
                .iter()
                .map(|m| m.to_bits())
                .collect(),
        )
    })
}

/// Runs `scene` with one thread, with two, and with two again, and checks the three agree.
fn assert_deterministic(name: &str, scene: &Scene, cloud: &Path) {
    let one = run_with_threads(scene, cloud, 1);
    let two = run_with_threads(scene, cloud, 2);
    let again = run_with_threads(scene, cloud, 2);
    assert!(
        one.4 == two.4,
        "{name}: masses differ between 1 and 2 threads"
    );
    assert!(one == two, "{name}: 1 and 2 threads differ");
    assert!(two == again, "{name}: two runs differ");
}

fn assets() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/assets"))
}

#[test]
fn the_hat_scene_with_resampling() {
    // The hat pulled up by its crown, resampled every 30 steps (points are inserted).
    let scenes = assets().join("scenes");
    let (scene, base) = Scene::load(&scenes.join("hat.ron")).unwrap();
    assert!(scene.resample.is_some());
    assert_deterministic("hat.ron", &scene, &base.join(&scene.cloud));
}

#[test]
fn the_kitten_scan_through_the_collapsed_mesh() {
    // At 1 % the scan's rings leave holes: its dense points' own network is collapsed onto
    // the simulation points (a mesh built with hash maps and edge flips), its normals are
    // estimated and oriented, its masses shared from the dense area. Pulled by its head.
    let cloud = assets().join("kitten.off");
    let points = read_cloud(&cloud, None).unwrap();
    let top = points
        .positions()
        .iter()
        .copied()
        .max_by(|a, b| a.y.total_cmp(&b.y))
        .unwrap();
    let feet = points
        .positions()
        .iter()
        .map(|p| p.y)
        .fold(f32::INFINITY, f32::min);
    let scene = Scene {
        cloud: "kitten.off".into(),
        normals: Default::default(),
        simplify: SimplifyConfig::target(52),
        material: Default::default(),
        solver: SolverConfig {
            integrator: Integrator::ImplicitEuler,
            ..SolverConfig::default()
        },
        transfer: Default::default(),
        resample: None,
        pressure: None,
        dt: 1.0 / 60.0,
        steps: 60,
        pins: vec![Region::Box {
            min: Vec3::new(-2.0, feet - 1.0, -2.0),
            max: Vec3::new(2.0, feet + 0.08, 2.0),
        }],
        pulls: vec![Pull {
            at: top,
            radius: Some(0.15),
            to: top,
            to_end: Some(top + Vec3::X * 0.1),
            stiffness: 300.0,
            damping: 1.0,
            start: 0,
            end: None,
        }],
        error_budget: None,
    };
    assert_deterministic("kitten at 1 %", &scene, &cloud);
}

#[test]
fn the_sphere_poke_scene_on_hinges() {
    let scenes = assets().join("scenes");
    let (mut scene, base) = Scene::load(&scenes.join("sphere_poke.ron")).unwrap();
    scene.material.bending = bevy_point_springs::core::solver::BendingModel::Hinges;
    assert_deterministic(
        "sphere_poke.ron on hinges",
        &scene,
        &base.join(&scene.cloud),
    );
}

#[test]
fn the_sphere_poke_scene() {
    let scenes = assets().join("scenes");
    let (scene, base) = Scene::load(&scenes.join("sphere_poke.ron")).unwrap();
    assert_deterministic("sphere_poke.ron", &scene, &base.join(&scene.cloud));
}
