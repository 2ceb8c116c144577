//! The spring network on the simulation points (the paper's §4.1–4.2).
//!
//! 1. Each simulation point's [local Delaunay ring](crate::core::ring) among its k nearest
//!    simulation points, counter-clockwise around its normal.
//! 2. **Consistent rings.** Local triangulations need not agree: j may be in i's ring while i
//!    is not in j's, and around a cocircular quad (a grid) each corner's triangulation picks
//!    the diagonal that avoids the corner itself. Every local triangle (i, a, b) asserts its
//!    three edges; the union of all asserted edges is then made planar: where an edge i–j
//!    crosses the edge a–b between its two ring neighbours (in i's tangent plane), the
//!    disputed edges are taken shortest first, each kept unless it crosses one already kept.
//!    Each point's final ring is its kept neighbours sorted counter-clockwise in its tangent
//!    plane; a sector between consecutive ring vertices is a face when they share an edge
//!    (and it spans at most 150°), and a point with a sector that is not a face is a boundary
//!    point. On a closed surface sampled well enough the result is a triangulation: E = 3V − 6
//!    on a sphere.
//! 3. **Springs.** Stretch springs join each point to its ring (every kept edge once); bend
//!    springs join ring vertices r and r + 2 (not across the gap of an open ring), minus pairs
//!    that already share a stretch spring. Rest lengths come from the rest shape.
//! 4. **Masses (eq 1).** m = ρ·area(R)/3, with R the fan of triangles between consecutive ring
//!    vertices taken at the points' true 3D positions (the tangent-plane projection would
//!    shrink curved regions by the cosine of their tilt). Each triangle of a consistent
//!    triangulation lies in three regions, so Σm = ρ·(area of the triangulated surface).
//!
//! A point left with fewer than three springs (a straggler the rings missed) is tied to its
//! nearest simulation points until it has three; a point whose ring encloses no area gets the
//! mean mass. The report says how often either happened.

use glam::Vec3;
use rayon::prelude::*;

use crate::core::knn::KnnIndex;
use crate::core::ring::{MAX_FAN_ANGLE, RingBuilder, RingShape};
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
    #[error("a spring network needs at least {needed} points (k + 1 with k = {k}), got {found}")]
    TooFewPoints {
        /// The k asked for.
        k: usize,
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
    /// Points whose ring is open.
    pub boundary_points: usize,
    /// Closed chains of boundary points (holes and outer rims).
    pub boundary_loops: usize,
    /// Connected components of the stretch springs.
    pub components: usize,
    /// Σm.
    pub total_mass: f32,
    /// Σ area(R)/3: the surface area the masses stand for.
    pub area: f32,
    /// Smallest region diameter d.
    pub min_diameter: f32,
    /// Largest region diameter d.
    pub max_diameter: f32,
    /// Edges held by one endpoint's local ring only (before links and crossings are resolved).
    pub disagreements: usize,
    /// Crossing edges removed to make the rings consistent.
    pub crossings_resolved: usize,
    /// Springs added to give stragglers [`MIN_STRETCH_SPRINGS`].
    pub fallback_springs: usize,
    /// Points whose ring enclosed no area and got the mean mass.
    pub fallback_masses: usize,
}

/// Simulation points with their springs and masses: the rest state of a deformable surface.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SpringNetwork {
    /// Rest positions.
    pub positions: Vec<Vec3>,
    /// Rest normals (unit).
    pub normals: Vec<Vec3>,
    /// Masses (eq 1), all positive.
    pub masses: Vec<f32>,
    /// Stretch springs: each point to its ring.
    pub stretch: Vec<Spring>,
    /// Bend springs: ring vertex r to ring vertex r + 2.
    pub bend: Vec<Spring>,
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

    /// The triangles of the rings, each once, counter-clockwise around the points' normals:
    /// point i with consecutive ring vertices a and b, listed by the smallest of the three
    /// (so a triangle the rings disagree on may be missing).
    pub fn triangles(&self) -> Vec<[u32; 3]> {
        let mut triangles = Vec::new();
        for i in 0..self.len() {
            let ring = self.ring(i);
            let m = ring.len();
            let pairs = if self.boundary[i] {
                m.saturating_sub(1)
            } else {
                m
            };
            if m < 2 {
                continue;
            }
            let i = i as u32;
            for j in 0..pairs {
                let (a, b) = (ring[j], ring[(j + 1) % m]);
                if i < a && i < b {
                    triangles.push([i, a, b]);
                }
            }
        }
        triangles
    }
}

/// Builds the spring network on simulation points with unit normals.
pub fn build_network(
    positions: &[Vec3],
    normals: &[Vec3],
    config: &NetworkConfig,
) -> Result<SpringNetwork, NetworkError> {
    validate(positions, normals, config)?;
    let n = positions.len();
    let k = config.k;
    let normals: Vec<Vec3> = normals.iter().map(|v| v.normalize()).collect();
    let index = KnnIndex::build(positions);
    let graph = index.knn_graph(positions, k);

    // 1. Local rings.
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
                let shape = builder.build(positions[i], normals[i], scratch, Some(&mut ring));
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

    // 2. Consistent edges: the union of the local rings, crossings resolved.
    // Each local triangle (i, a, b) asserts three edges: i–a, i–b and a–b. (Asserting a–b
    // matters on grids: around a cocircular quad each corner's triangulation picks the
    // diagonal that avoids the corner itself, so no diagonal would be held by its endpoints.)
    let mut spokes: Vec<(u32, u32)> = Vec::new();
    let mut links: Vec<(u32, u32)> = Vec::new();
    for (i, (_, ring)) in local.iter().enumerate() {
        let m = ring.len();
        for (r, &(j, face)) in ring.iter().enumerate() {
            spokes.push((i as u32, j));
            if face && m > 1 {
                links.push(key(j, ring[(r + 1) % m].0));
            }
        }
    }
    let mut held: Vec<(u32, u32)> = spokes.iter().map(|&(i, j)| key(i, j)).collect();
    held.par_sort_unstable();
    let disagreements = held
        .chunk_by(|a, b| a == b)
        .filter(|c| c.len() == 1)
        .count();
    let mut edges = held;
    edges.append(&mut links);
    edges.par_sort_unstable();
    edges.dedup();
    drop(spokes);
    let boundary: Vec<bool> = local.iter().map(|(s, _)| s.open).collect();
    let mut crossings_resolved = 0;
    for _ in 0..MAX_CROSSING_PASSES {
        let adjacency = Adjacency::new(n, &edges);
        let losers = crossing_losers(positions, &normals, &boundary, &adjacency, &edges);
        if losers.is_empty() {
            break;
        }
        crossings_resolved += losers.len();
        edges.retain(|e| losers.binary_search(e).is_err());
    }
    let length = |a: u32, b: u32| positions[a as usize].distance(positions[b as usize]);

    // Stragglers: tie to the nearest points until MIN_STRETCH_SPRINGS.
    let mut adjacency = Adjacency::new(n, &edges);
    let mut degree: Vec<usize> = (0..n).map(|i| adjacency.degree(i)).collect();
    let mut added: Vec<(u32, u32)> = Vec::new();
    let mut added_set: std::collections::HashSet<(u32, u32)> = std::collections::HashSet::new();
    for i in 0..n {
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
        adjacency = Adjacency::new(n, &edges);
    }
    edges.sort_unstable();

    // 3. Final rings, CCW in each tangent plane, with their faces; a point with a sector
    // that is not a triangle of the network is on the boundary.
    let finals: Vec<(Vec<u32>, bool, f32)> = (0..n)
        .into_par_iter()
        .with_min_len(256)
        .map(|i| final_ring(positions, normals[i], i, adjacency.neighbours(i), &edges))
        .collect();
    let mut rings = Vec::with_capacity(n);
    let mut boundary = Vec::with_capacity(n);
    let mut areas = Vec::with_capacity(n);
    for (ring, open, area) in finals {
        rings.push(ring);
        boundary.push(open);
        areas.push(area);
    }

    // 4. Masses from the 3D fans.
    let positive: Vec<f32> = areas.iter().copied().filter(|a| *a > 0.0).collect();
    let mean_area = if positive.is_empty() {
        return Err(NetworkError::NotASurface);
    } else {
        positive.iter().map(|a| f64::from(*a)).sum::<f64>() / positive.len() as f64
    } as f32;
    let fallback_masses = areas.len() - positive.len();
    let masses: Vec<f32> = areas
        .iter()
        .map(|&a| config.density * if a > 0.0 { a } else { mean_area } / 3.0)
        .collect();

    // Springs.
    let spring = |(a, b): (u32, u32)| Spring {
        a,
        b,
        rest_length: length(a, b),
    };
    let stretch: Vec<Spring> = edges.iter().copied().map(spring).collect();
    let mut bend_pairs: Vec<(u32, u32)> = Vec::new();
    for (i, ring) in rings.iter().enumerate() {
        let m = ring.len();
        if m < 3 {
            continue;
        }
        let pairs = if boundary[i] { m.saturating_sub(2) } else { m };
        for r in 0..pairs {
            let (a, b) = (ring[r], ring[(r + 2) % m]);
            if a != b && edges.binary_search(&key(a, b)).is_err() {
                bend_pairs.push(key(a, b));
            }
        }
    }
    bend_pairs.sort_unstable();
    bend_pairs.dedup();
    let bend: Vec<Spring> = bend_pairs.into_iter().map(spring).collect();

    // Report.
    let finite_d = || {
        local
            .iter()
            .map(|(s, _)| s.diameter)
            .filter(|d| d.is_finite())
    };
    let components = count_components(n, edges.iter().copied());
    let boundary_edges = rings.iter().enumerate().flat_map(|(i, ring)| {
        let ends = if boundary[i] && !ring.is_empty() {
            vec![ring[0], ring[ring.len() - 1]]
        } else {
            Vec::new()
        };
        ends.into_iter()
            .filter(|&j| boundary[j as usize])
            .map(move |j| key(i as u32, j))
    });
    let boundary_points = boundary.iter().filter(|b| **b).count();
    let loops = count_components(n, boundary_edges) - (n - boundary_points);
    let report = NetworkReport {
        points: n,
        stretch_springs: stretch.len(),
        bend_springs: bend.len(),
        boundary_points,
        boundary_loops: loops,
        components,
        total_mass: masses.iter().map(|m| f64::from(*m)).sum::<f64>() as f32,
        area: areas.iter().map(|a| f64::from(*a)).sum::<f64>() as f32 / 3.0,
        min_diameter: finite_d().fold(f32::INFINITY, f32::min),
        max_diameter: finite_d().fold(0.0, f32::max),
        disagreements,
        crossings_resolved,
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
    Ok(SpringNetwork {
        positions: positions.to_vec(),
        normals,
        masses,
        stretch,
        bend,
        boundary,
        ring_offsets,
        ring_indices,
        report,
    })
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
    let needed = (config.k + 1).max(MIN_SIMULATION_POINTS);
    if positions.len() < needed {
        return Err(NetworkError::TooFewPoints {
            k: config.k,
            needed,
            found: positions.len(),
        });
    }
    if let Some(i) = positions
        .iter()
        .zip(normals)
        .position(|(p, n)| !p.is_finite() || !n.is_finite() || n.length_squared() == 0.0)
    {
        return Err(NetworkError::InvalidPoint(i));
    }
    Ok(())
}

/// Passes of crossing removal (one or two suffice on real data).
const MAX_CROSSING_PASSES: usize = 8;

/// The edges to drop so that no two edges cross. A crossing is a run a, j, b of consecutive
/// vertices in point i's ring where the edge a–b exists and crosses i–j in i's tangent plane.
/// Edges in crossings are then taken shortest first (ties by index), each kept unless it
/// crosses an edge already kept: a greedy triangulation of the disputed edges, so a long edge
/// that cuts across several short ones loses to all of them. Sorted.
fn crossing_losers(
    positions: &[Vec3],
    normals: &[Vec3],
    boundary: &[bool],
    adjacency: &Adjacency,
    edges: &[(u32, u32)],
) -> Vec<(u32, u32)> {
    let n = positions.len();
    let mut conflicts: Vec<((u32, u32), (u32, u32))> = (0..n)
        .into_par_iter()
        .with_min_len(256)
        .flat_map_iter(|i| {
            let ring = sorted_ring(
                positions,
                normals[i],
                i,
                adjacency.neighbours(i),
                boundary[i],
            );
            let m = ring.len();
            let mut out = Vec::new();
            if m < 3 {
                return out;
            }
            let (t1, t2) = normals[i].any_orthonormal_pair();
            let flat = |v: u32| {
                let d = positions[v as usize] - positions[i];
                glam::Vec2::new(d.dot(t1), d.dot(t2))
            };
            let runs = if boundary[i] { m - 2 } else { m };
            for r in 0..runs {
                let (a, j, b) = if boundary[i] {
                    (ring[r], ring[r + 1], ring[r + 2])
                } else {
                    (ring[(r + m - 1) % m], ring[r], ring[(r + 1) % m])
                };
                if a == b || edges.binary_search(&key(a, b)).is_err() {
                    continue;
                }
                let (pa, pj, pb) = (flat(a), flat(j), flat(b));
                let ab = pb - pa;
                // i (the origin) and j on opposite sides of a–b, a and b on opposite sides of i–j.
                let crosses = ab.perp_dot(-pa) * ab.perp_dot(pj - pa) < 0.0
                    && pj.perp_dot(pa) * pj.perp_dot(pb) < 0.0;
                if !crosses {
                    continue;
                }
                out.push((key(i as u32, j), key(a, b)));
            }
            out
        })
        .collect();
    // Both directions, so each edge finds its rivals by binary search.
    let reversed: Vec<_> = conflicts.iter().map(|&(e, f)| (f, e)).collect();
    conflicts.extend(reversed);
    conflicts.par_sort_unstable();
    conflicts.dedup();
    let length = |e: (u32, u32)| positions[e.0 as usize].distance(positions[e.1 as usize]);
    let mut involved: Vec<(u32, u32)> = conflicts.iter().map(|c| c.0).collect();
    involved.dedup();
    involved.sort_by(|&e, &f| length(e).total_cmp(&length(f)).then(e.cmp(&f)));
    let mut kept: std::collections::HashSet<(u32, u32)> = std::collections::HashSet::new();
    let mut losers = Vec::new();
    for e in involved {
        let lo = conflicts.partition_point(|c| c.0 < e);
        let beaten = conflicts[lo..]
            .iter()
            .take_while(|c| c.0 == e)
            .any(|c| kept.contains(&c.1));
        if beaten {
            losers.push(e);
        } else {
            kept.insert(e);
        }
    }
    losers.sort_unstable();
    losers
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

/// Angle of `v` around `normal` in the tangent basis shared with the ring builder.
fn tangent_angle(normal: Vec3, v: Vec3) -> f32 {
    let (t1, t2) = normal.any_orthonormal_pair();
    v.dot(t2).atan2(v.dot(t1))
}

/// `neighbours` of point `i` sorted counter-clockwise around `normal`; for an open ring,
/// starting after the widest angular gap.
fn sorted_ring(
    positions: &[Vec3],
    normal: Vec3,
    i: usize,
    neighbours: &[u32],
    open: bool,
) -> Vec<u32> {
    let centre = positions[i];
    let mut by_angle: Vec<(f32, u32)> = neighbours
        .iter()
        .map(|&j| (tangent_angle(normal, positions[j as usize] - centre), j))
        .collect();
    by_angle.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let m = by_angle.len();
    let start = if open && m > 1 {
        (0..m)
            .max_by(|&r, &q| {
                let gap = |r: usize| {
                    let next = by_angle[(r + 1) % m].0;
                    (next - by_angle[r].0).rem_euclid(std::f32::consts::TAU)
                };
                gap(r).total_cmp(&gap(q)).then(q.cmp(&r))
            })
            .map_or(0, |r| (r + 1) % m)
    } else {
        0
    };
    (0..m).map(|r| by_angle[(start + r) % m].1).collect()
}

/// The final ring of point `i`: its `neighbours` sorted counter-clockwise around `normal`,
/// whether it is open, and the 3D area of its region. A sector between consecutive ring
/// vertices is a face when they share an edge and it spans at most [`MAX_FAN_ANGLE`]; the
/// ring is open when a sector is not a face, and then starts after the widest such gap. The
/// region is the fan of faces at the points' true positions.
fn final_ring(
    positions: &[Vec3],
    normal: Vec3,
    i: usize,
    neighbours: &[u32],
    edges: &[(u32, u32)],
) -> (Vec<u32>, bool, f32) {
    let centre = positions[i];
    let ring = sorted_ring(positions, normal, i, neighbours, false);
    let m = ring.len();
    if m < 2 {
        return (ring, true, 0.0);
    }
    let sweep = |r: usize| {
        let a = positions[ring[r] as usize] - centre;
        let b = positions[ring[(r + 1) % m] as usize] - centre;
        (tangent_angle(normal, b) - tangent_angle(normal, a)).rem_euclid(std::f32::consts::TAU)
    };
    let face: Vec<bool> = (0..m)
        .map(|r| {
            f64::from(sweep(r)) <= MAX_FAN_ANGLE
                && edges
                    .binary_search(&key(ring[r], ring[(r + 1) % m]))
                    .is_ok()
        })
        .collect();
    let open = face.iter().any(|f| !f);
    let mut area = 0.0f64;
    for r in (0..m).filter(|&r| face[r]) {
        let a = positions[ring[r] as usize] - centre;
        let b = positions[ring[(r + 1) % m] as usize] - centre;
        area += 0.5 * f64::from(a.cross(b).length());
    }
    let start = if open {
        (0..m)
            .filter(|&r| !face[r])
            .max_by(|&r, &q| sweep(r).total_cmp(&sweep(q)).then(q.cmp(&r)))
            .map_or(0, |r| (r + 1) % m)
    } else {
        0
    };
    let ring = (0..m).map(|r| ring[(start + r) % m]).collect();
    (ring, open, area as f32)
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
