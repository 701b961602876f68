//! Level 0: the matrix-free 5-point operator with hard and soft constraints (see `ALGORITHM.md`).
//!
//! General kernels (any number of sweeps, any initial guess). The assembly of the operator is in
//! `level0/assemble.rs`; the preconditioner's fused fast path is in `fast.rs`.

use super::par::{SharedMut, ZEROS, block_count, for_blocks, map_blocks, with_scratch};
use super::rows::{ALT, mask, max_abs_row, neighbour_row, prolong_row, recip, restrict_pair, sel};
use super::simd::multiversion;
use crate::problem::{FieldProblem, is_hard, soft_sigma};

mod assemble;
use assemble::level0_assemble_rows;

/// Edge differences of three rows for one cell's assembly: east of row `j`, north of row `j`,
/// north of row `j - 1`.
type EdgeRowsRef<'a> = (&'a [f32], &'a [f32], &'a [f32]);

/// Computes a problem's edge differences row by row during assembly, instead of reading them
/// from `FieldProblem::d_east` / `d_north`: `(j, (a, b), d_east_row, d_north_row, scratch)` fills
/// columns `a..b` of row `j` (at least; the rest of the rows is unspecified; `scratch` has
/// `EDGE_SCRATCH_PER_N * n + 2` floats). The assembly then needs no level-0 edge-difference
/// arrays.
pub(crate) type EdgeSource<'a> =
    &'a (dyn Fn(usize, (usize, usize), &mut [f32], &mut [f32], &mut [f32]) + Sync);

/// Runs of changed diagonals closer than this are reported as one (`Level0::assemble_rows`): each
/// run costs a few coarse cells of margin on every coarse level.
pub(crate) const DIRTY_GAP: usize = 8;

/// Scratch of an `EdgeSource` call, per level-0 cell of a row (plus 2).
pub(crate) const EDGE_SCRATCH_PER_N: usize = 4;

/// A second problem's level-0 right-hand side for the same operator (`Level0::swap_rhs`).
#[derive(Default)]
pub(crate) struct Rhs {
    value: Vec<f32>,
    f: Vec<f32>,
    row_lo: Vec<f32>,
    row_hi: Vec<f32>,
}

impl Rhs {
    /// A zero right-hand side for a level of side `n`.
    pub(crate) fn new(n: usize) -> Rhs {
        Rhs {
            value: vec![0.0; n * n],
            f: vec![0.0; n * n],
            row_lo: vec![f32::INFINITY; n],
            row_hi: vec![f32::NEG_INFINITY; n],
        }
    }

    /// The constrained values (the owner writes them; they take effect at the next assembly
    /// after `swap_rhs`).
    pub(crate) fn values_mut(&mut self) -> &mut [f32] {
        &mut self.value
    }
}

/// `sum a h` over the in-domain 4-neighbours of cell `(i, j)` of an `n x n` level, each tested
/// against the border, in the order west, east, south, north (the Gauss-Seidel update of a cell
/// one by one).
///
/// # Safety
/// `h` points to `n * n` cells, `(i, j)` is in the domain, and no other task writes those
/// neighbours meanwhile.
#[inline(always)]
pub(crate) unsafe fn neighbour_sum(
    h: SharedMut,
    n: usize,
    (ax, ay): (f32, f32),
    i: usize,
    j: usize,
) -> f32 {
    let k = j * n + i;
    let mut s = 0.0;
    // SAFETY: every index is tested against the border (contract for races).
    unsafe {
        if i > 0 {
            s += ax * h.get(k - 1);
        }
        if i + 1 < n {
            s += ax * h.get(k + 1);
        }
        if j > 0 {
            s += ay * h.get(k - n);
        }
        if j + 1 < n {
            s += ay * h.get(k + n);
        }
    }
    s
}

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
    /// Constrained values `E`. May be empty while lent out (`Hierarchy::take_values`): assembly
    /// then leaves it alone (the owner keeps the problem's values, the same array).
    pub value: Vec<f32>,
    /// Right-hand side `f = sigma E - sum a dd`.
    pub f: Vec<f32>,
    /// Per row: smallest and largest constrained value (weight > 0), +-infinity if none.
    row_lo: Vec<f32>,
    row_hi: Vec<f32>,
}

impl Level0 {
    /// An unassembled level of side `n` (all arrays zero until `assemble_rows`).
    pub fn new(n: usize, ax: f32, ay: f32) -> Level0 {
        let z = vec![0.0; n * n];
        let (row_lo, row_hi) = (vec![f32::INFINITY; n], vec![f32::NEG_INFINITY; n]);
        Level0 {
            n,
            ax,
            ay,
            diag: z.clone(),
            value: z.clone(),
            f: z,
            row_lo,
            row_hi,
        }
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

    /// Fills diagonal, values and right-hand side of rows `rows` from the problem (only columns
    /// `cols[j - rows.start]` of row `j` if `cols` is given), and caches each row's range of
    /// constrained values (for `relief`).
    ///
    /// Returns, per row, the columns whose diagonal changed, as sorted disjoint ranges (runs closer
    /// than `DIRTY_GAP` merged; the coarse operators depend on the diagonal only, so only cells
    /// near these need rebuilding).
    pub fn assemble_rows(
        &mut self,
        p: &FieldProblem,
        rows: std::ops::Range<usize>,
        edges: Option<EdgeSource>,
        cols: Option<&[(usize, usize)]>,
    ) -> Vec<Vec<std::ops::Range<usize>>> {
        level0_assemble_rows(self, p, rows, false, edges, cols)
    }

    /// Like `assemble_rows` but keeps the diagonal (same weights as before): only the constrained
    /// values and the right-hand side are written.
    pub fn assemble_values_rows(
        &mut self,
        p: &FieldProblem,
        rows: std::ops::Range<usize>,
        edges: Option<EdgeSource>,
        cols: Option<&[(usize, usize)]>,
    ) {
        level0_assemble_rows(self, p, rows, true, edges, cols);
    }

    /// Exchanges the constrained values, right-hand side and per-row value ranges with `rhs`
    /// (another problem with the same weights: see `Hierarchy::swap_rhs`).
    pub fn swap_rhs(&mut self, rhs: &mut Rhs) {
        let n = self.n;
        if rhs.f.len() != n * n {
            *rhs = Rhs::new(n);
        }
        std::mem::swap(&mut self.value, &mut rhs.value);
        std::mem::swap(&mut self.f, &mut rhs.f);
        std::mem::swap(&mut self.row_lo, &mut rhs.row_lo);
        std::mem::swap(&mut self.row_hi, &mut rhs.row_hi);
    }

    /// Relief of the constrained values of the assembled rows (see `FieldProblem::relief`).
    pub fn relief(&self) -> f32 {
        let lo = self.row_lo.iter().fold(f32::INFINITY, |a, b| a.min(*b));
        let hi = self.row_hi.iter().fold(f32::NEG_INFINITY, |a, b| a.max(*b));
        if hi > lo { (hi - lo).max(1.0) } else { 1.0 }
    }

    /// Assembles cell `i` of row `j` (any position) the general way; returns `(diag, inv, f)`.
    /// `d`: the edge differences east of row `j`, north of row `j` and north of row `j - 1` (the
    /// row below), or `None` if the problem has none.
    #[inline(always)]
    fn assemble_cell(
        &self,
        p: &FieldProblem,
        i: usize,
        j: usize,
        d: Option<EdgeRowsRef>,
    ) -> (f32, f32, f32) {
        let n = self.n;
        let (ax, ay) = (self.ax, self.ay);
        let idx = j * n + i;
        let w = p.weight[idx];
        if is_hard(w) {
            return (0.0, 0.0, 0.0);
        }
        let sigma = soft_sigma(w, ax, ay);
        let mut deg = 0.0;
        // Sum of a_ij * dd_ij, dd = wanted h_j - h_i.
        let mut flux = 0.0;
        if i + 1 < n {
            deg += ax;
            if let Some((de, _, _)) = d {
                flux += ax * de[i];
            }
        }
        if i > 0 {
            deg += ax;
            if let Some((de, _, _)) = d {
                flux -= ax * de[i - 1];
            }
        }
        if j + 1 < n {
            deg += ay;
            if let Some((_, dn, _)) = d {
                flux += ay * dn[i];
            }
        }
        if j > 0 {
            deg += ay;
            if let Some((_, _, ds)) = d {
                flux -= ay * ds[i];
            }
        }
        let d = deg + sigma;
        (d, 1.0 / d, sigma * p.value[idx] - flux)
    }

    /// Neighbour rows of row `j` of `h` (zeros outside the domain).
    #[inline(always)]
    fn around<'a>(&self, h: &'a [f32], j: usize) -> (&'a [f32], &'a [f32], &'a [f32]) {
        let n = self.n;
        let s = if j > 0 {
            &h[(j - 1) * n..j * n]
        } else {
            &ZEROS[..n]
        };
        let t = if j + 1 < n {
            &h[(j + 1) * n..(j + 2) * n]
        } else {
            &ZEROS[..n]
        };
        (s, &h[j * n..(j + 1) * n], t)
    }

    /// Residual of row `j` into `out` (0 on hard cells); `tmp` is scratch of `n` cells.
    #[inline(always)]
    fn residual_row(&self, h: &[f32], f: &[f32], j: usize, out: &mut [f32], tmp: &mut [f32]) {
        let n = self.n;
        let (s, c, t) = self.around(h, j);
        neighbour_row(c, s, t, self.ax, self.ay, tmp);
        let span = j * n..(j + 1) * n;
        let (f, d) = (&f[span.clone()], &self.diag[span]);
        for i in 0..n {
            out[i] = sel(mask(d[i] != 0.0), f[i] - d[i] * c[i] + tmp[i], 0.0);
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
    unsafe fn colour_row(
        &self,
        h: SharedMut,
        f: &[f32],
        j: usize,
        colour: usize,
        exact: bool,
        tmp: &mut [f32],
    ) {
        let n = self.n;
        let (ax, ay) = (self.ax, self.ay);
        let base = j * n;
        let (f, dg) = (&f[base..base + n], &self.diag[base..base + n]);
        if exact {
            let mut i = (colour + j) & 1;
            while i < n {
                if dg[i] != 0.0 {
                    let idx = base + i;
                    // SAFETY: in bounds; only other-colour cells are read (see the contract).
                    let s = unsafe { neighbour_sum(h, n, (ax, ay), i, j) };
                    // SAFETY: this task owns the cell (contract).
                    unsafe { h.set(idx, (f[i] + s) * recip(dg[i])) };
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
                    if j > 0 {
                        h.slice(base - n, n)
                    } else {
                        &ZEROS[..n]
                    },
                    h.slice(base, n),
                    if j + 1 < n {
                        h.slice(base + n, n)
                    } else {
                        &ZEROS[..n]
                    },
                )
            };
            neighbour_row(c, s, t, ax, ay, tmp);
        }
        // SAFETY: row j is owned by this task (contract) and no slice of it is alive.
        let c = unsafe { h.slice_mut(base, n) };
        let par = &ALT[(colour + j) & 1..][..n];
        for i in 0..n {
            let cand = (f[i] + tmp[i]) * recip(dg[i]);
            c[i] = sel(par[i] & mask(dg[i] != 0.0), cand, c[i]);
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

    /// `h += P u` on free cells (`u` is level 1, side n/2).
    pub fn prolong_add(&self, u: &[f32], h: &mut [f32]) {
        level0_prolong_add(self, u, h)
    }

    /// `reset_hard` over columns `cols[j - rows.start]` of rows `rows` only.
    pub fn reset_hard_cols(
        &self,
        h: &mut [f32],
        rows: std::ops::Range<usize>,
        cols: &[(usize, usize)],
    ) {
        let n = self.n;
        for (j, &(a, b)) in rows.zip(cols) {
            let (a, b) = (j * n + a.min(n), j * n + b.min(n));
            if a >= b {
                continue;
            }
            for ((o, d), v) in h[a..b]
                .iter_mut()
                .zip(&self.diag[a..b])
                .zip(&self.value[a..b])
            {
                if *d == 0.0 {
                    *o = *v;
                }
            }
        }
    }

    /// Resets hard cells of `h` to their values (warm start after the constraints changed).
    pub fn reset_hard(&self, h: &mut [f32]) {
        let n = self.n;
        let ptr = SharedMut(h.as_mut_ptr());
        for_blocks(n, block_count(n, n), 1, |_, rows| {
            let span = rows.start * n..rows.end * n;
            // SAFETY: these rows belong to this block.
            let o = unsafe { ptr.slice_mut(span.start, span.len()) };
            for ((o, d), v) in o
                .iter_mut()
                .zip(&self.diag[span.clone()])
                .zip(&self.value[span])
            {
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
                // SAFETY: see the block comment above (row ownership in this phase).
                unsafe { op.colour_row(ptr, f, a, first, edge(a), tmp) };
                for j in a..e {
                    if j + 1 < e {
                        // SAFETY: see the block comment above (row ownership in this phase).
                        unsafe { op.colour_row(ptr, f, j + 1, first, edge(j + 1), tmp) };
                    }
                    if !edge(j) {
                        // SAFETY: see the block comment above (row ownership in this phase).
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
    fn level0_prolong_add(op: &Level0, u: &[f32], h: &mut [f32]) {
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
                    let d = &op.diag[j * n..(j + 1) * n];
                    for i in 0..n {
                        o[i] = sel(mask(d[i] != 0.0), o[i] + e[i], o[i]);
                    }
                }
            })
        });
    }
}
