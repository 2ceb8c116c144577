//! Surfels: each point drawn as a small disc facing along its normal.
//!
//! The Bevy layer (`plugin::render`, feature `render`) keeps one record per dense point in
//! a GPU storage buffer, rewritten every frame, from which its vertex shader builds the
//! discs; the records are packed here ([`pack_surfels`]) so that the packing is tested and
//! timed without the renderer.

use glam::Vec3;

use crate::core::knn::KnnIndex;

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

#[cfg(test)]
mod tests {
    use super::*;

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
