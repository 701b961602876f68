//! Whole-level kernels for small coarse levels (side <= `DENSE_MAX_SIDE`).
//!
//! Small levels are visited many times per W-cycle and most of their cells are general (borders,
//! constraints), so row-by-row code with a standard-stencil fast path is dominated by per-row and
//! per-cell overhead there. These kernels treat the level as one flat array with per-cell stencil
//! planes: a colour pass computes the Gauss-Seidel candidate of *every* cell in one branch-free loop
//! and keeps it on the colour's cells. The unknowns are copied into a buffer with one zero row
//! (plus one cell) of padding at each end, so the 8 neighbours of any cell are in bounds; a stencil
//! never has a non-zero coefficient towards a cell outside the domain, so the reads that wrap around
//! a row end (or hit the padding) are multiplied by exactly 0.

use super::par::with_scratch;
use super::rows::{mask, restrict_pair, sel};
use super::simd::multiversion;

/// The 10 planes of a small level of side `n` (`CoarseOp::dense`): coefficients `0..9` and the
/// inverse centre.
#[inline(always)]
fn planes(n: usize, dense: &[f32]) -> [&[f32]; 10] {
    let nn = n * n;
    std::array::from_fn(|o| &dense[o * nn..(o + 1) * nn])
}

/// `out[k] = sum_{o != 4} c_o u_{idx + o}` for the cells `idx = start + k`, `k < len`, with the
/// padded unknowns `up` (cell `idx` at `idx + n + 1`). All views have exactly `len` cells so the
/// loop is bounds-check free.
#[inline(always)]
fn off_range(p: &[&[f32]; 10], up: &[f32], n: usize, start: usize, len: usize, out: &mut [f32]) {
    let v: [&[f32]; 9] = std::array::from_fn(|o| {
        let (oy, ox) = (o / 3, o % 3);
        &up[start + oy * n + ox..][..len]
    });
    let c: [&[f32]; 9] = std::array::from_fn(|o| &p[o][start..][..len]);
    let out = &mut out[..len];
    for i in 0..len {
        let a = c[0][i] * v[0][i] + c[1][i] * v[1][i] + c[2][i] * v[2][i];
        let m = c[3][i] * v[3][i] + c[5][i] * v[5][i];
        let b = c[6][i] * v[6][i] + c[7][i] * v[7][i] + c[8][i] * v[8][i];
        out[i] = a + m + b;
    }
}

multiversion! {
    /// One four-colour Gauss-Seidel sweep of a small level of side `n` with the stencil planes
    /// `dense`, colours ascending (`pre`) or descending.
    pub(crate) fn flat_sweep(n: usize, dense: &[f32], u: &mut [f32], f: &[f32], pre: bool) {
        let nn = n * n;
        let pad = n + 1;
        let p = planes(n, dense);
        let shift = n.trailing_zeros();
        with_scratch(2 * nn + 2 * pad, |s| {
            let (up, cand) = s.split_at_mut(nn + 2 * pad);
            up[..pad].fill(0.0);
            up[pad + nn..].fill(0.0);
            up[pad..pad + nn].copy_from_slice(&u[..nn]);
            let f = &f[..nn];
            let colours = if pre { [0, 1, 2, 3] } else { [3, 2, 1, 0] };
            for c in colours {
                // Every cell in one loop, kept on the colour's cells (row-by-row loops over the
                // colour's rows only measured slower on these small levels).
                let (ci, cj) = (c & 1, c >> 1);
                off_range(&p, up, n, 0, nn, cand);
                let pinv = &p[9][..nn];
                for idx in 0..nn {
                    cand[idx] = (f[idx] - cand[idx]) * pinv[idx];
                }
                let (keep, cand) = (&mut up[pad..pad + nn], &cand[..nn]);
                for idx in 0..nn {
                    let m = mask(((idx & 1) == ci) & (((idx >> shift) & 1) == cj));
                    keep[idx] = sel(m, cand[idx], keep[idx]);
                }
            }
            u[..nn].copy_from_slice(&up[pad..pad + nn]);
        });
    }
}

multiversion! {
    /// Residual `f - A u` of a small level of side `n` with the stencil planes `dense` (0 on
    /// inactive cells), restricted (sum of 2x2 children) into `coarse_f` (side n/2).
    pub(crate) fn flat_residual_restrict(
        n: usize,
        dense: &[f32],
        u: &[f32],
        f: &[f32],
        coarse_f: &mut [f32],
    ) {
        let nn = n * n;
        let nc = n / 2;
        let pad = n + 1;
        let p = planes(n, dense);
        with_scratch(2 * nn + 2 * pad, |s| {
            let (up, r) = s.split_at_mut(nn + 2 * pad);
            up[..pad].fill(0.0);
            up[pad + nn..].fill(0.0);
            up[pad..pad + nn].copy_from_slice(&u[..nn]);
            let f = &f[..nn];
            off_range(&p, up, n, 0, nn, r);
            let (c4, pinv, uc) = (&p[4][..nn], &p[9][..nn], &up[pad..pad + nn]);
            for idx in 0..nn {
                let res = (f[idx] - c4[idx] * uc[idx]) - r[idx];
                r[idx] = sel(mask(pinv[idx] != 0.0), res, 0.0);
            }
            for jc in 0..nc {
                restrict_pair(&r[2 * jc * n..][..n], &r[(2 * jc + 1) * n..][..n], &mut coarse_f[jc * nc..][..nc]);
            }
        });
    }
}
