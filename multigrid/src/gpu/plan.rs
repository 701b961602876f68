//! The GPU work as data: every pass of FMG, the preconditioner and FCG is an [`Op`] (kernel + level +
//! variant); a plan is a list of [`Step`]s built by plain functions, which the executor encodes. Dispatch
//! sizes and work units come from the same data, so all of it is unit-tested without a GPU.

use super::params::{
    MAX_PARTIALS, REDUCTION_WORKGROUP, STAGE_PQ, STAGE_R, STAGE_RZ, STAGE_Z, STAGE_ZPQ, TILE,
};
use super::shaders::Kernel;
use crate::cycle;
pub use crate::cycle::{CycleShape, FUSED_SIDE, MIN_FUSED_LEVEL, fused_from};
use crate::grid::COARSEST_SIDE;

/// Workgroups of an 8 x 8 kernel covering `x` by `y` threads.
pub fn groups_2d(x: usize, y: usize) -> [u32; 3] {
    [(x as u32).div_ceil(TILE), (y as u32).div_ceil(TILE), 1]
}

/// Workgroups of a reduction over `cells` values (each thread strides when the cap is reached).
pub fn partial_groups(cells: usize) -> u32 {
    (cells as u64)
        .div_ceil(REDUCTION_WORKGROUP as u64)
        .clamp(1, MAX_PARTIALS as u64) as u32
}

/// Side of the finest stored min/max level: `min(n, MINMAX_MAX_SIDE)` (64).
pub fn minmax_finest_side(n: usize) -> usize {
    n.min(crate::pyramid::MINMAX_MAX_SIDE)
}

/// Workgroups of `minmax_base` (one per cell of the finest stored level).
pub fn minmax_base_groups(n: usize) -> [u32; 3] {
    let s = minmax_finest_side(n) as u32;
    [s, s, 1]
}

/// Element offset of lift level `k >= 1` in the packed lift storage of a level-0 side `n` (levels
/// 1 ..= log2 n, level `k` of side `n >> k`; as `cpu/lift.rs`).
pub fn lift_offset(n: usize, k: usize) -> usize {
    (1..k).map(|l| (n >> l) * (n >> l)).sum()
}

/// Elements of the packed lift storage of a level-0 side `n` (levels 1 ..= log2 n; `(n^2 - 1) / 3`).
pub fn lift_len(n: usize) -> usize {
    lift_offset(n, n.trailing_zeros() as usize + 1)
}

/// One pass of the solver: a kernel on a level, with its variant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Op {
    /// Level-0 operator (diag, f, hard h) from the problem; `cold`: also `h = 0` on free cells.
    /// (Level 1's stencils are not stored: every level-1 pass computes them from the level-0
    /// diagonal, `shared/coarse_level1.wgsl`.)
    Assemble { cold: bool },
    /// Level-`level` stencils from level `level - 1` (`level >= 2`; level 2 from level 1's
    /// stencils computed from the level-0 diagonal).
    GalerkinCoarse { level: usize },
    /// One red-black colour on level 0, on `(z, r)`.
    SmoothLevel0 { colour: u32 },
    /// [`Op::ProlongLevel0`] (`z += P u_1`) and the post-sweep's first colour in one pass: the
    /// colour reads the prolonged neighbours it needs, computed where read, and the next colour
    /// pass overwrites the other colour's free cells, so nothing else of the prolongation is used.
    ProlongSmoothLevel0 { colour: u32 },
    /// The first red-black sweep on level 0 from `z = 0` (both colours) in one dispatch over
    /// 16 x 16 tiles (`smooth_level0_tiles.wgsl`): the values of the two colour passes.
    SweepLevel0FromZero,
    /// [`Op::SweepLevel0FromZero`] and the [`Op::ResidualRestrictLevel0`] after it in one
    /// dispatch: each tile restricts its residual from its workgroup copy (a ring of 3 cells).
    SweepRestrictLevel0FromZero,
    /// One of 4 colours on coarse level `level`.
    SmoothCoarse { level: usize, colour: u32 },
    /// `phases` colours (one or two whole sweeps; colour of phase m in bits 2m, 2m + 1 of
    /// `colours`) on coarse level `level` in one dispatch over 16 x 16 tiles
    /// (`smooth_coarse_tiles.wgsl`), from `u = 0` (`from_zero`) or from the level's `alt` buffer,
    /// into `u`: the same values as the colour passes; with `restrict`, also the
    /// [`Op::ResidualRestrictCoarse`] that follows, from each tile's copy (a ring one cell wider).
    SweepCoarse {
        level: usize,
        colours: u32,
        phases: u32,
        from_zero: bool,
        restrict: bool,
    },
    /// `f_1 = R (r - A z)` (preconditioner) or `f_1 = R (f - A h)` (`solution`: FMG start, `h` = the
    /// lift).
    ResidualRestrictLevel0 { solution: bool },
    /// `f_{level+1} = R (f - A u)` on coarse level `level`.
    ResidualRestrictCoarse { level: usize },
    /// `z += P u_1` (preconditioner) or `h += P u_1` (`solution`: end of FMG, `h = g + P u_1`), free
    /// cells only.
    ProlongLevel0 { solution: bool },
    /// `u_level += P u_{level+1}`, or `=` with inactive cells zeroed (`set`).
    ProlongCoarse { level: usize, set: bool },
    /// [`Op::ProlongCoarse`] into the level's `alt` buffer (every cell), the input of the
    /// [`Op::SweepCoarse`] that follows.
    ProlongCoarseAlt { level: usize, set: bool },
    /// `f_{level+1} = R f_level`.
    RestrictSum { level: usize },
    /// Exact solve on the coarsest level.
    CoarsestSolve,
    /// The local relaxation's windows: `z` = the seeds of `r` dilated, in 16 x 16 tiles, counted
    /// and bounded by a box (`mode` 0), then the workgroups of the colour passes over that box
    /// (`mode` 1, one thread); modes 2 and 3 are the same for FCG's stop-test relaxation
    /// ([`spike_relaxation`]).
    RelaxMask { mode: u32 },
    /// `sweeps` (at most [`MAX_RELAX_TILE_SWEEPS`]; 0 copies) red-black sweeps of the local
    /// relaxation of `h` in the windows (`z`) in one dispatch over 16 x 16 tiles of the windows' box
    /// (the workgroups `RelaxMask { mode: 1 }` wrote), from `h` into `r` (`to_z`: the scratch
    /// vector, once `z`) or back.
    RelaxTiles { sweeps: u32, to_z: bool },
    /// FCG's stop-test relaxation ([`spike_relaxation`]): `sweeps` red-black sweeps of the
    /// correction `A d = r` from `d = 0` in its windows, in one dispatch over 16 x 16 tiles of
    /// their box, `d` into `p` (FCG restarts after it).
    SpikeRelax { sweeps: u32 },
    /// The stop-test relaxation's update on the same tiles: `h += d` in the windows, `r -= A d`.
    SpikeUpdate,
    /// `r = f - A h`. (FCG's `q = A p` is never stored: `DotPartial` and `FcgUpdate` recompute it
    /// from `p` and `diag`, see `shaders/shared/apply_p.wgsl`.)
    ApplyLevel0,
    /// Reduction first pass of a stage (`STAGE_*`).
    DotPartial { stage: u32 },
    /// The preconditioner's last level-0 colour and the [`Op::DotPartial`] of `stage`
    /// (`STAGE_Z` or `STAGE_RZ`) after it in one pass (`smooth_dot_level0.wgsl`), with `z.A z`
    /// for [`Op::DotFinal`]'s `STAGE_ZPQ` (`colour` 2: the reduction alone).
    SmoothDotLevel0 { stage: u32, colour: u32 },
    /// Reduction second pass and scalars of a stage.
    DotFinal { stage: u32 },
    /// FCG update: 0 = `h, r` axpys, 1 = `p = z + beta p`, 2 = `p = z`.
    FcgUpdate { mode: u32 },
    /// FMG lift push of level `level >= 1` (`W`, `V`) from level `level - 1` (level 0: `a_0`, `E`).
    LiftPush { level: usize },
    /// FMG lift pull: `g_level` from `g_{level+1}` (`level == 0`: `h = g_0`).
    LiftPull { level: usize },
    /// FCG's stop test on the GPU: the indirect arguments of the stage that follows (`count`: an
    /// iteration, counted; else the first direction).
    Gate { count: bool },
    /// FCG's stop test on the GPU before its stop-test relaxation ([`spike_relaxation`]): the
    /// indirect arguments of its passes, all of them when the iteration before left
    /// `stop_rmax < rmax <= SPIKE_BAND stop_rmax`.
    SpikeGate,
    /// Every pass on the levels from `shape.fused_from()` down, in one dispatch of one workgroup
    /// (`coarse_fused.wgsl`): the cycle on that level (`fmg`: FMG's coarse part below it, from
    /// the restriction of its right-hand side on). Runs the steps of [`Op::fused_steps`] in
    /// their order, with a barrier after each.
    CoarseFused { shape: CycleShape, fmg: bool },
}

impl Op {
    /// The kernel of this pass on a hierarchy whose coarsest level is `coarsest`, with the level-0
    /// solution `h` in mip 0 of the height texture when `texture_h`: the passes that read level 1's
    /// stencils use the variants that compute them from the level-0 diagonal, the passes that bind
    /// `h` (not those binding `z` in its place) the variants that find it in the texture.
    pub fn kernel(self, coarsest: usize, texture_h: bool) -> Kernel {
        let k = self.base_kernel(coarsest);
        let binds_h = match self {
            Op::ResidualRestrictLevel0 { solution } | Op::ProlongLevel0 { solution } => solution,
            _ => true,
        };
        match k.with_texture_h() {
            Some(t) if texture_h && binds_h => t,
            _ => k,
        }
    }

    /// [`Self::kernel`] with `h` in a buffer.
    fn base_kernel(self, coarsest: usize) -> Kernel {
        match self {
            Op::Assemble { .. } => Kernel::AssembleLevel0,
            Op::GalerkinCoarse { level: 2 } => Kernel::GalerkinLevel2,
            Op::GalerkinCoarse { .. } => Kernel::GalerkinCoarse,
            Op::SmoothLevel0 { .. } | Op::ProlongSmoothLevel0 { .. } => Kernel::SmoothLevel0,
            Op::SweepLevel0FromZero | Op::SweepRestrictLevel0FromZero => Kernel::SmoothLevel0Tiles,
            Op::RelaxMask { .. } => Kernel::RelaxMask,
            Op::RelaxTiles { .. } | Op::SpikeRelax { .. } => Kernel::RelaxTiles,
            Op::SpikeUpdate => Kernel::SpikeUpdate,
            Op::SmoothCoarse { level: 1, .. } => Kernel::SmoothLevel1,
            Op::SmoothCoarse { .. } => Kernel::SmoothCoarse,
            Op::SweepCoarse { level: 1, .. } => Kernel::SmoothLevel1Tiles,
            Op::SweepCoarse { .. } => Kernel::SmoothCoarseTiles,
            Op::ResidualRestrictLevel0 { .. } => Kernel::ResidualRestrictLevel0,
            Op::ResidualRestrictCoarse { level: 1 } => Kernel::ResidualRestrictLevel1,
            Op::ResidualRestrictCoarse { .. } => Kernel::ResidualRestrictCoarse,
            Op::ProlongLevel0 { .. } => Kernel::ProlongLevel0,
            Op::ProlongCoarse { level: 1, .. } => Kernel::ProlongLevel1,
            Op::ProlongCoarse { .. } => Kernel::ProlongCoarse,
            Op::ProlongCoarseAlt { level: 1, .. } => Kernel::ProlongLevel1Alt,
            Op::ProlongCoarseAlt { .. } => Kernel::ProlongCoarseAlt,
            Op::RestrictSum { .. } => Kernel::RestrictSum,
            Op::CoarsestSolve if coarsest == 1 => Kernel::CoarsestSolveLevel1,
            Op::CoarsestSolve => Kernel::CoarsestSolve,
            Op::ApplyLevel0 => Kernel::ApplyLevel0,
            Op::DotPartial { .. } => Kernel::DotPartial,
            Op::SmoothDotLevel0 { .. } => Kernel::SmoothDotLevel0,
            Op::DotFinal { .. } => Kernel::DotFinal,
            Op::FcgUpdate { .. } => Kernel::FcgUpdate,
            Op::LiftPush { .. } => Kernel::LiftPush,
            Op::LiftPull { .. } => Kernel::LiftPull,
            Op::Gate { .. } | Op::SpikeGate => Kernel::FcgGate,
            Op::CoarseFused { .. } => Kernel::CoarseFused,
        }
    }

    /// The passes a [`Op::CoarseFused`] runs, as the unfused plan names them (empty for other
    /// ops): one cycle on level `shape.fused_from()`, or FMG's passes from the sums on that level
    /// to its cycle.
    pub fn fused_steps(self) -> Vec<Step> {
        let Op::CoarseFused { shape, fmg } = self else {
            return Vec::new();
        };
        let mut out = Vec::new();
        colour_passes(&shape, &cycle::fused_steps(&shape, fmg), &mut out);
        out
    }

    /// The level the op names: the level built by a Galerkin pass, the finer level of a transfer, the
    /// level smoothed or solved; 0 for level-0 and FCG passes.
    pub fn level(self, coarsest: usize) -> usize {
        match self {
            Op::GalerkinCoarse { level } => level,
            Op::SmoothCoarse { level, .. }
            | Op::SweepCoarse { level, .. }
            | Op::ResidualRestrictCoarse { level }
            | Op::ProlongCoarse { level, .. }
            | Op::ProlongCoarseAlt { level, .. }
            | Op::RestrictSum { level }
            | Op::LiftPush { level }
            | Op::LiftPull { level } => level,
            Op::CoarsestSolve => coarsest,
            Op::CoarseFused { shape, .. } => shape.fused_from().unwrap_or(coarsest),
            _ => 0,
        }
    }

    /// The level whose `alt` buffer the pass binds (levels above the fused ones have one).
    pub fn alt_level(self) -> Option<usize> {
        match self {
            Op::SweepCoarse { level, .. } | Op::ProlongCoarseAlt { level, .. } => Some(level),
            _ => None,
        }
    }

    /// Label of the pass, e.g. `multigrid.smooth_coarse.l3.c2`.
    pub fn label(self, coarsest: usize) -> String {
        let base = format!(
            "multigrid.{}.l{}",
            self.base_kernel(coarsest).file(),
            self.level(coarsest)
        );
        match self {
            Op::SmoothLevel0 { colour } | Op::SmoothCoarse { colour, .. } => {
                format!("{base}.c{colour}")
            }
            Op::ProlongSmoothLevel0 { colour } => format!("{base}.prolong.c{colour}"),
            Op::SweepRestrictLevel0FromZero => format!("{base}.restrict"),
            Op::RelaxTiles { sweeps, to_z } => {
                format!("{base}.s{sweeps}{}", if to_z { ".z" } else { ".h" })
            }
            Op::SpikeRelax { sweeps } => format!("{base}.spike.s{sweeps}"),
            Op::SpikeUpdate => format!("{base}.spike.update"),
            Op::SpikeGate => format!("{base}.spike"),
            Op::RelaxMask { mode } => format!("{base}.m{mode}"),
            Op::ResidualRestrictLevel0 { solution: true }
            | Op::ProlongLevel0 { solution: true } => {
                format!("{base}.h")
            }
            Op::ProlongCoarse { set: true, .. } | Op::ProlongCoarseAlt { set: true, .. } => {
                format!("{base}.set")
            }
            Op::SweepCoarse {
                phases,
                from_zero,
                restrict,
                ..
            } => format!(
                "{base}.p{phases}{}{}",
                if from_zero { ".zero" } else { "" },
                if restrict { ".restrict" } else { "" }
            ),
            Op::ApplyLevel0 => format!("{base}.residual"),
            Op::Assemble { cold: true } => format!("{base}.cold"),
            Op::DotPartial { stage } | Op::DotFinal { stage } => format!("{base}.s{stage}"),
            Op::SmoothDotLevel0 { stage, colour } => format!("{base}.s{stage}.c{colour}"),
            Op::FcgUpdate { mode } => format!("{base}.m{mode}"),
            Op::Gate { count } => format!("{base}.m{}", count as u32),
            Op::CoarseFused { fmg: true, .. } => format!("{base}.fmg"),
            _ => base,
        }
    }

    /// Workgroups to dispatch on a hierarchy whose level 0 has side `n`.
    pub fn workgroups(self, n: usize) -> [u32; 3] {
        let side = |k: usize| n >> k;
        match self {
            Op::Assemble { .. } | Op::ProlongLevel0 { .. } | Op::ApplyLevel0 => groups_2d(n, n),
            Op::RelaxMask { mode: 0 | 2 } => {
                let tiles = n.div_ceil(TILE_SIDE) as u32;
                [tiles, tiles, 1]
            }
            Op::RelaxMask { .. } => [1, 1, 1],
            Op::ResidualRestrictLevel0 { .. } => groups_2d(n / 2, n / 2),
            Op::GalerkinCoarse { level } => groups_2d(side(level), side(level)),
            Op::SmoothLevel0 { .. } | Op::ProlongSmoothLevel0 { .. } => groups_2d(n / 2, n),
            Op::SweepLevel0FromZero | Op::SweepRestrictLevel0FromZero => {
                let tiles = n.div_ceil(TILE_SIDE) as u32;
                [tiles, tiles, 1]
            }
            // The whole level's tiles (a plan dispatches them indirectly, over the box).
            Op::RelaxTiles { .. } | Op::SpikeRelax { .. } | Op::SpikeUpdate => {
                let tiles = n.div_ceil(TILE_SIDE) as u32;
                [tiles, tiles, 1]
            }
            Op::SmoothCoarse { level, .. }
            | Op::ResidualRestrictCoarse { level }
            | Op::RestrictSum { level } => groups_2d(side(level) / 2, side(level) / 2),
            Op::ProlongCoarse { level, .. }
            | Op::ProlongCoarseAlt { level, .. }
            | Op::LiftPull { level } => groups_2d(side(level), side(level)),
            Op::SweepCoarse { level, .. } => {
                let tiles = side(level).div_ceil(TILE_SIDE) as u32;
                [tiles, tiles, 1]
            }
            Op::LiftPush { level } => groups_2d(side(level), side(level)),
            Op::CoarsestSolve
            | Op::DotFinal { .. }
            | Op::Gate { .. }
            | Op::SpikeGate
            | Op::CoarseFused { .. } => [1, 1, 1],
            // FcgUpdate strides over the cells as DotPartial does (mode 0 writes its partials).
            Op::DotPartial { .. } | Op::FcgUpdate { .. } | Op::SmoothDotLevel0 { .. } => {
                [partial_groups(n * n), 1, 1]
            }
        }
    }

    /// Work units of the pass: a colour on level 0 is half a sweep (1 WU per sweep), one of the 4 colours
    /// on level k a quarter of `4^-k`; everything else counts 0 (as on the CPU). The local
    /// relaxation counts the cells of its windows instead (read back, see [`local_relaxation`]).
    pub fn work_units(self) -> f64 {
        match self {
            Op::SmoothLevel0 { .. } | Op::ProlongSmoothLevel0 { .. } => cycle::colour_work_units(0),
            Op::SmoothDotLevel0 { colour, .. } if colour < 2 => cycle::colour_work_units(0),
            Op::SweepLevel0FromZero | Op::SweepRestrictLevel0FromZero => cycle::sweep_work_units(0),
            Op::SmoothCoarse { level, .. } => cycle::colour_work_units(level),
            Op::SweepCoarse { level, phases, .. } => {
                phases as f64 * cycle::colour_work_units(level)
            }
            Op::CoarseFused { .. } => work_units(&self.fused_steps()),
            _ => 0.0,
        }
    }
}

/// One step of a plan.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Step {
    /// A compute dispatch.
    Dispatch(Op),
    /// A compute dispatch whose workgroups the last [`Op::Gate`] wrote (indirect): all of them, or
    /// none once FCG has stopped.
    Gated(Op),
    /// `u_level = 0`.
    ClearU { level: usize },
    /// `z = 0`.
    ClearZ,
    /// Copy `rmax`, `status` of the scalars to the 8-byte staging buffer.
    CopyStatus,
    /// Copy `relax_cells` and `relax_groups` of the scalars to the staging buffer, after `rmax` and
    /// `status`.
    CopyRelaxCells,
    /// Copy the whole scalar block to the staging buffer (after a queued run, see [`fcg_queued`]).
    CopyScalars,
    /// Copy the stop-test relaxation's cells, tile workgroups and runs
    /// ([`super::params::SPIKE_CELLS`] ..) to the staging buffer, after `rmax` and `status` (an
    /// iteration driven by the CPU reads the 20 bytes).
    CopySpike,
}

/// Step kinds of a fused program (`coarse_fused.wgsl`'s `K_*`, keep in sync).
pub mod fused_kind {
    /// One colour of `smooth_coarse`.
    pub const SMOOTH: u32 = 0;
    /// `residual_restrict_coarse`.
    pub const RESIDUAL_RESTRICT: u32 = 1;
    /// `u = 0`.
    pub const CLEAR_U: u32 = 2;
    /// `prolong_coarse`, `u += P uc`.
    pub const PROLONG_ADD: u32 = 3;
    /// `prolong_coarse`, `u = P uc` (inactive cells 0).
    pub const PROLONG_SET: u32 = 4;
    /// `restrict_sum`.
    pub const RESTRICT_SUM: u32 = 5;
    /// `coarsest_solve`.
    pub const COARSEST_SOLVE: u32 = 6;
}

/// The program [`Op::CoarseFused`] runs: one word per step of [`Op::fused_steps`], `kind | (level
/// - first fused level) << 4 | colour << 8` ([`fused_kind`]).
pub fn fused_program(op: Op) -> Vec<u32> {
    let Op::CoarseFused { shape, .. } = op else {
        return Vec::new();
    };
    let kf = shape.fused_from().unwrap_or(0);
    let word =
        |kind: u32, level: usize, colour: u32| kind | ((level - kf) as u32) << 4 | colour << 8;
    op.fused_steps()
        .into_iter()
        .map(|s| match s {
            Step::Dispatch(Op::SmoothCoarse { level, colour }) => {
                word(fused_kind::SMOOTH, level, colour)
            }
            Step::Dispatch(Op::ResidualRestrictCoarse { level }) => {
                word(fused_kind::RESIDUAL_RESTRICT, level, 0)
            }
            Step::ClearU { level } => word(fused_kind::CLEAR_U, level, 0),
            Step::Dispatch(Op::ProlongCoarse { level, set }) => {
                let kind = if set {
                    fused_kind::PROLONG_SET
                } else {
                    fused_kind::PROLONG_ADD
                };
                word(kind, level, 0)
            }
            Step::Dispatch(Op::RestrictSum { level }) => word(fused_kind::RESTRICT_SUM, level, 0),
            Step::Dispatch(Op::CoarsestSolve) => {
                word(fused_kind::COARSEST_SOLVE, shape.coarsest(), 0)
            }
            s => unreachable!("{s:?} in a fused cycle"),
        })
        .collect()
}

/// The [`Op::CoarseFused`] passes of `shape` (none without fused levels): the cycle, FMG's part.
pub fn fused_ops(shape: &CycleShape) -> Vec<Op> {
    if shape.fused_from().is_none() {
        return Vec::new();
    }
    [false, true]
        .map(|fmg| Op::CoarseFused { shape: *shape, fmg })
        .to_vec()
}

/// The passes of the cycle's steps `steps` (`crate::cycle`) on a solver of shape `shape`: one
/// pass per step, the lift's passes for [`cycle::Step::Lift`], then the colours of whole coarse
/// sweeps joined into tile passes ([`tile_sweeps`]).
pub fn passes(shape: &CycleShape, steps: &[cycle::Step], out: &mut Vec<Step>) {
    let mut one = Vec::new();
    colour_passes(shape, steps, &mut one);
    out.extend(fuse_passes(tile_sweeps(one)));
}

/// `steps` with the level-0 sweep from zero and the residual restriction after it joined
/// ([`Op::SweepRestrictLevel0FromZero`]), likewise a coarse tile sweep and the restriction after
/// it (`restrict` of [`Op::SweepCoarse`]), and each preconditioner prolongation onto level 0 that
/// two colour passes follow joined with the first of them ([`Op::ProlongSmoothLevel0`]).
pub fn fuse_passes(steps: Vec<Step>) -> Vec<Step> {
    let mut out: Vec<Step> = Vec::with_capacity(steps.len());
    let mut i = 0;
    while i < steps.len() {
        if let [
            Step::Dispatch(Op::SweepLevel0FromZero),
            Step::Dispatch(Op::ResidualRestrictLevel0 { solution: false }),
            ..,
        ] = steps[i..]
        {
            out.push(Step::Dispatch(Op::SweepRestrictLevel0FromZero));
            i += 2;
            continue;
        }
        if let [
            Step::Dispatch(Op::SweepCoarse {
                level,
                colours,
                phases,
                from_zero,
                restrict: false,
            }),
            Step::Dispatch(Op::ResidualRestrictCoarse { level: next }),
            ..,
        ] = steps[i..]
            && next == level
        {
            out.push(Step::Dispatch(Op::SweepCoarse {
                level,
                colours,
                phases,
                from_zero,
                restrict: true,
            }));
            i += 2;
            continue;
        }
        if let [
            Step::Dispatch(Op::ProlongLevel0 { solution: false }),
            Step::Dispatch(Op::SmoothLevel0 { colour }),
            Step::Dispatch(Op::SmoothLevel0 { colour: next }),
            ..,
        ] = steps[i..]
            && next == 1 - colour
        {
            out.push(Step::Dispatch(Op::ProlongSmoothLevel0 { colour }));
            out.push(steps[i + 2]);
            i += 3;
            continue;
        }
        out.push(steps[i]);
        i += 1;
    }
    out
}

/// Side of the tiles of [`Op::SweepCoarse`] (`smooth_coarse_tiles.wgsl`'s `TILE`).
pub const TILE_SIDE: usize = 16;
/// Most colour phases of one [`Op::SweepCoarse`] (`smooth_coarse_tiles.wgsl`'s `MAX_PHASES`):
/// two sweeps, a post-sweep and the next visit's pre-sweep.
pub const MAX_TILE_PHASES: usize = 8;

/// `steps` with each run of whole coarse sweeps on one level (at most [`MAX_TILE_PHASES`]
/// colours) that starts from `u = 0` (after its clear) or right after a prolongation as one
/// [`Op::SweepCoarse`], the prolongation then writing the level's `alt` buffer
/// ([`Op::ProlongCoarseAlt`]), and the level-0 sweep after `z = 0` as one
/// [`Op::SweepLevel0FromZero`]. Other colour passes stay as they are: a tile pass cannot read
/// the `u` its neighbour tiles write (level 0 has no `alt`: a level-sized buffer more).
pub fn tile_sweeps(steps: Vec<Step>) -> Vec<Step> {
    let colour_of = |s: Option<&Step>, level: usize| match s {
        Some(Step::Dispatch(Op::SmoothCoarse { level: l, colour })) if *l == level => Some(*colour),
        _ => None,
    };
    let mut out: Vec<Step> = Vec::with_capacity(steps.len());
    let mut i = 0;
    while i < steps.len() {
        let level0_pre = [0, 1].map(|colour| Step::Dispatch(Op::SmoothLevel0 { colour }));
        if out.last() == Some(&Step::ClearZ) && steps[i..].starts_with(&level0_pre) {
            out.push(Step::Dispatch(Op::SweepLevel0FromZero));
            i += 2;
            continue;
        }
        let Step::Dispatch(Op::SmoothCoarse { level, .. }) = steps[i] else {
            out.push(steps[i]);
            i += 1;
            continue;
        };
        let mut run = 0;
        while run < MAX_TILE_PHASES && colour_of(steps.get(i + run), level).is_some() {
            run += 1;
        }
        let phases = run - run % cycle::COARSE_COLOURS as usize;
        let start = match out.last() {
            Some(Step::ClearU { level: l }) if *l == level => Some(true),
            Some(Step::Dispatch(Op::ProlongCoarse { level: l, .. })) if *l == level => Some(false),
            _ => None,
        };
        let Some(from_zero) = start.filter(|_| phases > 0) else {
            out.push(steps[i]);
            i += 1;
            continue;
        };
        if let Some(Step::Dispatch(op)) = out.last_mut()
            && let Op::ProlongCoarse { level, set } = *op
        {
            *op = Op::ProlongCoarseAlt { level, set };
        }
        let colours = (0..phases)
            .filter_map(|m| colour_of(steps.get(i + m), level).map(|c| c << (2 * m)))
            .fold(0, |a, c| a | c);
        out.push(Step::Dispatch(Op::SweepCoarse {
            level,
            colours,
            phases: phases as u32,
            from_zero,
            restrict: false,
        }));
        i += phases;
    }
    out
}

/// The [`Op::SweepCoarse`] of the whole sweeps `run` on `level` (`true`: a pre-sweep, colours
/// ascending; `false`: descending).
pub fn sweep_op(level: usize, run: &[bool], from_zero: bool) -> Op {
    let n = cycle::COARSE_COLOURS;
    let colours = run.iter().enumerate().fold(0, |acc, (k, &pre)| {
        (0..n).fold(acc, |acc, c| {
            let colour = if pre { c } else { n - 1 - c };
            acc | colour << (2 * (k as u32 * n + c))
        })
    });
    Op::SweepCoarse {
        level,
        colours,
        phases: run.len() as u32 * n,
        from_zero,
        restrict: false,
    }
}

/// [`passes`] with every colour of a sweep as its own pass (the fused pass's program).
fn colour_passes(shape: &CycleShape, steps: &[cycle::Step], out: &mut Vec<Step>) {
    use cycle::Step as C;
    for s in steps {
        out.push(match *s {
            C::Clear { level: 0 } => Step::ClearZ,
            C::Clear { level } => Step::ClearU { level },
            C::Smooth { level: 0, colour } => Step::Dispatch(Op::SmoothLevel0 { colour }),
            C::Smooth { level, colour } => Step::Dispatch(Op::SmoothCoarse { level, colour }),
            C::ResidualRestrict { level: 0, solution } => {
                Step::Dispatch(Op::ResidualRestrictLevel0 { solution })
            }
            C::ResidualRestrict { level, .. } => {
                Step::Dispatch(Op::ResidualRestrictCoarse { level })
            }
            C::Prolong {
                level: 0, solution, ..
            } => Step::Dispatch(Op::ProlongLevel0 { solution }),
            C::Prolong { level, set, .. } => Step::Dispatch(Op::ProlongCoarse { level, set }),
            C::RestrictSum { level } => Step::Dispatch(Op::RestrictSum { level }),
            C::CoarsestSolve { .. } => Step::Dispatch(Op::CoarsestSolve),
            C::Lift => {
                out.extend(lift(shape));
                continue;
            }
            C::Fused { fmg } => Step::Dispatch(Op::CoarseFused { shape: *shape, fmg }),
        });
    }
}

/// The cycle on coarse level `k >= 1` for `(u_k, f_k)` ([`cycle::coarse_cycle`]).
pub fn coarse_cycle(shape: &CycleShape, k: usize, out: &mut Vec<Step>) {
    let mut steps = Vec::new();
    cycle::coarse_cycle(shape, k, &mut steps);
    passes(shape, &steps, out);
}

/// `z = M r`: one cycle on level 0 from `z = 0` ([`cycle::precondition`]).
pub fn precondition(shape: &CycleShape) -> Vec<Step> {
    let mut out = Vec::new();
    passes(shape, &cycle::precondition(shape), &mut out);
    out
}

/// Operator assembly after an upload: level 0 (`cold`: with `h = 0` on free cells), then every
/// stored Galerkin level (2 ..; level 1's stencils are computed where they are read).
pub fn assemble(shape: &CycleShape, cold: bool) -> Vec<Step> {
    let mut out = vec![Step::Dispatch(Op::Assemble { cold })];
    for level in 2..shape.levels {
        out.push(Step::Dispatch(Op::GalerkinCoarse { level }));
    }
    out
}

/// The FMG lift (`cpu/lift.rs`): push levels 1 ..= L, pull levels L-1 .. 0; leaves `h = g_0` and `g_k`
/// (k >= 1) in the packed storage (`p`, the weights in level-0 `z`).
pub fn lift(shape: &CycleShape) -> Vec<Step> {
    let top = shape.lift_levels();
    let mut out: Vec<Step> = (1..=top)
        .map(|level| Step::Dispatch(Op::LiftPush { level }))
        .collect();
    for level in (0..top).rev() {
        out.push(Step::Dispatch(Op::LiftPull { level }));
    }
    out
}

/// FMG cold start up to `h = g + P u_1` ([`cycle::fmg`]: the lift, `f_1 = R (f - A g)`, sums
/// down, exact coarsest solve, a cycle on each level from the coarsest up, the prolongation to
/// level 0).
pub fn fmg(shape: &CycleShape) -> Vec<Step> {
    let mut out = Vec::new();
    passes(shape, &cycle::fmg(shape), &mut out);
    out
}

/// `r = f - A h`, `rmax`, copied to the status buffer.
pub fn residual() -> Vec<Step> {
    vec![
        Step::Dispatch(Op::ApplyLevel0),
        Step::Dispatch(Op::DotPartial { stage: STAGE_R }),
        Step::Dispatch(Op::DotFinal { stage: STAGE_R }),
        Step::CopyStatus,
    ]
}

/// Local relaxation of `h` (`Hierarchy::relax_at_residuals` of the CPU): `r = f - A h`, the windows
/// of radius `RADIUS` around the cells whose residual exceeds the threshold (`relax_limit`, written
/// by the CPU), `sweeps` red-black sweeps of `h` there unless they cover more than a quarter of the
/// level (each colour pass dispatched over the windows' box only), and their cell count copied for
/// the work units (`cells * sweeps / n^2`, as on the CPU: the passes themselves count 0). `r` and
/// `z` are left as scratch: FCG's start follows.
pub fn local_relaxation(sweeps: usize) -> Vec<Step> {
    let mut out = vec![
        Step::Dispatch(Op::ApplyLevel0),
        Step::Dispatch(Op::RelaxMask { mode: 0 }),
        Step::Dispatch(Op::RelaxMask { mode: 1 }),
    ];
    out.extend(relax_tiles(sweeps).into_iter().map(Step::Dispatch));
    out.push(Step::CopyRelaxCells);
    out
}

/// FCG's stop-test relaxation after an iteration (the CPU's `relax_spikes` in `cpu/fcg.rs`): if
/// the iteration left `stop_rmax < rmax <= SPIKE_BAND stop_rmax` ([`Op::SpikeGate`]), the windows
/// around the cells of FCG's `r` above `stop_rmax`; unless they cover more than `n^2 /
/// SPIKE_SHARE` cells, `SPIKE_SWEEPS` sweeps of the correction there, `h += d`, `r -= A d` and
/// FCG restarted (`p` held `d`); then `max |r|` again. Its box pass and tile passes run always
/// (over an empty box when the mask did not run).
pub fn spike_relaxation() -> Vec<Step> {
    vec![
        Step::Dispatch(Op::SpikeGate),
        Step::Gated(Op::RelaxMask { mode: 2 }),
        Step::Dispatch(Op::RelaxMask { mode: 3 }),
        Step::Dispatch(Op::SpikeRelax {
            sweeps: crate::cycle::SPIKE_SWEEPS as u32,
        }),
        Step::Dispatch(Op::SpikeUpdate),
        Step::Gated(Op::DotPartial { stage: STAGE_R }),
        Step::Gated(Op::DotFinal { stage: STAGE_R }),
        Step::CopyStatus,
    ]
}

/// Most sweeps of one [`Op::RelaxTiles`] (`relax_tiles.wgsl`'s ring of 2 cells a sweep).
pub const MAX_RELAX_TILE_SWEEPS: u32 = 5;

/// The tile passes of a local relaxation of `sweeps` sweeps: from `h` into `z` and back, each with
/// at most [`MAX_RELAX_TILE_SWEEPS`] (none for 0 sweeps; a last pass of 0 sweeps copies `z` back
/// into `h` when the count of passes would be odd).
pub fn relax_tiles(sweeps: usize) -> Vec<Op> {
    let mut left = sweeps as u32;
    let passes = left.div_ceil(MAX_RELAX_TILE_SWEEPS).next_multiple_of(2);
    (0..passes)
        .map(|k| {
            let share = left.div_ceil(passes - k);
            left -= share;
            Op::RelaxTiles {
                sweeps: share,
                to_z: k % 2 == 0,
            }
        })
        .collect()
}

/// FCG start: the residual (read back for the history), `z = M r`, `rz`, `p = z`.
pub fn fcg_init(shape: &CycleShape) -> Vec<Step> {
    let mut out = residual();
    out.extend(fcg_first_direction(shape));
    out
}

/// The second half of [`fcg_init`], after the residual: `z = M r`, `rz`, `p = z`, `p.q` and
/// `alpha` (run only when the residual does not already meet the tolerance, see
/// `GpuFieldSolver::fcg_relaxed`). Its reduction reads `r` and `z` alone: `z.q` (from `p` and
/// `diag`) would be unused, `p = z` follows.
pub fn fcg_first_direction(shape: &CycleShape) -> Vec<Step> {
    let mut out = precondition_dot(shape, STAGE_RZ);
    out.push(Step::Dispatch(Op::DotFinal { stage: STAGE_ZPQ }));
    out.push(Step::Dispatch(Op::FcgUpdate { mode: 2 }));
    out
}

/// First half of an FCG iteration: `h += alpha p`, `r -= alpha q`, `rmax`, status, with `q = A p`
/// recomputed where it is read (no pass stores it), `alpha = (r.z) / (p.q)` from the direction
/// before (its reduction gives `p.q` from `z.A z`, [`precondition_dot`]). The update writes the
/// `max |r|` partials itself, so no `DotPartial` re-reads `r` before the final `rmax`.
pub fn fcg_step() -> Vec<Step> {
    vec![
        Step::Dispatch(Op::FcgUpdate { mode: 0 }),
        Step::Dispatch(Op::DotFinal { stage: STAGE_R }),
        Step::CopyStatus,
    ]
}

/// [`precondition`] and the reduction of `stage` (`STAGE_Z` or `STAGE_RZ`) with `z.A z` after it,
/// the last level-0 colour and the reduction joined in one [`Op::SmoothDotLevel0`] (without a
/// last colour pass, one that updates nothing).
pub fn precondition_dot(shape: &CycleShape, stage: u32) -> Vec<Step> {
    let mut out = precondition(shape);
    if let Some(Step::Dispatch(op)) = out.last_mut()
        && let Op::SmoothLevel0 { colour } = *op
    {
        *op = Op::SmoothDotLevel0 { stage, colour };
    } else {
        out.push(Step::Dispatch(Op::SmoothDotLevel0 { stage, colour: 2 }));
    }
    out
}

/// Second half, run only when FCG goes on: `z = M r`, `beta`, `rz`, `p = z + beta p`, `p.q`
/// (from `z.A z`, `z.q` and `beta`: the new direction is A-orthogonal to the old) and `alpha`.
pub fn fcg_direction(shape: &CycleShape) -> Vec<Step> {
    let mut out = precondition_dot(shape, STAGE_Z);
    out.push(Step::Dispatch(Op::DotFinal { stage: STAGE_ZPQ }));
    out.push(Step::Dispatch(Op::FcgUpdate { mode: 1 }));
    out
}

/// The dispatches of `steps` gated by the last [`Op::Gate`] (clears and copies stay: a stopped FCG
/// only clears scratch and copies its unchanged status).
pub fn gated(steps: Vec<Step>) -> Vec<Step> {
    steps
        .into_iter()
        .map(|s| match s {
            Step::Dispatch(op) => Step::Gated(op),
            s => s,
        })
        .collect()
}

/// FCG after a local relaxation, queued whole and stopped on the GPU (`fcg_gate.wgsl`): the
/// relaxation of `sweeps` sweeps, the residual, then (if `start`) the first direction unless the
/// tolerance holds and `iterations` gated iterations, and the scalars copied for one read at the
/// end. Without `start` the run is the relaxation alone (a warm field that usually needs no more). Runs the same
/// passes, in the same order, as the CPU-driven loop of `GpuFieldSolver::fcg_relaxed` that reads
/// the status after every iteration.
pub fn fcg_queued(shape: &CycleShape, sweeps: usize, iterations: u32, start: bool) -> Vec<Step> {
    let mut out = local_relaxation(sweeps);
    out.extend(residual());
    if start {
        out.push(Step::Dispatch(Op::Gate { count: false }));
        out.extend(gated(fcg_first_direction(shape)));
        out.extend(fcg_queued_iterations(shape, true, iterations));
    } else {
        out.push(Step::CopyScalars);
    }
    out
}

/// `iterations` gated FCG iterations (`first`: the first after the first direction), then the
/// scalars copied.
pub fn fcg_queued_iterations(shape: &CycleShape, first: bool, iterations: u32) -> Vec<Step> {
    let mut out = Vec::new();
    for i in 0..iterations {
        out.push(Step::Dispatch(Op::Gate { count: true }));
        if !(first && i == 0) {
            out.extend(gated(fcg_direction(shape)));
        }
        out.extend(gated(fcg_step()));
        out.extend(spike_relaxation());
    }
    out.push(Step::CopyScalars);
    out
}

/// `steps` with their gated dispatches as plain ones (for the work units they count if they run).
pub fn gated_as_dispatches(steps: &[Step]) -> Vec<Step> {
    steps
        .iter()
        .map(|s| match *s {
            Step::Gated(op) => Step::Dispatch(op),
            s => s,
        })
        .collect()
}

/// Work units of a plan.
pub fn work_units(steps: &[Step]) -> f64 {
    steps
        .iter()
        .map(|s| {
            if let Step::Dispatch(op) = s {
                op.work_units()
            } else {
                0.0
            }
        })
        .sum()
}

/// Every op the solver's plans can name, once (the pass table is built from it).
pub fn all_ops(levels: usize) -> Vec<Op> {
    let kc = levels - 1;
    let mut ops = vec![
        Op::Assemble { cold: false },
        Op::Assemble { cold: true },
        Op::CoarsestSolve,
        Op::ApplyLevel0,
    ];
    for level in 2..levels {
        ops.push(Op::GalerkinCoarse { level });
    }
    for colour in 0..2 {
        ops.push(Op::SmoothLevel0 { colour });
        ops.push(Op::ProlongSmoothLevel0 { colour });
    }
    ops.push(Op::SweepLevel0FromZero);
    ops.push(Op::SweepRestrictLevel0FromZero);
    for sweeps in 0..=MAX_RELAX_TILE_SWEEPS {
        for to_z in [true, false] {
            ops.push(Op::RelaxTiles { sweeps, to_z });
        }
    }
    ops.push(Op::SpikeRelax {
        sweeps: crate::cycle::SPIKE_SWEEPS as u32,
    });
    ops.push(Op::SpikeUpdate);
    for mode in 0..4 {
        ops.push(Op::RelaxMask { mode });
    }
    for level in 1..kc {
        for colour in 0..4 {
            ops.push(Op::SmoothCoarse { level, colour });
        }
        ops.push(Op::ResidualRestrictCoarse { level });
        ops.push(Op::RestrictSum { level });
        for set in [false, true] {
            ops.push(Op::ProlongCoarse { level, set });
            ops.push(Op::ProlongCoarseAlt { level, set });
        }
        // The runs `tile_sweeps` makes of the cycles' sweeps: from zero, pre-sweeps; after a
        // prolongation, post-sweeps (and the next visit's pre-sweep), or FMG's pre-sweeps.
        let (pre, post) = (true, false);
        for (from_zero, run) in [
            (true, &[pre][..]),
            (true, &[pre, pre]),
            (false, &[post]),
            (false, &[post, post]),
            (false, &[post, pre]),
            (false, &[pre]),
            (false, &[pre, pre]),
        ] {
            let op = sweep_op(level, run, from_zero);
            ops.push(op);
            if let Op::SweepCoarse {
                level,
                colours,
                phases,
                from_zero,
                ..
            } = op
            {
                ops.push(Op::SweepCoarse {
                    level,
                    colours,
                    phases,
                    from_zero,
                    restrict: true,
                });
            }
        }
    }
    for b in [false, true] {
        ops.push(Op::ResidualRestrictLevel0 { solution: b });
        ops.push(Op::ProlongLevel0 { solution: b });
    }
    let top = kc + COARSEST_SIDE.trailing_zeros() as usize;
    for level in 1..=top {
        ops.push(Op::LiftPush { level });
    }
    for level in 0..top {
        ops.push(Op::LiftPull { level });
    }
    for stage in [STAGE_PQ, STAGE_Z, STAGE_R] {
        ops.push(Op::DotPartial { stage });
        ops.push(Op::DotFinal { stage });
    }
    ops.push(Op::DotPartial { stage: STAGE_RZ });
    for stage in [STAGE_Z, STAGE_RZ] {
        for colour in 0..3 {
            ops.push(Op::SmoothDotLevel0 { stage, colour });
        }
    }
    ops.push(Op::DotFinal { stage: STAGE_ZPQ });
    for mode in 0..3 {
        ops.push(Op::FcgUpdate { mode });
    }
    ops
}

/// The ops of FCG's stop test on the GPU (bound to the solver's own gate buffers, so not in
/// [`all_ops`]).
pub const GATE_OPS: [Op; 3] = [
    Op::Gate { count: false },
    Op::Gate { count: true },
    Op::SpikeGate,
];

/// The distinct workgroup counts of the passes a gate controls (its size classes), in a fixed
/// order: [`fcg_queued`] names no other gated pass.
pub fn gate_classes(shape: &CycleShape, n: usize) -> Vec<[u32; 3]> {
    let mut classes: Vec<[u32; 3]> = Vec::new();
    for s in fcg_queued(shape, 0, 2, true) {
        if let Step::Gated(op) = s {
            let w = op.workgroups(n);
            if !classes.contains(&w) {
                classes.push(w);
            }
        }
    }
    classes
}

#[cfg(test)]
mod tests;
