//! One interface over both solver backends: [`Solver`] is what the command line and the editor ask
//! of a solver (take a sketch, step within a budget or solve to the tolerance, read heights, mips
//! and the min/max pyramid), implemented by [`CpuSolver`] and [`GpuSolver`] on their public
//! methods. Backend-specific work (the CPU's field parameters and phase times, the GPU's queued
//! takes and textures) stays on the solvers themselves.

use std::borrow::Cow;
use std::ops::Range;
use std::time::Instant;

use terrasketch_sketch::Sketch;

use crate::constraints::ConstraintMaps;
use crate::gpu::{GpuCounters, GpuError};
use crate::gpu_solver::GpuSolver;
use crate::grid::Grid;
use crate::pyramid::MinMaxLevel;
use crate::{Budget, CpuSolver, PhaseMs, Progress, SolveReport, SolverParams};

/// How [`Solver::edit_sketch`] took a sketch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Taken {
    /// Nothing the solver sees differs: no work is pending for it.
    Unchanged,
    /// From scratch (FMG).
    Cold,
    /// Warm from the current heights.
    Warm,
}

/// A solver backend. Errors are the device's (the CPU fails only on a mip level it does not
/// have, with the same error as the GPU).
pub trait Solver {
    /// "cpu" or "gpu".
    fn name(&self) -> &'static str;
    /// The device that runs the solve, for reports.
    fn adapter(&self) -> String;
    /// The grid.
    fn grid(&self) -> Grid;
    /// The height-solve parameters.
    fn params(&self) -> SolverParams;
    /// Replaces the whole sketch: the following steps solve it from scratch.
    fn set_sketch(&mut self, sketch: &Sketch) -> Result<(), GpuError>;
    /// Takes `sketch` after `from`, the sketch the solver has (none: taken cold): warm from the
    /// current heights where the backend can follow the difference, else cold.
    fn edit_sketch(&mut self, sketch: &Sketch, from: Option<&Sketch>) -> Result<Taken, GpuError>;
    /// Solver work within `budget` on the sketch taken last, then the mips and bounds published.
    fn step(&mut self, budget: Budget) -> Result<Progress, GpuError>;
    /// Replaces the sketch and solves it to the tolerance; `ms_total` covers rasterisation to the
    /// last level.
    fn solve_sketch(&mut self, sketch: &Sketch) -> Result<SolveReport, GpuError>;
    /// Takes `sketch`, an edit of `from` (the sketch the solver has), warm and solves it to the
    /// tolerance the fastest way the backend has: a drag frame with no budget. The report's work
    /// units and V-cycles are the update's; `ms_total` covers the whole update.
    fn update_warm(&mut self, sketch: &Sketch, from: &Sketch) -> Result<SolveReport, GpuError>;
    /// Continues the height solve of `sketch` (the one taken last) to `tolerance`, at most
    /// `max_iterations` level-0 iterations (a "converged" reference for measuring errors).
    fn refine_to(
        &mut self,
        sketch: &Sketch,
        tolerance: f32,
        max_iterations: u32,
    ) -> Result<(), GpuError>;
    /// Normalised level-0 residual of the heights (infinite before level 0 is ready).
    fn residual(&self) -> f32;
    /// Relief of the height constraints, metres.
    fn relief_m(&self) -> f32;
    /// Level-0 heights, metres, row 0 = south (read back from a device).
    fn heights(&self) -> Result<Cow<'_, [f32]>, GpuError>;
    /// Mip level `k` of the heights as last published (0 = full resolution).
    fn mip(&self, k: usize) -> Result<Cow<'_, [f32]>, GpuError>;
    /// The min/max pyramid as last published, finest first.
    fn min_max(&self) -> Result<Vec<MinMaxLevel>, GpuError>;
    /// Phase times since the last call (`None` where the phases run in one device submission).
    fn take_phase_ms(&mut self) -> Option<PhaseMs> {
        None
    }
    /// Bytes the solver allocated on a device (0 on the CPU).
    fn gpu_bytes(&self) -> u64 {
        0
    }
    /// The device's counters so far (none on the CPU).
    fn counters(&self) -> Option<GpuCounters> {
        None
    }
}

/// The level-0 texels whose constraints can differ between sketches `a` and `b`: the spans of every
/// stroke that differs, in both sketches (every texel if the extent or base elevation differ).
pub fn diff_spans(grid: &Grid, a: &Sketch, b: &Sketch) -> Vec<(usize, Range<usize>)> {
    let n = grid.n;
    if a.extent_m != b.extent_m || a.base_elevation_m != b.base_elevation_m {
        return (0..n).map(|j| (j, 0..n)).collect();
    }
    let mut spans = Vec::new();
    for i in 0..a.strokes.len().max(b.strokes.len()) {
        if a.strokes.get(i) != b.strokes.get(i) {
            spans.extend(ConstraintMaps::stroke_spans(a, i, grid));
            spans.extend(ConstraintMaps::stroke_spans(b, i, grid));
        }
    }
    spans
}

impl Solver for CpuSolver {
    fn name(&self) -> &'static str {
        "cpu"
    }

    fn adapter(&self) -> String {
        format!("cpu ({} threads)", rayon::current_num_threads())
    }

    fn grid(&self) -> Grid {
        CpuSolver::grid(self)
    }

    fn params(&self) -> SolverParams {
        *CpuSolver::params(self)
    }

    fn set_sketch(&mut self, sketch: &Sketch) -> Result<(), GpuError> {
        CpuSolver::set_sketch(self, sketch);
        Ok(())
    }

    /// Warm: only the texels of the strokes that differ are re-rasterised; cold from nothing or to
    /// or from an empty sketch.
    fn edit_sketch(&mut self, sketch: &Sketch, from: Option<&Sketch>) -> Result<Taken, GpuError> {
        match from {
            Some(a) if !a.strokes.is_empty() && !sketch.strokes.is_empty() => {
                let spans = diff_spans(&CpuSolver::grid(self), a, sketch);
                if spans.is_empty() {
                    return Ok(Taken::Unchanged);
                }
                self.update_sketch_spans(sketch, &spans);
                Ok(Taken::Warm)
            }
            _ => {
                CpuSolver::set_sketch(self, sketch);
                Ok(Taken::Cold)
            }
        }
    }

    fn step(&mut self, budget: Budget) -> Result<Progress, GpuError> {
        Ok(CpuSolver::step(self, budget))
    }

    fn solve_sketch(&mut self, sketch: &Sketch) -> Result<SolveReport, GpuError> {
        let t = Instant::now();
        CpuSolver::set_sketch(self, sketch);
        let mut r = self.solve();
        r.ms_total = t.elapsed().as_secs_f64() * 1e3;
        Ok(r)
    }

    /// Re-rasterises the texels of the strokes that differ and steps to the tolerance. The phase
    /// times stay with the solver (for [`Solver::take_phase_ms`]).
    fn update_warm(&mut self, sketch: &Sketch, from: &Sketch) -> Result<SolveReport, GpuError> {
        let t = Instant::now();
        let spans = diff_spans(&CpuSolver::grid(self), from, sketch);
        self.update_sketch_spans(sketch, &spans);
        // An unlimited step runs to the tolerance or the V-cycle cap.
        let p = CpuSolver::step(self, Budget::Unlimited);
        Ok(SolveReport {
            work_units: p.work_units,
            field_work_units: p.field_work_units,
            vcycles: p.vcycles,
            residual_final: p.residual,
            converged: p.converged,
            ms_total: t.elapsed().as_secs_f64() * 1e3,
            ..SolveReport::default()
        })
    }

    /// The sketch is the one taken already: the height solve continues under the tighter
    /// parameters, which are then restored.
    fn refine_to(
        &mut self,
        _sketch: &Sketch,
        tolerance: f32,
        max_iterations: u32,
    ) -> Result<(), GpuError> {
        let keep = *CpuSolver::params(self);
        self.set_params(SolverParams {
            tolerance,
            max_vcycles: max_iterations,
            ..keep
        });
        CpuSolver::step(self, Budget::Unlimited);
        self.set_params(keep);
        Ok(())
    }

    fn residual(&self) -> f32 {
        CpuSolver::residual(self)
    }

    fn relief_m(&self) -> f32 {
        CpuSolver::relief_m(self)
    }

    fn heights(&self) -> Result<Cow<'_, [f32]>, GpuError> {
        Ok(Cow::Borrowed(CpuSolver::heights(self)))
    }

    fn mip(&self, k: usize) -> Result<Cow<'_, [f32]>, GpuError> {
        let levels = CpuSolver::grid(self).mip_levels();
        if k >= levels {
            return Err(GpuError::BadLevel { level: k, levels });
        }
        Ok(Cow::Borrowed(CpuSolver::mip(self, k)))
    }

    fn min_max(&self) -> Result<Vec<MinMaxLevel>, GpuError> {
        Ok(self.minmax().to_vec())
    }

    fn take_phase_ms(&mut self) -> Option<PhaseMs> {
        Some(CpuSolver::take_phase_ms(self))
    }
}

impl Solver for GpuSolver {
    fn name(&self) -> &'static str {
        "gpu"
    }

    fn adapter(&self) -> String {
        GpuSolver::adapter(self).to_string()
    }

    fn grid(&self) -> Grid {
        *GpuSolver::grid(self)
    }

    fn params(&self) -> SolverParams {
        *GpuSolver::params(self)
    }

    /// Rasterises, solves the fields, runs FMG and starts FCG on the device (one blocking take),
    /// then publishes what it holds.
    fn set_sketch(&mut self, sketch: &Sketch) -> Result<(), GpuError> {
        self.begin(sketch, true)?;
        self.publish()
    }

    /// Cold from nothing or to an empty sketch, else warm (the fields and heights from their last
    /// solutions); the device re-rasterises the whole sketch either way.
    fn edit_sketch(&mut self, sketch: &Sketch, from: Option<&Sketch>) -> Result<Taken, GpuError> {
        if from == Some(sketch) {
            return Ok(Taken::Unchanged);
        }
        let cold = from.is_none() || sketch.strokes.is_empty();
        self.begin(sketch, cold)?;
        self.publish()?;
        Ok(if cold { Taken::Cold } else { Taken::Warm })
    }

    /// FCG iterations (each reads its residual back) until the tolerance holds, the device's
    /// iteration cap closes the gate or `budget` is spent.
    fn step(&mut self, budget: Budget) -> Result<Progress, GpuError> {
        let start = Instant::now();
        let tolerance = GpuSolver::params(self).tolerance;
        let residual = GpuSolver::residual(self);
        let mut p = Progress {
            finest_ready_level: residual.is_finite().then_some(0),
            residual,
            work_units: 0.0,
            field_work_units: 0.0,
            vcycles: 0,
            converged: residual <= tolerance,
        };
        while !p.converged {
            let Some(wu) = self.iterate()? else {
                break;
            };
            p.work_units += wu;
            p.vcycles += 1;
            p.residual = GpuSolver::residual(self);
            p.converged = p.residual <= tolerance;
            let spent = match budget {
                Budget::WorkUnits(w) => p.work_units >= w,
                Budget::Time(t) => start.elapsed() >= t,
                Budget::Unlimited => false,
            };
            if spent {
                break;
            }
        }
        if p.vcycles > 0 {
            self.publish()?;
        }
        Ok(p)
    }

    fn solve_sketch(&mut self, sketch: &Sketch) -> Result<SolveReport, GpuError> {
        GpuSolver::solve_sketch(self, sketch)
    }

    /// The device's own warm path: one read-back for the rasterisation's ranges, one for the
    /// queued solves (`from` is the sketch on the device already).
    fn update_warm(&mut self, sketch: &Sketch, _from: &Sketch) -> Result<SolveReport, GpuError> {
        self.update_sketch_warm(sketch)
    }

    fn refine_to(
        &mut self,
        sketch: &Sketch,
        tolerance: f32,
        max_iterations: u32,
    ) -> Result<(), GpuError> {
        GpuSolver::refine_to(self, sketch, tolerance, max_iterations)
    }

    fn residual(&self) -> f32 {
        GpuSolver::residual(self)
    }

    fn relief_m(&self) -> f32 {
        GpuSolver::relief_m(self)
    }

    fn heights(&self) -> Result<Cow<'_, [f32]>, GpuError> {
        Ok(Cow::Owned(self.read_heights()?))
    }

    fn mip(&self, k: usize) -> Result<Cow<'_, [f32]>, GpuError> {
        Ok(Cow::Owned(self.read_mip(k)?))
    }

    fn min_max(&self) -> Result<Vec<MinMaxLevel>, GpuError> {
        GpuSolver::min_max(self)
    }

    fn gpu_bytes(&self) -> u64 {
        GpuSolver::gpu_bytes(self)
    }

    fn counters(&self) -> Option<GpuCounters> {
        Some(self.context().counters())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::GpuContext;
    use terrasketch_sketch::benchmark_sketch;

    /// Largest difference of `a` and `b` relative to `relief`.
    fn max_rel(a: &[f32], b: &[f32], relief: f32) -> f32 {
        assert_eq!(a.len(), b.len());
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f32::max)
            / relief
    }

    /// What a backend gives through the trait for `a` solved cold, `b` taken after it and stepped
    /// to the tolerance, then `a` again by the warm update: heights, mip 1 and the pyramid's top.
    #[allow(clippy::type_complexity)]
    fn through_trait(
        s: &mut dyn Solver,
        a: &Sketch,
        b: &Sketch,
    ) -> Vec<(Vec<f32>, Vec<f32>, [f32; 2])> {
        let mut out = Vec::new();
        assert_eq!(s.edit_sketch(a, None).unwrap(), Taken::Cold);
        out.push(solved(s));
        assert_eq!(s.edit_sketch(b, Some(a)).unwrap(), Taken::Warm);
        out.push(solved(s));
        assert_eq!(s.edit_sketch(b, Some(b)).unwrap(), Taken::Unchanged);
        assert!(s.mip(s.grid().mip_levels()).is_err());
        let r = s.update_warm(a, b).unwrap();
        assert!(r.converged && r.vcycles >= 1, "{}: {r:?}", s.name());
        out.push(published(s));
        out
    }

    /// Heights, mip 1 and the pyramid's top as published now.
    fn published(s: &dyn Solver) -> (Vec<f32>, Vec<f32>, [f32; 2]) {
        let top = s.min_max().unwrap().last().map(|l| l.cells[0]).unwrap();
        let h = s.heights().unwrap().into_owned();
        (h, s.mip(1).unwrap().into_owned(), top)
    }

    /// Steps `s` to the tolerance; its heights, mip 1 and the pyramid's top.
    fn solved(s: &mut dyn Solver) -> (Vec<f32>, Vec<f32>, [f32; 2]) {
        let p = s.step(Budget::Unlimited).unwrap();
        assert!(p.converged, "{}: {p:?}", s.name());
        assert_eq!(p.finest_ready_level, Some(0));
        assert!(s.residual() <= s.params().tolerance);
        published(s)
    }

    /// The same sketch and edit through the trait on the CPU and the GPU agree within 1e-3 of the
    /// relief (ALGORITHM.md's agreement), at every published level.
    #[test]
    fn both_backends_agree_through_the_trait() {
        let a = benchmark_sketch();
        let mut b = a.clone();
        for p in &mut b.strokes[0].points {
            p[0] += 400.0;
            p[1] -= 250.0;
        }
        let grid = Grid::new(128, a.extent_m).unwrap();
        let params = SolverParams::default();
        let mut cpu = CpuSolver::new(grid, params).unwrap();
        let ctx = GpuContext::new().expect("the GPU test needs an adapter (WGPU_BACKEND=vulkan)");
        let mut gpu = GpuSolver::new(&ctx, grid, params).unwrap();
        let c = through_trait(&mut cpu, &a, &b);
        let g = through_trait(&mut gpu, &a, &b);
        let relief = Solver::relief_m(&cpu);
        assert!((relief - Solver::relief_m(&gpu)).abs() <= 1e-3 * relief);
        for (i, (c, g)) in c.iter().zip(&g).enumerate() {
            let d0 = max_rel(&c.0, &g.0, relief);
            let d1 = max_rel(&c.1, &g.1, relief);
            let dt = max_rel(&c.2, &g.2, relief);
            eprintln!("take {i}: heights {d0:.2e}, mip 1 {d1:.2e}, pyramid top {dt:.2e}");
            assert!(
                d0 <= 1e-3,
                "take {i}: heights differ by {d0:.2e} of the relief"
            );
            assert!(
                d1 <= 1e-3,
                "take {i}: mip 1 differs by {d1:.2e} of the relief"
            );
            assert!(
                dt <= 1e-3,
                "take {i}: pyramid top differs by {dt:.2e} of the relief"
            );
        }
        // The edit moved the land, and the warm update back to the first sketch restored it.
        assert_eq!((c.len(), g.len()), (3, 3));
        assert!(max_rel(&c[0].0, &c[1].0, relief) > 1e-2);
        assert!(max_rel(&c[0].0, &c[2].0, relief) <= 1e-2);
        assert_eq!(Solver::name(&gpu), "gpu");
        assert!(Solver::counters(&gpu).is_some() && Solver::counters(&cpu).is_none());
    }

    #[test]
    fn diff_spans_hold_the_changed_strokes_only() {
        let a = benchmark_sketch();
        let grid = Grid::new(128, a.extent_m).unwrap();
        assert!(diff_spans(&grid, &a, &a).is_empty());
        let mut b = a.clone();
        for p in &mut b.strokes[2].points {
            p[0] += 300.0;
        }
        let mut want = ConstraintMaps::stroke_spans(&a, 2, &grid);
        want.extend(ConstraintMaps::stroke_spans(&b, 2, &grid));
        assert_eq!(diff_spans(&grid, &a, &b), want);
        b.base_elevation_m += 1.0;
        let all = diff_spans(&grid, &a, &b);
        assert_eq!(all.len(), 128);
        assert!(all.iter().all(|(_, c)| *c == (0..128)));
    }
}
