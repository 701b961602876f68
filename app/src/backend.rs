//! Choosing and driving a solver backend from the command line.

use anyhow::{Context, Result};
use terrasketch_multigrid::gpu::GpuContext;
use terrasketch_multigrid::gpu_solver::GpuSolver;
use terrasketch_multigrid::{Budget, CpuSolver, Grid, SolveReport, SolverParams};
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

    /// Name of the device that runs the solve.
    pub fn adapter(&self) -> String {
        match self {
            AnySolver::Cpu(_) => format!("cpu ({} threads)", rayon::current_num_threads()),
            AnySolver::Gpu(s) => s.adapter().to_string(),
        }
    }

    /// Backend name for reports.
    pub fn backend_name(&self) -> &'static str {
        match self {
            AnySolver::Cpu(_) => "cpu",
            AnySolver::Gpu(_) => "gpu",
        }
    }

    /// Replaces the sketch and solves from scratch; `ms_total` covers rasterisation to the last level.
    pub fn solve_sketch(&mut self, sketch: &Sketch) -> Result<SolveReport> {
        match self {
            AnySolver::Cpu(s) => {
                let t = std::time::Instant::now();
                s.set_sketch(sketch);
                let mut r = s.solve();
                r.ms_total = t.elapsed().as_secs_f64() * 1e3;
                Ok(r)
            }
            AnySolver::Gpu(s) => Ok(s.solve_sketch(sketch)?),
        }
    }

    /// Level-0 heights (row 0 = south).
    pub fn heights(&self) -> Result<Vec<f32>> {
        match self {
            AnySolver::Cpu(s) => Ok(s.heights().to_vec()),
            AnySolver::Gpu(s) => Ok(s.read_heights()?),
        }
    }

    /// Relief of the height constraints, metres.
    pub fn relief_m(&self) -> f32 {
        match self {
            AnySolver::Cpu(s) => s.relief_m(),
            AnySolver::Gpu(s) => s.relief_m(),
        }
    }

    /// Continues the current height solve of `sketch` to a tolerance at f32 round-off (the
    /// "converged" reference; the GPU restarts FCG from the current heights).
    pub fn converge_fully(&mut self, sketch: &Sketch) -> Result<()> {
        match self {
            AnySolver::Cpu(s) => {
                let mut p = *s.params();
                p.tolerance = 1e-7;
                p.max_vcycles = 60;
                s.set_params(p);
                s.step(Budget::Unlimited);
                Ok(())
            }
            AnySolver::Gpu(s) => Ok(s.refine_to(sketch, 1e-7, 60)?),
        }
    }

    /// Bytes the solver allocated on the GPU (0 on the CPU).
    /// The GPU solver's device counters so far (None on the CPU).
    pub fn gpu_counters(&self) -> Option<terrasketch_multigrid::gpu::GpuCounters> {
        match self {
            AnySolver::Cpu(_) => None,
            AnySolver::Gpu(g) => Some(g.context().counters()),
        }
    }

    pub fn gpu_bytes(&self) -> u64 {
        match self {
            AnySolver::Cpu(_) => 0,
            AnySolver::Gpu(s) => s.gpu_bytes(),
        }
    }
}
