//! The surface the springs lie on: the points' local Delaunay rings voted into one oriented
//! triangle mesh, and the holes their disagreements leave closed.
//!
//! Local triangulations need not agree. j may be in i's ring while i is not in j's; around a
//! cocircular quad each corner picks the diagonal that avoids itself; on a noisy scan or a thin
//! part a neighbour projects to the wrong side. Taking the union of the rings' edges and
//! cutting crossings (what this module replaced) leaves holes where they disagree. Instead:
//!
//! 1. **Candidates.** Every face (i, a, b) of every point's local ring, counter-clockwise
//!    around i's normal. A triangle proposed by several of its corners gets that many votes.
//! 2. **Selection.** Candidates are taken by votes (most first), then smallest circumradius
//!    (where that leaves holes, the selection is also run by shortest longest edge, and the
//!    mesh with fewer boundary points is kept),
//!    each accepted when it keeps the mesh a locally embedded, consistently oriented surface.
//!    At each of its three corners, projected on that corner's tangent plane, it must turn
//!    counter-clockwise (its normal within 90° of the corner's normal: no fold-over), span
//!    less than [`MAX_CORNER_ANGLE`], and overlap no triangle already at that corner (so no
//!    two springs at a point cross, and no edge gets a third triangle); none of its
//!    directed edges may be in use (orientation stays consistent); and it may not overlap a
//!    nearby triangle that shares no corner with it (facing within 60° of it, near its plane,
//!    overlapping in projection on either's plane by more than [`OVERLAP_MARGIN`]): such a
//!    pair would lay two patches over one part of the surface, whose rims no ear can close.
//! 3. **Stragglers.** A point left without any triangle (inside a region its neighbours'
//!    triangles already cover) is inserted by splitting the triangle it projects into.
//! 4. **Closing.** A *closable* point (its own ring is closed, or open only by the ring's
//!    circumradius guard while its projected neighbours still surround it: a density slope,
//!    not an edge) left with a gap between two of its triangles gets the triangle across the
//!    gap (an *ear*), narrowest gap first, under the same tests, until no ear fits; a gap too
//!    wide for one ear narrows as the ears at its other points are added. A loop of boundary
//!    edges most of whose points are closable is a hole, and its other points are closed too.
//!    Every ear must lie over the dense cloud when it is known ([`DenseSupport`]), so the
//!    hat keeps its rim and the letter B its counters. What the strict tests leave is closed
//!    with ears that only keep the mesh a manifold, face within 90° of their corners' mean
//!    normal, and do not overlap at a corner whose normal they face within 60° of
//!    ([`MAX_CLOSING_ANGLE`]); where the surface curves sharply between coarse points, no
//!    triangle faces within 90° of all three corners' normals.
//! 5. **Points left under the surface.** A point still without a triangle splits the triangle
//!    of its neighbours whose plane it projects into.
//! 6. **Fans.** A hole no ear closes gets a fan from the dense point that sees its whole loop
//!    (see [`fill`]); that point joins the simulation points.
//! 7. **Patches.** A hole neither closes is triangulated whole where a triangulation fits
//!    (see [`patch`]).
//!
//! Closing ears, fans and patches all pass the overlap test of step 2 against triangles that
//! share no corner with them. The holes left are listed for the
//! network builder, which samples them more finely from the dense cloud and builds again.
//!
//! Every triangle is stored once, counter-clockwise around the (consistently oriented) normals.

use std::cmp::Reverse;
use std::f32::consts::TAU;

use glam::Vec3;

use super::DenseSupport;
use crate::core::cloud::knn::KnnGraph;
use crate::core::simplify::MAX_SIMPLIFY_K;

mod ears;
pub mod fill;
mod overlap;
pub mod patch;
mod stragglers;

pub use overlap::OVERLAP_MARGIN;
use overlap::overlaps;

/// Widest angle a triangle may span at any corner, in that corner's tangent plane (170°):
/// wider ones are slivers whose orientation a small error can flip.
pub const MAX_CORNER_ANGLE: f32 = 17.0 * std::f32::consts::PI / 18.0;

/// Widest corner angle of a triangle that closes a hole (179°): any triangle that does not
/// fold over (its normal within 90° of its corners' normals) is better than a hole.
pub const MAX_CLOSING_ANGLE: f32 = 179.0 * std::f32::consts::PI / 180.0;

/// A triangle facing further than this (cosine of 60°) from a corner's normal says nothing
/// about overlaps in that corner's tangent plane.
const STEEP_COS: f32 = 0.5;

/// Rounds of ear closing (each retries every gap; later rounds add only a few ears).
const MAX_CLOSING_ROUNDS: usize = 8;

/// The part of a triangle at one of its corners: the sector it covers in the corner's tangent
/// plane, counter-clockwise from one ring vertex to the next.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Wedge {
    /// Ring vertex where the sector starts.
    pub from: u32,
    /// Ring vertex where it ends.
    pub to: u32,
    /// Angle of `from` in the corner's tangent plane.
    start: f32,
    /// Angle swept from `from` to `to`, in (0, [`MAX_CORNER_ANGLE`]).
    sweep: f32,
}

/// How the mesh came about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct MeshStats {
    /// Distinct candidate triangles.
    pub candidates: usize,
    /// Candidates not proposed by all three of their corners.
    pub disputed: usize,
    /// Triangles added to close holes.
    pub ears: usize,
    /// Points without triangles inserted by splitting a triangle.
    pub inserted: usize,
    /// Holes filled by a fan from an added point.
    pub fans: usize,
    /// Holes triangulated whole.
    pub patches: usize,
}

/// An oriented triangle mesh over the simulation points, stored as each point's sectors (a
/// triangle is the three sectors at its corners).
#[derive(Debug, Clone, Default)]
pub(crate) struct SurfaceMesh {
    /// Per point, the sectors of its triangles sorted by start angle.
    pub wedges: Vec<Vec<Wedge>>,
    /// How the mesh came about.
    pub stats: MeshStats,
    /// Points added to fill holes (position, unit normal), numbered after the simulation
    /// points in order.
    pub added: Vec<(Vec3, Vec3)>,
    /// The holes left open: boundary loops most of whose points are closable.
    pub holes: Vec<Vec<u32>>,
}

impl SurfaceMesh {
    /// The triangles, each once (listed at its smallest corner), counter-clockwise around the
    /// normals.
    pub fn triangles(&self) -> Vec<[u32; 3]> {
        let mut out = Vec::new();
        for (v, wedges) in self.wedges.iter().enumerate() {
            let v = v as u32;
            out.extend(
                wedges
                    .iter()
                    .filter(|w| v < w.from && v < w.to)
                    .map(|w| [v, w.from, w.to]),
            );
        }
        out
    }

    /// Whether point `v` has a gap between its triangles (or none at all): a boundary point.
    pub fn is_open(&self, v: usize) -> bool {
        let w = &self.wedges[v];
        w.is_empty() || (0..w.len()).any(|i| w[i].to != w[(i + 1) % w.len()].from)
    }

    /// Whether point `v` has a triangle from ring vertex `a` to ring vertex `b`.
    pub fn has_wedge(&self, v: usize, a: u32, b: u32) -> bool {
        self.wedges[v].iter().any(|w| w.from == a && w.to == b)
    }

    /// Points where the surface pinches: two or more gaps between their triangles.
    pub fn pinched_points(&self) -> usize {
        (0..self.wedges.len())
            .filter(|&v| self.gaps(v).nth(1).is_some())
            .count()
    }

    /// The far corners of the two triangles at each inner edge, once from each end of the
    /// edge: around a point, ring vertices r and r + 2.
    pub fn wings(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        self.wedges.iter().flat_map(|w| {
            let m = w.len();
            (0..m)
                .filter(move |&i| m > 1 && w[i].to == w[(i + 1) % m].from)
                .map(move |i| (w[i].from, w[(i + 1) % m].to))
        })
    }

    /// Boundary loops: cycles of directed edges used by one triangle only, each as its points
    /// in order. At a point where the surface pinches (two gaps), each loop turns into the gap
    /// it arrived through.
    pub fn boundary_loops(&self) -> Vec<Vec<u32>> {
        // Boundary edge u → v: a wedge at v ends at u with a gap after it.
        let mut visited: std::collections::HashSet<(u32, u32)> = Default::default();
        let mut loops = Vec::new();
        for v in 0..self.wedges.len() {
            for (u, _) in self.gaps(v) {
                if visited.contains(&(u, v as u32)) {
                    continue;
                }
                // Walk: at v, the gap after u leads to x; the next edge is v → x.
                let mut points = Vec::new();
                let (mut from, mut at) = (u, v as u32);
                while visited.insert((from, at)) {
                    points.push(at);
                    let Some(next) = self
                        .gaps(at as usize)
                        .find(|&(g, _)| g == from)
                        .map(|(_, x)| x)
                    else {
                        break;
                    };
                    (from, at) = (at, next);
                }
                loops.push(points);
            }
        }
        loops
    }

    /// The mesh of `triangles` (each counter-clockwise around the unit `normals`), made
    /// without any test: each point's sectors in the order its fan links them (a fan that
    /// is not one chain, at a pinch, is listed chain after chain).
    pub fn from_triangles(positions: &[Vec3], normals: &[Vec3], triangles: &[[u32; 3]]) -> Self {
        let mut fans: Vec<Vec<(u32, u32)>> = vec![Vec::new(); positions.len()];
        for &[a, b, c] in triangles {
            fans[a as usize].push((b, c));
            fans[b as usize].push((c, a));
            fans[c as usize].push((a, b));
        }
        let wedges = fans
            .into_iter()
            .enumerate()
            .map(|(v, mut fan)| {
                let centre = positions[v];
                let (t1, t2) = normals[v].any_orthonormal_pair();
                let angle = |u: u32| {
                    let d = positions[u as usize] - centre;
                    d.dot(t2).atan2(d.dot(t1))
                };
                let mut ordered = Vec::with_capacity(fan.len());
                while !fan.is_empty() {
                    // A chain starts after a gap when there is one.
                    let start = (0..fan.len())
                        .find(|&i| !fan.iter().any(|w| w.1 == fan[i].0))
                        .unwrap_or(0);
                    let mut at = fan.swap_remove(start);
                    ordered.push(at);
                    while let Some(next) = fan.iter().position(|w| w.0 == at.1) {
                        at = fan.swap_remove(next);
                        ordered.push(at);
                    }
                }
                ordered
                    .into_iter()
                    .map(|(from, to)| {
                        let start = angle(from);
                        Wedge {
                            from,
                            to,
                            start,
                            sweep: (angle(to) - start).rem_euclid(TAU),
                        }
                    })
                    .collect()
            })
            .collect();
        Self {
            wedges,
            ..Self::default()
        }
    }

    /// The gaps at point `v` as (vertex before, vertex after), counter-clockwise.
    fn gaps(&self, v: usize) -> impl Iterator<Item = (u32, u32)> + '_ {
        let w = &self.wedges[v];
        let m = w.len();
        (0..m)
            .map(move |i| (w[i].to, w[(i + 1) % m].from))
            .filter(|(a, b)| a != b)
    }
}

/// Builds the mesh from candidate triangles (each counter-clockwise around its proposer's
/// normal), closing the gaps of the points marked `closable`.
pub(crate) fn build_mesh(
    positions: &[Vec3],
    normals: &[Vec3],
    graph: &KnnGraph,
    candidates: Vec<[u32; 3]>,
    closable: &[bool],
    dense: Option<&DenseSupport>,
) -> SurfaceMesh {
    let frames: Vec<(Vec3, Vec3)> = normals.iter().map(|n| n.any_orthonormal_pair()).collect();
    let build = |order: Order| {
        let mut b = Builder {
            graph,
            positions: positions.to_vec(),
            normals: normals.to_vec(),
            dense,
            frames: frames.clone(),
            limit: MAX_CORNER_ANGLE,
            mesh: SurfaceMesh {
                wedges: vec![Vec::new(); positions.len()],
                ..SurfaceMesh::default()
            },
        };
        b.select(candidates.clone(), order);
        b.insert_stragglers(graph);
        let closable = b.close(closable, graph);
        b.split_for_isolated(graph);
        b.fill_with_centres(&closable, graph);
        b.patch_holes(&closable);
        b.mesh.holes = b
            .mesh
            .boundary_loops()
            .into_iter()
            .filter(|points| b.is_hole(points, &closable))
            .collect();
        b.mesh.added = b.positions[positions.len()..]
            .iter()
            .copied()
            .zip(b.normals[positions.len()..].iter().copied())
            .collect();
        b.mesh
    };
    let open = |m: &SurfaceMesh| (0..m.wedges.len()).filter(|&v| m.is_open(v)).count();
    let first = build(Order::Circumradius);
    if open(&first) == 0 {
        return first;
    }
    // Where the Delaunay order leaves holes, the other order sometimes does not (and the
    // other way round): keep the better of the two.
    let second = build(Order::LongestEdge);
    if open(&second) < open(&first) {
        second
    } else {
        first
    }
}

/// The order in which candidates with as many votes are tried.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Order {
    /// Smallest circumradius first: the Delaunay choice where rings disagree on a cocircular
    /// neighbourhood (the spheres' networks are then their convex hulls).
    Circumradius,
    /// Shortest longest edge first.
    LongestEdge,
}

struct Builder<'a> {
    /// The simulation points' nearest neighbours.
    graph: &'a KnnGraph,
    /// Positions of the points: the simulation points, then those added to fill holes.
    positions: Vec<Vec3>,
    /// Their unit normals, consistently oriented.
    normals: Vec<Vec3>,
    /// The dense surface closing triangles must lie over, when known.
    dense: Option<&'a DenseSupport<'a>>,
    /// Tangent basis of each point.
    frames: Vec<(Vec3, Vec3)>,
    /// Widest corner angle accepted now.
    limit: f32,
    mesh: SurfaceMesh,
}

impl Builder<'_> {
    /// Angle of `u` around point `v` in `v`'s tangent plane.
    fn angle(&self, v: u32, u: u32) -> f32 {
        let d = self.positions[u as usize] - self.positions[v as usize];
        let (t1, t2) = self.frames[v as usize];
        d.dot(t2).atan2(d.dot(t1))
    }

    /// The sector triangle (v, x, y) would cover at `v`, when it turns counter-clockwise
    /// there by less than [`MAX_CORNER_ANGLE`].
    fn wedge(&self, v: u32, x: u32, y: u32) -> Option<Wedge> {
        let start = self.angle(v, x);
        let sweep = (self.angle(v, y) - start).rem_euclid(TAU);
        (sweep > 0.0 && sweep < self.limit).then_some(Wedge {
            from: x,
            to: y,
            start,
            sweep,
        })
    }

    /// The three sectors of triangle `t`, when it fits the mesh: see the module docs.
    fn fit(&self, [a, b, c]: [u32; 3]) -> Option<[Wedge; 3]> {
        if a == b || b == c || a == c {
            return None;
        }
        let mut out = [None; 3];
        for (slot, (v, x, y)) in [(a, b, c), (b, c, a), (c, a, b)].into_iter().enumerate() {
            let w = self.wedge(v, x, y)?;
            let taken = &self.mesh.wedges[v as usize];
            if taken.iter().any(|o| o.from == x || overlaps(o, &w)) {
                return None;
            }
            out[slot] = Some(w);
        }
        if self.overlaps_apart([a, b, c]) {
            return None;
        }
        Some([out[0]?, out[1]?, out[2]?])
    }

    /// Adds triangle `t` when it fits.
    fn try_add(&mut self, t: [u32; 3]) -> bool {
        let Some(wedges) = self.fit(t) else {
            return false;
        };
        for (v, w) in t.into_iter().zip(wedges) {
            let list = &mut self.mesh.wedges[v as usize];
            let at = list.partition_point(|o| o.start < w.start);
            list.insert(at, w);
        }
        true
    }

    /// Removes triangle `t`.
    fn remove(&mut self, [a, b, c]: [u32; 3]) {
        for (v, x) in [(a, b), (b, c), (c, a)] {
            self.mesh.wedges[v as usize].retain(|w| w.from != x);
        }
    }

    /// Step 2: greedy selection by votes, then `order`.
    fn select(&mut self, mut candidates: Vec<[u32; 3]>, order: Order) {
        // Same triangle, same orientation: the same rotation with the smallest index first.
        for t in &mut candidates {
            let r = (0..3).min_by_key(|&r| t[r]).unwrap_or(0);
            t.rotate_left(r);
        }
        candidates.sort_unstable();
        let mut voted: Vec<(Reverse<usize>, u32, [u32; 3])> = candidates
            .chunk_by(|a, b| a == b)
            .map(|group| {
                let t = group[0];
                let p = |i: u32| self.positions[i as usize];
                let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
                let key = match order {
                    // R = abc / (4·area).
                    Order::Circumradius => {
                        let twice_area = (b - a).cross(c - a).length();
                        a.distance(b) * b.distance(c) * c.distance(a)
                            / (2.0 * twice_area).max(f32::MIN_POSITIVE)
                    }
                    Order::LongestEdge => a
                        .distance_squared(b)
                        .max(b.distance_squared(c))
                        .max(c.distance_squared(a)),
                };
                (Reverse(group.len()), key.to_bits(), t)
            })
            .collect();
        voted.sort_unstable();
        self.mesh.stats.candidates = voted.len();
        self.mesh.stats.disputed = voted.iter().filter(|v| v.0.0 < 3).count();
        for (_, _, t) in voted {
            self.try_add(t);
        }
    }
}
