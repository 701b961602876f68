//! The fitted constants (`tools/src/bin/detail_calibrate.rs` on the shipped exemplar DEMs; the fit, its
//! leave-one-out check and the plot are in this crate's README).

/// Hurst exponent of the octave weights (`2^(-H)` per octave), from the DEMs' radially averaged power
/// spectra: `P(k) ~ k^-(2H + 2)`.
pub const HURST: f32 = 0.839;

/// Lattice spacing of the octave of weight one, metres, and the least top of the band (the
/// calibration's high-pass scale: wavelengths the sketch's strokes shape are left to the
/// diffusion).
pub const REFERENCE_WAVELENGTH_M: f32 = 512.0;

/// The band's top in cells when that is coarser than [`REFERENCE_WAVELENGTH_M`]: strokes drawn a
/// few dozen cells apart leave everything finer to the detail (chosen leave-one-out on the traced
/// exemplars, `detail_calibrate --protocol`).
pub const TOP_CELLS: f32 = 32.0;

/// Mean of `|n|` over the gradient noise (the billow octaves subtract it, so that the detail adds
/// no mean height).
pub const BILLOW_MEAN: f32 = 0.2437;

/// Standard deviation of the Gaussian whose high-pass residual the amplitude law is fitted to,
/// metres (the same filter measures the octave sum, so that one unit of amplitude is one metre of
/// residual RMS).
pub const HIGH_PASS_SIGMA_M: f64 = 128.0;

/// Separable Gaussian blur of a `w x ht` grid, `sigma` in cells per axis, borders clamped, the
/// kernel cut at three sigma: with [`HIGH_PASS_SIGMA_M`] the low-pass whose residual the law is
/// fitted to (`detail_calibrate`) and measured on (`trace`'s stroke roughness). Rows in parallel;
/// a copy of `h` if its length is not `w x ht`.
pub fn gaussian_blur(h: &[f32], w: usize, ht: usize, sigma: [f64; 2]) -> Vec<f32> {
    use rayon::prelude::*;
    let kernel = |s: f64| {
        let r = (3.0 * s).ceil() as i64;
        let k: Vec<f64> = (-r..=r)
            .map(|x| (-(x * x) as f64 / (2.0 * s * s)).exp())
            .collect();
        let sum: f64 = k.iter().sum();
        (r, k.into_iter().map(|v| v / sum).collect::<Vec<_>>())
    };
    let (rx, kx) = kernel(sigma[0]);
    let (ry, ky) = kernel(sigma[1]);
    if h.len() != w * ht || w == 0 {
        return h.to_vec();
    }
    let mut tmp = vec![0.0f32; w * ht];
    tmp.par_chunks_mut(w).enumerate().for_each(|(j, row)| {
        for (i, o) in row.iter_mut().enumerate() {
            let mut s = 0.0;
            for (t, k) in kx.iter().enumerate() {
                let x = (i as i64 + t as i64 - rx).clamp(0, w as i64 - 1) as usize;
                s += k * h[j * w + x] as f64;
            }
            *o = s as f32;
        }
    });
    let mut out = vec![0.0f32; w * ht];
    out.par_chunks_mut(w).enumerate().for_each(|(j, row)| {
        for (i, o) in row.iter_mut().enumerate() {
            let mut s = 0.0;
            for (t, k) in ky.iter().enumerate() {
                let y = (j as i64 + t as i64 - ry).clamp(0, ht as i64 - 1) as usize;
                s += k * tmp[y * w + i] as f64;
            }
            *o = s as f32;
        }
    });
    out
}

/// Detail RMS on flat land at roughness [`ROUGHNESS_REFERENCE`], metres of high-pass residual.
pub const RMS_FLAT_M: f32 = 1.75;

/// Growth of the detail RMS with the tangent of the local slope, metres per unit tangent.
pub const RMS_PER_SLOPE_M: f32 = 63.0;

/// Slope tangent above which the RMS stops growing (29 degrees).
pub const SLOPE_TAN_MAX: f32 = 0.554;

/// RMS of the octave sum's high-pass residual (same filter) per unit amplitude: amplitudes are
/// divided by it.
pub const FBM_RESIDUAL_RMS: f32 = 0.3465;

/// Factor on the law's amplitude. The law is fitted against each DEM's own low-pass slope, but it is
/// applied to the diffusion's, which is gentler than the land it sketches, and only outside the
/// fade around the strokes. Chosen leave-one-out on the traced exemplars, whose strokes carry the
/// roughness `trace` measures, with the fade of the level-1 map (README, Measured).
pub const AMPLITUDE_GAIN: f32 = 1.1;

/// Diffused roughness at which the detail has the calibrated RMS; amplitude scales with
/// `roughness / ROUGHNESS_REFERENCE` (0: smooth).
pub const ROUGHNESS_REFERENCE: f32 = 0.5;
