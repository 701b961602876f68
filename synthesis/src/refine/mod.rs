//! The realism pass: example-based patch synthesis from real DEMs that keeps every sketched
//! constraint (Tasse 2011, Crause 2015, with Scott & Dodgson's pit removal). See the crate's
//! README, section "Refinement", for the algorithm and its choices.
//!
//! Entry points: [`prepare_exemplars`] (resample, extract and cache ridge/valley networks) and
//! [`refine`].

mod exemplar;
pub mod field;
mod fine;
pub mod graphcut;
pub mod levels;
pub mod merge;
mod relief;
mod stats;
mod synth;
pub mod valleys;

use std::sync::atomic::AtomicBool;
use std::time::Instant;

use rayon::prelude::*;
use terrasketch_raster::Heightmap;

pub use exemplar::{
    FEATURE_FACTOR, FeatureLine, MAX_EXEMPLAR_SIDE, PreparedExemplar, extract_lines,
    prepare_exemplars,
};
use levels::LevelInput;
pub use levels::{Level, LevelView};
pub use merge::assemble_gradients;
use stats::finish;
pub use stats::{RefineStats, SEAM_JUMP_SPAN, seam_gradient_jump_ratio, seam_ratio, slope_hist};
pub use synth::{ExFields, NO_OWNER, Placed};

use crate::pits::PitMode;
use field::{Field, downsample, upsample_smooth};

/// Largest [`RefineParams::fine_detail`]: four times the detail of real land.
pub const MAX_FINE_DETAIL: f32 = 4.0;
/// Pits shallower than this are not counted in the statistics (metres).
pub const PIT_MIN_DEPTH_M: f32 = 10.0;
/// Smallest and largest accepted target side (the multigrid's range).
pub const MIN_SIDE: usize = 64;
/// Largest accepted target side.
pub const MAX_SIDE: usize = 16384;

/// What to refine.
#[derive(Clone, Debug)]
pub struct RefineInput {
    /// The target: `n x n` heights, row 0 = north, `n` a power of two from 64 to 16384, square
    /// cells (`cell_size_m[0]` is used).
    pub target: Heightmap,
    /// Hard constraints (sketched heights): `n * n` flags, `true` where the height must hold.
    pub constraint_mask: Option<Vec<bool>>,
    /// Constrained heights in metres (read where the mask is set); `n * n`.
    pub constraint_values: Option<Vec<f32>>,
    /// Wanted roughness in [0, 1] per cell (`n * n`): low picks smooth exemplar patches, high
    /// rugged ones. Default 0.5 everywhere.
    pub roughness: Option<Vec<f32>>,
    /// Cells that must stay sinks (lakes), `n * n`.
    pub sinks: Option<Vec<bool>>,
    /// Height tolerance of each constrained cell in metres (`n * n`, read where the mask is
    /// set): the output may differ from the constraint by up to this, so detail can play along
    /// a stroke. Absent or 0: exact.
    pub constraint_tolerance: Option<Vec<f32>>,
}

impl RefineInput {
    /// A square `n x n` target of `cell_m` metre cells (row 0 = north) and nothing else: no
    /// constraints, roughness, sinks or tolerances.
    pub fn target_only(n: usize, cell_m: f64, data: Vec<f32>) -> RefineInput {
        RefineInput {
            target: Heightmap {
                width: n,
                height: n,
                data,
                cell_size_m: [cell_m; 2],
            },
            constraint_mask: None,
            constraint_values: None,
            roughness: None,
            sinks: None,
            constraint_tolerance: None,
        }
    }
}

/// Relative weights of the matching costs (each cost is first divided by its mean over the
/// candidates of the slot, so the weights compare like with like).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct CostWeights {
    /// Feature patches: height profiles along and across the feature.
    pub feature_profile: f32,
    /// Feature patches: angle between the target's and the candidate's feature direction.
    pub feature_angle: f32,
    /// Multi-level noise variance against the roughness-derived wanted one.
    pub noise: f32,
    /// Fill patches: 4 x 4 descriptor of the smoothed detail against the target's.
    pub shape: f32,
    /// RMS difference with the output on the already-filled overlap.
    pub overlap: f32,
    /// Local character: log RMS slope of the low-pass over the patch window, target against
    /// candidate.
    pub relief: f32,
    /// Reuse: a candidate's cost is multiplied by `1 + reuse * r`, `r` the patches this level
    /// already took from around its site (see `synth::Reuse`), so one piece of land is not
    /// copied all over the map. 0 = no penalty.
    pub reuse: f32,
}

impl Default for CostWeights {
    fn default() -> Self {
        // Tasse 2011 ranks feature profile > angle > overlap >> noise on raw costs; after
        // normalisation we keep the order but let the noise (the roughness control) count.
        Self {
            feature_profile: 5.0,
            feature_angle: 2.0,
            noise: 1.0,
            shape: 1.0,
            overlap: 1.5,
            relief: 2.0,
            reuse: 0.2,
        }
    }
}

/// Parameters of [`refine`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RefineParams {
    /// Seed of the candidate jitter and of the fill lattice's phase.
    pub seed: u64,
    /// Patch side in cells (at least 16).
    pub patch_size: usize,
    /// Low-pass scale in cells separating the target's layout (kept) from the detail (from
    /// patches); 0 = half the patch size.
    pub lowpass_cells: usize,
    /// Pit removal mode (coarse level and final pass).
    pub pit_mode: PitMode,
    /// Fill-site budget per exemplar (each site is tried in 16 transforms).
    pub sites_per_exemplar: usize,
    /// Feature-site budget per exemplar and feature kind.
    pub feature_sites_per_exemplar: usize,
    /// Candidates kept for the overlap cost (round 2).
    pub overlap_candidates: usize,
    /// Candidates re-ranked by graph-cut seam cost (round 3).
    pub graphcut_candidates: usize,
    /// Relative random jitter of the round-1 costs (0 = none), seeded by `seed`.
    pub jitter: f32,
    /// Cost weights.
    pub weights: CostWeights,
    /// Weight (0..1) tying every cell to the low-pass target in the Poisson merge.
    pub low_weight: f32,
    /// Weight (0..1) tying constrained cells to their value in the Poisson merge.
    pub constraint_weight: f32,
    /// Most pyramid levels, the finest included (1 = one level, no pyramid).
    pub levels: usize,
    /// Detail band of the pyramid levels, in cells: each level replaces the land's detail
    /// below this scale (the user's `lowpass_cells`, when set, at the finest level).
    pub level_band_cells: usize,
    /// Soft-guide weight `a` of the coarsest level; level `k` of `L` blends the guide in with
    /// `a (2^k - 1) / (2^L - 1)` (0 at the finest).
    pub guide_weight: f32,
    /// Where the target's north-west cell lies in the world, in finest-level cells (column,
    /// row from the north-west): the fill lattice, the candidate jitter and the seam noise are
    /// keyed by world position, so a tile of a larger world draws what the whole world would
    /// draw there. `[0, 0]` for a whole world.
    pub origin: [i64; 2],
    /// Gain of the procedural detail added to the finest level in the octaves its exemplars do
    /// not measure (finer than two of their own cells; `fine::add_fine_band`): 1 is the law
    /// calibrated on real land, 0 none.
    pub fine_detail: f32,
}

impl Default for RefineParams {
    fn default() -> Self {
        Self {
            seed: 1,
            patch_size: 64,
            lowpass_cells: 0,
            pit_mode: PitMode::Breach,
            sites_per_exemplar: 800,
            feature_sites_per_exemplar: 300,
            overlap_candidates: 24,
            graphcut_candidates: 5,
            jitter: 0.15,
            weights: CostWeights::default(),
            low_weight: 1e-3,
            constraint_weight: 0.5,
            levels: 1 + exemplar::PYRAMID_LEVELS,
            level_band_cells: 4,
            guide_weight: 1.0,
            origin: [0, 0],
            fine_detail: 0.5,
        }
    }
}

impl RefineParams {
    /// The low-pass scale in cells.
    pub fn lowpass_factor(&self) -> usize {
        if self.lowpass_cells == 0 {
            (self.patch_size / 2).max(2)
        } else {
            self.lowpass_cells
        }
    }

    /// The band matched by the shape descriptor and feature profiles: `(lo, hi)` low-pass
    /// scales in cells, the descriptor being `lowpass(lo) - lowpass(hi)`. It reaches from the
    /// detail band's edge (at most 4 cells) up to the patch's half side, so with a narrow
    /// detail band (pyramid levels) patches are matched to the form of the land they land on.
    pub fn mid_band(&self) -> (usize, usize) {
        let lp = self.lowpass_factor();
        (lp.min(4), lp.max(self.patch_size / 2))
    }
}

/// The refined terrain and its figures.
#[derive(Clone, Debug)]
pub struct RefineOutput {
    /// Heights, row 0 = north, same size and cell size as the target.
    pub heights: Heightmap,
    /// Owning patch per cell (index into `placed`, or [`NO_OWNER`]).
    pub owner: Vec<u32>,
    /// Patches in placement order.
    pub placed: Vec<Placed>,
    /// Figures.
    pub stats: RefineStats,
}

/// Errors of the refinement.
#[derive(Debug, thiserror::Error)]
pub enum RefineError {
    /// The input is not usable (size, shape, values).
    #[error("{0}")]
    BadInput(String),
    /// No exemplar was given.
    #[error("no exemplar DEM to take patches from")]
    NoExemplars,
    /// An exemplar could not be resampled.
    #[error(transparent)]
    Dem(#[from] crate::DemError),
    /// The cancel flag was raised.
    #[error("refinement cancelled")]
    Cancelled,
}

/// Checks the input; a world's side must be a power of two, a region's a multiple of 16.
fn check_input(
    input: &RefineInput,
    params: &RefineParams,
    world: bool,
) -> Result<usize, RefineError> {
    let t = &input.target;
    let n = t.width;
    let side_ok = if world {
        n.is_power_of_two()
    } else {
        n.is_multiple_of(16)
    };
    if t.height != n || !side_ok || !(MIN_SIDE..=MAX_SIDE).contains(&n) {
        return Err(RefineError::BadInput(format!(
            "target is {}x{}; it must be square with a power-of-two side (a region: a multiple \
             of 16) from {MIN_SIDE} to {MAX_SIDE}",
            t.width, t.height
        )));
    }
    if t.data.len() != n * n || t.data.iter().any(|v| !v.is_finite()) {
        return Err(RefineError::BadInput(
            "target heights must be n*n finite values".into(),
        ));
    }
    let c = t.cell_size_m[0];
    if !(c.is_finite() && c > 0.0) {
        return Err(RefineError::BadInput(format!(
            "cell size {c} m is not positive"
        )));
    }
    let len_ok = |l: Option<usize>| l.is_none_or(|l| l == n * n);
    if !len_ok(input.constraint_mask.as_ref().map(Vec::len))
        || !len_ok(input.constraint_values.as_ref().map(Vec::len))
        || !len_ok(input.roughness.as_ref().map(Vec::len))
        || !len_ok(input.sinks.as_ref().map(Vec::len))
        || !len_ok(input.constraint_tolerance.as_ref().map(Vec::len))
    {
        return Err(RefineError::BadInput(
            "constraint, roughness and sink maps must have n*n cells".into(),
        ));
    }
    if input.constraint_mask.is_some() != input.constraint_values.is_some() {
        return Err(RefineError::BadInput(
            "constraint mask and values must be given together".into(),
        ));
    }
    if let (Some(m), Some(v)) = (&input.constraint_mask, &input.constraint_values)
        && m.iter().zip(v).any(|(&m, v)| m && !v.is_finite())
    {
        return Err(RefineError::BadInput(
            "a constrained height is not finite".into(),
        ));
    }
    if let Some(t) = &input.constraint_tolerance
        && t.iter().any(|t| !(t.is_finite() && *t >= 0.0))
    {
        return Err(RefineError::BadInput(
            "a height tolerance is negative or not finite".into(),
        ));
    }
    if !(0.0..=MAX_FINE_DETAIL).contains(&params.fine_detail) {
        return Err(RefineError::BadInput(format!(
            "fine detail gain {} must be from 0 to {MAX_FINE_DETAIL}",
            params.fine_detail
        )));
    }
    if params.patch_size < 16 || params.patch_size > n / 2 {
        return Err(RefineError::BadInput(format!(
            "patch size {} must be from 16 to half the target side ({})",
            params.patch_size,
            n / 2
        )));
    }
    Ok(n)
}

/// A `n/f` mask: a coarse cell is a sink if any of its cells is.
fn downsample_mask(mask: &[bool], n: usize, f: usize) -> Vec<bool> {
    let c = n.div_ceil(f);
    let mut out = vec![false; c * c];
    for (i, &m) in mask.iter().enumerate() {
        if m {
            out[(i / n / f) * c + (i % n) / f] = true;
        }
    }
    out
}

/// Coarse-level pit removal: removes depressions on a `1/4`-resolution copy (breaches carved as
/// valleys, see [`valleys`]) and adds the change back, B-spline upsampled, so drainage is fixed
/// at the scale of valleys, not cell by cell, and no channel is narrower than a few cells.
fn coarse_pit_removal(h: &mut Field, sinks: Option<&[bool]>, mode: PitMode, cell_m: f64) {
    let f = 4;
    let coarse = downsample(h, f);
    let mut fixed = coarse.v.clone();
    let sinks_c = sinks.map(|s| downsample_mask(s, h.w, f));
    valleys::remove_pits_as_valleys(
        &mut fixed,
        coarse.w,
        sinks_c.as_deref(),
        mode,
        cell_m * f as f64,
    );
    let delta = Field::new(
        coarse.w,
        coarse.h,
        fixed.iter().zip(&coarse.v).map(|(a, b)| a - b).collect(),
    );
    let up = upsample_smooth(&delta, f, h.w, h.h);
    h.v.par_iter_mut().zip(&up.v).for_each(|(a, d)| *a += d);
}

/// Refines `input` with patches of `exemplars` (see the module documentation).
///
/// `progress` gets a fraction in 0..1 and a phase name; `cancel` is polled between patches and
/// phases ([`RefineError::Cancelled`]). Deterministic for the same inputs and parameters.
pub fn refine(
    input: &RefineInput,
    exemplars: &[PreparedExemplar],
    params: &RefineParams,
    progress: &dyn Fn(f32, &str),
    cancel: &AtomicBool,
) -> Result<RefineOutput, RefineError> {
    refine_levels(input, exemplars, params, progress, &|_| {}, cancel)
}

/// [`refine`], calling `on_level` with each finished pyramid level (coarsest first, the finest
/// last, before the figures are measured).
pub fn refine_levels(
    input: &RefineInput,
    exemplars: &[PreparedExemplar],
    params: &RefineParams,
    progress: &dyn Fn(f32, &str),
    on_level: &dyn Fn(&LevelView),
    cancel: &AtomicBool,
) -> Result<RefineOutput, RefineError> {
    let t0 = Instant::now();
    let plan = world_plan(input, exemplars, params)?;
    let mut phases = Vec::new();
    let (_, finest) = run_levels(
        input,
        exemplars,
        params,
        &plan,
        None,
        0,
        &mut phases,
        progress,
        on_level,
        cancel,
    )?;
    let Some(res) = finest else {
        return Err(RefineError::BadInput(
            "the pyramid has no finest level".into(),
        ));
    };
    Ok(finish(input, exemplars, &plan, res, phases, t0, progress))
}

/// The pyramid of a whole-world refinement, once its input and exemplars are checked.
fn world_plan(
    input: &RefineInput,
    exemplars: &[PreparedExemplar],
    params: &RefineParams,
) -> Result<Vec<Level>, RefineError> {
    let n = check_input(input, params, true)?;
    if exemplars.is_empty() {
        return Err(RefineError::NoExemplars);
    }
    Ok(levels::plan(
        n,
        input.target.cell_size_m[0],
        params,
        exemplars,
    ))
}

/// The coarse part of a world's refinement, shared by its tiles: every pyramid level above the
/// finest, run on the whole world.
#[derive(Clone, Debug)]
pub struct CoarseWorld {
    /// The world's pyramid plan (coarsest first; one level = no pyramid).
    pub plan: Vec<Level>,
    /// The synthesis after the level just above the finest (`n/2` a side, row 0 = north);
    /// `None` without a pyramid.
    pub level1: Option<Field>,
}

/// Runs the levels of the world's pyramid above the finest ([`CoarseWorld`]); the finest
/// level is then made tile by tile with [`refine_region`]. Same inputs and seed, same bits.
pub fn refine_coarse(
    input: &RefineInput,
    exemplars: &[PreparedExemplar],
    params: &RefineParams,
    progress: &dyn Fn(f32, &str),
    on_level: &dyn Fn(&LevelView),
    cancel: &AtomicBool,
) -> Result<CoarseWorld, RefineError> {
    let plan = world_plan(input, exemplars, params)?;
    let mut phases = Vec::new();
    let (level1, _) = run_levels(
        input,
        exemplars,
        params,
        &plan,
        None,
        1,
        &mut phases,
        progress,
        on_level,
        cancel,
    )?;
    Ok(CoarseWorld { plan, level1 })
}

/// The finest level of a world's refinement on one square region of it (a tile and its halo):
/// `input` is the region (side a multiple of 16, at least [`MIN_SIDE`]), `params.origin` its
/// north-west cell in the world, `world` the world's coarse levels and `start` their synthesis
/// brought to the region (the level-1 field upsampled by 2 and cut to the region;
/// [`levels::upsample2_region`]), `None` when the world has no pyramid.
pub fn refine_region(
    input: &RefineInput,
    exemplars: &[PreparedExemplar],
    params: &RefineParams,
    world: &CoarseWorld,
    start: Option<Field>,
    progress: &dyn Fn(f32, &str),
    cancel: &AtomicBool,
) -> Result<RefineOutput, RefineError> {
    let t0 = Instant::now();
    let n = check_input(input, params, false)?;
    if exemplars.is_empty() {
        return Err(RefineError::NoExemplars);
    }
    if start.as_ref().is_some_and(|f| f.w != n || f.h != n)
        || start.is_some() == (world.plan.len() == 1)
    {
        return Err(RefineError::BadInput(
            "the region's start field does not match the world's pyramid".into(),
        ));
    }
    let finest = Level {
        side: n,
        ..world.plan[world.plan.len() - 1]
    };
    let mut phases = Vec::new();
    let (_, res) = run_levels(
        input,
        exemplars,
        params,
        &[finest],
        start.map(|s| (s, world.plan.len())),
        0,
        &mut phases,
        progress,
        &|_| {},
        cancel,
    )?;
    let Some(res) = res else {
        return Err(RefineError::BadInput(
            "the pyramid has no finest level".into(),
        ));
    };
    Ok(finish(
        input,
        exemplars,
        &world.plan,
        res,
        phases,
        t0,
        progress,
    ))
}

/// Runs `plan` (coarsest first) down to octave `stop_k`. `start` is the synthesis so far at the
/// first level's resolution and the world plan's length (a region's finest level). Returns the
/// last coarse field and, when the finest level ran, its result.
#[allow(clippy::too_many_arguments)]
fn run_levels(
    input: &RefineInput,
    exemplars: &[PreparedExemplar],
    params: &RefineParams,
    plan: &[Level],
    start: Option<(Field, usize)>,
    stop_k: usize,
    phases: &mut Vec<(String, f64)>,
    progress: &dyn Fn(f32, &str),
    on_level: &dyn Fn(&LevelView),
    cancel: &AtomicBool,
) -> Result<(Option<Field>, Option<levels::LevelResult>), RefineError> {
    let n = input.target.width;
    let cell = input.target.cell_size_m[0];
    let sinks = input.sinks.as_deref();
    let anchored = anchored_cells(input);
    let l_max = plan[0].k;
    let (mut prev, single) = match start {
        Some((field, world_levels)) => (Some(field), world_levels == 1),
        None => (None, plan.len() == 1),
    };
    let plan: Vec<Level> = plan.iter().copied().filter(|l| l.k >= stop_k).collect();
    let work: Vec<f64> = plan.iter().map(|l| (l.side * l.side) as f64).collect();
    let total_work: f64 = work.iter().sum();
    let mut done_work = 0.0;
    let mut finest = None;
    for (idx, &lvl) in plan.iter().enumerate() {
        let k = lvl.k;
        let name = format!("level {}/{} ({}^2)", idx + 1, plan.len(), lvl.side);
        let share = work[idx] / total_work;
        let base = done_work / total_work;
        let lp = |f: f32, what: &str| {
            progress(
                (base + share * f64::from(f)) as f32,
                &format!("{name}: {what}"),
            )
        };
        lp(0.0, "analysing the target");
        let guide = if k == 0 {
            Field::new(n, n, input.target.data.clone())
        } else {
            levels::field_at(&input.target.data, n, k)
        };
        let w_k = if single {
            0.0
        } else {
            levels::guide_weight(params.guide_weight, k, l_max)
        };
        let mut target = match prev.take() {
            None => guide.clone(),
            Some(p) if p.w == lvl.side => p,
            Some(p) => levels::upsample2(&p, n >> k),
        };
        if single {
            coarse_pit_removal(&mut target, sinks, params.pit_mode, cell);
        }
        let anchored_k = levels::anchored_at(&anchored, n, k);
        let sinks_k = sinks.map(|s| levels::mask_at(s, n, k));
        let rough_k = input
            .roughness
            .as_ref()
            .map(|r| levels::field_at(r, n, k).v);
        let lin = LevelInput {
            level: lvl,
            target,
            anchored: &anchored_k,
            sinks: sinks_k.as_deref(),
            roughness: rough_k.as_deref(),
            breach: k > 0,
            single,
        };
        let mut lap = Instant::now();
        let mut mark = |what: &str| {
            phases.push((format!("L{k} {what}"), lap.elapsed().as_secs_f64() * 1e3));
            lap = Instant::now();
        };
        let mut res = levels::synth_level(&lin, exemplars, params, &lp, cancel, &mut mark)?;
        if w_k > 0.0 {
            // The guide as a soft constraint (Scott & Dodgson's E-step blend), constraints
            // held again after it.
            levels::blend(&mut res.h, &guide, w_k);
            levels::hold_constraints(&mut res.h.v, lvl.side, &anchored_k);
        }
        if k == 0 {
            fine::add_fine_band(
                &mut res.h,
                input,
                &anchored,
                &res.owner,
                &res.placed,
                exemplars,
                cell,
                params.origin,
                params.seed,
                params.fine_detail,
            );
            mark("fine band");
            // The finest level is not breached by `synth_level`; its pits (from stitching, or
            // all of them without a pyramid) are drained at a quarter of its resolution, then
            // what is left (pits narrower than 4 cells) is breached with valley-shaped cuts,
            // never one-cell trenches.
            coarse_pit_removal(&mut res.h, sinks, params.pit_mode, cell);
            valleys::remove_pits_as_valleys(&mut res.h.v, n, sinks, params.pit_mode, cell);
            levels::hold_constraints(&mut res.h.v, n, &anchored);
            mark("pits");
        }
        on_level(&LevelView {
            index: idx,
            count: plan.len(),
            level: lvl,
            heights: &res.h.v,
        });
        done_work += work[idx];
        if k == 0 {
            finest = Some(res);
        } else {
            prev = Some(res.h);
        }
    }
    Ok((prev, finest))
}

/// Cells held like constraints in the merge and the re-imposition: the constraints, plus the
/// marked sinks at their target height (a lake floor must not be replaced by exemplar detail).
fn anchored_cells(input: &RefineInput) -> Vec<(usize, f32, f32)> {
    let n = input.target.width;
    let mut anchored = constrained_cells(input);
    if let Some(sk) = input.sinks.as_deref() {
        let is_constrained = input.constraint_mask.as_deref();
        anchored.extend(
            (0..n * n)
                .filter(|&i| sk[i] && !is_constrained.is_some_and(|m| m[i]))
                .map(|i| (i, input.target.data[i], 0.0)),
        );
    }
    anchored
}

/// The constrained cells: (index, height, tolerance).
fn constrained_cells(input: &RefineInput) -> Vec<(usize, f32, f32)> {
    let tolerance = input.constraint_tolerance.as_deref();
    match (&input.constraint_mask, &input.constraint_values) {
        (Some(m), Some(v)) => m
            .iter()
            .zip(v)
            .enumerate()
            .filter(|(_, (m, _))| **m)
            .map(|(i, (_, &v))| (i, v, tolerance.map_or(0.0, |t| t[i].max(0.0))))
            .collect(),
        _ => Vec::new(),
    }
}
