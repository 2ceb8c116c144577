//! Surfel geometry: each point drawn as a small disc facing along its normal.
//!
//! The Bevy layer (`plugin::render`, feature `render`) turns [`SurfelGeometry`] into one mesh
//! per surface; keeping the geometry here lets it be tested without the renderer.

use glam::Vec3;

use crate::core::knn::KnnIndex;

/// Rim vertices of each surfel disc.
pub const SURFEL_SIDES: usize = 6;

/// Neighbours whose farthest sets a surfel's size.
pub const SURFEL_NEIGHBOURS: usize = 6;

/// Default surfel radius as a multiple of the distance to the point's
/// [`SURFEL_NEIGHBOURS`]-th nearest neighbour: discs then overlap their neighbours' even where
/// the sampling is uneven (a latitude-longitude scan is dense along rows, sparse across), so
/// the surface reads as closed.
pub const DEFAULT_SURFEL_SCALE: f32 = 0.75;

/// Triangle-list geometry of a set of surfels.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfelGeometry {
    /// Vertex positions: per surfel its centre, then its rim.
    pub positions: Vec<[f32; 3]>,
    /// Vertex normals: the surfel's normal at each of its vertices.
    pub normals: Vec<[f32; 3]>,
    /// Triangle indices, counter-clockwise seen from the normal's side.
    pub indices: Vec<u32>,
}

/// One [`SURFEL_SIDES`]-gon per point, of the point's radius, in the plane perpendicular to its
/// normal (zero normals are replaced by +Z).
pub fn surfel_geometry(positions: &[Vec3], normals: &[Vec3], radii: &[f32]) -> SurfelGeometry {
    let per_point = SURFEL_SIDES + 1;
    let mut out = SurfelGeometry {
        positions: Vec::with_capacity(positions.len() * per_point),
        normals: Vec::with_capacity(positions.len() * per_point),
        indices: Vec::with_capacity(positions.len() * SURFEL_SIDES * 3),
    };
    let rim: Vec<(f32, f32)> = (0..SURFEL_SIDES)
        .map(|s| (s as f32 * std::f32::consts::TAU / SURFEL_SIDES as f32).sin_cos())
        .collect();
    for ((&p, &n), &radius) in positions.iter().zip(normals).zip(radii) {
        let n = n.normalize_or(Vec3::Z);
        let (t1, t2) = n.any_orthonormal_pair();
        let base = out.positions.len() as u32;
        out.positions.push(p.to_array());
        for &(s, c) in &rim {
            out.positions
                .push((p + (t1 * c + t2 * s) * radius).to_array());
        }
        out.normals
            .extend(std::iter::repeat_n(n.to_array(), per_point));
        for s in 0..SURFEL_SIDES as u32 {
            let next = (s + 1) % SURFEL_SIDES as u32;
            out.indices.extend([base, base + 1 + s, base + 1 + next]);
        }
    }
    out
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
    fn surfels_face_their_normals() {
        let g = surfel_geometry(&[Vec3::ZERO, Vec3::X], &[Vec3::Y, Vec3::Z], &[0.5, 0.5]);
        assert_eq!(g.positions.len(), 2 * (SURFEL_SIDES + 1));
        assert_eq!(g.indices.len(), 2 * SURFEL_SIDES * 3);
        // The first disc lies in the plane y = 0, its rim 0.5 from its centre.
        for v in &g.positions[1..=SURFEL_SIDES] {
            assert!(v[1].abs() < 1e-6);
            assert!((Vec3::from_array(*v).length() - 0.5).abs() < 1e-5);
        }
        // Triangles wind counter-clockwise seen from the normal.
        for tri in g.indices.chunks(3) {
            let [a, b, c] = [0, 1, 2].map(|k| Vec3::from_array(g.positions[tri[k] as usize]));
            let n = Vec3::from_array(g.normals[tri[0] as usize]);
            assert!((b - a).cross(c - a).dot(n) > 0.0);
        }
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
