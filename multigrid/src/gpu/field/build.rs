//! Making a [`GpuFieldSolver`]: its constructors and the one builder they share.

use super::*;

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

    pub(super) fn guest(
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

    pub(super) fn build(
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
                .filter(|op| op.alt_level().is_none_or(|k| k <= bufs.alt.len()))
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
                relief_on_gpu: false,
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
                spike_seen: [0; 3],
                pending: std::sync::Mutex::new(None),
            })
        })
    }
}
