//! A surface's side of one tick: where its coordinates lie in the world, the parts of it the
//! contacts read, the bounds it may sweep, and its points in world coordinates with the
//! velocity each will have without contacts.

use bevy::math::Affine3A;
use bevy::prelude::*;

use crate::core::solver::contact::{BodyState, PointGrid, StepBody, StepContact, step_masses};
use crate::plugin::components::{SimulationPoints, SurfaceMasses, SurfaceSprings, SurfaceStepper};

/// How a surface's coordinates map to the world for one tick.
#[derive(Clone, Copy)]
pub(super) struct SurfaceFrame {
    place: Affine3A,
    /// World vectors into the surface's coordinates (forces and impulses).
    pub(super) to_local: Mat3,
    /// The surface's coordinates into the world's (its linear part).
    linear: Mat3,
    /// The surface's gravity over one tick, in world coordinates.
    gravity_dt: Vec3,
    /// How much the frame scales lengths (radii).
    scale: f32,
}

impl SurfaceFrame {
    /// The frame of a surface placed at `place`, whose own gravity is `gravity`.
    pub(super) fn new(place: &GlobalTransform, gravity: Vec3, dt: f32) -> Self {
        let place = place.affine();
        let linear = Mat3::from(place.matrix3);
        let scale = uniform_scale(linear);
        Self {
            place,
            to_local: linear.inverse(),
            linear,
            gravity_dt: linear * gravity * dt,
            scale,
        }
    }
}

/// How much a frame of linear part `linear` scales lengths (the cube root of its volume
/// change): the points' radii in the world.
pub(super) fn uniform_scale(linear: Mat3) -> f32 {
    linear.determinant().abs().cbrt()
}

/// How far from a turn and a uniform scale a frame may be and still count as one (a share
/// of the scale squared).
const SIMILARITY_TOLERANCE: f32 = 1e-4;

impl SurfaceFrame {
    /// A contact for the step, from world coordinates into the surface's: a velocity v
    /// seen from the world is L·v, so n̂·(L·v) ≥ s reads (Lᵀn̂)·v ≥ s, normalised.
    pub(super) fn contact_to_local(&self, c: &StepContact) -> StepContact {
        let normal = self.linear.transpose() * c.normal;
        let length = normal.length();
        StepContact {
            normal: normal / length,
            min_speed: c.min_speed / length,
            body_velocity: self.to_local * c.body_velocity,
            arm: self.to_local * c.arm,
            ..*c
        }
    }

    /// Whether the frame is a turn and a uniform scale s (L = s·R, no mirror): then a body's
    /// turning is a turning in the surface's coordinates too.
    pub(super) fn is_similarity(&self) -> bool {
        let s2 = self.scale * self.scale;
        let gram = self.linear.transpose() * self.linear - Mat3::from_diagonal(Vec3::splat(s2));
        self.linear.determinant() > 0.0
            && gram
                .to_cols_array()
                .iter()
                .all(|e| e.abs() <= SIMILARITY_TOLERANCE * s2)
    }

    /// A dynamic body for the step, in the surface's coordinates (the frame a similarity
    /// L = s·R): velocities v ↦ L⁻¹v, turning ω ↦ Rᵀω, inverse mass Rᵀ·W·R and inverse
    /// inertia s²·Rᵀ·I⁻¹·R, so that an impulse J on the surface (L·J in the world) moves the
    /// body in its coordinates as it moves in the world's.
    pub(super) fn body_to_local(
        &self,
        predicted: &BodyState,
        guess: &BodyState,
        key: u64,
    ) -> StepBody {
        let s2 = self.scale * self.scale;
        let turn_back = self.linear.transpose() / self.scale;
        let lt = self.linear.transpose();
        StepBody {
            linear: self.to_local * predicted.linear,
            angular: turn_back * predicted.angular,
            guess_linear: self.to_local * guess.linear,
            guess_angular: turn_back * guess.angular,
            inv_mass: lt * Mat3::from_diagonal(predicted.inv_mass) * self.linear / s2,
            inv_inertia: lt * predicted.inv_inertia * self.linear,
            key,
        }
    }
}

/// The parts of a surface the contacts read.
pub(super) struct SurfaceView<'a> {
    pub(super) points: &'a SimulationPoints,
    pub(super) masses: &'a SurfaceMasses,
    pub(super) springs: &'a SurfaceSprings,
    pub(super) stepper: &'a SurfaceStepper,
    pub(super) radii: &'a [f32],
    pub(super) frame: SurfaceFrame,
}

/// A simulation point in world coordinates.
#[derive(Clone, Copy)]
pub(super) struct WorldPoint {
    /// Where it is.
    pub(super) at: Vec3,
    /// How fast it will go at the end of the tick without contacts.
    pub(super) velocity: Vec3,
    /// Its sphere's radius.
    pub(super) radius: f32,
}

/// A surface's points in world coordinates, bucketed for the search.
pub(super) struct WorldPoints {
    /// Each point, in the order of the surface's.
    pub(super) points: Vec<WorldPoint>,
    /// Each point's mass within one step ([`step_masses`]).
    pub(super) step_mass: Vec<f32>,
    /// The farthest any point's sphere reaches over the tick.
    pub(super) max_reach: f32,
    /// The points in cells about twice `max_reach` wide.
    pub(super) grid: PointGrid,
}

impl SurfaceView<'_> {
    /// The surface's bounds over the tick, in world coordinates, each point's sphere and its
    /// motion included: one pass over the points.
    pub(super) fn swept_bounds(&self, dt: f32) -> (Vec3, Vec3) {
        let frame = self.frame;
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        let mut reach = 0.0_f32;
        for i in 0..self.points.len() {
            let p = frame.place.transform_point3(self.points.position(i));
            lo = lo.min(p);
            hi = hi.max(p);
            let v = frame.place.transform_vector3(self.points.velocity(i)) + frame.gravity_dt;
            reach = reach.max(self.radii[i] * frame.scale + v.length() * dt);
        }
        lo -= Vec3::splat(reach);
        hi += Vec3::splat(reach);
        (lo, hi)
    }

    /// The points in world coordinates: where they are, how fast they will go without
    /// contacts, how far they reach.
    pub(super) fn world_points(&self, dt: f32) -> WorldPoints {
        let frame = self.frame;
        let step_mass = step_masses(
            self.masses.masses(),
            self.springs.iter().map(|(_, s)| s),
            dt,
        );
        let points: Vec<WorldPoint> = (0..self.points.len())
            .map(|i| {
                let at = frame.place.transform_point3(self.points.position(i));
                let own = self.own_dv(i, step_mass[i], dt);
                let velocity = frame.place.transform_vector3(self.points.velocity(i) + own);
                let radius = self.radii[i] * frame.scale;
                WorldPoint {
                    at,
                    velocity,
                    radius,
                }
            })
            .collect();
        let max_reach = points
            .iter()
            .map(|w| w.radius + w.velocity.length() * dt)
            .fold(0.0, f32::max);
        let positions: Vec<Vec3> = points.iter().map(|w| w.at).collect();
        let grid = PointGrid::new(&positions, 2.0 * max_reach);
        WorldPoints {
            points,
            step_mass,
            max_reach,
            grid,
        }
    }

    /// How much the surface's own forces change point `i`'s velocity over the tick (in its
    /// coordinates), with the point as heavy as its `step_mass` ([`step_masses`]): springs,
    /// gravity, drag, anchors and pressure, when the tick's forces have been accumulated;
    /// gravity alone otherwise.
    fn own_dv(&self, i: usize, step_mass: f32, dt: f32) -> Vec3 {
        if self.masses.is_pinned(i) || step_mass <= 0.0 {
            return Vec3::ZERO;
        }
        match self.stepper.own_force(i) {
            Some(f) => f * (dt / step_mass),
            None => self.stepper.gravity() * dt,
        }
    }

    /// Point `i`'s inverse mass within one step of `step_mass`: none if it is pinned.
    pub(super) fn inv_mass(&self, i: usize, step_mass: f32) -> f32 {
        if self.masses.is_pinned(i) || step_mass <= 0.0 {
            0.0
        } else {
            1.0 / step_mass
        }
    }
}
