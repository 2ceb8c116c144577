//! Where the simulation points' rings leave holes: refinement with dense points from the
//! holes' gaps, and a fine mesh over the dense points collapsed onto the simulation points.

use std::borrow::Cow;

use glam::Vec3;

use super::*;

/// Most dense points whose own network [`build_network_over`] builds to repair the holes
/// the simulation points' rings leave (beyond it, holes are left as they are).
pub const MAX_REPAIR_DENSE_POINTS: usize = 250_000;

/// A fine mesh over the dense points collapsed onto the simulation points (see [`collapse`]):
/// the file's faces when they make an oriented manifold, otherwise the dense points' own
/// network when it leaves no more holes than the simulation points' rings left (`holes`).
/// `None` when there is no such mesh (the dense network has more holes, or was not built: the
/// cloud is larger than [`MAX_REPAIR_DENSE_POINTS`] or noisy), or a simulation point is not
/// a dense point (or its projection on a local fit).
pub(super) fn collapsed_from_dense(
    positions: &[Vec3],
    normals: &[Vec3],
    config: &NetworkConfig,
    dense: &DenseSupport,
    holes: &Holes,
) -> Option<SpringNetwork> {
    let (dense_p, dense_n) = (dense.positions, dense.normals);
    if dense_n.len() != dense_p.len() {
        return None;
    }
    let FineMesh {
        positions: fine_p,
        normals: mut fine_n,
        triangles: mut fine_t,
    } = fine_mesh(config, dense, holes)?;
    let (keep, source) = dense_sources(positions, dense, fine_p.len())?;
    // Turn the fine mesh the way most simulation points' normals face.
    let against = source
        .iter()
        .zip(normals)
        .filter(|&(&j, n)| fine_n[j].dot(*n) < 0.0)
        .count();
    if 2 * against > positions.len() {
        fine_t.iter_mut().for_each(|t| t.swap(1, 2));
        fine_n.iter_mut().for_each(|n| *n = -*n);
    }
    // The simulation points keep their own normals (turned the fine mesh's way), so that no
    // collapse folds a triangle over from them.
    let along = |n: Vec3, j: usize| {
        let n = n.normalize_or_zero();
        match n.dot(fine_n[j]) {
            d if d < 0.0 => -n,
            d if d > 0.0 => n,
            _ => fine_n[j],
        }
    };
    let mut corner_n: Vec<Vec3> = (0..fine_p.len())
        .map(|j| dense_n.get(j).map_or(fine_n[j], |&n| along(n, j)))
        .collect();
    for (&j, &n) in source.iter().zip(normals) {
        corner_n[j] = along(n, j);
    }
    let collapsed = collapse::collapse_onto(&fine_p, &corner_n, &fine_t, &keep);
    // Renumber: the simulation points as given, then the dense points left.
    let n = positions.len();
    let mut number = vec![u32::MAX; fine_p.len()];
    for (i, &j) in source.iter().enumerate() {
        number[j] = i as u32;
    }
    let mut added = Vec::with_capacity(collapsed.left.len());
    for (k, &j) in collapsed.left.iter().enumerate() {
        number[j as usize] = (n + k) as u32;
        let j = j as usize;
        added.push(if j < dense_p.len() {
            let (p, normal) = dense.fitted_point(j as u32);
            (p, along(normal, j))
        } else {
            (fine_p[j], corner_n[j])
        });
    }
    let triangles: Vec<[u32; 3]> = collapsed
        .triangles
        .iter()
        .map(|t| t.map(|v| number[v as usize]))
        .collect();
    if triangles.iter().flatten().any(|&v| v == u32::MAX) {
        return None;
    }
    let unit: Vec<Vec3> = normals.iter().map(|v| v.normalize()).collect();
    // Turn each simulation point's normal the way the dense mesh's turns at its source.
    let mut oriented: Vec<Vec3> = unit
        .iter()
        .zip(&source)
        .map(|(&v, &j)| if v.dot(fine_n[j]) < 0.0 { -v } else { v })
        .collect();
    let mut all: Vec<Vec3> = positions.to_vec();
    for &(p, normal) in &added {
        all.push(p);
        oriented.push(normal);
    }
    let mut mesh = mesh::SurfaceMesh::from_triangles(&all, &oriented, &triangles);
    mesh.added = added;
    oriented.truncate(n);
    let graph = KnnIndex::build(positions).knn_graph(positions, config.k.min(n - 1));
    let (mut net, _) = assemble(positions, unit, oriented, &graph, &[], mesh, config).ok()?;
    net.report.collapsed_from_dense = true;
    Some(net)
}

/// A fine mesh over the dense points: positions, unit normals, triangles.
struct FineMesh<'a> {
    positions: Cow<'a, [Vec3]>,
    normals: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
}

/// The fine mesh over the dense points: the file's faces when they make an oriented
/// manifold, else the dense points' own network when it can be built and leaves no more
/// holes than the simulation points' rings left.
fn fine_mesh<'a>(
    config: &NetworkConfig,
    dense: &'a DenseSupport,
    holes: &Holes,
) -> Option<FineMesh<'a>> {
    let (dense_p, dense_n) = (dense.positions, dense.normals);
    if let Some(normals) = collapse::manifold_normals(dense_p, dense.triangles) {
        return Some(FineMesh {
            positions: Cow::Borrowed(dense_p),
            normals,
            triangles: dense.triangles.to_vec(),
        });
    }
    // On a noisy cloud (decided on local fits) the dense points' own rings are far worse
    // than the coarse ones (the CGAL sphere scan: 109 loops at its 21 002 points, projected
    // on their fits or not): not worth a build.
    if dense_p.len() > MAX_REPAIR_DENSE_POINTS || dense.fit_k.is_some() {
        return None;
    }
    let (fine, fine_holes) = build_once(dense_p, dense_n, config, Some(dense)).ok()?;
    if fine_holes.loops.len() > holes.loops.len() {
        return None;
    }
    Some(FineMesh {
        positions: Cow::Owned(fine.positions),
        normals: fine_holes.normals,
        triangles: fine.triangles,
    })
}

/// Which of the fine mesh's `fine_len` vertices are kept (the simulation points), and each
/// simulation point's vertex: the dense point nearest to it (itself, or what was projected
/// on a local fit). `None` when two simulation points share one.
fn dense_sources(
    positions: &[Vec3],
    dense: &DenseSupport,
    fine_len: usize,
) -> Option<(Vec<bool>, Vec<usize>)> {
    let mut keep = vec![false; fine_len];
    let mut source = Vec::with_capacity(positions.len());
    for &p in positions {
        let j = dense.near(p, 1).next()? as usize;
        if std::mem::replace(&mut keep[j], true) {
            return None;
        }
        source.push(j);
    }
    Some((keep, source))
}

/// Rounds of refinement at most (see [`build_network_over`]).
pub const REFINE_ROUNDS: usize = 4;

/// Where refinement probes a hole point's gap for dense points: (fraction of the gap's angle,
/// distance in the hole's mean edge lengths).
const REFINE_PROBES: [(f32, f32); 3] = [(0.25, 0.5), (0.5, 0.5), (0.75, 0.5)];

/// Nearest spacing of the points refinement adds, to each other and to the simulation points,
/// in the hole's mean edge lengths: the hole's region is sampled about twice as finely.
const REFINE_MIN_GAP: f32 = 0.4;

/// The holes a build left, and the normals it oriented the mesh around.
pub(super) struct Holes {
    /// Boundary loops most of whose points are closable, as point indices in the order
    /// [`mesh::SurfaceMesh::boundary_loops`] walks them.
    pub(super) loops: Vec<Vec<u32>>,
    /// The points' unit normals, consistently oriented.
    pub(super) normals: Vec<Vec3>,
}

impl Holes {
    /// Points on holes, counted once per loop through them.
    pub(super) fn points(&self) -> usize {
        self.loops.iter().map(Vec::len).sum()
    }
}

/// The dense points that fill the gaps of the `holes` (loops of indices into `positions`), as
/// simulation points (see [`DenseSupport::fitted_point`]): at each loop point, those nearest to
/// probes in its gap (between the loop's previous and next points, counter-clockwise in its
/// tangent plane) at [`REFINE_PROBES`] of the hole's mean edge, no nearer than
/// [`REFINE_MIN_GAP`] mean edges to a point already there or already added.
pub(super) fn refinement_points(
    positions: &[Vec3],
    holes: &Holes,
    dense: &DenseSupport,
) -> Vec<(Vec3, Vec3)> {
    let index = KnnIndex::build(positions);
    let mut out: Vec<(Vec3, Vec3)> = Vec::new();
    for hole in &holes.loops {
        let m = hole.len();
        let at = |i: usize| positions[hole[i % m] as usize];
        let edge = (0..m).map(|i| at(i).distance(at(i + 1))).sum::<f32>() / m as f32;
        let gap = REFINE_MIN_GAP * edge;
        for (i, &point) in hole.iter().enumerate() {
            let (prev, v, next) = (at(i + m - 1), at(i), at(i + 1));
            let (t1, t2) = holes.normals[point as usize].any_orthonormal_pair();
            let angle = |q: Vec3| {
                let d = q - v;
                d.dot(t2).atan2(d.dot(t1))
            };
            let start = angle(prev);
            let width = (angle(next) - start).rem_euclid(TAU);
            for (turn, reach) in REFINE_PROBES {
                let (sin, cos) = (start + turn * width).sin_cos();
                let probe = v + (t1 * cos + t2 * sin) * reach * edge;
                let Some(j) = dense.near(probe, 1).next() else {
                    continue;
                };
                if dense.point(j).0.distance(probe) > gap {
                    continue; // no dense surface there
                }
                let (q, normal) = dense.fitted_point(j);
                let free = index
                    .nearest(q, 1)
                    .first()
                    .is_some_and(|nb| nb.dist2.sqrt() > gap);
                if free && out.iter().all(|&(o, _)| o.distance(q) > gap) {
                    out.push((q, normal));
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {

    use glam::Vec3;

    use super::{DenseSupport, Holes, REFINE_MIN_GAP, refinement_points};

    #[test]
    fn refinement_samples_a_hole_from_the_dense_points_in_its_gaps() {
        // A dense square 4 × 4 at spacing 0.05; simulation points every 1 around a missing
        // centre: the hole's loop runs around the middle 2 × 2 block.
        let dense: Vec<Vec3> = (0..=80)
            .flat_map(|y| (0..=80).map(move |x| Vec3::new(x as f32, y as f32, 0.0) * 0.05))
            .collect();
        let dense_normals = vec![Vec3::Z; dense.len()];
        let support = DenseSupport::new(&dense, &dense_normals, 0.0, false);
        let positions: Vec<Vec3> = (0..25)
            .map(|i| Vec3::new((i % 5) as f32, (i / 5) as f32, 0.0))
            .filter(|p| *p != Vec3::new(2.0, 2.0, 0.0))
            .collect();
        let normals = vec![Vec3::Z; positions.len()];
        let index = |x: f32, y: f32| {
            positions
                .iter()
                .position(|p| *p == Vec3::new(x, y, 0.0))
                .unwrap() as u32
        };
        // Clockwise around +z (as boundary loops of holes run).
        let hole: Vec<u32> = [
            (1.0, 1.0),
            (1.0, 2.0),
            (1.0, 3.0),
            (2.0, 3.0),
            (3.0, 3.0),
            (3.0, 2.0),
            (3.0, 1.0),
            (2.0, 1.0),
        ]
        .into_iter()
        .map(|(x, y)| index(x, y))
        .collect();
        let holes = Holes {
            loops: vec![hole.clone()],
            normals,
        };
        let added = refinement_points(&positions, &holes, &support);
        assert!(added.len() >= 4, "{added:?}");
        let edge = 1.0;
        for (i, &(p, n)) in added.iter().enumerate() {
            assert_eq!(n, Vec3::Z);
            assert!(
                (0.99..=3.01).contains(&p.x) && (0.99..=3.01).contains(&p.y),
                "{p}"
            );
            for q in positions.iter().chain(added[..i].iter().map(|(q, _)| q)) {
                assert!(
                    p.distance(*q) > REFINE_MIN_GAP * edge - 1e-5,
                    "{p} near {q}"
                );
            }
        }
        // Every point of the hole gets new points in its gap, half an edge in.
        for &v in &hole {
            let p = positions[v as usize];
            assert!(added.iter().any(|(q, _)| q.distance(p) < 0.9 * edge), "{p}");
        }
    }
}
