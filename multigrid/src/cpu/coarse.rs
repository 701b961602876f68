//! Levels >= 1: 9-point Galerkin operators `A_k = R A_{k-1} P`, their smoother, residual and transfers.
//!
//! Most cells of a level see an unconstrained neighbourhood and carry the level's *standard* stencil
//! (see `galerkin.rs`); kernels run those cells through branch-free vector loops with the stencil in
//! registers and visit the few *general* cells one by one.

use super::direct::Lu;
use super::par::{SharedMut, block_count, block_rows, for_blocks, with_scratch};
use super::rows::{ALT, mask, prolong_row, restrict_pair, sel};
use super::simd::multiversion;

/// Relative threshold under which a coarse cell's centre coefficient marks it inactive.
pub(crate) const INACTIVE_REL: f32 = 1e-6;

/// Cell kinds.
pub(crate) const INACTIVE: u8 = 0;
pub(crate) const STANDARD: u8 = 1;
pub(crate) const GENERAL: u8 = 2;

/// One coarse level's operator: a 9-point stencil per cell, `st[(oy + 1) * 3 + (ox + 1)]`.
/// An inactive cell has an all-zero stencil. The stencils are not stored per cell (that would be
/// 36 bytes a cell): a standard cell's is `std_st`, the others' are in `general` (`stencil`).
pub(crate) struct CoarseOp {
    /// Cells per side.
    pub n: usize,
    /// A copy of every cell's stencil, row-major, on levels of side <= `ST_COPY_MAX_SIDE` only (for
    /// the GPU-vs-CPU tests, `gpu::oracle`); empty on larger levels. The kernels do not read it.
    pub st: Vec<[f32; 9]>,
    /// Per cell: `INACTIVE`, `STANDARD` (stencil equal to `std_st`) or `GENERAL`.
    pub kind: Vec<u8>,
    /// Per row: the general and inactive cells in column order (column and stencil; the only
    /// storage of their stencils).
    pub general: Vec<Vec<GenCell>>,
    /// Per row: number of standard cells.
    pub std_count: Vec<u32>,
    /// The standard stencil of this level (meaningful if `has_std`).
    pub std_st: [f32; 9],
    /// `1 / std_st[4]`.
    pub std_inv: f32,
    /// True if the standard stencil is mirror-symmetric (equal corners, equal north/south and
    /// east/west coefficients, as Galerkin gives for an unconstrained neighbourhood): the kernels
    /// then add the neighbours in pairs before multiplying (fewer operations, same up to round-off).
    pub std_sym: bool,
    /// False if this level has no standard stencil (it would be inactive).
    pub has_std: bool,
    /// LU factors of the active part (coarsest level only, rebuilt by `factor`).
    pub lu: Option<Lu>,
    /// Small levels (side <= `DENSE_MAX_SIDE`, many general cells): the stencils as 10 planes of
    /// `n * n` (coefficients 0..9, then `1 / c_4`, 0 on inactive cells) for the whole-level kernels
    /// of `flat.rs`. Empty on larger levels.
    pub dense: Vec<f32>,
}

/// Largest side of a level that keeps the copy `CoarseOp::st` of its stencils.
pub(crate) const ST_COPY_MAX_SIDE: usize = 128;

/// Largest side of a level that uses the whole-level kernels (`CoarseOp::dense`, `flat.rs`).
pub(crate) const DENSE_MAX_SIDE: usize = 32;

/// A general cell of a row: column and stencil.
#[derive(Clone, Copy, Debug)]
pub(crate) struct GenCell {
    /// Column.
    pub i: u32,
    /// The cell's stencil.
    pub st: [f32; 9],
}

/// The 1D factors of a cell-centred bilinear prolongation row: fine index `x` on a coarse grid of
/// side `nc` takes `0.75` from its parent and `0.25` from the side neighbour (clamped at the border).
#[inline(always)]
pub(crate) fn p_weights(x: usize, nc: usize) -> [(usize, f32); 2] {
    let parent = x / 2;
    let side = if x & 1 == 1 {
        (parent + 1).min(nc - 1)
    } else {
        parent.saturating_sub(1)
    };
    if side == parent {
        [(parent, 1.0), (parent, 0.0)]
    } else {
        [(parent, 0.75), (side, 0.25)]
    }
}

impl CoarseOp {
    /// An all-inactive level of side `n`.
    pub fn new(n: usize) -> CoarseOp {
        CoarseOp {
            n,
            st: if n <= ST_COPY_MAX_SIDE {
                vec![[0.0; 9]; n * n]
            } else {
                Vec::new()
            },
            kind: vec![INACTIVE; n * n],
            general: vec![Vec::new(); n],
            std_count: vec![0; n],
            std_st: [0.0; 9],
            std_inv: 0.0,
            std_sym: false,
            has_std: false,
            lu: None,
            dense: Vec::new(),
        }
    }

    /// The stencil of cell `(i, j)`: `std_st` for a standard cell, zeros for an inactive one, else
    /// looked up in the row's list of general cells.
    pub fn stencil(&self, i: usize, j: usize) -> &[f32; 9] {
        const ZERO: [f32; 9] = [0.0; 9];
        match self.kind[j * self.n + i] {
            STANDARD => &self.std_st,
            INACTIVE => &ZERO,
            _ => {
                let row = &self.general[j];
                match row.binary_search_by_key(&(i as u32), |g| g.i) {
                    Ok(k) => &row[k].st,
                    Err(_) => &ZERO,
                }
            }
        }
    }

    /// `sum_{o != 0} c_o u_{I+o}` for cell `(i, j)` with its own stencil. Neighbour indices are
    /// clamped to the domain: a stencil never has a non-zero coefficient towards a cell outside
    /// the domain (prolongation weights fold onto in-domain cells), so clamped terms add `0 * u`.
    ///
    /// # Safety
    /// `u` points to `n * n` cells and nobody writes the 8 neighbours during the call.
    #[inline(always)]
    unsafe fn off_sum(&self, u: SharedMut, st: &[f32; 9], i: usize, j: usize) -> f32 {
        let n = self.n;
        let (xm, xp) = (i.saturating_sub(1), (i + 1).min(n - 1));
        let (ym, yc, yp) = (j.saturating_sub(1) * n, j * n, (j + 1).min(n - 1) * n);
        // SAFETY: all indices are clamped into the domain (contract for races).
        unsafe {
            let mut s = 0.0;
            s += st[0] * u.get(ym + xm) + st[1] * u.get(ym + i) + st[2] * u.get(ym + xp);
            s += st[3] * u.get(yc + xm) + st[5] * u.get(yc + xp);
            s += st[6] * u.get(yp + xm) + st[7] * u.get(yp + i) + st[8] * u.get(yp + xp);
            s
        }
    }

    /// `out[i] = off-centre sum of the standard stencil` for `1 <= i < n - 1` of interior row `j`.
    #[inline(always)]
    fn std_off_row(&self, us: &[f32], uc: &[f32], un: &[f32], out: &mut [f32]) {
        let n = self.n;
        let s = self.std_st;
        let (us, uc, un, out) = (&us[..n], &uc[..n], &un[..n], &mut out[..n]);
        if self.std_sym {
            for i in 1..n - 1 {
                let corners = (us[i - 1] + un[i - 1]) + (us[i + 1] + un[i + 1]);
                out[i] = (s[0] * corners + s[1] * (us[i] + un[i])) + s[3] * (uc[i - 1] + uc[i + 1]);
            }
            return;
        }
        for i in 1..n - 1 {
            let a = s[0] * us[i - 1] + s[1] * us[i] + s[2] * us[i + 1];
            let b = s[3] * uc[i - 1] + s[5] * uc[i + 1];
            let c = s[6] * un[i - 1] + s[7] * un[i] + s[8] * un[i + 1];
            out[i] = a + b + c;
        }
    }

    /// `out[i] = south + north part of the standard stencil applied to u` for `1 <= i < n - 1`.
    #[inline(always)]
    fn std_vertical_row(&self, us: &[f32], un: &[f32], out: &mut [f32]) {
        let n = self.n;
        let s = self.std_st;
        let (us, un, out) = (&us[..n], &un[..n], &mut out[..n]);
        if self.std_sym {
            for i in 1..n - 1 {
                let corners = (us[i - 1] + un[i - 1]) + (us[i + 1] + un[i + 1]);
                out[i] = s[0] * corners + s[1] * (us[i] + un[i]);
            }
            return;
        }
        for i in 1..n - 1 {
            let a = s[0] * us[i - 1] + s[1] * us[i] + s[2] * us[i + 1];
            let c = s[6] * un[i - 1] + s[7] * un[i] + s[8] * un[i + 1];
            out[i] = a + c;
        }
    }

    /// Gauss-Seidel update of both sub-colours of row `j` (cells with `i & 1 == c0`, then the
    /// others), in place. The rows beside `j` do not change meanwhile, so their part of the
    /// standard stencil is computed once for both.
    ///
    /// # Safety
    /// `u` points to `n * n` cells; this task owns row `j`, and nobody writes rows `j - 1`, `j + 1`.
    #[inline(always)]
    unsafe fn row_both(&self, u: SharedMut, f: &[f32], j: usize, pre: bool, tmp: &mut [f32]) {
        let n = self.n;
        let base = j * n;
        let f = &f[base..base + n];
        let has_std = self.std_count[j] > 0;
        if has_std {
            // Standard cells are interior: rows j - 1 and j + 1 exist.
            // SAFETY: in bounds; see the contract.
            let (us, un) = unsafe { (u.slice(base - n, n), u.slice(base + n, n)) };
            self.std_vertical_row(us, un, tmp);
        }
        let order = if pre { [0, 1] } else { [1, 0] };
        for ci in order {
            if has_std {
                let (vert, cand) = tmp.split_at_mut(n);
                let (s3, s5, inv) = (self.std_st[3], self.std_st[5], self.std_inv);
                {
                    // SAFETY: row j is owned by this task; read-only while this slice lives.
                    let uc = unsafe { u.slice(base, n) };
                    if self.std_sym {
                        for i in 1..n - 1 {
                            cand[i] = (f[i] - (vert[i] + s3 * (uc[i - 1] + uc[i + 1]))) * inv;
                        }
                    } else {
                        for i in 1..n - 1 {
                            cand[i] = (f[i] - (vert[i] + (s3 * uc[i - 1] + s5 * uc[i + 1]))) * inv;
                        }
                    }
                }
                // Every cell of the colour takes the standard update here; the loop below then
                // overwrites the general and inactive ones, which only read the other colour.
                // (Computing all cells and selecting vectorises; strided loops over one colour
                // measured twice as slow.)
                // SAFETY: row j is owned by this task and no other slice of it is alive.
                let uc = unsafe { u.slice_mut(base, n) };
                let par = &ALT[ci..][..n];
                for i in 1..n - 1 {
                    uc[i] = sel(par[i], cand[i], uc[i]);
                }
            }
            for g in &self.general[j] {
                let i = g.i as usize;
                if i & 1 == ci {
                    // SAFETY: as above; `off_sum` reads only neighbours of other colours.
                    unsafe {
                        let v = if g.st[4] != 0.0 {
                            (f[i] - self.off_sum(u, &g.st, i, j)) / g.st[4]
                        } else {
                            0.0
                        };
                        u.set(base + i, v);
                    }
                }
            }
        }
    }

    /// One four-colour Gauss-Seidel sweep: colours `(i & 1) + 2 (j & 1)` ascending (`pre`) or
    /// descending. Even rows carry colours 0, 1 and odd rows 2, 3, so a sweep is "first-parity rows,
    /// then second-parity rows", run as a wavefront inside row blocks; second-parity rows at block
    /// edges are deferred until every block is done.
    pub fn sweep(&self, u: &mut [f32], f: &[f32], pre: bool) {
        if self.dense.is_empty() {
            coarse_sweep(self, u, f, pre)
        } else {
            super::flat::flat_sweep(self.n, &self.dense, u, f, pre)
        }
    }

    /// Residual `f - A u` of row `j` into `out` (0 on inactive cells).
    #[inline(always)]
    fn residual_row(&self, u: &[f32], f: &[f32], j: usize, out: &mut [f32], tmp: &mut [f32]) {
        let n = self.n;
        let base = j * n;
        let (fr, uc) = (&f[base..base + n], &u[base..base + n]);
        if self.std_count[j] > 0 {
            self.std_off_row(&u[base - n..base], uc, &u[base + n..base + 2 * n], tmp);
            // General and inactive cells are overwritten below.
            let c0 = self.std_st[4];
            out[0] = 0.0;
            out[n - 1] = 0.0;
            for i in 1..n - 1 {
                out[i] = fr[i] - c0 * uc[i] - tmp[i];
            }
        } else {
            out[..n].fill(0.0);
        }
        // Reading through a shared pointer is fine: nothing writes during a residual.
        let ptr = SharedMut(u.as_ptr() as *mut f32);
        for g in &self.general[j] {
            let i = g.i as usize;
            // SAFETY: in bounds, read only.
            out[i] = if g.st[4] != 0.0 {
                fr[i] - g.st[4] * uc[i] - unsafe { self.off_sum(ptr, &g.st, i, j) }
            } else {
                0.0
            };
        }
    }

    /// Residual restricted (sum of 2x2 children) into `coarse_f` (side n/2).
    pub fn residual_restrict(&self, u: &[f32], f: &[f32], coarse_f: &mut [f32]) {
        if self.dense.is_empty() {
            coarse_residual_restrict(self, u, f, coarse_f)
        } else {
            super::flat::flat_residual_restrict(self.n, &self.dense, u, f, coarse_f)
        }
    }

    /// `u += P uc` (set instead of add when `set`) on active cells; `uc` has side n/2.
    pub fn prolong(&self, uc: &[f32], u: &mut [f32], set: bool) {
        coarse_prolong(self, uc, u, set)
    }

    /// Solves `A u = f` exactly over the active cells (inactive cells get 0), with the LU factors
    /// from the last `factor` (Gaussian elimination with partial pivoting). Meant for the coarsest
    /// level (at most 8x8).
    pub fn solve_direct(&self, u: &mut [f32], f: &[f32]) {
        u.fill(0.0);
        if let Some(lu) = &self.lu {
            lu.solve(f, u);
        }
    }

    /// Rebuilds the stencil planes of a small level (no-op on large levels).
    pub fn build_dense(&mut self) {
        let n = self.n;
        if n > DENSE_MAX_SIDE {
            return;
        }
        let nn = n * n;
        self.dense.resize(10 * nn, 0.0);
        for c in 0..nn {
            let st = *self.stencil(c % n, c / n);
            for (o, v) in st.iter().enumerate() {
                self.dense[o * nn + c] = *v;
            }
            self.dense[9 * nn + c] = if st[4] != 0.0 { 1.0 / st[4] } else { 0.0 };
        }
    }

    /// Factors the active part of the operator for `solve_direct`.
    pub fn factor(&mut self) {
        let n = self.n;
        let st: Vec<[f32; 9]> = (0..n * n).map(|c| *self.stencil(c % n, c / n)).collect();
        self.lu = Some(Lu::new(n, &st));
    }
}

multiversion! {
    fn coarse_sweep(op: &CoarseOp, u: &mut [f32], f: &[f32], pre: bool) {
        let n = op.n;
        let fp = if pre { 0 } else { 1 };
        let count = block_count(n, n);
        let ptr = SharedMut(u.as_mut_ptr());
        let deferred = |j: usize, a: usize, e: usize| j & 1 != fp && ((j == a && a > 0) || (j + 1 == e && e < n));
        for_blocks(n, count, 2, |_, rows| {
            let (a, e) = (rows.start, rows.end);
            with_scratch(2 * n, |tmp| {
                // SAFETY (all calls): first-parity rows of this block read second-parity rows, which
                // are this block's (updated later, in order) or deferred edge rows of the neighbours
                // (not written in this phase); second-parity rows read first-parity rows of this
                // block only (the ones next to other blocks are deferred).
                for j in a..e {
                    if j & 1 == fp {
                        // SAFETY: see the block comment above (row ownership in this phase).
                        unsafe { op.row_both(ptr, f, j, pre, tmp) };
                        if j > a && !deferred(j - 1, a, e) {
                            // SAFETY: see the block comment above (row ownership in this phase).
                            unsafe { op.row_both(ptr, f, j - 1, pre, tmp) };
                        }
                    }
                }
                let last = e - 1;
                if last & 1 != fp && !deferred(last, a, e) {
                    // SAFETY: see the block comment above (row ownership in this phase).
                    unsafe { op.row_both(ptr, f, last, pre, tmp) };
                }
            });
        });
        if count > 1 {
            with_scratch(2 * n, |tmp| {
                for b in 0..count {
                    let r = block_rows(b, count, n, 2);
                    for j in [r.start, r.end - 1] {
                        if deferred(j, r.start, r.end) {
                            // SAFETY: serial; all first-parity rows are done.
                            unsafe { op.row_both(ptr, f, j, pre, tmp) };
                        }
                    }
                }
            });
        }
    }
}

multiversion! {
    fn coarse_residual_restrict(op: &CoarseOp, u: &[f32], f: &[f32], coarse_f: &mut [f32]) {
        let n = op.n;
        let nc = n / 2;
        let out = SharedMut(coarse_f.as_mut_ptr());
        for_blocks(nc, block_count(n, n), 1, |_, rows| {
            with_scratch(3 * n, |s| {
                let (r0, s) = s.split_at_mut(n);
                let (r1, tmp) = s.split_at_mut(n);
                for jc in rows {
                    op.residual_row(u, f, 2 * jc, r0, tmp);
                    op.residual_row(u, f, 2 * jc + 1, r1, tmp);
                    // SAFETY: coarse row jc belongs to this block.
                    restrict_pair(r0, r1, unsafe { out.slice_mut(jc * nc, nc) });
                }
            })
        });
    }
}

multiversion! {
    fn coarse_prolong(op: &CoarseOp, uc: &[f32], u: &mut [f32], set: bool) {
        let n = op.n;
        let nc = n / 2;
        let ptr = SharedMut(u.as_mut_ptr());
        for_blocks(n, block_count(n, n), 1, |_, rows| {
            with_scratch(n + nc + 2, |s| {
                let (e, v) = s.split_at_mut(n);
                for j in rows {
                    prolong_row(uc, nc, j, v, e);
                    // SAFETY: row j belongs to this block.
                    let o = unsafe { ptr.slice_mut(j * n, n) };
                    let kind = &op.kind[j * n..(j + 1) * n];
                    if set {
                        for i in 0..n {
                            o[i] = sel(mask(kind[i] != INACTIVE), e[i], 0.0);
                        }
                    } else {
                        for i in 0..n {
                            o[i] = sel(mask(kind[i] != INACTIVE), o[i] + e[i], o[i]);
                        }
                    }
                }
            })
        });
    }
}
