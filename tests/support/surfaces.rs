//! Surfaces shared by the surface tests (`tests/surface.rs`, `tests/watertight.rs`),
//! included by path: Cargo does not build files in a folder under `tests/` as tests of
//! their own.

use std::path::Path;

use bevy_point_springs::core::PointCloud;
use bevy_point_springs::core::network::{
    DenseSupport, NetworkConfig, SpringNetwork, build_network_over,
};
use bevy_point_springs::core::simplify::{Simplification, SimplifyConfig, simplify_cloud};

pub fn asset(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets")
        .join(name)
}

/// Simplifies `cloud` to `target` points and builds the network with density `rho`.
pub fn network_of(cloud: &PointCloud, target: usize, rho: f32) -> (Simplification, SpringNetwork) {
    let kept = simplify_cloud(cloud, &SimplifyConfig::target(target)).unwrap();
    let (p, n) = kept.gather(cloud.positions(), cloud.normals().unwrap());
    let config = NetworkConfig {
        density: rho,
        ..NetworkConfig::default()
    };
    let dense = DenseSupport::new(
        cloud.positions(),
        cloud.normals().unwrap(),
        kept.noise_level,
        kept.projected.is_some(),
    )
    .with_triangles(cloud.faces());
    let net = build_network_over(&p, &n, &config, Some(&dense)).unwrap();
    (kept, net)
}

/// The invariants every network must hold, whatever its input.
pub fn assert_valid(net: &SpringNetwork) {
    let n = net.len();
    assert!(n >= 4);
    let mut degree = vec![0usize; n];
    let mut pairs = std::collections::HashSet::new();
    for s in &net.stretch {
        assert!(s.a < s.b && (s.b as usize) < n, "{s:?}");
        assert!(s.rest_length > 0.0 && s.rest_length.is_finite(), "{s:?}");
        assert!(pairs.insert((s.a, s.b)), "duplicate stretch spring {s:?}");
        degree[s.a as usize] += 1;
        degree[s.b as usize] += 1;
    }
    for s in &net.bend {
        assert!(s.a < s.b && (s.b as usize) < n, "{s:?}");
        assert!(s.rest_length > 0.0 && s.rest_length.is_finite(), "{s:?}");
        assert!(
            pairs.insert((s.a, s.b)),
            "bend spring repeats a spring {s:?}"
        );
    }
    assert!(
        degree.iter().all(|&d| d >= 3),
        "a point has fewer than 3 stretch springs: min {}",
        degree.iter().min().unwrap()
    );
    assert!(net.masses.iter().all(|m| m.is_finite() && *m > 0.0));
    assert!(net.positions.iter().all(|p| p.is_finite()));
    for (i, d) in degree.iter().enumerate() {
        // Rings hold exactly the stretch neighbours.
        assert_eq!(net.ring(i).len(), *d);
    }
    let total: f64 = net.masses.iter().map(|m| f64::from(*m)).sum();
    assert!((total as f32 - net.report.total_mass).abs() <= 1e-4 * total as f32);
    // The mesh under the springs: manifold, no fold-overs, its report consistent.
    let r = net.report;
    assert_eq!((r.non_manifold_edges, r.fold_overs), (0, 0), "{r:?}");
    assert_eq!(r.triangles, net.triangles.len());
    assert_eq!(r.closed, r.boundary_points == 0, "{r:?}");
    assert!(!r.closed || r.boundary_loops == 0, "{r:?}");
}

/// Simplifies `cloud` to `fraction` of its points and builds the network.
pub fn network_at(cloud: &PointCloud, fraction: f64) -> SpringNetwork {
    let target = ((cloud.len() as f64 * fraction).round() as usize).max(4);
    network_of(cloud, target, 1.0).1
}
