//! The detail on solved sketches: hard constraints hold, the law and the seed behave, the fast row
//! evaluation is the point evaluation, and the quadtree bound holds everywhere.

use terrasketch_detail::amplitude::{
    AMPLITUDE_LEVEL, FADE_CELLS, ZERO_CELLS, amplitude_law, fade, gradient_at,
};
use terrasketch_detail::calibration::HURST;
use terrasketch_detail::noise::Octaves;
use terrasketch_detail::{
    AmplitudeInputs, HardCells, Shape, add_band_detail, add_detail, amplitude_map, amplitude_side,
    cell_min_wavelength_m, detail_field, fbm_bound, hard_counts, max_pyramid, sample_bilinear,
    seed32,
};
use terrasketch_multigrid::{CpuSolver, Grid, SolverParams};
use terrasketch_sketch::{Sketch, example_sketch};

/// Solves `sketch` at `n` and returns (grid, heights, amplitude map, elevation weights, values).
fn solved(sketch: &Sketch, n: usize) -> (Grid, Vec<f32>, Vec<f32>, Vec<f32>, Vec<f32>, f32) {
    let grid = Grid::new(n, sketch.extent_m).expect("grid");
    let mut s = CpuSolver::new(grid, SolverParams::default()).expect("solver");
    s.set_sketch(sketch);
    s.solve();
    let rough = s.roughness().to_vec();
    let weights = s.constraints().elev_weight.clone();
    let counts = hard_counts(n, &weights);
    let [dx, dy] = grid.cell_size_m();
    let amp = amplitude_map(&AmplitudeInputs {
        m: amplitude_side(n),
        cell_m: [2.0 * dx as f32, 2.0 * dy as f32],
        heights: s.mip(AMPLITUDE_LEVEL as usize),
        roughness: &rough,
        roughness_side: n / 4,
        hard: HardCells::Counts(&counts),
    });
    (
        grid,
        s.heights().to_vec(),
        amp,
        weights,
        s.elevation_values().to_vec(),
        s.relief_m(),
    )
}

#[test]
fn hard_constraints_hold_with_detail_and_the_rest_gets_calibrated_relief() {
    let sketch = example_sketch();
    let n = 256;
    let (_, mut h, amp, w, e, relief) = solved(&sketch, n);
    let before = h.clone();
    add_detail(&mut h, n, sketch.extent_m, &amp, sketch.seed);
    let (mut worst, mut hard) = (0.0f32, 0);
    for i in 0..n * n {
        if w[i] >= 1.0 {
            hard += 1;
            worst = worst.max((h[i] - e[i]).abs() / relief);
        }
    }
    assert!(hard > 500, "{hard} hard texels");
    assert!(worst <= 1e-3, "a hard texel moved by {worst} of the relief");
    let rms = (h
        .iter()
        .zip(&before)
        .map(|(a, b)| ((a - b) as f64).powi(2))
        .sum::<f64>()
        / (n * n) as f64)
        .sqrt();
    // The calibrated law gives metres to tens of metres on the example's slopes.
    assert!(rms > 2.0 && rms < 60.0, "detail RMS {rms} m");
}

#[test]
fn amplitude_grows_with_slope_and_vanishes_without_roughness() {
    let m = 32;
    let cell = [40.0f32, 40.0];
    // A plane tilted in x: slope tangent t.
    let plane = |t: f32| -> Vec<f32> { (0..m * m).map(|k| (k % m) as f32 * cell[0] * t).collect() };
    let counts = vec![0u32; m * m];
    let at = |t: f32, r: f32| {
        let heights = plane(t);
        let rough = vec![r; m * m];
        amplitude_map(&AmplitudeInputs {
            m,
            cell_m: cell,
            heights: &heights,
            roughness: &rough,
            roughness_side: m,
            hard: HardCells::Counts(&counts),
        })[m * m / 2 + m / 2]
    };
    assert!(at(0.3, 0.5) > 2.0 * at(0.05, 0.5));
    assert!(at(0.05, 0.5) > at(0.0, 0.5) && at(0.0, 0.5) > 0.0);
    assert_eq!(at(0.3, 0.0), 0.0);
    assert!((at(0.3, 1.0) / at(0.3, 0.5) - 2.0).abs() < 1e-5);
}

/// The row kernel equals the law cell by cell: the fade of the direct Chebyshev distance to a
/// block with a hard cell, times the law of the gradient `gradient_at` reads and the roughness of
/// the covering cell; and the solver's constraint summary, read in place, gives the same map.
#[test]
fn the_map_is_the_law_of_each_cell_and_the_summary_equals_the_counts() {
    let sketch = example_sketch();
    let n = 128;
    let (grid, _, amp, w, _, _) = solved(&sketch, n);
    let m = amplitude_side(n);
    let counts = hard_counts(n, &w);
    let mut s = CpuSolver::new(grid, SolverParams::default()).expect("solver");
    s.set_sketch(&sketch);
    s.solve();
    let rough = s.roughness().to_vec();
    let [dx, dy] = grid.cell_size_m();
    let cell_m = [2.0 * dx as f32, 2.0 * dy as f32];
    let mip = s.mip(AMPLITUDE_LEVEL as usize);
    let from_summary = amplitude_map(&AmplitudeInputs {
        m,
        cell_m,
        heights: mip,
        roughness: &rough,
        roughness_side: n / 4,
        hard: HardCells::Summary(s.hard_summary(AMPLITUDE_LEVEL)),
    });
    assert_eq!(from_summary, amp);
    let reach = ZERO_CELLS + FADE_CELLS;
    let (mut faded, mut zero) = (0, 0);
    for j in 0..m {
        for i in 0..m {
            let mut d = reach + 1;
            for y in j.saturating_sub(reach as usize)..(j + reach as usize + 1).min(m) {
                for x in i.saturating_sub(reach as usize)..(i + reach as usize + 1).min(m) {
                    if counts[y * m + x] > 0 {
                        d = d.min(x.abs_diff(i).max(y.abs_diff(j)) as i32);
                    }
                }
            }
            let [gx, gy] = gradient_at(mip, m, cell_m, i, j);
            let r = rough[(j / 2) * (n / 4) + i / 2];
            let want = fade(d) * amplitude_law((gx * gx + gy * gy).sqrt(), r);
            let got = amp[j * m + i];
            assert!(
                (got - want).abs() <= 1e-6 * want.abs().max(1e-3),
                "({i}, {j}): {got} against {want}"
            );
            faded += usize::from(d <= reach && d > ZERO_CELLS);
            zero += usize::from(d <= ZERO_CELLS);
        }
    }
    assert!(
        faded > 100 && zero > 100,
        "{faded} faded, {zero} zero cells"
    );
}

#[test]
fn the_fade_is_zero_next_to_hard_cells_and_full_further_out() {
    let m = 32;
    let mut counts = vec![0u32; m * m];
    counts[16 * m + 16] = 3;
    let flat = vec![0.0f32; m * m];
    let rough = vec![0.5f32; m * m];
    let amp = amplitude_map(&AmplitudeInputs {
        m,
        cell_m: [40.0, 40.0],
        heights: &flat,
        roughness: &rough,
        roughness_side: m,
        hard: HardCells::Counts(&counts),
    });
    let full = amp[0];
    assert!(full > 0.0);
    for (d, want) in [(0, 0.0), (1, 0.0), (2, 0.5), (3, 1.0), (5, 1.0)] {
        let got = amp[16 * m + 16 + d] / full;
        assert!((got - want).abs() < 1e-6, "distance {d}: {got}");
        let got = amp[(16 + d) * m + 16 - d] / full;
        assert!((got - want).abs() < 1e-6, "diagonal {d}: {got}");
    }
}

#[test]
fn the_fade_around_a_hard_line_is_a_few_level_0_cells_wide() {
    // A hard column at x = 64 on flat land: the amplitude as the texels sample it is zero within
    // 1-2 cells, full from 6-7 (the fade of 2 x 2 blocks, sampled bilinearly).
    let n = 128;
    let m = amplitude_side(n);
    let mut weights = vec![0.0f32; n * n];
    for j in 0..n {
        weights[j * n + 64] = 1.0;
    }
    let counts = hard_counts(n, &weights);
    let amp = amplitude_map(&AmplitudeInputs {
        m,
        cell_m: [20.0, 20.0],
        heights: &vec![0.0; m * m],
        roughness: &vec![0.5; (n / 4) * (n / 4)],
        roughness_side: n / 4,
        hard: HardCells::Counts(&counts),
    });
    let at = |i: usize| sample_bilinear(&amp, m, (i as f32 + 0.5) / n as f32, 0.5);
    let full = at(10);
    assert!(full > 0.0);
    for i in 63..=66 {
        assert_eq!(at(i), 0.0, "column {i}");
    }
    for i in [56, 58, 71, 73] {
        assert!(
            (at(i) - full).abs() < 1e-6,
            "column {i}: {} vs {full}",
            at(i)
        );
    }
    for i in [60, 62, 67, 69] {
        assert!(at(i) > 0.0 && at(i) < full, "column {i}: {}", at(i));
    }
}

#[test]
fn the_seed_decides_the_detail_and_the_same_seed_repeats_it() {
    let n = 128;
    let amp = vec![10.0f32; amplitude_side(n).pow(2)];
    let a = detail_field(n, [5000.0, 5000.0], &amp, 1);
    let b = detail_field(n, [5000.0, 5000.0], &amp, 1);
    let c = detail_field(n, [5000.0, 5000.0], &amp, 2);
    assert_eq!(a, b);
    let diff = a
        .iter()
        .zip(&c)
        .filter(|(x, y)| (*x - *y).abs() > 1e-3)
        .count();
    assert!(diff > n * n / 2, "seeds 1 and 2 differ at {diff} texels");
}

#[test]
fn the_row_evaluation_is_the_point_evaluation() {
    let n = 100;
    let ex = 3000.0f32;
    for seed in [0u64, 77, u64::MAX] {
        let o = Octaves::new(7.5, seed32(seed), HURST);
        let xs: Vec<f32> = (0..n).map(|i| (i as f32 + 0.5) / n as f32 * ex).collect();
        let scale: Vec<f32> = (0..n).map(|i| if i % 7 == 0 { 0.0 } else { 1.5 }).collect();
        for y in [3.75f32, 1234.5, 2999.0] {
            let mut row = vec![0.0f32; n];
            o.add_row(&xs, y, &scale, &mut row);
            for i in 0..n {
                let want = scale[i] * o.eval(xs[i], y);
                assert!(
                    (row[i] - want).abs() <= 1e-6,
                    "{seed} {y} {i}: {} vs {want}",
                    row[i]
                );
            }
        }
    }
}

#[test]
fn the_pyramid_bound_holds_at_every_texel() {
    let sketch = example_sketch();
    let n = 256;
    let (_, _, amp, _, _, _) = solved(&sketch, n);
    let d = detail_field(n, sketch.extent_m, &amp, 3);
    let m = amplitude_side(n);
    let sides = [64usize, 16, 1];
    let maxes = max_pyramid(m, &amp, &sides);
    let bound = fbm_bound(cell_min_wavelength_m(n, sketch.extent_m));
    for (side, mx) in sides.iter().zip(&maxes) {
        for j in 0..n {
            for i in 0..n {
                let c = (j * side / n) * side + i * side / n;
                assert!(
                    d[j * n + i].abs() <= mx[c] * bound + 1e-4,
                    "side {side} ({i}, {j})"
                );
            }
        }
    }
}

#[test]
fn the_detail_is_amplitude_times_the_level_0_noise() {
    let n = 128;
    let m = amplitude_side(n);
    let amp: Vec<f32> = (0..m * m).map(|k| (k % 7) as f32).collect();
    let ex = [4000.0, 3000.0];
    let d = detail_field(n, ex, &amp, 9);
    let noise = terrasketch_detail::noise_mips(n, ex, 9);
    assert_eq!(noise.len(), 8);
    assert_eq!(noise[7].len(), 1);
    for j in 0..n {
        for i in 0..n {
            let a = terrasketch_detail::sample_bilinear(
                &amp,
                m,
                (i as f32 + 0.5) / n as f32,
                (j as f32 + 0.5) / n as f32,
            );
            let want = if a > 0.0 {
                a * noise[0][j * n + i]
            } else {
                0.0
            };
            assert!((d[j * n + i] - want).abs() <= 1e-5, "({i}, {j})");
        }
    }
}

/// RMS and mean of `v`.
fn rms_mean(v: &[f32]) -> (f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().map(|x| f64::from(*x)).sum::<f64>() / n;
    let rms = (v.iter().map(|x| f64::from(*x).powi(2)).sum::<f64>() / n).sqrt();
    (rms, mean)
}

#[test]
fn the_band_reaches_up_to_the_unresolved_scale_on_coarse_cells() {
    use terrasketch_detail::add_detail_shaped;
    // 256^2 cells of 90 m: the top is 32 cells (2.9 km), not the 512 m reference.
    let n = 256;
    let ex = [256.0 * 90.0, 256.0 * 90.0];
    assert!((Shape::CALIBRATED.top_m(90.0) - 32.0 * 90.0).abs() < 1e-3);
    assert_eq!(Shape::CALIBRATED.top_m(10.0), 512.0);
    let amp = vec![1.0f32; amplitude_side(n).pow(2)];
    let fixed = Shape {
        top_cells: 0.0,
        ..Shape::CALIBRATED
    };
    let mut wide = vec![0.0f32; n * n];
    add_detail_shaped(&mut wide, n, ex, &amp, 5, &Shape::CALIBRATED);
    let mut narrow = vec![0.0f32; n * n];
    add_detail_shaped(&mut narrow, n, ex, &amp, 5, &fixed);
    // Means over 16 x 16 cells (1.4 km): only octaves coarser than that survive.
    let blocks = |h: &[f32]| -> Vec<f32> {
        let b = 16;
        (0..(n / b) * (n / b))
            .map(|k| {
                let (bi, bj) = (k % (n / b), k / (n / b));
                let mut s = 0.0;
                for j in 0..b {
                    for i in 0..b {
                        s += h[(bj * b + j) * n + bi * b + i];
                    }
                }
                s / (b * b) as f32
            })
            .collect()
    };
    let (coarse_wide, _) = rms_mean(&blocks(&wide));
    let (coarse_narrow, _) = rms_mean(&blocks(&narrow));
    assert!(
        coarse_wide > 4.0 * coarse_narrow,
        "kilometre-scale detail {coarse_wide} vs {coarse_narrow} with the band stopping at 512 m"
    );
    // The octaves the two share are the same octaves (seed, rotation and offset per octave).
    let fine = Octaves::with_shape(90.0, seed32(5), &fixed);
    let all = Octaves::with_shape(90.0, seed32(5), &Shape::CALIBRATED);
    assert!(all.count() > fine.count() + 1);
}

#[test]
fn billow_octaves_crease_the_valleys_and_add_no_mean_height() {
    let n = 256;
    let ex = [256.0 * 25.0, 256.0 * 25.0];
    let amp = vec![1.0f32; amplitude_side(n).pow(2)];
    let d = detail_field(n, ex, &amp, 21);
    let (rms, mean) = rms_mean(&d);
    assert!(mean.abs() < 0.1 * rms, "mean {mean}, rms {rms}");
    // V-shaped minima and rounded crests: the heights are skewed upward (gradient noise is not).
    let skew = d
        .iter()
        .map(|x| (f64::from(*x) - mean).powi(3))
        .sum::<f64>()
        / (n * n) as f64
        / (rms * rms - mean * mean).powf(1.5);
    assert!(skew > 0.2, "skewness {skew}");
    // The Laplacian is larger at the valley floors (lowest tenth) than at the crests (highest tenth).
    let mut order: Vec<usize> = (n + 1..n * n - n - 1)
        .filter(|k| k % n != 0 && k % n != n - 1)
        .collect();
    order.sort_by(|a, b| d[*a].total_cmp(&d[*b]));
    let lap = |k: usize| d[k - 1] + d[k + 1] + d[k - n] + d[k + n] - 4.0 * d[k];
    let tenth = order.len() / 10;
    let low: f32 = order[..tenth].iter().map(|k| lap(*k)).sum::<f32>() / tenth as f32;
    let high: f32 = -order[order.len() - tenth..]
        .iter()
        .map(|k| lap(*k))
        .sum::<f32>()
        / tenth as f32;
    assert!(
        low > 1.3 * high,
        "valley curvature {low}, crest curvature {high}"
    );
}

#[test]
fn coarse_mips_keep_level_0_band_and_its_bound() {
    // 90 m cells: level 0's top is 2.9 km; level 3 (720 m cells) must not add octaves above it.
    let n = 256;
    let ex = [256.0 * 90.0, 256.0 * 90.0];
    let noise = terrasketch_detail::noise_mips(n, ex, 4);
    let bound = fbm_bound(cell_min_wavelength_m(n, ex));
    for (k, level) in noise.iter().enumerate() {
        let top = level.iter().fold(0.0f32, |a, b| a.max(b.abs()));
        assert!(
            top <= bound,
            "mip {k}: |noise| {top} over the bound {bound}"
        );
    }
    // Level 1 is close to level 0 averaged over 2 x 2 (the same octaves but the finest).
    let (l0, l1) = (&noise[0], &noise[1]);
    let h = n / 2;
    let mut diff = 0.0f64;
    let mut power = 0.0f64;
    for j in 0..h {
        for i in 0..h {
            let avg = 0.25
                * (l0[2 * j * n + 2 * i]
                    + l0[2 * j * n + 2 * i + 1]
                    + l0[(2 * j + 1) * n + 2 * i]
                    + l0[(2 * j + 1) * n + 2 * i + 1]);
            diff += f64::from(avg - l1[j * h + i]).powi(2);
            power += f64::from(l1[j * h + i]).powi(2);
        }
    }
    assert!(
        diff < 0.2 * power,
        "level 1 differs from level 0's average: {diff} of {power}"
    );
}

#[test]
fn a_band_under_half_a_cell_is_nothing() {
    let (n, cell) = (64usize, 10.0f32);
    let m = n / 4;
    let band = |top: f32| {
        let mut h = vec![0.0f32; n * n];
        let (amp, tops, slope) = (
            vec![5.0; m * m],
            vec![top; m * m],
            vec![[0.3f32, 0.0]; m * m],
        );
        add_band_detail(&mut h, n, cell, [0.0, 0.0], &amp, &tops, &slope, 5);
        h
    };
    assert!(band(4.0).iter().all(|v| *v == 0.0));
    assert!(band(40.0).iter().any(|v| v.abs() > 0.1));
}

/// RMS of the differences between neighbours along x and along y.
fn step_rms(h: &[f32], n: usize) -> (f64, f64) {
    let (mut sx, mut sy) = (0.0f64, 0.0f64);
    for y in 0..n - 1 {
        for x in 0..n - 1 {
            sx += f64::from(h[y * n + x + 1] - h[y * n + x]).powi(2);
            sy += f64::from(h[(y + 1) * n + x] - h[y * n + x]).powi(2);
        }
    }
    let c = ((n - 1) * (n - 1)) as f64;
    ((sx / c).sqrt(), (sy / c).sqrt())
}

#[test]
fn the_bands_creases_run_down_the_slope() {
    let (n, cell) = (256usize, 10.0f32);
    let m = n / 4;
    let band = |g: [f32; 2]| {
        let mut h = vec![0.0f32; n * n];
        let slope = vec![g; m * m];
        add_band_detail(
            &mut h,
            n,
            cell,
            [0.0, 0.0],
            &vec![10.0; m * m],
            &vec![160.0; m * m],
            &slope,
            3,
        );
        step_rms(&h, n)
    };
    // Land falling along x: the creases run along x, so the heights change less along x.
    let (ax, ay) = band([0.5, 0.0]);
    assert!(ay > 1.2 * ax, "along x {ax}, across {ay}");
    let (bx, by) = band([0.0, -0.5]);
    assert!(bx > 1.2 * by, "across {bx}, along y {by}");
    // On the flat no direction wins.
    let (fx, fy) = band([0.0, 0.0]);
    assert!((fx / fy - 1.0).abs() < 0.1, "flat: {fx} against {fy}");
}

#[test]
fn the_band_holds_no_relief_coarser_than_twice_its_top() {
    let (n, cell) = (256usize, 10.0f32);
    let m = n / 4;
    let amp = vec![10.0f32; m * m];
    let mut whole = vec![0.0f32; n * n];
    let flat = vec![[0.0f32; 2]; m * m];
    add_band_detail(
        &mut whole,
        n,
        cell,
        [0.0, 0.0],
        &amp,
        &vec![1e9; m * m],
        &flat,
        9,
    );
    let mut band = vec![0.0f32; n * n];
    add_band_detail(
        &mut band,
        n,
        cell,
        [0.0, 0.0],
        &amp,
        &vec![40.0; m * m],
        &flat,
        9,
    );
    // Means over 16 x 16 cells (160 m) keep what is coarser than the band's 80 m cut-off.
    let coarse_rms = |h: &[f32]| -> f64 {
        let k = n / 16;
        let mut s = 0.0f64;
        for by in 0..k {
            for bx in 0..k {
                let mut b = 0.0f64;
                for y in 16 * by..16 * by + 16 {
                    for x in 16 * bx..16 * bx + 16 {
                        b += f64::from(h[y * n + x]);
                    }
                }
                s += (b / 256.0).powi(2);
            }
        }
        (s / (k * k) as f64).sqrt()
    };
    let rms =
        |h: &[f32]| (h.iter().map(|v| f64::from(*v).powi(2)).sum::<f64>() / h.len() as f64).sqrt();
    assert!(rms(&band) > 0.02 * rms(&whole), "the band is empty");
    assert!(
        coarse_rms(&band) < 0.1 * coarse_rms(&whole),
        "coarse relief {} of the band against {} of the whole sum",
        coarse_rms(&band),
        coarse_rms(&whole)
    );
}

#[test]
fn a_tile_of_the_band_draws_what_its_world_draws() {
    let (n, cell) = (64usize, 10.0f32);
    let m = n / 4;
    let tilt = vec![[0.3f32, -0.2]; m * m];
    let mut world = vec![0.0f32; n * n];
    add_band_detail(
        &mut world,
        n,
        cell,
        [-320.0, 160.0],
        &vec![4.0; m * m],
        &vec![80.0; m * m],
        &tilt,
        2,
    );
    let t = 32usize;
    let mut tile = vec![0.0f32; t * t];
    let (ox, oy) = (16usize, 8usize);
    let origin = [-320.0 + ox as f32 * cell, 160.0 + oy as f32 * cell];
    add_band_detail(
        &mut tile,
        t,
        cell,
        origin,
        &vec![4.0; 64],
        &vec![80.0; 64],
        &tilt[..64],
        2,
    );
    for y in 0..t {
        for x in 0..t {
            let (a, b) = (tile[y * t + x], world[(y + oy) * n + x + ox]);
            assert!(
                (a - b).abs() <= 1e-4 * (1.0 + b.abs()),
                "({x}, {y}): {a} against {b}"
            );
        }
    }
}
