//! Normal estimation and orientation on real scans and procedural surfaces.

use std::path::Path;

use bevy_point_springs::core::cloud::io::read_cloud;
use bevy_point_springs::core::cloud::knn::KnnIndex;
use bevy_point_springs::core::normals::{
    DEFAULT_NORMAL_K, NormalSource, ensure_normals, estimate_normals,
};
use bevy_point_springs::core::{PointCloud, cloud::shapes};
use glam::Vec3;

fn asset(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets")
        .join(name)
}

fn mean(values: impl Iterator<Item = f32>) -> f32 {
    let (sum, n) = values.fold((0.0f64, 0usize), |(s, n), v| (s + f64::from(v), n + 1));
    (sum / n as f64) as f32
}

/// Fraction of k-NN edges whose two normals point to opposite sides (orientation flips).
fn inconsistent_edges(positions: &[Vec3], normals: &[Vec3], k: usize) -> f32 {
    let graph = KnnIndex::build(positions).knn_graph(positions, k);
    let mut bad = 0;
    for (i, n) in normals.iter().enumerate() {
        bad += graph
            .neighbours(i)
            .iter()
            .filter(|&&j| n.dot(normals[j as usize]) < 0.0)
            .count();
    }
    bad as f32 / (positions.len() * k) as f32
}

#[test]
fn sphere926_estimated_normals_match_the_files() {
    let cloud = read_cloud(&asset("sphere926.pwn"), None).unwrap();
    let reference = cloud.normals().unwrap();
    // The file's normals are outward.
    assert!(
        cloud
            .positions()
            .iter()
            .zip(reference)
            .all(|(p, n)| p.dot(*n) > 0.0)
    );
    let (estimated, report) = estimate_normals(cloud.positions(), DEFAULT_NORMAL_K).unwrap();
    let abs_cos = mean(
        estimated
            .iter()
            .zip(reference)
            .map(|(a, b)| a.dot(*b).abs()),
    );
    let cos = mean(estimated.iter().zip(reference).map(|(a, b)| a.dot(*b)));
    println!("sphere926: mean |cos| = {abs_cos:.5}, mean cos = {cos:.5}, {report:?}");
    assert!(abs_cos >= 0.998, "mean |cos| {abs_cos}");
    assert!(cos >= 0.99, "mean cos {cos}");
    assert_eq!(report.components, 1);
}

#[test]
fn hat_normals_are_consistent_and_outward() {
    let hat = shapes::hat(4000, 1.0, shapes::HAT_DEFAULT_RIM);
    let (estimated, report) = estimate_normals(hat.positions(), DEFAULT_NORMAL_K).unwrap();
    let exact = hat.normals().unwrap();
    let cos = mean(estimated.iter().zip(exact).map(|(a, b)| a.dot(*b)));
    let worst = estimated
        .iter()
        .zip(exact)
        .map(|(a, b)| a.dot(*b))
        .fold(1.0f32, f32::min);
    println!("hat: mean cos {cos:.5}, worst {worst:.4}, {report:?}");
    assert_eq!(report.components, 1);
    assert!(cos >= 0.99, "mean cos {cos}");
    assert!(worst > 0.0, "a normal points inward: {worst}");
}

#[test]
fn half_sphere_scan_is_oriented_outward() {
    let cloud = read_cloud(&asset("half.xyz"), None).unwrap();
    let (estimated, report) = estimate_normals(cloud.positions(), DEFAULT_NORMAL_K).unwrap();
    // The scan is half of a sphere centred at the origin: outward is along p.
    let cos = mean(
        cloud
            .positions()
            .iter()
            .zip(&estimated)
            .map(|(p, n)| p.normalize().dot(*n)),
    );
    println!("half.xyz: mean cos to radial {cos:.5}, {report:?}");
    assert!(cos >= 0.98, "mean cos {cos}");
    assert!(inconsistent_edges(cloud.positions(), &estimated, 6) < 0.01);
}

#[test]
fn kitten_scan_is_consistent_and_outward() {
    let cloud = read_cloud(&asset("kitten.off"), None).unwrap();
    let (estimated, report) = estimate_normals(cloud.positions(), DEFAULT_NORMAL_K).unwrap();
    let flips = inconsistent_edges(cloud.positions(), &estimated, 6);
    let centroid = cloud.positions().iter().sum::<Vec3>() / cloud.len() as f32;
    let outward = mean(
        cloud
            .positions()
            .iter()
            .zip(&estimated)
            .map(|(p, n)| n.dot((*p - centroid).normalize_or_zero())),
    );
    println!("kitten: inconsistent edges {flips:.5}, mean outward cos {outward:.4}, {report:?}");
    assert!(flips < 0.01, "inconsistent edges {flips}");
    assert!(outward > 0.3, "mostly inward: {outward}");
}

#[test]
fn sheets_face_plus_z() {
    for sheet in [shapes::square_sheet(1.0, 0.02), shapes::letter_b(1.0, 0.01)] {
        let (estimated, report) = estimate_normals(sheet.positions(), DEFAULT_NORMAL_K).unwrap();
        assert_eq!(report.components, 1);
        assert!(estimated.iter().all(|n| n.z > 0.999), "{report:?}");
    }
}

#[test]
fn noisy_sphere_and_two_components() {
    // A sphere with radial noise of ±1 % of the radius (deterministic hash noise).
    let sphere = shapes::fibonacci_sphere(5000, 1.0);
    let noisy: Vec<Vec3> = sphere
        .positions()
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let h = ((i as u32).wrapping_mul(2_654_435_761) >> 8) as f32 / (1u32 << 24) as f32;
            *p * (1.0 + 0.02 * (h - 0.5))
        })
        .collect();
    let (estimated, _) = estimate_normals(&noisy, DEFAULT_NORMAL_K).unwrap();
    let outward = noisy
        .iter()
        .zip(&estimated)
        .filter(|(p, n)| p.dot(**n) > 0.0)
        .count();
    assert_eq!(outward, noisy.len(), "some noisy normals point inward");

    // Two separate spheres: two components, each outward.
    let mut both = shapes::fibonacci_sphere(2000, 1.0).into_parts().0;
    let centre = Vec3::new(5.0, 0.0, 0.0);
    both.extend(
        shapes::fibonacci_sphere(1500, 0.5)
            .positions()
            .iter()
            .map(|p| *p + centre),
    );
    let (estimated, report) = estimate_normals(&both, DEFAULT_NORMAL_K).unwrap();
    assert_eq!(report.components, 2);
    for (i, (p, n)) in both.iter().zip(&estimated).enumerate() {
        let c = if i < 2000 { Vec3::ZERO } else { centre };
        assert!((*p - c).dot(*n) > 0.0, "point {i} inward");
    }
}

#[test]
fn ensure_normals_keeps_good_and_replaces_zero_normals() {
    let mut sphere = read_cloud(&asset("sphere926.pwn"), None).unwrap();
    let before = sphere.normals().unwrap().to_vec();
    assert_eq!(ensure_normals(&mut sphere, 10).unwrap(), NormalSource::File);
    let after = sphere.normals().unwrap();
    assert!(before.iter().zip(after).all(|(a, b)| a.dot(*b) > 0.9999));

    let zeros = vec![Vec3::ZERO; sphere.len()];
    let mut zeroed = PointCloud::new(sphere.positions().to_vec(), Some(zeros)).unwrap();
    assert!(!zeroed.has_usable_normals());
    let source = ensure_normals(&mut zeroed, 10).unwrap();
    assert!(matches!(source, NormalSource::Estimated(_)));
    assert!(zeroed.has_usable_normals());
}
