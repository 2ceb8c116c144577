//! Which points of a surface are too close on its network to touch each other: a surface
//! meeting itself leaves out the pairs a few springs apart (they are held apart, or
//! together, by the springs, and their spheres overlap at rest).

use glam::Vec3;

use crate::core::network::SpringNetwork;

/// Points this many stretch springs apart (or fewer) do not touch each other in
/// self-contact: one ring (a point and the points it has springs to), together with the
/// pairs whose spheres overlap at rest. Two rings let a tight fold's sides, three springs
/// apart round it, pass through each other at a sheet's corner (`tests/meet.rs`, measured);
/// with one, the next ring (√3 spacings away on a lattice) meets the point only where the
/// sheet is squeezed to under 60 % of its rest size there.
pub const DEFAULT_SELF_CONTACT_RINGS: u32 = 2;

/// Each point's neighbours on the network within a number of stretch springs, and the
/// points whose spheres overlap at rest: the pairs self-contact leaves out.
#[derive(Debug, Clone, Default)]
pub struct NetworkNeighbours {
    /// Where each point's neighbours start in `items` (one more entry than points).
    start: Vec<u32>,
    /// Each point's neighbours, sorted.
    items: Vec<u32>,
    /// Where each point's near triangles start in `triangles`.
    triangle_start: Vec<u32>,
    /// Each point's near triangles (indices into the network's), sorted: those whose
    /// corners are all its neighbours; with the surface's thickness there.
    triangles: Vec<(u32, f32)>,
}

/// A point is kept this share of its rest distance from a near triangle at most (where its
/// sphere's radius is more): so that nothing touches at rest on an uneven network.
const NEAR_TRIANGLE_REST_SHARE: f32 = 0.5;

impl NetworkNeighbours {
    /// The points within `rings` stretch springs of each point of `network`, and those
    /// whose spheres (`radii`, in the network's coordinates) overlap at rest within twice
    /// the largest radius (thin parts whose two sides are close at rest: they do not push
    /// each other apart). A point is not its own neighbour.
    pub fn new(network: &SpringNetwork, rings: u32, radii: &[f32]) -> Self {
        let n = network.len();
        let adjacency = Adjacency::new(n, network);
        let rest = &network.positions;
        let largest = radii.iter().copied().fold(0.0_f32, f32::max);
        let grid = super::PointGrid::new(rest, (2.0 * largest).max(f32::EPSILON));
        let radius = |i: usize| radii.get(i).copied().unwrap_or(0.0);
        let mut start = Vec::with_capacity(n + 1);
        let mut items = Vec::new();
        // Breadth-first search from each point, marking the points met with the source.
        let mut seen = vec![u32::MAX; n];
        let mut frontier = Vec::new();
        let mut next = Vec::new();
        start.push(0);
        for i in 0..n {
            let from = items.len();
            seen[i] = i as u32;
            frontier.clear();
            frontier.push(i as u32);
            for _ in 0..rings {
                next.clear();
                for &p in &frontier {
                    for &q in adjacency.of(p as usize) {
                        if seen[q as usize] != i as u32 {
                            seen[q as usize] = i as u32;
                            next.push(q);
                            items.push(q);
                        }
                    }
                }
                std::mem::swap(&mut frontier, &mut next);
            }
            let r = Vec3::splat(radius(i) + largest);
            grid.near(rest[i] - r, rest[i] + r, |j| {
                if seen[j] != i as u32 && rest[i].distance(rest[j]) < radius(i) + radius(j) {
                    seen[j] = i as u32;
                    items.push(j as u32);
                }
            });
            items[from..].sort_unstable();
            start.push(items.len() as u32);
        }
        let mut neighbours = Self {
            start,
            items,
            triangle_start: Vec::new(),
            triangles: Vec::new(),
        };
        neighbours.find_near_triangles(network, radii);
        neighbours
    }

    /// Each point's near triangles: those not at the point whose corners are all its
    /// neighbours (the triangles a crease could fold over it), each with the thickness the
    /// point keeps from it: its sphere's radius, or less where it is closer at rest.
    fn find_near_triangles(&mut self, network: &SpringNetwork, radii: &[f32]) {
        let n = self.len();
        let valid = |t: &[u32; 3]| t.iter().all(|&c| (c as usize) < n);
        // The triangles at each point.
        let mut at_start = vec![0_u32; n + 1];
        for t in network.triangles.iter().filter(|t| valid(t)) {
            for &c in t {
                at_start[c as usize + 1] += 1;
            }
        }
        for i in 0..n {
            at_start[i + 1] += at_start[i];
        }
        let mut slot = at_start.clone();
        let mut at = vec![0_u32; at_start[n] as usize];
        for (k, t) in network.triangles.iter().enumerate() {
            if valid(t) {
                for &c in t {
                    at[slot[c as usize] as usize] = k as u32;
                    slot[c as usize] += 1;
                }
            }
        }
        self.triangle_start = Vec::with_capacity(n + 1);
        self.triangle_start.push(0);
        let mut triangles = Vec::new();
        let mut found = Vec::new();
        for i in 0..n {
            found.clear();
            for &j in self.of(i) {
                let j = j as usize;
                for &k in &at[at_start[j] as usize..at_start[j + 1] as usize] {
                    let t = network.triangles[k as usize];
                    let near = t.iter().all(|&c| self.contains(i, c as usize));
                    if near && !t.contains(&(i as u32)) {
                        found.push(k);
                    }
                }
            }
            found.sort_unstable();
            found.dedup();
            let radius = radii.get(i).copied().unwrap_or(0.0);
            let rest = &network.positions;
            triangles.extend(found.iter().map(|&k| {
                let [a, b, c] = network.triangles[k as usize].map(|c| rest[c as usize]);
                let (q, _) = super::closest_on_triangle(rest[i], a, b, c);
                (
                    k,
                    radius.min(NEAR_TRIANGLE_REST_SHARE * rest[i].distance(q)),
                )
            }));
            self.triangle_start.push(triangles.len() as u32);
        }
        self.triangles = triangles;
    }

    /// Point `i`'s near triangles (indices into the network's triangles), each with the
    /// thickness self-contact keeps the point from it: those not at the point whose corners
    /// are all its neighbours (none for a point out of range).
    pub fn near_triangles(&self, i: usize) -> &[(u32, f32)] {
        match (
            self.triangle_start.get(i),
            self.triangle_start.get(i.wrapping_add(1)),
        ) {
            (Some(&a), Some(&b)) => &self.triangles[a as usize..b as usize],
            _ => &[],
        }
    }

    /// Whether `j` is one of `i`'s neighbours (false for points out of range).
    pub fn contains(&self, i: usize, j: usize) -> bool {
        u32::try_from(j).is_ok_and(|j| self.of(i).binary_search(&j).is_ok())
    }

    /// Point `i`'s neighbours, sorted (none for a point out of range).
    pub fn of(&self, i: usize) -> &[u32] {
        match (self.start.get(i), self.start.get(i.wrapping_add(1))) {
            (Some(&a), Some(&b)) => &self.items[a as usize..b as usize],
            _ => &[],
        }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.start.len().saturating_sub(1)
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Each point's stretch springs' other ends.
struct Adjacency {
    start: Vec<u32>,
    ends: Vec<u32>,
}

impl Adjacency {
    fn new(n: usize, network: &SpringNetwork) -> Self {
        let springs = || {
            network
                .stretch
                .iter()
                .filter(|s| (s.a as usize) < n && (s.b as usize) < n && s.a != s.b)
        };
        let mut start = vec![0_u32; n + 1];
        for s in springs() {
            start[s.a as usize + 1] += 1;
            start[s.b as usize + 1] += 1;
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut slot = start.clone();
        let mut ends = vec![0; start[n] as usize];
        for s in springs() {
            for (a, b) in [(s.a, s.b), (s.b, s.a)] {
                ends[slot[a as usize] as usize] = b;
                slot[a as usize] += 1;
            }
        }
        Self { start, ends }
    }

    fn of(&self, i: usize) -> &[u32] {
        &self.ends[self.start[i] as usize..self.start[i + 1] as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::network::{NetworkConfig, build_network};
    use crate::core::solver::contact::point_radii;

    #[test]
    fn a_sheets_neighbours_are_its_rings_and_far_points_are_not() {
        let cloud = crate::core::cloud::shapes::square_sheet(1.0, 0.1);
        let network = build_network(
            cloud.positions(),
            cloud.normals().expect("a sheet has normals"),
            &NetworkConfig::default(),
        )
        .expect("a sheet builds");
        let radii = point_radii(&network, 0.5);
        let one = NetworkNeighbours::new(&network, 1, &radii);
        let two = NetworkNeighbours::new(&network, 2, &radii);
        let longest = network
            .stretch
            .iter()
            .map(|s| s.rest_length)
            .fold(0.0_f32, f32::max);
        assert_eq!(two.len(), network.len());
        for i in 0..network.len() {
            for s in network.stretch.iter().filter(|s| s.a as usize == i) {
                assert!(one.contains(i, s.b as usize) && one.contains(s.b as usize, i));
            }
            assert!(!two.contains(i, i), "not its own neighbour");
            assert!(one.of(i).iter().all(|&j| two.contains(i, j as usize)));
            // Nothing beyond two of the longest springs is a neighbour within two rings.
            for &j in two.of(i) {
                let d = network.positions[i].distance(network.positions[j as usize]);
                assert!(d <= 2.0 * longest + 1e-4, "{i} {j} {d}");
            }
        }
        // An inner point of a triangular lattice: its two rings hold 18 points.
        let centre = (0..network.len())
            .min_by(|&a, &b| {
                let c = Vec3::ZERO;
                network.positions[a]
                    .distance(c)
                    .total_cmp(&network.positions[b].distance(c))
            })
            .unwrap();
        assert!(
            (12..=30).contains(&two.of(centre).len()),
            "{}",
            two.of(centre).len()
        );
        // Its near triangles: the two rings' annulus (24 on a lattice), none at the point.
        let near = two.near_triangles(centre);
        assert!((18..=30).contains(&near.len()), "{}", near.len());
        for &(k, thickness) in near {
            assert!(thickness > 0.0 && thickness <= radii[centre]);
            let t = network.triangles[k as usize];
            assert!(!t.contains(&(centre as u32)));
            assert!(t.iter().all(|&c| two.contains(centre, c as usize)));
        }
        // Out of range: nothing, no panic.
        assert!(!two.contains(network.len() + 3, 0) && two.of(usize::MAX).is_empty());
        assert!(two.near_triangles(usize::MAX).is_empty());
    }
}
