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
fn bench_cloth_grid_reports_speed_and_sag() {
    let v = run_json(&[
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
fn bench_transfer_reports_speed_and_error() {
    let v = run_json(&[
        "bench", "transfer", "--points", "3000", "--sim", "300", "--repeat", "2", "--json",
    ]);
    assert_eq!(v["dense_points"], 3000);
    assert_eq!(v["sim_points"], 300);
    assert!(v["apply_ms"].as_f64().unwrap() > 0.0);
    assert!(v["speedup"].as_f64().unwrap() > 0.0);
    // Throughput against a memory copy in the same run: at least the written positions and
    // normals are counted, and the rate is those bytes over the frame's time.
    let bytes = v["frame_bytes"].as_f64().unwrap();
    assert!(bytes >= 3000.0 * 24.0, "{bytes} bytes");
    let gb_s = v["transfer_gb_s"].as_f64().unwrap();
    let from_time = bytes / (v["apply_ms"].as_f64().unwrap() * 1e-3) / 1e9;
    assert!(
        (gb_s - from_time).abs() <= 1e-9 * from_time,
        "{gb_s} vs {from_time}"
    );
    assert!(v["memcpy_gb_s"].as_f64().unwrap() > 0.0);
    // Both methods follow the bulge; the precomputed fit is the closer one.
    let ours = v["errors"]["position_mean"].as_f64().unwrap();
    let literal = v["literal_errors"]["position_mean"].as_f64().unwrap();
    assert!(ours < 0.01 && ours < literal, "{ours} vs {literal}");
    let out = run(&["bench", "transfer", "--points", "100", "--sim", "200"]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn bench_table1_measures_the_papers_sizes_with_every_integrator() {
    let scene = asset("scenes/sphere_poke.ron");
    let v = run_json(&[
        "bench",
        "table1",
        scene.to_str().unwrap(),
        "--steps",
        "3",
        "--repeats",
        "2",
        "--json",
    ]);
    assert_eq!(v["repeats"], 2);
    let rows = v["rows"].as_array().expect("rows");
    assert_eq!(rows.len(), 9, "three sizes, three integrators");
    for (row, paper) in rows.iter().zip([85, 85, 85, 273, 273, 273, 338, 338, 338]) {
        assert_eq!(row["paper_sim_points"], paper);
        assert_eq!(row["sim_points"], paper, "the network has the paper's size");
        assert_eq!(row["dense_points"], 3203);
        assert_eq!(row["transfers"], 3, "the poke moves the surface every step");
        let ms = row["ms_per_step"].as_f64().unwrap();
        let parts = row["ms_simulate"].as_f64().unwrap() + row["ms_transfer"].as_f64().unwrap();
        assert!(ms > 0.0 && (ms - parts).abs() <= 1e-9 * ms);
        let paper_s = row["paper_s"].as_f64().unwrap();
        assert!(
            (row["speedup"].as_f64().unwrap() - paper_s * 1e3 / ms).abs()
                < 1e-6 * paper_s * 1e3 / ms
        );
    }
    let out = run(&["bench", "table1", scene.to_str().unwrap(), "--steps", "0"]);
    assert_eq!(out.status.code(), Some(2));
    let out = run(&["bench", "table1", scene.to_str().unwrap(), "--repeats", "0"]);
    assert_eq!(out.status.code(), Some(2));
    let out = run(&["bench", "table1", "no/such/scene.ron"]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn bench_scale_reports_every_configuration_that_fits() {
    let stem = scratch("scale");
    let v = run_json(&[
        "bench",
        "scale",
        "--dense",
        "1500,3000",
        "--sim",
        "60,2000",
        "--steps",
        "2",
        "--chart",
        stem.to_str().unwrap(),
        "--json",
    ]);
    // The log-log charts: the preparation's stages and the step's costs.
    for chart in ["prepare", "step"] {
        let name = format!("{}_{chart}", stem.file_name().unwrap().to_string_lossy());
        let svg = std::fs::read_to_string(stem.with_file_name(&name).with_extension("svg"));
        let svg = svg.unwrap();
        assert!(svg.contains("simulation points") && svg.contains("dense points"));
        let png = std::fs::metadata(stem.with_file_name(&name).with_extension("png")).unwrap();
        assert!(png.len() > 10_000, "{png:?}");
    }
    let rows = v.as_array().expect("one row per configuration");
    // 2000 simulation points do not fit in 1500 dense ones: three configurations.
    let sizes: Vec<(u64, u64)> = rows
        .iter()
        .map(|r| {
            let n = |key: &str| r[key].as_u64().unwrap();
            (n("dense_points"), n("sim_points"))
        })
        .collect();
    assert_eq!(sizes, [(1500, 60), (3000, 60), (3000, 2000)]);
    for r in rows {
        let ms = |key: &str| r[key].as_f64().unwrap();
        let stages =
            ms("normals_ms") + ms("simplify_ms") + ms("network_ms") + ms("transfer_setup_ms");
        assert!(
            stages > 0.0 && stages <= ms("prepare_ms") * 1.000_001,
            "{r}"
        );
        assert!(ms("step_ms") > 0.0 && ms("transfer_ms") > 0.0 && ms("coefficient_mib") > 0.0);
        // The local/global solver's steps include its factorisation, timed alone too.
        assert!(ms("first_local_global_ms") > 0.0);
        assert!(ms("step_local_global_ms") * 2.0 >= ms("first_local_global_ms"));
        assert!(r["springs"].as_u64().unwrap() > 0);
    }
    let out = run(&["bench", "scale", "--dense", "3", "--steps", "1"]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn bench_solvers_compares_the_local_global_solver_with_cg() {
    let v = run_json(&[
        "bench",
        "solvers",
        "--scenes",
        "sheet",
        "--fraction",
        "0.1",
        "--seconds",
        "1",
        "--iterations",
        "1,4",
        "--json",
    ]);
    let rows = v["rows"].as_array().expect("rows");
    let solvers: Vec<&str> = rows.iter().map(|r| r["solver"].as_str().unwrap()).collect();
    assert_eq!(solvers, ["cg", "local-global ×1", "local-global ×4"]);
    assert!(rows[0]["rms_vs_cg_percent"].is_null());
    for r in rows {
        assert_eq!(r["stable"], true, "{r}");
        assert!(r["ms_step"].as_f64().unwrap() > 0.0);
    }
    // Four iterations a step end nearer CG's surface than one, and both near it.
    let rms = |r: &serde_json::Value| r["rms_vs_cg_percent"].as_f64().unwrap();
    assert!(
        rms(&rows[2]) <= rms(&rows[1]) && rms(&rows[1]) < 1.0,
        "{rows:?}"
    );
    for bad in [
        ["--iterations", "0"],
        ["--fraction", "0"],
        ["--rate", "0.5"],
    ] {
        let out = run(&["bench", "solvers", "--scenes", "sheet", bad[0], bad[1]]);
        assert_eq!(out.status.code(), Some(2), "{bad:?}");
    }
}

#[test]
fn bench_convergence_runs_every_problem_to_equilibrium_with_every_material() {
    let stem = scratch("convergence");
    let v = run_json(&[
        "bench",
        "convergence",
        "--fractions",
        "0.2,0.05",
        "--steps",
        "30",
        "--chart",
        stem.to_str().unwrap(),
        "--json",
    ]);
    let rows = v["rows"].as_array().expect("one row per run");
    // Four problems, four materials, two levels (sorted, the finest last).
    assert_eq!(rows.len(), 32);
    for pair in rows.chunks(2) {
        let f = |r: &serde_json::Value, key: &str| r[key].as_f64().unwrap();
        assert_eq!(pair[0]["problem"], pair[1]["problem"]);
        assert!(f(&pair[0], "sim_points") < f(&pair[1], "sim_points"));
        assert_eq!(f(&pair[1], "relative"), 1.0, "{}", pair[1]);
        for r in pair {
            // The masses are the dense area's at every level.
            assert!((f(r, "mass_ratio") - 1.0).abs() < 1e-3, "{r}");
            assert!(f(r, "sag") > 0.0 && f(r, "sag") < 1.0, "{r}");
        }
    }
    let materials: Vec<&str> = rows
        .iter()
        .map(|r| r["material"].as_str().unwrap())
        .collect();
    assert_eq!(
        &materials[..8],
        [
            "per_spring",
            "per_spring",
            "sheet",
            "sheet",
            "hinges",
            "hinges",
            "curvature",
            "curvature"
        ]
    );
    // The chart, twice; the SVG carries its text.
    let svg = std::fs::read_to_string(stem.with_extension("svg")).unwrap();
    assert!(
        svg.contains("simulation points")
            && svg.contains("Shell, sheet")
            && svg.contains("Shell, hinges")
            && svg.contains("Shell, curvature")
    );
    let png = std::fs::metadata(stem.with_extension("png")).unwrap();
    assert!(png.len() > 10_000, "{png:?}");
    let out = run(&["bench", "convergence", "--fractions", "0", "--steps", "1"]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn bench_report_quick_writes_every_file_and_meets_the_error_goal() {
    let out = scratch("report");
    let assets = asset("");
    run_ok(&[
        "bench",
        "report",
        "--quick",
        "--out",
        out.to_str().unwrap(),
        "--assets",
        assets.to_str().unwrap(),
    ]);
    // The CSV: the issue's columns, one row per scene, level and integrator.
    let csv = std::fs::read_to_string(out.join("report.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    for column in [
        "scene",
        "integrator",
        "dt",
        "sim_points",
        "dense_points",
        "ms_step",
        "ms_frame",
        "rms_error",
        "max_error",
        "normal_error_deg",
        "stable",
    ] {
        assert!(header.contains(&column), "{column} missing from {header:?}");
    }
    let col = |name: &str| header.iter().position(|c| *c == name).unwrap();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 4 * 3 * 3, "4 scenes, 3 levels, 3 integrators");
    let num = |r: &[&str], name: &str| r[col(name)].parse::<f64>().unwrap();
    for r in &rows {
        assert_eq!(r[col("stable")], "true", "{r:?}");
        assert!(num(r, "ms_frame") >= num(r, "ms_step"), "{r:?}");
        let (rms, max) = (num(r, "rms_error"), num(r, "max_error"));
        assert!((0.0..=max).contains(&rms) && max < 0.2, "{r:?}");
        // Every dense point simulated, any integrator: the reference's equilibrium.
        if r[col("fraction")] == "1" {
            assert!(rms < 1e-3, "{r:?}");
            assert_eq!(r[col("sim_points")], r[col("dense_points")], "{r:?}");
        }
    }
    // Every scene and integrator: coarser is further from the reference than full.
    for full in rows.iter().filter(|r| r[col("fraction")] == "1") {
        let tenth = rows
            .iter()
            .find(|r| r[0] == full[0] && r[1] == full[1] && r[col("fraction")] == "0.1")
            .unwrap();
        assert!(
            num(tenth, "rms_error") > num(full, "rms_error"),
            "{tenth:?}"
        );
        let speedup = num(full, "ms_frame") / num(tenth, "ms_frame");
        assert!((num(tenth, "speedup") - speedup).abs() < 0.01 * speedup);
    }
    // The summary: Table 1, and at 10 % an error under 1 % on every scene.
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let table1 = summary["table1"].as_array().unwrap();
    assert_eq!(table1.len(), 9);
    assert_eq!(table1[8]["sim_points"], 338);
    assert_eq!(table1[8]["paper_s"], 0.42);
    let best = summary["best_at_10pct"].as_array().unwrap();
    let scenes: Vec<&str> = best.iter().map(|b| b["scene"].as_str().unwrap()).collect();
    assert_eq!(scenes, ["sphere", "hat", "sheet", "kitten"]);
    for b in best {
        assert!(b["rms_error"].as_f64().unwrap() < 0.01, "{b}");
    }
    // The Markdown, and a chart per scene with its Pareto front.
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("## kitten") && md.contains("Table 1"));
    for scene in ["sphere", "hat", "sheet", "kitten"] {
        let svg = std::fs::read_to_string(out.join(format!("report_{scene}.svg"))).unwrap();
        assert!(svg.contains("Pareto front") && svg.contains("implicit-euler"));
        let png = std::fs::metadata(out.join(format!("report_{scene}.png"))).unwrap();
        assert!(png.len() > 10_000, "{png:?}");
    }
    let nowhere = scratch("report-nowhere");
    let bad = run(&[
        "bench",
        "report",
        "--quick",
        "--out",
        nowhere.to_str().unwrap(),
        "--assets",
        "no/such/folder",
    ]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(
        !nowhere.exists(),
        "nothing is made for a report that cannot run"
    );
    let unknown = run(&["bench", "report", "--quick", "--scenes", "sheet,teapot"]);
    assert_eq!(unknown.status.code(), Some(2));
    let said = String::from_utf8_lossy(&unknown.stderr);
    assert!(said.contains("teapot") && said.contains("kitten"), "{said}");
}

#[test]
fn bench_network_reports_each_level() {
    let hat = scratch("hat.ply");
    run_ok(&[
        "generate",
        "hat",
        "--points",
        "2000",
        "--noise",
        "0.5",
        "-o",
        hat.to_str().unwrap(),
    ]);
    let sphere = asset("sphere926.pwn");
    let v = run_json(&[
        "bench",
        "network",
        sphere.to_str().unwrap(),
        hat.to_str().unwrap(),
        "--levels",
        "5,20",
        "--json",
    ]);
    let rows = v.as_array().expect("one row per cloud and level");
    assert_eq!(rows.len(), 4);
    for row in &rows[..2] {
        assert_eq!(row["closed"], true, "{row}");
        assert_eq!(row["euler_characteristic"], 2, "{row}");
    }
    // The noisy hat: decided on local fits, one boundary loop (its rim), a disc (χ = 1).
    for row in &rows[2..] {
        assert_eq!(row["denoised"], true, "{row}");
        assert_eq!(row["boundary_loops"], 1, "{row}");
        assert_eq!(row["euler_characteristic"], 1, "{row}");
        assert_eq!(row["fold_overs"], 0, "{row}");
    }
    let bad = run(&[
        "bench",
        "network",
        sphere.to_str().unwrap(),
        "--levels",
        "0",
    ]);
    assert!(!bad.status.success());
}

#[test]
fn bench_crowd_steps_every_surface_with_the_tolerance_asked_for() {
    let args = [
        "bench",
        "crowd",
        "--surfaces",
        "3",
        "--dense",
        "300",
        "--sim",
        "40",
        "--ticks",
        "6",
        "--json",
    ];
    let default = run_json(&args);
    assert_eq!(default["surfaces"], 3);
    assert_eq!(default["integrator"], "implicit-euler");
    assert_eq!(default["guard_trips"], 0);
    assert_eq!(default["troubled_surfaces"], 0);
    let parts = ["ms_forces", "ms_stepping", "ms_transfer"].map(|k| default[k].as_f64().unwrap());
    let tick = default["ms_tick"].as_f64().unwrap();
    assert!((parts.iter().sum::<f64>() - tick).abs() <= 1e-9 * tick.max(1.0));
    // A tighter tolerance takes more iterations on the same scene.
    let tight = run_json(&[&args[..], &["--cg-tolerance", "1e-7"]].concat());
    assert_eq!(tight["cg_tolerance"].as_f64().unwrap() as f32, 1e-7);
    assert!(
        tight["cg_per_step"].as_f64().unwrap() > default["cg_per_step"].as_f64().unwrap(),
        "{tight} against {default}"
    );
    for bad in [&["--cg-tolerance", "1"][..], &["--surfaces", "0"]] {
        let out = run(&[&args[..], bad].concat());
        assert_eq!(out.status.code(), Some(2), "{bad:?}");
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
