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
//!    their tilt). Each triangle lies in three regions, so Σm = ρ·(area of the mesh).
//!
//! A point left with fewer than three springs (a straggler no triangle reached) is tied to
//! its nearest simulation points until it has three; a point without a triangle gets the mean
//! mass. The [report](NetworkReport) says how often either happened, whether the surface is
//! closed, its Euler characteristic, and (checked independently of the construction) its
//! fold-overs, crossing springs and non-manifold edges.

use std::borrow::Cow;
use std::f32::consts::TAU;

use glam::Vec3;
use rayon::prelude::*;

use crate::core::cloud::first_invalid_point;
use crate::core::cloud::knn::{KnnGraph, KnnIndex};
use crate::core::normals::orient_normals;
use crate::core::simplify::tangent_delaunay::{RingBuilder, RingShape};

mod check;
mod collapse;
pub mod mesh;
use crate::core::simplify::{MAX_SIMPLIFY_K, MIN_SIMPLIFY_K, MIN_SIMULATION_POINTS};

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
}

/// A spring between two simulation points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spring {
    /// First point (the smaller index).
    pub a: u32,
    /// Second point.
    pub b: u32,
    /// Natural length l⁰ (eq 2), the distance in the rest shape.
    pub rest_length: f32,
}

/// Counts and measures of a network.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
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
    /// Σ area(R)/3: the surface area the masses stand for (the mesh's area).
    pub area: f32,
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
#[derive(Debug, Clone, PartialEq, Default)]
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

/// Most dense points whose own network [`build_network_over`] builds to repair the holes
/// the simulation points' rings leave (beyond it, holes are left as they are).
pub const MAX_REPAIR_DENSE_POINTS: usize = 250_000;

/// A fine mesh over the dense points collapsed onto the simulation points (see [`collapse`]):
/// the file's faces when they make an oriented manifold, otherwise the dense points' own
/// network when it leaves no more holes than the simulation points' rings left (`holes`).
/// `None` when there is no such mesh (the dense network has more holes, or was not built: the
/// cloud is larger than [`MAX_REPAIR_DENSE_POINTS`] or noisy), or a simulation point is not
/// a dense point (or its projection on a local fit).
fn collapsed_from_dense(
    positions: &[Vec3],
    normals: &[Vec3],
    config: &NetworkConfig,
    dense: &DenseSupport,
    holes: &Holes,
) -> Option<SpringNetwork> {
    let (dense_p, dense_n) = (dense.positions, dense.normals);
    if dense_n.len() != dense_p.len() {
        return None;
    }
    // The fine mesh: the file's, or the dense points' own network.
    let (fine_p, mut fine_n, mut fine_t): (Cow<[Vec3]>, Vec<Vec3>, Vec<[u32; 3]>) =
        match collapse::manifold_normals(dense_p, dense.triangles) {
            Some(normals) => (Cow::Borrowed(dense_p), normals, dense.triangles.to_vec()),
            None => {
                // On a noisy cloud (decided on local fits) the dense points' own rings are
                // far worse than the coarse ones (the CGAL sphere scan: 109 loops at its
                // 21 002 points, projected on their fits or not): not worth a build.
                if dense_p.len() > MAX_REPAIR_DENSE_POINTS || dense.fit_k.is_some() {
                    return None;
                }
                let (fine, fine_holes) = build_once(dense_p, dense_n, config, Some(dense)).ok()?;
                if fine_holes.loops.len() > holes.loops.len() {
                    return None;
                }
                (
                    Cow::Owned(fine.positions),
                    fine_holes.normals,
                    fine.triangles,
                )
            }
        };
    // Each simulation point is the dense point nearest to it (itself, or what was projected).
    let mut keep = vec![false; fine_p.len()];
    let mut source = Vec::with_capacity(positions.len());
    for &p in positions {
        let j = dense.near(p, 1).next()? as usize;
        if std::mem::replace(&mut keep[j], true) {
            return None;
        }
        source.push(j);
    }
    // Turn the fine mesh the way most simulation points' normals face.
    let against = source
        .iter()
        .zip(normals)
        .filter(|&(&j, n)| fine_n[j].dot(*n) < 0.0)
        .count();
    if 2 * against > positions.len() {
        fine_t.iter_mut().for_each(|t| t.swap(1, 2));
        fine_n.iter_mut().for_each(|n| *n = -*n);
    }
    // The simulation points keep their own normals (turned the fine mesh's way), so that no
    // collapse folds a triangle over from them.
    let along = |n: Vec3, j: usize| {
        let n = n.normalize_or_zero();
        match n.dot(fine_n[j]) {
            d if d < 0.0 => -n,
            d if d > 0.0 => n,
            _ => fine_n[j],
        }
    };
    let mut corner_n: Vec<Vec3> = (0..fine_p.len())
        .map(|j| dense_n.get(j).map_or(fine_n[j], |&n| along(n, j)))
        .collect();
    for (&j, &n) in source.iter().zip(normals) {
        corner_n[j] = along(n, j);
    }
    let collapsed = collapse::collapse_onto(&fine_p, &corner_n, &fine_t, &keep);
    // Renumber: the simulation points as given, then the dense points left.
    let n = positions.len();
    let mut number = vec![u32::MAX; fine_p.len()];
    for (i, &j) in source.iter().enumerate() {
        number[j] = i as u32;
    }
    let mut added = Vec::with_capacity(collapsed.left.len());
    for (k, &j) in collapsed.left.iter().enumerate() {
        number[j as usize] = (n + k) as u32;
        let j = j as usize;
        added.push(if j < dense_p.len() {
            let (p, normal) = dense.fitted_point(j as u32);
            (p, along(normal, j))
        } else {
            (fine_p[j], corner_n[j])
        });
    }
    let triangles: Vec<[u32; 3]> = collapsed
        .triangles
        .iter()
        .map(|t| t.map(|v| number[v as usize]))
        .collect();
    if triangles.iter().flatten().any(|&v| v == u32::MAX) {
        return None;
    }
    let unit: Vec<Vec3> = normals.iter().map(|v| v.normalize()).collect();
    // Turn each simulation point's normal the way the dense mesh's turns at its source.
    let mut oriented: Vec<Vec3> = unit
        .iter()
        .zip(&source)
        .map(|(&v, &j)| if v.dot(fine_n[j]) < 0.0 { -v } else { v })
        .collect();
    let mut all: Vec<Vec3> = positions.to_vec();
    for &(p, normal) in &added {
        all.push(p);
        oriented.push(normal);
    }
    let mut mesh = mesh::SurfaceMesh::from_triangles(&all, &oriented, &triangles);
    mesh.added = added;
    oriented.truncate(n);
    let graph = KnnIndex::build(positions).knn_graph(positions, config.k.min(n - 1));
    let (mut net, _) = assemble(positions, unit, oriented, &graph, &[], mesh, config).ok()?;
    net.report.collapsed_from_dense = true;
    Some(net)
}

/// Rounds of refinement at most (see [`build_network_over`]).
pub const REFINE_ROUNDS: usize = 4;

/// Where refinement probes a hole point's gap for dense points: (fraction of the gap's angle,
/// distance in the hole's mean edge lengths).
const REFINE_PROBES: [(f32, f32); 3] = [(0.25, 0.5), (0.5, 0.5), (0.75, 0.5)];

/// Nearest spacing of the points refinement adds, to each other and to the simulation points,
/// in the hole's mean edge lengths: the hole's region is sampled about twice as finely.
const REFINE_MIN_GAP: f32 = 0.4;

/// The holes a build left, and the normals it oriented the mesh around.
struct Holes {
    /// Boundary loops most of whose points are closable, as point indices in the order
    /// [`mesh::SurfaceMesh::boundary_loops`] walks them.
    loops: Vec<Vec<u32>>,
    /// The points' unit normals, consistently oriented.
    normals: Vec<Vec3>,
}

impl Holes {
    /// Points on holes, counted once per loop through them.
    fn points(&self) -> usize {
        self.loops.iter().map(Vec::len).sum()
    }
}

/// The dense points that fill the gaps of the `holes` (loops of indices into `positions`), as
/// simulation points (see [`DenseSupport::fitted_point`]): at each loop point, those nearest to
/// probes in its gap (between the loop's previous and next points, counter-clockwise in its
/// tangent plane) at [`REFINE_PROBES`] of the hole's mean edge, no nearer than
/// [`REFINE_MIN_GAP`] mean edges to a point already there or already added.
fn refinement_points(positions: &[Vec3], holes: &Holes, dense: &DenseSupport) -> Vec<(Vec3, Vec3)> {
    let index = KnnIndex::build(positions);
    let mut out: Vec<(Vec3, Vec3)> = Vec::new();
    for hole in &holes.loops {
        let m = hole.len();
        let at = |i: usize| positions[hole[i % m] as usize];
        let edge = (0..m).map(|i| at(i).distance(at(i + 1))).sum::<f32>() / m as f32;
        let gap = REFINE_MIN_GAP * edge;
        for (i, &point) in hole.iter().enumerate() {
            let (prev, v, next) = (at(i + m - 1), at(i), at(i + 1));
            let (t1, t2) = holes.normals[point as usize].any_orthonormal_pair();
            let angle = |q: Vec3| {
                let d = q - v;
                d.dot(t2).atan2(d.dot(t1))
            };
            let start = angle(prev);
            let width = (angle(next) - start).rem_euclid(TAU);
            for (turn, reach) in REFINE_PROBES {
                let (sin, cos) = (start + turn * width).sin_cos();
                let probe = v + (t1 * cos + t2 * sin) * reach * edge;
                let Some(j) = dense.near(probe, 1).next() else {
                    continue;
                };
                if dense.point(j).0.distance(probe) > gap {
                    continue; // no dense surface there
                }
                let (q, normal) = dense.fitted_point(j);
                let free = index
                    .nearest(q, 1)
                    .first()
                    .is_some_and(|nb| nb.dist2.sqrt() > gap);
                if free && out.iter().all(|&(o, _)| o.distance(q) > gap) {
                    out.push((q, normal));
                }
            }
        }
    }
    out
}

/// One build of [`build_network_over`]: the network, and the holes it left.
fn build_once(
    positions: &[Vec3],
    normals: &[Vec3],
    config: &NetworkConfig,
    dense: Option<&DenseSupport>,
) -> Result<(SpringNetwork, Holes), NetworkError> {
    validate(positions, normals, config)?;
    let n = positions.len();
    let k = config.k.min(n - 1);
    let normals: Vec<Vec3> = normals.iter().map(|v| v.normalize()).collect();
    let index = KnnIndex::build(positions);
    let graph = index.knn_graph(positions, k);
    let oriented = oriented_normals(positions, &normals, &graph)?;

    // 1. Local rings, and their faces as candidate triangles.
    let local: Vec<(RingShape, Vec<(u32, bool)>)> = (0..n)
        .into_par_iter()
        .with_min_len(256)
        .map_init(
            || (RingBuilder::new(), Vec::with_capacity(k)),
            |(builder, scratch), i| {
                let row = graph.neighbours(i);
                scratch.clear();
                scratch.extend(row.iter().map(|&j| positions[j as usize]));
                let mut ring = Vec::new();
                let shape = builder.build(positions[i], oriented[i], scratch, Some(&mut ring));
                let ring = ring
                    .into_iter()
                    .map(|(slot, face)| (row[slot as usize], face))
                    .collect();
                (shape, ring)
            },
        )
        .collect();
    if let Some(i) = local.iter().position(|(s, _)| s.coincident) {
        let j = graph
            .neighbours(i)
            .iter()
            .copied()
            .find(|&j| positions[j as usize] == positions[i])
            .unwrap_or(graph.neighbours(i)[0]);
        return Err(NetworkError::CoincidentPoints(
            (i as u32).min(j),
            (i as u32).max(j),
        ));
    }
    if local.iter().all(|(s, _)| s.degenerate) {
        return Err(NetworkError::NotASurface);
    }
    let mut candidates = Vec::new();
    for (i, (_, ring)) in local.iter().enumerate() {
        let m = ring.len();
        for (r, &(a, face)) in ring.iter().enumerate() {
            if face && m > 1 {
                candidates.push([i as u32, a, ring[(r + 1) % m].0]);
            }
        }
    }
    let closable: Vec<bool> = local
        .iter()
        .map(|(s, _)| !s.degenerate && (!s.open || s.surrounded))
        .collect();

    // 2–3. One oriented mesh from the rings, holes closed.
    let mesh = mesh::build_mesh(positions, &oriented, &graph, candidates, &closable, dense);
    let diameters: Vec<f32> = local.iter().map(|(s, _)| s.diameter).collect();
    assemble(
        positions, normals, oriented, &graph, &diameters, mesh, config,
    )
}

/// The network on the `mesh` over the points (`normals` unit, `oriented` consistently, as the
/// mesh's triangles turn around them): springs, masses, rings and the report. `graph` holds
/// the given points' nearest neighbours, for stragglers; `diameters` their rings' d.
fn assemble(
    positions: &[Vec3],
    normals: Vec<Vec3>,
    oriented: Vec<Vec3>,
    graph: &KnnGraph,
    diameters: &[f32],
    mesh: mesh::SurfaceMesh,
    config: &NetworkConfig,
) -> Result<(SpringNetwork, Holes), NetworkError> {
    let n = positions.len();
    // Points that fill holes join the simulation points.
    let sampled = n;
    let (positions, oriented, normals) = if mesh.added.is_empty() {
        (Cow::Borrowed(positions), oriented, normals)
    } else {
        let mut positions = positions.to_vec();
        let (mut oriented, mut normals) = (oriented, normals);
        for &(p, normal) in &mesh.added {
            positions.push(p);
            oriented.push(normal);
            normals.push(normal);
        }
        (Cow::Owned(positions), oriented, normals)
    };
    let positions: &[Vec3] = &positions;
    let n = positions.len();
    let triangles = mesh.triangles();
    let mut edges: Vec<(u32, u32)> = triangles
        .iter()
        .flat_map(|&[a, b, c]| [key(a, b), key(b, c), key(c, a)])
        .collect();
    edges.par_sort_unstable();
    edges.dedup();
    let mesh_edges = edges.len();

    // Stragglers: tie to the nearest points until MIN_STRETCH_SPRINGS.
    let mut adjacency = Adjacency::new(n, &edges);
    let mut degree: Vec<usize> = (0..n).map(|i| adjacency.degree(i)).collect();
    let mut added: Vec<(u32, u32)> = Vec::new();
    let mut added_set: std::collections::HashSet<(u32, u32)> = std::collections::HashSet::new();
    for i in 0..sampled {
        for &j in graph.neighbours(i) {
            if degree[i] >= MIN_STRETCH_SPRINGS {
                break;
            }
            let e = key(i as u32, j);
            if !adjacency.neighbours(i).contains(&j) && added_set.insert(e) {
                added.push(e);
                degree[i] += 1;
                degree[j as usize] += 1;
            }
        }
    }
    let fallback_springs = added.len();
    if !added.is_empty() {
        edges.extend(added);
        edges.sort_unstable();
        adjacency = Adjacency::new(n, &edges);
    }

    // Rings, CCW around each point's own normal, starting after the widest gap.
    let rings: Vec<Vec<u32>> = (0..n)
        .into_par_iter()
        .with_min_len(256)
        .map(|i| final_ring(positions, normals[i], i, adjacency.neighbours(i), &mesh))
        .collect();
    let boundary: Vec<bool> = (0..n).map(|i| mesh.is_open(i)).collect();

    // 4. Masses: a third of each triangle's area to each corner.
    let mut areas = vec![0.0f64; n];
    for &[a, b, c] in &triangles {
        let p = |i: u32| positions[i as usize];
        let third = f64::from((p(b) - p(a)).cross(p(c) - p(a)).length()) / 6.0;
        for v in [a, b, c] {
            areas[v as usize] += third;
        }
    }
    let positive: Vec<f64> = areas.iter().copied().filter(|a| *a > 0.0).collect();
    if positive.is_empty() {
        return Err(NetworkError::NotASurface);
    }
    let mean_area = positive.iter().sum::<f64>() / positive.len() as f64;
    let fallback_masses = areas.len() - positive.len();
    let masses: Vec<f32> = areas
        .iter()
        .map(|&a| config.density * (if a > 0.0 { a } else { mean_area }) as f32)
        .collect();

    // Springs: stretch along every edge; bend between the far corners of the two triangles
    // at each inner edge (ring vertices r and r + 2 around either end).
    let length = |a: u32, b: u32| positions[a as usize].distance(positions[b as usize]);
    let spring = |(a, b): (u32, u32)| Spring {
        a,
        b,
        rest_length: length(a, b),
    };
    let stretch: Vec<Spring> = edges.iter().copied().map(spring).collect();
    let mut bend_pairs: Vec<(u32, u32)> = mesh
        .wings()
        .filter(|&(a, b)| a != b && edges.binary_search(&key(a, b)).is_err())
        .map(|(a, b)| key(a, b))
        .collect();
    bend_pairs.sort_unstable();
    bend_pairs.dedup();
    let bend: Vec<Spring> = bend_pairs.into_iter().map(spring).collect();

    // Report.
    let finite_d = || diameters.iter().copied().filter(|d| d.is_finite());
    let check = check::check(positions, &oriented, &triangles, &adjacency);
    let boundary_points = boundary.iter().filter(|b| **b).count();
    let isolated_points = mesh.wedges.iter().filter(|w| w.is_empty()).count();
    let boundary_loops = mesh.boundary_loops().len();
    let euler_characteristic = n as i64 - mesh_edges as i64 + triangles.len() as i64;
    let report = NetworkReport {
        points: n,
        stretch_springs: stretch.len(),
        bend_springs: bend.len(),
        triangles: triangles.len(),
        boundary_points,
        boundary_loops,
        closed: boundary_points == 0 && check.non_manifold_edges == 0,
        euler_characteristic,
        components: count_components(n, edges.iter().copied()),
        non_manifold_edges: check.non_manifold_edges,
        non_manifold_points: mesh.pinched_points(),
        fold_overs: check.fold_overs,
        crossings: check.crossings,
        total_mass: masses.iter().map(|m| f64::from(*m)).sum::<f64>() as f32,
        area: areas.iter().sum::<f64>() as f32,
        min_diameter: finite_d().fold(f32::INFINITY, f32::min),
        max_diameter: finite_d().fold(0.0, f32::max),
        candidates: mesh.stats.candidates,
        disputed_candidates: mesh.stats.disputed,
        closing_triangles: mesh.stats.ears,
        inserted_points: mesh.stats.inserted,
        filling_points: mesh.added.len(),
        isolated_points,
        collapsed_from_dense: false,
        fallback_springs,
        fallback_masses,
    };
    let mut ring_offsets = Vec::with_capacity(n + 1);
    ring_offsets.push(0u32);
    let mut ring_indices = Vec::new();
    for ring in &rings {
        ring_indices.extend_from_slice(ring);
        ring_offsets.push(ring_indices.len() as u32);
    }
    let network = SpringNetwork {
        positions: positions.to_vec(),
        normals,
        masses,
        stretch,
        bend,
        triangles,
        boundary,
        ring_offsets,
        ring_indices,
        report,
    };
    let holes = Holes {
        loops: mesh.holes,
        normals: oriented,
    };
    Ok((network, holes))
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
    if positions.len() != normals.len() {
        return Err(NetworkError::LengthMismatch {
            positions: positions.len(),
            normals: normals.len(),
        });
    }
    if positions.len() >= u32::MAX as usize {
        return Err(NetworkError::TooManyPoints(positions.len()));
    }
    let needed = MIN_SIMULATION_POINTS;
    if positions.len() < needed {
        return Err(NetworkError::TooFewPoints {
            needed,
            found: positions.len(),
        });
    }
    if let Some(i) = first_invalid_point(positions, normals) {
        return Err(NetworkError::InvalidPoint(i));
    }
    Ok(())
}

/// An undirected edge as (smaller, larger).
fn key(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

/// Neighbour lists of an undirected edge set.
struct Adjacency {
    offsets: Vec<u32>,
    targets: Vec<u32>,
}

impl Adjacency {
    fn new(n: usize, edges: &[(u32, u32)]) -> Self {
        let mut offsets = vec![0u32; n + 1];
        for &(a, b) in edges {
            offsets[a as usize + 1] += 1;
            offsets[b as usize + 1] += 1;
        }
        for i in 0..n {
            offsets[i + 1] += offsets[i];
        }
        let mut fill = offsets.clone();
        let mut targets = vec![0u32; offsets[n] as usize];
        for &(a, b) in edges {
            targets[fill[a as usize] as usize] = b;
            fill[a as usize] += 1;
            targets[fill[b as usize] as usize] = a;
            fill[b as usize] += 1;
        }
        Self { offsets, targets }
    }

    fn neighbours(&self, i: usize) -> &[u32] {
        &self.targets[self.offsets[i] as usize..self.offsets[i + 1] as usize]
    }

    fn degree(&self, i: usize) -> usize {
        self.neighbours(i).len()
    }
}

/// The ring of point `i`: its `neighbours` sorted counter-clockwise around `normal`, starting
/// after the widest sector that is not one of the mesh's triangles when there is one.
fn final_ring(
    positions: &[Vec3],
    normal: Vec3,
    i: usize,
    neighbours: &[u32],
    mesh: &mesh::SurfaceMesh,
) -> Vec<u32> {
    let centre = positions[i];
    let (t1, t2) = normal.any_orthonormal_pair();
    let angle = |j: u32| {
        let v = positions[j as usize] - centre;
        v.dot(t2).atan2(v.dot(t1))
    };
    let mut by_angle: Vec<(f32, u32)> = neighbours.iter().map(|&j| (angle(j), j)).collect();
    by_angle.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let m = by_angle.len();
    let gap = |r: usize| {
        let (a, b) = (by_angle[r].1, by_angle[(r + 1) % m].1);
        if mesh.has_wedge(i, a, b) || mesh.has_wedge(i, b, a) {
            None
        } else {
            Some((by_angle[(r + 1) % m].0 - by_angle[r].0).rem_euclid(TAU))
        }
    };
    let start = (0..m)
        .filter_map(|r| gap(r).map(|g| (g, r)))
        .max_by(|a, b| a.0.total_cmp(&b.0).then(b.1.cmp(&a.1)))
        .map_or(0, |(_, r)| (r + 1) % m);
    (0..m).map(|r| by_angle[(start + r) % m].1).collect()
}

/// Connected components of `n` points joined by `edges` (union-find).
fn count_components(n: usize, edges: impl Iterator<Item = (u32, u32)>) -> usize {
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn find(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            let up = parent[parent[x as usize] as usize];
            parent[x as usize] = up;
            x = up;
        }
        x
    }
    let mut components = n;
    for (a, b) in edges {
        let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
        if ra != rb {
            parent[ra.max(rb) as usize] = ra.min(rb);
            components -= 1;
        }
    }
    components
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::{DenseSupport, Holes, REFINE_MIN_GAP, refinement_points};

    #[test]
    fn refinement_samples_a_hole_from_the_dense_points_in_its_gaps() {
        // A dense square 4 × 4 at spacing 0.05; simulation points every 1 around a missing
        // centre: the hole's loop runs around the middle 2 × 2 block.
        let dense: Vec<Vec3> = (0..=80)
            .flat_map(|y| (0..=80).map(move |x| Vec3::new(x as f32, y as f32, 0.0) * 0.05))
            .collect();
        let dense_normals = vec![Vec3::Z; dense.len()];
        let support = DenseSupport::new(&dense, &dense_normals, 0.0, false);
        let positions: Vec<Vec3> = (0..25)
            .map(|i| Vec3::new((i % 5) as f32, (i / 5) as f32, 0.0))
            .filter(|p| *p != Vec3::new(2.0, 2.0, 0.0))
            .collect();
        let normals = vec![Vec3::Z; positions.len()];
        let index = |x: f32, y: f32| {
            positions
                .iter()
                .position(|p| *p == Vec3::new(x, y, 0.0))
                .unwrap() as u32
        };
        // Clockwise around +z (as boundary loops of holes run).
        let hole: Vec<u32> = [
            (1.0, 1.0),
            (1.0, 2.0),
            (1.0, 3.0),
            (2.0, 3.0),
            (3.0, 3.0),
            (3.0, 2.0),
            (3.0, 1.0),
            (2.0, 1.0),
        ]
        .into_iter()
        .map(|(x, y)| index(x, y))
        .collect();
        let holes = Holes {
            loops: vec![hole.clone()],
            normals,
        };
        let added = refinement_points(&positions, &holes, &support);
        assert!(added.len() >= 4, "{added:?}");
        let edge = 1.0;
        for (i, &(p, n)) in added.iter().enumerate() {
            assert_eq!(n, Vec3::Z);
            assert!(
                (0.99..=3.01).contains(&p.x) && (0.99..=3.01).contains(&p.y),
                "{p}"
            );
            for q in positions.iter().chain(added[..i].iter().map(|(q, _)| q)) {
                assert!(
                    p.distance(*q) > REFINE_MIN_GAP * edge - 1e-5,
                    "{p} near {q}"
                );
            }
        }
        // Every point of the hole gets new points in its gap, half an edge in.
        for &v in &hole {
            let p = positions[v as usize];
            assert!(added.iter().any(|(q, _)| q.distance(p) < 0.9 * edge), "{p}");
        }
    }
}
