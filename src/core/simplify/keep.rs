//! Points §3 keeps whatever their rings: the edge of a pinned region, so that a coarse level
//! holds the surface where the dense one is held.
//!
//! A scene pins the dense points inside its regions. A coarse level pins the simulation
//! points inside them, and §3 chooses those by their rings alone, so where a region is
//! narrower than the level's spacing (a sheet held along a band 0.05 wide, simplified to a
//! spacing of 0.13) the simulation points fall on its outer rim or beyond it, and the coarse
//! surface is free up to the rim where the dense one is held up to the band's inner edge: a
//! longer span, which sagged 5.6 % further at 10 % of the points (`bench report`'s sheet,
//! 2026-12-04). Keeping points along the inner edge, about one level spacing apart, puts the
//! coarse surface's held edge where the dense one's is.

use glam::Vec3;

use super::SimplifyConfig;
use crate::core::cloud::knn::{KnnIndex, SPACING_NEIGHBOURS};

/// The most of a level's points a pinned edge may keep: past it, the kept points are spaced
/// further apart, so that the level's interior keeps its share.
pub const MAX_EDGE_SHARE: f32 = 0.25;

/// The points to keep along the edge of the held points (`held`, one flag per point of
/// `positions`) for a level of `config`: held points with a free point among their
/// [`SPACING_NEIGHBOURS`] nearest, those with more free ones first, no two of them closer
/// than the level's spacing (for a target, the dense spacing measured there times
/// √(points / target); for a diameter threshold, half of it; the wider where both are set),
/// and at most [`MAX_EDGE_SHARE`] of a target. One flag per point (none when nothing is held
/// or everything is).
pub fn pinned_edge(positions: &[Vec3], held: &[bool], config: &SimplifyConfig) -> Vec<bool> {
    let n = positions.len();
    let target = config.target.filter(|t| *t > 0);
    if held.len() != n
        || (target.is_none() && config.max_diameter.is_none())
        || !held.iter().any(|h| *h)
        || held.iter().all(|h| *h)
    {
        return Vec::new();
    }
    let index = KnnIndex::build(positions);
    let mut edge = Vec::new();
    let (mut spacing_sum, mut spacing_count) = (0.0f64, 0usize);
    for (i, p) in positions.iter().enumerate() {
        if !held[i] {
            continue;
        }
        let near = index.nearest(*p, SPACING_NEIGHBOURS + 1);
        let others = near.iter().filter(|m| m.index as usize != i);
        let free = others.clone().filter(|m| !held[m.index as usize]).count();
        if free > 0 {
            edge.push((free, i));
            for m in others {
                spacing_sum += f64::from(m.dist2.sqrt());
                spacing_count += 1;
            }
        }
    }
    if edge.is_empty() || spacing_count == 0 {
        return Vec::new();
    }
    // The most exposed first (most free neighbours): where the edge zigzags through a
    // lattice, its inner points rather than the ones a row behind.
    edge.sort_by_key(|&(free, i)| (std::cmp::Reverse(free), i));
    let edge: Vec<usize> = edge.into_iter().map(|(_, i)| i).collect();
    let dense_spacing = (spacing_sum / spacing_count as f64) as f32;
    let by_target = target.map_or(0.0, |t| dense_spacing * (n as f32 / t as f32).sqrt());
    let by_diameter = config.max_diameter.map_or(0.0, |d| 0.5 * d);
    let mut spacing = by_target.max(by_diameter);
    let most = target.map_or(usize::MAX, |t| {
        ((MAX_EDGE_SHARE * t as f32) as usize).max(1)
    });
    loop {
        let mut kept = thin(positions, &edge, spacing);
        // No spacing to widen (the edge's points coincide with their neighbours) or none
        // left: the most exposed `most` of them.
        if !(spacing > 0.0 && spacing.is_finite()) {
            kept.truncate(most);
        }
        if kept.len() <= most {
            let mut keep = vec![false; n];
            for i in kept {
                keep[i] = true;
            }
            return keep;
        }
        // An edge is a curve: its kept points go as one over their spacing.
        spacing *= kept.len() as f32 / most as f32;
    }
}

/// The points of `candidates` kept greedily, in order, none within `spacing` of one kept
/// before it.
fn thin(positions: &[Vec3], candidates: &[usize], spacing: f32) -> Vec<usize> {
    if !(spacing > 0.0 && spacing.is_finite()) {
        return candidates.to_vec();
    }
    // Cells of the spacing, their indices bounded so that a neighbour's never overflows.
    let key = |p: Vec3| {
        let c = (p / spacing).floor();
        glam::IVec3::new(
            c.x.clamp(-1e9, 1e9) as i32,
            c.y.clamp(-1e9, 1e9) as i32,
            c.z.clamp(-1e9, 1e9) as i32,
        )
    };
    let mut grid: std::collections::HashMap<glam::IVec3, Vec<usize>> = Default::default();
    let mut kept = Vec::new();
    for &i in candidates {
        let p = positions[i];
        let c = key(p);
        let mut near = false;
        'cells: for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(list) = grid.get(&(c + glam::IVec3::new(dx, dy, dz))) else {
                        continue;
                    };
                    if list.iter().any(|&j| positions[j].distance(p) < spacing) {
                        near = true;
                        break 'cells;
                    }
                }
            }
        }
        if !near {
            grid.entry(c).or_default().push(i);
            kept.push(i);
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::cloud::shapes;
    use crate::core::simplify::{MIN_ROUND_POINTS, SimplifyError, simplify_keeping};
    use std::ops::ControlFlow;

    #[test]
    fn kept_points_stay_and_count_towards_the_target() {
        let cloud = shapes::fibonacci_sphere(4000, 1.0);
        let normals = cloud.normals().unwrap();
        let mut keep = vec![false; cloud.len()];
        for i in (0..cloud.len()).step_by(50) {
            keep[i] = true;
        }
        let go = &mut |_| ControlFlow::Continue(());
        for rounds_above in [usize::MAX, MIN_ROUND_POINTS] {
            let config = SimplifyConfig {
                rounds_above,
                ..SimplifyConfig::target(300)
            };
            let s = simplify_keeping(cloud.positions(), normals, &config, &keep, go).unwrap();
            assert_eq!(s.kept.len(), 300);
            let kept = s.kept.iter().filter(|&&i| keep[i as usize]).count();
            assert_eq!(kept, 80, "rounds above {rounds_above}");
        }
        // More kept than the target: they all stay, and nothing else.
        let keep: Vec<bool> = (0..cloud.len()).map(|i| i % 8 == 0).collect();
        let s = simplify_keeping(
            cloud.positions(),
            normals,
            &SimplifyConfig::target(300),
            &keep,
            go,
        )
        .unwrap();
        assert_eq!(s.kept.len(), 500);
        assert!(s.kept.iter().all(|&i| i % 8 == 0));
        let short = simplify_keeping(
            cloud.positions(),
            normals,
            &SimplifyConfig::target(300),
            &keep[1..],
            go,
        );
        assert!(matches!(short, Err(SimplifyError::KeepMismatch { .. })));
    }

    /// A square lattice of `side` × `side` points 0.1 apart, the columns x ≥ `from` held.
    fn lattice(side: usize, from: f32) -> (Vec<Vec3>, Vec<bool>) {
        let positions: Vec<Vec3> = (0..side * side)
            .map(|i| Vec3::new((i % side) as f32 * 0.1, (i / side) as f32 * 0.1, 0.0))
            .collect();
        let held = positions.iter().map(|p| p.x >= from - 1e-4).collect();
        (positions, held)
    }

    #[test]
    fn the_inner_edge_of_a_band_is_kept_a_level_spacing_apart() {
        // 40 × 40 points, the last three columns held; a level of 100 points is spaced four
        // dense spacings apart (the mean distance to six neighbours here: 0.114).
        let (positions, held) = lattice(40, 3.7);
        let keep = pinned_edge(&positions, &held, &SimplifyConfig::target(100));
        let kept: Vec<Vec3> = (0..positions.len())
            .filter(|&i| keep[i])
            .map(|i| positions[i])
            .collect();
        assert!(kept.iter().all(|p| (p.x - 3.7).abs() < 1e-4), "{kept:?}");
        // Along 3.9 m, 0.46 to twice that apart.
        assert!((5..=9).contains(&kept.len()), "{}", kept.len());
        let mut ys: Vec<f32> = kept.iter().map(|p| p.y).collect();
        ys.sort_by(f32::total_cmp);
        assert!(
            ys.windows(2)
                .all(|w| w[1] - w[0] >= 0.45 && w[1] - w[0] <= 0.92),
            "{ys:?}"
        );
    }

    #[test]
    fn a_long_edge_keeps_at_most_its_share_and_nothing_held_keeps_nothing() {
        let (positions, held) = lattice(40, 3.7);
        let keep = pinned_edge(&positions, &held, &SimplifyConfig::target(20));
        let kept = keep.iter().filter(|k| **k).count();
        assert!((2..=5).contains(&kept), "{kept}");
        let level = SimplifyConfig::target(100);
        assert!(pinned_edge(&positions, &vec![false; positions.len()], &level).is_empty());
        assert!(pinned_edge(&positions, &vec![true; positions.len()], &level).is_empty());
        assert!(pinned_edge(&positions, &held[1..], &level).is_empty());
        // Every point eight times in place, half of the copies held: every neighbour at no
        // distance, so no spacing to widen (this looped forever), and still the share.
        let stacked: Vec<Vec3> = positions[..40].iter().flat_map(|p| [*p; 8]).collect();
        let half: Vec<bool> = (0..stacked.len()).map(|i| i % 2 == 0).collect();
        let keep = pinned_edge(&stacked, &half, &SimplifyConfig::target(20));
        assert_eq!(keep.iter().filter(|k| **k).count(), 5);
        // By a diameter threshold: half of it apart.
        let keep = pinned_edge(&positions, &held, &SimplifyConfig::max_diameter(1.0));
        assert_eq!(keep.iter().filter(|k| **k).count(), 8);
    }
}
