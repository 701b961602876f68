//! The gradient-field and roughness solves: their tolerance and one field's cold or warm solve.

use std::ops::Range;

use super::CpuSolver;
use super::raster::RASTER_ROWS;
use super::warm::{Region, RowSpans, assembly_region, field_region};
use crate::SolverParams;
use crate::cpu::{FIELD_WARM_SWEEPS, FMG_SEED_RESIDUAL, Fcg, FieldState, Hierarchy, SWEEPS};
use crate::cycle::{GRADIENT_LEVEL, sweep_work_units};
use crate::fields;
use crate::problem::FieldProblem;

/// Tolerance of the gradient-field and roughness solves. The gradient field enters the heights only
/// through the edge differences inside the stroke bands, where most level-1 cells are hard, so it
/// needs far less accuracy than the heights (ALGORITHM.md, "Three fields"; test
/// `loose_field_tolerance_keeps_heights_within_1e3_of_a_tight_solve`).
pub const FIELD_TOLERANCE: f32 = 1e-2;

/// The field-solve parameters derived from the height-solve parameters: same cycle, tolerance
/// `FIELD_TOLERANCE`.
pub fn default_field_params(params: &SolverParams) -> SolverParams {
    SolverParams {
        tolerance: FIELD_TOLERANCE,
        ..*params
    }
}

/// Warm field solves relax locally around the level-1 cells whose normalised residual exceeds this
/// fraction of the field tolerance before FCG, which then usually has nothing left to do
/// (ALGORITHM.md, "Warm updates").
pub const FIELD_WARM_SEED: f32 = 0.5;

/// Solves one field: FMG + local relaxation + FCG when cold; when warm, local relaxation at the
/// largest residuals (`FIELD_WARM_SEED`) + FCG from the current state; with the work vectors `fcg`.
/// Returns work units.
pub(super) fn solve_field(
    h: &mut Hierarchy,
    st: &mut FieldState,
    params: &SolverParams,
    cold: bool,
    fcg: &mut Fcg,
    changed: Option<&Region>,
) -> (f64, Option<RowSpans>) {
    let mut wu = 0.0;
    let (threshold, sweeps) = if cold {
        h.flush_coarse();
        wu += h.fmg_with(st, params, fcg);
        (FMG_SEED_RESIDUAL, SWEEPS)
    } else {
        match changed {
            Some((rows, cols)) => h.reset_hard_cols(st, rows.clone(), cols),
            None => h.reset_hard(st),
        }
        // An edit leaves large residuals only next to the changed constraints (normalised 1-2 on
        // the benchmark drag): local sweeps there bring the field under its tolerance without a
        // global iteration (ALGORITHM.md, "Warm updates"); a few sweeps suffice for its
        // loose tolerance.
        (params.tolerance * FIELD_WARM_SEED, FIELD_WARM_SWEEPS)
    };
    // The residual computed to find the seeds is reused by FCG's start (recomputed only near
    // the relaxed cells).
    let (w, relaxed) = fcg.relax_at_residuals(h, st, threshold, sweeps);
    wu += w;
    // The coarse levels are needed (and rebuilt where assemblies changed the operator) only if
    // an iteration is.
    if fcg.begin_checked(h, st, params, Some(&relaxed)) {
        h.flush_coarse();
        wu += fcg.precondition_first(h, st, params);
    }
    let (stats, iterations) = h.iterate_started(st, params, fcg, 0.0);
    // Without a global iteration, only the relaxed cells (and the reset hard ones) changed.
    let changed = (!cold && iterations == 0).then_some(relaxed);
    (stats.work_units + wu, changed)
}

impl CpuSolver {
    /// Solves the gradient field (level 1) for the dirty rows and rebuilds the height problem's rows;
    /// notes the rows for the next roughness solve. Returns work units in level-0 units and, if
    /// the height problem was reassembled only in a region (a warm update), that region.
    pub(super) fn solve_fields(&mut self) -> (f64, Option<Region>) {
        let n = self.grid.n;
        let rows = self.dirty_rows.clone();
        let [ax, ay] = self.grid.axis_weights();
        let mut wu = 0.0;
        // Cold field solves borrow the height solve's FCG vectors (FMG and FCG start afresh after
        // them; only its reported state is kept); warm ones use their own, so that the heights'
        // residual survives for the next start.
        let (residual, iterations) = (self.fcg.residual, self.fcg.iterations);
        let fcg = if self.cold {
            &mut self.fcg
        } else {
            &mut self.field_fcg
        };
        // Gradient field on level 1: one operator, two right-hand sides (`gx` in the hierarchy,
        // `gy` in `grad_rhs_y`, swapped in for its solve). Cold: everything is assembled. Warm:
        // only the level-1 cells under the re-rasterised windows (the problem's weights and values
        // change nowhere else; the Galerkin operators follow the changed diagonal).
        let region1 = (!self.cold).then(|| field_region(n / 2, 2, &self.raster_windows));
        let px = FieldProblem::diffusion(
            n / 2,
            [ax, ay],
            std::mem::take(&mut self.grad_w),
            self.grad.take_values(),
        );
        match &region1 {
            None => self.grad.assemble_rows(&px, 0..n / 2),
            Some((r, cols)) => self
                .grad
                .assemble_rows_with(&px, r.clone(), None, Some(cols)),
        }
        self.grad.restore_values(px.value);
        let (wx, gx_region) = solve_field(
            &mut self.grad,
            &mut self.grad_x,
            &self.field_params,
            self.cold,
            fcg,
            region1.as_ref(),
        );
        self.grad.swap_rhs(&mut self.grad_rhs_y);
        let py = FieldProblem::diffusion(n / 2, [ax, ay], px.weight, self.grad.take_values());
        match &region1 {
            None => self.grad.assemble_values_rows(&py, 0..n / 2),
            Some((r, cols)) => self
                .grad
                .assemble_values_cols(&py, r.clone(), None, Some(cols)),
        }
        self.grad.restore_values(py.value);
        let (wy, gy_region) = solve_field(
            &mut self.grad,
            &mut self.grad_y,
            &self.field_params,
            self.cold,
            fcg,
            region1.as_ref(),
        );
        self.grad.swap_rhs(&mut self.grad_rhs_y);
        self.grad_w = py.weight;
        wu += sweep_work_units(GRADIENT_LEVEL) * (wx + wy);
        // Roughness (level 2) waits until asked for: note what changed.
        self.rough_rows = if self.rough_rows.is_empty() {
            rows.clone()
        } else {
            self.rough_rows.start.min(rows.start)..self.rough_rows.end.max(rows.end)
        };
        self.rough_cold |= self.cold;
        self.fcg.residual = residual;
        self.fcg.iterations = iterations;
        let region = self.assemble_heights(rows, gx_region, gy_region);
        (wu, region)
    }

    /// Rebuilds the height problem after the field solves: around the re-rasterised windows and
    /// the fields' relaxation windows (`gx_region`, `gy_region`, when no global iteration ran),
    /// else everywhere (the diffused field changes everywhere); operators only around the dirty
    /// `rows` then. Returns the region when the assembly was windowed.
    fn assemble_heights(
        &mut self,
        rows: Range<usize>,
        gx_region: Option<RowSpans>,
        gy_region: Option<RowSpans>,
    ) -> Option<Region> {
        let n = self.grid.n;
        let [ax, ay] = self.grid.axis_weights();
        let windows = std::mem::replace(&mut self.raster_windows, vec![(n, 0); n / RASTER_ROWS]);
        let region = match (self.cold, gx_region, gy_region) {
            (false, Some(rx), Some(ry)) => Some(assembly_region(n, &windows, [&rx, &ry])),
            _ => None,
        };
        // The edge differences are computed row by row inside the assembly (no level-0 arrays).
        let p = FieldProblem {
            n,
            ax,
            ay,
            weight: std::mem::take(&mut self.maps.elev_weight),
            value: self.heights.take_values(),
            ..FieldProblem::default()
        };
        let (grid, band, gx, gy) = (
            self.grid,
            &self.maps.band_weight,
            &self.grad_x.h,
            &self.grad_y.h,
        );
        let ew = &p.weight;
        let edges =
            move |j: usize, c: (usize, usize), de: &mut [f32], dn: &mut [f32], s: &mut [f32]| {
                fields::edge_differences_row(&grid, [band, ew], (gx, gy), j, c, de, dn, s)
            };
        match &region {
            Some((hrows, cols)) => {
                #[cfg(test)]
                {
                    self.windowed_assemblies += 1;
                }
                // Operators and right-hand sides only there.
                self.heights
                    .assemble_rows_with(&p, hrows.clone(), Some(&edges), Some(cols));
            }
            None => {
                // Right-hand sides on every row; the operators only where the constraints changed.
                let hrows = rows.start.saturating_sub(2)..(rows.end + 2).min(n);
                self.heights
                    .assemble_rows_with(&p, hrows.clone(), Some(&edges), None);
                if hrows != (0..n) {
                    self.heights
                        .assemble_values_rows_with(&p, 0..hrows.start, Some(&edges));
                    self.heights
                        .assemble_values_rows_with(&p, hrows.end..n, Some(&edges));
                }
            }
        }
        if self.cold {
            self.summary.rebuild(n, &p.weight, &p.value);
        } else {
            // Only the cells whose elevation constraint changed (rasterisation tracks them).
            self.summary
                .update_cells(n, &p.weight, &p.value, &self.changed);
        }
        self.maps.elev_weight = p.weight;
        self.heights.restore_values(p.value);
        region
    }
}
