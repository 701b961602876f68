//! Tests of the rasteriser: thickness, band gradients, row and column windows against a full
//! rasterisation, candidate ranges against every segment, stroke spans.

use super::*;
use terrasketch_sketch::{Stroke, StrokeKind};

fn grid(n: usize) -> Grid {
    Grid::new(n, [6400.0, 6400.0]).unwrap()
}

#[test]
fn curve_is_never_thinner_than_one_texel() {
    // A diagonal stroke at an awkward angle: every column it crosses has a hard texel.
    let g = grid(64);
    let s = Sketch {
        extent_m: g.extent_m,
        base_elevation_m: 0.0,
        seed: 0,
        strokes: vec![Stroke::new(
            StrokeKind::Ridge,
            vec![[130.0, 710.0, 500.0], [6100.0, 4333.0, 700.0]],
        )],
    };
    let m = ConstraintMaps::rasterize(&s, &g);
    let n = g.n;
    for i in 2..60 {
        let hard = (0..n).filter(|&j| m.elev_weight[j * n + i] >= 1.0).count();
        assert!(hard >= 1, "column {i} has no hard texel");
    }
    // Heights along the curve interpolate between 500 and 700.
    let vals: Vec<f32> = (0..n * n)
        .filter(|&k| m.elev_weight[k] >= 1.0)
        .map(|k| m.elev_value[k])
        .collect();
    assert!(vals.iter().all(|v| (499.0..=701.0).contains(v)));
}

#[test]
fn ridge_band_gradients_point_down_and_away() {
    let g = grid(64);
    let mut st = Stroke::new(
        StrokeKind::Ridge,
        vec![[0.0, 3200.0, 800.0], [6400.0, 3200.0, 800.0]],
    );
    st.slope_left_deg = 30.0;
    st.slope_right_deg = 10.0;
    st.width_m = 1000.0;
    st.falloff = terrasketch_sketch::Falloff::None;
    let mut s = Sketch {
        extent_m: g.extent_m,
        base_elevation_m: 0.0,
        seed: 0,
        strokes: vec![st],
    };
    let m = ConstraintMaps::rasterize(&s, &g);
    let n = g.n;
    // Travel is eastward: left = north. North of the ridge heights fall northward: gy = -tan 30.
    let north = 40 * n + 32; // y = 4050 m, 850 m north of the curve
    assert!((m.grad_y[north] + 30f32.to_radians().tan()).abs() < 1e-5);
    assert!(m.band_weight[north] == 1.0);
    let south = 26 * n + 32; // y = 2650 m, 550 m south
    assert!((m.grad_y[south] - 10f32.to_radians().tan()).abs() < 1e-5);
    // With a falloff the slope fades with the profile of the distance over the width.
    for falloff in [
        terrasketch_sketch::Falloff::Foot,
        terrasketch_sketch::Falloff::Sigmoid,
    ] {
        s.strokes[0].falloff = falloff;
        let f = ConstraintMaps::rasterize(&s, &g);
        for (k, d, tan) in [(north, 850.0, -30f64), (south, 550.0, 10.0)] {
            let want = tan.signum() * tan.abs().to_radians().tan() * falloff.profile(d / 1000.0);
            assert!((f.grad_y[k] as f64 - want).abs() < 1e-5, "{falloff:?} {d}");
        }
        assert_eq!(f.band_weight, m.band_weight);
    }
    // Outside the band: nothing.
    let far = 60 * n + 32;
    assert_eq!(m.band_weight[far], 0.0);
    assert_eq!(m.elev_weight[far], 0.0);
}

#[test]
fn incremental_rows_match_full_rasterisation() {
    let g = grid(128);
    let s = terrasketch_sketch::benchmark_sketch();
    let g = Grid::new(g.n, s.extent_m).unwrap();
    let full = ConstraintMaps::rasterize(&s, &g);
    let mut part = ConstraintMaps::rasterize(
        &Sketch {
            strokes: vec![],
            ..s.clone()
        },
        &g,
    );
    part.rasterize_rows(&s, &g, 0..50);
    part.rasterize_rows(&s, &g, 50..128);
    assert_eq!(full, part);
}

/// The maps with every segment a candidate for every texel of its rows.
fn rasterize_exhaustive(sketch: &Sketch, g: &Grid) -> ConstraintMaps {
    let mut m = ConstraintMaps::new(g.n);
    let out = m.arrays_mut().map(|v| &mut v[..]);
    rasterize_block(sketch, g, 0..g.n, 0..g.n, out, true);
    m
}

#[test]
fn candidate_ranges_find_the_closest_segment_of_every_texel() {
    // Wiggly strokes (the benchmark), a hairpin, a zig-zag with sharp turns and a dot.
    let mut sharp = terrasketch_sketch::example_sketch();
    let e = sharp.extent_m;
    let mut hairpin = Stroke::new(
        StrokeKind::Ridge,
        vec![
            [0.2 * e[0], 0.3 * e[1], 400.0],
            [0.8 * e[0], 0.32 * e[1], 600.0],
            [0.21 * e[0], 0.36 * e[1], 500.0],
        ],
    );
    hairpin.width_m = 0.1 * e[0];
    let zigzag = Stroke::new(
        StrokeKind::Valley,
        (0..12)
            .map(|k| {
                let x = (0.1 + 0.07 * k as f64) * e[0];
                let y = if k % 2 == 0 { 0.6 } else { 0.75 } * e[1];
                [x, y, 100.0 + 10.0 * k as f64]
            })
            .collect(),
    );
    let dot = Stroke::new(
        StrokeKind::Plateau,
        vec![
            [0.5 * e[0], 0.9 * e[1], 50.0],
            [0.5 * e[0], 0.9 * e[1], 50.0],
        ],
    );
    let mut ring = Stroke::new(
        StrokeKind::Ridge,
        (0..7)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / 7.0;
                [
                    (0.7 + 0.1 * a.cos()) * e[0],
                    (0.5 + 0.1 * a.sin()) * e[1],
                    300.0,
                ]
            })
            .collect(),
    );
    ring.closed = true;
    let mut polygon = ring.clone();
    polygon.curve = terrasketch_sketch::CurveKind::Polyline;
    for p in &mut polygon.points {
        p[1] -= 0.25 * e[1];
    }
    sharp.strokes.extend([hairpin, zigzag, dot, ring, polygon]);
    let bench = terrasketch_sketch::benchmark_sketch;
    for (s, n) in [
        (bench(), 128),
        (bench(), 256),
        (bench(), 512),
        (sharp.clone(), 256),
        (sharp, 512),
    ] {
        let g = Grid::new(n, s.extent_m).unwrap();
        let fast = ConstraintMaps::rasterize(&s, &g);
        let all = rasterize_exhaustive(&s, &g);
        // Distances decide the weights: the same closest distance gives the same weights.
        assert_eq!(fast.elev_weight, all.elev_weight);
        if let Some(k) = (0..n * n).find(|&k| fast.band_weight[k] != all.band_weight[k]) {
            panic!(
                "band weight at ({}, {}): {} against {} (of {} differing)",
                k % n,
                k / n,
                fast.band_weight[k],
                all.band_weight[k],
                (0..n * n)
                    .filter(|&k| fast.band_weight[k] != all.band_weight[k])
                    .count()
            );
        }
        assert_eq!(fast.rough_weight, all.rough_weight);
        // At a vertex two segments can be closest within rounding: values agree closely.
        let close =
            |a: &[f32], b: &[f32], tol: f32| a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol);
        assert!(close(&fast.elev_value, &all.elev_value, 1e-3));
        assert!(close(&fast.grad_x, &all.grad_x, 1e-4));
        assert!(close(&fast.grad_y, &all.grad_y, 1e-4));
        assert_eq!(fast.rough_value, all.rough_value);
    }
}

#[test]
fn column_windows_match_full_rasterisation_bit_for_bit() {
    for (s, n) in [
        (terrasketch_sketch::benchmark_sketch(), 128),
        (terrasketch_sketch::example_sketch(), 256),
    ] {
        let g = Grid::new(n, s.extent_m).unwrap();
        let full = ConstraintMaps::rasterize(&s, &g);
        let mut band = ConstraintMaps::new(0);
        // Windows of every shape: edges, one column, odd offsets, the whole grid.
        let mut seed = 7usize;
        let mut windows = vec![(0..n, 0..n), (0..1, n - 1..n), (n - 3..n, 0..1)];
        for _ in 0..20 {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let (a, b) = ((seed >> 20) % n, (seed >> 40) % n);
            let (c, d) = ((seed >> 8) % n, (seed >> 50) % n);
            windows.push((a.min(b)..a.max(b) + 1, c.min(d)..c.max(d) + 1));
        }
        for (rows, cols) in windows {
            ConstraintMaps::rasterize_band_cols(&mut band, &s, &g, rows.clone(), cols.clone());
            let w = cols.len();
            for (r, j) in rows.clone().enumerate() {
                for (c, i) in cols.clone().enumerate() {
                    let (k, l) = (r * w + c, j * n + i);
                    let pairs = [
                        (band.elev_weight[k], full.elev_weight[l]),
                        (band.elev_value[k], full.elev_value[l]),
                        (band.band_weight[k], full.band_weight[l]),
                        (band.grad_x[k], full.grad_x[l]),
                        (band.grad_y[k], full.grad_y[l]),
                        (band.rough_weight[k], full.rough_weight[l]),
                        (band.rough_value[k], full.rough_value[l]),
                    ];
                    for (m, (a, b)) in pairs.iter().enumerate() {
                        assert_eq!(
                            a.to_bits(),
                            b.to_bits(),
                            "map {m} at ({i},{j}), window {rows:?} x {cols:?}"
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn stroke_spans_cover_every_texel_the_stroke_changes() {
    let s = terrasketch_sketch::benchmark_sketch();
    let n = 128;
    let g = Grid::new(n, s.extent_m).unwrap();
    let full = ConstraintMaps::rasterize(&s, &g);
    for stroke in 0..s.strokes.len() {
        let mut without = s.clone();
        without.strokes.remove(stroke);
        let other = ConstraintMaps::rasterize(&without, &g);
        let spans = ConstraintMaps::stroke_spans(&s, stroke, &g);
        let covered = |i: usize, j: usize| spans.iter().any(|(r, c)| *r == j && c.contains(&i));
        let mut changed = 0;
        for j in 0..n {
            for i in 0..n {
                let l = j * n + i;
                let differs = [
                    (&full.elev_weight, &other.elev_weight),
                    (&full.elev_value, &other.elev_value),
                    (&full.band_weight, &other.band_weight),
                    (&full.grad_x, &other.grad_x),
                    (&full.grad_y, &other.grad_y),
                    (&full.rough_weight, &other.rough_weight),
                    (&full.rough_value, &other.rough_value),
                ]
                .iter()
                .any(|(a, b)| a[l].to_bits() != b[l].to_bits());
                if differs {
                    changed += 1;
                    assert!(
                        covered(i, j),
                        "stroke {stroke} changes ({i},{j}) outside its spans"
                    );
                }
            }
        }
        assert!(changed > 0, "stroke {stroke} changes nothing");
        // Spans are narrower than whole rows (they are worth having).
        let cells: usize = spans.iter().map(|(_, c)| c.len()).sum();
        assert!(cells < n * n, "stroke {stroke}: spans cover the whole grid");
    }
}
