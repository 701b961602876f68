//! End-to-end tests of `terrasketch trace`: a real DEM becomes a sketch that loads, solves and
//! reproduces the DEM's large forms; bad input is refused cleanly.

mod common;

use std::path::{Path, PathBuf};

use common::*;
use terrasketch_sketch::{StrokeKind, load_sketch};

fn exemplar(name: &str) -> String {
    concat!(env!("CARGO_MANIFEST_DIR"), "/../synthesis/exemplars/").to_owned() + name
}

fn path_str(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// An ESRI ASCII grid of `n x n` cells of 30 m with heights `f(col, row)`.
fn asc(dir: &Path, name: &str, n: usize, f: impl Fn(usize, usize) -> f64) -> PathBuf {
    let mut text = format!("ncols {n}\nnrows {n}\nxllcorner 0\nyllcorner 0\ncellsize 30\n");
    for row in 0..n {
        let line: Vec<String> = (0..n).map(|col| format!("{}", f(col, row))).collect();
        text += &(line.join(" ") + "\n");
    }
    write(dir, name, &text)
}

#[test]
fn a_real_dem_traces_into_a_sketch_that_solves_back_to_its_large_forms() {
    let dir = tempfile::tempdir().unwrap();
    let (sketch_path, dem_out) = (dir.path().join("z.json"), dir.path().join("z.tif"));
    let o = run(&[
        "trace",
        &exemplar("zurich_dhm25.tif"),
        "-o",
        path_str(&sketch_path),
        "--crop",
        "256",
        "--dem-output",
        path_str(&dem_out),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(report["width"], 256);
    let parsed = load_sketch(&sketch_path).unwrap();
    assert!(parsed.warnings.is_empty(), "{:?}", parsed.warnings);
    let sketch = parsed.sketch;
    assert_eq!(sketch.extent_m, [256.0 * 25.0; 2]);
    let count = |k: StrokeKind| sketch.strokes.iter().filter(|s| s.kind == k).count();
    assert_eq!(
        (count(StrokeKind::Valley), count(StrokeKind::Ridge)),
        (100, 100)
    );
    assert_eq!(report["valleys"], 100);

    let dem = terrasketch_raster::read_heightmap(&dem_out).unwrap();
    assert_eq!(
        (dem.width, dem.height, dem.cell_size_m),
        (256, 256, [25.0, 25.0])
    );
    let (lo, hi) = dem
        .data
        .iter()
        .fold((f32::MAX, f32::MIN), |(a, b), &h| (a.min(h), b.max(h)));
    let relief = f64::from(hi - lo);
    // Every control point lies on the DEM, near its height there (heights are smoothed along the
    // line over a few cells).
    let at = |x: f64, y: f64| {
        let (col, row) = ((x / 25.0) as usize, 256 - 1 - (y / 25.0) as usize);
        f64::from(dem.data[row * 256 + col])
    };
    let mut errors: Vec<f64> = Vec::new();
    for s in &sketch.strokes {
        assert!(s.points.len() >= 2);
        for p in &s.points {
            assert!(
                (0.0..6400.0).contains(&p[0]) && (0.0..6400.0).contains(&p[1]),
                "{p:?}"
            );
            errors.push((p[2] - at(p[0], p[1])).abs());
        }
        assert!(s.width_m > 0.0 && s.slope_left_deg < 60.0 && s.slope_right_deg < 60.0);
    }
    errors.sort_by(f64::total_cmp);
    let median = errors[errors.len() / 2];
    assert!(
        median < 0.005 * relief,
        "median height error {median} m, relief {relief} m"
    );

    // Solved at the DEM's own grid, the sketch gives back the DEM's large forms.
    let solved_path = dir.path().join("s.tif");
    let o = run(&[
        "solve",
        path_str(&sketch_path),
        "--size",
        "256",
        "-o",
        path_str(&solved_path),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let solved = terrasketch_raster::read_heightmap(&solved_path).unwrap();
    assert_eq!(solved.cell_size_m, [25.0, 25.0]);
    let mean = |v: &[f32]| v.iter().map(|&h| f64::from(h)).sum::<f64>() / v.len() as f64;
    let (ms, md) = (mean(&solved.data), mean(&dem.data));
    let (mut cov, mut vs, mut vd, mut sq) = (0.0, 0.0, 0.0, 0.0);
    for (&s, &d) in solved.data.iter().zip(&dem.data) {
        let (a, b) = (f64::from(s) - ms, f64::from(d) - md);
        cov += a * b;
        vs += a * a;
        vd += b * b;
        sq += (f64::from(s) - f64::from(d)).powi(2);
    }
    let correlation = cov / (vs * vd).sqrt();
    let rms = (sq / dem.data.len() as f64).sqrt();
    assert!(correlation > 0.98, "correlation {correlation}");
    assert!(
        rms < 0.03 * relief,
        "RMS {rms} m over a relief of {relief} m"
    );
}

#[test]
fn options_choose_the_count_length_and_falloff() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("g.json");
    let o = run(&[
        "trace",
        &exemplar("grand_canyon_terrarium_z11.png"),
        "-o",
        path_str(&out),
        "--strokes",
        "7",
        "--min-length",
        "3000",
        "--falloff",
        "sigmoid",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let sketch = load_sketch(&out).unwrap().sketch;
    let count = |k: StrokeKind| sketch.strokes.iter().filter(|s| s.kind == k).count();
    assert_eq!(
        (count(StrokeKind::Valley), count(StrokeKind::Ridge)),
        (4, 3)
    );
    for s in &sketch.strokes {
        assert_eq!(s.falloff, terrasketch_sketch::Falloff::Sigmoid);
        let length: f64 = s
            .points
            .windows(2)
            .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
            .sum();
        // Control points cut corners of the traced line, by at most a few cells each.
        assert!(length > 2500.0, "a stroke of {length} m");
    }
}

#[test]
fn a_flat_dem_gives_an_empty_sketch_with_a_warning_that_solves() {
    let dir = tempfile::tempdir().unwrap();
    let dem = asc(dir.path(), "flat.asc", 64, |_, _| 412.0);
    let out = dir.path().join("flat.json");
    let o = run(&["trace", path_str(&dem), "-o", path_str(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("warning") && e.contains("flat"), "{e}");
    let sketch = load_sketch(&out).unwrap().sketch;
    assert!(sketch.strokes.is_empty());
    assert_eq!(sketch.base_elevation_m, 412.0);
    let solved = dir.path().join("flat.exr");
    let o = run(&[
        "solve",
        path_str(&out),
        "--size",
        "64",
        "-o",
        path_str(&solved),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let map = terrasketch_raster::read_heightmap(&solved).unwrap();
    assert!(map.data.iter().all(|&h| h == 412.0));
}

#[test]
fn bad_input_is_refused_without_writing_anything() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.json");
    let text = write(dir.path(), "notes.txt", "not a DEM\n");
    let fake_tif = write(dir.path(), "fake.tif", "not a TIFF either\n");
    let tiny = asc(dir.path(), "tiny.asc", 8, |c, r| (c * r) as f64);
    let ok = asc(dir.path(), "ok.asc", 32, |c, r| {
        (c as f64 - 16.0).abs() * 10.0 + r as f64
    });
    let missing = dir.path().join("missing.tif");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec![path_str(&text)], "not a heightmap or DEM file"),
        (
            vec![path_str(&fake_tif)],
            "does not start with a TIFF signature",
        ),
        (vec![path_str(&tiny)], "too small"),
        (vec![path_str(&ok), "--strokes", "0"], "--strokes"),
        (vec![path_str(&ok), "--min-length=-5"], "--min-length"),
        (vec![path_str(&ok), "--crop", "16"], "--crop"),
        (vec![path_str(&ok), "--crop", "64"], "under 64"),
        (vec![path_str(&ok), "--cell-size", "nan"], "--cell-size"),
        (
            vec![path_str(&ok), "--channel-cells", "0"],
            "--channel-cells",
        ),
    ];
    for (mut args, needle) in cases {
        args.splice(0..0, ["trace"]);
        args.extend(["-o", path_str(&out)]);
        let o = run(&args);
        assert_refused(&o, needle);
        assert!(!out.exists(), "{args:?} wrote {}", out.display());
    }
    let o = run(&["trace", path_str(&missing), "-o", path_str(&out)]);
    assert_fails_with(&o, "No such file or directory");
    let nowhere = dir.path().join("no/such/folder/s.json");
    let o = run(&["trace", path_str(&ok), "-o", path_str(&nowhere)]);
    assert_refused(&o, "does not exist");
    // A good run next to the failed ones writes the sketch and nothing else.
    let o = run(&["trace", path_str(&ok), "-o", path_str(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(load_sketch(&out).is_ok());
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.') || n.contains("tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

/// Runs the editor with a display (the current one, or a fresh Xvfb via xvfb-run), as
/// `tests/editor.rs` does.
fn run_editor(args: &[&str], recovery_dir: &Path) -> std::process::Output {
    let mut cmd = if std::env::var_os("DISPLAY").is_some() {
        bin()
    } else {
        let mut c = std::process::Command::new("xvfb-run");
        c.args(["-a", "-s", "-screen 0 1280x800x24"])
            .arg(env!("CARGO_BIN_EXE_terrasketch"));
        c
    };
    cmd.args(args).env("TERRASKETCH_RECOVERY_DIR", recovery_dir);
    if std::env::var_os("WGPU_BACKEND").is_none() {
        cmd.env("WGPU_BACKEND", "vulkan");
    }
    cmd.output()
        .expect("the terrasketch binary (or xvfb-run) runs")
}

#[test]
fn the_editor_opens_a_traced_sketch_solves_it_and_saves_an_edit() {
    let dir = tempfile::tempdir().unwrap();
    let traced = dir.path().join("traced.json");
    let o = run(&[
        "trace",
        &exemplar("jacksboro_fault_srtm3.tif"),
        "-o",
        path_str(&traced),
        "--crop",
        "256",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let sketch = load_sketch(&traced).unwrap().sketch;
    // Probe the solved land at the middle control point of the first valley.
    let valley = sketch
        .strokes
        .iter()
        .find(|s| s.kind == StrokeKind::Valley)
        .unwrap();
    let p = valley.points[valley.points.len() / 2];
    let session = format!(
        r#"{{ "format": "terrasketch-session", "version": 1, "sketch": "traced.json", "size": 256,
  "window_px": [640, 400], "solver_budget_wu": 4, "backend": "cpu", "probes_m": [[{}, {}]],
  "events": [ {{ "wait_converged": 400 }}, {{ "mark": "opened" }}, {{ "wait": 1 }},
    {{ "select": 0 }}, {{ "set": {{ "width_m": 2500 }} }}, {{ "wait_converged": 400 }},
    {{ "save": "edited.json" }} ] }}"#,
        p[0], p[1]
    );
    let session_path = write(dir.path(), "session.json", &session);
    let log = dir.path().join("log.jsonl");
    let o = run_editor(
        &["--replay", path_str(&session_path), "--log", path_str(&log)],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let frames: Vec<serde_json::Value> = std::fs::read_to_string(&log)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert!(
        frames
            .iter()
            .all(|f| f["errors"].as_array().unwrap().is_empty())
    );
    let opened = frames.iter().find(|f| f["mark"] == "opened").unwrap();
    assert_eq!(opened["strokes"], sketch.strokes.len());
    assert_eq!(opened["converged"], true);
    let h = opened["probe_heights_m"][0].as_f64().unwrap();
    assert!(
        (h - p[2]).abs() < 1.0,
        "the editor shows {h} m at a control point of height {} m",
        p[2]
    );
    let edited = load_sketch(&dir.path().join("edited.json")).unwrap().sketch;
    assert_eq!(edited.strokes.len(), sketch.strokes.len());
    assert_eq!(edited.strokes[0].width_m, 2500.0);
    assert_eq!(edited.strokes[1..], sketch.strokes[1..]);
}
