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
//! **Normals.** The deformed tangents are t₁ + a₁ and t₂ + a₂ (a₁, a₂ the fitted
//! derivatives of the displacement), the deformed normal their cross product: exact for
//! any affine motion, and no k-NN search or PCA per frame.
//! [`pca_normals_of`](crate::core::normals::pca_normals_of) recomputes normals the paper's
//! way, for comparison; `fixtures::paper_transfer` is the paper's whole per-frame method,
//! kept as the baseline the precomputed transfer is measured against.
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

pub mod resample;

use glam::{DVec3, Vec3, Vec3A};
use rayon::prelude::*;

use crate::core::cloud::first_invalid_point;
use crate::core::cloud::knn::KnnIndex;

/// Default number of simulation points each dense point follows (`point-springs bench
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
/// 2 to 5 times smaller than at 1.0 (`point-springs bench transfer`).
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

/// Per-frame work is split in at least this many pieces (so small clouds still keep every
/// thread busy), of at least [`MIN_FRAME_CHUNK`] points.
const FRAME_PIECES: usize = 16;
const MIN_FRAME_CHUNK: usize = 128;

/// Dense points per parallel task of a per-frame product.
fn frame_chunk(n: usize) -> usize {
    (n / FRAME_PIECES).clamp(MIN_FRAME_CHUNK, CHUNK)
}

/// Called from outside a rayon thread pool, a frame of up to this many dense points runs on
/// the calling thread: handing the work to the pool and sleeping until it is done costs more
/// than the product itself (on the 3203-point sphere, 40 % of the time went to the wake-ups).
const SEQUENTIAL_POINTS: usize = 16_384;

/// Called from a thread of a rayon pool, where splitting costs little, a frame runs in
/// parallel from this many dense points (on the 3203-point sphere: 45 µs on two threads
/// against 66 µs on one).
const SEQUENTIAL_POINTS_IN_POOL: usize = 1024;

/// Whether a frame over `n` dense points should run in parallel.
fn parallel_frame(n: usize) -> bool {
    let limit = if rayon::current_thread_index().is_some() {
        SEQUENTIAL_POINTS_IN_POOL
    } else {
        SEQUENTIAL_POINTS
    };
    n > limit
}

/// Runs `work(chunk index, positions chunk, normals chunk)` over chunks of `size` points
/// (the normals chunk is empty when there are no normals), in parallel where
/// [`parallel_frame`] says so.
fn for_each_chunk(
    size: usize,
    positions: &mut [Vec3],
    normals: Option<&mut [Vec3]>,
    work: impl Fn(usize, &mut [Vec3], &mut [Vec3]) + Sync + Send,
) {
    let sequential = !parallel_frame(positions.len());
    match (normals, sequential) {
        (Some(normals), true) => positions
            .chunks_mut(size)
            .zip(normals.chunks_mut(size))
            .enumerate()
            .for_each(|(c, (p, n))| work(c, p, n)),
        (Some(normals), false) => positions
            .par_chunks_mut(size)
            .zip(normals.par_chunks_mut(size))
            .enumerate()
            .for_each(|(c, (p, n))| work(c, p, n)),
        (None, true) => positions
            .chunks_mut(size)
            .enumerate()
            .for_each(|(c, p)| work(c, p, &mut [])),
        (None, false) => positions
            .par_chunks_mut(size)
            .enumerate()
            .for_each(|(c, p)| work(c, p, &mut [])),
    }
}

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
}

/// Kinds of fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Fit {
    Full,
    Plane,
    Regularised,
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
#[derive(Debug, Clone)]
pub(crate) enum Neighbours {
    /// At most [`NARROW_INDEX_LIMIT`] simulation points.
    Narrow(Vec<u16>),
    /// More.
    Wide(Vec<u32>),
}

/// Precomputed transfer coefficients from simulation points to dense points.
#[derive(Debug, Clone)]
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
    /// The kinds of fit; its `residual` count is `residual_rows`' length.
    pub(crate) report: FitReport,
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
    /// Precomputes the transfer from simulation points at `sim_rest` to dense points at
    /// `rest` with unit `normals` (all in the rest state).
    pub fn new(
        rest: &[Vec3],
        normals: &[Vec3],
        sim_rest: &[Vec3],
        config: TransferConfig,
    ) -> Result<Self, TransferError> {
        if !(1..=MAX_TRANSFER_K).contains(&config.k) {
            return Err(TransferError::KOutOfRange(config.k));
        }
        if !(config.bandwidth > 0.0 && config.bandwidth.is_finite()) {
            return Err(TransferError::InvalidBandwidth(config.bandwidth));
        }
        if sim_rest.is_empty() {
            return Err(TransferError::NoSimulationPoints);
        }
        if sim_rest.len() > MAX_SIMULATION_POINTS {
            return Err(TransferError::TooManySimulationPoints(sim_rest.len()));
        }
        if rest.len() != normals.len() {
            return Err(TransferError::LengthMismatch {
                positions: rest.len(),
                normals: normals.len(),
            });
        }
        if let Some(index) = sim_rest.iter().position(|p| !p.is_finite()) {
            return Err(TransferError::InvalidPoint {
                which: "simulation",
                index,
            });
        }
        if let Some(index) = first_invalid_point(rest, normals) {
            return Err(TransferError::InvalidPoint {
                which: "dense",
                index,
            });
        }
        let mut transfer = Self {
            config,
            k: config.k.min(sim_rest.len()),
            rest: Vec::new(),
            normals: Vec::new(),
            sim_rest: sim_rest.to_vec(),
            neighbours: if sim_rest.len() <= NARROW_INDEX_LIMIT {
                Neighbours::Narrow(Vec::new())
            } else {
                Neighbours::Wide(Vec::new())
            },
            coefficients: Vec::new(),
            residual_rows: Vec::new(),
            report: FitReport::default(),
        };
        let normals: Vec<Vec3> = normals.iter().map(|n| n.normalize()).collect();
        transfer.extend(rest, &normals, &KnnIndex::build(sim_rest));
        Ok(transfer)
    }

    /// Adds dense points (validated, unit normals) with their own coefficients.
    pub(crate) fn extend(&mut self, rest: &[Vec3], normals: &[Vec3], index: &KnnIndex) {
        let (k, start) = (self.k, self.rest.len());
        self.rest.extend_from_slice(rest);
        self.normals.extend_from_slice(normals);
        let stride = row_stride(k);
        self.coefficients.resize((start + rest.len()) * stride, 0.0);
        let coefficients = &mut self.coefficients[start * stride..];
        let job = RowFit {
            rest,
            normals,
            sim: &self.sim_rest,
            index,
            k,
            bandwidth: self.config.bandwidth,
        };
        let fits = match &mut self.neighbours {
            Neighbours::Narrow(n) => job.fill(n, start, coefficients),
            Neighbours::Wide(n) => job.fill(n, start, coefficients),
        };
        for (row, (fit, reproduces_rest)) in fits.into_iter().enumerate() {
            match fit {
                Fit::Full => self.report.full += 1,
                Fit::Plane => self.report.plane += 1,
                Fit::Regularised => self.report.regularised += 1,
            }
            if !reproduces_rest {
                self.residual_rows.push(start + row);
            }
        }
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

    /// Which fit the dense points got.
    pub fn report(&self) -> FitReport {
        FitReport {
            residual: self.residual_rows.len(),
            ..self.report
        }
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

    /// Checks the displacement count and the output lengths.
    pub(crate) fn check(
        &self,
        displacements: &[Vec3],
        outputs: &[usize],
    ) -> Result<(), TransferError> {
        if displacements.len() != self.sim_rest.len() {
            return Err(TransferError::DisplacementCount {
                expected: self.sim_rest.len(),
                found: displacements.len(),
            });
        }
        if let Some(&found) = outputs.iter().find(|&&l| l != self.len()) {
            return Err(TransferError::OutputLength {
                expected: self.len(),
                found,
            });
        }
        Ok(())
    }

    /// Deformed dense positions and normals for the simulation points' `displacements`
    /// (current minus rest position), written into `positions` and `normals`.
    pub fn apply(
        &self,
        displacements: &[Vec3],
        positions: &mut [Vec3],
        normals: &mut [Vec3],
    ) -> Result<(), TransferError> {
        self.check(displacements, &[positions.len(), normals.len()])?;
        self.frame(displacements, positions, Some(normals));
        Ok(())
    }

    /// Deformed dense positions only (no normals: cheaper when a scene does not need them).
    pub fn apply_positions(
        &self,
        displacements: &[Vec3],
        positions: &mut [Vec3],
    ) -> Result<(), TransferError> {
        self.check(displacements, &[positions.len()])?;
        self.frame(displacements, positions, None);
        Ok(())
    }

    /// A frame (lengths checked) from displacements, split in chunks that run in parallel
    /// where [`parallel_frame`] says so.
    fn frame(&self, displacements: &[Vec3], positions: &mut [Vec3], normals: Option<&mut [Vec3]>) {
        let input = FrameInput::from_displacements(self, displacements);
        let size = frame_chunk(self.len());
        for_each_chunk(size, positions, normals, |chunk, pos, nrm| {
            self.rows(&input, chunk * size, pos, nrm);
        });
    }

    /// The whole frame `input` describes: deformed positions, and unit normals unless
    /// `normals` is empty. Large frames run in parallel on rayon's pool (see
    /// [`Self::frame_rows`] to split the work some other way).
    pub fn apply_frame(
        &self,
        input: &FrameInput,
        positions: &mut [Vec3],
        normals: &mut [Vec3],
    ) -> Result<(), TransferError> {
        if positions.len() != self.len() {
            return Err(TransferError::OutputLength {
                expected: self.len(),
                found: positions.len(),
            });
        }
        if input.current.len() != self.sim_rest.len() {
            return Err(TransferError::DisplacementCount {
                expected: self.sim_rest.len(),
                found: input.current.len(),
            });
        }
        if !(normals.is_empty() || normals.len() == positions.len()) {
            return Err(TransferError::OutputLength {
                expected: self.len(),
                found: normals.len(),
            });
        }
        let size = frame_chunk(self.len());
        let normals = (!normals.is_empty()).then_some(normals);
        for_each_chunk(size, positions, normals, |chunk, pos, nrm| {
            self.rows(input, chunk * size, pos, nrm);
        });
        Ok(())
    }

    /// Rows `first..first + positions.len()` of the frame `input` describes: the deformed
    /// positions, and the unit normals when `normals` is not empty (it must then be as long
    /// as `positions`). Chunks of a frame are independent, so a caller may compute them on
    /// threads of its own (the Bevy layer uses Bevy's task pool); the result does not
    /// depend on how the rows are split.
    pub fn frame_rows(
        &self,
        input: &FrameInput,
        first: usize,
        positions: &mut [Vec3],
        normals: &mut [Vec3],
    ) -> Result<(), TransferError> {
        if input.current.len() != self.sim_rest.len() {
            return Err(TransferError::DisplacementCount {
                expected: self.sim_rest.len(),
                found: input.current.len(),
            });
        }
        let end = first.checked_add(positions.len());
        if end.is_none_or(|end| end > self.len())
            || !(normals.is_empty() || normals.len() == positions.len())
        {
            return Err(TransferError::OutputLength {
                expected: self.len(),
                found: end.unwrap_or(usize::MAX).max(normals.len()),
            });
        }
        self.rows(input, first, positions, normals);
        Ok(())
    }

    /// One chunk of rows (ranges checked): [`Self::chunk_rows`] for the index width,
    /// compiled for the default k (and so fully unrolled) where that is the k.
    fn rows(&self, input: &FrameInput, first: usize, pos: &mut [Vec3], nrm: &mut [Vec3]) {
        const D: usize = DEFAULT_TRANSFER_K;
        match (&self.neighbours, self.k == D) {
            (Neighbours::Narrow(n), true) => self.chunk_rows::<_, D>(n, input, first, pos, nrm),
            (Neighbours::Narrow(n), false) => self.chunk_rows::<_, 0>(n, input, first, pos, nrm),
            (Neighbours::Wide(n), true) => self.chunk_rows::<_, D>(n, input, first, pos, nrm),
            (Neighbours::Wide(n), false) => self.chunk_rows::<_, 0>(n, input, first, pos, nrm),
        }
    }

    /// A chunk of rows over neighbour rows of one index width; `K` is k, or 0 for any.
    fn chunk_rows<I: NeighbourIndex, const K: usize>(
        &self,
        neighbours: &[I],
        input: &FrameInput,
        first: usize,
        pos: &mut [Vec3],
        nrm: &mut [Vec3],
    ) {
        // A constant in the body itself (not captured), so that the loops unroll.
        let k = if K == 0 { self.k } else { K };
        // Where the fit reproduces the rest surface, the fitted position and tangents of the
        // simulation points' current positions are the deformed ones.
        pulp::Arch::new().dispatch(FrameRows::<I, K> {
            transfer: self,
            neighbours,
            current: &input.current,
            first,
            positions: &mut *pos,
            normals: &mut *nrm,
        });
        let residual = self.residual_rows_in(first, pos.len());
        if !residual.is_empty() {
            let disp = &input.displacements;
            for &i in residual {
                let (u, g1, g2) = self.row_sums(neighbours, i, k, disp);
                pos[i - first] = self.rest[i] + Vec3::from(u);
                if let Some(n) = nrm.get_mut(i - first) {
                    let (t1, t2) = tangent_frame(self.normals[i]);
                    let (t1, t2) = (Vec3A::from(t1) + g1, Vec3A::from(t2) + g2);
                    *n = Vec3::from(t1.cross(t2));
                }
            }
        }
        // Normalised in a second, short loop: the square roots and divisions of many points
        // then overlap instead of each waiting for its own.
        for (row, n) in nrm.iter_mut().enumerate() {
            *n = unit_or(*n, || self.normals[first + row]);
        }
    }

    /// Convenience: [`Self::apply`] into new vectors.
    pub fn deform(&self, displacements: &[Vec3]) -> Result<(Vec<Vec3>, Vec<Vec3>), TransferError> {
        let mut positions = vec![Vec3::ZERO; self.len()];
        let mut normals = vec![Vec3::ZERO; self.len()];
        self.apply(displacements, &mut positions, &mut normals)?;
        Ok((positions, normals))
    }

    /// The residual rows among the `len` rows from `first` on.
    fn residual_rows_in(&self, first: usize, len: usize) -> &[usize] {
        let rows = &self.residual_rows;
        let from = rows.partition_point(|&i| i < first);
        let to = rows.partition_point(|&i| i < first + len);
        &rows[from..to]
    }

    /// The fitted displacement at dense point `i` and its derivatives along t₁ and t₂.
    pub(crate) fn fitted(&self, i: usize, displacements: &[Vec3A]) -> (Vec3A, Vec3A, Vec3A) {
        match &self.neighbours {
            Neighbours::Narrow(n) => self.row_sums(n, i, self.k, displacements),
            Neighbours::Wide(n) => self.row_sums(n, i, self.k, displacements),
        }
    }

    /// Row `i`'s fit of `values` (one per simulation point): its value at the dense point
    /// and its slopes along t₁ and t₂. With a the anchor's value and eⱼ = vⱼ − a the other
    /// neighbours' offsets from it, the value is a + Σ c⁰ⱼeⱼ and the slopes Σ c¹ⱼeⱼ and
    /// Σ c²ⱼeⱼ: every fit reproduces constants (its coefficients sum to 1 in the value and
    /// to 0 in the slopes), so the anchor's own coefficient need not be stored, and the
    /// sums run over small offsets rather than large absolute values.
    #[inline(always)]
    fn row_sums<I: NeighbourIndex>(
        &self,
        neighbours: &[I],
        i: usize,
        k: usize,
        values: &[Vec3A],
    ) -> (Vec3A, Vec3A, Vec3A) {
        // Two sets of sums, over even and odd neighbours: two short dependency chains
        // instead of one long one.
        let (anchor, others) = neighbours[i * k..(i + 1) * k].split_at(1);
        let m = k - 1;
        let row = &self.coefficients[i * row_stride(k)..][..3 * m];
        let (c0, rest) = row.split_at(m);
        let (c1, c2) = rest.split_at(m);
        let a = values[anchor[0].get()];
        let mut sums = [[Vec3A::ZERO; 3]; 2];
        let add = |s: &mut [Vec3A; 3], t: usize| {
            let e = values[others[t].get()] - a;
            s[0] += e * c0[t];
            s[1] += e * c1[t];
            s[2] += e * c2[t];
        };
        let mut t = 0;
        while t + 1 < m {
            let [even, odd] = &mut sums;
            add(even, t);
            add(odd, t + 1);
            t += 2;
        }
        if t < m {
            add(&mut sums[0], t);
        }
        let [even, odd] = sums;
        (a + (even[0] + odd[0]), even[1] + odd[1], even[2] + odd[2])
    }

    /// [`Self::row_sums`]' value alone.
    #[inline(always)]
    fn row_value<I: NeighbourIndex>(
        &self,
        neighbours: &[I],
        i: usize,
        k: usize,
        values: &[Vec3A],
    ) -> Vec3A {
        let (anchor, others) = neighbours[i * k..(i + 1) * k].split_at(1);
        let c0 = &self.coefficients[i * row_stride(k)..][..k - 1];
        let a = values[anchor[0].get()];
        a + others
            .iter()
            .zip(c0)
            .fold(Vec3A::ZERO, |s, (j, &c)| s + (values[j.get()] - a) * c)
    }
}

/// A chunk of a frame's rows computed from the simulation points' current positions
/// (positions and unnormalised normals, or positions alone when `normals` is empty), handed
/// to [`pulp`] so that the loop is compiled for, and runs with, the widest instruction set
/// the processor has (AVX2 broadcasts each coefficient straight from memory, and its
/// three-operand forms save the copies SSE2 needs). `K` is k, or 0 for any.
struct FrameRows<'a, I, const K: usize> {
    transfer: &'a Transfer,
    neighbours: &'a [I],
    current: &'a [Vec3A],
    first: usize,
    positions: &'a mut [Vec3],
    normals: &'a mut [Vec3],
}

impl<I: NeighbourIndex, const K: usize> pulp::WithSimd for FrameRows<'_, I, K> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        let t = self.transfer;
        let k = if K == 0 { t.k } else { K };
        let (neighbours, current, first) = (self.neighbours, self.current, self.first);
        if self.normals.is_empty() {
            for (row, p) in self.positions.iter_mut().enumerate() {
                *p = Vec3::from(t.row_value(neighbours, first + row, k, current));
            }
        } else {
            let rows = self.positions.iter_mut().zip(self.normals.iter_mut());
            for (row, (p, n)) in rows.enumerate() {
                let (v, s1, s2) = t.row_sums(neighbours, first + row, k, current);
                *p = Vec3::from(v);
                *n = Vec3::from(s1.cross(s2));
            }
        }
    }
}

/// Numbers stored per row for k neighbours: three coefficients for each but the anchor (one
/// unused number when k = 1, so that rows never have zero length).
pub(crate) fn row_stride(k: usize) -> usize {
    (3 * (k - 1)).max(1)
}

/// The fits of new dense points (validated, unit normals) to the simulation points.
struct RowFit<'a> {
    rest: &'a [Vec3],
    normals: &'a [Vec3],
    sim: &'a [Vec3],
    index: &'a KnnIndex,
    k: usize,
    bandwidth: f32,
}

impl RowFit<'_> {
    /// Fits the rows (in parallel): the neighbours are appended to `neighbours` from row
    /// `start` on (k a row), the coefficients written to `coefficients` ([`row_stride`] a
    /// row). Per row: its kind of fit, and whether it reproduces the rest surface.
    fn fill<I: NeighbourIndex>(
        &self,
        neighbours: &mut Vec<I>,
        start: usize,
        coefficients: &mut [f32],
    ) -> Vec<(Fit, bool)> {
        let (k, stride) = (self.k, row_stride(self.k));
        neighbours.resize((start + self.rest.len()) * k, I::default());
        neighbours[start * k..]
            .par_chunks_mut(CHUNK * k)
            .zip(coefficients.par_chunks_mut(CHUNK * stride))
            .enumerate()
            .flat_map_iter(|(chunk, (nbrs, coefs))| {
                let mut fits = Vec::with_capacity(nbrs.len() / k);
                let mut nbr = Vec::with_capacity(k);
                let mut coef = vec![Vec3A::ZERO; k];
                for (row, (nbrs, coefs)) in nbrs
                    .chunks_exact_mut(k)
                    .zip(coefs.chunks_exact_mut(stride))
                    .enumerate()
                {
                    let i = chunk * CHUNK + row;
                    let (p, n) = (self.rest[i], self.normals[i]);
                    nbr.clear();
                    nbr.extend(self.index.nearest(p, k).iter().map(|nb| nb.index));
                    let fit = fit_point(p, n, self.sim, &nbr, self.bandwidth, &mut coef);
                    let m = k - 1;
                    let (c0, rest) = coefs.split_at_mut(m);
                    let (c1, c2) = rest.split_at_mut(m);
                    for (stored, &j) in nbrs.iter_mut().zip(&nbr) {
                        *stored = I::new(j);
                    }
                    for (t, c) in coef[1..].iter().enumerate() {
                        (c0[t], c1[t], c2[t]) = (c.x, c.y, c.z);
                    }
                    fits.push((fit, reproduces_rest(p, n, self.sim, &nbr, &coef)));
                }
                fits
            })
            .collect()
    }
}

/// Whether the stored fit of dense point `p` (unit normal `n`) to its neighbours `nbr`
/// (coefficients `coef`, the anchor's unused) gives back, from the neighbours' rest
/// positions, `p` itself to within [`REST_TOLERANCE`] times the neighbourhood's reach and
/// the tangents t₁, t₂ to within [`REST_TOLERANCE`]. The full fit does, by construction
/// (it reproduces every affine function of position, and the position is one), up to the
/// rounding of its coefficients; so does a plane fit on flat ground.
fn reproduces_rest(p: Vec3, n: Vec3, sim: &[Vec3], nbr: &[u32], coef: &[Vec3A]) -> bool {
    let (t1, t2) = tangent_frame(n);
    let p = p.as_dvec3();
    let anchor = sim[nbr[0] as usize].as_dvec3();
    let (mut value, mut s1, mut s2) = (anchor, DVec3::ZERO, DVec3::ZERO);
    let mut reach = anchor.distance(p);
    for (&j, c) in nbr.iter().zip(coef).skip(1) {
        let x = sim[j as usize].as_dvec3();
        let e = x - anchor;
        value += f64::from(c.x) * e;
        s1 += f64::from(c.y) * e;
        s2 += f64::from(c.z) * e;
        reach = reach.max(x.distance(p));
    }
    value.distance(p) <= REST_TOLERANCE * reach
        && s1.distance(t1.as_dvec3()) <= REST_TOLERANCE
        && s2.distance(t2.as_dvec3()) <= REST_TOLERANCE
}

/// `n` normalised, or `fallback()` where `n` is (nearly) zero or not finite.
#[inline]
fn unit_or(n: Vec3, fallback: impl FnOnce() -> Vec3) -> Vec3 {
    let len = n.length();
    if len > MIN_NORMAL_LENGTH && len.is_finite() {
        n * len.recip()
    } else {
        fallback()
    }
}

/// The simulation points' current positions (rest plus displacement) as 16-byte SIMD
/// vectors (the per-frame loops gather them).
fn simd_positions(rest: &[Vec3], displacements: &[Vec3]) -> Vec<Vec3A> {
    rest.iter()
        .zip(displacements)
        .map(|(&x, &d)| Vec3A::from(x + d))
        .collect()
}

/// Displacements as 16-byte SIMD vectors (the per-frame loops gather them).
pub(crate) fn simd_displacements(displacements: &[Vec3]) -> Vec<Vec3A> {
    displacements.iter().map(|&d| Vec3A::from(d)).collect()
}

/// A symmetric positive semi-definite matrix of at most 4 × 4, and its Cholesky factor.
struct Normal4 {
    m: [[f64; 4]; 4],
    size: usize,
}

impl Normal4 {
    /// Cholesky factor L (lower) of the leading `size` block; `None` when a pivot falls below
    /// `rel` times the largest diagonal entry.
    fn cholesky(&self, rel: f64) -> Option<[[f64; 4]; 4]> {
        let n = self.size;
        let scale = (0..n).map(|i| self.m[i][i]).fold(0.0, f64::max);
        if scale <= 0.0 || !scale.is_finite() {
            return None;
        }
        let mut l = [[0.0; 4]; 4];
        for i in 0..n {
            for j in 0..=i {
                let mut s = self.m[i][j];
                for (a, b) in l[i][..j].iter().zip(&l[j][..j]) {
                    s -= a * b;
                }
                if i == j {
                    if s <= rel * scale {
                        return None;
                    }
                    l[i][i] = s.sqrt();
                } else {
                    l[i][j] = s / l[j][j];
                }
            }
        }
        Some(l)
    }
}

/// Solves L Lᵀ x = e_r for the leading `n` block.
fn solve_unit(l: &[[f64; 4]; 4], n: usize, r: usize) -> [f64; 4] {
    let mut y = [0.0; 4];
    for i in 0..n {
        let mut s = if i == r { 1.0 } else { 0.0 };
        for j in 0..i {
            s -= l[i][j] * y[j];
        }
        y[i] = s / l[i][i];
    }
    let mut x = [0.0; 4];
    for i in (0..n).rev() {
        let mut s = y[i];
        for j in i + 1..n {
            s -= l[j][i] * x[j];
        }
        x[i] = s / l[i][i];
    }
    x
}

/// Fits dense point `p` (unit normal `n`) to its neighbours `nbr` among `sim`: writes, per
/// neighbour, the coefficients of the value and the two tangent derivatives.
fn fit_point(
    p: Vec3,
    n: Vec3,
    sim: &[Vec3],
    nbr: &[u32],
    bandwidth: f32,
    coef: &mut [Vec3A],
) -> Fit {
    let (t1, t2) = tangent_frame(n);
    let (t1, t2, n) = (t1.as_dvec3(), t2.as_dvec3(), n.as_dvec3());
    let local: Vec<DVec3> = nbr
        .iter()
        .map(|&j| {
            let d = (sim[j as usize] - p).as_dvec3();
            DVec3::new(d.dot(t1), d.dot(t2), d.dot(n))
        })
        .collect();
    // h: the bandwidth times the farthest neighbour's distance (1 when all coincide with p).
    // The distance in space, not in the plane: neighbours that all project close to p (far
    // along the normal) must not make h, and with it the slopes' scale, tiny.
    let reach = local.iter().map(|q| q.length()).fold(0.0, f64::max);
    let h = if reach > 0.0 {
        f64::from(bandwidth) * reach
    } else {
        1.0
    };
    let basis = |q: &DVec3| [1.0, q.x / h, q.y / h, q.z / h];
    let weights: Vec<f64> = local
        .iter()
        .map(|q| (-(q.x * q.x + q.y * q.y) / (h * h)).exp())
        .collect();
    let mut normal = Normal4 {
        m: [[0.0; 4]; 4],
        size: 4,
    };
    for (q, &w) in local.iter().zip(&weights) {
        let phi = basis(q);
        for r in 0..4 {
            for s in 0..4 {
                normal.m[r][s] += w * phi[r] * phi[s];
            }
        }
    }
    // Coefficients of the value and the two slopes (unscaled by h) for a factored fit:
    // rows 0..3 of A⁻¹ (A symmetric), then c_r[j] = w_j φ(j)·row_r.
    let coefficients = |l: &[[f64; 4]; 4], size: usize, coef: &mut [Vec3A]| {
        let rows = [
            solve_unit(l, size, 0),
            solve_unit(l, size, 1),
            solve_unit(l, size, 2),
        ];
        let mut amplification = 0.0f64;
        for ((c, q), &w) in coef.iter_mut().zip(&local).zip(&weights) {
            let phi = basis(q);
            let dot = |row: &[f64; 4]| (0..size).map(|s| row[s] * phi[s]).sum::<f64>() * w;
            let value = dot(&rows[0]);
            amplification += value.abs();
            *c = Vec3A::new(
                value as f32,
                (dot(&rows[1]) / h) as f32,
                (dot(&rows[2]) / h) as f32,
            );
        }
        amplification
    };
    if let Some(l) = normal.cholesky(FULL_FIT_PIVOT)
        && coefficients(&l, 4, coef) <= MAX_AMPLIFICATION
    {
        return Fit::Full;
    }
    normal.size = 3;
    if let Some(l) = normal.cholesky(PLANE_FIT_PIVOT) {
        coefficients(&l, 3, coef);
        return Fit::Plane;
    }
    let ridge = RIDGE * weights.iter().sum::<f64>();
    normal.m[1][1] += ridge;
    normal.m[2][2] += ridge;
    match normal.cholesky(0.0) {
        Some(l) => {
            coefficients(&l, 3, coef);
        }
        None => {
            // No weight at all (cannot happen with finite input): follow the nearest.
            coef.iter_mut().for_each(|c| *c = Vec3A::ZERO);
            coef[0] = Vec3A::X;
        }
    }
    Fit::Regularised
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_solves_a_small_system() {
        let m = Normal4 {
            m: [
                [4.0, 1.0, 0.5, 0.0],
                [1.0, 3.0, 0.2, 0.1],
                [0.5, 0.2, 2.0, 0.3],
                [0.0, 0.1, 0.3, 1.0],
            ],
            size: 4,
        };
        let l = m.cholesky(1e-12).unwrap();
        for r in 0..4 {
            let x = solve_unit(&l, 4, r);
            for i in 0..4 {
                let row: f64 = (0..4).map(|j| m.m[i][j] * x[j]).sum();
                assert!((row - f64::from(u8::from(i == r))).abs() < 1e-12);
            }
        }
        let singular = Normal4 {
            m: [[1.0; 4]; 4],
            size: 2,
        };
        assert!(singular.cholesky(1e-8).is_none());
    }

    /// Every row's output the long way: rest position plus fitted displacement, normal from
    /// the rest frame plus the fitted slopes.
    fn long_way(t: &Transfer, displacements: &[Vec3]) -> (Vec<Vec3>, Vec<Vec3>) {
        let d = simd_displacements(displacements);
        (0..t.len())
            .map(|i| {
                let (u, g1, g2) = t.fitted(i, &d);
                let (t1, t2) = tangent_frame(t.normals[i]);
                let n = (Vec3A::from(t1) + g1).cross(Vec3A::from(t2) + g2);
                (t.rest[i] + Vec3::from(u), Vec3::from(n).normalize())
            })
            .unzip()
    }

    #[test]
    fn rows_from_current_positions_match_the_long_way() {
        // A frame computes most rows from the simulation points' current positions alone,
        // and the rows whose fit misses the rest surface (here: plane fits on a sphere,
        // with k = 4, and ridge fits to collinear points) from the displacements. Both must give what the long way gives, for
        // a motion that is neither rigid nor affine, away from the origin, with the
        // default k (unrolled) and another (not).
        let offset = Vec3::new(10.0, -3.0, 2.0);
        let moved = |cloud: crate::core::cloud::PointCloud| -> (Vec<Vec3>, Vec<Vec3>) {
            let p = cloud.positions().iter().map(|&p| p + offset).collect();
            (p, cloud.normals().unwrap().to_vec())
        };
        let (dense, normals) = moved(crate::core::cloud::shapes::fibonacci_sphere(3000, 1.0));
        let (sim, _) = moved(crate::core::cloud::shapes::fibonacci_sphere(300, 1.0));
        let (sheet, sheet_normals) = moved(crate::core::cloud::shapes::square_sheet(2.0, 0.05));
        let (sheet_sim, _) = moved(crate::core::cloud::shapes::square_sheet(2.0, 0.2));
        let wave = |x: Vec3| {
            let q = x - offset;
            Vec3::new((2.0 * q.y).sin(), q.x * q.z, (3.0 * q.x).cos() * q.y) * 0.1
        };
        // Collinear simulation points: ridge fits.
        let line: Vec<Vec3> = (0..20)
            .map(|i| offset + Vec3::new(i as f32 * 0.1 - 1.0, 0.03, 0.0))
            .collect();
        let (mut residual_seen, mut regularised_seen) = (false, false);
        for (p, n, s, k) in [
            (&dense, &normals, &sim, 4),
            (&dense, &normals, &sim, DEFAULT_TRANSFER_K),
            (&sheet, &sheet_normals, &sheet_sim, DEFAULT_TRANSFER_K),
            (&sheet, &sheet_normals, &line, DEFAULT_TRANSFER_K),
        ] {
            let config = TransferConfig {
                k,
                ..TransferConfig::default()
            };
            let t = Transfer::new(p, n, s, config).unwrap();
            let report = t.report();
            assert_eq!(report.residual, t.residual_rows.len());
            residual_seen |= report.residual > 0;
            regularised_seen |= report.regularised > 0;
            // At rest, the rest surface comes back.
            let (rest_p, rest_n) = t.deform(&vec![Vec3::ZERO; s.len()]).unwrap();
            for i in 0..p.len() {
                assert!(rest_p[i].distance(p[i]) < 2e-6, "k {k}, {i}");
                assert!(rest_n[i].distance(n[i]) < 1e-5, "k {k}, {i}");
            }
            let disp: Vec<Vec3> = s.iter().map(|&x| wave(x)).collect();
            let (pos, nrm) = t.deform(&disp).unwrap();
            let mut positions_only = vec![Vec3::ZERO; p.len()];
            t.apply_positions(&disp, &mut positions_only).unwrap();
            let (long_p, long_n) = long_way(&t, &disp);
            for i in 0..p.len() {
                assert!(pos[i].distance(long_p[i]) < 2e-6, "k {k}, {i}");
                assert!(positions_only[i].distance(long_p[i]) < 2e-6, "k {k}, {i}");
                assert!(nrm[i].distance(long_n[i]) < 1e-5, "k {k}, {i}");
            }
        }
        assert!(residual_seen && regularised_seen);
    }

    #[test]
    fn frame_is_right_handed() {
        for n in [
            Vec3::X,
            Vec3::Y,
            -Vec3::Z,
            Vec3::new(0.3, -0.4, 0.866).normalize(),
        ] {
            let (t1, t2) = tangent_frame(n);
            assert!((t1.cross(t2) - n).length() < 1e-6);
            assert!(t1.dot(n).abs() < 1e-6 && t2.dot(n).abs() < 1e-6);
        }
    }
}
