//! Flexible preconditioned conjugate gradients on level 0, the cycle as preconditioner.

use super::{CycleStats, FieldState, Hierarchy, fast};
use crate::SolverParams;
use crate::cycle::{SPIKE_BAND, SPIKE_SHARE, SPIKE_SWEEPS};

/// FCG's stop-test relaxation, after an iteration that left the normalised residual within
/// `SPIKE_BAND` times the tolerance: around the cells of `r` (FCG's residual) above the tolerance,
/// unless their windows cover more than `n^2 / SPIKE_SHARE` cells, `SPIKE_SWEEPS` sweeps of the
/// correction `A d = r` (`d` in `z`, which the next preconditioning rewrites), `h += d`,
/// `r -= A d`. Returns the work units, `max |r|` and whether it relaxed (FCG then restarts: the
/// GPU's twin keeps `d` in `p`). A maximum set by a few cells (a steep crossing, a plateau
/// corner) then ends the solve without another global iteration.
fn relax_spikes(
    hy: &Hierarchy,
    st: &mut FieldState,
    r: &mut [f32],
    z: &mut [f32],
    tolerance: f32,
) -> (f64, f32, bool) {
    let n = hy.n();
    let seeds = hy.cells_above(r, tolerance);
    let relaxed = hy.relax_correction(&mut st.h, r, z, &seeds, SPIKE_SWEEPS, n * n / SPIKE_SHARE);
    (
        relaxed.unwrap_or(0.0),
        fast::max_abs(n, r),
        relaxed.is_some(),
    )
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
        let (mut wu, mut restart) = (0.0, false);
        if params.stop_relaxation
            && self.residual > params.tolerance
            && self.residual <= SPIKE_BAND * params.tolerance
        {
            let (w, rmax, relaxed) = relax_spikes(hy, st, r, z, params.tolerance);
            (wu, restart) = (w, relaxed);
            self.residual = rmax * hy.residual_scale();
        }
        if self.residual > params.tolerance {
            let (w, rz, zq, _) = hy.precondition_dots(r, z, Some(q), None, st, params);
            wu += w;
            let beta = if restart { 0.0 } else { (-zq / pq) as f32 };
            self.dir = Some((1.0, beta));
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
