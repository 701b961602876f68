//! How a solver follows the document's sketch while the pen moves: one rule for both backends.
//!
//! A [`Follower`] takes the newest sketch only once what its solver shows for the previous one is
//! *coherent*: a warm start's local relaxation around the changed constraints has been followed by
//! at least one global correction (an FCG iteration), or the solver converged, or (cold) FMG shows a
//! coarse level. A frame with an edit runs the solver until that holds and the budget is spent,
//! within the frame's cap (`budget::Meter`); a frame without one runs until converged. So the land
//! moves towards the pen in every frame instead of showing only the cells next to the changed
//! constraints, or nothing while each new edit restarts the field solves.

use anyhow::Result;
use terrasketch_sketch::Sketch;

use super::budget::Meter;

/// How a solver took a sketch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Took {
    /// From scratch (FMG: every level it shows is a global solution).
    Cold,
    /// Warm from the previous sketch: only the local relaxation ran so far.
    Warm,
    /// Nothing that the solver sees changed.
    Nothing,
}

/// One unit of solver work.
#[derive(Debug, Clone, Copy, Default)]
pub struct Unit {
    /// Height work units (level-0 units of the solver's grid).
    pub height_wu: f64,
    /// Gradient-field work units.
    pub field_wu: f64,
    /// Level-0 iterations (global corrections).
    pub vcycles: u32,
    /// The solver met its current tolerance (or can make no further progress).
    pub converged: bool,
    /// What the solver shows after this unit is coherent by itself (an iteration, convergence, or a
    /// coarse FMG level).
    pub coherent: bool,
    /// The solver has queued all it will this frame (the GPU's work runs on after the frame's
    /// encoding; its results arrive with later frames): the frame's loop ends.
    pub frame_full: bool,
}

/// What a frame's solver work did.
#[derive(Debug, Clone, Copy, Default)]
pub struct FrameWork {
    /// Height work units (of the stepped solver's grid).
    pub height_wu: f64,
    /// Gradient-field work units.
    pub field_wu: f64,
    /// Level-0 iterations.
    pub vcycles: u32,
    /// Some work ran (the heights may have changed).
    pub ran: bool,
}

impl FrameWork {
    fn add(&mut self, u: &Unit) {
        self.height_wu += u.height_wu;
        self.field_wu += u.field_wu;
        self.vcycles += u.vcycles;
        self.ran = true;
    }

    /// Adds another frame's work.
    pub fn merge(&mut self, w: &FrameWork) {
        self.height_wu += w.height_wu;
        self.field_wu += w.field_wu;
        self.vcycles += w.vcycles;
        self.ran |= w.ran;
    }
}

/// What the follow rule needs from a solver (`terrain_cpu::CpuLive`, `terrain_gpu::GpuLive`).
pub trait LiveSolver {
    /// Cells of the solver's grid (its work units are per level-0 sweep of it).
    fn cells(&self) -> usize;
    /// Takes `sketch`, warm from `from` (the sketch it has), cold when there is none.
    fn take(&mut self, sketch: &Sketch, from: Option<&Sketch>) -> Result<(Took, Unit)>;
    /// One unit of work towards the current tolerance (the polish tolerance while polishing).
    fn advance(&mut self) -> Result<Unit>;
    /// True when the current tolerance already holds (right after a take).
    fn converged(&self) -> bool;
    /// True when level 0 holds heights (not only a cold start's coarse FMG levels).
    fn level0_ready(&self) -> bool;
    /// Starts the idle refinement to round-off; false if there is nothing to refine.
    fn begin_polish(&mut self) -> bool;
    /// Back to the normal tolerance after the idle refinement.
    fn end_polish(&mut self);
    /// Rebuilds the mips and bounds after work.
    fn publish(&mut self) -> Result<()>;
}

/// A solver and the sketch it has taken, stepped by the follow rule (see the module doc).
pub struct Follower<S> {
    /// The solver.
    pub solver: S,
    /// The sketch the solver has taken (`None`: the next take is cold).
    applied: Option<Sketch>,
    /// What the solver shows for `applied` is coherent.
    coherent: bool,
    /// Converged for `applied` at the normal tolerance.
    done: bool,
    /// The idle refinement is running or done.
    polishing: bool,
    /// The idle refinement is done.
    polished: bool,
}

impl<S: LiveSolver> Follower<S> {
    /// Follows with `solver`, which has taken nothing yet.
    pub fn new(solver: S) -> Follower<S> {
        Follower {
            solver,
            applied: None,
            coherent: true,
            done: false,
            polishing: false,
            polished: false,
        }
    }

    /// The next sketch is taken cold (the whole sketch was replaced).
    pub fn restart(&mut self) {
        self.normal_tolerance();
        self.applied = None;
        self.coherent = true;
        self.done = false;
    }

    /// True once any sketch was taken.
    pub fn started(&self) -> bool {
        self.applied.is_some()
    }

    /// True when the solver has taken `sketch`.
    pub fn has_taken(&self, sketch: &Sketch) -> bool {
        self.applied.as_ref() == Some(sketch)
    }

    /// True when converged for `sketch`.
    pub fn converged_for(&self, sketch: &Sketch) -> bool {
        self.done && self.has_taken(sketch)
    }

    /// True when what the solver shows is a coherent approximation for `sketch`.
    pub fn coherent_for(&self, sketch: &Sketch) -> bool {
        self.coherent && self.has_taken(sketch)
    }

    /// True when what the solver shows is coherent (for the sketch it has).
    pub fn coherent(&self) -> bool {
        self.coherent
    }

    /// True once converged and the idle refinement is done.
    pub fn polished(&self) -> bool {
        self.done && self.polished
    }

    /// True when the solver may take the next sketch: converged, or coherent on level 0 (a cold
    /// start first finishes FMG, which would otherwise restart with every edit).
    fn ready_for_next(&self) -> bool {
        self.done || (self.coherent && self.solver.level0_ready())
    }

    fn normal_tolerance(&mut self) {
        if self.polishing {
            self.solver.end_polish();
        }
        self.polishing = false;
        self.polished = false;
    }

    fn take(&mut self, sketch: &Sketch, meter: &mut Meter, work: &mut FrameWork) -> Result<()> {
        self.normal_tolerance();
        let (took, u) = self.solver.take(sketch, self.applied.as_ref())?;
        meter.add(u.height_wu + u.field_wu, self.solver.cells());
        work.add(&u);
        self.applied = Some(sketch.clone());
        match took {
            Took::Cold => self.coherent = true,
            Took::Warm => self.coherent = false,
            Took::Nothing => return Ok(()),
        }
        self.done = self.solver.converged();
        if self.done {
            self.coherent = true;
        }
        Ok(())
    }

    /// Steps towards `sketch` within the frame: takes it when what is shown for the previous one is
    /// coherent, then runs until coherent and the budget is spent (`settling`: until converged),
    /// or the cap is reached. Publishes once at the end if anything ran.
    pub fn follow(
        &mut self,
        sketch: &Sketch,
        meter: &mut Meter,
        settling: bool,
    ) -> Result<FrameWork> {
        let mut work = FrameWork::default();
        loop {
            if !self.has_taken(sketch) && self.ready_for_next() {
                self.take(sketch, meter, &mut work)?;
            }
            if self.done {
                break;
            }
            let u = self.solver.advance()?;
            meter.add(u.height_wu + u.field_wu, self.solver.cells());
            work.add(&u);
            self.done = u.converged;
            self.coherent |= u.coherent || u.converged;
            if u.frame_full
                || meter.cap_reached(settling)
                || (!settling && self.ready_for_next() && meter.budget_spent())
            {
                break;
            }
        }
        if work.ran {
            self.solver.publish()?;
        }
        Ok(work)
    }

    /// The idle refinement after convergence: one budget a frame until it is done.
    pub fn polish(&mut self, meter: &mut Meter) -> Result<FrameWork> {
        let mut work = FrameWork::default();
        if !self.done || self.polished {
            return Ok(work);
        }
        if !self.polishing {
            if !self.solver.begin_polish() {
                return Ok(work);
            }
            self.polishing = true;
        }
        loop {
            let u = self.solver.advance()?;
            meter.add(u.height_wu + u.field_wu, self.solver.cells());
            work.add(&u);
            if u.converged {
                self.polished = true;
                break;
            }
            if u.frame_full || meter.budget_spent() {
                break;
            }
        }
        self.solver.publish()?;
        Ok(work)
    }
}
