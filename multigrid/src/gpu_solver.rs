//! The GPU solver as the command line and the editor drive it: the same three fields as
//! [`crate::CpuSolver`] (gradient field on level 1, roughness on level 2, heights on level 0), each
//! solved by a [`GpuFieldSolver`], and the heights published as an R32Float texture with a full mip chain.
//!
//! Everything runs on the GPU: only the stroke geometry goes up (a few KB). [`crate::gpu::raster`]
//! rasterises it (the WGSL twin of [`crate::constraints`]) into the height problem and the roughness
//! problem on level 2, and downsamples the gradient-field problem (both the twin of
//! [`crate::fields::downsample_weighted`]); the
//! edge differences of the height problem are computed from the diffused gradient field inside the
//! height assembly (`assemble_level0.wgsl`, the twin of [`crate::fields::edge_differences`]; no
//! level-0 edge-difference buffers). Each field's last
//! solution is kept on the GPU for warm starts. Nothing is read back during a solve but the
//! rasteriser's 32 bytes of value ranges (the problems' reliefs) and FCG's 8-byte stop tests;
//! [`GpuContext::traffic`] counts every byte either way.
//!
//! Two ways to drive it: [`GpuSolver::solve_sketch`] / [`GpuSolver::update_sketch_warm`] solve to the
//! tolerance in one call; [`GpuSolver::begin`] + [`GpuSolver::iterate`] + [`GpuSolver::publish`] do the
//! same work in pieces (the editor's frame budget).

use std::time::Instant;

use terrasketch_sketch::Sketch;

use crate::constraints::ConstraintMaps;
use crate::cpu::{FIELD_WARM_SWEEPS, FMG_SEED_RESIDUAL, SWEEPS, WARM_SEED_RESIDUAL};
use crate::gpu::Slice;
use crate::gpu::raster::{self, GpuRaster, RasterStats};
use crate::gpu::{GpuContext, GpuError, GpuFieldSolver, GpuMips};
use crate::grid::Grid;
use crate::problem::FieldProblem;
use crate::pyramid::MinMaxLevel;
use crate::solver::{FIELD_WARM_SEED, default_field_params};
use crate::{SolveReport, SolverParams};

/// Heights, gradient field and roughness solved on the GPU.
pub struct GpuSolver {
    ctx: GpuContext,
    grid: Grid,
    params: SolverParams,
    grad: GpuFieldSolver,
    rough: GpuFieldSolver,
    heights: GpuFieldSolver,
    mips: GpuMips,
    adapter: String,
    /// Last solutions of the two gradient components (level 1), for warm starts and the height
    /// assembly (which computes the edge differences from them).
    gx: wgpu::Buffer,
    gy: wgpu::Buffer,
    raster: GpuRaster,
    extra_bytes: u64,
    /// Normalised residual of the heights after the last FCG start or iteration.
    residual: f32,
    /// A height problem is uploaded and FCG started on it.
    started: bool,
}

/// What [`GpuSolver::begin`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeginReport {
    /// Work units of the field solves (level-0 units) and of FMG (cold starts only).
    pub field_work_units: f64,
    /// Height work units (FMG on a cold start, plus the FCG start).
    pub work_units: f64,
    /// Normalised residual of the heights after the start.
    pub residual: f32,
}

impl GpuSolver {
    /// Allocates every GPU resource for `grid` on `ctx` (sizes are checked against the device first).
    pub fn new(ctx: &GpuContext, grid: Grid, params: SolverParams) -> Result<GpuSolver, GpuError> {
        let n = grid.n;
        let [ax, ay] = grid.axis_weights();
        // Sizes first: the gradient buffers are allocated before the solvers check theirs.
        crate::gpu::check_limits(n, &ctx.device.limits())?;
        let (gx, gy) = ctx.checked("multigrid.gradient.new", || {
            let storage = |label: &str, cells: usize| {
                ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: (cells * 4) as u64,
                    usage: wgpu::BufferUsages::STORAGE
                        | wgpu::BufferUsages::COPY_DST
                        | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                })
            };
            Ok((
                storage("multigrid.grad_x", n * n / 4),
                storage("multigrid.grad_y", n * n / 4),
            ))
        })?;
        let [dx, dy] = grid.cell_size_m();
        // The heights keep `h` in mip 0 of the height texture, which the mips then publish.
        let texture = ctx.checked("multigrid.heights.texture", || {
            Ok(crate::gpu::mips::height_texture(ctx, n))
        })?;
        // The heights' edge differences are computed inside their assembly from `gx`, `gy`; the
        // gradient field and roughness have none. None of the three has edge-difference buffers.
        let heights = GpuFieldSolver::with_gradient_edges(
            ctx,
            n,
            ax,
            ay,
            &params,
            (&gx, &gy, [dx as f32, dy as f32]),
            &texture,
        )?;
        // The field solves run one after the other before the height assembly (`begin`): their
        // coarse levels are the heights' (see `gpu::resources::Buffers`).
        // Their level-0 buffers (but roughness's `h`) and the rasteriser's `vy` are ranges of the
        // heights' level-0 buffers that are dead from the downsampling until the height assembly.
        let grad = GpuFieldSolver::in_host_level0(ctx, n / 2, ax, ay, &params, &heights)?;
        let rough = GpuFieldSolver::in_host_level0(ctx, n / 4, ax, ay, &params, &heights)?;
        // The mips' constraint pyramid lives in the heights' `weight`, dead from the assembly to
        // the next rasterisation: `publish` runs in between. Their texture is the heights' `h`.
        let mips = GpuMips::in_weight_of(&heights)?;
        let info = &ctx.adapter_info;
        let adapter = format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type);
        let raster = GpuRaster::new(ctx, &grid, &heights, &grad, &rough)?;
        let extra_bytes = gx.size() + gy.size() + raster.bytes;
        Ok(GpuSolver {
            ctx: ctx.clone(),
            grid,
            params,
            grad,
            rough,
            heights,
            mips,
            adapter,
            gx,
            gy,
            raster,
            extra_bytes,
            residual: f32::INFINITY,
            started: false,
        })
    }

    /// Name, backend and type of the adapter.
    pub fn adapter(&self) -> &str {
        &self.adapter
    }

    /// The device the solver runs on (its [`GpuContext::traffic`] counts the bytes moved).
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// The grid.
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// Bytes of every buffer and texture the solver allocated on the GPU.
    pub fn gpu_bytes(&self) -> u64 {
        self.grad.gpu_bytes()
            + self.rough.gpu_bytes()
            + self.heights.gpu_bytes()
            + self.mips.gpu_bytes()
            + self.extra_bytes
    }

    /// Solves `sketch` from scratch (FMG then FCG for each field) and updates the mip chain.
    pub fn solve_sketch(&mut self, sketch: &Sketch) -> Result<SolveReport, GpuError> {
        self.solve_to_tolerance(sketch, true)
    }

    /// Warm re-solve after an edit: re-rasterises, warm-starts every field from its last solution
    /// (operators rebuilt on the GPU) and iterates to the tolerance. Returns the report of this update.
    pub fn update_sketch_warm(&mut self, sketch: &Sketch) -> Result<SolveReport, GpuError> {
        self.solve_to_tolerance(sketch, false)
    }

    fn solve_to_tolerance(&mut self, sketch: &Sketch, cold: bool) -> Result<SolveReport, GpuError> {
        let t = Instant::now();
        let b = self.begin(sketch, cold)?;
        let mut report = SolveReport {
            levels: self.heights.levels() as u32,
            work_units: b.work_units,
            field_work_units: b.field_work_units,
            residual_initial: b.residual,
            ..SolveReport::default()
        };
        let (wu, vcycles) = self.iterate_to(self.params.tolerance, self.params.max_vcycles)?;
        report.work_units += wu;
        self.publish()?;
        report.vcycles = vcycles;
        report.residual_final = self.residual;
        report.converged = self.residual <= self.params.tolerance;
        if cold {
            let top = self.min_max()?;
            if let Some(l) = top.last() {
                report.height_min_m = l.cells[0][0];
                report.height_max_m = l.cells[0][1];
            }
        }
        report.ms_total = t.elapsed().as_secs_f64() * 1e3;
        Ok(report)
    }

    /// Takes `sketch`: rasterises it on the GPU (only the stroke geometry goes up), solves the
    /// gradient field and roughness (cold, or warm from their last solutions), assembles the height
    /// problem with its edge differences (cold: `h = 0` then FMG; warm: keeps `h`), relaxes the
    /// heights locally where the residual is large and starts FCG. The heights then need
    /// [`Self::iterate`] until [`Self::residual`] meets the tolerance, and [`Self::publish`] to
    /// show. Besides FCG's 8-byte stop tests (12 at the start: the relaxation's cell count), 32
    /// bytes come back (value ranges).
    pub fn begin(&mut self, sketch: &Sketch, cold: bool) -> Result<BeginReport, GpuError> {
        let (field_wu, mut wu) = self.prepare(sketch, cold)?;
        // Local relaxation before FCG, as the CPU: after FMG at its largest residuals; warm at
        // the residuals an edit leaves (the CPU seeds warm starts by the changed constraints,
        // which the GPU does not track).
        let threshold = if cold {
            FMG_SEED_RESIDUAL
        } else {
            WARM_SEED_RESIDUAL
        };
        let first = self.heights.fcg_start_relaxed(threshold, SWEEPS)?;
        wu += first.work_units;
        self.residual = first.residual;
        self.started = true;
        Ok(BeginReport {
            field_work_units: field_wu,
            work_units: wu,
            residual: self.residual,
        })
    }

    /// [`Self::begin`] up to FCG's start: rasterisation, field solves, height assembly (cold: and
    /// FMG). Returns the field and height work units.
    fn prepare(&mut self, sketch: &Sketch, cold: bool) -> Result<(f64, f64), GpuError> {
        let grid = self.grid;
        let n = grid.n;
        let [ax, ay] = grid.axis_weights();
        self.started = false;
        let stats = self.raster.run(sketch, &grid, true)?;
        let mut field_wu = 0.0;
        let mut wu = 0.0;
        if stats.elevation.is_none() {
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
            wu += self.heights.fmg()?;
        } else {
            field_wu = self.solve_fields(&stats, !cold)?;
            // The assembly computes the edge differences from `gx`, `gy` and the band weight.
            self.heights
                .assemble_on_gpu(raster::relief(stats.elevation), cold, &|_| {})?;
            if cold {
                wu += self.heights.fmg()?;
            }
        }
        Ok((field_wu, wu))
    }

    /// One FCG iteration of the heights after [`Self::begin`]. Returns its work units, or `None` when
    /// FCG cannot proceed (converged exactly) or nothing was begun.
    pub fn iterate(&mut self) -> Result<Option<f64>, GpuError> {
        if !self.started {
            return Ok(None);
        }
        match self.heights.fcg_iterate()? {
            Some(s) => {
                self.residual = s.residual;
                Ok(Some(s.work_units))
            }
            None => {
                self.started = false;
                Ok(None)
            }
        }
    }

    /// Normalised residual of the heights after the last start or iteration (infinite before any).
    pub fn residual(&self) -> f32 {
        self.residual
    }

    /// The solver parameters.
    pub fn params(&self) -> &SolverParams {
        &self.params
    }

    /// Rebuilds the mip chain and the min/max pyramid from the current heights (on the GPU): mips
    /// 1 ..; mip 0 is the heights' `h` itself, which every FCG iteration updates.
    pub fn publish(&mut self) -> Result<(), GpuError> {
        self.mips.update()
    }

    /// Rasterises `sketch` on the GPU and reads the level-0 constraint maps back in full, but the
    /// roughness maps (left empty: the rasteriser writes the roughness problem straight onto level 2),
    /// and that roughness problem (tests and tools, not the editor's frame loop). The maps share
    /// buffers with the height solve: the solver needs a [`Self::begin`] afterwards.
    pub fn rasterize_and_read(
        &mut self,
        sketch: &Sketch,
    ) -> Result<(ConstraintMaps, FieldProblem), GpuError> {
        self.started = false;
        self.raster.run(sketch, &self.grid, false)?;
        self.raster.read_maps(&self.grid)
    }

    /// Solves the gradient field (level 1) and roughness (level 2) whose problems the rasteriser wrote
    /// into their solvers, from scratch or warm (each component from its own last solution), to
    /// `FIELD_TOLERANCE` as the CPU does (local relaxation, then FCG if still needed), leaving the
    /// gradient components in `gx` / `gy` for the height assembly. Returns the work units (level-0
    /// units).
    fn solve_fields(&mut self, stats: &RasterStats, warm: bool) -> Result<f64, GpuError> {
        // As the CPU: the fields' own (looser) tolerance; a local relaxation after FMG, or, warm, at
        // the residuals the edit left, and FCG only if the tolerance still does not hold.
        let field_params = default_field_params(&self.params);
        let (max, tol) = (field_params.max_vcycles, field_params.tolerance);
        let (threshold, sweeps) = if warm {
            (tol * FIELD_WARM_SEED, FIELD_WARM_SWEEPS)
        } else {
            (FMG_SEED_RESIDUAL, SWEEPS)
        };
        let ctx = self.ctx.clone();
        let copy = |enc: &mut wgpu::CommandEncoder, from: &Slice, to: &Slice| from.copy_to(enc, to);
        let solve = |s: &mut GpuFieldSolver,
                     relief: f32,
                     pre: &dyn Fn(&mut wgpu::CommandEncoder)|
         -> Result<f64, GpuError> {
            s.assemble_on_gpu(relief, !warm, pre)?;
            let wu = if warm { 0.0 } else { s.fmg()? };
            Ok(wu + s.fcg_relaxed(max, tol, threshold, sweeps)?.stats.work_units)
        };
        // Gradient field on level 1: two right-hand sides on one operator, each warm from its own
        // last solution (the x values are in place; the y values wait in the rasteriser's `vy`).
        let h = self.grad.h_buffer()?.clone();
        let value = self.grad.bufs.value.clone();
        let (gx, gy) = (Slice::whole(self.gx.clone()), Slice::whole(self.gy.clone()));
        let vy = self.raster.vy.clone();
        let pre_x = |enc: &mut wgpu::CommandEncoder| {
            if warm {
                copy(enc, &gx, &h);
            }
        };
        let mut wu = 0.25 * solve(&mut self.grad, raster::relief(stats.grad_x), &pre_x)?;
        let pre_y = |enc: &mut wgpu::CommandEncoder| {
            copy(enc, &h, &gx);
            copy(enc, &vy, &value);
            if warm {
                copy(enc, &gy, &h);
            }
        };
        wu += 0.25 * solve(&mut self.grad, raster::relief(stats.grad_y), &pre_y)?;
        ctx.checked("multigrid.fields.keep", || {
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("multigrid.fields.keep"),
                });
            copy(&mut enc, &h, &gy);
            ctx.submit([enc.finish()]);
            Ok(())
        })?;
        // Roughness on level 2.
        wu += 0.0625 * solve(&mut self.rough, raster::relief(stats.roughness), &|_| {})?;
        Ok(wu)
    }

    /// Reads texels of mip `level` (`(x, y)` in texel coordinates of that level, row 0 = south): one
    /// 4-byte copy each (the editor's probes).
    pub fn read_texels(&self, level: u32, texels: &[[u32; 2]]) -> Result<Vec<f32>, GpuError> {
        let side = (self.grid.n >> level) as u32;
        if level as usize >= self.mips.mip_count() {
            return Err(GpuError::BadLevel {
                level: level as usize,
                levels: self.mips.mip_count(),
            });
        }
        if texels.is_empty() {
            return Ok(Vec::new());
        }
        if let Some(t) = texels.iter().find(|t| t[0] >= side || t[1] >= side) {
            return Err(GpuError::ProblemMismatch(format!(
                "texel {t:?} outside mip {level} of side {side}"
            )));
        }
        crate::gpu::read_texels(&self.ctx, self.mips.texture(), level, texels)
    }

    /// Continues the height solve of `sketch` (the one last begun) to `tolerance`, at most
    /// `max_iters` FCG iterations, for measuring the error at the stop point: a warm [`Self::begin`]
    /// (the same problem, `r = f - A h` recomputed from the current heights, which a mere
    /// continuation could not do: [`Self::publish`] reuses `f`), then iterations; then publishes.
    pub fn refine_to(
        &mut self,
        sketch: &Sketch,
        tolerance: f32,
        max_iters: u32,
    ) -> Result<(), GpuError> {
        self.begin(sketch, false)?;
        self.iterate_to(tolerance, max_iters)?;
        self.publish()
    }

    /// FCG iterations of the heights until the residual is at most `tolerance`, at most
    /// `max_iters`, or FCG cannot proceed. Returns their work units and number.
    fn iterate_to(&mut self, tolerance: f32, max_iters: u32) -> Result<(f64, u32), GpuError> {
        let (mut wu, mut iters) = (0.0, 0);
        while self.residual > tolerance && iters < max_iters {
            match self.iterate()? {
                Some(w) => {
                    wu += w;
                    iters += 1;
                }
                None => break,
            }
        }
        Ok((wu, iters))
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

    /// The heightmap texture (R32Float, full mip chain; mip 0 is the heights' `h`, see
    /// [`Self::publish`]).
    pub fn texture(&self) -> &wgpu::Texture {
        self.mips.texture()
    }

    /// Reads the two gradient components (level 1, the last solutions) back (tests).
    pub fn read_gradient(&self) -> Result<(Vec<f32>, Vec<f32>), GpuError> {
        let cells = (self.grid.n * self.grid.n / 4) as u64;
        self.ctx.checked("multigrid.read_gradient", || {
            Ok((
                crate::gpu::read_f32(&self.ctx, &self.gx, 0, cells, "gradient x")?,
                crate::gpu::read_f32(&self.ctx, &self.gy, 0, cells, "gradient y")?,
            ))
        })
    }

    /// The roughness's last solution (level 2, row 0 = south, f32) as `(buffer, byte offset, bytes)`,
    /// for passes that read it in place (the editor's detail amplitude).
    pub fn roughness_buffer(&self) -> Result<(wgpu::Buffer, u64, u64), GpuError> {
        let s = self.rough.h_buffer()?;
        Ok((s.buffer.clone(), s.offset, s.size))
    }

    /// Level 2 of the mips' constraint pyramid (per level-2 cell `vec2(count of hard level-0 cells,
    /// sum of their E)`) as `(buffer, byte offset, bytes)`: valid from [`Self::publish`] to the next
    /// [`Self::begin`] (it lives in the heights' `weight`).
    pub fn hard_counts_level2(&self) -> (wgpu::Buffer, u64, u64) {
        let n = self.grid.n;
        let start = crate::gpu::mips::constraint_offsets(n)[1] as u64 * 8;
        let w = &self.heights.bufs.weight;
        (
            w.buffer.clone(),
            w.offset + start,
            (n / 4 * n / 4 * 8) as u64,
        )
    }

    /// Reads the roughness (level 2, the last solution) back (tests).
    pub fn read_roughness(&self) -> Result<Vec<f32>, GpuError> {
        self.rough.read_solution()
    }

    /// Rasterises and assembles `sketch` as a warm [`Self::begin`] does, without starting FCG, and
    /// reads the level-0 height operator back: the diagonal (0 on hard cells) and the right-hand
    /// side `f`, into which the edge differences computed on the GPU enter (tests). `f` lives in
    /// FCG's `p` (`Buffers`), which FCG's start overwrites: the solver needs a [`Self::begin`]
    /// before it iterates again.
    pub fn read_height_operator(
        &mut self,
        sketch: &Sketch,
    ) -> Result<(Vec<f32>, Vec<f32>), GpuError> {
        self.prepare(sketch, false)?;
        Ok((self.heights.read_diag()?, self.heights.read_rhs(0)?))
    }

    /// Reads mip level `k` of the heightmap texture back (tests).
    pub fn read_mip(&self, k: usize) -> Result<Vec<f32>, GpuError> {
        self.mips.read_mip(k)
    }
}
