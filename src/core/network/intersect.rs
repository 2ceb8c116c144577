//! Where a triangulated surface passes through itself (or through another, given both in one
//! list): the edges that cross a triangle they share no corner with. A surface that never
//! crosses itself has none; a sheet whose fold passed through itself has a few at each
//! place it did. Self-contact is tested with it (`tests/meet.rs`), and a game or a batch run
//! may check a deformed surface with it.

use glam::{DVec3, Vec3};

use crate::core::solver::contact::PointGrid;

/// The number of (edge, triangle) pairs of `triangles` over `positions` where the edge
/// crosses the triangle and shares no corner with it. Each edge is counted once however
/// many triangles hold it; a crossing curve between two sheets is counted once per edge of
/// either sheet that it cuts. Triangles with a corner out of range, and non-finite
/// positions, are left out.
///
/// A grid over the triangles' centres finds the candidates, so the cost grows with the
/// surface, not its square (unless one triangle is far larger than the rest).
pub fn surface_intersections(positions: &[Vec3], triangles: &[[u32; 3]]) -> usize {
    let mut count = 0;
    let mut last = None;
    for_each_crossing(positions, triangles, |edge, _| {
        count += usize::from(last != Some(edge));
        last = Some(edge);
    });
    count
}

/// Every (edge, triangle) pair of `triangles` over `positions` where the edge crosses the
/// triangle and shares no corner with it: the edge's ends (ascending) and the triangle's
/// index, edge by edge in ascending order, each edge's triangles ascending. Left out as in
/// [`surface_intersections`].
pub fn crossings(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<([u32; 2], u32)> {
    let mut found = Vec::new();
    for_each_crossing(positions, triangles, |edge, t| found.push((edge, t)));
    found
}

/// Calls `crossed(edge, triangle)` for each crossing, in the order [`crossings`] gives.
fn for_each_crossing(positions: &[Vec3], all: &[[u32; 3]], mut crossed: impl FnMut([u32; 2], u32)) {
    let n = positions.len();
    let valid = |t: &[u32; 3]| {
        t.iter()
            .all(|&c| (c as usize) < n && positions[c as usize].is_finite())
    };
    let (index, triangles): (Vec<u32>, Vec<[u32; 3]>) = all
        .iter()
        .enumerate()
        .filter(|(_, t)| valid(t))
        .map(|(k, t)| (k as u32, *t))
        .unzip();
    if triangles.is_empty() {
        return;
    }
    let corners = |t: &[u32; 3]| t.map(|c| positions[c as usize]);
    let centres: Vec<Vec3> = triangles
        .iter()
        .map(|t| corners(t).iter().sum::<Vec3>() / 3.0)
        .collect();
    // The largest distance from a triangle's centre to one of its corners.
    let reach = triangles
        .iter()
        .zip(&centres)
        .flat_map(|(t, c)| corners(t).map(|p| p.distance(*c)))
        .fold(0.0_f32, f32::max);
    let grid = PointGrid::new(&centres, (2.0 * reach).max(f32::EPSILON));
    let mut edges: Vec<[u32; 2]> = triangles
        .iter()
        .flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
        .map(|[a, b]| [a.min(b), a.max(b)])
        .filter(|[a, b]| a != b)
        .collect();
    edges.sort_unstable();
    edges.dedup();
    let mut hits = Vec::new();
    for [a, b] in edges {
        let (p, q) = (positions[a as usize], positions[b as usize]);
        let (mid, half) = ((p + q) * 0.5, p.distance(q) * 0.5);
        let r = Vec3::splat(half + reach);
        hits.clear();
        grid.near(mid - r, mid + r, |k| {
            let t = &triangles[k];
            if t.contains(&a) || t.contains(&b) {
                return;
            }
            let [x, y, z] = corners(t);
            if segment_crosses_triangle(p, q, x, y, z) {
                hits.push(index[k]);
            }
        });
        hits.sort_unstable();
        for &t in &hits {
            crossed([a, b], t);
        }
    }
}

/// Whether the segment `p`–`q` passes through the triangle `a b c` (Möller–Trumbore, in
/// `f64`; a segment in the triangle's plane does not count).
pub fn segment_crosses_triangle(p: Vec3, q: Vec3, a: Vec3, b: Vec3, c: Vec3) -> bool {
    let (p, q, a, b, c) = (
        p.as_dvec3(),
        q.as_dvec3(),
        a.as_dvec3(),
        b.as_dvec3(),
        c.as_dvec3(),
    );
    let d = q - p;
    let (e1, e2) = (b - a, c - a);
    let h = d.cross(e2);
    let det = e1.dot(h);
    let scale = d.length() * e1.length() * e2.length();
    if det.abs() <= 1e-12 * scale || scale == 0.0 {
        return false;
    }
    let s: DVec3 = p - a;
    let u = s.dot(h) / det;
    if !(0.0..=1.0).contains(&u) {
        return false;
    }
    let w = s.cross(e1);
    let v = d.dot(w) / det;
    if v < 0.0 || u + v > 1.0 {
        return false;
    }
    let t = e2.dot(w) / det;
    (0.0..=1.0).contains(&t)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat square grid of `k × k` points in the plane y = `height`, turned by `turn`
    /// about x, and its triangles (indices from `offset`).
    fn sheet(k: u32, height: f32, offset: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut points = Vec::new();
        for z in 0..k {
            for x in 0..k {
                points.push(Vec3::new(x as f32, height, z as f32));
            }
        }
        let mut triangles = Vec::new();
        for z in 0..k - 1 {
            for x in 0..k - 1 {
                let i = offset + z * k + x;
                triangles.push([i, i + 1, i + k]);
                triangles.push([i + 1, i + k + 1, i + k]);
            }
        }
        (points, triangles)
    }

    #[test]
    fn a_segment_through_a_triangle_crosses_it_and_one_beside_it_does_not() {
        let (a, b, c) = (Vec3::ZERO, Vec3::X, Vec3::Z);
        let through =
            segment_crosses_triangle(Vec3::new(0.2, -1.0, 0.2), Vec3::new(0.2, 1.0, 0.2), a, b, c);
        let beside =
            segment_crosses_triangle(Vec3::new(0.8, -1.0, 0.8), Vec3::new(0.8, 1.0, 0.8), a, b, c);
        let short =
            segment_crosses_triangle(Vec3::new(0.2, 0.1, 0.2), Vec3::new(0.2, 1.0, 0.2), a, b, c);
        let flat = segment_crosses_triangle(Vec3::ZERO, Vec3::new(0.3, 0.0, 0.3), a, b, c);
        assert!(through);
        assert!(!beside && !short && !flat);
    }

    #[test]
    fn two_sheets_apart_do_not_cross_and_one_through_the_other_does() {
        let (mut points, mut triangles) = sheet(6, 0.0, 0);
        let (upper, upper_triangles) = sheet(6, 0.5, 36);
        points.extend(upper);
        triangles.extend(upper_triangles);
        assert_eq!(surface_intersections(&points, &triangles), 0);
        // Stand the second sheet up through the first: turn it about the line x = 2.5,
        // y = 0.5, so that it cuts the first along x = 2.5.
        let mut standing = points.clone();
        for p in &mut standing[36..] {
            let (x, y) = (p.x - 2.5, p.y);
            *p = Vec3::new(2.5 + 0.3 * (y - 0.5), x, p.z + 0.25);
        }
        let crossings = surface_intersections(&standing, &triangles);
        // The line x = 2.5 cuts the first sheet's 5 rows of cells, each through a
        // horizontal edge pair and diagonals; and the standing sheet's edges cross the
        // first sheet along its own row of cells.
        assert!(crossings >= 10, "{crossings}");
        // A brute-force count agrees.
        let mut edges: Vec<[u32; 2]> = triangles
            .iter()
            .flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
            .map(|[a, b]| [a.min(b), a.max(b)])
            .collect();
        edges.sort_unstable();
        edges.dedup();
        let brute = edges
            .iter()
            .filter(|[a, b]| {
                triangles.iter().any(|t| {
                    !t.contains(a)
                        && !t.contains(b)
                        && segment_crosses_triangle(
                            standing[*a as usize],
                            standing[*b as usize],
                            standing[t[0] as usize],
                            standing[t[1] as usize],
                            standing[t[2] as usize],
                        )
                })
            })
            .count();
        assert_eq!(crossings, brute);
        // Bad corners and positions are left out, without a panic.
        let mut bad = standing.clone();
        bad[0] = Vec3::NAN;
        let _ = surface_intersections(&bad, &[[0, 1, 2], [7, 8, 999]]);
    }
}
