//! Surfels: each point drawn as a small disc facing along its normal.
//!
//! The Bevy layer (`plugin::render`, feature `render`) keeps one record per dense point in
//! a GPU storage buffer, rewritten every frame, from which its vertex shader builds the
//! discs; the records are packed here ([`pack_surfels`]) so that the packing is tested and
//! timed without the renderer.

use glam::Vec3;

use crate::core::cloud::knn::{KnnGraph, KnnIndex};

/// Neighbours whose farthest sets a surfel's size.
pub const SURFEL_NEIGHBOURS: usize = 6;

/// Default surfel radius as a multiple of the distance to the point's
/// [`SURFEL_NEIGHBOURS`]-th nearest neighbour: discs then overlap their neighbours' even where
/// the sampling is uneven (a latitude-longitude scan is dense along rows, sparse across), so
/// the surface reads as closed.
pub const DEFAULT_SURFEL_SCALE: f32 = 0.75;

/// Bytes of one surfel record: position (3 × f32), radius (f32), normal (3 × f32), edge
/// (u32: 0 where the surface's edge does not cut the disc, see [`edge_word`]).
pub const SURFEL_BYTES: usize = 32;

/// Neighbours that decide whether a point lies on the surface's edge.
pub const EDGE_NEIGHBOURS: usize = 10;

/// The widest gap (radians) between the directions to a point's [`EDGE_NEIGHBOURS`] in its
/// tangent plane above which the point lies on the surface's edge: inside an even sampling
/// the gaps stay under about 90°, on a straight rim they are about 180°.
pub const EDGE_GAP: f32 = 3.0 * std::f32::consts::FRAC_PI_4;

/// The widest gap (radians) around an edge point above which it is a corner (a square
/// sheet's corner leaves 270°), whose disc is not drawn (see [`pack_surfels`]).
pub const CORNER_GAP: f32 = 5.0 * std::f32::consts::FRAC_PI_4;

/// Steps of an [`edge_word`]'s angle (over a turn) and offset (over a radius); `surfel.wgsl`
/// decodes with the same.
pub const EDGE_WORD_STEPS: u32 = 0xffff;

/// The surfels on a surface's edge (a sheet's rim, a hat's brim), each with its neighbours,
/// which all lie on its inner side. Drawn, an edge surfel is cut along the line through its
/// centre across its outward direction, found each frame from where its neighbours are, so
/// that the rim is the line through the edge points instead of a saw-tooth of whole discs.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfelEdges {
    /// The points on the edge, ascending.
    points: Vec<u32>,
    /// Each one's [`EDGE_NEIGHBOURS`] neighbours (fewer in a smaller cloud), in turn.
    neighbours: Vec<u32>,
    /// Neighbours per point.
    k: usize,
}

impl SurfelEdges {
    /// The edge points of a surface at rest (unit `normals`; `graph` their neighbours, built
    /// over `positions`): those whose neighbours leave a gap wider than [`EDGE_GAP`] around
    /// them in their tangent plane.
    fn in_graph(positions: &[Vec3], normals: &[Vec3], graph: &KnnGraph) -> Self {
        let n = positions.len().min(normals.len()).min(graph.len());
        let k = graph.k();
        let mut edges = Self {
            k,
            ..Self::default()
        };
        if k < 2 {
            return edges;
        }
        let mut angles = Vec::with_capacity(k);
        for i in 0..n {
            let normal = normals[i].normalize_or_zero();
            let (t, b) = shader_frame(normal);
            angles.clear();
            angles.extend(graph.neighbours(i).iter().map(|&j| {
                let d = positions[j as usize] - positions[i];
                d.dot(b).atan2(d.dot(t))
            }));
            if widest_gap(&mut angles).1 > EDGE_GAP {
                edges.points.push(i as u32);
                edges.neighbours.extend_from_slice(graph.neighbours(i));
            }
        }
        edges
    }

    /// Number of edge points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether no point lies on an edge (a closed surface).
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The edge points, ascending.
    pub fn points(&self) -> &[u32] {
        &self.points
    }

    /// The edge points, their neighbours (k a point, in turn) and k.
    pub(crate) fn parts(&self) -> (&[u32], &[u32], usize) {
        (&self.points, &self.neighbours, self.k)
    }
}

/// The most a surfel grows where the surface is stretched (times its radius at rest).
pub const MAX_SURFEL_STRETCH: f32 = 4.0;

/// How a surface's surfels are drawn: each one's radius at rest, how far its
/// [`SURFEL_NEIGHBOURS`]-th neighbour was then (the radius grows as the surface stretches
/// away from it, so that stretched regions stay closed), and the edge.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfelShape {
    /// Disc radius of each point at rest.
    radii: Vec<f32>,
    /// Each point's [`SURFEL_NEIGHBOURS`]-th nearest neighbour (itself in a lone point's
    /// cloud), and its distance at rest.
    far: Vec<(u32, f32)>,
    /// The points on the edge.
    edges: SurfelEdges,
}

impl SurfelShape {
    /// The surfels of a surface at rest (unit `normals`), their radii `scale` times the
    /// distance to their [`SURFEL_NEIGHBOURS`]-th neighbour (as [`surfel_radii`]).
    pub fn at_rest(positions: &[Vec3], normals: &[Vec3], scale: f32) -> Self {
        let n = positions.len().min(normals.len());
        let positions = &positions[..n];
        let graph = KnnIndex::build(positions).knn_graph(positions, EDGE_NEIGHBOURS);
        let column = SURFEL_NEIGHBOURS.min(graph.k());
        let far: Vec<(u32, f32)> = (0..n)
            .map(|i| match column.checked_sub(1) {
                Some(c) => (graph.neighbours(i)[c], graph.neighbour_dist2(i)[c].sqrt()),
                None => (i as u32, 1.0),
            })
            .collect();
        Self {
            radii: far.iter().map(|&(_, d)| scale * d).collect(),
            far,
            edges: SurfelEdges::in_graph(positions, normals, &graph),
        }
    }

    /// Number of surfels.
    pub fn len(&self) -> usize {
        self.radii.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.radii.is_empty()
    }

    /// Each surfel's radius at rest.
    pub fn radii(&self) -> &[f32] {
        &self.radii
    }

    /// Each point's far neighbour and its distance at rest.
    pub(crate) fn far(&self) -> &[(u32, f32)] {
        &self.far
    }

    /// The points on the surface's edge.
    pub fn edges(&self) -> &SurfelEdges {
        &self.edges
    }

    /// Surfel `i`'s radius with the surface at `positions`: its rest radius times how much
    /// farther its far neighbour now is (1 to [`MAX_SURFEL_STRETCH`]).
    fn radius(&self, i: usize, positions: &[Vec3]) -> f32 {
        let (j, rest) = self.far[i];
        let now = positions
            .get(j as usize)
            .map_or(rest, |q| q.distance(positions[i]));
        let stretch = if rest > 0.0 { now / rest } else { 1.0 };
        self.radii[i] * stretch.clamp(1.0, MAX_SURFEL_STRETCH)
    }
}

/// The widest gap between `angles` (radians, in (−π, π]; sorted here) going round the
/// circle: the angle it starts at and its width (2π for a single angle).
fn widest_gap(angles: &mut [f32]) -> (f32, f32) {
    angles.sort_by(f32::total_cmp);
    let (Some(&first), Some(&last)) = (angles.first(), angles.last()) else {
        return (0.0, 0.0);
    };
    let wrap = (last, first + std::f32::consts::TAU - last);
    angles
        .windows(2)
        .map(|w| (w[0], w[1] - w[0]))
        .fold(wrap, |best, gap| if gap.1 > best.1 { gap } else { best })
}

/// The tangent frame `surfel.wgsl` builds from a unit normal (Duff et al. 2017), in which
/// an edge surfel's outward angle is given.
fn shader_frame(n: Vec3) -> (Vec3, Vec3) {
    let s = if n.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (s + n.z);
    let t = Vec3::new(1.0 + s * n.x * n.x * a, s * n.x * n.y * a, -s * n.x);
    (t, n.cross(t))
}

/// Appends one record per point to `out` (little-endian, the GPU's order): position,
/// radius (`f32`s; the radius grown where the surface is stretched, see [`SurfelShape`]),
/// normal (`f32`s), and the edge word (`u32`, see [`edge_word`]): 0 for a disc that the
/// surface's edge does not cross. An edge point's disc is cut along the line through its
/// centre across its outward direction (the middle of the widest gap between the directions
/// to its neighbours as they are now); a neighbour's disc that reaches past that line is
/// cut along it too. A corner's disc (a gap wider than [`CORNER_GAP`]) gets radius 0, which
/// draws nothing. Stops at the shortest of the three; edge points past it are skipped.
pub fn pack_surfels(positions: &[Vec3], normals: &[Vec3], shape: &SurfelShape, out: &mut Vec<u8>) {
    let n = positions.len().min(normals.len()).min(shape.len());
    let start = out.len();
    out.resize(start + n * SURFEL_BYTES, 0);
    let records = &mut out[start..];
    for (i, ((p, q), record)) in positions
        .iter()
        .zip(normals)
        .zip(records.chunks_exact_mut(SURFEL_BYTES))
        .enumerate()
    {
        let r = shape.radius(i, positions);
        for (bytes, v) in record
            .chunks_exact_mut(4)
            .zip([p.x, p.y, p.z, r, q.x, q.y, q.z])
        {
            bytes.copy_from_slice(&v.to_le_bytes());
        }
    }
    let edges = &shape.edges;
    if edges.k == 0 {
        return;
    }
    let unit_normal = |i: usize| {
        normals
            .get(i)
            .filter(|_| i < n)
            .map(|v| v.normalize_or_zero())
            .filter(|v| *v != Vec3::ZERO)
    };
    // Each edge point is cut through its centre, and each of its neighbours that is not an
    // edge point itself where its disc reaches past the edge line (the cut nearest its
    // centre kept): an edge point's cut is only ever its own.
    let mut angles = Vec::with_capacity(edges.k);
    for (&i, neighbours) in edges.points.iter().zip(edges.neighbours.chunks(edges.k)) {
        let i = i as usize;
        let Some(normal) = unit_normal(i) else {
            continue;
        };
        let (t, b) = shader_frame(normal);
        angles.clear();
        angles.extend(
            neighbours
                .iter()
                .filter_map(|&j| positions.get(j as usize))
                .map(|&q| q - positions[i])
                .filter(|d| d.is_finite())
                .map(|d| d.dot(b).atan2(d.dot(t))),
        );
        let (start, width) = widest_gap(&mut angles);
        if !(width > 0.0 && width.is_finite()) {
            continue;
        }
        if width > CORNER_GAP {
            // A corner: one cut cannot follow both its edges, and its neighbours' discs,
            // each cut by its own edge, cover it.
            records[i * SURFEL_BYTES + 12..i * SURFEL_BYTES + 16].fill(0);
            continue;
        }
        let angle = start + 0.5 * width;
        let outward = angle.cos() * t + angle.sin() * b;
        cut(records, i, outward, normal, 0.0);
        for &j in neighbours {
            if edges.points.binary_search(&j).is_ok() {
                continue;
            }
            let j = j as usize;
            let Some(normal_j) = unit_normal(j) else {
                continue;
            };
            let inside = (positions[i] - positions[j]).dot(outward);
            let radius = shape.radius(j, positions);
            if inside >= 0.0 && inside < radius {
                cut(records, j, outward, normal_j, inside / radius);
            }
        }
    }
}

/// Cuts surfel `i`'s disc (unit `normal`) along the line `offset` radii out from its centre
/// across `outward` (projected into its plane), unless a cut at most as far out is there.
fn cut(records: &mut [u8], i: usize, outward: Vec3, normal: Vec3, offset: f32) {
    let at = i * SURFEL_BYTES + 28;
    let Some(bytes) = records.get_mut(at..at + 4) else {
        return;
    };
    let old = u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]);
    if old != 0 && edge_offset(old) <= offset {
        return;
    }
    let outward = outward - normal * outward.dot(normal);
    let (t, b) = shader_frame(normal);
    let angle = outward.dot(b).atan2(outward.dot(t));
    if outward.length_squared() > 0.0 && angle.is_finite() {
        bytes.copy_from_slice(&edge_word(angle, offset).to_le_bytes());
    }
}

/// The edge word of a disc cut across the direction at `angle` (radians, in [−π, π], in
/// the tangent frame `surfel.wgsl` builds) at `offset` radii from its centre (0 to 1): the
/// angle in the high 16 bits, the offset plus one in the low 16 (so a cut is never 0).
pub fn edge_word(angle: f32, offset: f32) -> u32 {
    use std::f32::consts::{PI, TAU};
    let a = ((angle + PI) / TAU * EDGE_WORD_STEPS as f32).round() as u32;
    let o = (offset.clamp(0.0, 1.0) * (EDGE_WORD_STEPS - 1) as f32).round() as u32 + 1;
    (a.min(EDGE_WORD_STEPS) << 16) | o
}

/// The angle (radians) an edge word cuts across.
pub fn edge_angle(word: u32) -> f32 {
    use std::f32::consts::{PI, TAU};
    (word >> 16) as f32 / EDGE_WORD_STEPS as f32 * TAU - PI
}

/// The offset (radii from the centre) at which an edge word cuts.
pub fn edge_offset(word: u32) -> f32 {
    (word & 0xffff).saturating_sub(1) as f32 / (EDGE_WORD_STEPS - 1) as f32
}

/// How far two packings of the same surfels (see [`pack_surfels`]) are apart: the GPU
/// transfer's records against the CPU's, say.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RecordDifferences {
    /// Records compared.
    pub records: usize,
    /// Largest distance between positions.
    pub position: f32,
    /// Largest distance between normals.
    pub normal: f32,
    /// Largest difference between radii, relative to the second record's.
    pub radius: f32,
    /// Records the second packing cuts along an edge.
    pub edges: usize,
    /// Edge words that differ at all.
    pub edge_words_differ: usize,
    /// Edge words that differ by more than one step in angle or offset (or where only one
    /// record is cut): more than rounding.
    pub edge_words_apart: usize,
}

/// Compares two packings record by record (as many records as the shorter holds).
pub fn compare_records(a: &[u8], b: &[u8]) -> RecordDifferences {
    let word = |r: &[u8], w: usize| {
        u32::from_le_bytes([r[4 * w], r[4 * w + 1], r[4 * w + 2], r[4 * w + 3]])
    };
    let float = |r: &[u8], w: usize| f32::from_bits(word(r, w));
    let vector = |r: &[u8], w: usize| Vec3::new(float(r, w), float(r, w + 1), float(r, w + 2));
    let steps = |w: u32| (i64::from(w >> 16), i64::from(w & 0xffff));
    let mut d = RecordDifferences::default();
    for (x, y) in a
        .chunks_exact(SURFEL_BYTES)
        .zip(b.chunks_exact(SURFEL_BYTES))
    {
        d.records += 1;
        d.position = d.position.max(vector(x, 0).distance(vector(y, 0)));
        d.normal = d.normal.max(vector(x, 4).distance(vector(y, 4)));
        let (rx, ry) = (float(x, 3), float(y, 3));
        d.radius = d
            .radius
            .max((rx - ry).abs() / ry.abs().max(f32::MIN_POSITIVE));
        let (wx, wy) = (word(x, 7), word(y, 7));
        d.edges += usize::from(wy != 0);
        d.edge_words_differ += usize::from(wx != wy);
        let ((ax, ox), (ay, oy)) = (steps(wx), steps(wy));
        // The angle wraps round at ±π.
        let angle = (ax - ay)
            .abs()
            .min(i64::from(EDGE_WORD_STEPS) - (ax - ay).abs());
        if (wx == 0) != (wy == 0) || angle > 1 || (ox - oy).abs() > 1 {
            d.edge_words_apart += 1;
        }
    }
    d
}

/// Each point's surfel radius: `scale` times the distance to its [`SURFEL_NEIGHBOURS`]-th
/// nearest neighbour (or to its farthest one in a smaller cloud; `scale` for a lone point).
pub fn surfel_radii(positions: &[Vec3], scale: f32) -> Vec<f32> {
    let graph = KnnIndex::build(positions).knn_graph(positions, SURFEL_NEIGHBOURS);
    (0..positions.len())
        .map(|i| {
            let far = graph.neighbour_dist2(i).last().map_or(1.0, |d2| d2.sqrt());
            scale * far
        })
        .collect()
}

/// Where a ray first meets a surfel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfelHit {
    /// The surfel's point.
    pub index: usize,
    /// Distance along the ray, in lengths of its direction.
    pub distance: f32,
    /// Where the ray meets the surfel's disc.
    pub position: Vec3,
    /// The surfel's unit normal, turned towards the ray's origin.
    pub normal: Vec3,
}

/// The first surfel (disc of `radii[i]` about `positions[i]`, facing along `normals[i]`, seen
/// from either side) that the ray from `origin` along `direction` meets, at most `max_distance`
/// along it. Every disc is tested (a pick is one ray per pointer per frame; 10^5 surfels take
/// well under a millisecond); points with a zero or non-finite normal or radius are skipped.
pub fn ray_cast_surfels(
    positions: &[Vec3],
    normals: &[Vec3],
    radii: &[f32],
    origin: Vec3,
    direction: Vec3,
    max_distance: f32,
) -> Option<SurfelHit> {
    let mut best: Option<SurfelHit> = None;
    for (index, ((&p, &n), &r)) in positions.iter().zip(normals).zip(radii).enumerate() {
        let facing = n.dot(direction);
        // Edge-on (or a degenerate normal): the disc has no area along the ray.
        if facing.abs() <= f32::EPSILON || !r.is_finite() || r <= 0.0 {
            continue;
        }
        let distance = (p - origin).dot(n) / facing;
        let limit = best.map_or(max_distance, |b| b.distance);
        if !(distance >= 0.0 && distance < limit) {
            continue;
        }
        let position = origin + direction * distance;
        if position.distance_squared(p) <= r * r {
            let normal = n.normalize_or_zero() * -facing.signum();
            best = Some(SurfelHit {
                index,
                distance,
                position,
                normal,
            });
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use std::f32::consts::{FRAC_PI_2, PI};

    use super::*;

    #[test]
    fn a_ray_meets_the_nearest_disc_it_passes_through() {
        // Three discs stacked along z, radius 0.5; a fourth off to the side.
        let positions = [
            Vec3::Z * 2.0,
            Vec3::Z,
            Vec3::Z * 3.0,
            Vec3::new(5.0, 0.0, 1.5),
        ];
        let normals = [Vec3::Z, -Vec3::Z, Vec3::Z, Vec3::Z];
        let radii = [0.5; 4];
        let down = |x: f32| {
            ray_cast_surfels(
                &positions,
                &normals,
                &radii,
                Vec3::new(x, 0.0, 10.0),
                -Vec3::Z,
                f32::INFINITY,
            )
        };
        let hit = down(0.2).unwrap();
        assert_eq!(hit.index, 2);
        assert!((hit.distance - 7.0).abs() < 1e-5);
        assert!((hit.position - Vec3::new(0.2, 0.0, 3.0)).length() < 1e-5);
        assert_eq!(hit.normal, Vec3::Z, "towards the ray's origin");
        assert!(down(0.6).is_none(), "outside every radius");
        assert_eq!(down(5.0).unwrap().index, 3);
        // From below, the back of a disc is hit too, and its normal turned to the ray.
        let up = ray_cast_surfels(&positions, &normals, &radii, Vec3::ZERO, Vec3::Z, 10.0);
        let up = up.unwrap();
        assert_eq!((up.index, up.normal), (1, -Vec3::Z));
        // Not beyond the limit, not behind the origin.
        let short = ray_cast_surfels(&positions, &normals, &radii, Vec3::ZERO, Vec3::Z, 0.9);
        assert!(short.is_none());
        let behind = ray_cast_surfels(&positions, &normals, &radii, Vec3::Z * 4.0, Vec3::Z, 9.0);
        assert!(behind.is_none());
        // An edge-on ray, a zero radius or normal: nothing.
        let edge = ray_cast_surfels(&positions, &normals, &radii, Vec3::Z * 2.0, Vec3::X, 9.0);
        assert!(edge.is_none());
        let none = ray_cast_surfels(
            &positions,
            &[Vec3::ZERO; 4],
            &radii,
            Vec3::Z * 9.0,
            -Vec3::Z,
            99.0,
        );
        assert!(none.is_none());
    }

    #[test]
    fn records_hold_position_radius_and_normal() {
        let mut out = vec![7u8];
        let positions = [Vec3::new(1.0, 2.0, 3.0), Vec3::X];
        // Each point's far neighbour itself: never stretched, the rest radii as they are.
        let shape = SurfelShape {
            radii: vec![0.5, 0.25],
            far: vec![(0, 1.0), (1, 1.0)],
            edges: SurfelEdges::default(),
        };
        pack_surfels(&positions, &[Vec3::Z, Vec3::Y], &shape, &mut out);
        assert_eq!(out.len(), 1 + 2 * SURFEL_BYTES);
        let floats: Vec<f32> = out[1..]
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        assert_eq!(&floats[..8], &[1.0, 2.0, 3.0, 0.5, 0.0, 0.0, 1.0, 0.0]);
        assert_eq!(&floats[8..], &[1.0, 0.0, 0.0, 0.25, 0.0, 1.0, 0.0, 0.0]);
    }

    #[test]
    fn radii_follow_local_spacing() {
        // A dense row and a sparse one: each point's disc scales with its own neighbourhood.
        let mut pts: Vec<Vec3> = (0..20)
            .map(|i| Vec3::new(i as f32 * 0.1, 0.0, 0.0))
            .collect();
        pts.extend((0..20).map(|i| Vec3::new(i as f32, 50.0, 0.0)));
        let r = surfel_radii(&pts, 1.0);
        assert!((r[10] - 0.3).abs() < 1e-4, "{}", r[10]);
        assert!((r[30] - 3.0).abs() < 1e-3, "{}", r[30]);
        assert_eq!(surfel_radii(&[Vec3::ZERO], 0.5), vec![0.5]);
    }

    /// The edge word of each record.
    fn edge_words(out: &[u8]) -> Vec<u32> {
        out.chunks_exact(SURFEL_BYTES)
            .map(|r| u32::from_le_bytes([r[28], r[29], r[30], r[31]]))
            .collect()
    }

    #[test]
    fn a_sheets_rim_is_its_edge_and_each_edge_surfel_points_out() {
        // A 12 × 12 grid in the plane z = 0, jittered a little.
        let side = 12;
        let positions: Vec<Vec3> = (0..side * side)
            .map(|i| {
                let (x, y) = ((i % side) as f32, (i / side) as f32);
                let jitter = ((i * 7919) % 13) as f32 * 0.01;
                Vec3::new(x + jitter, y - jitter, 0.0)
            })
            .collect();
        let normals = vec![Vec3::Z; positions.len()];
        let shape = SurfelShape::at_rest(&positions, &normals, DEFAULT_SURFEL_SCALE);
        let edges = shape.edges();
        let rim: Vec<u32> = (0..side * side)
            .filter(|i| {
                let (x, y) = (i % side, i / side);
                x == 0 || y == 0 || x == side - 1 || y == side - 1
            })
            .map(|i| i as u32)
            .collect();
        assert_eq!(edges.points(), rim.as_slice());
        let mut out = Vec::new();
        pack_surfels(&positions, &normals, &shape, &mut out);
        let words = edge_words(&out);
        // In the shader's frame for +z, t = +x and b = +y.
        let angle = |x: usize, y: usize| edge_angle(words[y * side + x]);
        for (x, y) in [(side - 1, 5), (5, side - 1), (0, 5), (5, 0)] {
            assert_eq!(
                edge_offset(words[y * side + x]),
                0.0,
                "cut through its centre"
            );
        }
        assert!(
            angle(side - 1, 5).abs() < 0.2,
            "right: {}",
            angle(side - 1, 5)
        );
        assert!((angle(5, side - 1) - FRAC_PI_2).abs() < 0.2, "top");
        assert!((angle(0, 5).abs() - PI).abs() < 0.2, "left");
        assert!((angle(5, 0) + FRAC_PI_2).abs() < 0.2, "bottom");
        let radius_at = |i: usize| {
            let r = &out[i * SURFEL_BYTES + 12..i * SURFEL_BYTES + 16];
            f32::from_le_bytes([r[0], r[1], r[2], r[3]])
        };
        assert_eq!(radius_at(side * side - 1), 0.0, "a corner draws nothing");
        assert!(radius_at(side * side - 2) > 0.0);
        assert_eq!(words[5 * side + 5], 0, "inside: no cut");
        // The row behind the right edge (a spacing in, discs of 0.75 × √2 spacings): cut
        // where they reach past the edge line, 1/1.06 of a radius out.
        let behind = words[5 * side + side - 2];
        assert!(edge_angle(behind).abs() < 0.2, "{}", edge_angle(behind));
        let offset = edge_offset(behind);
        assert!((0.8..1.0).contains(&offset), "{offset}");
        assert_eq!(words[5 * side + side - 4], 0, "three rows in: no cut");
        // Moved as a whole (turned a quarter about z), the directions turn with it.
        let turned: Vec<Vec3> = positions
            .iter()
            .map(|p| Vec3::new(-p.y, p.x, 0.0))
            .collect();
        let mut out = Vec::new();
        pack_surfels(&turned, &normals, &shape, &mut out);
        let words = edge_words(&out);
        let right = edge_angle(words[5 * side + side - 1]);
        assert!(
            (right - FRAC_PI_2).abs() < 0.2,
            "turned right edge: {right}"
        );
        // Turned, the discs keep their size; stretched twice as long along x, they grow
        // (the 6th neighbour of a grid point is a diagonal one: √5/√2 = 1.58 times as far).
        let radius = |out: &[u8], i: usize| {
            let r = &out[i * SURFEL_BYTES + 12..i * SURFEL_BYTES + 16];
            f32::from_le_bytes([r[0], r[1], r[2], r[3]])
        };
        let middle = 5 * side + 5;
        let kept = radius(&out, middle) / shape.radii()[middle];
        assert!((kept - 1.0).abs() < 1e-5, "turned: {kept}");
        let stretched: Vec<Vec3> = positions
            .iter()
            .map(|p| p * Vec3::new(2.0, 1.0, 1.0))
            .collect();
        let mut out = Vec::new();
        pack_surfels(&stretched, &normals, &shape, &mut out);
        let grown = radius(&out, middle) / shape.radii()[middle];
        assert!((1.4..=2.0).contains(&grown), "grown {grown} times");
    }

    #[test]
    fn a_closed_surface_has_no_edge() {
        let sphere = crate::core::cloud::shapes::fibonacci_sphere(2000, 1.0);
        let normals = sphere.normals().unwrap();
        let shape = SurfelShape::at_rest(sphere.positions(), normals, DEFAULT_SURFEL_SCALE);
        assert!(shape.edges().is_empty());
    }

    #[test]
    fn edge_words_round_trip() {
        for angle in [-PI, -1.0, 0.0, 0.5, PI] {
            for offset in [0.0, 0.25, 1.0] {
                let word = edge_word(angle, offset);
                assert_ne!(word, 0);
                assert!((edge_angle(word) - angle).abs() < 1e-4);
                assert!((edge_offset(word) - offset).abs() < 1e-4);
            }
        }
    }
}
