//! `lag_m` of the replay log: a side CPU solver converges on each new sketch (warm from the last
//! one), and the lag is the largest difference at the probes between it and what is displayed.
//! Only sessions that ask for it (`"lag": true`) pay for the side solves.

use anyhow::Result;
use terrasketch_multigrid::{Grid, SolverParams};
use terrasketch_sketch::Sketch;

use super::follow::LiveSolver;
use super::heightfield::sample_bilinear;
use super::terrain_cpu::{CpuLive, POLISH_TOLERANCE};

/// The side solver and the sketch it has converged on.
pub struct LagProbe {
    live: CpuLive,
    applied: Option<Sketch>,
}

impl LagProbe {
    /// A side solver of the terrain's `grid` (nothing solved yet).
    pub fn new(grid: Grid) -> Result<LagProbe> {
        Ok(LagProbe {
            live: Self::live(grid)?,
            applied: None,
        })
    }

    fn live(grid: Grid) -> Result<CpuLive> {
        let mut live = CpuLive::new(grid)?;
        // The editor's end state: its field tolerance, and heights refined as its idle refinement.
        live.solver.set_params(SolverParams {
            tolerance: POLISH_TOLERANCE,
            ..SolverParams::default()
        });
        Ok(live)
    }

    /// Converges on `sketch`, taken as the editor's solvers take it (warm from the last sketch,
    /// cold after an extent change).
    fn converge(&mut self, sketch: &Sketch) -> Result<()> {
        if self.applied.as_ref() == Some(sketch) {
            return Ok(());
        }
        let grid = self.live.solver.grid();
        if grid.extent_m != sketch.extent_m {
            self.live = Self::live(Grid::new(grid.n, sketch.extent_m)?)?;
            self.applied = None;
        }
        self.live.take(sketch, self.applied.as_ref())?;
        self.live.solver.solve();
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
        let n = self.live.solver.grid().n;
        let [ex, ey] = sketch.extent_m;
        probes_m
            .iter()
            .zip(shown_m)
            .filter_map(|(p, h)| {
                let h = (*h)?;
                (p[0].is_finite() && p[1].is_finite()).then(|| {
                    let c = sample_bilinear(
                        self.live.solver.heights(),
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
