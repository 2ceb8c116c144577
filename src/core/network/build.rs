//! One build of the network: the local rings voted into one mesh, then springs, masses,
//! rings and the report assembled on that mesh.

use std::borrow::Cow;

use glam::Vec3;
use rayon::prelude::*;

use super::*;

/// One build of [`build_network_over`]: the network, and the holes it left.
pub(super) fn build_once(
    positions: &[Vec3],
    normals: &[Vec3],
    config: &NetworkConfig,
    dense: Option<&DenseSupport>,
) -> Result<(SpringNetwork, Holes), NetworkError> {
    validate(positions, normals, config)?;
    let n = positions.len();
    let k = config.k.min(n - 1);
    let normals: Vec<Vec3> = normals.iter().map(|v| v.normalize()).collect();
    let index = KnnIndex::build(positions);
    let graph = index.knn_graph(positions, k);
    let oriented = oriented_normals(positions, &normals, &graph)?;

    // 1. Local rings, and their faces as candidate triangles.
    let local: Vec<(RingShape, Vec<(u32, bool)>)> = (0..n)
        .into_par_iter()
        .with_min_len(256)
        .map_init(
            || (RingBuilder::new(), Vec::with_capacity(k)),
            |(builder, scratch), i| {
                let row = graph.neighbours(i);
                scratch.clear();
                scratch.extend(row.iter().map(|&j| positions[j as usize]));
                let mut ring = Vec::new();
                let shape = builder.build(
                    positions[i],
                    oriented[i],
                    scratch,
                    (i as u32, row),
                    Some(&mut ring),
                );
                let ring = ring
                    .into_iter()
                    .map(|(slot, face)| (row[slot as usize], face))
                    .collect();
                (shape, ring)
            },
        )
        .collect();
    if let Some(i) = local.iter().position(|(s, _)| s.coincident) {
        let j = graph
            .neighbours(i)
            .iter()
            .copied()
            .find(|&j| positions[j as usize] == positions[i])
            .unwrap_or(graph.neighbours(i)[0]);
        return Err(NetworkError::CoincidentPoints(
            (i as u32).min(j),
            (i as u32).max(j),
        ));
    }
    if local.iter().all(|(s, _)| s.degenerate) {
        return Err(NetworkError::NotASurface);
    }
    let mut candidates = Vec::new();
    for (i, (_, ring)) in local.iter().enumerate() {
        let m = ring.len();
        for (r, &(a, face)) in ring.iter().enumerate() {
            if face && m > 1 {
                candidates.push([i as u32, a, ring[(r + 1) % m].0]);
            }
        }
    }
    let closable: Vec<bool> = local
        .iter()
        .map(|(s, _)| !s.degenerate && (!s.open || s.surrounded))
        .collect();

    // 2–3. One oriented mesh from the rings, holes closed.
    let mesh = mesh::build_mesh(positions, &oriented, &graph, candidates, &closable, dense);
    let diameters: Vec<f32> = local.iter().map(|(s, _)| s.diameter).collect();
    assemble(
        positions, normals, oriented, &graph, &diameters, mesh, config,
    )
}

/// The network on the `mesh` over the points (`normals` unit, `oriented` consistently, as the
/// mesh's triangles turn around them): springs, masses, rings and the report. `graph` holds
/// the given points' nearest neighbours, for stragglers; `diameters` their rings' d.
pub(super) fn assemble(
    positions: &[Vec3],
    normals: Vec<Vec3>,
    oriented: Vec<Vec3>,
    graph: &KnnGraph,
    diameters: &[f32],
    mesh: mesh::SurfaceMesh,
    config: &NetworkConfig,
) -> Result<(SpringNetwork, Holes), NetworkError> {
    // Points that fill holes join the simulation points.
    let sampled = positions.len();
    let (positions, oriented, normals) = with_filling_points(positions, oriented, normals, &mesh);
    let positions: &[Vec3] = &positions;
    let n = positions.len();
    let triangles = mesh.triangles();
    let mut edges = edges_of(&triangles);
    let mesh_edges = edges.len();

    // Stragglers: tie to the nearest points until MIN_STRETCH_SPRINGS.
    let mut adjacency = Adjacency::new(n, &edges);
    let fallback_springs = tie_stragglers(graph, sampled, n, &mut edges, &mut adjacency);

    // Rings, CCW around each point's own normal, starting after the widest gap.
    let rings: Vec<Vec<u32>> = (0..n)
        .into_par_iter()
        .with_min_len(256)
        .map(|i| final_ring(positions, normals[i], i, adjacency.neighbours(i), &mesh))
        .collect();
    let boundary: Vec<bool> = (0..n).map(|i| mesh.is_open(i)).collect();

    // 4. Masses: a third of each triangle's area to each corner.
    let (areas, masses, fallback_masses) = masses_of(positions, &triangles, config.density)?;

    // Springs: stretch along every edge; bend between the far corners of the two triangles
    // at each inner edge (ring vertices r and r + 2 around either end).
    let (stretch, bend) = springs_of(positions, &edges, &mesh);

    // Report.
    let finite_d = || diameters.iter().copied().filter(|d| d.is_finite());
    let check = check::check(positions, &oriented, &triangles, &adjacency);
    let boundary_points = boundary.iter().filter(|b| **b).count();
    let isolated_points = mesh.wedges.iter().filter(|w| w.is_empty()).count();
    let boundary_loops = mesh.boundary_loops().len();
    let euler_characteristic = n as i64 - mesh_edges as i64 + triangles.len() as i64;
    let report = NetworkReport {
        points: n,
        stretch_springs: stretch.len(),
        bend_springs: bend.len(),
        triangles: triangles.len(),
        boundary_points,
        boundary_loops,
        closed: boundary_points == 0 && check.non_manifold_edges == 0,
        euler_characteristic,
        components: count_components(n, edges.iter().copied()),
        non_manifold_edges: check.non_manifold_edges,
        non_manifold_points: mesh.pinched_points(),
        fold_overs: check.fold_overs,
        crossings: check.crossings,
        total_mass: masses.iter().map(|m| f64::from(*m)).sum::<f64>() as f32,
        area: areas.iter().sum::<f64>() as f32,
        dense_area: 0.0,
        min_diameter: finite_d().fold(f32::INFINITY, f32::min),
        max_diameter: finite_d().fold(0.0, f32::max),
        candidates: mesh.stats.candidates,
        disputed_candidates: mesh.stats.disputed,
        closing_triangles: mesh.stats.ears,
        inserted_points: mesh.stats.inserted,
        filling_points: mesh.added.len(),
        isolated_points,
        collapsed_from_dense: false,
        fallback_springs,
        fallback_masses,
    };
    let (ring_offsets, ring_indices) = flatten_rings(&rings);
    let network = SpringNetwork {
        positions: positions.to_vec(),
        normals,
        masses,
        stretch,
        bend,
        triangles,
        boundary,
        ring_offsets,
        ring_indices,
        report,
    };
    let holes = Holes {
        loops: mesh.holes,
        normals: oriented,
    };
    Ok((network, holes))
}

/// The points with the mesh's filling points after them, and their normals likewise.
fn with_filling_points<'a>(
    positions: &'a [Vec3],
    mut oriented: Vec<Vec3>,
    mut normals: Vec<Vec3>,
    mesh: &mesh::SurfaceMesh,
) -> (Cow<'a, [Vec3]>, Vec<Vec3>, Vec<Vec3>) {
    if mesh.added.is_empty() {
        return (Cow::Borrowed(positions), oriented, normals);
    }
    let mut positions = positions.to_vec();
    for &(p, normal) in &mesh.added {
        positions.push(p);
        oriented.push(normal);
        normals.push(normal);
    }
    (Cow::Owned(positions), oriented, normals)
}

/// The triangles' edges, each once, sorted.
fn edges_of(triangles: &[[u32; 3]]) -> Vec<(u32, u32)> {
    let mut edges: Vec<(u32, u32)> = triangles
        .iter()
        .flat_map(|&[a, b, c]| [key(a, b), key(b, c), key(c, a)])
        .collect();
    edges.par_sort_unstable();
    edges.dedup();
    edges
}

/// Ties each of the first `sampled` of `n` points left with fewer than [`MIN_STRETCH_SPRINGS`]
/// springs to its nearest points in `graph` until it has that many: the new edges join
/// `edges` (kept sorted) and `adjacency`. Returns how many were added.
fn tie_stragglers(
    graph: &KnnGraph,
    sampled: usize,
    n: usize,
    edges: &mut Vec<(u32, u32)>,
    adjacency: &mut Adjacency,
) -> usize {
    let mut degree: Vec<usize> = (0..n).map(|i| adjacency.degree(i)).collect();
    let mut added: Vec<(u32, u32)> = Vec::new();
    let mut added_set: std::collections::HashSet<(u32, u32)> = std::collections::HashSet::new();
    for i in 0..sampled {
        for &j in graph.neighbours(i) {
            if degree[i] >= MIN_STRETCH_SPRINGS {
                break;
            }
            let e = key(i as u32, j);
            if !adjacency.neighbours(i).contains(&j) && added_set.insert(e) {
                added.push(e);
                degree[i] += 1;
                degree[j as usize] += 1;
            }
        }
    }
    let fallback_springs = added.len();
    if !added.is_empty() {
        edges.extend(added);
        edges.sort_unstable();
        *adjacency = Adjacency::new(n, edges);
    }
    fallback_springs
}

/// Eq 1: each point's area (a third of each of its triangles) and mass (`density` × area;
/// the mean area where a point has none), and how many points got the mean.
pub(super) fn masses_of(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    density: f32,
) -> Result<(Vec<f64>, Vec<f32>, usize), NetworkError> {
    let mut areas = vec![0.0f64; positions.len()];
    for &[a, b, c] in triangles {
        let p = |i: u32| positions[i as usize];
        let third = f64::from((p(b) - p(a)).cross(p(c) - p(a)).length()) / 6.0;
        for v in [a, b, c] {
            areas[v as usize] += third;
        }
    }
    let positive: Vec<f64> = areas.iter().copied().filter(|a| *a > 0.0).collect();
    if positive.is_empty() {
        return Err(NetworkError::NotASurface);
    }
    let mean_area = positive.iter().sum::<f64>() / positive.len() as f64;
    let fallback_masses = areas.len() - positive.len();
    let masses: Vec<f32> = areas
        .iter()
        .map(|&a| density * (if a > 0.0 { a } else { mean_area }) as f32)
        .collect();
    Ok((areas, masses, fallback_masses))
}

/// Stretch springs along every edge (sorted), and bend springs between the far corners of
/// the two triangles at each inner edge of `mesh` that no edge already joins.
fn springs_of(
    positions: &[Vec3],
    edges: &[(u32, u32)],
    mesh: &mesh::SurfaceMesh,
) -> (Vec<Spring>, Vec<Spring>) {
    let length = |a: u32, b: u32| positions[a as usize].distance(positions[b as usize]);
    let spring = |(a, b): (u32, u32)| Spring {
        a,
        b,
        rest_length: length(a, b),
    };
    let stretch: Vec<Spring> = edges.iter().copied().map(spring).collect();
    let mut bend_pairs: Vec<(u32, u32)> = mesh
        .wings()
        .filter(|&(a, b)| a != b && edges.binary_search(&key(a, b)).is_err())
        .map(|(a, b)| key(a, b))
        .collect();
    bend_pairs.sort_unstable();
    bend_pairs.dedup();
    let bend: Vec<Spring> = bend_pairs.into_iter().map(spring).collect();
    (stretch, bend)
}

/// The rings laid end to end: offsets (one more than rings) and indices.
fn flatten_rings(rings: &[Vec<u32>]) -> (Vec<u32>, Vec<u32>) {
    let mut ring_offsets = Vec::with_capacity(rings.len() + 1);
    ring_offsets.push(0u32);
    let mut ring_indices = Vec::new();
    for ring in rings {
        ring_indices.extend_from_slice(ring);
        ring_offsets.push(ring_indices.len() as u32);
    }
    (ring_offsets, ring_indices)
}

/// An undirected edge as (smaller, larger).
pub(super) fn key(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

/// Neighbour lists of an undirected edge set.
pub(super) struct Adjacency {
    offsets: Vec<u32>,
    targets: Vec<u32>,
}

impl Adjacency {
    pub(super) fn new(n: usize, edges: &[(u32, u32)]) -> Self {
        let mut offsets = vec![0u32; n + 1];
        for &(a, b) in edges {
            offsets[a as usize + 1] += 1;
            offsets[b as usize + 1] += 1;
        }
        for i in 0..n {
            offsets[i + 1] += offsets[i];
        }
        let mut fill = offsets.clone();
        let mut targets = vec![0u32; offsets[n] as usize];
        for &(a, b) in edges {
            targets[fill[a as usize] as usize] = b;
            fill[a as usize] += 1;
            targets[fill[b as usize] as usize] = a;
            fill[b as usize] += 1;
        }
        Self { offsets, targets }
    }

    pub(super) fn neighbours(&self, i: usize) -> &[u32] {
        &self.targets[self.offsets[i] as usize..self.offsets[i + 1] as usize]
    }

    pub(super) fn degree(&self, i: usize) -> usize {
        self.neighbours(i).len()
    }
}

/// The ring of point `i`: its `neighbours` sorted counter-clockwise around `normal`, starting
/// after the widest sector that is not one of the mesh's triangles when there is one.
fn final_ring(
    positions: &[Vec3],
    normal: Vec3,
    i: usize,
    neighbours: &[u32],
    mesh: &mesh::SurfaceMesh,
) -> Vec<u32> {
    let centre = positions[i];
    let (t1, t2) = normal.any_orthonormal_pair();
    let angle = |j: u32| {
        let v = positions[j as usize] - centre;
        v.dot(t2).atan2(v.dot(t1))
    };
    let mut by_angle: Vec<(f32, u32)> = neighbours.iter().map(|&j| (angle(j), j)).collect();
    by_angle.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let m = by_angle.len();
    let gap = |r: usize| {
        let (a, b) = (by_angle[r].1, by_angle[(r + 1) % m].1);
        if mesh.has_wedge(i, a, b) || mesh.has_wedge(i, b, a) {
            None
        } else {
            Some((by_angle[(r + 1) % m].0 - by_angle[r].0).rem_euclid(TAU))
        }
    };
    let start = (0..m)
        .filter_map(|r| gap(r).map(|g| (g, r)))
        .max_by(|a, b| a.0.total_cmp(&b.0).then(b.1.cmp(&a.1)))
        .map_or(0, |(_, r)| (r + 1) % m);
    (0..m).map(|r| by_angle[(start + r) % m].1).collect()
}

/// Connected components of `n` points joined by `edges` (union-find).
fn count_components(n: usize, edges: impl Iterator<Item = (u32, u32)>) -> usize {
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn find(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            let up = parent[parent[x as usize] as usize];
            parent[x as usize] = up;
            x = up;
        }
        x
    }
    let mut components = n;
    for (a, b) in edges {
        let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
        if ra != rb {
            parent[ra.max(rb) as usize] = ra.min(rb);
            components -= 1;
        }
    }
    components
}
