//! Materials that do not depend on the resolution (issue 18): the total mass is ρ times the
//! surface's area at every simplification level, on a procedural sphere and on real scans,
//! and a sheet's moduli give the springs of a regular lattice exactly that modulus.

use std::f32::consts::PI;
use std::ops::ControlFlow;

use bevy_point_springs::core::PointCloud;
use bevy_point_springs::core::cloud::io::read_cloud;
use bevy_point_springs::core::cloud::shapes::{fibonacci_sphere, hat, square_sheet};
use bevy_point_springs::core::network::{NetworkError, dense_point_areas};
use bevy_point_springs::core::normals::{DEFAULT_NORMAL_K, ensure_normals};
use bevy_point_springs::core::pipeline::{PreparedSurface, SurfaceConfig, prepare_surface};
use bevy_point_springs::core::simplify::{DEFAULT_SIMPLIFY_K, SimplifyConfig};
use bevy_point_springs::core::solver::membrane::{LATTICE_POISSON_RATIO, membrane_energy};
use bevy_point_springs::core::solver::{
    BendingModel, DampingModel, ImplicitSolver, Integrator, MaterialUnits, Solver, SolverConfig,
    SpringMaterial,
};
use glam::Vec3;

#[allow(dead_code)]
#[path = "support/surfaces.rs"]
mod surfaces;
use surfaces::*;

/// Density of these tests (not 1, so that a mass mistaken for an area shows).
const RHO: f32 = 2.5;

fn prepared(cloud: &PointCloud, fraction: f32) -> PreparedSurface {
    let target = ((cloud.len() as f32 * fraction).round() as usize).max(20);
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(target),
        material: SpringMaterial {
            density: RHO,
            ..SpringMaterial::default()
        },
        ..SurfaceConfig::default()
    };
    prepare_surface(cloud.clone(), &config, &mut |_| ControlFlow::Continue(())).unwrap()
}

/// Σm / (ρ·area) − 1 at 2 % and 20 % of the points, and eq 1's for comparison.
fn mass_errors(cloud: &PointCloud, area: f32) -> Vec<(f32, f32)> {
    [0.02, 0.2]
        .into_iter()
        .map(|fraction| {
            let s = prepared(cloud, fraction);
            let total: f32 = s.solver.masses.masses().iter().sum();
            let eq1 = s.network.report.area / area - 1.0;
            println!(
                "{fraction}: {} points, mass {:+.3} %, eq 1 {:+.3} %",
                s.network.len(),
                100.0 * (total / (RHO * area) - 1.0),
                100.0 * eq1,
            );
            assert!(
                s.solver
                    .masses
                    .masses()
                    .iter()
                    .all(|m| m.is_finite() && *m > 0.0)
            );
            (fraction, total / (RHO * area) - 1.0)
        })
        .collect()
}

#[test]
fn the_total_mass_is_the_density_times_the_area_at_every_level() {
    let mut sphere = read_cloud(&asset("sphere3203.ply"), None).unwrap();
    ensure_normals(&mut sphere, DEFAULT_NORMAL_K).unwrap();
    for (f, e) in mass_errors(&sphere, 4.0 * PI) {
        assert!(e.abs() < 0.01, "sphere at {f}: {e}");
    }
    // CGAL's sphere of radius 10, sampled on circles of latitude: four points on a circle
    // everywhere, so neighbouring rings split quads by different diagonals.
    let sphere926 = read_cloud(&asset("sphere926.pwn"), None).unwrap();
    for (f, e) in mass_errors(&sphere926, 400.0 * PI) {
        assert!(e.abs() < 0.01, "sphere926 at {f}: {e}");
    }
    // The cap below y = -0.2 of the unit sphere: 2π·0.8. Its rim points' rings are open, and
    // their shares stop at the outermost ring triangles (1.5 % short).
    let hat = read_cloud(&asset("hat3000.ply"), None).unwrap();
    for (f, e) in mass_errors(&hat, 1.6 * PI) {
        assert!(e.abs() < 0.02, "hat at {f}: {e}");
    }
    let mut kitten = read_cloud(&asset("kitten.off"), None).unwrap();
    ensure_normals(&mut kitten, DEFAULT_NORMAL_K).unwrap();
    let (kept, full_network) = network_of(&kitten, kitten.len(), 1.0);
    let full = full_network.report.area;
    // §3's first pass measures the same shares as the stand-alone measure.
    let alone = dense_point_areas(
        kitten.positions(),
        kitten.normals().unwrap(),
        &[],
        DEFAULT_SIMPLIFY_K,
    )
    .unwrap();
    assert_eq!(kept.point_areas.len(), kitten.len());
    for (i, (a, b)) in kept.point_areas.iter().zip(&alone).enumerate() {
        assert!(
            (a - b).abs() <= 1e-6 * b.max(1e-3),
            "point {i}: {a} against {b}"
        );
    }
    for (f, e) in mass_errors(&kitten, full) {
        assert!(e.abs() < 0.01, "kitten at {f}: {e}");
    }
    let mut elephant = read_cloud(&asset("elephant.off"), None).unwrap();
    ensure_normals(&mut elephant, DEFAULT_NORMAL_K).unwrap();
    let mesh: f32 = dense_point_areas(
        elephant.positions(),
        elephant.normals().unwrap(),
        elephant.faces(),
        DEFAULT_SIMPLIFY_K,
    )
    .unwrap()
    .iter()
    .sum();
    println!("elephant mesh {mesh}");
    for (f, e) in mass_errors(&elephant, mesh) {
        assert!(e.abs() < 1e-4, "elephant at {f}: {e}");
    }
    let (p, _) = elephant.clone().into_parts();
    let mut bare = PointCloud::new(p, None).unwrap();
    ensure_normals(&mut bare, DEFAULT_NORMAL_K).unwrap();
    for (f, e) in mass_errors(&bare, mesh) {
        assert!(e.abs() < 0.01, "bare elephant at {f}: {e}");
    }
}

#[test]
fn a_sheets_modulus_gives_a_regular_lattice_that_modulus() {
    // Every point of a triangular lattice a simulation point: interior points have six
    // stretch springs of the spacing's length and the hexagonal cell's area.
    let spacing = 0.05;
    let cloud = square_sheet(1.0, spacing);
    let modulus = 80.0;
    let ratio = 0.25;
    let material = SpringMaterial {
        density: RHO,
        units: MaterialUnits::Sheet,
        stretch_stiffness: modulus,
        stretch_damping: ratio,
        ..SpringMaterial::default()
    };
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(cloud.len()),
        material,
        ..SurfaceConfig::default()
    };
    let s = prepare_surface(cloud.clone(), &config, &mut |_| ControlFlow::Continue(())).unwrap();
    assert_eq!(s.network.len(), cloud.len());
    let specs = material.springs(&s.network);
    let stretch = s.network.stretch.len();
    let mut degree = vec![0; s.network.len()];
    for spring in &s.network.stretch {
        degree[spring.a as usize] += 1;
        degree[spring.b as usize] += 1;
    }
    let inner = |i: u32| !s.network.boundary[i as usize] && degree[i as usize] == 6;
    // The lattice's Young's modulus is 2k/√3: k = √3/2 · modulus.
    let expected = 3f32.sqrt() / 2.0 * modulus;
    let cell_mass = RHO * 3f32.sqrt() / 2.0 * spacing * spacing;
    let mut checked = 0;
    for spec in &specs[..stretch] {
        if !(inner(spec.a) && inner(spec.b)) {
            continue;
        }
        checked += 1;
        assert!(
            (spec.stiffness / expected - 1.0).abs() < 0.01,
            "{spec:?} against {expected}"
        );
        // Critical damping of two equal masses m: 2√(k·m/2).
        let critical = 2.0 * (spec.stiffness * cell_mass / 2.0).sqrt();
        assert!(
            (spec.damping / (ratio * critical) - 1.0).abs() < 0.01,
            "{spec:?}"
        );
    }
    assert!(
        checked > stretch / 2,
        "{checked} of {stretch} springs inside"
    );
    // Per spring, the same numbers are the springs' own.
    let per_spring = SpringMaterial {
        units: MaterialUnits::PerSpring,
        ..material
    };
    assert!(
        per_spring.springs(&s.network)[..stretch]
            .iter()
            .all(|p| p.stiffness == modulus)
    );
}

#[test]
fn a_sheets_springs_and_couplings_are_the_membrane_on_an_uneven_network() {
    // The hat at 40 % of its points: §3 leaves uneven triangles, on which no spring
    // stiffness alone is the membrane (docs/PERFORMANCE.md, "Why the hat does not converge").
    let cloud = hat(3000, 1.0, -0.2);
    let material = SpringMaterial {
        density: RHO,
        units: MaterialUnits::Sheet,
        stretch_stiffness: 70.0,
        bending: BendingModel::Hinges,
        ..SpringMaterial::default()
    };
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(1200),
        material,
        ..SurfaceConfig::default()
    };
    let mut s = prepare_surface(cloud, &config, &mut |_| ControlFlow::Continue(())).unwrap();
    let network = &s.network;
    assert_eq!(network.report.fallback_springs, 0);
    let couplings = material.couplings(network);
    assert_eq!(couplings.len(), network.triangles.len());
    // Smooth deflections, in and out of the surface.
    let fields: [fn(Vec3) -> Vec3; 3] = [
        |p| Vec3::Y * 0.01 * (1.0 - p.x * p.x - p.z * p.z),
        |p| Vec3::new(p.z, 0.0, p.x) * 0.005 * (1.5 * p.y).cos(),
        |p| Vec3::new((2.0 * p.z).sin(), 0.3 * p.x, (1.7 * p.x).cos()) * 0.004,
    ];
    for (f, field) in fields.iter().enumerate() {
        let moved: Vec<Vec3> = network.positions.iter().map(|&p| p + field(p)).collect();
        for (i, &p) in moved.iter().enumerate() {
            s.solver.points.set_position(i, p).unwrap();
        }
        let springs = s.solver.energy().spring;
        let membrane = membrane_energy(
            &network.triangles,
            &network.positions,
            &moved,
            70.0,
            LATTICE_POISSON_RATIO,
        );
        // Only the length changes' second order terms differ (strains below 1 %).
        assert!(
            (springs / membrane - 1.0).abs() < 0.01,
            "field {f}: springs {springs} against the membrane's {membrane}"
        );
    }
}

/// The hat of `bench convergence` in a sheet's units on hinges, pinned at its rim, settled
/// under gravity at `points` simulation points: the mass-weighted mean sag of its points.
fn hat_sag(points: usize) -> f32 {
    let material = SpringMaterial {
        density: 0.2,
        units: MaterialUnits::Sheet,
        stretch_stiffness: 2.0 * 60.0 / 3f32.sqrt(),
        stretch_damping: 0.3,
        bending: BendingModel::Hinges,
        bending_modulus: 0.3,
        ..SpringMaterial::default()
    };
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(points),
        material,
        solver: SolverConfig {
            integrator: Integrator::ImplicitEuler,
            gravity: Vec3::NEG_Y * 9.81,
            drag: 1.0,
            ..SolverConfig::default()
        },
        ..SurfaceConfig::default()
    };
    let cloud = hat(3000, 1.0, -0.2);
    let mut s = prepare_surface(cloud, &config, &mut |_| ControlFlow::Continue(())).unwrap();
    let network = &s.network;
    for (i, &rim) in network.boundary.iter().enumerate() {
        if rim {
            s.solver.set_fixed(i, true).unwrap();
        }
    }
    for _ in 0..450 {
        s.solver.step(1.0 / 30.0).unwrap();
    }
    let total: f32 = network.masses.iter().sum();
    (0..network.len())
        .map(|i| (network.positions[i].y - s.solver.position(i).y) * network.masses[i])
        .sum::<f32>()
        / total
}

#[test]
fn a_sheets_hat_sags_the_same_at_a_coarse_and_a_middle_level() {
    // With springs alone the 40 % level was 11 % stiffer than the 5 % one (the springs are
    // not the membrane on §3's uneven triangles); with the couplings they agree to 1.5 %.
    let (coarse, middle) = (hat_sag(150), hat_sag(1200));
    eprintln!("hat sag: {coarse:.5} at 150 points, {middle:.5} at 1200");
    assert!(
        coarse > 0.0 && (middle / coarse - 1.0).abs() < 0.03,
        "{coarse} against {middle}"
    );
}

/// A 2 × 2 sheet of spacing `spacing`, simplified to `points` points (all of them: a regular
/// lattice), pinned along its rim and settled under gravity, bending as `bending` says with a
/// flexural rigidity heavy enough that bending carries most of the load: the mass-weighted
/// mean sag of its points.
fn sheet_sag(spacing: f32, points: Option<usize>, bending: BendingModel) -> f32 {
    let material = SpringMaterial {
        density: 0.2,
        units: MaterialUnits::Sheet,
        stretch_stiffness: 2.0 * 60.0 / 3f32.sqrt(),
        stretch_damping: 0.3,
        bending,
        bending_modulus: 3.0,
        ..SpringMaterial::default()
    };
    let cloud = square_sheet(2.0, spacing);
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(points.unwrap_or(cloud.len())),
        material,
        solver: SolverConfig {
            integrator: Integrator::ImplicitEuler,
            gravity: Vec3::NEG_Z * 9.81,
            drag: 1.0,
            ..SolverConfig::default()
        },
        ..SurfaceConfig::default()
    };
    let mut s = prepare_surface(cloud, &config, &mut |_| ControlFlow::Continue(())).unwrap();
    let network = &s.network;
    for (i, &rim) in network.boundary.iter().enumerate() {
        if rim {
            s.solver.set_fixed(i, true).unwrap();
        }
    }
    for _ in 0..300 {
        s.solver.step(1.0 / 30.0).unwrap();
    }
    let total: f32 = network.masses.iter().sum();
    (0..network.len())
        .map(|i| (network.positions[i].z - s.solver.position(i).z) * network.masses[i])
        .sum::<f32>()
        / total
}

/// The mean deflection of a simply supported a × a plate of flexural rigidity D under a
/// uniform load q (Navier's double series, which does not depend on Poisson's ratio):
/// w̄ = 64·q·a⁴/(π⁸·D)·Σ 1/(m²n²(m² + n²)²) over odd m and n.
fn navier_mean_deflection(q: f64, a: f64, d: f64) -> f64 {
    let mut sum = 0.0;
    for m in (1..200).step_by(2) {
        for n in (1..200).step_by(2) {
            let (m, n) = (f64::from(m), f64::from(n));
            sum += 1.0 / (m * m * n * n * (m * m + n * n).powi(2));
        }
    }
    64.0 * q * a.powi(4) / (std::f64::consts::PI.powi(8) * d) * sum
}

#[test]
fn a_plate_bending_on_its_curvature_sags_as_navier_says_on_an_uneven_network() {
    // A lattice of spacing 0.04 simplified by §3 to an uneven network of 740 points, pinned
    // along its rim: a simply supported plate. Hinges measure the fold where the flat
    // triangles meet, which depends on how the mesh is cut (−14 % here, measured; −26 % at
    // 1465 points); the fitted curvature, stabilised, does not (−0.5 %).
    let exact = navier_mean_deflection(0.2 * 9.81, 2.0, 3.0) as f32;
    let uneven = sheet_sag(0.04, Some(740), BendingModel::Curvature);
    eprintln!("plate: Navier {exact:.5}, curvature on 740 uneven points {uneven:.5}");
    assert!(
        (uneven / exact - 1.0).abs() < 0.03,
        "{uneven} against Navier's {exact}"
    );
}

/// Radius of the tube [`measured_modulus`] pulls, m.
const TUBE_RADIUS: f32 = 0.2;

/// A tube of [`TUBE_RADIUS`] and length 0.8 along Z on a triangular lattice of 40 points per
/// ring (rings along the circumference, every other one turned by half a spacing), normals
/// outward: a sheet with no free edge along the pull.
fn tube() -> PointCloud {
    let per_ring = 40;
    let spacing = std::f32::consts::TAU * TUBE_RADIUS / per_ring as f32;
    let pitch = spacing * 3f32.sqrt() / 2.0;
    let rings = (0.8 / pitch).round() as usize + 1;
    let (mut positions, mut normals) = (Vec::new(), Vec::new());
    for r in 0..rings {
        let turn = if r % 2 == 1 { 0.5 } else { 0.0 };
        for c in 0..per_ring {
            let phi = (c as f32 + turn) * std::f32::consts::TAU / per_ring as f32;
            let n = Vec3::new(phi.cos(), phi.sin(), 0.0);
            positions.push(n * TUBE_RADIUS + Vec3::Z * (r as f32 * pitch));
            normals.push(n);
        }
    }
    PointCloud::new(positions, Some(normals)).unwrap()
}

/// The Young's modulus a sheet of `material` shows when pulled in its plane: the [`tube`]
/// (every point simulated), free, pulled apart at its end rings by a force per width σ each
/// way, its axial strain measured over its middle half. (A flat sheet's free edges stiffen
/// it by about a row of springs each, 5 % on a 1 m sheet at a spacing of 0.025: the tube has
/// none.)
fn measured_modulus(material: SpringMaterial) -> f32 {
    let cloud = tube();
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(cloud.len()),
        material,
        solver: SolverConfig {
            integrator: Integrator::ImplicitEuler,
            gravity: Vec3::ZERO,
            drag: 5.0,
            cg_tolerance: 1e-6,
            ..SolverConfig::default()
        },
        ..SurfaceConfig::default()
    };
    let mut s =
        prepare_surface(cloud.clone(), &config, &mut |_| ControlFlow::Continue(())).unwrap();
    assert_eq!(s.network.len(), cloud.len());
    let solver = &mut s.solver;
    let rest = solver.positions();
    let top = rest.iter().map(|p| p.z).fold(0.0, f32::max);
    let sigma = 0.01 * material.stretch_stiffness;
    let circumference = std::f32::consts::TAU * TUBE_RADIUS;
    for (end, z, direction) in [(0, 0.0, -1.0f32), (1, top, 1.0)] {
        let ring: Vec<usize> = (0..rest.len())
            .filter(|&i| (rest[i].z - z).abs() < 1e-4)
            .collect();
        assert_eq!(ring.len(), 40, "end {end}");
        let force = sigma * circumference / ring.len() as f32;
        for i in ring {
            solver
                .set_external_force(i, Vec3::Z * direction * force)
                .unwrap();
        }
    }
    for _ in 0..600 {
        solver.step(1.0 / 30.0).unwrap();
        if solver.points.max_speed() < 1e-7 {
            break;
        }
    }
    assert!(
        solver.points.max_speed() < 1e-6,
        "{}",
        solver.points.max_speed()
    );
    // The strain: the slope of the axial displacement over z, by least squares over the
    // middle half.
    let middle: Vec<usize> = (0..rest.len())
        .filter(|&i| (rest[i].z - top / 2.0).abs() <= top / 4.0)
        .collect();
    let n = middle.len() as f32;
    let w = |i: usize| solver.position(i).z - rest[i].z;
    let mean_z = middle.iter().map(|&i| rest[i].z).sum::<f32>() / n;
    let mean_w = middle.iter().map(|&i| w(i)).sum::<f32>() / n;
    let (mut szw, mut szz) = (0.0, 0.0);
    for &i in &middle {
        let (dz, dw) = (rest[i].z - mean_z, w(i) - mean_w);
        szw += dz * dw;
        szz += dz * dz;
    }
    sigma / (szw / szz)
}

#[test]
fn a_sheet_on_hinges_measures_its_stated_modulus_in_its_plane() {
    let sheet = SpringMaterial {
        density: RHO,
        units: MaterialUnits::Sheet,
        stretch_stiffness: 80.0,
        bend_stiffness: 80.0,
        stretch_damping: 0.3,
        bend_damping: 0.3,
        bending: BendingModel::Springs,
        ..SpringMaterial::default()
    };
    let hinges = SpringMaterial {
        bending: BendingModel::Hinges,
        ..sheet
    };
    let (with_springs, with_hinges) = (measured_modulus(sheet), measured_modulus(hinges));
    eprintln!(
        "stated 80 N/m; measured {with_hinges:.2} on hinges, {with_springs:.2} with bend springs"
    );
    assert!((with_hinges / 80.0 - 1.0).abs() < 0.03, "{with_hinges}");
    // The bend springs stretch too: the sheet is stiffer than stated.
    assert!(with_springs > 1.5 * 80.0, "{with_springs}");
}

#[test]
fn bad_dense_input_is_a_typed_error_and_leaves_the_masses() {
    let sphere = fibonacci_sphere(400, 1.0);
    let (p, n) = (sphere.positions(), sphere.normals().unwrap());
    let k = DEFAULT_SIMPLIFY_K;
    let err = |r: Result<Vec<f32>, NetworkError>| r.unwrap_err();
    assert_eq!(
        err(dense_point_areas(p, &n[1..], &[], k)),
        NetworkError::LengthMismatch {
            positions: 400,
            normals: 399
        }
    );
    assert_eq!(
        err(dense_point_areas(p, n, &[[0, 1, 400]], k)),
        NetworkError::InvalidFace(0)
    );
    assert_eq!(
        err(dense_point_areas(p, n, &[[0, 1, 2], [3, 3, 4]], k)),
        NetworkError::InvalidFace(1)
    );
    let mut nan = p.to_vec();
    nan[7].y = f32::NAN;
    assert_eq!(
        err(dense_point_areas(&nan, n, &[], k)),
        NetworkError::InvalidPoint(7)
    );

    let mut s = prepared(&sphere, 0.2);
    let masses = s.network.masses.clone();
    let areas = dense_point_areas(p, n, &[], k).unwrap();
    let mut bad = areas.clone();
    bad[3] = -1.0;
    let net = &mut s.network;
    assert_eq!(
        net.share_dense_area(p, n, &bad, RHO),
        Err(NetworkError::InvalidArea(3))
    );
    bad[3] = f32::NAN;
    assert_eq!(
        net.share_dense_area(p, n, &bad, RHO),
        Err(NetworkError::InvalidArea(3))
    );
    assert_eq!(
        net.share_dense_area(p, n, &areas[1..], RHO),
        Err(NetworkError::AreaCount {
            points: 400,
            areas: 399
        })
    );
    assert_eq!(
        net.share_dense_area(&nan, n, &areas, RHO),
        Err(NetworkError::InvalidPoint(7))
    );
    assert_eq!(
        net.share_dense_area(p, n, &areas, 0.0),
        Err(NetworkError::InvalidDensity(0.0))
    );
    assert_eq!(
        net.share_dense_area(p, n, &vec![0.0; 400], RHO),
        Err(NetworkError::NotASurface)
    );
    assert_eq!(
        net.masses, masses,
        "refused input left the masses as they were"
    );
    // The same good input shares the same masses again.
    net.share_dense_area(p, n, &areas, RHO).unwrap();
    assert_eq!(net.masses, masses);
}

#[test]
fn a_free_sphere_keeps_its_spin_at_default_settings() {
    // The default settings (fitted curvature, axial damping, implicit Euler) at 60 Hz with
    // no gravity: a sphere spun at 1 rad/s about an axis through its centre turns on for
    // 5 s with its angular momentum kept to 1 %, and still round. Eq 3's damping stops it.
    assert_eq!(SolverConfig::default().damping_model, DampingModel::Axial);
    assert_eq!(SpringMaterial::default().bending, BendingModel::Curvature);
    assert_a_free_sphere_keeps_its_spin(BendingModel::Curvature, ImplicitSolver::default());
}

#[test]
fn a_free_sphere_bending_on_hinges_keeps_its_spin() {
    assert_a_free_sphere_keeps_its_spin(BendingModel::Hinges, ImplicitSolver::default());
}

#[test]
fn a_free_sphere_keeps_its_spin_on_the_prefactored_solver() {
    // Two local/global iterations a step alone kept 0.927 of the spin: the step's internal
    // impulses are made to sum to no force and no torque, as CG's are.
    assert_a_free_sphere_keeps_its_spin(BendingModel::Curvature, ImplicitSolver::LOCAL_GLOBAL);
}

/// A sphere bending on `bending`, at the default settings otherwise, spun at 1 rad/s with
/// no gravity: with axial damping its angular momentum is kept to 1 % over 5 s and it stays
/// round; eq 3's damping stops it.
fn assert_a_free_sphere_keeps_its_spin(bending: BendingModel, implicit_solver: ImplicitSolver) {
    for damping_model in [DampingModel::Axial, DampingModel::Relative] {
        let config = SurfaceConfig {
            material: SpringMaterial {
                bending,
                ..SpringMaterial::default()
            },
            solver: SolverConfig {
                gravity: Vec3::ZERO,
                damping_model,
                implicit_solver,
                ..SolverConfig::default()
            },
            ..SurfaceConfig::default()
        };
        let mut s = prepare_surface(fibonacci_sphere(2000, 1.0), &config, &mut |_| {
            ControlFlow::Continue(())
        })
        .unwrap();
        let solver = &mut s.solver;
        let axis = Vec3::new(0.3, 1.0, 0.2).normalize();
        for i in 0..solver.len() {
            let v = axis.cross(solver.position(i));
            solver.set_velocity(i, v).unwrap();
        }
        let spin = |s: &Solver| {
            let total: f32 = (0..s.len()).map(|i| s.mass(i)).sum();
            let centre = (0..s.len())
                .map(|i| s.mass(i) * s.position(i))
                .sum::<Vec3>()
                / total;
            (0..s.len())
                .map(|i| s.mass(i) * (s.position(i) - centre).cross(s.velocity(i)))
                .sum::<Vec3>()
        };
        let before = spin(solver);
        for _ in 0..300 {
            solver.step(1.0 / 60.0).unwrap();
        }
        let after = spin(solver);
        let kept = after.dot(before) / before.length_squared();
        let radii = (0..solver.len()).map(|i| solver.position(i).length());
        let (lo, hi) = radii.fold((f32::MAX, 0.0f32), |(lo, hi), r| (lo.min(r), hi.max(r)));
        println!(
            "{bending:?}, {damping_model:?}: {:.4} of the spin kept after 5 s, radii {lo:.4}..{hi:.4}",
            kept
        );
        if damping_model == DampingModel::Axial {
            assert!(
                (after - before).length() < 0.01 * before.length(),
                "{before} -> {after}"
            );
            assert!(lo > 0.97 && hi < 1.03, "radii {lo}..{hi}");
        } else {
            assert!(kept < 0.1, "eq 3 kept {kept}");
        }
    }
}
