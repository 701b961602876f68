//! `lag_m` of the replay log: a side CPU solver converges on each new sketch (warm from the last
//! one), and the lag is the largest difference at the probes between it and what is displayed.
//! Only sessions that ask for it (`"lag": true`) pay for the side solves.

use anyhow::Result;
use terrasketch_multigrid::{CpuSolver, Grid, SolverParams};
use terrasketch_sketch::Sketch;

use super::heightfield::sample_bilinear;
use super::terrain_cpu::{POLISH_TOLERANCE, diff_spans};

/// The side solver and the sketch it has converged on.
pub struct LagProbe {
    solver: CpuSolver,
    side: usize,
    applied: Option<Sketch>,
}

impl LagProbe {
    /// A side solver of the terrain's `grid` (nothing solved yet).
    pub fn new(grid: Grid) -> Result<LagProbe> {
        Ok(LagProbe {
            solver: Self::solver(grid.n, grid.extent_m)?,
            side: grid.n,
            applied: None,
        })
    }

    fn solver(n: usize, extent_m: [f64; 2]) -> Result<CpuSolver> {
        // The editor's end state: its field tolerance, and heights refined as its idle refinement.
        let params = SolverParams {
            tolerance: POLISH_TOLERANCE,
            ..SolverParams::default()
        };
        Ok(CpuSolver::new(Grid::new(n, extent_m)?, params)?)
    }

    /// Converges on `sketch` (warm from the last sketch when the extent is the same).
    fn converge(&mut self, sketch: &Sketch) -> Result<()> {
        if self.applied.as_ref() == Some(sketch) {
            return Ok(());
        }
        match &self.applied {
            Some(a) if a.extent_m == sketch.extent_m && !a.strokes.is_empty() => {
                let spans = diff_spans(&self.solver.grid(), a, sketch);
                self.solver.update_sketch_spans(sketch, &spans);
            }
            _ => {
                if self.solver.grid().extent_m != sketch.extent_m {
                    self.solver = Self::solver(self.side, sketch.extent_m)?;
                }
                self.solver.set_sketch(sketch);
            }
        }
        self.solver.solve();
        self.applied = Some(sketch.clone());
        Ok(())
    }

    /// The largest `|shown - converged|` over the probes that have a displayed height (None if none
    /// has, or the side solver could not be made).
    pub fn lag_m(
        &mut self,
        sketch: &Sketch,
        probes_m: &[[f64; 2]],
        shown_m: &[Option<f32>],
    ) -> Option<f32> {
        self.converge(sketch).ok()?;
        let n = self.solver.grid().n;
        let [ex, ey] = sketch.extent_m;
        probes_m
            .iter()
            .zip(shown_m)
            .filter_map(|(p, h)| {
                let h = (*h)?;
                (p[0].is_finite() && p[1].is_finite()).then(|| {
                    let c = sample_bilinear(
                        self.solver.heights(),
                        n,
                        (p[0] / ex) as f32,
                        (p[1] / ey) as f32,
                    );
                    (h - c).abs()
                })
            })
            .reduce(f32::max)
    }
}
