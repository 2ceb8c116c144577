//! The `point-springs` binary, end to end.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use bevy_point_springs::core::io::read_cloud;

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

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("bps-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn info_json_has_the_documented_keys() {
    let path = asset("sphere926.pwn");
    let out = run(&["info", path.to_str().unwrap(), "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
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
    let out = run(&["info", path.to_str().unwrap(), "--format", "xyz"]);
    assert!(out.status.success());
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
    let out = run(&[
        "normals",
        input.to_str().unwrap(),
        "-o",
        output.to_str().unwrap(),
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
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
    let out = run(&[
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
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
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
    // A closed triangulated surface: E = 3V − 6.
    assert_eq!(v["stretch_springs"], 3 * 120 - 6);
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
    let out = run(&["simplify", input, "--target", "40", "--max-diameter", "0.1"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("normals: estimated") && text.contains("1 loop(s)"),
        "{text}"
    );
}

#[test]
fn bench_cloth_grid_reports_speed_and_sag() {
    let out = run(&[
        "bench",
        "cloth-grid",
        "--size",
        "12",
        "--steps",
        "200",
        "--repeat",
        "1",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["particles"], 144);
    // 12×12: 132 + 120 horizontal, 2·121 diagonal, 132 + 120 vertical.
    assert_eq!(v["springs"], 746);
    assert_eq!(v["steps"], 200);
    assert_eq!(v["integrator"], "symplectic-euler");
    assert_eq!(v["finite"], true);
    assert!(v["us_per_step"].as_f64().unwrap() > 0.0);
    assert!(v["reference_us_per_step"].as_f64().unwrap() > 0.0);
    let sag = v["max_sag"].as_f64().unwrap();
    assert!(sag > 0.1, "{sag}");
    assert!(v["sag_difference"].as_f64().unwrap() < 1e-3);

    let text = run(&["bench", "cloth-grid", "--size", "4", "--steps", "10"]);
    assert!(text.status.success());
    assert!(String::from_utf8(text.stdout).unwrap().contains("speedup"));

    for args in [
        &["bench", "cloth-grid", "--size", "1"][..],
        &["bench", "cloth-grid", "--integrator", "leapfrog"],
        &["bench", "cloth-grid", "--size", "100000"],
    ] {
        let out = run(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(!out.stderr.is_empty());
    }
}
