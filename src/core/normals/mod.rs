//! Normal estimation (PCA over k nearest neighbours) and consistent orientation.
//!
//! * [`pca_normals`]: for each point, the eigenvector of the smallest eigenvalue of the
//!   covariance of the point and its k nearest neighbours (Hoppe et al. '92; the paper's §3).
//! * [`orient_normals`]: PCA gives a direction without a sign. Signs are made consistent by
//!   propagating from point to point over the symmetrised k-NN graph in order of decreasing
//!   confidence |nᵢ·nⱼ| (Prim's algorithm on the Riemannian graph with cost 1 − |nᵢ·nⱼ|, as in
//!   Hoppe '92, with the angle between normals quantised to 256 levels so that a bucket queue
//!   replaces the binary heap), one traversal per connected component. Each component is then turned
//!   *outward*: the sign of Σ nᵢ·(pᵢ − c) over the component (c its centroid), which for a
//!   closed surface is proportional to its enclosed volume and is positive for caps of a sphere
//!   too. A flat component (that sum ≈ 0) is turned so its mean normal points along the positive
//!   direction of its dominant axis.
//! * [`ensure_normals`]: keeps a cloud's own normals when they are usable, estimates otherwise.

pub mod denoise;

use glam::{DMat3, DVec3, Vec3};
use rayon::prelude::*;

use crate::core::cloud::PointCloud;
use crate::core::cloud::knn::{KnnGraph, KnnIndex, morton_order};

/// Default neighbourhood size for PCA normals (the paper's k lies in 10–20 for simplification;
/// 10 neighbours give stable normals on evenly sampled surfaces at the lowest cost).
pub const DEFAULT_NORMAL_K: usize = 10;

/// Fewest neighbours a plane fit can use.
pub const MIN_NORMAL_K: usize = 3;

/// |Σ n·(p − c)| below this fraction of Σ |p − c| marks a component as flat (no inside).
const FLAT_TOLERANCE: f64 = 1.0e-3;

/// Relative size under which a covariance matrix counts as zero or isotropic.
const DEGENERATE_EPS: f64 = 1.0e-12;

/// Points per rayon task in [`pca_normals`].
const PCA_CHUNK: usize = 2048;

/// Why normals could not be estimated.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum NormalsError {
    /// A plane fit needs at least [`MIN_NORMAL_K`] + 1 points.
    #[error("normal estimation needs at least {needed} points, the cloud has {found}")]
    TooFewPoints {
        /// Points needed.
        needed: usize,
        /// Points in the cloud.
        found: usize,
    },
    /// `k` below [`MIN_NORMAL_K`].
    #[error("normal estimation needs k ≥ {MIN_NORMAL_K} neighbours, got {0}")]
    KTooSmall(usize),
    /// Orientation packs point indices into 31 bits.
    #[error("normal orientation supports at most 2^31 - 1 points, the cloud has {0}")]
    TooManyPoints(usize),
}

/// Where a cloud's normals came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum NormalSource {
    /// The file's own normals (normalised).
    File,
    /// Estimated by PCA and oriented.
    Estimated(OrientationReport),
    /// From the file's faces: each vertex's area-weighted sum of its triangles' normals
    /// (see [`vertex_normals_from_faces`]).
    Faces,
    /// The file's own normals, whose signs disagreed between neighbours too often (more
    /// than [`INCONSISTENT_NORMALS`] of the k-NN pairs): their directions kept, their signs
    /// made consistent and turned outward by [`orient_normals`].
    FileReoriented(OrientationReport),
}

/// The share of k-NN pairs whose file normals point apart (a negative dot product) above
/// which [`ensure_normals`] re-orients them. Signs flipped at random disagree on about half
/// the pairs; consistent normals only where two sides of a thin part or a sharp edge are
/// neighbours: up to 12 % on the CGAL scans (`building.ply`'s thin walls) and 19.5 % on a
/// planar curve's normals (`point_set_2.xyz`).
pub const INCONSISTENT_NORMALS: f32 = 0.3;

/// How many points' neighbourhoods [`reorient_if_inconsistent`] samples (evenly) to
/// estimate the share of disagreeing pairs.
pub const CONSISTENCY_SAMPLE: usize = 20_000;

/// What [`orient_normals`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct OrientationReport {
    /// Connected components of the symmetrised k-NN graph.
    pub components: usize,
    /// Points whose normal ended up with the opposite sign from PCA's.
    pub flipped: usize,
    /// Points whose neighbourhood had no plane (all coincident or isotropic); they got an
    /// arbitrary unit normal before orientation.
    pub degenerate: usize,
}

/// Unit PCA normals (unoriented) from each point's k-NN neighbourhood, in parallel.
///
/// Returns the normals and how many neighbourhoods were degenerate (all points coincident, or
/// spread equally in every direction): those get the +Z axis so nothing is ever NaN.
pub fn pca_normals(positions: &[Vec3], graph: &KnnGraph) -> (Vec<Vec3>, usize) {
    let mut normals = vec![Vec3::ZERO; positions.len()];
    let degenerate: usize = normals
        .par_chunks_mut(PCA_CHUNK)
        .enumerate()
        .map(|(chunk, out)| {
            let mut bad = 0;
            for (row, n) in out.iter_mut().enumerate() {
                let i = chunk * PCA_CHUNK + row;
                *n = match plane_normal(positions[i], graph.neighbours(i), positions) {
                    Some(v) => v,
                    None => {
                        bad += 1;
                        Vec3::Z
                    }
                };
            }
            bad
        })
        .sum();
    (normals, degenerate)
}

/// Normal of the least-squares plane through `centre` and its neighbours, if there is one.
fn plane_normal(centre: Vec3, neighbours: &[u32], positions: &[Vec3]) -> Option<Vec3> {
    // Work relative to the centre point in f64: no cancellation for far-off clouds.
    let rel = |j: u32| (positions[j as usize] - centre).as_dvec3();
    let count = (neighbours.len() + 1) as f64;
    let mean = neighbours.iter().map(|&j| rel(j)).sum::<DVec3>() / count;
    let mut c = [[0.0f64; 3]; 3];
    let mut add = |d: DVec3| {
        let d = d.to_array();
        for r in 0..3 {
            for s in r..3 {
                c[r][s] += d[r] * d[s];
            }
        }
    };
    add(-mean);
    for &j in neighbours {
        add(rel(j) - mean);
    }
    let m = DMat3::from_cols_array_2d(&[
        [c[0][0], c[0][1], c[0][2]],
        [c[0][1], c[1][1], c[1][2]],
        [c[0][2], c[1][2], c[2][2]],
    ]);
    smallest_eigenvector(m).map(|v| v.as_vec3())
}

/// Unit eigenvector of the smallest eigenvalue of a symmetric positive semi-definite 3×3
/// matrix, or `None` when there is no preferred direction (zero or isotropic matrix).
///
/// Eigenvalues by the closed-form trigonometric method; the eigenvector as the largest cross
/// product of two rows of `A − λI`. When the smallest eigenvalue is double (collinear points)
/// any unit vector perpendicular to the dominant direction is returned.
pub fn smallest_eigenvector(a: DMat3) -> Option<DVec3> {
    let scale = a.to_cols_array().iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if !scale.is_finite() || scale <= 0.0 {
        return None;
    }
    let a = a * (1.0 / scale);
    let (a00, a11, a22) = (a.x_axis.x, a.y_axis.y, a.z_axis.z);
    let (a01, a02, a12) = (a.y_axis.x, a.z_axis.x, a.z_axis.y);
    let q = (a00 + a11 + a22) / 3.0;
    let p1 = a01 * a01 + a02 * a02 + a12 * a12;
    let p2 = (a00 - q).powi(2) + (a11 - q).powi(2) + (a22 - q).powi(2) + 2.0 * p1;
    let p = (p2 / 6.0).sqrt();
    if p <= DEGENERATE_EPS {
        return None;
    }
    let b = (a - DMat3::from_diagonal(DVec3::splat(q))) * (1.0 / p);
    let r = (b.determinant() / 2.0).clamp(-1.0, 1.0);
    let phi = r.acos() / 3.0;
    let largest = q + 2.0 * p * phi.cos();
    let smallest = q + 2.0 * p * (phi + 2.0 * std::f64::consts::FRAC_PI_3).cos();
    if let Some(v) = null_vector(a, smallest) {
        return Some(v);
    }
    // Double smallest eigenvalue: the largest one is simple; its eigenvector is the line.
    null_vector(a, largest).map(|line| line.any_orthonormal_vector())
}

/// Unit vector spanning the null space of `A − λI` when that space is one-dimensional.
fn null_vector(a: DMat3, lambda: f64) -> Option<DVec3> {
    let m = a - DMat3::from_diagonal(DVec3::splat(lambda));
    // Rows of a symmetric matrix are its columns.
    let (r0, r1, r2) = (m.x_axis, m.y_axis, m.z_axis);
    let candidates = [r0.cross(r1), r0.cross(r2), r1.cross(r2)];
    let best = candidates
        .into_iter()
        .max_by(|u, v| u.length_squared().total_cmp(&v.length_squared()))?;
    let len2 = best.length_squared();
    (len2 > DEGENERATE_EPS).then(|| best / len2.sqrt())
}

/// Makes the signs of `normals` consistent across each connected component of the symmetrised
/// k-NN graph and turns each component outward (see the module docs).
pub fn orient_normals(
    positions: &[Vec3],
    normals: &mut [Vec3],
    graph: &KnnGraph,
) -> Result<OrientationReport, NormalsError> {
    let n = positions.len();
    if n >= (1 << 31) {
        return Err(NormalsError::TooManyPoints(n));
    }
    let reverse = ReverseEdges::build(graph);
    let mut component = vec![u32::MAX; n];
    let mut flipped_by_pca_sign = vec![false; n];
    let mut queue = BucketQueue::new();
    let mut components = 0u32;
    for seed in 0..n {
        if component[seed] != u32::MAX {
            continue;
        }
        let id = components;
        components += 1;
        queue.push(1.0, seed as u32, false);
        while let Some((i, flip)) = queue.pop() {
            let i = i as usize;
            if component[i] != u32::MAX {
                continue;
            }
            component[i] = id;
            if flip {
                normals[i] = -normals[i];
                flipped_by_pca_sign[i] = true;
            }
            let ni = normals[i];
            for &j in graph.neighbours(i).iter().chain(reverse.of(i)) {
                if component[j as usize] == u32::MAX {
                    let dot = ni.dot(normals[j as usize]);
                    queue.push(dot.abs(), j, dot < 0.0);
                }
            }
        }
    }
    let turned = turn_outward(positions, normals, &component, components as usize);
    let flipped = component
        .iter()
        .zip(&flipped_by_pca_sign)
        .filter(|&(&c, &f)| f != turned[c as usize])
        .count();
    Ok(OrientationReport {
        components: components as usize,
        flipped,
        degenerate: 0,
    })
}

/// Confidence levels of the propagation queue. Edges are popped from the most confident
/// non-empty level (angles between normals quantised to π/2 / 256 ≈ 0.35°), which orders the
/// traversal like Prim's minimum spanning tree while pushing and popping in O(1).
const CONFIDENCE_LEVELS: usize = 256;

/// A monotone bucket queue of (point, flip) entries keyed by confidence |nᵢ·nⱼ|.
struct BucketQueue {
    buckets: Vec<Vec<u32>>,
    /// Highest bucket that may be non-empty.
    top: usize,
}

impl BucketQueue {
    fn new() -> Self {
        Self {
            buckets: vec![Vec::new(); CONFIDENCE_LEVELS],
            top: 0,
        }
    }

    /// Bucket of a confidence: by the angle between the normals, most confident highest.
    fn level(confidence: f32) -> usize {
        let angle = confidence.clamp(0.0, 1.0).acos() * std::f32::consts::FRAC_2_PI;
        let from_top = (angle * CONFIDENCE_LEVELS as f32) as usize;
        CONFIDENCE_LEVELS - 1 - from_top.min(CONFIDENCE_LEVELS - 1)
    }

    fn push(&mut self, confidence: f32, index: u32, flip: bool) {
        let level = Self::level(confidence);
        self.buckets[level].push((index << 1) | u32::from(flip));
        self.top = self.top.max(level);
    }

    fn pop(&mut self) -> Option<(u32, bool)> {
        loop {
            if let Some(entry) = self.buckets[self.top].pop() {
                return Some((entry >> 1, entry & 1 == 1));
            }
            if self.top == 0 {
                return None;
            }
            self.top -= 1;
        }
    }
}

/// Edges j → i of the k-NN graph whose reverse i → j is not already in the graph, as CSR, so
/// that neighbours(i) ∪ reverse.of(i) is the symmetrised neighbourhood.
struct ReverseEdges {
    offsets: Vec<u32>,
    targets: Vec<u32>,
}

impl ReverseEdges {
    fn build(graph: &KnnGraph) -> Self {
        let n = graph.len();
        let k = graph.k();
        // For each edge i → j: does j list i too?
        let mutual: Vec<bool> = (0..n * k)
            .into_par_iter()
            .map(|e| {
                let (i, j) = (e / k, graph.neighbours(e / k)[e % k]);
                graph.neighbours(j as usize).contains(&(i as u32))
            })
            .collect();
        let mut offsets = vec![0u32; n + 1];
        for (e, _) in mutual.iter().enumerate().filter(|(_, m)| !**m) {
            offsets[graph.neighbours(e / k)[e % k] as usize + 1] += 1;
        }
        for i in 0..n {
            offsets[i + 1] += offsets[i];
        }
        let mut fill = offsets.clone();
        let mut targets = vec![0u32; offsets[n] as usize];
        for (e, _) in mutual.iter().enumerate().filter(|(_, m)| !**m) {
            let j = graph.neighbours(e / k)[e % k] as usize;
            targets[fill[j] as usize] = (e / k) as u32;
            fill[j] += 1;
        }
        Self { offsets, targets }
    }

    fn of(&self, i: usize) -> &[u32] {
        &self.targets[self.offsets[i] as usize..self.offsets[i + 1] as usize]
    }
}

/// Flips whole components outward; returns, per component, whether it was flipped.
fn turn_outward(
    positions: &[Vec3],
    normals: &mut [Vec3],
    component: &[u32],
    count: usize,
) -> Vec<bool> {
    let mut centroid = vec![(DVec3::ZERO, 0usize); count];
    for (p, &c) in positions.iter().zip(component) {
        centroid[c as usize].0 += p.as_dvec3();
        centroid[c as usize].1 += 1;
    }
    // Per component: Σ n·(p − c), Σ |p − c|, Σ n.
    let mut sums = vec![(0.0f64, 0.0f64, DVec3::ZERO); count];
    for ((p, n), &c) in positions.iter().zip(normals.iter()).zip(component) {
        let (sum, size) = centroid[c as usize];
        let d = p.as_dvec3() - sum / size as f64;
        let s = &mut sums[c as usize];
        s.0 += n.as_dvec3().dot(d);
        s.1 += d.length();
        s.2 += n.as_dvec3();
    }
    let flip: Vec<bool> = sums
        .iter()
        .map(|&(signed, spread, mean_normal)| {
            if signed.abs() > FLAT_TOLERANCE * spread {
                signed < 0.0
            } else {
                let axis = mean_normal.abs().max_position();
                mean_normal[axis] < 0.0
            }
        })
        .collect();
    for (n, &c) in normals.iter_mut().zip(component) {
        if flip[c as usize] {
            *n = -*n;
        }
    }
    flip
}

/// Estimates consistently oriented unit normals for `positions` from `k` nearest neighbours.
pub fn estimate_normals(
    positions: &[Vec3],
    k: usize,
) -> Result<(Vec<Vec3>, OrientationReport), NormalsError> {
    if k < MIN_NORMAL_K {
        return Err(NormalsError::KTooSmall(k));
    }
    if positions.len() < MIN_NORMAL_K + 1 {
        return Err(NormalsError::TooFewPoints {
            needed: MIN_NORMAL_K + 1,
            found: positions.len(),
        });
    }
    // Work on the points in Morton order: neighbours then sit close in memory, which makes the
    // k-NN queries, the PCA gathers and the orientation traversal cache-friendly.
    let order = morton_order(positions);
    let sorted: Vec<Vec3> = order.iter().map(|&i| positions[i as usize]).collect();
    let index = KnnIndex::build(&sorted);
    let graph = index.knn_graph(&sorted, k);
    let (mut sorted_normals, degenerate) = pca_normals(&sorted, &graph);
    let mut report = orient_normals(&sorted, &mut sorted_normals, &graph)?;
    report.degenerate = degenerate;
    let mut normals = vec![Vec3::ZERO; positions.len()];
    for (&i, n) in order.iter().zip(sorted_normals) {
        normals[i as usize] = n;
    }
    Ok((normals, report))
}

/// Gives `cloud` normals: its own when [usable](PointCloud::has_usable_normals) (normalised),
/// otherwise those of its faces when it has faces at every point
/// ([`vertex_normals_from_faces`]), otherwise estimated with `k` neighbours and oriented.
pub fn ensure_normals(cloud: &mut PointCloud, k: usize) -> Result<NormalSource, NormalsError> {
    if cloud.has_usable_normals() {
        let mut normals = cloud.normals().unwrap_or_default().to_vec();
        let reoriented = reorient_if_inconsistent(cloud.positions(), &mut normals, k)?;
        // Same length and finite: re-setting only normalises.
        let _ = cloud.set_normals(normals);
        return Ok(reoriented.map_or(NormalSource::File, NormalSource::FileReoriented));
    }
    if let Some(normals) = vertex_normals_from_faces(cloud.positions(), cloud.faces()) {
        let _ = cloud.set_normals(normals);
        return Ok(NormalSource::Faces);
    }
    let (normals, report) = estimate_normals(cloud.positions(), k)?;
    let _ = cloud.set_normals(normals);
    Ok(NormalSource::Estimated(report))
}

/// Re-orients `normals` ([`orient_normals`] over the `k`-NN graph) when more than
/// [`INCONSISTENT_NORMALS`] of the graph's pairs point apart; `None` when they agree well
/// enough (or the cloud is too small to tell) and are left as they are.
pub fn reorient_if_inconsistent(
    positions: &[Vec3],
    normals: &mut [Vec3],
    k: usize,
) -> Result<Option<OrientationReport>, NormalsError> {
    if positions.len() <= k.max(MIN_NORMAL_K) || normals.len() != positions.len() {
        return Ok(None);
    }
    let k = k.max(MIN_NORMAL_K);
    let index = KnnIndex::build(positions);
    // The share is estimated on an even sample of the points: the full graph is built only
    // when the normals need orienting.
    let stride = positions.len().div_ceil(CONSISTENCY_SAMPLE).max(1);
    let (mut pairs, mut apart) = (0usize, 0usize);
    for i in (0..positions.len()).step_by(stride) {
        for nb in index.nearest(positions[i], k + 1) {
            let j = nb.index as usize;
            if j != i {
                pairs += 1;
                apart += usize::from(normals[i].dot(normals[j]) < 0.0);
            }
        }
    }
    if (apart as f32) <= INCONSISTENT_NORMALS * pairs as f32 {
        return Ok(None);
    }
    let graph = index.knn_graph(positions, k);
    orient_normals(positions, normals, &graph).map(Some)
}

/// Unit vertex normals of a triangle mesh: each vertex's area-weighted sum of its triangles'
/// normals, so they turn the way the triangles do; on a closed mesh (every edge in two
/// triangles) wound inwards (negative enclosed volume), turned outwards. `None` when a point
/// has no triangle with area, or there are no triangles.
pub fn vertex_normals_from_faces(positions: &[Vec3], faces: &[[u32; 3]]) -> Option<Vec<Vec3>> {
    if faces.is_empty() {
        return None;
    }
    let (sums, volume) = face_normal_sums(positions, faces);
    let normals: Vec<Vec3> = sums.into_iter().map(Vec3::normalize_or_zero).collect();
    if normals.contains(&Vec3::ZERO) {
        return None;
    }
    let mut edges: Vec<(u32, u32)> = faces
        .iter()
        .flat_map(|&[a, b, c]| [(a, b), (b, c), (c, a)])
        .map(|(a, b)| (a.min(b), a.max(b)))
        .collect();
    edges.sort_unstable();
    let closed = edges.chunk_by(|x, y| x == y).all(|same| same.len() == 2);
    Some(if closed && volume < 0.0 {
        normals.into_iter().map(|n| -n).collect()
    } else {
        normals
    })
}

/// Each point's sum of its triangles' normals (each as long as twice its triangle's area),
/// and six times the volume the triangles enclose (signed: positive when wound outwards).
pub(crate) fn face_normal_sums(positions: &[Vec3], faces: &[[u32; 3]]) -> (Vec<Vec3>, f64) {
    let mut sums = vec![Vec3::ZERO; positions.len()];
    let mut volume = 0.0f64;
    for &t in faces {
        let [a, b, c] = t.map(|v| positions[v as usize]);
        let normal = (b - a).cross(c - a);
        volume += f64::from(a.dot(normal));
        for v in t {
            sums[v as usize] += normal;
        }
    }
    (sums, volume)
}

/// Normals of `positions` by PCA over their `k` nearest neighbours, each turned to agree
/// with the matching `reference` normal (the paper's way of updating normals).
pub fn pca_normals_of(positions: &[Vec3], reference: &[Vec3], k: usize) -> Vec<Vec3> {
    let index = KnnIndex::build(positions);
    let graph = index.knn_graph(positions, k);
    let (mut normals, _) = pca_normals(positions, &graph);
    normals.par_iter_mut().zip(reference).for_each(|(n, r)| {
        if n.dot(*r) < 0.0 {
            *n = -*n;
        }
    });
    normals
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eigenvector_of_plane_and_line() {
        // Points spread in x and y: normal is z.
        let plane = DMat3::from_diagonal(DVec3::new(4.0, 1.0, 1e-9));
        let v = smallest_eigenvector(plane).unwrap();
        assert!((v.z.abs() - 1.0).abs() < 1e-9);
        // A rotated plane.
        let rot = DMat3::from_rotation_y(0.7) * DMat3::from_rotation_x(-0.3);
        let m = rot * plane * rot.transpose();
        let v = smallest_eigenvector(m).unwrap();
        assert!((v.dot(rot * DVec3::Z).abs() - 1.0).abs() < 1e-9);
        // A line along x: any unit vector perpendicular to x.
        let line = DMat3::from_diagonal(DVec3::new(3.0, 0.0, 0.0));
        let v = smallest_eigenvector(line).unwrap();
        assert!(v.x.abs() < 1e-12 && (v.length() - 1.0).abs() < 1e-12);
        // Zero and isotropic: no direction.
        assert!(smallest_eigenvector(DMat3::ZERO).is_none());
        assert!(smallest_eigenvector(DMat3::IDENTITY).is_none());
    }

    #[test]
    fn coincident_points_give_finite_normals() {
        let pts = vec![Vec3::ONE; 20];
        let (normals, report) = estimate_normals(&pts, 5).unwrap();
        assert_eq!(report.degenerate, 20);
        assert!(
            normals
                .iter()
                .all(|n| n.is_finite() && (n.length() - 1.0).abs() < 1e-6)
        );
    }

    #[test]
    fn rejects_too_few_points_and_tiny_k() {
        assert_eq!(
            estimate_normals(&[Vec3::ZERO; 3], 10),
            Err(NormalsError::TooFewPoints {
                needed: 4,
                found: 3
            })
        );
        assert_eq!(
            estimate_normals(&[Vec3::ZERO; 30], 2),
            Err(NormalsError::KTooSmall(2))
        );
    }
}
