//! The spring network on the simulation points (the paper's §4.1–4.2).
//!
//! 1. Each simulation point's [local Delaunay ring](crate::core::simplify::tangent_delaunay) among its k nearest
//!    simulation points, counter-clockwise around its normal (the paper's construction).
//! 2. **One surface.** Local triangulations need not agree, and where they disagree the union
//!    of their edges has holes. The rings' faces are voted into one oriented triangle mesh,
//!    and the gaps left at points whose own ring is closed are closed with ears (see
//!    [`mesh`]): on a closed surface the result is closed (E = 3V − 6 on a sphere), and an open
//!    surface keeps exactly its true boundary. No two springs at a point cross and no triangle
//!    folds over (every triangle's normal is within 90° of its corners' normals). Where the
//!    rings still leave holes, a fine mesh over the dense points (a mesh file's faces, or the
//!    dense points' own network) is collapsed onto the simulation points instead (see
//!    [`build_network_over`]), which keeps that mesh's topology.
//! 3. **Springs.** Stretch springs along every edge of the mesh; bend springs between the far
//!    corners of the two triangles at each inner edge (around a point, ring vertices r and
//!    r + 2), minus pairs that already share a stretch spring. Rest lengths come from the rest
//!    shape.
//! 4. **Masses (eq 1).** m = ρ·area(R)/3, with R the point's triangles at the points' true 3D
//!    positions (the tangent-plane projection would shrink curved regions by the cosine of
//!    their tilt). Each triangle lies in three regions, so Σm = ρ·(area of the mesh). The
//!    pipeline then shares the *dense* surface's area out instead
//!    ([`SpringNetwork::share_dense_area`]), so that Σm does not shrink with the level.
//!
//! A point left with fewer than three springs (a straggler no triangle reached) is tied to
//! its nearest simulation points until it has three; a point without a triangle gets the mean
//! mass. The [report](NetworkReport) says how often either happened, whether the surface is
//! closed, its Euler characteristic, and (checked independently of the construction) its
//! fold-overs, crossing springs and non-manifold edges.

use std::f32::consts::TAU;

use glam::Vec3;

use crate::core::cloud::knn::{KnnGraph, KnnIndex};
use crate::core::cloud::{PointsProblem, check_points};
use crate::core::normals::orient_normals;
use crate::core::simplify::tangent_delaunay::{RingBuilder, RingShape};

mod build;
mod check;
mod collapse;
mod intersect;
mod mass;
pub mod mesh;
mod repair;
mod reshape;
pub use intersect::{crossings, segment_crosses_triangle, surface_intersections};
pub use reshape::RestShape;

use crate::core::simplify::{MAX_SIMPLIFY_K, MIN_SIMPLIFY_K, MIN_SIMULATION_POINTS};
use build::{Adjacency, assemble, build_once};
pub use mass::{MassShare, SHARE_CANDIDATES, dense_areas_after, dense_point_areas};
use repair::{Holes, collapsed_from_dense, refinement_points};
pub use repair::{MAX_REPAIR_DENSE_POINTS, REFINE_ROUNDS};

/// Default surface density ρ (mass per unit area).
pub const DEFAULT_DENSITY: f32 = 1.0;

/// Fewest stretch springs a point gets.
pub const MIN_STRETCH_SPRINGS: usize = 3;

/// How to build a network.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NetworkConfig {
    /// Neighbours per point for the rings (the paper's k).
    pub k: usize,
    /// Surface density ρ: mass per unit area.
    pub density: f32,
}

impl Default for NetworkConfig {
    fn default() -> Self {
        Self {
            k: crate::core::simplify::DEFAULT_SIMPLIFY_K,
            density: DEFAULT_DENSITY,
        }
    }
}

/// Why a network could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NetworkError {
    /// k outside the accepted range.
    #[error("k must be between {MIN_SIMPLIFY_K} and {MAX_SIMPLIFY_K}, got {0}")]
    KOutOfRange(usize),
    /// Density not a positive finite number.
    #[error("the density must be a positive finite number, got {0}")]
    InvalidDensity(f32),
    /// Too few simulation points.
    #[error("a spring network needs at least {needed} points, got {found}")]
    TooFewPoints {
        /// Points needed.
        needed: usize,
        /// Points given.
        found: usize,
    },
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
    /// Two simulation points coincide (a spring between them would have no length).
    #[error(
        "simulation points {0} and {1} coincide; simplify the cloud first (it removes duplicates)"
    )]
    CoincidentPoints(u32, u32),
    /// No point has a surface neighbourhood.
    #[error("no point has a surface neighbourhood (all points collinear or coincident)")]
    NotASurface,
    /// Point indices are stored in 32 bits.
    #[error("a network supports at most 2^32 - 1 points, got {0}")]
    TooManyPoints(usize),
    /// Dense points and their areas differ in number.
    #[error("{points} dense points but {areas} areas")]
    AreaCount {
        /// Number of dense points.
        points: usize,
        /// Number of areas.
        areas: usize,
    },
    /// A dense point's area is negative or not finite.
    #[error("dense point {0} has a negative or non-finite area")]
    InvalidArea(usize),
    /// A face names a point that does not exist, or the same point twice.
    #[error("face {0} names a point out of range or one point twice")]
    InvalidFace(usize),
}

/// A spring between two simulation points.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Spring {
    /// First point (the smaller index).
    pub a: u32,
    /// Second point.
    pub b: u32,
    /// Natural length l⁰ (eq 2), the distance in the rest shape.
    pub rest_length: f32,
}

/// Counts and measures of a network.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct NetworkReport {
    /// Simulation points.
    pub points: usize,
    /// Stretch springs.
    pub stretch_springs: usize,
    /// Bend springs.
    pub bend_springs: usize,
    /// Triangles of the mesh the springs lie on.
    pub triangles: usize,
    /// Points with a gap between their triangles (or no triangle): boundary points.
    pub boundary_points: usize,
    /// Closed chains of boundary edges (holes and outer rims).
    pub boundary_loops: usize,
    /// No boundary point and no non-manifold edge: the network is a watertight surface.
    pub closed: bool,
    /// V − E + F of the mesh (2 for a closed surface of genus 0, 1 for a disc).
    pub euler_characteristic: i64,
    /// Connected components of the stretch springs.
    pub components: usize,
    /// Edges with more than two triangles, or two triangles on the same side (always 0; a
    /// check of the construction).
    pub non_manifold_edges: usize,
    /// Points where the surface pinches: two or more gaps between their triangles.
    pub non_manifold_points: usize,
    /// Triangles whose normal is 90° or more from a corner's normal (always 0; a check).
    pub fold_overs: usize,
    /// Pairs of springs that cross in the tangent plane of a point next to all four ends
    /// (always 0; a check).
    pub crossings: usize,
    /// Σm.
    pub total_mass: f32,
    /// Σ area(R)/3: the area of the network's mesh (the area eq 1's masses stand for).
    pub area: f32,
    /// The dense surface's area, when the masses are shares of it
    /// ([`SpringNetwork::share_dense_area`], as [`prepare_surface`](crate::core::pipeline::prepare_surface)
    /// builds them); 0 when they are eq 1's.
    pub dense_area: f32,
    /// Smallest region diameter d.
    pub min_diameter: f32,
    /// Largest region diameter d.
    pub max_diameter: f32,
    /// Distinct triangles the local rings proposed.
    pub candidates: usize,
    /// Of those, triangles not proposed by all three of their corners (rings disagreeing).
    pub disputed_candidates: usize,
    /// Triangles added to close holes the rings left.
    pub closing_triangles: usize,
    /// Points without a triangle inserted by splitting a triangle.
    pub inserted_points: usize,
    /// Dense points added as simulation points to fill holes: centres of fans over holes no
    /// ear closed, and points sampling holes more finely where they were left (see
    /// [`build_network_over`]); numbered after the simulation points given.
    pub filling_points: usize,
    /// Points left without any triangle.
    pub isolated_points: usize,
    /// Whether the network is a fine mesh over the dense points (a mesh file's faces, or the
    /// dense points' own network) collapsed onto the simulation points, because their rings
    /// left more holes (see [`build_network_over`]).
    pub collapsed_from_dense: bool,
    /// Springs added to give stragglers [`MIN_STRETCH_SPRINGS`].
    pub fallback_springs: usize,
    /// Points without a triangle that got the mean mass.
    pub fallback_masses: usize,
}

/// Simulation points with their springs and masses: the rest state of a deformable surface.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct SpringNetwork {
    /// Rest positions: the points the network was built on, then any dense points added to
    /// fill holes ([`NetworkReport::filling_points`]).
    pub positions: Vec<Vec3>,
    /// Rest normals (unit).
    pub normals: Vec<Vec3>,
    /// Masses (eq 1), all positive.
    pub masses: Vec<f32>,
    /// Stretch springs: each point to its ring.
    pub stretch: Vec<Spring>,
    /// Bend springs: ring vertex r to ring vertex r + 2.
    pub bend: Vec<Spring>,
    /// The triangles the springs lie on, counter-clockwise around the normals (outward on a
    /// closed surface with outward normals).
    pub triangles: Vec<[u32; 3]>,
    /// Whether each point's ring is open.
    pub boundary: Vec<bool>,
    /// Ring of point i: `ring_indices[ring_offsets[i]..ring_offsets[i + 1]]`, CCW around its
    /// normal, starting after the gap for boundary points.
    pub ring_offsets: Vec<u32>,
    /// See `ring_offsets`.
    pub ring_indices: Vec<u32>,
    /// Counts and measures.
    pub report: NetworkReport,
}

impl SpringNetwork {
    /// Checks what every use of a network relies on: one position, normal, mass and
    /// boundary flag per point, all finite (masses positive), springs and triangles between
    /// distinct points that exist, and rings that index the points in order. A network read
    /// from a file is checked so before it is used; one the pipeline built passes.
    pub fn check(&self) -> Result<(), String> {
        let n = self.positions.len();
        if n == 0 {
            return Err("a network without points".into());
        }
        if self.normals.len() != n || self.masses.len() != n || self.boundary.len() != n {
            return Err(format!(
                "{n} points but {} normals, {} masses, {} boundary flags",
                self.normals.len(),
                self.masses.len(),
                self.boundary.len()
            ));
        }
        if !self
            .positions
            .iter()
            .chain(&self.normals)
            .all(|p| p.is_finite())
        {
            return Err("a position or normal is not finite".into());
        }
        if !self.masses.iter().all(|m| m.is_finite() && *m > 0.0) {
            return Err("a mass is not finite and positive".into());
        }
        let point = |i: u32| (i as usize) < n;
        for s in self.stretch.iter().chain(&self.bend) {
            let ends = point(s.a) && point(s.b) && s.a != s.b;
            if !(ends && s.rest_length.is_finite() && s.rest_length >= 0.0) {
                return Err(format!("a spring {}–{} ({})", s.a, s.b, s.rest_length));
            }
        }
        for &[a, b, c] in &self.triangles {
            if !(point(a) && point(b) && point(c)) || a == b || b == c || a == c {
                return Err(format!("a triangle {a}, {b}, {c}"));
            }
        }
        let offsets = &self.ring_offsets;
        if offsets.len() != n + 1
            || offsets.first() != Some(&0)
            || offsets.windows(2).any(|w| w[0] > w[1])
            || offsets.last().map(|&l| l as usize) != Some(self.ring_indices.len())
        {
            return Err("ring offsets out of order".into());
        }
        if !self.ring_indices.iter().all(|&i| point(i)) {
            return Err("a ring names a point that does not exist".into());
        }
        Ok(())
    }

    /// Rest length of spring `i`, counting the stretch springs first and then the bend
    /// springs (the order of the solver's [`Springs`](crate::core::solver::Springs)).
    ///
    /// # Panics
    /// When `i` is not below the number of springs.
    pub fn rest_length(&self, i: usize) -> f32 {
        match i.checked_sub(self.stretch.len()) {
            None => self.stretch[i].rest_length,
            Some(b) => self.bend[b].rest_length,
        }
    }

    /// Each point's area: its mass over the density the masses were built with (eq 1's
    /// area(R)/3, or its share of the dense surface's area).
    pub fn point_areas(&self) -> Vec<f32> {
        let area = if self.report.dense_area > 0.0 {
            self.report.dense_area
        } else {
            self.report.area
        };
        let per_mass = f64::from(area) / f64::from(self.report.total_mass);
        let per_mass = if per_mass.is_finite() { per_mass } else { 0.0 };
        self.masses
            .iter()
            .map(|&m| (f64::from(m) * per_mass) as f32)
            .collect()
    }

    /// The hinges of the mesh: every edge shared by exactly two triangles that run it in
    /// opposite directions, as `[p₀, p₁, w₁, w₂]` with the triangles (p₀, p₁, w₁) and
    /// (p₁, p₀, w₂) (see [`Hinges`](crate::core::solver::Hinges)), in the order of the
    /// triangles. An edge of three or more triangles, or of two running it the same way,
    /// carries none.
    pub fn hinge_stencils(&self) -> Vec<[u32; 4]> {
        use std::collections::HashMap;
        // Directed edge → the far corner of its triangle, or None when it occurs twice.
        let mut far: HashMap<(u32, u32), Option<u32>> = HashMap::new();
        let directed = |t: &[u32; 3]| [(t[0], t[1], t[2]), (t[1], t[2], t[0]), (t[2], t[0], t[1])];
        for t in &self.triangles {
            for (a, b, c) in directed(t) {
                far.entry((a, b))
                    .and_modify(|w| *w = None)
                    .or_insert(Some(c));
            }
        }
        let mut out = Vec::new();
        for t in &self.triangles {
            for (a, b, c) in directed(t) {
                if a > b {
                    continue;
                }
                if let (Some(Some(w1)), Some(Some(w2))) = (far.get(&(a, b)), far.get(&(b, a)))
                    && *w1 == c
                    && w1 != w2
                {
                    out.push([a, b, *w1, *w2]);
                }
            }
        }
        out
    }

    /// The consistent ring of point `i`.
    pub fn ring(&self, i: usize) -> &[u32] {
        &self.ring_indices[self.ring_offsets[i] as usize..self.ring_offsets[i + 1] as usize]
    }

    /// Number of simulation points.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether the network is empty.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }
}

/// The dense cloud the simulation points were chosen from, which tells a hole in the surface
/// from a gap the coarse rings left, and gives the points that fill the gaps ears cannot.
///
/// A triangle closing a gap must lie over dense points: a dense point must lie within
/// [`SUPPORT_SPACINGS`] local dense spacings of its centroid along the triangle's plane (plus
/// three noise deviations on a noisy cloud), and within half the triangle's longest edge across
/// it (a coarse triangle's centroid sits below a curved surface by its sagitta; a hole, like the
/// letter B's counters, is empty along the plane).
#[derive(Debug)]
pub struct DenseSupport<'a> {
    positions: &'a [Vec3],
    normals: &'a [Vec3],
    index: KnnIndex,
    reach: f32,
    /// Neighbours of the local plane a dense point is projected on before it becomes a
    /// simulation point, when the simulation points were (see [`Denoise`](crate::core::normals::denoise::Denoise)).
    fit_k: Option<usize>,
    /// The triangles of a mesh over the dense points, when the file had one.
    triangles: &'a [[u32; 3]],
}

/// How far along a closing triangle's plane (in local dense spacings: the mean distance to
/// the nearest [`SUPPORT_NEIGHBOURS`]) its centroid may be from a dense point.
pub const SUPPORT_SPACINGS: f32 = 2.0;

/// Neighbours averaged for the local dense spacing, and dense points looked at around a
/// centroid.
pub const SUPPORT_NEIGHBOURS: usize = 8;

impl<'a> DenseSupport<'a> {
    /// Indexes the dense `positions` (with unit `normals`, as many), whose noise level (in
    /// spacings, from [`noise_level`](crate::core::normals::denoise::noise_level)) is `noise`; `fitted`
    /// when the simulation points were projected on local fits
    /// ([`Simplification::projected`](crate::core::simplify::Simplification::projected)), so
    /// that points taken from the dense cloud are projected alike.
    pub fn new(positions: &'a [Vec3], normals: &'a [Vec3], noise: f32, fitted: bool) -> Self {
        Self {
            positions,
            normals,
            index: KnnIndex::build(positions),
            reach: SUPPORT_SPACINGS + 3.0 * noise.max(0.0),
            fit_k: fitted.then(|| crate::core::normals::denoise::fit_k(noise)),
            triangles: &[],
        }
    }

    /// The dense surface with the triangles of a mesh over its points (a mesh file's faces,
    /// [`PointCloud::faces`](crate::core::cloud::PointCloud::faces)), each naming three
    /// distinct points. Where the simulation points' rings leave holes, the network is then
    /// this mesh collapsed onto them when that leaves fewer (see [`build_network_over`]);
    /// triangles that do not make a manifold surface are not used.
    pub fn with_triangles(mut self, triangles: &'a [[u32; 3]]) -> Self {
        self.triangles = triangles;
        self
    }

    /// Whether the dense surface lies under the triangle (a, b, c).
    pub fn covers(&self, [a, b, c]: [Vec3; 3]) -> bool {
        let centre = (a + b + c) / 3.0;
        let normal = (b - a).cross(c - a).normalize_or_zero();
        let longest = a.distance(b).max(b.distance(c)).max(c.distance(a));
        let near = self.index.nearest(centre, SUPPORT_NEIGHBOURS);
        let Some(first) = near.first() else {
            return true;
        };
        let anchor = self.positions[first.index as usize];
        let around = self.index.nearest(anchor, SUPPORT_NEIGHBOURS + 1);
        let spacing = around.iter().skip(1).map(|nb| nb.dist2.sqrt()).sum::<f32>()
            / around.len().saturating_sub(1).max(1) as f32;
        near.iter().any(|nb| {
            let d = self.positions[nb.index as usize] - centre;
            let across = d.dot(normal);
            (d - across * normal).length() <= self.reach * spacing && across.abs() <= 0.5 * longest
        })
    }

    /// Indices of the `k` dense points nearest to `probe`.
    pub(crate) fn near(&self, probe: Vec3, k: usize) -> impl Iterator<Item = u32> + '_ {
        self.index.nearest(probe, k).into_iter().map(|nb| nb.index)
    }

    /// Position and unit normal of dense point `i` as given.
    pub(crate) fn point(&self, i: u32) -> (Vec3, Vec3) {
        let normal = self.normals.get(i as usize).copied().unwrap_or(Vec3::ZERO);
        (self.positions[i as usize], normal.normalize_or_zero())
    }

    /// Dense point `i` as a simulation point: projected on its local fit where the simulation
    /// points were.
    pub(crate) fn fitted_point(&self, i: u32) -> (Vec3, Vec3) {
        let (p, n) = self.point(i);
        match self.fit_k {
            Some(k) => crate::core::normals::denoise::project_on_fit(
                p,
                n,
                self.positions,
                &self.index,
                k,
                &mut Vec::new(),
            ),
            None => (p, n),
        }
    }
}

/// Builds the spring network on simulation points with consistently oriented unit normals
/// (as [`ensure_normals`](crate::core::normals::ensure_normals) gives; normals whose signs
/// disagree between neighbours are oriented first). See [`build_network_over`] to let the
/// dense cloud tell holes from gaps.
pub fn build_network(
    positions: &[Vec3],
    normals: &[Vec3],
    config: &NetworkConfig,
) -> Result<SpringNetwork, NetworkError> {
    build_network_over(positions, normals, config, None)
}

/// [`build_network`], closing gaps only where the `dense` surface the points came from lies and
/// filling holes no ear closes with fans from dense points. Where holes are left (a thin part
/// or a sharp turn sampled too coarsely for its points' rings to agree), the dense points in
/// their gaps are added about twice as finely as the holes' edges and the network is built
/// again, up to [`REFINE_ROUNDS`] times, each kept only when it leaves fewer points on holes.
/// Where holes (or points without a triangle) are still left, a fine mesh over the dense
/// points (the file's faces given by [`DenseSupport::with_triangles`], or else the dense
/// points' own network) is collapsed onto the simulation points, which keeps its topology:
/// that network is taken when it has fewer boundary loops, or as many and fewer boundary
/// points ([`NetworkReport::collapsed_from_dense`]). Added points join the network's points
/// after the given ones.
pub fn build_network_over(
    positions: &[Vec3],
    normals: &[Vec3],
    config: &NetworkConfig,
    dense: Option<&DenseSupport>,
) -> Result<SpringNetwork, NetworkError> {
    let (mut net, mut holes) = build_once(positions, normals, config, dense)?;
    let Some(dense) = dense else {
        return Ok(net);
    };
    for _ in 0..REFINE_ROUNDS {
        let open = holes.points();
        if open == 0 {
            break;
        }
        let extra = refinement_points(&net.positions, &holes, dense);
        if extra.is_empty() {
            break;
        }
        let (mut p, mut n) = (net.positions.clone(), net.normals.clone());
        for (q, normal) in extra {
            p.push(q);
            n.push(normal);
        }
        // A refinement that fails, or leaves as much open, is not kept.
        let Ok((next, next_holes)) = build_once(&p, &n, config, Some(dense)) else {
            break;
        };
        if next_holes.points() >= open {
            break;
        }
        (net, holes) = (next, next_holes);
    }
    if (!holes.loops.is_empty() || net.report.isolated_points > 0)
        && let Some(repaired) = collapsed_from_dense(positions, normals, config, dense, &holes)
    {
        let ring = &net.report;
        let better = (
            repaired.report.boundary_loops,
            repaired.report.boundary_points,
        ) < (ring.boundary_loops, ring.boundary_points);
        if better {
            let (min_diameter, max_diameter) = (ring.min_diameter, ring.max_diameter);
            net = repaired;
            net.report.min_diameter = min_diameter;
            net.report.max_diameter = max_diameter;
        }
    }
    net.report.filling_points = net.len() - positions.len();
    Ok(net)
}

/// Knn pairs whose normals may point apart before orientation is redone: a consistently
/// oriented surface has almost none (the two faces of a thin part are not nearest neighbours
/// of each other at the levels simplification keeps).
const MAX_DISAGREEING_NORMALS: f64 = 0.05;

/// The normals the mesh is built around: `normals` when neighbours agree on their signs,
/// otherwise oriented over the k-NN graph ([`orient_normals`]).
fn oriented_normals(
    positions: &[Vec3],
    normals: &[Vec3],
    graph: &KnnGraph,
) -> Result<Vec<Vec3>, NetworkError> {
    let n = positions.len();
    let near = graph.k().min(3);
    let disagree = (0..n)
        .flat_map(|i| graph.neighbours(i)[..near].iter().map(move |&j| (i, j)))
        .filter(|&(i, j)| normals[i].dot(normals[j as usize]) < 0.0)
        .count();
    let mut oriented = normals.to_vec();
    if disagree as f64 > MAX_DISAGREEING_NORMALS * (n * near) as f64 {
        orient_normals(positions, &mut oriented, graph)
            .map_err(|_| NetworkError::TooManyPoints(n))?;
    }
    Ok(oriented)
}

fn validate(
    positions: &[Vec3],
    normals: &[Vec3],
    config: &NetworkConfig,
) -> Result<(), NetworkError> {
    if !(MIN_SIMPLIFY_K..=MAX_SIMPLIFY_K).contains(&config.k) {
        return Err(NetworkError::KOutOfRange(config.k));
    }
    if !(config.density > 0.0 && config.density.is_finite()) {
        return Err(NetworkError::InvalidDensity(config.density));
    }
    check_points(positions, normals, MIN_SIMULATION_POINTS).map_err(NetworkError::from)
}

impl From<PointsProblem> for NetworkError {
    fn from(problem: PointsProblem) -> Self {
        match problem {
            PointsProblem::LengthMismatch { positions, normals } => {
                Self::LengthMismatch { positions, normals }
            }
            PointsProblem::TooMany(n) => Self::TooManyPoints(n),
            PointsProblem::TooFew { needed, found } => Self::TooFewPoints { needed, found },
            PointsProblem::Invalid(i) => Self::InvalidPoint(i),
        }
    }
}
