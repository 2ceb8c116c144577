//! Procedural point-sampled surfaces for tests, benches and examples.
//!
//! Bevy's convention is used throughout: +Y is up. Every shape comes with exact unit normals.
//!
//! * [`fibonacci_sphere`]: n points spread evenly over a sphere (the paper's sphere had 3203).
//! * [`hat`]: the lower part of a sphere, an open surface (the paper's hat, Fig. 6).
//! * [`square_sheet`]: a flat square in the XY plane, normals +Z.
//! * [`letter_b`]: a flat sheet in the shape of the letter "B" (the paper's Fig. 7).
//! * [`uneven_sphere`]: a sphere whose density falls smoothly by a given ratio from pole to
//!   pole, and [`with_noise`]: Gaussian noise on any cloud; both make scan-like test data.
//!
//! The sheets are sampled on a triangular lattice, which has a unique Delaunay triangulation
//! (no four co-circular points), unlike a square grid.

use glam::{Vec2, Vec3};
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};

use crate::core::cloud::PointCloud;

/// The golden angle in radians, π(3 − √5): successive Fibonacci-spiral points turn by it.
pub const GOLDEN_ANGLE: f32 = 2.399_963_3;

/// Point count of the PointShop3D sphere used in the paper (§6).
pub const PAPER_SPHERE_POINTS: usize = 3203;

/// Default height of the hat's rim as a fraction of the radius: the cap below y = −0.2·r.
pub const HAT_DEFAULT_RIM: f32 = -0.2;

/// Height of a triangular-lattice row relative to the point spacing, √3/2.
const LATTICE_ROW: f32 = 0.866_025_4;

/// `n` points evenly spread over a sphere of `radius` centred at the origin (Fibonacci
/// spiral), with outward normals.
pub fn fibonacci_sphere(n: usize, radius: f32) -> PointCloud {
    spiral_band(n, radius, -1.0, 1.0)
}

/// The lower part of a sphere of `radius` (an open "hat"): `n` points evenly spread over the
/// cap y ≤ `rim`·radius, `rim` in (−1, 1], with outward normals (away from the centre).
pub fn hat(n: usize, radius: f32, rim: f32) -> PointCloud {
    spiral_band(n, radius, -1.0, rim.clamp(-1.0, 1.0))
}

/// Fibonacci spiral over the spherical band lo ≤ y/r ≤ hi: equal-area steps in y (Archimedes)
/// and golden-angle steps in azimuth.
fn spiral_band(n: usize, radius: f32, lo: f32, hi: f32) -> PointCloud {
    let mut positions = Vec::with_capacity(n);
    let mut normals = Vec::with_capacity(n);
    for i in 0..n {
        // Top to bottom, so a band's first point is at its rim.
        let y = hi - (hi - lo) * (i as f32 + 0.5) / n as f32;
        let ring = (1.0 - y * y).max(0.0).sqrt();
        let (s, c) = (i as f32 * GOLDEN_ANGLE).sin_cos();
        let normal = Vec3::new(ring * c, y, ring * s);
        normals.push(normal);
        positions.push(normal * radius);
    }
    PointCloud::new(positions, Some(normals)).unwrap_or_default()
}

/// Samples a planar region (given by `inside`) on a triangular lattice of `spacing`, in the XY
/// plane with normals +Z, over the box [`min`, `max`].
fn lattice_sheet(min: Vec2, max: Vec2, spacing: f32, inside: impl Fn(Vec2) -> bool) -> PointCloud {
    let mut positions = Vec::new();
    if spacing > 0.0 && spacing.is_finite() {
        let row_height = spacing * LATTICE_ROW;
        let rows = ((max.y - min.y) / row_height).floor() as usize + 1;
        let cols = ((max.x - min.x) / spacing).floor() as usize + 1;
        for r in 0..rows {
            let shift = if r % 2 == 1 { spacing * 0.5 } else { 0.0 };
            for c in 0..cols {
                let p = Vec2::new(
                    min.x + shift + c as f32 * spacing,
                    min.y + r as f32 * row_height,
                );
                if p.x <= max.x + spacing * 1e-3 && inside(p) {
                    positions.push(p.extend(0.0));
                }
            }
        }
    }
    let normals = vec![Vec3::Z; positions.len()];
    PointCloud::new(positions, Some(normals)).unwrap_or_default()
}

/// A flat square sheet of side `side`, centred at the origin in the XY plane (normals +Z),
/// sampled on a triangular lattice of `spacing`.
pub fn square_sheet(side: f32, spacing: f32) -> PointCloud {
    let h = side * 0.5;
    lattice_sheet(Vec2::splat(-h), Vec2::splat(h), spacing, |_| true)
}

/// A flat sheet shaped like the letter "B", `height` tall, centred at the origin in the XY
/// plane (normals +Z), sampled on a triangular lattice of `spacing`.
///
/// The letter is a vertical stem and two bowls (half-annuli joined to the stem by bars), the
/// lower bowl slightly wider, as in a typical sans-serif "B".
pub fn letter_b(height: f32, spacing: f32) -> PointCloud {
    let h = height;
    let stroke = 0.18 * h;
    let stem_right = stroke;
    let bowl_x = 0.30 * h;
    // (centre y, outer radius) of the upper and lower bowls.
    let bowls = [(0.76 * h, 0.24 * h), (0.265 * h, 0.265 * h)];
    let inside = |p: Vec2| {
        if p.x <= stem_right {
            return p.x >= 0.0 && p.y >= 0.0 && p.y <= h;
        }
        bowls.iter().any(|&(cy, outer)| {
            let inner = outer - stroke;
            let d = p - Vec2::new(bowl_x, cy);
            if p.x <= bowl_x {
                // Bars joining the stem: the bowl's top and bottom strokes.
                (d.y.abs() >= inner) && (d.y.abs() <= outer)
            } else {
                let r = d.length();
                r >= inner && r <= outer
            }
        })
    };
    let width = bowl_x + bowls[1].1;
    let sheet = lattice_sheet(Vec2::ZERO, Vec2::new(width, h), spacing, inside);
    // Centre it.
    let offset = Vec3::new(width * 0.5, h * 0.5, 0.0);
    let (positions, normals) = sheet.into_parts();
    PointCloud::new(positions.into_iter().map(|p| p - offset).collect(), normals)
        .unwrap_or_default()
}

/// A sphere of `radius` sampled with about `n` points whose density falls smoothly (as an
/// exponential in height) from the top pole to the bottom one by `ratio` (10 gives 10:1).
/// Points are kept from a denser Fibonacci sphere, so the result is deterministic for a `seed`.
pub fn uneven_sphere(n: usize, radius: f32, ratio: f32, seed: u64) -> PointCloud {
    let ratio = if ratio.is_finite() {
        ratio.max(1.0)
    } else {
        1.0
    };
    // Mean keep probability over the sphere (y uniform in [-1, 1] by area):
    // ∫ ratio^((y − 1) / 2) dy / 2 = (1 − 1/ratio) / ln(ratio).
    let mean = if ratio > 1.0 {
        (1.0 - 1.0 / ratio) / ratio.ln()
    } else {
        1.0
    };
    let dense = fibonacci_sphere((n as f32 / mean).ceil() as usize, radius);
    let mut rng = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(seed);
    let (positions, normals) = dense.into_parts();
    let normals = normals.unwrap_or_default();
    let (mut p, mut q) = (Vec::new(), Vec::new());
    for (x, m) in positions.into_iter().zip(normals) {
        let keep = ratio.powf((m.y - 1.0) * 0.5);
        if rng.random::<f32>() < keep {
            p.push(x);
            q.push(m);
        }
    }
    PointCloud::new(p, Some(q)).unwrap_or_default()
}

/// `cloud` with isotropic Gaussian noise of standard deviation `sigma` (in the cloud's units)
/// added to every position; normals are kept (those of the surface before the noise), as a
/// scanner that also measured normals would give. Deterministic for a `seed`.
pub fn with_noise(cloud: &PointCloud, sigma: f32, seed: u64) -> PointCloud {
    let mut rng = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut gauss = || -> f32 { StandardNormal.sample(&mut rng) };
    let positions = cloud
        .positions()
        .iter()
        .map(|p| *p + sigma * Vec3::new(gauss(), gauss(), gauss()))
        .collect();
    PointCloud::new(positions, cloud.normals().map(<[Vec3]>::to_vec)).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uneven_sphere_has_its_density_ratio() {
        let s = uneven_sphere(20_000, 1.0, 10.0, 7);
        assert!((s.len() as f32 - 20_000.0).abs() < 600.0, "{}", s.len());
        // Points per unit height near the top and near the bottom (equal areas).
        let top = s.positions().iter().filter(|p| p.y > 0.8).count() as f32;
        let bottom = s.positions().iter().filter(|p| p.y < -0.8).count() as f32;
        // Keep probabilities ratio^((y − 1)/2): about ratio^0.9 apart between y = ±0.9.
        let expected = 10f32.powf(0.9);
        assert!(
            (top / bottom / expected - 1.0).abs() < 0.15,
            "{top} / {bottom}"
        );
    }

    #[test]
    fn noise_has_its_standard_deviation() {
        let s = fibonacci_sphere(20_000, 1.0);
        let noisy = with_noise(&s, 0.01, 3);
        let var = s
            .positions()
            .iter()
            .zip(noisy.positions())
            .map(|(a, b)| f64::from(a.distance_squared(*b)))
            .sum::<f64>()
            / (3.0 * s.len() as f64);
        assert!((var.sqrt() / 0.01 - 1.0).abs() < 0.02, "{}", var.sqrt());
        assert_eq!(noisy.normals(), s.normals());
    }

    #[test]
    fn sphere_points_lie_on_the_sphere() {
        let s = fibonacci_sphere(PAPER_SPHERE_POINTS, 2.0);
        assert_eq!(s.len(), PAPER_SPHERE_POINTS);
        for (p, n) in s.positions().iter().zip(s.normals().unwrap()) {
            assert!((p.length() - 2.0).abs() < 1e-5);
            assert!((*p / 2.0 - *n).length() < 1e-5);
        }
    }

    #[test]
    fn hat_is_below_its_rim() {
        let h = hat(2000, 1.0, HAT_DEFAULT_RIM);
        assert_eq!(h.len(), 2000);
        assert!(h.positions().iter().all(|p| p.y <= HAT_DEFAULT_RIM + 1e-6));
        let b = h.bounds().unwrap();
        assert!((b.min.y + 1.0).abs() < 1e-3);
    }

    #[test]
    fn sheets_have_expected_density() {
        let s = square_sheet(1.0, 0.05);
        // Triangular lattice: one point per (√3/2)·h² of area.
        let expected = 1.0 / (LATTICE_ROW * 0.05 * 0.05);
        assert!(
            (s.len() as f32 - expected).abs() / expected < 0.1,
            "{}",
            s.len()
        );
        let b = letter_b(1.0, 0.02);
        assert!(b.len() > 500);
        let bb = b.bounds().unwrap();
        assert!((bb.max.y - bb.min.y - 1.0).abs() < 0.03);
        // The counters (holes) of the B are empty: the centre of the upper bowl.
        let hole = Vec3::new(0.30 - 0.2825, 0.76 - 0.5, 0.0);
        assert!(b.positions().iter().all(|p| p.distance(hole) > 0.02));
    }
}
