//! [`GpuFieldSolver`]: the GPU twin of `cpu::Hierarchy` + one `cpu::FieldState`.

use super::kernels::{PassSpec, PassTable, Pipelines, Res};
use super::params::{
    INACTIVE_REL, Params, RELAX_CELLS_OFFSET, RELAX_GROUPS_OFFSET, STATUS_BYTES, STENCIL_BYTES,
    STENCIL_WORDS, Scalars,
};
use super::plan::{self, CycleShape, Op, Step};
use super::readback;
use super::resources::{
    Buffers, Edges, HStore, RELAX_ARGS_OFFSET, check_limits, pass_spec, solve_levels,
};
use super::shaders::Kernel;
use super::slice::Slice;
use super::{GpuContext, GpuError};
use crate::SolverParams;
use crate::cpu::CycleStats;
use crate::problem::FieldProblem;
use wgpu::util::DeviceExt;

/// What one [`GpuFieldSolver::fcg`] call did.
#[derive(Debug, Clone, PartialEq)]
pub struct FcgReport {
    /// Work units spent (preconditioner sweeps, counted as on the CPU) and the final normalised residual.
    pub stats: CycleStats,
    /// FCG iterations done (= applications of the preconditioner after the first).
    pub iterations: u32,
    /// Normalised residual before the first iteration and after each one.
    pub history: Vec<f32>,
}

/// The GPU solver of one diffusion field: operators on every level (level 0 matrix-free, Galerkin
/// coarse levels built on the GPU) and the unknowns, with FMG and FCG exactly as `ALGORITHM.md`.
pub struct GpuFieldSolver {
    ctx: GpuContext,
    n: usize,
    ax: f32,
    ay: f32,
    shape: CycleShape,
    relief: f32,
    uploaded: bool,
    pipelines: Pipelines,
    table: PassTable<Op>,
    pub(crate) bufs: Buffers,
    status: wgpu::Buffer,
    gpu_bytes: u64,
    plans: Plans,
    fcg_state: FcgState,
    gate: Gate,
    /// The FCG run queued by [`Self::queue_fcg_relaxed`], until [`Self::queued_report`] reads it.
    queued: Option<Queued>,
    /// The status staging buffer's requested mapping ([`Self::request_report`]).
    pending: std::sync::Mutex<Option<readback::MapPending>>,
}

/// FCG's stop test on the GPU: the gate passes and the indirect arguments they write.
struct Gate {
    table: PassTable<Op>,
    /// Size classes of the gated passes ([`plan::gate_classes`]): class `c` has its arguments at
    /// byte `12 c` of `args`.
    classes: Vec<[u32; 3]>,
    args: wgpu::Buffer,
    _sizes: wgpu::Buffer,
    /// Estimated bytes of the gated passes of the first direction, the first iteration and a later
    /// one (counted once known to have run).
    bytes: [u64; 3],
}

/// A queued FCG run ([`GpuFieldSolver::queue_fcg_relaxed`]).
#[derive(Debug, Clone, Copy)]
struct Queued {
    sweeps: usize,
    /// Gated iterations queued so far.
    iterations: u32,
    /// FCG's start was queued (else only the relaxation).
    start: bool,
    /// The relaxation's bytes were counted (by the first report of the run).
    relax_counted: bool,
}

/// What a queued FCG run did ([`GpuFieldSolver::queued_report`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QueuedReport {
    /// Work units (relaxation, first direction and iterations, counted as on the CPU) and the
    /// normalised residual at the stop.
    pub stats: CycleStats,
    /// FCG iterations that ran.
    pub iterations: u32,
    /// FCG started (the first direction ran): [`GpuFieldSolver::fcg_iterate`] may follow.
    pub started: bool,
    /// Normalised residual after the local relaxation, before FCG.
    pub residual_start: f32,
    /// True when the gate stopped FCG before the queued iterations ran out (tolerance met, the
    /// iteration cap reached, or `p.q <= 0`); false when more iterations may be queued.
    pub stopped: bool,
}

/// How a solver's buffers are laid out (the arguments of [`Buffers::new`] after the size): with
/// edge-difference buffers, the gradient field its assembly computes edge differences from, the
/// finer solver whose coarse levels it uses, and the texture whose mip 0 is `h`.
type Layout<'a> = (
    bool,
    Option<(&'a wgpu::Buffer, &'a wgpu::Buffer, [f32; 2])>,
    Option<(&'a Buffers, usize, bool)>,
    Option<&'a wgpu::Texture>,
);

/// Where FCG is: not started (or the problem changed), started, or past its first iteration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum FcgState {
    Idle,
    Started,
    Iterating,
}

struct Plans {
    assemble: Vec<Step>,
    assemble_cold: Vec<Step>,
    lift: Vec<Step>,
    fmg: Vec<Step>,
    fcg_init: Vec<Step>,
    fcg_first: Vec<Step>,
    fcg_next: Vec<Step>,
    residual: Vec<Step>,
    fcg_first_direction: Vec<Step>,
}

impl Plans {
    /// The assembly plan; `cold` also sets `h = 0` on the free cells.
    fn assemble(&self, cold: bool) -> &[Step] {
        if cold {
            &self.assemble_cold
        } else {
            &self.assemble
        }
    }

    fn new(shape: &CycleShape) -> Plans {
        let mut fcg_next = plan::fcg_direction(shape);
        fcg_next.extend(plan::fcg_step());
        Plans {
            assemble: plan::assemble(shape, false),
            assemble_cold: plan::assemble(shape, true),
            lift: plan::lift(shape),
            fmg: plan::fmg(shape),
            fcg_init: plan::fcg_init(shape),
            fcg_first: plan::fcg_step(),
            fcg_next,
            residual: plan::residual(),
            fcg_first_direction: plan::fcg_first_direction(shape),
        }
    }
}

impl Gate {
    /// The gate passes of a solver of side `n`: one size class per distinct workgroup count of the
    /// gated passes, their full counts in `sizes` (written once), `args` written by each gate.
    fn new(
        ctx: &GpuContext,
        pipelines: &Pipelines,
        table: &PassTable<Op>,
        shape: &CycleShape,
        n: usize,
        bufs: &Buffers,
    ) -> Gate {
        let classes = plan::gate_classes(shape, n);
        let words: Vec<u32> = classes.iter().flatten().copied().collect();
        let buffer = |label: &str, usage: wgpu::BufferUsages| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: (4 * words.len()).max(12) as u64,
                usage: wgpu::BufferUsages::STORAGE | usage,
                mapped_at_creation: false,
            })
        };
        let sizes = buffer("multigrid.gate.sizes", wgpu::BufferUsages::COPY_DST);
        let args = buffer("multigrid.gate.args", wgpu::BufferUsages::INDIRECT);
        ctx.queue
            .write_buffer(&sizes, 0, bytemuck::cast_slice(&words));
        ctx.count_up(4 * words.len() as u64);
        let specs = plan::GATE_OPS
            .iter()
            .map(|&op| PassSpec {
                key: op,
                kernel: Kernel::FcgGate,
                params: Params {
                    n: classes.len() as u32,
                    mode: matches!(op, Op::Gate { count: true }) as u32,
                    ..Params::default()
                },
                resources: vec![
                    Res::Buffer(&sizes),
                    Res::Buffer(&bufs.scalars),
                    Res::Buffer(&args),
                ],
                workgroups: op.workgroups(n),
                label: op.label(shape.coarsest()),
            })
            .collect();
        let gate_table = PassTable::new(ctx, pipelines, "multigrid.gate.params", specs);
        let bytes_of = |steps: Vec<Step>| -> u64 {
            steps
                .iter()
                .map(|s| match s {
                    Step::Gated(op) => table.bytes_moved(op),
                    _ => 0,
                })
                .sum()
        };
        let mut next = plan::gated(plan::fcg_direction(shape));
        next.extend(plan::gated(plan::fcg_step()));
        let bytes = [
            bytes_of(plan::gated(plan::fcg_first_direction(shape))),
            bytes_of(plan::gated(plan::fcg_step())),
            bytes_of(next),
        ];
        Gate {
            table: gate_table,
            classes,
            args,
            _sizes: sizes,
            bytes,
        }
    }

    /// Byte offset in `args` of the class of `op`'s workgroups on a level-0 side `n`.
    fn offset(&self, op: Op, n: usize) -> u64 {
        let w = op.workgroups(n);
        let c = self
            .classes
            .iter()
            .position(|&c| c == w)
            .unwrap_or_else(|| panic!("gated pass {op:?} has no size class"));
        12 * c as u64
    }
}

impl GpuFieldSolver {
    /// The cycle of `ALGORITHM.md`: V(1,1) on level 0, W from level 1 to level 3 (`gamma 2` from
    /// level 1 until level 3), V below.
    pub fn algorithm_params() -> SolverParams {
        SolverParams {
            pre_sweeps: 1,
            post_sweeps: 1,
            gamma: 2,
            gamma_from_level: 1,
            ..SolverParams::default()
        }
    }

    /// A solver for an `n x n` field with edge weights `ax`, `ay`, cycling as [`Self::algorithm_params`],
    /// taking problems with or without edge differences ([`Self::with_edges`]). Checks the size against
    /// the device limits before allocating anything.
    pub fn new(ctx: &GpuContext, n: usize, ax: f32, ay: f32) -> Result<GpuFieldSolver, GpuError> {
        Self::with_params(ctx, n, ax, ay, &Self::algorithm_params())
    }

    /// As [`Self::new`] with the cycle shape (sweeps, `gamma`, `gamma_from_level`) of `params`, counted
    /// exactly like `cpu::Hierarchy` (tolerance and `max_vcycles` are given per call).
    pub fn with_params(
        ctx: &GpuContext,
        n: usize,
        ax: f32,
        ay: f32,
        params: &SolverParams,
    ) -> Result<GpuFieldSolver, GpuError> {
        Self::with_edges(ctx, n, ax, ay, params, true)
    }

    /// As [`Self::with_params`]; with `edges == false` the solver takes only problems without edge
    /// differences (`d = 0`, empty `d_east` / `d_north`) and allocates no level-0 buffers for them
    /// (`buffer_sizes(n, false)`: the gradient field and roughness of [`crate::gpu_solver::GpuSolver`]).
    pub fn with_edges(
        ctx: &GpuContext,
        n: usize,
        ax: f32,
        ay: f32,
        params: &SolverParams,
        edges: bool,
    ) -> Result<GpuFieldSolver, GpuError> {
        Self::build(ctx, n, ax, ay, params, (edges, None, None, None))
    }

    /// As [`Self::with_edges`], with the solution `h` in mip 0 of `texture` instead of a buffer
    /// (an `n x n` R32Float texture with `STORAGE_BINDING | TEXTURE_BINDING | COPY_SRC`, e.g.
    /// [`crate::gpu::mips::height_texture`], which [`crate::gpu::GpuMips::new`] then publishes
    /// without copying `h`): the passes that read or write `h` use their texture variants (the same
    /// arithmetic, so the same bits). The texture is not counted in [`Self::gpu_bytes`].
    pub fn with_texture_h(
        ctx: &GpuContext,
        n: usize,
        ax: f32,
        ay: f32,
        params: &SolverParams,
        edges: bool,
        texture: &wgpu::Texture,
    ) -> Result<GpuFieldSolver, GpuError> {
        Self::build(ctx, n, ax, ay, params, (edges, None, None, Some(texture)))
    }

    /// As [`Self::with_edges`] without edge differences, for a coarser field solved between uses of
    /// `host` (side `n << shift`, `shift >= 1`, on the same device): this solver's coarse levels
    /// `k >= 1` are `host`'s levels `k + shift` (stencils, `u`, `f`), so it allocates only its level
    /// 0 ([`crate::gpu::allocated_sizes`]). Uploading or assembling a problem on either solver
    /// rebuilds those levels: after a solve of one, the other needs a new problem (or warm start)
    /// before it iterates again; the last solution `h` of each is kept. (`GpuSolver` goes further:
    /// [`Self::in_host_level0`].)
    pub fn sharing_coarse_levels(
        ctx: &GpuContext,
        n: usize,
        ax: f32,
        ay: f32,
        params: &SolverParams,
        host: &GpuFieldSolver,
    ) -> Result<GpuFieldSolver, GpuError> {
        Self::guest(ctx, n, ax, ay, params, host, false)
    }

    /// As [`Self::sharing_coarse_levels`], and its level-0 buffers but those [`allocated_sizes`]
    /// keeps (roughness: `h`) are ranges of `host`'s level-0 buffers that `host` leaves dead while
    /// this solver runs (`GpuSolver`'s gradient field and roughness; the ranges and when each is live:
    /// the `Buffers` doc comment in `gpu::resources`). After a solve of this solver, only its `h`
    /// survives (when allocated) a use of `host` and of the other guest.
    ///
    /// [`allocated_sizes`]: crate::gpu::allocated_sizes
    pub(crate) fn in_host_level0(
        ctx: &GpuContext,
        n: usize,
        ax: f32,
        ay: f32,
        params: &SolverParams,
        host: &GpuFieldSolver,
    ) -> Result<GpuFieldSolver, GpuError> {
        Self::guest(ctx, n, ax, ay, params, host, true)
    }

    fn guest(
        ctx: &GpuContext,
        n: usize,
        ax: f32,
        ay: f32,
        params: &SolverParams,
        host: &GpuFieldSolver,
        level0: bool,
    ) -> Result<GpuFieldSolver, GpuError> {
        let shift = host
            .n
            .checked_div(n)
            .map_or(0, |r| r.trailing_zeros() as usize);
        if shift == 0 || host.n != n << shift {
            return Err(GpuError::ProblemMismatch(format!(
                "a {n} x {n} solver cannot share the coarse levels of a {0} x {0} one",
                host.n
            )));
        }
        Self::build(
            ctx,
            n,
            ax,
            ay,
            params,
            (false, None, Some((&host.bufs, shift, level0)), None),
        )
    }

    /// As [`Self::with_params`] for the heights of [`crate::gpu_solver::GpuSolver`]: the assembly
    /// computes the edge differences from the level-1 gradient field `gx`, `gy` (`(n / 2)^2` values
    /// each), the band weight the rasteriser leaves in this solver's `r` and the elevation weight, for
    /// cells of `cell_m = [dx, dy]` metres; no edge-difference buffers. A problem uploaded to it
    /// ([`Self::upload_problem`]) has no edge differences. Its `h` is mip 0 of `texture` (the
    /// height texture, as [`Self::with_texture_h`]) and its `f` its own `p` (see `Buffers`).
    pub(crate) fn with_gradient_edges(
        ctx: &GpuContext,
        n: usize,
        ax: f32,
        ay: f32,
        params: &SolverParams,
        (gx, gy, cell_m): (&wgpu::Buffer, &wgpu::Buffer, [f32; 2]),
        texture: &wgpu::Texture,
    ) -> Result<GpuFieldSolver, GpuError> {
        let need = (n * n / 4 * 4) as u64;
        if gx.size() < need || gy.size() < need {
            return Err(GpuError::ProblemMismatch(format!(
                "gradient buffers of {} and {} bytes for a {n} x {n} height solver (need {need})",
                gx.size(),
                gy.size()
            )));
        }
        Self::build(
            ctx,
            n,
            ax,
            ay,
            params,
            (false, Some((gx, gy, cell_m)), None, Some(texture)),
        )
    }

    fn build(
        ctx: &GpuContext,
        n: usize,
        ax: f32,
        ay: f32,
        params: &SolverParams,
        (edges, gradient, host, h_texture): Layout<'_>,
    ) -> Result<GpuFieldSolver, GpuError> {
        check_limits(n, &ctx.device.limits())?;
        if !(ax.is_finite() && ay.is_finite() && ax > 0.0 && ay > 0.0) {
            return Err(GpuError::ProblemMismatch(format!(
                "edge weights ax = {ax}, ay = {ay} must be positive"
            )));
        }
        ctx.checked("multigrid.new", || {
            let levels = solve_levels(n);
            let shape = CycleShape {
                shift: host.map_or(0, |h| h.1),
                ..CycleShape::new(levels, params)
            };
            // A guest must fuse exactly the host's fused levels (their `u`, `f` are one buffer).
            if let Some((hb, shift, _)) = host
                && hb.fused_from.and_then(|k| k.checked_sub(shift)) != shape.fused_from()
            {
                return Err(GpuError::ProblemMismatch(format!(
                    "a {n} x {n} solver cannot fuse the coarse levels it shares"
                )));
            }
            let (mut bufs, mut buffer_bytes) =
                Buffers::new(ctx, n, edges, gradient, host, h_texture)?;
            // The fused passes' programs: the cycle's, then FMG's.
            let fused = plan::fused_ops(&shape);
            let words: Vec<u32> = fused
                .iter()
                .flat_map(|&op| plan::fused_program(op))
                .collect();
            if !words.is_empty() {
                let program = ctx
                    .device
                    .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some("multigrid.fused_program"),
                        contents: bytemuck::cast_slice(&words),
                        usage: wgpu::BufferUsages::STORAGE,
                    });
                buffer_bytes += program.size();
                bufs.fused_program = Some(program);
            }
            let threshold = INACTIVE_REL * (2.0 * ax + 2.0 * ay);
            let specs: Vec<_> = plan::all_ops(levels)
                .into_iter()
                .chain(fused)
                .map(|op| pass_spec(op, n, levels, ax, ay, threshold, &bufs))
                .collect();
            // The kernels the passes use (their variants depend on the levels and on where `h` is).
            let mut kernels: Vec<Kernel> = vec![Kernel::FcgGate];
            for k in specs.iter().map(|s| s.kernel) {
                if !kernels.contains(&k) {
                    kernels.push(k);
                }
            }
            let pipelines = Pipelines::new(ctx, &kernels);
            let table = PassTable::new(ctx, &pipelines, "multigrid.params", specs);
            let gate = Gate::new(ctx, &pipelines, &table, &shape, n, &bufs);
            let status = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("multigrid.status"),
                size: STATUS_STAGING_BYTES,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let gpu_bytes = buffer_bytes
                + table.bytes
                + STATUS_STAGING_BYTES
                + gate.table.bytes
                + 2 * gate.args.size();
            Ok(GpuFieldSolver {
                ctx: ctx.clone(),
                n,
                ax,
                ay,
                shape,
                relief: 1.0,
                uploaded: false,
                pipelines,
                table,
                bufs,
                status,
                gpu_bytes,
                plans: Plans::new(&shape),
                fcg_state: FcgState::Idle,
                gate,
                queued: None,
                pending: std::sync::Mutex::new(None),
            })
        })
    }

    /// Cells per side of level 0.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Levels including level 0 (the coarsest has side 8).
    pub fn levels(&self) -> usize {
        self.shape.levels
    }

    /// Relief of the last uploaded problem (normalises residuals).
    pub fn relief(&self) -> f32 {
        self.relief
    }

    /// Bytes of every buffer this solver allocated (level buffers, params arena, status staging;
    /// readbacks use short-lived staging buffers that are not counted).
    pub fn gpu_bytes(&self) -> u64 {
        self.gpu_bytes
    }

    /// The device this solver runs on.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// Uploads a new problem (cold): `h = 0` on free cells and `E` on hard cells, then the level-0
    /// operator and every Galerkin level are assembled on the GPU. Follow with [`Self::fmg`].
    pub fn upload_problem(&mut self, p: &FieldProblem) -> Result<(), GpuError> {
        self.upload(p, true)
    }

    /// Warm start: uploads and reassembles like [`Self::upload_problem`] but keeps `h` (hard cells reset to
    /// their new `E`). Follow with [`Self::fcg`].
    pub fn warm_start(&mut self, p: &FieldProblem) -> Result<(), GpuError> {
        self.upload(p, false)
    }

    /// Assembles the operator from `weight` / `value` that GPU passes wrote (nothing is uploaded):
    /// `pre` is recorded first (the passes that fill `weight`, `value` and, for the heights of
    /// `GpuSolver`, the band weight in `r`), then the level-0 operator (and, when `cold`, `h = 0`
    /// on the free cells: the assembly pass writes it, so `h` may be a texture) and, with
    /// `coarse`, the Galerkin operators are built (without: only a local relaxation may follow,
    /// which reads level 0 alone; a cycle needs another assembly with them). `relief` normalises
    /// the residuals from now on.
    pub(crate) fn assemble_on_gpu(
        &mut self,
        relief: f32,
        cold: bool,
        coarse: bool,
        pre: &dyn Fn(&mut wgpu::CommandEncoder),
    ) -> Result<(), GpuError> {
        let steps = self.plans.assemble(cold);
        let steps = if coarse { steps } else { &steps[..1] };
        let ctx = self.ctx.clone();
        ctx.checked("multigrid.assemble_on_gpu", || {
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("multigrid.assemble_on_gpu"),
                });
            pre(&mut enc);
            self.encode(&mut enc, steps, "multigrid.assemble");
            ctx.submit([enc.finish()]);
            Ok(())
        })?;
        self.relief = relief.max(1.0);
        self.uploaded = true;
        self.fcg_state = FcgState::Idle;
        Ok(())
    }

    /// The level-0 unknowns `h` (for copies in and out of warm-start stores), if they are in a
    /// buffer.
    pub(crate) fn h_buffer(&self) -> Result<&Slice, GpuError> {
        self.bufs.h.buffer().ok_or_else(|| {
            GpuError::ProblemMismatch("this solver keeps h in a texture, not a buffer".into())
        })
    }

    fn upload(&mut self, p: &FieldProblem, cold: bool) -> Result<(), GpuError> {
        let cells = self.n * self.n;
        if p.n != self.n || p.weight.len() != cells || p.value.len() != cells {
            return Err(GpuError::ProblemMismatch(format!(
                "problem n = {} with {} weights and {} values for a {} x {} solver",
                p.n,
                p.weight.len(),
                p.value.len(),
                self.n,
                self.n
            )));
        }
        let has_d = !p.d_east.is_empty() || !p.d_north.is_empty();
        if has_d && !matches!(self.bufs.edges, Edges::Uploaded(..)) {
            return Err(GpuError::ProblemMismatch(
                "edge differences given to a solver without edge-difference buffers".into(),
            ));
        }
        if has_d && (p.d_east.len() != cells || p.d_north.len() != cells) {
            return Err(GpuError::ProblemMismatch(format!(
                "d_east has {} and d_north {} values, expected {cells} each (or both empty)",
                p.d_east.len(),
                p.d_north.len()
            )));
        }
        if p.ax != self.ax || p.ay != self.ay {
            return Err(GpuError::ProblemMismatch(format!(
                "problem edge weights ({}, {}) differ from the solver's ({}, {})",
                p.ax, p.ay, self.ax, self.ay
            )));
        }
        let ctx = self.ctx.clone();
        ctx.checked("multigrid.upload", || {
            let b = &self.bufs;
            let q = &ctx.queue;
            q.write_buffer(
                &b.weight.buffer,
                b.weight.offset,
                bytemuck::cast_slice(&p.weight),
            );
            q.write_buffer(
                &b.value.buffer,
                b.value.offset,
                bytemuck::cast_slice(&p.value),
            );
            ctx.count_up(8 * cells as u64);
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("multigrid.upload"),
                });
            match &b.edges {
                Edges::Uploaded(de, dn) if has_d => {
                    q.write_buffer(de, 0, bytemuck::cast_slice(&p.d_east));
                    q.write_buffer(dn, 0, bytemuck::cast_slice(&p.d_north));
                    ctx.count_up(8 * cells as u64);
                }
                Edges::Uploaded(de, dn) => {
                    enc.clear_buffer(de, 0, None);
                    enc.clear_buffer(dn, 0, None);
                }
                // Band weight 0: the assembly computes d = 0.
                Edges::Gradient { .. } => b.r.clear(&mut enc),
                // The assembly reads no edge differences (d = 0).
                Edges::None => {}
            }
            self.encode(&mut enc, self.plans.assemble(cold), "multigrid.assemble");
            ctx.submit([enc.finish()]);
            Ok(())
        })?;
        self.relief = p.relief();
        self.uploaded = true;
        self.fcg_state = FcgState::Idle;
        Ok(())
    }

    fn require_problem(&self) -> Result<(), GpuError> {
        if self.uploaded {
            Ok(())
        } else {
            Err(GpuError::ProblemMismatch("no problem uploaded yet".into()))
        }
    }

    /// FMG cold start (`ALGORITHM.md`, `cpu::Hierarchy::fmg`): the lift `g` (push-pull extension of the
    /// constrained values, [`Self::lift`]) into `h`, `f_1 = R (f - A g)`, sums down to the coarsest
    /// level, exact solve there, for k = kc-1 .. 1 interpolation and one coarse cycle, then
    /// `h = g + P u_1` on free cells (`E` on hard cells). The levels' unknowns `u_k` approximate
    /// `h - g` ([`Self::read_level`], [`Self::read_lift`]). Returns the work units spent (the lift
    /// counts 0, as on the CPU).
    pub fn fmg(&mut self) -> Result<f64, GpuError> {
        self.require_problem()?;
        self.fcg_state = FcgState::Idle;
        self.ctx.checked("multigrid.fmg", || {
            self.submit(&self.plans.fmg, "multigrid.fmg");
            Ok(plan::work_units(&self.plans.fmg))
        })
    }

    /// Only the FMG lift (the first passes of [`Self::fmg`], `cpu::Hierarchy::fmg_start`'s `push_pull`):
    /// `h = g_0` and `g_k` for k = 1 ..= log2 n ([`Self::read_lift`]). Overwrites `h` (the solution is
    /// lost), level-0 `z` and FCG's `p`: a running FCG must be restarted. For tests and diagnostics.
    pub fn lift(&mut self) -> Result<(), GpuError> {
        self.require_problem()?;
        self.fcg_state = FcgState::Idle;
        self.ctx.checked("multigrid.lift", || {
            self.submit(&self.plans.lift, "multigrid.lift");
            Ok(())
        })
    }

    /// The FMG lift `g_k` of level `k` = 1 ..= log2 n (side `n >> k`, down to 1 x 1), row 0 = south, as
    /// left by [`Self::fmg`] or [`Self::lift`]. Only valid until FCG starts ([`Self::fcg`],
    /// [`Self::fcg_start`]), which reuses the storage (FCG's `p`).
    pub fn read_lift(&self, k: usize) -> Result<Vec<f32>, GpuError> {
        let top = self.shape.lift_levels();
        if k == 0 || k > top {
            return Err(GpuError::BadLevel {
                level: k,
                levels: top + 1,
            });
        }
        let side = (self.n >> k) as u64;
        let first = plan::lift_offset(self.n, k) as u64;
        self.ctx.checked("multigrid.read_lift", || {
            readback::read_f32(
                &self.ctx,
                &self.bufs.lift_values().buffer,
                self.bufs.lift_values().first_f32() + first,
                side * side,
                "lift",
            )
        })
    }

    /// FCG(1) on level 0 from the current `h` with one cycle as preconditioner, while the normalised
    /// residual is above `tolerance` and fewer than `max_iters` iterations ran (as
    /// `cpu::Hierarchy::iterate_to_tolerance`). `alpha` / `beta` are computed on the GPU; the CPU reads
    /// 8 bytes per iteration for the stop test.
    pub fn fcg(&mut self, max_iters: u32, tolerance: f32) -> Result<FcgReport, GpuError> {
        let first = self.fcg_start()?;
        self.iterate_from(first, max_iters, tolerance)
    }

    /// [`Self::fcg`] after a local relaxation of `h` (`sweeps` sweeps around the cells whose
    /// normalised residual exceeds `threshold`), as the CPU solves its fields
    /// (`Fcg::relax_at_residuals`, then `begin_checked`): the preconditioner is applied, and FCG
    /// iterates, only if the residual after the relaxation still exceeds `tolerance` (then one
    /// more round trip than [`Self::fcg_start_relaxed`]).
    pub fn fcg_relaxed(
        &mut self,
        max_iters: u32,
        tolerance: f32,
        threshold: f32,
        sweeps: usize,
    ) -> Result<FcgReport, GpuError> {
        let (rmax, relaxed) = self.relax_and_read(&self.plans.residual, threshold, sweeps)?;
        let residual = rmax * self.residual_scale();
        if residual <= tolerance || max_iters == 0 {
            // Converged by the relaxation: FCG has no direction (`fcg_iterate` must not follow).
            self.fcg_state = FcgState::Idle;
            return Ok(FcgReport {
                stats: CycleStats {
                    work_units: relaxed,
                    residual,
                },
                iterations: 0,
                history: vec![residual],
            });
        }
        let ctx = self.ctx.clone();
        ctx.checked("multigrid.fcg.start", || {
            self.submit(&self.plans.fcg_first_direction, "multigrid.fcg.start");
            Ok(())
        })?;
        self.fcg_state = FcgState::Started;
        let first = CycleStats {
            work_units: relaxed + plan::work_units(&self.plans.fcg_first_direction),
            residual,
        };
        self.iterate_from(first, max_iters, tolerance)
    }

    /// [`Self::fcg_relaxed`] queued whole, with its stop test on the GPU (`fcg_gate.wgsl`) and
    /// nothing read back: the local relaxation, the residual, the first direction unless the
    /// tolerance already holds, and `iterations` gated iterations of at most `max_iters` in all
    /// (more with [`Self::queue_more`]); with `iterations == None` the relaxation alone. The passes that run, and so the result, are those of
    /// [`Self::fcg_relaxed`]; [`Self::queued_report`] reads what happened.
    pub fn queue_fcg_relaxed(
        &mut self,
        max_iters: u32,
        tolerance: f32,
        threshold: f32,
        sweeps: usize,
        iterations: Option<u32>,
        report_to: Option<(&wgpu::Buffer, u64)>,
    ) -> Result<(), GpuError> {
        self.require_problem()?;
        let scale = self.residual_scale();
        let scalars = Scalars {
            relax_limit: threshold / scale,
            stop_rmax: tolerance / scale,
            iterations_left: max_iters,
            ..Scalars::default()
        };
        let ctx = self.ctx.clone();
        ctx.checked("multigrid.fcg.queued", || {
            self.ctx
                .queue
                .write_buffer(&self.bufs.scalars, 0, bytemuck::bytes_of(&scalars));
            self.ctx.count_up(std::mem::size_of::<Scalars>() as u64);
            let mut enc = self
                .ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("multigrid.fcg.queued"),
                });
            let steps = plan::fcg_queued(
                &self.shape,
                sweeps,
                iterations.unwrap_or(0),
                iterations.is_some(),
            );
            self.encode(&mut enc, &steps, "multigrid.fcg.queued");
            if let Some((dst, offset)) = report_to {
                enc.copy_buffer_to_buffer(&self.bufs.scalars, 0, dst, offset, STATUS_STAGING_BYTES);
            }
            self.ctx.submit([enc.finish()]);
            Ok(())
        })?;
        self.fcg_state = FcgState::Idle;
        self.queued = Some(Queued {
            sweeps,
            iterations: iterations.unwrap_or(0),
            start: iterations.is_some(),
            relax_counted: false,
        });
        Ok(())
    }

    /// Queues `iterations` more gated iterations of the run [`Self::queue_fcg_relaxed`] queued
    /// (they do nothing once the gate has stopped it).
    pub fn queue_more(&mut self, iterations: u32) -> Result<(), GpuError> {
        self.queue_more_reporting(iterations, None).map(|_| ())
    }

    /// [`Self::queue_more`], the scalars also copied to `report_to` (buffer, byte offset) after
    /// them. Returns the work units the queued iterations count if they all run.
    pub(crate) fn queue_more_reporting(
        &mut self,
        iterations: u32,
        report_to: Option<(&wgpu::Buffer, u64)>,
    ) -> Result<f64, GpuError> {
        let Some(q) = self.queued.as_mut().filter(|q| q.start) else {
            return Err(GpuError::ProblemMismatch(
                "queue_more without a queued FCG start".into(),
            ));
        };
        let first = q.iterations == 0;
        let steps = plan::fcg_queued_iterations(&self.shape, first, iterations);
        q.iterations += iterations;
        let wu = plan::work_units(&plan::gated_as_dispatches(&steps));
        let ctx = self.ctx.clone();
        ctx.checked("multigrid.fcg.queued", || {
            let mut enc = self
                .ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("multigrid.fcg.queued"),
                });
            self.encode(&mut enc, &steps, "multigrid.fcg.queued");
            if let Some((dst, offset)) = report_to {
                enc.copy_buffer_to_buffer(&self.bufs.scalars, 0, dst, offset, STATUS_STAGING_BYTES);
            }
            self.ctx.submit([enc.finish()]);
            Ok(())
        })?;
        Ok(wu)
    }

    /// Normalised residual and iterations run of a copy of the scalar block (`report_to` of the
    /// queued runs), without touching the run's state (the editor's non-blocking reads).
    pub(crate) fn residual_of(&self, bytes: &[u8]) -> (f32, u32) {
        let w: [u32; 16] = words_of(bytes);
        (f32::from_bits(w[0]) * self.residual_scale(), w[10])
    }

    /// The report of the queued run from a copy of its scalar block ([`Self::queue_fcg_relaxed`]'s
    /// `report_to`, [`QUEUED_REPORT_BYTES`] bytes).
    pub(crate) fn report_of(&mut self, bytes: &[u8]) -> Result<QueuedReport, GpuError> {
        if (bytes.len() as u64) < STATUS_STAGING_BYTES {
            return Err(GpuError::ProblemMismatch(format!(
                "{} bytes for a {STATUS_STAGING_BYTES}-byte FCG report",
                bytes.len()
            )));
        }
        self.report_from(words_of(bytes))
    }

    /// Copies the queued run's scalars to the staging buffer and maps it (the read completes at the
    /// next device poll: [`Self::queued_report`] after one wait, shared by every solver polled).
    pub(crate) fn request_report(&self) -> Result<(), GpuError> {
        if self.queued.is_none() {
            return Err(GpuError::ProblemMismatch(
                "no queued FCG run to report".into(),
            ));
        }
        let mut pending = self
            .pending
            .lock()
            .map_err(|_| GpuError::ProblemMismatch("status staging lock poisoned".into()))?;
        if pending.is_none() {
            *pending = Some(readback::request_map(&self.status, STATUS_STAGING_BYTES));
        }
        Ok(())
    }

    /// [`Self::queued_report`] if the report [`Self::request_report`] asked for has arrived (after a
    /// non-blocking poll of the device), else `None`: never waits.
    pub fn try_queued_report(&mut self) -> Result<Option<QueuedReport>, GpuError> {
        self.request_report()?;
        self.ctx
            .poll_nonblocking()
            .map_err(|e| GpuError::Readback {
                what: "multigrid.status".into(),
                message: e.to_string(),
            })?;
        let words = self.take_pending(false)?;
        Ok(match words {
            Some(w) => Some(self.report_from(w)?),
            None => None,
        })
    }

    /// The status words of a requested mapping (`wait`: blocking if not there yet), `None` when
    /// none was requested or (without `wait`) it has not arrived.
    fn take_pending(&self, wait: bool) -> Result<Option<[u32; 16]>, GpuError> {
        let mut pending = self
            .pending
            .lock()
            .map_err(|_| GpuError::ProblemMismatch("status staging lock poisoned".into()))?;
        let Some(rx) = pending.as_ref() else {
            return Ok(None);
        };
        let Some(bytes) = readback::finish_map(
            &self.ctx,
            &self.status,
            STATUS_STAGING_BYTES,
            rx,
            wait,
            "multigrid.status",
        )?
        else {
            return Ok(None);
        };
        *pending = None;
        Ok(Some(words_of(&bytes)))
    }

    /// What the queued run did so far: its scalars after the last queued pass (one blocking wait
    /// unless [`Self::request_report`] was polled already). The run stays queued: more iterations
    /// may follow ([`Self::queue_more`]) unless the report says it stopped.
    pub fn queued_report(&mut self) -> Result<QueuedReport, GpuError> {
        let words = match self.take_pending(true)? {
            Some(w) => w,
            None => self.read_words::<16>()?,
        };
        self.report_from(words)
    }

    /// The report of the queued run from its status words.
    fn report_from(&mut self, words: [u32; 16]) -> Result<QueuedReport, GpuError> {
        let Some(q) = self.queued else {
            return Err(GpuError::ProblemMismatch(
                "no queued FCG run to report".into(),
            ));
        };
        let rmax = f32::from_bits(words[0]);
        let status = words[1];
        let stop_rmax = f32::from_bits(words[7]);
        let cells = words[9] as usize;
        let iterations = words[10];
        let left = words[11];
        let rmax_start = f32::from_bits(words[12]);
        if !q.relax_counted {
            self.ctx.count_moved(self.relax_bytes(words[14], q.sweeps));
            if let Some(q) = self.queued.as_mut() {
                q.relax_counted = true;
            }
        }
        // The first direction ran when the first gate let FCG start (it zeroes `left` otherwise).
        let direction = q.start && (iterations > 0 || left > 0);
        let n2 = self.n * self.n;
        let relaxed = if cells * 4 > n2 {
            0.0
        } else {
            (cells * q.sweeps) as f64 / n2 as f64
        };
        let mut wu = relaxed;
        if direction {
            wu += plan::work_units(&self.plans.fcg_first_direction);
            self.ctx.count_moved(self.gate.bytes[0]);
        }
        if iterations > 0 {
            wu += plan::work_units(&self.plans.fcg_first)
                + (iterations - 1) as f64 * plan::work_units(&self.plans.fcg_next);
            self.ctx
                .count_moved(self.gate.bytes[1] + (iterations - 1) as u64 * self.gate.bytes[2]);
        }
        self.fcg_state = match (iterations, direction) {
            (0, false) => FcgState::Idle,
            (0, true) => FcgState::Started,
            _ => FcgState::Iterating,
        };
        let residual = rmax * self.residual_scale();
        Ok(QueuedReport {
            stats: CycleStats {
                work_units: wu,
                residual,
            },
            iterations,
            residual_start: if direction {
                rmax_start * self.residual_scale()
            } else {
                residual
            },
            started: direction,
            stopped: rmax <= stop_rmax
                || (q.start && (status != 0 || left == 0 || iterations < q.iterations)),
        })
    }

    /// FCG iterations after a start that left `first` until the residual meets `tolerance` or
    /// `max_iters` iterations ran.
    fn iterate_from(
        &mut self,
        first: CycleStats,
        max_iters: u32,
        tolerance: f32,
    ) -> Result<FcgReport, GpuError> {
        let mut wu = first.work_units;
        let mut history = vec![first.residual];
        let mut residual = first.residual;
        let mut iterations = 0;
        while residual > tolerance && iterations < max_iters {
            match self.fcg_iterate()? {
                Some(s) => {
                    wu += s.work_units;
                    residual = s.residual;
                    history.push(residual);
                    iterations += 1;
                }
                None => break,
            }
        }
        Ok(FcgReport {
            stats: CycleStats {
                work_units: wu,
                residual,
            },
            iterations,
            history,
        })
    }

    /// Starts FCG from the current `h` (`cpu::Fcg::start`): `r = f - A h`, `z = M r`, `p = z`. Returns
    /// the work units and the normalised residual of `h`.
    pub fn fcg_start(&mut self) -> Result<CycleStats, GpuError> {
        self.require_problem()?;
        let ctx = self.ctx.clone();
        let rmax = ctx.checked("multigrid.fcg.start", || {
            self.ctx.queue.write_buffer(
                &self.bufs.scalars,
                0,
                bytemuck::bytes_of(&Scalars::default()),
            );
            self.ctx.count_up(std::mem::size_of::<Scalars>() as u64);
            self.submit(&self.plans.fcg_init, "multigrid.fcg.start");
            Ok(self.read_status()?.0)
        })?;
        self.fcg_state = FcgState::Started;
        Ok(CycleStats {
            work_units: plan::work_units(&self.plans.fcg_init),
            residual: rmax * self.residual_scale(),
        })
    }

    /// [`Self::fcg_start`] after a local relaxation of `h` (as the CPU's `Fcg::relax_at_residuals`
    /// before its start): `sweeps` red-black sweeps in the windows of radius `RADIUS` around the
    /// cells whose normalised residual exceeds `threshold`, unless they cover more than a quarter
    /// of the level. One submission; the window count comes back with FCG's status (4 bytes more).
    /// The work units include the relaxation's, counted as on the CPU (cells swept / level-0
    /// cells).
    pub fn fcg_start_relaxed(
        &mut self,
        threshold: f32,
        sweeps: usize,
    ) -> Result<CycleStats, GpuError> {
        let (rmax, relaxed) = self.relax_and_read(&self.plans.fcg_init, threshold, sweeps)?;
        self.fcg_state = FcgState::Started;
        Ok(CycleStats {
            work_units: relaxed + plan::work_units(&self.plans.fcg_init),
            residual: rmax * self.residual_scale(),
        })
    }

    /// Runs a [`plan::local_relaxation`] of `sweeps` sweeps with seed `threshold`, then `then`
    /// (which starts with the residual and its status copy), in one submission; returns the
    /// residual's `rmax` and the relaxation's work units.
    fn relax_and_read(
        &self,
        then: &[Step],
        threshold: f32,
        sweeps: usize,
    ) -> Result<(f32, f64), GpuError> {
        self.require_problem()?;
        let ctx = self.ctx.clone();
        let scalars = Scalars {
            relax_limit: threshold / self.residual_scale(),
            ..Scalars::default()
        };
        let (rmax, cells) = ctx.checked("multigrid.fcg.start", || {
            self.ctx
                .queue
                .write_buffer(&self.bufs.scalars, 0, bytemuck::bytes_of(&scalars));
            self.ctx.count_up(std::mem::size_of::<Scalars>() as u64);
            let relax = plan::local_relaxation(sweeps);
            self.submit_all(&[&relax, then], "multigrid.fcg.start_relaxed");
            let [rmax, _, cells, groups] = self.read_words::<4>()?;
            self.ctx.count_moved(self.relax_bytes(groups, sweeps));
            Ok((f32::from_bits(rmax), cells as usize))
        })?;
        let n2 = self.n * self.n;
        let relaxed = if cells * 4 > n2 {
            0.0
        } else {
            (cells * sweeps) as f64 / n2 as f64
        };
        Ok((rmax, relaxed))
    }

    /// One FCG iteration after [`Self::fcg_start`]: (from the second on) `z = M r`, `beta`, `p = z + beta p`;
    /// then `q = A p` (recomputed where read, never stored), `alpha`, `h += alpha p`, `r -= alpha q`.
    /// Returns the work units and the normalised residual after it, or `None` when it cannot proceed
    /// (`p.q <= 0`: converged exactly), like `cpu::Fcg::iterate`. (The CPU preconditions at the end of an iteration, the GPU at the start of the
    /// next one; a run stopped by the tolerance counts the same work units.)
    pub fn fcg_iterate(&mut self) -> Result<Option<CycleStats>, GpuError> {
        self.require_problem()?;
        let steps = match self.fcg_state {
            FcgState::Idle => {
                return Err(GpuError::ProblemMismatch(
                    "fcg_iterate before fcg_start".into(),
                ));
            }
            FcgState::Started => &self.plans.fcg_first,
            FcgState::Iterating => &self.plans.fcg_next,
        };
        let ctx = self.ctx.clone();
        let (rmax, status) = ctx.checked("multigrid.fcg.iteration", || {
            self.submit(steps, "multigrid.fcg.iteration");
            self.read_status()
        })?;
        let work_units = plan::work_units(steps);
        self.fcg_state = FcgState::Iterating;
        if status != 0 {
            return Ok(None);
        }
        Ok(Some(CycleStats {
            work_units,
            residual: rmax * self.residual_scale(),
        }))
    }

    /// Normalised residual `max |f - A h| / ((2 ax + 2 ay) relief)` of the current `h` (uses `r` as
    /// scratch: a running FCG must be restarted with [`Self::fcg_start`]).
    pub fn residual(&mut self) -> Result<f32, GpuError> {
        self.require_problem()?;
        self.fcg_state = FcgState::Idle;
        self.ctx.checked("multigrid.residual", || {
            self.submit(&self.plans.residual, "multigrid.residual");
            Ok(self.read_status()?.0 * self.residual_scale())
        })
    }

    /// The level-0 solution `h` (row 0 = south).
    pub fn read_solution(&self) -> Result<Vec<f32>, GpuError> {
        self.read_level(0)
    }

    /// Level-k unknowns (k = 0: `h`; k >= 1: `u_k`), row 0 = south.
    pub fn read_level(&self, k: usize) -> Result<Vec<f32>, GpuError> {
        if let (0, HStore::Texture { texture, .. }) = (k, &self.bufs.h) {
            return self.ctx.checked("multigrid.read_level", || {
                readback::read_texture_r32(&self.ctx, texture, 0, self.n as u32, "h")
            });
        }
        let (buf, first) = match (k, self.bufs.h.buffer()) {
            (0, Some(h)) => (&h.buffer, h.first_f32()),
            (k, _) if k >= 1 && k < self.levels() => {
                (&self.bufs.u[k - 1].buffer, self.bufs.u[k - 1].first_f32())
            }
            _ => {
                return Err(GpuError::BadLevel {
                    level: k,
                    levels: self.levels(),
                });
            }
        };
        let side = (self.n >> k) as u64;
        self.ctx.checked("multigrid.read_level", || {
            readback::read_f32(&self.ctx, buf, first, side * side, "level unknowns")
        })
    }

    /// Level-k right-hand side (k = 0: `f`; k >= 1: `f_k` as last used by a cycle or FMG).
    pub fn read_rhs(&self, k: usize) -> Result<Vec<f32>, GpuError> {
        let (buf, first) = match k {
            0 => (&self.bufs.f.buffer, self.bufs.f.first_f32()),
            k if k < self.levels() => {
                (&self.bufs.fc[k - 1].buffer, self.bufs.fc[k - 1].first_f32())
            }
            _ => {
                return Err(GpuError::BadLevel {
                    level: k,
                    levels: self.levels(),
                });
            }
        };
        let side = (self.n >> k) as u64;
        self.ctx.checked("multigrid.read_rhs", || {
            readback::read_f32(&self.ctx, buf, first, side * side, "right-hand side")
        })
    }

    /// The level-0 diagonal (0 on hard cells) as assembled on the GPU.
    pub fn read_diag(&self) -> Result<Vec<f32>, GpuError> {
        let cells = (self.n * self.n) as u64;
        self.ctx.checked("multigrid.read_diag", || {
            readback::read_f32(
                &self.ctx,
                &self.bufs.diag.buffer,
                self.bufs.diag.first_f32(),
                cells,
                "diag",
            )
        })
    }

    /// The Galerkin stencils of level `k >= 1`, `c[(oy + 1) * 3 + (ox + 1)]`: for `k >= 2` decoded
    /// from the records the GPU keeps ([`unpack_stencils`]); level 1's, which nothing stores, as the
    /// level-1 passes compute them from the level-0 diagonal (`stencils_level1.wgsl` writes them
    /// out; all zero for an inactive cell; an error if the centre-only activity test the
    /// prolongation uses disagrees with the full evaluation somewhere).
    pub fn read_stencils(&self, k: usize) -> Result<Vec<[f32; 9]>, GpuError> {
        if k == 0 || k >= self.levels() {
            return Err(GpuError::BadLevel {
                level: k,
                levels: self.levels(),
            });
        }
        if k == 1 {
            return self.read_level1_stencils();
        }
        let side = (self.n >> k) as u64;
        let bytes = self.ctx.checked("multigrid.read_stencils", || {
            readback::read_bytes(
                &self.ctx,
                &self.bufs.stencil[k - 2],
                0,
                side * side * STENCIL_BYTES,
                "stencils",
            )
        })?;
        let words: Vec<u32> = bytes
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        Ok(unpack_stencils(&words))
    }

    fn read_level1_stencils(&self) -> Result<Vec<[f32; 9]>, GpuError> {
        let side = self.n / 2;
        let values = (10 * side * side) as u64;
        let ctx = &self.ctx;
        let flat = ctx.checked("multigrid.read_stencils.l1", || {
            let out = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("multigrid.stencils_level1"),
                size: 4 * values,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let pipelines = Pipelines::new(ctx, &[Kernel::StencilsLevel1]);
            let spec = PassSpec {
                key: (),
                kernel: Kernel::StencilsLevel1,
                params: Params {
                    n: side as u32,
                    ax: self.ax,
                    ay: self.ay,
                    threshold: INACTIVE_REL * (2.0 * self.ax + 2.0 * self.ay),
                    ..Params::default()
                },
                resources: vec![Res::Slice(&self.bufs.diag), Res::Buffer(&out)],
                workgroups: plan::groups_2d(side, side),
                label: "multigrid.stencils_level1".into(),
            };
            let table = PassTable::new(ctx, &pipelines, "multigrid.stencils_level1", vec![spec]);
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("multigrid.stencils_level1"),
                });
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("multigrid.stencils_level1"),
                    timestamp_writes: None,
                });
                table.dispatch(&pipelines, &mut pass, &());
            }
            ctx.submit([enc.finish()]);
            readback::read_f32(ctx, &out, 0, values, "level-1 stencils")
        })?;
        if let Some(cell) = flat
            .chunks_exact(10)
            .position(|c| (c[4] != 0.0) != (c[9] != 0.0))
        {
            return Err(GpuError::ProblemMismatch(format!(
                "level-1 cell {cell}: the centre-only activity test disagrees with the stencil"
            )));
        }
        Ok(flat
            .chunks_exact(10)
            .map(|c| std::array::from_fn(|k| c[k]))
            .collect())
    }

    /// Estimated bytes of a local relaxation's `sweeps` sweeps whose colour passes ran `groups`
    /// workgroups each (over the windows' box): the whole-level estimate of a colour pass
    /// scaled by the share of its workgroups that ran.
    fn relax_bytes(&self, groups: u32, sweeps: usize) -> u64 {
        let [x, y, _] = Op::RelaxLevel0 { colour: 0 }.workgroups(self.n);
        let full = (x as u64 * y as u64).max(1);
        (0..2)
            .map(|colour| {
                let bytes = self.table.bytes_moved(&Op::RelaxLevel0 { colour });
                (bytes as u128 * groups.min(x * y) as u128 / full as u128) as u64
            })
            .sum::<u64>()
            * sweeps as u64
    }

    fn residual_scale(&self) -> f32 {
        1.0 / ((2.0 * self.ax + 2.0 * self.ay) * self.relief)
    }

    fn read_status(&self) -> Result<(f32, u32), GpuError> {
        let [rmax, status] = self.read_words::<2>()?;
        Ok((f32::from_bits(rmax), status))
    }

    /// The first `N` words of the status staging buffer: `rmax`, `status` (`STATUS_BYTES`), then
    /// `relax_cells` after a local relaxation.
    fn read_words<const N: usize>(&self) -> Result<[u32; N], GpuError> {
        const { assert!(4 * N as u64 <= STATUS_STAGING_BYTES) };
        const { assert!(4 * N as u64 >= STATUS_BYTES) };
        let size = 4 * N as u64;
        let bytes = readback::map_read(&self.ctx, &self.status, size, "multigrid.status")?;
        Ok(words_of(&bytes))
    }

    fn submit(&self, steps: &[Step], label: &str) {
        self.submit_all(&[steps], label);
    }

    /// Encodes `plans` one after the other into one command buffer and submits it.
    fn submit_all(&self, plans: &[&[Step]], label: &str) {
        let mut enc = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
        for steps in plans {
            self.encode(&mut enc, steps, label);
        }
        self.ctx.submit([enc.finish()]);
    }

    /// Records `op`, from the gate's table for the gate passes.
    fn dispatch(&self, pass: &mut wgpu::ComputePass<'_>, op: &Op) {
        match op {
            Op::Gate { .. } => self.gate.table.dispatch(&self.pipelines, pass, op),
            _ => self.table.dispatch(&self.pipelines, pass, op),
        }
    }

    /// Encodes a plan: runs of dispatches share one compute pass; clears and copies go between passes.
    fn encode(&self, enc: &mut wgpu::CommandEncoder, steps: &[Step], label: &str) {
        let mut i = 0;
        while i < steps.len() {
            match steps[i] {
                Step::ClearU { level } => {
                    self.bufs.u[level - 1].clear(enc);
                    i += 1;
                }
                Step::ClearZ => {
                    self.bufs.z.clear(enc);
                    i += 1;
                }
                Step::CopyStatus => {
                    enc.copy_buffer_to_buffer(&self.bufs.scalars, 0, &self.status, 0, STATUS_BYTES);
                    i += 1;
                }
                // Runs of dispatches, gated or not, share one compute pass.
                Step::Dispatch(_) | Step::Gated(_) => {
                    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some(label),
                        timestamp_writes: None,
                    });
                    while let Some(Step::Gated(op) | Step::Dispatch(op)) = steps.get(i) {
                        match steps[i] {
                            Step::Gated(_) if !matches!(op, Op::Gate { .. }) => {
                                self.table.dispatch_indirect(
                                    &self.pipelines,
                                    &mut pass,
                                    op,
                                    &self.gate.args,
                                    self.gate.offset(*op, self.n),
                                )
                            }
                            // Over the windows' box only (`relax_mask` mode 2 wrote its size).
                            Step::Dispatch(Op::RelaxLevel0 { .. }) => self.table.dispatch_indirect(
                                &self.pipelines,
                                &mut pass,
                                op,
                                &self.bufs.relax_box,
                                RELAX_ARGS_OFFSET,
                            ),
                            _ => self.dispatch(&mut pass, op),
                        }
                        i += 1;
                    }
                }
                Step::CopyScalars => {
                    enc.copy_buffer_to_buffer(
                        &self.bufs.scalars,
                        0,
                        &self.status,
                        0,
                        STATUS_STAGING_BYTES,
                    );
                    i += 1;
                }
                Step::CopyRelaxCells => {
                    enc.copy_buffer_to_buffer(
                        &self.bufs.scalars,
                        RELAX_CELLS_OFFSET,
                        &self.status,
                        STATUS_BYTES,
                        4,
                    );
                    enc.copy_buffer_to_buffer(
                        &self.bufs.scalars,
                        RELAX_GROUPS_OFFSET,
                        &self.status,
                        STATUS_BYTES + 4,
                        4,
                    );
                    i += 1;
                }
            }
        }
    }
}

/// Bytes of the status staging buffer: `rmax`, `status` (the [`STATUS_BYTES`] read per FCG
/// iteration), `relax_cells` (read after a local relaxation), padding.
/// The first `N` little-endian words of `bytes` (which holds at least `4 N`).
fn words_of<const N: usize>(bytes: &[u8]) -> [u32; N] {
    std::array::from_fn(|i| {
        u32::from_le_bytes([
            bytes[4 * i],
            bytes[4 * i + 1],
            bytes[4 * i + 2],
            bytes[4 * i + 3],
        ])
    })
}

const STATUS_STAGING_BYTES: u64 = std::mem::size_of::<Scalars>() as u64;

/// Bytes of one queued run's report (its scalar block).
pub const QUEUED_REPORT_BYTES: u64 = STATUS_STAGING_BYTES;

/// The 9-point stencils `c[(oy + 1) * 3 + (ox + 1)]` from the records of
/// `shaders/shared/stencil.wgsl` (`STENCIL_WORDS` words per cell), decoded as the passes decode
/// them: the off-centre coefficients are 16-bit snorm (`unpack2x16snorm`) times the cell's scale,
/// the centre is the row sum minus them.
pub fn unpack_stencils(words: &[u32]) -> Vec<[f32; 9]> {
    words
        .chunks_exact(STENCIL_WORDS)
        .map(|w| {
            let scale = f32::from_bits(w[5]);
            let pair = |x: u32| [x as u16, (x >> 16) as u16].map(|h| snorm(h) * scale);
            let ([c0, c1], [c2, c3]) = (pair(w[0]), pair(w[1]));
            let ([c5, c6], [c7, c8]) = (pair(w[2]), pair(w[3]));
            let off = ((c0 + c1) + (c2 + c3)) + ((c5 + c6) + (c7 + c8));
            [c0, c1, c2, c3, f32::from_bits(w[4]) - off, c5, c6, c7, c8]
        })
        .collect()
}

/// `unpack2x16snorm` of one half: `max(v / 32767, -1)` for the 16 bits `v` as a signed integer.
fn snorm(v: u16) -> f32 {
    (f32::from(v as i16) / 32767.0).max(-1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The record `st_record` writes, in Rust (`pack2x16snorm`: `round(32767 clamp(v, -1, 1))`).
    fn pack(c: [f32; 9]) -> [u32; STENCIL_WORDS] {
        let off = [c[0], c[1], c[2], c[3], c[5], c[6], c[7], c[8]];
        let scale = off.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        let sum = c[4] + (((c[0] + c[1]) + (c[2] + c[3])) + ((c[5] + c[6]) + (c[7] + c[8])));
        let inv = if scale > 0.0 { 1.0 / scale } else { 0.0 };
        let h = |v: f32| u32::from(((v * inv).clamp(-1.0, 1.0) * 32767.0).round() as i16 as u16);
        let pair = |a: f32, b: f32| h(a) | h(b) << 16;
        [
            pair(c[0], c[1]),
            pair(c[2], c[3]),
            pair(c[5], c[6]),
            pair(c[7], c[8]),
            sum.to_bits(),
            scale.to_bits(),
        ]
    }

    /// Decoded stencils keep their row sums to f32 rounding and move each off-centre coefficient
    /// by at most 1 / 65534 of the row's largest (the largest itself comes back exactly); an
    /// all-zero record (inactive cell) decodes to an exactly zero centre.
    #[test]
    fn records_keep_row_sums_and_round_coefficients_to_snorm16() {
        let rows: [[f32; 9]; 4] = [
            [
                -0.0625, -0.375, -0.0625, -0.375, 2.5625, -0.375, -0.0625, -0.375, -0.0625,
            ],
            [
                -0.1, -0.2, 0.013, -0.31, 3996.7, -1.7e-3, -0.29, -0.33, -0.07,
            ],
            [
                -1.3e-5, -2.2e-5, -0.9e-5, -3.1e-5, 1.5e-4, -3.3e-5, -2.9e-5, -3.0e-5, -1.1e-5,
            ],
            [-7.0, -0.1, 0.0, -6.9, 31.0, -6.95, -0.12, -7.01, -0.05],
        ];
        for c in rows {
            let d = unpack_stencils(&pack(c))[0];
            let scale = [c[0], c[1], c[2], c[3], c[5], c[6], c[7], c[8]]
                .iter()
                .fold(0.0f32, |m, v| m.max(v.abs()));
            for k in (0..9).filter(|&k| k != 4) {
                assert!(
                    (d[k] - c[k]).abs() <= scale / 65534.0 * 1.001,
                    "{c:?}: coefficient {k} {} -> {}",
                    c[k],
                    d[k]
                );
            }
            let sum = |s: &[f32; 9]| s.iter().map(|&v| f64::from(v)).sum::<f64>();
            let rel = (sum(&d) - sum(&c)).abs() / f64::from(c[4]);
            assert!(
                rel <= 1e-6,
                "{c:?}: row sum moved by {rel:.1e} of the centre"
            );
        }
        let exact = [0.0, -0.375, 0.0, -0.375, 1.5, -0.375, 0.0, -0.375, 0.0];
        assert_eq!(unpack_stencils(&pack(exact))[0], exact);
        assert_eq!(snorm(0x8000), -1.0);
        assert_eq!(snorm(0x7fff), 1.0);
        assert_eq!(unpack_stencils(&[0; STENCIL_WORDS])[0][4], 0.0);
        assert_eq!(unpack_stencils(&[0; 3 * STENCIL_WORDS]).len(), 3);
    }
}
