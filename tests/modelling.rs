//! Modelling (issue 17): plastic flow (a pull beyond the yield strain leaves a permanent
//! shape; below yield, or with an elastic material, the surface returns to rest), baking
//! the current shape into the rest shape, and exporting the deformed surface.

use std::ops::ControlFlow;

use bevy_point_springs::core::cloud::io::{PlyEncoding, read_cloud};
use bevy_point_springs::core::cloud::shapes;
use bevy_point_springs::core::network::{
    NetworkConfig, NetworkError, SpringNetwork, build_network,
};
use bevy_point_springs::core::pipeline::{
    ExportError, PreparedSurface, SurfaceConfig, prepare_surface,
};
use bevy_point_springs::core::simplify::{SimplifyConfig, simplify_cloud};
use bevy_point_springs::core::solver::{
    Anchor, BendingModel, Integrator, Plasticity, Solver, SolverConfig, SolverError, SpringMaterial,
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
    for bending in [BendingModel::Springs, BendingModel::Hinges] {
        let material = SpringMaterial {
            bending,
            ..plastic()
        };
        let (kept, flowed) = pull_and_release(&network, material, pull);
        assert!(flowed > 0);
        // Well beyond the yield strain the springs near the centre took most of the pull as
        // their rest length (and the hinges their bend as their rest angle): the dent stays.
        assert!(
            kept > 0.3 * pull,
            "{bending:?}, plastic: the centre kept {kept} of a {pull} pull"
        );
        // The same pull on the elastic material springs back.
        let elastic = SpringMaterial {
            bending,
            ..SpringMaterial::default()
        };
        let (elastic, _) = pull_and_release(&network, elastic, pull);
        println!(
            "{bending:?}: a {pull} m pull: plastic keeps {kept} m ({flowed} flows), elastic {elastic} m"
        );
        assert!(
            elastic < 0.02 * pull,
            "{bending:?}, elastic: the centre kept {elastic}"
        );
    }
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
            ..Plasticity::ELASTIC
        };
        assert!(matches!(
            solver.springs.set_plasticity(bad),
            Err(SolverError::InvalidPlasticity { .. })
        ));
    }
    assert!(solver.springs.plasticity().is_elastic());
}

/// A 2000-point sphere on 200 simulation points without gravity, its bottom held and its
/// top pulled up 0.3 for a second, then let go (still moving).
fn pulled_sphere() -> PreparedSurface {
    pulled_sphere_bending(BendingModel::Springs)
}

/// [`pulled_sphere`] with the bending model `bending`.
fn pulled_sphere_bending(bending: BendingModel) -> PreparedSurface {
    let config = SurfaceConfig {
        material: SpringMaterial {
            bending,
            ..SpringMaterial::default()
        },
        simplify: SimplifyConfig::target(200),
        solver: SolverConfig {
            integrator: Integrator::ImplicitEuler,
            gravity: Vec3::ZERO,
            ..SolverConfig::default()
        },
        ..SurfaceConfig::default()
    };
    let mut surface = prepare_surface(shapes::fibonacci_sphere(2000, 1.0), &config, &mut |_| {
        ControlFlow::Continue(())
    })
    .unwrap();
    let solver = &mut surface.solver;
    for i in 0..solver.len() {
        if solver.position(i).y < -0.7 {
            solver.set_fixed(i, true).unwrap();
        }
    }
    let top = (0..solver.len())
        .max_by(|&a, &b| solver.position(a).y.total_cmp(&solver.position(b).y))
        .unwrap();
    let anchor = solver
        .add_anchor(Anchor {
            point: top as u32,
            target: solver.position(top) + Vec3::Y * 0.3,
            stiffness: 500.0,
            damping: 5.0,
        })
        .unwrap();
    for _ in 0..60 {
        solver.step(DT).unwrap();
    }
    solver.remove_anchor(anchor).unwrap();
    solver.step(DT).unwrap();
    surface
}

#[test]
fn a_baked_shape_stays_put() {
    let mut surface = pulled_sphere();
    let pulled = surface.solver.positions();
    let top_y = pulled.iter().map(|p| p.y).fold(f32::MIN, f32::max);
    assert!(top_y > 1.1, "the pull raised the top to {top_y}");
    surface.bake().unwrap();
    let dense_rest = surface.dense.transfer().rest_positions().to_vec();
    assert!(
        dense_rest == surface.dense.positions(),
        "the deformed surface is the rest one"
    );
    // The rest shape is the pulled one: with no force, nothing moves, not even once.
    for _ in 0..60 {
        surface.solver.step(DT).unwrap();
        let fastest = surface.solver.points.max_speed();
        assert_eq!(fastest, 0.0);
    }
    assert!(
        surface.solver.positions() == pulled,
        "no simulation point moved"
    );
    // The transfer gives the rest surface back to its coefficients' rounding (as it does
    // for a surface just prepared).
    surface.dense.follow(&surface.solver.points).unwrap();
    let off = farthest(surface.dense.positions(), &dense_rest);
    assert!(off < 1e-5, "the dense surface moved by {off}");
    // The masses are the pulled shape's: its area grew, and the mass with it (each point's
    // share of the dense area grown with its region; density 1).
    let grown = pulled_area_ratio(&surface);
    let fresh = pulled_sphere().network.report.total_mass;
    let mass: f32 = surface.network.masses.iter().sum();
    println!(
        "baked: area {grown:.4} of the rest sphere's, mass {:.4} of its, dense surface within {off:e}",
        mass / fresh
    );
    assert!(grown > 1.002, "area ratio {grown}");
    assert!((mass / surface.network.report.dense_area - 1.0).abs() < 1e-4);
    assert!(
        (mass / fresh / grown - 1.0).abs() < 0.01,
        "{mass} / {fresh} against {grown}"
    );
}

#[test]
fn a_baked_shape_on_hinges_stays_put() {
    let mut surface = pulled_sphere_bending(BendingModel::Hinges);
    let pulled = surface.solver.positions();
    let before = surface
        .solver
        .springs
        .hinges()
        .angles(&surface.solver.points);
    surface.bake().unwrap();
    // The rest angles are the pulled shape's.
    let rest: Vec<f32> = surface
        .solver
        .springs
        .hinges()
        .iter()
        .map(|h| h.rest_angle)
        .collect();
    assert!(rest == before);
    for _ in 0..60 {
        surface.solver.step(DT).unwrap();
    }
    let moved = farthest(&surface.solver.positions(), &pulled);
    assert!(moved < 1e-6, "a point moved {moved}");
    assert!(surface.solver.energy().bending < 1e-12);
}

#[test]
fn a_baked_shape_on_its_curvature_stays_put() {
    let mut surface = pulled_sphere_bending(BendingModel::Curvature);
    assert!(surface.solver.curvature_count() > 0);
    let pulled = surface.solver.positions();
    assert!(surface.solver.energy().bending > 1e-6);
    surface.bake().unwrap();
    // The rest curvatures and the fits' rest residual heights are the pulled shape's: no
    // bending energy, no force.
    assert!(surface.solver.energy().bending < 1e-12);
    for _ in 0..60 {
        surface.solver.step(DT).unwrap();
    }
    let moved = farthest(&surface.solver.positions(), &pulled);
    assert!(moved < 1e-6, "a point moved {moved}");
}

/// The largest distance between the points of `a` and those of `b`, pairwise.
fn farthest(a: &[Vec3], b: &[Vec3]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0f32, f32::max)
}

/// The baked network's area over the area of the unit sphere's network it came from.
fn pulled_area_ratio(surface: &PreparedSurface) -> f32 {
    let fresh = pulled_sphere();
    surface.network.report.area / fresh.network.report.area
}

#[test]
fn an_export_reads_back_bit_for_bit_and_a_failed_one_leaves_the_old_file() {
    let mut surface = pulled_sphere();
    surface.dense.follow(&surface.solver.points).unwrap();
    let dir = std::env::temp_dir().join(format!("point-springs-export-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("pulled.ply");
    surface
        .dense
        .export(&path, PlyEncoding::BinaryLittleEndian)
        .unwrap();
    let back = read_cloud(&path, None).unwrap();
    assert_eq!(back.positions(), surface.dense.positions());
    assert_eq!(back.normals().unwrap(), surface.dense.normals());
    // Nothing else was left beside it.
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
    // Into a folder that does not exist: a typed error.
    let nowhere = dir.join("no such folder").join("pulled.ply");
    assert!(matches!(
        surface.dense.export(&nowhere, PlyEncoding::Ascii),
        Err(ExportError::Save(_))
    ));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn reshaping_refuses_bad_shapes_with_typed_errors() {
    let network = sheet();
    let mut shape = network.positions.clone();
    assert!(matches!(
        network.reshaped(&shape[1..], 1.0),
        Err(NetworkError::LengthMismatch { .. })
    ));
    assert!(matches!(
        network.reshaped(&shape, 0.0),
        Err(NetworkError::InvalidDensity(_))
    ));
    shape[17] = Vec3::NAN;
    assert!(matches!(
        network.reshaped(&shape, 1.0),
        Err(NetworkError::InvalidPoint(17))
    ));
}
