//! Level-0 assembly: the operator's diagonal and right-hand side from a problem's weights,
//! values and edge differences, row by row in parallel, with the runs of changed diagonals that
//! tell the coarse levels what to rebuild.

use rayon::prelude::*;

use super::{DIRTY_GAP, EDGE_SCRATCH_PER_N, EdgeRowsRef, EdgeSource, Level0};
use crate::cpu::par::{SharedMut, ZEROS, block_count, with_scratch};
use crate::cpu::rows::{mask, sel};
use crate::cpu::simd::multiversion;
use crate::problem::{FieldProblem, MAX_SOFT_WEIGHT, is_hard};

multiversion! {
    /// The body of `Level0::assemble_rows` and `assemble_values_rows` (see there); returns, per
    /// row, the runs of changed diagonals (none in values-only mode).
    pub(super) fn level0_assemble_rows(op: &mut Level0, p: &FieldProblem, rows: std::ops::Range<usize>, values_only: bool, edges: Option<EdgeSource>, cols: Option<&[(usize, usize)]>) -> Vec<Vec<std::ops::Range<usize>>> {
        let n = op.n;
        let (ax, ay) = (op.ax, op.ay);
        let arrays = !p.d_east.is_empty();
        let full = op.full_diag();
        let keep_value = op.value.len() == n * n;
        let ptrs = [&mut op.diag, &mut op.value, &mut op.f, &mut op.row_lo, &mut op.row_hi]
            .map(|v| SharedMut(v.as_mut_ptr()));
        let op = &*op;
        // Columns of row `j` to assemble.
        let span = |j: usize| -> (usize, usize) {
            match cols {
                Some(c) => {
                    let (a, b) = c[j - rows.start];
                    (a.min(n), b.min(n))
                }
                None => (0, n),
            }
        };
        let row = |j: usize, old: &mut [f32], d: Option<EdgeRowsRef>| -> Vec<std::ops::Range<usize>> {
            let (c0, c1) = span(j);
            if c0 >= c1 {
                return Vec::new();
            }
            // SAFETY: each row `j` is written by exactly one task; the first three arrays have n * n
            // cells, the last two n.
            let [diag, f] = [0, 2].map(|k| unsafe { ptrs[k].slice_mut(j * n, n) });
            // `saved`: the old diagonal; in values-only mode the new diagonal goes to scratch instead
            // of the level.
            let (saved, spare) = old.split_at_mut(n);
            let sd = &mut spare[..n];
            let diag = if values_only {
                sd
            } else {
                saved[c0..c1].copy_from_slice(&diag[c0..c1]);
                diag
            };
            let base = j * n;
            let (w, e) = (&p.weight[base..base + n], &p.value[base..base + n]);
            if keep_value {
                // SAFETY: as above (row j of an n * n array, this task's).
                let value = unsafe { ptrs[1].slice_mut(j * n, n) };
                value[c0..c1].copy_from_slice(&e[c0..c1]);
            }
            let interior_row = j > 0 && j + 1 < n;
            if interior_row {
                // Interior cells: every neighbour exists, so `deg` is the full diagonal; the same sums
                // as `assemble_cell`, branch-free.
                let zeros = &ZEROS[..n];
                let edges = d.unwrap_or((zeros, zeros, zeros));
                assemble_interior(c0.max(1)..c1.min(n - 1), [ax, ay], full, (w, e), edges, diag, f);
                for i in [0, n - 1] {
                    if (c0..c1).contains(&i) {
                        (diag[i], _, f[i]) = op.assemble_cell(p, i, j, d);
                    }
                }
            } else {
                for i in c0..c1 {
                    (diag[i], _, f[i]) = op.assemble_cell(p, i, j, d);
                }
            }
            // The row's range of constrained values (for `relief`), over the whole row.
            let (lo, hi) = constrained_range(w, e);
            // SAFETY: entry j belongs to this task.
            unsafe {
                ptrs[3].set(j, lo);
                ptrs[4].set(j, hi);
            }
            if values_only {
                return Vec::new();
            }
            changed_runs(saved, diag, c0..c1)
        };
        let nrows = rows.len();
        let per_block = |r: std::ops::Range<usize>| -> Vec<Vec<std::ops::Range<usize>>> {
            let extra = if edges.is_some() { (3 + EDGE_SCRATCH_PER_N) * n + 2 } else { 0 };
            with_scratch(2 * n + extra, |s| {
                let (old, s) = s.split_at_mut(2 * n);
                match edges {
                    Some(edges) => rolling_edge_rows(edges, n, rows.clone(), r, &span, s, |j, d| {
                        row(j, old, Some(d))
                    }),
                    None => r
                        .map(|k| {
                            let j = rows.start + k;
                            let b = j * n;
                            let d = arrays.then(|| {
                                let ds = if j > 0 { &p.d_north[b - n..b] } else { &ZEROS[..n] };
                                (&p.d_east[b..b + n], &p.d_north[b..b + n], ds)
                            });
                            row(j, old, d)
                        })
                        .collect(),
                }
            })
        };
        if block_count(nrows, n) == 1 {
            per_block(0..nrows)
        } else {
            let chunk = nrows.div_ceil(4 * rayon::current_num_threads()).max(1);
            let starts: Vec<usize> = (0..nrows).step_by(chunk).collect();
            let parts: Vec<Vec<Vec<std::ops::Range<usize>>>> =
                starts.par_iter().map(|&a| per_block(a..(a + chunk).min(nrows))).collect();
            parts.concat()
        }
    }
}

/// Assembles the cells `cells` of an interior row, whose neighbours all exist: the diagonal is
/// `full` plus the soft weight's term, the same sums as `Level0::assemble_cell`, branch-free.
#[inline(always)]
fn assemble_interior(
    cells: std::ops::Range<usize>,
    [ax, ay]: [f32; 2],
    full: f32,
    (w, e): (&[f32], &[f32]),
    (de, dn, ds): EdgeRowsRef,
    diag: &mut [f32],
    f: &mut [f32],
) {
    let s4 = 2.0 * ax + 2.0 * ay;
    for i in cells {
        let flux = ((ax * de[i] - ax * de[i - 1]) + ay * dn[i]) - ay * ds[i];
        let wc = w[i].min(MAX_SOFT_WEIGHT);
        let sigma = sel(mask(w[i] <= 0.0), 0.0, s4 * wc / (1.0 - wc));
        let d = full + sigma;
        let free = mask(!is_hard(w[i]));
        diag[i] = sel(free, d, 0.0);
        f[i] = sel(free, sigma * e[i] - flux, 0.0);
    }
}

/// The range `(lo, hi)` of a row's constrained values `e` (where the weight `w` is positive),
/// infinite both ways when none is.
#[inline(always)]
fn constrained_range(w: &[f32], e: &[f32]) -> (f32, f32) {
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for i in 0..w.len() {
        let c = mask(w[i] > 0.0);
        lo = lo.min(sel(c, e[i], f32::INFINITY));
        hi = hi.max(sel(c, e[i], f32::NEG_INFINITY));
    }
    (lo, hi)
}

/// Runs of the columns `cols` whose diagonal changed from `saved` to `diag` (bit for bit), merged
/// across gaps shorter than `DIRTY_GAP`.
#[inline(always)]
fn changed_runs(
    saved: &[f32],
    diag: &[f32],
    cols: std::ops::Range<usize>,
) -> Vec<std::ops::Range<usize>> {
    let mut runs: Vec<std::ops::Range<usize>> = Vec::new();
    let mut i = cols.start;
    while i < cols.end {
        if saved[i].to_bits() == diag[i].to_bits() {
            i += 1;
            continue;
        }
        let start = i;
        while i < cols.end && saved[i].to_bits() != diag[i].to_bits() {
            i += 1;
        }
        match runs.last_mut() {
            Some(last) if start - last.end < DIRTY_GAP => last.end = i,
            _ => runs.push(start..i),
        }
    }
    runs
}

/// Assembles rows `rows.start + k` for `k` in `block` with `row`, their edge differences computed
/// by `edges` on rolling rows in `scratch` (`(3 + EDGE_SCRATCH_PER_N) * n + 2` floats; `span`:
/// the columns of a row). The north differences of the row below are kept from the previous row
/// (computed once before the block's first row). Row j's differences are computed over the
/// columns of rows j and j + 1 (and one more to the west: a cell reads its west edge), so that
/// they also serve row j + 1 as its row below.
#[inline(always)]
fn rolling_edge_rows<T>(
    edges: EdgeSource,
    n: usize,
    rows: std::ops::Range<usize>,
    block: std::ops::Range<usize>,
    span: &impl Fn(usize) -> (usize, usize),
    scratch: &mut [f32],
    mut row: impl FnMut(usize, EdgeRowsRef) -> T,
) -> Vec<T> {
    let (de, s) = scratch.split_at_mut(n);
    let (mut dn, s) = s.split_at_mut(n);
    let (mut ds, es) = s.split_at_mut(n);
    let cover = |j: usize, next: Option<usize>| -> (usize, usize) {
        let (a, b) = span(j);
        let (c, d) = next.filter(|&k| k < rows.end).map_or((0, 0), span);
        let (a, b) = match (a < b, c < d) {
            (true, true) => (a.min(c), b.max(d)),
            (true, false) => (a, b),
            (false, _) => (c, d),
        };
        (a.saturating_sub(1), b)
    };
    let first = rows.start + block.start;
    if first > 0 {
        let (a, b) = cover(first, None);
        edges(first - 1, (a, b), de, ds, es);
    } else {
        ds.fill(0.0);
    }
    block
        .map(|k| {
            let j = rows.start + k;
            let (a, b) = cover(j, Some(j + 1));
            if a < b {
                edges(j, (a, b), de, dn, es);
            }
            let out = row(j, (&*de, &*dn, &*ds));
            std::mem::swap(&mut dn, &mut ds);
            out
        })
        .collect()
}
