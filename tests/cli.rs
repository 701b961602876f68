//! End-to-end tests of the `terrasketch` command line: real binary, real files.

mod common;

use common::*;

#[test]
fn solve_writes_every_format_and_json() {
    let dir = tempfile::tempdir().unwrap();
    let sketch = write(dir.path(), "s.json", GOOD);
    for ext in ["exr", "tif", "png", "r16"] {
        let out = dir.path().join(format!("h.{ext}"));
        let o = run(&[
            "solve",
            sketch.to_str().unwrap(),
            "--size",
            "64",
            "-o",
            out.to_str().unwrap(),
            "--json",
        ]);
        assert!(o.status.success(), "{ext}: {}", stderr(&o));
        let v: serde_json::Value =
            serde_json::from_slice(&o.stdout).expect("one JSON object on stdout");
        for key in [
            "size",
            "backend",
            "adapter",
            "levels",
            "vcycles",
            "work_units",
            "residual_initial",
            "residual_final",
            "ms_total",
            "height_min_m",
            "height_max_m",
        ] {
            assert!(v.get(key).is_some(), "missing {key} in {v}");
        }
        assert_eq!(v["size"], 64);
        let (lo, hi) = (
            v["height_min_m"].as_f64().unwrap(),
            v["height_max_m"].as_f64().unwrap(),
        );
        // The ridge crest reaches 1100 m and the valley 250 m; the solve must span them.
        assert!((1090.0..1300.0).contains(&hi), "max {hi}");
        assert!(lo <= 260.0, "min {lo}");
        let len = std::fs::metadata(&out).unwrap().len();
        assert!(len > 64 * 64, "{ext} file too small: {len}");
        if ext == "r16" {
            assert_eq!(len, 64 * 64 * 2);
            assert!(
                stderr(&o).contains("stretched over"),
                "r16 must print its stretch"
            );
        }
    }
    // Exact round trip of the f32 formats: EXR and TIFF hold the same heights.
    let a = terrasketch_raster::read_heightmap(&dir.path().join("h.exr")).unwrap();
    let b = terrasketch_raster::read_heightmap(&dir.path().join("h.tif")).unwrap();
    assert_eq!(a.data, b.data);
    assert_eq!(a.cell_size_m, [100.0, 100.0]);
}

#[test]
fn exported_raster_is_north_up() {
    let dir = tempfile::tempdir().unwrap();
    // A single plateau near the north edge: the top rows of the file must be the high ones.
    let s = r#"{ "format": "terrasketch-sketch", "version": 1, "extent_m": [6400, 6400],
      "strokes": [ { "kind": "plateau", "points": [[500, 6000, 800], [5900, 6000, 800]], "width_m": 300 },
                   { "kind": "plateau", "points": [[500, 400, 100], [5900, 400, 100]], "width_m": 300 } ] }"#;
    let sketch = write(dir.path(), "n.json", s);
    let out = dir.path().join("n.exr");
    let o = run(&[
        "solve",
        sketch.to_str().unwrap(),
        "--size",
        "64",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let m = terrasketch_raster::read_heightmap(&out).unwrap();
    let row = |r: usize| m.data[r * 64 + 32];
    assert!(row(4) > 790.0, "north row holds {}", row(4));
    assert!(row(59) < 110.0, "south row holds {}", row(59));
}

#[test]
fn bad_sketches_fail_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.exr");
    let o = out.to_str().unwrap();
    let cases: &[(&str, &str, &str)] = &[
        (
            "malformed.json",
            "{ \"format\": \"terrasketch-sketch\",\n  \"version\": 1,, }",
            "line 2",
        ),
        (
            "format.json",
            r#"{ "format": "other", "version": 1, "extent_m": [1,1], "strokes": [] }"#,
            "format",
        ),
        (
            "version.json",
            r#"{ "format": "terrasketch-sketch", "version": 7, "extent_m": [1,1], "strokes": [] }"#,
            "version",
        ),
        (
            "nan.json",
            r#"{ "format": "terrasketch-sketch", "version": 1, "extent_m": [100,100], "strokes": [ { "kind": "ridge", "points": [[1,1,1],[2,2,1e999]] } ] }"#,
            "",
        ),
        (
            "onepoint.json",
            r#"{ "format": "terrasketch-sketch", "version": 1, "extent_m": [100,100], "strokes": [ { "kind": "ridge", "points": [[1,1,1]] } ] }"#,
            "point",
        ),
        (
            "kind.json",
            r#"{ "format": "terrasketch-sketch", "version": 1, "extent_m": [100,100], "strokes": [ { "kind": "volcano", "points": [[1,1,1],[2,2,2]] } ] }"#,
            "volcano",
        ),
        (
            "extent.json",
            r#"{ "format": "terrasketch-sketch", "version": 1, "extent_m": [0, 100], "strokes": [] }"#,
            "extent",
        ),
    ];
    for (name, text, needle) in cases {
        let p = write(dir.path(), name, text);
        let r = run(&["solve", p.to_str().unwrap(), "--size", "64", "-o", o]);
        assert_fails_with(&r, needle);
        assert!(!out.exists(), "{name}: no output may be written");
    }
    let missing = run(&["solve", "/nonexistent/x.json", "--size", "64", "-o", o]);
    assert_fails_with(&missing, "/nonexistent/x.json");
}

#[test]
fn out_of_bounds_inputs_are_refused_with_status_2() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.exr");
    let o = out.to_str().unwrap();
    let sketch = |extent: &str, base: &str, z: &str| {
        format!(
            r#"{{ "format": "terrasketch-sketch", "version": 1, "extent_m": {extent}, "base_elevation_m": {base},
              "strokes": [ {{ "kind": "ridge", "points": [[10, 10, 5], [90, 90, {z}]] }} ] }}"#
        )
    };
    let cases = [
        (
            "z.json",
            sketch("[6400, 6400]", "0", "1e30"),
            "strokes[0].points[1] z",
        ),
        (
            "base.json",
            sketch("[6400, 6400]", "-1e30", "5"),
            "base_elevation_m",
        ),
        ("huge.json", sketch("[1e30, 6400]", "0", "5"), "extent_m"),
        ("tiny.json", sketch("[0.5, 0.5]", "0", "5"), "extent_m"),
    ];
    for (name, text, field) in &cases {
        let p = write(dir.path(), name, text);
        assert_refused(
            &run(&["solve", p.to_str().unwrap(), "--size", "64", "-o", o]),
            field,
        );
        assert!(!out.exists(), "{name}: no output may be written");
    }
    // 10 m over 2048 cells is 4.9 mm a cell.
    let p = write(dir.path(), "cells.json", &sketch("[10, 10]", "0", "5"));
    let r = run(&["solve", p.to_str().unwrap(), "--size", "2048", "-o", o]);
    assert_refused(&r, "cell size");
    assert!(stderr(&r).contains("1 cm"), "{}", stderr(&r));
    assert!(!out.exists());

    // A heightmap input holding a height of 1e30 m.
    let far = dir.path().join("far.exr");
    let mut map = terrasketch_raster::Heightmap {
        width: 32,
        height: 32,
        data: vec![10.0; 32 * 32],
        cell_size_m: [10.0, 10.0],
    };
    map.data[3 * 32 + 4] = 1e30;
    terrasketch_raster::write_heightmap(&far, &map).unwrap();
    assert_refused(
        &run(&["metrics", far.to_str().unwrap()]),
        "height at row 3, column 4",
    );
}

#[test]
fn bad_sizes_and_paths_fail_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let sketch = write(dir.path(), "s.json", GOOD);
    let s = sketch.to_str().unwrap();
    let out = dir.path().join("o.exr");
    let o = out.to_str().unwrap();
    assert_refused(&run(&["solve", s, "--size", "63", "-o", o]), "64 to 16385");
    assert_refused(&run(&["solve", s, "--size", "16386", "-o", o]), "16385");
    assert_fails_with(
        &run(&["solve", s, "--size", "99999999999999999999", "-o", o]),
        "size",
    );
    assert_fails_with(
        &run(&["solve", s, "--size", "64", "-o", "/nonexistent-dir/o.exr"]),
        "does not exist",
    );
    assert_fails_with(
        &run(&[
            "solve",
            s,
            "--size",
            "64",
            "-o",
            dir.path().join("o.bmp").to_str().unwrap(),
        ]),
        "bmp",
    );
    assert_fails_with(
        &run(&["solve", s, "--size", "64", "--tolerance=-1", "-o", o]),
        "tolerance",
    );
    assert_fails_with(
        &run(&["solve", s, "--size", "64", "--tolerance", "nan", "-o", o]),
        "tolerance",
    );
    // Tile-parallel refine and stitch: refused before any work, nothing written.
    let tile = |size: &str, tiles: &str, tile: &str, out: &str| {
        run(&[
            "refine", s, "--size", size, "--tiles", tiles, "--tile", tile, "-o", out,
        ])
    };
    assert_refused(&tile("63", "2,2", "0,0", o), "--size 63");
    assert_refused(&tile("256", "2,2", "0,2", o), "outside the 2,2 tiles");
    assert_refused(&tile("256", "3,2", "0,0", o), "--tiles");
    let png = dir.path().join("o.png");
    assert_refused(
        &tile("256", "2,2", "0,0", png.to_str().unwrap()),
        "tiles are written as f32",
    );
    let not_sidecar = write(dir.path(), "x.tile.json", "{}");
    assert_refused(
        &run(&["stitch", not_sidecar.to_str().unwrap(), "-o", o]),
        "is not a tile sidecar",
    );
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    assert_refused(
        &run(&["stitch", empty.to_str().unwrap(), "-o", o]),
        "holds no tile sidecar",
    );
    assert!(!out.exists() && !png.exists());
}

#[test]
fn strokes_leaving_the_extent_are_clipped_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let s = r#"{ "format": "terrasketch-sketch", "version": 1, "extent_m": [6400, 6400],
      "strokes": [ { "kind": "ridge", "points": [[-3000, 3200, 900], [9000, 3300, 1100]] } ] }"#;
    let sketch = write(dir.path(), "c.json", s);
    let out = dir.path().join("c.exr");
    let o = run(&[
        "solve",
        sketch.to_str().unwrap(),
        "--size",
        "64",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("warning"),
        "expected a clipping warning: {}",
        stderr(&o)
    );
    assert!(out.exists());
}

#[test]
fn empty_sketch_is_flat_at_base_elevation() {
    let dir = tempfile::tempdir().unwrap();
    let s = r#"{ "format": "terrasketch-sketch", "version": 1, "extent_m": [1000, 1000], "base_elevation_m": 42.5, "strokes": [] }"#;
    let sketch = write(dir.path(), "e.json", s);
    let out = dir.path().join("e.tif");
    let o = run(&[
        "solve",
        sketch.to_str().unwrap(),
        "--size",
        "64",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let m = terrasketch_raster::read_heightmap(&out).unwrap();
    assert!(m.data.iter().all(|h| *h == 42.5));
}

#[test]
fn help_and_version_work() {
    for args in [
        vec!["--help"],
        vec!["--version"],
        vec!["solve", "--help"],
        vec!["bench", "solver", "--help"],
        vec!["bench", "drag", "--help"],
    ] {
        let o = run(&args);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        assert!(!o.stdout.is_empty());
    }
}

#[test]
fn bench_solver_prints_the_documented_figures() {
    let o = run(&["bench", "solver", "--size", "64", "--repeat", "1", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for key in [
        "ms_median",
        "ms_min",
        "work_units",
        "vcycles",
        "convergence_factor",
        "error_vs_converged",
        "adapter",
        "peak_rss_mb",
        "gpu_bytes",
    ] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
    assert!(v["error_vs_converged"].as_f64().unwrap() <= 1e-3);
}

#[test]
fn bench_drag_prints_the_documented_figures_and_stays_accurate() {
    let o = run(&["bench", "drag", "--size", "64", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for key in [
        "p50_ms",
        "p95_ms",
        "work_units_per_update",
        "updates",
        "error_vs_converged",
    ] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
    assert_eq!(v["updates"].as_u64(), Some(60));
    // 60 warm updates in a row end as close to the converged heights as a cold solve does.
    assert!(v["error_vs_converged"].as_f64().unwrap() <= 1e-3, "{v}");
}

#[test]
fn bench_drag_on_the_gpu_counts_the_editors_frames_without_waits() {
    // Runs on the software adapter in CI (scripts/test installs it); a missing adapter fails here.
    let o = run(&[
        "bench",
        "drag",
        "--size",
        "256",
        "--backend",
        "gpu",
        "--frames",
        "3",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let (update, frame) = (
        &v["gpu_counts_per_update"],
        &v["gpu_counts_per_editor_frame"],
    );
    // The update reads its reports back (one wait); the editor's frame waits for nothing.
    assert_eq!(update["blocking_waits"].as_u64(), Some(1), "{v}");
    assert_eq!(frame["blocking_waits"].as_u64(), Some(0), "{v}");
    // The same work: the frame's queued iterations are counted although only their residual is
    // read back.
    let bytes = |c: &serde_json::Value| c["bytes_moved_estimate"].as_f64().unwrap();
    assert!(
        (bytes(frame) / bytes(update) - 1.0).abs() < 0.05,
        "{} against {}",
        bytes(frame),
        bytes(update)
    );
    // Without a wait the encoding overlaps the device's work: the frame costs less on paper.
    let mid = |c: &serde_json::Value| c["paper_model_ms"]["mid_range"].as_f64().unwrap();
    assert!(mid(frame) < mid(update), "{v}");
    // What the last frame shows is as close to the converged heights as the updates.
    assert!(
        v["editor_frame_error_vs_converged"].as_f64().unwrap() <= 1e-3,
        "{v}"
    );
    // The update's kernels add up to its counts.
    let passes = v["gpu_bytes_by_pass_per_update"].as_array().unwrap();
    let sum = |key: &str| passes.iter().map(|p| p[key].as_u64().unwrap()).sum::<u64>();
    assert_eq!(
        sum("dispatches"),
        update["dispatches"].as_u64().unwrap(),
        "{v}"
    );
    assert_eq!(
        sum("bytes"),
        update["bytes_moved_estimate"].as_u64().unwrap(),
        "{v}"
    );
}

#[test]
fn gpu_backend_without_an_adapter_says_how_to_install_one() {
    let dir = tempfile::tempdir().unwrap();
    let sketch = write(dir.path(), "s.json", GOOD);
    let out = dir.path().join("g.exr");
    // Point the Vulkan loader at no driver at all: no adapter can be found.
    let o = bin()
        .args([
            "solve",
            sketch.to_str().unwrap(),
            "--size",
            "64",
            "--backend",
            "gpu",
            "-o",
            out.to_str().unwrap(),
        ])
        .env("WGPU_BACKEND", "vulkan")
        .env("VK_ICD_FILENAMES", "/nonexistent/none.json")
        .env("VK_DRIVER_FILES", "/nonexistent/none.json")
        .output()
        .unwrap();
    assert_fails_with(&o, "mesa-vulkan-drivers");
    assert!(!out.exists());
}

#[test]
fn gpu_and_cpu_solves_agree() {
    // Runs on the software adapter in CI (scripts/test installs it); a missing adapter fails here.
    let dir = tempfile::tempdir().unwrap();
    let sketch = write(dir.path(), "s.json", GOOD);
    let mut maps = Vec::new();
    for backend in ["cpu", "gpu"] {
        let out = dir.path().join(format!("{backend}.exr"));
        let o = run(&[
            "solve",
            sketch.to_str().unwrap(),
            "--size",
            "128",
            "--backend",
            backend,
            "-o",
            out.to_str().unwrap(),
            "--json",
        ]);
        assert!(o.status.success(), "{backend}: {}", stderr(&o));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(v["backend"], backend);
        maps.push(terrasketch_raster::read_heightmap(&out).unwrap());
    }
    let (lo, hi) = maps[0]
        .data
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), h| {
            (a.min(*h), b.max(*h))
        });
    let worst = maps[0]
        .data
        .iter()
        .zip(&maps[1].data)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(
        worst <= 1e-3 * (hi - lo),
        "GPU vs CPU differ by {worst} m over a relief of {} m",
        hi - lo
    );
}

#[test]
fn a_file_that_is_no_heightmap_gives_one_error_naming_the_format() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.tif");
    let o = out.to_str().unwrap();
    let cases = [
        ("notes.tif", "as GeoTIFF"),
        ("notes.png", "as PNG"),
        ("notes.exr", "as OpenEXR"),
        ("notes.asc", "as ESRI ASCII grid"),
        ("N46E008.hgt", "as SRTM .hgt"),
        ("notes.txt", "not a heightmap or DEM file"),
    ];
    for (name, what) in cases {
        let p = write(dir.path(), name, "these are notes, not heights\n");
        let p = p.to_str().unwrap();
        let masks = dir.path().join("masks");
        for args in [
            vec!["metrics", p],
            vec!["refine", p, "--size", "64", "-o", o],
            vec!["masks", p, "-o", masks.to_str().unwrap()],
        ] {
            let r = run(&args);
            assert_refused(&r, what);
            assert!(stderr(&r).contains(name), "{args:?}: {}", stderr(&r));
            assert!(!stderr(&r).contains("nor as"), "{args:?}: {}", stderr(&r));
        }
        assert!(!out.exists(), "{name}: no output");
    }
    // A metrics summary names the GeoTIFF's CRS, transform and no-data value.
    let dem = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../synthesis/exemplars/zurich_dhm25.tif"
    );
    let r = run(&["metrics", dem, "--json"]);
    assert!(r.status.success(), "{}", stderr(&r));
    let v: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    let source = &v["source"];
    assert_eq!(source["format"], "GeoTIFF", "{source}");
    assert_eq!(source["nodata"], -9999.0, "{source}");
    let tie = &source["georeference"]["transform"]["tiepoints"][0];
    assert_eq!(tie[3], 677_562.5, "{source}");
}

#[test]
fn metrics_of_a_solve_and_a_real_dem() {
    let dir = tempfile::tempdir().unwrap();
    let sketch = write(dir.path(), "s.json", GOOD);
    let out = dir.path().join("m.exr");
    let o = run(&[
        "solve",
        sketch.to_str().unwrap(),
        "--size",
        "128",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let dem = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../synthesis/exemplars/zurich_dhm25.tif"
    );
    let o = run(&[
        "metrics",
        out.to_str().unwrap(),
        "--reference",
        dem,
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let m = &v["metrics"];
    for key in [
        "slope_mean_deg",
        "slope_p90_deg",
        "slope_histogram",
        "spectral_slope",
        "pit_count",
        "hypsometric_integral",
    ] {
        assert!(m.get(key).is_some(), "missing metrics.{key} in {m}");
    }
    // A diffusion surface is smoother than real terrain: a steeper (more negative) spectral slope.
    let own = m["spectral_slope"].as_f64().unwrap();
    let real = v["reference_metrics"]["spectral_slope"].as_f64().unwrap();
    assert!(own < real, "diffusion {own} vs real {real}");
    assert!(
        v["comparison"]["slope_wasserstein_deg"].as_f64().is_some(),
        "{}",
        v["comparison"]
    );
    assert_fails_with(
        &run(&["metrics", "/nonexistent/x.tif"]),
        "/nonexistent/x.tif",
    );
}

#[test]
fn corner_sampled_1025_matches_the_cell_centred_1024() {
    let dir = tempfile::tempdir().unwrap();
    let cells = solve_example(dir.path(), 1024, "exr");
    let corners = solve_example(dir.path(), 1025, "tif");
    assert_eq!((corners.width, corners.height), (1025, 1025));
    assert_eq!(cells.cell_size_m, [10.0, 10.0]);
    assert_eq!(corners.cell_size_m, [10.0, 10.0]);
    let (lo, hi) = cells
        .data
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &h| {
            (a.min(h), b.max(h))
        });
    let relief = f64::from(hi - lo);
    assert!(relief > 100.0, "relief {relief}");
    // Interior corner (r, c) of the 1025 export lies between cells r-1, r and c-1, c of the 1024.
    let mut errors = Vec::new();
    for r in 1..1024 {
        for c in 1..1024 {
            let t = |rr: usize, cc: usize| f64::from(cells.data[rr * 1024 + cc]);
            let mean = (t(r - 1, c - 1) + t(r - 1, c) + t(r, c - 1) + t(r, c)) / 4.0;
            errors.push((f64::from(corners.data[r * 1025 + c]) - mean).abs() / relief);
        }
    }
    errors.sort_by(f64::total_cmp);
    let (median, max) = (errors[errors.len() / 2], errors[errors.len() - 1]);
    assert!(
        median <= 1e-4 && max <= 5e-3,
        "median {median:e}, max {max:e}"
    );
    // The corners are the edge cells' values (the solver's Neumann border).
    assert_eq!(corners.data[0], cells.data[0]);
    assert_eq!(corners.data[1025 * 1025 - 1], cells.data[1024 * 1024 - 1]);
}

#[test]
fn unreal_sizes_sample_corners_of_the_extent() {
    let dir = tempfile::tempdir().unwrap();
    let m = solve_example(dir.path(), 1009, "exr");
    assert_eq!((m.width, m.height), (1009, 1009));
    // 1009 samples span 10240 m: 1008 intervals.
    assert_eq!(m.cell_size_m, [10240.0 / 1008.0; 2]);
    let cells = solve_example(dir.path(), 1024, "exr");
    // The centre sample (504, 504) is the extent's centre, the corner of the 1024 solve's
    // cells 511 and 512.
    let t = |r: usize, c: usize| cells.data[r * 1024 + c];
    let mean = 0.5 * (0.5 * (t(511, 511) + t(511, 512)) + 0.5 * (t(512, 511) + t(512, 512)));
    assert!((m.data[504 * 1009 + 504] - mean).abs() < 1e-3);
}

#[test]
fn sizes_that_cannot_fit_in_memory_are_refused_up_front() {
    let dir = tempfile::tempdir().unwrap();
    let sketch = write(dir.path(), "s.json", GOOD);
    let out = dir.path().join("big.exr");
    let started = std::time::Instant::now();
    let o = bin()
        .args(["solve", sketch.to_str().unwrap(), "--size", "4097", "-o"])
        .arg(&out)
        .env("TERRASKETCH_MEMORY_LIMIT_MB", "100")
        .output()
        .unwrap();
    assert_refused(&o, "--size 4097 needs about");
    assert!(
        stderr(&o).contains("more than the 0.1 GiB available"),
        "{}",
        stderr(&o)
    );
    assert!(
        started.elapsed().as_secs_f64() < 5.0,
        "refused before solving"
    );
    assert!(!out.exists());
    // A refinement too: 4096^2 cells at 128 bytes each is over 2 GiB.
    let o = bin()
        .args(["refine", sketch.to_str().unwrap(), "--size", "4096", "-o"])
        .arg(&out)
        .env("TERRASKETCH_MEMORY_LIMIT_MB", "1024")
        .output()
        .unwrap();
    assert_refused(&o, "a 4096^2 refinement and the export");
    assert!(!out.exists());
}

/// `solve` adds the procedural detail by default; `--detail off` is the pure diffusion; the sketch's
/// `seed` picks the detail.
#[test]
fn solve_writes_detail_by_default_and_detail_off_is_the_diffusion() {
    let dir = tempfile::tempdir().unwrap();
    let range = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/range.json");
    let text = std::fs::read_to_string(range).unwrap();
    let seeded = write(
        dir.path(),
        "seeded.json",
        &text.replacen("\"strokes\"", "\"seed\": 5,\n  \"strokes\"", 1),
    );
    let solve = |sketch: &str, name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let mut args = vec![
            "solve",
            sketch,
            "--size",
            "256",
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let o = run(&args);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        terrasketch_raster::read_heightmap(&out).unwrap().data
    };
    let default = solve(range, "d.exr", &[]);
    let on = solve(range, "on.exr", &["--detail", "on"]);
    let off = solve(range, "off.exr", &["--detail", "off"]);
    let other_seed = solve(seeded.to_str().unwrap(), "s.exr", &[]);
    assert_eq!(default, on);
    let rms = |a: &[f32], b: &[f32]| {
        (a.iter()
            .zip(b)
            .map(|(x, y)| ((x - y) as f64).powi(2))
            .sum::<f64>()
            / a.len() as f64)
            .sqrt()
    };
    assert!(rms(&on, &off) > 2.0, "detail RMS {}", rms(&on, &off));
    assert!(
        rms(&on, &other_seed) > 2.0,
        "seed change {}",
        rms(&on, &other_seed)
    );
    let o = run(&[
        "solve", range, "--size", "64", "--detail", "maybe", "-o", "x.exr",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}
