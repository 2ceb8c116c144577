//! Unit tests of the transfer's rows against the long way.

use super::*;

/// Every row's output the long way: rest position plus fitted displacement, normal from
/// the rest frame plus the fitted slopes.
fn long_way(t: &Transfer, displacements: &[Vec3]) -> (Vec<Vec3>, Vec<Vec3>) {
    let d = simd_displacements(displacements);
    (0..t.len())
        .map(|i| {
            let (u, g1, g2) = t.fitted(i, &d);
            let (t1, t2) = tangent_frame(t.normals[i]);
            let n = (Vec3A::from(t1) + g1).cross(Vec3A::from(t2) + g2);
            (t.rest[i] + Vec3::from(u), Vec3::from(n).normalize())
        })
        .unzip()
}

#[test]
fn rows_from_current_positions_match_the_long_way() {
    // A frame computes most rows from the simulation points' current positions alone,
    // and the rows whose fit misses the rest surface (here: plane fits on a sphere,
    // with k = 4, and ridge fits to collinear points) from the displacements. Both must give what the long way gives, for
    // a motion that is neither rigid nor affine, away from the origin, with the
    // default k (unrolled) and another (not).
    let offset = Vec3::new(10.0, -3.0, 2.0);
    let moved = |cloud: crate::core::cloud::PointCloud| -> (Vec<Vec3>, Vec<Vec3>) {
        let p = cloud.positions().iter().map(|&p| p + offset).collect();
        (p, cloud.normals().unwrap().to_vec())
    };
    let (dense, normals) = moved(crate::core::cloud::shapes::fibonacci_sphere(3000, 1.0));
    let (sim, _) = moved(crate::core::cloud::shapes::fibonacci_sphere(300, 1.0));
    let (sheet, sheet_normals) = moved(crate::core::cloud::shapes::square_sheet(2.0, 0.05));
    let (sheet_sim, _) = moved(crate::core::cloud::shapes::square_sheet(2.0, 0.2));
    let wave = |x: Vec3| {
        let q = x - offset;
        Vec3::new((2.0 * q.y).sin(), q.x * q.z, (3.0 * q.x).cos() * q.y) * 0.1
    };
    // Collinear simulation points: ridge fits.
    let line: Vec<Vec3> = (0..20)
        .map(|i| offset + Vec3::new(i as f32 * 0.1 - 1.0, 0.03, 0.0))
        .collect();
    let (mut residual_seen, mut regularised_seen) = (false, false);
    for (p, n, s, k) in [
        (&dense, &normals, &sim, 4),
        (&dense, &normals, &sim, DEFAULT_TRANSFER_K),
        (&sheet, &sheet_normals, &sheet_sim, DEFAULT_TRANSFER_K),
        (&sheet, &sheet_normals, &line, DEFAULT_TRANSFER_K),
    ] {
        let config = TransferConfig {
            k,
            ..TransferConfig::default()
        };
        let t = Transfer::new(p, n, s, config).unwrap();
        let report = t.report();
        assert_eq!(report.residual, t.residual_rows.len());
        residual_seen |= report.residual > 0;
        regularised_seen |= report.regularised > 0;
        // At rest, the rest surface comes back.
        let (rest_p, rest_n) = t.deform(&vec![Vec3::ZERO; s.len()]).unwrap();
        for i in 0..p.len() {
            assert!(rest_p[i].distance(p[i]) < 2e-6, "k {k}, {i}");
            assert!(rest_n[i].distance(n[i]) < 1e-5, "k {k}, {i}");
        }
        let disp: Vec<Vec3> = s.iter().map(|&x| wave(x)).collect();
        let (pos, nrm) = t.deform(&disp).unwrap();
        let mut positions_only = vec![Vec3::ZERO; p.len()];
        t.apply_positions(&disp, &mut positions_only).unwrap();
        let (long_p, long_n) = long_way(&t, &disp);
        for i in 0..p.len() {
            assert!(pos[i].distance(long_p[i]) < 2e-6, "k {k}, {i}");
            assert!(positions_only[i].distance(long_p[i]) < 2e-6, "k {k}, {i}");
            assert!(nrm[i].distance(long_n[i]) < 1e-5, "k {k}, {i}");
        }
    }
    assert!(residual_seen && regularised_seen);
}

#[test]
fn frame_is_right_handed() {
    for n in [
        Vec3::X,
        Vec3::Y,
        -Vec3::Z,
        Vec3::new(0.3, -0.4, 0.866).normalize(),
    ] {
        let (t1, t2) = tangent_frame(n);
        assert!((t1.cross(t2) - n).length() < 1e-6);
        assert!(t1.dot(n).abs() < 1e-6 && t2.dot(n).abs() < 1e-6);
    }
}
