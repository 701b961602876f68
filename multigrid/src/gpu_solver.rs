//! The GPU solver as the command line and the editor drive it: the same three fields as
//! [`crate::CpuSolver`] (gradient field on level 1, roughness on level 2, heights on level 0), each
//! solved by a [`GpuFieldSolver`], and the heights published as an R32Float texture with a full mip chain.
//!
//! Everything runs on the GPU: only the stroke geometry goes up (a few KB). [`crate::gpu::raster`]
//! rasterises it (the WGSL twin of [`crate::constraints`]) in one pass into the height problem, the
//! gradient-field problem on level 1 and the roughness problem on level 2 (their blocks summed as
//! [`crate::fields::downsample_weighted`] sums them), with the problems' value ranges; the
//! edge differences of the height problem are computed from the diffused gradient field inside the
//! height assembly (`assemble_level0.wgsl`, the twin of [`crate::fields::edge_differences`]; no
//! level-0 edge-difference buffers). Each field's last
//! solution is kept on the GPU for warm starts. FCG's stop tests run on the GPU (`fcg_gate.wgsl`):
//! nothing is read back during a solve but one report per solve (the problems' reliefs, which
//! normalise the residuals, are computed on the GPU: `relief_scale.wgsl`); [`GpuContext::traffic`]
//! counts every byte either way.
//!
//! Three ways to drive it: [`GpuSolver::solve_sketch`] / [`GpuSolver::update_sketch_warm`] solve to
//! the tolerance in one call (one round trip when the guessed iterations suffice);
//! [`GpuSolver::begin`] + [`GpuSolver::iterate`] + [`GpuSolver::publish`] do the same work in pieces,
//! reading each step's residual; [`GpuSolver::take_queued`] + [`GpuSolver::queue_iterations`] +
//! [`GpuSolver::poll`] queue it and read what the device delivers without waiting (the editor).

use std::time::Instant;

use terrasketch_sketch::Sketch;

use crate::cpu::{FIELD_WARM_SWEEPS, FMG_SEED_RESIDUAL, SWEEPS, WARM_SEED_RESIDUAL};
use crate::cycle::{GRADIENT_LEVEL, ROUGHNESS_LEVEL, sweep_work_units};
use crate::gpu::QUEUED_REPORT_BYTES;
use crate::gpu::Queued;
use crate::gpu::QueuedReport;
use crate::gpu::Slice;
use crate::gpu::raster::{GpuRaster, RasterMaps, ReliefOf};
use crate::gpu::readback;
use crate::gpu::{GpuContext, GpuError, GpuFieldSolver, GpuMips};
use crate::grid::Grid;
use crate::problem::FieldProblem;
use crate::pyramid::MinMaxLevel;
use crate::solver::{FIELD_WARM_SEED, default_field_params};
use crate::{SolveReport, SolverParams};

mod reads;
mod steps;

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
    /// The scalar blocks of a take's queued FCG runs (gradient x, y, roughness, heights), read
    /// back together: two buffers used in turn, so a take need not wait for the mapping of the
    /// one it replaces.
    reports: [wgpu::Buffer; 2],
    /// The buffer of the newest take.
    newest: usize,
    /// The runs each reports buffer's take queued, to read a replaced take's reports.
    takes: [Option<TakeRuns>; 2],
    /// FCG iterations queued for each field (gradient x, y, roughness) and for the heights' first
    /// chunk, for cold (0) and warm (1) takes: about what the last ones needed (raised at once
    /// when short, lowered by one a take), so a take rarely needs another round trip.
    speculate: [[u32; 4]; 2],
    /// The heights' `[min, max]` read with the last take's reports (valid when it published).
    top_min_max: Option<[f32; 2]>,
    /// The editor's take whose reports were requested without waiting ([`Self::take_queued`]).
    take_pending: std::sync::Mutex<Option<(readback::MapPending, bool)>>,
    /// The mapping of a replaced take's reports (in the other buffer), dropped once delivered.
    replaced_pending: Option<readback::MapPending>,
    /// Staging buffers of the heights' scalars after queued iterations ([`Self::queue_iterations`]),
    /// each with its requested mapping and the take it reports on.
    iteration_reports: Vec<(wgpu::Buffer, Option<(readback::MapPending, u64)>)>,
    /// Takes so far: an iteration report of an earlier take says nothing of the current one.
    take_serial: u64,
}

/// What the editor learnt from the device without waiting ([`GpuSolver::poll`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LiveStatus {
    /// Normalised residual of the heights at the newest report, if one arrived.
    pub residual: Option<f32>,
    /// The take's report arrived and a field solve fell short of its tolerance: take the sketch
    /// again ([`GpuSolver::take_queued`] then queues more iterations for it).
    pub retake: bool,
    /// Work units of the take's FCG runs (relaxations, starts, field iterations), known now.
    pub late_work_units: f64,
    /// Of which the field solves' (level-0 units).
    pub late_field_work_units: f64,
}

/// Index of the heights in [`GpuSolver`]'s reports.
const HEIGHTS: usize = 3;
/// Byte offset in the reports of the published heights' `[min, max]` (after the four FCG runs).
const TOP_MIN_MAX: u64 = 4 * QUEUED_REPORT_BYTES;
/// Bytes of the reports buffer.
const REPORTS_BYTES: u64 = TOP_MIN_MAX + 8;
/// Staging buffers for the heights' reports after the editor's queued iterations.
const ITERATION_REPORTS: usize = 3;
/// FCG iterations the editor's takes allow before the gate closes for good (the editor queues
/// them one by one, [`GpuSolver::queue_iterations`]).
const EDITOR_MAX_ITERATIONS: u32 = 100_000;
/// Gated iterations queued per extra round trip of a solve to the tolerance.
const MORE_ITERATIONS: u32 = 4;

/// The FCG runs a take queued (gradient x, y, roughness when it solved the fields; the heights).
#[derive(Debug, Clone, Copy)]
struct TakeRuns {
    cold: bool,
    fields: Option<[Queued; 3]>,
    heights: Option<Queued>,
}

/// What a take's queued runs did (read after one wait).
struct TakeReports {
    /// Work units of the field solves (level-0 units, FCG part).
    field_wu: f64,
    /// Every field met its tolerance (or its cap) within the iterations queued for it.
    fields_done: bool,
    /// The heights' run.
    heights: crate::gpu::QueuedReport,
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
        // heights' level-0 buffers that are dead from the rasterisation until the height assembly.
        let grad = GpuFieldSolver::in_host_level0(ctx, n / 2, ax, ay, &params, &heights)?;
        let rough = GpuFieldSolver::in_host_level0(ctx, n / 4, ax, ay, &params, &heights)?;
        // The mips' constraint pyramid lives in the heights' `weight`, dead from the assembly to
        // the next rasterisation: `publish` runs in between. Their texture is the heights' `h`.
        let mips = GpuMips::in_weight_of(&heights)?;
        let info = &ctx.adapter_info;
        let adapter = format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type);
        let raster = GpuRaster::new(ctx, &grid, &heights, &grad, &rough)?;
        let reports = [0, 1].map(|_| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("multigrid.reports"),
                size: REPORTS_BYTES,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        });
        let extra_bytes = gx.size() + gy.size() + raster.bytes + 2 * REPORTS_BYTES;
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
            reports,
            newest: 0,
            takes: [None, None],
            replaced_pending: None,
            top_min_max: None,
            take_pending: std::sync::Mutex::new(None),
            take_serial: 0,
            iteration_reports: (0..ITERATION_REPORTS)
                .map(|_| {
                    let b = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some("multigrid.iteration_report"),
                        size: QUEUED_REPORT_BYTES,
                        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                        mapped_at_creation: false,
                    });
                    (b, None)
                })
                .collect(),
            // Cold fields need 1-2 iterations after FMG and warm ones usually none (their
            // relaxation meets the tolerance); the heights 3 cold and 1-2 warm.
            speculate: [[2, 2, 2, 4], [0, 0, 0, 2]],
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

    /// A solve to the tolerance with FCG's stop tests on the GPU: the rasterisation, the field
    /// solves, the height assembly and the heights' FCG are queued with the iterations the last
    /// solve needed and their reports read back together (one wait). Only
    /// when that guess falls short does a field solve run again (the take is redone, as its buffers
    /// are reused by the heights) or the heights get more iterations.
    fn solve_to_tolerance(&mut self, sketch: &Sketch, cold: bool) -> Result<SolveReport, GpuError> {
        let t = Instant::now();
        let max = self.params.max_vcycles;
        let (mut r, mut wu, field_wu) = loop {
            let (field_wu, height_wu) = self.prepare(
                sketch,
                cold,
                Some((
                    self.speculate[!cold as usize][HEIGHTS],
                    self.params.tolerance,
                    self.params.max_vcycles,
                )),
            )?;
            // Published in the same round trip: right unless the heights need more iterations.
            self.mips
                .update_and_copy_top(Some((&self.reports[self.newest], TOP_MIN_MAX)))?;
            let r = self.read_take(cold)?;
            if r.fields_done {
                break (r.heights, height_wu, field_wu + r.field_wu);
            }
        };
        let mut top = self.top_min_max;
        let mut published = true;
        let residual_initial = r.residual_start;
        while !r.stopped && r.iterations < max {
            self.heights.queue_more(MORE_ITERATIONS)?;
            r = self.heights.queued_report()?;
            published = false;
        }
        let guess = &mut self.speculate[!cold as usize][HEIGHTS];
        *guess = r.iterations.max(guess.saturating_sub(1));
        wu += r.stats.work_units;
        self.residual = r.stats.residual;
        self.started = r.started;
        if !published {
            self.publish()?;
            if cold {
                top = self.min_max()?.last().map(|l| l.cells[0]);
            }
        }
        let mut report = SolveReport {
            levels: self.heights.levels() as u32,
            work_units: wu,
            field_work_units: field_wu,
            residual_initial,
            vcycles: r.iterations,
            residual_final: self.residual,
            converged: self.residual <= self.params.tolerance,
            ..SolveReport::default()
        };
        if let (true, Some([lo, hi])) = (cold, top) {
            report.height_min_m = lo;
            report.height_max_m = hi;
        }
        report.ms_total = t.elapsed().as_secs_f64() * 1e3;
        Ok(report)
    }

    /// Reads the reports of the last [`Self::prepare`] (one wait), updates the iterations queued
    /// next time, and says whether every field met its tolerance within what was queued (if not,
    /// the next prepare queues more for it).
    fn read_take(&mut self, cold: bool) -> Result<TakeReports, GpuError> {
        let pending = self
            .take_pending
            .lock()
            .map_err(|_| GpuError::ProblemMismatch("reports lock poisoned".into()))?
            .take();
        let bytes = match pending {
            // The editor's take asked for them already: the mapping is on its way.
            Some((rx, _)) => readback::finish_map(
                &self.ctx,
                &self.reports[self.newest],
                REPORTS_BYTES,
                &rx,
                true,
                "solver reports",
            )?
            .unwrap_or_default(),
            None => self.ctx.checked("multigrid.reports", || {
                readback::map_read(
                    &self.ctx,
                    &self.reports[self.newest],
                    REPORTS_BYTES,
                    "solver reports",
                )
            })?,
        };
        self.take_reports(&bytes, cold)
    }

    /// The reports of a take from the reports buffer's bytes (see [`Self::read_take`]).
    fn take_reports(&mut self, bytes: &[u8], cold: bool) -> Result<TakeReports, GpuError> {
        let warm = !cold as usize;
        if (bytes.len() as u64) < REPORTS_BYTES {
            return Err(GpuError::ProblemMismatch("short solver reports".into()));
        }
        let t = TOP_MIN_MAX as usize;
        let f = |i: usize| f32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
        self.top_min_max = Some([f(t), f(t + 4)]);
        let at = |i: usize| &bytes[i * QUEUED_REPORT_BYTES as usize..];
        let mut field_wu = 0.0;
        let mut fields_done = true;
        // The newest take's field runs (none for an empty sketch).
        if self.takes[self.newest].is_some_and(|t| t.fields.is_some()) {
            let reports = [
                self.grad.report_of(at(0))?,
                self.grad.report_of(at(1))?,
                self.rough.report_of(at(2))?,
            ];
            (field_wu, fields_done) = self.note_field_reports(&reports, warm);
        }
        let heights = self.heights.report_of(at(HEIGHTS))?;
        Ok(TakeReports {
            field_wu,
            fields_done,
            heights,
        })
    }

    /// Updates the iterations the next takes of this kind (`warm`: 0 cold, 1 warm) queue for each
    /// field from its report; returns the fields' work units and whether every field met its
    /// tolerance within what was queued.
    fn note_field_reports(&mut self, reports: &[QueuedReport; 3], warm: usize) -> (f64, bool) {
        let scales = [GRADIENT_LEVEL, GRADIENT_LEVEL, ROUGHNESS_LEVEL].map(sweep_work_units);
        let mut field_wu = 0.0;
        let mut fields_done = true;
        for (i, (f, scale)) in reports.iter().zip(scales).enumerate() {
            field_wu += scale * f.stats.work_units;
            let guess = &mut self.speculate[warm][i];
            if f.stopped {
                *guess = f.iterations.max(guess.saturating_sub(1));
            } else {
                fields_done = false;
                *guess = (f.iterations + 2).max(*guess + 2);
            }
        }
        (field_wu, fields_done)
    }

    /// Reads the reports of a take a newer one replaced (`take`, what it queued): the fields'
    /// iteration guesses learn from them and their passes' bytes are counted; the solvers' state,
    /// which is the newer take's, is left alone.
    fn note_replaced_take(&mut self, bytes: &[u8], take: TakeRuns) -> Result<(), GpuError> {
        if (bytes.len() as u64) < REPORTS_BYTES {
            return Err(GpuError::ProblemMismatch("short solver reports".into()));
        }
        let at = |i: usize| &bytes[i * QUEUED_REPORT_BYTES as usize..];
        if let Some([x, y, r]) = take.fields {
            let reports = [
                self.grad.earlier_report(at(0), x)?,
                self.grad.earlier_report(at(1), y)?,
                self.rough.earlier_report(at(2), r)?,
            ];
            self.note_field_reports(&reports, !take.cold as usize);
        }
        if let Some(h) = take.heights {
            self.heights.earlier_report(at(HEIGHTS), h)?;
        }
        Ok(())
    }

    /// [`Self::publish`], with the min/max pyramid requested for [`Self::try_min_max`].
    pub fn publish_and_request_min_max(&mut self) -> Result<(), GpuError> {
        self.mips.update_and_request_min_max()
    }

    /// The min/max pyramid of an earlier [`Self::publish_and_request_min_max`], if delivered.
    pub fn try_min_max(&self) -> Result<Option<Vec<MinMaxLevel>>, GpuError> {
        self.mips.try_min_max()
    }

    /// One FCG iteration of the heights after [`Self::begin`]. Returns its work units, or `None` when
    /// FCG cannot proceed (converged exactly) or nothing was begun.
    pub fn iterate(&mut self) -> Result<Option<f64>, GpuError> {
        self.iterate_at(self.params.tolerance)
    }

    /// [`Self::iterate`] with the stop-test relaxation at `tolerance` (the CPU's FCG relaxes at
    /// the tolerance its loop stops at).
    fn iterate_at(&mut self, tolerance: f32) -> Result<Option<f64>, GpuError> {
        if !self.started {
            return Ok(None);
        }
        self.heights.set_stop(tolerance)?;
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

    /// Rasterises `sketch` on the GPU and reads back what the rasteriser wrote: the level-0
    /// elevation and band maps, the level-1 gradient-field problem and the level-2 roughness
    /// problem (tests and tools, not the editor's frame loop; no level-0 gradient or roughness map
    /// exists on the GPU). The maps share buffers with the height solve: the solver needs a
    /// [`Self::begin`] afterwards.
    pub fn rasterize_and_read(&mut self, sketch: &Sketch) -> Result<RasterMaps, GpuError> {
        self.started = false;
        self.raster.run(sketch, &self.grid)?;
        self.raster.read_maps(&self.grid)
    }

    /// Solves the gradient field (level 1) and roughness (level 2) whose problems the rasteriser wrote
    /// into their solvers, from scratch or warm (each component from its own last solution), to
    /// `FIELD_TOLERANCE` as the CPU does (local relaxation, then FCG if still needed), leaving the
    /// gradient components in `gx` / `gy` for the height assembly. Each problem's relief comes from
    /// the rasteriser's value ranges on the GPU. Returns the work units (level-0 units).
    fn solve_fields(&mut self, warm: bool) -> Result<(f64, [Queued; 3]), GpuError> {
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
        // Both gradient components queue as many iterations (they share one solver's state).
        // A field that needed no FCG last time queues its relaxation alone.
        let queue = |k: u32| (k > 0).then_some(k);
        let guess = self.speculate[warm as usize];
        let grad_iters = queue(guess[0].max(guess[1]));
        let rough_iters = queue(guess[2]);
        let reports = self.reports[self.newest].clone();
        let raster = &self.raster;
        let solve = |s: &mut GpuFieldSolver,
                     relief: ReliefOf,
                     pre: &dyn Fn(&mut wgpu::CommandEncoder),
                     iterations: Option<u32>,
                     slot: u64|
         -> Result<(f64, Queued), GpuError> {
            // A warm field that queues its relaxation alone runs no cycle: its coarse operators
            // (the heights' levels, which the height assembly rebuilds) are not built.
            s.assemble_on_gpu(None, !warm, !warm || iterations.is_some(), pre)?;
            let wu = if warm { 0.0 } else { s.fmg()? };
            let report = Some((&reports, slot * QUEUED_REPORT_BYTES));
            let scale = |enc: &mut wgpu::CommandEncoder| raster.encode_relief(enc, relief);
            s.queue_fcg_relaxed(
                max,
                tol,
                threshold,
                sweeps,
                iterations,
                report,
                Some(&scale),
            )?;
            let run = s
                .queued_run()
                .ok_or_else(|| GpuError::ProblemMismatch("a field run was not queued".into()))?;
            Ok((wu, run))
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
        let (wx, run_x) = solve(&mut self.grad, ReliefOf::GradX, &pre_x, grad_iters, 0)?;
        let pre_y = |enc: &mut wgpu::CommandEncoder| {
            copy(enc, &h, &gx);
            copy(enc, &vy, &value);
            if warm {
                copy(enc, &gy, &h);
            }
        };
        let (wy, run_y) = solve(&mut self.grad, ReliefOf::GradY, &pre_y, grad_iters, 1)?;
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
        let (wr, run_r) = solve(
            &mut self.rough,
            ReliefOf::Roughness,
            &|_| {},
            rough_iters,
            2,
        )?;
        let mut wu = sweep_work_units(GRADIENT_LEVEL) * wx;
        wu += sweep_work_units(GRADIENT_LEVEL) * wy;
        wu += sweep_work_units(ROUGHNESS_LEVEL) * wr;
        Ok((wu, [run_x, run_y, run_r]))
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
            match self.iterate_at(tolerance)? {
                Some(w) => {
                    wu += w;
                    iters += 1;
                }
                None => break,
            }
        }
        Ok((wu, iters))
    }
}
