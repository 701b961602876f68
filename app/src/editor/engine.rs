//! What `Terrain` needs from a solver backend, so that its frame loop and budget policy exist once:
//! [`TerrainSolver`] is implemented by the CPU engine (`terrain_cpu::CpuEngine`: a solver and its
//! twins) and the GPU engine (`terrain_gpu::GpuEngine`). Both follow the sketch by the rule of
//! `follow`; this trait is what the terrain asks of them around it. What a single solver answers
//! the same way on both backends comes through the multigrid crate's [`Solver`].

use anyhow::Result;
use terrasketch_multigrid::Solver;
use terrasketch_multigrid::gpu::GpuCounters;
use terrasketch_multigrid::pyramid;
use terrasketch_sketch::Sketch;

use super::budget::Meter;
use super::follow::FrameWork;
use super::heightfield::HeightField;

/// A min/max level of the heights: side and `[min, max]` per cell (row 0 south).
pub type MinMaxLevel = (usize, Vec<[f32; 2]>);

/// The pyramid's levels as the terrain keeps them.
pub fn min_max_levels(levels: Vec<pyramid::MinMaxLevel>) -> Vec<MinMaxLevel> {
    levels.into_iter().map(|l| (l.side, l.cells)).collect()
}

/// What a backend may update once a frame's step is accounted for (see
/// [`TerrainSolver::after_step`]).
pub struct AfterStep {
    /// Converged and refined for the document's sketch.
    pub settled: bool,
    /// The tool button is held (nothing large is read back meanwhile).
    pub pointer_held: bool,
    /// The heights' version after the step.
    pub version: u64,
}

/// A solver backend as the terrain steps and reads it.
pub trait TerrainSolver {
    /// The solver at the terrain's size.
    fn full_solver(&self) -> &dyn Solver;
    /// The solver that is shown (a CPU twin while it follows edits, else the full one).
    fn shown(&self) -> &dyn Solver;
    /// "gpu" or "cpu".
    fn name(&self) -> &'static str {
        self.full_solver().name()
    }
    /// One frame of solver work for `sketch` within `meter`'s budget and caps; `edited` if an edit
    /// arrived this frame (the edit itself is the difference from the sketch the solver has).
    fn step(&mut self, sketch: &Sketch, meter: &mut Meter, edited: bool) -> Result<FrameWork>;
    /// The whole sketch was replaced: the next sketch is taken cold.
    fn restart(&mut self);
    /// False while there is no progress to report (the GPU solver before its first take).
    fn progress_ready(&self) -> bool;
    /// Converged for `sketch` (what is shown meets the tolerance).
    fn converged_for(&self, sketch: &Sketch) -> bool;
    /// Nothing is left to do for `sketch` (converged, and the idle refinement done).
    fn settled_for(&self, sketch: &Sketch) -> bool;
    /// Which of the backend's solvers is shown (changes when a twin takes over or hands back: the
    /// shown heights change even if no work ran).
    fn shown_solver(&self) -> usize;
    /// Finest mip of the terrain's grid that is ready.
    fn finest_ready(&self) -> Option<u32>;
    /// Residual of the shown solver.
    fn residual(&self) -> f32 {
        self.shown().residual()
    }
    /// Mip `k` of the heights held on the CPU (empty when they live on the device).
    fn mip(&self, k: usize) -> &[f32];
    /// Level-0 heights of the full solver (read back in full from a device: snapshots and
    /// export).
    fn heights(&self) -> Result<Vec<f32>> {
        Ok(self.full_solver().heights()?.into_owned())
    }
    /// The min/max pyramid's levels when new ones are to be shown: after a step that `changed`
    /// the heights, or whenever a device delivers them; `wanted` when the terrain has none yet.
    fn min_max(&mut self, changed: bool, wanted: bool) -> Result<Option<Vec<MinMaxLevel>>>;
    /// Backend upkeep once the step is accounted for (the GPU's picking copy).
    fn after_step(&mut self, _end: &AfterStep) -> Result<()> {
        Ok(())
    }
    /// The copy of the heights used for picking, when the backend keeps one of its own.
    fn pick(&self) -> Option<&HeightField> {
        None
    }
    /// What the device did since the last call (all 0 on the CPU).
    fn take_counters(&mut self) -> GpuCounters {
        GpuCounters::default()
    }
}
