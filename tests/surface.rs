//! Simplification (§3) and the spring network (§4.1–4.2) on the paper's cases, real scans and
//! degenerate input.

use std::f32::consts::PI;

use bevy_point_springs::core::cloud::io::read_cloud;
use bevy_point_springs::core::network::{
    NetworkConfig, NetworkError, SpringNetwork, build_network,
};
use bevy_point_springs::core::normals::{DEFAULT_NORMAL_K, ensure_normals};
use bevy_point_springs::core::simplify::{
    Simplification, SimplifyConfig, SimplifyError, StopReason, simplify, simplify_cloud,
};
use bevy_point_springs::core::{PointCloud, cloud::shapes};
use glam::{DVec3, Vec3};
use proptest::prelude::*;
use spade::{DelaunayTriangulation, HasPosition, Point2, Triangulation};

#[allow(dead_code)]
#[path = "support/surfaces.rs"]
mod surfaces;
use surfaces::*;

#[derive(Clone, Copy)]
struct Projected {
    pos: Point2<f64>,
    index: usize,
}

impl HasPosition for Projected {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> {
        self.pos
    }
}

/// Surface area of the convex hull of points on a sphere centred at the origin, computed
/// independently of the network: stereographic projection from one of the points maps the
/// hull's faces to the Delaunay triangles of the projected others (faces at the pole to the
/// hull edges of the projection).
fn spherical_hull_area(points: &[Vec3]) -> f64 {
    let unit: Vec<DVec3> = points.iter().map(|p| p.as_dvec3().normalize()).collect();
    let pole = unit[0];
    let (t1, t2) = pole.any_orthonormal_pair();
    let mut tri: DelaunayTriangulation<Projected> = DelaunayTriangulation::new();
    for (index, x) in unit.iter().enumerate().skip(1) {
        let y = (*x - x.dot(pole) * pole) / (1.0 - x.dot(pole));
        tri.insert(Projected {
            pos: Point2::new(y.dot(t1), y.dot(t2)),
            index,
        })
        .unwrap();
    }
    let p3 = |i: usize| points[i].as_dvec3();
    let area = |a: DVec3, b: DVec3, c: DVec3| 0.5 * (b - a).cross(c - a).length();
    let mut total = 0.0;
    for face in tri.inner_faces() {
        let [a, b, c] = face.vertices().map(|v| v.data().index);
        total += area(p3(a), p3(b), p3(c));
    }
    for edge in tri.convex_hull() {
        total += area(
            p3(0),
            p3(edge.from().data().index),
            p3(edge.to().data().index),
        );
    }
    total
}

#[test]
fn paper_sphere_simplifies_to_table_1_sizes() {
    let sphere = shapes::fibonacci_sphere(shapes::PAPER_SPHERE_POINTS, 1.0);
    let rho = 2.5;
    let sphere_mass = rho * 4.0 * PI;
    for target in [85usize, 273, 338] {
        let (kept, net) = network_of(&sphere, target, rho);
        assert_eq!(kept.kept.len(), target);
        assert_eq!(kept.stop, StopReason::TargetReached);
        assert_valid(&net);
        let r = net.report;
        assert_eq!((r.points, r.components, r.boundary_points), (target, 1, 0));
        // Consistent rings triangulate the sphere: Euler's E = 3V − 6.
        assert_eq!(r.stretch_springs, 3 * target - 6, "{r:?}");
        let hull = rho as f64 * spherical_hull_area(&net.positions);
        let vs_sphere = r.total_mass / sphere_mass - 1.0;
        let vs_hull = f64::from(r.total_mass) / hull - 1.0;
        println!(
            "{target} points: Σm = {:.4}, ρ4πr² = {sphere_mass:.4} ({:+.2} %), ρ·hull = {hull:.4} ({:+.3} %), {} stretch, {} bend",
            r.total_mass,
            100.0 * vs_sphere,
            100.0 * vs_hull,
            r.stretch_springs,
            r.bend_springs
        );
        assert!(vs_sphere.abs() < 0.05, "{vs_sphere}");
        assert!(vs_hull.abs() < 0.015, "{vs_hull}");
    }
}

#[test]
fn hat_keeps_one_clean_boundary_loop() {
    let rim = shapes::HAT_DEFAULT_RIM;
    let hat = shapes::hat(4000, 1.0, rim);
    let (_, net) = network_of(&hat, 300, 1.0);
    let rel = assert_one_rim_loop(&net, rim);
    let r = net.report;
    println!("hat: {r:?}, Σm vs area {:+.2} %", 100.0 * rel);
}

/// Asserts that a hat's network is valid, one piece with one boundary loop, its boundary
/// points on the rim (within a sampling step) and every point on the rim a boundary point,
/// and its mass within 5 % of the hat's area; returns the mass's relative error.
fn assert_one_rim_loop(net: &SpringNetwork, rim: f32) -> f32 {
    assert_valid(net);
    let r = net.report;
    assert_eq!((r.components, r.boundary_loops), (1, 1), "{r:?}");
    let step = r.max_diameter;
    for (p, b) in net.positions.iter().zip(&net.boundary) {
        if *b {
            assert!(
                p.y > rim - 0.5 * step,
                "boundary point {p} far from the rim"
            );
        }
    }
    let rim_count = net
        .positions
        .iter()
        .filter(|p| p.y > rim - 0.05 * step)
        .count();
    assert!(
        r.boundary_points >= rim_count,
        "{r:?}, {rim_count} points on the rim"
    );
    let area = 2.0 * PI * (1.0 + rim);
    let rel = r.total_mass / area - 1.0;
    assert!(rel.abs() < 0.05, "Σm vs area {rel}");
    rel
}

/// Simplifies `cloud` on every thread and on one, asserts the two agree bit for bit, and
/// returns the result.
fn simplify_on_any_thread_count(cloud: &PointCloud, config: &SimplifyConfig) -> Simplification {
    let run = || simplify_cloud(cloud, config).unwrap();
    let a = run();
    let one_thread = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(run);
    assert_eq!(a.kept, one_thread.kept);
    let bits = |s: &Simplification| s.diameters.iter().map(|d| d.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a), bits(&one_thread));
    a
}

#[test]
fn flat_sheet_mass_matches_its_area() {
    let side = 2.0;
    let sheet = shapes::square_sheet(side, 0.04);
    let rho = 0.3;
    let (_, net) = network_of(&sheet, 300, rho);
    assert_valid(&net);
    let r = net.report;
    assert_eq!((r.components, r.boundary_loops), (1, 1), "{r:?}");
    let rel = r.total_mass / (rho * side * side) - 1.0;
    println!("sheet: {r:?}, Σm vs ρ·area {:+.2} %", 100.0 * rel);
    assert!(rel.abs() < 0.03, "{rel}");
}

#[test]
fn letter_b_keeps_its_two_counters() {
    let b = shapes::letter_b(1.0, 0.01);
    let (_, net) = network_of(&b, 600, 1.0);
    assert_valid(&net);
    // The outline and the two holes.
    assert_eq!(net.report.boundary_loops, 3, "{:?}", net.report);
    assert_eq!(net.report.components, 1);
}

#[test]
fn real_scans_give_valid_networks() {
    // sphere926.pwn: a closed scan with the file's normals.
    let cloud = read_cloud(&asset("sphere926.pwn"), None).unwrap();
    let (_, net) = network_of(&cloud, 150, 1.0);
    assert_valid(&net);
    assert_eq!(
        (net.report.components, net.report.boundary_points),
        (1, 0),
        "{:?}",
        net.report
    );
    // half.xyz: an open half sphere without normals (estimated).
    let mut cloud = read_cloud(&asset("half.xyz"), None).unwrap();
    ensure_normals(&mut cloud, DEFAULT_NORMAL_K).unwrap();
    let (_, net) = network_of(&cloud, 300, 1.0);
    assert_valid(&net);
    assert_eq!(net.report.components, 1, "{:?}", net.report);
    assert_eq!(net.report.boundary_loops, 1, "{:?}", net.report);
}

#[test]
fn simplification_is_deterministic_whatever_the_thread_count() {
    let sphere = shapes::fibonacci_sphere(5000, 1.0);
    let config = SimplifyConfig::target(400);
    let a = simplify_on_any_thread_count(&sphere, &config);
    assert_eq!(a, simplify_cloud(&sphere, &config).unwrap());
}

#[test]
fn a_large_cloud_simplified_in_rounds_keeps_its_rim_its_rules_and_its_bits() {
    // 60 000 points: the first 40 000 removals go in rounds of independent points (the
    // rest one at a time), on both threads.
    let rim = shapes::HAT_DEFAULT_RIM;
    let hat = shapes::hat(60_000, 1.0, rim);
    let config = SimplifyConfig {
        rounds_above: 20_000,
        ..SimplifyConfig::target(600)
    };
    let a = simplify_on_any_thread_count(&hat, &config);
    let (p, n) = a.gather(hat.positions(), hat.normals().unwrap());
    let net = build_network(&p, &n, &NetworkConfig::default()).unwrap();
    assert_one_rim_loop(&net, rim);
    // The threshold rule holds exactly after rounds too.
    let sphere = shapes::fibonacci_sphere(40_000, 1.0);
    let d = 0.1;
    let in_rounds = SimplifyConfig {
        rounds_above: 20_000,
        ..SimplifyConfig::max_diameter(d)
    };
    let by_threshold = simplify_cloud(&sphere, &in_rounds).unwrap();
    assert_eq!(by_threshold.stop, StopReason::ThresholdReached);
    assert!(by_threshold.min_diameter() >= d);
    let n = by_threshold.kept.len();
    assert!((1_000..20_000).contains(&n), "{n}");
    // Duplicates go in rounds too, one of each pair.
    let mut positions = sphere.positions()[..30_000].to_vec();
    let mut normals = sphere.normals().unwrap()[..30_000].to_vec();
    positions.extend_from_within(..2_000);
    normals.extend_from_within(..2_000);
    let twice = PointCloud::new(positions, Some(normals)).unwrap();
    let config = SimplifyConfig {
        rounds_above: 20_000,
        ..SimplifyConfig::target(3_000)
    };
    let s = simplify_cloud(&twice, &config).unwrap();
    assert_eq!(s.duplicates_removed, 2_000);
    let mut kept: Vec<[u32; 3]> = s
        .kept
        .iter()
        .map(|&i| twice.positions()[i as usize].to_array().map(f32::to_bits))
        .collect();
    kept.sort_unstable();
    kept.dedup();
    assert_eq!(kept.len(), 3_000);
}

#[test]
fn threshold_rule_holds_exactly_and_combines_with_a_target() {
    let sphere = shapes::fibonacci_sphere(3203, 1.0);
    let d = 0.45;
    let by_threshold = simplify_cloud(&sphere, &SimplifyConfig::max_diameter(d)).unwrap();
    assert_eq!(by_threshold.stop, StopReason::ThresholdReached);
    assert!(
        by_threshold.min_diameter() >= d,
        "{}",
        by_threshold.min_diameter()
    );
    let n = by_threshold.kept.len();
    assert!(n > 50 && n < 3203, "{n}");
    // The same network check sees the same diameters.
    let (p, nn) = by_threshold.gather(sphere.positions(), sphere.normals().unwrap());
    let net = build_network(&p, &nn, &NetworkConfig::default()).unwrap();
    assert!(net.report.min_diameter >= d * 0.999, "{:?}", net.report);
    // Both rules: whichever is met first stops.
    let both = |target| SimplifyConfig {
        target: Some(target),
        ..SimplifyConfig::max_diameter(d)
    };
    let early = simplify_cloud(&sphere, &both(n + 100)).unwrap();
    assert_eq!(
        (early.kept.len(), early.stop),
        (n + 100, StopReason::TargetReached)
    );
    let late = simplify_cloud(&sphere, &both(n / 2)).unwrap();
    assert_eq!(
        (late.kept.len(), late.stop),
        (n, StopReason::ThresholdReached)
    );
    assert_eq!(late.kept, by_threshold.kept);
}

#[test]
fn duplicates_are_removed_first_and_never_kept() {
    let sphere = shapes::fibonacci_sphere(1000, 1.0);
    let (p, n) = sphere.clone().into_parts();
    let n = n.unwrap();
    let doubled = PointCloud::new(
        p.iter().chain(&p).copied().collect(),
        Some(n.iter().chain(&n).copied().collect()),
    )
    .unwrap();
    // Even a target above the distinct count removes every duplicate.
    let kept = simplify_cloud(&doubled, &SimplifyConfig::target(1500)).unwrap();
    assert_eq!(kept.duplicates_removed, 1000);
    assert_eq!(kept.kept.len(), 1000);
    let (_, net) = network_of(&doubled, 200, 1.0);
    assert_valid(&net);
    assert!((net.report.total_mass / (4.0 * PI) - 1.0).abs() < 0.05);
    // A network straight on duplicated points is refused, clearly.
    let err = build_network(
        doubled.positions(),
        doubled.normals().unwrap(),
        &NetworkConfig::default(),
    )
    .unwrap_err();
    assert!(
        matches!(err, NetworkError::CoincidentPoints(a, b) if b == a + 1000),
        "{err}"
    );
}

#[test]
fn degenerate_input_gets_typed_errors() {
    let sphere = shapes::fibonacci_sphere(100, 1.0);
    let (p, n) = (sphere.positions(), sphere.normals().unwrap());
    let target = SimplifyConfig::target(20);
    let err = |p: &[Vec3], n: &[Vec3], c: &SimplifyConfig| simplify(p, n, c).unwrap_err();
    assert!(matches!(
        err(&p[..10], &n[..10], &target),
        SimplifyError::TooFewPoints {
            needed: 13,
            found: 10,
            ..
        }
    ));
    let line: Vec<Vec3> = (0..50).map(|i| Vec3::X * i as f32).collect();
    let up = vec![Vec3::Y; 50];
    assert_eq!(err(&line, &up, &target), SimplifyError::NotASurface);
    let same = vec![Vec3::ONE; 50];
    assert_eq!(err(&same, &up, &target), SimplifyError::NotASurface);
    let none = SimplifyConfig {
        target: None,
        ..target
    };
    assert_eq!(err(p, n, &none), SimplifyError::NoStoppingRule);
    assert_eq!(
        err(p, n, &SimplifyConfig { k: 2, ..target }),
        SimplifyError::KOutOfRange(2)
    );
    assert_eq!(
        err(p, n, &SimplifyConfig::target(3)),
        SimplifyError::TargetTooSmall(3)
    );
    for bad in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        assert!(matches!(
            err(p, n, &SimplifyConfig::max_diameter(bad)),
            SimplifyError::InvalidThreshold(_)
        ));
    }
    let mut bad_normals = n.to_vec();
    bad_normals[7] = Vec3::ZERO;
    assert_eq!(
        err(p, &bad_normals, &target),
        SimplifyError::InvalidPoint(7)
    );
    bad_normals[7] = Vec3::NAN;
    assert_eq!(
        err(p, &bad_normals, &target),
        SimplifyError::InvalidPoint(7)
    );
    assert!(matches!(
        err(p, &n[1..], &target),
        SimplifyError::LengthMismatch { .. }
    ));
    let no_normals = PointCloud::new(p.to_vec(), None).unwrap();
    assert_eq!(
        simplify_cloud(&no_normals, &target).unwrap_err(),
        SimplifyError::NoNormals
    );

    let net = |p: &[Vec3], n: &[Vec3], c: NetworkConfig| build_network(p, n, &c).unwrap_err();
    let cfg = NetworkConfig::default();
    assert!(matches!(
        net(&p[..3], &n[..3], cfg),
        NetworkError::TooFewPoints { .. }
    ));
    assert_eq!(net(&line, &up, cfg), NetworkError::NotASurface);
    assert!(matches!(
        net(
            p,
            n,
            NetworkConfig {
                density: 0.0,
                ..cfg
            }
        ),
        NetworkError::InvalidDensity(_)
    ));
    assert!(matches!(
        net(
            p,
            n,
            NetworkConfig {
                density: f32::NAN,
                ..cfg
            }
        ),
        NetworkError::InvalidDensity(_)
    ));
    assert_eq!(
        net(p, n, NetworkConfig { k: 100, ..cfg }),
        NetworkError::KOutOfRange(100)
    );
    // Every error says what is wrong in words.
    assert!(SimplifyError::NotASurface.to_string().contains("collinear"));
}

#[test]
fn a_plane_with_a_stray_line_still_gives_a_valid_network() {
    // A sheet with a row of points sticking out of it: stragglers get fallback springs.
    let sheet = shapes::square_sheet(1.0, 0.05);
    let (mut p, n) = sheet.into_parts();
    let mut n = n.unwrap();
    for i in 1..6 {
        p.push(Vec3::new(0.0, 0.0, 0.05 * i as f32));
        n.push(Vec3::X);
    }
    let net = build_network(&p, &n, &NetworkConfig::default()).unwrap();
    assert_valid(&net);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(
        std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(24)
    ))]

    /// Jittered sheets of any size and tilt: simplify + network always gives a valid network.
    #[test]
    fn jittered_sheets_give_valid_networks(
        side in 0.5f32..5.0,
        jitter in 0.0f32..0.4,
        tilt in 0.0f32..1.5,
        seed in any::<u32>(),
        keep in 0.05f32..0.9,
    ) {
        let spacing = side / 30.0;
        let sheet = shapes::square_sheet(side, spacing);
        let rot = glam::Quat::from_rotation_x(tilt);
        let (p, _) = sheet.into_parts();
        let p: Vec<Vec3> = p
            .iter()
            .enumerate()
            .map(|(i, v)| {
                let h = |s: u32| {
                    ((i as u32 ^ seed).wrapping_mul(2_654_435_761).wrapping_add(s)) as f32
                        / u32::MAX as f32
                        - 0.5
                };
                rot * (*v + Vec3::new(h(1), h(2), h(3) * 0.2) * jitter * spacing)
            })
            .collect();
        let n = vec![rot * Vec3::Z; p.len()];
        let target = ((p.len() as f32 * keep) as usize).max(20);
        let kept = simplify(&p, &n, &SimplifyConfig::target(target)).unwrap();
        prop_assert_eq!(kept.kept.len(), target);
        let (sp, sn) = kept.gather(&p, &n);
        let net = build_network(&sp, &sn, &NetworkConfig::default()).unwrap();
        assert_valid(&net);
        prop_assert_eq!(net.report.components, 1);
        let rel = net.report.total_mass / (side * side) - 1.0;
        prop_assert!(rel.abs() < 0.2, "Σm off by {}", rel);
    }
}
