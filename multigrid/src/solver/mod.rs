//! The CPU solver as the editor and the command line drive it: sketch in, mipmapped heightmap out,
//! incrementally (`step` within a budget) or all at once (`solve`).

use std::ops::Range;
use std::time::{Duration, Instant};

use rayon::prelude::*;
use terrasketch_sketch::Sketch;

use crate::constraints::ConstraintMaps;
use crate::cpu::{FMG_SEED_RESIDUAL, Fcg, FieldState, Hierarchy, Rhs, SWEEPS};
use crate::grid::Grid;
use crate::pyramid::{
    HardSummary, MinMaxLevel, display_downsample_into, display_value, minmax_pyramid,
};
use crate::{SolverError, SolverParams};

mod field;
mod raster;
mod read;
mod warm;

pub use field::{FIELD_TOLERANCE, FIELD_WARM_SEED, default_field_params};
use raster::RASTER_ROWS;
use warm::RowSpans;

/// How much work one `step` may do.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Budget {
    /// Stop once this many work units are spent (at least one unit of work is done).
    WorkUnits(f64),
    /// Stop once this much time has passed (at least one unit of work is done).
    Time(Duration),
    /// Run until converged.
    Unlimited,
}

/// What a `step` achieved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress {
    /// Finest mip level holding a solution (0 = full resolution), or `None` before any.
    pub finest_ready_level: Option<u32>,
    /// Normalised level-0 residual (`max |r| / ((2 ax + 2 ay) relief)`), `f32::INFINITY` before level 0.
    pub residual: f32,
    /// Work units spent by this step on the heights.
    pub work_units: f64,
    /// Work units spent by this step on the gradient field (roughness is solved when asked for:
    /// `CpuSolver::roughness`).
    pub field_work_units: f64,
    /// Level-0 iterations (V-cycles) done by this step.
    pub vcycles: u32,
    /// True once the heights meet the tolerance for the current constraints.
    pub converged: bool,
}

/// Wall time of the solver's phases, milliseconds (CPU solver).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PhaseMs {
    /// Rasterising the constraints (`set_sketch`, `update_sketch*`).
    pub rasterize: f64,
    /// The gradient-field solves, the edge differences and the height problem's assembly (and, when
    /// cold, the FMG lift).
    pub fields: f64,
    /// The height solve: FMG, local relaxation, FCG.
    pub heights: f64,
    /// The mip chain and the min/max pyramid.
    pub publish: f64,
}

/// Totals of a whole solve, for reports and benchmarks.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SolveReport {
    /// Multigrid levels of the height solve (level 0 to the coarsest).
    pub levels: u32,
    /// Level-0 iterations of the height solve.
    pub vcycles: u32,
    /// Work units of the height solve (FMG included).
    pub work_units: f64,
    /// Work units of the gradient-field solves (on level 1, in level-0 units; roughness is solved when
    /// asked for: `CpuSolver::roughness`).
    pub field_work_units: f64,
    /// Normalised residual right after FMG (or of the warm-start guess).
    pub residual_initial: f32,
    /// Normalised residual at the end.
    pub residual_final: f32,
    /// Wall time of the whole solve, rasterisation included.
    pub ms_total: f64,
    /// Lowest height, metres.
    pub height_min_m: f32,
    /// Highest height, metres.
    pub height_max_m: f32,
    /// True if the tolerance was met.
    pub converged: bool,
    /// Wall time per phase (CPU solver; the rasterisation of the `set_sketch` / `update_sketch*`
    /// before the solve).
    pub phase_ms: PhaseMs,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Phase {
    /// The gradient field must be (re)solved, then heights.
    Fields,
    /// Cold start: FMG on coarse level `k` is next.
    Fmg(usize),
    /// FMG done or warm start: FCG must be (re)started.
    FcgStart,
    /// FCG iterating.
    Fcg,
    /// Converged.
    Done,
}

/// The CPU solver: owns the constraint maps, three hierarchies and their states, and the mip chain.
pub struct CpuSolver {
    grid: Grid,
    params: SolverParams,
    /// Tolerance of the gradient-field and roughness solves.
    field_params: SolverParams,
    /// Level-0 elevation weights and band weights. The elevation values are kept only as the height
    /// hierarchy's level-0 values (`Hierarchy::values_mut`, written by `rasterize`); the gradient
    /// and roughness maps only in their downsampled forms below. The other arrays are empty.
    maps: ConstraintMaps,
    /// The gradient-field problem's level-1 weights (`fields::gradient_problem`; its values are
    /// kept only as right-hand sides: `gx` in `grad`, `gy` in `grad_rhs_y`).
    grad_w: Vec<f32>,
    /// The roughness problem's level-2 weights and values (`fields::roughness_problem`).
    rough_w: Vec<f32>,
    rough_v: Vec<f32>,
    base_elevation_m: f32,
    empty: bool,
    grad: Hierarchy,
    /// The `gy` problem's right-hand side (the hierarchy holds `gx`'s; `Hierarchy::swap_rhs`).
    grad_rhs_y: Rhs,
    grad_x: FieldState,
    grad_y: FieldState,
    rough: Hierarchy,
    rough_state: FieldState,
    /// Level-0 rows whose roughness problem changed since roughness was last solved (empty: up to
    /// date). Roughness does not enter the heights: it is solved when asked for (`roughness`).
    rough_rows: Range<usize>,
    /// The next roughness solve starts cold (FMG).
    rough_cold: bool,
    heights: Hierarchy,
    height_state: FieldState,
    fcg: Fcg,
    /// Work vectors of the warm gradient-field solves (cold ones borrow `fcg`'s), so that the
    /// heights' residual in `fcg` survives an edit: a warm start recomputes it only where the
    /// problem or the heights changed (`stale`). Only `r` (level 1) unless a field solve
    /// iterates.
    field_fcg: Fcg,
    /// Level-0 cells whose elevation constraint changed since the last solve (for local relaxation).
    changed: Vec<u32>,
    /// Per group of `RASTER_ROWS` rows, the column window re-rasterised since the last field solve
    /// (empty: `(n, 0)`): with the field relaxation windows, where the height problem can change.
    raster_windows: Vec<(usize, usize)>,
    phase: Phase,
    cold: bool,
    dirty_rows: Range<usize>,
    summary: HardSummary,
    /// `mips[k - 1]` = mip level k (level 0 is the height state itself).
    mips: Vec<Vec<f32>>,
    finest_ready: Option<u32>,
    minmax: Vec<MinMaxLevel>,
    report: SolveReport,
    /// Phase times since the last `take_phase_ms` (or `solve`).
    phase_ms: PhaseMs,
    /// Where the residual in the FCG vectors may be stale (`Some(spans)`: `f - A h` everywhere
    /// else; `None`: anywhere): the cells the local relaxation changed after FMG left a fresh
    /// residual, or, after a warm start's solve, the regions the edits since reassembled and the
    /// cells their relaxations changed (accumulated over edits until FCG starts). FCG's start
    /// recomputes the residual only there (`Fcg::start_if_needed_after`).
    stale: Option<RowSpans>,
    /// The running `step` may return before level 0 is ready, so FMG publishes each coarse level
    /// as it is done (a `Budget::Unlimited` step runs to the end: only level 0 is published).
    show_coarse: bool,
    /// The next FCG start runs at least one iteration even if the tolerance already holds
    /// (`require_iteration`).
    force_iteration: bool,
    /// Height assemblies restricted to a region (tests).
    #[cfg(test)]
    windowed_assemblies: usize,
}

impl CpuSolver {
    /// Allocates a solver for `grid`. Refuses grids the machine cannot hold before allocating.
    pub fn new(grid: Grid, params: SolverParams) -> Result<CpuSolver, SolverError> {
        let n = grid.n;
        let [ax, ay] = grid.axis_weights();
        let mut grad = Hierarchy::new(n / 2, ax, ay);
        // A drag's warm gradient solves usually run no cycle: their coarse levels are rebuilt
        // only when one does (ALGORITHM.md, "Warm updates").
        grad.set_defer_coarse(true);
        let rough = Hierarchy::new(n / 4, ax, ay);
        let heights = Hierarchy::new(n, ax, ay);
        let mips = (1..grid.mip_levels())
            .map(|k| vec![0.0; grid.side(k) * grid.side(k)])
            .collect();
        let field_params = default_field_params(&params);
        Ok(CpuSolver {
            grid,
            params,
            field_params,
            maps: ConstraintMaps {
                n,
                elev_weight: vec![0.0; n * n],
                elev_value: Vec::new(),
                band_weight: vec![0.0; n * n],
                grad_x: Vec::new(),
                grad_y: Vec::new(),
                rough_weight: Vec::new(),
                rough_value: Vec::new(),
            },
            grad_w: vec![0.0; n * n / 4],
            rough_w: vec![0.0; n * n / 16],
            rough_v: vec![0.0; n * n / 16],
            base_elevation_m: 0.0,
            empty: true,
            grad_rhs_y: Rhs::new(n / 2),
            grad_x: grad.new_state(),
            grad_y: grad.new_state(),
            grad,
            rough_state: rough.new_state(),
            rough,
            rough_rows: 0..0,
            rough_cold: true,
            height_state: heights.new_state(),
            heights,
            fcg: Fcg::default(),
            field_fcg: Fcg::default(),
            changed: Vec::new(),
            raster_windows: vec![(n, 0); n / RASTER_ROWS],
            phase: Phase::Done,
            cold: true,
            dirty_rows: 0..0,
            summary: HardSummary::default(),
            mips,
            finest_ready: None,
            minmax: Vec::new(),
            report: SolveReport::default(),
            phase_ms: PhaseMs::default(),
            stale: None,
            show_coarse: true,
            force_iteration: false,
            #[cfg(test)]
            windowed_assemblies: 0,
        })
    }

    /// The grid.
    pub fn grid(&self) -> Grid {
        self.grid
    }

    /// Replaces the whole sketch: rasterises everything and restarts from scratch (FMG).
    pub fn set_sketch(&mut self, sketch: &Sketch) {
        self.rasterize(sketch, 0..self.grid.n, false);
        self.base_elevation_m = sketch.base_elevation_m as f32;
        self.cold = true;
        self.finest_ready = None;
        self.mark_dirty(0..self.grid.n);
    }

    /// Updates the sketch after an edit that touched level-0 rows `rows` (see
    /// `ConstraintMaps::stroke_rows`: pass the union of the edited strokes' old and new rows).
    /// Re-rasterises only those rows and warm-starts from the current solution.
    pub fn update_sketch(&mut self, sketch: &Sketch, rows: Range<usize>) {
        let n = self.grid.n;
        let rows = rows.start.min(n)..rows.end.min(n);
        let spans: Vec<(usize, Range<usize>)> = rows.map(|j| (j, 0..n)).collect();
        self.update_sketch_spans(sketch, &spans);
    }

    /// Updates the sketch after an edit that touched the level-0 texels `spans` (row, columns),
    /// in any order and possibly overlapping (see `ConstraintMaps::stroke_spans`: pass the edited
    /// strokes' old and new spans). Re-rasterises only those texels (widened to whole level-2
    /// cells and, per group of 4 rows, to one column window) and warm-starts from the current
    /// solution.
    pub fn update_sketch_spans(&mut self, sketch: &Sketch, spans: &[(usize, Range<usize>)]) {
        let n = self.grid.n;
        let mut lo = n;
        let mut hi = 0;
        for (j, c) in spans {
            if *j < n && c.start < c.end.min(n) {
                lo = lo.min(*j);
                hi = hi.max(*j + 1);
            }
        }
        if lo >= hi {
            return;
        }
        self.rasterize_spans(sketch, spans, true);
        self.base_elevation_m = sketch.base_elevation_m as f32;
        self.mark_dirty(lo..hi);
    }

    fn mark_dirty(&mut self, rows: Range<usize>) {
        let n = self.grid.n;
        let rows = rows.start.min(n)..rows.end.min(n);
        self.dirty_rows = if self.dirty_rows.is_empty() {
            rows
        } else {
            self.dirty_rows.start.min(rows.start)..self.dirty_rows.end.max(rows.end)
        };
        self.empty = self.maps.elev_weight.iter().all(|w| *w <= 0.0);
        if self.cold {
            // Nothing valid to show until the restart has produced its first level.
            self.finest_ready = None;
        }
        self.phase = Phase::Fields;
    }

    /// Runs solver work within `budget`, publishes the mips and bounds, and reports progress.
    pub fn step(&mut self, budget: Budget) -> Progress {
        if self.phase == Phase::Done {
            // Nothing to do, nothing new to publish.
            return self.advance(budget);
        }
        let mut p = self.advance(budget);
        self.publish();
        p.finest_ready_level = self.finest_ready;
        p
    }

    /// Runs solver work within `budget` without publishing the mips and bounds (coarse FMG levels
    /// excepted): a caller that runs several small steps in a frame publishes once, with
    /// [`Self::publish`], before it reads the mips.
    pub fn advance(&mut self, budget: Budget) -> Progress {
        crate::cpu::par::on_worker(|| self.advance_on_worker(budget))
    }

    /// Rebuilds the mip chain above level 0 and the min/max pyramid from the current heights.
    pub fn publish(&mut self) {
        let t = Instant::now();
        crate::cpu::par::on_worker(|| self.publish_mips_and_bounds());
        self.phase_ms.publish += t.elapsed().as_secs_f64() * 1e3;
    }

    fn advance_on_worker(&mut self, budget: Budget) -> Progress {
        let start = Instant::now();
        let mut progress = Progress {
            finest_ready_level: self.finest_ready,
            residual: self.fcg.residual,
            work_units: 0.0,
            field_work_units: 0.0,
            vcycles: 0,
            converged: self.phase == Phase::Done,
        };
        if self.phase == Phase::Done {
            return progress;
        }
        self.show_coarse = !matches!(budget, Budget::Unlimited);
        loop {
            self.unit(&mut progress);
            let spent = match budget {
                Budget::WorkUnits(w) => progress.work_units + progress.field_work_units >= w,
                Budget::Time(t) => start.elapsed() >= t,
                Budget::Unlimited => false,
            };
            if self.phase == Phase::Done || spent {
                break;
            }
        }
        progress.finest_ready_level = self.finest_ready;
        progress.residual = if self.finest_ready == Some(0) {
            self.fcg.residual
        } else {
            f32::INFINITY
        };
        progress.converged = self.phase == Phase::Done;
        progress
    }

    /// Solves to the tolerance from the current state; returns the totals of this solve.
    pub fn solve(&mut self) -> SolveReport {
        let t = Instant::now();
        self.report = SolveReport {
            levels: self.heights.levels() as u32,
            ..SolveReport::default()
        };
        let p = self.step(Budget::Unlimited);
        self.report.ms_total = t.elapsed().as_secs_f64() * 1e3;
        self.report.phase_ms = self.take_phase_ms();
        self.report.residual_final = p.residual;
        self.report.converged = p.converged;
        let (lo, hi) = self.height_range();
        self.report.height_min_m = lo;
        self.report.height_max_m = hi;
        self.report
    }

    /// One unit of work: a field solve, one FMG level, or one level-0 iteration.
    fn unit(&mut self, progress: &mut Progress) {
        let t = Instant::now();
        let fields = self.phase == Phase::Fields;
        self.unit_work(progress);
        let ms = t.elapsed().as_secs_f64() * 1e3;
        if fields {
            self.phase_ms.fields += ms;
        } else {
            self.phase_ms.heights += ms;
        }
    }

    fn unit_work(&mut self, progress: &mut Progress) {
        match self.phase {
            Phase::Fields => self.fields_phase(progress),
            Phase::Fmg(k) => self.fmg_phase(k, progress),
            Phase::FcgStart => self.fcg_start_phase(progress),
            Phase::Fcg => {
                match self
                    .fcg
                    .iterate(&self.heights, &mut self.height_state, &self.params)
                {
                    Some(s) => self.add_wu(progress, s.work_units),
                    None => self.phase = Phase::Done,
                }
                progress.vcycles += 1;
                self.report.vcycles += 1;
                if self.fcg.residual <= self.params.tolerance
                    || self.fcg.iterations >= self.params.max_vcycles
                {
                    self.phase = Phase::Done;
                }
            }
            Phase::Done => {}
        }
    }

    /// The field solves and the height problem's assembly; then the heights' start: cold FMG, or
    /// a warm local relaxation around the changed constraints.
    fn fields_phase(&mut self, progress: &mut Progress) {
        let (wu, height_region) = self.solve_fields();
        progress.field_work_units += wu;
        self.report.field_work_units += wu;
        if self.empty {
            let base = self.base_elevation_m;
            self.height_state.h.iter_mut().for_each(|h| *h = base);
            self.stale = None;
            self.finest_ready = Some(0);
            self.fcg.residual = 0.0;
            self.phase = Phase::Done;
            self.cold = true;
        } else if self.cold {
            self.stale = None;
            // The lift lives in the FCG vectors until FMG is done (FCG restarts after it).
            let (lift, mut scratch) = self.fcg.lend_pair();
            let k = self
                .heights
                .fmg_start(&mut self.height_state, lift, &mut scratch);
            self.fcg.return_pair(Vec::new(), scratch);
            self.phase = Phase::Fmg(k);
        } else {
            // Only cells whose constraint changed can hold a stale hard value.
            self.heights
                .reset_hard_cells(&mut self.height_state, &self.changed);
            let (wu, relaxed) =
                self.heights
                    .relax_around_spans(&mut self.height_state.h, &self.changed, SWEEPS);
            self.add_wu(progress, wu);
            // FCG's start recomputes the residual only where it can have changed: the
            // (windowed) assembly's region and the relaxed cells, added to those of the
            // edits since the last start.
            self.stale = match (self.stale.take(), height_region) {
                (Some(mut spans), Some((rows, cols))) => {
                    spans.extend(relaxed);
                    spans.extend(
                        rows.zip(cols)
                            .filter(|(_, c)| c.0 < c.1)
                            .map(|(j, (a, b))| (j as u32, a as u32, b as u32)),
                    );
                    Some(spans)
                }
                _ => None,
            };
            self.phase = Phase::FcgStart;
        }
        self.changed.clear();
        self.dirty_rows = 0..0;
    }

    /// FMG level `k`; after the finest, the local relaxation at the largest residuals left.
    fn fmg_phase(&mut self, k: usize, progress: &mut Progress) {
        let wu = self
            .heights
            .fmg_level(k, &mut self.height_state, &self.params);
        self.add_wu(progress, wu);
        if self.show_coarse {
            self.publish_coarse(k);
        }
        self.phase = if k > 1 {
            Phase::Fmg(k - 1)
        } else {
            Phase::FcgStart
        };
        if k == 1 {
            let lift = self.heights.fmg_finish(&mut self.height_state);
            let (_, q) = self.fcg.lend_pair();
            self.fcg.return_pair(lift, q);
            // Local relaxation at the largest residuals FMG leaves (ALGORITHM.md); FCG's
            // start reuses the residual computed to find them.
            let (wu, relaxed) = self.fcg.relax_at_residuals(
                &self.heights,
                &mut self.height_state,
                FMG_SEED_RESIDUAL,
                SWEEPS,
            );
            self.stale = Some(relaxed);
            self.add_wu(progress, wu);
        }
    }

    /// FCG's start (the residual where it can have changed, one preconditioning if needed).
    fn fcg_start_phase(&mut self, progress: &mut Progress) {
        let stale = self.stale.take();
        let force = std::mem::take(&mut self.force_iteration);
        // A forced start preconditions whatever the residual (tolerance 0 for the check).
        let start_params = SolverParams {
            tolerance: if force { 0.0 } else { self.params.tolerance },
            ..self.params
        };
        let wu = self.fcg.start_if_needed_after(
            &self.heights,
            &mut self.height_state,
            &start_params,
            stale.as_deref(),
        );
        // FCG keeps its residual up to date from here on.
        self.stale = Some(Vec::new());
        self.add_wu(progress, wu);
        self.report.residual_initial = self.fcg.residual;
        self.finest_ready = Some(0);
        self.cold = false;
        // As the start's check: preconditioned (so FCG may iterate) iff above it.
        let met = self.fcg.residual <= start_params.tolerance;
        self.phase = if met || self.params.max_vcycles == 0 {
            Phase::Done
        } else {
            Phase::Fcg
        };
    }

    fn add_wu(&mut self, progress: &mut Progress, wu: f64) {
        progress.work_units += wu;
        self.report.work_units += wu;
    }

    /// During FMG: mip `k` from the level-k unknowns, coarser mips by display downsampling.
    fn publish_coarse(&mut self, k: usize) {
        // FMG's level-k unknowns approximate h - g (the lift).
        let u = self.heights.level_unknowns(&self.height_state, k);
        let g = self.heights.level_lift(&self.height_state, k);
        let summary = &self.summary.levels[k - 1];
        self.mips[k - 1]
            .par_iter_mut()
            .zip(u)
            .zip(g)
            .zip(summary)
            .for_each(|(((m, u), g), s)| *m = display_value(*s, *u + *g));
        for l in k + 1..self.grid.mip_levels() {
            let (fine, coarse) = self.mips.split_at_mut(l - 1);
            display_downsample_into(&fine[l - 2], &self.summary.levels[l - 1], &mut coarse[0]);
        }
        self.finest_ready = Some(k as u32);
    }

    fn publish_mips_and_bounds(&mut self) {
        if self.finest_ready == Some(0) {
            for l in 1..self.grid.mip_levels() {
                if l == 1 {
                    display_downsample_into(
                        &self.height_state.h,
                        &self.summary.levels[0],
                        &mut self.mips[0],
                    );
                } else {
                    let (fine, coarse) = self.mips.split_at_mut(l - 1);
                    display_downsample_into(
                        &fine[l - 2],
                        &self.summary.levels[l - 1],
                        &mut coarse[0],
                    );
                }
            }
            self.minmax = minmax_pyramid(self.grid.n, &self.height_state.h);
        } else if let Some(k) = self.finest_ready {
            // Bounds from the finest ready mip, expanded to at most 64x64 cells.
            let k = k as usize;
            let side = self.grid.side(k);
            self.minmax = minmax_pyramid(side, &self.mips[k - 1]);
        }
    }
}

#[cfg(test)]
mod tests;
