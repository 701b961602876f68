//! Pit removal: synthetic pitted fields, marked sinks, border-open depressions and a real DEM.

mod common;

use terrasketch_synthesis::pits::{
    PitMode, count_pits, find_depressions, is_interior_sink, remove_pits,
};
use terrasketch_synthesis::{LoadOptions, load_dem};

/// Small deterministic generator (SplitMix64).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// A tilted plane (100 m per 100 cells towards the east, some north-south tilt) with `n` conical
/// pits of random radius (2..8 cells) and depth (5..40 m) dug into it.
fn pitted_field(w: usize, h: usize, n: usize, seed: u64) -> Vec<f32> {
    let mut rng = Rng(seed);
    let mut z: Vec<f32> = (0..w * h)
        .map(|i| 500.0 + (i % w) as f32 * 1.0 + (i / w) as f32 * 0.3)
        .collect();
    for _ in 0..n {
        let cx = 10.0 + rng.unit() * (w as f32 - 20.0);
        let cy = 10.0 + rng.unit() * (h as f32 - 20.0);
        let r = 2.0 + rng.unit() * 6.0;
        let depth = 5.0 + rng.unit() * 35.0;
        for y in 0..h {
            for x in 0..w {
                let d = ((x as f32 - cx).powi(2) + (y as f32 - cy).powi(2)).sqrt();
                if d < r {
                    z[y * w + x] -= depth * (1.0 - d / r);
                }
            }
        }
    }
    z
}

fn interior_sinks(z: &[f32], w: usize, h: usize, mask: Option<&[bool]>) -> usize {
    (0..z.len())
        .filter(|&i| !mask.is_some_and(|m| m[i]) && is_interior_sink(z, w, h, i))
        .count()
}

const MODES: [PitMode; 4] = [
    PitMode::Fill { epsilon: false },
    PitMode::Fill { epsilon: true },
    PitMode::Breach,
    PitMode::Hybrid {
        max_depth_m: 5.0,
        max_length: 20,
    },
];

#[test]
fn every_mode_leaves_no_interior_pit() {
    let (w, h) = (160, 120);
    let field = pitted_field(w, h, 40, 7);
    let before = find_depressions(&field, w, h, None);
    assert!(before.len() >= 20, "only {} pits dug", before.len());
    assert!(interior_sinks(&field, w, h, None) >= 20);
    for mode in MODES {
        let mut z = field.clone();
        let stats = remove_pits(&mut z, w, h, None, mode);
        assert_eq!(stats.pits_found, before.len(), "{mode:?}");
        assert!(
            stats.cells_changed > 0 && stats.max_change_m > 1.0,
            "{mode:?}"
        );
        assert!(find_depressions(&z, w, h, None).is_empty(), "{mode:?}");
        assert!(z.iter().all(|v| v.is_finite()));
        if mode != (PitMode::Fill { epsilon: false }) {
            // Strict drainage: every interior cell has a strictly lower neighbour.
            assert_eq!(interior_sinks(&z, w, h, None), 0, "{mode:?}");
        }
        match mode {
            PitMode::Fill { .. } => assert_eq!(stats.cells_lowered, 0),
            PitMode::Breach => assert_eq!(stats.cells_raised, 0),
            PitMode::Hybrid { .. } => {
                assert!(
                    stats.cells_raised > 0 && stats.cells_lowered > 0,
                    "{stats:?}"
                )
            }
        }
        // Cells away from every pit are untouched by filling.
        if let PitMode::Fill { epsilon: false } = mode {
            assert!(z.iter().zip(&field).all(|(a, b)| a >= b));
        }
    }
}

#[test]
fn hybrid_cuts_no_deeper_than_its_limit() {
    let (w, h) = (120, 100);
    let field = pitted_field(w, h, 25, 11);
    let mut z = field.clone();
    remove_pits(
        &mut z,
        w,
        h,
        None,
        PitMode::Hybrid {
            max_depth_m: 3.0,
            max_length: 50,
        },
    );
    let deepest_cut = z
        .iter()
        .zip(&field)
        .map(|(a, b)| b - a)
        .fold(0.0f32, f32::max);
    assert!(deepest_cut <= 3.0 + 1e-3, "cut {deepest_cut}");
}

#[test]
fn a_marked_sink_survives() {
    let (w, h) = (64, 64);
    // A lake basin 30 m deep in the middle of a tilted plane, plus one unmarked pit.
    let mut z: Vec<f32> = (0..w * h).map(|i| 100.0 + (i % w) as f32 * 0.5).collect();
    let mut mask = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            let d = ((x as f32 - 32.0).powi(2) + (y as f32 - 32.0).powi(2)).sqrt();
            if d < 10.0 {
                z[y * w + x] -= 30.0 * (1.0 - d / 10.0);
            }
            if d < 1.5 {
                mask[y * w + x] = true;
            }
            let d2 = ((x as f32 - 12.0).powi(2) + (y as f32 - 12.0).powi(2)).sqrt();
            if d2 < 4.0 {
                z[y * w + x] -= 15.0 * (1.0 - d2 / 4.0);
            }
        }
    }
    assert_eq!(count_pits(&z, w, h, None, 10.0), 2);
    assert_eq!(count_pits(&z, w, h, Some(&mask), 10.0), 1);
    for mode in MODES {
        let mut out = z.clone();
        let stats = remove_pits(&mut out, w, h, Some(&mask), mode);
        assert_eq!(stats.pits_found, 1, "{mode:?}");
        for i in 0..w * h {
            if mask[i] {
                assert_eq!(out[i], z[i], "{mode:?}: sink cell {i} changed");
            }
        }
        // The lake is still a closed basin around the sink: its rim is well above its floor.
        assert!(out[32 * w + 32] < out[32 * w + 40] - 10.0, "{mode:?}");
        assert!(find_depressions(&out, w, h, Some(&mask)).is_empty());
        if mode != (PitMode::Fill { epsilon: false }) {
            assert_eq!(interior_sinks(&out, w, h, Some(&mask)), 0, "{mode:?}");
        }
    }
}

#[test]
fn depressions_open_to_the_border_are_not_pits() {
    let (w, h) = (50, 40);
    // A trench that runs to the west edge and gets deeper towards it: it drains off the grid.
    let mut z: Vec<f32> = vec![200.0; w * h];
    for x in 0..30 {
        for y in 18..22 {
            z[y * w + x] = 150.0 + x as f32;
        }
    }
    assert!(find_depressions(&z, w, h, None).is_empty());
    let mut out = z.clone();
    let stats = remove_pits(&mut out, w, h, None, PitMode::Fill { epsilon: false });
    assert_eq!((stats.pits_found, stats.cells_changed), (0, 0));
    // Closing the trench's mouth with a wall makes it a pit.
    for y in 17..23 {
        z[y * w] = 250.0;
    }
    let pits = find_depressions(&z, w, h, None);
    assert_eq!(pits.len(), 1);
    // Spill level 200 m (the plateau), floor 151 m (x = 1).
    assert!((pits[0].depth_m - 49.0).abs() < 1e-3, "{}", pits[0].depth_m);
}

#[test]
fn mismatched_input_is_left_alone() {
    let mut z = vec![1.0f32; 10];
    assert_eq!(
        remove_pits(&mut z, 4, 4, None, PitMode::Breach).cells_changed,
        0
    );
    assert_eq!(count_pits(&z, 4, 4, None, 0.0), 0);
    let mask = vec![false; 3];
    let mut z = vec![1.0f32; 16];
    assert_eq!(
        remove_pits(&mut z, 4, 4, Some(&mask), PitMode::Breach).pits_found,
        0
    );
    assert!(!is_interior_sink(&[], 0, 3, 0));
    assert!(find_depressions(&[], 0, 0, None).is_empty());
    let mut nan = vec![f32::NAN; 16];
    let _ = remove_pits(&mut nan, 4, 4, None, PitMode::default());
}

#[test]
fn real_dem_pits_before_and_after() {
    let dem = load_dem(
        &common::exemplar("jacksboro_fault_srtm3.tif"),
        &LoadOptions::default(),
    )
    .unwrap();
    let (w, h) = (dem.width, dem.height);
    let before_any = find_depressions(&dem.heights_m, w, h, None).len();
    let before_10 = count_pits(&dem.heights_m, w, h, None, 10.0);
    assert!(
        before_any > 0,
        "an integer SRTM tile always has some closed depressions"
    );
    for mode in MODES {
        let mut z = dem.heights_m.clone();
        let t = std::time::Instant::now();
        let stats = remove_pits(&mut z, w, h, None, mode);
        eprintln!(
            "jacksboro {mode:?}: pits {before_any} (>10 m: {before_10}) -> {}; changed {} cells, max {:.1} m, {:?}",
            find_depressions(&z, w, h, None).len(),
            stats.cells_changed,
            stats.max_change_m,
            t.elapsed()
        );
        assert_eq!(stats.pits_found, before_any);
        assert!(find_depressions(&z, w, h, None).is_empty(), "{mode:?}");
        if mode != (PitMode::Fill { epsilon: false }) {
            assert_eq!(interior_sinks(&z, w, h, None), 0, "{mode:?}");
        }
        // Real terrain: pit removal is a small edit.
        assert!(stats.cells_changed < w * h / 4, "{mode:?}: {stats:?}");
    }
}

#[test]
fn every_shipped_exemplar_breaches_clean() {
    let (dems, failures) =
        terrasketch_synthesis::load_exemplar_dir(&terrasketch_synthesis::shipped_exemplar_dir());
    assert!(failures.is_empty() && dems.len() == 5);
    for dem in &dems {
        let (w, h) = (dem.width, dem.height);
        let before_10 = count_pits(&dem.heights_m, w, h, None, 10.0);
        let mut z = dem.heights_m.clone();
        let t = std::time::Instant::now();
        let stats = remove_pits(&mut z, w, h, None, PitMode::Breach);
        let elapsed = t.elapsed();
        let after = find_depressions(&z, w, h, None).len();
        eprintln!(
            "{}: {} pits (>10 m: {before_10}) -> {after}; breach changed {} cells ({:.2} %), max {:.1} m, {elapsed:?}",
            dem.name,
            stats.pits_found,
            stats.cells_changed,
            100.0 * stats.cells_changed as f64 / (w * h) as f64,
            stats.max_change_m,
        );
        assert_eq!(after, 0, "{}", dem.name);
        assert_eq!(interior_sinks(&z, w, h, None), 0, "{}", dem.name);
        assert_eq!(stats.cells_raised, 0);
    }
}

#[test]
fn breaches_are_carved_as_valleys_not_trenches() {
    use terrasketch_synthesis::metrics::count_trenches;
    use terrasketch_synthesis::refine::valleys::remove_pits_as_valleys;
    // A valley falling east (1 m per cell, round-bottomed across rows) blocked by a 60 m dam
    // at x = 40: the breach cuts through the dam along the valley floor, row 32.
    let n = 64;
    let z: Vec<f32> = (0..n * n)
        .map(|i| {
            let (x, y) = ((i % n) as f32, (i / n) as f32);
            let dam = 60.0 * (-((x - 40.0).powi(2)) / 16.0).exp();
            500.0 - x + 0.1 * (y - 32.0).powi(2) + dam
        })
        .collect();
    let mut plain = z.clone();
    remove_pits(&mut plain, n, n, None, PitMode::Breach);
    assert!(
        count_trenches(&plain, n, n) >= 1,
        "a plain breach cuts a trench"
    );
    let mut carved = z.clone();
    remove_pits_as_valleys(&mut carved, n, None, PitMode::Breach, 10.0);
    assert_eq!(count_trenches(&carved, n, n), 0);
    assert_eq!(
        terrasketch_synthesis::pits::count_pits(&carved, n, n, None, 0.0),
        0,
        "still drained"
    );
    // The carved channel is no deeper than the plain breach, and wider: its banks are lowered.
    let deepest = |h: &[f32]| h.iter().zip(&z).map(|(a, b)| b - a).fold(0.0f32, f32::max);
    assert!(deepest(&carved) <= deepest(&plain) + 0.5);
    let lowered = |h: &[f32]| h.iter().zip(&z).filter(|(a, b)| **a < **b - 1.0).count();
    let (c, p) = (lowered(&carved), lowered(&plain));
    assert!(
        p >= 8 && c >= 5 * p,
        "cells lowered by > 1 m: carved {c}, plain {p}"
    );
}
