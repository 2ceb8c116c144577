//! The library against the baselines its benchmarks time it against: the same answers,
//! so the timings compare like with like.

use bevy_point_springs::core::cloud::shapes;
use bevy_point_springs::core::simplify::{SimplifyConfig, simplify};
use bevy_point_springs::core::solver::cloth::{CLOTH_DT, CLOTH_SIZE, CLOTH_STEPS, cloth_grid};
use bevy_point_springs::core::transfer::{Transfer, TransferConfig};
use glam::Vec3;
use point_springs_bench::baselines::cloth::{ReferenceCloth, max_sag};
use point_springs_bench::baselines::paper_transfer::literal_transfer;

#[test]
fn cloth_grid_sag_matches_the_straightforward_loop() {
    let grid = cloth_grid(CLOTH_SIZE).unwrap();
    assert_eq!(grid.springs.len(), 5826);
    let mut solver = grid.solver().unwrap();
    let mut reference = ReferenceCloth::new(&grid);
    for _ in 0..CLOTH_STEPS {
        let r = solver.step(CLOTH_DT).unwrap();
        assert!(r.finite && !r.recovered && r.substeps == 1);
        reference.step(CLOTH_DT);
    }
    let sag = max_sag(&grid.positions, &solver.positions());
    let reference_sag = max_sag(&grid.positions, &reference.x);
    assert!(sag > 1.0, "the cloth fell {sag}");
    assert!(
        (sag - reference_sag).abs() < 1e-3,
        "{sag} vs {reference_sag}"
    );
    let worst = solver
        .positions()
        .iter()
        .zip(&reference.x)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f32::max);
    assert!(worst < 1e-3, "positions differ by {worst}");
    // The fixed corners stayed put.
    for i in grid.fixed {
        assert_eq!(solver.position(i as usize), grid.positions[i as usize]);
    }
}

/// Dense cloud (positions, normals) and simulation points chosen from it by §3.
fn surface(
    cloud: &bevy_point_springs::core::PointCloud,
    target: usize,
) -> (Vec<Vec3>, Vec<Vec3>, Vec<Vec3>) {
    let (p, n) = (cloud.positions(), cloud.normals().unwrap());
    let kept = simplify(p, n, &SimplifyConfig::target(target)).unwrap();
    let (sim, _) = kept.gather(p, n);
    (p.to_vec(), n.to_vec(), sim)
}

#[test]
fn the_literal_method_agrees_on_a_smooth_deformation() {
    let cloud = shapes::fibonacci_sphere(3203, 1.0);
    let (dense, normals, sim) = surface(&cloud, 338);
    // A smooth bulge: displacement along the normal, largest at the top.
    let disp: Vec<Vec3> = sim
        .iter()
        .map(|s| *s * 0.2 * s.y.max(0.0).powi(2))
        .collect();
    let config = TransferConfig::default();
    let transfer = Transfer::new(&dense, &normals, &sim, config).unwrap();
    let (pos, nrm) = transfer.deform(&disp).unwrap();
    let (lit_pos, lit_nrm) = literal_transfer(&dense, &normals, &sim, &disp, config, 10);
    let worst_p = pos
        .iter()
        .zip(&lit_pos)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f32::max);
    // Both fits are linear and the bulge is not: they differ by about the bulge's second
    // derivative times the neighbourhood's size squared (0.4 × 0.15² ≈ 0.01).
    assert!(worst_p < 0.02, "{worst_p}");
    let mean_cos = nrm
        .iter()
        .zip(&lit_nrm)
        .map(|(a, b)| a.dot(*b))
        .sum::<f32>()
        / nrm.len() as f32;
    assert!(mean_cos > 0.995, "{mean_cos}");
}
