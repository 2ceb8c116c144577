//! Stage 1, the dense surface, and the data every later stage shares: [`PointCloud`]
//! (positions, optional per-point normals, a mesh file's faces) with its checks
//! ([`check_points`], [`first_invalid_point`], [`MAX_ABS_COORDINATE`]) and summary
//! statistics; the file readers and writers ([`io`]); nearest-neighbour search and the local
//! spacing ([`knn`]); procedural surfaces for tests and demos ([`shapes`]); and the surfel
//! discs the renderer draws from positions and normals ([`surfels`]).

pub mod io;
pub mod knn;
pub mod shapes;
pub mod surfels;

use glam::Vec3;

use crate::core::cloud::knn::KnnIndex;

/// Largest absolute coordinate accepted anywhere in the crate.
///
/// Squared distances of points this far apart still fit in an `f32` (1e30 < 3.4e38), so k-NN
/// queries and spring lengths stay finite. Real scans (even planet-scale in millimetres) are far
/// below it; a larger value is almost certainly corrupt data.
pub const MAX_ABS_COORDINATE: f32 = 1.0e15;

/// Length below which a normal counts as zero ("no normal").
pub const ZERO_NORMAL_EPS: f32 = 1.0e-6;

/// Why a set of arrays is not a valid [`PointCloud`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CloudError {
    /// `normals.len() != positions.len()`.
    #[error("{normals} normals given for {positions} positions")]
    NormalCountMismatch {
        /// Number of positions.
        positions: usize,
        /// Number of normals.
        normals: usize,
    },
    /// A coordinate is NaN or infinite.
    #[error("point {index} has a non-finite {what} {value:?}")]
    NonFinite {
        /// Index of the point.
        index: usize,
        /// `"position"` or `"normal"`.
        what: &'static str,
        /// The offending vector.
        value: Vec3,
    },
    /// A face names a point the cloud does not have, or one point twice.
    #[error("face {index} {face:?} is not a triangle of the cloud's {points} points")]
    BadFace {
        /// Index of the face.
        index: usize,
        /// Its corners.
        face: [u32; 3],
        /// Number of points.
        points: usize,
    },
    /// A coordinate exceeds [`MAX_ABS_COORDINATE`].
    #[error("point {index} has a coordinate beyond ±{MAX_ABS_COORDINATE:e}: {value:?}")]
    OutOfRange {
        /// Index of the point.
        index: usize,
        /// The offending position.
        value: Vec3,
    },
}

/// Axis-aligned bounding box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Smallest corner.
    pub min: Vec3,
    /// Largest corner.
    pub max: Vec3,
}

impl Aabb {
    /// The box's diagonal length.
    pub fn diagonal(&self) -> f32 {
        (self.max - self.min).length()
    }

    /// The box's centre.
    pub fn center(&self) -> Vec3 {
        (self.max + self.min) * 0.5
    }
}

/// Nearest-neighbour spacing statistics of a cloud.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpacingStats {
    /// Mean distance from a point to its nearest other point.
    pub mean: f32,
    /// Smallest such distance (0 when the cloud has duplicate points).
    pub min: f32,
    /// Largest such distance.
    pub max: f32,
}

/// A point-sampled surface: positions and, when known, unit normals, and the triangles of a
/// mesh over the points when the file had one.
///
/// Invariants (checked by [`PointCloud::new`] and [`PointCloud::with_faces`]): every
/// coordinate is finite and within ±[`MAX_ABS_COORDINATE`]; `normals`, when present, has one
/// entry per position; every face names three distinct points of the cloud.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointCloud {
    positions: Vec<Vec3>,
    normals: Option<Vec<Vec3>>,
    faces: Vec<[u32; 3]>,
}

impl PointCloud {
    /// Builds a cloud, validating lengths and coordinates.
    pub fn new(positions: Vec<Vec3>, normals: Option<Vec<Vec3>>) -> Result<Self, CloudError> {
        for (index, &p) in positions.iter().enumerate() {
            check_position(index, p)?;
        }
        if let Some(normals) = &normals {
            if normals.len() != positions.len() {
                return Err(CloudError::NormalCountMismatch {
                    positions: positions.len(),
                    normals: normals.len(),
                });
            }
            for (index, &n) in normals.iter().enumerate() {
                if !n.is_finite() {
                    return Err(CloudError::NonFinite {
                        index,
                        what: "normal",
                        value: n,
                    });
                }
            }
        }
        Ok(Self {
            positions,
            normals,
            faces: Vec::new(),
        })
    }

    /// The cloud with the triangles of a mesh over its points (a mesh file's faces). The
    /// network uses them, where the points' own rings leave holes, as the surface's true
    /// connectivity (see [`build_network_over`](crate::core::network::build_network_over)).
    pub fn with_faces(mut self, faces: Vec<[u32; 3]>) -> Result<Self, CloudError> {
        let points = self.positions.len();
        for (index, &face @ [a, b, c]) in faces.iter().enumerate() {
            if a == b || b == c || c == a || face.iter().any(|&v| v as usize >= points) {
                return Err(CloudError::BadFace {
                    index,
                    face,
                    points,
                });
            }
        }
        self.faces = faces;
        Ok(self)
    }

    /// The triangles of the mesh over the points, if the cloud came with one (else empty).
    pub fn faces(&self) -> &[[u32; 3]] {
        &self.faces
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether the cloud has no points.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Point positions.
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// Per-point normals, if the cloud has any.
    pub fn normals(&self) -> Option<&[Vec3]> {
        self.normals.as_deref()
    }

    /// Whether the cloud carries normals that can be used as they are: present, and none of
    /// them zero. A file whose normals are all (or partly) zero needs estimated ones.
    pub fn has_usable_normals(&self) -> bool {
        self.normals
            .as_ref()
            .is_some_and(|n| n.iter().all(|v| v.length() > ZERO_NORMAL_EPS))
    }

    /// Replaces the normals (one per point, finite), normalising each to unit length.
    pub fn set_normals(&mut self, normals: Vec<Vec3>) -> Result<(), CloudError> {
        if normals.len() != self.positions.len() {
            return Err(CloudError::NormalCountMismatch {
                positions: self.positions.len(),
                normals: normals.len(),
            });
        }
        let mut normals = normals;
        for (index, n) in normals.iter_mut().enumerate() {
            if !n.is_finite() {
                return Err(CloudError::NonFinite {
                    index,
                    what: "normal",
                    value: *n,
                });
            }
            *n = n.normalize_or_zero();
        }
        self.normals = Some(normals);
        Ok(())
    }

    /// Splits the cloud into its arrays (its faces, if any, are dropped).
    pub fn into_parts(self) -> (Vec<Vec3>, Option<Vec<Vec3>>) {
        (self.positions, self.normals)
    }

    /// Axis-aligned bounds, or `None` for an empty cloud.
    pub fn bounds(&self) -> Option<Aabb> {
        let first = *self.positions.first()?;
        let (min, max) = self
            .positions
            .iter()
            .fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p)));
        Some(Aabb { min, max })
    }

    /// Nearest-neighbour spacing statistics, or `None` with fewer than two points.
    ///
    /// Pass an index already built over this cloud's positions to avoid building another.
    pub fn spacing(&self, index: &KnnIndex) -> Option<SpacingStats> {
        spacing_stats(&self.positions, index)
    }
}

/// Nearest-neighbour spacing of `positions` (indexed by `index`), or `None` with fewer than two.
pub fn spacing_stats(positions: &[Vec3], index: &KnnIndex) -> Option<SpacingStats> {
    if positions.len() < 2 {
        return None;
    }
    let graph = index.knn_graph(positions, 1);
    let (sum, min, max) =
        graph
            .dist2()
            .iter()
            .fold((0.0f64, f32::INFINITY, 0.0f32), |(sum, lo, hi), &d2| {
                let d = d2.sqrt();
                (sum + f64::from(d), lo.min(d), hi.max(d))
            });
    Some(SpacingStats {
        mean: (sum / positions.len() as f64) as f32,
        min,
        max,
    })
}

/// The first point whose position or normal is not finite, or whose normal is zero: what
/// simplification, the network and the transfer refuse.
pub fn first_invalid_point(positions: &[Vec3], normals: &[Vec3]) -> Option<usize> {
    positions
        .iter()
        .zip(normals)
        .position(|(p, n)| !p.is_finite() || !n.is_finite() || n.length_squared() == 0.0)
}

/// What is wrong with positions and normals given side by side (see [`check_points`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PointsProblem {
    /// Positions and normals differ in length.
    LengthMismatch {
        /// Number of positions.
        positions: usize,
        /// Number of normals.
        normals: usize,
    },
    /// More points than 32-bit indices can name.
    TooMany(usize),
    /// Fewer points than the stage needs.
    TooFew {
        /// Points needed.
        needed: usize,
        /// Points given.
        found: usize,
    },
    /// The first point whose position is not finite, or whose normal is zero or not finite
    /// ([`first_invalid_point`]).
    Invalid(usize),
}

/// The checks every stage that takes points with normals by index makes (simplification,
/// the network), in this order: equal lengths, indices that fit in 32 bits, at least
/// `needed` points, every point valid. Each stage turns the problem into its own typed error.
pub fn check_points(
    positions: &[Vec3],
    normals: &[Vec3],
    needed: usize,
) -> Result<(), PointsProblem> {
    if positions.len() != normals.len() {
        return Err(PointsProblem::LengthMismatch {
            positions: positions.len(),
            normals: normals.len(),
        });
    }
    if positions.len() >= u32::MAX as usize {
        return Err(PointsProblem::TooMany(positions.len()));
    }
    if positions.len() < needed {
        return Err(PointsProblem::TooFew {
            needed,
            found: positions.len(),
        });
    }
    match first_invalid_point(positions, normals) {
        Some(i) => Err(PointsProblem::Invalid(i)),
        None => Ok(()),
    }
}

/// Checks one position against the cloud invariants.
pub(crate) fn check_position(index: usize, p: Vec3) -> Result<(), CloudError> {
    if !p.is_finite() {
        return Err(CloudError::NonFinite {
            index,
            what: "position",
            value: p,
        });
    }
    if p.abs().max_element() > MAX_ABS_COORDINATE {
        return Err(CloudError::OutOfRange { index, value: p });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_mismatched_and_non_finite() {
        let p = vec![Vec3::ZERO, Vec3::X];
        assert!(matches!(
            PointCloud::new(p.clone(), Some(vec![Vec3::Z])),
            Err(CloudError::NormalCountMismatch { .. })
        ));
        assert!(matches!(
            PointCloud::new(vec![Vec3::new(f32::NAN, 0.0, 0.0)], None),
            Err(CloudError::NonFinite { index: 0, .. })
        ));
        assert!(matches!(
            PointCloud::new(vec![Vec3::ZERO, Vec3::splat(1e20)], None),
            Err(CloudError::OutOfRange { index: 1, .. })
        ));
        let mut c = PointCloud::new(p, None).unwrap();
        assert!(!c.has_usable_normals());
        c.set_normals(vec![Vec3::Z * 2.0, Vec3::Y]).unwrap();
        assert!(c.has_usable_normals());
        assert_eq!(c.normals().unwrap()[0], Vec3::Z);
    }

    #[test]
    fn bounds_of_points() {
        let c = PointCloud::new(
            vec![Vec3::new(1.0, -2.0, 3.0), Vec3::new(-1.0, 5.0, 0.0)],
            None,
        )
        .unwrap();
        let b = c.bounds().unwrap();
        assert_eq!(b.min, Vec3::new(-1.0, -2.0, 0.0));
        assert_eq!(b.max, Vec3::new(1.0, 5.0, 3.0));
        assert!(PointCloud::default().bounds().is_none());
    }
}
