//! The fail-safe that keeps a surface from passing through itself (issue 64, item 5):
//! after a step, any edge of the network that now crosses one of its triangles (and did
//! not at the step's start) is undone by impact zones (Provot 1997; Bridson, Fedkiw and
//! Anderson 2002): the points of each crossing, and of crossings that share a point, are
//! one zone, which moves as one body over the step — from where its points started, at
//! their mass-weighted mean velocity — and takes that velocity. Zones that still cross
//! something grow by what they cross, and are tried again; if crossings remain after
//! [`ZONE_PASSES`], every free point moves so, which cannot cross (a surface moved rigidly
//! from a state without crossings has none).
//!
//! A zone's momentum is kept and its kinetic energy can only fall (the mean velocity of
//! its points, mass-weighted); the springs inside it keep their lengths from the step's
//! start. Self-contact's contacts keep a crease open nearly always; this catches the
//! rest (a fold closing within the rings it leaves out, a fast crumple), which before
//! crossed for a tick or two.

use glam::Vec3;

use crate::core::network::crossings;
use crate::core::solver::parts::{Masses, PointState};

/// Rounds of growing the zones before every free point moves together.
pub const ZONE_PASSES: usize = 4;

/// What [`untangle`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Untangled {
    /// Crossings the step made.
    pub crossings: usize,
    /// Points moved back into zones.
    pub points: usize,
    /// Whether the whole surface had to move as one.
    pub whole: bool,
}

/// Undoes the crossings of `triangles` that a step of `h` seconds made, `start` the
/// points' positions when it began: the points of each crossing, joined with crossings that
/// share a point, move as one zone from where they started at their mass-weighted mean
/// velocity and take it; zones still crossing grow and are tried again ([`ZONE_PASSES`]),
/// then every free point moves so. Points that are pinned keep their own motion, and a zone
/// holding one moves with the pinned points' mean velocity. Nothing is done (and nothing is reported but the count) where the
/// surface already crossed itself at the start, or the sizes disagree.
pub fn untangle(
    start: &[Vec3],
    points: &mut PointState,
    masses: &Masses,
    triangles: &[[u32; 3]],
    h: f32,
) -> Untangled {
    let n = points.len();
    if start.len() != n || masses.len() != n {
        return Untangled::default();
    }
    let positions: Vec<Vec3> = points.iter_positions().collect();
    let found = crossings(&positions, triangles);
    let mut report = Untangled {
        crossings: found.len(),
        ..Untangled::default()
    };
    if found.is_empty() || !crossings(start, triangles).is_empty() {
        return report;
    }
    let velocities: Vec<Vec3> = (0..n).map(|i| points.velocity(i)).collect();
    let mut zone = Zones::new(n);
    let mut found = found;
    for _ in 0..ZONE_PASSES {
        for ([a, b], t) in &found {
            let Some(corners) = triangles.get(*t as usize) else {
                continue;
            };
            for &c in corners.iter().chain([b]) {
                zone.join(*a as usize, c as usize);
            }
        }
        zone.settle(start, &velocities, points, masses, h);
        let now: Vec<Vec3> = points.iter_positions().collect();
        found = crossings(&now, triangles);
        if found.is_empty() {
            report.points = zone.count();
            return report;
        }
    }
    // Every free point moves as one body.
    for i in 1..n {
        zone.join(0, i);
    }
    zone.settle(start, &velocities, points, masses, h);
    report.points = zone.count();
    report.whole = true;
    report
}

/// Points joined into zones (a union–find over the points; a point alone is in none).
struct Zones {
    parent: Vec<usize>,
    joined: Vec<bool>,
}

impl Zones {
    fn new(n: usize) -> Self {
        Self {
            parent: (0..n).collect(),
            joined: vec![false; n],
        }
    }

    fn root(&mut self, mut i: usize) -> usize {
        while self.parent[i] != i {
            self.parent[i] = self.parent[self.parent[i]];
            i = self.parent[i];
        }
        i
    }

    fn join(&mut self, a: usize, b: usize) {
        if a >= self.parent.len() || b >= self.parent.len() {
            return;
        }
        self.joined[a] = true;
        self.joined[b] = true;
        let (ra, rb) = (self.root(a), self.root(b));
        // The smaller index is the root: the zones do not depend on the order of joins.
        if ra != rb {
            let (low, high) = (ra.min(rb), ra.max(rb));
            self.parent[high] = low;
        }
    }

    fn count(&self) -> usize {
        self.joined.iter().filter(|&&j| j).count()
    }

    /// Moves each zone from its points' `start` over `h` at its mean velocity (pinned
    /// points, if it holds any, set it; else the free points' mass-weighted mean) and gives
    /// its free points that velocity.
    fn settle(
        &mut self,
        start: &[Vec3],
        velocities: &[Vec3],
        points: &mut PointState,
        masses: &Masses,
        h: f32,
    ) {
        let n = self.parent.len();
        // Per root: Σ m·v and Σ m of the free points, Σ v and the count of the pinned.
        let mut free = vec![(Vec3::ZERO, 0.0_f32); n];
        let mut pinned = vec![(Vec3::ZERO, 0_u32); n];
        for (i, &v) in velocities.iter().enumerate().take(n) {
            if !self.joined[i] {
                continue;
            }
            let r = self.root(i);
            if masses.is_pinned(i) {
                pinned[r].0 += v;
                pinned[r].1 += 1;
            } else {
                let m = masses.mass(i);
                free[r].0 += v * m;
                free[r].1 += m;
            }
        }
        for (i, &from) in start.iter().enumerate().take(n) {
            if !self.joined[i] || masses.is_pinned(i) {
                continue;
            }
            let r = self.root(i);
            let v = match (pinned[r], free[r]) {
                ((sum, count), _) if count > 0 => sum / count as f32,
                (_, (momentum, mass)) if mass > 0.0 => momentum / mass,
                _ => Vec3::ZERO,
            };
            // In range: each point of the surface, finite values.
            let _ = points.set_velocity(i, v);
            let _ = points.set_position(i, from + v * h);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::network::surface_intersections;

    /// Two 4 × 4 sheets, a unit apart in y, their triangles, and unit masses.
    fn two_sheets() -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut points = Vec::new();
        let mut triangles = Vec::new();
        for (layer, y) in [(0_u32, 0.0_f32), (1, 1.0)] {
            let offset = layer * 16;
            for z in 0..4 {
                for x in 0..4 {
                    points.push(Vec3::new(x as f32, y, z as f32));
                }
            }
            for z in 0..3 {
                for x in 0..3 {
                    let i = offset + z * 4 + x;
                    triangles.push([i, i + 1, i + 4]);
                    triangles.push([i + 1, i + 5, i + 4]);
                }
            }
        }
        (points, triangles)
    }

    #[test]
    fn a_point_pushed_through_the_other_layer_is_held_back_with_its_zone() {
        let (start, triangles) = two_sheets();
        let n = start.len();
        let masses = Masses::new(&vec![1.0; n]).unwrap();
        // The upper layer's middle point went 1.5 down in a step of 0.1 s (through the
        // lower layer); the rest did not move.
        let h = 0.1;
        let mut points = PointState::new(&start).unwrap();
        let middle = 16 + 5;
        points
            .set_velocity(middle, Vec3::new(0.0, -15.0, 0.0))
            .unwrap();
        points
            .set_position(middle, start[middle] + Vec3::new(0.0, -1.5, 0.0))
            .unwrap();
        let momentum: Vec3 = (0..n).map(|i| points.velocity(i)).sum();
        let energy: f32 = (0..n).map(|i| points.velocity(i).length_squared()).sum();
        let positions: Vec<Vec3> = points.iter_positions().collect();
        assert!(surface_intersections(&positions, &triangles) > 0);
        let done = untangle(&start, &mut points, &masses, &triangles, h);
        assert!(
            done.crossings > 0 && done.points > 0 && !done.whole,
            "{done:?}"
        );
        let positions: Vec<Vec3> = points.iter_positions().collect();
        assert_eq!(surface_intersections(&positions, &triangles), 0);
        // Momentum kept, kinetic energy not gained.
        let after: Vec3 = (0..n).map(|i| points.velocity(i)).sum();
        assert!((after - momentum).length() < 1e-4, "{after} {momentum}");
        let energy_after: f32 = (0..n).map(|i| points.velocity(i).length_squared()).sum();
        assert!(energy_after <= energy, "{energy_after} {energy}");
    }

    #[test]
    fn a_surface_that_crossed_itself_at_the_start_is_left_alone() {
        let (mut start, triangles) = two_sheets();
        start[16 + 5].y = -0.5;
        let masses = Masses::new(&vec![1.0; start.len()]).unwrap();
        let mut points = PointState::new(&start).unwrap();
        let before = points.clone();
        let done = untangle(&start, &mut points, &masses, &triangles, 0.1);
        assert!(done.crossings > 0 && done.points == 0);
        assert_eq!(points, before);
    }
}
