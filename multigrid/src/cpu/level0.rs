//! Level 0: the matrix-free 5-point operator with hard and soft constraints (see `ALGORITHM.md`).
//!
//! General kernels (any number of sweeps, any initial guess). The preconditioner's fused fast path is
//! in `fast.rs`.

use super::par::{SharedMut, ZEROS, block_count, for_blocks, map_blocks, with_scratch};
use super::simd::multiversion;
use super::rows::{ALT, mask, max_abs_row, neighbour_row, prolong_row, restrict_pair, sel};
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
    /// `1 / diag` on free cells, exactly 0 on hard cells.
    pub inv: Vec<f32>,
}

impl Level0 {
    /// An unconstrained level of side `n` (every cell free, `f = 0`).
    pub fn new(n: usize, ax: f32, ay: f32) -> Level0 {
        let z = vec![0.0; n * n];
        Level0 { n, ax, ay, diag: z.clone(), value: z.clone(), f: z.clone(), inv: z }
    }

    /// Diagonal of a free interior cell without soft constraint (summed as `assemble_rows` does).
    pub fn full_diag(&self) -> f32 {
        let mut deg = 0.0f32;
        deg += self.ax;
        deg += self.ax;
        deg += self.ay;
        deg += self.ay;
        deg + 0.0
    }

    /// Fills diagonal, values and right-hand side of rows `rows` from the problem.
    pub fn assemble_rows(&mut self, p: &FieldProblem, rows: std::ops::Range<usize>) {
        let n = self.n;
        let (ax, ay) = (self.ax, self.ay);
        let has_d = !p.d_east.is_empty();
        let ptrs = [&mut self.diag, &mut self.value, &mut self.f, &mut self.inv].map(|v| SharedMut(v.as_mut_ptr()));
        let row = |j: usize| {
            // SAFETY: each row `j` is written by exactly one task; the four arrays have n * n cells.
            let [diag, value, f, inv] = ptrs.map(|p| unsafe { p.slice_mut(j * n, n) });
            for i in 0..n {
                let idx = j * n + i;
                let w = p.weight[idx];
                value[i] = p.value[idx];
                if is_hard(w) {
                    diag[i] = 0.0;
                    f[i] = 0.0;
                    inv[i] = 0.0;
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
                inv[i] = 1.0 / diag[i];
                f[i] = sigma * p.value[idx] - flux;
            }
        };
        let nrows = rows.len();
        let count = block_count(nrows, n);
        for_blocks(nrows, count, 1, |_, r| r.for_each(|k| row(rows.start + k)));
    }

    /// Neighbour rows of row `j` of `h` (zeros outside the domain).
    #[inline(always)]
    fn around<'a>(&self, h: &'a [f32], j: usize) -> (&'a [f32], &'a [f32], &'a [f32]) {
        let n = self.n;
        let s = if j > 0 { &h[(j - 1) * n..j * n] } else { &ZEROS[..n] };
        let t = if j + 1 < n { &h[(j + 1) * n..(j + 2) * n] } else { &ZEROS[..n] };
        (s, &h[j * n..(j + 1) * n], t)
    }

    /// Residual of row `j` into `out` (0 on hard cells); `tmp` is scratch of `n` cells.
    #[inline(always)]
    fn residual_row(&self, h: &[f32], f: &[f32], j: usize, out: &mut [f32], tmp: &mut [f32]) {
        let n = self.n;
        let (s, c, t) = self.around(h, j);
        neighbour_row(c, s, t, self.ax, self.ay, tmp);
        let span = j * n..(j + 1) * n;
        let (f, d, inv) = (&f[span.clone()], &self.diag[span.clone()], &self.inv[span]);
        for i in 0..n {
            out[i] = sel(mask(inv[i] != 0.0), f[i] - d[i] * c[i] + tmp[i], 0.0);
        }
    }

    /// Gauss-Seidel update of the cells of colour `colour` (`(i + j) & 1`) in row `j`, in place.
    /// `exact` reads only the other colour's cells (for rows whose neighbour rows another task
    /// updates in the same pass); otherwise the whole neighbour rows are read.
    ///
    /// # Safety
    /// `h` points to `n * n` cells; no other task writes row `j` or reads its `colour` cells, and
    /// no other task writes the cells read here (the other colour in rows `j-1..=j+1`, and with
    /// `!exact` all of rows `j - 1` and `j + 1`).
    #[inline(always)]
    unsafe fn colour_row(&self, h: SharedMut, f: &[f32], j: usize, colour: usize, exact: bool, tmp: &mut [f32]) {
        let n = self.n;
        let (ax, ay) = (self.ax, self.ay);
        let base = j * n;
        let (f, inv) = (&f[base..base + n], &self.inv[base..base + n]);
        if exact {
            let mut i = (colour + j) & 1;
            while i < n {
                if inv[i] != 0.0 {
                    let idx = base + i;
                    // SAFETY: in bounds; only other-colour cells are read (see the contract).
                    let s = unsafe {
                        let mut s = 0.0;
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
                        s
                    };
                    // SAFETY: this task owns the cell (contract).
                    unsafe { h.set(idx, (f[i] + s) * inv[i]) };
                }
                i += 2;
            }
            return;
        }
        {
            // SAFETY: rows j-1..=j+1 are in bounds and not written by others (contract); row j is
            // only read here, before the writes below.
            let (s, c, t) = unsafe {
                (
                    if j > 0 { h.slice(base - n, n) } else { &ZEROS[..n] },
                    h.slice(base, n),
                    if j + 1 < n { h.slice(base + n, n) } else { &ZEROS[..n] },
                )
            };
            neighbour_row(c, s, t, ax, ay, tmp);
        }
        // SAFETY: row j is owned by this task (contract) and no slice of it is alive.
        let c = unsafe { h.slice_mut(base, n) };
        let par = &ALT[(colour + j) & 1..][..n];
        for i in 0..n {
            let cand = (f[i] + tmp[i]) * inv[i];
            c[i] = sel(par[i] & mask(inv[i] != 0.0), cand, c[i]);
        }
    }

    /// One symmetric-order Gauss-Seidel sweep: colour `first` on all cells, then the other colour.
    /// Rows are processed in a wavefront (first colour of row j+1, then second colour of row j)
    /// inside each parallel block; second-colour updates of block edge rows are deferred.
    pub fn sweep(&self, h: &mut [f32], f: &[f32], first: usize) {
        level0_sweep(self, h, f, first)
    }

    /// Computes the residual and restricts it (sum of 2x2 children) into `coarse_f` (side n/2).
    pub fn residual_restrict(&self, h: &[f32], f: &[f32], coarse_f: &mut [f32]) {
        level0_residual_restrict(self, h, f, coarse_f)
    }

    /// `max |r|` over level 0.
    pub fn residual_max(&self, h: &[f32], f: &[f32]) -> f32 {
        level0_residual_max(self, h, f)
    }

    /// Right-hand side of the FMG start, restricted to level 1: `R f~` where
    /// `f~ = f + sum_{hard j} a_ij E_j` on free cells and 0 on hard cells.
    pub fn restricted_rhs_with_hard(&self, coarse_f: &mut [f32]) {
        // f~ is exactly the residual of the field that is E on hard cells and 0 elsewhere.
        let n = self.n;
        let mut base = vec![0.0f32; n * n];
        let ptr = SharedMut(base.as_mut_ptr());
        for_blocks(n, block_count(n, n), 1, |_, rows| {
            for j in rows {
                // SAFETY: row j belongs to this block.
                let b = unsafe { ptr.slice_mut(j * n, n) };
                let (d, v) = (&self.diag[j * n..(j + 1) * n], &self.value[j * n..(j + 1) * n]);
                for i in 0..n {
                    b[i] = sel(mask(d[i] == 0.0), v[i], 0.0);
                }
            }
        });
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
        level0_prolong_impl(self, u, h, set)
    }

    /// `out = A p` on free cells, 0 on hard cells (`p` must be 0 on hard cells).
    pub fn apply(&self, p: &[f32], out: &mut [f32]) {
        level0_apply(self, p, out)
    }

    /// Resets hard cells of `h` to their values (warm start after the constraints changed).
    pub fn reset_hard(&self, h: &mut [f32]) {
        let n = self.n;
        let ptr = SharedMut(h.as_mut_ptr());
        for_blocks(n, block_count(n, n), 1, |_, rows| {
            let span = rows.start * n..rows.end * n;
            // SAFETY: these rows belong to this block.
            let o = unsafe { ptr.slice_mut(span.start, span.len()) };
            for ((o, d), v) in o.iter_mut().zip(&self.diag[span.clone()]).zip(&self.value[span]) {
                if *d == 0.0 {
                    *o = *v;
                }
            }
        });
    }
}

multiversion! {
    fn level0_sweep(op: &Level0, h: &mut [f32], f: &[f32], first: usize) {
            let n = op.n;
            let second = 1 - first;
            let count = block_count(n, n);
            let ptr = SharedMut(h.as_mut_ptr());
            for_blocks(n, count, 1, |_, rows| {
                let (a, e) = (rows.start, rows.end);
                let edge = |j: usize| (j == a && a > 0) || (j + 1 == e && e < n);
                with_scratch(n, |tmp| {
                    // SAFETY (all calls below): rows a..e belong to this block. First-colour updates read
                    // only second-colour cells of the rows beside the block (exact on edge rows), which
                    // nobody writes in this phase because second-colour updates of edge rows are deferred.
                    // Second-colour updates of inner rows read rows inside the block only.
                    unsafe { op.colour_row(ptr, f, a, first, edge(a), tmp) };
                    for j in a..e {
                        if j + 1 < e {
                            unsafe { op.colour_row(ptr, f, j + 1, first, edge(j + 1), tmp) };
                        }
                        if !edge(j) {
                            unsafe { op.colour_row(ptr, f, j, second, false, tmp) };
                        }
                    }
                });
            });
            if count > 1 {
                with_scratch(n, |tmp| {
                    for b in 0..count {
                        let rows = super::par::block_rows(b, count, n, 1);
                        for j in [rows.start, rows.end - 1] {
                            if (j == rows.start && j > 0) || (j + 1 == rows.end && rows.end < n) {
                                // SAFETY: serial; all first-colour updates are done.
                                unsafe { op.colour_row(ptr, f, j, second, true, tmp) };
                            }
                        }
                    }
                });
            }
    }
}

multiversion! {
    fn level0_residual_restrict(op: &Level0, h: &[f32], f: &[f32], coarse_f: &mut [f32]) {
            let nc = op.n / 2;
            let out = SharedMut(coarse_f.as_mut_ptr());
            for_blocks(nc, block_count(op.n, op.n), 1, |_, rows| {
                with_scratch(3 * op.n, |s| {
                    let (r0, rest) = s.split_at_mut(op.n);
                    let (r1, tmp) = rest.split_at_mut(op.n);
                    for jc in rows {
                        op.residual_row(h, f, 2 * jc, r0, tmp);
                        op.residual_row(h, f, 2 * jc + 1, r1, tmp);
                        // SAFETY: coarse row jc belongs to this block.
                        restrict_pair(r0, r1, unsafe { out.slice_mut(jc * nc, nc) });
                    }
                })
            });
    }
}

multiversion! {
    fn level0_residual_max(op: &Level0, h: &[f32], f: &[f32]) -> f32 {
            let n = op.n;
            let per_block = |_, rows: std::ops::Range<usize>| {
                with_scratch(2 * n, |s| {
                    let (r, tmp) = s.split_at_mut(n);
                    rows.map(|j| {
                        op.residual_row(h, f, j, r, tmp);
                        max_abs_row(r)
                    })
                    .fold(0.0f32, f32::max)
                })
            };
            map_blocks(n, block_count(n, n), 1, per_block, 0.0, f32::max)
    }
}

multiversion! {
    fn level0_prolong_impl(op: &Level0, u: &[f32], h: &mut [f32], set: bool) {
            let n = op.n;
            let nc = n / 2;
            let ptr = SharedMut(h.as_mut_ptr());
            for_blocks(n, block_count(n, n), 1, |_, rows| {
                with_scratch(n + nc + 2, |s| {
                    let (e, v) = s.split_at_mut(n);
                    for j in rows {
                        prolong_row(u, nc, j, v, e);
                        // SAFETY: row j belongs to this block.
                        let o = unsafe { ptr.slice_mut(j * n, n) };
                        let (d, val) = (&op.diag[j * n..(j + 1) * n], &op.value[j * n..(j + 1) * n]);
                        if set {
                            for i in 0..n {
                                o[i] = sel(mask(d[i] != 0.0), e[i], val[i]);
                            }
                        } else {
                            for i in 0..n {
                                o[i] = sel(mask(d[i] != 0.0), o[i] + e[i], o[i]);
                            }
                        }
                    }
                })
            });
    }
}

multiversion! {
    fn level0_apply(op: &Level0, p: &[f32], out: &mut [f32]) {
            let n = op.n;
            let ptr = SharedMut(out.as_mut_ptr());
            for_blocks(n, block_count(n, n), 1, |_, rows| {
                with_scratch(n, |tmp| {
                    for j in rows {
                        let (s, c, t) = op.around(p, j);
                        neighbour_row(c, s, t, op.ax, op.ay, tmp);
                        // SAFETY: row j belongs to this block.
                        let o = unsafe { ptr.slice_mut(j * n, n) };
                        let d = &op.diag[j * n..(j + 1) * n];
                        for i in 0..n {
                            o[i] = sel(mask(d[i] != 0.0), d[i] * c[i] - tmp[i], 0.0);
                        }
                    }
                })
            });
    }
}
