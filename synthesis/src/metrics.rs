//! Terrain descriptors for comparing a synthesised terrain with real ones (`terrasketch metrics`).
//!
//! [`terrain_metrics`] measures one heightmap; [`compare`] sets it against a reference.
//!
//! * **Slope** in degrees from central differences (one-sided on the border), using the cell size
//!   of each axis: mean, 90th percentile (exact, by selection) and a histogram of fractions in
//!   fixed 1-degree bins `[k, k+1)` for `k` in `0..90` (90 degrees goes to the last bin).
//! * **Curvature**: the Laplacian `d2z/dx2 + d2z/dy2` in 1/m on interior cells (5-point stencil):
//!   mean absolute value and standard deviation. The Laplacian is the sum of the two principal
//!   curvatures for gentle slopes; it is the descriptor the refine seam ratio uses too.
//! * **Spectral slope**: the heightmap's central square of side `N` (the largest power of two that
//!   fits, at most [`SPECTRUM_MAX_SIDE`], at least 16) minus its least-squares plane, multiplied
//!   by a 2-D Hann window to limit edge leakage, is transformed (radix-2 FFT in `fft.rs`). |F|^2 is
//!   averaged over integer annuli of radial wavenumber `k` (cycles per window) and
//!   `log10 P` is fitted against `log10 k` by least squares over `k` in `[4, N/4]`: wavelengths
//!   from a quarter of the window down to 4 cells, which avoids the window's low-frequency
//!   smear and the smoothing that resampling leaves near the Nyquist frequency. This is the slope
//!   of the 2-D radial spectrum: a surface whose 1-D transects follow `k^-2` (Pelletier 1997)
//!   gives about -3 here; a diffusion fill gives a much steeper (more negative) value.
//! * **Octave power**: the same window's |F|^2 summed over the octaves `k` in `[2^j, 2^(j+1))`
//!   of radial wavenumber, longest wavelength first: how much relief each scale carries. With a
//!   reference of the same window and cell size, [`compare`] gives the ratio per octave (1 = the
//!   reference's relief at that scale).
//! * **Pits**: closed depressions deeper than `pit_min_depth_m` (default 10 m): connected
//!   regions raised by a priority-flood fill from the border, regions touching the border
//!   excluded (see [`crate::pits::find_depressions`]); also per 100 km^2.
//! * **Hypsometric integral** `(mean - min) / (max - min)` over the whole grid.
//! * **Flat fraction**: share of cells whose slope is under [`FLAT_SLOPE_DEG`].
//! * **Roughness CV**: the slope map is cut into non-overlapping [`ROUGHNESS_WINDOW`]-cell square
//!   tiles (partial tiles at the right and bottom edges dropped); the standard deviation of slope
//!   in each tile is its local roughness; the CV is the standard deviation of those over their
//!   mean. Uniform texture gives a low CV, rugged-next-to-flat land a high one.
//! * **Axis ratio**: the slope map on the spectrum's central square, minus its mean and
//!   Hann-windowed, is transformed; the mean power on the axes (`kx = 0` or `ky = 0`) over
//!   radii `[N/4, N/2)` is divided by the mean power on the diagonals (`|kx| = |ky|`) over the
//!   same radii. Straight axis-aligned seams and creases raise it; isotropic land gives about 1.
//! * **Trenches**: straight one-cell channels: maximal runs of at least [`TRENCH_MIN_RUN`] cells
//!   along a row (or a column), each more than [`TRENCH_DEPTH_M`] below both of its neighbours
//!   across the run (the cells above and below it, or left and right).

use rayon::prelude::*;

use crate::fft;
use crate::pits;

/// Number of 1-degree slope bins (0..90 degrees).
pub const SLOPE_BINS: usize = 90;
/// Largest side of the square window used for the power spectrum.
pub const SPECTRUM_MAX_SIDE: usize = 1024;
/// Default depth a closed depression must exceed to count as a pit, in metres.
pub const DEFAULT_PIT_MIN_DEPTH_M: f32 = 10.0;
/// Cells with a slope under this (degrees) count as flat.
pub const FLAT_SLOPE_DEG: f64 = 2.0;
/// Side of the tiles whose slope spread is the local roughness.
pub const ROUGHNESS_WINDOW: usize = 16;
/// Shortest run of cells that counts as a trench.
pub const TRENCH_MIN_RUN: usize = 8;
/// Depth below both neighbours across the run that makes a cell part of a trench, metres.
pub const TRENCH_DEPTH_M: f32 = 2.0;

/// Descriptors of one heightmap. All lengths in metres, angles in degrees.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Metrics {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Cell size `[x, y]` in metres.
    pub cell_size_m: [f64; 2],
    /// Mean slope in degrees.
    pub slope_mean_deg: f64,
    /// 90th percentile of slope in degrees.
    pub slope_p90_deg: f64,
    /// Fraction of cells per 1-degree slope bin, [`SLOPE_BINS`] entries summing to 1.
    pub slope_histogram: Vec<f64>,
    /// Mean |Laplacian| over interior cells, in 1/m.
    pub laplacian_mean_abs_per_m: f64,
    /// Standard deviation of the Laplacian over interior cells, in 1/m.
    pub laplacian_std_per_m: f64,
    /// Slope of log10(power) against log10(radial wavenumber); `None` if the grid is under 16
    /// cells a side or flat.
    pub spectral_slope: Option<f64>,
    /// Side of the square window the spectrum was computed on (0 if none).
    pub spectrum_window_cells: usize,
    /// Fitted wavelength band `[longest, shortest]` in metres (mean of the two cell sizes).
    pub spectrum_band_m: [f64; 2],
    /// Closed depressions deeper than `pit_min_depth_m`.
    pub pit_count: usize,
    /// Depth threshold used for `pit_count`, in metres.
    pub pit_min_depth_m: f32,
    /// `pit_count` per 100 km^2 of grid area.
    pub pits_per_100km2: f64,
    /// Hypsometric integral `(mean - min) / (max - min)`; 0 for a flat grid.
    pub hypsometric_integral: f64,
    /// Lowest height.
    pub height_min_m: f64,
    /// Highest height.
    pub height_max_m: f64,
    /// Mean height.
    pub height_mean_m: f64,
    /// Share of cells with a slope under [`FLAT_SLOPE_DEG`].
    pub flat_fraction: f64,
    /// Coefficient of variation of the local slope standard deviation in
    /// [`ROUGHNESS_WINDOW`]-cell tiles (0 if there is no full tile or no roughness).
    pub roughness_cv: f64,
    /// Axis-to-diagonal power of the slope map's spectrum in its high-frequency half (`None`
    /// when the grid is under 16 cells a side or the slope is uniform).
    pub axis_ratio: Option<f64>,
    /// Straight one-cell trenches (see the module documentation).
    pub trenches: usize,
    /// Power of the spectrum's window per octave of wavelength, longest first (see the module
    /// documentation; empty when there is no spectrum).
    pub octave_power: Vec<OctavePower>,
}

/// The power one octave of wavelengths carries in a heightmap's spectrum window.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct OctavePower {
    /// Longest wavelength of the octave, metres.
    pub longest_m: f64,
    /// Shortest wavelength of the octave, metres.
    pub shortest_m: f64,
    /// Summed |F|^2 of the plane-removed, Hann-windowed heights over the octave, m^2.
    pub power_m2: f64,
}

/// How a heightmap compares with a reference.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Comparison {
    /// 1-D Wasserstein (earth mover's) distance between the slope distributions, in degrees,
    /// computed from the 1-degree histograms with mass spread uniformly within each bin.
    pub slope_wasserstein_deg: f64,
    /// `a.spectral_slope - reference.spectral_slope`, when both exist.
    pub spectral_slope_diff: Option<f64>,
    /// `a.slope_mean_deg - reference.slope_mean_deg`.
    pub slope_mean_diff_deg: f64,
    /// `a.pits_per_100km2 - reference.pits_per_100km2`.
    pub pits_per_100km2_diff: f64,
    /// `a.hypsometric_integral - reference.hypsometric_integral`.
    pub hypsometric_integral_diff: f64,
    /// `a`'s power over the reference's per octave, longest first (1 = the reference's relief
    /// at that scale), when both spectra have the same window and cell size.
    pub octave_power_ratio: Option<Vec<f64>>,
}

/// Measures a heightmap (row-major, `width * height` heights in metres) with the default pit
/// depth threshold. A grid whose length is not `width * height`, or an invalid cell size, gives
/// a [`Metrics`] with zero counts and no spectral slope instead of panicking.
pub fn terrain_metrics(
    heights: &[f32],
    width: usize,
    height: usize,
    cell_size_m: [f64; 2],
) -> Metrics {
    terrain_metrics_with(heights, width, height, cell_size_m, DEFAULT_PIT_MIN_DEPTH_M)
}

/// Measures a loaded [`Dem`](crate::Dem) with the default pit depth threshold.
pub fn dem_metrics(dem: &crate::Dem) -> Metrics {
    terrain_metrics(&dem.heights_m, dem.width, dem.height, dem.cell_size_m)
}

/// [`terrain_metrics`] with a chosen pit depth threshold in metres.
pub fn terrain_metrics_with(
    heights: &[f32],
    width: usize,
    height: usize,
    cell_size_m: [f64; 2],
    pit_min_depth_m: f32,
) -> Metrics {
    let mut m = Metrics {
        width,
        height,
        cell_size_m,
        slope_mean_deg: 0.0,
        slope_p90_deg: 0.0,
        slope_histogram: vec![0.0; SLOPE_BINS],
        laplacian_mean_abs_per_m: 0.0,
        laplacian_std_per_m: 0.0,
        spectral_slope: None,
        spectrum_window_cells: 0,
        spectrum_band_m: [0.0, 0.0],
        pit_count: 0,
        pit_min_depth_m,
        pits_per_100km2: 0.0,
        hypsometric_integral: 0.0,
        height_min_m: 0.0,
        height_max_m: 0.0,
        height_mean_m: 0.0,
        flat_fraction: 0.0,
        roughness_cv: 0.0,
        axis_ratio: None,
        trenches: 0,
        octave_power: Vec::new(),
    };
    let cells_ok = width > 0 && height > 0 && width.checked_mul(height) == Some(heights.len());
    let cell_ok = cell_size_m.iter().all(|c| c.is_finite() && *c > 0.0);
    if !cells_ok || !cell_ok || heights.iter().any(|h| !h.is_finite()) {
        return m;
    }
    let slopes = slope_degrees(heights, width, height, cell_size_m);
    m.flat_fraction = flat_fraction(&slopes);
    m.roughness_cv = roughness_cv(&slopes, width, height);
    m.axis_ratio = axis_ratio(&slopes, width, height);
    m.trenches = count_trenches(heights, width, height);
    slope_stats(slopes, &mut m);
    laplacian_stats(heights, width, height, cell_size_m, &mut m);
    spectrum(heights, width, height, cell_size_m, &mut m);
    m.pit_count = pits::count_pits(heights, width, height, None, pit_min_depth_m);
    let area_km2 = width as f64 * height as f64 * cell_size_m[0] * cell_size_m[1] / 1e6;
    m.pits_per_100km2 = m.pit_count as f64 * 100.0 / area_km2;
    let (lo, hi, sum) = heights.iter().fold(
        (f64::INFINITY, f64::NEG_INFINITY, 0.0),
        |(lo, hi, s), &h| {
            let h = f64::from(h);
            (lo.min(h), hi.max(h), s + h)
        },
    );
    m.height_min_m = lo;
    m.height_max_m = hi;
    m.height_mean_m = sum / heights.len() as f64;
    if hi > lo {
        m.hypsometric_integral = (m.height_mean_m - lo) / (hi - lo);
    }
    m
}

/// Slope in degrees at every cell: central differences inside, one-sided on the border.
pub fn slope_degrees(heights: &[f32], width: usize, height: usize, cell: [f64; 2]) -> Vec<f64> {
    if width.checked_mul(height) != Some(heights.len()) || heights.is_empty() {
        return Vec::new();
    }
    let h = |x: usize, y: usize| f64::from(heights[y * width + x]);
    // Rows in parallel: each cell depends only on the input, so the bits do not change.
    let mut out = vec![0.0f64; heights.len()];
    out.par_chunks_mut(width).enumerate().for_each(|(y, row)| {
        let (y0, y1) = (y.saturating_sub(1), (y + 1).min(height - 1));
        for (x, o) in row.iter_mut().enumerate() {
            let (x0, x1) = (x.saturating_sub(1), (x + 1).min(width - 1));
            let gx = if x1 > x0 {
                (h(x1, y) - h(x0, y)) / ((x1 - x0) as f64 * cell[0])
            } else {
                0.0
            };
            let gy = if y1 > y0 {
                (h(x, y1) - h(x, y0)) / ((y1 - y0) as f64 * cell[1])
            } else {
                0.0
            };
            *o = gx.hypot(gy).atan().to_degrees();
        }
    });
    out
}

/// Normalised histogram of slopes in degrees: `SLOPE_BINS` one-degree bins, the last one open-ended.
pub fn slope_histogram(slopes_deg: &[f64]) -> Vec<f64> {
    let mut hist = vec![0.0f64; SLOPE_BINS];
    let k = 1.0 / slopes_deg.len().max(1) as f64;
    for &s in slopes_deg {
        hist[(s.floor().max(0.0) as usize).min(SLOPE_BINS - 1)] += k;
    }
    hist
}

fn slope_stats(mut slopes: Vec<f64>, m: &mut Metrics) {
    if slopes.is_empty() {
        return;
    }
    let n = slopes.len() as f64;
    m.slope_mean_deg = slopes.iter().sum::<f64>() / n;
    m.slope_histogram = slope_histogram(&slopes);
    let k = ((0.9 * n).ceil() as usize).clamp(1, slopes.len()) - 1;
    let (_, p90, _) = slopes.select_nth_unstable_by(k, f64::total_cmp);
    m.slope_p90_deg = *p90;
}

fn laplacian_stats(heights: &[f32], width: usize, height: usize, cell: [f64; 2], m: &mut Metrics) {
    if width < 3 || height < 3 {
        return;
    }
    let h = |x: usize, y: usize| f64::from(heights[y * width + x]);
    let (cx2, cy2) = (cell[0] * cell[0], cell[1] * cell[1]);
    let (mut n, mut sum, mut sum_abs, mut sum_sq) = (0.0, 0.0, 0.0, 0.0);
    for y in 1..height - 1 {
        for x in 1..width - 1 {
            let c = h(x, y);
            let lap = (h(x - 1, y) + h(x + 1, y) - 2.0 * c) / cx2
                + (h(x, y - 1) + h(x, y + 1) - 2.0 * c) / cy2;
            n += 1.0;
            sum += lap;
            sum_abs += lap.abs();
            sum_sq += lap * lap;
        }
    }
    let mean = sum / n;
    m.laplacian_mean_abs_per_m = sum_abs / n;
    m.laplacian_std_per_m = (sum_sq / n - mean * mean).max(0.0).sqrt();
}

fn spectrum(heights: &[f32], width: usize, height: usize, cell: [f64; 2], m: &mut Metrics) {
    let Some(n) = spectrum_side(width, height) else {
        return;
    };
    let mut data = central_square(width, height, n, |i| f64::from(heights[i]));
    remove_plane(&mut data, n);
    hann_2d(&mut data, n);
    let power = fft::power_2d(&data, n);
    let radial = fft::radial_average(&power, n);
    let (k_lo, k_hi) = (4usize, n / 4);
    let points: Vec<(f64, f64)> = (k_lo..=k_hi)
        .filter_map(|k| {
            let p = *radial.get(k)?;
            (p > 0.0 && p.is_finite()).then(|| ((k as f64).log10(), p.log10()))
        })
        .collect();
    let cell_mean = 0.5 * (cell[0] + cell[1]);
    m.spectrum_window_cells = n;
    m.spectrum_band_m = [
        n as f64 * cell_mean / k_lo as f64,
        n as f64 * cell_mean / k_hi as f64,
    ];
    m.spectral_slope = fit_slope(&points);
    m.octave_power = octaves(&power, n, cell_mean);
}

/// Radial power summed per octave `k` in `[2^j, 2^(j+1))` cycles per window, up to `n / 2`.
fn octaves(power: &[f64], n: usize, cell_mean: f64) -> Vec<OctavePower> {
    let radial = fft::radial_sum(power, n);
    let wave = |k: usize| n as f64 * cell_mean / k as f64;
    let mut out = Vec::new();
    let mut lo = 1usize;
    while lo <= n / 2 {
        let hi = (2 * lo).min(n / 2 + 1);
        out.push(OctavePower {
            longest_m: wave(lo),
            shortest_m: wave(hi - 1),
            power_m2: radial[lo..hi].iter().sum(),
        });
        lo *= 2;
    }
    out
}

/// Side of the square window the spectra use: the largest power of two that fits, at most
/// [`SPECTRUM_MAX_SIDE`]; `None` under 16 cells.
fn spectrum_side(width: usize, height: usize) -> Option<usize> {
    let side = width.min(height).min(SPECTRUM_MAX_SIDE);
    (side >= 16).then(|| 1usize << (usize::BITS - 1 - side.leading_zeros()))
}

/// The central `n x n` square of a `width x height` grid, read through `at(index)`.
fn central_square(width: usize, height: usize, n: usize, at: impl Fn(usize) -> f64) -> Vec<f64> {
    let (x0, y0) = ((width - n) / 2, (height - n) / 2);
    (0..n * n)
        .map(|i| at((y0 + i / n) * width + x0 + i % n))
        .collect()
}

/// Multiplies an `n x n` grid by a separable Hann window (limits edge leakage).
fn hann_2d(data: &mut [f64], n: usize) {
    let hann: Vec<f64> = (0..n)
        .map(|i| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / n as f64).cos())
        .collect();
    for (i, v) in data.iter_mut().enumerate() {
        *v *= hann[i / n] * hann[i % n];
    }
}

/// Share of slopes under [`FLAT_SLOPE_DEG`].
pub fn flat_fraction(slopes_deg: &[f64]) -> f64 {
    if slopes_deg.is_empty() {
        return 0.0;
    }
    let flat = slopes_deg.iter().filter(|&&s| s < FLAT_SLOPE_DEG).count();
    flat as f64 / slopes_deg.len() as f64
}

/// Coefficient of variation of the per-tile slope standard deviation ([`ROUGHNESS_WINDOW`]
/// tiles, partial ones dropped); 0 without a full tile or when every tile is smooth.
pub fn roughness_cv(slopes_deg: &[f64], width: usize, height: usize) -> f64 {
    let t = ROUGHNESS_WINDOW;
    if width.checked_mul(height) != Some(slopes_deg.len()) || width < t || height < t {
        return 0.0;
    }
    let mut local = Vec::with_capacity((width / t) * (height / t));
    for ty in 0..height / t {
        for tx in 0..width / t {
            let (mut s, mut s2) = (0.0, 0.0);
            for y in ty * t..(ty + 1) * t {
                for &v in &slopes_deg[y * width + tx * t..y * width + (tx + 1) * t] {
                    s += v;
                    s2 += v * v;
                }
            }
            let k = (t * t) as f64;
            local.push((s2 / k - (s / k) * (s / k)).max(0.0).sqrt());
        }
    }
    let k = local.len() as f64;
    let mean = local.iter().sum::<f64>() / k;
    if mean <= 1e-6 {
        return 0.0;
    }
    let var = local.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / k;
    var.sqrt() / mean
}

/// Mean spectral power of the slope map on the axes over that on the diagonals, radii
/// `[N/4, N/2)` of the central `N x N` square (mean removed, Hann window). `None` below 16
/// cells or for a uniform slope.
pub fn axis_ratio(slopes_deg: &[f64], width: usize, height: usize) -> Option<f64> {
    if width.checked_mul(height) != Some(slopes_deg.len()) {
        return None;
    }
    let n = spectrum_side(width, height)?;
    let mut data = central_square(width, height, n, |i| slopes_deg[i]);
    let mean = data.iter().sum::<f64>() / data.len() as f64;
    data.iter_mut().for_each(|v| *v -= mean);
    hann_2d(&mut data, n);
    let p = fft::power_2d(&data, n);
    let at = |kx: usize, ky: usize| p[(ky % n) * n + kx % n];
    let (mut axis, mut axis_n) = (0.0, 0usize);
    for k in n / 4..n / 2 {
        axis += at(k, 0) + at(n - k, 0) + at(0, k) + at(0, n - k);
        axis_n += 4;
    }
    // Diagonal cells (d, d) with radius d * sqrt(2) in [n/4, n/2).
    let (mut diag, mut diag_n) = (0.0, 0usize);
    for d in 1..n / 2 {
        let r = d as f64 * std::f64::consts::SQRT_2;
        if r < (n / 4) as f64 || r >= (n / 2) as f64 {
            continue;
        }
        diag += at(d, d) + at(n - d, d) + at(d, n - d) + at(n - d, n - d);
        diag_n += 4;
    }
    let (axis, diag) = (axis / axis_n as f64, diag / diag_n.max(1) as f64);
    (diag > 0.0 && axis.is_finite()).then(|| axis / diag)
}

/// Straight one-cell trenches: maximal runs of at least [`TRENCH_MIN_RUN`] cells along a row or
/// a column, each more than [`TRENCH_DEPTH_M`] below both of its neighbours across the run.
pub fn count_trenches(heights: &[f32], width: usize, height: usize) -> usize {
    if width.checked_mul(height) != Some(heights.len()) || width < 3 || height < 3 {
        return 0;
    }
    let h = |x: usize, y: usize| heights[y * width + x];
    let low_in_row = |x: usize, y: usize| {
        let c = h(x, y) + TRENCH_DEPTH_M;
        c < h(x, y - 1) && c < h(x, y + 1)
    };
    let low_in_col = |x: usize, y: usize| {
        let c = h(x, y) + TRENCH_DEPTH_M;
        c < h(x - 1, y) && c < h(x + 1, y)
    };
    let runs = |len: usize, low: &dyn Fn(usize) -> bool| {
        let (mut count, mut run) = (0, 0);
        for i in 0..=len {
            if i < len && low(i) {
                run += 1;
            } else {
                count += usize::from(run >= TRENCH_MIN_RUN);
                run = 0;
            }
        }
        count
    };
    let rows: usize = (1..height - 1)
        .map(|y| runs(width, &|x| low_in_row(x, y)))
        .sum();
    let cols: usize = (1..width - 1)
        .map(|x| runs(height, &|y| low_in_col(x, y)))
        .sum();
    rows + cols
}

/// Subtracts the least-squares plane `a + b x + c y` (x, y centred, so the normal equations are
/// diagonal).
fn remove_plane(data: &mut [f64], n: usize) {
    let c = (n as f64 - 1.0) / 2.0;
    let (mut s, mut sx, mut sy, mut xx) = (0.0, 0.0, 0.0, 0.0);
    for (i, v) in data.iter().enumerate() {
        let (x, y) = ((i % n) as f64 - c, (i / n) as f64 - c);
        s += v;
        sx += v * x;
        sy += v * y;
        xx += x * x;
    }
    let count = data.len() as f64;
    let (a, b, cc) = (s / count, sx / xx, sy / xx);
    for (i, v) in data.iter_mut().enumerate() {
        let (x, y) = ((i % n) as f64 - c, (i / n) as f64 - c);
        *v -= a + b * x + cc * y;
    }
}

/// Least-squares slope of `y` on `x`; `None` with fewer than 3 points or no spread in `x`.
fn fit_slope(points: &[(f64, f64)]) -> Option<f64> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let mx = points.iter().map(|p| p.0).sum::<f64>() / n;
    let my = points.iter().map(|p| p.1).sum::<f64>() / n;
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = points.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

/// Compares `a` with `reference`: Wasserstein distance between slope distributions, difference
/// of spectral slopes and of the other scalar descriptors (`a` minus `reference`).
pub fn compare(a: &Metrics, reference: &Metrics) -> Comparison {
    Comparison {
        slope_wasserstein_deg: wasserstein_binned(&a.slope_histogram, &reference.slope_histogram),
        spectral_slope_diff: a
            .spectral_slope
            .zip(reference.spectral_slope)
            .map(|(x, y)| x - y),
        slope_mean_diff_deg: a.slope_mean_deg - reference.slope_mean_deg,
        pits_per_100km2_diff: a.pits_per_100km2 - reference.pits_per_100km2,
        hypsometric_integral_diff: a.hypsometric_integral - reference.hypsometric_integral,
        octave_power_ratio: octave_power_ratio(a, reference),
    }
}

/// Per-octave power of `a` over `reference`'s, when the octaves are the same wavelengths.
fn octave_power_ratio(a: &Metrics, reference: &Metrics) -> Option<Vec<f64>> {
    let same = a.spectrum_window_cells == reference.spectrum_window_cells
        && a.cell_size_m == reference.cell_size_m
        && !a.octave_power.is_empty()
        && a.octave_power.len() == reference.octave_power.len();
    same.then(|| {
        a.octave_power
            .iter()
            .zip(&reference.octave_power)
            .map(|(x, r)| {
                if r.power_m2 > 0.0 {
                    x.power_m2 / r.power_m2
                } else {
                    0.0
                }
            })
            .collect()
    })
}

/// W1 between two histograms on 1-degree bins: the integral of |F_a - F_b| with each CDF linear
/// inside a bin (mass spread uniformly over the bin). Histograms are normalised first; an empty
/// one counts as all mass at 0 degrees.
pub fn wasserstein_binned(a: &[f64], b: &[f64]) -> f64 {
    let bins = a.len().max(b.len());
    let norm = |h: &[f64]| {
        let s: f64 = h.iter().sum();
        (0..bins)
            .map(|i| match (s > 0.0, h.get(i)) {
                (true, Some(v)) => v / s,
                (false, _) if i == 0 => 1.0,
                _ => 0.0,
            })
            .collect::<Vec<f64>>()
    };
    let (a, b) = (norm(a), norm(b));
    let (mut fa, mut fb, mut total) = (0.0, 0.0, 0.0);
    for i in 0..bins {
        let d0: f64 = fa - fb;
        fa += a[i];
        fb += b[i];
        let d1: f64 = fa - fb;
        total += if d0 * d1 >= 0.0 {
            0.5 * (d0.abs() + d1.abs())
        } else {
            0.5 * (d0 * d0 + d1 * d1) / (d0.abs() + d1.abs())
        };
    }
    total
}
