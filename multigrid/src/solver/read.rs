//! What the CPU solver shows: heights, mips, bounds, fields and parameters.

use rayon::prelude::*;

use super::field::solve_field;
use super::{CpuSolver, Phase, PhaseMs};
use crate::SolverParams;
use crate::constraints::ConstraintMaps;
use crate::cpu::Fcg;
use crate::cycle::{ROUGHNESS_LEVEL, sweep_work_units};
use crate::problem::FieldProblem;
use crate::pyramid::MinMaxLevel;

impl CpuSolver {
    /// The phase times accumulated since the last call (or the last `solve`), and resets them.
    pub fn take_phase_ms(&mut self) -> PhaseMs {
        std::mem::take(&mut self.phase_ms)
    }

    /// Level-0 heights, metres, row 0 = south.
    pub fn heights(&self) -> &[f32] {
        &self.height_state.h
    }

    /// Mip level `k` (0 = full resolution), row 0 = south.
    pub fn mip(&self, k: usize) -> &[f32] {
        if k == 0 {
            &self.height_state.h
        } else {
            &self.mips[k - 1]
        }
    }

    /// Makes the next FCG start (after the current edit's field solves) run at least one iteration
    /// even if the residual already meets the tolerance: a gentle edit (a band widened a little)
    /// can leave a residual under the tolerance after the local relaxation while the heights away
    /// from the changed cells have not moved yet, and the editor shows a global correction.
    pub fn require_iteration(&mut self) {
        if self.phase != Phase::Done {
            self.force_iteration = true;
        }
    }

    /// Normalised level-0 residual of the heights (`f32::INFINITY` before level 0 is ready).
    pub fn residual(&self) -> f32 {
        if self.finest_ready == Some(0) {
            self.fcg.residual
        } else {
            f32::INFINITY
        }
    }

    /// Finest mip level holding a solution.
    pub fn finest_ready_level(&self) -> Option<u32> {
        self.finest_ready
    }

    /// Per cell of mip `level` >= 1 (side n >> level, row 0 = south), `(sum of E, count)` of the
    /// hard level-0 cells under it: the mips' constraint summary, kept current by every edit
    /// (empty before any, and for level 0 or a level past the chain).
    pub fn hard_summary(&self, level: u32) -> &[(f32, f32)] {
        (level as usize)
            .checked_sub(1)
            .and_then(|k| self.summary.levels.get(k))
            .map(Vec::as_slice)
            .unwrap_or(&[])
    }

    /// The min/max pyramid (levels of side <= 64, finest first).
    pub fn minmax(&self) -> &[MinMaxLevel] {
        &self.minmax
    }

    /// The diffused gradient field on level 1 (`gx`, `gy`), row 0 = south.
    pub fn gradient_field(&self) -> (&[f32], &[f32]) {
        (&self.grad_x.h, &self.grad_y.h)
    }

    /// The diffused roughness on level 2, row 0 = south, solved now if the sketch changed since it
    /// was last asked for (the heights do not depend on it, so the height solves leave it alone:
    /// at 1024^2 this saves 2-3 ms per solve and per drag update).
    pub fn roughness(&mut self) -> &[f32] {
        crate::cpu::par::on_worker(|| self.solve_roughness());
        &self.rough_state.h
    }

    /// Solves roughness (level 2) if its problem changed: the rows that changed are reassembled,
    /// then FMG + FCG if cold, else FCG from the last solution. Returns work units (level-0 units).
    pub(super) fn solve_roughness(&mut self) -> f64 {
        let rows = std::mem::replace(&mut self.rough_rows, 0..0);
        if rows.is_empty() {
            return 0.0;
        }
        let n = self.grid.n;
        let pr = FieldProblem::diffusion(
            n / 4,
            self.grid.axis_weights(),
            std::mem::take(&mut self.rough_w),
            std::mem::take(&mut self.rough_v),
        );
        let r2 = (rows.start / 4).saturating_sub(1)..(rows.end.div_ceil(4) + 1).min(n / 4);
        self.rough.assemble_rows(&pr, r2);
        (self.rough_w, self.rough_v) = (pr.weight, pr.value);
        // Work vectors of its own (a sixteenth of level 0 each, freed after): the heights' may
        // be in use by a solve in progress.
        let mut fcg = Fcg::default();
        let cold = std::mem::replace(&mut self.rough_cold, false);
        sweep_work_units(ROUGHNESS_LEVEL)
            * solve_field(
                &mut self.rough,
                &mut self.rough_state,
                &self.field_params,
                cold,
                &mut fcg,
                None,
            )
            .0
    }

    /// The level-0 constraint maps, but only the elevation weight and the band weight: the other
    /// arrays are empty (the elevation values are `elevation_values`; the gradient and roughness
    /// maps are kept only downsampled; `ConstraintMaps::rasterize` gives the full maps).
    pub fn constraints(&self) -> &ConstraintMaps {
        &self.maps
    }

    /// The level-0 constrained elevations (metres, meaningful where the elevation weight is > 0).
    pub fn elevation_values(&self) -> &[f32] {
        self.heights.values()
    }

    /// Lowest and highest level-0 height.
    pub fn height_range(&self) -> (f32, f32) {
        self.height_state
            .h
            .par_iter()
            .fold(
                || (f32::INFINITY, f32::NEG_INFINITY),
                |(a, b), h| (a.min(*h), b.max(*h)),
            )
            .reduce(
                || (f32::INFINITY, f32::NEG_INFINITY),
                |x, y| (x.0.min(y.0), x.1.max(y.1)),
            )
    }

    /// Relief of the height constraints (metres, at least 1).
    pub fn relief_m(&self) -> f32 {
        self.heights.relief()
    }

    /// Parameters of the gradient-field and roughness solves (see `default_field_params`).
    pub fn field_params(&self) -> &SolverParams {
        &self.field_params
    }

    /// Replaces the parameters of the gradient-field and roughness solves (takes effect at the next
    /// field solve, i.e. after the next `set_sketch` / `update_sketch`).
    pub fn set_field_params(&mut self, params: SolverParams) {
        self.field_params = params;
    }

    /// The solver parameters.
    pub fn params(&self) -> &SolverParams {
        &self.params
    }

    /// Replaces the parameters (takes effect at the next step).
    pub fn set_params(&mut self, params: SolverParams) {
        self.params = params;
        if self.phase == Phase::Done
            && self.finest_ready == Some(0)
            && self.fcg.residual > params.tolerance
        {
            self.phase = Phase::FcgStart;
        }
    }

    /// Bytes held by the solver's arrays (approximate, for reports).
    pub fn bytes(&self) -> usize {
        let n = self.grid.n;
        let l0 = n * n * 4;
        // maps (2 + 3/4 + 2/16) + heights level 0 (diag, value, f, h) + FCG (4, and the warm
        // field solves' own) + mips.
        l0 * (2 + 4) + l0 * 3 / 4 + l0 / 8 + self.fcg.bytes() + self.field_fcg.bytes() + l0 / 3
    }
}
