//! The generated scene the benchmarks share: the paper's Fig. 5 sphere at any size.

use std::path::PathBuf;

use bevy_point_springs::core::PointCloud;
use bevy_point_springs::core::cloud::shapes::fibonacci_sphere;
use bevy_point_springs::core::scene::{Pull, Region, Scene};
use bevy_point_springs::core::simplify::SimplifyConfig;
use bevy_point_springs::core::solver::{Integrator, SolverConfig, SpringMaterial};
use glam::Vec3;

/// The step of the generated scene, s.
pub const POKED_SPHERE_DT: f32 = 1.0 / 60.0;

/// The sphere of the paper's Fig. 5 at any size, held in its cup and pressed from above for
/// the whole run (the points never come to rest, so no transfer is skipped).
pub fn poked_sphere(dense: usize, sim: usize, steps: usize) -> (Scene, PointCloud) {
    let scene = Scene {
        cloud: PathBuf::from(format!("<generated sphere of {dense} points>")),
        normals: Default::default(),
        simplify: SimplifyConfig::target(sim),
        material: SpringMaterial {
            stretch_stiffness: 60.0,
            bend_stiffness: 60.0,
            stretch_damping: 0.6,
            bend_damping: 0.3,
            ..SpringMaterial::default()
        },
        solver: SolverConfig {
            integrator: Integrator::ImplicitEuler,
            gravity: Vec3::ZERO,
            drag: 4.0,
            ..SolverConfig::default()
        },
        transfer: Default::default(),
        resample: None,
        pressure: Some(1000.0),
        dt: POKED_SPHERE_DT,
        steps,
        pins: vec![Region::Box {
            min: Vec3::splat(-2.0),
            max: Vec3::new(2.0, -0.6, 2.0),
        }],
        pulls: vec![Pull {
            at: Vec3::Y,
            radius: Some(0.3),
            to: Vec3::Y,
            to_end: Some(Vec3::Y * 0.55),
            stiffness: 300.0,
            damping: 1.0,
            start: 0,
            end: None,
        }],
        error_budget: None,
    };
    (scene, fibonacci_sphere(dense, 1.0))
}
