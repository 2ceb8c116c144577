//! Simplification (§3) + spring network (§4) on procedural spheres of 10^4, 10^5 and 10^6
//! points, each simplified a hundredfold, so the cost curve can be read off.
//!
//! `cargo bench --no-default-features --bench simplify`. The target: 10^6 points to
//! 10^4 simulation points in under 20 s on a 2-core machine.

use std::hint::black_box;
use std::time::Duration;

use bevy_point_springs::core::cloud::shapes::fibonacci_sphere;
use bevy_point_springs::core::network::{NetworkConfig, build_network};
use bevy_point_springs::core::simplify::{SimplifyConfig, simplify};
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};

/// Input sizes; each is simplified to 1 % of its points.
const SIZES: [usize; 3] = [10_000, 100_000, 1_000_000];

/// Reduction factor.
const RATIO: usize = 100;

fn simplify_and_network(c: &mut Criterion) {
    let mut group = c.benchmark_group("simplify_network");
    group.sample_size(10);
    for n in SIZES {
        let sphere = fibonacci_sphere(n, 1.0);
        let (positions, normals) = (sphere.positions(), sphere.normals().unwrap());
        let config = SimplifyConfig::target(n / RATIO);
        // Seconds per run grow with n: give the big runs the time they need.
        group.measurement_time(Duration::from_secs(if n >= 1_000_000 { 120 } else { 10 }));
        group.bench_with_input(BenchmarkId::new("simplify", n), &n, |b, _| {
            b.iter(|| simplify(black_box(positions), normals, &config).unwrap())
        });
        let kept = simplify(positions, normals, &config).unwrap();
        let (p, nn) = kept.gather(positions, normals);
        group.bench_with_input(BenchmarkId::new("network", n), &n, |b, _| {
            b.iter(|| build_network(black_box(&p), &nn, &NetworkConfig::default()).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, simplify_and_network);
criterion_main!(benches);
