//! The `point-springs` binary, end to end.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use bevy_point_springs::core::cloud::io::read_cloud;

fn asset(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets")
        .join(name)
}

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_point-springs"))
        .args(args)
        .output()
        .expect("the binary runs")
}

/// Runs the binary and asserts that it succeeded (showing its error output if not).
fn run_ok(args: &[&str]) -> Output {
    let out = run(args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Runs the binary, asserts that it succeeded, and parses its JSON report.
fn run_json(args: &[&str]) -> serde_json::Value {
    serde_json::from_slice(&run_ok(args).stdout).expect("a JSON report")
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("bps-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn info_json_has_the_documented_keys() {
    let path = asset("sphere926.pwn");
    let v = run_json(&["info", path.to_str().unwrap(), "--json"]);
    assert_eq!(v["points"], 926);
    assert_eq!(v["has_normals"], true);
    assert_eq!(v["format"], "pwn");
    for (key, sign) in [("bbox_min", -1.0), ("bbox_max", 1.0)] {
        let corner = v[key].as_array().unwrap();
        assert_eq!(corner.len(), 3);
        for c in corner {
            assert!(
                (c.as_f64().unwrap() - sign * 10.0).abs() < 0.1,
                "{key}: {c}"
            );
        }
    }
    let spacing = v["mean_spacing"].as_f64().unwrap();
    // 926 points on a sphere of radius 10: about √(4π·100/926) ≈ 1.16 apart.
    assert!(spacing > 0.5 && spacing < 1.5, "mean spacing {spacing}");
}

#[test]
fn info_text_and_format_override() {
    let path = asset("sphere926.pwn");
    let out = run_ok(&["info", path.to_str().unwrap(), "--format", "xyz"]);
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("points        926"), "{text}");
    assert!(text.contains("format        xyz"), "{text}");
}

#[test]
fn bad_input_exits_2_and_names_the_file() {
    let bad = scratch("broken.xyz");
    std::fs::write(&bad, "1 2 3\n4 five 6\n").unwrap();
    let out = run(&["info", bad.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(
        err.contains("broken.xyz") && err.contains("line 2"),
        "{err}"
    );
    assert!(out.stdout.is_empty());

    let out = run(&["info", "no-such-file.ply"]);
    assert_eq!(out.status.code(), Some(2));
    let out = run(&["info", "cloud.unknown"]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn normals_command_writes_an_oriented_ply() {
    let input = asset("half.xyz");
    let output = scratch("half-normals.ply");
    let v = run_json(&[
        "normals",
        input.to_str().unwrap(),
        "-o",
        output.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(v["normals"], "estimated");
    assert_eq!(v["components"], 1);
    let cloud = read_cloud(&output, None).unwrap();
    assert_eq!(cloud.len(), 325);
    let outward = cloud
        .positions()
        .iter()
        .zip(cloud.normals().unwrap())
        .filter(|(p, n)| p.dot(**n) > 0.0)
        .count();
    assert!(outward as f32 / 325.0 > 0.97, "{outward} of 325 outward");
}

#[test]
fn simplify_writes_simulation_points_and_reports_the_network() {
    let input = asset("sphere926.pwn");
    let output = scratch("sim.ply");
    let v = run_json(&[
        "simplify",
        input.to_str().unwrap(),
        "--target",
        "120",
        "--density",
        "2",
        "-o",
        output.to_str().unwrap(),
        "--json",
    ]);
    for key in [
        "input_points",
        "sim_points",
        "stretch_springs",
        "bend_springs",
        "boundary_points",
        "components",
        "total_mass",
        "min_diameter",
        "seconds",
    ] {
        assert!(!v[key].is_null(), "missing {key}: {v}");
    }
    assert_eq!(v["input_points"], 926);
    assert_eq!(v["sim_points"], 120);
    assert_eq!(v["components"], 1);
    assert_eq!(v["boundary_points"], 0);
    // Watertightness stated plainly.
    assert_eq!(v["closed"], true);
    assert_eq!(v["euler_characteristic"], 2);
    assert_eq!(v["boundary_loops"], 0);
    assert_eq!(
        (v["fold_overs"].as_u64(), v["crossings"].as_u64()),
        (Some(0), Some(0))
    );
    assert_eq!(v["denoised"], false);
    // The sphere's rings leave no hole for a dense point to fill.
    assert_eq!(v["filling_points"], 0);
    // A closed triangulated surface: E = 3V − 6.
    assert_eq!(v["stretch_springs"], 3 * 120 - 6);
    // The masses share out the dense surface's area, as the simulation's do; the coarse
    // network's mesh cuts across the convex sphere, so it is smaller.
    let f = |key: &str| v[key].as_f64().unwrap();
    assert!(
        (f("total_mass") / (2.0 * f("dense_area")) - 1.0).abs() < 1e-5,
        "{v}"
    );
    assert!(f("area") < f("dense_area"), "{v}");
    let written = read_cloud(&output, None).unwrap();
    assert_eq!(written.len(), 120);
    assert!(written.has_usable_normals());
    // The simulation points are points of the input.
    let input_cloud = read_cloud(&input, None).unwrap();
    assert!(
        written
            .positions()
            .iter()
            .all(|p| input_cloud.positions().contains(p))
    );
}

#[test]
fn simplify_needs_a_stopping_rule_and_rejects_bad_values() {
    let input = asset("half.xyz");
    let input = input.to_str().unwrap();
    for args in [
        vec!["simplify", input],
        vec!["simplify", input, "--target", "2"],
        vec!["simplify", input, "--max-diameter", "-1"],
        vec!["simplify", input, "--target", "50", "--density", "0"],
        vec!["simplify", input, "--target", "50", "-k", "1"],
    ] {
        let out = run(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(!out.stderr.is_empty());
    }
    // Both rules together: the threshold on an open surface, normals estimated.
    let out = run_ok(&["simplify", input, "--target", "40", "--max-diameter", "0.1"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("normals: estimated") && text.contains("1 loop(s)"),
        "{text}"
    );
}

#[test]
fn run_writes_the_deformed_surface_and_reports_it() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/hat.ron");
    let out_ply = scratch("hat.ply");
    let out_png = scratch("hat.png");
    let v = run_json(&[
        "run",
        scene.to_str().unwrap(),
        "-o",
        out_ply.to_str().unwrap(),
        "--png",
        out_png.to_str().unwrap(),
        "--json",
    ]);
    for key in [
        "dense_points",
        "sim_points",
        "springs",
        "steps",
        "integrator",
        "ms_per_step",
        "ms_transfer",
        "max_displacement",
        "energy_final",
        "finite",
        "resampled_points",
    ] {
        assert!(!v[key].is_null(), "missing {key}: {v}");
    }
    // The hat's 3000 dense points, and the points resampling added to its crown.
    assert_eq!(v["dense_points_at_rest"], 3000);
    let resampled = v["resampled_points"].as_u64().unwrap();
    assert!(resampled > 0);
    assert_eq!(v["dense_points"].as_u64().unwrap(), 3000 + resampled);
    assert_eq!(v["sim_points"], 300);
    assert_eq!(v["steps"], 300);
    assert_eq!(v["integrator"], "implicit-euler");
    assert_eq!(v["finite"], true);
    // The crown was pulled 0.9 out.
    let moved = v["max_displacement"].as_f64().unwrap();
    assert!(moved > 0.7 && moved < 1.0, "{moved}");
    // The PLY holds the deformed surface with unit normals; the picture was drawn.
    let cloud = read_cloud(&out_ply, None).unwrap();
    assert_eq!(cloud.len() as u64, 3000 + resampled);
    let normals = cloud.normals().unwrap();
    assert!(normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-4));
    let png = std::fs::read(&out_png).unwrap();
    assert!(png.starts_with(b"\x89PNG") && png.len() > 10_000);
}

#[test]
fn run_resumes_from_a_snapshot_bit_for_bit() {
    // The hat (300 steps, resampling) straight through, snapshots every 120 steps; then
    // resumed from the last one (step 240), by the snapshot alone and with the scene named.
    let scene = asset("scenes/hat.ron");
    let straight = scratch("straight.ply");
    let snapshot = scratch("hat.snapshot");
    let v = run_json(&[
        "run",
        scene.to_str().unwrap(),
        "-o",
        straight.to_str().unwrap(),
        "--snapshot-every",
        "120",
        "--snapshot",
        snapshot.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(v["snapshots_written"], 2);
    let bytes = |p: &Path| std::fs::read(p).unwrap();
    for with_scene in [false, true] {
        let resumed = scratch(&format!("resumed_{with_scene}.ply"));
        let mut args = vec!["run"];
        if with_scene {
            args.push(scene.to_str().unwrap());
        }
        args.extend([
            "--resume",
            snapshot.to_str().unwrap(),
            "-o",
            resumed.to_str().unwrap(),
            "--json",
        ]);
        let v = run_json(&args);
        assert_eq!(v["resumed_at_step"], 240);
        assert_eq!(v["steps"], 300);
        assert!(
            bytes(&resumed) == bytes(&straight),
            "resumed output differs"
        );
    }
    // Another scene, a damaged snapshot, and no scene at all: exit 2, saying why.
    let other = asset("scenes/sphere_poke.ron");
    let damaged = scratch("damaged.snapshot");
    std::fs::write(&damaged, &bytes(&snapshot)[..100]).unwrap();
    for (args, needle) in [
        (
            vec![
                "run",
                other.to_str().unwrap(),
                "--resume",
                snapshot.to_str().unwrap(),
            ],
            "another scene",
        ),
        (
            vec!["run", "--resume", damaged.to_str().unwrap()],
            "damaged",
        ),
        (vec!["run"], "<SCENE>"),
    ] {
        let out = run(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle), "{args:?}: {err}");
    }
}

#[test]
fn run_rejects_bad_scenes_with_exit_2() {
    let broken = scratch("broken.ron");
    std::fs::write(&broken, "(cloud: \"x.ply\", steps: many)").unwrap();
    let missing_cloud = scratch("missing_cloud.ron");
    std::fs::write(
        &missing_cloud,
        r#"(cloud: "no-such-cloud.ply", simplify: (target: Some(40)), dt: 0.01, steps: 5)"#,
    )
    .unwrap();
    for (scene, needle) in [
        (broken.to_str().unwrap(), "broken.ron"),
        (missing_cloud.to_str().unwrap(), "no-such-cloud.ply"),
        ("no-such-scene.ron", "no-such-scene.ron"),
    ] {
        let out = run(&["run", scene]);
        assert_eq!(out.status.code(), Some(2), "{scene}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle), "{err}");
    }
}

#[test]
fn generate_and_render() {
    let sphere = scratch("generated_sphere.ply");
    run_ok(&[
        "generate",
        "sphere",
        "--points",
        "500",
        "-o",
        sphere.to_str().unwrap(),
    ]);
    let cloud = read_cloud(&sphere, None).unwrap();
    assert_eq!(cloud.len(), 500);
    assert!(cloud.has_usable_normals());
    let letter = scratch("generated_b.ply");
    run_ok(&[
        "generate",
        "letter-b",
        "--spacing",
        "0.05",
        "-o",
        letter.to_str().unwrap(),
    ]);
    assert!(read_cloud(&letter, None).unwrap().len() > 300);

    let picture = scratch("two.png");
    run_ok(&[
        "render",
        sphere.to_str().unwrap(),
        letter.to_str().unwrap(),
        "-o",
        picture.to_str().unwrap(),
        "--width",
        "400",
        "--height",
        "200",
    ]);
    assert!(std::fs::read(&picture).unwrap().starts_with(b"\x89PNG"));

    for args in [
        &["generate", "sphere", "--radius", "-1", "-o", "x.ply"][..],
        &["generate", "sheet", "--spacing", "0.00001", "-o", "x.ply"],
        &["render", "no-such.ply", "-o", "x.png"],
        &[
            "render",
            sphere.to_str().unwrap(),
            "-o",
            "x.png",
            "--view",
            "0,1,0",
        ],
    ] {
        let out = run(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
    }
}

#[test]
fn prepare_writes_a_prepared_file_that_reads_back() {
    use bevy_point_springs::core::pipeline::SurfaceConfig;
    use bevy_point_springs::core::pipeline::prepared::{SourceFingerprint, read_prepared};
    use bevy_point_springs::core::simplify::SimplifyConfig;
    let out = scratch("kitten.psprep");
    let kitten = asset("kitten.off");
    let report = run_json(&[
        "prepare",
        kitten.to_str().unwrap(),
        "--target",
        "300",
        "-o",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(report["dense_points"], 5210);
    assert_eq!(report["sim_points"].as_u64(), Some(300));
    assert!(report["bytes"].as_u64().unwrap() > 100_000);
    assert!(report["ready_share"].as_f64().unwrap() > 0.0);
    // The file is the preparation of the kitten with those settings.
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(300),
        ..SurfaceConfig::default()
    };
    let cloud = read_cloud(&kitten, None).unwrap();
    let surface = read_prepared(&out, SourceFingerprint::of(&cloud, &config)).unwrap();
    assert_eq!(surface.network.len(), 300);
    assert!(
        read_prepared(
            &out,
            SourceFingerprint::of(&cloud, &SurfaceConfig::default())
        )
        .is_err()
    );
    // Settings that are not a surface's: bad input.
    let settings = scratch("bad-settings.ron");
    std::fs::write(&settings, "(simplify: (target: Some(-3)))").unwrap();
    let bad = run(&[
        "prepare",
        kitten.to_str().unwrap(),
        "--settings",
        settings.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("bad-settings.ron"));
}
