//! The solver's share of a frame: a time budget (interactive use) or a work budget (replays that must
//! give the same frames on any machine), and the caps on a frame's solver work.

use std::time::{Duration, Instant};

/// Cells of the reference grid (1024^2) that work budgets are counted in: one reference work unit
/// is one level-0 sweep's worth of work on a 1024^2 grid, so the same budget means about the same
/// time at every grid size.
pub const REFERENCE_CELLS: f64 = 1024.0 * 1024.0;

/// The solver's time per frame in interactive use.
pub const DEFAULT_FRAME_BUDGET: Duration = Duration::from_millis(10);

/// A frame's solver budget.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FrameBudget {
    /// Wall time.
    Time(Duration),
    /// Reference work units (see [`REFERENCE_CELLS`]): deterministic, whatever the machine.
    Work(f64),
}

/// The smallest solver time a frame with an edit may be capped at (a budget of a few
/// milliseconds would otherwise leave no room for one global correction).
const MIN_EDIT_CAP: Duration = Duration::from_millis(40);
/// A frame with an edit may run the solver up to this many budgets (at least `MIN_EDIT_CAP`), so
/// that what is shown has had a global correction.
const EDIT_CAP_BUDGETS: u32 = 4;
/// A frame without an edit (the pointer rests) may run the solver up to this many budgets, so that
/// the terrain settles within a few frames of the stop.
const SETTLE_CAP_BUDGETS: u32 = 25;

/// Counts a frame's solver work against its budget and caps.
#[derive(Debug, Clone)]
pub struct Meter {
    budget: FrameBudget,
    start: Instant,
    /// Reference work units spent so far.
    work: f64,
}

impl Meter {
    /// Starts counting now.
    pub fn new(budget: FrameBudget) -> Meter {
        Meter {
            budget,
            start: Instant::now(),
            work: 0.0,
        }
    }

    /// Adds `work_units` of solver work on a grid of `cells` cells.
    pub fn add(&mut self, work_units: f64, cells: usize) {
        self.work += work_units * cells as f64 / REFERENCE_CELLS;
    }

    /// Reference work units spent so far.
    pub fn work(&self) -> f64 {
        self.work
    }

    /// True once the frame's budget is spent.
    pub fn budget_spent(&self) -> bool {
        match self.budget {
            FrameBudget::Time(t) => self.start.elapsed() >= t,
            FrameBudget::Work(w) => self.work >= w,
        }
    }

    /// True once the frame's cap is reached: `EDIT_CAP_BUDGETS` budgets (at least `MIN_EDIT_CAP` of
    /// time) in a frame with an edit, `SETTLE_CAP_BUDGETS` budgets in a frame without one.
    pub fn cap_reached(&self, settling: bool) -> bool {
        match self.budget {
            FrameBudget::Time(t) => self.start.elapsed() >= time_cap(t, settling),
            FrameBudget::Work(w) => {
                let times = if settling {
                    SETTLE_CAP_BUDGETS
                } else {
                    EDIT_CAP_BUDGETS
                };
                self.work >= w * times as f64
            }
        }
    }
}

/// The solver time a frame may take with a time budget `t` (see `Meter::cap_reached`).
fn time_cap(t: Duration, settling: bool) -> Duration {
    if settling {
        t * SETTLE_CAP_BUDGETS
    } else {
        (t * EDIT_CAP_BUDGETS).max(MIN_EDIT_CAP)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn work_is_counted_in_reference_units_and_capped() {
        let mut m = Meter::new(FrameBudget::Work(4.0));
        // One work unit on a 2048^2 grid is four reference units.
        m.add(1.0, 2048 * 2048);
        assert_eq!(m.work(), 4.0);
        assert!(m.budget_spent());
        assert!(!m.cap_reached(false));
        m.add(12.0, 1024 * 1024);
        assert!(m.cap_reached(false), "4 budgets with an edit");
        assert!(!m.cap_reached(true), "25 budgets when settling");
        m.add(84.0, 1024 * 1024);
        assert!(m.cap_reached(true));
    }

    #[test]
    fn a_time_budget_caps_edits_at_forty_milliseconds_at_least() {
        let ms = Duration::from_millis;
        assert_eq!(time_cap(ms(1), false), ms(40));
        assert_eq!(time_cap(ms(20), false), ms(80));
        assert_eq!(time_cap(ms(1), true), ms(25));
        let m = Meter::new(FrameBudget::Time(ms(1)));
        std::thread::sleep(ms(2));
        assert!(m.budget_spent());
    }
}
