//! The GPU solver as the editor steps it, on the editor's device (its height texture is drawn
//! directly), under the same follow rule as the CPU solver (`follow`; [`GpuLive`] is the GPU side of
//! it).

use anyhow::Result;
use terrasketch_multigrid::SolverParams;
use terrasketch_multigrid::gpu::GpuCounters;
use terrasketch_multigrid::gpu_solver::GpuSolver;
use terrasketch_sketch::Sketch;

use super::budget::Meter;
use super::follow::{Follower, FrameWork, LiveSolver, Took, Unit};
use super::heightfield::HeightField;
use super::terrain_cpu::POLISH_TOLERANCE;

/// FCG iterations of the idle refinement on the GPU (f32 round-off can stop short of 1e-6).
const GPU_POLISH_ITERS: u32 = 40;

/// FCG iterations the GPU queues in one frame at most. Nothing waits for them: the device runs
/// them after the frame's encoding, and their residual arrives with a later frame, so queuing
/// more would only run past convergence. Two keep what is shown coherent (one global correction
/// after each take) and converge a drag's small edits within a frame or two.
const GPU_ITERATIONS_PER_FRAME: u32 = 2;

/// The GPU solver under the follow rule: a take is `GpuSolver::take_queued` (rasterisation, field
/// solves, assembly, local relaxation, FCG start, queued without waiting for their reports), a
/// unit of work one queued FCG iteration. Residuals arrive a frame or so late (`GpuSolver::poll`);
/// a frame waits for the device only for the rasteriser's value ranges of a take.
pub struct GpuLive {
    /// The solver.
    pub solver: GpuSolver,
    /// The idle refinement runs (its tolerance is `POLISH_TOLERANCE`).
    polishing: bool,
    /// FCG iterations of the idle refinement so far.
    polish_iters: u32,
    /// A warm take still owes its global correction (one FCG iteration, whatever the residual).
    owes_iteration: bool,
    /// The sketch last taken and whether cold (taken again when a field solve fell short).
    taken: Option<(Sketch, bool)>,
    /// Iterations queued in the current frame.
    queued_this_frame: u32,
}

impl GpuLive {
    fn target(&self) -> f32 {
        if self.polishing {
            POLISH_TOLERANCE
        } else {
            SolverParams::default().tolerance
        }
    }

    /// A new frame: iterations may be queued again.
    pub fn new_frame(&mut self) {
        self.queued_this_frame = 0;
    }
}

impl LiveSolver for GpuLive {
    fn cells(&self) -> usize {
        let n = self.solver.grid().n;
        n * n
    }

    fn take(&mut self, sketch: &Sketch, from: Option<&Sketch>) -> Result<(Took, Unit)> {
        let cold = from.is_none() || sketch.strokes.is_empty();
        let b = self.solver.take_queued(sketch, cold)?;
        self.owes_iteration = !cold;
        self.taken = Some((sketch.clone(), cold));
        let unit = Unit {
            height_wu: b.work_units,
            field_wu: b.field_work_units,
            ..Unit::default()
        };
        Ok((if cold { Took::Cold } else { Took::Warm }, unit))
    }

    fn advance(&mut self) -> Result<Unit> {
        let mut unit = Unit::default();
        let status = self.solver.poll()?;
        unit.field_wu = status.late_field_work_units;
        unit.height_wu = status.late_work_units - status.late_field_work_units;
        if status.retake
            && let Some((sketch, cold)) = self.taken.clone()
        {
            // A field solve needed more iterations than the take queued: the take again, with
            // them (the guess was raised).
            let b = self.solver.take_queued(&sketch, cold)?;
            unit.height_wu += b.work_units;
            unit.field_wu += b.field_work_units;
            self.owes_iteration = !cold;
        }
        if self.queued_this_frame >= GPU_ITERATIONS_PER_FRAME {
            unit.frame_full = true;
            return Ok(unit);
        }
        if self.polishing && self.polish_iters >= GPU_POLISH_ITERS {
            unit.converged = true;
            return Ok(unit);
        }
        if self.solver.residual() > self.target() || std::mem::take(&mut self.owes_iteration) {
            unit.height_wu += self.solver.queue_iterations(1)?;
            unit.vcycles = 1;
            unit.coherent = true;
            self.queued_this_frame += 1;
            self.polish_iters += self.polishing as u32;
        }
        unit.converged = self.solver.residual() <= self.target();
        Ok(unit)
    }

    fn converged(&self) -> bool {
        !self.owes_iteration && self.solver.residual() <= self.target()
    }

    fn level0_ready(&self) -> bool {
        true
    }

    fn begin_polish(&mut self) -> bool {
        self.polishing = true;
        self.polish_iters = 0;
        true
    }

    fn end_polish(&mut self) {
        self.polishing = false;
    }

    fn publish(&mut self) -> Result<()> {
        Ok(self.solver.publish_and_request_min_max()?)
    }
}

/// The GPU solver, its follow state and what the editor reads back from it.
pub struct GpuEngine {
    /// The solver under the follow rule.
    pub live: Follower<GpuLive>,
    /// The picking copy (`Terrain::field`), refreshed when the terrain settles.
    pub pick: Option<HeightField>,
    /// Version of the heights the picking copy was read at.
    pub pick_version: u64,
    /// The device counters at the start of the frame.
    pub counters_mark: GpuCounters,
}

impl GpuEngine {
    /// The engine around `solver` (nothing taken yet).
    pub fn new(solver: GpuSolver) -> GpuEngine {
        GpuEngine {
            counters_mark: solver.context().counters(),
            live: Follower::new(GpuLive {
                solver,
                polishing: false,
                polish_iters: 0,
                owes_iteration: false,
                taken: None,
                queued_this_frame: 0,
            }),
            pick: None,
            pick_version: u64::MAX,
        }
    }

    /// The solver.
    pub fn solver(&self) -> &GpuSolver {
        &self.live.solver.solver
    }

    /// The min/max pyramid requested by the last publish, if the device has delivered it (never
    /// waits: the quadtree's bounds follow the heights a frame or so late).
    pub fn try_min_max(&self) -> Result<Option<Vec<terrasketch_multigrid::pyramid::MinMaxLevel>>> {
        Ok(self.live.solver.solver.try_min_max()?)
    }

    /// One frame of solver work for `sketch`; `edited` if an edit arrived this frame.
    pub fn step(&mut self, sketch: &Sketch, meter: &mut Meter, edited: bool) -> Result<FrameWork> {
        self.live.solver.new_frame();
        if self.live.converged_for(sketch) {
            self.live.polish(meter)
        } else {
            self.live.follow(sketch, meter, !edited)
        }
    }
}
