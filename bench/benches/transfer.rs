//! Displacement transfer (§5): the precomputed sparse product against the paper's literal
//! per-frame method (k-NN search, 3 × 3 solve per point, PCA normals), both parallel, in
//! the same run.
//!
//! `cargo bench --no-default-features --bench transfer`. The target: at least 100×
//! faster on the 3203-point sphere (338 simulation points, as in the paper's Table 1) and
//! on a 10^6-point sphere with 10^4 simulation points.

use std::hint::black_box;
use std::time::Duration;

use bevy_point_springs::core::cloud::shapes::fibonacci_sphere;
use bevy_point_springs::core::simplify::{SimplifyConfig, simplify};
use bevy_point_springs::core::transfer::{Transfer, TransferConfig};
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use glam::Vec3;
use point_springs_bench::baselines::paper_transfer::literal_transfer;

/// Neighbours for the literal method's PCA normals.
const PCA_K: usize = 10;

/// A smooth bulge over the upper half: displacement along the radius, largest at the top.
fn bulge(sim: &[Vec3]) -> Vec<Vec3> {
    sim.iter()
        .map(|s| *s * 0.2 * s.y.max(0.0).powi(2))
        .collect()
}

fn transfer(c: &mut Criterion) {
    let mut group = c.benchmark_group("transfer");
    group.sample_size(10);
    // The paper's sphere: simulation points chosen by §3. The large one: a 10^4-point sphere
    // as simulation points (simplifying 10^6 points takes half a minute of set-up).
    let paper = fibonacci_sphere(3203, 1.0);
    let (p, n) = (paper.positions(), paper.normals().unwrap());
    let kept = simplify(p, n, &SimplifyConfig::target(338)).unwrap();
    let (paper_sim, _) = kept.gather(p, n);
    let large = fibonacci_sphere(1_000_000, 1.0);
    let large_sim = fibonacci_sphere(10_000, 1.0);
    let cases = [
        ("3203_to_338", &paper, paper_sim),
        ("1e6_to_1e4", &large, large_sim.positions().to_vec()),
    ];
    for (name, dense, sim) in cases {
        let (p, n) = (dense.positions(), dense.normals().unwrap());
        let disp = bulge(&sim);
        let config = TransferConfig::default();
        group.measurement_time(Duration::from_secs(if p.len() > 100_000 { 30 } else { 5 }));
        group.bench_with_input(BenchmarkId::new("precompute", name), &name, |b, _| {
            b.iter(|| Transfer::new(black_box(p), n, &sim, config).unwrap())
        });
        let t = Transfer::new(p, n, &sim, config).unwrap();
        let mut positions = vec![Vec3::ZERO; p.len()];
        let mut normals = vec![Vec3::ZERO; p.len()];
        group.bench_with_input(BenchmarkId::new("precomputed", name), &name, |b, _| {
            b.iter(|| {
                t.apply(black_box(&disp), &mut positions, &mut normals)
                    .unwrap()
            })
        });
        group.bench_with_input(
            BenchmarkId::new("precomputed_positions_only", name),
            &name,
            |b, _| b.iter(|| t.apply_positions(black_box(&disp), &mut positions).unwrap()),
        );
        group.bench_with_input(BenchmarkId::new("literal", name), &name, |b, _| {
            b.iter(|| literal_transfer(black_box(p), n, &sim, &disp, config, PCA_K))
        });
    }
    group.finish();
}

criterion_group!(benches, transfer);
criterion_main!(benches);
