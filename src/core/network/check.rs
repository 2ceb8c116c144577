//! Checks of a finished mesh, independent of how it was built: fold-overs, non-manifold
//! edges and crossing springs. The construction rules all three out; the report counts them so
//! that a test (or a user) sees it.

use std::collections::HashMap;

use glam::{Vec2, Vec3};

use super::Adjacency;

/// What [`check`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(super) struct MeshCheck {
    /// Triangles whose normal is 90° or more from the mean of their corners' normals.
    pub fold_overs: usize,
    /// Undirected edges with more than two triangles, or two triangles using the same direction.
    pub non_manifold_edges: usize,
    /// Spring pairs that cross (see [`crossings`]).
    pub crossings: usize,
}

/// Checks `triangles` (counter-clockwise around `normals`) and the springs in `adjacency`.
pub(super) fn check(
    positions: &[Vec3],
    normals: &[Vec3],
    triangles: &[[u32; 3]],
    adjacency: &Adjacency,
) -> MeshCheck {
    let p = |i: u32| positions[i as usize];
    let fold_overs = triangles
        .iter()
        .filter(|&&[a, b, c]| {
            let normal = (p(b) - p(a)).cross(p(c) - p(a));
            let mean = normals[a as usize] + normals[b as usize] + normals[c as usize];
            normal.dot(mean) <= 0.0
        })
        .count();
    // Directed edge → triangles using it.
    let mut directed: HashMap<(u32, u32), u32> = HashMap::with_capacity(3 * triangles.len());
    for &[a, b, c] in triangles {
        for e in [(a, b), (b, c), (c, a)] {
            *directed.entry(e).or_default() += 1;
        }
    }
    let non_manifold_edges = directed
        .iter()
        .filter(|&(&(a, b), &count)| {
            let twin = directed.get(&(b, a)).copied().unwrap_or(0);
            // Count each undirected edge once: from its smaller end, or from the larger end when
            // only that direction exists.
            let first = a < b || twin == 0;
            first && (count > 1 || twin > 1)
        })
        .count();
    MeshCheck {
        fold_overs,
        non_manifold_edges,
        crossings: crossings(positions, normals, adjacency),
    }
}

/// Springs closer than this fraction of the shorter one's length, crossing in projection,
/// cross (further apart, they pass each other on different sheets of a curved or thin part).
const CROSSING_GAP: f32 = 0.1;

/// Pairs of springs i–j and a–b (four distinct points, a and b both joined to i) that cross
/// properly in i's tangent plane and pass within [`CROSSING_GAP`] of each other in space.
/// Points more than 60° out of that plane are left out (their projection says nothing).
fn crossings(positions: &[Vec3], normals: &[Vec3], adjacency: &Adjacency) -> usize {
    let mut count = 0;
    let max_elevation = 60f32.to_radians().tan();
    for i in 0..positions.len() {
        let around = adjacency.neighbours(i);
        let (t1, t2) = normals[i].any_orthonormal_pair();
        let flat = |v: u32| {
            let d = positions[v as usize] - positions[i];
            let q = Vec2::new(d.dot(t1), d.dot(t2));
            (d.dot(normals[i]).abs() <= max_elevation * q.length()).then_some(q)
        };
        for &a in around {
            for &b in adjacency.neighbours(a as usize) {
                if b <= a || !around.contains(&b) {
                    continue;
                }
                let (Some(pa), Some(pb)) = (flat(a), flat(b)) else {
                    continue;
                };
                for &j in around {
                    if j == a || j == b {
                        continue;
                    }
                    let Some(pj) = flat(j) else { continue };
                    if segments_cross(Vec2::ZERO, pj, pa, pb) {
                        let p = |v: u32| positions[v as usize];
                        let gap = segment_distance(p(i as u32), p(j), p(a), p(b));
                        let shorter = p(i as u32).distance(p(j)).min(p(a).distance(p(b)));
                        if gap < CROSSING_GAP * shorter {
                            count += 1;
                        }
                    }
                }
            }
        }
    }
    count
}

/// Whether segments p–q and a–b cross at a point inside both.
fn segments_cross(p: Vec2, q: Vec2, a: Vec2, b: Vec2) -> bool {
    let side = |o: Vec2, d: Vec2, x: Vec2| d.perp_dot(x - o);
    side(p, q - p, a) * side(p, q - p, b) < 0.0 && side(a, b - a, p) * side(a, b - a, q) < 0.0
}

/// Shortest distance between segments p–q and a–b.
fn segment_distance(p: Vec3, q: Vec3, a: Vec3, b: Vec3) -> f32 {
    let (d1, d2, r) = (q - p, b - a, p - a);
    let (aa, ee, f) = (d1.length_squared(), d2.length_squared(), d2.dot(r));
    if aa <= f32::EPSILON || ee <= f32::EPSILON {
        return p.distance(a);
    }
    let (c, bb) = (d1.dot(r), d1.dot(d2));
    let denom = aa * ee - bb * bb;
    let mut s = if denom > 0.0 {
        ((bb * f - c * ee) / denom).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut t = (bb * s + f) / ee;
    if t < 0.0 {
        t = 0.0;
        s = (-c / aa).clamp(0.0, 1.0);
    } else if t > 1.0 {
        t = 1.0;
        s = ((bb - c) / aa).clamp(0.0, 1.0);
    }
    (p + d1 * s).distance(a + d2 * t)
}
