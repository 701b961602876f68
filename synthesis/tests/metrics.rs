//! Terrain metrics on fields with known answers, and the values of the shipped exemplars.

mod common;

use std::f64::consts::PI;

use terrasketch_synthesis::metrics::{
    SLOPE_BINS, compare, dem_metrics, terrain_metrics, terrain_metrics_with, wasserstein_binned,
};
use terrasketch_synthesis::protocol::square_at_own_cell;
use terrasketch_synthesis::{LoadOptions, load_dem, load_exemplar_dir, shipped_exemplar_dir};

/// Small deterministic generator (SplitMix64), uniform in [0, 1).
struct Rng(u64);

impl Rng {
    fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn ramp(w: usize, h: usize, dz_per_cell: f32) -> Vec<f32> {
    (0..w * h).map(|i| (i % w) as f32 * dz_per_cell).collect()
}

#[test]
fn a_plane_has_its_slope_everywhere() {
    let (w, h) = (64, 48);
    // 10 m per 10 m cell east-west: 45 degrees.
    let m = terrain_metrics(&ramp(w, h, 10.0), w, h, [10.0, 10.0]);
    assert!((m.slope_mean_deg - 45.0).abs() < 1e-9);
    assert!((m.slope_p90_deg - 45.0).abs() < 1e-9);
    assert_eq!(m.slope_histogram.len(), SLOPE_BINS);
    assert!((m.slope_histogram[45] - 1.0).abs() < 1e-9);
    assert!(m.laplacian_mean_abs_per_m.abs() < 1e-9 && m.laplacian_std_per_m.abs() < 1e-9);
    assert!((m.hypsometric_integral - 0.5).abs() < 1e-9);
    assert_eq!(m.pit_count, 0);
    // The cell size of each axis is used: 10 m per 20 m cell is atan(0.5).
    let m = terrain_metrics(&ramp(w, h, 10.0), w, h, [20.0, 5.0]);
    assert!((m.slope_mean_deg - 0.5f64.atan().to_degrees()).abs() < 1e-6);
}

#[test]
fn paraboloid_laplacian_and_hypsometry() {
    let (w, h) = (41, 41);
    // z = (x^2 + y^2) m with 1 m cells: Laplacian 4 everywhere.
    let z: Vec<f32> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32 - 20.0, (i / w) as f32 - 20.0);
            x * x + y * y
        })
        .collect();
    let m = terrain_metrics(&z, w, h, [1.0, 1.0]);
    assert!((m.laplacian_mean_abs_per_m - 4.0).abs() < 1e-6);
    assert!(m.laplacian_std_per_m < 1e-6);
    // A bowl is concave up: most of its area is low, HI well under 0.5.
    assert!(m.hypsometric_integral < 0.45, "{}", m.hypsometric_integral);
}

/// A periodic random field with 2-D radial power `k^-beta` on integer wavevectors up to `kmax`.
fn power_law_field(n: usize, beta: f64, kmax: i64, seed: u64) -> Vec<f32> {
    let mut rng = Rng(seed);
    let mut z = vec![0.0f64; n * n];
    let mut waves = Vec::new();
    for ky in 0..=kmax {
        for kx in -kmax..=kmax {
            if ky == 0 && kx <= 0 {
                continue;
            }
            let k = ((kx * kx + ky * ky) as f64).sqrt();
            if k > kmax as f64 {
                continue;
            }
            waves.push((
                kx as f64,
                ky as f64,
                k.powf(-beta / 2.0),
                2.0 * PI * rng.unit(),
            ));
        }
    }
    for (i, v) in z.iter_mut().enumerate() {
        let (x, y) = ((i % n) as f64, (i / n) as f64);
        for &(kx, ky, a, phase) in &waves {
            *v += a * (2.0 * PI * (kx * x + ky * y) / n as f64 + phase).cos();
        }
    }
    z.iter().map(|&v| (1000.0 + 300.0 * v) as f32).collect()
}

#[test]
fn spectral_slope_of_a_power_law_field() {
    let n = 128;
    for beta in [3.0, 4.0] {
        let z = power_law_field(n, beta, 48, 3);
        let m = terrain_metrics(&z, n, n, [30.0, 30.0]);
        let s = m.spectral_slope.unwrap();
        eprintln!(
            "beta {beta}: measured {s:.3}, band {:?} m",
            m.spectrum_band_m
        );
        assert!((s + beta).abs() < 0.25, "beta {beta}: measured {s}");
        assert_eq!(m.spectrum_window_cells, 128);
    }
    // A plane plus a little rough noise: detrending removes the plane's huge edge step, so the
    // spectrum is that of the noise (flat, slope near 0), not the plane's k^-2 leakage.
    let mut rng = Rng(5);
    let z: Vec<f32> = ramp(n, n, 10.0)
        .iter()
        .map(|v| v + rng.unit() as f32)
        .collect();
    let s = terrain_metrics(&z, n, n, [30.0, 30.0])
        .spectral_slope
        .unwrap();
    assert!(s.abs() < 0.3, "{s}");
    // Too small for a spectrum.
    assert_eq!(
        terrain_metrics(&ramp(10, 10, 1.0), 10, 10, [1.0, 1.0]).spectral_slope,
        None
    );
}

/// Two waves along x, 5 and 40 cycles per window, amplitudes 10 and 1: each octave holds its own
/// wave's power (ratio 100), the other octaves next to nothing, and the wavelengths are in metres.
#[test]
fn octave_power_puts_each_wave_in_its_octave() {
    let n = 128;
    let wave = |k: f64, i: usize| (2.0 * PI * k * (i % n) as f64 / n as f64).cos();
    let z: Vec<f32> = (0..n * n)
        .map(|i| (500.0 + 10.0 * wave(5.0, i) + wave(40.0, i)) as f32)
        .collect();
    let m = terrain_metrics(&z, n, n, [10.0, 10.0]);
    let o = &m.octave_power;
    // Octaves [1,2) .. [64,65): 7 of them, the first from 1280 m.
    assert_eq!(o.len(), 7, "{o:?}");
    assert_eq!((o[0].longest_m, o[0].shortest_m), (1280.0, 1280.0));
    assert_eq!((o[2].longest_m, o[2].shortest_m), (320.0, 1280.0 / 7.0));
    let total: f64 = o.iter().map(|b| b.power_m2).sum();
    let (low, high) = (o[2].power_m2, o[5].power_m2);
    assert!((low + high) / total > 0.99, "{o:?}");
    assert!((80.0..125.0).contains(&(low / high)), "{}", low / high);
    // Twice the relief is 4 times the power in each octave, and a reference of another cell size
    // has no per-octave ratio.
    let doubled: Vec<f32> = z.iter().map(|v| 2.0 * v).collect();
    let ratio = compare(&terrain_metrics(&doubled, n, n, [10.0, 10.0]), &m)
        .octave_power_ratio
        .expect("same window and cell size");
    assert!(
        ratio
            .iter()
            .all(|r| (r - 4.0).abs() < 1e-6 * 4.0 || *r == 0.0),
        "{ratio:?}"
    );
    assert!((ratio[2] - 4.0).abs() < 1e-6, "{ratio:?}");
    let other = terrain_metrics(&z, n, n, [20.0, 20.0]);
    assert_eq!(compare(&other, &m).octave_power_ratio, None);
    // Too small for a spectrum.
    assert!(
        terrain_metrics(&ramp(10, 10, 1.0), 10, 10, [1.0, 1.0])
            .octave_power
            .is_empty()
    );
}

#[test]
fn smoothing_steepens_the_spectrum_and_narrows_slopes() {
    let n = 128;
    let rough = power_law_field(n, 3.0, 60, 8);
    // Five passes of a 3x3 box blur (wrapping): a diffusion-like smoothing.
    let mut smooth = rough.clone();
    for _ in 0..5 {
        let prev = smooth.clone();
        for y in 0..n {
            for x in 0..n {
                let mut s = 0.0;
                for dy in [n - 1, 0, 1] {
                    for dx in [n - 1, 0, 1] {
                        s += prev[(y + dy) % n * n + (x + dx) % n];
                    }
                }
                smooth[y * n + x] = s / 9.0;
            }
        }
    }
    let a = terrain_metrics(&rough, n, n, [30.0, 30.0]);
    let b = terrain_metrics(&smooth, n, n, [30.0, 30.0]);
    let c = compare(&b, &a);
    eprintln!("{c:?}");
    assert!(c.spectral_slope_diff.unwrap() < -1.0);
    assert!(c.slope_mean_diff_deg < 0.0 && c.slope_wasserstein_deg > 0.5);
    assert_eq!(compare(&a, &a).slope_wasserstein_deg, 0.0);
    assert_eq!(compare(&a, &a).spectral_slope_diff, Some(0.0));
}

#[test]
fn wasserstein_between_histograms() {
    let mut a = vec![0.0; SLOPE_BINS];
    let mut b = vec![0.0; SLOPE_BINS];
    a[10] = 1.0;
    b[20] = 1.0;
    assert!((wasserstein_binned(&a, &b) - 10.0).abs() < 1e-12);
    assert!((wasserstein_binned(&b, &a) - 10.0).abs() < 1e-12);
    // Half the mass moved by 10 bins: 5 degrees. Unnormalised input is normalised.
    let c: Vec<f64> = a.iter().zip(&b).map(|(x, y)| 3.0 * (x + y)).collect();
    assert!((wasserstein_binned(&a, &c) - 5.0).abs() < 1e-12);
    // Planes at 10 and 30 degrees, measured end to end.
    let (w, h) = (32, 32);
    let m10 = terrain_metrics(&ramp(w, h, 10f32.to_radians().tan()), w, h, [1.0, 1.0]);
    let m30 = terrain_metrics(&ramp(w, h, 30f32.to_radians().tan()), w, h, [1.0, 1.0]);
    let d = compare(&m10, &m30).slope_wasserstein_deg;
    assert!((d - 20.0).abs() < 1.0, "{d}");
}

#[test]
fn pits_are_counted_by_depth_and_area() {
    let (w, h) = (100, 100);
    let mut z = ramp(w, h, 1.0);
    // Three conical pits 25 m deep and one 8 m deep (walls steeper than the 1 m per cell ramp).
    for (cx, cy, depth) in [
        (30.0, 30.0, 25.0),
        (70.0, 30.0, 25.0),
        (50.0, 70.0, 25.0),
        (20.0, 80.0, 8.0),
    ] {
        for y in 0..h {
            for x in 0..w {
                let d = ((x as f32 - cx).powi(2) + (y as f32 - cy).powi(2)).sqrt();
                if d < 5.0 {
                    z[y * w + x] -= depth * (1.0 - d / 5.0);
                }
            }
        }
    }
    // 100 x 100 cells of 100 m: 100 km^2.
    let m = terrain_metrics(&z, w, h, [100.0, 100.0]);
    assert_eq!(m.pit_count, 3);
    assert!((m.pits_per_100km2 - 3.0).abs() < 1e-9);
    assert_eq!(
        terrain_metrics_with(&z, w, h, [100.0, 100.0], 1.0).pit_count,
        4
    );
}

#[test]
fn bad_input_gives_empty_metrics_and_json_works() {
    let m = terrain_metrics(&[1.0; 5], 3, 3, [1.0, 1.0]);
    assert_eq!((m.pit_count, m.spectral_slope), (0, None));
    let m = terrain_metrics(&[], 0, 0, [1.0, 1.0]);
    assert_eq!(m.pit_count, 0);
    let m = terrain_metrics(&[f32::NAN; 9], 3, 3, [1.0, 1.0]);
    assert_eq!(m.slope_mean_deg, 0.0);
    let m = terrain_metrics(&[1.0; 9], 3, 3, [0.0, 1.0]);
    assert_eq!(m.slope_mean_deg, 0.0);
    let json =
        serde_json::to_string(&terrain_metrics(&ramp(20, 20, 1.0), 20, 20, [1.0, 1.0])).unwrap();
    assert!(json.contains("\"slope_mean_deg\":45"));
    assert!(json.contains("\"spectral_slope\""));
}

#[test]
fn shipped_exemplar_metrics() {
    let (dems, failures) = load_exemplar_dir(&shipped_exemplar_dir());
    assert!(failures.is_empty() && dems.len() == 5);
    eprintln!(
        "| exemplar | slope mean | slope p90 | Lap. mean abs (1/m) | spectral slope | band (m) | pits >10 m | per 100 km2 | HI |"
    );
    for dem in &dems {
        let t = std::time::Instant::now();
        let m = dem_metrics(dem);
        eprintln!(
            "| {} | {:.2} | {:.2} | {:.2e} | {:.2} | {:.0}-{:.0} | {} | {:.2} | {:.3} | ({:?})",
            dem.name,
            m.slope_mean_deg,
            m.slope_p90_deg,
            m.laplacian_mean_abs_per_m,
            m.spectral_slope.unwrap_or(f64::NAN),
            m.spectrum_band_m[0],
            m.spectrum_band_m[1],
            m.pit_count,
            m.pits_per_100km2,
            m.hypsometric_integral,
            t.elapsed()
        );
        let s = m.spectral_slope.unwrap();
        // Real terrain: radial 2-D spectra between k^-2 and k^-5 in the fitted band.
        assert!((-5.0..=-2.0).contains(&s), "{}: {s}", dem.name);
        assert!(m.slope_p90_deg > m.slope_mean_deg && m.slope_mean_deg > 0.5);
        assert!(m.hypsometric_integral > 0.05 && m.hypsometric_integral < 0.95);
        assert!((m.slope_histogram.iter().sum::<f64>() - 1.0).abs() < 1e-9);
    }
    // A loaded file directly, and an exemplar compared with itself.
    let z = load_dem(
        &common::exemplar("zurich_dhm25.tif"),
        &LoadOptions::default(),
    )
    .unwrap();
    let m = dem_metrics(&z);
    assert_eq!(compare(&m, &m).slope_wasserstein_deg, 0.0);
}

#[test]
fn flat_fraction_of_planes_and_roughness_cv() {
    let n = 64;
    // 0.2 m per 10 m cell (1.15 degrees): all flat; 0.5 m (2.9 degrees): none.
    let m = terrain_metrics(&ramp(n, n, 0.2), n, n, [10.0, 10.0]);
    assert_eq!(m.flat_fraction, 1.0);
    assert_eq!(m.roughness_cv, 0.0, "a plane has no local roughness at all");
    let m = terrain_metrics(&ramp(n, n, 0.5), n, n, [10.0, 10.0]);
    assert_eq!(m.flat_fraction, 0.0);
    // Uniform noise everywhere: every tile about as rough as the others.
    let mut rng = Rng(11);
    let noise: Vec<f32> = (0..n * n).map(|_| 20.0 * rng.unit() as f32).collect();
    let uniform = terrain_metrics(&noise, n, n, [10.0, 10.0]);
    assert!(uniform.roughness_cv < 0.15, "{}", uniform.roughness_cv);
    // The same noise on the west half only, the east half a plane: half the tiles have no
    // roughness, so the CV is about 1 (mean s/2, standard deviation s/2).
    let half: Vec<f32> = (0..n * n)
        .map(|i| if i % n < n / 2 { noise[i] } else { 10.0 })
        .collect();
    let m = terrain_metrics(&half, n, n, [10.0, 10.0]);
    // (The tile column east of the boundary picks up some slope from it, hence not exactly 1.)
    assert!(
        m.roughness_cv > 0.7 && m.roughness_cv > 5.0 * uniform.roughness_cv,
        "{} vs uniform {}",
        m.roughness_cv,
        uniform.roughness_cv
    );
    assert!(m.flat_fraction > 0.45 && m.flat_fraction < 0.55);
}

#[test]
fn axis_ratio_sees_axis_aligned_steps_and_not_isotropic_land() {
    let n = 128;
    let iso = power_law_field(n, 3.0, 60, 4);
    let a = terrain_metrics(&iso, n, n, [30.0, 30.0])
        .axis_ratio
        .unwrap();
    // Central differences damp the axes' highest frequencies more than the diagonals', so
    // isotropic land sits below 1 (about 0.7).
    assert!((0.55..0.9).contains(&a), "isotropic field: {a}");
    // The same land with 8 m steps along rows and columns at irregular spacings of 3 to 9 cells
    // (terraces, or the straight seams of a patch lattice).
    let mut rng = Rng(9);
    let mut cuts = vec![0usize; n];
    let mut next = 0usize;
    for (i, c) in cuts.iter_mut().enumerate() {
        if i == next {
            next += 3 + (rng.unit() * 7.0) as usize;
        }
        *c = next;
    }
    let steps: Vec<f32> = iso
        .iter()
        .enumerate()
        .map(|(i, v)| v + 8.0 * (cuts[i % n] + cuts[i / n]) as f32)
        .collect();
    let s = terrain_metrics(&steps, n, n, [30.0, 30.0])
        .axis_ratio
        .unwrap();
    assert!(s > 1.3 * a, "steps: {s}, without: {a}");
    // Diagonal steps (lines x + y = const) hardly change it.
    let diag: Vec<f32> = iso
        .iter()
        .enumerate()
        .map(|(i, v)| v + 8.0 * ((i % n + i / n) / 8) as f32)
        .collect();
    let d = terrain_metrics(&diag, n, n, [30.0, 30.0])
        .axis_ratio
        .unwrap();
    assert!(
        d < 1.1 * a && d < s,
        "diagonal steps: {d}, axis steps {s}, none: {a}"
    );
    assert_eq!(
        terrain_metrics(&ramp(8, 8, 1.0), 8, 8, [1.0; 2]).axis_ratio,
        None
    );
}

#[test]
fn trenches_are_straight_one_cell_runs() {
    let (w, h) = (40, 30);
    let base = ramp(w, h, 0.5);
    let carve = |cells: &[(usize, usize)], depth: f32| {
        let mut z = base.clone();
        for &(x, y) in cells {
            z[y * w + x] -= depth;
        }
        z
    };
    let row = |y: usize, x0: usize, len: usize| (x0..x0 + len).map(|x| (x, y)).collect::<Vec<_>>();
    let count = |z: &[f32]| terrain_metrics(z, w, h, [10.0, 10.0]).trenches;
    assert_eq!(count(&base), 0);
    assert_eq!(count(&carve(&row(10, 5, 8), 3.0)), 1, "8 cells, 3 m deep");
    assert_eq!(count(&carve(&row(10, 5, 7), 3.0)), 0, "too short");
    assert_eq!(count(&carve(&row(10, 5, 20), 1.5)), 0, "too shallow");
    // A column trench (the ramp rises along x, so the left neighbour is 0.5 m lower).
    let col: Vec<(usize, usize)> = (3..15).map(|y| (20, y)).collect();
    assert_eq!(count(&carve(&col, 3.0)), 1);
    assert_eq!(
        count(&carve(&col, 2.4)),
        0,
        "only 1.9 m below its west neighbour"
    );
    // Two cells wide: no cell is below both neighbours across the run.
    let mut wide = row(10, 5, 12);
    wide.extend(row(11, 5, 12));
    assert_eq!(count(&carve(&wide, 5.0)), 0);
    // A run broken in the middle into 9 + 9 cells: two trenches.
    let mut broken = row(20, 2, 9);
    broken.extend(row(20, 12, 9));
    assert_eq!(count(&carve(&broken, 4.0)), 2);
}

#[test]
fn shipped_exemplars_new_descriptors() {
    // Each DEM on its own grid, centred power-of-two square (the values in the README's
    // metrics table): (name, flat_fraction, roughness_cv, axis_ratio).
    let expected = [
        ("grand_canyon_terrarium_z11", 0.049, 0.31, 0.57),
        ("jacksboro_fault_srtm3", 0.042, 0.23, 0.65),
        ("kossou_plains_srtm3", 0.517, 0.32, 0.58),
        ("sierra_nevada_north_srtm3", 0.078, 0.48, 0.62),
        ("zurich_dhm25", 0.396, 0.72, 0.48),
    ];
    let (dems, _) = load_exemplar_dir(&shipped_exemplar_dir());
    let mut bad = Vec::new();
    for (name, flat, cv, axis) in expected {
        let dem = dems.iter().find(|d| d.name == name).unwrap();
        let (h, n, cell) = square_at_own_cell(dem, 1024).unwrap();
        let m = terrain_metrics(&h, n, n, cell);
        let a = m.axis_ratio.unwrap_or(f64::NAN);
        eprintln!(
            "| {name} | {n} | {:.1} | {:.1} | {:.3} | {:.2} | {a:.2} | {:.2} | {} |",
            cell[1],
            m.slope_mean_deg,
            m.flat_fraction,
            m.roughness_cv,
            m.spectral_slope.unwrap(),
            m.trenches
        );
        if (m.flat_fraction - flat).abs() >= 0.005
            || (m.roughness_cv - cv).abs() >= 0.01
            || (a - axis).abs() >= 0.01
            || a > 0.9
        {
            bad.push(format!(
                "{name}: flat {} (LOOK {flat}), roughness_cv {} ({cv}), axis_ratio {a} ({axis})",
                m.flat_fraction, m.roughness_cv
            ));
        }
    }
    assert!(bad.is_empty(), "{bad:#?}");
}
