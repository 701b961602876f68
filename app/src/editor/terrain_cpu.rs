//! The CPU solver as the editor steps it: each solver follows the document's sketch by the rule of
//! `follow` ([`CpuLive`] is the CPU side of it).
//!
//! Grids larger than [`LIVE_SIDE`] also keep a twin solver of that side over the same extent. While
//! edits arrive, the twin follows the pen and its levels are shown as the big grid's coarse mips
//! (coarse first: the finest *ready* level is drawn); the full solver takes the sketch once the
//! pointer rests and is shown again as soon as it is coherent. When a solver that follows edits
//! cannot reach a coherent state within a frame's cap (a slow or loaded machine), a spare twin of
//! half its side, kept converged in idle frames, takes over the following edits (down to
//! [`MIN_LIVE_SIDE`]); until a coherent state exists the display keeps the last one.

use anyhow::Result;
use terrasketch_multigrid::{Budget, CpuSolver, Grid, Solver, SolverParams, Taken};
use terrasketch_sketch::Sketch;

use super::budget::Meter;
use super::engine::{MinMaxLevel, TerrainSolver, min_max_levels};
use super::follow::{self, FrameWork, LiveSolver, Took, Unit};

/// Side of the twin that follows edits on larger grids: its warm update with one global correction
/// fits the edit cap on a 2-core machine, where a 4096^2 one takes several times the cap.
pub const LIVE_SIDE: usize = 1024;

/// The smallest twin: below it a coarse preview shows too little of the land to be worth it.
pub const MIN_LIVE_SIDE: usize = 256;

/// Tolerance of the idle refinement after convergence: two converged states of the same sketch
/// (before an edit, after its undo) then agree to round-off.
pub const POLISH_TOLERANCE: f32 = 1e-6;

/// Work one solver call may do before the frame's budget and caps are checked again.
const STEP_WORK_UNITS: f64 = 0.25;

/// The CPU solver under the follow rule.
pub struct CpuLive {
    /// The solver.
    pub solver: Box<CpuSolver>,
}

impl CpuLive {
    /// A solver of `grid` (nothing taken yet).
    pub fn new(grid: Grid) -> Result<CpuLive> {
        Ok(CpuLive {
            solver: Box::new(CpuSolver::new(grid, SolverParams::default())?),
        })
    }
}

impl LiveSolver for CpuLive {
    fn cells(&self) -> usize {
        let n = self.solver.grid().n;
        n * n
    }

    /// As `Solver::edit_sketch` (warm: only the texels of the strokes that differ are
    /// re-rasterised); what is shown after a warm take has a global correction, however gentle
    /// the edit.
    fn take(&mut self, sketch: &Sketch, from: Option<&Sketch>) -> Result<(Took, Unit)> {
        let took = match Solver::edit_sketch(self.solver.as_mut(), sketch, from)? {
            Taken::Unchanged => Took::Nothing,
            Taken::Cold => Took::Cold,
            Taken::Warm => {
                self.solver.require_iteration();
                Took::Warm
            }
        };
        Ok((took, Unit::default()))
    }

    fn advance(&mut self) -> Result<Unit> {
        let p = self.solver.advance(Budget::WorkUnits(STEP_WORK_UNITS));
        Ok(Unit {
            height_wu: p.work_units,
            field_wu: p.field_work_units,
            vcycles: p.vcycles,
            converged: p.converged,
            coherent: p.vcycles > 0 || p.finest_ready_level.is_some_and(|k| k > 0),
            frame_full: false,
        })
    }

    fn converged(&self) -> bool {
        // A take always leaves the field solves to run.
        false
    }

    fn level0_ready(&self) -> bool {
        self.solver.finest_ready_level() == Some(0)
    }

    fn begin_polish(&mut self) -> bool {
        if self.solver.finest_ready_level() != Some(0) {
            return false;
        }
        self.solver.set_params(SolverParams {
            tolerance: POLISH_TOLERANCE,
            ..SolverParams::default()
        });
        true
    }

    fn end_polish(&mut self) {
        self.solver.set_params(SolverParams::default());
    }

    fn publish(&mut self) -> Result<()> {
        self.solver.publish();
        Ok(())
    }
}

/// A CPU solver under the follow rule.
pub type Follower = follow::Follower<CpuLive>;

/// The CPU engine: the solver at the terrain's size and, on larger grids, the twin that follows
/// edits (see the module doc).
pub struct CpuEngine {
    /// The solver at the terrain's size.
    pub full: Follower,
    /// The twin that follows edits instead of `full` (side `LIVE_SIDE` on larger grids, or a former
    /// spare after a missed cap).
    pub live: Option<Follower>,
    /// A twin of half the side of the solver that follows edits, converged in idle frames, for
    /// when that solver misses the cap (none below `MIN_LIVE_SIDE`).
    spare: Option<Follower>,
    /// The display keeps what it shows for this frame (set when a spare takes over: it has not yet
    /// taken the newest sketch, and what it holds is older than what is shown).
    hold: bool,
    /// The twin's levels are shown (as the full grid's mips `live_level..`).
    pub showing_live: bool,
    /// Mip level of the full grid that the twin's level 0 stands for.
    pub live_level: u32,
}

impl CpuEngine {
    /// Solvers for `grid` (nothing taken yet).
    pub fn new(grid: Grid) -> Result<CpuEngine> {
        let mut engine = CpuEngine {
            full: Follower::new(CpuLive::new(grid)?),
            live: None,
            spare: None,
            hold: false,
            showing_live: false,
            live_level: 0,
        };
        if grid.n > LIVE_SIDE {
            engine.live = Some(engine.twin(LIVE_SIDE)?);
            engine.live_level = (grid.n / LIVE_SIDE).trailing_zeros();
        }
        engine.spare = engine.twin(engine.edit_side() / 2).ok();
        Ok(engine)
    }

    /// A twin of side `side` over the full grid's extent (nothing taken yet); refused below
    /// `MIN_LIVE_SIDE`.
    fn twin(&self, side: usize) -> Result<Follower> {
        anyhow::ensure!(side >= MIN_LIVE_SIDE, "no twin below {MIN_LIVE_SIDE}");
        let extent_m = self.full.solver.solver.grid().extent_m;
        Ok(Follower::new(CpuLive::new(Grid::new(side, extent_m)?)?))
    }

    /// Side of the solver that follows edits.
    fn edit_side(&self) -> usize {
        match &self.live {
            Some(l) => l.solver.solver.grid().n,
            None => self.full.solver.solver.grid().n,
        }
    }

    /// After an edit frame that ended without a coherent state: the spare (half the side) follows
    /// the next edits, and a new spare of half its side is made (nothing below `MIN_LIVE_SIDE`).
    fn halve_edit_side(&mut self) {
        let Some(spare) = self.spare.take() else {
            return;
        };
        let side = spare.solver.solver.grid().n;
        self.live = Some(spare);
        self.live_level = (self.full.solver.solver.grid().n / side).trailing_zeros();
        // Its coarser levels are in the texture already (uploaded from the solver it replaces).
        self.showing_live = true;
        self.hold = true;
        self.spare = self.twin(side / 2).ok();
    }

    /// The whole sketch was replaced: every solver takes the next one cold.
    pub fn restart(&mut self) {
        self.full.restart();
        for t in [&mut self.live, &mut self.spare].into_iter().flatten() {
            t.restart();
        }
        self.showing_live = false;
    }

    /// One frame of solver work for `sketch`; `edited` if an edit arrived this frame. Returns the
    /// work in reference units and the iterations of the solver that is shown.
    pub fn step(&mut self, sketch: &Sketch, meter: &mut Meter, edited: bool) -> Result<FrameWork> {
        self.hold = false;
        if edited {
            let (w, coherent) = match &mut self.live {
                Some(live) => {
                    let w = live.follow(sketch, meter, false)?;
                    self.showing_live = true;
                    (w, live.coherent_for(sketch))
                }
                None => {
                    let w = self.full.follow(sketch, meter, false)?;
                    (w, self.full.coherent_for(sketch))
                }
            };
            if !coherent {
                self.halve_edit_side();
            }
            return Ok(w);
        }
        let mut work = if self.full.converged_for(sketch) {
            self.full.polish(meter)?
        } else {
            self.full.follow(sketch, meter, true)?
        };
        if self.showing_live && self.full.coherent_for(sketch) {
            self.showing_live = false;
        }
        // While idle, the twins catch up so that the next drag starts warm.
        for t in [&mut self.live, &mut self.spare].into_iter().flatten() {
            if self.full.polished() && !t.converged_for(sketch) && !meter.budget_spent() {
                let w = t.follow(sketch, meter, false)?;
                work.merge(&w);
            }
        }
        Ok(work)
    }

    /// True when what the shown solver holds is coherent (see `Follower::coherent`): else the
    /// display keeps the last coherent state.
    pub fn shown_coherent(&self) -> bool {
        if self.hold {
            return false;
        }
        match (&self.live, self.showing_live) {
            (Some(l), true) => l.coherent(),
            _ => self.full.coherent(),
        }
    }

    /// The solver that is shown.
    pub fn shown(&self) -> &CpuSolver {
        match (&self.live, self.showing_live) {
            (Some(l), true) => &l.solver.solver,
            _ => &self.full.solver.solver,
        }
    }

    /// Finest mip of the full grid that is ready.
    pub fn finest_ready(&self) -> Option<u32> {
        let offset = if self.showing_live {
            self.live_level
        } else {
            0
        };
        self.shown().finest_ready_level().map(|k| k + offset)
    }

    /// Mip `k` of the full grid as shown (empty for levels finer than the twin while it is shown).
    pub fn mip(&self, k: usize) -> &[f32] {
        if self.showing_live {
            let off = self.live_level as usize;
            return if k >= off {
                self.shown().mip(k - off)
            } else {
                &[]
            };
        }
        self.full.solver.solver.mip(k)
    }

    /// True when converged for `sketch` (the full solver) and the twin is not shown.
    pub fn converged_for(&self, sketch: &Sketch) -> bool {
        self.full.converged_for(sketch) && !self.showing_live
    }

    /// True when nothing is left to do for `sketch`.
    pub fn settled_for(&self, sketch: &Sketch) -> bool {
        self.converged_for(sketch)
            && (self.full.polished() || self.full.solver.solver.finest_ready_level() != Some(0))
    }
}

impl TerrainSolver for CpuEngine {
    fn full_solver(&self) -> &dyn Solver {
        self.full.solver.solver.as_ref()
    }

    fn shown(&self) -> &dyn Solver {
        CpuEngine::shown(self)
    }

    fn step(&mut self, sketch: &Sketch, meter: &mut Meter, edited: bool) -> Result<FrameWork> {
        CpuEngine::step(self, sketch, meter, edited)
    }

    fn restart(&mut self) {
        CpuEngine::restart(self);
    }

    fn progress_ready(&self) -> bool {
        true
    }

    fn converged_for(&self, sketch: &Sketch) -> bool {
        CpuEngine::converged_for(self, sketch)
    }

    fn settled_for(&self, sketch: &Sketch) -> bool {
        CpuEngine::settled_for(self, sketch)
    }

    fn shown_solver(&self) -> usize {
        self.showing_live as usize
    }

    fn finest_ready(&self) -> Option<u32> {
        CpuEngine::finest_ready(self)
    }

    fn mip(&self, k: usize) -> &[f32] {
        CpuEngine::mip(self, k)
    }

    fn min_max(&mut self, changed: bool, _wanted: bool) -> Result<Option<Vec<MinMaxLevel>>> {
        if !changed {
            return Ok(None);
        }
        let levels = min_max_levels(Solver::min_max(CpuEngine::shown(self))?);
        Ok((!levels.is_empty()).then_some(levels))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::editor::budget::FrameBudget;

    /// Moves stroke 0 of `s` by `(dx, dy)` metres.
    fn moved(s: &Sketch, dx: f64, dy: f64) -> Sketch {
        let mut s = s.clone();
        for p in &mut s.strokes[0].points {
            p[0] += dx;
            p[1] += dy;
        }
        s
    }

    #[test]
    fn every_edit_frame_shows_a_global_correction() {
        let mut sketch = terrasketch_sketch::benchmark_sketch();
        let grid = Grid::new(256, sketch.extent_m).unwrap();
        let mut f = Follower::new(CpuLive::new(grid).unwrap());
        let mut m = Meter::new(FrameBudget::Work(1000.0));
        f.follow(&sketch, &mut m, true).unwrap();
        assert!(f.converged_for(&sketch));
        for _ in 0..5 {
            sketch = moved(&sketch, 150.0, 90.0);
            // A budget below one warm update (its cap of 4 budgets above it): the frame still ends
            // only once the edit had a global correction.
            let mut m = Meter::new(FrameBudget::Work(0.2));
            let w = f.follow(&sketch, &mut m, false).unwrap();
            assert!(f.coherent_for(&sketch));
            assert!(
                w.vcycles >= 1 || f.converged_for(&sketch),
                "no FCG iteration after the edit: {w:?}"
            );
        }
    }

    #[test]
    fn a_gentle_edit_still_gets_a_global_correction() {
        // A band widened by a few percent can leave the residual under the tolerance after the
        // local relaxation; the frame still runs an FCG iteration, so the land away from the
        // changed cells moves too.
        let mut sketch = terrasketch_sketch::example_sketch();
        let grid = Grid::new(256, sketch.extent_m).unwrap();
        let mut f = Follower::new(CpuLive::new(grid).unwrap());
        f.follow(&sketch, &mut Meter::new(FrameBudget::Work(1000.0)), true)
            .unwrap();
        for _ in 0..4 {
            sketch.strokes[1].width_m += 60.0;
            let w = f
                .follow(&sketch, &mut Meter::new(FrameBudget::Work(0.2)), false)
                .unwrap();
            assert!(w.vcycles >= 1, "no global correction: {w:?}");
        }
    }

    #[test]
    fn an_edit_is_not_taken_before_the_previous_one_is_coherent() {
        let sketch = terrasketch_sketch::benchmark_sketch();
        let grid = Grid::new(256, sketch.extent_m).unwrap();
        let mut f = Follower::new(CpuLive::new(grid).unwrap());
        f.follow(&sketch, &mut Meter::new(FrameBudget::Work(1000.0)), true)
            .unwrap();
        let a = moved(&sketch, 200.0, 0.0);
        // A cap below one warm update: the frame ends before the global correction.
        let mut m = Meter::new(FrameBudget::Work(1e-4));
        // The edit cap is 4 budgets: 4e-4 reference units, less than the field solve.
        f.follow(&a, &mut m, false).unwrap();
        assert!(!f.coherent_for(&a), "the cap stopped the frame early");
        let b = moved(&a, 200.0, 0.0);
        let w = f
            .follow(&b, &mut Meter::new(FrameBudget::Work(1e-4)), false)
            .unwrap();
        // The previous edit is continued first; the new one waits.
        assert!(f.has_taken(&a), "the new edit was taken too early ({w:?})");
        let mut frames = 0;
        while !f.coherent_for(&b) && frames < 20 {
            f.follow(&b, &mut Meter::new(FrameBudget::Work(1e-4)), false)
                .unwrap();
            frames += 1;
        }
        assert!(
            f.coherent_for(&b),
            "the newest edit was taken and corrected"
        );
    }

    #[test]
    fn a_solver_that_misses_the_cap_hands_edits_to_a_warm_spare_of_half_its_side() {
        let mut sketch = terrasketch_sketch::benchmark_sketch();
        let grid = Grid::new(512, sketch.extent_m).unwrap();
        let mut e = CpuEngine::new(grid).unwrap();
        assert!(e.live.is_none(), "no twin at 512");
        for _ in 0..60 {
            e.step(&sketch, &mut Meter::new(FrameBudget::Work(100.0)), false)
                .unwrap();
        }
        assert!(e.settled_for(&sketch));
        let spare = e.spare.as_ref().expect("a spare of half the side");
        assert_eq!(spare.solver.solver.grid().n, 256);
        assert!(spare.converged_for(&sketch), "the spare is warm");
        // A cap far below one warm update at 512: the frame ends incoherent, the display holds.
        sketch = moved(&sketch, 150.0, 90.0);
        e.step(&sketch, &mut Meter::new(FrameBudget::Work(0.01)), true)
            .unwrap();
        assert!(
            !e.shown_coherent(),
            "the display keeps the last coherent state"
        );
        assert_eq!(e.live.as_ref().map(|l| l.solver.solver.grid().n), Some(256));
        assert_eq!(
            e.spare.as_ref().map(|l| l.solver.solver.grid().n),
            None,
            "none below 256"
        );
        // The next edit is followed by the warm 256^2 twin, shown as mip 1.
        sketch = moved(&sketch, 150.0, 90.0);
        let w = e
            .step(&sketch, &mut Meter::new(FrameBudget::Work(0.2)), true)
            .unwrap();
        assert!(e.shown_coherent(), "{w:?}");
        assert_eq!(e.finest_ready(), Some(1));
        assert_eq!(e.mip(1).len(), 256 * 256);
        assert!(e.mip(0).is_empty(), "nothing finer than the twin is shown");
        // Once the pointer rests the full solver takes the sketch and is shown again.
        for _ in 0..20 {
            e.step(&sketch, &mut Meter::new(FrameBudget::Work(4.0)), false)
                .unwrap();
        }
        assert!(!e.showing_live);
        assert!(e.converged_for(&sketch));
        assert_eq!(e.finest_ready(), Some(0));
    }
}
