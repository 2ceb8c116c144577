//! The local Delaunay 1-ring of a point (the paper's §3, Figure 3), shared by simplification
//! and the spring network.
//!
//! A point's k nearest neighbours are projected on its tangent plane and triangulated in 2D
//! together with the point ([spade]). The triangles at the point form its region R; their
//! outer vertices, counter-clockwise around the normal, are its ring. When the point lies on
//! the convex hull of the projected set the ring does not close: the point is on the boundary
//! of an open surface.
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
use spade::handles::FixedVertexHandle;
use spade::{DelaunayTriangulation, HasPosition, Point2, Triangulation};

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

/// A projected neighbour: its position in the tangent plane and its slot in the input list
/// (the centre is slot `u32::MAX`).
#[derive(Debug, Clone, Copy)]
struct Projected {
    pos: Point2<f64>,
    slot: u32,
}

impl HasPosition for Projected {
    type Scalar = f64;

    fn position(&self) -> Point2<f64> {
        self.pos
    }
}

/// Slot value marking the centre vertex.
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
    tri: DelaunayTriangulation<Projected>,
    /// Projected neighbours kept so far, as (slot, position).
    kept: Vec<(u32, DVec2)>,
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
            tri: DelaunayTriangulation::new(),
            kept: Vec::new(),
            fan: Vec::new(),
            region: Vec::new(),
        }
    }

    /// The ring of the point at `centre` with unit `normal`, from its `neighbours` (nearest
    /// first, the point itself excluded). When `ring` is given it receives the ring as indices
    /// into `neighbours`, counter-clockwise around `normal`, starting after the widest gap
    /// when the ring is open, each with whether the triangle between it and the next ring
    /// vertex is surface.
    pub fn build(
        &mut self,
        centre: Vec3,
        normal: Vec3,
        neighbours: &[Vec3],
        ring: Option<&mut Vec<(u32, bool)>>,
    ) -> RingShape {
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
        shape.coincident = self.project(centre, normal, neighbours, scale);
        if self.kept.len() < 2 {
            return shape;
        }
        shape.surrounded = self.surrounds();
        let Some(centre_handle) = self.triangulate() else {
            return shape;
        };
        // Local spacing: the mean distance to the nearest few neighbours.
        let near = neighbours.len().min(SPACING_NEIGHBOURS);
        let spacing = neighbours[..near]
            .iter()
            .map(|p| p.distance(centre))
            .sum::<f32>()
            / near as f32;
        self.collect_fan(
            centre_handle,
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
    fn project(&mut self, centre: Vec3, normal: Vec3, neighbours: &[Vec3], scale: f32) -> bool {
        let mut coincident = false;
        let (t1, t2) = normal.any_orthonormal_pair();
        let max_elevation = MAX_ELEVATION_DEG.to_radians().tan();
        let coincident2 = (COINCIDENT_REL * scale).powi(2);
        self.kept.clear();
        for (slot, p) in neighbours.iter().enumerate() {
            let v = *p - centre;
            if v.length_squared() <= coincident2 {
                coincident = true;
                continue;
            }
            let (x, y) = (v.dot(t1), v.dot(t2));
            let tangential = x.hypot(y);
            if v.dot(normal).abs() > max_elevation * tangential {
                continue;
            }
            let q = DVec2::new(f64::from(x), f64::from(y)) / f64::from(scale);
            if self.kept.iter().any(|&(_, k)| k == q) {
                continue;
            }
            self.kept.push((slot as u32, q));
        }
        coincident
    }

    /// The Delaunay triangulation of the centre and `self.kept`; the centre's handle, or
    /// `None` when it cannot be inserted.
    fn triangulate(&mut self) -> Option<FixedVertexHandle> {
        self.tri.clear();
        let centre_handle = match self.tri.insert(Projected {
            pos: Point2::new(0.0, 0.0),
            slot: CENTRE,
        }) {
            Ok(h) => h,
            Err(_) => return None,
        };
        for &(slot, q) in &self.kept {
            // Coordinates are O(1) after scaling; an insertion error means a value too small
            // to represent, i.e. a point at the centre, which was skipped above.
            let _ = self.tri.insert(Projected {
                pos: Point2::new(q.x, q.y),
                slot,
            });
        }
        Some(centre_handle)
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

    /// Whether the kept projected neighbours leave no angular gap of [`MAX_FAN_ANGLE`] or more
    /// around the centre (uses `self.region` as scratch).
    fn surrounds(&mut self) -> bool {
        self.region.clear();
        self.region.extend(
            self.kept
                .iter()
                .map(|&(_, q)| DVec2::new(q.y.atan2(q.x), 0.0)),
        );
        self.region.sort_unstable_by(|a, b| a.x.total_cmp(&b.x));
        let m = self.region.len();
        (0..m).all(|i| {
            let gap =
                (self.region[(i + 1) % m].x - self.region[i].x).rem_euclid(std::f64::consts::TAU);
            gap < MAX_FAN_ANGLE && (m > 1 || gap > 0.0)
        })
    }

    /// Fills `self.fan` with the centre's neighbours in CCW order, each with whether the face
    /// between it and the next one is surface.
    /// `max_circumradius` is in the scaled (projected) units.
    fn collect_fan(&mut self, centre: FixedVertexHandle, max_circumradius: f64) {
        self.fan.clear();
        let to_dvec = |p: Point2<f64>| DVec2::new(p.x, p.y);
        for e in self.tri.vertex(centre).out_edges() {
            let to = e.to();
            let a = to_dvec(to.position());
            let b = to_dvec(e.ccw().to().position());
            // The face left of centre→to is (centre, to, next CCW neighbour).
            let surface = !e.face().is_outer()
                && fan_angle(a, b) <= MAX_FAN_ANGLE
                && circumradius(a, b) <= max_circumradius;
            self.fan.push((to.data().slot, a, surface));
        }
    }
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
        let s = b.build(Vec3::ZERO, Vec3::Z, &hexagon(1.0), Some(&mut ring));
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
        b.build(Vec3::ZERO, -Vec3::Z, &hexagon(1.0), Some(&mut rev));
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
        let s = RingBuilder::new().build(Vec3::ZERO, Vec3::Z, &pts, Some(&mut ring));
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
        let s = RingBuilder::new().build(Vec3::ZERO, Vec3::Z, &pts, None);
        assert!(s.open);
        assert!(s.area < std::f32::consts::FRAC_PI_2 + 0.1);
    }

    #[test]
    fn degenerate_and_coincident_neighbourhoods() {
        let mut b = RingBuilder::new();
        let line: Vec<Vec3> = (1..6).map(|i| Vec3::X * i as f32).collect();
        let s = b.build(Vec3::ZERO, Vec3::Z, &line, None);
        assert!(s.degenerate && s.diameter.is_infinite());
        let mut with_dup = hexagon(1.0);
        with_dup.push(Vec3::ZERO);
        let s = b.build(Vec3::ZERO, Vec3::Z, &with_dup, None);
        assert!(s.coincident && !s.degenerate);
        let all_same = vec![Vec3::ONE; 4];
        let s = b.build(Vec3::ONE, Vec3::Z, &all_same, None);
        assert!(s.coincident && s.degenerate);
        let s = b.build(Vec3::ZERO, Vec3::Z, &[], None);
        assert!(s.degenerate && !s.coincident);
    }

    #[test]
    fn steep_neighbours_are_skipped() {
        // A point straight above the centre (the far side of a thin plate) is not projected.
        let mut pts = hexagon(1.0);
        pts.push(Vec3::new(0.1, 0.0, 0.5));
        let mut ring = Vec::new();
        let s = RingBuilder::new().build(Vec3::ZERO, Vec3::Z, &pts, Some(&mut ring));
        assert!(!s.open);
        assert!(ring.iter().all(|&(slot, _)| slot != 6));
    }
}
