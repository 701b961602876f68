//! The CPU backend (rayon): the reference implementation of `ALGORITHM.md`.

mod coarse;
mod direct;
mod fast;
mod flat;
mod galerkin;
mod level0;
mod lift;
mod local;
pub(crate) mod par;
pub(crate) mod rows;
pub(crate) mod simd;

use crate::cycle::{self, CycleShape, Step as CycleStep};
pub(crate) use crate::cycle::{
    FIELD_WARM_SWEEPS, FMG_SEED_RESIDUAL, RADIUS, SWEEPS, WARM_SEED_RESIDUAL,
};
use crate::problem::FieldProblem;
use crate::{SolverParams, grid::COARSEST_SIDE};
pub(crate) use coarse::CoarseOp;
pub(crate) use level0::Level0;
pub(crate) use level0::{EDGE_SCRATCH_PER_N, EdgeSource, Rhs};
use par::{SharedMut, block_count, for_blocks, map_blocks};

/// The operators of one problem on every level: level 0 matrix-free, levels >= 1 Galerkin.
pub struct Hierarchy {
    pub(crate) level0: Level0,
    /// `coarse[k - 1]` is level k, down to the coarsest (side `COARSEST_SIDE`).
    pub(crate) coarse: Vec<CoarseOp>,
    relief: f32,
    /// True once every coarse cell has been built (the first assembly builds them all, whatever
    /// changed: a coarse row keeps in its list every cell that is not standard, and a cell never
    /// built would be missing from it).
    built: bool,
    /// With `defer_coarse`, the level-0 cells whose operator changed since the coarse levels were
    /// last built: per row, sorted disjoint column ranges (empty rows: nothing pending).
    pending: Vec<Vec<std::ops::Range<usize>>>,
    /// Whether `assemble*` leaves the coarse levels to `flush_coarse` (after the first assembly).
    defer_coarse: bool,
    /// Work vectors of `iterate_to_tolerance`, kept between solves (fresh vectors cost page faults
    /// comparable to a whole iteration).
    fcg_cache: std::sync::Mutex<Fcg>,
    /// The cycle steps run since `start_trace` (tests compare them with `crate::cycle`).
    #[cfg(test)]
    trace: std::sync::Mutex<Option<Vec<CycleStep>>>,
}

/// The unknowns and right-hand sides of one field on every level.
#[derive(Clone)]
pub struct FieldState {
    /// Level-0 solution (row 0 = south).
    pub h: Vec<f32>,
    /// `u[k - 1]`: level-k unknowns.
    u: Vec<Vec<f32>>,
    /// `f[k - 1]`: level-k right-hand sides.
    f: Vec<Vec<f32>>,
    /// The FMG lift on levels 1 ..= log2 n, packed (`lift.rs`): written by `fmg_start`, read for
    /// display during FMG, emptied by `fmg_finish` (its storage is usually lent, see `fmg_start`).
    lift: Vec<f32>,
}

/// What one call did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CycleStats {
    /// Work units spent (one sweep over level 0 = 1).
    pub work_units: f64,
    /// `max |r| / ((2 ax + 2 ay) relief)` on level 0 after the call.
    pub residual: f32,
}

/// `a.b` in f64.
fn dot(a: &[f32], b: &[f32]) -> f64 {
    let n = (a.len() as f64).sqrt() as usize;
    let per_block = |_, r: std::ops::Range<usize>| {
        rows::dot_row(&a[r.start * n..r.end * n], &b[r.start * n..r.end * n])
    };
    map_blocks(n, block_count(n, n), 1, per_block, 0.0, |x, y| x + y)
}

/// Flexible preconditioned conjugate gradients (FCG(1)) on level 0, the cycle as preconditioner.
/// Kept as a struct so that the editor can run one iteration per step.
///
/// The vectors only grow: a solve on a smaller level (the gradient field borrows the heights'
/// vectors) uses their first `len` cells, so that returning to the larger level does not fill
/// them with zeros again (12 MB per drag update at 1024^2).
#[derive(Default)]
pub struct Fcg {
    r: Vec<f32>,
    z: Vec<f32>,
    p: Vec<f32>,
    q: Vec<f32>,
    /// Cells of the level being solved (the vectors' first `len` cells are in use).
    len: usize,
    /// Cells of the level whose residual `f - A h` `r` holds (0: none): left by
    /// `relax_at_residuals`, or by the last start and kept by its iterations (up to the rounding
    /// of the recurrence `r -= alpha q`). A later start may then recompute it only where the
    /// problem or `h` changed since (`start_if_needed_after`).
    r_level: usize,
    rz: f64,
    /// The next direction `p = a z + b p` as `(a, b)`, applied lazily, fused with the next
    /// `q = A p`; `None`: `p = z`.
    dir: Option<(f32, f32)>,
    /// `Some(z.Az)` when the preconditioner that computed `z` also left `A z` in `q` (the first
    /// iteration then takes `p = z`, `q = A p` and `p.q` from there instead of a pass of its own).
    q_ready: Option<f64>,
    /// Starts that recomputed the residual only near changed cells (tests).
    #[cfg(test)]
    pub(crate) partial_starts: usize,
    /// Iterations since `start`.
    pub iterations: u32,
    /// Normalised residual after the last `start` or iteration.
    pub residual: f32,
}

impl Fcg {
    /// Starts from the current `st.h`: `r = f - A h`, `z = M r`, `p = z`. Returns work units.
    pub fn start(&mut self, hy: &Hierarchy, st: &mut FieldState, params: &SolverParams) -> f64 {
        self.begin(hy, st, None);
        self.precondition_first(hy, st, params)
    }

    /// Like `start`, but checks the residual first: if it already meets `params.tolerance` (or no
    /// iteration is allowed, `max_vcycles == 0`), the preconditioner is not applied and 0 work units
    /// are spent. `iterate` must only be called when this left `residual > tolerance`.
    pub fn start_if_needed(
        &mut self,
        hy: &Hierarchy,
        st: &mut FieldState,
        params: &SolverParams,
    ) -> f64 {
        self.start_if_needed_after(hy, st, params, None)
    }

    /// `start_if_needed`; with `changed`, `r` must hold `f - A h` as it was before the cells
    /// `changed` (row spans `(row, first column, end column)`) of `h` changed: the residual is
    /// then recomputed only near them (`relax_at_residuals` leaves it so).
    pub(crate) fn start_if_needed_after(
        &mut self,
        hy: &Hierarchy,
        st: &mut FieldState,
        params: &SolverParams,
        changed: Option<&[(u32, u32, u32)]>,
    ) -> f64 {
        if !self.begin_checked(hy, st, params, changed) {
            return 0.0;
        }
        self.precondition_first(hy, st, params)
    }

    /// The first half of `start_if_needed_after`: the residual (no cycle, so `hy`'s coarse
    /// levels may be stale). Returns true if an iteration is needed: then `precondition_first`
    /// must follow before `iterate`.
    pub(crate) fn begin_checked(
        &mut self,
        hy: &Hierarchy,
        st: &FieldState,
        params: &SolverParams,
        changed: Option<&[(u32, u32, u32)]>,
    ) -> bool {
        self.begin(hy, st, changed);
        self.residual > params.tolerance && params.max_vcycles > 0
    }

    /// The common start: `r = f - A h` (recomputed only near `changed` if `r` holds the
    /// residual from before those cells changed, see `start_if_needed_after`), its normalised
    /// maximum, and no direction yet.
    fn begin(&mut self, hy: &Hierarchy, st: &FieldState, changed: Option<&[(u32, u32, u32)]>) {
        let l0 = &hy.level0;
        let len = st.h.len();
        let fresh = changed.is_some() && self.r_level == len;
        // Only `r` is needed unless an iteration follows (`precondition_first` fits the rest).
        if self.r.len() < len {
            self.r.resize(len, 0.0);
        }
        self.len = len;
        self.r_level = len;
        let r = &mut self.r[..len];
        let rmax = match changed {
            Some(c) if fresh => {
                #[cfg(test)]
                {
                    self.partial_starts += 1;
                }
                fast::residual_near(l0, &st.h, r, c);
                fast::max_abs(l0.n, r)
            }
            _ => fast::initial_residual(l0, &st.h, r),
        };
        self.residual = rmax * hy.residual_scale();
        self.iterations = 0;
        self.dir = None;
        self.q_ready = None;
        self.rz = 0.0;
    }

    /// `z = M r` after `begin` (`p = z` is taken lazily by the first iteration). Returns work
    /// units.
    pub(crate) fn precondition_first(
        &mut self,
        hy: &Hierarchy,
        st: &mut FieldState,
        params: &SolverParams,
    ) -> f64 {
        let len = self.len;
        self.fit(len);
        let (wu, rz, _, zaz) = hy.precondition_dots(
            &self.r[..len],
            &mut self.z[..len],
            None,
            Some(&mut self.q[..len]),
            st,
            params,
        );
        self.rz = rz;
        self.q_ready = zaz;
        wu
    }

    /// One iteration. Returns work units and the residual after it; `None` if the iteration
    /// cannot proceed (exactly converged: `p.Ap = 0`).
    pub fn iterate(
        &mut self,
        hy: &Hierarchy,
        st: &mut FieldState,
        params: &SolverParams,
    ) -> Option<CycleStats> {
        let l0 = &hy.level0;
        let len = self.len;
        let ready = match (self.dir, self.q_ready.take()) {
            (None, Some(pq)) => {
                // `p = z` (the vectors exchanged: `z` is rewritten before it is read again),
                // `q = A z` and `p.q` left by the preconditioner.
                std::mem::swap(&mut self.p, &mut self.z);
                Some(pq)
            }
            _ => None,
        };
        let (r, z, p, q) = (
            &mut self.r[..len],
            &mut self.z[..len],
            &mut self.p[..len],
            &mut self.q[..len],
        );
        let pq = match ready {
            Some(pq) => pq,
            None => fast::direction(l0, z, p, q, self.dir),
        };
        // Unless preconditioned below, a further iteration keeps this direction.
        self.dir = Some((0.0, 1.0));
        if pq <= 0.0 || !pq.is_finite() {
            return None;
        }
        let alpha = (self.rz / pq) as f32;
        let rmax = fast::update(l0.n, &mut st.h, p, r, q, alpha);
        self.iterations += 1;
        self.residual = rmax * hy.residual_scale();
        let mut wu = 0.0;
        if self.residual > params.tolerance {
            let (w, rz, zq, _) = hy.precondition_dots(r, z, Some(q), None, st, params);
            wu = w;
            self.dir = Some((1.0, (-zq / pq) as f32));
            self.rz = rz;
        }
        Some(CycleStats {
            work_units: wu,
            residual: self.residual,
        })
    }

    /// Local relaxation of `st.h` (`sweeps` sweeps) around the cells whose normalised residual
    /// exceeds `threshold` (`Hierarchy::relax_around_spans`), leaving in `r` the residual from
    /// before it, for `start_if_needed_after` with the returned spans. Returns work units and the
    /// relaxed cells.
    pub(crate) fn relax_at_residuals(
        &mut self,
        hy: &Hierarchy,
        st: &mut FieldState,
        threshold: f32,
        sweeps: usize,
    ) -> (f64, Vec<(u32, u32, u32)>) {
        let len = st.h.len();
        if self.r.len() < len {
            self.r.resize(len, 0.0);
        }
        let seeds = hy.large_residual_cells(&st.h, &mut self.r[..len], threshold);
        self.r_level = len;
        hy.relax_around_spans(&mut st.h, &seeds, sweeps)
    }

    /// Makes the vectors at least `len` long (growing only) and `len` the level in use.
    fn fit(&mut self, len: usize) {
        for v in [&mut self.r, &mut self.z, &mut self.p, &mut self.q] {
            if v.len() < len {
                v.resize(len, 0.0);
            }
        }
        self.len = len;
    }

    /// Lends the vectors `p` and `q` (any length, any contents) as scratch; `return_pair` gives
    /// them back. Only between a completed solve and the next `start*`, which recomputes them.
    pub(crate) fn lend_pair(&mut self) -> (Vec<f32>, Vec<f32>) {
        self.r_level = 0;
        (std::mem::take(&mut self.p), std::mem::take(&mut self.q))
    }

    /// Returns the vectors lent by `lend_pair`.
    pub(crate) fn return_pair(&mut self, p: Vec<f32>, q: Vec<f32>) {
        (self.p, self.q) = (p, q);
    }

    /// The residual vector of the level in use (tests).
    #[cfg(test)]
    pub(crate) fn residual_vector(&self) -> &[f32] {
        &self.r[..self.len]
    }

    /// Bytes held by the work vectors.
    pub fn bytes(&self) -> usize {
        4 * (self.r.capacity() + self.z.capacity() + self.p.capacity() + self.q.capacity())
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

/// `out[ic, jc] = sum of the 4 children of fine` (side of `out` = side of `fine` / 2).
fn restrict_sum(fine: &[f32], out: &mut [f32]) {
    let nc = (out.len() as f64).sqrt() as usize;
    let nf = 2 * nc;
    let ptr = SharedMut(out.as_mut_ptr());
    for_blocks(nc, block_count(nf, nf), 1, |_, r| {
        for jc in r {
            // SAFETY: coarse row jc belongs to this block.
            let o = unsafe { ptr.slice_mut(jc * nc, nc) };
            rows::restrict_pair(
                &fine[2 * jc * nf..][..nf],
                &fine[(2 * jc + 1) * nf..][..nf],
                o,
            );
        }
    });
}

impl Hierarchy {
    /// An unconstrained hierarchy for an `n x n` grid with edge weights `ax`, `ay`.
    pub fn new(n: usize, ax: f32, ay: f32) -> Hierarchy {
        let level0 = Level0::new(n, ax, ay);
        let mut coarse = Vec::new();
        let mut side = n / 2;
        while side >= COARSEST_SIDE {
            coarse.push(CoarseOp::new(side));
            side /= 2;
        }
        let std = galerkin::standard_stencils(ax, ay, level0.full_diag(), coarse.len());
        for (op, (st, active)) in coarse.iter_mut().zip(std) {
            op.set_standard(st, active);
        }
        Hierarchy {
            level0,
            coarse,
            relief: 1.0,
            built: false,
            pending: Vec::new(),
            defer_coarse: false,
            fcg_cache: Default::default(),
            #[cfg(test)]
            trace: Default::default(),
        }
    }

    /// Cells per side of level 0.
    pub fn n(&self) -> usize {
        self.level0.n
    }

    /// Number of levels including level 0.
    pub fn levels(&self) -> usize {
        self.coarse.len() + 1
    }

    /// Relief used to normalise residuals: `max E - min E` over the constrained cells of the
    /// assembled rows (at least 1; see `FieldProblem::relief`).
    pub fn relief(&self) -> f32 {
        self.relief
    }

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

    /// A zero state for this hierarchy.
    pub fn new_state(&self) -> FieldState {
        FieldState {
            h: vec![0.0; self.n() * self.n()],
            u: self.coarse.iter().map(|c| vec![0.0; c.n * c.n]).collect(),
            f: self.coarse.iter().map(|c| vec![0.0; c.n * c.n]).collect(),
            lift: Vec::new(),
        }
    }

    pub(crate) fn residual_scale(&self) -> f32 {
        1.0 / ((2.0 * self.level0.ax + 2.0 * self.level0.ay) * self.relief)
    }

    /// Normalised residual of `state` on level 0.
    pub fn residual(&self, state: &FieldState) -> f32 {
        self.level0.residual_max(&state.h, &self.level0.f) * self.residual_scale()
    }

    /// Sets the hard cells among `cells` (level-0 indices) to their values.
    pub fn reset_hard_cells(&self, state: &mut FieldState, cells: &[u32]) {
        let l0 = &self.level0;
        for &c in cells {
            let k = c as usize;
            if l0.diag[k] == 0.0 {
                state.h[k] = l0.value[k];
            }
        }
    }

    /// `reset_hard` over columns `cols[j - rows.start]` of rows `rows` only: where the constraints
    /// changed (the hard cells elsewhere already hold their values).
    pub(crate) fn reset_hard_cols(
        &self,
        state: &mut FieldState,
        rows: std::ops::Range<usize>,
        cols: &[(usize, usize)],
    ) {
        self.level0.reset_hard_cols(&mut state.h, rows, cols);
    }

    /// Sets hard cells of the state to their values (after constraints changed, before V-cycles).
    pub fn reset_hard(&self, state: &mut FieldState) {
        self.level0.reset_hard(&mut state.h);
    }

    /// Prepares FMG: the lift `g` (`lift.rs`) into `st.h` (level 0) and into `lift` (levels >= 1,
    /// packed; any vector, resized, kept in the state until `fmg_finish` hands it back), the
    /// restricted residual of `g` and the coarser right-hand sides, and the exact coarsest solution.
    /// `scratch` is any vector (resized). Returns the index of the next level to cycle on (the
    /// coarsest level minus one).
    pub fn fmg_start(
        &self,
        st: &mut FieldState,
        mut lift: Vec<f32>,
        scratch: &mut Vec<f32>,
    ) -> usize {
        debug_assert!(
            !self.coarse_pending(),
            "coarse levels stale: flush_coarse first"
        );
        self.note(CycleStep::Lift);
        lift::push_pull(&self.level0, &mut st.h, &mut lift, scratch);
        st.lift = lift;
        self.note(CycleStep::ResidualRestrict {
            level: 0,
            solution: true,
        });
        self.level0
            .residual_restrict(&st.h, &self.level0.f, &mut st.f[0]);
        for k in 1..self.coarse.len() {
            self.note(CycleStep::RestrictSum { level: k });
            let (a, b) = st.f.split_at_mut(k);
            restrict_sum(&a[k - 1], &mut b[0]);
        }
        let kc = self.coarse.len();
        self.note(CycleStep::CoarsestSolve { level: kc });
        self.coarse[kc - 1].solve_direct(&mut st.u[kc - 1], &st.f[kc - 1]);
        kc - 1
    }

    /// FMG step on level `k >= 1`: interpolate from level k+1, then one V-cycle. Returns work units.
    pub fn fmg_level(&self, k: usize, st: &mut FieldState, params: &SolverParams) -> f64 {
        self.note(CycleStep::Prolong {
            level: k,
            set: true,
            solution: false,
        });
        {
            let (a, b) = st.u.split_at_mut(k);
            self.coarse[k - 1].prolong(&b[0], &mut a[k - 1], true);
        }
        self.vcycle_coarse(k, st, params)
    }

    /// Last FMG step: `h = g + P u_1` on free cells (hard cells hold their values already).
    /// Returns the lift's storage (see `fmg_start`).
    pub fn fmg_finish(&self, st: &mut FieldState) -> Vec<f32> {
        self.note(CycleStep::Prolong {
            level: 0,
            set: false,
            solution: true,
        });
        self.level0.prolong_add(&st.u[0], &mut st.h);
        std::mem::take(&mut st.lift)
    }

    /// FMG on the coarse levels and interpolation to level 0 (hard cells get their values).
    /// Returns work units.
    pub fn fmg(&self, st: &mut FieldState, params: &SolverParams) -> f64 {
        self.fmg_with(st, params, &mut Fcg::default())
    }

    /// `fmg` with the lift stored in `fcg`'s work vectors (dead until FCG starts).
    pub fn fmg_with(&self, st: &mut FieldState, params: &SolverParams, fcg: &mut Fcg) -> f64 {
        let (lift, mut scratch) = fcg.lend_pair();
        let mut wu = 0.0;
        let mut k = self.fmg_start(st, lift, &mut scratch);
        while k >= 1 {
            wu += self.fmg_level(k, st, params);
            k -= 1;
        }
        let lift = self.fmg_finish(st);
        fcg.return_pair(lift, scratch);
        wu
    }

    /// Full multigrid from scratch, then FCG until the tolerance holds.
    /// Returns the stats and the number of level-0 iterations.
    pub fn solve(&self, st: &mut FieldState, params: &SolverParams) -> (CycleStats, u32) {
        let wu = self.fmg(st, params);
        let (stats, it) = self.iterate_to_tolerance(st, params);
        (
            CycleStats {
                work_units: wu + stats.work_units,
                residual: stats.residual,
            },
            it,
        )
    }

    /// FCG from the current `st.h` (hard cells must hold their values) until the tolerance holds.
    pub fn iterate_to_tolerance(
        &self,
        st: &mut FieldState,
        params: &SolverParams,
    ) -> (CycleStats, u32) {
        // Concurrent solves on one hierarchy (different states) each get their own vectors.
        let mut local = None;
        let mut guard = match self.fcg_cache.try_lock() {
            Ok(g) => Some(g),
            Err(std::sync::TryLockError::Poisoned(e)) => Some(e.into_inner()),
            Err(std::sync::TryLockError::WouldBlock) => None,
        };
        let fcg = match guard.as_deref_mut() {
            Some(f) => f,
            None => local.insert(Fcg::default()),
        };
        self.iterate_to_tolerance_with(st, params, fcg)
    }

    /// `iterate_to_tolerance` with caller-provided FCG work vectors (resized as needed; a solver
    /// can lend one set of vectors to several problems solved one after the other).
    pub fn iterate_to_tolerance_with(
        &self,
        st: &mut FieldState,
        params: &SolverParams,
        fcg: &mut Fcg,
    ) -> (CycleStats, u32) {
        self.iterate_to_tolerance_after(st, params, fcg, None)
    }

    /// `iterate_to_tolerance_with`, starting with `Fcg::start_if_needed_after(.., changed)`.
    pub(crate) fn iterate_to_tolerance_after(
        &self,
        st: &mut FieldState,
        params: &SolverParams,
        fcg: &mut Fcg,
        changed: Option<&[(u32, u32, u32)]>,
    ) -> (CycleStats, u32) {
        let wu = fcg.start_if_needed_after(self, st, params, changed);
        self.iterate_started(st, params, fcg, wu)
    }

    /// FCG iterations after a start (`wu` work units spent so far) until the tolerance holds.
    pub(crate) fn iterate_started(
        &self,
        st: &mut FieldState,
        params: &SolverParams,
        fcg: &mut Fcg,
        mut wu: f64,
    ) -> (CycleStats, u32) {
        while fcg.residual > params.tolerance && fcg.iterations < params.max_vcycles {
            match fcg.iterate(self, st, params) {
                Some(s) => wu += s.work_units,
                None => break,
            }
        }
        (
            CycleStats {
                work_units: wu,
                residual: fcg.residual,
            },
            fcg.iterations,
        )
    }

    /// One V-cycle on level 0. Returns work units and the residual after it.
    pub fn vcycle(&self, st: &mut FieldState, params: &SolverParams) -> CycleStats {
        let l0 = &self.level0;
        let mut wu = 0.0;
        for _ in 0..params.pre_sweeps {
            l0.sweep(&mut st.h, &l0.f, 0);
            wu += 1.0;
        }
        l0.residual_restrict(&st.h, &l0.f, &mut st.f[0]);
        wu += self.coarse_visits(1, 0, st, params);
        l0.prolong_add(&st.u[0], &mut st.h);
        for _ in 0..params.post_sweeps {
            l0.sweep(&mut st.h, &l0.f, 1);
            wu += 1.0;
        }
        CycleStats {
            work_units: wu,
            residual: self.residual(st),
        }
    }

    /// Applies one V-cycle to the error equation `A e = r` from `e = 0`: `z = M r`.
    /// Uses the coarse storage of `st` as scratch. Returns work units.
    pub fn precondition(
        &self,
        r: &[f32],
        z: &mut [f32],
        st: &mut FieldState,
        params: &SolverParams,
    ) -> f64 {
        self.precondition_dots(r, z, None, None, st, params).0
    }

    /// `precondition`, also returning `r.z` and `z.q` (0 without `q`) of the result; with `aq`,
    /// `Some(z.Az)` if the fused path also wrote `A z` into `aq` (`fast::post_phase`), else
    /// `None` (`aq` untouched).
    fn precondition_dots(
        &self,
        r: &[f32],
        z: &mut [f32],
        q: Option<&[f32]>,
        aq: Option<&mut [f32]>,
        st: &mut FieldState,
        params: &SolverParams,
    ) -> (f64, f64, f64, Option<f64>) {
        let l0 = &self.level0;
        debug_assert!(
            !self.coarse_pending(),
            "coarse levels stale: flush_coarse first"
        );
        if params.pre_sweeps == 1 && params.post_sweeps == 1 {
            // Fused path: the pre-smoothed `z` is a function of `r` alone, so `pre_phase` does not
            // store it and `post_phase` recomputes it. The same steps as `precondition_plain`.
            self.note(CycleStep::Clear { level: 0 });
            self.note_sweep(0, true);
            self.note(CycleStep::ResidualRestrict {
                level: 0,
                solution: false,
            });
            fast::pre_phase(l0, r, &mut st.f[0]);
            let wu = self.coarse_visits(1, 0, st, params);
            self.note(CycleStep::Prolong {
                level: 0,
                set: false,
                solution: false,
            });
            self.note_sweep(0, false);
            let with_aq = aq.is_some();
            let (rz, zq, zaz) = fast::post_phase(l0, z, &st.u[0], r, q, aq);
            let wu = wu + 2.0 * cycle::sweep_work_units(0);
            return (wu, rz, zq, with_aq.then_some(zaz));
        }
        let (wu, rz, zq) = self.precondition_plain(r, z, q, st, params);
        (wu, rz, zq, None)
    }

    /// `precondition_dots` step by step (any sweeps; the fused path is its one-sweep case):
    /// work units, `r.z` and `z.q` (0 without `q`).
    fn precondition_plain(
        &self,
        r: &[f32],
        z: &mut [f32],
        q: Option<&[f32]>,
        st: &mut FieldState,
        params: &SolverParams,
    ) -> (f64, f64, f64) {
        let l0 = &self.level0;
        let mut wu = 0.0;
        self.note(CycleStep::Clear { level: 0 });
        z.fill(0.0);
        for _ in 0..params.pre_sweeps {
            self.note_sweep(0, true);
            l0.sweep(z, r, 0);
            wu += cycle::sweep_work_units(0);
        }
        self.note(CycleStep::ResidualRestrict {
            level: 0,
            solution: false,
        });
        l0.residual_restrict(z, r, &mut st.f[0]);
        wu += self.coarse_visits(1, 0, st, params);
        self.note(CycleStep::Prolong {
            level: 0,
            set: false,
            solution: false,
        });
        l0.prolong_add(&st.u[0], z);
        for _ in 0..params.post_sweeps {
            self.note_sweep(0, false);
            l0.sweep(z, r, 1);
            wu += cycle::sweep_work_units(0);
        }
        (wu, dot(r, z), q.map_or(0.0, |q| dot(z, q)))
    }

    /// `u_k = 0`, then the visits of level `k` from level `k - 1` (`CycleShape::visits`).
    /// Returns work units.
    fn coarse_visits(
        &self,
        k: usize,
        from: usize,
        st: &mut FieldState,
        params: &SolverParams,
    ) -> f64 {
        self.note(CycleStep::Clear { level: k });
        st.u[k - 1].fill(0.0);
        let visits = CycleShape::unfused(self.levels(), params).visits(from);
        let mut wu = 0.0;
        for _ in 0..visits {
            wu += self.vcycle_coarse(k, st, params);
        }
        wu
    }

    /// V-cycle on coarse level `k >= 1` for `(u_k, f_k)`. Returns work units.
    fn vcycle_coarse(&self, k: usize, st: &mut FieldState, params: &SolverParams) -> f64 {
        let op = &self.coarse[k - 1];
        let kc = self.coarse.len();
        if k == kc {
            self.note(CycleStep::CoarsestSolve { level: k });
            op.solve_direct(&mut st.u[k - 1], &st.f[k - 1]);
            return 0.0;
        }
        let scale = cycle::sweep_work_units(k);
        let mut wu = 0.0;
        for _ in 0..params.pre_sweeps {
            self.note_sweep(k, true);
            op.sweep(&mut st.u[k - 1], &st.f[k - 1], true);
            wu += scale;
        }
        self.note(CycleStep::ResidualRestrict {
            level: k,
            solution: false,
        });
        {
            let (fa, fb) = st.f.split_at_mut(k);
            op.residual_restrict(&st.u[k - 1], &fa[k - 1], &mut fb[0]);
        }
        wu += self.coarse_visits(k + 1, k, st, params);
        self.note(CycleStep::Prolong {
            level: k,
            set: false,
            solution: false,
        });
        {
            let (ua, ub) = st.u.split_at_mut(k);
            op.prolong(&ub[0], &mut ua[k - 1], false);
        }
        for _ in 0..params.post_sweeps {
            self.note_sweep(k, false);
            op.sweep(&mut st.u[k - 1], &st.f[k - 1], false);
            wu += scale;
        }
        wu
    }

    /// Notes that the cycle step `step` runs (kept only in tests, from `start_trace`).
    #[inline(always)]
    fn note(&self, step: CycleStep) {
        #[cfg(test)]
        if let Ok(mut t) = self.trace.lock()
            && let Some(v) = t.as_mut()
        {
            v.push(step);
        }
        #[cfg(not(test))]
        let _ = step;
    }

    /// Notes one sweep on `level` as its colours, in the order the kernels run them: level 0
    /// colour 0 then 1 (`pre`, `Level0::sweep(.., 0)`) or 1 then 0; a coarse level's four
    /// colours ascending (`pre`, `CoarseOp::sweep(.., true)`) or descending.
    #[inline(always)]
    fn note_sweep(&self, level: usize, pre: bool) {
        let n = if level == 0 { 2 } else { 4 };
        for c in 0..n {
            let colour = if pre { c } else { n - 1 - c };
            self.note(CycleStep::Smooth { level, colour });
        }
    }

    /// Starts recording the cycle steps this hierarchy runs (tests).
    #[cfg(test)]
    pub(crate) fn start_trace(&self) {
        *self.trace.lock().unwrap_or_else(|e| e.into_inner()) = Some(Vec::new());
    }

    /// The steps recorded since `start_trace`, and stops recording (tests).
    #[cfg(test)]
    pub(crate) fn take_trace(&self) -> Vec<CycleStep> {
        let mut t = self.trace.lock().unwrap_or_else(|e| e.into_inner());
        t.take().unwrap_or_default()
    }

    /// `f - A h` on level 0, computed afresh (tests).
    #[cfg(test)]
    pub(crate) fn residual_vector(&self, h: &[f32]) -> Vec<f32> {
        let mut r = vec![0.0; h.len()];
        fast::initial_residual(&self.level0, h, &mut r);
        r
    }

    /// Level 0's diagonal and right-hand side (tests).
    #[cfg(test)]
    pub(crate) fn level0_diag_rhs(&self) -> (&[f32], &[f32]) {
        (&self.level0.diag, &self.level0.f)
    }

    /// True if every coarse row's list holds exactly its cells that are not standard (the
    /// kernels give every other cell the standard stencil; tests).
    #[cfg(test)]
    pub(crate) fn general_lists_are_complete(&self) -> bool {
        self.coarse.iter().all(|c| {
            (0..c.n).all(|j| {
                let listed: Vec<usize> = c.general[j].iter().map(|g| g.i as usize).collect();
                let expected: Vec<usize> = (0..c.n)
                    .filter(|&i| c.kind[j * c.n + i] != coarse::STANDARD)
                    .collect();
                let count = (c.n - expected.len()) as u32;
                listed == expected && c.std_count[j] == count
            })
        })
    }

    /// Every coarse level's operator as stored (kinds, per-row standard counts, the general
    /// cells' columns and stencil bits), for exact comparisons (tests).
    #[cfg(test)]
    #[allow(clippy::type_complexity)]
    pub(crate) fn coarse_fingerprint(&self) -> Vec<(Vec<u8>, Vec<u32>, Vec<(u32, [u32; 9])>)> {
        self.coarse
            .iter()
            .map(|c| {
                let general = c
                    .general
                    .iter()
                    .flatten()
                    .map(|g| (g.i, g.st.map(f32::to_bits)))
                    .collect();
                (c.kind.clone(), c.std_count.clone(), general)
            })
            .collect()
    }

    /// Level-k unknowns of the state (k >= 1), row 0 = south. During FMG they approximate
    /// `h - g` (see `level_lift`).
    pub fn level_unknowns<'a>(&self, st: &'a FieldState, k: usize) -> &'a [f32] {
        &st.u[k - 1]
    }

    /// The FMG lift on level k (k >= 1), between `fmg_start` and `fmg_finish` (empty otherwise).
    pub fn level_lift<'a>(&self, st: &'a FieldState, k: usize) -> &'a [f32] {
        let n = self.n();
        let side = n >> k;
        let o = lift::offset(n, k);
        st.lift.get(o..o + side * side).unwrap_or(&[])
    }
}

/// Helpers of the kernel tests.
#[cfg(test)]
pub(crate) mod testutil {
    use super::Hierarchy;

    /// A deterministic generator (64-bit LCG, upper bits).
    pub(crate) struct Lcg(pub u64);

    impl Lcg {
        /// The next number in `0 .. 2^31`.
        pub(crate) fn next(&mut self) -> u32 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 33) as u32
        }

        /// The next number in `0 .. m` as f32.
        pub(crate) fn below(&mut self, m: u32) -> f32 {
            (self.next() % m) as f32
        }
    }

    /// Row spans `(row, first column, end column)` the plain way: all sorted, then overlapping
    /// or touching spans of a row merged (the reference for the kernels that group them faster).
    pub(crate) fn sort_and_merge<T: Ord + Copy>(mut raw: Vec<(T, T, T)>) -> Vec<(T, T, T)> {
        raw.sort_unstable();
        let mut spans: Vec<(T, T, T)> = Vec::new();
        for (y, a, b) in raw {
            match spans.last_mut() {
                Some((ly, _, lb)) if *ly == y && a <= *lb => *lb = (*lb).max(b),
                _ => spans.push((y, a, b)),
            }
        }
        spans
    }

    /// A hierarchy of side `n` (unit edge weights) assembled from per-cell weights drawn from
    /// `weights` and values in `0 .. 1000`.
    pub(crate) fn random_hierarchy(n: usize, weights: &[f32], rng: &mut Lcg) -> Hierarchy {
        let count = weights.len() as u32;
        let weight: Vec<f32> = (0..n * n)
            .map(|_| weights[(rng.next() % count) as usize])
            .collect();
        let value: Vec<f32> = (0..n * n).map(|_| rng.below(1000)).collect();
        let p = crate::FieldProblem::diffusion(n, [1.0, 1.0], weight, value);
        let mut hy = Hierarchy::new(n, 1.0, 1.0);
        hy.assemble(&p);
        hy
    }
}

#[cfg(test)]
mod tests {
    use super::testutil::{Lcg, random_hierarchy};
    use super::*;

    /// Parameter sets: the default W(1,1) from level 1 to 3, and others that move every branch.
    fn param_sets() -> Vec<SolverParams> {
        [
            (1, 1, 2, 1, 3),
            (2, 1, 2, 0, 4),
            (0, 2, 1, 0, 0),
            (1, 2, 3, 2, 9),
            (1, 1, 2, 0, 1),
        ]
        .map(|(pre, post, gamma, from, until)| SolverParams {
            pre_sweeps: pre,
            post_sweeps: post,
            gamma,
            gamma_from_level: from,
            gamma_until_level: until,
            ..SolverParams::default()
        })
        .to_vec()
    }

    fn work_units(shape: &CycleShape, steps: &[CycleStep]) -> f64 {
        steps.iter().map(|s| s.work_units(shape)).sum()
    }

    /// The CPU executor runs exactly the steps of `crate::cycle` (the GPU plan's source): FMG,
    /// the preconditioner (fused or step by step) and a whole solve, on several sizes and
    /// parameter sets, with the work units the steps count.
    #[test]
    fn the_cpu_runs_the_cycle_steps() {
        let mut rng = Lcg(7);
        for n in [16, 32, 64, 128, 256] {
            let hy = random_hierarchy(n, &[0.0, 0.0, 0.0, 1.0, 1e3], &mut rng);
            for params in param_sets() {
                let shape = CycleShape::unfused(hy.levels(), &params);
                let what = format!("{n}^2, {params:?}");
                let mut st = hy.new_state();
                hy.start_trace();
                let wu = hy.fmg(&mut st, &params);
                let fmg = cycle::fmg(&shape);
                assert_eq!(hy.take_trace(), fmg, "FMG, {what}");
                assert_eq!(wu, work_units(&shape, &fmg), "FMG work units, {what}");

                let r = hy.residual_vector(&st.h);
                let mut z = vec![0.0; n * n];
                hy.start_trace();
                let wu = hy.precondition(&r, &mut z, &mut st, &params);
                let pre = cycle::precondition(&shape);
                assert_eq!(hy.take_trace(), pre, "preconditioner, {what}");
                assert_eq!(wu, work_units(&shape, &pre), "preconditioner WU, {what}");

                // A whole solve: FMG, then one preconditioner per FCG direction.
                let mut st = hy.new_state();
                hy.start_trace();
                let (stats, _) = hy.solve(&mut st, &params);
                let trace = hy.take_trace();
                let directions = trace
                    .iter()
                    .filter(|s| **s == CycleStep::Clear { level: 0 })
                    .count();
                assert!(directions >= 1, "{what}");
                let mut expected = fmg.clone();
                for _ in 0..directions {
                    expected.extend(&pre);
                }
                assert_eq!(trace, expected, "solve, {what}");
                assert_eq!(stats.work_units, work_units(&shape, &expected), "{what}");
            }
        }
    }

    /// The fused one-sweep preconditioner (`fast::pre_phase`, `fast::post_phase`) against the
    /// same steps run one by one (`precondition_plain`), on problems with free, soft and hard
    /// cells: the same work units, and `z` within 4 ulps of its largest value (not bit for bit:
    /// `pre_phase` computes the residual after the sweep in the form it has in exact arithmetic,
    /// zero on black cells, where the plain residual pass leaves round-off; about a fifth of the
    /// cells differ in their last bits).
    #[test]
    fn the_fused_preconditioner_equals_the_plain_one() {
        let mut rng = Lcg(11);
        let params = SolverParams::default();
        for n in [16, 64, 256] {
            let hy = random_hierarchy(n, &[0.0, 0.0, 0.0, 1.0, 1e3], &mut rng);
            let r: Vec<f32> = (0..n * n).map(|_| rng.below(2000) - 1000.0).collect();
            let q: Vec<f32> = (0..n * n).map(|_| rng.below(2000) - 1000.0).collect();
            let mut st = hy.new_state();
            let mut fused = vec![0.0; n * n];
            let (wu, rz, zq, _) =
                hy.precondition_dots(&r, &mut fused, Some(&q), None, &mut st, &params);
            let mut st = hy.new_state();
            let mut plain = vec![0.0; n * n];
            let (wu0, rz0, zq0) = hy.precondition_plain(&r, &mut plain, Some(&q), &mut st, &params);
            assert_eq!(wu, wu0, "{n}^2");
            let scale = plain.iter().fold(0.0f32, |m, x| m.max(x.abs()));
            let ulps = 4.0 * scale * f32::EPSILON;
            for (i, (a, b)) in fused.iter().zip(&plain).enumerate() {
                assert!(
                    (a - b).abs() <= ulps,
                    "{n}^2 cell {i}: fused {a}, plain {b}"
                );
            }
            let close = |a: f64, b: f64| (a - b).abs() <= 1e-6 * a.abs().max(b.abs());
            assert!(close(rz, rz0), "{n}^2: r.z {rz} against {rz0}");
            let zq_scale = (dot(&plain, &plain) * dot(&q, &q)).sqrt();
            assert!(
                (zq - zq0).abs() <= 1e-6 * zq_scale,
                "{n}^2: z.q {zq} against {zq0}"
            );
        }
    }
}
