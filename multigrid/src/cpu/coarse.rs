//! Levels >= 1: 9-point Galerkin operators `A_k = R A_{k-1} P`, their smoother, residual and transfers.

use rayon::prelude::*;

use super::level0::Level0;
use super::par::{PARALLEL_MIN_CELLS, ROWS_PER_TASK, SharedMut};

/// Relative threshold under which a coarse cell's centre coefficient marks it inactive.
pub(crate) const INACTIVE_REL: f32 = 1e-6;

/// One coarse level's operator: a 9-point stencil per cell, `st[(oy + 1) * 3 + (ox + 1)]`.
/// An inactive cell has an all-zero stencil.
pub(crate) struct CoarseOp {
    /// Cells per side.
    pub n: usize,
    /// Stencils, row-major, row 0 = south.
    pub st: Vec<[f32; 9]>,
}

/// The 1D factors of a cell-centred bilinear prolongation row: fine index `x` on a coarse grid of
/// side `nc` takes `0.75` from its parent and `0.25` from the side neighbour (clamped at the border).
#[inline(always)]
pub(crate) fn p_weights(x: usize, nc: usize) -> [(usize, f32); 2] {
    let parent = x / 2;
    let side = if x & 1 == 1 { (parent + 1).min(nc - 1) } else { parent.saturating_sub(1) };
    if side == parent { [(parent, 1.0), (parent, 0.0)] } else { [(parent, 0.75), (side, 0.25)] }
}

/// Accumulates `sum_{fine j} coeff * P(j, .)` into the stencil `acc` of coarse cell `(ic, jc)`.
#[inline(always)]
fn scatter(acc: &mut [f32; 9], coeff: f32, fx: usize, fy: usize, nc: usize, ic: usize, jc: usize) {
    let wx = p_weights(fx, nc);
    let wy = p_weights(fy, nc);
    for (cy, wyv) in wy {
        if wyv == 0.0 {
            continue;
        }
        let oy = cy + 1 - jc; // in 0..=2 by construction
        for (cx, wxv) in wx {
            if wxv == 0.0 {
                continue;
            }
            let ox = cx + 1 - ic;
            acc[oy * 3 + ox] += coeff * wxv * wyv;
        }
    }
}

impl CoarseOp {
    /// An all-inactive level of side `n`.
    pub fn new(n: usize) -> CoarseOp {
        CoarseOp { n, st: vec![[0.0; 9]; n * n] }
    }

    /// True if coarse cell `idx` is active.
    #[inline(always)]
    pub fn is_active(&self, idx: usize) -> bool {
        self.st[idx][4] != 0.0
    }

    /// Builds rows `rows` of `R A_0 P` from level 0.
    pub fn galerkin_from_level0_rows(&mut self, fine: &Level0, rows: std::ops::Range<usize>) {
        let nc = self.n;
        let nf = fine.n;
        let threshold = INACTIVE_REL * (2.0 * fine.ax + 2.0 * fine.ay);
        let build_row = |(jc, out): (usize, &mut [[f32; 9]])| {
            for (ic, st) in out.iter_mut().enumerate() {
                let mut acc = [0.0f32; 9];
                for cy in 0..2 {
                    for cx in 0..2 {
                        let (i, j) = (2 * ic + cx, 2 * jc + cy);
                        let idx = j * nf + i;
                        let d = fine.diag[idx];
                        if d == 0.0 {
                            continue; // hard row: not part of A_ff
                        }
                        scatter(&mut acc, d, i, j, nc, ic, jc);
                        if i > 0 && fine.diag[idx - 1] != 0.0 {
                            scatter(&mut acc, -fine.ax, i - 1, j, nc, ic, jc);
                        }
                        if i + 1 < nf && fine.diag[idx + 1] != 0.0 {
                            scatter(&mut acc, -fine.ax, i + 1, j, nc, ic, jc);
                        }
                        if j > 0 && fine.diag[idx - nf] != 0.0 {
                            scatter(&mut acc, -fine.ay, i, j - 1, nc, ic, jc);
                        }
                        if j + 1 < nf && fine.diag[idx + nf] != 0.0 {
                            scatter(&mut acc, -fine.ay, i, j + 1, nc, ic, jc);
                        }
                    }
                }
                *st = if acc[4] > threshold { acc } else { [0.0; 9] };
            }
        };
        let start = rows.start * nc;
        let end = rows.end * nc;
        let slice = &mut self.st[start..end];
        if nf * nf >= PARALLEL_MIN_CELLS {
            slice
                .par_chunks_mut(nc)
                .enumerate()
                .with_min_len(ROWS_PER_TASK / 2)
                .for_each(|(r, out)| build_row((rows.start + r, out)));
        } else {
            slice.chunks_mut(nc).enumerate().for_each(|(r, out)| build_row((rows.start + r, out)));
        }
    }

    /// Builds rows `rows` of `R A_f P` from the finer coarse level `fine`.
    pub fn galerkin_from_coarse_rows(&mut self, fine: &CoarseOp, threshold: f32, rows: std::ops::Range<usize>) {
        let nc = self.n;
        let nf = fine.n;
        let build_row = |(jc, out): (usize, &mut [[f32; 9]])| {
            for (ic, st) in out.iter_mut().enumerate() {
                let mut acc = [0.0f32; 9];
                for cy in 0..2 {
                    for cx in 0..2 {
                        let (i, j) = (2 * ic + cx, 2 * jc + cy);
                        let row = &fine.st[j * nf + i];
                        if row[4] == 0.0 {
                            continue;
                        }
                        for oy in 0..3 {
                            let y = j + oy;
                            if y < 1 || y > nf {
                                continue;
                            }
                            let y = y - 1;
                            for ox in 0..3 {
                                let c = row[oy * 3 + ox];
                                if c == 0.0 {
                                    continue;
                                }
                                let x = i + ox;
                                if x < 1 || x > nf {
                                    continue;
                                }
                                let x = x - 1;
                                if fine.st[y * nf + x][4] == 0.0 {
                                    continue; // inactive fine cell: P row is zero
                                }
                                scatter(&mut acc, c, x, y, nc, ic, jc);
                            }
                        }
                    }
                }
                *st = if acc[4] > threshold { acc } else { [0.0; 9] };
            }
        };
        let slice = &mut self.st[rows.start * nc..rows.end * nc];
        if nf * nf >= PARALLEL_MIN_CELLS {
            slice
                .par_chunks_mut(nc)
                .enumerate()
                .with_min_len(ROWS_PER_TASK / 2)
                .for_each(|(r, out)| build_row((rows.start + r, out)));
        } else {
            slice.chunks_mut(nc).enumerate().for_each(|(r, out)| build_row((rows.start + r, out)));
        }
    }

    /// `sum_{o != 0} c_o u_{I+o}` for cell `(i, j)`.
    #[inline(always)]
    fn off_sum(&self, u: SharedMut, i: usize, j: usize) -> f32 {
        let n = self.n;
        let st = &self.st[j * n + i];
        let mut s = 0.0;
        if i > 0 && j > 0 && i + 1 < n && j + 1 < n {
            let b = j * n + i;
            // SAFETY: interior cell, all 8 neighbours in bounds; see `smooth_colour` for races.
            unsafe {
                s += st[0] * u.get(b - n - 1) + st[1] * u.get(b - n) + st[2] * u.get(b - n + 1);
                s += st[3] * u.get(b - 1) + st[5] * u.get(b + 1);
                s += st[6] * u.get(b + n - 1) + st[7] * u.get(b + n) + st[8] * u.get(b + n + 1);
            }
        } else {
            for oy in 0..3 {
                let y = j + oy;
                if y < 1 || y > n {
                    continue;
                }
                for ox in 0..3 {
                    let x = i + ox;
                    if (ox == 1 && oy == 1) || x < 1 || x > n {
                        continue;
                    }
                    // SAFETY: bounds checked above.
                    s += st[oy * 3 + ox] * unsafe { u.get((y - 1) * n + (x - 1)) };
                }
            }
        }
        s
    }

    /// One Gauss-Seidel pass over colour `(ci, cj)`: cells with `i & 1 == ci` and `j & 1 == cj`.
    pub fn smooth_colour(&self, u: &mut [f32], f: &[f32], ci: usize, cj: usize) {
        let n = self.n;
        let ptr = SharedMut(u.as_mut_ptr());
        let row = |r: usize| {
            let j = 2 * r + cj;
            let mut i = ci;
            while i < n {
                let idx = j * n + i;
                let c0 = self.st[idx][4];
                if c0 != 0.0 {
                    let s = self.off_sum(ptr, i, j);
                    // SAFETY: cells of one colour are written by one row task each and are never
                    // 9-point neighbours of each other (they differ by 2 in i or j).
                    unsafe { ptr.set(idx, (f[idx] - s) / c0) };
                }
                i += 2;
            }
        };
        if n * n >= PARALLEL_MIN_CELLS {
            (0..n / 2).into_par_iter().with_min_len(ROWS_PER_TASK / 2).for_each(row);
        } else {
            (0..n / 2).for_each(row);
        }
    }

    /// Residual `f - A u` of cell `(i, j)`.
    #[inline(always)]
    fn residual_at(&self, u: &[f32], f: &[f32], i: usize, j: usize) -> f32 {
        let idx = j * self.n + i;
        let c0 = self.st[idx][4];
        if c0 == 0.0 {
            return 0.0;
        }
        // Reading through a shared pointer is fine: nothing writes during a residual.
        let ptr = SharedMut(u.as_ptr() as *mut f32);
        f[idx] - c0 * u[idx] - self.off_sum(ptr, i, j)
    }

    /// Residual restricted (sum of 2x2 children) into `coarse_f` (side n/2); returns `max |r|`.
    pub fn residual_restrict(&self, u: &[f32], f: &[f32], coarse_f: &mut [f32]) -> f32 {
        let nc = self.n / 2;
        let coarse_row = |(jc, out): (usize, &mut [f32])| -> f32 {
            let mut m = 0.0f32;
            for (ic, o) in out.iter_mut().enumerate() {
                let mut s = 0.0;
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let r = self.residual_at(u, f, 2 * ic + dx, 2 * jc + dy);
                    m = m.max(r.abs());
                    s += r;
                }
                *o = s;
            }
            m
        };
        if self.n * self.n >= PARALLEL_MIN_CELLS {
            coarse_f.par_chunks_mut(nc).enumerate().map(coarse_row).reduce(|| 0.0, f32::max)
        } else {
            coarse_f.chunks_mut(nc).enumerate().map(coarse_row).fold(0.0, f32::max)
        }
    }

    /// `u += P uc` (set instead of add when `set`) on active cells; `uc` has side n/2.
    pub fn prolong(&self, uc: &[f32], u: &mut [f32], set: bool) {
        let n = self.n;
        let nc = n / 2;
        let row = |(j, out): (usize, &mut [f32])| {
            let wy = p_weights(j, nc);
            for (i, o) in out.iter_mut().enumerate() {
                if self.st[j * n + i][4] == 0.0 {
                    if set {
                        *o = 0.0;
                    }
                    continue;
                }
                let wx = p_weights(i, nc);
                let mut e = 0.0;
                for (cy, wyv) in wy {
                    for (cx, wxv) in wx {
                        e += wxv * wyv * uc[cy * nc + cx];
                    }
                }
                if set {
                    *o = e;
                } else {
                    *o += e;
                }
            }
        };
        if n * n >= PARALLEL_MIN_CELLS {
            u.par_chunks_mut(n).enumerate().for_each(row);
        } else {
            u.chunks_mut(n).enumerate().for_each(row);
        }
    }

    /// Solves `A u = f` exactly (Gaussian elimination with partial pivoting over the active cells).
    /// Meant for the coarsest level (at most 8x8). Inactive cells get 0.
    pub fn solve_direct(&self, u: &mut [f32], f: &[f32]) {
        let n = self.n;
        let active: Vec<usize> = (0..n * n).filter(|&c| self.is_active(c)).collect();
        let m = active.len();
        u.iter_mut().for_each(|v| *v = 0.0);
        if m == 0 {
            return;
        }
        let mut pos = vec![usize::MAX; n * n];
        for (k, &c) in active.iter().enumerate() {
            pos[c] = k;
        }
        let mut a = vec![0.0f64; m * m];
        let mut b = vec![0.0f64; m];
        for (r, &c) in active.iter().enumerate() {
            let (i, j) = (c % n, c / n);
            b[r] = f[c] as f64;
            for oy in 0..3 {
                for ox in 0..3 {
                    let (x, y) = (i + ox, j + oy);
                    if x < 1 || y < 1 || x > n || y > n {
                        continue;
                    }
                    let nb = (y - 1) * n + (x - 1);
                    if pos[nb] != usize::MAX {
                        a[r * m + pos[nb]] += self.st[c][oy * 3 + ox] as f64;
                    }
                }
            }
        }
        for col in 0..m {
            let piv = (col..m)
                .max_by(|&p, &q| a[p * m + col].abs().total_cmp(&a[q * m + col].abs()))
                .unwrap_or(col);
            if a[piv * m + col].abs() < 1e-30 {
                continue; // singular direction: leave it at 0
            }
            if piv != col {
                for k in 0..m {
                    a.swap(piv * m + k, col * m + k);
                }
                b.swap(piv, col);
            }
            let d = a[col * m + col];
            for r in col + 1..m {
                let factor = a[r * m + col] / d;
                if factor != 0.0 {
                    for k in col..m {
                        a[r * m + k] -= factor * a[col * m + k];
                    }
                    b[r] -= factor * b[col];
                }
            }
        }
        let mut x = vec![0.0f64; m];
        for r in (0..m).rev() {
            let mut s = b[r];
            for k in r + 1..m {
                s -= a[r * m + k] * x[k];
            }
            let d = a[r * m + r];
            x[r] = if d.abs() < 1e-30 { 0.0 } else { s / d };
        }
        for (k, &c) in active.iter().enumerate() {
            u[c] = x[k] as f32;
        }
    }
}
