//! The overlap test between triangles that share no corner: two patches laid over one part
//! of the surface would leave rims no ear can close.

use glam::Vec3;

use super::*;

impl Builder<'_> {
    /// Whether triangle `t` overlaps a triangle of the mesh that shares no corner with it
    /// (those that do are tested by their sectors): both facing within 60° of each other,
    /// near each other along their normals, and overlapping when projected on either's plane.
    pub(super) fn overlaps_apart(&self, t: [u32; 3]) -> bool {
        self.overlaps_apart_at(t, t.map(|i| self.positions[i as usize]))
    }

    /// [`Builder::overlaps_apart`] for the triangle with corners `t` at `tri` (a corner not yet
    /// in the mesh is `u32::MAX`).
    pub(super) fn overlaps_apart_at(&self, t: [u32; 3], tri: [Vec3; 3]) -> bool {
        let p = |i: u32| self.positions[i as usize];
        let (centre, radius) = bounding_sphere(tri);
        let mut plane = None;
        // The corners' neighbours, each once; a triangle is visited at the first of its
        // corners among them.
        let mut around = [0u32; 3 * MAX_SIMPLIFY_K];
        let mut len = 0;
        for v in t.into_iter().filter(|&v| (v as usize) < self.graph.len()) {
            for &j in self.graph.neighbours(v as usize) {
                if len < around.len() {
                    around[len] = j;
                    len += 1;
                }
            }
        }
        let around = &mut around[..len];
        around.sort_unstable();
        let len = partition_dedup(around);
        let around = &around[..len];
        let listed = |c: u32, j: u32| c < j && around.binary_search(&c).is_ok();
        let near = around.iter().flat_map(|&j| {
            self.mesh.wedges[j as usize]
                .iter()
                .filter(move |w| !listed(w.from, j) && !listed(w.to, j))
                .map(move |w| [j, w.from, w.to])
        });
        for u in near {
            if u.iter().any(|c| t.contains(c)) {
                continue;
            }
            let other = u.map(p);
            // Most triangles near the corners are too far to touch: rule them out cheaply.
            let (other_centre, other_radius) = bounding_sphere(other);
            if centre.distance_squared(other_centre) >= (radius + other_radius).powi(2) {
                continue;
            }
            let own = match plane {
                Some(own) => own,
                None => match Plane::of(tri) {
                    Some(own) => *plane.insert(own),
                    None => return false,
                },
            };
            let Some(other_plane) = Plane::of(other) else {
                continue;
            };
            if own.normal.dot(other_plane.normal) > STEEP_COS
                && own.near(other)
                && other_plane.near(tri)
                && own.overlap(tri, other)
                && other_plane.overlap(other, tri)
            {
                return true;
            }
        }
        false
    }
}

impl Builder<'_> {
    /// The triangles at `v`'s nearest neighbours (each as often as it has corners there).
    pub(super) fn triangles_near<'g>(
        &'g self,
        v: u32,
        graph: &'g KnnGraph,
    ) -> impl Iterator<Item = [u32; 3]> + 'g {
        graph.neighbours(v as usize).iter().flat_map(move |&j| {
            self.mesh.wedges[j as usize]
                .iter()
                .map(move |w| [j, w.from, w.to])
        })
    }
}

/// The centroid of a triangle and the distance from it to the farthest corner.
pub(super) fn bounding_sphere(tri: [Vec3; 3]) -> (Vec3, f32) {
    let centre = (tri[0] + tri[1] + tri[2]) / 3.0;
    let radius = tri
        .iter()
        .map(|&q| q.distance_squared(centre))
        .fold(0.0, f32::max);
    (centre, radius.sqrt())
}

/// A triangle's plane, for the overlap test between triangles that share no corner.
#[derive(Clone, Copy)]
struct Plane {
    origin: Vec3,
    normal: Vec3,
    frame: (Vec3, Vec3),
    /// The triangle's longest edge.
    size: f32,
}

impl Plane {
    pub(super) fn of([a, b, c]: [Vec3; 3]) -> Option<Self> {
        let normal = (b - a).cross(c - a).try_normalize()?;
        Some(Self {
            origin: (a + b + c) / 3.0,
            normal,
            frame: normal.any_orthonormal_pair(),
            size: a.distance(b).max(b.distance(c)).max(c.distance(a)),
        })
    }

    /// Whether the centroid of `tri` lies within half this triangle's size of its plane.
    pub(super) fn near(&self, tri: [Vec3; 3]) -> bool {
        let centroid = (tri[0] + tri[1] + tri[2]) / 3.0;
        (centroid - self.origin).dot(self.normal).abs() < 0.5 * self.size
    }

    /// Whether `own` (this plane's triangle) and `other`, projected on this plane, overlap by
    /// more than a sliver (a separating-axis test: no edge direction of either separates them).
    pub(super) fn overlap(&self, own: [Vec3; 3], other: [Vec3; 3]) -> bool {
        let flat = |q: Vec3| {
            let d = q - self.origin;
            glam::Vec2::new(d.dot(self.frame.0), d.dot(self.frame.1))
        };
        let (s, o) = (own.map(flat), other.map(flat));
        let margin = OVERLAP_MARGIN * self.size;
        for tri in [s, o] {
            for i in 0..3 {
                let e = tri[(i + 1) % 3] - tri[i];
                let axis = glam::Vec2::new(-e.y, e.x).normalize_or_zero();
                let range = |t: [glam::Vec2; 3]| {
                    t.iter().fold((f32::MAX, f32::MIN), |(lo, hi), q| {
                        let x = q.dot(axis);
                        (lo.min(x), hi.max(x))
                    })
                };
                let (a, b) = (range(s), range(o));
                if a.1 <= b.0 + margin || b.1 <= a.0 + margin {
                    return false;
                }
            }
        }
        true
    }
}

/// Overlap between triangles sharing no corner below this fraction of a triangle's size
/// (longest edge) is touching, not overlapping: on noisy scans, smaller overlaps are the noise
/// of the points along the normal seen in projection (a tenth closes 45 more loops over the
/// benchmark clouds than a thousandth, and 10 more than a twentieth).
pub const OVERLAP_MARGIN: f32 = 0.1;

/// Whether two sectors around the same point overlap (sharing an end is not overlapping).
pub(super) fn overlaps(a: &Wedge, b: &Wedge) -> bool {
    (b.start - a.start).rem_euclid(TAU) < a.sweep || (a.start - b.start).rem_euclid(TAU) < b.sweep
}

/// Moves the distinct values of the sorted `values` to its front; returns how many there are.
fn partition_dedup(values: &mut [u32]) -> usize {
    let mut len = 0;
    for i in 0..values.len() {
        if i == 0 || values[i] != values[len - 1] {
            values[len] = values[i];
            len += 1;
        }
    }
    len
}
