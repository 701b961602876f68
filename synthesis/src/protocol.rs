//! Scott & Dodgson's guide-reproduction protocol, leave-one-out: each DEM is rebuilt from its own
//! 16x-downsampled-then-upsampled guide with the other DEMs as exemplars, and the result, the
//! guide and the real DEM are measured with [`crate::metrics`]. Also a hillshade writer for
//! looking at the results.

use std::path::Path;
use std::sync::atomic::AtomicBool;

use crate::Dem;
use crate::metrics::{Metrics, compare, terrain_metrics};
use crate::refine::field::{Field, lowpass};
use crate::refine::{
    PreparedExemplar, RefineError, RefineInput, RefineParams, prepare_exemplars, refine,
};

/// The guide is the real DEM block-averaged by this factor and brought back up (cubic B-spline).
pub const GUIDE_FACTOR: usize = 16;
/// Largest side of the reproduced square.
pub const MAX_PROTOCOL_SIDE: usize = 1024;

/// The DEM on its own grid (no resampling) as the largest centred power-of-two square of at
/// most `max_side` cells: `(heights, side, cell_size_m [x, y])`. Errors when under 64 cells a
/// side.
pub fn square_at_own_cell(
    dem: &Dem,
    max_side: usize,
) -> Result<(Vec<f32>, usize, [f64; 2]), String> {
    let fit = dem.width.min(dem.height).min(max_side.max(1));
    let n = 1usize << (usize::BITS - 1 - fit.max(1).leading_zeros());
    if n < 64 {
        return Err(format!(
            "{} is {}x{} cells: under 64 a side",
            dem.name, dem.width, dem.height
        ));
    }
    let (x0, y0) = ((dem.width - n) / 2, (dem.height - n) / 2);
    let mut out = Vec::with_capacity(n * n);
    for y in y0..y0 + n {
        out.extend_from_slice(&dem.heights_m[y * dem.width + x0..y * dem.width + x0 + n]);
    }
    Ok((out, n, dem.cell_size_m))
}

/// The guide of a real `n x n` grid: block average by [`GUIDE_FACTOR`], B-spline back up.
pub fn guide(real: &[f32], n: usize) -> Vec<f32> {
    lowpass(&Field::new(n, n, real.to_vec()), GUIDE_FACTOR).v
}

/// One DEM's leave-one-out reproduction.
pub struct Reproduction {
    /// The DEM's name.
    pub name: String,
    /// Side and cell size of the square.
    pub side: usize,
    /// The DEM's cell size `[x, y]` in metres.
    pub cell_size_m: [f64; 2],
    /// The real square, the guide and the refined result (`side^2`, row 0 = north).
    pub real: Vec<f32>,
    /// The guide.
    pub guide: Vec<f32>,
    /// The refined result.
    pub refined: Vec<f32>,
    /// Metrics of the real square, the guide and the refined result.
    pub metrics: [Metrics; 3],
    /// Slope W1 (degrees) of the guide and of the refined result against the real square.
    pub slope_w1_deg: [f64; 2],
    /// Refinement time, milliseconds.
    pub ms_refine: f64,
    /// Pits deeper than 10 m per 100 km^2 in the exemplars used (pooled).
    pub exemplar_pits_per_100km2: f64,
}

/// Rebuilds `dems[index]` from its guide with the other DEMs as exemplars.
pub fn reproduce(
    dems: &[Dem],
    index: usize,
    params: &RefineParams,
    cache_dir: Option<&Path>,
) -> Result<Reproduction, RefineError> {
    let dem = dems
        .get(index)
        .ok_or_else(|| RefineError::BadInput(format!("no DEM {index}")))?;
    let (real, n, cells) =
        square_at_own_cell(dem, MAX_PROTOCOL_SIDE).map_err(RefineError::BadInput)?;
    // The synthesis works on square cells: the geometric mean of the DEM's two; the
    // measurements use the DEM's own.
    let cell = (cells[0] * cells[1]).sqrt();
    let guide = guide(&real, n);
    let others: Vec<Dem> = dems
        .iter()
        .enumerate()
        .filter(|&(i, _)| i != index)
        .map(|(_, d)| d.clone())
        .collect();
    let prepared: Vec<PreparedExemplar> = prepare_exemplars(&others, cell, cache_dir, &|_, _| {})?;
    let input = RefineInput::target_only(n, cell, guide.clone());
    let out = refine(
        &input,
        &prepared,
        params,
        &|_, _| {},
        &AtomicBool::new(false),
    )?;
    let refined = out.heights.data;
    let m = |h: &[f32]| terrain_metrics(h, n, n, cells);
    let metrics = [m(&real), m(&guide), m(&refined)];
    let slope_w1_deg = [
        compare(&metrics[1], &metrics[0]).slope_wasserstein_deg,
        compare(&metrics[2], &metrics[0]).slope_wasserstein_deg,
    ];
    Ok(Reproduction {
        name: dem.name.clone(),
        side: n,
        cell_size_m: cells,
        real,
        guide,
        refined,
        metrics,
        slope_w1_deg,
        ms_refine: out.stats.ms_total,
        exemplar_pits_per_100km2: out.stats.exemplar_pits_per_100km2,
    })
}

/// Hillshade (sun azimuth 315 degrees, altitude 45) of a `w x h` grid, row 0 = north, as 8-bit
/// grey: `cos(zenith) cos(slope) + sin(zenith) sin(slope) cos(azimuth - aspect)`, clamped to 0.
pub fn hillshade(heights: &[f32], w: usize, h: usize, cell_m: [f64; 2]) -> Vec<u8> {
    if w < 2 || h < 2 || heights.len() != w * h {
        return vec![0; heights.len()];
    }
    let at = |x: usize, y: usize| f64::from(heights[y * w + x]);
    let (zen, az) = (45f64.to_radians(), 315f64.to_radians());
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h {
        let (y0, y1) = (y.saturating_sub(1), (y + 1).min(h - 1));
        for x in 0..w {
            let (x0, x1) = (x.saturating_sub(1), (x + 1).min(w - 1));
            let dzdx = (at(x1, y) - at(x0, y)) / ((x1 - x0) as f64 * cell_m[0]);
            // Row 0 is north: northward is decreasing y.
            let dzdy = (at(x, y0) - at(x, y1)) / ((y1 - y0) as f64 * cell_m[1]);
            let slope = dzdx.hypot(dzdy).atan();
            // Aspect: direction the slope faces, clockwise from north.
            let aspect = (-dzdx).atan2(-dzdy);
            let s = zen.cos() * slope.cos() + zen.sin() * slope.sin() * (az - aspect).cos();
            out.push((s.clamp(0.0, 1.0) * 255.0).round() as u8);
        }
    }
    out
}

/// Writes an 8-bit grey PNG.
pub fn write_grey_png(path: &Path, pixels: &[u8], w: usize, h: usize) -> std::io::Result<()> {
    let err = |e: png::EncodingError| std::io::Error::other(e.to_string());
    let file = std::io::BufWriter::new(std::fs::File::create(path)?);
    let mut enc = png::Encoder::new(file, w as u32, h as u32);
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Eight);
    enc.write_header()
        .map_err(err)?
        .write_image_data(pixels)
        .map_err(err)
}
