//! Assembling a hierarchy: level 0 from a problem (whole, by rows, by columns, values only), the
//! coarse Galerkin levels rebuilt where level 0 changed (at once, or deferred until a cycle needs
//! them).

use super::{EdgeSource, Hierarchy, Rhs, coarse};
use crate::problem::FieldProblem;

impl Hierarchy {
    /// Rebuilds everything from `p`.
    pub fn assemble(&mut self, p: &FieldProblem) {
        let n = self.n();
        self.assemble_rows(p, 0..n);
    }

    /// Rebuilds level-0 rows `rows` from `p` and every coarse row they influence.
    pub fn assemble_rows(&mut self, p: &FieldProblem, rows: std::ops::Range<usize>) {
        self.assemble_rows_with(p, rows, None, None);
    }

    /// `assemble_rows` with the edge differences computed row by row by `edges` (instead of
    /// read from `p.d_east` / `p.d_north`, which are then empty): the same result, bit for bit,
    /// without level-0 edge-difference arrays. With `cols`, only columns `cols[j - rows.start]`
    /// of row `j` are assembled (the rest of the level must already hold this problem).
    pub(crate) fn assemble_rows_with(
        &mut self,
        p: &FieldProblem,
        rows: std::ops::Range<usize>,
        edges: Option<EdgeSource>,
        cols: Option<&[(usize, usize)]>,
    ) {
        debug_assert_eq!(p.n, self.n());
        let n = self.n();
        let (lo, hi) = (rows.start.min(n), rows.end.min(n));
        if lo >= hi {
            return;
        }
        let cols = cols.map(|c| &c[lo - rows.start..hi - rows.start]);
        let dirty = self.level0.assemble_rows(p, lo..hi, edges, cols);
        self.relief = self.level0.relief();
        if self.defer_coarse && self.built {
            // Noted for `flush_coarse`.
            if self.pending.len() != n {
                self.pending = vec![Vec::new(); n];
            }
            for (row, ranges) in self.pending[lo..hi].iter_mut().zip(dirty) {
                if !ranges.is_empty() {
                    row.extend(ranges);
                    merge_ranges(row);
                }
            }
            return;
        }
        self.rebuild_coarse(lo..hi, dirty);
    }

    /// Makes a hierarchy that defers its coarse levels (`defer` true) rebuild them after later
    /// assemblies only when `flush_coarse` is called: for a problem whose warm solves usually
    /// need no cycle (the gradient field during a drag). The first assembly builds them at once.
    pub(crate) fn set_defer_coarse(&mut self, defer: bool) {
        self.defer_coarse = defer;
    }

    /// True if an assembly changed the level-0 operator since the coarse levels were last built
    /// (see `set_defer_coarse`): no cycle may run before `flush_coarse`.
    pub(crate) fn coarse_pending(&self) -> bool {
        self.pending.iter().any(|r| !r.is_empty())
    }

    /// Rebuilds the coarse cells the deferred assemblies left stale (see `set_defer_coarse`):
    /// the same operators, bit for bit, as rebuilding after each assembly (every coarse cell is a
    /// function of the finer level's current operator; the union of the changed cells is
    /// rebuilt once).
    pub(crate) fn flush_coarse(&mut self) {
        let Some(lo) = self.pending.iter().position(|r| !r.is_empty()) else {
            return;
        };
        let hi = self
            .pending
            .iter()
            .rposition(|r| !r.is_empty())
            .map_or(lo, |h| h + 1);
        let dirty: Vec<Vec<std::ops::Range<usize>>> = self.pending[lo..hi]
            .iter_mut()
            .map(std::mem::take)
            .collect();
        self.rebuild_coarse(lo..hi, dirty);
    }

    /// Rebuilds every coarse cell influenced by the level-0 cells `dirty` (per row of `rows`,
    /// column ranges whose operator changed), the dense coarsest operator and its factors.
    fn rebuild_coarse(
        &mut self,
        rows: std::ops::Range<usize>,
        mut dirty: Vec<Vec<std::ops::Range<usize>>>,
    ) {
        let n = self.n();
        let (mut lo, mut hi) = (rows.start, rows.end);
        if !self.built {
            // First assembly: every coarse cell is built (see `built`).
            dirty = vec![vec![0..n]; n];
            (lo, hi) = (0, n);
            self.built = true;
        }
        // Coarse rows influenced: a level-k cell depends on the level-(k-1) cells 2I-1 ..= 2I+2 (both
        // directions), so rows and changed columns map to coarse ones with a margin of one cell.
        let threshold = coarse::INACTIVE_REL * (2.0 * self.level0.ax + 2.0 * self.level0.ay);
        for k in 0..self.coarse.len() {
            let nc = self.coarse[k].n;
            let clo = (lo / 2).saturating_sub(1);
            let chi = (hi.div_ceil(2) + 1).min(nc);
            let cols: Vec<Vec<std::ops::Range<usize>>> = (clo..chi)
                .map(|jc| {
                    let mut ranges: Vec<std::ops::Range<usize>> = Vec::new();
                    for y in (2 * jc).saturating_sub(1)..(2 * jc + 3).min(hi) {
                        if y < lo {
                            continue;
                        }
                        for c in &dirty[y - lo] {
                            ranges.push(
                                (c.start / 2).saturating_sub(1)..(c.end.div_ceil(2) + 1).min(nc),
                            );
                        }
                    }
                    merge_ranges(&mut ranges);
                    ranges
                })
                .collect();
            if k == 0 {
                self.coarse[0].galerkin_from_level0_rows(&self.level0, clo..chi, &cols);
            } else {
                let (a, b) = self.coarse.split_at_mut(k);
                b[0].galerkin_from_coarse_rows(&a[k - 1], threshold, clo..chi, &cols);
            }
            dirty = cols;
            lo = clo;
            hi = chi;
        }
        for op in &mut self.coarse {
            op.build_dense();
        }
        if let Some(last) = self.coarse.last_mut() {
            last.factor();
        }
    }

    /// Updates only the constrained values and right-hand side of rows `rows` (same weights as the
    /// last `assemble*`, so the operators stay valid).
    pub fn assemble_values_rows(&mut self, p: &FieldProblem, rows: std::ops::Range<usize>) {
        self.assemble_values_rows_with(p, rows, None);
    }

    /// `assemble_values_rows` with the edge differences from `edges` (see `assemble_rows_with`).
    pub(crate) fn assemble_values_rows_with(
        &mut self,
        p: &FieldProblem,
        rows: std::ops::Range<usize>,
        edges: Option<EdgeSource>,
    ) {
        self.assemble_values_cols(p, rows, edges, None);
    }

    /// `assemble_values_rows_with`, only columns `cols[j - rows.start]` of row `j` if `cols` is
    /// given.
    pub(crate) fn assemble_values_cols(
        &mut self,
        p: &FieldProblem,
        rows: std::ops::Range<usize>,
        edges: Option<EdgeSource>,
        cols: Option<&[(usize, usize)]>,
    ) {
        let n = self.n();
        let (lo, hi) = (rows.start.min(n), rows.end.min(n));
        if lo >= hi {
            return;
        }
        let cols = cols.map(|c| &c[lo - rows.start..hi - rows.start]);
        self.level0.assemble_values_rows(p, lo..hi, edges, cols);
        self.relief = self.level0.relief();
    }

    /// Exchanges level 0's right-hand side (constrained values, `f`, relief) with `rhs`: two
    /// problems with the same weights (the gradient field's `gx` and `gy`) share the operators
    /// and keep one right-hand side each, so that each is reassembled only where it changed. An
    /// empty `rhs` becomes a zero one of this level's size first.
    pub(crate) fn swap_rhs(&mut self, rhs: &mut Rhs) {
        self.level0.swap_rhs(rhs);
        self.relief = self.level0.relief();
    }

    /// Lends out level 0's constrained values (the level holds none until `restore_values`). For
    /// an owner that keeps the problem's values itself: it passes the same array back in as the
    /// problem's `value` to `assemble*`, which then reads it there instead of copying it.
    pub(crate) fn take_values(&mut self) -> Vec<f32> {
        std::mem::take(&mut self.level0.value)
    }

    /// Gives back the values lent by `take_values`.
    pub(crate) fn restore_values(&mut self, value: Vec<f32>) {
        self.level0.value = value;
    }

    /// Level 0's constrained values (as last assembled, or written by `values_mut`).
    pub(crate) fn values(&self) -> &[f32] {
        &self.level0.value
    }

    /// Level 0's constrained values, for an owner that keeps the problem's values there between
    /// assemblies (they take effect at the next `assemble*`, which must precede any solve).
    pub(crate) fn values_mut(&mut self) -> &mut [f32] {
        &mut self.level0.value
    }
}

/// Sorts `ranges` and merges the overlapping or touching ones.
fn merge_ranges(ranges: &mut Vec<std::ops::Range<usize>>) {
    ranges.retain(|r| r.start < r.end);
    ranges.sort_unstable_by_key(|r| r.start);
    let mut out: Vec<std::ops::Range<usize>> = Vec::with_capacity(ranges.len());
    for r in ranges.drain(..) {
        match out.last_mut() {
            Some(last) if r.start <= last.end => last.end = last.end.max(r.end),
            _ => out.push(r),
        }
    }
    *ranges = out;
}
