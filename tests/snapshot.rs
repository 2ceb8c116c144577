//! Nothing lost: a snapshot of a running scene, saved and restored onto the scene prepared
//! again, continues the run bit for bit; damaged and foreign snapshots are typed errors.

use std::path::{Path, PathBuf};

use bevy_point_springs::core::cloud::io::read_cloud;
use bevy_point_springs::core::scene::{Scene, SceneRun, Snapshot, SnapshotError};
use bevy_point_springs::core::solver::{BendingModel, Integrator};
use glam::Vec3;

/// Vectors as their bits.
type Bits = Vec<[u32; 3]>;

fn bits(v: &[Vec3]) -> Bits {
    v.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
}

fn scene(name: &str) -> (Scene, PathBuf) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets/scenes")
        .join(name);
    Scene::load(&path).unwrap()
}

fn prepare(scene: &Scene, base: &Path) -> SceneRun {
    scene.prepare(base).unwrap()
}

/// The deformed surface at the end of `run`, as bits, with the solver's state.
fn finish(mut run: SceneRun) -> (Bits, Bits, Bits) {
    run.run(&mut |_| {}).unwrap();
    let deformed = run.deformed().unwrap();
    (
        bits(deformed.cloud.positions()),
        bits(deformed.cloud.normals().unwrap()),
        bits(&run.solver().points.velocities()),
    )
}

/// Runs `scene` straight through, and again stopped after each of `stops` steps: a
/// snapshot taken, encoded, decoded and restored onto the scene prepared anew, the run
/// finished from there. Every run must end in the same bits.
fn assert_resumes_bit_for_bit(name: &str, scene: &Scene, base: &Path, stops: &[usize]) {
    let straight = finish(prepare(scene, base));
    for &stop in stops {
        let mut first = prepare(scene, base);
        for _ in 0..stop {
            first.step().unwrap();
        }
        let snapshot = first.snapshot();
        let bytes = snapshot.to_bytes();
        let decoded = Snapshot::from_bytes(&bytes).unwrap();
        assert!(decoded == snapshot, "{name}: the encoding is not exact");
        let cloud = read_cloud(&base.join(&scene.cloud), None).unwrap();
        let resumed = decoded.resume(cloud).unwrap();
        assert!(
            resumed.snapshot() == snapshot,
            "{name}: restored state differs at step {stop}"
        );
        assert_eq!(resumed.step_count(), stop);
        assert!(
            finish(resumed) == straight,
            "{name}: resumed at step {stop}, the run ends elsewhere"
        );
    }
}

#[test]
fn the_hat_resumes_bit_for_bit_through_resampling() {
    // Implicit Euler (a warm-started solve), a pull that moves, resampling every 30 steps:
    // stopped before any point is inserted, after some, and after the pull let go.
    let (scene, base) = scene("hat.ron");
    assert_resumes_bit_for_bit("hat", &scene, &base, &[1, 95, 250]);
}

#[test]
fn the_sphere_with_gas_resumes_bit_for_bit() {
    let (scene, base) = scene("sphere_poke.ron");
    assert_resumes_bit_for_bit("sphere", &scene, &base, &[40, 160]);
}

#[test]
fn a_plastic_surface_stepped_explicitly_resumes_bit_for_bit() {
    // Rest lengths that creep (plastic state), symplectic Euler with sub-steps.
    let (mut scene, base) = scene("hat.ron");
    scene.material.yield_strain = 0.02;
    scene.material.creep_rate = 2.0;
    scene.solver.integrator = Integrator::SymplecticEuler;
    scene.steps = 120;
    scene.resample = None;
    for pull in &mut scene.pulls {
        pull.end = pull.end.map(|e| e.min(100));
        pull.start = pull.start.min(99);
    }
    assert_resumes_bit_for_bit("plastic hat", &scene, &base, &[60]);
}

/// The hat bending as `bending` says with a bend that creeps (plastic bending), implicit
/// Euler, stopped at step 60 while the pull bends it past the yield angle.
fn assert_plastic_bending_resumes(name: &str, bending: BendingModel) {
    let (mut scene, base) = scene("hat.ron");
    scene.material.bending = bending;
    scene.material.yield_angle = 0.02;
    scene.material.creep_rate = 2.0;
    scene.steps = 120;
    scene.resample = None;
    for pull in &mut scene.pulls {
        pull.end = pull.end.map(|e| e.min(100));
        pull.start = pull.start.min(99);
    }
    assert_resumes_bit_for_bit(name, &scene, &base, &[60]);
}

#[test]
fn a_plastic_surface_on_hinges_resumes_bit_for_bit() {
    // Rest angles that creep.
    assert_plastic_bending_resumes("plastic hat on hinges", BendingModel::Hinges);
}

#[test]
fn a_plastic_surface_bending_on_its_curvature_resumes_bit_for_bit() {
    // Rest curvatures that creep.
    assert_plastic_bending_resumes("plastic hat on its curvature", BendingModel::Curvature);
}

#[test]
fn a_snapshot_file_round_trips_and_is_written_atomically() {
    let (scene, base) = scene("sphere_poke.ron");
    let mut run = prepare(&scene, &base);
    for _ in 0..30 {
        run.step().unwrap();
    }
    let dir = std::env::temp_dir().join(format!("bps-snapshot-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("sphere.snapshot");
    let mut snapshot = run.snapshot();
    snapshot.scene_file = Some(scene_path("sphere_poke.ron"));
    snapshot.write(&path).unwrap();
    let read = Snapshot::read(&path).unwrap();
    assert!(read == snapshot);
    // Resumed through the scene file it names.
    let resumed = read.resume_from_file().unwrap();
    assert_eq!(resumed.step_count(), 30);
    // Only the snapshot is in the folder: the temporary file was renamed into place.
    let names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, ["sphere.snapshot"]);
    // A missing file and a folder are typed errors.
    assert!(matches!(
        Snapshot::read(&dir.join("none.snapshot")),
        Err(SnapshotError::Io { .. })
    ));
    std::fs::remove_dir_all(&dir).ok();
}

fn scene_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets/scenes")
        .join(name)
}

#[test]
fn damaged_and_foreign_snapshots_are_typed_errors() {
    let (scene, base) = scene("hat.ron");
    let mut run = prepare(&scene, &base);
    for _ in 0..40 {
        run.step().unwrap();
    }
    let snapshot = run.snapshot();
    let bytes = snapshot.to_bytes();
    // Not a snapshot.
    assert!(matches!(
        Snapshot::from_bytes(b"ply\nformat ascii 1.0\n"),
        Err(SnapshotError::NotASnapshot)
    ));
    // Cut anywhere: an error, never a panic.
    for cut in (0..bytes.len()).step_by(bytes.len() / 97 + 1) {
        assert!(Snapshot::from_bytes(&bytes[..cut]).is_err(), "cut at {cut}");
    }
    // A byte changed anywhere: an error, or a snapshot that restores or is refused.
    let cloud = read_cloud(&base.join(&scene.cloud), None).unwrap();
    let fresh = scene.prepare_run(cloud).unwrap();
    for at in (8..bytes.len()).step_by(bytes.len() / 61 + 1) {
        let mut damaged = bytes.clone();
        damaged[at] ^= 0x5a;
        if let Ok(s) = Snapshot::from_bytes(&damaged) {
            let _ = fresh.clone().restore(&s);
        }
    }
    // A length of 10^12 where the first list starts: refused without allocating it.
    let mut huge = bytes[..8].to_vec();
    huge.extend([0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x7f]);
    assert!(Snapshot::from_bytes(&huge).is_err());
    // Another scene: refused, and the run left as it was.
    let (other, other_base) = self::scene("sphere_poke.ron");
    let mut other_run = prepare(&other, &other_base);
    let before = other_run.snapshot();
    assert!(matches!(
        other_run.restore(&snapshot),
        Err(SnapshotError::OtherScene)
    ));
    assert!(other_run.snapshot() == before);
    // The same scene with a state that does not fit (a point too many): refused, unchanged.
    let mut wrong = snapshot.clone();
    wrong.solver.positions.push(Vec3::ZERO);
    let mut target = fresh.clone();
    let before = target.snapshot();
    assert!(target.restore(&wrong).is_err());
    assert!(target.snapshot() == before);
}
