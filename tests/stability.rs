//! The solver on hard cases: stiffness of a million, a poke of 10^4 g, coincident points,
//! bad time steps; anchors and drag while running; bad input as typed errors.

use bevy_point_springs::core::solver::cloth::cloth_grid;
use bevy_point_springs::core::solver::{
    Anchor, DampingModel, InstabilityResponse, Integrator, STANDARD_GRAVITY, Solver, SolverConfig,
    SolverError, SpringSpec, SubstepPolicy,
};
use glam::Vec3;

#[path = "support/solvers.rs"]
mod solvers;
use solvers::*;

// ---------------------------------------------------------------------------------------
// Hard cases.

/// An 8×8 cloth hanging from two corners with stiffness 10^6 and the paper's damping (eq 3).
fn stiff_cloth(integrator: Integrator, substeps: SubstepPolicy) -> Solver {
    let stiff = |s| SpringSpec {
        stiffness: 1.0e6,
        ..s
    };
    let config = SolverConfig {
        integrator,
        substeps,
        damping_model: DampingModel::Relative,
        ..SolverConfig::default()
    };
    cloth_solver(8, stiff, config, true)
}

#[test]
fn stiffness_of_a_million_at_30_hz() {
    let dt = 1.0 / 30.0;
    // Bounded: the energy never exceeds its start by more than ten times what gravity could
    // release if the whole cloth dropped by its own diagonal (62.8 N · 0.99 m). Linearised
    // backward Euler overshoots a little while the stiff springs first take the load (the
    // spring energy peaks near 190 J, a strain of about 1 %), then dissipates.
    let weight = 64.0 * 0.1 * 9.81;
    let bound = |e0: f64| e0 + 10.0 * weight * 0.7 * 2f64.sqrt();
    // Implicit: any step.
    let mut s = stiff_cloth(Integrator::ImplicitEuler, SubstepPolicy::default());
    let e0 = s.energy().total();
    for _ in 0..30 {
        let r = s.step(dt).unwrap();
        assert!(r.finite && !r.recovered, "{r:?}");
        let e = s.energy().total();
        assert!(e <= bound(e0), "{e} vs {e0}");
    }
    assert!(s.energy().total() < e0, "dissipated by the end");
    let sag = -s.positions().iter().map(|p| p.y).fold(0.0, f32::min);
    assert!(sag > 0.05 && sag < 2.0, "sag {sag}");
    // Explicit: refused without sub-steps, or sub-stepped below the stable step.
    for integrator in [Integrator::SymplecticEuler, Integrator::ExplicitEuler] {
        let mut refusing = stiff_cloth(integrator, SubstepPolicy::Refuse);
        assert!(matches!(
            refusing.step(dt),
            Err(SolverError::StepTooLarge { .. })
        ));
        let mut s = stiff_cloth(
            integrator,
            SubstepPolicy::Auto {
                max_substeps: 10_000,
            },
        );
        let stable = s.stability().dt(integrator);
        let r = s.step(dt).unwrap();
        assert!(
            r.finite && !r.recovered && !r.limited,
            "{integrator}: {r:?}"
        );
        assert!(r.substep_dt < stable, "{integrator}: {r:?} vs {stable}");
        let e = s.energy().total();
        assert!(e <= bound(e0), "{integrator}: {e} vs {e0}");
    }
}

#[test]
fn a_poke_of_ten_thousand_times_gravity() {
    for integrator in Integrator::ALL {
        let grid = cloth_grid(9).unwrap();
        let mut s = grid
            .solver_with(integrator, SubstepPolicy::default())
            .unwrap();
        // The paper's damping (eq 3): explicit Euler needs it (see the next assertion).
        let mut c = *s.config();
        if integrator == Integrator::ExplicitEuler {
            // By default no stable explicit step means implicit Euler takes over ...
            let mut falls_back = s.clone();
            let r = falls_back.step(1.0 / 60.0).unwrap();
            assert!(r.fell_back && r.finite, "{r:?}");
            assert_eq!(falls_back.stepper.integrator(), Integrator::ImplicitEuler);
            // ... and without a fall-back the solver says it cannot.
            c.on_instability = InstabilityResponse::Freeze;
            s.set_config(c).unwrap();
            assert!(matches!(
                s.step(1.0 / 60.0),
                Err(SolverError::StepTooLarge { stable_dt, .. }) if stable_dt == 0.0
            ));
        }
        c.damping_model = DampingModel::Relative;
        s.set_config(c).unwrap();
        let centre = 40;
        let force = 1.0e4 * 0.1 * STANDARD_GRAVITY;
        s.set_external_force(centre, force).unwrap();
        let dt = 1.0 / 60.0;
        for _ in 0..30 {
            let r = s.step(dt).unwrap();
            assert!(
                r.finite && !r.recovered && !r.limited,
                "{integrator}: {r:?}"
            );
        }
        let pushed = s.position(centre).y;
        assert!(
            pushed < -0.5,
            "{integrator}: the poked point is at {pushed}"
        );
        s.clear_external_forces();
        for _ in 0..30 {
            let r = s.step(dt).unwrap();
            assert!(r.finite && !r.recovered, "{integrator}: {r:?}");
        }
        assert!(s.positions().iter().all(|p| p.is_finite()));
        assert!(s.velocities().iter().all(|v| v.is_finite()));
    }
}

#[test]
fn coincident_points_joined_by_a_spring() {
    for integrator in Integrator::ALL {
        for rest in [0.0, 1.0] {
            let p = Vec3::new(0.5, 0.5, 0.5);
            let mut s = Solver::new(
                &[p, p],
                &[1.0, 1.0],
                &[spring(0, 1, rest, 10.0, 1.0)],
                config(integrator),
            )
            .unwrap();
            for _ in 0..600 {
                let r = s.step(1.0 / 60.0).unwrap();
                assert!(r.finite && !r.recovered, "{integrator}: {r:?}");
            }
            let d = s.position(0).distance(s.position(1));
            assert!(
                (d - rest).abs() < 1e-2,
                "{integrator}, rest {rest}: distance {d}"
            );
            assert!(s.energy().total().is_finite());
        }
    }
}

#[test]
fn zero_and_bad_time_steps() {
    for integrator in Integrator::ALL {
        let mut s = oscillator(integrator);
        let before = s.positions();
        let r = s.step(0.0).unwrap();
        assert_eq!(r.substeps, 0);
        assert!(r.finite && !r.recovered, "{r:?}");
        assert_eq!(s.positions(), before);
        for bad in [-1.0, f32::NAN, f32::INFINITY] {
            assert!(matches!(s.step(bad), Err(SolverError::InvalidTimeStep(_))));
        }
        assert_eq!(s.positions(), before);
    }
}

// ---------------------------------------------------------------------------------------
// Anchors, drag, errors.

#[test]
fn anchors_pin_poke_and_drag_while_running() {
    let p = [Vec3::ZERO];
    let mut s = Solver::new(
        &p,
        &[1.0],
        &[],
        SolverConfig {
            integrator: Integrator::ImplicitEuler,
            drag: 1.0,
            ..SolverConfig::default()
        },
    )
    .unwrap();
    let id = s
        .add_anchor(Anchor {
            point: 0,
            target: Vec3::ZERO,
            stiffness: 1.0e4,
            damping: 100.0,
        })
        .unwrap();
    for _ in 0..120 {
        s.step(1.0 / 60.0).unwrap();
    }
    // A pin: it sags by m·g/k only.
    assert!(
        (s.position(0).y + 9.81e-4).abs() < 1e-5,
        "{}",
        s.position(0)
    );
    // A drag: move the target, the point follows.
    s.set_anchor_target(id, Vec3::new(1.0, 0.0, 0.0)).unwrap();
    for _ in 0..120 {
        s.step(1.0 / 60.0).unwrap();
    }
    assert!((s.position(0).x - 1.0).abs() < 1e-3, "{}", s.position(0));
    // Released, it falls.
    assert!(s.remove_anchor(id).is_some());
    assert!(s.remove_anchor(id).is_none());
    assert_eq!(
        s.set_anchor_target(id, Vec3::ZERO),
        Err(SolverError::UnknownAnchor)
    );
    let y = s.position(0).y;
    for _ in 0..30 {
        s.step(1.0 / 60.0).unwrap();
    }
    assert!(s.position(0).y < y - 0.05);
    // A new anchor reuses the slot but not the handle.
    let again = s
        .add_anchor(Anchor {
            point: 0,
            target: Vec3::ZERO,
            stiffness: 1.0,
            damping: 0.0,
        })
        .unwrap();
    assert_ne!(again, id);
    assert_eq!(s.anchors().count(), 1);
}

#[test]
fn drag_decays_velocity_exponentially() {
    let mut s = Solver::new(
        &[Vec3::ZERO],
        &[2.0],
        &[],
        SolverConfig {
            drag: 0.5,
            ..config(Integrator::SymplecticEuler)
        },
    )
    .unwrap();
    s.set_velocity(0, Vec3::X).unwrap();
    for _ in 0..1000 {
        s.step(1.0e-3).unwrap();
    }
    let expected = (-0.5f32).exp();
    assert!((s.velocity(0).x - expected).abs() < 1e-3);
}

#[test]
fn bad_input_gets_typed_errors() {
    let p = [Vec3::ZERO, Vec3::X];
    let c = SolverConfig::default();
    let ok = spring(0, 1, 1.0, 1.0, 0.0);
    type Case = (&'static str, Result<Solver, SolverError>);
    let cases: Vec<Case> = vec![
        ("masses", Solver::new(&p, &[1.0], &[ok], c)),
        ("zero mass", Solver::new(&p, &[1.0, 0.0], &[ok], c)),
        ("nan mass", Solver::new(&p, &[1.0, f32::NAN], &[ok], c)),
        (
            "nan position",
            Solver::new(&[Vec3::NAN, Vec3::X], &[1.0; 2], &[ok], c),
        ),
        (
            "huge position",
            Solver::new(&[Vec3::splat(1e30), Vec3::X], &[1.0; 2], &[ok], c),
        ),
        (
            "self spring",
            Solver::new(&p, &[1.0; 2], &[spring(1, 1, 1.0, 1.0, 0.0)], c),
        ),
        (
            "out of range",
            Solver::new(&p, &[1.0; 2], &[spring(0, 2, 1.0, 1.0, 0.0)], c),
        ),
        (
            "negative stiffness",
            Solver::new(&p, &[1.0; 2], &[spring(0, 1, 1.0, -1.0, 0.0)], c),
        ),
        (
            "nan rest",
            Solver::new(&p, &[1.0; 2], &[spring(0, 1, f32::NAN, 1.0, 0.0)], c),
        ),
        (
            "inf damping",
            Solver::new(&p, &[1.0; 2], &[spring(0, 1, 1.0, 1.0, f32::INFINITY)], c),
        ),
        (
            "negative drag",
            Solver::new(&p, &[1.0; 2], &[ok], SolverConfig { drag: -1.0, ..c }),
        ),
        (
            "margin",
            Solver::new(
                &p,
                &[1.0; 2],
                &[ok],
                SolverConfig {
                    stability_margin: 2.0,
                    ..c
                },
            ),
        ),
        (
            "no sub-steps",
            Solver::new(
                &p,
                &[1.0; 2],
                &[ok],
                SolverConfig {
                    substeps: SubstepPolicy::Auto { max_substeps: 0 },
                    ..c
                },
            ),
        ),
    ];
    for (name, result) in cases {
        let err = result.expect_err(name);
        assert!(!err.to_string().is_empty(), "{name}");
    }
    let mut s = Solver::new(&p, &[1.0; 2], &[ok], c).unwrap();
    assert!(s.set_position(5, Vec3::ZERO).is_err());
    assert!(s.set_velocity(0, Vec3::INFINITY).is_err());
    assert!(s.set_external_force(0, Vec3::NAN).is_err());
    assert!(s.set_fixed(2, true).is_err());
    let bad_anchor = Anchor {
        point: 0,
        target: Vec3::NAN,
        stiffness: 1.0,
        damping: 0.0,
    };
    assert!(s.add_anchor(bad_anchor).is_err());
    assert!(
        s.add_anchor(Anchor {
            point: 9,
            ..bad_anchor
        })
        .is_err()
    );
    assert!(
        s.add_anchor(Anchor {
            target: Vec3::ZERO,
            stiffness: -1.0,
            ..bad_anchor
        })
        .is_err()
    );
    assert_eq!(
        "euler".parse::<Integrator>().unwrap_err().to_string(),
        "unknown integrator \"euler\" (expected explicit-euler, symplectic-euler or implicit-euler)"
    );
}
