//! A coarse mesh on the simulation points from a fine one on the dense points: every dense
//! vertex that is not a simulation point is merged into a neighbour (a *half-edge collapse*),
//! shortest edge first, then the coarse triangles are flipped towards Delaunay.
//!
//! A collapse keeps the surface's topology when the edge passes the link condition (the two
//! ends share exactly the neighbours of the triangles on the edge) and a boundary vertex only
//! moves along the boundary, so a closed fine mesh gives a closed coarse one with the same
//! Euler characteristic, and an open one keeps its boundary loops. It is refused where a moved
//! triangle would turn over (its normal more than [`MAX_TURN_COS`] from the old one, or 90° or
//! more from its corners' mean normal) or would repeat a triangle already there; the vertices
//! no collapse can remove are left in the mesh (the network adds them as filling points).
//!
//! This is how [`build_network_over`](super::build_network_over) repairs the holes the coarse
//! rings leave where the dense points' own network has fewer: the rings of the dense points
//! agree where those of the coarse ones, a dozen spacings apart on a thin part, do not.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};

use glam::Vec3;

/// A moved triangle's normal must stay within about 72° of its old one (cosine 0.3).
pub const MAX_TURN_COS: f32 = 0.3;

/// The turn limit for the vertices the first pass left: a moved triangle may turn by up to
/// 90° (it must still face within 90° of its corners' mean normal).
pub const RELAXED_TURN_COS: f32 = 0.0;

/// Two triangles are flipped towards Delaunay only when they face within about 25° of each
/// other (cosine 0.9): flipping across a sharper crease would cut the feature off.
pub const FLIP_MAX_CREASE_COS: f32 = 0.9;

/// Flips tried at most, per edge of the mesh.
const FLIPS_PER_EDGE: usize = 20;

/// Unit vertex normals of a mesh (area-weighted sums of its triangles' normals, so they turn
/// the way the triangles do), when the `triangles` make an oriented manifold surface over
/// `positions`: each directed edge in one triangle at most, each undirected edge in two at
/// most, and every triangle with some area. `None` otherwise, or when there are none.
pub(crate) fn manifold_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> Option<Vec<Vec3>> {
    if triangles.is_empty() {
        return None;
    }
    let mut directed: Vec<(u32, u32)> = triangles.iter().flat_map(|&t| edges(t)).collect();
    directed.sort_unstable();
    if directed.windows(2).any(|w| w[0] == w[1]) {
        return None; // an edge used twice the same way: not oriented, or not a manifold
    }
    let flat = triangles.iter().any(|t| {
        let [a, b, c] = t.map(|v| positions[v as usize]);
        let normal = (b - a).cross(c - a);
        normal.length_squared() <= 0.0 || !normal.is_finite()
    });
    if flat {
        return None;
    }
    let (sums, _) = crate::core::normals::face_normal_sums(positions, triangles);
    Some(sums.into_iter().map(Vec3::normalize_or_zero).collect())
}

/// What [`collapse_onto`] left.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Collapsed {
    /// The coarse triangles, over the fine mesh's vertex indices, oriented as given.
    pub triangles: Vec<[u32; 3]>,
    /// Vertices not to keep that no collapse could remove, ascending.
    pub left: Vec<u32>,
    /// Delaunay flips made.
    pub flips: usize,
}

/// Collapses the fine mesh (`triangles` over `positions`, each counter-clockwise around the
/// unit `normals`) onto the vertices marked in `keep`, then flips its edges towards Delaunay.
pub(crate) fn collapse_onto(
    positions: &[Vec3],
    normals: &[Vec3],
    triangles: &[[u32; 3]],
    keep: &[bool],
) -> Collapsed {
    let mut mesh = Mesh::new(positions, normals, triangles);
    let n = positions.len();
    // First with the turn limit, then, for the vertices left, with none beyond facing the
    // corners' normals.
    for (turn_cos, winding) in [
        (MAX_TURN_COS, true),
        (RELAXED_TURN_COS, true),
        (RELAXED_TURN_COS, false),
    ] {
        mesh.turn_cos = turn_cos;
        mesh.winding = winding;
        let mut queue: BinaryHeap<Reverse<(u32, u32)>> = BinaryHeap::new();
        let mut scratch = Vec::new();
        let push = |mesh: &Mesh, queue: &mut BinaryHeap<Reverse<(u32, u32)>>, v: u32| {
            if let Some((cost, _)) = mesh.best_target(v) {
                queue.push(Reverse((cost.to_bits(), v)));
            }
        };
        for v in 0..n as u32 {
            if !keep[v as usize]
                && !mesh.removed[v as usize]
                && !mesh.adjacent[v as usize].is_empty()
            {
                push(&mesh, &mut queue, v);
            }
        }
        while let Some(Reverse((bits, v))) = queue.pop() {
            if mesh.removed[v as usize] {
                continue;
            }
            let Some((cost, u)) = mesh.best_target(v) else {
                continue; // retried when its neighbourhood changes
            };
            if cost.to_bits() > bits {
                queue.push(Reverse((cost.to_bits(), v)));
                continue;
            }
            // Only the vertices that were next to `v` have new triangles or a new edge to
            // `u`; the others next to `u` can only lose collapses (`u` gained neighbours).
            let around = std::mem::take(&mut scratch);
            scratch = mesh.collapse(v, u, around);
            for &w in scratch.iter().chain([&u]) {
                if !keep[w as usize] {
                    push(&mesh, &mut queue, w);
                }
            }
        }
    }
    let flips = mesh.flip_to_delaunay();
    let left = (0..n as u32)
        .filter(|&v| !keep[v as usize] && !mesh.removed[v as usize])
        .filter(|&v| !mesh.incident[v as usize].is_empty())
        .collect();
    Collapsed {
        triangles: mesh.alive_triangles(),
        left,
        flips,
    }
}

/// A triangle mesh under collapses: triangles with alive flags, each vertex's triangles and
/// its neighbours (sorted).
struct Mesh<'a> {
    positions: &'a [Vec3],
    normals: &'a [Vec3],
    triangles: Vec<[u32; 3]>,
    alive: Vec<bool>,
    /// Alive triangles at each vertex.
    incident: Vec<Vec<u32>>,
    /// Vertices sharing an alive triangle with each vertex, ascending.
    adjacent: Vec<Vec<u32>>,
    removed: Vec<bool>,
    /// Cosine of the widest turn a moved triangle may make.
    turn_cos: f32,
    /// Whether the fan at the vertex collapsed into must wind once around it.
    winding: bool,
}

impl<'a> Mesh<'a> {
    fn new(positions: &'a [Vec3], normals: &'a [Vec3], triangles: &[[u32; 3]]) -> Self {
        let n = positions.len();
        let mut incident = vec![Vec::new(); n];
        let mut adjacent = vec![Vec::new(); n];
        for (t, &[a, b, c]) in triangles.iter().enumerate() {
            for (v, x, y) in [(a, b, c), (b, c, a), (c, a, b)] {
                incident[v as usize].push(t as u32);
                adjacent[v as usize].extend([x, y]);
            }
        }
        for list in &mut adjacent {
            list.sort_unstable();
            list.dedup();
        }
        Self {
            positions,
            normals,
            triangles: triangles.to_vec(),
            alive: vec![true; triangles.len()],
            incident,
            adjacent,
            removed: vec![false; n],
            turn_cos: MAX_TURN_COS,
            winding: true,
        }
    }

    fn alive_triangles(&self) -> Vec<[u32; 3]> {
        self.triangles
            .iter()
            .zip(&self.alive)
            .filter(|(_, alive)| **alive)
            .map(|(t, _)| *t)
            .collect()
    }

    /// The triangles on edge (v, u), at most three (more make it non-manifold anyway).
    fn on_edge(&self, v: u32, u: u32) -> impl Iterator<Item = u32> + '_ {
        self.incident[v as usize]
            .iter()
            .copied()
            .filter(move |&t| self.triangles[t as usize].contains(&u))
            .take(3)
    }

    /// Whether `v` has an edge with one triangle only.
    fn on_boundary(&self, v: u32) -> bool {
        self.adjacent[v as usize]
            .iter()
            .any(|&u| self.on_edge(v, u).count() == 1)
    }

    fn normal(&self, [a, b, c]: [u32; 3]) -> Vec3 {
        let p = |i: u32| self.positions[i as usize];
        (p(b) - p(a)).cross(p(c) - p(a))
    }

    /// Whether triangle `t` faces within 90° of its corners' mean normal, with some area.
    fn faces_its_corners(&self, t: [u32; 3], scale: f32) -> bool {
        let normal = self.normal(t);
        let mean: Vec3 = t.iter().map(|&i| self.normals[i as usize]).sum();
        normal.length_squared() > 1e-12 * scale * scale * scale * scale
            && normal.normalize().dot(mean.normalize_or_zero()) > 0.0
    }

    /// Whether `t` is already a triangle at `at` (in either orientation).
    fn exists(&self, at: u32, t: [u32; 3]) -> bool {
        let mut key = t;
        key.sort_unstable();
        self.incident[at as usize].iter().any(|&s| {
            let mut other = self.triangles[s as usize];
            other.sort_unstable();
            other == key
        })
    }

    /// The cheapest neighbour `v` may collapse into, with the edge's length.
    fn best_target(&self, v: u32) -> Option<(f32, u32)> {
        let p = self.positions[v as usize];
        let boundary = self.on_boundary(v);
        // Nearest first: the first that may collapse is the one (a test costs the target's
        // whole fan, and a kept point's grows as it absorbs its neighbours).
        let mut by_length: Vec<(f32, u32)> = self.adjacent[v as usize]
            .iter()
            .map(|&u| (p.distance(self.positions[u as usize]), u))
            .collect();
        by_length.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        by_length
            .into_iter()
            .find(|&(_, u)| self.can_collapse(v, u, boundary))
    }

    /// Whether `v` (a boundary vertex when `boundary`) may collapse into `u` (see the
    /// module's notes).
    fn can_collapse(&self, v: u32, u: u32, boundary: bool) -> bool {
        let mut opposite = [u32::MAX; 3];
        let mut shared = 0;
        for t in self.on_edge(v, u) {
            opposite[shared] = third(self.triangles[t as usize], v, u);
            shared += 1;
        }
        if shared == 0 || shared > 2 || (shared == 2 && boundary) {
            return false; // a boundary vertex moves only along the boundary
        }
        let opposite = &mut opposite[..shared];
        opposite.sort_unstable();
        // Link condition: the common neighbours are the opposite corners, no more.
        let (nv, nu) = (&self.adjacent[v as usize], &self.adjacent[u as usize]);
        let (mut i, mut j, mut common) = (0, 0, 0);
        while i < nv.len() && j < nu.len() {
            match nv[i].cmp(&nu[j]) {
                std::cmp::Ordering::Less => i += 1,
                std::cmp::Ordering::Greater => j += 1,
                std::cmp::Ordering::Equal => {
                    if common == shared || opposite[common] != nv[i] {
                        return false;
                    }
                    common += 1;
                    i += 1;
                    j += 1;
                }
            }
        }
        if common != shared {
            return false;
        }
        let scale = self.positions[v as usize].distance(self.positions[u as usize]);
        self.incident[v as usize].iter().all(|&t| {
            let old = self.triangles[t as usize];
            if old.contains(&u) {
                return true;
            }
            // With the link condition, a moved triangle can repeat one at `u` only when it
            // joins the two opposite corners (`v` had three neighbours, as on a tetrahedron).
            let moved = old.map(|w| if w == v { u } else { w });
            let repeats =
                shared == 2 && opposite.iter().all(|o| old.contains(o)) && self.exists(u, moved);
            let (before, after) = (self.normal(old), self.normal(moved));
            !repeats
                && self.faces_its_corners(moved, scale)
                && before.normalize_or_zero().dot(after.normalize()) > self.turn_cos
        }) && (!self.winding || self.fan_winds_once(v, u))
    }

    /// Whether, after `v` collapses into `u`, the triangles at `u` turn counter-clockwise
    /// around `u`'s normal in its tangent plane and wind around it at most once: no two of
    /// them overlap there (which would lay two layers of springs over one part).
    fn fan_winds_once(&self, v: u32, u: u32) -> bool {
        let centre = self.positions[u as usize];
        let normal = self.normals[u as usize];
        let sweep = |[a, b, c]: [u32; 3]| {
            // The corner at u, from the next corner to the one after it.
            let (x, y) = if a == u {
                (b, c)
            } else if b == u {
                (c, a)
            } else {
                (a, b)
            };
            let (dx, dy) = (
                self.positions[x as usize] - centre,
                self.positions[y as usize] - centre,
            );
            let (dx, dy) = (dx - normal * dx.dot(normal), dy - normal * dy.dot(normal));
            normal.dot(dx.cross(dy)).atan2(dx.dot(dy))
        };
        let kept = self.incident[u as usize]
            .iter()
            .map(|&t| self.triangles[t as usize])
            .filter(|t| !t.contains(&v));
        let moved = self.incident[v as usize]
            .iter()
            .map(|&t| self.triangles[t as usize])
            .filter(|t| !t.contains(&u))
            .map(|t| t.map(|w| if w == v { u } else { w }));
        let mut total = 0.0;
        for t in kept.chain(moved) {
            let angle = sweep(t);
            if angle <= 0.0 {
                return false;
            }
            total += angle;
        }
        total <= std::f32::consts::TAU * (1.0 + 1e-3)
    }

    /// Merges `v` into `u`: the triangles on the edge go, the others move their corner.
    /// Returns `v`'s neighbours other than `u`, in `out` (cleared first).
    fn collapse(&mut self, v: u32, u: u32, mut out: Vec<u32>) -> Vec<u32> {
        out.clear();
        for t in std::mem::take(&mut self.incident[v as usize]) {
            let tri = self.triangles[t as usize];
            if tri.contains(&u) {
                self.alive[t as usize] = false;
                for w in tri {
                    self.incident[w as usize].retain(|&s| s != t);
                }
            } else {
                self.triangles[t as usize] = tri.map(|w| if w == v { u } else { w });
                self.incident[u as usize].push(t);
            }
        }
        for w in std::mem::take(&mut self.adjacent[v as usize]) {
            let list = &mut self.adjacent[w as usize];
            list.retain(|&x| x != v);
            if w != u {
                if let Err(at) = list.binary_search(&u) {
                    list.insert(at, u);
                }
                if let Err(at) = self.adjacent[u as usize].binary_search(&w) {
                    self.adjacent[u as usize].insert(at, w);
                }
                out.push(w);
            }
        }
        self.removed[v as usize] = true;
        out
    }

    /// Flips inner edges whose two opposite angles sum to more than π while the two triangles
    /// face within [`FLIP_MAX_CREASE_COS`] of each other; returns the flips made.
    fn flip_to_delaunay(&mut self) -> usize {
        // Directed edge → its triangle.
        let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
        for (t, tri) in self.triangles.iter().enumerate() {
            if self.alive[t] {
                for e in edges(*tri) {
                    directed.insert(e, t as u32);
                }
            }
        }
        let mut stack: Vec<(u32, u32)> = directed.keys().copied().filter(|(a, b)| a < b).collect();
        // The map's order is random per instance: sorted, the flips (and the mesh) are the
        // same on every run.
        stack.sort_unstable();
        let budget = FLIPS_PER_EDGE * stack.len().max(1);
        let mut flips = 0;
        let mut tries = 0;
        while let Some((a, b)) = stack.pop() {
            tries += 1;
            if tries > budget {
                break;
            }
            let (Some(&t1), Some(&t2)) = (directed.get(&(a, b)), directed.get(&(b, a))) else {
                continue;
            };
            let c = third(self.triangles[t1 as usize], a, b);
            let d = third(self.triangles[t2 as usize], a, b);
            if c == d || directed.contains_key(&(c, d)) || directed.contains_key(&(d, c)) {
                continue;
            }
            let p = |i: u32| self.positions[i as usize];
            let angle = |apex: u32| (p(a) - p(apex)).angle_between(p(b) - p(apex));
            if angle(c) + angle(d) <= std::f32::consts::PI + 1e-4 {
                continue;
            }
            let (n1, n2) = (
                self.normal([a, b, c]).normalize_or_zero(),
                self.normal([b, a, d]).normalize_or_zero(),
            );
            if n1.dot(n2) < FLIP_MAX_CREASE_COS {
                continue;
            }
            let (new1, new2) = ([a, d, c], [d, b, c]);
            let scale = p(c).distance(p(d));
            let fits = |t: [u32; 3]| {
                let n = self.normal(t).normalize_or_zero();
                self.faces_its_corners(t, scale) && n.dot(n1) > 0.0 && n.dot(n2) > 0.0
            };
            if !fits(new1) || !fits(new2) {
                continue;
            }
            for (t, tri) in [(t1, [a, b, c]), (t2, [b, a, d])] {
                for e in edges(tri) {
                    directed.remove(&e);
                }
                for &w in &tri {
                    self.incident[w as usize].retain(|&s| s != t);
                }
            }
            for (t, tri) in [(t1, new1), (t2, new2)] {
                self.triangles[t as usize] = tri;
                for e in edges(tri) {
                    directed.insert(e, t);
                }
                for &w in &tri {
                    self.incident[w as usize].push(t);
                }
            }
            stack.extend([(a, d), (d, b), (b, c), (c, a)].map(|(x, y)| (x.min(y), x.max(y))));
            flips += 1;
        }
        flips
    }
}

/// The directed edges of a triangle.
fn edges([a, b, c]: [u32; 3]) -> [(u32, u32); 3] {
    [(a, b), (b, c), (c, a)]
}

/// The corner of `t` that is neither `a` nor `b`.
fn third(t: [u32; 3], a: u32, b: u32) -> u32 {
    t.into_iter().find(|&w| w != a && w != b).unwrap_or(a)
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::collapse_onto;

    /// A closed octahedron-like sphere: a UV sphere with `rings` × `segments` vertices plus
    /// the poles, triangles outward.
    fn uv_sphere(rings: u32, segments: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut p = vec![Vec3::Z, -Vec3::Z];
        for r in 1..=rings {
            let theta = std::f32::consts::PI * r as f32 / (rings + 1) as f32;
            for s in 0..segments {
                let phi = std::f32::consts::TAU * s as f32 / segments as f32;
                p.push(Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                ));
            }
        }
        let at = |r: u32, s: u32| 2 + (r - 1) * segments + s % segments;
        let mut t = Vec::new();
        for s in 0..segments {
            t.push([0, at(1, s), at(1, s + 1)]);
            t.push([1, at(rings, s + 1), at(rings, s)]);
            for r in 1..rings {
                t.push([at(r, s), at(r + 1, s), at(r + 1, s + 1)]);
                t.push([at(r, s), at(r + 1, s + 1), at(r, s + 1)]);
            }
        }
        (p, t)
    }

    /// V − E + F, with the boundary edges.
    fn euler_and_boundary(triangles: &[[u32; 3]]) -> (i64, usize) {
        let mut edges = std::collections::HashMap::new();
        let mut vertices = std::collections::HashSet::new();
        for &[a, b, c] in triangles {
            for (x, y) in [(a, b), (b, c), (c, a)] {
                *edges.entry((x.min(y), x.max(y))).or_insert(0) += 1;
                vertices.insert(x);
            }
        }
        let boundary = edges.values().filter(|&&c| c == 1).count();
        (
            vertices.len() as i64 - edges.len() as i64 + triangles.len() as i64,
            boundary,
        )
    }

    #[test]
    fn a_closed_sphere_stays_closed_on_the_kept_vertices() {
        let (p, t) = uv_sphere(12, 24);
        let n: Vec<Vec3> = p.iter().map(|v| v.normalize()).collect();
        // Keep every fourth vertex (and the poles).
        let keep: Vec<bool> = (0..p.len()).map(|i| i < 2 || i % 4 == 0).collect();
        let out = collapse_onto(&p, &n, &t, &keep);
        assert!(out.left.is_empty(), "left {:?}", out.left);
        assert_eq!(euler_and_boundary(&out.triangles), (2, 0));
        let used: std::collections::HashSet<u32> =
            out.triangles.iter().flatten().copied().collect();
        assert!(used.iter().all(|&v| keep[v as usize]));
        assert_eq!(used.len(), keep.iter().filter(|k| **k).count());
        for &[a, b, c] in &out.triangles {
            let normal = (p[b as usize] - p[a as usize]).cross(p[c as usize] - p[a as usize]);
            assert!(normal.dot(p[a as usize] + p[b as usize] + p[c as usize]) > 0.0);
        }
        assert!(out.flips > 0, "a UV sphere's thinned grid is not Delaunay");
    }

    #[test]
    fn an_open_sheet_keeps_its_boundary_loop() {
        // A 9 × 9 grid in the plane, two triangles per cell, every other row and column kept.
        let m = 9u32;
        let p: Vec<Vec3> = (0..m * m)
            .map(|i| Vec3::new((i % m) as f32, (i / m) as f32, 0.0))
            .collect();
        let n = vec![Vec3::Z; p.len()];
        let mut t = Vec::new();
        for y in 0..m - 1 {
            for x in 0..m - 1 {
                let i = y * m + x;
                t.push([i, i + 1, i + m + 1]);
                t.push([i, i + m + 1, i + m]);
            }
        }
        let keep: Vec<bool> = (0..p.len() as u32)
            .map(|i| (i % m).is_multiple_of(2) && (i / m).is_multiple_of(2))
            .collect();
        let out = collapse_onto(&p, &n, &t, &keep);
        assert!(out.left.is_empty(), "left {:?}", out.left);
        let (euler, boundary) = euler_and_boundary(&out.triangles);
        assert_eq!(euler, 1, "still a disc");
        assert_eq!(boundary, 16, "the 5 × 5 grid's rim");
        assert_eq!(out.triangles.len(), 32);
        let area: f32 = out
            .triangles
            .iter()
            .map(|&[a, b, c]| {
                let q = |i: u32| p[i as usize];
                (q(b) - q(a)).cross(q(c) - q(a)).z * 0.5
            })
            .sum();
        assert!(
            (area - 64.0).abs() < 1e-3,
            "all of the square, facing up: {area}"
        );
    }

    #[test]
    fn a_vertex_whose_removal_would_fold_the_surface_is_left() {
        // A tetrahedron keeps three corners: removing the fourth would lay two triangles on one.
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        let centre = p.iter().copied().sum::<Vec3>() / 4.0;
        let n: Vec<Vec3> = p.iter().map(|v| (*v - centre).normalize()).collect();
        let t = vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
        let out = collapse_onto(&p, &n, &t, &[true, true, true, false]);
        assert_eq!(out.left, vec![3]);
        assert_eq!(out.triangles.len(), 4);
    }
}
