//! Procedural detail added to the diffusion terrain, calibrated on real DEMs (see README.md).
//!
//! `detail(x) = A(x) * fbm(x)`: `A` is the level-1 amplitude map ([`amplitude_map`]: the calibrated
//! RMS for the local slope, scaled by the diffused roughness, zero around hard elevation
//! constraints) sampled bilinearly, `fbm` a sum of integer-hashed gradient-noise octaves
//! ([`noise::fbm`]) from the band's top ([`noise::Shape::top_m`]: the larger of
//! [`calibration::REFERENCE_WAVELENGTH_M`] and [`calibration::TOP_CELLS`] cells) down to the
//! sampling's own scale. The
//! editor draws `amplitude x noise_mips[k]` in the terrain vertex shader; the WGSL twin of
//! [`amplitude_map`] is `shaders/render/detail_amplitude.wgsl` (the GPU solver's amplitude).
#![warn(missing_docs)]

pub mod amplitude;
pub mod calibration;
pub mod noise;

use rayon::prelude::*;

pub use amplitude::{
    AmplitudeInputs, HardCells, amplitude_map, amplitude_side, hard_counts, max_pyramid,
    sample_bilinear,
};
pub use noise::{Shape, fbm, fbm_bound, fine_octaves, seed32};

/// The detail of an `n x n` heightmap (cell-centred, row 0 = south) over `extent_m`, from the
/// amplitude map `amp` (side [`amplitude_side`]): octaves finer than a cell are left out (`min_wavelength_m`
/// = the larger cell side). Zero wherever the amplitude is.
pub fn detail_field(n: usize, extent_m: [f64; 2], amp: &[f32], seed: u64) -> Vec<f32> {
    let mut out = vec![0.0f32; n * n];
    add_detail(&mut out, n, extent_m, amp, seed);
    out
}

/// The finest lattice spacing a heightmap of side `n` over `extent_m` resolves: its larger cell side
/// (octaves at or below it are display-only).
pub fn cell_min_wavelength_m(n: usize, extent_m: [f64; 2]) -> f32 {
    (extent_m[0].max(extent_m[1]) / n as f64) as f32
}

/// Adds the detail ([`detail_field`]) to `heights` (`n x n`) in place; nothing if the sizes do not
/// match.
pub fn add_detail(heights: &mut [f32], n: usize, extent_m: [f64; 2], amp: &[f32], seed: u64) {
    add_detail_shaped(heights, n, extent_m, amp, seed, &Shape::CALIBRATED);
}

/// [`add_detail`] with another octave shape (the calibration compares candidates).
pub fn add_detail_shaped(
    heights: &mut [f32],
    n: usize,
    extent_m: [f64; 2],
    amp: &[f32],
    seed: u64,
    shape: &Shape,
) {
    let m = amplitude_side(n);
    if amp.len() != m * m || m == 0 || heights.len() != n * n {
        return;
    }
    let ex = [extent_m[0] as f32, extent_m[1] as f32];
    let min_wl = cell_min_wavelength_m(n, extent_m);
    let octaves = noise::Octaves::with_shape(min_wl, seed32(seed), shape);
    let xs: Vec<f32> = (0..n)
        .map(|i| (i as f32 + 0.5) / n as f32 * ex[0])
        .collect();
    // Bilinear taps of the amplitude per column (`sample_bilinear`'s, shared by every row).
    let cols: Vec<(usize, usize, f32)> = (0..n)
        .map(|i| taps(m, (i as f32 + 0.5) / n as f32))
        .collect();
    heights.par_chunks_mut(n).enumerate().for_each(|(j, row)| {
        let v = (j as f32 + 0.5) / n as f32;
        let (j0, j1, fy) = taps(m, v);
        let (south, north) = (&amp[j0 * m..(j0 + 1) * m], &amp[j1 * m..(j1 + 1) * m]);
        let scale: Vec<f32> = cols
            .iter()
            .map(|&(i0, i1, fx)| {
                let s = south[i0] * (1.0 - fx) + south[i1] * fx;
                let n = north[i0] * (1.0 - fx) + north[i1] * fx;
                s * (1.0 - fy) + n * fy
            })
            .collect();
        octaves.add_row(&xs, v * ex[1], &scale, row);
    });
}

/// Stretch of the band's octaves along the slope ([`add_band_detail`]).
pub const ALIGNED_STRETCH: f32 = 2.0;

/// Octaves of at least this many cells are stretched along the slope; finer ones, whose billow
/// creases are a cell or two wide, stay round (stretched, they cut straight one-cell trenches).
pub const ALIGNED_MIN_CELLS: f32 = 4.0;

/// The octaves of [`add_detail`] that a source of heights does not resolve, added to `heights`
/// (`n x n` square cells of `cell_m` metres, row 0 = south; texel `(i, j)` at
/// `origin_m + (i + 0.5, j + 0.5) cell_m`, so a tile draws what its world draws there) in place,
/// with creases that run down the slope.
/// - Octave `k` of lattice spacing `s_k` counts with the weight `clamp(2 - s_k / top, 0, 1)`: all
///   of it up to `top`, none from twice `top`; `top` is sampled bilinearly from `band_top_m`
///   (side `n / 4`, metres, like `amp`).
/// - Each octave is the blend of four independent copies, those of [`ALIGNED_MIN_CELLS`] cells
///   and more stretched [`ALIGNED_STRETCH`] times along 0, 45, 90 and 135 degrees, weighted by
///   `cos^4` of their angle to the slope's direction and normalised so that the blend keeps the
///   variance of one copy. `slope` (side `n / 4`, the heights' gradient in metres per metre,
///   sampled bilinearly) gives the direction; under 3 degrees the copies mix evenly, fully
///   aligned from 10.
///
/// Nothing if the sizes do not match.
#[allow(clippy::too_many_arguments)]
pub fn add_band_detail(
    heights: &mut [f32],
    n: usize,
    cell_m: f32,
    origin_m: [f32; 2],
    amp: &[f32],
    band_top_m: &[f32],
    slope: &[[f32; 2]],
    seed: u64,
) {
    let m = n / 4;
    if amp.len() != m * m
        || band_top_m.len() != m * m
        || slope.len() != m * m
        || m == 0
        || heights.len() != n * n
    {
        return;
    }
    let octaves = noise::Octaves::with_shape(cell_m, seed32(seed), &Shape::CALIBRATED);
    let cols: Vec<(usize, usize, f32)> = (0..n)
        .map(|i| taps(m, (i as f32 + 0.5) / n as f32))
        .collect();
    let (flat, steep) = (3f32.to_radians().tan(), 10f32.to_radians().tan());
    heights.par_chunks_mut(n).enumerate().for_each(|(j, row)| {
        let (j0, j1, fy) = taps(m, (j as f32 + 0.5) / n as f32);
        let lerp = |v: [f32; 4], fx: f32| {
            let south = v[0] * (1.0 - fx) + v[1] * fx;
            let north = v[2] * (1.0 - fx) + v[3] * fx;
            south * (1.0 - fy) + north * fy
        };
        let y = origin_m[1] + (j as f32 + 0.5) * cell_m;
        for (i, out) in row.iter_mut().enumerate() {
            let (i0, i1, fx) = cols[i];
            let corners = [j0 * m + i0, j0 * m + i1, j1 * m + i0, j1 * m + i1];
            let a = lerp(corners.map(|c| amp[c]), fx);
            if a <= 0.0 {
                continue;
            }
            let top = lerp(corners.map(|c| band_top_m[c]), fx).max(f32::MIN_POSITIVE);
            let gx = lerp(corners.map(|c| slope[c][0]), fx);
            let gy = lerp(corners.map(|c| slope[c][1]), fx);
            let g = (gx * gx + gy * gy).sqrt();
            let t = ((g - flat) / (steep - flat)).clamp(0.0, 1.0);
            let aligned = t * t * (3.0 - 2.0 * t);
            let (c, s) = if g > 0.0 {
                (gx / g, gy / g)
            } else {
                (1.0, 0.0)
            };
            let mut w = [0.0f32; 4];
            for (wd, [dc, ds]) in w.iter_mut().zip(noise::ALIGNED_DIRECTIONS) {
                let cos = c * dc + s * ds;
                *wd = 1.0 - aligned + aligned * (cos * cos) * (cos * cos);
            }
            let norm = w.iter().map(|v| v * v).sum::<f32>().sqrt();
            let x = origin_m[0] + (i as f32 + 0.5) * cell_m;
            let mut sum = 0.0f32;
            for k in 0..octaves.count() {
                let wl = octaves.wavelength_m(k);
                let cover = (2.0 - wl / top).clamp(0.0, 1.0);
                if cover <= 0.0 {
                    continue;
                }
                let stretch = if wl >= ALIGNED_MIN_CELLS * cell_m {
                    ALIGNED_STRETCH
                } else {
                    1.0
                };
                for (d, wd) in w.iter().enumerate() {
                    if *wd > 1e-3 {
                        sum += cover * wd * octaves.eval_aligned(k, d, stretch, x, y);
                    }
                }
            }
            *out += a * sum / norm;
        }
    });
}

/// The two texels and the weight of the second along one axis of [`sample_bilinear`].
fn taps(m: usize, u: f32) -> (usize, usize, f32) {
    let s = m as f32;
    let p = (u * s - 0.5).clamp(0.0, s - 1.0);
    let p0 = p.floor();
    let i0 = p0 as usize;
    (i0, (i0 + 1).min(m - 1), p - p0)
}

/// The octave sums the editor displays, per mip of an `n x n` heightmap over `extent_m`: level `k`
/// (side `n >> k`) at its texel centres, octaves finer than its cell left out, the band's top level
/// 0's. Level 0 is
/// [`detail_field`]'s sum: `detail = amplitude * noise[0]` texel by texel.
pub fn noise_mips(n: usize, extent_m: [f64; 2], seed: u64) -> Vec<Vec<f32>> {
    let mut out = Vec::new();
    let mut side = n;
    // Every level keeps level 0's band top: a coarse mip shows fewer fine octaves, never coarser
    // ones (which would pop between levels and break the quadtree's bound).
    let top_m = Shape::CALIBRATED.top_m(cell_min_wavelength_m(n, extent_m));
    while side >= 1 {
        let min_wl = cell_min_wavelength_m(side, extent_m);
        let shape = Shape {
            top_cells: top_m / min_wl,
            ..Shape::CALIBRATED
        };
        let octaves = noise::Octaves::with_shape(min_wl, seed32(seed), &shape);
        let xs: Vec<f32> = (0..side)
            .map(|i| (i as f32 + 0.5) / side as f32 * extent_m[0] as f32)
            .collect();
        let ones = vec![1.0f32; side];
        let mut level = vec![0.0f32; side * side];
        level.par_chunks_mut(side).enumerate().for_each(|(j, row)| {
            let v = (j as f32 + 0.5) / side as f32;
            octaves.add_row(&xs, v * extent_m[1] as f32, &ones, row);
        });
        out.push(level);
        side /= 2;
    }
    out
}
