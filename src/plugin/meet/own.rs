//! A surface meeting itself (issue 35, item 2): its points against its own points more than
//! a few springs apart on its network, with the contacts between surfaces' technique.
//!
//! Each point is a sphere (the radius the surfaces' contacts give it, half a spacing by
//! default), so a layer's points sit one spacing from the layer they rest on and no point
//! fits through a triangle of another layer (its corners are within 0.58 spacing of its
//! centre). Pairs within [`SurfaceMeeting::self_rings`](super::SurfaceMeeting::self_rings)
//! springs, and pairs whose spheres overlap at rest, are left out ([`NetworkNeighbours`]).
//! The pairs that could touch over the tick are found in a grid; each point in turn is a
//! body that the points after it push, resolved with the speculative sweep and friction of
//! the rigid contacts' `resolve`, every point's predicted velocity carried from one contact
//! to the next (a Gauss–Seidel pass over the surface). Each point is also kept off the
//! triangles near it on the network (a crease folding one triangle through its neighbour).
//! Each impulse goes to both sides as equal and opposite forces over the tick, and the
//! contacts to the step. See `docs/ARCHITECTURE.md`, "Surfaces meeting surfaces", for why
//! points and triangles.

use std::sync::Arc;

use bevy::prelude::*;

use crate::core::network::SpringNetwork;
use crate::core::solver::contact::{
    ContactParams, NetworkNeighbours, PointGrid, Stencil, StencilProximity, closest_on_triangle,
    group_step_masses, recovery, stencil_impulse,
};

use super::{CONTACT_PASSES, Pair, Side, Sphere, Touch, hand_to_step, one, push_apart};

/// The pairs self-contact leaves out, kept until the network, the rings or the radii change.
#[derive(Debug, Clone, Default)]
pub(super) struct Neighbours {
    neighbours: NetworkNeighbours,
    of: Option<(Arc<SpringNetwork>, u32, Vec<f32>)>,
}

impl Neighbours {
    /// Builds the neighbours again where the network, the rings or the radii changed.
    pub(super) fn refresh(&mut self, network: &Arc<SpringNetwork>, rings: u32, radii: &[f32]) {
        let current = matches!(&self.of,
            Some((n, r, s)) if Arc::ptr_eq(n, network) && *r == rings && s == radii);
        if !current {
            self.neighbours = NetworkNeighbours::new(network, rings, radii);
            self.of = Some((Arc::clone(network), rings, radii.to_vec()));
        }
    }

    /// The network the neighbours were found on.
    fn network(&self) -> Option<Arc<SpringNetwork>> {
        self.of.as_ref().map(|(n, _, _)| Arc::clone(n))
    }
}

/// The surface of `pair` against itself this tick (`side`: its points in world
/// coordinates); see the [module documentation](self).
pub(super) fn meet_itself(pair: &mut Pair<'_>, side: &Side, dt: f32) {
    let params = ContactParams {
        friction: pair.meeting.friction,
        depth_recovery: pair.meeting.depth_recovery,
    };
    let n = side.at.len();
    let Some(network) = pair.report.neighbours.network() else {
        return;
    };
    if params.validate().is_err() || pair.report.neighbours.neighbours.len() != n {
        return;
    }
    let neighbours = &pair.report.neighbours.neighbours;
    let reach = 2.0 * side.reach;
    let mut touching = vec![false; n];
    let pairs = point_pairs(side, neighbours, reach, &mut touching);
    let near = near_triangles(side, neighbours, &network, &mut touching);
    if pairs.is_empty() && near.is_empty() {
        return;
    }
    let step = group_step_masses(
        pair.masses.masses(),
        pair.springs.iter().map(|(_, s)| s),
        &touching,
        dt,
    );
    let full = side.full_step_masses(pair.springs, dt);
    let mut v: Vec<Vec3> = (0..n).map(|i| side.predicted(i, full[i])).collect();
    let inv = |i: usize| side.inv_mass(i, step[i]);
    let mut impulses = Vec::new();
    let (mut touches, mut folds) = (Vec::new(), Vec::new());
    for _ in 0..CONTACT_PASSES {
        for (k, near) in &pairs {
            let k = *k;
            let body = Sphere {
                at: side.at[k],
                radius: side.radius[k],
                inv_mass: inv(k),
            };
            let mut velocity = v[k];
            let spheres = (&side.at[..], &side.radius[..]);
            let pushed = push_apart(
                &body,
                &mut velocity,
                near,
                spheres,
                &mut v,
                &inv,
                dt,
                &params,
            );
            v[k] = velocity;
            for (i, impulse, normal, recover) in pushed {
                impulses.push((i, impulse));
                impulses.push((k, -impulse));
                touches.push(Touch {
                    point: i,
                    other: k,
                    normal,
                    recover,
                });
            }
        }
        for (f, fold) in near.iter().enumerate() {
            let stencil = |points: [usize; 3], weights: [f32; 3]| Stencil {
                weights,
                velocities: points.map(|c| v[c]),
                inv_masses: points.map(inv),
            };
            let proximity = StencilProximity {
                normal: fold.normal,
                gap: fold.gap,
                near: stencil(fold.near, fold.near_weights),
                far: stencil(fold.far, fold.far_weights),
            };
            let Some(j) = stencil_impulse(&proximity, dt, &params) else {
                continue;
            };
            for (sign, points, weights) in [
                (1.0, fold.near, fold.near_weights),
                (-1.0, fold.far, fold.far_weights),
            ] {
                for (c, w) in points.into_iter().zip(weights).filter(|(_, w)| *w > 0.0) {
                    v[c] += sign * j * w * inv(c);
                    impulses.push((c, sign * j * w));
                }
            }
            folds.push(f);
        }
    }
    touches.sort_unstable_by_key(|t| (t.point, t.other));
    touches.dedup_by_key(|t| (t.point, t.other));
    folds.sort_unstable();
    folds.dedup();
    let entity = pair.entity;
    if !pair.meeting.in_step {
        touches.clear();
        folds.clear();
    }
    for t in &touches {
        let (i, k) = (t.point, t.other);
        hand_to_step(
            pair,
            side,
            (i, v[i]),
            (t.normal, 0.5 * t.recover),
            (entity, one(k), v[k]),
            &params,
        );
        hand_to_step(
            pair,
            side,
            (k, v[k]),
            (-t.normal, 0.5 * t.recover),
            (entity, one(i), v[i]),
            &params,
        );
    }
    for fold in folds.into_iter().map(|f| &near[f]) {
        let sides = [
            (
                fold.normal,
                (fold.near, fold.near_weights),
                (fold.far, fold.far_weights),
            ),
            (
                -fold.normal,
                (fold.far, fold.far_weights),
                (fold.near, fold.near_weights),
            ),
        ];
        for (normal, (points, weights), (others, other_weights)) in sides {
            let with = [0, 1, 2].map(|j| (others[j] as u32, other_weights[j]));
            let there: Vec3 = (0..3).map(|j| v[others[j]] * other_weights[j]).sum();
            for (c, _) in points.into_iter().zip(weights).filter(|(_, w)| *w > 0.0) {
                hand_to_step(
                    pair,
                    side,
                    (c, v[c]),
                    (normal, 0.5 * recovery(fold.gap, &params)),
                    (entity, with, there),
                    &params,
                );
            }
        }
    }
    let mut touched = vec![false; n];
    for (i, j) in impulses {
        if pair.forces.add(i, side.to_local * (j / dt)).is_ok() {
            touched[i] = true;
        }
    }
    pair.report.self_touching = touched.iter().filter(|&&t| t).count();
}

/// A pair is looked at where its gap is within what both sides' velocities now (gravity's
/// included) close over the tick, plus this share of its thickness: the springs'
/// acceleration within the tick is left to the next (contacts a few spacings thick are not
/// closed by it in one).
const NEAR_SLACK: f32 = 0.25;

/// Each point with the points after it that could touch it over the tick and are not its
/// neighbours (found within `reach` in a grid); marks them `touching`.
fn point_pairs(
    side: &Side,
    neighbours: &NetworkNeighbours,
    reach: f32,
    touching: &mut [bool],
) -> Vec<(usize, Vec<usize>)> {
    let grid = PointGrid::new(&side.at, reach.max(f32::EPSILON));
    let mut pairs = Vec::new();
    for (k, &p) in side.at.iter().enumerate() {
        let mut near = Vec::new();
        grid.near(p - Vec3::splat(reach), p + Vec3::splat(reach), |i| {
            if i > k
                && side.at[i].distance(p) - side.radius[i] - side.radius[k]
                    <= side.motion[i]
                        + side.motion[k]
                        + NEAR_SLACK * (side.radius[i] + side.radius[k])
                && !(side.pinned[i] && side.pinned[k])
                && !neighbours.contains(k, i)
            {
                near.push(i);
            }
        });
        if !near.is_empty() {
            touching[k] = true;
            for &i in &near {
                touching[i] = true;
            }
            pairs.push((k, near));
        }
    }
    pairs
}

/// Two nearby parts of the surface at the tick's start: a point and one of its near
/// triangles (unused entries of weight 0).
struct Fold {
    near: [usize; 3],
    near_weights: [f32; 3],
    far: [usize; 3],
    far_weights: [f32; 3],
    /// From the far side towards the near side (world).
    normal: Vec3,
    /// Distance less the thickness kept there (world).
    gap: f32,
}

impl Fold {
    /// The fold between the near side's point `near` and the far side's `far` (world, at
    /// the weights), with `face` the far side's orientation for when they meet exactly,
    /// if they could meet over the tick (and not all of it is pinned).
    fn new(
        side: &Side,
        (near_points, near_weights): ([usize; 3], [f32; 3]),
        (far_points, far_weights): ([usize; 3], [f32; 3]),
        near: Vec3,
        far: Vec3,
        face: Vec3,
        thickness: f32,
    ) -> Option<Self> {
        let pinned = |points: [usize; 3], weights: [f32; 3]| {
            (0..3).all(|j| weights[j] <= 0.0 || side.pinned[points[j]])
        };
        if pinned(near_points, near_weights) && pinned(far_points, far_weights) {
            return None;
        }
        let d = near - far;
        let length = d.length();
        let thickness = thickness * side.scale;
        let motion = |points: [usize; 3], weights: [f32; 3]| {
            (0..3)
                .filter(|&j| weights[j] > 0.0)
                .map(|j| side.motion[points[j]])
                .fold(0.0_f32, f32::max)
        };
        let closing = motion(near_points, near_weights) + motion(far_points, far_weights);
        if !length.is_finite() || length - thickness > closing + NEAR_SLACK * thickness {
            return None;
        }
        let normal = if length > f32::EPSILON {
            d / length
        } else {
            // Exactly met: against the way they close.
            let at = |points: [usize; 3], weights: [f32; 3]| -> Vec3 {
                (0..3).map(|j| side.start[points[j]] * weights[j]).sum()
            };
            let closing = at(near_points, near_weights) - at(far_points, far_weights);
            let face = face.normalize_or(Vec3::Y);
            if closing.dot(face) > 0.0 { -face } else { face }
        };
        Some(Self {
            near: near_points,
            near_weights,
            far: far_points,
            far_weights,
            normal,
            gap: length - thickness,
        })
    }
}

/// Each point against its near triangles ([`NetworkNeighbours::near_triangles`]) where
/// they could meet over the tick; marks their points `touching`.
fn near_triangles(
    side: &Side,
    neighbours: &NetworkNeighbours,
    network: &SpringNetwork,
    touching: &mut [bool],
) -> Vec<Fold> {
    let n = side.at.len();
    // Each triangle's centre, the farthest of its corners from it, and the fastest corner:
    // a point is no nearer the triangle than its distance from the centre less that.
    let bounds: Vec<Option<(Vec3, f32, f32)>> = network
        .triangles
        .iter()
        .map(|t| {
            let corners = t.map(|c| c as usize);
            corners.iter().all(|&c| c < n).then(|| {
                let at = corners.map(|c| side.at[c]);
                let centre = (at[0] + at[1] + at[2]) / 3.0;
                let radius = at.iter().map(|p| p.distance(centre)).fold(0.0, f32::max);
                let motion = corners.iter().map(|&c| side.motion[c]).fold(0.0, f32::max);
                (centre, radius, motion)
            })
        })
        .collect();
    let mut folds = Vec::new();
    for p in 0..n {
        for &(t, thickness) in neighbours.near_triangles(p) {
            let (Some(corners), Some(Some((centre, radius, motion)))) =
                (network.triangles.get(t as usize), bounds.get(t as usize))
            else {
                continue;
            };
            let corners = corners.map(|c| c as usize);
            let at = side.at[p];
            let could = motion + side.motion[p] + (1.0 + NEAR_SLACK) * thickness * side.scale;
            if at.distance(*centre) - radius > could {
                continue;
            }
            let [a, b, c] = corners.map(|c| side.at[c]);
            let (q, weights) = closest_on_triangle(at, a, b, c);
            let face = (b - a).cross(c - a);
            let point = ([p, p, p], [1.0, 0.0, 0.0]);
            folds.extend(Fold::new(
                side,
                point,
                (corners, weights),
                side.at[p],
                q,
                face,
                thickness,
            ));
        }
    }
    for fold in &folds {
        for (points, weights) in [(fold.near, fold.near_weights), (fold.far, fold.far_weights)] {
            for (c, w) in points.into_iter().zip(weights) {
                touching[c] |= w > 0.0;
            }
        }
    }
    folds
}
