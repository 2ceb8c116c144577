//! Displacement transfer (§5): exact for rigid and affine motion, exact normals for them,
//! robust on degenerate neighbourhoods. (The paper's literal per-frame method against it is
//! `bench/tests/baselines.rs`.)

use std::path::Path;

use bevy_point_springs::core::cloud::io::read_cloud;
use bevy_point_springs::core::cloud::shapes;
use bevy_point_springs::core::simplify::{SimplifyConfig, simplify};
use bevy_point_springs::core::transfer::{
    MAX_SIMULATION_POINTS, NARROW_INDEX_LIMIT, Transfer, TransferConfig, TransferError,
};
use glam::{Mat3, Quat, Vec3};

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

/// A test surface: name, dense positions, dense normals, simulation points.
type Case = (&'static str, Vec<Vec3>, Vec<Vec3>, Vec<Vec3>);

fn surfaces() -> Vec<Case> {
    let asset = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/sphere926.pwn");
    let scan = read_cloud(&asset, None).unwrap();
    let mut out = Vec::new();
    for (name, cloud, target) in [
        ("sphere", shapes::fibonacci_sphere(3203, 1.0), 338),
        ("hat", shapes::hat(3000, 1.0, shapes::HAT_DEFAULT_RIM), 300),
        ("sheet", shapes::square_sheet(2.0, 0.04), 200),
        ("sphere926.pwn", scan, 150),
    ] {
        let (p, n, s) = surface(&cloud, target);
        out.push((name, p, n, s));
    }
    out
}

/// The affine map x ↦ M x + b applied as displacements of the simulation points; checks
/// every dense point's position and normal against the same map.
fn check_affine(m: Mat3, b: Vec3) {
    for (name, dense, normals, sim) in surfaces() {
        let transfer = Transfer::new(&dense, &normals, &sim, TransferConfig::default()).unwrap();
        let disp: Vec<Vec3> = sim.iter().map(|s| m * *s + b - *s).collect();
        let (pos, nrm) = transfer.deform(&disp).unwrap();
        let scale = disp.iter().map(|d| d.length()).fold(0.0, f32::max);
        let cofactor = m.inverse().transpose();
        let mut worst_p: f32 = 0.0;
        let mut worst_n: f32 = 0.0;
        for i in 0..dense.len() {
            let expected = m * dense[i] + b;
            worst_p = worst_p.max((pos[i] - expected).length() / scale);
            let expected_n = (cofactor * normals[i]).normalize();
            worst_n = worst_n.max((nrm[i] - expected_n).length());
        }
        assert!(
            worst_p < 1e-5,
            "{name}: relative position error {worst_p:e}"
        );
        assert!(worst_n < 1e-5, "{name}: normal error {worst_n:e}");
        let r = transfer.report();
        assert_eq!(r.regularised, 0, "{name}: {r:?}");
        if name == "sheet" {
            // Flat: the paper's plane fit everywhere.
            assert_eq!(r.full, 0, "{name}: {r:?}");
        } else {
            // Curved: the fit with the normal coordinate almost everywhere.
            assert!(r.full > dense.len() * 9 / 10, "{name}: {r:?}");
        }
    }
}

#[test]
fn a_rigid_motion_is_reproduced_at_every_dense_point() {
    let rotation = Mat3::from_quat(Quat::from_axis_angle(
        Vec3::new(1.0, 2.0, 3.0).normalize(),
        0.7,
    ));
    check_affine(rotation, Vec3::new(0.3, -0.2, 0.5));
}

#[test]
fn an_affine_displacement_is_reproduced_with_exact_normals() {
    let m = Mat3::from_cols_array(&[1.3, 0.1, -0.2, 0.05, 0.75, 0.15, 0.1, 0.2, 1.4]);
    check_affine(m, Vec3::new(0.1, -0.2, 0.3));
}

#[test]
fn a_translation_is_exact_even_where_the_fit_is_degenerate() {
    // Simulation points on a line: no plane fit; the slopes are damped, the value is a
    // weighted mean, so translations still come through exactly and nothing is NaN.
    let sim: Vec<Vec3> = (0..10)
        .map(|i| Vec3::new(i as f32 * 0.1, 0.0, 0.0))
        .collect();
    let dense: Vec<Vec3> = (0..50)
        .map(|i| Vec3::new(i as f32 * 0.02, 0.01 * (i % 3) as f32, 0.0))
        .collect();
    let normals = vec![Vec3::Z; dense.len()];
    let transfer = Transfer::new(&dense, &normals, &sim, TransferConfig::default()).unwrap();
    assert_eq!(transfer.report().regularised, dense.len());
    let t = Vec3::new(0.5, -1.0, 2.0);
    let (pos, nrm) = transfer.deform(&vec![t; sim.len()]).unwrap();
    for i in 0..dense.len() {
        assert!((pos[i] - dense[i] - t).length() < 1e-5);
        assert!((nrm[i] - Vec3::Z).length() < 1e-5);
    }
    // A wild displacement stays finite.
    let wild: Vec<Vec3> = (0..sim.len())
        .map(|i| Vec3::splat(1e6 * (i as f32 - 5.0)))
        .collect();
    let (pos, nrm) = transfer.deform(&wild).unwrap();
    assert!(pos.iter().chain(&nrm).all(|v| v.is_finite()));
    assert!(nrm.iter().all(|n| (n.length() - 1.0).abs() < 1e-4));
}

#[test]
fn one_simulation_point_moves_everything_with_it() {
    let dense = shapes::fibonacci_sphere(100, 1.0);
    let (p, n) = (dense.positions(), dense.normals().unwrap());
    let transfer = Transfer::new(p, n, &[Vec3::ZERO], TransferConfig::default()).unwrap();
    let (pos, nrm) = transfer.deform(&[Vec3::X]).unwrap();
    for i in 0..p.len() {
        assert!((pos[i] - p[i] - Vec3::X).length() < 1e-6);
        assert!((nrm[i] - n[i]).length() < 1e-6);
    }
}

#[test]
fn crushed_neighbourhoods_keep_their_rest_normal() {
    let sheet = shapes::square_sheet(1.0, 0.05);
    let (p, n, sim) = surface(&sheet, 60);
    let transfer = Transfer::new(&p, &n, &sim, TransferConfig::default()).unwrap();
    // Every simulation point to the origin: the tangents collapse.
    let disp: Vec<Vec3> = sim.iter().map(|s| -*s).collect();
    let (pos, nrm) = transfer.deform(&disp).unwrap();
    assert!(pos.iter().all(|q| q.length() < 1e-4));
    assert!(nrm.iter().zip(&n).all(|(a, b)| (*a - *b).length() < 1e-6));
}

#[test]
fn bad_input_gets_typed_errors() {
    let p = [Vec3::ZERO, Vec3::X];
    let n = [Vec3::Z, Vec3::Z];
    let c = TransferConfig::default();
    assert_eq!(
        Transfer::new(&p, &n, &[], c).unwrap_err(),
        TransferError::NoSimulationPoints
    );
    assert!(matches!(
        Transfer::new(&p, &n[..1], &p, c),
        Err(TransferError::LengthMismatch { .. })
    ));
    assert!(matches!(
        Transfer::new(&p, &[Vec3::Z, Vec3::ZERO], &p, c),
        Err(TransferError::InvalidPoint {
            which: "dense",
            index: 1
        })
    ));
    assert!(matches!(
        Transfer::new(&p, &n, &[Vec3::NAN], c),
        Err(TransferError::InvalidPoint {
            which: "simulation",
            ..
        })
    ));
    assert_eq!(
        Transfer::new(&p, &n, &p, TransferConfig { k: 0, ..c }).unwrap_err(),
        TransferError::KOutOfRange(0)
    );
    assert_eq!(
        Transfer::new(
            &p,
            &n,
            &p,
            TransferConfig {
                bandwidth: -1.0,
                ..c
            }
        )
        .unwrap_err(),
        TransferError::InvalidBandwidth(-1.0)
    );
    let t = Transfer::new(&p, &n, &p, c).unwrap();
    assert!(matches!(
        t.deform(&[Vec3::ZERO]),
        Err(TransferError::DisplacementCount {
            expected: 2,
            found: 1
        })
    ));
    let mut short = [Vec3::ZERO; 1];
    assert!(matches!(
        t.apply_positions(&[Vec3::ZERO; 2], &mut short),
        Err(TransferError::OutputLength { .. })
    ));
    // Too many simulation points is refused before anything is built for them.
    let crowd = vec![Vec3::ZERO; MAX_SIMULATION_POINTS + 1];
    assert!(matches!(
        Transfer::new(&p, &n, &crowd, c),
        Err(TransferError::TooManySimulationPoints(count)) if count == MAX_SIMULATION_POINTS + 1
    ));
}

/// Mean distance from each point to its 6 nearest, averaged over the cloud.
fn mean_spacing(points: &[Vec3]) -> f32 {
    let index = bevy_point_springs::core::cloud::knn::KnnIndex::build(points);
    let spacing = index.knn_graph(points, 6).mean_distances();
    spacing.iter().sum::<f32>() / points.len() as f32
}

#[test]
fn resampling_fills_a_stretched_sheet() {
    use bevy_point_springs::core::transfer::resample::{ResampleConfig, ResampleError, Resampler};
    let sheet = shapes::square_sheet(1.0, 0.02);
    let (dense, normals, sim) = surface(&sheet, 150);
    let mut transfer = Transfer::new(&dense, &normals, &sim, TransferConfig::default()).unwrap();
    let mut resampler = Resampler::new(&transfer);
    // Stretch 2.5 times along X: past the factor of 1.5 once, not twice.
    let disp: Vec<Vec3> = sim.iter().map(|s| Vec3::new(1.5 * s.x, 0.0, 0.0)).collect();
    let rest = mean_spacing(&dense);
    let (before, _) = transfer.deform(&disp).unwrap();
    let stretched = mean_spacing(&before) / rest;
    assert!(stretched > 1.5, "{stretched}");
    let config = ResampleConfig::default();
    let report = resampler.resample(&mut transfer, &disp, &config).unwrap();
    assert!(!report.capped);
    assert_eq!(report.passes, 1, "{report:?}");
    // About one new point per old one: the spacing along X is halved.
    let n = dense.len();
    assert!(
        report.inserted > n * 8 / 10 && report.inserted < n * 15 / 10,
        "{report:?} of {n}"
    );
    assert_eq!(transfer.len(), n + report.inserted);
    let (after, normals_after) = transfer.deform(&disp).unwrap();
    let ratio = mean_spacing(&after) / rest;
    assert!(
        ratio < config.factor,
        "spacing grew by {ratio} after resampling"
    );
    // The new points lie on the stretched sheet and face the same way.
    assert!(
        after
            .iter()
            .all(|p| p.z.abs() < 1e-5 && p.x.abs() <= 1.25 + 1e-4)
    );
    assert!(normals_after.iter().all(|m| (m.z.abs() - 1.0).abs() < 1e-5));
    // Nothing to do once the surface is back at rest.
    let mut again = resampler.clone();
    let zero = vec![Vec3::ZERO; sim.len()];
    assert_eq!(
        again
            .resample(&mut transfer, &zero, &config)
            .unwrap()
            .inserted,
        0
    );
    // Bad settings are refused.
    let bad = ResampleConfig {
        factor: 1.0,
        ..config
    };
    assert!(resampler.resample(&mut transfer, &disp, &bad).is_err());
    // So are displacements that do not match the simulation points.
    assert!(matches!(
        resampler.resample(&mut transfer, &disp[1..], &config),
        Err(ResampleError::Transfer(
            TransferError::DisplacementCount { .. }
        ))
    ));
}

#[test]
fn fine_networks_reproduce_a_rigid_motion_too() {
    // 10^5 dense points following 10^4 simulation points (fine: the neighbours barely leave
    // the tangent plane, the fit with the normal coordinate still holds).
    let dense = shapes::fibonacci_sphere(100_000, 1.0);
    let sim = shapes::fibonacci_sphere(10_000, 1.0);
    let (p, n) = (dense.positions(), dense.normals().unwrap());
    let transfer = Transfer::new(p, n, sim.positions(), TransferConfig::default()).unwrap();
    assert_eq!(transfer.report().full, p.len(), "{:?}", transfer.report());
    let rotation = Mat3::from_quat(Quat::from_axis_angle(
        Vec3::new(-2.0, 1.0, 0.5).normalize(),
        1.1,
    ));
    let t = Vec3::new(-0.4, 0.1, 0.2);
    let disp: Vec<Vec3> = sim
        .positions()
        .iter()
        .map(|s| rotation * *s + t - *s)
        .collect();
    let (pos, nrm) = transfer.deform(&disp).unwrap();
    let scale = disp.iter().map(|d| d.length()).fold(0.0, f32::max);
    for i in 0..p.len() {
        assert!(
            (pos[i] - (rotation * p[i] + t)).length() < 1e-5 * scale,
            "{i}"
        );
        assert!((nrm[i] - rotation * n[i]).length() < 1e-5, "{i}");
    }
}

#[test]
fn more_than_65536_simulation_points_take_wide_indices() {
    // Up to 2^16 simulation points, neighbour indices are stored in 16 bits; past that, in 32.
    // Both give the same transfer: a rigid motion comes back exactly, and the last simulation
    // points (whose indices do not fit in 16 bits) are followed too.
    let k = TransferConfig::default().k;
    for sims in [NARROW_INDEX_LIMIT, NARROW_INDEX_LIMIT + 4000] {
        let sim = shapes::fibonacci_sphere(sims, 1.0);
        // The dense points: a cap around the last simulation points (whose indices need all
        // 32 bits when there are more than 2^16).
        let (p, n) = (
            &sim.positions()[sims - 3000..],
            &sim.normals().unwrap()[sims - 3000..],
        );
        let transfer = Transfer::new(p, n, sim.positions(), TransferConfig::default()).unwrap();
        let index_bytes = if sims <= NARROW_INDEX_LIMIT { 2 } else { 4 };
        // Per dense point: k indices, and three 4-byte coefficients for each neighbour but
        // the anchor; every row of the sphere reproduces the rest surface.
        assert_eq!(transfer.report().residual, 0, "{sims}");
        assert_eq!(
            transfer.coefficient_bytes(),
            p.len() * (k * index_bytes + 3 * 4 * (k - 1)),
            "{sims}"
        );
        let rotation = Mat3::from_quat(Quat::from_axis_angle(
            Vec3::new(1.0, 2.0, -1.0).normalize(),
            0.7,
        ));
        let disp: Vec<Vec3> = sim.positions().iter().map(|s| rotation * *s - *s).collect();
        let (pos, nrm) = transfer.deform(&disp).unwrap();
        let mut worst: f32 = 0.0;
        for i in 0..p.len() {
            worst = worst.max((pos[i] - rotation * p[i]).length());
            assert!((nrm[i] - rotation * n[i]).length() < 1e-5, "{sims}: {i}");
        }
        assert!(worst < 1e-5, "{sims}: {worst}");
        // A displacement of only the last simulation point moves the dense point at its
        // place, and only points near it.
        let mut one = vec![Vec3::ZERO; sims];
        one[sims - 1] = Vec3::X;
        let (pos, _) = transfer.deform(&one).unwrap();
        let moved = |i: usize| (pos[i] - p[i]).x;
        assert!(moved(p.len() - 1) > 0.2, "{sims}: {}", moved(p.len() - 1));
        assert_eq!(moved(0), 0.0, "{sims}");
    }
}
