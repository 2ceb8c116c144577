//! Baking (issue 17): the same network, its current shape made the rest shape.

use glam::Vec3;

use super::build::masses_of;
use super::{NetworkError, NetworkReport, Spring, SpringNetwork};
use crate::core::normals::face_normal_sums;

impl SpringNetwork {
    /// The same points, springs, triangles and rings with `positions` (one per point, finite)
    /// as the rest shape: rest lengths measured there, masses (eq 1) from the triangles'
    /// areas there with `density`, and normals from the triangles there, each on the side
    /// its rest normal took of the rest triangles (a point without a triangle keeps its
    /// normal).
    pub fn reshaped(&self, positions: &[Vec3], density: f32) -> Result<Self, NetworkError> {
        if positions.len() != self.len() {
            return Err(NetworkError::LengthMismatch {
                positions: positions.len(),
                normals: self.len(),
            });
        }
        if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
            return Err(NetworkError::InvalidPoint(i));
        }
        if !(density > 0.0 && density.is_finite()) {
            return Err(NetworkError::InvalidDensity(density));
        }
        let (before, _) = face_normal_sums(&self.positions, &self.triangles);
        let (after, _) = face_normal_sums(positions, &self.triangles);
        let normals = self
            .normals
            .iter()
            .zip(before.iter().zip(&after))
            .map(|(&old, (&b, &a))| {
                let a = a.normalize_or_zero();
                match (a == Vec3::ZERO, b.dot(old) < 0.0) {
                    (true, _) => old,
                    (false, true) => -a,
                    (false, false) => a,
                }
            })
            .collect();
        let (areas, mut masses, _) = masses_of(positions, &self.triangles, density)?;
        let mut report = self.report;
        report.area = areas.iter().sum::<f64>() as f32;
        if report.dense_area > 0.0 {
            // Shares of the dense area: each grows or shrinks with the point's region.
            let (before, _, _) = masses_of(&self.positions, &self.triangles, density)?;
            let was = f64::from(self.report.total_mass) / f64::from(self.report.dense_area);
            let density_ratio = f64::from(density) / was;
            for (i, m) in masses.iter_mut().enumerate() {
                let grown = areas[i] / before[i];
                let grown = if grown.is_finite() && grown > 0.0 {
                    grown
                } else {
                    1.0
                };
                *m = (f64::from(self.masses[i]) * grown * density_ratio) as f32;
            }
        }
        report.total_mass = masses.iter().map(|&m| f64::from(m)).sum::<f64>() as f32;
        if report.dense_area > 0.0 {
            report.dense_area = report.total_mass / density;
        }
        Ok(self.with_shape(RestShape {
            positions: positions.to_vec(),
            normals,
            masses,
            area: report.area,
            total_mass: report.total_mass,
            dense_area: report.dense_area,
        }))
    }

    /// What [`Self::reshaped`] changes: the rest shape (for a saved game of a baked surface).
    pub fn rest_shape(&self) -> RestShape {
        RestShape {
            positions: self.positions.clone(),
            normals: self.normals.clone(),
            masses: self.masses.clone(),
            area: self.report.area,
            total_mass: self.report.total_mass,
            dense_area: self.report.dense_area,
        }
    }

    /// The same network with the rest shape `shape` put back (rest lengths measured there):
    /// the network [`Self::reshaped`] gave, bit for bit, when `shape` is that one's. A shape
    /// of another network (other counts) or with bad values is refused.
    pub fn with_rest_shape(&self, shape: RestShape) -> Result<Self, NetworkError> {
        let n = self.len();
        if shape.positions.len() != n || shape.normals.len() != n {
            return Err(NetworkError::LengthMismatch {
                positions: shape.positions.len(),
                normals: shape.normals.len(),
            });
        }
        if shape.masses.len() != n {
            return Err(NetworkError::LengthMismatch {
                positions: n,
                normals: shape.masses.len(),
            });
        }
        if let Some(i) = (0..n).find(|&i| {
            !(shape.positions[i].is_finite()
                && (shape.normals[i].length() - 1.0).abs() < 1e-3
                && shape.masses[i] > 0.0
                && shape.masses[i].is_finite())
        }) {
            return Err(NetworkError::InvalidPoint(i));
        }
        Ok(self.with_shape(shape))
    }

    fn with_shape(&self, shape: RestShape) -> Self {
        let positions = &shape.positions;
        let length = |s: &Spring| Spring {
            rest_length: positions[s.a as usize].distance(positions[s.b as usize]),
            ..*s
        };
        let report = NetworkReport {
            area: shape.area,
            total_mass: shape.total_mass,
            dense_area: shape.dense_area,
            ..self.report
        };
        Self {
            stretch: self.stretch.iter().map(length).collect(),
            bend: self.bend.iter().map(length).collect(),
            positions: shape.positions,
            normals: shape.normals,
            masses: shape.masses,
            triangles: self.triangles.clone(),
            boundary: self.boundary.clone(),
            ring_offsets: self.ring_offsets.clone(),
            ring_indices: self.ring_indices.clone(),
            report,
        }
    }
}

/// The rest shape of a network (what baking changes): positions, normals, masses and the
/// measures that follow them.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RestShape {
    /// Rest positions.
    pub positions: Vec<Vec3>,
    /// Unit rest normals.
    pub normals: Vec<Vec3>,
    /// Masses.
    pub masses: Vec<f32>,
    /// [`NetworkReport::area`].
    pub area: f32,
    /// [`NetworkReport::total_mass`].
    pub total_mass: f32,
    /// [`NetworkReport::dense_area`].
    pub dense_area: f32,
}
