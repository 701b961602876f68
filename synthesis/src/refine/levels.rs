//! Multi-resolution synthesis: the patch synthesis runs coarse to fine over a factor-2 pyramid.
//! Each level matches patches against the synthesis so far (the level above, upsampled), with
//! the guide blended in as a soft constraint whose weight halves per level towards the finest
//! (Scott & Dodgson: `w = a (2^k - 1) / (2^L - 1)`); hard constraints and marked sinks are held
//! at every level, and pits are breached (carved as valleys) at every level but the finest.

use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;

use super::exemplar::PYRAMID_LEVELS;
use super::field::{Field, downsample, layout_lowpass, lowpass, upsample_smooth};
use super::synth::{Placed, Synth};
use super::{PreparedExemplar, RefineError, RefineParams, extract_lines, merge, valleys};

/// Smallest level side (the multigrid's smallest grid).
pub const MIN_LEVEL_SIDE: usize = 64;
/// Smallest patch side at any level.
pub const MIN_PATCH: usize = 16;

/// One level of the plan: `side = n / 2^k` cells of `cell_m` metres, patches of `patch` cells.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Level {
    /// Octave below the target (0 = finest).
    pub k: usize,
    /// Side in cells.
    pub side: usize,
    /// Cell size in metres.
    pub cell_m: f64,
    /// Patch side in cells.
    pub patch: usize,
}

/// A finished level, shown by the editor while the finer ones run.
pub struct LevelView<'a> {
    /// Position in the run (0 = first, the coarsest).
    pub index: usize,
    /// Number of levels in the run.
    pub count: usize,
    /// The level.
    pub level: Level,
    /// `side x side` heights, row 0 = north.
    pub heights: &'a [f32],
}

/// Whether an exemplar field offers at least one patch site of side `p` (see `Synth::new`'s
/// margin: the rotated patch must fit).
fn holds_patch(f: &Field, p: usize) -> bool {
    let margin = (p as f32 * std::f32::consts::FRAC_1_SQRT_2).ceil() + 2.0;
    (f.w.min(f.h) as f32) > 2.0 * margin
}

/// Whether an exemplar field offers a level's patches room to vary: at least two patch
/// positions along each axis inside the margin. A level that only a sliver of one exemplar can
/// fill would copy that one piece of land everywhere.
fn offers_level(f: &Field, p: usize) -> bool {
    let margin = (p as f32 * std::f32::consts::FRAC_1_SQRT_2).ceil() + 2.0;
    (f.w.min(f.h) as f32) >= 2.0 * margin + p as f32
}

/// The exemplar heights for octave `k` (0 = the prepared ones).
fn exemplar_field(e: &PreparedExemplar, k: usize) -> Option<&Field> {
    if k == 0 {
        Some(&e.heights)
    } else {
        e.levels.get(k - 1)
    }
}

/// The pyramid for an `n`-cell target: from the finest level up while the level stays at least
/// [`MIN_LEVEL_SIDE`] cells, at most [`PYRAMID_LEVELS`] octaves (16x, the scale of a guide's
/// own structure), and at least half the exemplars offer room for two patches a side there. Coarse levels use
/// patches of at most a quarter of the level's side. Coarsest first.
pub fn plan(n: usize, cell_m: f64, params: &RefineParams, ex: &[PreparedExemplar]) -> Vec<Level> {
    let mut out = vec![Level {
        k: 0,
        side: n,
        cell_m,
        patch: params.patch_size,
    }];
    if params.levels <= 1 {
        return out;
    }
    for k in 1..=PYRAMID_LEVELS.min(params.levels - 1) {
        let side = n >> k;
        let patch = params.patch_size.min(side / 4).max(MIN_PATCH);
        if side < MIN_LEVEL_SIDE {
            break;
        }
        // A level most exemplars cannot fill would take all its detail, and so the character
        // of the whole map, from the few large ones (at 16x a mountain target got the
        // structure of a plain, the only DEM large enough there).
        let offering = ex
            .iter()
            .filter(|e| exemplar_field(e, k).is_some_and(|f| offers_level(f, patch)))
            .count();
        if offering == 0 || 2 * offering < ex.len() {
            break;
        }
        out.push(Level {
            k,
            side,
            cell_m: cell_m * (1u64 << k) as f64,
            patch,
        });
    }
    out.reverse();
    out
}

/// Warnings about exemplars for this plan: too small for a patch at some levels.
pub fn plan_warnings(levels: &[Level], ex: &[PreparedExemplar]) -> Vec<String> {
    let mut out = Vec::new();
    for e in ex {
        let small: Vec<String> = levels
            .iter()
            .filter(|l| !exemplar_field(e, l.k).is_some_and(|f| holds_patch(f, l.patch)))
            .map(|l| format!("{:.0} m", l.cell_m))
            .collect();
        if !small.is_empty() {
            out.push(format!(
                "exemplar {} is smaller than a patch at the level(s) with {} cells; it is not \
                 used there",
                e.name,
                small.join(", ")
            ));
        }
    }
    out
}

/// Soft-guide weight at octave `k` of `l_max` (Scott & Dodgson): `a (2^k - 1) / (2^L - 1)`,
/// 0 at the finest level, `a` at the coarsest.
pub fn guide_weight(a: f32, k: usize, l_max: usize) -> f32 {
    if l_max == 0 {
        return 0.0;
    }
    a * ((1u64 << k) - 1) as f32 / ((1u64 << l_max) - 1) as f32
}

/// Everything one level needs, at that level's resolution.
pub struct LevelInput<'a> {
    /// The level.
    pub level: Level,
    /// What patches are matched against: the guide blended with the synthesis so far.
    pub target: Field,
    /// Cells held like constraints (index, height, tolerance in metres).
    pub anchored: &'a [(usize, f32, f32)],
    /// Marked sinks.
    pub sinks: Option<&'a [bool]>,
    /// Wanted roughness.
    pub roughness: Option<&'a [f32]>,
    /// Breach pits (every level but the finest).
    pub breach: bool,
    /// The only level (no pyramid): the detail band is the patch's half side, as without one.
    pub single: bool,
}

/// What one level produced.
pub struct LevelResult {
    /// The merged, pit-free (coarse levels) and constrained heights.
    pub h: Field,
    /// Owning patch per cell.
    pub owner: Vec<u32>,
    /// Patches in placement order.
    pub placed: Vec<Placed>,
    /// Feature and fill patches placed, candidate sites (fill, feature), target lines found.
    pub counts: [usize; 5],
    /// Heights after the merge, before pit removal and constraints.
    pub merged: Option<Vec<f32>>,
}

/// Runs the patch synthesis at one level: features (finest level only, where the exemplars'
/// networks were extracted), best-first fill, gradient-domain merge with weak ties to the
/// target's low-pass, pit removal, constraints.
pub fn synth_level(
    lv: &LevelInput,
    exemplars: &[PreparedExemplar],
    params: &RefineParams,
    progress: &dyn Fn(f32, &str),
    cancel: &AtomicBool,
    phases: &mut dyn FnMut(&str),
) -> Result<LevelResult, RefineError> {
    let l = lv.level;
    let n = l.side;
    let mut lparams = params.clone();
    lparams.patch_size = l.patch;
    lparams.origin = params.origin.map(|o| o.div_euclid(1 << l.k));
    if !lv.single && l.k > 0 {
        lparams.lowpass_cells = params.level_band_cells.max(1);
    }
    // Exemplars at this level's cell size (coarse levels: no feature networks).
    let level_ex: Vec<PreparedExemplar>;
    let ex: &[PreparedExemplar] = if l.k == 0 {
        exemplars
    } else {
        level_ex = exemplars
            .iter()
            .filter_map(|e| {
                let f = exemplar_field(e, l.k)?;
                holds_patch(f, l.patch).then(|| PreparedExemplar {
                    heights: f.clone(),
                    features: Vec::new(),
                    levels: Vec::new(),
                    cell_size_m: l.cell_m,
                    ..e.clone_meta()
                })
            })
            .collect();
        &level_ex
    };
    if ex.is_empty() {
        return Err(RefineError::BadInput(format!(
            "no exemplar is large enough for {}-cell patches at {:.1} m cells",
            l.patch, l.cell_m
        )));
    }
    let check = || {
        if cancel.load(Ordering::Relaxed) {
            Err(RefineError::Cancelled)
        } else {
            Ok(())
        }
    };
    let low = layout_lowpass(&lv.target, lparams.lowpass_factor());
    let (mid_lo, mid_hi) = lparams.mid_band();
    // The target's form at the patch scale: what the relief cost compares (the guide is only
    // reliable at this scale) and the upper edge of the matched band.
    let form = lowpass(&lv.target, mid_hi);
    let target_mid = lowpass(&lv.target, mid_lo).minus(&form);
    let lines = if l.k == 0 {
        extract_lines(&lv.target, l.cell_m)
    } else {
        Vec::new()
    };
    let mut synth = Synth::new(n, ex, target_mid, &form, lv.roughness, &lparams)?;
    phases("setup");
    check()?;
    let pf = |f: f32| progress(0.3 * f, "feature patches");
    synth.place_features(&lines, cancel, &pf)?;
    phases("features");
    let pfill = |f: f32| progress(0.3 + 0.5 * f, "filling");
    synth.fill(cancel, &pfill)?;
    phases("fill");
    check()?;

    progress(0.8, "merging");
    let (de, dn) = merge::assemble_gradients(
        n,
        (l.patch / 2) as i32,
        &synth.owner,
        &synth.dout,
        &synth.placed,
        synth.fields(),
        &low,
    );
    let mut weight = vec![params.low_weight.clamp(0.0, 0.999); n * n];
    let mut value = low.v.clone();
    for &(i, v, _) in lv.anchored {
        weight[i] = params.constraint_weight.clamp(0.0, 0.999);
        value[i] = v;
    }
    let mut h = Field::new(n, n, merge::poisson(n, weight, value, de, dn, 1e-4));
    phases("merge");
    check()?;

    let merged = (l.k == 0).then(|| h.v.clone());
    if lv.breach {
        progress(0.9, "removing pits");
        valleys::remove_pits_as_valleys(&mut h.v, n, lv.sinks, params.pit_mode, l.cell_m);
        phases("pits");
        check()?;
    }
    progress(0.95, "holding constraints");
    hold_constraints(&mut h.v, n, lv.anchored);
    phases("constraints");
    let counts = [
        synth.patches_feature,
        synth.patches_fill,
        synth.sites.0,
        synth.sites.1,
        lines.len(),
    ];
    Ok(LevelResult {
        h,
        owner: synth.owner,
        placed: synth.placed,
        counts,
        merged,
    })
}

/// Brings every anchored cell within its tolerance of its height: the shortfall (the distance
/// to the nearest allowed height) is diffused by the multigrid with those cells hard and added,
/// then each anchored cell is clamped into its band. With tolerance 0 the cell is set exactly.
pub fn hold_constraints(h: &mut [f32], n: usize, anchored: &[(usize, f32, f32)]) {
    if anchored.is_empty() {
        return;
    }
    let mut w = vec![0.0f32; n * n];
    let mut d = vec![0.0f32; n * n];
    for &(i, v, tol) in anchored {
        w[i] = 1.0;
        d[i] = h[i].clamp(v - tol, v + tol) - h[i];
    }
    let corr = merge::poisson(n, w, d, Vec::new(), Vec::new(), 1e-5);
    h.par_iter_mut().zip(&corr).for_each(|(a, c)| *a += c);
    for &(i, v, tol) in anchored {
        h[i] = h[i].clamp(v - tol, v + tol);
    }
}

/// Anchored cells at octave `k`: a coarse cell is anchored when any of its cells is, at the
/// mean of their heights, with the smallest of their tolerances.
pub fn anchored_at(anchored: &[(usize, f32, f32)], n: usize, k: usize) -> Vec<(usize, f32, f32)> {
    if k == 0 {
        return anchored.to_vec();
    }
    let f = 1usize << k;
    let c = n / f;
    let mut acc: Vec<(f64, u32, f32)> = vec![(0.0, 0, f32::INFINITY); c * c];
    for &(i, v, tol) in anchored {
        let j = (i / n / f) * c + (i % n) / f;
        acc[j].0 += f64::from(v);
        acc[j].1 += 1;
        acc[j].2 = acc[j].2.min(tol);
    }
    acc.iter()
        .enumerate()
        .filter(|(_, a)| a.1 > 0)
        .map(|(j, a)| (j, (a.0 / f64::from(a.1)) as f32, a.2))
        .collect()
}

/// A mask at octave `k`: a coarse cell is set if any of its cells is.
pub fn mask_at(mask: &[bool], n: usize, k: usize) -> Vec<bool> {
    let f = 1usize << k;
    let c = n / f;
    let mut out = vec![false; c * c];
    for (i, &m) in mask.iter().enumerate() {
        if m {
            out[(i / n / f) * c + (i % n) / f] = true;
        }
    }
    out
}

/// A field at octave `k` (block average).
pub fn field_at(v: &[f32], n: usize, k: usize) -> Field {
    downsample(&Field::new(n, n, v.to_vec()), 1 << k)
}

/// `h = w g + (1 - w) h`.
pub fn blend(h: &mut Field, g: &Field, w: f32) {
    h.v.par_iter_mut()
        .zip(&g.v)
        .for_each(|(a, b)| *a = w * b + (1.0 - w) * *a);
}

/// The synthesis so far brought up by 2 (cubic B-spline) to `side x side`: the next level's
/// target.
pub fn upsample2(prev: &Field, side: usize) -> Field {
    upsample_smooth(prev, 2, side, side)
}

/// Cells of margin [`level1_window`] cuts around a region: the B-spline reaches two coarse
/// cells.
const UPSAMPLE_MARGIN: usize = 4;

/// The window `(first, end)` (columns, rows) of a world's level-1 field (`half` a side) that
/// [`upsample2_region`] needs for the `side x side` region at `origin` (finest cells).
pub fn level1_window(origin: [usize; 2], side: usize, half: usize) -> ([usize; 2], [usize; 2]) {
    let c0 = origin.map(|o| (o / 2).saturating_sub(UPSAMPLE_MARGIN));
    let c1 = origin.map(|o| ((o + side).div_ceil(2) + UPSAMPLE_MARGIN).min(half));
    (c0, c1)
}

/// The world's level-1 synthesis brought up by 2 on the `side x side` region at `origin`
/// (finest cells, even), from `crop`, the [`level1_window`] of it starting at coarse cell
/// `crop_origin`: the same values as [`upsample2`] of the whole world cut to the region (a crop
/// at the world's edge clamps there as the world does; elsewhere the margin keeps the clamping
/// out of the region), without the whole world at the finest resolution.
pub fn upsample2_region(
    crop: &Field,
    crop_origin: [usize; 2],
    origin: [usize; 2],
    side: usize,
) -> Field {
    let up = upsample_smooth(crop, 2, 2 * crop.w, 2 * crop.h);
    let (dx, dy) = (
        origin[0] - 2 * crop_origin[0],
        origin[1] - 2 * crop_origin[1],
    );
    let mut out = Vec::with_capacity(side * side);
    for y in 0..side {
        let row = (y + dy) * up.w + dx;
        out.extend_from_slice(&up.v[row..row + side]);
    }
    Field::new(side, side, out)
}
