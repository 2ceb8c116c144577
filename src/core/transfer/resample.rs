//! Density maintenance after large stretch (the paper's last step of §5).
//!
//! The transfer's fitted gradient gives each dense point its local stretch: the deformed
//! tangents t₁ + ∂u/∂x̄ and t₂ + ∂u/∂ȳ form a 3 × 2 matrix F whose largest singular value σ
//! is the largest factor by which distances around the point grew, in the direction e of the
//! matching singular vector. Where σ times the point's rest spacing exceeds `factor` times
//! the spacing the surface was sampled at, a new point goes halfway to the point's nearest
//! neighbour on either side along ±e (within 45° of it and two spacings), with the mean of
//! their normals — in the rest state, between two samples of the surface; a point on a
//! boundary gets none on the outside. The point's spacing is then halved, so it splits
//! again only where the stretch is twice as large. New points get their own transfer
//! coefficients, like
//! any dense point, so they follow the simulation from then on. Candidates closer than a
//! third of their spacing to an existing point or an accepted candidate are dropped (the
//! two points of a pair propose the same midpoint). Passes repeat up to `max_passes`, and
//! the total is capped at `max_new_per_point` times the points there were.

use std::collections::HashMap;

use glam::{Vec3, Vec3A};
use rayon::prelude::*;

use crate::core::cloud::knn::{KnnIndex, SPACING_NEIGHBOURS};
use crate::core::transfer::{Transfer, simd_displacements, tangent_frame};

/// Default spacing growth that triggers resampling.
pub const DEFAULT_RESAMPLE_FACTOR: f32 = 1.5;

/// Default number of passes.
pub const DEFAULT_RESAMPLE_PASSES: usize = 3;

/// Default cap on new points, per point there was before resampling.
pub const DEFAULT_MAX_NEW_PER_POINT: f32 = 3.0;

/// Existing points searched for a point's neighbour along the stretch.
const SIDE_NEIGHBOURS: usize = 8;

/// That neighbour lies within 45° of the stretch direction...
const MIN_SIDE_COS: f32 = std::f32::consts::FRAC_1_SQRT_2;

/// ...and within this many spacings.
const MAX_SIDE_DISTANCE: f32 = 2.0;

/// A candidate closer than this fraction of its spacing to another point is dropped.
const MIN_GAP: f32 = 1.0 / 3.0;

/// Default number of simulation steps between resampling checks of a running surface.
pub const DEFAULT_RESAMPLE_INTERVAL: u32 = 30;

/// Resampling settings. In a scene file: `resample: Some((factor: 1.5))`, every field
/// optional.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ResampleConfig {
    /// Resample where the local spacing grew by more than this factor (> 1).
    pub factor: f32,
    /// Passes at most.
    pub max_passes: usize,
    /// New points at most, per point there was.
    pub max_new_per_point: f32,
    /// A running surface checks every this many simulation steps (after the step whose
    /// count is a multiple of it), so that a surface gets the same points however often it
    /// is drawn.
    pub interval: u32,
}

impl ResampleConfig {
    /// Checks the settings.
    pub fn validate(&self) -> Result<(), ResampleError> {
        if !(self.factor > 1.0 && self.factor.is_finite()) {
            return Err(ResampleError::InvalidConfig(
                "the factor must be a finite number above 1",
            ));
        }
        if !(self.max_new_per_point >= 0.0 && self.max_new_per_point.is_finite()) {
            return Err(ResampleError::InvalidConfig(
                "the cap on new points must be finite and not negative",
            ));
        }
        if self.interval == 0 {
            return Err(ResampleError::InvalidConfig(
                "the interval must be at least one step",
            ));
        }
        Ok(())
    }
}

impl Default for ResampleConfig {
    fn default() -> Self {
        Self {
            factor: DEFAULT_RESAMPLE_FACTOR,
            max_passes: DEFAULT_RESAMPLE_PASSES,
            max_new_per_point: DEFAULT_MAX_NEW_PER_POINT,
            interval: DEFAULT_RESAMPLE_INTERVAL,
        }
    }
}

/// Why resampling could not run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ResampleError {
    /// A setting out of range.
    #[error("invalid resampling setting: {0}")]
    InvalidConfig(&'static str),
    /// The displacements do not match the transfer's simulation points.
    #[error(transparent)]
    Transfer(#[from] crate::core::transfer::TransferError),
}

/// What a resampling did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct ResampleReport {
    /// Points inserted.
    pub inserted: usize,
    /// Passes that inserted points.
    pub passes: usize,
    /// Whether the cap on new points stopped it.
    pub capped: bool,
}

/// Rest spacing per dense point, kept beside a [`Transfer`] that gets resampled.
#[derive(Debug, Clone)]
pub struct Resampler {
    /// Each dense point's rest spacing (halved for inserted points).
    spacing: Vec<f32>,
    /// The spacing the surface was sampled at where each point lies (inherited).
    sampled: Vec<f32>,
}

/// The largest singular value of [t₁ + g₁, t₂ + g₂] and its direction in the rest tangent
/// plane.
fn stretch(normal: Vec3, g1: Vec3A, g2: Vec3A) -> (f32, Vec3) {
    let (t1, t2) = tangent_frame(normal);
    let (a, b) = (Vec3A::from(t1) + g1, Vec3A::from(t2) + g2);
    // FᵀF = [[p, q], [q, r]].
    let (p, q, r) = (a.dot(a), a.dot(b), b.dot(b));
    let mean = 0.5 * (p + r);
    let lambda = mean + (0.25 * (p - r) * (p - r) + q * q).sqrt();
    // Eigenvector of λ: (q, λ − p) or (λ − r, q), whichever is longer.
    let (e1, e2) = if (lambda - p).abs() > (lambda - r).abs() {
        (q, lambda - p)
    } else {
        (lambda - r, q)
    };
    let dir = (e1 * t1 + e2 * t2).normalize_or(t1);
    (lambda.max(0.0).sqrt(), dir)
}

impl Resampler {
    /// Each dense point's rest spacing and the spacing sampled where it lies (what a
    /// snapshot keeps).
    pub(crate) fn spacings(&self) -> (&[f32], &[f32]) {
        (&self.spacing, &self.sampled)
    }

    /// Replaces what [`Self::spacings`] gave (one of each per dense point, checked by the
    /// caller).
    pub(crate) fn set_spacings(&mut self, spacing: &[f32], sampled: &[f32]) {
        self.spacing = spacing.to_vec();
        self.sampled = sampled.to_vec();
    }

    /// Measures the rest spacing of the transfer's dense points.
    pub fn new(transfer: &Transfer) -> Self {
        let rest = transfer.rest_positions();
        let index = KnnIndex::build(rest);
        let mut spacing = index.knn_graph(rest, SPACING_NEIGHBOURS).mean_distances();
        // A single point has no neighbours, and no spacing to keep.
        spacing.resize(rest.len(), 0.0);
        Self {
            sampled: spacing.clone(),
            spacing,
        }
    }

    /// Rest spacing of each dense point.
    pub fn spacing(&self) -> &[f32] {
        &self.spacing
    }

    /// Inserts dense points where the simulation points' `displacements` stretched the
    /// surface (see the module docs). The transfer gains the new points.
    pub fn resample(
        &mut self,
        transfer: &mut Transfer,
        displacements: &[Vec3],
        config: &ResampleConfig,
    ) -> Result<ResampleReport, ResampleError> {
        config.validate()?;
        transfer.check(displacements, &[])?;
        let displacements = &simd_displacements(displacements);
        let mut report = ResampleReport::default();
        let budget = (transfer.len() as f64 * f64::from(config.max_new_per_point)) as usize;
        // Built when the first points are inserted: most checks of a running surface find
        // nothing to split.
        let mut sim_index = None;
        for _ in 0..config.max_passes {
            // Each over-stretched point's stretch direction (the fit and its singular value
            // computed once per point and pass).
            let splits: Vec<Option<Vec3>> = (0..transfer.len())
                .into_par_iter()
                .map(|i| {
                    let (_, g1, g2) = transfer.fitted(i, displacements);
                    let (sigma, dir) = stretch(transfer.normals[i], g1, g2);
                    let s = self.spacing[i];
                    (s > 0.0 && sigma * s > config.factor * self.sampled[i]).then_some(dir)
                })
                .collect();
            if splits.iter().all(Option::is_none) {
                break;
            }
            // Candidates from every over-stretched point, in point order: the midpoint to
            // its neighbour on either side along the stretch (none past a boundary).
            let index = KnnIndex::build(&transfer.rest);
            let candidates: Vec<(Vec3, Vec3, f32, f32)> = splits
                .par_iter()
                .enumerate()
                .filter_map(|(i, dir)| dir.map(|dir| (i, dir)))
                .flat_map_iter(|(i, dir)| {
                    let n = transfer.normals[i];
                    let (s, sampled) = (self.spacing[i], self.sampled[i]);
                    let p = transfer.rest[i];
                    let found = index.nearest(p, SIDE_NEIGHBOURS + 1);
                    let rest = &transfer.rest;
                    let normals = &transfer.normals;
                    [1.0f32, -1.0].into_iter().filter_map(move |sign| {
                        found
                            .iter()
                            .filter(|nb| nb.index as usize != i && nb.dist2 > 0.0)
                            .filter(|nb| nb.dist2.sqrt() <= MAX_SIDE_DISTANCE * s)
                            .map(|nb| {
                                let d = rest[nb.index as usize] - p;
                                (nb.index as usize, d.dot(sign * dir) / d.length())
                            })
                            .filter(|&(_, cos)| cos >= MIN_SIDE_COS)
                            .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)))
                            .map(|(j, _)| {
                                let mid = 0.5 * (p + rest[j]);
                                let normal = (n + normals[j]).normalize_or(n);
                                (mid, normal, 0.5 * s, sampled)
                            })
                    })
                })
                .collect();
            if candidates.is_empty() {
                break;
            }
            let accepted = self.thin(&index, candidates);
            let room = budget.saturating_sub(report.inserted);
            if accepted.len() > room {
                report.capped = true;
            }
            let accepted = &accepted[..accepted.len().min(room)];
            if accepted.is_empty() {
                break;
            }
            // A point that split now has neighbours at half its spacing.
            for (s, split) in self.spacing.iter_mut().zip(&splits) {
                if split.is_some() {
                    *s *= 0.5;
                }
            }
            let rest: Vec<Vec3> = accepted.iter().map(|c| c.0).collect();
            let normals: Vec<Vec3> = accepted.iter().map(|c| c.1).collect();
            let sim_index = sim_index.get_or_insert_with(|| KnnIndex::build(&transfer.sim_rest));
            transfer.extend(&rest, &normals, sim_index);
            self.spacing.extend(accepted.iter().map(|c| c.2));
            self.sampled.extend(accepted.iter().map(|c| c.3));
            report.inserted += accepted.len();
            report.passes += 1;
            if report.capped {
                break;
            }
        }
        Ok(report)
    }

    /// Drops candidates within [`MIN_GAP`] of their spacing from an existing point or an
    /// earlier accepted candidate.
    fn thin(
        &self,
        index: &KnnIndex,
        candidates: Vec<(Vec3, Vec3, f32, f32)>,
    ) -> Vec<(Vec3, Vec3, f32, f32)> {
        let clear: Vec<bool> = candidates
            .par_iter()
            .map(|c| {
                index
                    .nearest(c.0, 1)
                    .first()
                    .is_none_or(|nb| nb.dist2.sqrt() >= MIN_GAP * c.2)
            })
            .collect();
        // Accepted candidates in a hash grid whose cells are as large as the largest gap.
        let cell = candidates
            .iter()
            .map(|c| MIN_GAP * c.2)
            .fold(0.0f32, f32::max)
            .max(f32::MIN_POSITIVE);
        let key = |p: Vec3| (p / cell).floor().as_ivec3().to_array();
        let mut grid: HashMap<[i32; 3], Vec<Vec3>> = HashMap::new();
        let mut accepted = Vec::new();
        for (c, ok) in candidates.into_iter().zip(clear) {
            if !ok {
                continue;
            }
            let [x, y, z] = key(c.0);
            let gap2 = (MIN_GAP * c.2).powi(2);
            let near = (-1..=1).any(|dx| {
                (-1..=1).any(|dy| {
                    (-1..=1).any(|dz| {
                        grid.get(&[x + dx, y + dy, z + dz])
                            .is_some_and(|ps| ps.iter().any(|q| q.distance_squared(c.0) < gap2))
                    })
                })
            });
            if !near {
                grid.entry([x, y, z]).or_default().push(c.0);
                accepted.push(c);
            }
        }
        accepted
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stretch_of_a_pure_extension() {
        let n = Vec3::Z;
        let (t1, t2) = tangent_frame(n);
        // Stretch by 3 along t1: ∂u/∂x̄ = 2 t1.
        let (t1a, t2a) = (Vec3A::from(t1), Vec3A::from(t2));
        let (sigma, dir) = stretch(n, 2.0 * t1a, Vec3A::ZERO);
        assert!((sigma - 3.0).abs() < 1e-5);
        assert!(dir.dot(t1).abs() > 0.9999);
        let (sigma, dir) = stretch(n, Vec3A::ZERO, 1.0 * t2a);
        assert!((sigma - 2.0).abs() < 1e-5);
        assert!(dir.dot(t2).abs() > 0.9999);
        let (sigma, _) = stretch(n, Vec3A::ZERO, Vec3A::ZERO);
        assert!((sigma - 1.0).abs() < 1e-6);
    }
}
