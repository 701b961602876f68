//! Level 0: the matrix-free 5-point operator with hard and soft constraints (see `ALGORITHM.md`).

use rayon::prelude::*;

use super::par::{PARALLEL_MIN_CELLS, ROWS_PER_TASK, SharedMut};
use crate::problem::{FieldProblem, is_hard, soft_sigma};

/// The finest level of one problem: operator diagonal, constrained values and right-hand side.
pub(crate) struct Level0 {
    /// Cells per side.
    pub n: usize,
    /// East/west edge weight.
    pub ax: f32,
    /// North/south edge weight.
    pub ay: f32,
    /// Operator diagonal `sum a_ij + sigma` on free cells; exactly 0 on hard cells.
    pub diag: Vec<f32>,
    /// Constrained values `E`.
    pub value: Vec<f32>,
    /// Right-hand side `f = sigma E - sum a dd`.
    pub f: Vec<f32>,
}

impl Level0 {
    /// An unconstrained level of side `n` (every cell free, `f = 0`).
    pub fn new(n: usize, ax: f32, ay: f32) -> Level0 {
        Level0 { n, ax, ay, diag: vec![0.0; n * n], value: vec![0.0; n * n], f: vec![0.0; n * n] }
    }

    /// Fills diagonal, values and right-hand side of rows `rows` from the problem.
    pub fn assemble_rows(&mut self, p: &FieldProblem, rows: std::ops::Range<usize>) {
        let n = self.n;
        let (ax, ay) = (self.ax, self.ay);
        let has_d = !p.d_east.is_empty();
        let span = rows.start * n..rows.end * n;
        let row = |(r, ((diag, value), f)): (usize, ((&mut [f32], &mut [f32]), &mut [f32]))| {
            let j = rows.start + r;
            for i in 0..n {
                let idx = j * n + i;
                let w = p.weight[idx];
                value[i] = p.value[idx];
                if is_hard(w) {
                    diag[i] = 0.0;
                    f[i] = 0.0;
                    continue;
                }
                let sigma = soft_sigma(w, ax, ay);
                let mut deg = 0.0;
                // Sum of a_ij * dd_ij, dd = wanted h_j - h_i.
                let mut flux = 0.0;
                if i + 1 < n {
                    deg += ax;
                    if has_d {
                        flux += ax * p.d_east[idx];
                    }
                }
                if i > 0 {
                    deg += ax;
                    if has_d {
                        flux -= ax * p.d_east[idx - 1];
                    }
                }
                if j + 1 < n {
                    deg += ay;
                    if has_d {
                        flux += ay * p.d_north[idx];
                    }
                }
                if j > 0 {
                    deg += ay;
                    if has_d {
                        flux -= ay * p.d_north[idx - n];
                    }
                }
                diag[i] = deg + sigma;
                f[i] = sigma * p.value[idx] - flux;
            }
        };
        self.diag[span.clone()]
            .par_chunks_mut(n)
            .zip(self.value[span.clone()].par_chunks_mut(n))
            .zip(self.f[span].par_chunks_mut(n))
            .enumerate()
            .with_min_len(ROWS_PER_TASK)
            .for_each(row);
    }

    /// True if cell `idx` is hard.
    #[inline(always)]
    pub fn is_hard(&self, idx: usize) -> bool {
        self.diag[idx] == 0.0
    }

    /// `sum_j a_ij h_j` over the in-domain neighbours of `(i, j)`.
    #[inline(always)]
    fn neighbour_sum(&self, h: &[f32], i: usize, j: usize) -> f32 {
        let n = self.n;
        let idx = j * n + i;
        let mut s = 0.0;
        if i > 0 {
            s += self.ax * h[idx - 1];
        }
        if i + 1 < n {
            s += self.ax * h[idx + 1];
        }
        if j > 0 {
            s += self.ay * h[idx - n];
        }
        if j + 1 < n {
            s += self.ay * h[idx + n];
        }
        s
    }

    /// One Gauss-Seidel pass over the cells of colour `(i + j) & 1 == colour`.
    pub fn smooth_colour(&self, h: &mut [f32], f: &[f32], colour: usize) {
        let n = self.n;
        let ptr = SharedMut(h.as_mut_ptr());
        let row = |j: usize| {
            // SAFETY: this pass writes only cells of one colour, each from exactly one row task; their
            // 4-neighbours have the other colour and are only read. Indices are in bounds (i, j < n).
            unsafe { self.smooth_row(ptr, f, j, colour) };
        };
        if n * n >= PARALLEL_MIN_CELLS {
            (0..n).into_par_iter().with_min_len(ROWS_PER_TASK).for_each(row);
        } else {
            (0..n).for_each(row);
        }
    }

    /// # Safety
    /// See `smooth_colour`.
    #[inline(always)]
    unsafe fn smooth_row(&self, h: SharedMut, f: &[f32], j: usize, colour: usize) {
        let n = self.n;
        let (ax, ay) = (self.ax, self.ay);
        let start = (colour + j) & 1;
        let interior_row = j > 0 && j + 1 < n;
        let mut i = start;
        while i < n {
            let idx = j * n + i;
            let d = self.diag[idx];
            if d != 0.0 {
                let s = if interior_row && i > 0 && i + 1 < n {
                    unsafe {
                        ax * (h.get(idx - 1) + h.get(idx + 1)) + ay * (h.get(idx - n) + h.get(idx + n))
                    }
                } else {
                    let mut s = 0.0;
                    unsafe {
                        if i > 0 {
                            s += ax * h.get(idx - 1);
                        }
                        if i + 1 < n {
                            s += ax * h.get(idx + 1);
                        }
                        if j > 0 {
                            s += ay * h.get(idx - n);
                        }
                        if j + 1 < n {
                            s += ay * h.get(idx + n);
                        }
                    }
                    s
                };
                unsafe { h.set(idx, (f[idx] + s) / d) };
            }
            i += 2;
        }
    }

    /// Residual of cell `(i, j)` (0 on hard cells).
    #[inline(always)]
    pub fn residual_at(&self, h: &[f32], f: &[f32], i: usize, j: usize) -> f32 {
        let idx = j * self.n + i;
        let d = self.diag[idx];
        if d == 0.0 { 0.0 } else { f[idx] - d * h[idx] + self.neighbour_sum(h, i, j) }
    }

    /// Computes the residual, restricts it (sum of 2x2 children) into `coarse_f` (side n/2), and
    /// returns `max |r|`.
    pub fn residual_restrict(&self, h: &[f32], f: &[f32], coarse_f: &mut [f32]) -> f32 {
        let nc = self.n / 2;
        let coarse_row = |(jc, out): (usize, &mut [f32])| -> f32 {
            let mut m = 0.0f32;
            for (ic, o) in out.iter_mut().enumerate() {
                let r00 = self.residual_at(h, f, 2 * ic, 2 * jc);
                let r10 = self.residual_at(h, f, 2 * ic + 1, 2 * jc);
                let r01 = self.residual_at(h, f, 2 * ic, 2 * jc + 1);
                let r11 = self.residual_at(h, f, 2 * ic + 1, 2 * jc + 1);
                m = m.max(r00.abs()).max(r10.abs()).max(r01.abs()).max(r11.abs());
                *o = r00 + r10 + r01 + r11;
            }
            m
        };
        if self.n * self.n >= PARALLEL_MIN_CELLS {
            coarse_f
                .par_chunks_mut(nc)
                .enumerate()
                .with_min_len(ROWS_PER_TASK / 2)
                .map(coarse_row)
                .reduce(|| 0.0, f32::max)
        } else {
            coarse_f.chunks_mut(nc).enumerate().map(coarse_row).fold(0.0, f32::max)
        }
    }

    /// `max |r|` over level 0.
    pub fn residual_max(&self, h: &[f32], f: &[f32]) -> f32 {
        let n = self.n;
        (0..n)
            .into_par_iter()
            .with_min_len(ROWS_PER_TASK)
            .map(|j| (0..n).map(|i| self.residual_at(h, f, i, j).abs()).fold(0.0, f32::max))
            .reduce(|| 0.0, f32::max)
    }

    /// Right-hand side of the FMG start, restricted to level 1: `R f~` where
    /// `f~ = f + sum_{hard j} a_ij E_j` on free cells and 0 on hard cells.
    pub fn restricted_rhs_with_hard(&self, coarse_f: &mut [f32]) -> f32 {
        // f~ is exactly the residual of the field that is E on hard cells and 0 elsewhere.
        let mut base = vec![0.0f32; self.n * self.n];
        for (idx, b) in base.iter_mut().enumerate() {
            if self.diag[idx] == 0.0 {
                *b = self.value[idx];
            }
        }
        self.residual_restrict(&base, &self.f, coarse_f)
    }

    /// `h += P u` on free cells (`u` is level 1, side n/2).
    pub fn prolong_add(&self, u: &[f32], h: &mut [f32]) {
        self.prolong_impl(u, h, false);
    }

    /// `h = P u` on free cells and `h = E` on hard cells.
    pub fn prolong_set(&self, u: &[f32], h: &mut [f32]) {
        self.prolong_impl(u, h, true);
    }

    fn prolong_impl(&self, u: &[f32], h: &mut [f32], set: bool) {
        let n = self.n;
        let nc = n / 2;
        let row = |(j, out): (usize, &mut [f32])| {
            let jc = j / 2;
            let jn = if j & 1 == 1 { (jc + 1).min(nc - 1) } else { jc.saturating_sub(1) };
            for (i, o) in out.iter_mut().enumerate() {
                let idx = j * n + i;
                if self.diag[idx] == 0.0 {
                    if set {
                        *o = self.value[idx];
                    }
                    continue;
                }
                let ic = i / 2;
                let inb = if i & 1 == 1 { (ic + 1).min(nc - 1) } else { ic.saturating_sub(1) };
                let e = 0.5625 * u[jc * nc + ic]
                    + 0.1875 * (u[jc * nc + inb] + u[jn * nc + ic])
                    + 0.0625 * u[jn * nc + inb];
                if set {
                    *o = e;
                } else {
                    *o += e;
                }
            }
        };
        if n * n >= PARALLEL_MIN_CELLS {
            h.par_chunks_mut(n).enumerate().with_min_len(ROWS_PER_TASK).for_each(row);
        } else {
            h.chunks_mut(n).enumerate().for_each(row);
        }
    }

    /// `out = A p` on free cells, 0 on hard cells (`p` must be 0 on hard cells).
    pub fn apply(&self, p: &[f32], out: &mut [f32]) {
        let n = self.n;
        out.par_chunks_mut(n).enumerate().with_min_len(ROWS_PER_TASK).for_each(|(j, o)| {
            for (i, v) in o.iter_mut().enumerate() {
                let idx = j * n + i;
                let d = self.diag[idx];
                *v = if d == 0.0 { 0.0 } else { d * p[idx] - self.neighbour_sum(p, i, j) };
            }
        });
    }

    /// Resets hard cells of `h` to their values (warm start after the constraints changed).
    pub fn reset_hard(&self, h: &mut [f32]) {
        for (idx, v) in h.iter_mut().enumerate() {
            if self.diag[idx] == 0.0 {
                *v = self.value[idx];
            }
        }
    }
}
