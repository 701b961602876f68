//! The GPU solver as the editor steps it, on the editor's device (its height texture is drawn
//! directly). The same rule as the CPU engine (`terrain_cpu`): the newest sketch is taken only once
//! what is shown for the previous one had a global correction (an FCG iteration after the warm
//! start's local relaxation) or converged, and a frame with an edit runs until that holds, within its
//! cap.

use terrasketch_multigrid::SolverParams;
use terrasketch_multigrid::gpu::{GpuCounters, GpuError};
use terrasketch_multigrid::gpu_solver::GpuSolver;
use terrasketch_sketch::Sketch;

use super::budget::Meter;
use super::terrain::HeightField;
use super::terrain_cpu::{FrameWork, POLISH_TOLERANCE};

/// FCG iterations of the idle refinement on the GPU (f32 round-off can stop short of 1e-6).
const GPU_POLISH_ITERS: u32 = 40;

/// The GPU solver and its stepping state.
pub struct GpuEngine {
    /// The solver.
    pub solver: GpuSolver,
    /// The sketch the solver has taken (`None`: nothing yet, or replaced: the next start is cold).
    applied: Option<Sketch>,
    /// What is shown for `applied` had a global correction (see the module doc).
    coherent: bool,
    /// Converged for `applied` at the normal tolerance.
    done: bool,
    /// FCG iterations of the idle refinement so far.
    polish_iters: u32,
    /// The idle refinement is done.
    polished: bool,
    /// The picking copy (`Terrain::field`), refreshed when the terrain settles.
    pub pick: Option<HeightField>,
    /// Version of the heights the picking copy was read at.
    pub pick_version: u64,
    /// The device counters at the start of the frame.
    pub counters_mark: GpuCounters,
}

/// What a GPU frame did.
#[derive(Debug, Clone, Copy, Default)]
pub struct GpuFrame {
    /// The work done.
    pub work: FrameWork,
    /// The heights changed (the mips and bounds were rebuilt).
    pub published: bool,
}

impl GpuEngine {
    /// The engine around `solver` (nothing taken yet).
    pub fn new(solver: GpuSolver) -> GpuEngine {
        GpuEngine {
            counters_mark: solver.context().counters(),
            solver,
            applied: None,
            coherent: false,
            done: false,
            polish_iters: 0,
            polished: false,
            pick: None,
            pick_version: u64::MAX,
        }
    }

    /// The next start is cold (the whole sketch was replaced).
    pub fn restart(&mut self) {
        self.applied = None;
        self.done = false;
        self.polished = false;
    }

    /// True once any sketch was taken (mip 0 holds heights).
    pub fn ready(&self) -> bool {
        self.applied.is_some()
    }

    /// True when converged for `sketch`.
    pub fn converged_for(&self, sketch: &Sketch) -> bool {
        self.done && self.applied.as_ref() == Some(sketch)
    }

    /// True when converged for `sketch` and the idle refinement is done.
    pub fn settled_for(&self, sketch: &Sketch) -> bool {
        self.converged_for(sketch) && self.polished
    }

    /// One frame of solver work for `sketch`; `edited` if an edit arrived this frame.
    pub fn step(
        &mut self,
        sketch: &Sketch,
        meter: &mut Meter,
        edited: bool,
    ) -> Result<GpuFrame, GpuError> {
        let settling = !edited;
        let cells = self.solver.grid().n * self.solver.grid().n;
        let tolerance = SolverParams::default().tolerance;
        let mut frame = GpuFrame::default();
        if self.converged_for(sketch) {
            return self.polish(meter);
        }
        loop {
            let stale = self.applied.as_ref() != Some(sketch);
            if stale && (self.applied.is_none() || self.coherent || self.done) {
                let cold = self.applied.is_none() || sketch.strokes.is_empty();
                let b = self.solver.begin(sketch, cold)?;
                meter.add(b.work_units + b.field_work_units, cells);
                frame.work.height_wu += b.work_units;
                frame.work.field_wu += b.field_work_units;
                frame.published = true;
                self.applied = Some(sketch.clone());
                // A cold start ran FMG: a global solution.
                self.coherent = cold;
                self.done = false;
                self.polish_iters = 0;
                self.polished = false;
            }
            if self.solver.residual() <= tolerance {
                self.done = true;
                self.coherent = true;
            }
            if self.done {
                if self.applied.as_ref() == Some(sketch) {
                    break;
                }
                continue;
            }
            match self.solver.iterate()? {
                Some(wu) => {
                    meter.add(wu, cells);
                    frame.work.height_wu += wu;
                    frame.work.vcycles += 1;
                    frame.published = true;
                    self.coherent = true;
                }
                // Converged exactly (or nothing begun): nothing more to do for this sketch.
                None => {
                    self.done = true;
                    self.coherent = true;
                }
            }
            if self.solver.residual() <= tolerance {
                self.done = true;
            }
            if meter.cap_reached(settling) || (!settling && self.coherent && meter.budget_spent()) {
                break;
            }
        }
        Ok(frame)
    }

    /// The idle refinement after convergence: FCG iterations towards `POLISH_TOLERANCE` for one
    /// budget a frame, at most `GPU_POLISH_ITERS` in all.
    fn polish(&mut self, meter: &mut Meter) -> Result<GpuFrame, GpuError> {
        let mut frame = GpuFrame::default();
        let cells = self.solver.grid().n * self.solver.grid().n;
        while !self.polished {
            if self.solver.residual() <= POLISH_TOLERANCE || self.polish_iters >= GPU_POLISH_ITERS {
                self.polished = true;
                break;
            }
            match self.solver.iterate()? {
                Some(wu) => {
                    meter.add(wu, cells);
                    frame.work.height_wu += wu;
                    frame.work.vcycles += 1;
                    frame.published = true;
                    self.polish_iters += 1;
                }
                None => self.polished = true,
            }
            if meter.budget_spent() {
                break;
            }
        }
        Ok(frame)
    }
}
