//! The dense surface of a running simulation: the transfer each frame, resampling when due.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use glam::Vec3;

use crate::core::cloud::io::{PlyEncoding, SaveError, write_ply};
use crate::core::solver::Masses;

use super::*;

/// The dense surface of a running simulation: its rest points and transfer coefficients
/// (inside the [`Transfer`]), its deformed positions and normals, and the resampling that
/// keeps it dense where it stretches.
#[derive(Debug, Clone)]
pub struct DenseCloud {
    /// Shared with the jobs of [`Self::job`] (copied on write while one runs).
    transfer: Arc<Transfer>,
    resample: Option<ResampleConfig>,
    resampler: Option<Resampler>,
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    input: FrameInput,
    /// Whether `positions` and `normals` follow the positions in `input`.
    fresh: bool,
    /// Bumped each time the positions or normals change.
    revision: u64,
    /// Points inserted by resampling so far.
    inserted: usize,
    /// The step count resampling last looked at (a paused surface is not checked again).
    maintained_at: u64,
    /// The revision of the masses whose pins the transfer holds to (0: none seen).
    pins_revision: u64,
    /// Names the transfer's coefficients: a new one each time they change (see
    /// [`Self::transfer_id`]).
    transfer_id: u64,
}

/// The next [`DenseCloud::transfer_id`].
static NEXT_TRANSFER_ID: AtomicU64 = AtomicU64::new(1);

fn next_transfer_id() -> u64 {
    NEXT_TRANSFER_ID.fetch_add(1, Ordering::Relaxed)
}

/// Where a [`DenseCloud`] stands (for a snapshot): its deformed points, the points
/// resampling inserted (their rest positions and normals, from which their transfer rows are
/// fitted again), the resampler's spacings and its counters.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DenseState {
    /// Deformed positions (inserted points included).
    pub positions: Vec<Vec3>,
    /// Deformed unit normals (a PCA normal update orients by them).
    pub normals: Vec<Vec3>,
    /// Rest positions of the points resampling inserted, in order.
    pub inserted_rest: Vec<Vec3>,
    /// Their rest normals.
    pub inserted_normals: Vec<Vec3>,
    /// The resampler's rest spacing per dense point (empty without resampling).
    pub spacing: Vec<f32>,
    /// The resampler's sampled spacing per dense point (empty without resampling).
    pub sampled: Vec<f32>,
    /// The step count resampling last looked at.
    pub maintained_at: u64,
    /// The revision of the positions and normals.
    pub revision: u64,
}

/// The rest shape of a dense surface's transfer, as a bake left it (for a saved game: a
/// surface prepared again from its source gets it back with [`DenseCloud::with_rest`]). The
/// points resampling inserted are not in it (a [`DenseState`] holds them).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DenseRest {
    /// Rest positions of the dense points.
    pub positions: Vec<Vec3>,
    /// Their unit rest normals.
    pub normals: Vec<Vec3>,
    /// Rest positions of the simulation points the transfer follows.
    pub simulation: Vec<Vec3>,
    /// The dense points named held ([`Pins::dense`]; none beyond the list's end).
    pub held: Vec<bool>,
}

/// The pieces of a frame, for callers that split its rows over threads of their own
/// (see [`DenseCloud::frame_parts`]).
#[derive(Debug)]
pub struct FrameParts<'a> {
    /// The coefficients.
    pub transfer: &'a Transfer,
    /// The simulation state the frame follows.
    pub input: &'a FrameInput,
    /// Where the deformed positions go.
    pub positions: &'a mut [Vec3],
    /// Where the deformed normals go.
    pub normals: &'a mut [Vec3],
}

impl DenseCloud {
    /// The dense surface at rest, following the transfer's simulation points;
    /// `resample` says whether and how it resamples.
    pub fn new(transfer: Transfer, resample: Option<ResampleConfig>) -> Self {
        Self {
            positions: transfer.rest_positions().to_vec(),
            normals: transfer.rest_normals().to_vec(),
            resampler: resample.map(|_| Resampler::new(&transfer)),
            transfer: Arc::new(transfer),
            resample,
            input: FrameInput::default(),
            fresh: false,
            revision: 1,
            inserted: 0,
            maintained_at: 0,
            pins_revision: 0,
            transfer_id: next_transfer_id(),
        }
    }

    /// Makes the dense points by pinned simulation points follow the pins exactly
    /// ([`Transfer::hold`]) with the pins of `masses` (and the dense points
    /// [`Self::hold_where`] named). Cheap when the masses did not change since the last
    /// call; call it whenever pins may have changed (the plugin does, every tick). Returns
    /// whether rows were fitted again (the next frame then runs even where the simulation
    /// points did not move).
    pub fn hold(&mut self, masses: &Masses) -> Result<bool, TransferError> {
        if masses.revision == self.pins_revision {
            return Ok(false);
        }
        let dense = self.transfer.pins().dense.clone();
        self.hold_pins(masses, dense)
    }

    /// [`Self::hold`], and the dense points whose rest position `held` picks are held to the
    /// pins as well, even where their nearest simulation point is free: a pinned region
    /// drawn at the dense resolution (a scene's pin regions; points resampling inserts later
    /// are held only by their nearest simulation point).
    pub fn hold_where(
        &mut self,
        masses: &Masses,
        held: impl Fn(Vec3) -> bool,
    ) -> Result<bool, TransferError> {
        let dense = self
            .transfer
            .rest_positions()
            .iter()
            .map(|&p| held(p))
            .collect();
        self.hold_pins(masses, dense)
    }

    fn hold_pins(&mut self, masses: &Masses, dense: Vec<bool>) -> Result<bool, TransferError> {
        let pins = Pins {
            simulation: (0..masses.len()).map(|i| masses.is_pinned(i)).collect(),
            dense,
        };
        let refit = Arc::make_mut(&mut self.transfer).hold(&pins)? > 0;
        self.pins_revision = masses.revision;
        self.fresh &= !refit;
        if refit {
            self.transfer_id = next_transfer_id();
        }
        Ok(refit)
    }

    /// Number of dense points (resampled ones included).
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// The transfer coefficients (and the rest points and normals).
    pub fn transfer(&self) -> &Transfer {
        &self.transfer
    }

    /// The deformed positions as of the last frame (the rest positions before the first).
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// The deformed unit normals as of the last frame.
    pub fn normals(&self) -> &[Vec3] {
        &self.normals
    }

    /// Where it stands (see [`DenseState`]).
    pub fn state(&self) -> DenseState {
        let original = self.transfer.len() - self.inserted;
        let (spacing, sampled) = self
            .resampler
            .as_ref()
            .map(|r| {
                let (s, t) = r.spacings();
                (s.to_vec(), t.to_vec())
            })
            .unwrap_or_default();
        DenseState {
            positions: self.positions.clone(),
            normals: self.normals.clone(),
            inserted_rest: self.transfer.rest[original..].to_vec(),
            inserted_normals: self.transfer.normals[original..].to_vec(),
            spacing,
            sampled,
            maintained_at: self.maintained_at,
            revision: self.revision,
        }
    }

    /// Puts back what [`Self::state`] gave, on the dense cloud of the same surface as
    /// prepared (before any point was inserted): the inserted points' rows are fitted again.
    /// A state of another surface (other counts) or with bad values is refused, nothing
    /// changed.
    pub fn restore(&mut self, state: &DenseState) -> Result<(), TransferError> {
        let original = self.transfer.len() - self.inserted;
        let total = original + state.inserted_rest.len();
        let counts_match = self.inserted == 0
            && state.positions.len() == total
            && state.normals.len() == total
            && state.inserted_normals.len() == state.inserted_rest.len()
            && match &self.resampler {
                Some(_) => state.spacing.len() == total && state.sampled.len() == total,
                None => state.spacing.is_empty() && state.inserted_rest.is_empty(),
            };
        if !counts_match {
            return Err(TransferError::Snapshot(format!(
                "{} points ({} inserted) for a surface of {} points",
                state.positions.len(),
                state.inserted_rest.len(),
                original
            )));
        }
        let finite = |v: &[Vec3]| v.iter().all(|p| p.is_finite());
        let unit = |v: &[Vec3]| v.iter().all(|n| (n.length() - 1.0).abs() < 1e-3);
        if !(finite(&state.positions)
            && finite(&state.inserted_rest)
            && unit(&state.normals)
            && unit(&state.inserted_normals)
            && state
                .spacing
                .iter()
                .chain(&state.sampled)
                .all(|s| s.is_finite() && *s >= 0.0))
        {
            return Err(TransferError::Snapshot(
                "a non-finite value, or a normal not of unit length".to_owned(),
            ));
        }
        if !state.inserted_rest.is_empty() {
            let index = crate::core::cloud::knn::KnnIndex::build(&self.transfer.sim_rest);
            Arc::make_mut(&mut self.transfer).extend(
                &state.inserted_rest,
                &state.inserted_normals,
                &index,
            );
            self.transfer_id = next_transfer_id();
        }
        if let Some(resampler) = self.resampler.as_mut() {
            resampler.set_spacings(&state.spacing, &state.sampled);
        }
        self.positions.clone_from(&state.positions);
        self.normals.clone_from(&state.normals);
        self.inserted = state.inserted_rest.len();
        self.maintained_at = state.maintained_at;
        self.revision = state.revision;
        self.fresh = false;
        Ok(())
    }

    /// The rest shape of its transfer (see [`DenseRest`]).
    pub fn rest(&self) -> DenseRest {
        let original = self.transfer.len() - self.inserted;
        DenseRest {
            positions: self.transfer.rest[..original].to_vec(),
            normals: self.transfer.normals[..original].to_vec(),
            simulation: self.transfer.sim_rest.clone(),
            held: self.transfer.pins().dense.clone(),
        }
    }

    /// A dense cloud of this one's settings at the rest shape `rest` (a baked one), at rest,
    /// no point inserted, no pin held yet: [`Self::restore`] a [`DenseState`] onto it, then
    /// [`Self::hold_rest`]. The same rest gives the same coefficients, bit for bit. Bad
    /// values are refused.
    pub fn with_rest(&self, rest: &DenseRest) -> Result<Self, TransferError> {
        let transfer = Transfer::with_unit_normals(
            &rest.positions,
            &rest.normals,
            &rest.simulation,
            self.transfer.config(),
        )?;
        Ok(Self::new(transfer, self.resample))
    }

    /// [`Self::hold`] with `masses`' pins and the dense points `rest` names held (after
    /// [`Self::with_rest`] and [`Self::restore`]).
    pub fn hold_rest(&mut self, masses: &Masses, rest: &DenseRest) -> Result<(), TransferError> {
        self.hold_pins(masses, rest.held.clone()).map(|_| ())
    }

    /// Makes the revision larger than both its own and `other` (a cloud put in place of one
    /// at revision `other`, whose uploads and caches must see a change).
    pub fn advance_revision_past(&mut self, other: u64) {
        self.revision = self.revision.max(other) + 1;
    }

    /// Changes each time the positions or normals do (for uploads).
    pub fn revision(&self) -> u64 {
        self.revision
    }

    /// Names the transfer's coefficients and rest points: unique to this cloud (and its
    /// clones), and new each time they change (pins held anew, points inserted by
    /// resampling or a snapshot). A copy of the coefficients elsewhere (the GPU's) is
    /// current while this stays the same.
    pub fn transfer_id(&self) -> u64 {
        self.transfer_id
    }

    /// Points resampling has inserted so far.
    pub fn inserted(&self) -> usize {
        self.inserted
    }

    /// The largest distance of a dense point from its rest position.
    pub fn max_displacement(&self) -> f32 {
        self.positions
            .iter()
            .zip(self.transfer.rest_positions())
            .map(|(p, r)| p.distance(*r))
            .fold(0.0, f32::max)
    }

    /// The deformed surface as a cloud.
    pub fn to_cloud(&self) -> Result<PointCloud, CloudError> {
        PointCloud::new(self.positions.clone(), Some(self.normals.clone()))
    }

    /// Resamples when it is due: resampling is on and `steps` (the simulation steps taken
    /// so far) is a positive multiple of its interval not looked at before. Inserted points follow the
    /// simulation from the next frame on.
    pub fn maintain(
        &mut self,
        sim: &PointState,
        steps: u64,
    ) -> Result<ResampleReport, ResampleError> {
        let (Some(config), Some(resampler)) = (self.resample, self.resampler.as_mut()) else {
            return Ok(ResampleReport::default());
        };
        if steps == self.maintained_at || !steps.is_multiple_of(u64::from(config.interval.max(1))) {
            return Ok(ResampleReport::default());
        }
        self.maintained_at = steps;
        let rest = self.transfer.simulation_rest();
        let displacements: Vec<Vec3> = sim
            .iter_positions()
            .zip(rest)
            .map(|(p, r)| p - *r)
            .collect();
        let report =
            resampler.resample(Arc::make_mut(&mut self.transfer), &displacements, &config)?;
        if report.inserted > 0 {
            self.inserted += report.inserted;
            let added = &self.transfer.rest_positions()[self.positions.len()..];
            self.positions.extend_from_slice(added);
            let added = &self.transfer.rest_normals()[self.normals.len()..];
            self.normals.extend_from_slice(added);
            self.fresh = false;
            self.transfer_id = next_transfer_id();
        }
        Ok(report)
    }

    /// Loads the simulation state `sim` for the next frame. Returns false, and the frame
    /// need not run, when the dense surface already follows exactly this state.
    pub fn begin_frame(&mut self, sim: &PointState) -> Result<bool, TransferError> {
        if self.fresh && same_positions(&self.input, sim) {
            return Ok(false);
        }
        self.input
            .set_positions(&self.transfer, sim.position_arrays())?;
        self.fresh = false;
        Ok(true)
    }

    /// The pieces of the frame [`Self::begin_frame`] loaded, to compute its rows in chunks
    /// ([`Transfer::frame_rows`]); call [`Self::finish_frame`] afterwards.
    pub fn frame_parts(&mut self) -> FrameParts<'_> {
        FrameParts {
            transfer: &self.transfer,
            input: &self.input,
            positions: &mut self.positions,
            normals: &mut self.normals,
        }
    }

    /// Completes a frame whose rows were computed through [`Self::frame_parts`]: PCA
    /// normals where the settings ask for them, and a new revision.
    pub fn finish_frame(&mut self) {
        if let NormalUpdate::Pca(k) = self.transfer.config().normals {
            self.normals = pca_normals_of(&self.positions, &self.normals, k);
        }
        self.fresh = true;
        self.revision += 1;
    }

    /// Makes the deformed surface the rest surface (baking): carries `sim` to every dense
    /// point first, then computes the transfer's coefficients anew from the dense points'
    /// current positions and normals to the simulation points' current positions.
    /// Resampling starts again from the new rest surface.
    /// The pins held to stay held.
    pub fn rebase(&mut self, sim: &PointState) -> Result<(), TransferError> {
        self.follow(sim)?;
        let mut transfer = Transfer::new(
            &self.positions,
            &self.normals,
            &sim.positions(),
            self.transfer.config(),
        )?;
        transfer.hold(self.transfer.pins())?;
        *self = Self {
            revision: self.revision + 1,
            inserted: self.inserted,
            maintained_at: self.maintained_at,
            pins_revision: self.pins_revision,
            ..Self::new(transfer, self.resample)
        };
        Ok(())
    }

    /// What a bake or an export of this surface at the simulation state `sim` needs, to be
    /// done away from the simulation's tick (on another thread): the transfer shared, not
    /// copied (the running surface copies it on write meanwhile), and `sim`. Taking it costs
    /// O(simulation points).
    pub fn job(&self, sim: &PointState) -> DenseJob {
        DenseJob {
            transfer: Arc::clone(&self.transfer),
            resample: self.resample,
            sim: sim.clone(),
            revision: self.revision,
            inserted: self.inserted,
            maintained_at: self.maintained_at,
            pins_revision: self.pins_revision,
        }
    }

    /// Writes the deformed dense surface, positions and normals, as it stands after the last
    /// [`Self::follow`], to a PLY file. The file is written beside `path` and renamed into
    /// place, so a failed export never leaves a truncated file (an old one stays as it was).
    pub fn export(&self, path: &Path, encoding: PlyEncoding) -> Result<(), ExportError> {
        write_ply(path, &self.to_cloud()?, encoding)?;
        Ok(())
    }

    /// Carries the simulation state `sim` to every dense point (the whole frame, on
    /// rayon's pool when it is large). Returns whether anything was computed: false when
    /// the dense surface already follows this state.
    pub fn follow(&mut self, sim: &PointState) -> Result<bool, TransferError> {
        if !self.begin_frame(sim)? {
            return Ok(false);
        }
        self.transfer
            .apply_frame(&self.input, &mut self.positions, &mut self.normals)?;
        self.finish_frame();
        Ok(true)
    }
}

/// Whether the frame input holds exactly the positions of `sim` (bit for bit).
fn same_positions(input: &FrameInput, sim: &PointState) -> bool {
    let [x, y, z] = sim.position_arrays();
    let current = input.current();
    current.len() == x.len()
        && current.iter().enumerate().all(|(i, c)| {
            c.x.to_bits() == x[i].to_bits()
                && c.y.to_bits() == y[i].to_bits()
                && c.z.to_bits() == z[i].to_bits()
        })
}

/// Why the dense surface could not be exported.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The deformed surface is not a valid cloud (a position beyond the coordinate limit).
    #[error(transparent)]
    Cloud(#[from] CloudError),
    /// The file could not be written.
    #[error(transparent)]
    Save(#[from] SaveError),
    /// The deformed surface could not be computed.
    #[error(transparent)]
    Transfer(#[from] TransferError),
}

/// A dense surface's share of a bake or an export, taken by [`DenseCloud::job`] and done
/// anywhere later: it reads nothing of the running surface.
#[derive(Debug, Clone)]
pub struct DenseJob {
    transfer: Arc<Transfer>,
    resample: Option<ResampleConfig>,
    sim: PointState,
    revision: u64,
    inserted: usize,
    maintained_at: u64,
    pins_revision: u64,
}

impl DenseJob {
    /// The dense surface following the job's simulation state, and that state.
    fn followed(self) -> Result<(DenseCloud, PointState), TransferError> {
        let mut cloud = DenseCloud {
            positions: self.transfer.rest_positions().to_vec(),
            // Overwritten by the frame (PCA normals orient by the frame's own).
            normals: self.transfer.rest_normals().to_vec(),
            resampler: None,
            transfer: self.transfer,
            resample: self.resample,
            input: FrameInput::default(),
            fresh: false,
            revision: self.revision,
            inserted: self.inserted,
            maintained_at: self.maintained_at,
            pins_revision: self.pins_revision,
            transfer_id: next_transfer_id(),
        };
        cloud.follow(&self.sim)?;
        Ok((cloud, self.sim))
    }

    /// Writes the deformed dense surface at the job's state (see [`DenseCloud::export`]).
    pub fn export(self, path: &Path, encoding: PlyEncoding) -> Result<(), ExportError> {
        let (cloud, _) = self.followed()?;
        cloud.export(path, encoding)
    }

    /// The dense surface with its deformed shape at the job's state made its rest shape
    /// (see [`DenseCloud::rebase`]).
    pub fn rebased(self) -> Result<DenseCloud, TransferError> {
        let (mut cloud, sim) = self.followed()?;
        cloud.rebase(&sim)?;
        Ok(cloud)
    }
}
