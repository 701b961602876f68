//! [`GpuFieldSolver`]: the GPU twin of `cpu::Hierarchy` + one `cpu::FieldState`.

use super::kernels::{PassSpec, PassTable, Pipelines, Res};
use super::params::{
    INACTIVE_REL, Params, RELAX_CELLS_OFFSET, RELAX_GROUPS_OFFSET, SPIKE_CELLS, SPIKE_GROUPS,
    SPIKE_RUNS, SPIKE_WORDS, STAGE_R, STAGE_Z, STATUS_BYTES, STENCIL_BYTES, STENCIL_WORDS, Scalars,
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
use plans::{Gate, Plans};
use wgpu::util::DeviceExt;

mod build;
mod encode;
mod plans;
mod queued;
mod reads;
#[cfg(test)]
mod tests;

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
    /// The relief of the assembled problem is computed on the GPU and not known here yet: the
    /// next report read ([`Self::report_of`]) carries it.
    relief_on_gpu: bool,
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
    /// The stop-test relaxation's words (cells, tile workgroups, runs) of the scalar block as last
    /// counted: the CPU-driven iterations count what is beyond them (a write of the block resets
    /// them to 0).
    spike_seen: [u32; 3],
    /// The status staging buffer's requested mapping ([`Self::request_report`]).
    pending: std::sync::Mutex<Option<readback::MapPending>>,
}

/// A queued FCG run ([`GpuFieldSolver::queue_fcg_relaxed`]); kept with a report that is read
/// after a later run was queued ([`GpuFieldSolver::earlier_report`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Queued {
    sweeps: usize,
    /// Gated iterations queued so far.
    iterations: u32,
    /// FCG's start was queued (else only the relaxation).
    start: bool,
    /// The relaxation's bytes were counted (by the first report of the run).
    relax_counted: bool,
    /// The first direction's bytes were counted.
    direction_counted: bool,
    /// Gated iterations whose bytes were counted: by a report that shows them run, or when queued
    /// for the editor, whose iteration reports carry only the residual (an upper bound).
    iterations_counted: u32,
    /// Stop-test relaxations (runs, tile workgroups) whose bytes were counted.
    spikes_counted: [u32; 2],
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

impl GpuFieldSolver {
    /// Cells per side of level 0.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Levels including level 0 (the coarsest has side 8).
    pub fn levels(&self) -> usize {
        self.shape.levels
    }

    /// Relief of the last uploaded problem (normalises residuals). For a problem whose relief the
    /// GPU computes (`assemble_on_gpu` without one), known once a report of its run is read.
    pub fn relief(&self) -> f32 {
        self.relief
    }

    /// The axis weights `[ax, ay]` (`dy / dx`, `dx / dy`).
    pub(crate) fn axis_weights(&self) -> [f32; 2] {
        [self.ax, self.ay]
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
    /// the residuals from now on; `None`: the GPU computes it, and the runs queued on this problem
    /// must scale their limits on the GPU ([`Self::queue_fcg_relaxed`]'s `relief_pass`).
    pub(crate) fn assemble_on_gpu(
        &mut self,
        relief: Option<f32>,
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
        if let Some(r) = relief {
            self.relief = r.max(1.0);
        }
        self.relief_on_gpu = relief.is_none();
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
        self.relief_on_gpu = false;
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
        self.spike_seen = [0; 3];
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

    /// FCG iterations after a start that left `first` until the residual meets `tolerance` or
    /// `max_iters` iterations ran.
    fn iterate_from(
        &mut self,
        first: CycleStats,
        max_iters: u32,
        tolerance: f32,
    ) -> Result<FcgReport, GpuError> {
        if first.residual > tolerance && max_iters > 0 {
            self.set_stop(tolerance)?;
        }
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
        self.require_known_relief()?;
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
        self.spike_seen = [0; 3];
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
        self.spike_seen = [0; 3];
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
        self.require_known_relief()?;
        let ctx = self.ctx.clone();
        let scalars = Scalars {
            relax_limit: threshold * self.rmax_per_residual(),
            relief: self.relief,
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
            self.ctx
                .count_moved(&self.relax_bytes(groups, sweeps, false));
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
        let [rmax, status, cells, groups, runs] = ctx.checked("multigrid.fcg.iteration", || {
            self.submit(steps, "multigrid.fcg.iteration");
            self.read_words::<5>()
        })?;
        let rmax = f32::from_bits(rmax);
        let work_units = plan::work_units(steps) + self.count_spikes([cells, groups, runs]);
        self.fcg_state = FcgState::Iterating;
        if status != 0 {
            return Ok(None);
        }
        Ok(Some(CycleStats {
            work_units,
            residual: rmax * self.residual_scale(),
        }))
    }

    /// Stop-test relaxations counted since the scalar block was last written (tests).
    #[doc(hidden)]
    pub fn spike_runs(&self) -> u32 {
        self.spike_seen[2]
    }

    /// The tolerance the stop-test relaxation of FCG iterations driven by the CPU
    /// ([`Self::fcg_iterate`]) works to: `stop_rmax` in the scalar block (a start writes 0, which
    /// never runs it). The CPU's FCG relaxes at its own tolerance, so loops set theirs first.
    pub fn set_stop(&mut self, tolerance: f32) -> Result<(), GpuError> {
        self.require_known_relief()?;
        let stop = tolerance * self.rmax_per_residual();
        self.ctx.queue.write_buffer(
            &self.bufs.scalars,
            std::mem::offset_of!(Scalars, stop_rmax) as u64,
            bytemuck::bytes_of(&stop),
        );
        self.ctx.count_up(4);
        Ok(())
    }

    /// The work units of the stop-test relaxations beyond those counted before (`spike_seen`)
    /// by their counts `now` (cells, tile workgroups, runs), whose bytes it counts.
    fn count_spikes(&mut self, now: [u32; 3]) -> f64 {
        let [cells, groups, runs] =
            std::array::from_fn(|k| now[k].saturating_sub(self.spike_seen[k]));
        self.spike_seen = now;
        self.ctx.count_moved(&self.spike_bytes(runs, groups));
        self.spike_work_units(cells)
    }

    /// Bytes of `runs` stop-test relaxations whose tile passes ran `groups` workgroups in all.
    fn spike_bytes(&self, runs: u32, groups: u32) -> Vec<(Kernel, u64)> {
        let mut out: Vec<(Kernel, u64)> = (0..runs)
            .flat_map(|_| self.gate.spike_bytes.iter().copied())
            .collect();
        out.extend(self.relax_bytes(groups, crate::cycle::SPIKE_SWEEPS, true));
        out
    }

    /// Work units of stop-test relaxations over `cells` window cells (as the CPU counts them).
    fn spike_work_units(&self, cells: u32) -> f64 {
        (cells as usize * crate::cycle::SPIKE_SWEEPS) as f64 / (self.n * self.n) as f64
    }

    /// `max |r|` of the current `r`, normalised as an FCG iteration reports it, recounted by the
    /// reduction passes alone (`DotPartial` and `DotFinal` of `STAGE_R`): tests check it against the
    /// one `FcgUpdate` reduces as it writes `r`. Rewrites `rmax` only, with that same value.
    #[doc(hidden)]
    pub fn recount_residual(&mut self) -> Result<f32, GpuError> {
        self.require_problem()?;
        let steps = [
            Step::Dispatch(Op::DotPartial { stage: STAGE_R }),
            Step::Dispatch(Op::DotFinal { stage: STAGE_R }),
            Step::CopyStatus,
        ];
        let ctx = self.ctx.clone();
        ctx.checked("multigrid.recount_residual", || {
            self.submit(&steps, "multigrid.recount_residual");
            Ok(self.read_status()?.0 * self.residual_scale())
        })
    }

    /// `r.z` in the scalar block, then `r.z` recounted with `z.q` by the reduction passes of
    /// `STAGE_Z`: tests check that FCG's first direction, which reduces `r.z` alone, leaves the same
    /// value. Rewrites `zq` and `beta` (which an iteration right after the first direction does not
    /// read) and `rz` (with the recounted value).
    #[doc(hidden)]
    pub fn recount_rz(&mut self) -> Result<(f32, f32), GpuError> {
        self.require_problem()?;
        let recount = [
            Step::Dispatch(Op::DotPartial { stage: STAGE_Z }),
            Step::Dispatch(Op::DotFinal { stage: STAGE_Z }),
            Step::CopyScalars,
        ];
        let ctx = self.ctx.clone();
        ctx.checked("multigrid.recount_rz", || {
            self.submit(&[Step::CopyScalars], "multigrid.recount_rz");
            let before = self.read_words::<16>()?[2];
            self.submit(&recount, "multigrid.recount_rz");
            let after = self.read_words::<16>()?[2];
            Ok((f32::from_bits(before), f32::from_bits(after)))
        })
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

    /// Estimated bytes of a local relaxation of `sweeps` sweeps whose tile passes ran `groups`
    /// workgroups each (over the windows' box): the whole-level estimate of each pass scaled by
    /// the share of its workgroups that ran.
    fn relax_bytes(&self, groups: u32, sweeps: usize, spike: bool) -> Vec<(Kernel, u64)> {
        let [x, y, _] = Op::SpikeUpdate.workgroups(self.n);
        let full = (x as u64 * y as u64).max(1);
        let ops = if spike {
            vec![
                Op::SpikeRelax {
                    sweeps: sweeps as u32,
                },
                Op::SpikeUpdate,
            ]
        } else {
            plan::relax_tiles(sweeps)
        };
        ops.into_iter()
            .filter_map(|op| self.table.bytes_moved(&op))
            .map(|(k, bytes)| {
                (
                    k,
                    (bytes as u128 * groups.min(x * y) as u128 / full as u128) as u64,
                )
            })
            .collect()
    }

    fn residual_scale(&self) -> f32 {
        1.0 / self.rmax_per_residual()
    }

    /// `rmax` per unit of normalised residual, `(2 ax + 2 ay) relief`: the limits the CPU writes
    /// are normalised limits times this (as `relief_scale.wgsl` computes them on the GPU).
    fn rmax_per_residual(&self) -> f32 {
        (2.0 * self.ax + 2.0 * self.ay) * self.relief
    }

    /// The residual scale of a report whose scalar block carries `relief_word` (word 15; 0: none
    /// was written, the solver's own relief applies).
    fn scale_of(&self, relief_word: u32) -> f32 {
        let relief = f32::from_bits(relief_word);
        if relief > 0.0 {
            1.0 / ((2.0 * self.ax + 2.0 * self.ay) * relief)
        } else {
            self.residual_scale()
        }
    }

    /// Takes the relief a report carries (word 15 of the scalar block; 0: none was written).
    fn learn_relief(&mut self, word: u32) {
        let relief = f32::from_bits(word);
        if relief > 0.0 {
            self.relief = relief;
            self.relief_on_gpu = false;
        }
    }

    /// A problem is uploaded and its relief is known on the CPU (runs that write their own
    /// limits need it; those whose relief the GPU computes are queued with their relief pass).
    fn require_known_relief(&self) -> Result<(), GpuError> {
        self.require_problem()?;
        if self.relief_on_gpu {
            return Err(relief_unknown());
        }
        Ok(())
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
}

/// The error of a run that needs the relief on the CPU while the GPU computes it.
fn relief_unknown() -> GpuError {
    GpuError::ProblemMismatch(
        "the problem's relief is computed on the GPU: queue its run with the relief pass".into(),
    )
}

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

/// Bytes of the status staging buffer: `rmax`, `status` (the [`STATUS_BYTES`] read per FCG
/// iteration), `relax_cells` (read after a local relaxation), padding.
const STATUS_STAGING_BYTES: u64 = std::mem::size_of::<Scalars>() as u64;

/// Bytes of one queued run's report (its scalar block).
pub const QUEUED_REPORT_BYTES: u64 = STATUS_STAGING_BYTES;
