//! Row kernels shared by the levels: branch-free loops over whole rows that the compiler vectorises.

/// `out[i] = ax (c[i-1] + c[i+1]) + ay (s[i] + t[i])` for `i < n`, a missing west/east neighbour
/// omitted (pass `ZEROS` for a missing south/north row). `c`, `s`, `t`, `out` have `n >= 2` cells.
#[inline(always)]
pub(crate) fn neighbour_row(c: &[f32], s: &[f32], t: &[f32], ax: f32, ay: f32, out: &mut [f32]) {
    let n = out.len();
    let (c, s, t) = (&c[..n], &s[..n], &t[..n]);
    out[0] = ax * c[1] + ay * (s[0] + t[0]);
    for i in 1..n - 1 {
        out[i] = ax * (c[i - 1] + c[i + 1]) + ay * (s[i] + t[i]);
    }
    out[n - 1] = ax * c[n - 2] + ay * (s[n - 1] + t[n - 1]);
}

/// Bilinear prolongation of one fine row `j` (fine side `2 nc`) from the coarse field `u`:
/// `out[i] = sum_{coarse c} P(j, i; c) u[c]` with the clamped cell-centred weights of `ALGORITHM.md`.
/// `v` is scratch of `nc + 2` cells.
#[inline(always)]
pub(crate) fn prolong_row(u: &[f32], nc: usize, j: usize, v: &mut [f32], out: &mut [f32]) {
    let jc = j / 2;
    let jn = if j & 1 == 1 {
        (jc + 1).min(nc - 1)
    } else {
        jc.saturating_sub(1)
    };
    let (a, b) = (&u[jc * nc..(jc + 1) * nc], &u[jn * nc..(jn + 1) * nc]);
    let v = &mut v[..nc + 2];
    for k in 0..nc {
        v[k + 1] = 0.75 * a[k] + 0.25 * b[k];
    }
    v[0] = v[1];
    v[nc + 1] = v[nc];
    let out = &mut out[..2 * nc];
    for k in 0..nc {
        out[2 * k] = 0.75 * v[k + 1] + 0.25 * v[k];
        out[2 * k + 1] = 0.75 * v[k + 1] + 0.25 * v[k + 2];
    }
}

/// `prolong_row` over fine columns `a..b` only (`cols = (a, b)`; at least those are written, each
/// with the same value as `prolong_row` gives it). `v` is scratch of `nc + 2` cells.
#[inline(always)]
pub(crate) fn prolong_row_cols(
    u: &[f32],
    nc: usize,
    j: usize,
    v: &mut [f32],
    out: &mut [f32],
    cols: (usize, usize),
) {
    if cols == (0, 2 * nc) {
        return prolong_row(u, nc, j, v, out);
    }
    let (a, b) = (cols.0.min(2 * nc), cols.1.min(2 * nc));
    if a >= b {
        return;
    }
    let jc = j / 2;
    let jn = if j & 1 == 1 {
        (jc + 1).min(nc - 1)
    } else {
        jc.saturating_sub(1)
    };
    let (ra, rb) = (&u[jc * nc..(jc + 1) * nc], &u[jn * nc..(jn + 1) * nc]);
    let v = &mut v[..nc + 2];
    // Coarse cells k0..k1 cover the fine columns; v[k + 1] for k in k0 - 1 ..= k1 (clamped).
    let (k0, k1) = (a / 2, b.div_ceil(2));
    for k in k0.saturating_sub(1)..(k1 + 1).min(nc) {
        v[k + 1] = 0.75 * ra[k] + 0.25 * rb[k];
    }
    if k0 == 0 {
        v[0] = v[1];
    }
    if k1 == nc {
        v[nc + 1] = v[nc];
    }
    let out = &mut out[..2 * nc];
    for k in k0..k1 {
        out[2 * k] = 0.75 * v[k + 1] + 0.25 * v[k];
        out[2 * k + 1] = 0.75 * v[k + 1] + 0.25 * v[k + 2];
    }
}

/// `out[k] = x[2k] + x[2k+1] + y[2k] + y[2k+1]`: the restriction (sum of 2x2 children) of two rows.
#[inline(always)]
pub(crate) fn restrict_pair(x: &[f32], y: &[f32], out: &mut [f32]) {
    let nc = out.len();
    let (x, y) = (&x[..2 * nc], &y[..2 * nc]);
    for k in 0..nc {
        out[k] = x[2 * k] + x[2 * k + 1] + y[2 * k] + y[2 * k + 1];
    }
}

/// `sum a[i] b[i]` in f64.
#[inline(always)]
pub(crate) fn dot_row(a: &[f32], b: &[f32]) -> f64 {
    let b = &b[..a.len()];
    #[cfg(target_arch = "x86_64")]
    if super::simd::has_avx2() {
        // SAFETY: the CPU supports AVX2 (checked at run time).
        return unsafe { dot_row_avx2(a, b) };
    }
    // Eight independent partial sums.
    let mut s = [0.0f64; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for k in 0..8 {
            s[k] += x[k] as f64 * y[k] as f64;
        }
    }
    for (x, y) in ra.iter().zip(rb) {
        s[0] += *x as f64 * *y as f64;
    }
    ((s[0] + s[4]) + (s[1] + s[5])) + ((s[2] + s[6]) + (s[3] + s[7]))
}

/// `dot_row` with AVX2 intrinsics (the same eight partial sums; LLVM does not vectorise the
/// f32 -> f64 widening well on its own).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn dot_row_avx2(a: &[f32], b: &[f32]) -> f64 {
    use std::arch::x86_64::*;
    let n = a.len().min(b.len());
    let k8 = n / 8 * 8;
    let (mut s0, mut s1) = (_mm256_setzero_pd(), _mm256_setzero_pd());
    let mut i = 0;
    while i < k8 {
        // SAFETY: i + 8 <= n for both slices; unaligned loads.
        unsafe {
            let (x0, x1) = (
                _mm_loadu_ps(a.as_ptr().add(i)),
                _mm_loadu_ps(a.as_ptr().add(i + 4)),
            );
            let (y0, y1) = (
                _mm_loadu_ps(b.as_ptr().add(i)),
                _mm_loadu_ps(b.as_ptr().add(i + 4)),
            );
            s0 = _mm256_add_pd(s0, _mm256_mul_pd(_mm256_cvtps_pd(x0), _mm256_cvtps_pd(y0)));
            s1 = _mm256_add_pd(s1, _mm256_mul_pd(_mm256_cvtps_pd(x1), _mm256_cvtps_pd(y1)));
        }
        i += 8;
    }
    let mut s = [0.0f64; 8];
    // SAFETY: 4 doubles each into an 8-double array.
    unsafe {
        _mm256_storeu_pd(s.as_mut_ptr(), s0);
        _mm256_storeu_pd(s.as_mut_ptr().add(4), s1);
    }
    for k in k8..n {
        s[0] += a[k] as f64 * b[k] as f64;
    }
    ((s[0] + s[4]) + (s[1] + s[5])) + ((s[2] + s[6]) + (s[3] + s[7]))
}

/// `(sum a[i] b[i], sum b[i] c[i])` in f64 (one pass over `b`).
#[inline(always)]
pub(crate) fn dot2_row(a: &[f32], b: &[f32], c: &[f32]) -> (f64, f64) {
    #[cfg(target_arch = "x86_64")]
    if super::simd::has_avx2() {
        // SAFETY: the CPU supports AVX2 (checked at run time).
        return unsafe { (dot_row_avx2(a, b), dot_row_avx2(b, c)) };
    }
    (dot_row(a, b), dot_row(b, c))
}

/// `max |a[i]|` (NaN ignored, like `f32::max`).
#[inline(always)]
pub(crate) fn max_abs_row(a: &[f32]) -> f32 {
    // Compare-and-select on 8 independent lanes: vectorises to `maxps`.
    let mut m = [0.0f32; 8];
    let mut chunks = a.chunks_exact(8);
    for c in &mut chunks {
        for k in 0..8 {
            m[k] = max_gt(m[k], c[k].abs());
        }
    }
    for v in chunks.remainder() {
        m[0] = max_gt(m[0], v.abs());
    }
    m.iter().fold(0.0f32, |a, b| max_gt(a, *b))
}

/// `v` if `v > m`, else `m` (so NaN never wins).
#[inline(always)]
pub(crate) fn max_gt(m: f32, v: f32) -> f32 {
    if v > m { v } else { m }
}

/// Length of `ALT`.
const ALT_LEN: usize = crate::grid::MAX_SIDE + 4;

/// `ALT[i]` is all ones for even `i`, 0 for odd: `ALT[i + p]` selects cells with `i & 1 == p`.
pub(crate) static ALT: [u32; ALT_LEN] = {
    let mut a = [0u32; ALT_LEN];
    let mut i = 0;
    while i < ALT_LEN {
        if i % 2 == 0 {
            a[i] = u32::MAX;
        }
        i += 1;
    }
    a
};

/// All ones if `c`, else 0.
#[inline(always)]
pub(crate) fn mask(c: bool) -> u32 {
    (c as u32).wrapping_neg()
}

/// `1 / d`, and 0 for `d = 0` (a hard cell's diagonal): the inverse diagonal, computed where it is
/// used rather than stored (`n * n` floats less per level 0; the same value as a stored `1.0 / d`).
#[inline(always)]
pub(crate) fn recip(d: f32) -> f32 {
    sel(mask(d != 0.0), 1.0 / d, 0.0)
}

/// `a` where `m` is all ones, `b` where it is 0 (bitwise, exact).
#[inline(always)]
pub(crate) fn sel(m: u32, a: f32, b: f32) -> f32 {
    f32::from_bits((a.to_bits() & m) | (b.to_bits() & !m))
}
