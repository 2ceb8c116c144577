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
use std::collections::BinaryHeap;
use std::f32::consts::TAU;

use glam::Vec3;

use super::DenseSupport;
use crate::core::cloud::knn::KnnGraph;
use crate::core::simplify::MAX_SIMPLIFY_K;

pub mod fill;
pub mod patch;

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

    /// Whether triangle `t` overlaps a triangle of the mesh that shares no corner with it
    /// (those that do are tested by their sectors): both facing within 60° of each other,
    /// near each other along their normals, and overlapping when projected on either's plane.
    fn overlaps_apart(&self, t: [u32; 3]) -> bool {
        self.overlaps_apart_at(t, t.map(|i| self.positions[i as usize]))
    }

    /// [`Builder::overlaps_apart`] for the triangle with corners `t` at `tri` (a corner not yet
    /// in the mesh is `u32::MAX`).
    fn overlaps_apart_at(&self, t: [u32; 3], tri: [Vec3; 3]) -> bool {
        let p = |i: u32| self.positions[i as usize];
        let (centre, radius) = bounding_sphere(tri);
        let mut plane = None;
        // The corners' neighbours, each once; a triangle is visited at the first of its
        // corners among them.
        let mut around = [0u32; 3 * MAX_SIMPLIFY_K];
        let mut len = 0;
        for v in t.into_iter().filter(|&v| (v as usize) < self.graph.len()) {
            for &j in self.graph.neighbours(v as usize) {
                if len < around.len() {
                    around[len] = j;
                    len += 1;
                }
            }
        }
        let around = &mut around[..len];
        around.sort_unstable();
        let len = partition_dedup(around);
        let around = &around[..len];
        let listed = |c: u32, j: u32| c < j && around.binary_search(&c).is_ok();
        let near = around.iter().flat_map(|&j| {
            self.mesh.wedges[j as usize]
                .iter()
                .filter(move |w| !listed(w.from, j) && !listed(w.to, j))
                .map(move |w| [j, w.from, w.to])
        });
        for u in near {
            if u.iter().any(|c| t.contains(c)) {
                continue;
            }
            let other = u.map(p);
            // Most triangles near the corners are too far to touch: rule them out cheaply.
            let (other_centre, other_radius) = bounding_sphere(other);
            if centre.distance_squared(other_centre) >= (radius + other_radius).powi(2) {
                continue;
            }
            let own = match plane {
                Some(own) => own,
                None => match Plane::of(tri) {
                    Some(own) => *plane.insert(own),
                    None => return false,
                },
            };
            let Some(other_plane) = Plane::of(other) else {
                continue;
            };
            if own.normal.dot(other_plane.normal) > STEEP_COS
                && own.near(other)
                && other_plane.near(tri)
                && own.overlap(tri, other)
                && other_plane.overlap(other, tri)
            {
                return true;
            }
        }
        false
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

    /// Step 3: ears across the gaps of closable points, narrowest first. A loop most of whose
    /// points are closable is a hole: its other points are closed too. First ears that pass
    /// every test of the selection; then, for what is left, ears that only keep the mesh a
    /// manifold and do not fold over (see [`Builder::add_ear`]).
    /// Returns which points are closable in the end.
    fn close(&mut self, closable: &[bool], graph: &KnnGraph) -> Vec<bool> {
        self.limit = MAX_CLOSING_ANGLE;
        let mut closable = closable.to_vec();
        self.ear_rounds(&mut closable, true);
        // Points the strict ears surrounded: split in while sectors are still sorted.
        self.insert_stragglers(graph);
        self.ear_rounds(&mut closable, false);
        closable
    }

    /// Rounds of ears across the gaps of `closable` points, narrowest first, `strict`ly
    /// tested ([`Builder::try_add`]) or not ([`Builder::add_ear`]); a loop most of whose points
    /// are closable makes all of them closable.
    fn ear_rounds(&mut self, closable: &mut [bool], strict: bool) {
        for _ in 0..MAX_CLOSING_ROUNDS {
            for points in self.mesh.boundary_loops() {
                let inner = points.iter().filter(|&&v| closable[v as usize]).count();
                if 2 * inner >= points.len() {
                    for v in points {
                        closable[v as usize] = true;
                    }
                }
            }
            let mut queue: BinaryHeap<Reverse<(u32, u32, u32, u32)>> = BinaryHeap::new();
            for v in (0..closable.len()).filter(|&v| closable[v]) {
                self.queue_gaps(v as u32, &mut queue);
            }
            let before = self.mesh.stats.ears;
            while let Some(Reverse((_, v, u, x))) = queue.pop() {
                let added = if !self.over_dense([v, u, x]) {
                    false
                } else if strict {
                    self.try_add([v, u, x])
                } else {
                    self.add_ear(v, u, x)
                };
                if added {
                    self.mesh.stats.ears += 1;
                    for w in [v, u, x] {
                        if closable[w as usize] {
                            self.queue_gaps(w, &mut queue);
                        }
                    }
                }
            }
            if self.mesh.stats.ears == before {
                break;
            }
        }
    }

    /// Adds the ear (v, u, x) across the gap at `v` from `u` to `x`, where a hole's loop runs
    /// u → v → x, when it keeps the mesh a manifold (the edge u → x is not in use) and does not
    /// fold over: it turns counter-clockwise at `v` by less than [`MAX_CLOSING_ANGLE`] and its
    /// normal is within 90° of the mean of its corners' normals. Where the surface curves
    /// sharply between coarse points (a finger, an ear, a thin leg), no triangle across a hole
    /// can face within 90° of all three corners' normals; tangent planes then say nothing about
    /// overlaps at `u` and `x`, so the new sectors go into their fans by the loop's order, not
    /// by angle.
    fn add_ear(&mut self, v: u32, u: u32, x: u32) -> bool {
        let normals = &self.normals;
        if self.wedge(v, u, x).is_none() || !self.ear_is_manifold(v, u, x) {
            return false;
        }
        let p = |i: u32| self.positions[i as usize];
        let normal = (p(u) - p(v)).cross(p(x) - p(v)).normalize_or_zero();
        let mean = normals[v as usize] + normals[u as usize] + normals[x as usize];
        if normal.dot(mean) <= 0.0 || self.overlaps_apart([v, u, x]) {
            return false;
        }
        // Where the triangle faces within 60° of a side corner's normal, that corner's tangent
        // plane is meaningful: the ear must not overlap its triangles there.
        for (c, from, to) in [(u, x, v), (x, v, u)] {
            if normal.dot(normals[c as usize]) > STEEP_COS {
                let Some(w) = self.wedge(c, from, to) else {
                    return false;
                };
                if self.mesh.wedges[c as usize].iter().any(|o| overlaps(o, &w)) {
                    return false;
                }
            }
        }
        self.insert_ear(v, u, x)
    }

    /// Whether the ear (v, u, x) across the gap at `v` from `u` to `x` keeps the mesh a
    /// manifold: that gap exists, no directed edge of the ear is in use, and where u and x are
    /// joined already the ear closes the gap between them at both ends (anything else would
    /// glue two sheets together at u or x).
    fn ear_is_manifold(&self, v: u32, u: u32, x: u32) -> bool {
        let fan = |p: u32| &self.mesh.wedges[p as usize];
        let used = |a: u32, b: u32| fan(a).iter().any(|w| w.from == b);
        if u == x || used(v, u) || used(u, x) || used(x, v) {
            return false;
        }
        let (fv, fu, fx) = (fan(v), fan(u), fan(x));
        let gap_at_v = (0..fv.len()).any(|i| fv[i].to == u && fv[(i + 1) % fv.len()].from == x);
        let (Some(at_u), Some(at_x)) = (
            fu.iter().position(|w| w.from == v),
            fx.iter().position(|w| w.to == v),
        ) else {
            return false;
        };
        gap_at_v
            && (!fu.iter().any(|w| w.to == x) || fu[(at_u + fu.len() - 1) % fu.len()].to == x)
            && (!fx.iter().any(|w| w.from == u) || fx[(at_x + 1) % fx.len()].from == u)
    }

    /// Inserts the ear (v, u, x) (checked by [`Builder::ear_is_manifold`]) into the fans of its
    /// corners by the loop's order.
    fn insert_ear(&mut self, v: u32, u: u32, x: u32) -> bool {
        let fan = |p: u32| &self.mesh.wedges[p as usize];
        let (fv, fu, fx) = (fan(v), fan(u), fan(x));
        let at_v = (0..fv.len()).find(|&i| fv[i].to == u && fv[(i + 1) % fv.len()].from == x);
        let at_u = fu.iter().position(|w| w.from == v);
        let at_x = fx.iter().position(|w| w.to == v);
        let (Some(at_v), Some(at_u), Some(at_x)) = (at_v, at_u, at_x) else {
            return false;
        };
        let (wv, wu, wx) = (
            self.raw_wedge(v, u, x),
            self.raw_wedge(u, x, v),
            self.raw_wedge(x, v, u),
        );
        self.mesh.wedges[v as usize].insert(at_v + 1, wv);
        self.mesh.wedges[u as usize].insert(at_u, wu);
        self.mesh.wedges[x as usize].insert(at_x + 1, wx);
        true
    }

    /// The sector of triangle (c, from, to) at `c`, whatever its angle.
    fn raw_wedge(&self, c: u32, from: u32, to: u32) -> Wedge {
        let start = self.angle(c, from);
        Wedge {
            from,
            to,
            start,
            sweep: (self.angle(c, to) - start).rem_euclid(TAU),
        }
    }

    /// Step 5: a point still without a triangle (the closed surface passes just over or under
    /// it) splits the triangle of its neighbours that it lies over: its projection on that
    /// triangle's plane inside it, nearer to the plane than the triangle is long, and each new
    /// triangle facing within 90° of its corners' mean normal. The new sectors go into the
    /// corners' fans in place of the old one.
    fn split_for_isolated(&mut self, graph: &KnnGraph) {
        let mut over_edges = Vec::new();
        let normals = &self.normals;
        // Points added to fill holes always have their fans.
        for v in 0..graph.len() as u32 {
            if !self.mesh.wedges[v as usize].is_empty() {
                continue;
            }
            let p = self.positions[v as usize];
            let at = |i: u32| self.positions[i as usize];
            let inside = self.triangles_near(v, graph).find(|&[a, b, c]| {
                let (pa, pb, pc) = (at(a), at(b), at(c));
                let n = (pb - pa).cross(pc - pa);
                let area2 = n.length_squared();
                if area2 == 0.0 {
                    return false;
                }
                let height = (p - pa).dot(n) / area2.sqrt();
                let longest = pa.distance(pb).max(pb.distance(pc)).max(pc.distance(pa));
                let faces_up = |x: u32, y: u32| {
                    let mean = normals[x as usize] + normals[y as usize] + normals[v as usize];
                    (at(y) - at(x)).cross(p - at(x)).dot(mean) > 0.0
                };
                [(pb, pc), (pc, pa), (pa, pb)]
                    .iter()
                    .all(|&(x, y)| (y - x).cross(p - x).dot(n) > 0.0)
                    && height.abs() < longest
                    && faces_up(a, b)
                    && faces_up(b, c)
                    && faces_up(c, a)
            });
            let Some([a, b, c]) = inside else {
                over_edges.push(v);
                continue;
            };
            for (corner, from, to) in [(a, b, c), (b, c, a), (c, a, b)] {
                let first = self.raw_wedge(corner, from, v);
                let second = self.raw_wedge(corner, v, to);
                let fan = &mut self.mesh.wedges[corner as usize];
                if let Some(at) = fan.iter().position(|w| w.from == from && w.to == to) {
                    fan[at] = first;
                    fan.insert(at + 1, second);
                }
            }
            self.mesh.wedges[v as usize] = vec![
                self.raw_wedge(v, a, b),
                self.raw_wedge(v, b, c),
                self.raw_wedge(v, c, a),
            ];
            self.mesh.stats.inserted += 1;
        }
        for v in over_edges {
            self.split_edge_for(v, graph);
        }
    }

    /// Step 5 where `v` projects into no triangle: it lies over an inner edge a–b of its
    /// neighbours' triangles (a, b, c) and (b, a, d), between a and b and within the edge's
    /// length of it, and splits both into four, each facing within 90° of its corners' mean
    /// normal. The nearest such edge is split.
    fn split_edge_for(&mut self, v: u32, graph: &KnnGraph) {
        let p = self.positions[v as usize];
        let at = |i: u32| self.positions[i as usize];
        let faces_up = |t: [u32; 3]| {
            let [x, y, z] = t.map(at);
            let mean: Vec3 = t.iter().map(|&i| self.normals[i as usize]).sum();
            (y - x).cross(z - x).dot(mean) > 0.0
        };
        let mut best: Option<(f32, [u32; 4])> = None;
        for [a, b, c] in self.triangles_near(v, graph) {
            // The twin across a–b, as the wedge at a from d to b.
            let Some(d) = self.mesh.wedges[a as usize]
                .iter()
                .find(|w| w.to == b)
                .map(|w| w.from)
            else {
                continue;
            };
            let (pa, pb) = (at(a), at(b));
            let edge = pb - pa;
            let t = (p - pa).dot(edge) / edge.length_squared();
            let distance = (pa + edge * t).distance(p);
            let fits = (0.05..=0.95).contains(&t)
                && distance < edge.length()
                && d != c
                && [[a, v, c], [v, b, c], [b, v, d], [v, a, d]]
                    .into_iter()
                    .all(faces_up);
            if fits && best.is_none_or(|(nearest, _)| distance < nearest) {
                best = Some((distance, [a, b, c, d]));
            }
        }
        let Some((_, [a, b, c, d])) = best else {
            return;
        };
        let replace = |b: &mut Self, corner: u32, from: u32, to: u32, new: &[(u32, u32)]| {
            let wedges: Vec<Wedge> = new
                .iter()
                .map(|&(f, t)| b.raw_wedge(corner, f, t))
                .collect();
            let fan = &mut b.mesh.wedges[corner as usize];
            if let Some(i) = fan.iter().position(|w| w.from == from && w.to == to) {
                fan.splice(i..=i, wedges);
            }
        };
        replace(self, a, b, c, &[(v, c)]);
        replace(self, a, d, b, &[(d, v)]);
        replace(self, b, c, a, &[(c, v)]);
        replace(self, b, a, d, &[(v, d)]);
        replace(self, c, a, b, &[(a, v), (v, b)]);
        replace(self, d, b, a, &[(b, v), (v, a)]);
        self.mesh.wedges[v as usize] = [(a, d), (d, b), (b, c), (c, a)]
            .map(|(f, t)| self.raw_wedge(v, f, t))
            .to_vec();
        self.mesh.stats.inserted += 1;
    }

    /// The triangles at `v`'s nearest neighbours (each as often as it has corners there).
    fn triangles_near<'g>(
        &'g self,
        v: u32,
        graph: &'g KnnGraph,
    ) -> impl Iterator<Item = [u32; 3]> + 'g {
        graph.neighbours(v as usize).iter().flat_map(move |&j| {
            self.mesh.wedges[j as usize]
                .iter()
                .map(move |w| [j, w.from, w.to])
        })
    }

    /// Whether triangle `t` lies over the dense surface (always, when it is not known).
    fn over_dense(&self, [a, b, c]: [u32; 3]) -> bool {
        let p = |i: u32| self.positions[i as usize];
        self.dense.is_none_or(|d| d.covers([p(a), p(b), p(c)]))
    }

    /// Queues the ears across `v`'s gaps that are narrow enough, keyed by their angle.
    fn queue_gaps(&self, v: u32, queue: &mut BinaryHeap<Reverse<(u32, u32, u32, u32)>>) {
        let gaps: Vec<(u32, u32)> = self.mesh.gaps(v as usize).collect();
        for (u, x) in gaps {
            if let Some(w) = self.wedge(v, u, x) {
                queue.push(Reverse((w.sweep.to_bits(), v, u, x)));
            }
        }
    }

    /// Step 3 (run before closing and between its strict and relaxed ears, while every sector
    /// is still sorted by angle): a point with no triangle splits a triangle at one of its
    /// nearest neighbours that it projects into.
    fn insert_stragglers(&mut self, graph: &KnnGraph) {
        for v in 0..graph.len() as u32 {
            if !self.mesh.wedges[v as usize].is_empty() {
                continue;
            }
            let near: Vec<[u32; 3]> = self.triangles_near(v, graph).collect();
            for t @ [a, b, c] in near {
                if !self.mesh.has_wedge(a as usize, b, c) {
                    continue; // split already
                }
                self.remove(t);
                let mut added = Vec::new();
                for part in [[a, b, v], [b, c, v], [c, a, v]] {
                    if !self.try_add(part) {
                        break;
                    }
                    added.push(part);
                }
                if added.len() == 3 {
                    self.mesh.stats.inserted += 1;
                    break;
                }
                // Undo: drop what was added, put the triangle back.
                for part in added {
                    self.remove(part);
                }
                let restored = self.try_add(t);
                debug_assert!(restored, "a removed triangle fits again");
            }
        }
    }
}

/// Moves the distinct values of the sorted `values` to its front; returns how many there are.
fn partition_dedup(values: &mut [u32]) -> usize {
    let mut len = 0;
    for i in 0..values.len() {
        if i == 0 || values[i] != values[len - 1] {
            values[len] = values[i];
            len += 1;
        }
    }
    len
}

/// The centroid of a triangle and the distance from it to the farthest corner.
fn bounding_sphere(tri: [Vec3; 3]) -> (Vec3, f32) {
    let centre = (tri[0] + tri[1] + tri[2]) / 3.0;
    let radius = tri
        .iter()
        .map(|&q| q.distance_squared(centre))
        .fold(0.0, f32::max);
    (centre, radius.sqrt())
}

/// A triangle's plane, for the overlap test between triangles that share no corner.
#[derive(Clone, Copy)]
struct Plane {
    origin: Vec3,
    normal: Vec3,
    frame: (Vec3, Vec3),
    /// The triangle's longest edge.
    size: f32,
}

impl Plane {
    fn of([a, b, c]: [Vec3; 3]) -> Option<Self> {
        let normal = (b - a).cross(c - a).try_normalize()?;
        Some(Self {
            origin: (a + b + c) / 3.0,
            normal,
            frame: normal.any_orthonormal_pair(),
            size: a.distance(b).max(b.distance(c)).max(c.distance(a)),
        })
    }

    /// Whether the centroid of `tri` lies within half this triangle's size of its plane.
    fn near(&self, tri: [Vec3; 3]) -> bool {
        let centroid = (tri[0] + tri[1] + tri[2]) / 3.0;
        (centroid - self.origin).dot(self.normal).abs() < 0.5 * self.size
    }

    /// Whether `own` (this plane's triangle) and `other`, projected on this plane, overlap by
    /// more than a sliver (a separating-axis test: no edge direction of either separates them).
    fn overlap(&self, own: [Vec3; 3], other: [Vec3; 3]) -> bool {
        let flat = |q: Vec3| {
            let d = q - self.origin;
            glam::Vec2::new(d.dot(self.frame.0), d.dot(self.frame.1))
        };
        let (s, o) = (own.map(flat), other.map(flat));
        let margin = OVERLAP_MARGIN * self.size;
        for tri in [s, o] {
            for i in 0..3 {
                let e = tri[(i + 1) % 3] - tri[i];
                let axis = glam::Vec2::new(-e.y, e.x).normalize_or_zero();
                let range = |t: [glam::Vec2; 3]| {
                    t.iter().fold((f32::MAX, f32::MIN), |(lo, hi), q| {
                        let x = q.dot(axis);
                        (lo.min(x), hi.max(x))
                    })
                };
                let (a, b) = (range(s), range(o));
                if a.1 <= b.0 + margin || b.1 <= a.0 + margin {
                    return false;
                }
            }
        }
        true
    }
}

/// Overlap between triangles sharing no corner below this fraction of a triangle's size
/// (longest edge) is touching, not overlapping: on noisy scans, smaller overlaps are the noise
/// of the points along the normal seen in projection (a tenth closes 45 more loops over the
/// benchmark clouds than a thousandth, and 10 more than a twentieth).
pub const OVERLAP_MARGIN: f32 = 0.1;

/// Whether two sectors around the same point overlap (sharing an end is not overlapping).
fn overlaps(a: &Wedge, b: &Wedge) -> bool {
    (b.start - a.start).rem_euclid(TAU) < a.sweep || (a.start - b.start).rem_euclid(TAU) < b.sweep
}
