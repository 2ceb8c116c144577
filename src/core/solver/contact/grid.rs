//! A uniform grid over the simulation points, so that a body's bounding box finds the points
//! near it without testing all of them.

use glam::Vec3;

/// Points bucketed in a uniform grid, so that the points near a box are found without
/// looking at all of them. Built in two passes (a counting sort), no hashing.
#[derive(Debug, Clone)]
pub struct PointGrid {
    origin: Vec3,
    cell: f32,
    dims: [usize; 3],
    /// `starts[c]..starts[c + 1]` indexes `items` for cell `c`.
    starts: Vec<u32>,
    items: Vec<u32>,
}

/// A grid has at most this many cells per point (cells grow beyond the asked size to keep
/// to it).
const GRID_CELLS_PER_POINT: f32 = 4.0;

impl PointGrid {
    /// Buckets `points` in cells of about `cell` (larger where the points' bounds would
    /// need too many cells). Non-finite points go nowhere.
    pub fn new(points: &[Vec3], cell: f32) -> Self {
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for p in points.iter().filter(|p| p.is_finite()) {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        if !lo.is_finite() {
            return Self {
                origin: Vec3::ZERO,
                cell: 1.0,
                dims: [1; 3],
                starts: vec![0, 0],
                items: Vec::new(),
            };
        }
        let extent = (hi - lo).max(Vec3::splat(f32::EPSILON));
        let budget = (points.len() as f32 * GRID_CELLS_PER_POINT).max(1.0);
        let mut size = if cell.is_finite() && cell > 0.0 {
            cell
        } else {
            extent.max_element()
        };
        let count = |size: f32| (extent / size).floor() + Vec3::ONE;
        while count(size).x * count(size).y * count(size).z > budget {
            size *= 1.5;
        }
        let n = count(size);
        let dims = [n.x as usize, n.y as usize, n.z as usize];
        let mut grid = Self {
            origin: lo,
            cell: size,
            dims,
            starts: vec![0; dims[0] * dims[1] * dims[2] + 1],
            items: Vec::new(),
        };
        let cells: Vec<Option<usize>> = points.iter().map(|p| grid.cell_of(*p)).collect();
        for c in cells.iter().flatten() {
            grid.starts[c + 1] += 1;
        }
        for c in 1..grid.starts.len() {
            grid.starts[c] += grid.starts[c - 1];
        }
        let mut next = grid.starts.clone();
        grid.items = vec![0; grid.starts[grid.starts.len() - 1] as usize];
        for (i, c) in cells.iter().enumerate() {
            if let Some(c) = c {
                grid.items[next[*c] as usize] = i as u32;
                next[*c] += 1;
            }
        }
        grid
    }

    fn coords(&self, p: Vec3) -> [usize; 3] {
        let q = ((p - self.origin) / self.cell).floor().max(Vec3::ZERO);
        [
            (q.x as usize).min(self.dims[0] - 1),
            (q.y as usize).min(self.dims[1] - 1),
            (q.z as usize).min(self.dims[2] - 1),
        ]
    }

    fn cell_of(&self, p: Vec3) -> Option<usize> {
        p.is_finite().then(|| {
            let [x, y, z] = self.coords(p);
            (z * self.dims[1] + y) * self.dims[0] + x
        })
    }

    /// Calls `f` with every point in the cells that meet the box `min..max` (a superset
    /// of the points inside it).
    pub fn near(&self, min: Vec3, max: Vec3, mut f: impl FnMut(usize)) {
        if !(min.is_finite() && max.is_finite()) || self.items.is_empty() {
            return;
        }
        let top = self.origin
            + self.cell
                * Vec3::new(
                    self.dims[0] as f32,
                    self.dims[1] as f32,
                    self.dims[2] as f32,
                );
        if max.cmplt(self.origin).any() || min.cmpgt(top).any() {
            return;
        }
        let (a, b) = (self.coords(min), self.coords(max));
        for z in a[2]..=b[2] {
            for y in a[1]..=b[1] {
                let row = (z * self.dims[1] + y) * self.dims[0];
                let (s, e) = (self.starts[row + a[0]], self.starts[row + b[0] + 1]);
                for &i in &self.items[s as usize..e as usize] {
                    f(i as usize);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grid_finds_every_point_in_a_box_and_few_outside() {
        let cloud = crate::core::cloud::shapes::fibonacci_sphere(5000, 1.0);
        let points = cloud.positions();
        let grid = PointGrid::new(points, 0.1);
        for (min, max) in [
            (Vec3::splat(-0.2), Vec3::splat(0.3)),
            (Vec3::new(0.5, -1.5, -1.5), Vec3::splat(1.5)),
            (Vec3::splat(-5.0), Vec3::splat(5.0)),
            (Vec3::splat(3.0), Vec3::splat(4.0)),
        ] {
            let mut found = Vec::new();
            grid.near(min, max, |i| found.push(i));
            let inside: Vec<usize> = (0..points.len())
                .filter(|&i| points[i].cmpge(min).all() && points[i].cmple(max).all())
                .collect();
            assert!(inside.iter().all(|i| found.contains(i)), "{min} {max}");
            let unique: std::collections::HashSet<_> = found.iter().collect();
            assert_eq!(unique.len(), found.len(), "each point once");
            assert!(
                found.len() <= inside.len() * 3 + 200,
                "{} vs {}",
                found.len(),
                inside.len()
            );
        }
        // Bad input goes nowhere and finds nothing.
        let grid = PointGrid::new(&[Vec3::NAN, Vec3::ONE], 0.1);
        let mut found = Vec::new();
        grid.near(Vec3::ZERO, Vec3::splat(2.0), |i| found.push(i));
        assert_eq!(found, [1]);
    }
}
