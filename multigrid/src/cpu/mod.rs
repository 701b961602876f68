//! The CPU backend (rayon): the reference implementation of `ALGORITHM.md`.

mod assembly;
mod coarse;
mod direct;
mod fast;
mod fcg;
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
use crate::{SolverParams, grid::COARSEST_SIDE};
pub(crate) use coarse::CoarseOp;
pub use fcg::Fcg;
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
mod tests;
