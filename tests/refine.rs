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
    // Each constrained cell within its stroke's height tolerance (2 m by default).
    assert!(j["constraint_max_excess_m"].as_f64().unwrap() <= 1e-3 * relief);
    assert!(
        j["constraint_max_error_m"].as_f64().unwrap()
            <= j["constraint_tolerance_max_m"].as_f64().unwrap() + 1e-3 * relief
    );
    assert_eq!(j["features_from_cache"], 0);
    // Second run: features come from the cache, output identical.
    let first = std::fs::read(&out).unwrap();
    let o = run(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["features_from_cache"], 1);
    assert_eq!(std::fs::read(&out).unwrap(), first, "same seed, same file");
    assert_eq!(j["fine_detail"], 0.5, "the default gain is reported");
    // Without the octaves finer than the exemplar, another file; a gain out of range is refused.
    let mut plain = args.to_vec();
    plain.extend(["--fine-detail", "0"]);
    let o = run(&plain);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_ne!(
        std::fs::read(&out).unwrap(),
        first,
        "--fine-detail 0 changed nothing"
    );
    for bad in ["5", "-1", "nan", "x"] {
        let flag = format!("--fine-detail={bad}");
        let mut a = args.to_vec();
        a.push(&flag);
        let o = run(&a);
        assert_eq!(o.status.code(), Some(2), "{bad}: {}", stderr(&o));
        assert_fails_with(&o, "--fine-detail");
    }
    let o = run(&args);
    assert!(o.status.success(), "{}", stderr(&o));
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
    for size in ["63", "16386", "1000000"] {
        assert_fails_with(
            &run(&["refine", s, "--exemplars", z, "--size", size, "-o", o]),
            "from 64 to 16385",
        );
    }
    assert_fails_with(
        &run(&[
            "refine",
            s,
            "--exemplars",
            z,
            "--size",
            "65",
            "--tiles",
            "3,2",
            "-o",
            o,
        ]),
        "--tiles",
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

#[test]
fn refine_keeps_the_crs_transform_and_nodata_of_a_geotiff() {
    use tiff::tags::Tag;
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    let zurich = exemplar("zurich_dhm25.tif");
    let step = 1.0 / 3600.0;
    let inputs = [
        (
            "mercator",
            &KEYS_3857[..],
            vec![
                (Tag::ModelPixelScaleTag, vec![30.0, 30.0, 0.0]),
                (
                    Tag::ModelTiepointTag,
                    vec![0.0, 0.0, 0.0, 951_000.0, 6_003_000.0, 0.0],
                ),
            ],
        ),
        (
            "lonlat",
            &KEYS_4326[..],
            vec![(
                Tag::ModelTransformationTag,
                vec![
                    step, 0.0, 0.0, 8.5, 0.0, -step, 0.0, 47.4, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                    1.0,
                ],
            )],
        ),
    ];
    for (name, keys, transform) in inputs {
        let input = dir.path().join(format!("{name}.tif"));
        write_gis_tiff(&input, 64, keys, &transform);
        let (want, _) = geo_tags(&input);
        let refine = |size: &str, out: &Path, extra: &[&str]| {
            let mut args = vec![
                "refine",
                input.to_str().unwrap(),
                "--exemplars",
                zurich.to_str().unwrap(),
                "--size",
                size,
                "--patch-size",
                "16",
                "-o",
                out.to_str().unwrap(),
                "--cache-dir",
                cache.to_str().unwrap(),
            ];
            args.extend_from_slice(extra);
            let o = run(&args);
            assert!(o.status.success(), "{name} {size}: {}", stderr(&o));
        };
        // Same size: the georeference and the no-data cell are written back unchanged.
        let out = dir.path().join(format!("{name}_64.tif"));
        refine("64", &out, &[]);
        let (got, data) = geo_tags(&out);
        assert_eq!(got, want, "{name}: CRS, transform and no-data");
        assert_eq!(
            data[10 * 64 + 20],
            -9999.0,
            "{name}: the no-data cell stays no-data"
        );
        assert_eq!(data.iter().filter(|&&h| h == -9999.0).count(), 1, "{name}");
        // 65 corner samples from the 64 refinement: same CRS and no-data, the transform moved
        // half a pixel so that sample k sits on the input's cell corner k.
        let out = dir.path().join(format!("{name}_65.tif"));
        refine("65", &out, &[]);
        let (got, _) = geo_tags(&out);
        assert_eq!(
            (&got.keys, &got.nodata),
            (&want.keys, &want.nodata),
            "{name}"
        );
        let corner = |t: &GeoTags, i: f64, j: f64| -> [f64; 2] {
            match (&t.matrix, &t.scale, &t.tiepoints) {
                (Some(m), _, _) => [m[0] * i + m[1] * j + m[3], m[4] * i + m[5] * j + m[7]],
                (None, Some(s), Some(p)) => [(i - p[0]) * s[0] + p[3], p[4] - (j - p[1]) * s[1]],
                _ => panic!("{t:?}"),
            }
        };
        // Pixel-is-area: sample k's pixel centre is at k + 1/2; pixel-is-point: at k.
        let centre = if keys == KEYS_3857 { 0.5 } else { 0.0 };
        for (i, j) in [(0.0, 0.0), (64.0, 0.0), (17.0, 40.0), (64.0, 64.0)] {
            let a = corner(&got, i + centre, j + centre);
            let b = corner(&want, i + centre - 0.5, j + centre - 0.5);
            assert!(
                (a[0] - b[0]).abs() < 1e-9 * b[0].abs().max(1.0)
                    && (a[1] - b[1]).abs() < 1e-9 * b[1].abs().max(1.0),
                "{name} sample ({i}, {j}): {a:?} vs input corner {b:?}"
            );
        }
        // Tiles of the same output: each keeps the CRS, and the south-east tile's first sample
        // is the world's sample (32, 32), with the same height.
        let tiled = dir.path().join(format!("{name}_tiled.tif"));
        refine("65", &tiled, &["--tiles", "2,2"]);
        let (world, world_data) = geo_tags(&out);
        let (tile, tile_data) = geo_tags(&dir.path().join(format!("{name}_tiled_x1_y0.tif")));
        assert_eq!(
            (&tile.keys, &tile.nodata),
            (&want.keys, &want.nodata),
            "{name}"
        );
        let a = corner(&tile, centre, centre);
        let b = corner(&world, 32.0 + centre, 32.0 + centre);
        assert!(
            (a[0] - b[0]).abs() < 1e-6 && (a[1] - b[1]).abs() < 1e-6,
            "{a:?} vs {b:?}"
        );
        assert_eq!(tile_data[0], world_data[32 * 65 + 32], "{name}: same land");
        let manifest = dir.path().join(format!("{name}_tiled.tiles.json"));
        let manifest: serde_json::Value =
            serde_json::from_slice(&std::fs::read(manifest).unwrap()).unwrap();
        let epsg = if keys == KEYS_3857 { 3857 } else { 4326 };
        assert_eq!(manifest["crs_epsg"], epsg, "{manifest}");
        if keys == KEYS_3857 {
            // Tile x1_y0: samples 32..=64 both ways, pixels half a cell past them.
            let bounds = &manifest["tiles"][1]["crs_bounds"];
            let want = [951_945.0, 6_001_065.0, 952_935.0, 6_002_055.0];
            for (k, w) in want.iter().enumerate() {
                assert!((bounds[k].as_f64().unwrap() - w).abs() < 1e-6, "{bounds}");
            }
        }
    }
}

mod common;
use common::{GeoTags, KEYS_3857, KEYS_4326, geo_tags, write_gis_tiff};

/// `refine --tile` of `examples/range.json`, a 256^2 world in 2 x 2 tiles with 16 cells of
/// overlap, shipped exemplars.
fn tile_args<'a>(
    world_out: &'a str,
    tile: &'a str,
    cache: &'a str,
    extra: &[&'a str],
) -> Vec<&'a str> {
    let mut a = vec![
        "refine",
        concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/range.json"),
        "--size",
        "256",
        "--tiles",
        "2,2",
        "--overlap",
        "16",
        "--tile",
        tile,
        "-o",
        world_out,
        "--cache-dir",
        cache,
        "--json",
    ];
    a.extend_from_slice(extra);
    a
}

fn p99(mut v: Vec<f32>) -> f32 {
    let k = ((v.len() as f64 * 0.99) as usize).min(v.len() - 1);
    *v.select_nth_unstable_by(k, f32::total_cmp).1
}

#[test]
fn tiles_are_deterministic_independent_and_stitch_without_seams() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cache = d.join("cache");
    let cache = cache.to_str().unwrap();
    let coarse = d.join("world.coarse");
    let coarse_s = coarse.to_str().unwrap();
    let o = run(&[
        "refine",
        concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/range.json"),
        "--size",
        "256",
        "--coarse-out",
        coarse_s,
        "--cache-dir",
        cache,
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let all = d.join("all");
    std::fs::create_dir(&all).unwrap();
    let world = all.join("w.exr");
    let world_s = world.to_str().unwrap();
    for tile in ["0,0", "1,0", "0,1", "1,1"] {
        let o = run(&tile_args(world_s, tile, cache, &["--coarse", coarse_s]));
        assert!(o.status.success(), "{tile}: {}", stderr(&o));
    }
    // The same tile alone in another folder, with the coarse file and without it (its process
    // then computes the world's coarse levels itself): the same bits, whatever else ran.
    for (k, extra) in [vec!["--coarse", coarse_s], vec![]].into_iter().enumerate() {
        let alone = d.join(format!("alone{k}"));
        std::fs::create_dir(&alone).unwrap();
        let w = alone.join("w.exr");
        let o = run(&tile_args(w.to_str().unwrap(), "1,0", cache, &extra));
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(
            std::fs::read(alone.join("w_x1_y0.exr")).unwrap()
                == std::fs::read(all.join("w_x1_y0.exr")).unwrap(),
            "tile 1,0 differs between runs ({extra:?})"
        );
        assert!(alone.join("w_x1_y0.tile.json").is_file());
    }
    let out = d.join("stitched.exr");
    let o = run(&[
        "stitch",
        all.join("w_x0_y0.tile.json").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let seam = j["seam_laplacian_p99_ratio"].as_f64().unwrap();
    assert!(seam > 0.0 && seam < 1.5, "tile-border seam ratio {seam}");
    let apart = j["overlap_rms_difference_m"].as_f64().unwrap();
    assert!(apart > 0.0, "the tiles are equal in their overlaps: {j}");
    let h = terrasketch_raster::read_heightmap(&out).unwrap();
    assert_eq!((h.width, h.height), (256, 256));
    assert!(h.data.iter().all(|v| v.is_finite()));
    // Outside the overlaps the stitched world is each tile itself.
    let t00 = terrasketch_raster::read_heightmap(&all.join("w_x0_y0.exr")).unwrap();
    let t10 = terrasketch_raster::read_heightmap(&all.join("w_x1_y0.exr")).unwrap();
    // Tile 0,0 is the south-west one: rows 112..256 of the world, columns 0..144.
    assert_eq!((t00.width, t00.height), (144, 144));
    for y in 0..100 {
        for x in 0..100 {
            assert_eq!(
                h.data[(144 + y) * 256 + x].to_bits(),
                t00.data[(32 + y) * 144 + x].to_bits()
            );
        }
    }
    // The overlap of 0,0 and 1,0 (world columns 112..144): both tiles make the same land
    // there up to detail (the coarse levels are shared), and the blend is continuous: no
    // east-west step across it is steeper than the land's steepest 1 % elsewhere.
    let (mut diff, mut relief) = (0.0f64, (f32::INFINITY, f32::NEG_INFINITY));
    for y in 0..144 {
        for x in 112..144 {
            let a = t00.data[y * 144 + x];
            let b = t10.data[y * 144 + (x - 112)];
            diff += f64::from((a - b) * (a - b));
        }
    }
    for v in &h.data {
        relief = (relief.0.min(*v), relief.1.max(*v));
    }
    let rms = (diff / (144.0 * 32.0)).sqrt();
    let relief = f64::from(relief.1 - relief.0);
    assert!(
        rms < 0.05 * relief,
        "overlap RMS {rms} m of {relief} m relief"
    );
    // The blend rule: across the overlap the stitched land is the smoothstep mix of the two
    // tiles (continuous at both edges of the overlap, where one tile's weight reaches 0).
    let mut differ = 0.0f32;
    for y in 32..144 {
        for x in 112..144 {
            let (a, b) = (t00.data[y * 144 + x], t10.data[y * 144 + (x - 112)]);
            let t = ((x - 112) as f32 + 0.5) / 32.0;
            let w = t * t * (3.0 - 2.0 * t);
            let want = (1.0 - w) * a + w * b;
            let got = h.data[(112 + y) * 256 + x];
            assert!(
                (got - want).abs() < 1e-3,
                "({x}, {y}): {got} m, blend {want} m"
            );
            differ = differ.max((a - b).abs());
        }
    }
    assert!(
        differ > 0.01,
        "the two tiles are equal in the overlap: the blend is untested"
    );
    let steps = |cols: std::ops::Range<usize>| -> Vec<f32> {
        (1..255)
            .flat_map(|y| {
                let h = &h;
                cols.clone()
                    .map(move |x| (h.data[y * 256 + x + 1] - h.data[y * 256 + x]).abs())
            })
            .collect()
    };
    let zone = steps(112..144).into_iter().fold(0.0f32, f32::max);
    let elsewhere = p99(steps(150..250));
    assert!(
        zone < 2.0 * elsewhere,
        "step {zone} m in the overlap, p99 {elsewhere} m elsewhere"
    );

    // Error paths: one line, status 2, nothing written.
    let bad_out = d.join("bad.exr");
    let bad_s = bad_out.to_str().unwrap();
    let refused = |o: &Output, what: &str| {
        common::assert_refused(o, what);
        assert!(!bad_out.exists(), "{what}: something was written");
    };
    refused(&run(&tile_args(bad_s, "2,0", cache, &[])), "outside");
    refused(&run(&tile_args(bad_s, "0,x", cache, &[])), "I,J");
    let mut big = tile_args(bad_s, "0,0", cache, &[]);
    big[7] = "100";
    refused(&run(&big), "more than half a tile");
    // A coarse file made with another seed.
    let o = run(&tile_args(
        bad_s,
        "0,0",
        cache,
        &["--coarse", coarse_s, "--seed", "2"],
    ));
    refused(&o, "seed");
    assert!(!d.join("bad_x0_y0.exr").exists());
    let junk = d.join("junk.coarse");
    std::fs::write(&junk, b"TSCOARSE\x05\0\0\0\0\0\0\0{}").unwrap();
    refused(
        &run(&tile_args(
            bad_s,
            "0,0",
            cache,
            &["--coarse", junk.to_str().unwrap()],
        )),
        "coarse-world file",
    );
    // Stitch: a missing tile, a tile of another seed, a changed or missing tile file.
    let copy = |name: &str| {
        let c = d.join(name);
        std::fs::create_dir(&c).unwrap();
        for e in std::fs::read_dir(&all).unwrap() {
            let p = e.unwrap().path();
            std::fs::copy(&p, c.join(p.file_name().unwrap())).unwrap();
        }
        c
    };
    let stitch = |m: &Path| run(&["stitch", m.to_str().unwrap(), "-o", bad_s]);
    let c = copy("missing");
    std::fs::remove_file(c.join("w_x1_y1.tile.json")).unwrap();
    refused(&stitch(&c), "tiles 1,1 of world w are missing");
    let c = copy("seed");
    let side = c.join("w_x0_y1.tile.json");
    let mut s: serde_json::Value = serde_json::from_slice(&std::fs::read(&side).unwrap()).unwrap();
    s["key"]["seed"] = serde_json::json!(7);
    std::fs::write(&side, serde_json::to_vec(&s).unwrap()).unwrap();
    refused(&stitch(&c), "seed");
    let c = copy("fine");
    let side = c.join("w_x0_y1.tile.json");
    let mut s: serde_json::Value = serde_json::from_slice(&std::fs::read(&side).unwrap()).unwrap();
    s["key"]["fine_detail"] = serde_json::json!(1.5);
    std::fs::write(&side, serde_json::to_vec(&s).unwrap()).unwrap();
    refused(&stitch(&c), "fine detail");
    let c = copy("size");
    let side = c.join("w_x0_y1.tile.json");
    let mut s: serde_json::Value = serde_json::from_slice(&std::fs::read(&side).unwrap()).unwrap();
    s["key"]["size"] = serde_json::json!(512);
    std::fs::write(&side, serde_json::to_vec(&s).unwrap()).unwrap();
    refused(&stitch(&c), "size");
    let c = copy("changed");
    std::fs::copy(c.join("w_x0_y0.exr"), c.join("w_x1_y0.exr")).unwrap();
    refused(&stitch(&c), "not the one its sidecar describes");
    let c = copy("gone");
    std::fs::remove_file(c.join("w_x0_y0.exr")).unwrap();
    refused(&stitch(&c), "cannot be read");
    refused(&stitch(&d.join("nowhere")), "does not exist");
}

/// A GeoTIFF world refined tile by tile at a corner-sampled size: every tile keeps the CRS, its
/// window's transform and the no-data cells, and the stitched world has the single refine's
/// CRS, transform, no-data samples and size.
#[test]
fn tiles_of_a_geotiff_keep_its_place_and_stitch_to_a_corner_sampled_size() {
    use tiff::tags::Tag;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cache = d.join("cache");
    let (cache, zurich) = (cache.to_str().unwrap(), exemplar("zurich_dhm25.tif"));
    let input = d.join("mercator.tif");
    let transform = vec![
        (Tag::ModelPixelScaleTag, vec![30.0, 30.0, 0.0]),
        (
            Tag::ModelTiepointTag,
            vec![0.0, 0.0, 0.0, 951_000.0, 6_003_000.0, 0.0],
        ),
    ];
    write_gis_tiff(&input, 128, &KEYS_3857, &transform);
    let (want, _) = geo_tags(&input);
    let refine = |extra: &[&str]| {
        let mut args = vec![
            "refine",
            input.to_str().unwrap(),
            "--exemplars",
            zurich.to_str().unwrap(),
            "--size",
            "129",
            "--patch-size",
            "16",
            "--cache-dir",
            cache,
        ];
        args.extend_from_slice(extra);
        let o = run(&args);
        assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
    };
    let single = d.join("single.tif");
    refine(&["-o", single.to_str().unwrap()]);
    let coarse = d.join("world.coarse");
    refine(&["--coarse-out", coarse.to_str().unwrap()]);
    let tiles = d.join("tiles");
    std::fs::create_dir(&tiles).unwrap();
    let world = tiles.join("w.tif");
    for tile in ["0,0", "1,0", "0,1", "1,1"] {
        refine(&[
            "--tiles",
            "2,2",
            "--overlap",
            "8",
            "--tile",
            tile,
            "--coarse",
            coarse.to_str().unwrap(),
            "-o",
            world.to_str().unwrap(),
        ]);
    }
    // Pixel-is-area: the model coordinates of pixel corner (i, j).
    let corner = |t: &GeoTags, i: f64, j: f64| -> [f64; 2] {
        let (s, p) = (t.scale.as_ref().unwrap(), t.tiepoints.as_ref().unwrap());
        [(i - p[0]) * s[0] + p[3], p[4] - (j - p[1]) * s[1]]
    };
    let close = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 1e-6 && (a[1] - b[1]).abs() < 1e-6;
    // Tile 1,0 (south-east) is cells 56..128 both ways of the 128-cell world, one input cell each.
    let (tile, tile_data) = geo_tags(&tiles.join("w_x1_y0.tif"));
    assert_eq!((&tile.keys, &tile.nodata), (&want.keys, &want.nodata));
    assert!(close(corner(&tile, 0.0, 0.0), corner(&want, 56.0, 56.0)));
    assert!(
        tile_data.iter().all(|&h| h != -9999.0),
        "no no-data cell there"
    );
    // Tile 0,1 (north-west) holds the input's no-data cell at row 10, column 20.
    let (tile, tile_data) = geo_tags(&tiles.join("w_x0_y1.tif"));
    assert!(close(corner(&tile, 0.0, 0.0), corner(&want, 0.0, 0.0)));
    assert_eq!(tile_data[10 * 72 + 20], -9999.0);
    assert_eq!(tile_data.iter().filter(|&&h| h == -9999.0).count(), 1);

    let stitched = d.join("stitched.tif");
    let o = run(&[
        "stitch",
        tiles.to_str().unwrap(),
        "-o",
        stitched.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["size"], 129, "{j}");
    let (got, data) = geo_tags(&stitched);
    let (single, single_data) = geo_tags(&single);
    assert_eq!((&got.keys, &got.nodata), (&want.keys, &want.nodata));
    assert_eq!(data.len(), 129 * 129);
    for (i, j) in [(0.0, 0.0), (128.0, 128.0), (17.0, 40.0)] {
        assert!(
            close(corner(&got, i, j), corner(&single, i, j)),
            "sample corner ({i}, {j})"
        );
    }
    let holes = |v: &[f32]| -> Vec<usize> { (0..v.len()).filter(|&k| v[k] == -9999.0).collect() };
    assert_eq!(
        holes(&data),
        holes(&single_data),
        "the same no-data samples"
    );
    assert_eq!(holes(&data), vec![10 * 129 + 20]);
    // The same land as the single refine, up to the tiles' own detail.
    let (mut diff, mut lo, mut hi) = (0.0f64, f32::INFINITY, f32::NEG_INFINITY);
    for (a, b) in data
        .iter()
        .zip(&single_data)
        .filter(|(a, _)| **a != -9999.0)
    {
        diff += f64::from(a - b).powi(2);
        (lo, hi) = (lo.min(*b), hi.max(*b));
    }
    let rms = (diff / (data.len() - 1) as f64).sqrt();
    assert!(
        rms < 0.1 * f64::from(hi - lo),
        "RMS {rms} m of {} m",
        hi - lo
    );
}
