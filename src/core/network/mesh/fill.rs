//! Step 6: holes no ear closes, filled by a fan from a dense point.
//!
//! Some holes have no ear that fits at any of their points: at the end of a thin part whose tip
//! kept no simulation point (a leg, a trunk, an ear) every point's gap is wider than 179° in its
//! own tangent plane; elsewhere an ear's diagonal is a spring on the other side already, or the
//! ear folds over where the surface turns sharply between coarse points. The dense cloud still
//! covers such a hole. The dense point that sees the whole loop best becomes a simulation point
//! joined to every point of the loop: the fan adds no edge between loop points, so it cannot make
//! an edge non-manifold, and its triangles are half the size of an ear's.
//!
//! A dense point is a *centre* for a loop when, in the centre's tangent plane, the loop winds
//! once around it with every triangle turning counter-clockwise by less than
//! [`MAX_CLOSING_ANGLE`] (the loop is star-shaped from it); every triangle faces within 90° of
//! the centre's normal and of its corners' mean normal; at a loop point whose normal a triangle
//! faces within 60° of, the centre lies inside that point's gap; and every triangle lies over
//! the dense cloud. Of the centres, the one whose worst triangle is the most regular wins.

use std::f32::consts::TAU;

use glam::Vec3;

use super::{Builder, MAX_CLOSING_ANGLE, STEEP_COS, Wedge};
use crate::core::cloud::knn::KnnGraph;

/// Dense points tried as a hole's centre around each probe.
const CENTRE_CANDIDATES: usize = 48;

/// Probes for centres, in loop radii from the loop's centroid along the direction the loop's
/// gaps open into (the tip of a thin part lies beyond the centroid of the loop around it).
const PROBE_STEPS: [f32; 5] = [0.0, 0.5, 1.0, 1.5, 2.0];

/// Largest loop filled with a fan (points): a bigger hole is a missing region, not a gap.
const MAX_FAN_LOOP: usize = 64;

/// A candidate centre's fan: its position, its normal (turned to the fan's side) and the
/// regularity of its worst triangle.
struct Fan {
    centre: Vec3,
    normal: Vec3,
    quality: f32,
}

impl Builder<'_> {
    /// Fills each hole whose points are mostly `closable` (see [`Builder::close`]) with a fan
    /// from the best centre, when one exists (see the module docs).
    pub(super) fn fill_with_centres(&mut self, closable: &[bool], graph: &KnnGraph) {
        let Some(dense) = self.dense else {
            return;
        };
        for points in self.holes_up_to(MAX_FAN_LOOP, closable) {
            let mut candidates: Vec<u32> = self
                .probes(&points)
                .into_iter()
                .flat_map(|probe| dense.near(probe, CENTRE_CANDIDATES))
                .collect();
            candidates.sort_unstable();
            candidates.dedup();
            // A dense point that is a simulation point already (one left without a triangle
            // inside the hole, say) would become a second point in the same place.
            let taken: Vec<Vec3> = points
                .iter()
                .filter(|&&v| (v as usize) < graph.len())
                .flat_map(|&v| graph.neighbours(v as usize))
                .map(|&j| self.positions[j as usize])
                .collect();
            let best = candidates
                .into_iter()
                .filter_map(|i| {
                    let (p, n) = dense.point(i);
                    if taken.contains(&p) {
                        return None;
                    }
                    self.fan(&points, p, n).map(|fan| (i, fan))
                })
                .max_by(|a, b| a.1.quality.total_cmp(&b.1.quality));
            let Some((index, raw)) = best else {
                continue;
            };
            // On a noisy cloud the simulation points lie on local fits: so does the centre,
            // where its fan still fits.
            let (p, n) = dense.fitted_point(index);
            let fan = self.fan(&points, p, n).unwrap_or(raw);
            self.insert_fan(&points, fan.centre, fan.normal);
        }
    }

    /// The boundary loops of 3 to `max` distinct points most of whose points are `closable`
    /// (holes: not an outer rim, nor a loop through a pinch).
    pub(super) fn holes_up_to(&self, max: usize, closable: &[bool]) -> Vec<Vec<u32>> {
        let mut holes = self.mesh.boundary_loops();
        holes.retain(|points| {
            let mut distinct = points.clone();
            distinct.sort_unstable();
            distinct.dedup();
            (3..=max).contains(&points.len())
                && distinct.len() == points.len()
                && self.is_hole(points, closable)
        });
        holes
    }

    /// Whether most of the loop's `points` are closable: a hole, not an outer rim.
    pub(super) fn is_hole(&self, points: &[u32], closable: &[bool]) -> bool {
        let inner = points
            .iter()
            .filter(|&&v| closable.get(v as usize).copied().unwrap_or(true))
            .count();
        2 * inner >= points.len()
    }

    /// Where to look for a centre: the loop's centroid, and points beyond it along the mean
    /// direction its gaps open into (each gap's bisector in its point's tangent plane).
    fn probes(&self, points: &[u32]) -> Vec<Vec3> {
        let m = points.len();
        let at = |i: usize| self.positions[points[i % m] as usize];
        let centroid = (0..m).map(at).sum::<Vec3>() / m as f32;
        let radius = (0..m).map(|i| at(i).distance(centroid)).fold(0.0, f32::max);
        let inward: Vec3 = (0..m)
            .map(|i| {
                let (prev, v, next) = (points[(i + m - 1) % m], points[i], points[(i + 1) % m]);
                let start = self.angle(v, prev);
                let sweep = (self.angle(v, next) - start).rem_euclid(TAU);
                let (t1, t2) = self.frames[v as usize];
                let (sin, cos) = (start + 0.5 * sweep).sin_cos();
                t1 * cos + t2 * sin
            })
            .sum();
        let inward = inward.normalize_or_zero();
        PROBE_STEPS
            .iter()
            .map(|s| centroid + inward * radius * s)
            .collect()
    }

    /// The fan from `centre` (unit normal `normal`, either sign) over the loop `points`, when
    /// it fills the hole (see the module docs).
    fn fan(&self, points: &[u32], centre: Vec3, normal: Vec3) -> Option<Fan> {
        let m = points.len();
        let at = |i: usize| self.positions[points[i % m] as usize];
        let nrm = |i: usize| self.normals[points[i % m] as usize];
        // Triangle i is (loop i + 1, loop i, centre): counter-clockwise around the surface's
        // normals when the loop runs as `boundary_loops` walks it.
        let area: Vec3 = (0..m)
            .map(|i| (at(i + 1) - centre).cross(at(i) - centre))
            .sum();
        if normal == Vec3::ZERO || area == Vec3::ZERO {
            return None;
        }
        let normal = if normal.dot(area) < 0.0 {
            -normal
        } else {
            normal
        };
        let (t1, t2) = normal.any_orthonormal_pair();
        let angle = |p: Vec3| {
            let d = p - centre;
            d.dot(t2).atan2(d.dot(t1))
        };
        let mut total = 0.0;
        let mut quality = f32::INFINITY;
        let mut facing = Vec::with_capacity(m);
        for i in 0..m {
            let (a, b) = (at(i + 1), at(i));
            let sweep = (angle(b) - angle(a)).rem_euclid(TAU);
            if !(sweep > 0.0 && sweep < MAX_CLOSING_ANGLE) {
                return None;
            }
            total += sweep;
            let cross = (b - a).cross(centre - a);
            let face = cross.normalize_or_zero();
            let mean = nrm(i) + nrm(i + 1) + normal;
            if face.dot(mean) <= 0.0 {
                return None;
            }
            let squares =
                a.distance_squared(b) + b.distance_squared(centre) + centre.distance_squared(a);
            quality = quality.min(2.0 * 3f32.sqrt() * cross.length() / squares);
            facing.push(face);
        }
        if (total - TAU).abs() > 1e-3 {
            return None; // the loop does not wind once around the centre
        }
        // At each loop point, where both its new triangles face near its normal, the centre
        // must lie in its gap.
        for i in 0..m {
            let (prev, v, next) = (points[(i + m - 1) % m], points[i], points[(i + 1) % m]);
            let n = self.normals[v as usize];
            if facing[(i + m - 1) % m].dot(n) > STEEP_COS && facing[i].dot(n) > STEEP_COS {
                let (f1, f2) = self.frames[v as usize];
                let d = centre - self.positions[v as usize];
                let start = self.angle(v, prev);
                let to_centre = (d.dot(f2).atan2(d.dot(f1)) - start).rem_euclid(TAU);
                let to_next = (self.angle(v, next) - start).rem_euclid(TAU);
                if !(to_centre > 0.0 && to_centre < to_next) {
                    return None;
                }
            }
        }
        let dense = self.dense?;
        (0..m)
            .all(|i| {
                let corners = [points[(i + 1) % m], points[i], u32::MAX];
                let tri = [at(i + 1), at(i), centre];
                dense.covers(tri) && !self.overlaps_apart_at(corners, tri)
            })
            .then_some(Fan {
                centre,
                normal,
                quality,
            })
    }

    /// Adds `centre` as a point and its fan over the loop `points` (checked by
    /// [`Builder::fan`]): at each loop point, two sectors in place of its gap.
    fn insert_fan(&mut self, points: &[u32], centre: Vec3, normal: Vec3) {
        let m = points.len();
        let around = |i: usize| (points[(i + m - 1) % m], points[i], points[(i + 1) % m]);
        let gaps: Option<Vec<usize>> = (0..m)
            .map(|i| {
                let (prev, v, next) = around(i);
                let fan = &self.mesh.wedges[v as usize];
                let len = fan.len();
                (0..len).find(|&g| fan[g].to == prev && fan[(g + 1) % len].from == next)
            })
            .collect();
        let Some(gaps) = gaps else {
            return; // not the loop the mesh has (cannot happen: loops come from gaps)
        };
        let c = self.positions.len() as u32;
        self.positions.push(centre);
        self.normals.push(normal);
        self.frames.push(normal.any_orthonormal_pair());
        self.mesh.wedges.push(Vec::new());
        for (i, g) in gaps.into_iter().enumerate() {
            let (prev, v, next) = around(i);
            let (first, second) = (self.raw_wedge(v, prev, c), self.raw_wedge(v, c, next));
            let fan = &mut self.mesh.wedges[v as usize];
            fan.insert(g + 1, first);
            fan.insert(g + 2, second);
        }
        let mut wedges: Vec<Wedge> = (0..m)
            .map(|i| self.raw_wedge(c, points[(i + 1) % m], points[i]))
            .collect();
        wedges.sort_by(|a, b| a.start.total_cmp(&b.start));
        self.mesh.wedges[c as usize] = wedges;
        self.mesh.stats.fans += 1;
        self.mesh.stats.ears += m;
    }
}

#[cfg(test)]
mod tests {
    use std::f32::consts::{PI, TAU};

    use glam::Vec3;

    use super::super::{Builder, MAX_CLOSING_ANGLE, SurfaceMesh};
    use crate::core::cloud::knn::{KnnGraph, KnnIndex};
    use crate::core::network::DenseSupport;

    /// Points of a capsule: a cylinder of radius 1 from z = -2 to z = 0 with hemispherical
    /// caps, about `spacing` apart, with outward normals.
    fn capsule(spacing: f32) -> (Vec<Vec3>, Vec<Vec3>) {
        let (mut p, mut n) = (Vec::new(), Vec::new());
        let around = (TAU / spacing) as usize;
        for k in 0..=(2.0 / spacing) as usize {
            let z = -(k as f32) * spacing;
            for j in 0..around {
                let a = TAU * j as f32 / around as f32 + 0.5 * k as f32;
                let r = Vec3::new(a.cos(), a.sin(), 0.0);
                p.push(r + Vec3::Z * z);
                n.push(r);
            }
        }
        for (centre, up) in [(Vec3::ZERO, 1.0f32), (Vec3::Z * -2.0, -1.0)] {
            let rows = (0.5 * PI / spacing) as usize;
            for i in 1..=rows {
                let polar = 0.5 * PI * (1.0 - i as f32 / rows as f32);
                let count = ((TAU * polar.sin() / spacing) as usize).max(1);
                for j in 0..count {
                    let a = TAU * j as f32 / count as f32;
                    let d = Vec3::new(
                        polar.sin() * a.cos(),
                        polar.sin() * a.sin(),
                        up * polar.cos(),
                    );
                    p.push(centre + d);
                    n.push(d);
                }
            }
        }
        (p, n)
    }

    /// Three rings of six points on the capsule's cylinder, with outward normals.
    fn tube_points() -> (Vec<Vec3>, Vec<Vec3>) {
        let (mut positions, mut normals) = (Vec::new(), Vec::new());
        for ring in 0..3 {
            for j in 0..6 {
                let a = TAU * j as f32 / 6.0 + 0.5 * ring as f32;
                let r = Vec3::new(a.cos(), a.sin(), 0.0);
                positions.push(r - Vec3::Z * ring as f32);
                normals.push(r);
            }
        }
        (positions, normals)
    }

    /// The nearest neighbours of the tube's points.
    fn tube_graph() -> KnnGraph {
        let (positions, _) = tube_points();
        KnnIndex::build(&positions).knn_graph(&positions, 8)
    }

    /// The tube's points meshed as a tube whose ends no ear can close (every gap at an end is
    /// a half-turn in its point's tangent plane).
    fn tube<'a>(dense: &'a DenseSupport<'a>, graph: &'a KnnGraph) -> Builder<'a> {
        let (positions, normals) = tube_points();
        let mut b = Builder {
            graph,
            frames: normals.iter().map(|n| n.any_orthonormal_pair()).collect(),
            positions,
            normals,
            dense: Some(dense),
            limit: MAX_CLOSING_ANGLE,
            mesh: SurfaceMesh {
                wedges: vec![Vec::new(); 18],
                ..SurfaceMesh::default()
            },
        };
        for ring in 0..2u32 {
            for j in 0..6u32 {
                let (a, b1) = (ring * 6 + j, ring * 6 + (j + 1) % 6);
                let (c, d) = (a + 6, b1 + 6);
                // Each quad in whichever orientation fits (counter-clockwise outside).
                for t in [[a, c, d], [a, d, b1], [a, b1, d], [a, d, c]] {
                    b.try_add(t);
                }
            }
        }
        b
    }

    #[test]
    fn the_open_ends_of_a_tube_get_fans_from_the_dense_tips() {
        let (dense_p, dense_n) = capsule(0.05);
        let dense = DenseSupport::new(&dense_p, &dense_n, 0.0, false);
        let graph = tube_graph();
        let mut b = tube(&dense, &graph);
        assert_eq!(b.mesh.triangles().len(), 24, "the tube's wall");
        let loops = b.mesh.boundary_loops();
        assert_eq!(loops.len(), 2);
        for points in &loops {
            let (u, v, x) = (points[0], points[1], points[2]);
            assert!(b.wedge(v, u, x).is_none(), "no ear fits at a tube's end");
        }

        b.fill_with_centres(&[true; 18], &graph);

        assert_eq!(b.mesh.stats.fans, 2);
        assert_eq!(b.positions.len(), 20);
        assert!((0..20).all(|v| !b.mesh.is_open(v)), "the tube is closed");
        assert!(b.mesh.boundary_loops().is_empty());
        assert_eq!(b.mesh.pinched_points(), 0);
        // The centres are on the caps, near their tips, with outward normals.
        for (v, tip) in [(18, Vec3::Z), (19, Vec3::Z * -3.0)] {
            assert!(b.positions[v].distance(tip) < 0.5, "{:?}", b.positions[v]);
            assert!(b.normals[v].dot(tip.normalize()) > 0.8);
        }
        // Every triangle faces outwards.
        for [a, c, d] in b.mesh.triangles() {
            let p = |i: u32| b.positions[i as usize];
            let centre = (p(a) + p(c) + p(d)) / 3.0;
            let axis = Vec3::new(0.0, 0.0, centre.z.clamp(-2.0, 0.0));
            let face = (p(c) - p(a)).cross(p(d) - p(a));
            assert!(
                face.dot(centre - axis) > 0.0,
                "triangle {a} {c} {d} faces inwards"
            );
        }
    }

    #[test]
    fn a_hole_over_no_dense_points_is_left_open() {
        // The same tube over a dense cylinder without caps: its ends are rims.
        let (dense_p, dense_n): (Vec<Vec3>, Vec<Vec3>) = {
            let (p, n) = capsule(0.05);
            p.into_iter()
                .zip(n)
                .filter(|(p, _)| (-2.0..=0.0).contains(&p.z))
                .unzip()
        };
        let dense = DenseSupport::new(&dense_p, &dense_n, 0.0, false);
        let graph = tube_graph();
        let mut b = tube(&dense, &graph);
        b.fill_with_centres(&[true; 18], &graph);
        assert_eq!(b.mesh.stats.fans, 0);
        assert_eq!(b.positions.len(), 18);
        assert_eq!(b.mesh.boundary_loops().len(), 2);
    }
}
