//! k-nearest-neighbour search over a fixed point set ([kiddo] k-d tree), reused by every stage.
//!
//! [kiddo]: https://crates.io/crates/kiddo

use std::num::NonZeroUsize;

use glam::Vec3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

/// Points per rayon task when building a graph.
const QUERY_CHUNK: usize = 1024;

/// Nearest neighbours averaged for a point's *local spacing* (the mean distance to them), the
/// length scale the ring's hole test, resampling and the CLI's renderer measure in.
pub const SPACING_NEIGHBOURS: usize = 6;

/// A neighbour found by a query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Neighbour {
    /// Index of the point in the indexed slice.
    pub index: u32,
    /// Squared distance to the query point.
    pub dist2: f32,
}

/// A k-d tree over a slice of points.
pub struct KnnIndex {
    tree: Option<ImmutableKdTree<f32, 3>>,
    len: usize,
}

impl std::fmt::Debug for KnnIndex {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("KnnIndex").field("len", &self.len).finish()
    }
}

impl KnnIndex {
    /// Builds the index. Positions must be finite (every [`PointCloud`](crate::core::PointCloud)
    /// is); there must be fewer than 2^32 of them.
    pub fn build(positions: &[Vec3]) -> Self {
        let coords: Vec<[f32; 3]> = positions.iter().map(|p| p.to_array()).collect();
        let tree = if coords.is_empty() {
            None
        } else {
            // Construction fails only for more than u32::MAX points.
            ImmutableKdTree::new_from_slice(&coords).ok()
        };
        Self {
            tree,
            len: positions.len(),
        }
    }

    /// Number of indexed points.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the index is empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The `k` points nearest `query`, nearest first (fewer if the index holds fewer).
    pub fn nearest(&self, query: Vec3, k: usize) -> Vec<Neighbour> {
        let (Some(tree), Some(k)) = (&self.tree, NonZeroUsize::new(k.min(self.len))) else {
            return Vec::new();
        };
        tree.query(&query.to_array())
            .nearest_n::<SquaredEuclidean<f32>>(k)
            .execute()
            .into_iter()
            .map(|r| Neighbour {
                index: r.item,
                dist2: r.distance,
            })
            .collect()
    }

    /// For every point of `positions` (the slice this index was built over), its `k` nearest
    /// *other* points, nearest first. `k` is clamped to `len - 1`. Runs in parallel.
    ///
    /// Queries run in Morton (Z-curve) order, so consecutive queries visit the same parts of
    /// the tree whatever order the input points come in; rows are returned in input order.
    pub fn knn_graph(&self, positions: &[Vec3], k: usize) -> KnnGraph {
        let n = positions.len();
        debug_assert_eq!(n, self.len, "knn_graph needs the indexed positions");
        let k = k.min(n.saturating_sub(1));
        if k == 0 {
            return KnnGraph {
                k,
                indices: vec![0; n * k],
                dist2: vec![0.0; n * k],
            };
        }
        let order = morton_order(positions);
        // Rows in query (Morton) order first.
        let mut sorted_idx = vec![0u32; n * k];
        let mut sorted_d = vec![0f32; n * k];
        let fill = |(chunk, (idx_out, d_out)): (usize, (&mut [u32], &mut [f32]))| {
            for (row, (idx_row, d_row)) in idx_out
                .chunks_exact_mut(k)
                .zip(d_out.chunks_exact_mut(k))
                .enumerate()
            {
                let i = order[chunk * QUERY_CHUNK + row] as usize;
                let found = self.nearest(positions[i], k + 1);
                // Drop the point itself; with duplicates it may not come first.
                let own = found
                    .iter()
                    .position(|nb| nb.index as usize == i)
                    .unwrap_or(found.len() - 1);
                let others = found
                    .iter()
                    .enumerate()
                    .filter(|&(j, _)| j != own)
                    .map(|(_, nb)| nb);
                for ((slot_i, slot_d), nb) in idx_row.iter_mut().zip(d_row.iter_mut()).zip(others) {
                    *slot_i = nb.index;
                    *slot_d = nb.dist2;
                }
            }
        };
        let chunk = QUERY_CHUNK * k;
        sorted_idx
            .par_chunks_mut(chunk)
            .zip(sorted_d.par_chunks_mut(chunk))
            .enumerate()
            .for_each(fill);
        // Back to input order: row order[r] of the result is row r of the sorted rows.
        let mut rank = vec![0u32; n];
        for (r, &i) in order.iter().enumerate() {
            rank[i as usize] = r as u32;
        }
        let mut indices = vec![0u32; n * k];
        let mut dist2 = vec![0f32; n * k];
        indices
            .par_chunks_mut(k)
            .zip(dist2.par_chunks_mut(k))
            .enumerate()
            .with_min_len(QUERY_CHUNK)
            .for_each(|(i, (idx_row, d_row))| {
                let r = rank[i] as usize * k;
                idx_row.copy_from_slice(&sorted_idx[r..r + k]);
                d_row.copy_from_slice(&sorted_d[r..r + k]);
            });
        KnnGraph { k, indices, dist2 }
    }
}

/// Bits per axis of a Morton code (3 × 21 = 63 bits).
const MORTON_BITS: u32 = 21;

/// Indices of `positions` sorted along a Morton (Z-order) curve through their bounding box:
/// points close in this order are close in space.
pub fn morton_order(positions: &[Vec3]) -> Vec<u32> {
    let Some(first) = positions.first() else {
        return Vec::new();
    };
    let (lo, hi) = positions
        .iter()
        .fold((*first, *first), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    let cells = ((1u32 << MORTON_BITS) - 1) as f32;
    let scale = (hi - lo).max(Vec3::splat(f32::MIN_POSITIVE)).recip() * cells;
    let mut keyed: Vec<(u64, u32)> = positions
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            let q = ((*p - lo) * scale)
                .clamp(Vec3::ZERO, Vec3::splat(cells))
                .as_uvec3();
            (
                spread_bits(q.x) | (spread_bits(q.y) << 1) | (spread_bits(q.z) << 2),
                i as u32,
            )
        })
        .collect();
    keyed.par_sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// Spreads the low 21 bits of `v` so that two zero bits separate each.
fn spread_bits(v: u32) -> u64 {
    let mut x = u64::from(v) & 0x1f_ffff;
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

/// Each point's `k` nearest other points (row-major `n × k`), nearest first.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct KnnGraph {
    k: usize,
    indices: Vec<u32>,
    dist2: Vec<f32>,
}

impl KnnGraph {
    /// Neighbours per point.
    pub fn k(&self) -> usize {
        self.k
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.indices.len().checked_div(self.k).unwrap_or(0)
    }

    /// Whether the graph has no rows.
    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }

    /// Neighbour indices of point `i`, nearest first.
    pub fn neighbours(&self, i: usize) -> &[u32] {
        &self.indices[i * self.k..(i + 1) * self.k]
    }

    /// Squared distances of point `i`'s neighbours, in the same order.
    pub fn neighbour_dist2(&self, i: usize) -> &[f32] {
        &self.dist2[i * self.k..(i + 1) * self.k]
    }

    /// All squared distances, row-major.
    pub fn dist2(&self) -> &[f32] {
        &self.dist2
    }

    /// Each point's mean distance to its neighbours: the local spacing of the sampling
    /// (empty when the graph has no columns).
    pub fn mean_distances(&self) -> Vec<f32> {
        if self.k == 0 {
            return Vec::new();
        }
        self.dist2
            .chunks_exact(self.k)
            .map(|row| row.iter().map(|d2| d2.sqrt()).sum::<f32>() / self.k as f32)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn graph_excludes_self_and_matches_brute_force() {
        let pts: Vec<Vec3> = (0..200)
            .map(|i| {
                let t = i as f32 * 0.37;
                Vec3::new(t.sin() * 3.0, (t * 1.7).cos(), (i % 13) as f32 * 0.1)
            })
            .collect();
        let index = KnnIndex::build(&pts);
        let g = index.knn_graph(&pts, 5);
        assert_eq!((g.len(), g.k()), (200, 5));
        for i in 0..pts.len() {
            let mut brute: Vec<(f32, usize)> = (0..pts.len())
                .filter(|&j| j != i)
                .map(|j| (pts[i].distance_squared(pts[j]), j))
                .collect();
            brute.sort_by(|a, b| a.0.total_cmp(&b.0));
            assert!(!g.neighbours(i).contains(&(i as u32)));
            for (slot, &d) in g.neighbour_dist2(i).iter().enumerate() {
                assert!((d - brute[slot].0).abs() <= 1e-5 * (1.0 + d));
            }
        }
    }

    #[test]
    fn morton_order_is_a_permutation_that_keeps_neighbours_close() {
        assert_eq!(spread_bits(0b111), 0b1001001);
        let pts: Vec<Vec3> = (0..1000)
            .map(|i| Vec3::new((i % 10) as f32, ((i / 10) % 10) as f32, (i / 100) as f32))
            .collect();
        let order = morton_order(&pts);
        let mut seen = order.clone();
        seen.sort_unstable();
        assert!(seen.iter().enumerate().all(|(i, &v)| v as usize == i));
        // On a grid, successive points along the curve are mostly unit steps apart.
        let steps: f32 = order
            .windows(2)
            .map(|w| pts[w[0] as usize].distance(pts[w[1] as usize]))
            .sum();
        assert!(steps / 999.0 < 2.0);
    }

    #[test]
    fn mean_distances_are_the_local_spacing() {
        let line: Vec<Vec3> = (0..5).map(|i| Vec3::X * i as f32).collect();
        let g = KnnIndex::build(&line).knn_graph(&line, 2);
        // The ends see 1 and 2 away, the middle points 1 and 1.
        assert_eq!(g.mean_distances(), vec![1.5, 1.0, 1.0, 1.0, 1.5]);
        let one = [Vec3::ONE];
        assert!(
            KnnIndex::build(&one)
                .knn_graph(&one, 3)
                .mean_distances()
                .is_empty()
        );
    }

    #[test]
    fn tiny_and_duplicate_inputs() {
        assert!(KnnIndex::build(&[]).nearest(Vec3::ZERO, 3).is_empty());
        let one = [Vec3::ONE];
        let g = KnnIndex::build(&one).knn_graph(&one, 8);
        assert_eq!(g.k(), 0);
        let dup = [Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, Vec3::X];
        let g = KnnIndex::build(&dup).knn_graph(&dup, 2);
        for i in 0..4 {
            assert!(!g.neighbours(i).contains(&(i as u32)));
        }
    }
}
