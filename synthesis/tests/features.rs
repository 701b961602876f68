//! Ridge and valley extraction on synthetic fields and a real DEM.

mod common;

use terrasketch_synthesis::features::{
    FeatureKind, FeatureNetwork, FeatureParams, extract_features, feature_cache_key,
    polyline_length,
};
use terrasketch_synthesis::{LoadOptions, load_dem};

/// Small deterministic generator (SplitMix64).
struct Rng(u64);

impl Rng {
    fn unit(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
}

const W: usize = 128;
const H: usize = 112;
const CELL: [f64; 2] = [30.0, 30.0];
/// The true crest line: y = SLOPE * x + OFFSET (cells).
const SLOPE: f32 = 0.4;
const OFFSET: f32 = 25.0;

fn line_distance(x: f32, y: f32) -> f32 {
    (SLOPE * x - y + OFFSET).abs() / (SLOPE * SLOPE + 1.0).sqrt()
}

/// A Gaussian ridge (200 m high, sigma 8 cells) along the line, on a gentle regional tilt, with
/// +-1.5 m of white noise.
fn noisy_ridge(seed: u64) -> Vec<f32> {
    let mut rng = Rng(seed);
    (0..W * H)
        .map(|i| {
            let (x, y) = ((i % W) as f32, (i / W) as f32);
            let d = line_distance(x, y);
            300.0 + 0.2 * x + 200.0 * (-d * d / (2.0 * 64.0)).exp() + 3.0 * (rng.unit() - 0.5)
        })
        .collect()
}

/// Length of the true line inside the grid, in cells.
fn true_length() -> f32 {
    // y = 0.4 x + 25 runs from x = 0 (y = 25) to x = 127 (y = 75.8): inside for every x.
    (W as f32 - 1.0) * (1.0 + SLOPE * SLOPE).sqrt()
}

fn check_one_line_along_the_crest(net: &FeatureNetwork) {
    let lengths: Vec<f64> = net.polylines.iter().map(|p| polyline_length(p)).collect();
    eprintln!(
        "{:?}: {} candidates, {} polylines, lengths {lengths:.1?}",
        net.kind,
        net.candidates,
        net.polylines.len()
    );
    assert_eq!(net.polylines.len(), 1, "lengths {lengths:?}");
    let line = &net.polylines[0];
    let len = polyline_length(line) as f32;
    assert!(
        len > 0.85 * true_length() && len < 1.25 * true_length(),
        "length {len} vs {}",
        true_length()
    );
    for p in line {
        assert!(
            line_distance(p[0], p[1]) <= 2.0,
            "point {p:?} off the crest"
        );
    }
    let masked: Vec<usize> = (0..W * H).filter(|&i| net.mask[i]).collect();
    assert!(masked.len() as f32 >= 0.85 * true_length());
    for i in masked {
        assert!(line_distance((i % W) as f32, (i / W) as f32) <= 2.0);
    }
}

#[test]
fn a_noisy_straight_ridge_gives_one_line_along_it() {
    for seed in [1, 2, 3] {
        let z = noisy_ridge(seed);
        let net = extract_features(
            &z,
            W,
            H,
            CELL,
            FeatureKind::Ridge,
            &FeatureParams::default(),
        );
        check_one_line_along_the_crest(&net);
    }
}

#[test]
fn a_noisy_straight_valley_gives_one_line_along_it() {
    let z: Vec<f32> = noisy_ridge(5).iter().map(|v| 1000.0 - v).collect();
    let net = extract_features(
        &z,
        W,
        H,
        CELL,
        FeatureKind::Valley,
        &FeatureParams::default(),
    );
    check_one_line_along_the_crest(&net);
    // The same field has no ridge along that line.
    let ridges = extract_features(
        &z,
        W,
        H,
        CELL,
        FeatureKind::Ridge,
        &FeatureParams::default(),
    );
    for line in &ridges.polylines {
        assert!(line.iter().all(|p| line_distance(p[0], p[1]) > 2.0));
    }
}

#[test]
fn a_flat_or_tilted_field_has_no_features() {
    let flat = vec![250.0f32; W * H];
    let tilted: Vec<f32> = (0..W * H).map(|i| (i % W + 2 * (i / W)) as f32).collect();
    for z in [flat, tilted] {
        for kind in [FeatureKind::Ridge, FeatureKind::Valley] {
            let net = extract_features(&z, W, H, CELL, kind, &FeatureParams::default());
            assert_eq!(net.candidates, 0);
            assert!(net.polylines.is_empty() && !net.mask.iter().any(|&m| m));
        }
    }
}

#[test]
fn output_is_deterministic() {
    let z = noisy_ridge(9);
    let params = FeatureParams::default();
    let a = extract_features(&z, W, H, CELL, FeatureKind::Ridge, &params);
    let b = extract_features(&z, W, H, CELL, FeatureKind::Ridge, &params);
    assert_eq!(a, b);
}

#[test]
fn mismatched_input_gives_an_empty_network() {
    let net = extract_features(
        &[1.0; 7],
        4,
        4,
        CELL,
        FeatureKind::Ridge,
        &Default::default(),
    );
    assert!(net.polylines.is_empty());
    let net = extract_features(&[], 0, 5, CELL, FeatureKind::Valley, &Default::default());
    assert!(net.polylines.is_empty());
    let zero_radius = FeatureParams {
        profile_radius: 0,
        ..FeatureParams::default()
    };
    let _ = terrasketch_synthesis::features::profile_strength(
        &[1.0; 16],
        4,
        4,
        CELL,
        FeatureKind::Ridge,
        zero_radius.profile_radius,
    );
    assert!(
        terrasketch_synthesis::features::profile_strength(&[], 0, 3, CELL, FeatureKind::Ridge, 3)
            .is_empty()
    );
    let nan = vec![f32::NAN; 64];
    let net = extract_features(&nan, 8, 8, CELL, FeatureKind::Ridge, &Default::default());
    assert!(net.polylines.is_empty());
}

#[test]
fn every_shipped_exemplar_has_a_network() {
    let (dems, failures) =
        terrasketch_synthesis::load_exemplar_dir(&terrasketch_synthesis::shipped_exemplar_dir());
    assert!(failures.is_empty());
    for dem in &dems {
        for kind in [FeatureKind::Ridge, FeatureKind::Valley] {
            let t = std::time::Instant::now();
            let net = extract_features(
                &dem.heights_m,
                dem.width,
                dem.height,
                dem.cell_size_m,
                kind,
                &FeatureParams::default(),
            );
            let total: f64 = net.polylines.iter().map(|p| polyline_length(p)).sum();
            eprintln!(
                "{} {kind:?}: {} candidates, {} polylines, {total:.0} cells of line, {:?}",
                dem.name,
                net.candidates,
                net.polylines.len(),
                t.elapsed()
            );
            assert!(!net.polylines.is_empty(), "{} {kind:?}", dem.name);
            let masked = net.mask.iter().filter(|&&m| m).count();
            assert!(masked <= net.candidates && masked < dem.width * dem.height / 5);
        }
    }
}

#[test]
fn real_dem_networks_and_cache_key() {
    let dem = load_dem(
        &common::exemplar("zurich_dhm25.tif"),
        &LoadOptions::default(),
    )
    .unwrap();
    let params = FeatureParams::default();
    for kind in [FeatureKind::Ridge, FeatureKind::Valley] {
        let t = std::time::Instant::now();
        let net = extract_features(
            &dem.heights_m,
            dem.width,
            dem.height,
            dem.cell_size_m,
            kind,
            &params,
        );
        let total: f64 = net.polylines.iter().map(|p| polyline_length(p)).sum();
        eprintln!(
            "zurich {kind:?}: {} candidates, {} polylines, {total:.0} cells of line, {:?}",
            net.candidates,
            net.polylines.len(),
            t.elapsed()
        );
        assert!(net.polylines.len() >= 5, "a hilly 10 km tile has a network");
        for line in &net.polylines {
            assert!(line.len() >= 2);
            for p in line {
                assert!(p[0] >= 0.0 && p[1] >= 0.0);
                assert!(p[0] <= (dem.width - 1) as f32 && p[1] <= (dem.height - 1) as f32);
            }
        }
    }
    let key = feature_cache_key(&dem, &params);
    assert_eq!(key.len(), 16);
    assert_eq!(key, feature_cache_key(&dem, &params));
    let other = FeatureParams {
        min_branch_cells: 9,
        ..params.clone()
    };
    assert_ne!(key, feature_cache_key(&dem, &other));
    let mut changed = dem.clone();
    changed.heights_m[100] += 1.0;
    assert_ne!(key, feature_cache_key(&changed, &params));
}
