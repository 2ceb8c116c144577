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

/// A sphere's dense and simulation points, with the simulation points below y = −0.5 pinned.
fn pinned_sphere() -> (Vec<Vec3>, Vec<Vec3>, Vec<Vec3>, Vec<bool>) {
    let dense = crate::core::cloud::shapes::fibonacci_sphere(3000, 1.0);
    let sim = crate::core::cloud::shapes::fibonacci_sphere(300, 1.0)
        .positions()
        .to_vec();
    let pinned = sim.iter().map(|p| p.y < -0.5).collect();
    let (p, n) = dense.into_parts();
    (p, n.unwrap(), sim, pinned)
}

#[test]
fn held_rows_follow_the_pins_alone() {
    let (p, n, sim, pinned) = pinned_sphere();
    let mut t = Transfer::new(&p, &n, &sim, TransferConfig::default()).unwrap();
    let pins = Pins {
        simulation: pinned.clone(),
        dense: Vec::new(),
    };
    let refit = t.hold(&pins).unwrap();
    assert!(refit > 0 && t.report().held > 0 && t.report().held <= refit);
    assert_eq!(
        t.hold(&pins).unwrap(),
        0,
        "the same pins again: nothing to do"
    );
    // The free points wave; the pins hold still, then turn rigidly about an axis through
    // the origin.
    let wave = |x: Vec3| Vec3::new((3.0 * x.y).sin(), x.x * x.z, 0.5) * 0.2;
    let index = KnnIndex::build(&sim);
    let nearest_pinned = |i: usize| pinned[index.nearest(p[i], 1)[0].index as usize];
    for turn in [glam::Quat::IDENTITY, glam::Quat::from_rotation_z(0.3)] {
        let disp: Vec<Vec3> = sim
            .iter()
            .zip(&pinned)
            .map(|(&x, &pin)| if pin { turn * x - x } else { wave(x) })
            .collect();
        let (pos, nrm) = t.deform(&disp).unwrap();
        let mut moved = 0.0f32;
        for i in 0..p.len() {
            // Every row whose nearest is pinned is held, and a few more close to a pin.
            assert!(t.kinds[i].held || !nearest_pinned(i), "{i}");
            if !t.kinds[i].held {
                moved = moved.max(pos[i].distance(p[i]));
                continue;
            }
            // Still pins hold every row; a turn comes back exactly where the pinned
            // neighbours' fit reproduces the rest surface (not where a held row has too
            // few pinned neighbours for more than a plane or a mean).
            if turn == glam::Quat::IDENTITY || !t.residual_rows.contains(&i) {
                assert!(pos[i].distance(turn * p[i]) < 2e-6, "{i}");
                assert!(nrm[i].distance(turn * n[i]) < 1e-4, "{i}");
            }
        }
        assert!(moved > 0.05, "the free part moved {moved}");
    }
}

#[test]
fn holding_again_gives_what_a_transfer_built_with_those_pins_gives() {
    let (p, n, sim, pinned) = pinned_sphere();
    let fresh = Transfer::new(&p, &n, &sim, TransferConfig::default()).unwrap();
    let pins = |pinned: Vec<bool>| Pins {
        simulation: pinned,
        dense: Vec::new(),
    };
    let mut once = fresh.clone();
    once.hold(&pins(pinned.clone())).unwrap();
    // Other pins first (a cap at the top), then these: the same rows, bit for bit.
    let mut twice = fresh.clone();
    twice
        .hold(&pins(sim.iter().map(|x| x.y > 0.6).collect()))
        .unwrap();
    twice.hold(&pins(pinned.clone())).unwrap();
    let bits = |t: &Transfer| -> Vec<u32> { t.coefficients.iter().map(|c| c.to_bits()).collect() };
    assert_eq!(bits(&once), bits(&twice));
    assert_eq!(once.residual_rows, twice.residual_rows);
    // Freed again: the transfer as built.
    twice.hold(&pins(vec![false; sim.len()])).unwrap();
    assert_eq!(bits(&twice), bits(&fresh));
    assert_eq!(twice.report(), fresh.report());
    assert_eq!(
        twice.hold(&pins(vec![true; 3])),
        Err(TransferError::PinCount {
            expected: sim.len(),
            found: 3
        })
    );
}

#[test]
fn named_dense_points_are_held_where_a_pinned_neighbour_is() {
    let (p, n, sim, pinned) = pinned_sphere();
    let mut t = Transfer::new(&p, &n, &sim, TransferConfig::default()).unwrap();
    let by_nearest = {
        let mut u = t.clone();
        u.hold(&Pins {
            simulation: pinned.clone(),
            dense: Vec::new(),
        })
        .unwrap();
        u.report().held
    };
    // A band just above the pinned cap, at the dense resolution.
    let dense: Vec<bool> = p.iter().map(|x| x.y < -0.45).collect();
    t.hold(&Pins {
        simulation: pinned.clone(),
        dense,
    })
    .unwrap();
    assert!(t.report().held > by_nearest);
    // A list of names shorter than the rows (rows added since) names none beyond its end.
    let mut shorter = t.clone();
    let mut names: Vec<bool> = p.iter().map(|x| x.y < -0.45).collect();
    names.truncate(p.len() - 100);
    assert!(
        shorter
            .hold(&Pins {
                simulation: pinned.clone(),
                dense: names,
            })
            .is_ok()
    );
    let disp: Vec<Vec3> = sim
        .iter()
        .zip(&pinned)
        .map(|(_, &pin)| if pin { Vec3::ZERO } else { Vec3::X * 0.1 })
        .collect();
    let (pos, _) = t.deform(&disp).unwrap();
    for i in (0..p.len()).filter(|&i| p[i].y < -0.45) {
        assert!(pos[i].distance(p[i]) < 2e-6, "{i}");
    }
}

#[test]
fn rows_added_under_pins_match_rows_built_then_held() {
    // Resampling adds rows to a transfer already held to its pins: they must be what a
    // transfer built with all the rows and then held gives, bit for bit.
    let (p, n, sim, pinned) = pinned_sphere();
    let pins = Pins {
        simulation: pinned,
        dense: Vec::new(),
    };
    let config = TransferConfig::default();
    let mut whole = Transfer::new(&p, &n, &sim, config).unwrap();
    whole.hold(&pins).unwrap();
    let split = 2000;
    let mut grown = Transfer::new(&p[..split], &n[..split], &sim, config).unwrap();
    grown.hold(&pins).unwrap();
    // (extend takes unit normals, as the resampler hands them; new() normalises its own.)
    let unit: Vec<Vec3> = n.iter().map(|v| v.normalize()).collect();
    grown.extend(&p[split..], &unit[split..], &KnnIndex::build(&sim));
    let bits = |t: &Transfer| -> Vec<u32> { t.coefficients.iter().map(|c| c.to_bits()).collect() };
    assert_eq!(bits(&grown), bits(&whole));
    let indices = |t: &Transfer| match &t.neighbours {
        Neighbours::Narrow(v) => v.iter().map(|&i| u32::from(i)).collect::<Vec<_>>(),
        Neighbours::Wide(v) => v.clone(),
    };
    assert_eq!(indices(&grown), indices(&whole));
    assert_eq!(grown.residual_rows, whole.residual_rows);
    assert_eq!(grown.report(), whole.report());
}
