//! A transfer and a surface's surfel shape laid out for a GPU compute pass.
//!
//! The renderer (`plugin::gpu_transfer`, feature `render`) can run a frame of the transfer
//! on the GPU and write the surfel records straight into the storage buffer the surfels
//! are drawn from: each frame then uploads only the simulation points (16 bytes each), not
//! the dense surface (32 bytes a dense point), and the CPU neither transfers nor packs.
//! [`GpuTransferLayout`] is what that pass reads, built once per transfer (again when
//! resampling grows it, pins change or a bake replaces it): flat arrays of `u32` and `f32`
//! whose layout `surfel_transfer.wgsl` reads with the constants below.
//!
//! The pass does, in three dispatches over the dense points, what the CPU does in
//! [`Transfer::apply_frame`] and [`pack_surfels`](crate::core::cloud::surfels::pack_surfels):
//! 1. each row's fitted position and normal (the residual rows from the displacements, the
//!    rest position and the rest frame, as on the CPU);
//! 2. each disc's radius, grown with the stretch to its far neighbour;
//! 3. the edge cuts: an edge point's own (or, at a corner, radius 0), and each other point's
//!    nearest cut by the edge points it neighbours. The CPU loops over the edge points and
//!    writes into their neighbours' records; the GPU turns that around (each point reads the
//!    edge points that may cut it, its *cutters*, in the CPU's order), so every invocation
//!    writes only its own record and the result does not depend on scheduling.

use glam::Vec3;

use super::{Neighbours, Transfer};
use crate::core::cloud::surfels::SurfelShape;

/// `u32` words per dense point in [`GpuTransferLayout::points`]: rest position (3 × `f32`),
/// rest radius, rest normal (3 × `f32`), the far neighbour's rest distance, the far
/// neighbour, flags and cutter count, the edge row (edge points) and the first cutter.
pub const POINT_WORDS: usize = 12;

/// Flag: the row is computed from the displacements (see [`Transfer`]'s residual rows).
pub const FLAG_RESIDUAL: u32 = 1;

/// Flag: the point lies on the surface's edge.
pub const FLAG_EDGE: u32 = 2;

/// The cutter count is kept in the flags word above this bit.
pub const CUTTER_SHIFT: u32 = 8;

/// Most neighbours an edge row may hold (the shader sorts their angles in an array this
/// long; [`EDGE_NEIGHBOURS`](crate::core::cloud::surfels::EDGE_NEIGHBOURS) is 10).
pub const MAX_EDGE_K: usize = 16;

/// Why a transfer cannot be laid out for the GPU.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum GpuLayoutError {
    /// The surfel shape was measured for another number of dense points.
    #[error("the surfel shape has {shape} points, the transfer {dense}")]
    ShapeMismatch {
        /// Points of the shape.
        shape: usize,
        /// Dense points of the transfer.
        dense: usize,
    },
    /// More edge neighbours than the shader sorts.
    #[error("{0} edge neighbours per point; the GPU pass takes at most {MAX_EDGE_K}")]
    EdgeNeighbours(usize),
    /// A point's cutters do not fit the flags word.
    #[error("dense point {0} has too many edge points around it")]
    Cutters(usize),
}

/// What the GPU transfer pass reads, built from a [`Transfer`] and the [`SurfelShape`] of
/// its dense points.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GpuTransferLayout {
    /// Dense points.
    pub dense: u32,
    /// Simulation points.
    pub simulation: u32,
    /// Neighbours per row.
    pub k: u32,
    /// Coefficients per row (3(k − 1), at least 1).
    pub stride: u32,
    /// Neighbours per edge row.
    pub edge_k: u32,
    /// Where the cutters start in [`Self::edges`] (after the edge rows).
    pub cutters: u32,
    /// The simulation points' rest positions (w = 0): the residual rows' displacements are
    /// the current positions minus these.
    pub sim_rest: Vec<[f32; 4]>,
    /// Row i: its k neighbours, the anchor first.
    pub indices: Vec<u32>,
    /// Row i: the value, t₁-slope and t₂-slope coefficients of the other neighbours'
    /// offsets from the anchor, [`Self::stride`] numbers.
    pub coefficients: Vec<f32>,
    /// [`POINT_WORDS`] words per dense point (floats as their bits).
    pub points: Vec<u32>,
    /// The edge rows (each: the edge point, then its [`Self::edge_k`] neighbours), then
    /// the cutters (each point's edge rows, ascending, from its first-cutter word on).
    pub edges: Vec<u32>,
}

impl GpuTransferLayout {
    /// The layout of `transfer` drawn with `shape` (measured on the transfer's rest points).
    pub fn new(transfer: &Transfer, shape: &SurfelShape) -> Result<Self, GpuLayoutError> {
        let n = transfer.len();
        if shape.len() != n {
            return Err(GpuLayoutError::ShapeMismatch {
                shape: shape.len(),
                dense: n,
            });
        }
        let (edge_points, edge_neighbours, edge_k) = shape.edges().parts();
        if edge_k > MAX_EDGE_K {
            return Err(GpuLayoutError::EdgeNeighbours(edge_k));
        }
        let indices = match &transfer.neighbours {
            Neighbours::Narrow(v) => v.iter().map(|&j| u32::from(j)).collect(),
            Neighbours::Wide(v) => v.clone(),
        };
        // Edge rows, and each point's cutters (the edge rows whose neighbours it is among;
        // ascending, as the CPU visits them).
        let mut edges = Vec::with_capacity(edge_points.len() * (1 + edge_k));
        let mut cut_by: Vec<Vec<u32>> = vec![Vec::new(); n];
        let mut edge_row = vec![u32::MAX; n];
        if edge_k > 0 {
            for (r, (&i, neighbours)) in edge_points
                .iter()
                .zip(edge_neighbours.chunks(edge_k))
                .enumerate()
            {
                edges.push(i);
                edges.extend_from_slice(neighbours);
                edge_row[i as usize] = r as u32;
                for &j in neighbours {
                    cut_by[j as usize].push(r as u32);
                }
            }
        }
        let cutters = edges.len() as u32;
        let mut points = Vec::with_capacity(n * POINT_WORDS);
        let far = shape.far();
        for i in 0..n {
            let (rest, normal) = (transfer.rest[i], transfer.normals[i]);
            let mut flags = 0;
            if transfer.kinds[i].residual {
                flags |= FLAG_RESIDUAL;
            }
            let first_cutter = edges.len() as u32 - cutters;
            if edge_row[i] != u32::MAX {
                flags |= FLAG_EDGE;
            } else {
                // An edge point's cut is only ever its own (as on the CPU).
                let count = u32::try_from(cut_by[i].len())
                    .ok()
                    .filter(|&c| c < 1 << (32 - CUTTER_SHIFT))
                    .ok_or(GpuLayoutError::Cutters(i))?;
                flags |= count << CUTTER_SHIFT;
                edges.extend_from_slice(&cut_by[i]);
            }
            let (far_index, far_distance) = far[i];
            points.extend(bits(rest));
            points.push(shape.radii()[i].to_bits());
            points.extend(bits(normal));
            points.push(far_distance.to_bits());
            points.push(far_index);
            points.push(flags);
            points.push(edge_row[i]);
            points.push(first_cutter);
        }
        Ok(Self {
            dense: n as u32,
            simulation: transfer.sim_rest.len() as u32,
            k: transfer.k as u32,
            stride: super::row_stride(transfer.k) as u32,
            edge_k: edge_k as u32,
            cutters,
            sim_rest: transfer
                .sim_rest
                .iter()
                .map(|p| [p.x, p.y, p.z, 0.0])
                .collect(),
            indices,
            coefficients: transfer.coefficients.clone(),
            points,
            edges,
        })
    }

    /// Bytes of the largest array (each is bound as one storage buffer, which the device
    /// limits: `max_storage_buffer_binding_size`).
    pub fn largest_array_bytes(&self) -> usize {
        [
            size_of_val(self.sim_rest.as_slice()),
            size_of_val(self.indices.as_slice()),
            size_of_val(self.coefficients.as_slice()),
            size_of_val(self.points.as_slice()),
            size_of_val(self.edges.as_slice()),
        ]
        .into_iter()
        .max()
        .unwrap_or(0)
    }

    /// Bytes of all the arrays (uploaded once per layout).
    pub fn bytes(&self) -> usize {
        size_of_val(self.sim_rest.as_slice())
            + size_of_val(self.indices.as_slice())
            + size_of_val(self.coefficients.as_slice())
            + size_of_val(self.points.as_slice())
            + size_of_val(self.edges.as_slice())
    }
}

/// A vector's coordinates as bits.
fn bits(v: Vec3) -> [u32; 3] {
    v.to_array().map(f32::to_bits)
}

#[cfg(test)]
mod tests {
    use glam::{Quat, Vec3A};

    use super::*;
    use crate::core::cloud::shapes::fibonacci_sphere;
    use crate::core::cloud::surfels::DEFAULT_SURFEL_SCALE;
    use crate::core::transfer::{FrameInput, TransferConfig};

    fn row(layout: &GpuTransferLayout, i: usize) -> &[u32] {
        &layout.points[i * POINT_WORDS..(i + 1) * POINT_WORDS]
    }

    /// The first dispatch's positions, computed from the layout alone (as the shader does),
    /// against the CPU frame.
    #[test]
    fn the_layout_holds_the_transfer_rows() {
        let dense = fibonacci_sphere(1500, 1.0);
        let (p, n) = (dense.positions(), dense.normals().unwrap());
        let sim: Vec<Vec3> = fibonacci_sphere(150, 1.0).positions().to_vec();
        let transfer = Transfer::new(p, n, &sim, TransferConfig::default()).unwrap();
        let shape = SurfelShape::at_rest(p, n, DEFAULT_SURFEL_SCALE);
        let layout = GpuTransferLayout::new(&transfer, &shape).unwrap();
        assert_eq!(layout.dense as usize, p.len());
        assert_eq!(layout.points.len(), p.len() * POINT_WORDS);
        // A closed sphere: no edge, no cutter.
        assert!(layout.edges.is_empty());

        let turn = Quat::from_rotation_z(0.7);
        let current: Vec<Vec3> = sim.iter().map(|&s| turn * s * 1.2).collect();
        let mut input = FrameInput::default();
        let xs: Vec<f32> = current.iter().map(|c| c.x).collect();
        let ys: Vec<f32> = current.iter().map(|c| c.y).collect();
        let zs: Vec<f32> = current.iter().map(|c| c.z).collect();
        input.set_positions(&transfer, [&xs, &ys, &zs]).unwrap();
        let mut expected = vec![Vec3::ZERO; p.len()];
        transfer
            .apply_frame(&input, &mut expected, &mut [])
            .unwrap();

        let (k, stride) = (layout.k as usize, layout.stride as usize);
        for (i, want) in expected.iter().enumerate() {
            let residual = row(&layout, i)[9] & FLAG_RESIDUAL != 0;
            let value = |j: u32| {
                let c = Vec3A::from(current[j as usize]);
                let rest = layout.sim_rest[j as usize];
                if residual {
                    c - Vec3A::new(rest[0], rest[1], rest[2])
                } else {
                    c
                }
            };
            let ids = &layout.indices[i * k..(i + 1) * k];
            let c0 = &layout.coefficients[i * stride..i * stride + k - 1];
            let a = value(ids[0]);
            let fitted = ids[1..]
                .iter()
                .zip(c0)
                .fold(a, |s, (&j, &c)| s + (value(j) - a) * c);
            let at = if residual {
                let r = row(&layout, i);
                Vec3A::new(
                    f32::from_bits(r[0]),
                    f32::from_bits(r[1]),
                    f32::from_bits(r[2]),
                ) + fitted
            } else {
                fitted
            };
            assert!(Vec3::from(at).distance(*want) < 1e-5, "row {i}");
        }
    }

    #[test]
    fn a_sheet_lists_its_edge_rows_and_each_points_cutters() {
        // A 30 × 30 grid in the plane z = 0.
        let positions: Vec<Vec3> = (0..900)
            .map(|i| Vec3::new((i % 30) as f32, (i / 30) as f32, 0.0) * 0.1)
            .collect();
        let normals = vec![Vec3::Z; positions.len()];
        let sim: Vec<Vec3> = positions.iter().step_by(7).copied().collect();
        let transfer =
            Transfer::new(&positions, &normals, &sim, TransferConfig::default()).unwrap();
        let shape = SurfelShape::at_rest(&positions, &normals, DEFAULT_SURFEL_SCALE);
        let layout = GpuTransferLayout::new(&transfer, &shape).unwrap();
        let (edge_points, neighbours, edge_k) = shape.edges().parts();
        // The rim: 4 × 29 points.
        assert_eq!(edge_points.len(), 116);
        assert_eq!(layout.cutters as usize, edge_points.len() * (1 + edge_k));
        for (r, &e) in edge_points.iter().enumerate() {
            let words = row(&layout, e as usize);
            assert_ne!(words[9] & FLAG_EDGE, 0);
            assert_eq!(words[10], r as u32);
            assert_eq!(layout.edges[r * (1 + edge_k)], e);
        }
        // Every (edge row, non-edge neighbour) pair appears once among the cutters, in the
        // neighbour's list, ascending.
        let mut pairs = 0;
        for j in 0..positions.len() {
            let words = row(&layout, j);
            if words[9] & FLAG_EDGE != 0 {
                assert_eq!(words[9] >> CUTTER_SHIFT, 0);
                continue;
            }
            let count = (words[9] >> CUTTER_SHIFT) as usize;
            let start = layout.cutters as usize + words[11] as usize;
            let list = &layout.edges[start..start + count];
            assert!(list.windows(2).all(|w| w[0] < w[1]));
            for &r in list {
                let r = r as usize;
                assert!(neighbours[r * edge_k..(r + 1) * edge_k].contains(&(j as u32)));
            }
            pairs += count;
        }
        let expected = neighbours
            .iter()
            .filter(|&&j| edge_points.binary_search(&j).is_err())
            .count();
        assert_eq!(pairs, expected);
    }

    #[test]
    fn a_shape_of_another_surface_is_refused() {
        let dense = fibonacci_sphere(300, 1.0);
        let (p, n) = (dense.positions(), dense.normals().unwrap());
        let sim = fibonacci_sphere(40, 1.0).positions().to_vec();
        let transfer = Transfer::new(p, n, &sim, TransferConfig::default()).unwrap();
        let shape = SurfelShape::at_rest(&p[..200], &n[..200], 1.0);
        assert_eq!(
            GpuTransferLayout::new(&transfer, &shape),
            Err(GpuLayoutError::ShapeMismatch {
                shape: 200,
                dense: 300
            })
        );
    }
}
