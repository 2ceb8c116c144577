//! The local Delaunay 1-ring of a point (the paper's §3, Figure 3), shared by simplification
//! and the spring network.
//!
//! A point's k nearest neighbours are projected on its tangent plane, and the point's star in
//! the 2D Delaunay triangulation of the projected set is found directly: the triangles at the
//! point form its region R; their outer vertices, counter-clockwise around the normal, are its
//! ring. When the point lies on the convex hull of the projected set the ring does not close:
//! the point is on the boundary of an open surface.
//!
//! Only the star is needed, not the whole triangulation. Inverting the plane in a circle about
//! the point (q ↦ q / |q|²) maps the circles through it to lines, and the inside of such a
//! circle to the far side of its line; so a triangle (point, a, b) is Delaunay exactly when
//! a*b* is an edge of the convex hull of the point and the inverted neighbours, and the star
//! is that hull, found by a Graham scan of the neighbours sorted by angle (Graham's own scan,
//! about a point inside the hull). Its turn test is the in-circle determinant of the lifted
//! points, with no division. Triangulating the 13 points with [spade] was about a third of
//! §3's CPU time on a 10^6-point sphere; the star is about a tenth (perf), and the k-nearest
//! query is now a ring's largest cost. A test checks the star against spade's triangulation
//! on random neighbourhoods.
//!
//! Three guards the paper does not spell out keep real data well-behaved:
//!
//! * a fan triangle whose angle at the point exceeds [`MAX_FAN_ANGLE`], or whose
//!   circumradius exceeds [`MAX_CIRCUMRADIUS`] local spacings, is a *gap*, not surface: it
//!   spans a hole or runs along a boundary the point sits just inside of (a noisy rim), and
//!   is left out of R like the outside of the hull; a neighbour that only borders gaps is not
//!   in the ring;
//! * a neighbour more than [`MAX_ELEVATION_DEG`] out of the tangent plane is skipped (the far
//!   side of a thin part, the other face at a sharp crease): its projection would land inside
//!   the local surface;
//! * a neighbour at the point's own position (relative distance below [`COINCIDENT_REL`]) is
//!   skipped and reported, so duplicates can be removed first.
//!
//! [spade]: https://crates.io/crates/spade

use glam::{DVec2, DVec3, Vec3};

use crate::core::cloud::knn::SPACING_NEIGHBOURS;

/// A fan triangle with a wider angle than this at the centre (150°) is a gap in the surface.
pub const MAX_FAN_ANGLE: f64 = 5.0 * std::f64::consts::PI / 6.0;

/// A fan triangle whose circumradius exceeds this many local spacings spans a hole (an
/// alpha-shape test): its far side is across the hole, not on the surface.
pub const MAX_CIRCUMRADIUS: f32 = 1.5;

/// Neighbours further out of the tangent plane than this (degrees) are not projected.
pub const MAX_ELEVATION_DEG: f32 = 60.0;

/// Two points closer than this fraction of the neighbourhood size coincide.
pub const COINCIDENT_REL: f32 = 1.0e-6;

/// A lifted in-circle determinant smaller than this fraction of the sum of its terms' sizes
/// is a tie (four points on one circle): f64 rounds the determinant of exact f32 offsets to
/// about 10^-15 of that sum. The points of a regular grid stored in f32 are off their common
/// circles by about 10^-6 of the spacing, far above this; they are decided by their
/// positions, the same way in every ring of a flat cloud, as the offsets are exact.
pub const TIE_REL: f64 = 1.0e-12;

/// Marks the centre in the star's hull scan (an index no neighbour has).
const CENTRE: u32 = u32::MAX;

/// The shape of a point's region R.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RingShape {
    /// Diameter of R in the tangent plane (same units as the positions). Infinite when the
    /// ring is degenerate.
    pub diameter: f32,
    /// Area of R in the tangent plane.
    pub area: f32,
    /// The ring does not close: the point is on a boundary.
    pub open: bool,
    /// A neighbour coincides with the point.
    pub coincident: bool,
    /// No triangle at the point (its projected neighbourhood is collinear or empty).
    pub degenerate: bool,
    /// The projected neighbours surround the point: no angular gap between consecutive ones
    /// reaches [`MAX_FAN_ANGLE`]. A point on a boundary is not surrounded; a point whose ring
    /// is open only by the circumradius guard (a density jump, not an edge) is.
    pub surrounded: bool,
}

/// The centre's share of the area of its ring's surface triangles, measured at the points'
/// 3D positions: its mixed Voronoi area (Meyer, Desbrun, Schröder and Barr 2003), the part
/// of each triangle nearer the centre than its other corners (a quarter or a half of an
/// obtuse triangle). Over a consistent mesh the shares add up to its area exactly, and where
/// four points lie on a circle the share is the same whichever diagonal a ring took, so
/// neighbouring rings that chose differently still add up (a third of each triangle would
/// count such a quad up to twice: +30 % on CGAL's latitude–longitude `sphere926.pwn`).
/// `ring` as [`RingBuilder::build`] writes it, its slots indexing `neighbours`.
pub fn ring_voronoi_area(centre: Vec3, neighbours: &[Vec3], ring: &[(u32, bool)]) -> f32 {
    let n = ring.len();
    let p = centre.as_dvec3();
    let area: f64 = (0..n)
        .filter(|&r| ring[r].1)
        .map(|r| {
            let q = neighbours[ring[r].0 as usize].as_dvec3();
            let s = neighbours[ring[(r + 1) % n].0 as usize].as_dvec3();
            voronoi_share(p, q, s)
        })
        .sum();
    if area.is_finite() { area as f32 } else { 0.0 }
}

/// The part of triangle (p, q, r) nearer p than q and r, or a half (obtuse at p) or a
/// quarter (obtuse elsewhere) of it.
fn voronoi_share(p: DVec3, q: DVec3, r: DVec3) -> f64 {
    let twice_area = (q - p).cross(r - p).length();
    if twice_area <= 0.0 {
        return 0.0;
    }
    let at_p = (q - p).dot(r - p);
    let at_q = (p - q).dot(r - q);
    let at_r = (p - r).dot(q - r);
    if at_p < 0.0 {
        twice_area / 4.0
    } else if at_q < 0.0 || at_r < 0.0 {
        twice_area / 8.0
    } else {
        // (|pr|² cot q + |pq|² cot r) / 8, with cot = dot / (2·area).
        ((r - p).length_squared() * at_q + (q - p).length_squared() * at_r) / (8.0 * twice_area)
    }
}

/// Whether point `i` coincides with one of a lower index among its `neighbours` (nearest
/// first; coincidence relative to the farthest one, as the ring builder takes it).
pub(crate) fn twin_before(i: usize, neighbours: &[u32], positions: &[Vec3]) -> bool {
    let p = positions[i];
    let reach2 = neighbours
        .iter()
        .map(|&j| positions[j as usize].distance_squared(p))
        .fold(0.0f32, f32::max);
    let coincident2 = COINCIDENT_REL * COINCIDENT_REL * reach2;
    neighbours
        .iter()
        .any(|&j| (j as usize) < i && positions[j as usize].distance_squared(p) <= coincident2)
}

/// Reusable scratch space for [`RingBuilder::build`] (one per thread).
pub struct RingBuilder {
    /// Projected neighbours kept so far, as (slot, position, id); sorted by angle once the
    /// star is found.
    kept: Vec<(u32, DVec2, u32)>,
    /// The centre's id (see [`RingBuilder::build`]).
    centre_id: u32,
    /// The star's hull scan: indices into `kept`, or [`CENTRE`].
    hull: Vec<u32>,
    /// Ring slots in CCW order, their projected positions, and whether the face after each is
    /// surface (not a gap).
    fan: Vec<(u32, DVec2, bool)>,
    /// Vertices of R (for the diameter).
    region: Vec<DVec2>,
}

impl Default for RingBuilder {
    fn default() -> Self {
        Self::new()
    }
}

impl std::fmt::Debug for RingBuilder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RingBuilder").finish_non_exhaustive()
    }
}

impl RingBuilder {
    /// Empty scratch space.
    pub fn new() -> Self {
        Self {
            kept: Vec::new(),
            centre_id: 0,
            hull: Vec::new(),
            fan: Vec::new(),
            region: Vec::new(),
        }
    }

    /// The ring of the point at `centre` with unit `normal`, from its `neighbours` (nearest
    /// first, the point itself excluded). When `ring` is given it receives the ring as indices
    /// into `neighbours`, counter-clockwise around `normal`, starting after the widest gap
    /// when the ring is open, each with whether the triangle between it and the next ring
    /// vertex is surface.
    ///
    /// `ids` names the centre and each neighbour (`ids.1[i]` for `neighbours[i]`) with an
    /// index unique in the cloud: where four points lie on one circle (a regular grid) every
    /// ring that holds them takes the same diagonal, chosen by these indices (see
    /// [`TIE_REL`]). A neighbour past the end of `ids.1` ranks after every named point.
    pub fn build(
        &mut self,
        centre: Vec3,
        normal: Vec3,
        neighbours: &[Vec3],
        ids: (u32, &[u32]),
        ring: Option<&mut Vec<(u32, bool)>>,
    ) -> RingShape {
        self.centre_id = ids.0;
        let mut shape = RingShape {
            diameter: f32::INFINITY,
            degenerate: true,
            ..RingShape::default()
        };
        if let Some(r) = &ring {
            debug_assert!(r.is_empty());
        }
        let scale = neighbours
            .iter()
            .map(|p| p.distance_squared(centre))
            .fold(0.0f32, f32::max)
            .sqrt();
        if !(scale > 0.0 && scale.is_finite() && normal.is_finite()) {
            shape.coincident = !neighbours.is_empty() && scale == 0.0;
            return shape;
        }
        shape.coincident = self.project(centre, normal, neighbours, ids.1, scale);
        if self.kept.len() < 2 {
            return shape;
        }
        self.sort_by_angle();
        shape.surrounded = self.surrounds();
        // Local spacing: the mean distance to the nearest few neighbours.
        let near = neighbours.len().min(SPACING_NEIGHBOURS);
        let spacing = neighbours[..near]
            .iter()
            .map(|p| p.distance(centre))
            .sum::<f32>()
            / near as f32;
        let on_hull = self.star();
        self.collect_fan(
            on_hull,
            f64::from(MAX_CIRCUMRADIUS * spacing) / f64::from(scale),
        );
        let n = self.fan.len();
        let surface_faces = self.fan.iter().filter(|f| f.2).count();
        if surface_faces == 0 {
            return shape;
        }
        shape.degenerate = false;
        shape.open = surface_faces < n;
        let (area, d2) = self.measure_region(shape.open);
        let s = f64::from(scale);
        shape.diameter = (d2.sqrt() * s) as f32;
        shape.area = (area * s * s) as f32;
        if let Some(ring) = ring {
            self.write_ring(shape.open, ring);
        }
        shape
    }

    /// Projects the `neighbours` onto the tangent plane at `centre` (scaled by `scale`) into
    /// `self.kept`, skipping those too steep above or below it and repeats. Returns whether
    /// one coincides with the centre.
    ///
    /// The offsets from the centre are taken in f64, where the difference of two f32
    /// positions is exact: every ring of a flat cloud then sees its points where the others
    /// see them, and decides a near-tie the same way.
    fn project(
        &mut self,
        centre: Vec3,
        normal: Vec3,
        neighbours: &[Vec3],
        ids: &[u32],
        scale: f32,
    ) -> bool {
        let mut coincident = false;
        let (t1, t2) = normal.any_orthonormal_pair();
        let (t1, t2, n) = (t1.as_dvec3(), t2.as_dvec3(), normal.as_dvec3());
        let max_elevation = f64::from(MAX_ELEVATION_DEG).to_radians().tan();
        let coincident2 = f64::from(COINCIDENT_REL * scale).powi(2);
        let (c, inv_scale) = (centre.as_dvec3(), 1.0 / f64::from(scale));
        self.kept.clear();
        for (slot, p) in neighbours.iter().enumerate() {
            let v = p.as_dvec3() - c;
            if v.length_squared() <= coincident2 {
                coincident = true;
                continue;
            }
            let (x, y) = (v.dot(t1), v.dot(t2));
            let tangential = (x * x + y * y).sqrt();
            if v.dot(n).abs() > max_elevation * tangential {
                continue;
            }
            let q = DVec2::new(x, y) * inv_scale;
            if self.kept.iter().any(|k| k.1 == q) {
                continue;
            }
            let id = ids.get(slot).copied().unwrap_or(u32::MAX);
            self.kept.push((slot as u32, q, id));
        }
        coincident
    }

    /// The area of the region R the fan's surface faces cover, and its squared diameter
    /// (an `open` region's: the disc it would span), both in scaled coordinates.
    fn measure_region(&mut self, open: bool) -> (f64, f64) {
        let n = self.fan.len();
        // Area and vertices of R.
        let mut area = 0.0f64;
        self.region.clear();
        self.region.push(DVec2::ZERO);
        for r in 0..n {
            let (_, pa, surface) = self.fan[r];
            let pb = self.fan[(r + 1) % n].1;
            let prev_surface = self.fan[(r + n - 1) % n].2;
            if surface || prev_surface {
                self.region.push(pa);
            }
            if surface {
                area += 0.5 * pa.perp_dot(pb);
            }
        }
        let mut d2 = 0.0f64;
        if open {
            // An open region is a part of the disc it would span if the surface went on: its
            // diameter is that disc's (twice its reach), so corners and rims rank like the
            // interior instead of going first.
            for a in &self.region {
                d2 = d2.max(4.0 * a.length_squared());
            }
        } else {
            for (i, a) in self.region.iter().enumerate() {
                for b in &self.region[i + 1..] {
                    d2 = d2.max(a.distance_squared(*b));
                }
            }
        }
        (area, d2)
    }

    /// The ring as indices into the neighbours, counter-clockwise, each with whether the
    /// face after it is surface.
    fn write_ring(&self, open: bool, ring: &mut Vec<(u32, bool)>) {
        let n = self.fan.len();
        // Start after the widest gap (any start for a closed ring).
        let start = if open {
            let widest = (0..n)
                .filter(|&r| !self.fan[r].2)
                .max_by(|&r, &q| {
                    let gap = |r: usize| fan_angle(self.fan[r].1, self.fan[(r + 1) % n].1);
                    gap(r).total_cmp(&gap(q)).then(q.cmp(&r))
                })
                .unwrap_or(0);
            (widest + 1) % n
        } else {
            0
        };
        // Vertices that only border gaps are not neighbours on the surface.
        ring.extend(
            (0..n)
                .map(|r| (start + r) % n)
                .filter(|&r| self.fan[r].2 || self.fan[(r + n - 1) % n].2)
                .map(|r| (self.fan[r].0, self.fan[r].2)),
        );
    }

    /// Sorts `self.kept` counter-clockwise by angle (from the +x axis), the farther of two
    /// in one direction first.
    fn sort_by_angle(&mut self) {
        self.kept.sort_unstable_by(|&(i, a, _), &(j, b, _)| {
            pseudo_angle(a)
                .total_cmp(&pseudo_angle(b))
                .then(b.length_squared().total_cmp(&a.length_squared()))
                .then(i.cmp(&j))
        });
    }

    /// Whether the kept projected neighbours (sorted by angle) leave no angular gap of
    /// [`MAX_FAN_ANGLE`] or more around the centre.
    fn surrounds(&self) -> bool {
        let m = self.kept.len();
        m > 1 && (0..m).all(|r| !wide_gap(self.kept[r].1, self.kept[(r + 1) % m].1))
    }

    /// The centre's star: its Delaunay neighbours among `self.kept` (sorted by angle) into
    /// `self.hull`, counter-clockwise, as the convex hull of the centre and the inverted
    /// neighbours. When the centre is on that hull (an angular gap of π or more: it is on the
    /// convex hull of its neighbourhood) the scan starts with the centre, runs from the first
    /// neighbour after the gap, and ends on the centre again, which is then dropped; the last
    /// neighbour's face is the outside. Returns whether the centre is on the hull.
    fn star(&mut self) -> bool {
        let m = self.kept.len();
        self.hull.clear();
        let at = |r: usize| self.kept[r % m].1;
        // An angular gap of π or more (at most one, unless every point is on one line).
        let gap = (0..m).find(|&r| {
            let (a, b) = (at(r), at(r + 1));
            let cross = a.perp_dot(b);
            cross < 0.0 || (cross == 0.0 && a.dot(b) < 0.0) || m == 1
        });
        let (start, open) = match gap {
            Some(r) => ((r + 1) % m, true),
            // The nearest neighbour is the farthest inverted point: surely on the hull.
            None => {
                let nearest = (0..m)
                    .min_by(|&r, &q| at(r).length_squared().total_cmp(&at(q).length_squared()))
                    .unwrap_or(0);
                (nearest, false)
            }
        };
        if open {
            self.hull.push(CENTRE);
        }
        for r in 0..m {
            self.push_hull(((start + r) % m) as u32);
        }
        // Close the hull on its first vertex.
        let first = self.hull[0];
        while self.hull.len() >= 3 && !self.left_turn(first) {
            self.hull.pop();
        }
        if open {
            self.hull.remove(0);
        }
        open
    }

    /// Pushes `c` on the hull scan, first dropping the vertices it makes a right turn or a
    /// straight line after.
    fn push_hull(&mut self, c: u32) {
        while self.hull.len() >= 2 && !self.left_turn(c) {
            self.hull.pop();
        }
        self.hull.push(c);
    }

    /// Whether the last two vertices of the hull scan and `c` turn left, in the inverted
    /// plane: the sign of the lifted in-circle determinant for three neighbours, of a cross
    /// product when one of them is the centre.
    fn left_turn(&self, c: u32) -> bool {
        let h = self.hull.len();
        let (a, b) = (self.hull[h - 2], self.hull[h - 1]);
        let pos = |i: u32| self.kept[i as usize].1;
        if a == CENTRE {
            pos(b).perp_dot(pos(c)) > 0.0
        } else if b == CENTRE {
            pos(c).perp_dot(pos(a)) > 0.0
        } else if c == CENTRE {
            pos(a).perp_dot(pos(b)) > 0.0
        } else {
            let id = |i: u32| self.kept[i as usize].2;
            in_circle_outside(
                (pos(a), id(a)),
                (pos(b), id(b)),
                (pos(c), id(c)),
                self.centre_id,
            )
        }
    }

    /// Fills `self.fan` from the star (`self.hull`): the centre's neighbours in CCW order,
    /// each with whether the face between it and the next one is surface. `on_hull`: the
    /// centre is on the hull of its neighbourhood, and the last neighbour's face is the
    /// outside. `max_circumradius` is in the scaled (projected) units.
    fn collect_fan(&mut self, on_hull: bool, max_circumradius: f64) {
        self.fan.clear();
        let n = self.hull.len();
        for r in 0..n {
            let (slot, a, _) = self.kept[self.hull[r] as usize];
            let b = self.kept[self.hull[(r + 1) % n] as usize].1;
            let outside = n < 2 || (on_hull && r == n - 1);
            // The face (centre, a, b): a proper counter-clockwise triangle (an angle in (0, π)
            // at the centre, so at most MAX_FAN_ANGLE when its cosine is at least that
            // angle's), not the outside.
            let surface = !outside
                && a.perp_dot(b) > 0.0
                && a.dot(b) >= MAX_FAN_ANGLE.cos() * (a.length() * b.length())
                && circumradius(a, b) <= max_circumradius;
            self.fan.push((slot, a, surface));
        }
    }
}

/// Whether the counter-clockwise angle from `a` to `b` about the origin is
/// [`MAX_FAN_ANGLE`] or more.
fn wide_gap(a: DVec2, b: DVec2) -> bool {
    let cross = a.perp_dot(b);
    if cross < 0.0 {
        return true;
    }
    let cos = a.dot(b) / (a.length() * b.length());
    if cross == 0.0 {
        return cos < 0.0;
    }
    cos <= MAX_FAN_ANGLE.cos()
}

/// A number that grows with the counter-clockwise angle of `v` from the +x axis, in [0, 4)
/// (the "diamond angle": no trigonometry).
fn pseudo_angle(v: DVec2) -> f64 {
    let t = v.x.abs() + v.y.abs();
    if t == 0.0 {
        return 0.0;
    }
    let p = v.y / t;
    if v.x >= 0.0 {
        if v.y >= 0.0 { p } else { 4.0 + p }
    } else {
        2.0 - p
    }
}

/// The orientation of the inverted points a*, b*, c* (q* = q / |q|²) times |a|²|b|²|c|²:
/// the determinant of the points lifted to the paraboloid, positive when the circle through
/// the origin, `a` and `b` does not hold `c` (for `a`, `b` counter-clockwise about the
/// origin).
fn lifted_orientation(a: DVec2, b: DVec2, c: DVec2) -> f64 {
    let (la, lb, lc) = (a.length_squared(), b.length_squared(), c.length_squared());
    a.x * (b.y * lc - lb * c.y) - a.y * (b.x * lc - lb * c.x) + la * (b.x * c.y - b.y * c.x)
}

/// Whether the circle through the origin (the centre, named `centre_id`), `a` and `b` leaves
/// `c` outside ([`lifted_orientation`] > 0), each point given with its id.
///
/// Where the four points lie on one circle (the determinant within [`TIE_REL`] of its terms)
/// the tie is broken by simulation of simplicity (Edelsbrunner and Mücke 1990): each point's
/// lifted height is raised by an infinitesimal that is larger the smaller its id, and the sign
/// is that of the determinant's derivative for the point with the smallest id, the first
/// whose cofactor is not zero. The four points and their ids are the same in every ring that
/// holds them, so every such ring takes the same diagonal of the quadrilateral; a strict test
/// alone drops the vertex shared by the two triangles, and the rings of a square grid then
/// disagree on every cell's diagonal.
fn in_circle_outside(a: (DVec2, u32), b: (DVec2, u32), c: (DVec2, u32), centre_id: u32) -> bool {
    let ((a, ia), (b, ib), (c, ic)) = (a, b, c);
    let (la, lb, lc) = (a.length_squared(), b.length_squared(), c.length_squared());
    let det = lifted_orientation(a, b, c);
    // The neighbours are scaled into the unit disc, where the terms add up to at most 6.
    if det.abs() > TIE_REL * 6.0 {
        return det > 0.0;
    }
    let terms = a.x.abs() * (b.y.abs() * lc + lb * c.y.abs())
        + a.y.abs() * (b.x.abs() * lc + lb * c.x.abs())
        + la * (b.x * c.y).abs()
        + la * (b.y * c.x).abs();
    if det.abs() > TIE_REL * terms {
        return det > 0.0;
    }
    // d det / d (lift): a → b × c, b → c × a, c → a × b, the centre (origin) → −orient(a, b, c).
    let (bc, ca, ab) = (b.perp_dot(c), c.perp_dot(a), a.perp_dot(b));
    let mut by_id = [(ia, bc), (ib, ca), (ic, ab), (centre_id, -(ab + bc + ca))];
    by_id.sort_unstable_by_key(|&(id, _)| id);
    by_id
        .iter()
        .find(|&&(_, d)| d != 0.0)
        .is_some_and(|&(_, d)| d > 0.0)
}

/// Circumradius of the triangle (origin, `a`, `b`); infinite when degenerate.
fn circumradius(a: DVec2, b: DVec2) -> f64 {
    let twice_area = a.perp_dot(b).abs();
    if twice_area == 0.0 {
        return f64::INFINITY;
    }
    a.length() * b.length() * (a - b).length() / (2.0 * twice_area)
}

/// The angle at the origin from `a` to `b`, counter-clockwise, in [0, 2π).
fn fan_angle(a: DVec2, b: DVec2) -> f64 {
    let angle = a.perp_dot(b).atan2(a.dot(b));
    if angle < 0.0 {
        angle + std::f64::consts::TAU
    } else {
        angle
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    impl RingBuilder {
        /// [`RingBuilder::build`] with the neighbours named by their slots and the centre
        /// after them.
        fn build_local(
            &mut self,
            centre: Vec3,
            normal: Vec3,
            neighbours: &[Vec3],
            ring: Option<&mut Vec<(u32, bool)>>,
        ) -> RingShape {
            let ids: Vec<u32> = (0..neighbours.len() as u32).collect();
            self.build(centre, normal, neighbours, (ids.len() as u32, &ids), ring)
        }
    }

    fn hexagon(r: f32) -> Vec<Vec3> {
        (0..6)
            .map(|i| {
                let a = i as f32 * std::f32::consts::FRAC_PI_3;
                Vec3::new(r * a.cos(), r * a.sin(), 0.0)
            })
            .collect()
    }

    #[test]
    fn hexagon_ring_is_closed_and_ccw() {
        let mut b = RingBuilder::new();
        let mut ring = Vec::new();
        let s = b.build_local(Vec3::ZERO, Vec3::Z, &hexagon(1.0), Some(&mut ring));
        assert!(!s.open && !s.degenerate && !s.coincident);
        assert!((s.diameter - 2.0).abs() < 1e-5, "{}", s.diameter);
        let hex_area = 1.5 * 3f32.sqrt();
        assert!((s.area - hex_area).abs() < 1e-5, "{}", s.area);
        assert_eq!(ring.len(), 6);
        assert!(ring.iter().all(|&(_, face)| face));
        let ring: Vec<u32> = ring.iter().map(|&(slot, _)| slot).collect();
        // CCW around +Z: consecutive slots increase by one (mod 6).
        for w in 0..6 {
            assert_eq!((ring[w] + 1) % 6, ring[(w + 1) % 6]);
        }
        // Seen from -Z the order reverses.
        let mut rev = Vec::new();
        b.build_local(Vec3::ZERO, -Vec3::Z, &hexagon(1.0), Some(&mut rev));
        let rev: Vec<u32> = rev.iter().map(|&(slot, _)| slot).collect();
        for w in 0..6 {
            assert_eq!((rev[(w + 1) % 6] + 1) % 6, rev[w]);
        }
    }

    #[test]
    fn half_disc_is_open_and_starts_after_the_gap() {
        // Centre on the straight edge of a half disc.
        let pts: Vec<Vec3> = (0..5)
            .map(|i| {
                let a = i as f32 * std::f32::consts::FRAC_PI_4;
                Vec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect();
        let mut ring = Vec::new();
        let s = RingBuilder::new().build_local(Vec3::ZERO, Vec3::Z, &pts, Some(&mut ring));
        assert!(s.open && !s.degenerate);
        let slots: Vec<u32> = ring.iter().map(|&(slot, _)| slot).collect();
        assert_eq!(slots, vec![0, 1, 2, 3, 4]);
        assert!(!ring[4].1 && ring[..4].iter().all(|&(_, face)| face));
        assert!((s.diameter - 2.0).abs() < 1e-5);
    }

    #[test]
    fn centre_just_inside_a_straight_boundary_is_open() {
        // The centre sits a hair above the line through its two side neighbours: the hull
        // closes with a sliver of almost 180°, which is a gap, not surface.
        let mut pts = vec![Vec3::new(1.0, -0.01, 0.0), Vec3::new(-1.0, -0.01, 0.0)];
        pts.extend((1..4).map(|i| {
            let a = i as f32 * std::f32::consts::FRAC_PI_4;
            Vec3::new(a.cos(), a.sin(), 0.0)
        }));
        let s = RingBuilder::new().build_local(Vec3::ZERO, Vec3::Z, &pts, None);
        assert!(s.open);
        assert!(s.area < std::f32::consts::FRAC_PI_2 + 0.1);
    }

    #[test]
    fn degenerate_and_coincident_neighbourhoods() {
        let mut b = RingBuilder::new();
        let line: Vec<Vec3> = (1..6).map(|i| Vec3::X * i as f32).collect();
        let s = b.build_local(Vec3::ZERO, Vec3::Z, &line, None);
        assert!(s.degenerate && s.diameter.is_infinite());
        let mut with_dup = hexagon(1.0);
        with_dup.push(Vec3::ZERO);
        let s = b.build_local(Vec3::ZERO, Vec3::Z, &with_dup, None);
        assert!(s.coincident && !s.degenerate);
        let all_same = vec![Vec3::ONE; 4];
        let s = b.build_local(Vec3::ONE, Vec3::Z, &all_same, None);
        assert!(s.coincident && s.degenerate);
        let s = b.build_local(Vec3::ZERO, Vec3::Z, &[], None);
        assert!(s.degenerate && !s.coincident);
        // Too few ids: no panic, and where nothing ties the ring is the same.
        let hex = hexagon(1.0);
        let named = b.build_local(Vec3::ZERO, Vec3::Z, &hex, None);
        let unnamed = b.build(Vec3::ZERO, Vec3::Z, &hex, (0, &[]), None);
        assert_eq!(named, unnamed);
    }

    /// The centre's Delaunay neighbours among `neighbours` (in the plane z = 0, the centre
    /// at the origin), by spade's full triangulation: the slots, ascending.
    fn spade_star(neighbours: &[Vec3]) -> Vec<u32> {
        use spade::{DelaunayTriangulation, HasPosition, Point2, Triangulation};
        struct P(Point2<f64>, u32);
        impl HasPosition for P {
            type Scalar = f64;
            fn position(&self) -> Point2<f64> {
                self.0
            }
        }
        let mut tri = DelaunayTriangulation::<P>::new();
        let centre = tri.insert(P(Point2::new(0.0, 0.0), CENTRE)).unwrap();
        for (slot, q) in neighbours.iter().enumerate() {
            let q = Point2::new(f64::from(q.x), f64::from(q.y));
            tri.insert(P(q, slot as u32)).unwrap();
        }
        let mut star: Vec<u32> = tri
            .vertex(centre)
            .out_edges()
            .map(|e| e.to().data().1)
            .collect();
        star.sort_unstable();
        star
    }

    proptest::proptest! {
        /// The star by inversion and a hull scan is the star of spade's triangulation, for
        /// neighbourhoods all around the centre and on one side of it (a boundary point).
        #[test]
        fn the_star_is_the_delaunay_triangulations(
            points in proptest::collection::vec((0.05f32..1.0, 0.0f32..1.0), 3..20),
            half in proptest::bool::ANY,
        ) {
            let span = if half { std::f32::consts::PI } else { std::f32::consts::TAU };
            let neighbours: Vec<Vec3> = points
                .iter()
                .map(|&(r, t)| Vec3::new(r * (t * span).cos(), r * (t * span).sin(), 0.0))
                .collect();
            let mut b = RingBuilder::new();
            let shape = b.build_local(Vec3::ZERO, Vec3::Z, &neighbours, None);
            let mut star: Vec<u32> = b.hull.iter().map(|&h| b.kept[h as usize].0).collect();
            star.sort_unstable();
            proptest::prop_assert_eq!(star, spade_star(&neighbours));
            if half {
                proptest::prop_assert!(shape.open || shape.degenerate);
            }
        }
    }

    /// The faces of every ring of an `n` × `n` grid of spacing `h` in the plane through
    /// `origin` spanned by `u` and `v` (unit normal `normal`), each as its sorted corners, for
    /// the points at least two rows from the edge; the neighbours are the k = 12 nearest by
    /// distance, then index.
    fn grid_faces(n: usize, h: f32, origin: Vec3, (u, v): (Vec3, Vec3)) -> Vec<Vec<[u32; 3]>> {
        let normal = u.cross(v).normalize();
        let points: Vec<Vec3> = (0..n * n)
            .map(|i| origin + h * ((i % n) as f32 * u + (i / n) as f32 * v))
            .collect();
        let mut b = RingBuilder::new();
        (0..points.len())
            .map(|i| {
                let (x, y) = (i % n, i / n);
                if x < 2 || y < 2 || x + 2 >= n || y + 2 >= n {
                    return Vec::new();
                }
                let mut near: Vec<u32> = (0..points.len() as u32)
                    .filter(|&j| j as usize != i)
                    .collect();
                near.sort_by(|&a, &c| {
                    let d = |j: u32| points[j as usize].distance_squared(points[i]);
                    d(a).total_cmp(&d(c)).then(a.cmp(&c))
                });
                near.truncate(12);
                let neighbours: Vec<Vec3> = near.iter().map(|&j| points[j as usize]).collect();
                let mut ring = Vec::new();
                let shape = b.build(
                    points[i],
                    normal,
                    &neighbours,
                    (i as u32, &near),
                    Some(&mut ring),
                );
                assert!(!shape.open && !shape.degenerate, "point {i}: {shape:?}");
                (0..ring.len())
                    .filter(|&r| ring[r].1)
                    .map(|r| {
                        let next = ring[(r + 1) % ring.len()].0;
                        let mut face = [i as u32, near[ring[r].0 as usize], near[next as usize]];
                        face.sort_unstable();
                        face
                    })
                    .collect()
            })
            .collect()
    }

    /// Where four neighbours lie on one circle (every cell of a square grid), the rings of all
    /// four take the same diagonal: each face of an inner point's ring is a face of its other
    /// corners' rings. Exactly cocircular (spacing 0.5: the tie is broken by the ids), cocircular
    /// to f32 rounding (0.025 off the origin, like `letter_b.ply`), and in a tilted plane.
    #[test]
    fn the_rings_of_a_grid_agree_on_every_diagonal() {
        let tilted = Vec3::new(1.0, 2.0, 3.0).normalize().any_orthonormal_pair();
        for (h, origin, basis) in [
            (0.5, Vec3::ZERO, (Vec3::X, Vec3::Y)),
            (0.025, Vec3::new(-0.975, -1.0, 0.0), (Vec3::X, Vec3::Y)),
            (0.025, Vec3::new(0.3, -0.7, 0.2), tilted),
        ] {
            let n = 10;
            let faces = grid_faces(n, h, origin, basis);
            let mut checked = 0;
            for (i, ring) in faces.iter().enumerate() {
                for face in ring {
                    for &corner in face.iter().filter(|&&c| c as usize != i) {
                        let theirs = &faces[corner as usize];
                        if theirs.is_empty() {
                            continue;
                        }
                        assert!(
                            theirs.contains(face),
                            "spacing {h}: face {face:?} of point {i} is not in point {corner}'s ring {theirs:?}"
                        );
                        checked += 1;
                    }
                }
            }
            assert!(checked > 200, "{checked}");
        }
    }

    #[test]
    fn steep_neighbours_are_skipped() {
        // A point straight above the centre (the far side of a thin plate) is not projected.
        let mut pts = hexagon(1.0);
        pts.push(Vec3::new(0.1, 0.0, 0.5));
        let mut ring = Vec::new();
        let s = RingBuilder::new().build_local(Vec3::ZERO, Vec3::Z, &pts, Some(&mut ring));
        assert!(!s.open);
        assert!(ring.iter().all(|&(slot, _)| slot != 6));
    }
}
