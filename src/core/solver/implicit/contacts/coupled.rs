//! How the surface's pushes on a moving body change with the body's velocity, linear and
//! angular together ([`Resist`]), and the quasi-Newton step of the body towards the velocity
//! those pushes give it.
//!
//! A push at arm r along normal n changes with the body's linear velocity V and angular
//! velocity ω as n·δV + (r×n)·δω: a turn changes the linear push, and a shift the torque.
//! The rounds solved the two apart, each with its own 3×3 estimate, and left the cross terms
//! out; on a stiff surface, given more rounds, they drove each other further apart: a 1 kg
//! crate dropped 0.1 m onto a firm gas-filled ball (`tests/contact_scenes.rs`, stretch
//! stiffness 5000) raised the scene's energy by 1769 J at six rounds a step, and by 98 J
//! with the two solved together (measured 2026-12-08). See decision 0035.

use faer::Mat;
use faer::linalg::solvers::Solve;
use glam::{DMat3, DVec3};

use super::super::{outer, point_inertia};

/// `[r]×`: the matrix that takes v to r × v.
fn skew(r: DVec3) -> DMat3 {
    DMat3::from_cols(
        DVec3::new(0.0, r.z, -r.y),
        DVec3::new(-r.z, 0.0, r.x),
        DVec3::new(r.y, -r.x, 0.0),
    )
}

/// A body's linear and angular parts, as one 6-vector: (m/s, rad/s) or (N·s, N·m·s).
pub(in crate::core::solver::implicit) type Pair = (DVec3, DVec3);

/// dJ/dV for one body: how the linear and angular impulse the surface takes (J) change with
/// the body's linear and angular velocity (V), as four 3×3 blocks of a 6×6 matrix, and what
/// weighs a turn against a shift in Broyden's update (a turn of 1 rad/s counts as the
/// contacts' mean arm in m/s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(in crate::core::solver::implicit) struct Resist {
    linear_linear: DMat3,
    linear_angular: DMat3,
    angular_linear: DMat3,
    angular_angular: DMat3,
    /// Σ of the masses added times their squared arms, and Σ of the masses: the mean
    /// squared arm is their ratio ([`Resist::weight`]).
    length_squared: f64,
    mass: f64,
}

impl Default for Resist {
    fn default() -> Self {
        Self {
            linear_linear: DMat3::ZERO,
            linear_angular: DMat3::ZERO,
            angular_linear: DMat3::ZERO,
            angular_angular: DMat3::ZERO,
            length_squared: 0.0,
            mass: 0.0,
        }
    }
}

impl Resist {
    /// Adds a point of step mass `mass` held along unit `normal` at `arm` from the body's
    /// centre: its push changes by `mass` times its speed change along the normal.
    pub(in crate::core::solver::implicit) fn add(&mut self, normal: DVec3, arm: DVec3, mass: f64) {
        let turn = arm.cross(normal);
        self.linear_linear += outer(normal, normal) * mass;
        self.linear_angular += outer(normal, turn) * mass;
        self.angular_linear += outer(turn, normal) * mass;
        self.angular_angular += outer(turn, turn) * mass;
        self.length_squared += arm.length_squared() * mass;
        self.mass += mass;
    }

    /// Adds a point of step mass `mass` carried by the body at `arm` from its centre (it
    /// moves with the body in every direction: V + ω×r).
    pub(in crate::core::solver::implicit) fn add_carried(&mut self, arm: DVec3, mass: f64) {
        let cross = skew(arm);
        self.linear_linear += DMat3::IDENTITY * mass;
        self.linear_angular -= cross * mass;
        self.angular_linear += cross * mass;
        self.angular_angular += point_inertia(mass, arm);
        self.length_squared += arm.length_squared() * mass;
        self.mass += mass;
    }

    /// Whether no point was added.
    pub(in crate::core::solver::implicit) fn is_empty(&self) -> bool {
        self.mass == 0.0
    }

    /// The change of the impulse for a change `dv` of the velocity.
    fn apply(&self, (linear, angular): Pair) -> Pair {
        (
            self.linear_linear * linear + self.linear_angular * angular,
            self.angular_linear * linear + self.angular_angular * angular,
        )
    }

    /// The weight of a turn against a shift (m²): the mean squared arm, 1 with no arms.
    fn weight(&self) -> f64 {
        let mean = self.length_squared / self.mass;
        if mean > 0.0 && mean.is_finite() {
            mean
        } else {
            1.0
        }
    }

    /// Broyden's update from a step `dx` of the velocity that changed the impulse by `dy`,
    /// in the norm that weighs a turn by the mean arm: afterwards `self·dx = dy`.
    pub(in crate::core::solver::implicit) fn broyden(&self, dx: Pair, dy: Pair) -> Self {
        let w = self.weight();
        let length = dx.0.length_squared() + w * dx.1.length_squared();
        if !(length > 0.0 && length.is_finite()) {
            return *self;
        }
        let seen = self.apply(dx);
        let (miss_linear, miss_angular) = ((dy.0 - seen.0) / length, (dy.1 - seen.1) / length);
        let (across_linear, across_angular) = (dx.0, dx.1 * w);
        Self {
            linear_linear: self.linear_linear + outer(miss_linear, across_linear),
            linear_angular: self.linear_angular + outer(miss_linear, across_angular),
            angular_linear: self.angular_linear + outer(miss_angular, across_linear),
            angular_angular: self.angular_angular + outer(miss_angular, across_angular),
            ..*self
        }
    }

    /// The body's step δ towards its velocity with the surface: the solution of
    /// (I + W·C)·δ = −`miss`, W the body's inverse mass and inertia, C this; `None` where it
    /// is not finite.
    pub(in crate::core::solver::implicit) fn step(
        &self,
        (inv_mass, inv_inertia): (DMat3, DMat3),
        miss: Pair,
    ) -> Option<Pair> {
        let blocks = [
            [
                inv_mass * self.linear_linear,
                inv_mass * self.linear_angular,
            ],
            [
                inv_inertia * self.angular_linear,
                inv_inertia * self.angular_angular,
            ],
        ];
        let system = Mat::<f64>::from_fn(6, 6, |row, col| {
            let block = blocks[row / 3][col / 3];
            let identity = if row == col { 1.0 } else { 0.0 };
            identity + block.col(col % 3)[row % 3]
        });
        let right = Mat::<f64>::from_fn(6, 1, |row, _| {
            let part = if row < 3 { miss.0 } else { miss.1 };
            -part[row % 3]
        });
        let x = system.partial_piv_lu().solve(&right);
        let step = (
            DVec3::new(x[(0, 0)], x[(1, 0)], x[(2, 0)]),
            DVec3::new(x[(3, 0)], x[(4, 0)], x[(5, 0)]),
        );
        (step.0.is_finite() && step.1.is_finite()).then_some(step)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A point at arm r held along n: the secant equation holds after an update, and the
    /// step solves (I + W·C)·δ = −miss.
    #[test]
    fn the_step_solves_the_coupled_system_and_broyden_meets_its_secant() {
        let mut resist = Resist::default();
        resist.add(DVec3::Y, DVec3::new(0.1, -0.1, 0.0), 2.0);
        resist.add(DVec3::Y, DVec3::new(-0.1, -0.1, 0.05), 1.0);
        // A turn of 1 rad/s about z moves the first point 0.1 m/s up and the second 0.1 m/s
        // down: the push along y changes by 2·0.1 − 1·0.1.
        assert!((resist.linear_angular.col(2).y - 0.1).abs() < 1e-12);
        let w = (DMat3::IDENTITY * 1.0, DMat3::IDENTITY * 150.0);
        let miss = (DVec3::new(0.0, -1.0, 0.0), DVec3::new(0.3, 0.0, -0.5));
        let (dl, da) = resist.step(w, miss).unwrap();
        let (cl, ca) = resist.apply((dl, da));
        let back = (dl + w.0 * cl, da + w.1 * ca);
        assert!((back.0 + miss.0).length() < 1e-9 && (back.1 + miss.1).length() < 1e-9);

        let dx = (DVec3::new(0.1, 0.2, -0.3), DVec3::new(1.0, 0.0, 2.0));
        let dy = (DVec3::new(0.5, 0.1, 0.0), DVec3::new(-0.2, 0.3, 0.1));
        let updated = resist.broyden(dx, dy);
        // A carried point: its push is its mass times its velocity change, V + ω×r.
        let mut carried = Resist::default();
        let arm = DVec3::new(0.2, -0.1, 0.3);
        carried.add_carried(arm, 2.0);
        let (linear, angular) = carried.apply(dx);
        let push = 2.0 * (dx.0 + dx.1.cross(arm));
        assert!((linear - push).length() < 1e-12 && (angular - arm.cross(push)).length() < 1e-12);
        let seen = updated.apply(dx);
        assert!((seen.0 - dy.0).length() < 1e-9 && (seen.1 - dy.1).length() < 1e-9);
    }
}
