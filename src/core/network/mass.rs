//! Masses from the dense surface's area (issue 18): the same total mass at every
//! simplification level.
//!
//! Eq 1 gives each simulation point ρ·area(R)/3 from its ring on the *coarse* network, so the
//! total is ρ times the coarse mesh's area, which cuts across the detail it skips: on real
//! scans at 2 % of the points it was 6 % short of ρ times the scan's mesh area. Here every
//! dense point carries its own share of the area ([`dense_point_areas`]), and
//! [`SpringNetwork::share_dense_area`] gives each share to the simulation point nearest to
//! it on the same side of the surface: each simulation point's mass is ρ times the area of
//! its restricted Voronoi cell on the dense surface, and the total is ρ times the dense
//! surface's area whatever the level.

use glam::Vec3;
use rayon::prelude::*;

use super::{NetworkError, SpringNetwork};
use crate::core::cloud::check_points;
use crate::core::cloud::knn::KnnIndex;
use crate::core::simplify::Simplification;
use crate::core::simplify::tangent_delaunay::{RingBuilder, ring_voronoi_area, twin_before};

/// Simulation points looked at around a dense point for the nearest one on its side of the
/// surface (the nearest at all is taken when none of these is).
pub const SHARE_CANDIDATES: usize = 4;

/// Dense points per parallel task.
const CHUNK: usize = 4096;

/// Each dense point's share of the surface's area.
///
/// - With a mesh's `faces` (each naming three points): a third of the area of each face at
///   the point, so the shares add up to the mesh's area exactly.
/// - Without, or for a point in no face: its mixed Voronoi area within its local Delaunay
///   ring (the §3 construction among its `k` nearest points), the triangles measured at the
///   points' 3D positions as eq 1 measures them (see
///   [`ring_voronoi_area`](crate::core::simplify::tangent_delaunay::ring_voronoi_area)). The
///   shares add up to the area of the mesh the rings make of the dense points, even where
///   neighbouring rings split a quad of points on a circle by different diagonals.
///   A point whose ring is degenerate (collinear neighbours) gets 0, and so does a point
///   that coincides with one of a lower index (a duplicate: its twin has the area).
///   [`Simplification::point_areas`](crate::core::simplify::Simplification::point_areas)
///   holds the same shares, measured in §3's first pass at no extra search.
///
/// Points and normals of different counts, a non-finite position, a zero or non-finite
/// normal, and a face naming a point out of range or one point twice are typed errors.
pub fn dense_point_areas(
    positions: &[Vec3],
    normals: &[Vec3],
    faces: &[[u32; 3]],
    k: usize,
) -> Result<Vec<f32>, NetworkError> {
    check_points(positions, normals, 0)?;
    let n = positions.len();
    if let Some(f) = faces.iter().position(|&[a, b, c]| {
        a == b || b == c || a == c || [a, b, c].iter().any(|&i| i as usize >= n)
    }) {
        return Err(NetworkError::InvalidFace(f));
    }
    let mut areas = vec![0.0f64; n];
    for &[a, b, c] in faces {
        let p = |i: u32| positions[i as usize];
        let third = f64::from((p(b) - p(a)).cross(p(c) - p(a)).length()) / 6.0;
        for v in [a, b, c] {
            areas[v as usize] += third;
        }
    }
    let missing: Vec<usize> = (0..n).filter(|&i| areas[i] == 0.0).collect();
    if missing.is_empty() {
        return Ok(areas.into_iter().map(|a| a as f32).collect());
    }
    let index = KnnIndex::build(positions);
    let ring_thirds: Vec<f32> = missing
        .par_chunks(CHUNK)
        .flat_map_iter(|chunk| {
            let mut rings = RingBuilder::new();
            let mut found = Vec::with_capacity(k + 1);
            let mut neighbours = Vec::with_capacity(k + 1);
            let mut ring = Vec::with_capacity(k);
            chunk
                .iter()
                .map(|&i| {
                    found.clear();
                    found.extend(
                        index
                            .nearest(positions[i], k + 1)
                            .into_iter()
                            .map(|nb| nb.index)
                            .filter(|&j| j as usize != i)
                            .take(k),
                    );
                    neighbours.clear();
                    neighbours.extend(found.iter().map(|&j| positions[j as usize]));
                    ring.clear();
                    let shape = rings.build(
                        positions[i],
                        normals[i],
                        &neighbours,
                        (i as u32, &found),
                        Some(&mut ring),
                    );
                    if shape.degenerate || twin_before(i, &found, positions) {
                        return 0.0;
                    }
                    ring_voronoi_area(positions[i], &neighbours, &ring)
                })
                .collect::<Vec<_>>()
        })
        .collect();
    for (&i, a) in missing.iter().zip(ring_thirds) {
        areas[i] = f64::from(a);
    }
    Ok(areas.into_iter().map(|a| a as f32).collect())
}

/// The dense points' shares of the area after §3 has run on them: [`dense_point_areas`]
/// with a mesh's `faces`, and otherwise the shares §3's first pass measured
/// ([`Simplification::point_areas`]), so that no ring is built twice. `k` is the
/// neighbours §3 used.
pub fn dense_areas_after(
    kept: &Simplification,
    positions: &[Vec3],
    normals: &[Vec3],
    faces: &[[u32; 3]],
    k: usize,
) -> Result<Vec<f32>, NetworkError> {
    if faces.is_empty() && kept.point_areas.len() == positions.len() {
        check_points(positions, normals, 0)?;
        Ok(kept.point_areas.clone())
    } else {
        dense_point_areas(positions, normals, faces, k)
    }
}

/// What [`SpringNetwork::share_dense_area`] did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MassShare {
    /// Σ of the dense points' areas: the area the masses now stand for.
    pub dense_area: f32,
    /// Simulation points no dense point was nearest to, which kept eq 1's share before the
    /// masses were scaled to the total.
    pub unreached: usize,
}

impl SpringNetwork {
    /// Replaces the masses (eq 1) with shares of the dense surface's area: each dense point's
    /// `dense_areas` entry goes to the nearest simulation point (at rest) whose normal is
    /// within 90° of the dense point's, or the nearest at all when none of the
    /// [`SHARE_CANDIDATES`] nearest is (so the two sides of a thin part keep their own
    /// mass), and each mass is `density` times the area it received. A simulation point that
    /// received nothing keeps eq 1's area; the masses are then scaled so that their sum is
    /// `density` times the dense area exactly. The report's `total_mass` and `dense_area`
    /// follow. Bad dense points (as for [`dense_point_areas`]), a count of areas that is not
    /// theirs, a negative or non-finite area, and a bad density are typed errors, and leave
    /// the masses as they were.
    pub fn share_dense_area(
        &mut self,
        dense_positions: &[Vec3],
        dense_normals: &[Vec3],
        dense_areas: &[f32],
        density: f32,
    ) -> Result<MassShare, NetworkError> {
        if !(density > 0.0 && density.is_finite()) {
            return Err(NetworkError::InvalidDensity(density));
        }
        check_points(dense_positions, dense_normals, 1)?;
        if dense_areas.len() != dense_positions.len() {
            return Err(NetworkError::AreaCount {
                points: dense_positions.len(),
                areas: dense_areas.len(),
            });
        }
        if let Some(i) = dense_areas
            .iter()
            .position(|a| !(a.is_finite() && *a >= 0.0))
        {
            return Err(NetworkError::InvalidArea(i));
        }
        let n = self.len();
        let index = KnnIndex::build(&self.positions);
        // Which simulation point each dense point gives its area to, in parallel; the sums
        // then run in the dense points' order, so the masses do not depend on how rayon
        // splits the work (the same bits with any number of threads).
        let receivers: Vec<Option<u32>> = dense_positions
            .par_chunks(CHUNK)
            .zip(dense_normals.par_chunks(CHUNK))
            .flat_map_iter(|(ps, ns)| {
                ps.iter().zip(ns).map(|(&p, &normal)| {
                    let near = index.nearest(p, SHARE_CANDIDATES);
                    let same_side = near
                        .iter()
                        .find(|nb| self.normals[nb.index as usize].dot(normal) > 0.0);
                    same_side.or(near.first()).map(|nb| nb.index)
                })
            })
            .collect();
        let mut received = vec![0.0f64; n];
        for (receiver, &a) in receivers.iter().zip(dense_areas) {
            if let Some(j) = receiver {
                received[*j as usize] += f64::from(a);
            }
        }
        let dense_area: f64 = dense_areas.iter().map(|&a| f64::from(a)).sum();
        if dense_area.is_nan() || dense_area <= 0.0 {
            return Err(NetworkError::NotASurface);
        }
        let mut unreached = 0;
        let areas: Vec<f64> = received
            .iter()
            .zip(&self.masses)
            .map(|(&r, &m)| {
                if r > 0.0 {
                    r
                } else {
                    unreached += 1;
                    f64::from(m / self.report.total_mass.max(f32::MIN_POSITIVE)) * dense_area
                }
            })
            .collect();
        let scale = dense_area / areas.iter().sum::<f64>();
        self.masses = areas
            .iter()
            .map(|&a| (f64::from(density) * a * scale) as f32)
            .collect();
        self.report.total_mass = self.masses.iter().map(|&m| f64::from(m)).sum::<f64>() as f32;
        self.report.dense_area = dense_area as f32;
        Ok(MassShare {
            dense_area: dense_area as f32,
            unreached,
        })
    }
}
