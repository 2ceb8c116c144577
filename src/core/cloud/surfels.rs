//! Surfels: each point drawn as a small disc facing along its normal.
//!
//! The Bevy layer (`plugin::render`, feature `render`) keeps one record per dense point in
//! a GPU storage buffer, rewritten every frame, from which its vertex shader builds the
//! discs; the records are packed here ([`pack_surfels`]) so that the packing is tested and
//! timed without the renderer.

use glam::Vec3;

use crate::core::cloud::knn::KnnIndex;

/// Neighbours whose farthest sets a surfel's size.
pub const SURFEL_NEIGHBOURS: usize = 6;

/// Default surfel radius as a multiple of the distance to the point's
/// [`SURFEL_NEIGHBOURS`]-th nearest neighbour: discs then overlap their neighbours' even where
/// the sampling is uneven (a latitude-longitude scan is dense along rows, sparse across), so
/// the surface reads as closed.
pub const DEFAULT_SURFEL_SCALE: f32 = 0.75;

/// Bytes of one surfel record: position (3 × f32), radius (f32), normal (3 × f32), padding.
pub const SURFEL_BYTES: usize = 32;

/// Appends one record per point to `out` (little-endian `f32`, the GPU's order): position,
/// radius, normal, a zero. Stops at the shortest of the three inputs.
pub fn pack_surfels(positions: &[Vec3], normals: &[Vec3], radii: &[f32], out: &mut Vec<u8>) {
    let n = positions.len().min(normals.len()).min(radii.len());
    let start = out.len();
    out.resize(start + n * SURFEL_BYTES, 0);
    let records = out[start..].chunks_exact_mut(SURFEL_BYTES);
    for (((p, q), &r), record) in positions.iter().zip(normals).zip(radii).zip(records) {
        let values = [p.x, p.y, p.z, r, q.x, q.y, q.z, 0.0];
        for (bytes, v) in record.chunks_exact_mut(4).zip(values) {
            bytes.copy_from_slice(&v.to_le_bytes());
        }
    }
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
        pack_surfels(&positions, &[Vec3::Z, Vec3::Y], &[0.5, 0.25], &mut out);
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
}
