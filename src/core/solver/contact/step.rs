//! Contacts solved within the step ([`StepContact`]): which one of a point's contacts the
//! step keeps, Coulomb friction at the velocity level, and the projection an explicit step
//! ends with. The implicit step's own solve with them is in `solver::implicit`.

use glam::{DVec3, Vec3};

use super::StepContact;
use crate::core::solver::parts::{Masses, PointState};

/// Speeds (m/s) within this of a contact's least normal speed meet it.
pub(crate) const SPEED_SLACK: f64 = 1e-6;

/// Sliding speeds (m/s) below this count as none.
const SLIDE_EPSILON: f64 = 1e-9;

/// The contacts the step keeps, as indices into `contacts`: one per point that is not
/// pinned, the one its velocity `v` at the step's start falls furthest short of where a
/// point touches several bodies (a point takes one normal; a corner of two walls holds it
/// against the one it presses hardest, the other one the next tick).
pub(crate) fn one_per_point(
    contacts: &[StepContact],
    points: &PointState,
    masses: &Masses,
) -> Vec<usize> {
    let shortfall = |c: &StepContact| c.min_speed - c.normal.dot(points.v.get(c.point as usize));
    let mut kept: Vec<usize> = (0..contacts.len())
        .filter(|&k| !masses.is_pinned(contacts[k].point as usize))
        .collect();
    kept.sort_by(|&a, &b| {
        let (ca, cb) = (&contacts[a], &contacts[b]);
        ca.point
            .cmp(&cb.point)
            .then(shortfall(cb).total_cmp(&shortfall(ca)))
            .then(a.cmp(&b))
    });
    kept.dedup_by_key(|k| contacts[*k].point);
    kept
}

/// Coulomb friction at the velocity level: the change that slows the point's slide along
/// the body (`relative` velocity, less its part along `normal`) by at most μ times the
/// normal velocity change the contact made, and never reverses it.
pub(crate) fn friction_dv(relative: DVec3, normal: DVec3, mu: f64, normal_dv: f64) -> DVec3 {
    let slide = relative - normal * normal.dot(relative);
    let speed = slide.length();
    if speed <= SLIDE_EPSILON || mu <= 0.0 || normal_dv <= 0.0 {
        return DVec3::ZERO;
    }
    -slide * ((mu * normal_dv).min(speed) / speed)
}

/// After an explicit step of `h`: each kept contact's point (it has no neighbours within
/// the step) takes the least velocity change along the normal that meets the contact, then
/// friction, and moves `h` times that change further, as if its velocity had had it all
/// step. Adds each contact's impulse (mass times change) to `impulses`.
pub(crate) fn project(
    points: &mut PointState,
    masses: &Masses,
    contacts: &[StepContact],
    h: f32,
    impulses: &mut [Vec3],
) {
    for k in one_per_point(contacts, points, masses) {
        let c = &contacts[k];
        let i = c.point as usize;
        let v = points.v.get(i).as_dvec3();
        let normal = c.normal.as_dvec3();
        let normal_dv = (f64::from(c.min_speed) - normal.dot(v)).max(0.0);
        if normal_dv <= SPEED_SLACK {
            continue;
        }
        let pushed = v + normal * normal_dv;
        let relative = pushed - c.body_velocity.as_dvec3();
        let change =
            normal * normal_dv + friction_dv(relative, normal, f64::from(c.friction), normal_dv);
        let change = change.as_vec3();
        points.v.set(i, points.v.get(i) + change);
        points.x.set(i, points.x.get(i) + change * h);
        impulses[k] += change * masses.mass[i];
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::core::solver::cloth::{CLOTH_MASS, cloth_grid};
    use crate::core::solver::contact::StepBody;
    use crate::core::solver::{ImplicitSolver, Integrator, Solver, SolverError, SubstepPolicy};

    const DT: f32 = 1.0 / 60.0;

    /// The 8 × 8 benchmark cloth (0.7 m square in the XZ plane, springs of stiffness 1000)
    /// with nothing fixed, stepped by `integrator`, under gravity or not.
    fn sheet(integrator: Integrator, gravity: bool) -> Solver {
        let grid = cloth_grid(8).unwrap();
        let mut solver = grid
            .solver_with(integrator, SubstepPolicy::Unchecked)
            .unwrap();
        for i in grid.fixed {
            solver.set_fixed(i as usize, false).unwrap();
        }
        let mut config = *solver.config();
        if !gravity {
            config.gravity = Vec3::ZERO;
        }
        solver.set_config(config).unwrap();
        solver
    }

    fn contact(point: usize, normal: Vec3, min_speed: f32) -> StepContact {
        StepContact {
            point: point as u32,
            normal,
            min_speed,
            body_velocity: Vec3::ZERO,
            friction: 0.5,
            body: None,
            arm: Vec3::ZERO,
        }
    }

    /// Hands every point a contact with the ground at y = 0 (touching: it may not go down).
    fn on_the_ground(solver: &mut Solver) {
        solver.clear_external_forces();
        for i in 0..solver.len() {
            let gap = solver.position(i).y;
            solver.add_contact(contact(i, Vec3::Y, -gap / DT)).unwrap();
        }
    }

    #[test]
    fn a_sheet_on_the_ground_stays_put_and_the_ground_carries_its_weight() {
        let cases = [
            (Integrator::ImplicitEuler, ImplicitSolver::ConjugateGradient),
            (
                Integrator::SymplecticEuler,
                ImplicitSolver::ConjugateGradient,
            ),
            (Integrator::ImplicitEuler, ImplicitSolver::LOCAL_GLOBAL),
        ];
        for (integrator, implicit_solver) in cases {
            let mut solver = sheet(integrator, true);
            let mut config = *solver.config();
            config.implicit_solver = implicit_solver;
            solver.set_config(config).unwrap();
            let weight = CLOTH_MASS * 9.81 * solver.len() as f32;
            for _ in 0..60 {
                on_the_ground(&mut solver);
                solver.step(DT).unwrap();
                let carried: Vec3 = solver.contact_impulses().iter().sum();
                assert!(
                    (carried.y / DT - weight).abs() < 1e-3 * weight,
                    "{integrator:?}, {implicit_solver:?}: the ground carried {} N of {weight} N",
                    carried.y / DT
                );
            }
            for i in 0..solver.len() {
                assert!(solver.position(i).y.abs() < 1e-5, "{}", solver.position(i));
                assert!(solver.velocity(i).length() < 1e-4, "{}", solver.velocity(i));
            }
        }
    }

    #[test]
    fn a_pusher_moves_the_points_it_holds_as_fast_as_itself_and_no_faster() {
        // No gravity; a body pushes the middle 2 × 2 points along the sheet at 1 m/s, along
        // −X, where the stretch springs carry the push to the rest (out of the plane, a flat
        // sheet has no linear stiffness to carry it).
        let mut solver = sheet(Integrator::ImplicitEuler, false);
        let held = [27, 28, 35, 36];
        for &i in &held {
            solver.add_contact(contact(i, -Vec3::X, 1.0)).unwrap();
        }
        solver.step(DT).unwrap();
        for i in 0..solver.len() {
            let v = solver.velocity(i).x;
            if held.contains(&i) {
                assert!((v + 1.0).abs() < 1e-5, "held point {i} at {v} m/s");
            } else {
                assert!(v <= 1e-6 && v > -1.0, "point {i} at {v} m/s");
            }
        }
        // The sheet's momentum is what the body gave it (the springs' impulses cancel).
        let momentum: Vec3 = (0..solver.len())
            .map(|i| solver.velocity(i) * CLOTH_MASS)
            .sum();
        let given: Vec3 = solver.contact_impulses().iter().sum();
        assert!(
            (momentum - given).length() < 1e-4 * given.length(),
            "momentum {momentum}, impulses {given}"
        );
        // More than the held points' own mass times 1 m/s: their neighbours came along.
        assert!(given.x < -1.5 * CLOTH_MASS * held.len() as f32, "{given}");
    }

    #[test]
    fn a_body_pushing_the_sheet_is_solved_with_it_and_takes_the_opposite_impulse() {
        // No gravity; a 0.5 kg body moving along −X at 1 m/s meets the middle 2 × 2 points
        // of the free sheet (6.4 kg), pushing along the sheet.
        let mut solver = sheet(Integrator::ImplicitEuler, false);
        let mass = 0.5;
        let body = solver
            .external
            .add_body(StepBody {
                linear: -Vec3::X,
                angular: Vec3::ZERO,
                guess_linear: -Vec3::X,
                guess_angular: Vec3::ZERO,
                inv_mass: glam::Mat3::IDENTITY / mass,
                inv_inertia: glam::Mat3::ZERO,
                key: 1,
            })
            .unwrap();
        let held = [27, 28, 35, 36];
        for &i in &held {
            let c = StepContact {
                body: Some(body),
                body_velocity: -Vec3::X,
                ..contact(i, -Vec3::X, 1.0)
            };
            solver.add_contact(c).unwrap();
        }
        solver.step(DT).unwrap();
        let given: Vec3 = solver.contact_impulses().iter().sum();
        // The body takes the opposite of what the surface took.
        let body_velocity = -Vec3::X - given / mass;
        let momentum: Vec3 = (0..solver.len())
            .map(|i| solver.velocity(i) * CLOTH_MASS)
            .sum();
        assert!((momentum + body_velocity * mass + Vec3::X * mass).length() < 1e-4);
        // The sheet slowed it, and the held points end moving with it.
        assert!(body_velocity.x > -0.9, "{body_velocity}");
        for &i in &held {
            let v = solver.velocity(i).x;
            assert!(
                (v - body_velocity.x).abs() < 0.01,
                "{v} against {body_velocity}"
            );
        }
    }

    #[test]
    fn a_contact_that_would_pull_lets_go() {
        // A sheet leaving the ground at 1 m/s: the ground holds nothing back.
        for integrator in [Integrator::ImplicitEuler, Integrator::SymplecticEuler] {
            let mut solver = sheet(integrator, true);
            for i in 0..solver.len() {
                solver.set_velocity(i, Vec3::Y).unwrap();
            }
            on_the_ground(&mut solver);
            solver.step(DT).unwrap();
            assert!(
                solver.contact_impulses().iter().all(|j| *j == Vec3::ZERO),
                "{integrator:?}"
            );
            let v = solver.velocity(0).y;
            assert!((v - (1.0 - 9.81 * DT)).abs() < 1e-4, "{integrator:?}: {v}");
        }
    }

    #[test]
    fn the_contacts_held_carry_over_so_a_restored_solver_steps_bit_for_bit() {
        let mut solver = sheet(Integrator::ImplicitEuler, true);
        for _ in 0..10 {
            on_the_ground(&mut solver);
            solver.step(DT).unwrap();
        }
        let (diagnostics, warm_start, held) = solver.stepper.carried();
        assert_eq!(
            held.0.len(),
            solver.len(),
            "every point rests on the ground"
        );
        assert_eq!(held.1.len(), solver.len());
        // A stepper restored from what it carried steps as the original does.
        let mut restored = solver.clone();
        restored.stepper.implicit = Default::default();
        restored
            .stepper
            .set_carried(diagnostics, &warm_start, (&held.0, &held.1));
        assert_eq!(restored.stepper.carried().2, held);
        for s in [&mut solver, &mut restored] {
            on_the_ground(s);
            s.step(DT).unwrap();
        }
        for i in 0..solver.len() {
            assert_eq!(solver.velocity(i), restored.velocity(i));
        }
    }

    #[test]
    fn friction_slows_a_slide_by_at_most_mu_times_the_push_and_never_reverses_it() {
        let n = DVec3::Y;
        // A slow slide is stopped.
        let dv = friction_dv(DVec3::new(0.1, -1.0, 0.0), n, 0.5, 1.0);
        assert!((dv - DVec3::new(-0.1, 0.0, 0.0)).length() < 1e-12);
        // A fast one slowed by μ·Δvₙ.
        let dv = friction_dv(DVec3::new(3.0, 0.0, 4.0), n, 0.5, 1.0);
        assert!((dv - DVec3::new(-0.3, 0.0, -0.4)).length() < 1e-12);
        // No push, no friction.
        assert_eq!(friction_dv(DVec3::X, n, 0.5, 0.0), DVec3::ZERO);
    }

    #[test]
    fn contacts_with_bad_numbers_are_refused() {
        let mut solver = sheet(Integrator::ImplicitEuler, true);
        let n = solver.len();
        assert!(solver.add_contact(contact(n, Vec3::Y, 0.0)).is_err());
        assert!(solver.add_contact(contact(0, Vec3::ZERO, 0.0)).is_err());
        assert!(solver.add_contact(contact(0, Vec3::NAN, 0.0)).is_err());
        assert!(
            solver
                .add_contact(contact(0, Vec3::Y, f32::INFINITY))
                .is_err()
        );
        let mut bad = contact(0, Vec3::Y, 0.0);
        bad.friction = -1.0;
        assert!(solver.add_contact(bad).is_err());
        bad.friction = 0.5;
        bad.body_velocity = Vec3::splat(f32::NAN);
        assert!(solver.add_contact(bad).is_err());
        // A body with a number that is not finite, and a contact naming a body not added.
        let mut body = StepBody {
            linear: Vec3::ZERO,
            angular: Vec3::ZERO,
            guess_linear: Vec3::ZERO,
            guess_angular: Vec3::ZERO,
            inv_mass: glam::Mat3::IDENTITY,
            inv_inertia: glam::Mat3::IDENTITY,
            key: 0,
        };
        body.inv_mass.x_axis.x = f32::NAN;
        assert!(matches!(
            solver.external.add_body(body),
            Err(SolverError::InvalidContact { what: "body", .. })
        ));
        let named = StepContact {
            body: Some(0),
            ..contact(0, Vec3::Y, 0.0)
        };
        assert!(matches!(
            solver.add_contact(named),
            Err(SolverError::InvalidContact {
                what: "body index",
                ..
            })
        ));
        let mut far = contact(0, Vec3::Y, 0.0);
        far.arm = Vec3::splat(f32::INFINITY);
        assert!(solver.add_contact(far).is_err());
        // A normal of any length is made unit.
        solver.add_contact(contact(0, Vec3::Y * 3.0, 0.0)).unwrap();
        solver.step(DT).unwrap();
        assert!(solver.velocity(0).is_finite());
    }
}
