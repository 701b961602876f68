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

/// The GPU solver under the follow rule: a take is `GpuSolver::begin` (rasterisation, field solves,
/// assembly, local relaxation, FCG start), a unit of work one FCG iteration.
pub struct GpuLive {
    /// The solver.
    pub solver: GpuSolver,
    /// The idle refinement runs (its tolerance is `POLISH_TOLERANCE`).
    polishing: bool,
    /// FCG iterations of the idle refinement so far.
    polish_iters: u32,
    /// A warm take still owes its global correction (one FCG iteration, whatever the residual).
    owes_iteration: bool,
}

impl GpuLive {
    fn target(&self) -> f32 {
        if self.polishing {
            POLISH_TOLERANCE
        } else {
            SolverParams::default().tolerance
        }
    }
}

impl LiveSolver for GpuLive {
    fn cells(&self) -> usize {
        let n = self.solver.grid().n;
        n * n
    }

    fn take(&mut self, sketch: &Sketch, from: Option<&Sketch>) -> Result<(Took, Unit)> {
        let cold = from.is_none() || sketch.strokes.is_empty();
        let b = self.solver.begin(sketch, cold)?;
        self.owes_iteration = !cold;
        let unit = Unit {
            height_wu: b.work_units,
            field_wu: b.field_work_units,
            ..Unit::default()
        };
        Ok((if cold { Took::Cold } else { Took::Warm }, unit))
    }

    fn advance(&mut self) -> Result<Unit> {
        let mut unit = Unit::default();
        if self.solver.residual() > self.target() || std::mem::take(&mut self.owes_iteration) {
            match self.solver.iterate()? {
                Some(wu) => {
                    unit.height_wu = wu;
                    unit.vcycles = 1;
                    unit.coherent = true;
                    self.polish_iters += self.polishing as u32;
                }
                // Converged exactly, or nothing begun: nothing more to do.
                None => unit.converged = true,
            }
        }
        unit.converged |= self.solver.residual() <= self.target()
            || (self.polishing && self.polish_iters >= GPU_POLISH_ITERS);
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
        Ok(self.solver.publish()?)
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
            }),
            pick: None,
            pick_version: u64::MAX,
        }
    }

    /// The solver.
    pub fn solver(&self) -> &GpuSolver {
        &self.live.solver.solver
    }

    /// One frame of solver work for `sketch`; `edited` if an edit arrived this frame.
    pub fn step(&mut self, sketch: &Sketch, meter: &mut Meter, edited: bool) -> Result<FrameWork> {
        if self.live.converged_for(sketch) {
            self.live.polish(meter)
        } else {
            self.live.follow(sketch, meter, !edited)
        }
    }
}
