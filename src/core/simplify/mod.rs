//! Tangent-plane Delaunay simplification (the paper's §3): from a dense cloud to the
//! *simulation points*.
//!
//! Every point gets its region R from the [local Delaunay ring](crate::core::simplify::tangent_delaunay) of its k
//! nearest remaining neighbours; d is the diameter of R. The point with the smallest d is
//! removed, repeatedly, until a target count is reached or every d exceeds a threshold (either
//! rule, or both: the first one met stops). Removing a point changes the neighbourhood of the
//! points that had it among their k nearest, and only those are re-evaluated:
//!
//! * a min-priority queue keyed by (d, index) holds every remaining point;
//! * each point remembers its k nearest neighbours, and each point the list of points that
//!   have it among theirs (reverse lists);
//! * a removal marks the points of its reverse list *dirty* and leaves their queue entries as
//!   they are (lazy update). A dirty point reaching the top of the queue is re-evaluated
//!   and pushed back with its new d; a clean point at the top is removed.
//! * neighbours come from a [kiddo] k-d tree that still holds removed points: a query asks
//!   for the point, its k nearest and 8 spares, scaled by the share of removed points, skips
//!   the removed ones, and asks for more when too few remain. The tree is rebuilt from the
//!   remaining points whenever a quarter of the points it holds are gone. Each point keeps
//!   the spares too: while k of its k + 8 are left and the k-th is nearer than anything its
//!   query passed over, they are its k nearest and a re-evaluation needs no query. (kiddo's
//!   mutable tree cannot be built over flat data: a bucket of more than 32 points with one
//!   equal coordinate cannot be split.)
//!
//! A large cloud (more than [`SimplifyConfig::rounds_above`] points left) is simplified in
//! *rounds* first: the smallest keys are found by selection and made exact (their dirty
//! points judged again together, on every thread), then the smallest points are removed in
//! order, skipping any in the neighbour row or reverse list of one already taken, so that no
//! removal of a round changes another's ring; a round takes at most one in 64 of the points
//! left. Below the bound the queue takes over, one point at a time.
//!
//! Removing a neighbour almost always widens a ring, so a stale key is a lower bound of the
//! true d and the clean point at the top really is the smallest. Before stopping on the
//! threshold, every dirty point is re-evaluated once more, so the rule holds exactly: every
//! remaining d is at least the threshold.
//!
//! Points that coincide with a neighbour have d = 0 and go first; they are removed even when
//! the target count is reached, so simulation points never coincide. The result depends only
//! on the input: the same cloud gives the same simulation points, bit for bit, whatever the
//! thread count (ties in distance or d are broken by the points' rank along a Morton curve,
//! the order the work runs in for memory locality).
//!
//! [kiddo]: https://crates.io/crates/kiddo

mod keep;
mod removal;
pub mod tangent_delaunay;

pub use keep::{MAX_EDGE_SHARE, pinned_edge};
use removal::State;

use std::borrow::Cow;
use std::num::NonZeroUsize;
use std::ops::ControlFlow;

use glam::Vec3;

use crate::core::cloud::knn::morton_order;
use crate::core::cloud::{PointCloud, PointsProblem, check_points};
use crate::core::normals::denoise::{Denoise, decision_surface};
use crate::core::simplify::tangent_delaunay::{RingBuilder, RingShape};

/// Default neighbourhood size (the paper recommends 10–20).
pub const DEFAULT_SIMPLIFY_K: usize = 12;

/// Smallest neighbourhood that can hold a closed ring.
pub const MIN_SIMPLIFY_K: usize = 4;

/// Largest neighbourhood accepted (a ring is rarely more than 8 points).
pub const MAX_SIMPLIFY_K: usize = 64;

/// Fewest simulation points a surface can have (a tetrahedron).
pub const MIN_SIMULATION_POINTS: usize = 4;

/// The k-d tree is rebuilt when REBUILD_DEAD of every REBUILD_OF points it holds are removed
/// (queries must skip removed points; rebuilding costs about one initial pass of queries).
const REBUILD_DEAD: usize = 1;
/// See [`REBUILD_DEAD`].
const REBUILD_OF: usize = 4;

/// Neighbours kept beyond the k of each point's last evaluation. Points are only ever
/// removed, so as long as k of the k + NEIGHBOUR_SPARES it had are left and the k-th of them
/// is nearer than anything the query that found them passed over, they are still its k
/// nearest remaining: about half the re-evaluations then need no k-d query (the query was a
/// quarter of §3's time on a 10^6-point sphere).
const NEIGHBOUR_SPARES: usize = 8;

/// A spare neighbour list answers only while its k-th point is nearer than this share of
/// the farthest distance its query returned (squared distances): the tree's own distance
/// arithmetic may round differently from ours.
const SPARES_MARGIN: f32 = 1.0 - 1e-5;

/// Points per rayon task when evaluating rings in bulk.
const EVAL_CHUNK: usize = 64;

/// The default of [`SimplifyConfig::rounds_above`]: a large scan (10^6 points) is
/// simplified in rounds down to here, every smaller cloud one point at a time.
pub const DEFAULT_ROUNDS_ABOVE: usize = 200_000;

/// Rounds never run below this many points left, whatever [`SimplifyConfig::rounds_above`]
/// says (a round's budget would be under two).
const MIN_ROUND_POINTS: usize = 1_000;

/// A round of removals takes at most one in this many of the points left: the smaller the
/// share, the closer to removing one point at a time.
const ROUND_SHARE: usize = 64;

/// A round looks at this many times its budget of the smallest keys: the ones it skips as
/// neighbours of the ones it takes need room.
const ROUND_LOOKAHEAD: usize = 2;

/// A round judges the stale keys among this many times its window's smallest keys at once
/// (each stale key judged grows and lets the next one in; one at a time, that took a dozen
/// passes a round).
const STALE_WINDOW: usize = 2;

/// Progress is reported about this many times over a run.
const PROGRESS_STEPS: usize = 100;

/// Simulation points a surface gets when nothing else is said (the paper's Table 1 runs
/// 85 to 338).
pub const DEFAULT_SIMULATION_POINTS: usize = 500;

/// How far to simplify. At least one of `target` and `max_diameter` must be set; by default
/// the target is [`DEFAULT_SIMULATION_POINTS`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimplifyConfig {
    /// Neighbours per point (the paper's k, 10–20 recommended).
    pub k: usize,
    /// Stop when this many points remain.
    pub target: Option<usize>,
    /// Stop when every remaining point's d is at least this (the paper's threshold).
    pub max_diameter: Option<f32>,
    /// Whether to decide on the points projected on local fits (a noisy scan; see
    /// [`denoise`](crate::core::normals::denoise)). By default, when the cloud measures noisy.
    pub denoise: Denoise,
    /// While more points than this are left, they are removed in rounds: the smallest
    /// regions that do not touch one another together, the rings they change judged again
    /// on every thread (a 10^6-point sphere to 10^4 on two threads: 23.5 s → 17.3 s with
    /// the default). The networks differ from one-at-a-time removal as much as two nearby
    /// levels do, not in kind. `usize::MAX` removes one point at a time throughout, as the
    /// paper does. By default [`DEFAULT_ROUNDS_ABOVE`]; never below 1000 points.
    pub rounds_above: usize,
}

impl Default for SimplifyConfig {
    fn default() -> Self {
        Self::target(DEFAULT_SIMULATION_POINTS)
    }
}

impl SimplifyConfig {
    /// Simplify to `target` points with the default k.
    pub fn target(target: usize) -> Self {
        Self {
            k: DEFAULT_SIMPLIFY_K,
            target: Some(target),
            max_diameter: None,
            denoise: Denoise::Auto,
            rounds_above: DEFAULT_ROUNDS_ABOVE,
        }
    }

    /// Simplify until every region is at least `diameter` across, with the default k.
    pub fn max_diameter(diameter: f32) -> Self {
        Self {
            k: DEFAULT_SIMPLIFY_K,
            target: None,
            max_diameter: Some(diameter),
            denoise: Denoise::Auto,
            rounds_above: DEFAULT_ROUNDS_ABOVE,
        }
    }
}

/// Why a cloud could not be simplified.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimplifyError {
    /// Neither a target count nor a diameter threshold was given.
    #[error(
        "simplification needs a stopping rule: a target point count, a diameter threshold, or both"
    )]
    NoStoppingRule,
    /// k outside [`MIN_SIMPLIFY_K`]..=[`MAX_SIMPLIFY_K`].
    #[error("k must be between {MIN_SIMPLIFY_K} and {MAX_SIMPLIFY_K}, got {0}")]
    KOutOfRange(usize),
    /// A target below [`MIN_SIMULATION_POINTS`].
    #[error("the target must be at least {MIN_SIMULATION_POINTS} points, got {0}")]
    TargetTooSmall(usize),
    /// A threshold that is not a positive finite number.
    #[error("the diameter threshold must be a positive finite number, got {0}")]
    InvalidThreshold(f32),
    /// Fewer points than k + 1.
    #[error("simplification with k = {k} needs at least {needed} points, the cloud has {found}")]
    TooFewPoints {
        /// The k asked for.
        k: usize,
        /// Points needed (k + 1).
        needed: usize,
        /// Points given.
        found: usize,
    },
    /// The flags of the points to keep do not match the points.
    #[error("{keep} flags of points to keep for {positions} points")]
    KeepMismatch {
        /// Points given.
        positions: usize,
        /// Flags given.
        keep: usize,
    },
    /// The cloud has no normals (tangent planes need them).
    #[error("simplification needs normals; estimate them first (normals::ensure_normals)")]
    NoNormals,
    /// Positions and normals differ in length.
    #[error("{positions} positions but {normals} normals")]
    LengthMismatch {
        /// Number of positions.
        positions: usize,
        /// Number of normals.
        normals: usize,
    },
    /// A position or normal is not finite, or a normal is zero.
    #[error("point {0} has a non-finite position or a zero or non-finite normal")]
    InvalidPoint(usize),
    /// Every neighbourhood projects to a line or a point: the cloud is not a surface.
    #[error("no point has a surface neighbourhood (all points collinear or coincident)")]
    NotASurface,
    /// Point indices are stored in 32 bits.
    #[error("simplification supports at most 2^32 - 1 points, the cloud has {0}")]
    TooManyPoints(usize),
    /// The progress callback asked to stop.
    #[error("simplification was cancelled")]
    Cancelled,
}

/// What ended a simplification.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopReason {
    /// The target count was reached.
    TargetReached,
    /// Every remaining region is at least the threshold across.
    ThresholdReached,
    /// No remaining point can be removed (each has a degenerate neighbourhood).
    NothingRemovable,
    /// The progress callback asked to stop.
    Cancelled,
}

/// The simulation points chosen from a cloud.
#[derive(Debug, Clone, PartialEq)]
pub struct Simplification {
    /// Indices of the kept points in the input, ascending.
    pub kept: Vec<u32>,
    /// d (the diameter of R) of each kept point among the kept points, in `kept` order;
    /// infinite where the neighbourhood is degenerate.
    pub diameters: Vec<f32>,
    /// Whether each kept point's ring is open (a boundary point), in `kept` order.
    pub boundary: Vec<bool>,
    /// Points removed in all.
    pub removed: usize,
    /// Of those, points removed because they coincided with a neighbour.
    pub duplicates_removed: usize,
    /// Ring evaluations performed (initial ones included): the cost of the lazy queue.
    pub evaluations: usize,
    /// What stopped the removal.
    pub stop: StopReason,
    /// The cloud's noise level (see [`denoise::noise_level`](crate::core::normals::denoise::noise_level));
    /// 0 when not measured ([`Denoise::Off`]).
    pub noise_level: f32,
    /// When the decisions were made on the points projected on local fits: the kept points'
    /// projected positions and normals, in `kept` order (what [`Simplification::gather`]
    /// returns).
    pub projected: Option<(Vec<Vec3>, Vec<Vec3>)>,
    /// Each input point's share of the surface's area, in input order: its mixed Voronoi
    /// area within its local Delaunay ring among its k nearest points, measured in 3D, from
    /// the first pass (0 for a degenerate ring and for a duplicate; see
    /// [`dense_point_areas`](crate::core::network::dense_point_areas), which measures the
    /// same). The masses are shared out from these.
    pub point_areas: Vec<f32>,
}

impl Simplification {
    /// The smallest d among the kept points (infinite if none is finite).
    pub fn min_diameter(&self) -> f32 {
        self.diameters.iter().copied().fold(f32::INFINITY, f32::min)
    }

    /// The kept points' positions and normals gathered from the input, or their projections
    /// on local fits when the decisions were made on those.
    pub fn gather(&self, positions: &[Vec3], normals: &[Vec3]) -> (Vec<Vec3>, Vec<Vec3>) {
        if let Some((p, n)) = &self.projected {
            return (p.clone(), n.clone());
        }
        let pick = |v: &[Vec3]| self.kept.iter().map(|&i| v[i as usize]).collect();
        (pick(positions), pick(normals))
    }
}

/// Where a running simplification stands, for progress displays.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimplifyProgress {
    /// Points left.
    pub points: usize,
    /// Points removed so far.
    pub removed: usize,
    /// The target count, if one was given.
    pub target: Option<usize>,
    /// The d of the last removed point.
    pub last_diameter: f32,
}

/// Simplifies a cloud with normals. See [`simplify`].
pub fn simplify_cloud(
    cloud: &PointCloud,
    config: &SimplifyConfig,
) -> Result<Simplification, SimplifyError> {
    let normals = cloud.normals().ok_or(SimplifyError::NoNormals)?;
    simplify(cloud.positions(), normals, config)
}

/// Chooses simulation points from `positions` with unit `normals` (consistently oriented or
/// not: only the tangent planes matter).
pub fn simplify(
    positions: &[Vec3],
    normals: &[Vec3],
    config: &SimplifyConfig,
) -> Result<Simplification, SimplifyError> {
    simplify_with_progress(positions, normals, config, &mut |_| {
        ControlFlow::Continue(())
    })
}

/// [`simplify`], calling `progress` about a hundred times along the way; when it answers
/// [`ControlFlow::Break`], simplification stops with [`SimplifyError::Cancelled`].
pub fn simplify_with_progress(
    positions: &[Vec3],
    normals: &[Vec3],
    config: &SimplifyConfig,
    progress: &mut dyn FnMut(SimplifyProgress) -> ControlFlow<()>,
) -> Result<Simplification, SimplifyError> {
    simplify_keeping(positions, normals, config, &[], progress)
}

/// [`simplify_with_progress`] keeping the points that `keep` marks (one flag per point, or
/// none at all): they are never removed, and they count towards the target, so that a
/// feature the surface must show at every level (the edge of a pinned band: see
/// [`pinned_edge`]) stands on points of its own. A kept point that coincides with another
/// goes all the same, as any duplicate. Where the kept points alone exceed the target, they
/// all stay and nothing else does.
pub fn simplify_keeping(
    positions: &[Vec3],
    normals: &[Vec3],
    config: &SimplifyConfig,
    keep: &[bool],
    progress: &mut dyn FnMut(SimplifyProgress) -> ControlFlow<()>,
) -> Result<Simplification, SimplifyError> {
    validate(positions, normals, config)?;
    if !keep.is_empty() && keep.len() != positions.len() {
        return Err(SimplifyError::KeepMismatch {
            positions: positions.len(),
            keep: keep.len(),
        });
    }
    let (positions, normals, noise_level) = decision_surface(positions, normals, config.denoise);
    let projected = matches!(positions, Cow::Owned(_));
    let (positions, normals) = (&*positions, &*normals);
    // Work in Morton order: neighbours then sit close in memory (positions, neighbour rows,
    // reverse lists), which matters when removals jump around a large cloud.
    let order = morton_order(positions);
    let sorted: Vec<Vec3> = order.iter().map(|&i| positions[i as usize]).collect();
    let sorted_normals: Vec<Vec3> = order.iter().map(|&i| normals[i as usize]).collect();
    let rounds_above = config.rounds_above.max(MIN_ROUND_POINTS);
    let locked: Vec<bool> = if keep.is_empty() {
        Vec::new()
    } else {
        order.iter().map(|&i| keep[i as usize]).collect()
    };
    let mut state = State::new(&sorted, &sorted_normals, config.k, rounds_above, locked);
    state.evaluate_all();
    if state.shapes.iter().all(|s| s.degenerate) {
        return Err(SimplifyError::NotASurface);
    }
    let floor = config
        .target
        .unwrap_or(MIN_SIMULATION_POINTS)
        .max(MIN_SIMULATION_POINTS);
    let stop = state.run(floor, config, progress);
    if stop == StopReason::Cancelled {
        return Err(SimplifyError::Cancelled);
    }
    let mut result = state.finish(stop);
    // Back to input indices, ascending.
    let mut back: Vec<(u32, f32, bool)> = result
        .kept
        .iter()
        .zip(&result.diameters)
        .zip(&result.boundary)
        .map(|((&i, &d), &b)| (order[i as usize], d, b))
        .collect();
    back.sort_unstable_by_key(|&(i, _, _)| i);
    result.kept = back.iter().map(|t| t.0).collect();
    result.diameters = back.iter().map(|t| t.1).collect();
    result.boundary = back.iter().map(|t| t.2).collect();
    let mut point_areas = vec![0.0; result.point_areas.len()];
    for (&i, &a) in order.iter().zip(&result.point_areas) {
        point_areas[i as usize] = a;
    }
    result.point_areas = point_areas;
    result.noise_level = noise_level;
    if projected {
        let pick = |v: &[Vec3]| result.kept.iter().map(|&i| v[i as usize]).collect();
        result.projected = Some((pick(positions), pick(normals)));
    }
    Ok(result)
}

fn validate(
    positions: &[Vec3],
    normals: &[Vec3],
    config: &SimplifyConfig,
) -> Result<(), SimplifyError> {
    if config.target.is_none() && config.max_diameter.is_none() {
        return Err(SimplifyError::NoStoppingRule);
    }
    if !(MIN_SIMPLIFY_K..=MAX_SIMPLIFY_K).contains(&config.k) {
        return Err(SimplifyError::KOutOfRange(config.k));
    }
    if let Some(t) = config.target
        && t < MIN_SIMULATION_POINTS
    {
        return Err(SimplifyError::TargetTooSmall(t));
    }
    if let Some(d) = config.max_diameter
        && !(d > 0.0 && d.is_finite())
    {
        return Err(SimplifyError::InvalidThreshold(d));
    }
    check_points(positions, normals, config.k + 1).map_err(|problem| match problem {
        PointsProblem::LengthMismatch { positions, normals } => {
            SimplifyError::LengthMismatch { positions, normals }
        }
        PointsProblem::TooMany(n) => SimplifyError::TooManyPoints(n),
        PointsProblem::TooFew { needed, found } => SimplifyError::TooFewPoints {
            k: config.k,
            needed,
            found,
        },
        PointsProblem::Invalid(i) => SimplifyError::InvalidPoint(i),
    })
}
