//! A small in-place radix-2 complex FFT and the radially averaged power spectrum built on it.
//!
//! Written here instead of depending on `rustfft`: the metrics need one power-of-two 2-D transform
//! of at most 1024^2 per call, which an iterative Cooley-Tukey transform does in well under a
//! second, and this keeps the crate's dependency list (and its audit surface) unchanged.

use std::f64::consts::PI;

/// In-place forward FFT of `re` + i `im` (length a power of two; other lengths are left as is).
pub(crate) fn fft_in_place(re: &mut [f64], im: &mut [f64]) {
    let n = re.len();
    if n < 2 || !n.is_power_of_two() || im.len() != n {
        return;
    }
    // Bit-reversal permutation.
    let bits = n.trailing_zeros();
    for i in 0..n {
        let j = i.reverse_bits() >> (usize::BITS - bits);
        if j > i {
            re.swap(i, j);
            im.swap(i, j);
        }
    }
    let mut len = 2;
    while len <= n {
        let ang = -2.0 * PI / len as f64;
        let (w_im, w_re) = ang.sin_cos();
        for start in (0..n).step_by(len) {
            let (mut cr, mut ci) = (1.0f64, 0.0f64);
            for k in 0..len / 2 {
                let a = start + k;
                let b = a + len / 2;
                let tr = re[b] * cr - im[b] * ci;
                let ti = re[b] * ci + im[b] * cr;
                re[b] = re[a] - tr;
                im[b] = im[a] - ti;
                re[a] += tr;
                im[a] += ti;
                let ncr = cr * w_re - ci * w_im;
                ci = cr * w_im + ci * w_re;
                cr = ncr;
            }
        }
        len <<= 1;
    }
}

/// 2-D power spectrum |F|^2 of an `n x n` grid (row-major, `n` a power of two).
pub(crate) fn power_2d(data: &[f64], n: usize) -> Vec<f64> {
    let mut re = data.to_vec();
    let mut im = vec![0.0; re.len()];
    if n == 0 || re.len() != n * n {
        return Vec::new();
    }
    for row in 0..n {
        let r = row * n..(row + 1) * n;
        fft_in_place(&mut re[r.clone()], &mut im[r]);
    }
    let (mut cre, mut cim) = (vec![0.0; n], vec![0.0; n]);
    for col in 0..n {
        for row in 0..n {
            cre[row] = re[row * n + col];
            cim[row] = im[row * n + col];
        }
        fft_in_place(&mut cre, &mut cim);
        for row in 0..n {
            re[row * n + col] = cre[row];
            im[row * n + col] = cim[row];
        }
    }
    re.iter().zip(&im).map(|(a, b)| a * a + b * b).collect()
}

/// Radially averaged power: entry `k` is the mean of |F|^2 over integer wavenumber annulus
/// `k - 0.5 <= |(kx, ky)| < k + 0.5` (cycles per window), for `k` in `0..=n/2`.
pub(crate) fn radial_average(power: &[f64], n: usize) -> Vec<f64> {
    let (sum, count) = annuli(power, n);
    sum.iter()
        .zip(&count)
        .map(|(s, &c)| if c > 0 { s / c as f64 } else { 0.0 })
        .collect()
}

/// Radially summed power: entry `k` is the sum of |F|^2 over the same annulus as
/// [`radial_average`] (the power a band of wavelengths carries, however many modes it has).
pub(crate) fn radial_sum(power: &[f64], n: usize) -> Vec<f64> {
    annuli(power, n).0
}

/// Sum and count of `power` per integer annulus `k` in `0..=n/2`.
fn annuli(power: &[f64], n: usize) -> (Vec<f64>, Vec<usize>) {
    let half = n / 2;
    let mut sum = vec![0.0; half + 1];
    let mut count = vec![0usize; half + 1];
    let signed = |i: usize| {
        if i <= half {
            i as f64
        } else {
            i as f64 - n as f64
        }
    };
    for row in 0..n {
        let ky = signed(row);
        for col in 0..n {
            let kx = signed(col);
            let k = (kx * kx + ky * ky).sqrt().round() as usize;
            if k <= half
                && let Some(p) = power.get(row * n + col)
            {
                sum[k] += p;
                count[k] += 1;
            }
        }
    }
    (sum, count)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fft_matches_a_direct_dft() {
        let n = 16;
        let x: Vec<f64> = (0..n).map(|i| ((i * 7 % 5) as f64) - 1.5).collect();
        let (mut re, mut im) = (x.clone(), vec![0.0; n]);
        fft_in_place(&mut re, &mut im);
        for k in 0..n {
            let (mut sr, mut si) = (0.0, 0.0);
            for (j, v) in x.iter().enumerate() {
                let a = -2.0 * PI * (k * j) as f64 / n as f64;
                sr += v * a.cos();
                si += v * a.sin();
            }
            assert!((sr - re[k]).abs() < 1e-9 && (si - im[k]).abs() < 1e-9);
        }
    }

    #[test]
    fn a_plane_wave_puts_power_in_one_annulus() {
        let n = 32;
        let data: Vec<f64> = (0..n * n)
            .map(|i| (2.0 * PI * 5.0 * (i % n) as f64 / n as f64).cos())
            .collect();
        let radial = radial_average(&power_2d(&data, n), n);
        let best = radial
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .map(|(k, _)| k);
        assert_eq!(best, Some(5));
    }
}
