//! The realism pass: constraints kept, determinism, max-flow against brute force, gradient-domain
//! merging, pit removal, Scott & Dodgson's reconstruction protocol, the feature cache.

mod common;

use std::sync::atomic::AtomicBool;

use terrasketch_raster::Heightmap;
use terrasketch_synthesis::metrics::{compare, terrain_metrics};
use terrasketch_synthesis::refine::field::{Field, downsample, to_exemplar, to_target, upsample};
use terrasketch_synthesis::refine::graphcut::FlowGraph;
use terrasketch_synthesis::refine::merge::poisson;
use terrasketch_synthesis::refine::{
    ExFields, NO_OWNER, Placed, PreparedExemplar, RefineInput, RefineOutput, RefineParams,
    assemble_gradients, prepare_exemplars, refine,
};
use terrasketch_synthesis::{Dem, LoadOptions, load_dem, shipped_exemplar_dir};

fn shipped(name: &str) -> Dem {
    load_dem(&shipped_exemplar_dir().join(name), &LoadOptions::default()).unwrap()
}

fn prepared(names: &[&str], cell: f64) -> Vec<PreparedExemplar> {
    let dems: Vec<Dem> = names.iter().map(|n| shipped(n)).collect();
    prepare_exemplars(&dems, cell, None, &|_, _| {}).unwrap()
}

/// A smooth synthetic range: a Gaussian ridge running diagonally on a tilted plane.
fn smooth_target(n: usize, cell: f64) -> Vec<f32> {
    (0..n * n)
        .map(|i| {
            let (x, y) = ((i % n) as f32, (i / n) as f32);
            let d = (x - y) / n as f32;
            300.0 + 600.0 * (-d * d * 30.0).exp() + 0.5 * x * cell as f32 / 10.0
        })
        .collect()
}

fn run(input: &RefineInput, ex: &[PreparedExemplar], params: &RefineParams) -> RefineOutput {
    refine(input, ex, params, &|_, _| {}, &AtomicBool::new(false)).unwrap()
}

fn sketch_like_input(n: usize, cell: f64) -> RefineInput {
    let data = smooth_target(n, cell);
    // Constraints: the ridge crest and a point in the south-east, as a sketch's strokes give.
    let mut mask = vec![false; n * n];
    for t in 8..n - 8 {
        mask[t * n + t] = true;
    }
    mask[(n - 20) * n + n - 30] = true;
    let values = data.clone();
    RefineInput {
        target: Heightmap {
            width: n,
            height: n,
            data,
            cell_size_m: [cell; 2],
        },
        constraint_mask: Some(mask),
        constraint_values: Some(values),
        roughness: Some(vec![0.7; n * n]),
        sinks: None,
        constraint_tolerance: None,
    }
}

fn small_params(seed: u64) -> RefineParams {
    RefineParams {
        seed,
        patch_size: 32,
        sites_per_exemplar: 300,
        feature_sites_per_exemplar: 100,
        ..RefineParams::default()
    }
}

#[test]
fn refine_keeps_constraints_and_is_deterministic() {
    let (n, cell) = (128, 60.0);
    let ex = prepared(&["jacksboro_fault_srtm3.tif", "zurich_dhm25.tif"], cell);
    let input = sketch_like_input(n, cell);
    let a = run(&input, &ex, &small_params(7));
    assert!(a.heights.data.iter().all(|v| v.is_finite()));
    let mask = input.constraint_mask.as_ref().unwrap();
    let values = input.constraint_values.as_ref().unwrap();
    let (lo, hi) = values
        .iter()
        .zip(mask)
        .filter(|(_, m)| **m)
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), (v, _)| {
            (l.min(*v), h.max(*v))
        });
    let relief = hi - lo;
    for i in (0..n * n).filter(|&i| mask[i]) {
        let err = (a.heights.data[i] - values[i]).abs();
        assert!(
            err <= 1e-3 * relief,
            "cell {i}: error {err} m, relief {relief}"
        );
    }
    assert!(a.stats.constraint_max_error_m <= 1e-3 * f64::from(relief));
    assert!(a.stats.patches_fill > 0);
    // The output is not the input: detail was added away from the constraints.
    let changed = a
        .heights
        .data
        .iter()
        .zip(&input.target.data)
        .filter(|(x, y)| (*x - *y).abs() > 1.0)
        .count();
    assert!(changed > n * n / 4, "only {changed} cells changed");
    let b = run(&input, &ex, &small_params(7));
    assert!(
        a.heights
            .data
            .iter()
            .zip(&b.heights.data)
            .all(|(x, y)| x.to_bits() == y.to_bits()),
        "same seed must give the same bits"
    );
    let c = run(&input, &ex, &small_params(8));
    let differ = a
        .heights
        .data
        .iter()
        .zip(&c.heights.data)
        .filter(|(x, y)| x != y)
        .count();
    assert!(
        differ > n * n / 10,
        "another seed changed only {differ} cells"
    );
}

/// Minimum cut by enumerating every source set (small graphs only).
fn brute_min_cut(n: usize, edges: &[(usize, usize, f64)], src: &[f64], snk: &[f64]) -> f64 {
    (0u32..1 << n)
        .map(|set| {
            let ins = |a: usize| set >> a & 1 == 1;
            let mut c = 0.0;
            for a in 0..n {
                c += if ins(a) { snk[a] } else { src[a] };
            }
            for &(a, b, w) in edges {
                if ins(a) && !ins(b) {
                    c += w;
                }
            }
            c
        })
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn max_flow_equals_brute_force_min_cut() {
    let mut state = 12345u64;
    let mut rnd = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 33) as f64) / (1u64 << 31) as f64
    };
    for trial in 0..200 {
        let n = 2 + trial % 9;
        let mut edges = Vec::new();
        let mut g = FlowGraph::new(n);
        for a in 0..n {
            for b in 0..n {
                if a != b && rnd() < 0.4 {
                    let w = (rnd() * 10.0).floor();
                    edges.push((a, b, w));
                    g.add_edge(a, b, w, 0.0);
                }
            }
        }
        let src: Vec<f64> = (0..n)
            .map(|_| {
                if rnd() < 0.5 {
                    (rnd() * 10.0).floor()
                } else {
                    0.0
                }
            })
            .collect();
        let snk: Vec<f64> = (0..n)
            .map(|_| {
                if rnd() < 0.5 {
                    (rnd() * 10.0).floor()
                } else {
                    0.0
                }
            })
            .collect();
        for a in 0..n {
            g.add_terminals(a, src[a], snk[a]);
        }
        let flow = g.max_flow();
        let want = brute_min_cut(n, &edges, &src, &snk);
        assert!(
            (flow - want).abs() < 1e-9,
            "trial {trial}: flow {flow}, min cut {want}"
        );
        // The reported side is a cut of that capacity.
        let side = g.source_side();
        let mut c = 0.0;
        for a in 0..n {
            c += if side[a] { snk[a] } else { src[a] };
        }
        for &(a, b, w) in &edges {
            if side[a] && !side[b] {
                c += w;
            }
        }
        assert!(
            (c - want).abs() < 1e-9,
            "trial {trial}: side cut {c}, min cut {want}"
        );
    }
}

#[test]
fn graph_cut_on_a_toy_overlap_follows_the_cheap_column() {
    // A 6 x 4 overlap: column 0 tied to the old patch, column 5 to the new one; horizontal
    // edges cost 5 except between columns 3 and 4 (cost 1): the cut must take that column.
    let (w, h) = (6, 4);
    let mut g = FlowGraph::new(w * h);
    for y in 0..h {
        g.add_terminals(y * w, 0.0, 1e30);
        g.add_terminals(y * w + w - 1, 1e30, 0.0);
        for x in 0..w - 1 {
            let c = if x == 3 { 1.0 } else { 5.0 };
            g.add_edge(y * w + x, y * w + x + 1, c, c);
        }
        if y + 1 < h {
            for x in 0..w {
                g.add_edge(y * w + x, (y + 1) * w + x, 3.0, 3.0);
            }
        }
    }
    assert!((g.max_flow() - 4.0).abs() < 1e-9);
    let side = g.source_side();
    for y in 0..h {
        for x in 0..w {
            assert_eq!(side[y * w + x], x >= 4, "({x}, {y})");
        }
    }
}

#[test]
fn gradient_merge_of_two_patches_of_one_surface_reproduces_it() {
    let n = 64;
    // One smooth surface as the exemplar's detail; two patches cut from it at matching
    // places, owners split along a wavy seam.
    let surf = |x: f32, y: f32| 40.0 * (x * 0.11).sin() * (y * 0.07).cos() + 0.8 * x - 0.3 * y;
    // Both patches use transform 0 (a rotation by 22.5 degrees) and map output cells to the
    // exemplar through one common frame: exemplar e = C0 + R (o - P0).
    let (ew, eh) = (160, 160);
    let (c0, p0) = ([80.0f32, 80.0f32], [32.0f32, 32.0f32]);
    let band = Field::new(
        ew,
        eh,
        (0..ew * eh)
            .map(|i| {
                let (u, v) = to_target(0, (i % ew) as f32 - c0[0], (i / ew) as f32 - c0[1]);
                surf(p0[0] + u, p0[1] + v)
            })
            .collect(),
    );
    let fields = vec![ExFields {
        mid: band.clone(),
        band,
    }];
    let at = |p: [i32; 2]| {
        let (a, b) = to_exemplar(0, p[0] as f32 - p0[0], p[1] as f32 - p0[1]);
        Placed {
            ex: 0,
            k: 0,
            c: [c0[0] + a, c0[1] + b],
            p,
            gain: 1.0,
        }
    };
    let placed = vec![at([16, 32]), at([48, 32])];
    let half = 32;
    let mut owner = vec![NO_OWNER; n * n];
    let mut dout = vec![0.0f32; n * n];
    for y in 0..n {
        let seam = 30 + (4.0 * (y as f32 * 0.3).sin()) as usize;
        for x in 0..n {
            owner[y * n + x] = u32::from(x >= seam);
            dout[y * n + x] = surf(x as f32, y as f32);
        }
    }
    let low = Field::new(n, n, vec![0.0; n * n]);
    let (de, dn) = assemble_gradients(n, half, &owner, &dout, &placed, &fields, &low);
    let mut weight = vec![0.0f32; n * n];
    let mut value = vec![0.0f32; n * n];
    weight[0] = 1.0;
    value[0] = surf(0.0, 0.0);
    let h = poisson(n, weight, value, de, dn, 1e-7);
    // The rotated patches are sampled bilinearly: with a curvature of up to 0.5 m per cell^2
    // that alone errs by about 0.06 m (of a 40 m relief).
    for y in 0..n {
        for x in 0..n {
            let err = (h[y * n + x] - surf(x as f32, y as f32)).abs();
            assert!(err < 0.1, "({x}, {y}): {err}");
        }
    }
}

#[test]
fn pits_are_removed_from_a_pitted_field() {
    let (n, cell) = (128, 60.0);
    let mut data = smooth_target(n, cell);
    // Twelve 150 m deep pits.
    for k in 0..12 {
        let (cx, cy) = (15 + (k % 4) * 30, 20 + (k / 4) * 40);
        for y in cy - 4..=cy + 4 {
            for x in cx - 4..=cx + 4 {
                let d2 = ((x as f32 - cx as f32).powi(2) + (y as f32 - cy as f32).powi(2)) / 9.0;
                data[y * n + x] -= 150.0 * (-d2).exp();
            }
        }
    }
    let before = terrasketch_synthesis::pits::count_pits(&data, n, n, None, 10.0);
    assert!(before >= 9, "the field has {before} pits");
    let input = RefineInput::target_only(n, cell, data);
    let ex = prepared(&["jacksboro_fault_srtm3.tif"], cell);
    let out = run(&input, &ex, &small_params(3));
    assert_eq!(out.stats.pits_after, 0);
    assert_eq!(
        terrasketch_synthesis::pits::count_pits(&out.heights.data, n, n, None, 0.0),
        0,
        "no interior pit of any depth is left"
    );
}

#[test]
fn scott_dodgson_reconstruction_is_closer_to_the_real_dem_than_its_target() {
    // Real DEM: a 256 x 256 window of the Sierra Nevada at 92 m cells.
    let (n, cell) = (256, 92.0);
    let sierra = terrasketch_synthesis::resample_to_cell_size(
        &shipped("sierra_nevada_north_srtm3.tif"),
        cell,
    )
    .unwrap();
    let (x0, y0) = ((sierra.width - n) / 2, (sierra.height - n) / 2);
    let real: Vec<f32> = (0..n * n)
        .map(|i| sierra.heights_m[(y0 + i / n) * sierra.width + x0 + i % n])
        .collect();
    let real_f = Field::new(n, n, real.clone());
    let target = upsample(&downsample(&real_f, 16), 16, n, n).v;
    let ex = prepared(
        &[
            "jacksboro_fault_srtm3.tif",
            "grand_canyon_terrarium_z11.png",
            "zurich_dhm25.tif",
            "kossou_plains_srtm3.tif",
        ],
        cell,
    );
    let input = RefineInput::target_only(n, cell, target.clone());
    let params = RefineParams {
        patch_size: 32,
        ..RefineParams::default()
    };
    let out = run(&input, &ex, &params);
    let m_real = terrain_metrics(&real, n, n, [cell; 2]);
    let m_target = terrain_metrics(&target, n, n, [cell; 2]);
    let m_out = terrain_metrics(&out.heights.data, n, n, [cell; 2]);
    let (c_t, c_o) = (compare(&m_target, &m_real), compare(&m_out, &m_real));
    assert!(
        c_o.slope_wasserstein_deg < c_t.slope_wasserstein_deg,
        "slope W1 to the real DEM: output {} vs target {}",
        c_o.slope_wasserstein_deg,
        c_t.slope_wasserstein_deg
    );
    let (st, so) = (
        c_t.spectral_slope_diff.unwrap().abs(),
        c_o.spectral_slope_diff.unwrap().abs(),
    );
    assert!(
        so < st,
        "spectral slope difference: output {so} vs target {st}"
    );
}

#[test]
fn feature_cache_skips_extraction_and_survives_corruption() {
    let dir = common::ScratchDir::new("refine-cache");
    let dems = vec![shipped("zurich_dhm25.tif")];
    let first = prepare_exemplars(&dems, 40.0, Some(&dir.0), &|_, _| {}).unwrap();
    assert!(!first[0].features_from_cache);
    assert!(!first[0].features.is_empty());
    let second = prepare_exemplars(&dems, 40.0, Some(&dir.0), &|_, _| {}).unwrap();
    assert!(
        second[0].features_from_cache,
        "second run must read the cache"
    );
    assert_eq!(second[0].features, first[0].features);
    assert_eq!(second[0].pits_deep, first[0].pits_deep);
    // Corrupt every cache file: recomputed, same result, and the cache is repaired.
    for e in std::fs::read_dir(&dir.0).unwrap() {
        let p = e.unwrap().path();
        let mut b = std::fs::read(&p).unwrap();
        let mid = b.len() / 2;
        b[mid] ^= 0xff;
        std::fs::write(&p, b).unwrap();
    }
    let third = prepare_exemplars(&dems, 40.0, Some(&dir.0), &|_, _| {}).unwrap();
    assert!(!third[0].features_from_cache);
    assert!(third[0].cache_warning.is_some());
    assert_eq!(third[0].features, first[0].features);
    let fourth = prepare_exemplars(&dems, 40.0, Some(&dir.0), &|_, _| {}).unwrap();
    assert!(fourth[0].features_from_cache);
}

#[test]
fn bad_inputs_are_refused() {
    let ex = prepared(&["zurich_dhm25.tif"], 40.0);
    let mut input = sketch_like_input(64, 40.0);
    input.target.width = 60;
    let r = refine(
        &input,
        &ex,
        &small_params(1),
        &|_, _| {},
        &AtomicBool::new(false),
    );
    assert!(r.is_err());
    let mut input = sketch_like_input(64, 40.0);
    input.roughness = Some(vec![0.5; 10]);
    assert!(
        refine(
            &input,
            &ex,
            &small_params(1),
            &|_, _| {},
            &AtomicBool::new(false)
        )
        .is_err()
    );
    let input = sketch_like_input(64, 40.0);
    assert!(
        refine(
            &input,
            &[],
            &small_params(1),
            &|_, _| {},
            &AtomicBool::new(false)
        )
        .is_err()
    );
    for gain in [f32::NAN, -0.5, 5.0, f32::INFINITY] {
        let p = RefineParams {
            fine_detail: gain,
            ..small_params(1)
        };
        match refine(&input, &ex, &p, &|_, _| {}, &AtomicBool::new(false)) {
            Err(e) => assert!(e.to_string().contains("fine detail"), "{e}"),
            Ok(_) => panic!("fine detail gain {gain} was accepted"),
        }
    }
    let cancelled = refine(
        &input,
        &ex,
        &small_params(1),
        &|_, _| {},
        &AtomicBool::new(true),
    );
    assert!(matches!(
        cancelled,
        Err(terrasketch_synthesis::refine::RefineError::Cancelled)
    ));
}

#[test]
fn marked_sinks_are_kept() {
    let (n, cell) = (128, 60.0);
    let mut data = smooth_target(n, cell);
    // A wide 200 m deep lake basin in the south-west, marked as a sink at its centre.
    let (cx, cy) = (30usize, 96usize);
    for y in cy - 14..=cy + 14 {
        for x in cx - 14..=cx + 14 {
            let d2 = ((x as f32 - cx as f32).powi(2) + (y as f32 - cy as f32).powi(2)) / 40.0;
            data[y * n + x] -= 200.0 * (-d2).exp();
        }
    }
    let mut sinks = vec![false; n * n];
    for y in cy - 1..=cy + 1 {
        for x in cx - 1..=cx + 1 {
            sinks[y * n + x] = true;
        }
    }
    let input = RefineInput {
        target: Heightmap {
            width: n,
            height: n,
            data,
            cell_size_m: [cell; 2],
        },
        constraint_mask: None,
        constraint_values: None,
        roughness: None,
        sinks: Some(sinks.clone()),
        constraint_tolerance: None,
    };
    let ex = prepared(&["jacksboro_fault_srtm3.tif"], cell);
    let out = run(&input, &ex, &small_params(5));
    let h = &out.heights.data;
    assert_eq!(out.stats.pits_after, 0, "no pit outside the marked sink");
    // The basin is still a closed depression when the sink is not excluded.
    let with_lake = terrasketch_synthesis::pits::count_pits(h, n, n, None, 10.0);
    assert!(with_lake >= 1, "the marked lake was drained");
}

/// The seam gradient-jump metric sees a crease along a seam (a line in a hillshade) that leaves
/// the Laplacian's 99th percentile, dominated by rough texture elsewhere, nearly unchanged, and
/// stays near 1 when the surface is smooth across the seam.
#[test]
fn seam_gradient_jump_sees_a_crease_on_the_seam() {
    use terrasketch_synthesis::refine::{seam_gradient_jump_ratio, seam_ratio};
    let n = 128usize;
    // Left half patch 0, right half patch 1: one vertical seam between x = 63 and 64.
    let owner: Vec<u32> = (0..n * n).map(|i| u32::from(i % n >= n / 2)).collect();
    // Rough texture (a seeded hash) on a smooth swell.
    let texture = |i: usize| {
        let mut z = (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ 0x5151;
        z = (z ^ (z >> 31)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        ((z >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 2.0
    };
    let swell = |x: f32, y: f32| 40.0 * (x / 20.0).sin() * (y / 27.0).cos();
    let smooth: Vec<f32> = (0..n * n)
        .map(|i| swell((i % n) as f32, (i / n) as f32) + texture(i))
        .collect();
    // The same plus a crease: the slope turns by 0.6 m per cell across the seam.
    let creased: Vec<f32> = smooth
        .iter()
        .enumerate()
        .map(|(i, &v)| v + 0.3 * ((i % n) as f32 - 63.5).abs())
        .collect();
    let r_smooth = seam_gradient_jump_ratio(&smooth, &owner, n);
    let r_crease = seam_gradient_jump_ratio(&creased, &owner, n);
    assert!((0.7..1.3).contains(&r_smooth), "smooth {r_smooth}");
    assert!(r_crease > 1.5 * r_smooth, "crease {r_crease} vs {r_smooth}");
    // The Laplacian tail barely moves: the old metric misses this crease.
    let (l_smooth, l_crease) = (
        seam_ratio(&smooth, &owner, n),
        seam_ratio(&creased, &owner, n),
    );
    assert!(l_crease < 1.25, "laplacian {l_smooth} -> {l_crease}");
    // No seam, no figure.
    assert_eq!(seam_gradient_jump_ratio(&smooth, &vec![0; n * n], n), 0.0);
}

#[test]
fn flat_targets_get_flat_land_and_rugged_targets_rugged_land() {
    // West half a plain, east half a smooth steep slope with no detail of its own to match:
    // only the relief of the layout tells that the east is mountain land. The exemplars hold
    // both (Zurich's lake and plain, Jacksboro's dissected ridges).
    let (n, cell) = (128, 40.0);
    let data: Vec<f32> = (0..n * n)
        .map(|i| {
            let (x, y) = ((i % n) as f32, (i / n) as f32);
            let east = ((x - 56.0) / 16.0).clamp(0.0, 1.0);
            400.0 + east * (8.0 * (x - 56.0) + 4.0 * y)
        })
        .collect();
    let input = RefineInput::target_only(n, cell, data.clone());
    let ex = prepared(&["zurich_dhm25.tif", "jacksboro_fault_srtm3.tif"], cell);
    // Detail (the output minus its own 8-cell low-pass) as an RMS over the west (plain) and
    // east (hills) halves.
    let detail = |relief: f32, seed: u64| {
        let mut params = small_params(seed);
        params.weights.relief = relief;
        let out = run(&input, &ex, &params).heights.data;
        let low = terrasketch_synthesis::refine::field::lowpass(&Field::new(n, n, out.clone()), 8);
        let rms = |xs: std::ops::Range<usize>| {
            let (mut s, mut c) = (0.0f64, 0usize);
            for y in 8..n - 8 {
                for x in xs.clone() {
                    let d = f64::from(out[y * n + x] - low.v[y * n + x]);
                    s += d * d;
                    c += 1;
                }
            }
            (s / c as f64).sqrt()
        };
        // The plain is measured a patch's half side (16 cells) and more west of where the slope
        // starts (x = 56): a patch straddling the slope's foot carries the slope's detail over
        // its whole window.
        (rms(8..40), rms(80..n - 8))
    };
    let default = RefineParams::default().weights.relief;
    // Summed over three seeds: one seed's 128^2 map holds a few dozen patches.
    let sum3 = |relief: f32| {
        (5..8).fold((0.0, 0.0), |(w, e), seed| {
            let (a, b) = detail(relief, seed);
            (w + a, e + b)
        })
    };
    let ((west, east), (west0, east0)) = (sum3(default), sum3(0.0));
    eprintln!(
        "detail RMS west / east: {west:.2} / {east:.2} m; without the relief cost {west0:.2} / {east0:.2} m"
    );
    assert!(
        east > 2.0 * west,
        "the slope is rugged, the plain less: {east} vs {west}"
    );
    assert!(
        east / west > 1.5 * east0 / west0,
        "{east} / {west} vs {east0} / {west0}"
    );
}

#[test]
fn coarse_and_flat_exemplars_are_named_in_warnings() {
    // Kossou's 92 m cells brought to 20 m: 4.6 times finer.
    let ex = prepared(&["kossou_plains_srtm3.tif", "zurich_dhm25.tif"], 20.0);
    assert!(
        ex[0]
            .warnings
            .iter()
            .any(|w| w.contains("kossou_plains_srtm3")),
        "{:?}",
        ex[0].warnings
    );
    assert!(ex[1].warnings.is_empty(), "{:?}", ex[1].warnings);
    // An all-flat exemplar: a warning, and a refinement with it alone runs without a panic.
    let mut flat = shipped("zurich_dhm25.tif");
    flat.heights_m.iter_mut().for_each(|h| *h = 500.0);
    flat.name = "flat".into();
    let ex = prepare_exemplars(&[flat], 25.0, None, &|_, _| {}).unwrap();
    assert!(
        ex[0].warnings.iter().any(|w| w.contains("flat")),
        "{:?}",
        ex[0].warnings
    );
    let (n, cell) = (64, 25.0);
    let input = RefineInput::target_only(n, cell, smooth_target(n, cell));
    let params = RefineParams {
        patch_size: 16,
        ..small_params(1)
    };
    let out = refine(&input, &ex, &params, &|_, _| {}, &AtomicBool::new(false)).unwrap();
    assert!(out.heights.data.iter().all(|v| v.is_finite()));
}

/// Share of the seam edges (4-neighbours with different owners) lying on straight runs of at
/// least `len` edges along one row or column boundary.
fn straight_seam_share(owner: &[u32], n: usize, len: usize) -> f64 {
    let (mut long, mut all) = (0usize, 0usize);
    let mut count = |run: usize| {
        all += run;
        if run >= len {
            long += run;
        }
    };
    for b in 0..n - 1 {
        // Boundary between rows b and b + 1, then between columns b and b + 1.
        for across in [n, 1] {
            let along = if across == n { 1 } else { n };
            let base = if across == n { b * n } else { b };
            let mut run = 0;
            for t in 0..n {
                let i = base + t * along;
                if owner[i] != owner[i + across] {
                    run += 1;
                } else {
                    count(run);
                    run = 0;
                }
            }
            count(run);
        }
    }
    long as f64 / all.max(1) as f64
}

#[test]
fn patch_seams_do_not_follow_window_edges() {
    // Minimum cuts favour short seams, and a window's straight edge is the shortest: the fill
    // must not leave seams running straight along rows or columns for half a patch or more.
    let (n, cell) = (256, 30.0);
    let ex = prepared(&["jacksboro_fault_srtm3.tif", "zurich_dhm25.tif"], cell);
    let input = sketch_like_input(n, cell);
    let params = RefineParams {
        levels: 1,
        ..small_params(3)
    };
    let out = run(&input, &ex, &params);
    let share = straight_seam_share(&out.owner, n, params.patch_size / 2);
    assert!(
        share < 0.05,
        "{share:.3} of the seam edges on straight runs"
    );
}

#[test]
fn patches_are_not_taken_from_the_same_place_over_and_over() {
    // A uniform slope: every slot wants the same kind of land, and without a reuse cost the best
    // few spots of the exemplars fill the whole map (their particular ridges repeat everywhere).
    let (n, cell) = (256, 40.0);
    let data: Vec<f32> = (0..n * n)
        .map(|i| 400.0 + 6.0 * (i % n) as f32 + 2.0 * (i / n) as f32)
        .collect();
    let input = RefineInput::target_only(n, cell, data);
    let ex = prepared(&["zurich_dhm25.tif", "jacksboro_fault_srtm3.tif"], cell);
    // Patches per spot (exemplar and quarter-patch cell of its centre): the busiest spot's count
    // and the number of spots used.
    let spots = |reuse: f32| {
        let mut params = RefineParams {
            levels: 1,
            ..small_params(4)
        };
        params.weights.reuse = reuse;
        let out = run(&input, &ex, &params);
        let q = (params.patch_size / 4) as f32;
        let mut count = std::collections::BTreeMap::new();
        for p in &out.placed {
            let key = (p.ex, (p.c[0] / q) as i32, (p.c[1] / q) as i32);
            *count.entry(key).or_insert(0usize) += 1;
        }
        let busiest = count.values().copied().max().unwrap_or(0);
        (busiest, count.len(), out.placed.len())
    };
    let (busy0, spots0, placed0) = spots(0.0);
    let (busy, spots1, placed) = spots(RefineParams::default().weights.reuse);
    eprintln!(
        "busiest spot / spots / patches: {busy0} / {spots0} / {placed0} without the reuse cost, \
         {busy} / {spots1} / {placed} with it"
    );
    assert!(busy < busy0, "{busy} vs {busy0}");
    assert!(spots1 > spots0, "{spots1} vs {spots0}");
}

/// RMS of the 5-point Laplacian over the interior: relief at two to four cells.
fn laplacian_rms(h: &[f32], n: usize) -> f64 {
    let mut s = 0.0f64;
    for y in 1..n - 1 {
        for x in 1..n - 1 {
            let i = y * n + x;
            let l = h[i - 1] + h[i + 1] + h[i - n] + h[i + n] - 4.0 * h[i];
            s += f64::from(l) * f64::from(l);
        }
    }
    (s / ((n - 2) * (n - 2)) as f64).sqrt()
}

#[test]
fn octaves_finer_than_the_exemplars_come_from_the_calibrated_detail() {
    // 10 m cells from a 75-92 m DEM: below about 160 m the exemplar holds only interpolation.
    let (n, cell) = (128, 10.0);
    let ex = prepared(&["jacksboro_fault_srtm3.tif"], cell);
    let mut input = sketch_like_input(n, cell);
    let point = (n - 20) * n + n - 30;
    let mask = input.constraint_mask.clone().unwrap();
    let tolerance: Vec<f32> = (0..n * n)
        .map(|i| if mask[i] && i != point { 2.0 } else { 0.0 })
        .collect();
    input.constraint_tolerance = Some(tolerance.clone());
    let params = |g: f32| RefineParams {
        fine_detail: g,
        ..small_params(3)
    };
    let off = run(&input, &ex, &params(0.0));
    let on = run(&input, &ex, &params(0.5));
    let (lap_off, lap_on) = (
        laplacian_rms(&off.heights.data, n),
        laplacian_rms(&on.heights.data, n),
    );
    assert!(
        lap_on > 2.0 * lap_off,
        "fine relief {lap_on} with the band, {lap_off} without"
    );
    // The sketched heights hold: the exact point exactly, the crest within its tolerance.
    let values = input.constraint_values.as_ref().unwrap();
    assert!((on.heights.data[point] - values[point]).abs() <= 1e-3);
    for i in (0..n * n).filter(|&i| mask[i]) {
        let err = (on.heights.data[i] - values[i]).abs();
        assert!(err <= tolerance[i] + 1e-3, "cell {i}: {err} m off");
    }
    // Only the fine band moved: means over 64 x 64 cells stay within a few metres (relief 600 m).
    let block = |h: &[f32], bx: usize, by: usize| -> f64 {
        let mut s = 0.0f64;
        for y in 64 * by..64 * by + 64 {
            for x in 64 * bx..64 * bx + 64 {
                s += f64::from(h[y * n + x]);
            }
        }
        s / 4096.0
    };
    for by in 0..n / 64 {
        for bx in 0..n / 64 {
            let d = (block(&on.heights.data, bx, by) - block(&off.heights.data, bx, by)).abs();
            assert!(d < 5.0, "block ({bx}, {by}) moved {d} m");
        }
    }
}
