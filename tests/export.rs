//! End-to-end tests of the engine-ready outputs of the `terrasketch` binary: tiled rasters,
//! meshes (read back with the `gltf` crate) and masks of analytic terrains.

mod common;

use std::path::{Path, PathBuf};

use common::*;

/// Runs `solve GOOD --size 257 --tiles 4,4` with `extra` arguments into `dir/world.EXT`.
fn tiled(dir: &Path, ext: &str, extra: &[&str]) -> serde_json::Value {
    let sketch = write(dir, "s.json", GOOD);
    let out = dir.join(format!("world.{ext}"));
    let mut args = vec![
        "solve",
        sketch.to_str().unwrap(),
        "--size",
        "257",
        "--tiles",
        "4,4",
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = run(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!out.exists(), "tiles only, no single file");
    let text = std::fs::read_to_string(dir.join("world.tiles.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// The manifest's tiles read back, with their windows.
fn read_tiles(
    dir: &Path,
    manifest: &serde_json::Value,
) -> Vec<(usize, usize, [usize; 4], terrasketch_raster::Heightmap)> {
    let tiles = manifest["tiles"].as_array().unwrap();
    tiles
        .iter()
        .map(|t| {
            let u = |k: &str| t[k].as_u64().unwrap() as usize;
            let map =
                terrasketch_raster::read_heightmap(&dir.join(t["file"].as_str().unwrap())).unwrap();
            assert_eq!((map.width, map.height), (u("width"), u("height")));
            (
                u("i"),
                u("j"),
                [u("column"), u("row"), u("width"), u("height")],
                map,
            )
        })
        .collect()
}

#[test]
fn tiled_export_shares_bit_identical_edges_and_stitches_back() {
    let dir = tempfile::tempdir().unwrap();
    let sketch = write(dir.path(), "s.json", GOOD);
    let single = dir.path().join("single.exr");
    let o = run(&[
        "solve",
        sketch.to_str().unwrap(),
        "--size",
        "257",
        "-o",
        single.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let single = terrasketch_raster::read_heightmap(&single).unwrap();

    for (ext, overlap) in [("exr", "0"), ("tif", "3"), ("png", "0")] {
        let sub = dir.path().join(format!("{ext}{overlap}"));
        std::fs::create_dir(&sub).unwrap();
        let manifest = tiled(&sub, ext, &["--overlap", overlap]);
        assert_eq!(manifest["sampling"], "corners");
        assert_eq!(manifest["extent_m"], serde_json::json!([6400.0, 6400.0]));
        let tiles = read_tiles(&sub, &manifest);
        assert_eq!(tiles.len(), 16);
        assert!(sub.join("world_x3_y0.".to_owned() + ext).exists());
        // Stitched back: every tile sample equals the world's at its window (within the PNG's
        // quantisation for the 16-bit format; exact for EXR and TIFF).
        let mut covered = vec![false; 257 * 257];
        for (_, _, [c0, r0, w, h], map) in &tiles {
            for r in 0..*h {
                for c in 0..*w {
                    let want = single.data[(r0 + r) * 257 + c0 + c];
                    let got = map.data[r * w + c];
                    if ext == "png" {
                        assert!((want - got).abs() <= 0.02, "{ext}: {want} vs {got}");
                    } else {
                        assert_eq!(want.to_bits(), got.to_bits(), "{ext} ({r0}+{r}, {c0}+{c})");
                    }
                    covered[(r0 + r) * 257 + c0 + c] = true;
                }
            }
        }
        assert!(
            covered.iter().all(|&c| c),
            "{ext}: the tiles cover the world"
        );
        // Shared edges: the east column of tile (i, j) is the west column of (i + 1, j), the
        // north row of (i, j) the south row of (i, j + 1), bit for bit (the PNG's codes too).
        let at = |i: usize, j: usize| tiles.iter().find(|t| t.0 == i && t.1 == j).unwrap();
        let ov: usize = overlap.parse().unwrap();
        for j in 0..4 {
            for i in 0..4 {
                let (_, _, [c0, r0, w, h], a) = at(i, j);
                if i < 3 {
                    let (_, _, [c1, _, w1, _], b) = at(i + 1, j);
                    // The world column both hold: the west tile's core edge.
                    let col = c0 + w - 1 - ov;
                    for r in 0..*h {
                        assert_eq!(
                            a.data[r * w + col - c0].to_bits(),
                            b.data[r * w1 + col - c1].to_bits()
                        );
                    }
                }
                if j < 3 {
                    let (_, _, [_, r1, _, h1], b) = at(i, j + 1);
                    // The world row both hold: the south tile's core north edge.
                    let row = r0 + ov;
                    assert!(row >= *r1 && row < r1 + h1);
                    let a_row = &a.data[(row - r0) * w..(row - r0 + 1) * w];
                    let b_row = &b.data[(row - r1) * w..(row - r1 + 1) * w];
                    let bits = |s: &[f32]| s.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(a_row), bits(b_row), "{ext} rows of ({i},{j})");
                }
            }
        }
    }
}

#[test]
fn bad_tile_requests_are_refused_before_solving() {
    let dir = tempfile::tempdir().unwrap();
    let sketch = write(dir.path(), "s.json", GOOD);
    let s = sketch.to_str().unwrap();
    let out = dir.path().join("w.exr");
    let o = out.to_str().unwrap();
    let cases: [(&[&str], &str); 4] = [
        (&["--size", "257", "--tiles", "3,4"], "--tiles"),
        (&["--size", "257", "--tiles", "4"], "--tiles"),
        (
            &["--size", "257", "--tiles", "4,4", "--overlap", "100"],
            "--overlap",
        ),
        (
            &["--size", "257", "--tiles", "4,4", "--tile-name", "t.exr"],
            "--tile-name",
        ),
    ];
    for (extra, field) in cases {
        let mut args = vec!["solve", s, "-o", o];
        args.extend_from_slice(extra);
        assert_refused(&run(&args), field);
    }
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "only the sketch"
    );
}

/// What a test reads from a GLB: positions, normals, indices and the POSITION accessor's bounds.
type GlbMesh = (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<u32>, [[f32; 3]; 2]);

/// A GLB's triangles, read by the `gltf` crate (which validates the document).
fn read_glb(path: &Path) -> GlbMesh {
    let bytes = std::fs::read(path).unwrap();
    let glb = gltf::Gltf::from_slice(&bytes).expect("a valid glTF 2.0 binary");
    let blob = glb.blob.clone().expect("a binary chunk");
    let mesh = glb.document.meshes().next().expect("one mesh");
    let prim = mesh.primitives().next().expect("one primitive");
    assert_eq!(prim.mode(), gltf::mesh::Mode::Triangles);
    let bb = prim.bounding_box();
    let reader = prim.reader(|_| Some(&blob[..]));
    let positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
    let normals: Vec<[f32; 3]> = reader.read_normals().unwrap().collect();
    let indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
    (positions, normals, indices, [bb.min, bb.max])
}

#[test]
fn glb_mesh_loads_with_its_bounds_and_simplifies_within_the_error_bound() {
    let dir = tempfile::tempdir().unwrap();
    // The pure diffusion: the simplification ratio below is a property of smooth land.
    let heights = solve_example_with(dir.path(), 1025, "exr", &["--detail", "off"]);
    let (lo, hi) = heights
        .data
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &h| {
            (a.min(h), b.max(h))
        });
    let mesh = |name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let mut args = vec![
            "solve",
            concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/range.json"),
            "--size",
            "1024",
            "--detail",
            "off",
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let o = run(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        read_glb(&out)
    };
    let (positions, normals, indices, bounds) = mesh("grid.glb", &[]);
    assert_eq!(indices.len() / 3, 2 * 1024 * 1024);
    assert_eq!(positions.len(), 1025 * 1025);
    assert_eq!(bounds, [[0.0, lo, -10240.0], [10240.0, hi, 0.0]]);
    for n in &normals {
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-5 && n[1] > 0.0, "{n:?}");
    }

    let (positions, _, indices, bounds) = mesh("simple.glb", &["--max-error", "1"]);
    let triangles = indices.len() / 3;
    assert!(triangles * 5 <= 2 * 1024 * 1024, "{triangles} triangles");
    assert_eq!(bounds[0][0], 0.0);
    assert_eq!(bounds[1][0], 10240.0);
    // Every sample lies within 1 m of the triangle above or below it; the triangles face up
    // and tile the extent exactly once.
    let mut worst = 0.0f64;
    let mut area = 0.0f64;
    for t in indices.chunks_exact(3) {
        let p = [t[0], t[1], t[2]].map(|i| positions[i as usize]);
        // Grid coordinates: column = x / 10, row = 1024 + z / 10.
        let g = p.map(|v| {
            (
                (v[0] / 10.0).round() as i64,
                (1024.0 + v[2] / 10.0).round() as i64,
            )
        });
        let twice = (g[1].0 - g[0].0) * (g[2].1 - g[0].1) - (g[2].0 - g[0].0) * (g[1].1 - g[0].1);
        assert!(twice < 0, "triangle faces down: {p:?}");
        area += (twice.abs() as f64) / 2.0;
        let (c_lo, c_hi) = (
            g.iter().map(|v| v.0).min().unwrap(),
            g.iter().map(|v| v.0).max().unwrap(),
        );
        let (r_lo, r_hi) = (
            g.iter().map(|v| v.1).min().unwrap(),
            g.iter().map(|v| v.1).max().unwrap(),
        );
        for r in r_lo..=r_hi {
            for c in c_lo..=c_hi {
                let w0 = (g[1].0 - c) * (g[2].1 - r) - (g[2].0 - c) * (g[1].1 - r);
                let w1 = (g[2].0 - c) * (g[0].1 - r) - (g[0].0 - c) * (g[2].1 - r);
                let w2 = twice - w0 - w1;
                if w0 <= 0 && w1 <= 0 && w2 <= 0 {
                    let z = (w0 as f64 * f64::from(p[0][1])
                        + w1 as f64 * f64::from(p[1][1])
                        + w2 as f64 * f64::from(p[2][1]))
                        / twice as f64;
                    let h = f64::from(heights.data[r as usize * 1025 + c as usize]);
                    worst = worst.max((z - h).abs());
                }
            }
        }
    }
    assert_eq!(area, 1024.0 * 1024.0, "the triangles tile the extent");
    assert!(worst <= 1.0 + 1e-3, "vertical error {worst} m");
    eprintln!("simplified: {triangles} triangles, vertical error {worst:.6} m");
}

#[test]
fn obj_mesh_and_bad_mesh_requests() {
    let dir = tempfile::tempdir().unwrap();
    let sketch = write(dir.path(), "s.json", GOOD);
    let s = sketch.to_str().unwrap();
    let obj = dir.path().join("t.obj");
    let o = run(&["solve", s, "--size", "64", "-o", obj.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&obj).unwrap();
    assert_eq!(
        text.lines().filter(|l| l.starts_with("v ")).count(),
        65 * 65
    );
    assert_eq!(
        text.lines().filter(|l| l.starts_with("vn ")).count(),
        65 * 65
    );
    assert_eq!(
        text.lines().filter(|l| l.starts_with("f ")).count(),
        2 * 64 * 64
    );
    let glb = dir.path().join("t.glb");
    let g = glb.to_str().unwrap();
    let exr = dir.path().join("t.exr");
    let cases: [(&[&str], &str); 5] = [
        (
            &[
                "--size",
                "64",
                "--max-error",
                "1",
                "-o",
                exr.to_str().unwrap(),
            ],
            "--max-error",
        ),
        (&["--size", "64", "--max-error=-1", "-o", g], "--max-error"),
        (
            &["--size", "100", "--max-error", "1", "-o", g],
            "--max-error",
        ),
        (&["--size", "8192", "-o", g], "4097"),
        (&["--size", "65", "--tiles", "2,2", "-o", g], "--tiles"),
    ];
    for (extra, field) in cases {
        let mut args = vec!["solve", s];
        args.extend_from_slice(extra);
        assert_refused(&run(&args), field);
    }
    assert!(!glb.exists() && !exr.exists());
}

/// Writes a `n x n` EXR heightmap of `f(x, y)` (x east, y north, metres; 10 m cells, north-up).
fn analytic(dir: &Path, name: &str, n: usize, f: impl Fn(f64, f64) -> f64) -> PathBuf {
    let mut data = Vec::with_capacity(n * n);
    for r in 0..n {
        for c in 0..n {
            data.push(f(c as f64 * 10.0, (n - 1 - r) as f64 * 10.0) as f32);
        }
    }
    let path = dir.join(name);
    let map = terrasketch_raster::Heightmap {
        width: n,
        height: n,
        data,
        cell_size_m: [10.0, 10.0],
    };
    terrasketch_raster::write_heightmap(&path, &map).unwrap();
    path
}

/// Runs `masks IN -o DIR` with `extra` arguments and returns DIR.
fn masks(input: &Path, dir: &Path, extra: &[&str]) -> PathBuf {
    let out = dir.join(format!(
        "{}-masks",
        input.file_stem().unwrap().to_str().unwrap()
    ));
    let mut args = vec![
        "masks",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = run(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    out
}

fn png8(path: &Path) -> Vec<u8> {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    buf.truncate(info.buffer_size());
    buf
}

#[test]
fn masks_of_planes_are_their_analytic_values() {
    let dir = tempfile::tempdir().unwrap();
    // Rising to the south-east at 45 degrees: facing the sun at azimuth 315, altitude 45.
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let plane = analytic(dir.path(), "plane.exr", 17, |x, y| s * (x - y) + 500.0);
    let out = masks(&plane, dir.path(), &["--format", "exr"]);
    let read = |name: &str| {
        terrasketch_raster::read_heightmap(&out.join(name))
            .unwrap()
            .data
    };
    for (i, v) in read("slope.exr").iter().enumerate() {
        assert!((v - 45.0).abs() < 1e-3, "slope at {i}: {v}");
    }
    assert!(read("curvature.exr").iter().all(|v| v.abs() < 1e-6));
    assert!(png8(&out.join("hillshade.png")).iter().all(|&v| v == 255));
    let height = read("height.exr");
    let (lo, hi) = height
        .iter()
        .fold((1.0f32, 0.0f32), |(a, b), &v| (a.min(v), b.max(v)));
    assert_eq!((lo, hi), (0.0, 1.0));
    let listed: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("masks.json")).unwrap()).unwrap();
    assert_eq!(listed["masks"].as_array().unwrap().len(), 5);

    // Flat ground: slope 0, lit at the sun's altitude, 255 * sin(45) = 180.
    let flat = analytic(dir.path(), "flat.exr", 9, |_, _| 7.0);
    let out = masks(&flat, dir.path(), &[]);
    assert!(png8(&out.join("hillshade.png")).iter().all(|&v| v == 180));
    let slope = terrasketch_raster::read_heightmap(&out.join("slope.png")).unwrap();
    assert!(slope.data.iter().all(|&v| v == 0.0));

    // Falling to the east: D8 sends every sample east, so column c gathers c + 1 samples.
    let ramp = analytic(dir.path(), "ramp.exr", 12, |x, _| 1000.0 - x);
    let out = masks(&ramp, dir.path(), &["--format", "exr"]);
    let flow = terrasketch_raster::read_heightmap(&out.join("flow.exr")).unwrap();
    for r in 0..12 {
        for c in 0..12 {
            assert_eq!(flow.data[r * 12 + c], (c + 1) as f32, "({r}, {c})");
        }
    }
}

#[test]
fn masks_of_cones_drain_and_curve_as_they_should() {
    let dir = tempfile::tempdir().unwrap();
    let n = 33;
    let centre = 160.0;
    let r = |x: f64, y: f64| ((x - centre).powi(2) + (y - centre).powi(2)).sqrt();
    // A funnel (inverted cone): every sample drains to the centre.
    let funnel = analytic(dir.path(), "funnel.exr", n, |x, y| 100.0 + r(x, y));
    let out = masks(&funnel, dir.path(), &["--format", "exr"]);
    let flow = terrasketch_raster::read_heightmap(&out.join("flow.exr")).unwrap();
    assert_eq!(flow.data[16 * n + 16], (n * n) as f32);
    // A paraboloid hill: mean curvature at the top is -(r + t) / 2 = 1 / a for h = -(x^2 + y^2) / (2a).
    let a = 200.0;
    let hill = analytic(dir.path(), "hill.exr", n, |x, y| {
        500.0 - r(x, y).powi(2) / (2.0 * a)
    });
    let out = masks(&hill, dir.path(), &["--format", "exr"]);
    let curvature = terrasketch_raster::read_heightmap(&out.join("curvature.exr")).unwrap();
    let top = curvature.data[16 * n + 16];
    assert!((f64::from(top) - 1.0 / a).abs() < 1e-6, "curvature {top}");
    // A peak sheds its flow: the top drains nothing but itself.
    let flow = terrasketch_raster::read_heightmap(&out.join("flow.exr")).unwrap();
    assert_eq!(flow.data[16 * n + 16], 1.0);
    // PNG: the flow is ln(accumulation) over [0, ln(n^2)].
    let out = masks(&funnel, dir.path(), &[]);
    let flow = terrasketch_raster::read_heightmap(&out.join("flow.png")).unwrap();
    let centre_ln = flow.data[16 * n + 16];
    assert!((f64::from(centre_ln) - ((n * n) as f64).ln()).abs() < 1e-3);
}

#[test]
fn masks_refuse_bad_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let tiny = analytic(dir.path(), "tiny.exr", 2, |_, _| 0.0);
    let out = dir.path().join("m");
    assert_refused(
        &run(&["masks", tiny.to_str().unwrap(), "-o", out.to_str().unwrap()]),
        "3 x 3",
    );
    let ok = analytic(dir.path(), "ok.exr", 8, |x, _| x);
    assert_refused(
        &run(&[
            "masks",
            ok.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--cell-size",
            "0.001",
        ]),
        "--cell-size",
    );
    let file = write(dir.path(), "file", "x");
    assert_refused(
        &run(&["masks", ok.to_str().unwrap(), "-o", file.to_str().unwrap()]),
        "not a folder",
    );
}
