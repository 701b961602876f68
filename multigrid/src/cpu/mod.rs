//! The CPU backend (rayon): the reference implementation of `ALGORITHM.md`.

mod coarse;
mod level0;
mod par;

use rayon::prelude::*;

use crate::problem::FieldProblem;
use crate::{SolverParams, grid::COARSEST_SIDE};
pub(crate) use coarse::CoarseOp;
pub(crate) use level0::Level0;

/// The operators of one problem on every level: level 0 matrix-free, levels >= 1 Galerkin.
pub struct Hierarchy {
    pub(crate) level0: Level0,
    /// `coarse[k - 1]` is level k, down to the coarsest (side `COARSEST_SIDE`).
    pub(crate) coarse: Vec<CoarseOp>,
    relief: f32,
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
}

/// What one call did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CycleStats {
    /// Work units spent (one sweep over level 0 = 1).
    pub work_units: f64,
    /// `max |r| / ((2 ax + 2 ay) relief)` on level 0 after the call.
    pub residual: f32,
}

fn dot(a: &[f32], b: &[f32]) -> f64 {
    a.par_chunks(4096).zip(b.par_chunks(4096)).map(|(x, y)| x.iter().zip(y).map(|(a, b)| *a as f64 * *b as f64).sum::<f64>()).sum()
}

fn max_abs(a: &[f32]) -> f32 {
    a.par_chunks(4096).map(|x| x.iter().fold(0.0f32, |m, v| m.max(v.abs()))).reduce(|| 0.0, f32::max)
}

/// `out[ic, jc] = sum of the 4 children of fine` (side of `out` = side of `fine` / 2).
fn restrict_sum(fine: &[f32], out: &mut [f32]) {
    let nc = (out.len() as f64).sqrt() as usize;
    let nf = 2 * nc;
    let row = |(jc, o): (usize, &mut [f32])| {
        for (ic, v) in o.iter_mut().enumerate() {
            let b = 2 * jc * nf + 2 * ic;
            *v = fine[b] + fine[b + 1] + fine[b + nf] + fine[b + nf + 1];
        }
    };
    out.par_chunks_mut(nc).enumerate().with_min_len(16).for_each(row);
}

impl Hierarchy {
    /// An unconstrained hierarchy for an `n x n` grid with edge weights `ax`, `ay`.
    pub fn new(n: usize, ax: f32, ay: f32) -> Hierarchy {
        let mut coarse = Vec::new();
        let mut side = n / 2;
        while side >= COARSEST_SIDE {
            coarse.push(CoarseOp::new(side));
            side /= 2;
        }
        Hierarchy { level0: Level0::new(n, ax, ay), coarse, relief: 1.0 }
    }

    /// Cells per side of level 0.
    pub fn n(&self) -> usize {
        self.level0.n
    }

    /// Number of levels including level 0.
    pub fn levels(&self) -> usize {
        self.coarse.len() + 1
    }

    /// Relief used to normalise residuals.
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
        debug_assert_eq!(p.n, self.n());
        self.relief = p.relief();
        let n = self.n();
        let (lo, hi) = (rows.start.min(n), rows.end.min(n));
        if lo >= hi {
            return;
        }
        self.level0.assemble_rows(p, lo..hi);
        // Coarse rows influenced: a level-k row depends on level-(k-1) rows 2J-2 ..= 2J+3.
        let (mut lo, mut hi) = (lo, hi);
        let threshold = coarse::INACTIVE_REL * (2.0 * self.level0.ax + 2.0 * self.level0.ay);
        for k in 0..self.coarse.len() {
            let nc = self.coarse[k].n;
            let clo = (lo / 2).saturating_sub(1);
            let chi = (hi.div_ceil(2) + 1).min(nc);
            if k == 0 {
                self.coarse[0].galerkin_from_level0_rows(&self.level0, clo..chi);
            } else {
                let (a, b) = self.coarse.split_at_mut(k);
                b[0].galerkin_from_coarse_rows(&a[k - 1], threshold, clo..chi);
            }
            lo = clo;
            hi = chi;
        }
    }

    /// A zero state for this hierarchy.
    pub fn new_state(&self) -> FieldState {
        FieldState {
            h: vec![0.0; self.n() * self.n()],
            u: self.coarse.iter().map(|c| vec![0.0; c.n * c.n]).collect(),
            f: self.coarse.iter().map(|c| vec![0.0; c.n * c.n]).collect(),
        }
    }

    fn residual_scale(&self) -> f32 {
        1.0 / ((2.0 * self.level0.ax + 2.0 * self.level0.ay) * self.relief)
    }

    /// Normalised residual of `state` on level 0.
    pub fn residual(&self, state: &FieldState) -> f32 {
        self.level0.residual_max(&state.h, &self.level0.f) * self.residual_scale()
    }

    /// Sets hard cells of the state to their values (after constraints changed, before V-cycles).
    pub fn reset_hard(&self, state: &mut FieldState) {
        self.level0.reset_hard(&mut state.h);
    }

    /// Prepares FMG: coarse right-hand sides and the exact coarsest solution. Returns the index of
    /// the next level to cycle on (the coarsest level minus one).
    pub fn fmg_start(&self, st: &mut FieldState) -> usize {
        self.level0.restricted_rhs_with_hard(&mut st.f[0]);
        for k in 1..self.coarse.len() {
            let (a, b) = st.f.split_at_mut(k);
            restrict_sum(&a[k - 1], &mut b[0]);
        }
        let kc = self.coarse.len();
        self.coarse[kc - 1].solve_direct(&mut st.u[kc - 1], &st.f[kc - 1]);
        kc - 1
    }

    /// FMG step on level `k >= 1`: interpolate from level k+1, then one V-cycle. Returns work units.
    pub fn fmg_level(&self, k: usize, st: &mut FieldState, params: &SolverParams) -> f64 {
        {
            let (a, b) = st.u.split_at_mut(k);
            self.coarse[k - 1].prolong(&b[0], &mut a[k - 1], true);
        }
        self.vcycle_coarse(k, st, params)
    }

    /// Last FMG step: interpolate level 1 onto level 0 (hard cells get their values), one V-cycle.
    pub fn fmg_finish(&self, st: &mut FieldState, params: &SolverParams) -> CycleStats {
        self.level0.prolong_set(&st.u[0], &mut st.h);
        self.vcycle(st, params)
    }

    /// Full multigrid from scratch, then V-cycles until the tolerance holds.
    pub fn solve(&self, st: &mut FieldState, params: &SolverParams) -> (CycleStats, u32) {
        let mut wu = 0.0;
        let mut k = self.fmg_start(st);
        while k >= 1 {
            wu += self.fmg_level(k, st, params);
            k -= 1;
        }
        let mut stats = self.fmg_finish(st, params);
        wu += stats.work_units;
        let mut cycles = 1;
        while stats.residual > params.tolerance && cycles < params.max_vcycles {
            stats = self.vcycle(st, params);
            wu += stats.work_units;
            cycles += 1;
        }
        (CycleStats { work_units: wu, residual: stats.residual }, cycles)
    }

    /// One V-cycle on level 0. Returns work units and the residual after it.
    pub fn vcycle(&self, st: &mut FieldState, params: &SolverParams) -> CycleStats {
        let l0 = &self.level0;
        let mut wu = 0.0;
        for _ in 0..params.pre_sweeps {
            l0.smooth_colour(&mut st.h, &l0.f, 0);
            l0.smooth_colour(&mut st.h, &l0.f, 1);
            wu += 1.0;
        }
        l0.residual_restrict(&st.h, &l0.f, &mut st.f[0]);
        st.u[0].iter_mut().for_each(|v| *v = 0.0);
        let visits = if params.gamma_from_level == 0 { params.gamma } else { 1 };
        for _ in 0..visits {
            wu += self.vcycle_coarse(1, st, params);
        }
        l0.prolong_add(&st.u[0], &mut st.h);
        for _ in 0..params.post_sweeps {
            l0.smooth_colour(&mut st.h, &l0.f, 1);
            l0.smooth_colour(&mut st.h, &l0.f, 0);
            wu += 1.0;
        }
        CycleStats { work_units: wu, residual: self.residual(st) }
    }

    /// Applies one V-cycle to the error equation `A e = r` from `e = 0`: `z = M r`.
    /// Uses the coarse storage of `st` as scratch. Returns work units.
    pub fn precondition(&self, r: &[f32], z: &mut [f32], st: &mut FieldState, params: &SolverParams) -> f64 {
        let l0 = &self.level0;
        z.iter_mut().for_each(|v| *v = 0.0);
        let mut wu = 0.0;
        for _ in 0..params.pre_sweeps {
            l0.smooth_colour(z, r, 0);
            l0.smooth_colour(z, r, 1);
            wu += 1.0;
        }
        l0.residual_restrict(z, r, &mut st.f[0]);
        st.u[0].iter_mut().for_each(|v| *v = 0.0);
        let visits = if params.gamma_from_level == 0 { params.gamma } else { 1 };
        for _ in 0..visits {
            wu += self.vcycle_coarse(1, st, params);
        }
        l0.prolong_add(&st.u[0], z);
        for _ in 0..params.post_sweeps {
            l0.smooth_colour(z, r, 1);
            l0.smooth_colour(z, r, 0);
            wu += 1.0;
        }
        wu
    }

    /// Flexible preconditioned conjugate gradients on level 0 with the V-cycle as preconditioner,
    /// from the current `st.h`, for at most `max_iters` iterations or until the tolerance holds.
    /// Returns the stats and the number of iterations (= V-cycles).
    pub fn pcg(&self, st: &mut FieldState, params: &SolverParams, max_iters: u32) -> (CycleStats, u32, Vec<f32>) {
        let l0 = &self.level0;
        let len = st.h.len();
        let mut r = vec![0.0f32; len];
        let mut z = vec![0.0f32; len];
        let mut p = vec![0.0f32; len];
        let mut q = vec![0.0f32; len];
        let scale = self.residual_scale();
        // r = f - A h
        l0.apply(&st.h, &mut q);
        r.par_iter_mut().zip(&l0.f).zip(&q).enumerate().for_each(|(i, ((r, f), q))| {
            *r = if l0.diag[i] == 0.0 { 0.0 } else { f - q };
        });
        let mut hist = vec![max_abs(&r) * scale];
        let mut wu = self.precondition(&r, &mut z, st, params);
        p.copy_from_slice(&z);
        let mut rz = dot(&r, &z);
        let mut iters = 0;
        while iters < max_iters {
            l0.apply(&p, &mut q);
            let pq = dot(&p, &q);
            if pq <= 0.0 {
                break;
            }
            let alpha = (rz / pq) as f32;
            st.h.par_iter_mut().zip(&p).for_each(|(h, p)| *h += alpha * p);
            r.par_iter_mut().zip(&q).for_each(|(r, q)| *r -= alpha * q);
            iters += 1;
            let res = max_abs(&r) * scale;
            hist.push(res);
            if res <= params.tolerance {
                break;
            }
            wu += self.precondition(&r, &mut z, st, params);
            let zq = dot(&z, &q);
            let beta = (-zq / pq) as f32;
            rz = dot(&r, &z);
            p.par_iter_mut().zip(&z).for_each(|(p, z)| *p = z + beta * *p);
        }
        let res = *hist.last().unwrap_or(&0.0);
        (CycleStats { work_units: wu, residual: res }, iters, hist)
    }

    /// V-cycle on coarse level `k >= 1` for `(u_k, f_k)`. Returns work units.
    fn vcycle_coarse(&self, k: usize, st: &mut FieldState, params: &SolverParams) -> f64 {
        let op = &self.coarse[k - 1];
        let kc = self.coarse.len();
        if k == kc {
            op.solve_direct(&mut st.u[k - 1], &st.f[k - 1]);
            return 0.0;
        }
        let scale = 0.25f64.powi(k as i32);
        let mut wu = 0.0;
        for _ in 0..params.pre_sweeps {
            for c in 0..4 {
                op.smooth_colour(&mut st.u[k - 1], &st.f[k - 1], c & 1, c >> 1);
            }
            wu += scale;
        }
        {
            let (fa, fb) = st.f.split_at_mut(k);
            op.residual_restrict(&st.u[k - 1], &fa[k - 1], &mut fb[0]);
        }
        st.u[k].iter_mut().for_each(|v| *v = 0.0);
        let visits = if k >= params.gamma_from_level as usize { params.gamma } else { 1 };
        for _ in 0..visits {
            wu += self.vcycle_coarse(k + 1, st, params);
        }
        {
            let (ua, ub) = st.u.split_at_mut(k);
            op.prolong(&ub[0], &mut ua[k - 1], false);
        }
        for _ in 0..params.post_sweeps {
            for c in (0..4).rev() {
                op.smooth_colour(&mut st.u[k - 1], &st.f[k - 1], c & 1, c >> 1);
            }
            wu += scale;
        }
        wu
    }

    /// Level-k unknowns of the state (k >= 1), row 0 = south.
    pub fn level_unknowns<'a>(&self, st: &'a FieldState, k: usize) -> &'a [f32] {
        &st.u[k - 1]
    }
}

