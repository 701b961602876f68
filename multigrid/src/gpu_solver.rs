//! The GPU solver as the command line drives it: the same three fields as [`crate::CpuSolver`]
//! (gradient field on level 1, roughness on level 2, heights on level 0), each solved by a
//! [`GpuFieldSolver`], and the heights published as an R32Float texture with a full mip chain.
//!
//! Rasterisation and the edge differences are computed on the CPU (shared with the CPU backend in
//! [`crate::fields`]); the gradient field is read back once per solve for that (n^2/4 floats).

use std::time::Instant;

use terrasketch_sketch::Sketch;

use crate::constraints::ConstraintMaps;
use crate::fields;
use crate::gpu::{GpuContext, GpuError, GpuFieldSolver, GpuMips};
use crate::grid::Grid;
use crate::problem::FieldProblem;
use crate::pyramid::MinMaxLevel;
use crate::{SolveReport, SolverParams};

/// Heights, gradient field and roughness solved on the GPU.
pub struct GpuSolver {
    grid: Grid,
    params: SolverParams,
    grad: GpuFieldSolver,
    rough: GpuFieldSolver,
    heights: GpuFieldSolver,
    mips: GpuMips,
    adapter: String,
}

impl GpuSolver {
    /// Allocates every GPU resource for `grid` on `ctx` (sizes are checked against the device first).
    pub fn new(ctx: &GpuContext, grid: Grid, params: SolverParams) -> Result<GpuSolver, GpuError> {
        let n = grid.n;
        let [ax, ay] = grid.axis_weights();
        let heights = GpuFieldSolver::with_params(ctx, n, ax, ay, &params)?;
        let grad = GpuFieldSolver::with_params(ctx, n / 2, ax, ay, &params)?;
        let rough = GpuFieldSolver::with_params(ctx, n / 4, ax, ay, &params)?;
        let mips = GpuMips::new(&heights)?;
        let info = &ctx.adapter_info;
        let adapter = format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type);
        Ok(GpuSolver {
            grid,
            params,
            grad,
            rough,
            heights,
            mips,
            adapter,
        })
    }

    /// Name, backend and type of the adapter.
    pub fn adapter(&self) -> &str {
        &self.adapter
    }

    /// Bytes of every buffer and texture the solver allocated on the GPU.
    pub fn gpu_bytes(&self) -> u64 {
        self.grad.gpu_bytes()
            + self.rough.gpu_bytes()
            + self.heights.gpu_bytes()
            + self.mips.gpu_bytes()
    }

    /// Solves `sketch` from scratch (FMG then FCG for each field) and updates the mip chain.
    pub fn solve_sketch(&mut self, sketch: &Sketch) -> Result<SolveReport, GpuError> {
        let t = Instant::now();
        let grid = self.grid;
        let n = grid.n;
        let [ax, ay] = grid.axis_weights();
        let maps = ConstraintMaps::rasterize(sketch, &grid);
        let mut report = SolveReport {
            levels: self.heights.levels() as u32,
            ..SolveReport::default()
        };
        if maps.elev_weight.iter().all(|w| *w <= 0.0) {
            // Empty sketch: every cell hard at the base elevation (the diffusion problem is singular).
            let base = sketch.base_elevation_m as f32;
            let p = FieldProblem {
                n,
                ax,
                ay,
                weight: vec![1.0; n * n],
                value: vec![base; n * n],
                ..Default::default()
            };
            self.heights.upload_problem(&p)?;
            self.heights.fmg()?;
            self.mips.update()?;
            report.converged = true;
            report.height_min_m = base;
            report.height_max_m = base;
            report.ms_total = t.elapsed().as_secs_f64() * 1e3;
            return Ok(report);
        }
        let (d_east, d_north, field_wu) = self.solve_fields(&maps, false)?;
        let p = FieldProblem {
            n,
            ax,
            ay,
            weight: maps.elev_weight,
            value: maps.elev_value,
            d_east,
            d_north,
        };
        self.heights.upload_problem(&p)?;
        let wu = self.heights.fmg()?;
        let fcg = self
            .heights
            .fcg(self.params.max_vcycles, self.params.tolerance)?;
        self.mips.update()?;
        report.work_units = wu + fcg.stats.work_units;
        report.field_work_units = field_wu;
        report.vcycles = fcg.iterations;
        report.residual_initial = fcg.history.first().copied().unwrap_or(f32::INFINITY);
        report.residual_final = fcg.stats.residual;
        report.converged = fcg.stats.residual <= self.params.tolerance;
        let top = self.min_max()?;
        if let Some(l) = top.last() {
            report.height_min_m = l.cells[0][0];
            report.height_max_m = l.cells[0][1];
        }
        report.ms_total = t.elapsed().as_secs_f64() * 1e3;
        Ok(report)
    }

    /// Warm re-solve after an edit: re-rasterises, warm-starts every field from its last solution
    /// (operators rebuilt on the GPU) and iterates to the tolerance. Returns the report of this update.
    pub fn update_sketch_warm(&mut self, sketch: &Sketch) -> Result<SolveReport, GpuError> {
        let t = Instant::now();
        let grid = self.grid;
        let n = grid.n;
        let [ax, ay] = grid.axis_weights();
        let maps = ConstraintMaps::rasterize(sketch, &grid);
        let mut report = SolveReport {
            levels: self.heights.levels() as u32,
            ..SolveReport::default()
        };
        let (d_east, d_north, field_wu) = self.solve_fields(&maps, true)?;
        let p = FieldProblem {
            n,
            ax,
            ay,
            weight: maps.elev_weight,
            value: maps.elev_value,
            d_east,
            d_north,
        };
        self.heights.warm_start(&p)?;
        let fcg = self
            .heights
            .fcg(self.params.max_vcycles, self.params.tolerance)?;
        self.mips.update()?;
        report.work_units = fcg.stats.work_units;
        report.field_work_units = field_wu;
        report.vcycles = fcg.iterations;
        report.residual_initial = fcg.history.first().copied().unwrap_or(f32::INFINITY);
        report.residual_final = fcg.stats.residual;
        report.converged = fcg.stats.residual <= self.params.tolerance;
        report.ms_total = t.elapsed().as_secs_f64() * 1e3;
        Ok(report)
    }

    /// Solves the gradient field (level 1) and roughness (level 2) for `maps`, from scratch or warm, and
    /// returns the height problem's edge differences and the work units (in level-0 units).
    fn solve_fields(
        &mut self,
        maps: &ConstraintMaps,
        warm: bool,
    ) -> Result<(Vec<f32>, Vec<f32>, f64), GpuError> {
        let grid = self.grid;
        let n = grid.n;
        let (max, tol) = (self.params.max_vcycles, self.params.tolerance);
        let solve = |s: &mut GpuFieldSolver, p: &FieldProblem| -> Result<f64, GpuError> {
            let wu = if warm {
                s.warm_start(p)?;
                0.0
            } else {
                s.upload_problem(p)?;
                s.fmg()?
            };
            Ok(wu + s.fcg(max, tol)?.stats.work_units)
        };
        // Gradient field on level 1: two right-hand sides on one operator.
        let (mut px, vy) = fields::gradient_problem(&grid, maps);
        let mut wu = 0.25 * solve(&mut self.grad, &px)?;
        let gx = self.grad.read_solution()?;
        px.value = vy;
        wu += 0.25 * solve(&mut self.grad, &px)?;
        let gy = self.grad.read_solution()?;
        // Roughness on level 2.
        wu += 0.0625 * solve(&mut self.rough, &fields::roughness_problem(&grid, maps))?;
        let mut d_east = vec![0.0f32; n * n];
        let mut d_north = vec![0.0f32; n * n];
        fields::edge_differences(&grid, maps, (&gx, &gy), 0..n, (&mut d_east, &mut d_north));
        Ok((d_east, d_north, wu))
    }

    /// Continues the height solve to `tolerance` (for measuring the error at the stop point).
    pub fn refine_to(&mut self, tolerance: f32, max_iters: u32) -> Result<(), GpuError> {
        self.heights.fcg(max_iters, tolerance)?;
        Ok(())
    }

    /// Reads the level-0 heights back (row 0 = south).
    pub fn read_heights(&self) -> Result<Vec<f32>, GpuError> {
        self.heights.read_solution()
    }

    /// Relief of the height constraints.
    pub fn relief_m(&self) -> f32 {
        self.heights.relief()
    }

    /// Reads the min/max pyramid (a few KB).
    pub fn min_max(&self) -> Result<Vec<MinMaxLevel>, GpuError> {
        self.mips.read_min_max()
    }

    /// The heightmap texture (R32Float, full mip chain).
    pub fn texture(&self) -> &wgpu::Texture {
        self.mips.texture()
    }

    /// Reads mip level `k` of the heightmap texture back (tests).
    pub fn read_mip(&self, k: usize) -> Result<Vec<f32>, GpuError> {
        self.mips.read_mip(k)
    }
}
