//! End-to-end tests of `terrasketch refine`: real binary, real exemplar files.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_terrasketch"))
        .args(args)
        .output()
        .expect("the terrasketch binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn exemplar(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../synthesis/exemplars")
        .join(name)
}

const SKETCH: &str = r#"{ "format": "terrasketch-sketch", "version": 1,
  "extent_m": [6400.0, 6400.0], "base_elevation_m": 100.0,
  "strokes": [
    { "kind": "ridge", "points": [[800, 3200, 900], [5600, 3300, 1100]], "slope_left_deg": 25, "slope_right_deg": 20, "width_m": 1200, "roughness": 0.7 },
    { "kind": "valley", "points": [[3000, 600, 300], [3100, 2400, 250]] } ] }"#;

fn assert_fails_with(o: &Output, needle: &str) {
    let e = stderr(o);
    assert!(!o.status.success(), "expected failure; stderr: {e}");
    assert!(!e.contains("panicked"), "panicked: {e}");
    assert!(
        e.to_lowercase().contains(&needle.to_lowercase()),
        "message {e:?} lacks {needle:?}"
    );
}

#[test]
fn refine_a_sketch_then_a_heightmap() {
    let dir = tempfile::tempdir().unwrap();
    let sketch = dir.path().join("s.json");
    std::fs::write(&sketch, SKETCH).unwrap();
    let out = dir.path().join("r.tif");
    let cache = dir.path().join("cache");
    let zurich = exemplar("zurich_dhm25.tif");
    let args = [
        "refine",
        sketch.to_str().unwrap(),
        "--exemplars",
        zurich.to_str().unwrap(),
        "--size",
        "128",
        "-o",
        out.to_str().unwrap(),
        "--cache-dir",
        cache.to_str().unwrap(),
        "--json",
    ];
    let o = run(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for key in [
        "ms_total",
        "patches_feature",
        "patches_fill",
        "exemplars",
        "pits_before",
        "pits_after",
        "constraint_max_error_m",
        "relief_m",
        "slope_w1_to_exemplars",
        "slope_w1_diffusion_to_exemplars",
        "seam_laplacian_p99_ratio",
        "seam_gradient_jump_ratio",
    ] {
        assert!(j[key].is_number(), "{key} missing in {j}");
    }
    assert_eq!(j["exemplars"], 1);
    assert!(j["patches_fill"].as_u64().unwrap() > 0);
    let relief = j["constraint_relief_m"].as_f64().unwrap();
    assert!(j["constraint_max_error_m"].as_f64().unwrap() <= 1e-3 * relief);
    assert_eq!(j["features_from_cache"], 0);
    // Second run: features come from the cache, output identical.
    let first = std::fs::read(&out).unwrap();
    let o = run(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["features_from_cache"], 1);
    assert_eq!(std::fs::read(&out).unwrap(), first, "same seed, same file");
    // The descriptors users compare terrains with, on the refined file.
    let o = run(&["metrics", out.to_str().unwrap(), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let m: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let m = &m["metrics"];
    let flat = m["flat_fraction"].as_f64().unwrap();
    assert!((0.0..=1.0).contains(&flat), "{m}");
    assert!(m["roughness_cv"].as_f64().unwrap() > 0.0, "{m}");
    assert!(m["axis_ratio"].as_f64().unwrap() > 0.0, "{m}");
    assert!(m["trenches"].is_u64(), "{m}");
    // The refined file as a heightmap target, resampled to 64.
    let out2 = dir.path().join("r2.exr");
    let o = run(&[
        "refine",
        out.to_str().unwrap(),
        "--exemplars",
        zurich.to_str().unwrap(),
        "--size",
        "64",
        "--patch-size",
        "16",
        "-o",
        out2.to_str().unwrap(),
        "--cache-dir",
        cache.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("refined 64^2"), "{}", stderr(&o));
    assert!(out2.is_file());
}

#[test]
fn refine_error_paths() {
    let dir = tempfile::tempdir().unwrap();
    let sketch = dir.path().join("s.json");
    std::fs::write(&sketch, SKETCH).unwrap();
    let out = dir.path().join("r.tif");
    let (s, o) = (sketch.to_str().unwrap(), out.to_str().unwrap());
    let missing = dir.path().join("no-such-folder");
    assert_fails_with(
        &run(&[
            "refine",
            s,
            "--exemplars",
            missing.to_str().unwrap(),
            "--size",
            "128",
            "-o",
            o,
        ]),
        "does not exist",
    );
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    assert_fails_with(
        &run(&[
            "refine",
            s,
            "--exemplars",
            empty.to_str().unwrap(),
            "--size",
            "128",
            "-o",
            o,
        ]),
        "no readable DEM",
    );
    let z = exemplar("zurich_dhm25.tif");
    let z = z.to_str().unwrap();
    assert_fails_with(
        &run(&["refine", s, "--exemplars", z, "--size", "100", "-o", o]),
        "power of two",
    );
    assert_fails_with(
        &run(&["refine", s, "--exemplars", z, "--size", "1000000", "-o", o]),
        "power of two",
    );
    assert_fails_with(
        &run(&[
            "refine",
            s,
            "--exemplars",
            z,
            "--size",
            "64",
            "--patch-size",
            "64",
            "-o",
            o,
        ]),
        "patch size",
    );
    let nothing = dir.path().join("nothing.json");
    assert_fails_with(
        &run(&[
            "refine",
            nothing.to_str().unwrap(),
            "--exemplars",
            z,
            "--size",
            "64",
            "-o",
            o,
        ]),
        "does not exist",
    );
    let bad_out = dir.path().join("r.xyz");
    assert_fails_with(
        &run(&[
            "refine",
            s,
            "--exemplars",
            z,
            "--size",
            "64",
            "-o",
            bad_out.to_str().unwrap(),
        ]),
        "xyz",
    );
    assert!(!out.exists(), "no output after failures");
}
