//! Normal estimation + orientation on a 10^6-point procedural sphere, and its stages.
//!
//! `cargo bench --bench normals`. The target: the whole pipeline (k-d tree, k-NN graph,
//! PCA, orientation) under 2 s for 10^6 points on a 2-core machine.

use std::hint::black_box;
use std::time::Duration;

use bevy_point_springs::core::cloud::knn::{KnnIndex, morton_order};
use bevy_point_springs::core::cloud::shapes::fibonacci_sphere;
use bevy_point_springs::core::normals::{
    DEFAULT_NORMAL_K, estimate_normals, orient_normals, pca_normals,
};
use criterion::{Criterion, criterion_group, criterion_main};

const MILLION: usize = 1_000_000;

fn normals(c: &mut Criterion) {
    let sphere = fibonacci_sphere(MILLION, 1.0);
    let positions = sphere.positions();
    let mut group = c.benchmark_group("normals_1e6");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(20));
    group.bench_function("total (index + graph + pca + orient)", |b| {
        b.iter(|| estimate_normals(black_box(positions), DEFAULT_NORMAL_K).unwrap())
    });
    // The stages below run as `estimate_normals` runs them: on the points in Morton order.
    group.bench_function("stage: morton order", |b| {
        b.iter(|| morton_order(black_box(positions)))
    });
    let sorted: Vec<_> = morton_order(positions)
        .iter()
        .map(|&i| positions[i as usize])
        .collect();
    let positions = &sorted[..];
    group.bench_function("stage: kd-tree build", |b| {
        b.iter(|| KnnIndex::build(black_box(positions)))
    });
    let index = KnnIndex::build(positions);
    group.bench_function("stage: knn graph (k = 10)", |b| {
        b.iter(|| index.knn_graph(black_box(positions), DEFAULT_NORMAL_K))
    });
    let graph = index.knn_graph(positions, DEFAULT_NORMAL_K);
    group.bench_function("stage: pca", |b| {
        b.iter(|| pca_normals(black_box(positions), &graph))
    });
    let (unoriented, _) = pca_normals(positions, &graph);
    group.bench_function("stage: orientation", |b| {
        b.iter(|| {
            let mut n = unoriented.clone();
            orient_normals(black_box(positions), &mut n, &graph).unwrap()
        })
    });
    group.finish();
}

criterion_group!(benches, normals);
criterion_main!(benches);
