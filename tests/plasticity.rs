//! Plastic flow (issue 17): a pull beyond the yield strain leaves a permanent shape; below
//! yield, or with an elastic material, the surface returns to rest.

use bevy_point_springs::core::cloud::shapes;
use bevy_point_springs::core::network::{NetworkConfig, SpringNetwork, build_network};
use bevy_point_springs::core::simplify::{SimplifyConfig, simplify_cloud};
use bevy_point_springs::core::solver::{
    Anchor, Integrator, Plasticity, Solver, SolverConfig, SolverError, SpringMaterial,
};
use glam::Vec3;

/// Tick of the runs, seconds.
const DT: f32 = 1.0 / 60.0;

/// Seconds the centre is held out of the plane, then seconds it is left to settle.
const HOLD_SECONDS: f32 = 2.0;
const SETTLE_SECONDS: f32 = 6.0;

/// A 1 m square sheet in the xz plane as a spring network of about 400 simulation points.
fn sheet() -> SpringNetwork {
    let cloud = shapes::square_sheet(1.0, 0.02);
    let kept = simplify_cloud(&cloud, &SimplifyConfig::target(400)).unwrap();
    let (p, n) = kept.gather(cloud.positions(), cloud.normals().unwrap());
    build_network(&p, &n, &NetworkConfig::default()).unwrap()
}

/// The sheet with its rim held, its centre pulled `pull` metres out of the plane for
/// [`HOLD_SECONDS`] and let go for [`SETTLE_SECONDS`]; returns how far the centre ends up
/// from where it started, and how many times a spring flowed over the run.
fn pull_and_release(network: &SpringNetwork, material: SpringMaterial, pull: f32) -> (f32, usize) {
    let config = SolverConfig {
        integrator: Integrator::ImplicitEuler,
        gravity: Vec3::ZERO,
        drag: 4.0,
        ..SolverConfig::default()
    };
    let mut solver = Solver::from_network(network, &material, config).unwrap();
    let rim = 0.5 - 0.03;
    for (i, p) in network.positions.iter().enumerate() {
        if p.x.abs() > rim || p.z.abs() > rim {
            solver.set_fixed(i, true).unwrap();
        }
    }
    let centre = (0..network.len())
        .min_by(|&a, &b| {
            let d = |i: usize| network.positions[i].length_squared();
            d(a).total_cmp(&d(b))
        })
        .unwrap();
    let start = network.positions[centre];
    let anchor = solver
        .add_anchor(Anchor {
            point: centre as u32,
            target: start + Vec3::Y * pull,
            stiffness: 2000.0,
            damping: 20.0,
        })
        .unwrap();
    let mut flowed = 0;
    for _ in 0..(HOLD_SECONDS / DT) as usize {
        flowed += solver.step(DT).unwrap().flowed_springs;
    }
    solver.remove_anchor(anchor).unwrap();
    for _ in 0..(SETTLE_SECONDS / DT) as usize {
        flowed += solver.step(DT).unwrap().flowed_springs;
    }
    (solver.position(centre).distance(start), flowed)
}

fn plastic() -> SpringMaterial {
    SpringMaterial {
        yield_strain: 0.05,
        creep_rate: 5.0,
        ..SpringMaterial::default()
    }
}

#[test]
fn a_pull_beyond_yield_leaves_a_permanent_dent() {
    let network = sheet();
    let pull = 0.3;
    let (kept, flowed) = pull_and_release(&network, plastic(), pull);
    assert!(flowed > 0);
    // Well beyond the yield strain the springs near the centre took most of the pull as
    // their rest length: the dent stays.
    assert!(
        kept > 0.3 * pull,
        "plastic: the centre kept {kept} of a {pull} pull"
    );
    // The same pull on the elastic material springs back.
    let (elastic, _) = pull_and_release(&network, SpringMaterial::default(), pull);
    println!("a {pull} m pull: plastic keeps {kept} m ({flowed} flows), elastic {elastic} m");
    assert!(elastic < 0.02 * pull, "elastic: the centre kept {elastic}");
}

#[test]
fn below_yield_the_surface_returns_to_rest() {
    let network = sheet();
    // The shortest springs (0.02 m) strain by 12 % under this pull: below a 20 % yield.
    let pull = 0.01;
    let material = SpringMaterial {
        yield_strain: 0.2,
        ..plastic()
    };
    let (kept, flowed) = pull_and_release(&network, material, pull);
    println!("a {pull} m pull below yield: the centre keeps {kept} m");
    assert_eq!(flowed, 0, "no spring may pass the yield strain");
    assert!(
        kept < 1e-3 * pull,
        "the centre kept {kept} of a {pull} pull"
    );
}

#[test]
fn bad_plasticity_is_a_typed_error() {
    let network = sheet();
    let mut solver = Solver::from_network(
        &network,
        &SpringMaterial::default(),
        SolverConfig::default(),
    )
    .unwrap();
    for (yield_strain, creep_rate) in [(-0.1, 1.0), (0.1, f32::NAN), (f32::INFINITY, 1.0)] {
        let bad = Plasticity {
            yield_strain,
            creep_rate,
        };
        assert!(matches!(
            solver.springs.set_plasticity(bad),
            Err(SolverError::InvalidPlasticity { .. })
        ));
    }
    assert!(solver.springs.plasticity().is_elastic());
}
