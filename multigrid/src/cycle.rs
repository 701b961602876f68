//! The multigrid cycle as data, for both backends: the steps of the preconditioner's cycle and of
//! FMG on each level ([`Step`]), the shape that decides them ([`CycleShape`], with the visit rule
//! [`CycleShape::visits`]), and the algorithm's constants (colours, work units, the local
//! relaxation's sweeps and thresholds).
//!
//! Two executors follow it: the GPU plan (`gpu/plan.rs`) maps each step to its passes, and the CPU
//! (`cpu/mod.rs`, `Hierarchy`) runs the same steps by recursion, with fused level-0 kernels for the
//! common one-sweep case (`cpu/fast.rs`); a test walks the CPU and fails on any difference from
//! these sequences.

use crate::SolverParams;
use crate::grid::COARSEST_SIDE;

/// Colours of a level-0 Gauss-Seidel sweep (red-black, 5-point operator).
pub const LEVEL0_COLOURS: u32 = 2;
/// Colours of a coarse-level sweep (four colours `(i & 1) + 2 (j & 1)`, 9-point Galerkin operators).
pub const COARSE_COLOURS: u32 = 4;
/// Cells of level `k + 1` per cell of level `k` (2 x 2 coarsening): a sweep on level `k` costs
/// `CELL_RATIO^k` work units.
pub const CELL_RATIO: f64 = 0.25;

/// Level of the heights' hierarchy the gradient field is solved on (a sweep costs
/// `sweep_work_units(GRADIENT_LEVEL)` of the heights' work units).
pub const GRADIENT_LEVEL: usize = 1;
/// Level the roughness is solved on.
pub const ROUGHNESS_LEVEL: usize = 2;

/// Work units of one sweep over level `level` (a level-0 sweep is the unit).
pub fn sweep_work_units(level: usize) -> f64 {
    CELL_RATIO.powi(level as i32)
}

/// Work units of one colour of a sweep on `level`.
pub fn colour_work_units(level: usize) -> f64 {
    sweep_work_units(level) / colours(level) as f64
}

/// Colours of one sweep on `level`.
pub fn colours(level: usize) -> u32 {
    if level == 0 {
        LEVEL0_COLOURS
    } else {
        COARSE_COLOURS
    }
}

/// Chebyshev radius of the local relaxation's window around each seed.
pub(crate) const RADIUS: usize = 6;
/// Red-black sweeps of the local relaxation over its windows.
pub(crate) const SWEEPS: usize = 10;
/// Red-black sweeps of a warm gradient-field (or roughness) update's relaxation: its residual
/// test is 30 times looser than the heights', and on the benchmark drag 2 sweeps already keep
/// every update under it (1 does not: a global field iteration follows), so 4 leave a margin.
pub(crate) const FIELD_WARM_SWEEPS: usize = 4;
/// FCG's stop-test relaxation: an iteration that leaves the normalised residual above the tolerance
/// but at most this many times it relaxes the correction around the cells above the tolerance
/// (`SPIKE_SWEEPS` sweeps) before the next iteration (ALGORITHM.md, "The W-cycle stops at
/// level 3").
pub(crate) const SPIKE_BAND: f32 = 2.0;
/// Red-black sweeps of the stop-test relaxation (one GPU tile pass holds at most 5).
pub(crate) const SPIKE_SWEEPS: usize = 5;
/// The stop-test relaxation's windows may cover at most `n^2 / SPIKE_SHARE` cells of the level
/// (more is not a spike: the next iteration does it better).
pub(crate) const SPIKE_SHARE: usize = 256;
/// Normalised residual above which a cell seeds a local-relaxation window after FMG.
pub(crate) const FMG_SEED_RESIDUAL: f32 = 0.1;
/// Normalised residual above which a cell seeds a window in a warm start of the GPU solver (the
/// CPU seeds its warm starts by the cells whose constraint changed).
pub(crate) const WARM_SEED_RESIDUAL: f32 = 0.01;

/// Largest side of the levels a backend may run as one fused step ([`Step::Fused`]; the GPU's
/// `coarse_fused.wgsl`): 64^2 + 32^2 + 16^2 + 8^2 = 5440 cells, 131 KB of stencil records and 44 KB
/// of `u` and `f`, small enough for one compute unit and its caches. At most 64: the fused pass
/// binds one stencil buffer per level, four at most.
pub const FUSED_SIDE: usize = 64;

/// The finest level a solver fuses: `GpuSolver`'s gradient field and roughness use the heights'
/// levels from 2 and 3 on as their own, and fuse the same levels as the heights (a pass binding a
/// fused and an unfused level would bind the fused levels' buffer twice), from their level 2 on
/// (level 1's stencils are computed from the level-0 diagonal, which the fused pass does not
/// bind): so the heights fuse from level 4.
pub const MIN_FUSED_LEVEL: usize = 4;

/// The first fused level of a hierarchy of `levels` levels with fused levels of side at most
/// `fuse_side` (see [`CycleShape::fused_from`]).
pub fn fused_from(levels: usize, fuse_side: usize) -> Option<usize> {
    let kc = levels.checked_sub(1)?;
    if fuse_side < COARSEST_SIDE {
        return None;
    }
    let below = (fuse_side / COARSEST_SIDE).ilog2() as usize;
    let kf = kc.saturating_sub(below).max(MIN_FUSED_LEVEL);
    (kf < kc).then_some(kf)
}

/// The shape of the cycles: levels and the [`SolverParams`] fields that matter here.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CycleShape {
    /// Levels including level 0 (the coarsest is `levels - 1`).
    pub levels: usize,
    /// Pre-smoothing sweeps.
    pub pre_sweeps: u32,
    /// Post-smoothing sweeps.
    pub post_sweeps: u32,
    /// Coarse visits per level where it applies.
    pub gamma: u32,
    /// First level from which `gamma` applies (0 = also from level 0 to 1).
    pub gamma_from_level: u32,
    /// First level from which the visits are single again.
    pub gamma_until_level: u32,
    /// Levels of at most this side (and >= [`MIN_FUSED_LEVEL`]) run as one [`Step::Fused`] when
    /// there are two or more of them; 0: no fused step (the CPU).
    pub fuse_side: usize,
    /// Levels above this solver's level 0 in the solver whose coarse levels it uses (0: its own),
    /// so that both fuse the same levels (see [`CycleShape::fused_from`]).
    pub shift: usize,
}

impl CycleShape {
    /// From the solver parameters, fusing the levels of side <= [`FUSED_SIDE`] (the GPU).
    pub fn new(levels: usize, p: &SolverParams) -> CycleShape {
        CycleShape {
            levels,
            pre_sweeps: p.pre_sweeps,
            post_sweeps: p.post_sweeps,
            gamma: p.gamma,
            gamma_from_level: p.gamma_from_level,
            gamma_until_level: p.gamma_until_level,
            fuse_side: FUSED_SIDE,
            shift: 0,
        }
    }

    /// From the solver parameters, every step on its own (the CPU).
    pub fn unfused(levels: usize, p: &SolverParams) -> CycleShape {
        CycleShape {
            fuse_side: 0,
            ..CycleShape::new(levels, p)
        }
    }

    /// The first level of [`Step::Fused`]: the finest level `>= 2` of side at most `fuse_side`,
    /// if it is not the coarsest (level 1's stencils are computed from the level-0 diagonal,
    /// which the GPU's fused pass does not bind).
    pub fn fused_from(&self) -> Option<usize> {
        let kf = fused_from(self.levels + self.shift, self.fuse_side)?.checked_sub(self.shift)?;
        (kf >= 2).then_some(kf)
    }

    /// Index of the coarsest level.
    pub fn coarsest(&self) -> usize {
        self.levels - 1
    }

    /// The coarsest lift level `L = log2 n` (side 1; below the coarsest solver level).
    pub fn lift_levels(&self) -> usize {
        self.coarsest() + COARSEST_SIDE.trailing_zeros() as usize
    }

    /// Visits of level `k + 1` from level `k`: `gamma` from the levels `gamma_from_level ..
    /// gamma_until_level`, else one; the coarsest level always once (its solve is exact, so a
    /// second visit has nothing left to correct).
    pub fn visits(&self, k: usize) -> u32 {
        if k + 1 == self.coarsest() {
            1
        } else if k >= self.gamma_from_level as usize && k < self.gamma_until_level as usize {
            self.gamma
        } else {
            1
        }
    }
}

/// One step of the algorithm on one level. On level 0 the preconditioner works on `z` with
/// right-hand side `r` (from `z = 0`), FMG on the solution `h` with right-hand side `f`
/// (`solution`); a coarse level `k` on `(u_k, f_k)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Step {
    /// `z = 0` (level 0) or `u_level = 0`.
    Clear { level: usize },
    /// One colour of a Gauss-Seidel sweep on `level` ([`colours`] per sweep: ascending before the
    /// coarse-grid correction, descending after it).
    Smooth { level: usize, colour: u32 },
    /// `f_{level+1} = R (rhs - A x)` on `level`.
    ResidualRestrict { level: usize, solution: bool },
    /// `x_level += P u_{level+1}` on free cells, or `=` with inactive cells zeroed (`set`: FMG's
    /// interpolation to a coarse level).
    Prolong {
        level: usize,
        set: bool,
        solution: bool,
    },
    /// `f_{level+1} = R f_level` (FMG's right-hand sides).
    RestrictSum { level: usize },
    /// The exact solve on the coarsest level.
    CoarsestSolve { level: usize },
    /// FMG's lift: `h = g_0` and the lift's levels (`cpu/lift.rs`).
    Lift,
    /// The levels from [`CycleShape::fused_from`] down as one step: one cycle on that level, or
    /// (`fmg`) FMG's part from the sums on that level (see [`fused_steps`]).
    Fused { fmg: bool },
}

impl Step {
    /// The level the step works on (the finer level of a transfer; 0 for the lift).
    pub fn level(self, shape: &CycleShape) -> usize {
        match self {
            Step::Clear { level }
            | Step::Smooth { level, .. }
            | Step::ResidualRestrict { level, .. }
            | Step::Prolong { level, .. }
            | Step::RestrictSum { level }
            | Step::CoarsestSolve { level } => level,
            Step::Lift => 0,
            Step::Fused { .. } => shape.fused_from().unwrap_or(shape.coarsest()),
        }
    }

    /// Work units: a colour [`colour_work_units`], every other step 0 (a fused step counts its
    /// steps).
    pub fn work_units(self, shape: &CycleShape) -> f64 {
        match self {
            Step::Smooth { level, .. } => colour_work_units(level),
            Step::Fused { fmg } => fused_steps(shape, fmg)
                .iter()
                .map(|s| s.work_units(shape))
                .sum(),
            _ => 0.0,
        }
    }
}

/// One sweep on `level`: its colours ascending (`pre`) or descending.
fn sweep(level: usize, pre: bool, out: &mut Vec<Step>) {
    let n = colours(level);
    for c in 0..n {
        let colour = if pre { c } else { n - 1 - c };
        out.push(Step::Smooth { level, colour });
    }
}

/// The cycle on coarse level `k >= 1` for `(u_k, f_k)`: pre-sweeps, residual restricted, `u_{k+1}
/// = 0`, [`CycleShape::visits`] cycles on level `k + 1`, prolongation, post-sweeps; the exact
/// solve on the coarsest level.
pub fn coarse_cycle(shape: &CycleShape, k: usize, out: &mut Vec<Step>) {
    if Some(k) == shape.fused_from() {
        out.push(Step::Fused { fmg: false });
        return;
    }
    if k == shape.coarsest() {
        out.push(Step::CoarsestSolve { level: k });
        return;
    }
    for _ in 0..shape.pre_sweeps {
        sweep(k, true, out);
    }
    out.push(Step::ResidualRestrict {
        level: k,
        solution: false,
    });
    out.push(Step::Clear { level: k + 1 });
    for _ in 0..shape.visits(k) {
        coarse_cycle(shape, k + 1, out);
    }
    out.push(Step::Prolong {
        level: k,
        set: false,
        solution: false,
    });
    for _ in 0..shape.post_sweeps {
        sweep(k, false, out);
    }
}

/// The preconditioner `z = M r`: one cycle on level 0 from `z = 0`.
pub fn precondition(shape: &CycleShape) -> Vec<Step> {
    let mut out = vec![Step::Clear { level: 0 }];
    for _ in 0..shape.pre_sweeps {
        sweep(0, true, &mut out);
    }
    out.push(Step::ResidualRestrict {
        level: 0,
        solution: false,
    });
    out.push(Step::Clear { level: 1 });
    for _ in 0..shape.visits(0) {
        coarse_cycle(shape, 1, &mut out);
    }
    out.push(Step::Prolong {
        level: 0,
        set: false,
        solution: false,
    });
    for _ in 0..shape.post_sweeps {
        sweep(0, false, &mut out);
    }
    out
}

/// FMG from scratch up to `h = g + P u_1`: the lift, `f_1 = R (f - A g)`, [`fmg_coarse`] from
/// level 1, the prolongation to level 0.
pub fn fmg(shape: &CycleShape) -> Vec<Step> {
    let mut out = vec![
        Step::Lift,
        Step::ResidualRestrict {
            level: 0,
            solution: true,
        },
    ];
    fmg_coarse(shape, 1, &mut out);
    out.push(Step::Prolong {
        level: 0,
        set: false,
        solution: true,
    });
    out
}

/// FMG's steps on levels `top ..`, from `f_top`: the sums down (`f_{k+1} = R f_k`), the exact
/// coarsest solve, then for `k = kc-1 .. top`: `u_k = P u_{k+1}` and one cycle on level `k`. The
/// levels from `shape.fused_from()` down are one [`Step::Fused`].
pub fn fmg_coarse(shape: &CycleShape, top: usize, out: &mut Vec<Step>) {
    let kc = shape.coarsest();
    let fused = shape.fused_from().filter(|&kf| kf >= top);
    let bottom = fused.unwrap_or(kc);
    for level in top..bottom {
        out.push(Step::RestrictSum { level });
    }
    out.push(match fused {
        Some(_) => Step::Fused { fmg: true },
        None => Step::CoarsestSolve { level: kc },
    });
    for k in (top..bottom).rev() {
        out.push(Step::Prolong {
            level: k,
            set: true,
            solution: false,
        });
        coarse_cycle(shape, k, out);
    }
}

/// The steps a [`Step::Fused`] stands for, unfused (empty without fused levels): one cycle on
/// level `shape.fused_from()`, or FMG's steps from the sums on that level.
pub fn fused_steps(shape: &CycleShape, fmg: bool) -> Vec<Step> {
    let Some(kf) = shape.fused_from() else {
        return Vec::new();
    };
    let unfused = CycleShape {
        fuse_side: 0,
        ..*shape
    };
    let mut out = Vec::new();
    if fmg {
        fmg_coarse(&unfused, kf, &mut out);
    } else {
        coarse_cycle(&unfused, kf, &mut out);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The work-unit scales are exact powers of two: a coarse colour's share is the GPU's former
    /// `0.25 * 0.25^k`, a level-0 colour half a sweep.
    #[test]
    fn work_units_of_one_colour() {
        let s = CycleShape::unfused(6, &SolverParams::default());
        assert_eq!(
            Step::Smooth {
                level: 0,
                colour: 1
            }
            .work_units(&s),
            0.5
        );
        for k in 1..6 {
            let w = Step::Smooth {
                level: k,
                colour: 3,
            }
            .work_units(&s);
            assert_eq!(w, 0.25 * 0.25f64.powi(k as i32));
        }
        assert_eq!(Step::CoarsestSolve { level: 5 }.work_units(&s), 0.0);
    }

    /// Every cycle visits the coarsest level once per visit of its parent, and a sweep's colours
    /// come ascending before the correction and descending after it.
    #[test]
    fn cycle_structure() {
        let p = SolverParams::default();
        let s = CycleShape::unfused(4, &p);
        let pre = precondition(&s);
        let solves = pre
            .iter()
            .filter(|st| matches!(st, Step::CoarsestSolve { .. }))
            .count();
        assert_eq!(
            solves, 2,
            "level 2 twice from level 1, level 3 once from each"
        );
        assert_eq!(
            pre[..4],
            [
                Step::Clear { level: 0 },
                Step::Smooth {
                    level: 0,
                    colour: 0
                },
                Step::Smooth {
                    level: 0,
                    colour: 1
                },
                Step::ResidualRestrict {
                    level: 0,
                    solution: false
                },
            ]
        );
        assert_eq!(
            pre[pre.len() - 2..],
            [
                Step::Smooth {
                    level: 0,
                    colour: 1
                },
                Step::Smooth {
                    level: 0,
                    colour: 0
                },
            ]
        );
        assert!(!pre.iter().any(|s| matches!(s, Step::Fused { .. })));
        let fused = CycleShape::new(8, &p);
        assert_eq!(fused.fused_from(), Some(4));
        let f = fmg(&fused);
        let expanded: Vec<Step> = f
            .iter()
            .flat_map(|s| match s {
                Step::Fused { fmg } => fused_steps(&fused, *fmg),
                s => vec![*s],
            })
            .collect();
        assert_eq!(expanded, fmg(&CycleShape::unfused(8, &p)));
    }
}
