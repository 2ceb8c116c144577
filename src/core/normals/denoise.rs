//! The surface simplification and the network decide on, when a scan is noisy.
//!
//! The paper's tests (§3, §4.1) project a point's neighbours on its tangent plane and
//! triangulate them there. On a scan whose noise is comparable to the point spacing, the
//! neighbours scatter above and below that plane by as much as they lie apart along it: their
//! projections cross, rings open where the surface is whole, and the local triangulations
//! disagree (the CGAL sphere scan, whose noise is about 1.6 spacings, kept 9 holes and 1285
//! boundary points at 1500 simulation points). So, when a cloud is noisy, the decisions are
//! made on its points *projected on local plane fits* (a moving-least-squares step of degree
//! one, the surface of the paper's §2 reference \[1\]): each point moves along the normal of the
//! least-squares plane through its neighbours onto that plane, and takes that plane's normal.
//! The simulation points are still chosen among the input's points; the network is built on
//! their projected positions, so its springs and masses describe the smooth surface, while the
//! dense points keep their own positions (and their noise) through the transfer.
//!
//! * [`noise_level`] measures the noise: the median, over up to [`NOISE_SAMPLES`] points, of
//!   the RMS distance of a point's [`NOISE_K`] nearest neighbours to their least-squares
//!   quadric height field (over their least-squares plane; a quadric follows curvature, so
//!   detail does not count as noise), scaled for the six fitted parameters, in mean
//!   nearest-neighbour spacings.
//! * [`Denoise::Auto`] projects when the level is above [`AUTO_NOISE_LEVEL`].
//! * [`project_on_fits`] fits each plane to enough neighbours that the noise averages out:
//!   a radius of about four noise deviations, between [`MIN_FIT_K`] and [`MAX_FIT_K`] points.

use std::borrow::Cow;

use glam::{DMat3, DVec3, Vec3};
use rayon::prelude::*;

use crate::core::cloud::knn::KnnIndex;
use crate::core::normals::smallest_eigenvector;

/// Neighbours of each sampled point for the noise measure.
pub const NOISE_K: usize = 16;

/// Points sampled (evenly through the cloud) for the noise measure.
pub const NOISE_SAMPLES: usize = 4096;

/// Noise level (RMS distance to local planes, in spacings) above which [`Denoise::Auto`]
/// projects the points on local fits.
pub const AUTO_NOISE_LEVEL: f32 = 0.35;

/// Fewest neighbours a projecting plane fit uses.
pub const MIN_FIT_K: usize = 24;

/// Most neighbours a projecting plane fit uses (bounds the cost on very noisy clouds).
pub const MAX_FIT_K: usize = 128;

/// Points per rayon task in [`project_on_fits`].
const FIT_CHUNK: usize = 1024;

/// Whether simplification and the network decide on the points projected on local fits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum Denoise {
    /// Project when the measured [`noise_level`] is above [`AUTO_NOISE_LEVEL`].
    #[default]
    Auto,
    /// Always project.
    On,
    /// Never project (the paper's method as written).
    Off,
}

/// The noise of a cloud: see the module docs. 0 for fewer than [`NOISE_K`] + 1 points.
pub fn noise_level(positions: &[Vec3], index: &KnnIndex) -> f32 {
    let n = positions.len();
    if n <= NOISE_K {
        return 0.0;
    }
    let stride = n.div_ceil(NOISE_SAMPLES);
    let samples: Vec<(f32, f32)> = (0..n)
        .step_by(stride)
        .collect::<Vec<_>>()
        .par_iter()
        .filter_map(|&i| {
            let near = index.nearest(positions[i], NOISE_K + 1);
            let nearest = near.iter().map(|nb| nb.dist2).find(|&d| d > 0.0)?.sqrt();
            let points: Vec<Vec3> = near.iter().map(|nb| positions[nb.index as usize]).collect();
            let rms = quadric_residual(positions[i], &points)?;
            Some((rms, nearest))
        })
        .collect();
    if samples.is_empty() {
        return 0.0;
    }
    let spacing = samples.iter().map(|s| f64::from(s.1)).sum::<f64>() / samples.len() as f64;
    let mut rms: Vec<f32> = samples.iter().map(|s| s.0).collect();
    rms.sort_unstable_by(f32::total_cmp);
    (f64::from(rms[rms.len() / 2]) / spacing) as f32
}

/// Whether `mode` projects a cloud of noise `level`.
pub fn projects(mode: Denoise, level: f32) -> bool {
    match mode {
        Denoise::Auto => level > AUTO_NOISE_LEVEL,
        Denoise::On => true,
        Denoise::Off => false,
    }
}

/// Neighbours a projecting fit uses at noise `level`: 160·level², enough for a radius of
/// about four noise deviations (the measure reads low on strong noise: 0.59 for a deviation
/// of 0.5 spacings, 0.89 for 1.5, as noise shrinks the nearest-neighbour spacing too).
pub fn fit_k(level: f32) -> usize {
    ((160.0 * level * level).ceil() as usize).clamp(MIN_FIT_K, MAX_FIT_K)
}

/// Each point moved onto the least-squares plane through its `k` nearest neighbours, with that
/// plane's normal (turned to agree with the point's own normal). A point whose neighbourhood
/// has no plane keeps its position and normal.
pub fn project_on_fits(
    positions: &[Vec3],
    normals: &[Vec3],
    index: &KnnIndex,
    k: usize,
) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut out = vec![(Vec3::ZERO, Vec3::ZERO); positions.len()];
    out.par_chunks_mut(FIT_CHUNK)
        .enumerate()
        .for_each(|(chunk, rows)| {
            let mut points = Vec::with_capacity(k + 1);
            for (row, slot) in rows.iter_mut().enumerate() {
                let i = chunk * FIT_CHUNK + row;
                *slot = project_on_fit(positions[i], normals[i], positions, index, k, &mut points);
            }
        });
    out.into_iter().unzip()
}

/// Point `p` (normal `n`) moved onto the least-squares plane through its `k` nearest
/// neighbours among the indexed `positions`, with that plane's normal turned to agree with `n`;
/// `(p, n)` where the neighbourhood has no plane. `scratch` is reused between calls.
pub fn project_on_fit(
    p: Vec3,
    n: Vec3,
    positions: &[Vec3],
    index: &KnnIndex,
    k: usize,
    scratch: &mut Vec<Vec3>,
) -> (Vec3, Vec3) {
    scratch.clear();
    scratch.extend(
        index
            .nearest(p, k + 1)
            .iter()
            .map(|nb| positions[nb.index as usize]),
    );
    match plane_fit(p, scratch) {
        Some((centre, normal)) => {
            let normal = if normal.dot(n) < 0.0 { -normal } else { normal };
            (p - (p - centre).dot(normal) * normal, normal)
        }
        None => (p, n),
    }
}

/// The positions and normals decisions are made on: `positions` and `normals` themselves, or
/// their projections on local fits when `mode` says so for their [`noise_level`]. Returns the
/// level measured too.
pub fn decision_surface<'a>(
    positions: &'a [Vec3],
    normals: &'a [Vec3],
    mode: Denoise,
) -> (Cow<'a, [Vec3]>, Cow<'a, [Vec3]>, f32) {
    if mode == Denoise::Off || positions.len() <= NOISE_K {
        return (Cow::Borrowed(positions), Cow::Borrowed(normals), 0.0);
    }
    let index = KnnIndex::build(positions);
    let level = noise_level(positions, &index);
    if !projects(mode, level) {
        return (Cow::Borrowed(positions), Cow::Borrowed(normals), level);
    }
    let (p, n) = project_on_fits(positions, normals, &index, fit_k(level));
    (Cow::Owned(p), Cow::Owned(n), level)
}

/// RMS residual of the least-squares quadric height field z = ax² + bxy + cy² + dx + ey + f
/// over the least-squares plane of `points`, scaled by √(n / (n − 6)) for the fitted
/// parameters; `None` when there is no plane or the fit is singular.
fn quadric_residual(origin: Vec3, points: &[Vec3]) -> Option<f32> {
    const TERMS: usize = 6;
    if points.len() <= TERMS {
        return None;
    }
    let (centre, normal) = plane_fit(origin, points)?;
    let (t1, t2) = normal.as_dvec3().any_orthonormal_pair();
    let local: Vec<(f64, f64, f64)> = points
        .iter()
        .map(|p| {
            let d = (*p - centre).as_dvec3();
            (d.dot(t1), d.dot(t2), d.dot(normal.as_dvec3()))
        })
        .collect();
    let scale = local
        .iter()
        .map(|&(x, y, _)| x.abs().max(y.abs()))
        .fold(0.0f64, f64::max);
    if scale <= 0.0 {
        return None;
    }
    let row = |x: f64, y: f64| {
        let (x, y) = (x / scale, y / scale);
        [x * x, x * y, y * y, x, y, 1.0]
    };
    // Normal equations AᵀA c = Aᵀz, solved by Gaussian elimination with partial pivoting.
    let mut m = [[0.0f64; TERMS + 1]; TERMS];
    for &(x, y, z) in &local {
        let r = row(x, y);
        for i in 0..TERMS {
            for j in 0..TERMS {
                m[i][j] += r[i] * r[j];
            }
            m[i][TERMS] += r[i] * z;
        }
    }
    for col in 0..TERMS {
        let pivot = (col..TERMS).max_by(|&a, &b| m[a][col].abs().total_cmp(&m[b][col].abs()))?;
        if m[pivot][col].abs() < 1e-12 * m[0][0].abs().max(1e-300) {
            return None;
        }
        m.swap(col, pivot);
        let pivot_row = m[col];
        for row in m.iter_mut().skip(col + 1) {
            let f = row[col] / pivot_row[col];
            for (x, p) in row.iter_mut().zip(pivot_row).skip(col) {
                *x -= f * p;
            }
        }
    }
    let mut coef = [0.0f64; TERMS];
    for r in (0..TERMS).rev() {
        let tail: f64 = (r + 1..TERMS).map(|c| m[r][c] * coef[c]).sum();
        coef[r] = (m[r][TERMS] - tail) / m[r][r];
    }
    let n = local.len() as f64;
    let sum2: f64 = local
        .iter()
        .map(|&(x, y, z)| {
            let fit: f64 = row(x, y).iter().zip(&coef).map(|(a, b)| a * b).sum();
            (z - fit).powi(2)
        })
        .sum();
    Some((sum2 / (n - TERMS as f64)).sqrt() as f32)
}

/// Centroid and unit normal of the least-squares plane through `points` (computed relative to
/// `origin` in f64), when there is one.
fn plane_fit(origin: Vec3, points: &[Vec3]) -> Option<(Vec3, Vec3)> {
    if points.len() < 3 {
        return None;
    }
    let rel: Vec<DVec3> = points.iter().map(|p| (*p - origin).as_dvec3()).collect();
    let mean = rel.iter().sum::<DVec3>() / rel.len() as f64;
    let mut c = DMat3::ZERO;
    for d in &rel {
        let d = *d - mean;
        c += DMat3::from_cols(d * d.x, d * d.y, d * d.z);
    }
    let normal = smallest_eigenvector(c)?;
    Some((origin + mean.as_vec3(), normal.as_vec3()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::cloud::shapes;

    #[test]
    fn noise_level_follows_the_noise() {
        let clean = shapes::fibonacci_sphere(20_000, 1.0);
        let level = |cloud: &crate::core::PointCloud| {
            noise_level(cloud.positions(), &KnnIndex::build(cloud.positions()))
        };
        let spacing = clean
            .spacing(&KnnIndex::build(clean.positions()))
            .unwrap()
            .mean;
        let l0 = level(&clean);
        assert!(l0 < 0.05, "{l0}");
        let mut last = l0;
        for sigma in [0.1, 0.5, 1.5] {
            let l = level(&shapes::with_noise(&clean, sigma * spacing, 5));
            assert!(l > last, "{sigma}: {l} after {last}");
            last = l;
        }
    }

    #[test]
    fn projection_brings_noisy_points_back_to_the_sphere() {
        let clean = shapes::fibonacci_sphere(20_000, 1.0);
        let spacing = clean
            .spacing(&KnnIndex::build(clean.positions()))
            .unwrap()
            .mean;
        let noisy = shapes::with_noise(&clean, 1.5 * spacing, 9);
        let off = |p: &[Vec3]| {
            (p.iter()
                .map(|x| f64::from(x.length() - 1.0).powi(2))
                .sum::<f64>()
                / p.len() as f64)
                .sqrt() as f32
        };
        let (p, n, level) =
            decision_surface(noisy.positions(), noisy.normals().unwrap(), Denoise::Auto);
        assert!(projects(Denoise::Auto, level), "{level}");
        let before = off(noisy.positions());
        let after = off(&p);
        assert!(after < 0.4 * before, "{after} vs {before}");
        // Normals: close to radial.
        let mean_cos = p
            .iter()
            .zip(n.iter())
            .map(|(x, m)| f64::from(x.normalize().dot(*m)))
            .sum::<f64>()
            / p.len() as f64;
        assert!(mean_cos > 0.95, "{mean_cos}");
        // A clean cloud is left as it is.
        let (p, _, _) =
            decision_surface(clean.positions(), clean.normals().unwrap(), Denoise::Auto);
        assert!(matches!(p, Cow::Borrowed(_)));
    }
}
