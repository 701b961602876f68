//! Choosing and driving a solver backend from the command line: everything both backends do goes
//! through the multigrid crate's [`Solver`] trait; the variants stay open for the benchmarks and
//! the detail pass, which reach backend-specific methods (field parameters, phase times, the
//! GPU's roughness read-back).

use anyhow::{Context, Result};
use terrasketch_multigrid::gpu::GpuContext;
use terrasketch_multigrid::gpu_solver::GpuSolver;
use terrasketch_multigrid::{CpuSolver, Grid, SolveReport, Solver, SolverParams};
use terrasketch_sketch::Sketch;

use crate::BackendKind;

/// A solver on either backend, as the command line uses it.
pub enum AnySolver {
    /// The CPU (rayon) solver.
    Cpu(Box<CpuSolver>),
    /// The GPU (wgpu) solver.
    Gpu(Box<GpuSolver>),
}

impl AnySolver {
    /// Creates a solver on `kind` for `grid`. For the GPU, a missing adapter is an error that says how
    /// to install one.
    pub fn new(kind: BackendKind, grid: Grid, params: SolverParams) -> Result<AnySolver> {
        match kind {
            BackendKind::Cpu => Ok(AnySolver::Cpu(Box::new(CpuSolver::new(grid, params)?))),
            BackendKind::Gpu => {
                let ctx = GpuContext::new().context("--backend gpu needs a GPU adapter")?;
                let solver =
                    GpuSolver::new(&ctx, grid, params).context("cannot set up the GPU solver")?;
                Ok(AnySolver::Gpu(Box::new(solver)))
            }
        }
    }

    /// The solver as either backend's [`Solver`].
    pub fn solver(&self) -> &dyn Solver {
        match self {
            AnySolver::Cpu(s) => s.as_ref(),
            AnySolver::Gpu(s) => s.as_ref(),
        }
    }

    /// [`Self::solver`], mutable.
    pub fn solver_mut(&mut self) -> &mut dyn Solver {
        match self {
            AnySolver::Cpu(s) => s.as_mut(),
            AnySolver::Gpu(s) => s.as_mut(),
        }
    }

    /// Name of the device that runs the solve.
    pub fn adapter(&self) -> String {
        self.solver().adapter()
    }

    /// Backend name for reports.
    pub fn backend_name(&self) -> &'static str {
        self.solver().name()
    }

    /// Replaces the sketch and solves from scratch; `ms_total` covers rasterisation to the last level.
    pub fn solve_sketch(&mut self, sketch: &Sketch) -> Result<SolveReport> {
        Ok(self.solver_mut().solve_sketch(sketch)?)
    }

    /// Level-0 heights (row 0 = south).
    pub fn heights(&self) -> Result<Vec<f32>> {
        Ok(self.solver().heights()?.into_owned())
    }

    /// Relief of the height constraints, metres.
    pub fn relief_m(&self) -> f32 {
        self.solver().relief_m()
    }

    /// Continues the current height solve of `sketch` to a tolerance at f32 round-off (the
    /// "converged" reference; the GPU restarts FCG from the current heights).
    pub fn converge_fully(&mut self, sketch: &Sketch) -> Result<()> {
        Ok(self.solver_mut().refine_to(sketch, 1e-7, 60)?)
    }

    /// The GPU solver's device counters so far (None on the CPU).
    pub fn gpu_counters(&self) -> Option<terrasketch_multigrid::gpu::GpuCounters> {
        self.solver().counters()
    }

    /// Bytes the solver allocated on the GPU (0 on the CPU).
    pub fn gpu_bytes(&self) -> u64 {
        self.solver().gpu_bytes()
    }
}
