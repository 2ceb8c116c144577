//! The solver's step: the standard cloth benchmark against the straightforward loop over the
//! springs (same run, one thread), and every integrator on a simplified point-cloud sphere.
//!
//! `cargo bench --no-default-features --bench solver`. The target: at least 3× fewer
//! µs per cloth step than the straightforward loop.

use std::hint::black_box;

use bevy_point_springs::core::cloud::shapes::fibonacci_sphere;
use bevy_point_springs::core::network::{NetworkConfig, build_network};
use bevy_point_springs::core::simplify::{SimplifyConfig, simplify};
use bevy_point_springs::core::solver::cloth::{CLOTH_DT, CLOTH_SIZE, cloth_grid};
use bevy_point_springs::core::solver::{
    Integrator, Solver, SolverConfig, SpringMaterial, SubstepPolicy,
};
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use point_springs_bench::baselines::cloth::ReferenceCloth;

/// Steps per measured iteration (one benchmark run is 1000 steps; a tenth of it is timed per
/// iteration so criterion can take many samples).
const STEPS: usize = 100;

fn cloth(c: &mut Criterion) {
    let grid = cloth_grid(CLOTH_SIZE).unwrap();
    let mut group = c.benchmark_group("cloth_grid_100_steps");
    group.bench_function("solver", |b| {
        let mut solver = grid.solver().unwrap();
        b.iter(|| {
            for _ in 0..STEPS {
                black_box(solver.step(CLOTH_DT).unwrap());
            }
        })
    });
    group.bench_function("straightforward", |b| {
        let mut reference = ReferenceCloth::new(&grid);
        b.iter(|| {
            for _ in 0..STEPS {
                reference.step(black_box(CLOTH_DT));
            }
        })
    });
    // What a game would run instead: implicit Euler at 60 Hz.
    group.bench_function("implicit_60hz_one_step", |b| {
        let mut solver = grid
            .solver_with(Integrator::ImplicitEuler, SubstepPolicy::default())
            .unwrap();
        b.iter(|| black_box(solver.step(1.0 / 60.0).unwrap()))
    });
    group.finish();
}

/// One step on simplified spheres: explicit schemes at their own stable step (one
/// sub-step, so the figure is the cost per sub-step), implicit Euler at 60 Hz.
fn sphere(c: &mut Criterion) {
    let mut group = c.benchmark_group("sphere_network_step");
    for (dense, target) in [(3203, 338), (100_000, 10_000)] {
        let cloud = fibonacci_sphere(dense, 1.0);
        let (p, n) = (cloud.positions(), cloud.normals().unwrap());
        let kept = simplify(p, n, &SimplifyConfig::target(target)).unwrap();
        let (sp, sn) = kept.gather(p, n);
        let network = build_network(&sp, &sn, &NetworkConfig::default()).unwrap();
        for integrator in Integrator::ALL {
            let config = SolverConfig {
                integrator,
                ..SolverConfig::default()
            };
            let mut solver =
                Solver::from_network(&network, &SpringMaterial::default(), config).unwrap();
            solver.set_fixed(0, true).unwrap();
            let dt = if integrator.is_explicit() {
                solver.stability().dt(integrator) * config.stability_margin
            } else {
                1.0 / 60.0
            };
            group.bench_with_input(
                BenchmarkId::new(integrator.name(), target),
                &target,
                |b, _| b.iter(|| black_box(solver.step(dt).unwrap())),
            );
        }
    }
    group.finish();
}

criterion_group!(benches, cloth, sphere);
criterion_main!(benches);
