//! Step 7: holes that neither ears nor a fan closed, triangulated as polygons.
//!
//! Ears are tried one corner at a time and in each corner's tangent plane; a fan needs one dense
//! point that sees the whole loop. A small hole at a sharp turn of the surface (a quad whose
//! loop crosses itself in every tangent plane, a diagonal already taken on the other side) can
//! defeat both and still have a triangulation that keeps the mesh a manifold and folds nowhere.
//! Each such hole is triangulated whole, by dynamic programming over its loop (the classic
//! minimum-weight polygon triangulation, as in Liepa's hole filling). Of the triangulations
//! that add no edge the mesh has already, and whose every triangle faces within 80°
//! ([`MAX_PATCH_TILT_COS`]) of its corners' mean normal, lies over the dense cloud and overlaps
//! no triangle near it, the one whose worst triangle tilts least wins, then the one of least
//! area.
//!
//! A loop that winds the wrong way round has no such triangulation: every triangle across it
//! would face backwards. It is left open.

use super::{Builder, Wedge};

/// Largest loop triangulated (points): the work grows with the cube of its length.
pub const MAX_PATCH_LOOP: usize = 64;

/// Cosine of the widest angle a patch triangle may tilt from its corners' mean normal (80°).
pub const MAX_PATCH_TILT_COS: f32 = 0.173_648_18;

/// The best triangulation of a sub-polygon: its worst tilt (1 − cosine), its area, and the
/// apex chosen over its base.
#[derive(Clone, Copy)]
struct Cell {
    worst: f32,
    area: f32,
    apex: usize,
}

impl Cell {
    /// Better when the worst triangle tilts less, then when the area is smaller.
    fn better_than(&self, other: &Cell) -> bool {
        (self.worst, self.area) < (other.worst, other.area)
    }
}

impl Builder<'_> {
    /// Triangulates each hole left whose points are mostly `closable`, when a triangulation
    /// fits (see the module docs).
    pub(super) fn patch_holes(&mut self, closable: &[bool]) {
        for points in self.holes_up_to(MAX_PATCH_LOOP, closable) {
            if let Some(triangles) = self.triangulate(&points) {
                self.insert_patch(&points, &triangles);
            }
        }
    }

    /// The best triangulation of the loop `points` (each triangle counter-clockwise around the
    /// normals), when one fits.
    fn triangulate(&self, points: &[u32]) -> Option<Vec<[u32; 3]>> {
        let m = points.len();
        let joined = |a: usize, b: usize| {
            self.mesh.wedges[points[a] as usize]
                .iter()
                .any(|w| w.from == points[b] || w.to == points[b])
        };
        // best[i][k]: sub-polygon i, i + 1, …, k closed by the chord k – i.
        let mut best: Vec<Vec<Option<Cell>>> = vec![vec![None; m]; m];
        for i in 0..m - 1 {
            best[i][i + 1] = Some(Cell {
                worst: 0.0,
                area: 0.0,
                apex: i,
            });
        }
        for span in 2..m {
            for i in 0..m - span {
                let k = i + span;
                // The chord closing the sub-polygon must be new (the whole loop's base, 0 – m-1,
                // is a loop edge).
                if !(i == 0 && k == m - 1) && joined(i, k) {
                    continue;
                }
                let mut cell: Option<Cell> = None;
                for j in i + 1..k {
                    let (Some(left), Some(right)) = (best[i][j], best[j][k]) else {
                        continue;
                    };
                    // Loop edges run i → i + 1: the triangle runs the other way round.
                    let t = [points[k], points[j], points[i]];
                    let Some((tilt, area)) = self.patch_triangle(t) else {
                        continue;
                    };
                    let candidate = Cell {
                        worst: tilt.max(left.worst).max(right.worst),
                        area: area + left.area + right.area,
                        apex: j,
                    };
                    if cell.is_none_or(|c| candidate.better_than(&c)) {
                        cell = Some(candidate);
                    }
                }
                best[i][k] = cell;
            }
        }
        best[0][m - 1]?;
        let mut out = Vec::with_capacity(m - 2);
        let mut stack = vec![(0, m - 1)];
        while let Some((i, k)) = stack.pop() {
            if k - i < 2 {
                continue;
            }
            let j = best[i][k]?.apex;
            out.push([points[k], points[j], points[i]]);
            stack.push((i, j));
            stack.push((j, k));
        }
        Some(out)
    }

    /// A patch triangle's tilt (1 − cosine to its corners' mean normal) and area, when it is
    /// not degenerate, tilts less than 80° ([`MAX_PATCH_TILT_COS`]) and lies over the dense cloud.
    fn patch_triangle(&self, t @ [a, b, c]: [u32; 3]) -> Option<(f32, f32)> {
        let p = |i: u32| self.positions[i as usize];
        let cross = (p(b) - p(a)).cross(p(c) - p(a));
        let normal = cross.try_normalize()?;
        let mean = (self.normals[a as usize] + self.normals[b as usize] + self.normals[c as usize])
            .try_normalize()?;
        let cos = normal.dot(mean);
        (cos > MAX_PATCH_TILT_COS && self.over_dense(t) && !self.overlaps_apart(t))
            .then_some((1.0 - cos, 0.5 * cross.length()))
    }

    /// Adds the triangles of a patch over the loop `points`: at each loop point, its sectors in
    /// place of its gap, in order from the point before it on the loop to the point after.
    fn insert_patch(&mut self, points: &[u32], triangles: &[[u32; 3]]) {
        let m = points.len();
        for i in 0..m {
            let (prev, v, next) = (points[(i + m - 1) % m], points[i], points[(i + 1) % m]);
            let mut sectors: Vec<Wedge> = triangles
                .iter()
                .filter_map(|&[a, b, c]| {
                    let (from, to) = if a == v {
                        (b, c)
                    } else if b == v {
                        (c, a)
                    } else if c == v {
                        (a, b)
                    } else {
                        return None;
                    };
                    Some(self.raw_wedge(v, from, to))
                })
                .collect();
            // Chain them from `prev` to `next`.
            let mut chain = Vec::with_capacity(sectors.len());
            let mut at = prev;
            while let Some(s) = sectors.iter().position(|w| w.from == at) {
                let w = sectors.swap_remove(s);
                at = w.to;
                chain.push(w);
            }
            debug_assert!(
                at == next && sectors.is_empty(),
                "a patch fans out from prev to next"
            );
            let fan = &mut self.mesh.wedges[v as usize];
            let len = fan.len();
            let Some(g) = (0..len).find(|&g| fan[g].to == prev && fan[(g + 1) % len].from == next)
            else {
                continue; // cannot happen: the loop came from these gaps
            };
            for (offset, w) in chain.into_iter().enumerate() {
                fan.insert(g + 1 + offset, w);
            }
        }
        self.mesh.stats.ears += triangles.len();
        self.mesh.stats.patches += 1;
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::super::{Builder, MAX_CLOSING_ANGLE, SurfaceMesh};
    use crate::core::cloud::knn::{KnnGraph, KnnIndex};

    /// A flat square of 5 × 5 points in the plane z = 0 (normals +z), all triangles but those
    /// of the centre cell's two halves.
    fn sheet(graph: &KnnGraph, positions: Vec<Vec3>) -> Builder<'_> {
        let n = positions.len();
        let normals = vec![Vec3::Z; n];
        Builder {
            graph,
            frames: normals.iter().map(|n| n.any_orthonormal_pair()).collect(),
            positions,
            normals,
            dense: None,
            limit: MAX_CLOSING_ANGLE,
            mesh: SurfaceMesh {
                wedges: vec![Vec::new(); n],
                ..SurfaceMesh::default()
            },
        }
    }

    fn grid() -> Vec<Vec3> {
        (0..25)
            .map(|i| Vec3::new((i % 5) as f32, (i / 5) as f32, 0.0))
            .collect()
    }

    #[test]
    fn a_square_hole_is_triangulated_and_the_sheet_closes_around_it() {
        let positions = grid();
        let graph = KnnIndex::build(&positions).knn_graph(&positions, 8);
        let mut b = sheet(&graph, positions);
        // Every cell of the 4 × 4 grid but the 2 × 2 block in the middle (a 8-point hole).
        for y in 0..4u32 {
            for x in 0..4u32 {
                if (1..3).contains(&x) && (1..3).contains(&y) {
                    continue;
                }
                let v = y * 5 + x;
                assert!(b.try_add([v, v + 1, v + 6]));
                assert!(b.try_add([v, v + 6, v + 5]));
            }
        }
        let loops = b.mesh.boundary_loops();
        assert_eq!(loops.len(), 2, "the outline and the hole");
        let hole: Vec<u32> = loops.into_iter().find(|l| !l.contains(&0)).expect("a hole");
        assert_eq!(hole.len(), 8);
        // The centre point (12) has no triangle: the hole's loop runs around it. The patch
        // covers the hole with the loop's own points (12 stays outside it).
        let closable: Vec<bool> = (0..25).map(|v| hole.contains(&(v as u32))).collect();
        b.patch_holes(&closable);
        assert_eq!(b.mesh.stats.patches, 1);
        let loops = b.mesh.boundary_loops();
        assert_eq!(loops.len(), 1, "only the outline is left");
        assert_eq!(b.mesh.triangles().len(), 24 + 6);
        let area: f32 = b
            .mesh
            .triangles()
            .iter()
            .map(|&[a, c, d]| {
                let p = |i: u32| b.positions[i as usize];
                let normal = (p(c) - p(a)).cross(p(d) - p(a));
                assert!(normal.z > 0.0, "every triangle faces up");
                0.5 * normal.length()
            })
            .sum();
        assert!(
            (area - 16.0).abs() < 1e-4,
            "the square's area, no overlap: {area}"
        );
    }

    #[test]
    fn a_diagonal_taken_elsewhere_is_not_reused() {
        // A quad hole 0-1-2-3 whose diagonal 0–2 is an edge already (a triangle hanging off
        // below the hole, folded under it): the patch takes the other diagonal, 1–3.
        let positions = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.5, -1.0, 0.0),
            Vec3::new(2.0, 0.5, 0.0),
            Vec3::new(0.5, 2.0, 0.0),
            Vec3::new(-1.0, 0.5, 0.0),
            Vec3::new(0.6, 0.4, -0.5),
        ];
        let graph = KnnIndex::build(&positions).knn_graph(&positions, 4);
        let mut b = sheet(&graph, positions);
        for t in [[0, 4, 1], [1, 5, 2], [2, 6, 3], [3, 7, 0]] {
            assert!(b.try_add(t));
        }
        // The edge 0–2 in a triangle elsewhere.
        let w = b.raw_wedge(0, 8, 2);
        b.mesh.wedges[0].push(w);
        let w = b.raw_wedge(2, 0, 8);
        b.mesh.wedges[2].push(w);
        // Loop edges run as the triangles' edges: 0 → 3 → 2 → 1.
        let hole = [0u32, 3, 2, 1];
        let triangles = b.triangulate(&hole).expect("a triangulation fits");
        assert_eq!(triangles.len(), 2);
        for t in &triangles {
            assert!(t.contains(&1) && t.contains(&3), "the diagonal 1–3: {t:?}");
        }
    }

    #[test]
    fn a_loop_that_winds_backwards_is_not_patched() {
        let positions = grid();
        let graph = KnnIndex::build(&positions).knn_graph(&positions, 8);
        let b = sheet(&graph, positions);
        // Seen from above, counter-clockwise: a patch over it would face down.
        assert!(b.triangulate(&[0, 1, 6, 5]).is_none());
        assert!(b.triangulate(&[0, 5, 6, 1]).is_some());
    }

    #[test]
    fn triangles_that_overlap_without_sharing_a_corner_are_refused() {
        let mut positions = grid();
        // Three more points, over the cells at the origin.
        positions.extend([
            Vec3::new(0.2, 0.1, 0.05),
            Vec3::new(1.2, 0.1, 0.05),
            Vec3::new(0.2, 1.1, 0.05),
        ]);
        let graph = KnnIndex::build(&positions).knn_graph(&positions, 8);
        let mut b = sheet(&graph, positions);
        assert!(b.try_add([0, 1, 6]));
        assert!(b.try_add([0, 6, 5]));
        // Shares no corner with them and lies across both: refused.
        assert!(b.overlaps_apart([25, 26, 27]));
        assert!(!b.try_add([25, 26, 27]));
        // The next cell shares the edge 1–6 (tested by sectors, not here) and overlaps nothing.
        assert!(!b.overlaps_apart([1, 2, 7]));
        assert!(b.try_add([1, 2, 7]));
        // A triangle that faces away (the other side of a thin part) is not an overlap.
        assert!(!b.overlaps_apart([25, 27, 26]));
    }
}
