//! Baking (issue 17): the same network, its current shape made the rest shape.

use glam::Vec3;

use super::build::masses_of;
use super::{NetworkError, Spring, SpringNetwork};
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
        let length = |s: &Spring| Spring {
            rest_length: positions[s.a as usize].distance(positions[s.b as usize]),
            ..*s
        };
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
        Ok(Self {
            positions: positions.to_vec(),
            normals,
            masses,
            stretch: self.stretch.iter().map(length).collect(),
            bend: self.bend.iter().map(length).collect(),
            triangles: self.triangles.clone(),
            boundary: self.boundary.clone(),
            ring_offsets: self.ring_offsets.clone(),
            ring_indices: self.ring_indices.clone(),
            report,
        })
    }
}
