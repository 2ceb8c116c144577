//! Displacement transfer (the paper's §5, eq 7–12): from the simulation points back to every
//! dense point.
//!
//! For each dense point p with unit normal n, its k nearest simulation points *in the rest
//! state* are expressed in p's tangent frame (t₁, t₂, n): coordinates (x̄, ȳ) in the plane,
//! z̄ along the normal. Each displacement component u is fitted by weighted linear least
//! squares with Gaussian weights w = exp(−r²/h²), r the distance from p to a neighbour's
//! projection on the plane and h = `bandwidth` × the distance to the farthest neighbour.
//! The fitted value at p, u(p) = a₀ = e₀ᵀA⁻¹PᵀWu, is a fixed linear combination Σⱼ cⱼuⱼ of
//! the neighbours' displacements, and so are the tangent derivatives a₁ = ∂u/∂x̄ and
//! a₂ = ∂u/∂ȳ. Those coefficients are computed once ([`Transfer::new`], in parallel); each
//! frame is then a sparse matrix–vector product ([`Transfer::apply`], in parallel for large
//! clouds).
//!
//! **What a frame reads.** Every fit reproduces constants, so its value coefficients sum to 1
//! and its slope coefficients to 0: a row stores the coefficients of the other neighbours'
//! offsets from one of them, its anchor, and not the anchor's own. And where the fit
//! reproduces the rest surface itself (the full fit does, as the position is an affine
//! function of position; so does a plane fit on flat ground), the same sums over the
//! simulation points' *current positions* give the deformed position and the deformed
//! tangents t₁ + a₁, t₂ + a₂ directly: a frame then reads neither the dense point's rest
//! position nor its normal, only 10 indices and 27 coefficients (k = 10). The few rows that
//! do not reproduce the rest surface to [`REST_TOLERANCE`] (plane fits on curved ground,
//! ridge fits) are listed and computed the long way, from the displacements, the rest
//! position and the rest frame.
//!
//! **The normal coordinate.** The paper fits u = a₀ + a₁x̄ + a₂ȳ on the plane. On a curved
//! surface the neighbours sit off the plane by z̄ ≈ r²/2R, and an affine motion of them
//! (a rotation, say) moves them by M·(x̄t₁ + ȳt₂ + z̄n): the plane fit cannot follow the z̄
//! part, so even a rigid rotation would be transferred with an error growing with
//! curvature. So the fit is u = a₀ + a₁x̄ + a₂ȳ + a₃z̄, which reproduces every affine
//! displacement exactly, wherever the neighbours leave the plane (no Cholesky pivot below
//! [`FULL_FIT_PIVOT`]) and the fit does not amplify noise in the displacements more than
//! [`MAX_AMPLIFICATION`] times (Σ|cⱼ|; every dense point of the benchmark spheres passes,
//! see [`Transfer::report`]); elsewhere it is the paper's plane fit, exact on coplanar
//! neighbours. Where even the plane fit is singular (collinear neighbours, fewer than
//! three) the slopes are damped by a ridge term: the value then tends to a weighted mean,
//! never NaN.
//!
//! **Pins.** [`Transfer::hold`] fits the dense points by pinned simulation points over
//! their pinned neighbours alone (zero coefficients for the free ones), so the drawn
//! surface holds where the simulation does.
//!
//! **Normals.** The deformed tangents are t₁ + a₁ and t₂ + a₂ (a₁, a₂ the fitted
//! derivatives of the displacement), the deformed normal their cross product: exact for
//! any affine motion, and no k-NN search or PCA per frame.
//! [`pca_normals_of`](crate::core::normals::pca_normals_of) recomputes normals the paper's
//! way, for comparison; the paper's whole per-frame method, the baseline the precomputed
//! transfer is measured against, is in the `point-springs-bench` crate
//! (`bench/src/baselines/paper_transfer.rs`).
//!
//! ```
//! use bevy_point_springs::core::cloud::shapes::fibonacci_sphere;
//! use bevy_point_springs::core::transfer::{Transfer, TransferConfig};
//! use glam::{Quat, Vec3};
//!
//! let dense = fibonacci_sphere(2000, 1.0);
//! let sim_rest = fibonacci_sphere(200, 1.0).positions().to_vec();
//! let (p, n) = (dense.positions(), dense.normals().unwrap());
//! // Once:
//! let transfer = Transfer::new(p, n, &sim_rest, TransferConfig::default()).unwrap();
//! // Every frame: the simulation points' displacements in, the dense surface out.
//! let turn = Quat::from_rotation_y(0.5);
//! let displacements: Vec<Vec3> = sim_rest.iter().map(|&s| turn * s - s).collect();
//! let (positions, normals) = transfer.deform(&displacements).unwrap();
//! // A rigid motion comes back exactly, normals included.
//! for i in 0..p.len() {
//!     assert!(positions[i].distance(turn * p[i]) < 1e-5);
//!     assert!(normals[i].distance(turn * n[i]) < 1e-5);
//! }
//! ```

mod fit;
mod frame;
mod pins;
mod spread;

pub use pins::{PIN_BLEND, PIN_HOLD, Pins};

pub(crate) use frame::simd_displacements;
use frame::simd_positions;
pub mod gpu;
pub mod resample;

use glam::{Vec3, Vec3A};

use crate::core::cloud::first_invalid_point;
use crate::core::cloud::knn::KnnIndex;

/// Default number of simulation points each dense point follows (`point-springs-bench
/// transfer` measures k against error: 10 is as accurate as 12 and a sixth cheaper per frame).
pub const DEFAULT_TRANSFER_K: usize = 10;

/// Largest k accepted.
pub const MAX_TRANSFER_K: usize = 32;

/// Most simulation points a transfer follows (a bound on the memory a bad input can ask
/// for; a game's surface has thousands).
pub const MAX_SIMULATION_POINTS: usize = 1 << 23;

/// Up to this many simulation points, neighbour indices are stored in 16 bits: a frame then
/// reads 14 bytes a neighbour instead of 16 (the frame is bound by memory traffic at 10⁶
/// dense points).
pub const NARROW_INDEX_LIMIT: usize = 1 << 16;

/// Default Gaussian bandwidth, as a multiple of the farthest neighbour's distance: the
/// farthest then weighs e⁻⁴ ≈ 2 % (the fit changes little when the neighbour set changes
/// from one dense point to the next), and the error against a known smooth deformation is
/// 2 to 5 times smaller than at 1.0 (`point-springs-bench transfer`).
pub const DEFAULT_BANDWIDTH: f32 = 0.5;

/// The fit with the normal coordinate needs its Cholesky pivots above this fraction of the
/// largest (in coordinates scaled by h): the neighbours must not be coplanar.
pub const FULL_FIT_PIVOT: f64 = 1.0e-10;

/// ...and it is kept only when the sum of the absolute value coefficients, Σ|cⱼ| — how much
/// it can amplify noise in the displacements (1 for a weighted mean) — is at most this.
pub const MAX_AMPLIFICATION: f64 = 3.0;

/// The plane fit is taken as singular below this relative pivot.
const PLANE_FIT_PIVOT: f64 = 1.0e-8;

/// Ridge weight on the slopes of a singular fit, relative to the total weight.
const RIDGE: f64 = 1.0e-3;

/// Dense points per parallel task.
const CHUNK: usize = 2048;

/// How closely a row's fit must give back the rest surface from the simulation points'
/// rest positions (the position relative to the neighbourhood's reach, the unit tangents
/// absolutely) for a frame to use the simulation points' current positions directly.
/// Coefficients rounded to `f32` reproduce it to about 10⁻⁷.
pub const REST_TOLERANCE: f64 = 1.0e-6;

/// Below this length a deformed normal is taken as undefined (a fully crushed neighbourhood)
/// and the rest normal is kept.
const MIN_NORMAL_LENGTH: f32 = 1.0e-12;

/// How the deformed dense surface gets its normals.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum NormalUpdate {
    /// From the fitted displacement gradient (exact for affine motion, no search).
    #[default]
    Gradient,
    /// PCA over `k` neighbours of the deformed cloud, the paper's way (a k-NN search per
    /// frame: slow).
    Pca(usize),
}

/// How to build a transfer. In a scene file: `transfer: (k: 10, bandwidth: 0.5)`, every
/// field optional.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TransferConfig {
    /// Simulation points each dense point follows.
    pub k: usize,
    /// Gaussian bandwidth h as a multiple of the farthest neighbour's distance.
    pub bandwidth: f32,
    /// How the deformed normals are found (not used by [`Transfer`] itself, whose frames
    /// always give gradient normals; [`NormalUpdate::Pca`] replaces them afterwards).
    pub normals: NormalUpdate,
}

impl Default for TransferConfig {
    fn default() -> Self {
        Self {
            k: DEFAULT_TRANSFER_K,
            bandwidth: DEFAULT_BANDWIDTH,
            normals: NormalUpdate::Gradient,
        }
    }
}

/// Why a transfer could not be built or applied.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TransferError {
    /// There are no simulation points to follow.
    #[error("a transfer needs at least one simulation point")]
    NoSimulationPoints,
    /// More than [`MAX_SIMULATION_POINTS`] simulation points.
    #[error("a transfer follows at most {MAX_SIMULATION_POINTS} simulation points, got {0}")]
    TooManySimulationPoints(usize),
    /// k outside 1..=MAX_TRANSFER_K.
    #[error("the transfer's k must be between 1 and {MAX_TRANSFER_K}, got {0}")]
    KOutOfRange(usize),
    /// The bandwidth is not a positive finite number.
    #[error("the bandwidth must be a positive finite number, got {0}")]
    InvalidBandwidth(f32),
    /// Positions and normals differ in length.
    #[error("{positions} dense positions but {normals} normals")]
    LengthMismatch {
        /// Dense positions.
        positions: usize,
        /// Dense normals.
        normals: usize,
    },
    /// A position is not finite, or a normal not finite or zero.
    #[error("{which} point {index} has a non-finite position or a zero or non-finite normal")]
    InvalidPoint {
        /// "dense" or "simulation".
        which: &'static str,
        /// The point.
        index: usize,
    },
    /// The displacements do not match the simulation points.
    #[error("expected {expected} simulation displacements, got {found}")]
    DisplacementCount {
        /// Simulation points.
        expected: usize,
        /// Displacements given.
        found: usize,
    },
    /// The pins do not match the simulation points.
    #[error("expected a pin flag for each of {expected} simulation points, got {found}")]
    PinCount {
        /// Simulation points.
        expected: usize,
        /// Flags given.
        found: usize,
    },
    /// A snapshot's dense surface does not fit this one, or holds bad values.
    #[error("the snapshot's dense surface does not fit: {0}")]
    Snapshot(String),
    /// Forces handed to [`Transfer::spread_forces`] do not match the points.
    #[error("the {which} forces: expected {expected}, got {found}")]
    ForceCount {
        /// "dense" or "simulation".
        which: &'static str,
        /// Points.
        expected: usize,
        /// Forces given.
        found: usize,
    },
    /// A force handed to [`Transfer::spread_forces`] is not finite.
    #[error("the force on dense point {0} is not finite")]
    InvalidForce(usize),
    /// An output slice has the wrong length.
    #[error("the output holds {found} points, the transfer {expected}")]
    OutputLength {
        /// Dense points.
        expected: usize,
        /// Output length.
        found: usize,
    },
}

/// Which fit each dense point got.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FitReport {
    /// Fits with the normal coordinate (exact for affine motion on curved surfaces).
    pub full: usize,
    /// The paper's plane fit (coplanar neighbours).
    pub plane: usize,
    /// Ridge-damped fits (collinear or too few neighbours).
    pub regularised: usize,
    /// Rows whose fit does not give back the rest surface itself (plane fits on curved
    /// ground, ridge fits, a single neighbour); a frame computes them the longer way, from
    /// the displacements and the rest frame.
    pub residual: usize,
    /// Rows that follow pinned simulation points alone ([`Transfer::hold`]).
    pub held: usize,
}

/// A stored neighbour index (16 or 32 bits, see [`NARROW_INDEX_LIMIT`]).
pub(crate) trait NeighbourIndex: Copy + Default + Send + Sync {
    /// From an index known to fit.
    fn new(j: u32) -> Self;
    /// As an index.
    fn get(self) -> usize;
}

impl NeighbourIndex for u16 {
    #[inline]
    fn new(j: u32) -> Self {
        debug_assert!((j as usize) < NARROW_INDEX_LIMIT);
        j as u16
    }
    #[inline(always)]
    fn get(self) -> usize {
        usize::from(self)
    }
}

impl NeighbourIndex for u32 {
    #[inline]
    fn new(j: u32) -> Self {
        j
    }
    #[inline(always)]
    fn get(self) -> usize {
        self as usize
    }
}

/// The simulation points each dense point follows, k a row.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) enum Neighbours {
    /// At most [`NARROW_INDEX_LIMIT`] simulation points.
    Narrow(Vec<u16>),
    /// More.
    Wide(Vec<u32>),
}

/// Precomputed transfer coefficients from simulation points to dense points.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Transfer {
    pub(crate) config: TransferConfig,
    /// Neighbours per dense point (k, or all simulation points when there are fewer).
    pub(crate) k: usize,
    pub(crate) rest: Vec<Vec3>,
    /// Unit rest normals. A frame reads them (and `rest`) only for the residual rows, which
    /// derive their tangent frame from them ([`tangent_frame`]), and where a deformed
    /// normal is undefined.
    pub(crate) normals: Vec<Vec3>,
    pub(crate) sim_rest: Vec<Vec3>,
    /// Row i: the k simulation points dense point i follows, the first of them its anchor.
    pub(crate) neighbours: Neighbours,
    /// Row i (3(k − 1) numbers): the coefficients of the other neighbours' offsets from the
    /// anchor in the fitted value, then in the slope along t₁, then along t₂ (see
    /// [`Transfer::row_sums`]). Each frame streams every row, so their size is the
    /// per-frame cost; three separate runs let each coefficient be broadcast straight from
    /// memory.
    pub(crate) coefficients: Vec<f32>,
    /// The rows (ascending) whose fit does not reproduce the rest surface to
    /// [`REST_TOLERANCE`] (plane fits on curved ground, ridge fits, a single neighbour):
    /// a frame computes them from the displacements, the rest position and the rest frame,
    /// instead of from the simulation points' positions alone.
    pub(crate) residual_rows: Vec<usize>,
    /// Per row: its kind of fit, whether it is a residual row, whether it is held.
    pub(crate) kinds: Vec<fit::RowKind>,
    /// What the dense points are held to (see [`Transfer::hold`]).
    pub(crate) pins: Pins,
}

/// What a frame of a [`Transfer`] reads of the simulation: the simulation points' current
/// positions (and, where some rows need them, their displacements) as 16-byte SIMD
/// vectors. Keep one per surface and refill it each frame: nothing is allocated once it
/// has grown to size.
#[derive(Debug, Clone, Default)]
pub struct FrameInput {
    current: Vec<Vec3A>,
    displacements: Vec<Vec3A>,
}

impl FrameInput {
    /// The input for simulation points displaced by `displacements` from the transfer's rest
    /// positions (lengths checked by the caller).
    fn from_displacements(transfer: &Transfer, displacements: &[Vec3]) -> Self {
        let mut input = Self {
            current: simd_positions(&transfer.sim_rest, displacements),
            displacements: Vec::new(),
        };
        if !transfer.residual_rows.is_empty() {
            input.displacements = simd_displacements(displacements);
        }
        input
    }

    /// The simulation points' positions the input holds.
    pub(crate) fn current(&self) -> &[Vec3A] {
        &self.current
    }

    /// Fills the input from the simulation points' current positions, given as three
    /// coordinate arrays (see `PointState::position_arrays`).
    pub fn set_positions(
        &mut self,
        transfer: &Transfer,
        [x, y, z]: [&[f32]; 3],
    ) -> Result<(), TransferError> {
        let n = transfer.sim_rest.len();
        if let Some(found) = [x.len(), y.len(), z.len()].into_iter().find(|&l| l != n) {
            return Err(TransferError::DisplacementCount { expected: n, found });
        }
        self.current.clear();
        self.current
            .extend((0..n).map(|i| Vec3A::new(x[i], y[i], z[i])));
        self.displacements.clear();
        if !transfer.residual_rows.is_empty() {
            let rest = &transfer.sim_rest;
            self.displacements.extend(
                self.current
                    .iter()
                    .zip(rest)
                    .map(|(&c, &r)| c - Vec3A::from(r)),
            );
        }
        Ok(())
    }
}

/// The tangent frame (t₁, t₂) of a unit normal, with t₁ × t₂ = n (Duff et al.'s branchless
/// basis: one division, no cross product; it runs for every dense point every frame).
#[inline]
pub fn tangent_frame(n: Vec3) -> (Vec3, Vec3) {
    n.any_orthonormal_pair()
}

impl Transfer {
    /// Checks what a frame relies on: rows, normals, kinds and coefficients for every dense
    /// point, neighbours that exist, residual rows in order and as the kinds say, all
    /// numbers finite. A transfer read from a file is checked so before it is used; one
    /// [`Transfer::new`] built passes.
    pub fn check_parts(&self) -> Result<(), String> {
        let (n, m) = (self.rest.len(), self.sim_rest.len());
        if m == 0 || self.k == 0 || self.k != self.config.k.min(m) {
            return Err(format!("{m} simulation points, k = {}", self.k));
        }
        if self.normals.len() != n || self.kinds.len() != n {
            return Err(format!(
                "{n} dense points but {} normals and {} row kinds",
                self.normals.len(),
                self.kinds.len()
            ));
        }
        let finite = self
            .rest
            .iter()
            .chain(&self.normals)
            .chain(&self.sim_rest)
            .all(|p| p.is_finite());
        if !finite || !self.coefficients.iter().all(|c| c.is_finite()) {
            return Err("a position, normal or coefficient is not finite".into());
        }
        if self.coefficients.len() != n * row_stride(self.k) {
            return Err(format!(
                "{} coefficients for {n} rows",
                self.coefficients.len()
            ));
        }
        let in_range = match &self.neighbours {
            Neighbours::Narrow(v) if m <= NARROW_INDEX_LIMIT => {
                v.len() == n * self.k && v.iter().all(|&j| usize::from(j) < m)
            }
            Neighbours::Wide(v) if m > NARROW_INDEX_LIMIT => {
                v.len() == n * self.k && v.iter().all(|&j| (j as usize) < m)
            }
            _ => false,
        };
        if !in_range {
            return Err("neighbours missing or out of range".into());
        }
        let residual = (0..n).filter(|&i| self.kinds[i].residual);
        if !residual.eq(self.residual_rows.iter().copied()) {
            return Err("the residual rows are not those the row kinds name".into());
        }
        if !(self.pins.simulation.is_empty() || self.pins.simulation.len() == m)
            || self.pins.dense.len() > n
        {
            return Err("pins for points that do not exist".into());
        }
        Ok(())
    }

    /// Number of dense points.
    pub fn len(&self) -> usize {
        self.rest.len()
    }

    /// Whether there are no dense points.
    pub fn is_empty(&self) -> bool {
        self.rest.is_empty()
    }

    /// Number of simulation points followed.
    pub fn simulation_points(&self) -> usize {
        self.sim_rest.len()
    }

    /// Rest positions of the simulation points followed.
    pub fn simulation_rest(&self) -> &[Vec3] {
        &self.sim_rest
    }

    /// Rest positions of the dense points.
    pub fn rest_positions(&self) -> &[Vec3] {
        &self.rest
    }

    /// Rest normals of the dense points.
    pub fn rest_normals(&self) -> &[Vec3] {
        &self.normals
    }

    /// The settings.
    pub fn config(&self) -> TransferConfig {
        self.config
    }

    /// Bytes of precomputed data (neighbour indices and coefficients).
    pub fn coefficient_bytes(&self) -> usize {
        let indices = match &self.neighbours {
            Neighbours::Narrow(n) => size_of_val(n.as_slice()),
            Neighbours::Wide(n) => size_of_val(n.as_slice()),
        };
        indices
            + size_of_val(self.coefficients.as_slice())
            + size_of_val(self.residual_rows.as_slice())
    }
}

/// Numbers stored per row for k neighbours: three coefficients for each but the anchor (one
/// unused number when k = 1, so that rows never have zero length).
pub(crate) fn row_stride(k: usize) -> usize {
    (3 * (k - 1)).max(1)
}

#[cfg(test)]
mod tests;
