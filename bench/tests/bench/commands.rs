//! The `point-springs-bench` binary, end to end (run from the repository root, as its
//! defaults expect).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use bevy_point_springs::core::cloud::io::{PlyEncoding, write_ply};
use bevy_point_springs::core::cloud::knn::KnnIndex;
use bevy_point_springs::core::cloud::shapes;

/// The seed `point-springs generate` uses by default.
const NOISE_SEED: u64 = 1;

/// The repository root (the bench crate is its `bench/` folder).
fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

fn asset(name: &str) -> PathBuf {
    root().join("assets").join(name)
}

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_point-springs-bench"))
        .args(args)
        .current_dir(root())
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
    let dir = std::env::temp_dir().join(format!("bps-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn cloth_grid_reports_speed_and_sag() {
    let v = run_json(&[
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

    let text = run(&["cloth-grid", "--size", "4", "--steps", "10"]);
    assert!(text.status.success());
    assert!(String::from_utf8(text.stdout).unwrap().contains("speedup"));

    for args in [
        &["cloth-grid", "--size", "1"][..],
        &["cloth-grid", "--integrator", "leapfrog"],
        &["cloth-grid", "--size", "100000"],
    ] {
        let out = run(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(!out.stderr.is_empty());
    }
}

#[test]
fn transfer_reports_speed_and_error() {
    let v = run_json(&[
        "transfer", "--points", "3000", "--sim", "300", "--repeat", "2", "--json",
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
    let out = run(&["transfer", "--points", "100", "--sim", "200"]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn table1_measures_the_papers_sizes_with_every_integrator() {
    let scene = asset("scenes/sphere_poke.ron");
    let v = run_json(&[
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
    let out = run(&["table1", scene.to_str().unwrap(), "--steps", "0"]);
    assert_eq!(out.status.code(), Some(2));
    let out = run(&["table1", scene.to_str().unwrap(), "--repeats", "0"]);
    assert_eq!(out.status.code(), Some(2));
    let out = run(&["table1", "no/such/scene.ron"]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn scale_reports_every_configuration_that_fits() {
    let stem = scratch("scale");
    let v = run_json(&[
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
    let out = run(&["scale", "--dense", "3", "--steps", "1"]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn solvers_compares_the_local_global_solver_with_cg() {
    let v = run_json(&[
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
        let out = run(&["solvers", "--scenes", "sheet", bad[0], bad[1]]);
        assert_eq!(out.status.code(), Some(2), "{bad:?}");
    }
}

#[test]
fn convergence_runs_every_problem_to_equilibrium_with_every_material() {
    let stem = scratch("convergence");
    let v = run_json(&[
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
    let out = run(&["convergence", "--fractions", "0", "--steps", "1"]);
    assert_eq!(out.status.code(), Some(2));
}

/// Runs `report --quick` on `scenes` into a scratch folder named `name` and checks what it
/// wrote: the CSV, the summary (Table 1, and at 10 % an error under 1 % on each scene), the
/// Markdown and a chart per scene.
fn quick_report(name: &str, scenes: &[&str]) {
    let out = scratch(name);
    let assets = asset("");
    run_ok(&[
        "report",
        "--quick",
        "--scenes",
        &scenes.join(","),
        "--out",
        out.to_str().unwrap(),
        "--assets",
        assets.to_str().unwrap(),
    ]);
    // The CSV: the columns, one row per scene, level and integrator.
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
    assert_eq!(
        rows.len(),
        scenes.len() * 3 * 3,
        "3 levels, 3 integrators a scene"
    );
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
    let best_scenes: Vec<&str> = best.iter().map(|b| b["scene"].as_str().unwrap()).collect();
    assert_eq!(best_scenes, scenes);
    for b in best {
        assert!(b["rms_error"].as_f64().unwrap() < 0.01, "{b}");
    }
    // The Markdown, and a chart per scene with its Pareto front.
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("Table 1"));
    for scene in scenes {
        assert!(md.contains(&format!("## {scene}")), "{scene}");
        let svg = std::fs::read_to_string(out.join(format!("report_{scene}.svg"))).unwrap();
        assert!(svg.contains("Pareto front") && svg.contains("implicit-euler"));
        let png = std::fs::metadata(out.join(format!("report_{scene}.png"))).unwrap();
        assert!(png.len() > 10_000, "{png:?}");
    }
}

// The report's scenes in two tests, so that they run at once on the test threads (the
// report runs one scene at a time; the kitten alone takes as long as the other three).
#[test]
fn report_quick_writes_every_file_and_meets_the_error_goal() {
    quick_report("report", &["sphere", "hat", "sheet"]);
    let nowhere = scratch("report-nowhere");
    let bad = run(&[
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
    let unknown = run(&["report", "--quick", "--scenes", "sheet,teapot"]);
    assert_eq!(unknown.status.code(), Some(2));
    let said = String::from_utf8_lossy(&unknown.stderr);
    assert!(said.contains("teapot") && said.contains("kitten"), "{said}");
}

#[test]
fn report_quick_on_the_kitten_meets_the_error_goal() {
    quick_report("report-kitten", &["kitten"]);
}

#[test]
fn network_reports_each_level() {
    // A hat of 2000 points with Gaussian noise of half a mean spacing (`point-springs
    // generate hat --points 2000 --noise 0.5`).
    let hat = scratch("hat.ply");
    let clean = shapes::hat(2000, 1.0, shapes::HAT_DEFAULT_RIM);
    let spacing = clean
        .spacing(&KnnIndex::build(clean.positions()))
        .unwrap()
        .mean;
    let noisy = shapes::with_noise(&clean, 0.5 * spacing, NOISE_SEED);
    write_ply(&hat, &noisy, PlyEncoding::BinaryLittleEndian).unwrap();
    let sphere = asset("sphere926.pwn");
    let v = run_json(&[
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
    let bad = run(&["network", sphere.to_str().unwrap(), "--levels", "0"]);
    assert!(!bad.status.success());
}

#[test]
fn crowd_steps_every_surface_with_the_tolerance_asked_for() {
    let args = [
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
