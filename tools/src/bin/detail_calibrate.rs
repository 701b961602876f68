//! Fits the detail's constants (`src/calibration.rs`) on the shipped exemplar DEMs and checks the fit
//! leave-one-out; writes the plot shown in the README.
//!
//! `cargo run --release -p terrasketch-tools --bin detail_calibrate -- [PLOT.png]`
//!
//! Per DEM: a Gaussian low-pass (sigma `HIGH_PASS_SIGMA_M`) stands for the smooth land the diffusion
//! draws; the residual (DEM minus low-pass) is the detail it lacks. Its RMS is binned by the
//! low-pass slope (2-degree bins, a 3-sigma border left out). The amplitude law
//! `rms = flat + per_slope * min(tan s, tan_max)` is fitted by least squares over the bins, every
//! DEM weighted equally. The Hurst exponent comes from the DEMs' spectral slopes
//! (`synthesis::metrics`, `P ~ k^beta`, `H = (-beta - 2) / 2`). The octave sum's own residual RMS
//! under the same filter (`FBM_RESIDUAL_RMS`) turns metres of residual into amplitude.

use std::path::Path;

use terrasketch_detail::amplitude::AMPLITUDE_LEVEL;
use terrasketch_detail::calibration::{
    AMPLITUDE_GAIN, FBM_RESIDUAL_RMS, HIGH_PASS_SIGMA_M, REFERENCE_WAVELENGTH_M, gaussian_blur,
};
use terrasketch_detail::noise::{Shape, fbm_with};
use terrasketch_detail::{
    AmplitudeInputs, HardCells, add_detail_shaped, amplitude_map, amplitude_side,
    cell_min_wavelength_m, fbm_bound, hard_counts,
};
use terrasketch_multigrid::{CpuSolver, Grid, SolverParams};
use terrasketch_synthesis::metrics::dem_metrics;
use terrasketch_synthesis::metrics::{compare, terrain_metrics};
use terrasketch_synthesis::{Dem, load_exemplar_dir, shipped_exemplar_dir};

const BIN_DEG: f64 = 2.0;
const BINS: usize = 25;
/// Bins with fewer cells are not fitted.
const MIN_BIN_CELLS: usize = 200;

struct Measured {
    name: String,
    cell_m: f64,
    /// Per bin: (cells, rms of the residual, metres).
    bins: Vec<(usize, f64)>,
    hurst: f64,
}

/// Residual RMS per slope bin of `h` (`w x ht`, cell `cell`): the module's measurement.
fn residual_bins(h: &[f32], w: usize, ht: usize, cell: [f64; 2]) -> Vec<(usize, f64)> {
    let sigma = [HIGH_PASS_SIGMA_M / cell[0], HIGH_PASS_SIGMA_M / cell[1]];
    let low = gaussian_blur(h, w, ht, sigma);
    let mx = (3.0 * sigma[0]).ceil() as usize + 1;
    let my = (3.0 * sigma[1]).ceil() as usize + 1;
    let mut acc = vec![(0usize, 0.0f64); BINS];
    for j in my..ht.saturating_sub(my) {
        for i in mx..w.saturating_sub(mx) {
            let gx = (low[j * w + i + 1] - low[j * w + i - 1]) as f64 / (2.0 * cell[0]);
            let gy = (low[(j + 1) * w + i] - low[(j - 1) * w + i]) as f64 / (2.0 * cell[1]);
            let deg = (gx * gx + gy * gy).sqrt().atan().to_degrees();
            let b = ((deg / BIN_DEG) as usize).min(BINS - 1);
            let r = (h[j * w + i] - low[j * w + i]) as f64;
            acc[b].0 += 1;
            acc[b].1 += r * r;
        }
    }
    acc.into_iter()
        .map(|(c, s)| (c, if c > 0 { (s / c as f64).sqrt() } else { 0.0 }))
        .collect()
}

fn bin_tan(b: usize) -> f64 {
    ((b as f64 + 0.5) * BIN_DEG).to_radians().tan()
}

fn measure(dem: &Dem) -> Measured {
    let m = dem_metrics(dem);
    let beta = m.spectral_slope.unwrap_or(-3.0);
    Measured {
        name: dem.name.clone(),
        cell_m: 0.5 * (dem.cell_size_m[0] + dem.cell_size_m[1]),
        bins: residual_bins(&dem.heights_m, dem.width, dem.height, dem.cell_size_m),
        hurst: (-beta - 2.0) / 2.0,
    }
}

/// The law fitted on `set`: (flat, per_slope, tan_max), minimising the squared log10 ratio of the
/// law to each filled bin (real land's detail varies by a factor, not by metres), every DEM weighted
/// equally and its bins by their cell counts; a grid search (the law has three parameters).
fn fit(set: &[&Measured]) -> (f64, f64, f64) {
    let cost = |flat: f64, per: f64, tan_max: f64| {
        let mut c = 0.0;
        for d in set {
            let total: usize = d
                .bins
                .iter()
                .filter(|b| b.0 >= MIN_BIN_CELLS)
                .map(|b| b.0)
                .sum();
            for (b, &(n, rms)) in d.bins.iter().enumerate() {
                if n < MIN_BIN_CELLS || rms <= 0.0 {
                    continue;
                }
                let law = flat + per * bin_tan(b).min(tan_max);
                c += n as f64 / total as f64 * (law / rms).log10().powi(2);
            }
        }
        c
    };
    let mut best = (f64::INFINITY, 0.0, 0.0, 0.0);
    for bf in 1..=40 {
        let flat = bf as f64 * 0.25;
        for bp in 1..=150 {
            let per = bp as f64;
            for bt in 2..BINS {
                let tan_max = bin_tan(bt);
                let c = cost(flat, per, tan_max);
                if c < best.0 {
                    best = (c, flat, per, tan_max);
                }
            }
        }
    }
    (best.1, best.2, best.3)
}

/// The octave sum's residual RMS under the same filter, unit amplitude, on a 512^2 grid of `cell`.
fn fbm_residual_rms(shape: &Shape, cell: f64) -> f64 {
    let n = 512;
    let h: Vec<f32> = (0..n * n)
        .map(|k| {
            let (i, j) = (k % n, k / n);
            let (x, y) = ((i as f64 + 0.5) * cell, (j as f64 + 0.5) * cell);
            fbm_with(x as f32, y as f32, cell as f32, 7, shape)
        })
        .collect();
    let bins = residual_bins(&h, n, n, [cell, cell]);
    let (c, s) = bins.iter().fold((0usize, 0.0), |(c, s), &(bc, r)| {
        (c + bc, s + r * r * bc as f64)
    });
    (s / c as f64).sqrt()
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("--protocol") {
        match args.get(1) {
            Some(dir) => protocol(Path::new(dir)),
            None => {
                eprintln!(
                    "usage: detail_calibrate --protocol DIR (a trace_protocol.sh --keep DIR)"
                );
                std::process::exit(2);
            }
        }
        return;
    }
    let plot = args.first().cloned();
    let (dems, failures) = load_exemplar_dir(&shipped_exemplar_dir());
    for (p, e) in &failures {
        eprintln!("skipped {}: {e}", p.display());
    }
    let measured: Vec<Measured> = dems.iter().map(measure).collect();
    println!("per DEM: name, cell m, Hurst, residual RMS (m) per 2-degree slope bin (cells)");
    for d in &measured {
        let bins: Vec<String> = d
            .bins
            .iter()
            .enumerate()
            .filter(|(_, b)| b.0 >= MIN_BIN_CELLS)
            .map(|(i, b)| format!("{}:{:.1}({})", i * 2, b.1, b.0))
            .collect();
        println!(
            "{} {:.1} H={:.3} {}",
            d.name,
            d.cell_m,
            d.hurst,
            bins.join(" ")
        );
    }
    let all: Vec<&Measured> = measured.iter().collect();
    let hurst = all.iter().map(|d| d.hurst).sum::<f64>() / all.len() as f64;
    let (flat, per, tan_max) = fit(&all);
    let shape = Shape {
        hurst: hurst as f32,
        ..Shape::CALIBRATED
    };
    let k = 0.5 * (fbm_residual_rms(&shape, 25.0) + fbm_residual_rms(&shape, 90.0));
    // The mean of |n| the billow octaves subtract: one octave's noise over 1000^2 points.
    let mut abs_sum = 0.0f64;
    for j in 0..1000 {
        for i in 0..1000 {
            let (x, y) = (i as f32 * 0.0731 + 0.013, j as f32 * 0.0697 + 0.021);
            abs_sum += f64::from(terrasketch_detail::noise::gradient_noise(x, y, 12345).abs());
        }
    }
    println!("BILLOW_MEAN = {:.4}", abs_sum / 1e6);
    println!(
        "\nall five: HURST = {hurst:.3}; RMS_FLAT_M = {flat:.2}; RMS_PER_SLOPE_M = {per:.2}; SLOPE_TAN_MAX = {tan_max:.3} ({:.1} deg); FBM_RESIDUAL_RMS = {k:.4} (reference octave {REFERENCE_WAVELENGTH_M} m)",
        tan_max.atan().to_degrees()
    );
    println!("\nleave-one-out: the held-out DEM's bins against the law fitted on the other four");
    println!(
        "name, Hurst (others' mean vs own), RMS log10 error of the predicted bins, mean ratio predicted/measured"
    );
    for (i, d) in measured.iter().enumerate() {
        let others: Vec<&Measured> = measured
            .iter()
            .enumerate()
            .filter(|(j, _)| *j != i)
            .map(|(_, m)| m)
            .collect();
        let h = others.iter().map(|o| o.hurst).sum::<f64>() / others.len() as f64;
        let (f, p, t) = fit(&others);
        let (mut e2, mut ratio, mut n) = (0.0, 0.0, 0.0);
        for (b, &(c, rms)) in d.bins.iter().enumerate() {
            if c < MIN_BIN_CELLS || rms <= 0.0 {
                continue;
            }
            let pred = f + p * bin_tan(b).min(t);
            e2 += (pred / rms).log10().powi(2);
            ratio += pred / rms;
            n += 1.0;
        }
        println!(
            "{}: H {h:.3} vs {:.3}; flat {f:.2} m, per slope {p:.1} m; log10 error {:.3}; ratio {:.2}",
            d.name,
            d.hurst,
            (e2 / n).sqrt(),
            ratio / n
        );
    }
    if let Some(path) = plot {
        draw_plot(&path, &measured, (flat, per, tan_max));
        println!("\nplot: {path}");
    }
}

/// Residual RMS against slope: each DEM's bins as dots (one colour each, in load order), the law as
/// a black line; x 0..50 degrees (grid every 10), y 0..100 m (grid every 20).
fn draw_plot(path: &str, measured: &[Measured], (flat, per, tan_max): (f64, f64, f64)) {
    let (w, h) = (640u32, 400u32);
    let (x0, y0, x1, y1) = (40.0, 360.0, 620.0, 20.0);
    let px = |deg: f64| x0 + (x1 - x0) * deg / 50.0;
    let py = |m: f64| y0 + (y1 - y0) * m / 100.0;
    let mut img = image::RgbImage::from_pixel(w, h, image::Rgb([255, 255, 255]));
    let put = |img: &mut image::RgbImage, x: f64, y: f64, c: [u8; 3]| {
        if x >= 0.0 && y >= 0.0 && (x as u32) < w && (y as u32) < h {
            img.put_pixel(x as u32, y as u32, image::Rgb(c));
        }
    };
    for g in 0..=5 {
        let x = px(g as f64 * 10.0);
        for y in y1 as i32..=y0 as i32 {
            put(&mut img, x, y as f64, [215, 215, 215]);
        }
        let y = py(g as f64 * 20.0);
        for x in x0 as i32..=x1 as i32 {
            put(&mut img, x as f64, y, [215, 215, 215]);
        }
    }
    let colours = [
        [200, 40, 40],
        [40, 120, 200],
        [40, 160, 60],
        [200, 120, 20],
        [140, 60, 180],
    ];
    for (d, c) in measured.iter().zip(colours.iter().cycle()) {
        for (b, &(n, rms)) in d.bins.iter().enumerate() {
            if n < MIN_BIN_CELLS {
                continue;
            }
            let (cx, cy) = (px((b as f64 + 0.5) * BIN_DEG), py(rms));
            for dy in -3..=3 {
                for dx in -3..=3 {
                    if dx * dx + dy * dy <= 9 {
                        put(&mut img, cx + dx as f64, cy + dy as f64, *c);
                    }
                }
            }
        }
    }
    for xi in 0..=(x1 - x0) as i32 * 4 {
        let deg = xi as f64 / 4.0 / (x1 - x0) * 50.0;
        let m = flat + per * deg.to_radians().tan().min(tan_max);
        for t in -1..=1 {
            put(&mut img, px(deg), py(m) + t as f64, [0, 0, 0]);
        }
    }
    if let Err(e) = img.save(path) {
        eprintln!("cannot write {path}: {e}");
    }
}

/// Band RMS of `h` between Gaussian scales `sigma / 2` and `sigma` (cells), a 3-sigma border left
/// out: the relief of the octave around wavelength `4 sigma`.
fn band_rms(h: &[f32], n: usize, sigma: f64) -> f64 {
    let fine = gaussian_blur(h, n, n, [0.5 * sigma, 0.5 * sigma]);
    let coarse = gaussian_blur(h, n, n, [sigma, sigma]);
    let b = (3.0 * sigma).ceil() as usize + 1;
    let (mut s, mut c) = (0.0, 0usize);
    for j in b..n.saturating_sub(b) {
        for i in b..n.saturating_sub(b) {
            let d = (fine[j * n + i] - coarse[j * n + i]) as f64;
            s += d * d;
            c += 1;
        }
    }
    if c > 0 { (s / c as f64).sqrt() } else { 0.0 }
}

/// The traced-sketch protocol's squares (`scripts/trace_protocol.sh --keep DIR`): each sketch
/// solved again here (CPU, diffusion only), then (1) per octave the diffusion's band RMS over the
/// DEM's: the top of the band the detail must fill is the coarsest octave where the diffusion holds
/// under half the DEM's power (ratio 0.71), and (2) the protocol's figures for candidate shapes.
/// Candidates: `DETAIL_TOPS` (cells) x plain and billow x `DETAIL_GAINS`; `DETAIL_BOUNDS=1` also
/// prints what other fades would allow ([`bounds`]).
fn protocol(dir: &Path) {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .map(|r| {
            r.filter_map(|e| e.ok())
                .filter_map(|e| {
                    let f = e.file_name().to_string_lossy().into_owned();
                    f.strip_suffix(".dem.tif").map(str::to_owned)
                })
                .collect()
        })
        .unwrap_or_default();
    names.sort();
    let gains: Vec<f32> = std::env::var("DETAIL_GAINS")
        .ok()
        .map(|v| v.split(',').filter_map(|t| t.parse().ok()).collect())
        .unwrap_or_else(|| vec![1.0]);
    let tops: Vec<f32> = std::env::var("DETAIL_TOPS")
        .ok()
        .map(|v| v.split(',').filter_map(|t| t.parse().ok()).collect())
        .unwrap_or_else(|| vec![0.0, 8.0, 16.0, 32.0]);
    let mut crossings = Vec::new();
    // Per DEM, per candidate (top, billow, gain): W1 with the detail over W1 of the diffusion alone.
    type Candidate = (f32, bool, f32);
    let mut w1_ratios: Vec<(String, Vec<(Candidate, f64)>)> = Vec::new();
    for name in &names {
        let sketch = match terrasketch_sketch::load_sketch(&dir.join(format!("{name}.json"))) {
            Ok(p) => p.sketch,
            Err(e) => {
                eprintln!("{name}: {e}");
                continue;
            }
        };
        let dem = match terrasketch_synthesis::load_dem(
            &dir.join(format!("{name}.dem.tif")),
            &Default::default(),
        ) {
            Ok(d) => d,
            Err(e) => {
                eprintln!("{name}: {e}");
                continue;
            }
        };
        let n = dem.width;
        let Ok(grid) = Grid::new(n, sketch.extent_m) else {
            continue;
        };
        let Ok(mut s) = CpuSolver::new(grid, SolverParams::default()) else {
            continue;
        };
        s.set_sketch(&sketch);
        s.solve();
        let rough = s.roughness().to_vec();
        let counts = hard_counts(n, &s.constraints().elev_weight);
        let [dx, dy] = grid.cell_size_m();
        let amp: Vec<f32> = amplitude_map(&AmplitudeInputs {
            m: amplitude_side(n),
            cell_m: [2.0 * dx as f32, 2.0 * dy as f32],
            heights: s.mip(AMPLITUDE_LEVEL as usize),
            roughness: &rough,
            roughness_side: n / 4,
            hard: HardCells::Counts(&counts),
        })
        .into_iter()
        .collect();
        let base = s.heights().to_vec();
        let cell = [dx, dy];
        // The DEM's rows are north-up, the solver's south-up: band powers do not care.
        let mut ratios = Vec::new();
        let mut sigma = 1.0;
        while 8.0 * sigma < n as f64 / 4.0 {
            let r = band_rms(&base, n, sigma) / band_rms(&dem.heights_m, n, sigma).max(1e-9);
            ratios.push((sigma, r));
            sigma *= 2.0;
        }
        let cross = ratios
            .iter()
            .filter(|(_, r)| *r < std::f64::consts::FRAC_1_SQRT_2)
            .map(|(s, _)| 4.0 * s)
            .fold(0.0, f64::max);
        crossings.push((name.clone(), cross));
        let shown: Vec<String> = ratios
            .iter()
            .map(|(s, r)| format!("{:.0}:{r:.2}", 4.0 * s))
            .collect();
        println!(
            "{name} {n}^2, cell {:.1} m: diffusion/DEM band RMS by wavelength (cells) {}; top {cross:.0} cells",
            dx,
            shown.join(" ")
        );
        let reference = terrain_metrics(&dem.heights_m, n, n, cell);
        let live = amp.iter().filter(|a| **a > 0.0).count() as f64 / amp.len() as f64;
        println!("  amplitude > 0 on {:.0} % of the blocks", 100.0 * live);
        let report = |label: &str, h: &[f32]| -> f64 {
            let m = terrain_metrics(h, n, n, cell);
            let c = compare(&m, &reference);
            println!(
                "  {label:<28} W1 {:.2}  spectral {:.2} / {:.2} ({:+.2})  flat {:.3} / {:.3} ({:.2})",
                c.slope_wasserstein_deg,
                m.spectral_slope.unwrap_or(f64::NAN),
                reference.spectral_slope.unwrap_or(f64::NAN),
                c.spectral_slope_diff.unwrap_or(f64::NAN),
                m.flat_fraction,
                reference.flat_fraction,
                m.flat_fraction / reference.flat_fraction.max(1e-9)
            );
            c.slope_wasserstein_deg
        };
        let w1_off = report("diffusion", &base);
        if std::env::var("DETAIL_BOUNDS").is_ok() {
            bounds(&BoundsInput {
                n,
                sketch: &sketch,
                base: &base,
                weights: &s.constraints().elev_weight,
                amp_free: &amplitude_map(&AmplitudeInputs {
                    m: amplitude_side(n),
                    cell_m: [2.0 * dx as f32, 2.0 * dy as f32],
                    heights: s.mip(AMPLITUDE_LEVEL as usize),
                    roughness: &rough,
                    roughness_side: n / 4,
                    hard: HardCells::Counts(&vec![0u32; counts.len()]),
                }),
                amp: &amp,
                report: &report,
            });
        }
        let mut row = Vec::new();
        let candidates: Vec<Candidate> = [false, true]
            .into_iter()
            .flat_map(|b| {
                tops.iter()
                    .flat_map(|&t| gains.iter().map(move |&g| (t, b, g)))
                    .collect::<Vec<_>>()
            })
            .collect();
        for &(top, billow, gain) in &candidates {
            {
                let shape = Shape {
                    top_cells: top,
                    billow,
                    ..Shape::CALIBRATED
                };
                // Each candidate's amplitude in its own units (its residual RMS under the filter).
                let k = 0.5 * (fbm_residual_rms(&shape, 25.0) + fbm_residual_rms(&shape, 90.0));
                let to_shape = gain / AMPLITUDE_GAIN * (f64::from(FBM_RESIDUAL_RMS) / k) as f32;
                let amp_shape: Vec<f32> = amp.iter().map(|a| a * to_shape).collect();
                let mut h = base.clone();
                add_detail_shaped(&mut h, n, sketch.extent_m, &amp_shape, sketch.seed, &shape);
                let w1 = report(&format!("top {top}, billow {billow}, gain {gain}"), &h);
                row.push(((top, billow, gain), w1 / w1_off.max(1e-9)));
            }
        }
        w1_ratios.push((name.clone(), row));
    }
    println!(
        "\nleave-one-out shape: the candidate with the least summed W1 ratio (detail on / off) on the other DEMs, and its ratio on the held-out one:"
    );
    for (i, (name, row)) in w1_ratios.iter().enumerate() {
        let best = (0..row.len())
            .min_by(|&a, &b| {
                let sum = |c: usize| -> f64 {
                    w1_ratios
                        .iter()
                        .enumerate()
                        .filter(|(j, _)| *j != i)
                        .map(|(_, r)| r.1[c].1)
                        .sum()
                };
                sum(a).total_cmp(&sum(b))
            })
            .unwrap_or(0);
        let ((top, billow, gain), r) = row[best];
        println!("{name}: top {top} cells, billow {billow}, gain {gain}; held-out W1 ratio {r:.2}");
    }
    println!("\nleave-one-out band top (mean of the other DEMs' log2 top, cells):");
    for (i, (name, _)) in crossings.iter().enumerate() {
        let others: Vec<f64> = crossings
            .iter()
            .enumerate()
            .filter(|(j, c)| *j != i && c.1 > 0.0)
            .map(|(_, c)| c.1.log2())
            .collect();
        if !others.is_empty() {
            let k = (others.iter().sum::<f64>() / others.len() as f64).exp2();
            println!("{name}: {k:.0}");
        }
    }
}

/// The inputs of [`bounds`].
struct BoundsInput<'a> {
    n: usize,
    sketch: &'a terrasketch_sketch::Sketch,
    /// The diffusion's heights.
    base: &'a [f32],
    /// Level-0 elevation weights.
    weights: &'a [f32],
    /// The amplitude map without the fade.
    amp_free: &'a [f32],
    /// The amplitude map as shipped.
    amp: &'a [f32],
    report: &'a dyn Fn(&str, &[f32]) -> f64,
}

/// What the detail could do on a square if the fade allowed it (`DETAIL_BOUNDS=1`): the shipped
/// octaves without any fade at a share of the law's amplitude (hard cells not kept: an upper
/// bound), with a fade measured in level-0 cells (zero on hard texels, full `r` cells away), and
/// with the fade's zero blocks given the amplitude that keeps the detail within a height tolerance
/// (every stroke's the same).
fn bounds(b: &BoundsInput) {
    let n = b.n;
    let extent = b.sketch.extent_m;
    let with = |amp: &[f32]| -> Vec<f32> {
        let mut h = b.base.to_vec();
        add_detail_shaped(&mut h, n, extent, amp, b.sketch.seed, &Shape::CALIBRATED);
        h
    };
    for share in [1.0f32, 0.5, 0.3, 0.2, 0.1] {
        let a: Vec<f32> = b.amp_free.iter().map(|x| x * share).collect();
        (b.report)(&format!("no fade, law x {share}"), &with(&a));
    }
    let free = with(b.amp_free);
    let hard: Vec<bool> = b.weights.iter().map(|w| *w >= 1.0).collect();
    for r in [2i32, 4] {
        let mut h = b.base.to_vec();
        for j in 0..n as i32 {
            for i in 0..n as i32 {
                let mut d2 = i32::MAX;
                for y in (j - r).max(0)..=(j + r).min(n as i32 - 1) {
                    for x in (i - r).max(0)..=(i + r).min(n as i32 - 1) {
                        if hard[y as usize * n + x as usize] {
                            d2 = d2.min((x - i) * (x - i) + (y - j) * (y - j));
                        }
                    }
                }
                let t = ((d2 as f32).sqrt() / r as f32).min(1.0);
                let k = j as usize * n + i as usize;
                h[k] += t * t * (3.0 - 2.0 * t) * (free[k] - b.base[k]);
            }
        }
        (b.report)(&format!("level-0 fade over {r} cells"), &h);
    }
    let bound = fbm_bound(cell_min_wavelength_m(n, extent));
    for tol in [2.0f32, 10.0, 50.0] {
        let a: Vec<f32> = b
            .amp
            .iter()
            .zip(b.amp_free)
            .map(|(a, f)| if *a > 0.0 { *a } else { f.min(tol / bound) })
            .collect();
        (b.report)(&format!("tolerance {tol} m on the strokes"), &with(&a));
    }
    // The band's top at the local stroke spacing: the law's amplitude times `(d / TOP_CELLS)^H`,
    // `d` the distance (level-0 cells) to the nearest hard texel (zero on it).
    let dist = chamfer(n, &hard);
    for top in [16.0f32, 32.0] {
        let h: Vec<f32> = (0..n * n)
            .map(|k| {
                let s = (dist[k] / top)
                    .min(1.0)
                    .powf(terrasketch_detail::calibration::HURST);
                b.base[k] + s * (free[k] - b.base[k])
            })
            .collect();
        (b.report)(&format!("law x (distance / {top} cells)^H"), &h);
    }
    let share = hard.iter().filter(|h| **h).count() as f64 / (n * n) as f64;
    println!("  hard texels {:.1} %", 100.0 * share);
}

/// Distance (cells, 3-4 chamfer / 3) from every texel of an `n x n` grid to the nearest `true` one.
fn chamfer(n: usize, hard: &[bool]) -> Vec<f32> {
    let big = 3.0 * (2 * n) as f32;
    let mut d: Vec<f32> = hard.iter().map(|h| if *h { 0.0 } else { big }).collect();
    let at = |i: isize, j: isize| -> Option<usize> {
        (i >= 0 && j >= 0 && (i as usize) < n && (j as usize) < n)
            .then(|| j as usize * n + i as usize)
    };
    let pass = |d: &mut Vec<f32>, forward: bool| {
        let taps: [(isize, isize, f32); 4] = if forward {
            [(-1, 0, 3.0), (-1, -1, 4.0), (0, -1, 3.0), (1, -1, 4.0)]
        } else {
            [(1, 0, 3.0), (1, 1, 4.0), (0, 1, 3.0), (-1, 1, 4.0)]
        };
        for jj in 0..n {
            for ii in 0..n {
                let (i, j) = if forward {
                    (ii, jj)
                } else {
                    (n - 1 - ii, n - 1 - jj)
                };
                let k = j * n + i;
                for (di, dj, w) in taps {
                    if let Some(q) = at(i as isize + di, j as isize + dj) {
                        d[k] = d[k].min(d[q] + w);
                    }
                }
            }
        }
    };
    pass(&mut d, true);
    pass(&mut d, false);
    d.iter().map(|v| v / 3.0).collect()
}
