//! The figures of a refinement ([`RefineStats`]) and the seam and slope measures behind them.

use std::time::Instant;

use rayon::prelude::*;
use terrasketch_raster::Heightmap;

use super::{
    Level, NO_OWNER, PIT_MIN_DEPTH_M, Placed, PreparedExemplar, RefineInput, RefineOutput,
    constrained_cells, levels,
};
use crate::pits;

/// Figures of one refinement.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct RefineStats {
    /// Wall time of [`refine`](super::refine) in milliseconds.
    pub ms_total: f64,
    /// Time spent per phase, milliseconds: setup, features, fill, merge, pits, constraints, stats.
    pub ms_phases: Vec<(String, f64)>,
    /// Feature patches placed.
    pub patches_feature: usize,
    /// Fill patches placed.
    pub patches_fill: usize,
    /// Exemplars used.
    pub exemplars: usize,
    /// Candidate sites for fill patches (each in 16 transforms).
    pub fill_sites: usize,
    /// Candidate sites for feature patches (each in 16 transforms).
    pub feature_sites: usize,
    /// Target ridge/valley polylines found.
    pub target_feature_lines: usize,
    /// Pits deeper than [`PIT_MIN_DEPTH_M`] (marked sinks excluded) of the stitched terrain,
    /// before any pit removal.
    pub pits_before: usize,
    /// The same count on the output.
    pub pits_after: usize,
    /// `pits_after` per 100 km^2.
    pub pits_after_per_100km2: f64,
    /// Pits deeper than [`PIT_MIN_DEPTH_M`] per 100 km^2 in the prepared exemplars (pooled).
    pub exemplar_pits_per_100km2: f64,
    /// Largest |output - constraint| over constrained cells, metres (0 without constraints).
    pub constraint_max_error_m: f64,
    /// Largest amount by which a constrained cell is outside its tolerance, metres (0 when all
    /// hold).
    pub constraint_max_excess_m: f64,
    /// Largest height tolerance of a constrained cell, metres.
    pub constraint_tolerance_max_m: f64,
    /// The pyramid levels run, coarsest first.
    pub levels: Vec<Level>,
    /// Problems with the exemplars for this run (too small for patches at some level).
    pub warnings: Vec<String>,
    /// Relief of the constrained values (max - min), metres.
    pub constraint_relief_m: f64,
    /// Relief of the output (max - min), metres.
    pub relief_m: f64,
    /// Wasserstein distance (degrees) between the output's slope distribution and that of the
    /// exemplars used, pooled by the number of output cells each one gave.
    pub slope_w1_to_exemplars: f64,
    /// The same for the input target (e.g. the diffusion-only terrain).
    pub slope_w1_input_to_exemplars: f64,
    /// W1 between the output's slopes and every exemplar pooled by its size (used or not).
    pub slope_w1_to_all_exemplars: f64,
    /// The same for the input target.
    pub slope_w1_input_to_all_exemplars: f64,
    /// Output cells taken from each exemplar, by name.
    pub exemplar_cells_used: Vec<(String, usize)>,
    /// 99th percentile of |Laplacian| on seam cells over that on all cells.
    pub seam_laplacian_p99_ratio: f64,
    /// Mean jump of the gradient perpendicular to a seam across seam edges over the same on
    /// all edges (see [`seam_gradient_jump_ratio`]); 1 = seams are invisible in a hillshade.
    pub seam_gradient_jump_ratio: f64,
}

/// Slope histogram (1-degree bins, as in [`crate::metrics`]) of a grid, normalised.
pub fn slope_hist(v: &[f32], w: usize, h: usize, cell: f64) -> Vec<f64> {
    crate::metrics::slope_histogram(&crate::metrics::slope_degrees(v, w, h, [cell; 2]))
}

/// The output and its figures from the finest level's result.
pub(super) fn finish(
    input: &RefineInput,
    exemplars: &[PreparedExemplar],
    plan: &[Level],
    res: levels::LevelResult,
    mut phases: Vec<(String, f64)>,
    t0: Instant,
    progress: &dyn Fn(f32, &str),
) -> RefineOutput {
    let n = input.target.width;
    let cell = input.target.cell_size_m[0];
    let sinks = input.sinks.as_deref();
    let constrained = constrained_cells(input);
    let h = res.h;
    let mut lap = Instant::now();
    let mut mark = |name: &str, lap: &mut Instant| {
        phases.push((name.to_owned(), lap.elapsed().as_secs_f64() * 1e3));
        *lap = Instant::now();
    };
    // The two pit counts are floods (each serial): they run beside each other and beside the
    // slope histograms and seam ratios, which read the same finished grids.
    let ((pits_before, pits_after), (out_hist, in_hist, (seam_lap, seam_jump))) = rayon::join(
        || {
            rayon::join(
                || {
                    res.merged
                        .as_ref()
                        .map_or(0, |m| pits::count_pits(m, n, n, sinks, PIT_MIN_DEPTH_M))
                },
                || pits::count_pits(&h.v, n, n, sinks, PIT_MIN_DEPTH_M),
            )
        },
        || {
            (
                slope_hist(&h.v, n, n, cell),
                slope_hist(&input.target.data, n, n, cell),
                rayon::join(
                    || seam_ratio(&h.v, &res.owner, n),
                    || seam_gradient_jump_ratio(&h.v, &res.owner, n),
                ),
            )
        },
    );
    let [
        patches_feature,
        patches_fill,
        fill_sites,
        feature_sites,
        target_lines,
    ] = res.counts;
    let synth_owner = res.owner;
    let synth_placed = res.placed;

    // 7. Figures.
    progress(0.96, "measuring");
    let mut stats = RefineStats {
        patches_feature,
        patches_fill,
        exemplars: exemplars.len(),
        target_feature_lines: target_lines,
        fill_sites,
        feature_sites,
        pits_before,
        levels: plan.to_vec(),
        warnings: levels::plan_warnings(plan, exemplars),
        ..Default::default()
    };
    stats.pits_after = pits_after;
    let area_km2 = (n * n) as f64 * cell * cell / 1e6;
    stats.pits_after_per_100km2 = stats.pits_after as f64 * 100.0 / area_km2;
    constraint_figures(&mut stats, &constrained, &h.v);
    let (lo, hi) =
        h.v.iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
    stats.relief_m = f64::from(hi - lo);
    exemplar_figures(
        &mut stats,
        exemplars,
        (&synth_owner, &synth_placed),
        (&out_hist, &in_hist),
        cell,
    );
    stats.seam_laplacian_p99_ratio = seam_lap;
    stats.seam_gradient_jump_ratio = seam_jump;
    mark("stats", &mut lap);
    stats.ms_phases = phases;
    stats.ms_total = t0.elapsed().as_secs_f64() * 1e3;
    progress(1.0, "done");
    RefineOutput {
        heights: Heightmap {
            width: n,
            height: n,
            data: h.v,
            cell_size_m: input.target.cell_size_m,
        },
        owner: synth_owner,
        placed: synth_placed,
        stats,
    }
}

/// The constraint figures of `stats` from the output heights `h`: largest error and excess over
/// the tolerance, largest tolerance and the relief of the constrained values (all 0 without
/// constraints).
fn constraint_figures(stats: &mut RefineStats, constrained: &[(usize, f32, f32)], h: &[f32]) {
    if constrained.is_empty() {
        return;
    }
    let (mut lo, mut hi, mut err) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64);
    let mut over = 0.0f64;
    for &(i, v, tol) in constrained {
        let v = f64::from(v);
        lo = lo.min(v);
        hi = hi.max(v);
        let e = (f64::from(h[i]) - v).abs();
        err = err.max(e);
        over = over.max(e - f64::from(tol));
    }
    stats.constraint_max_error_m = err;
    stats.constraint_max_excess_m = over.max(0.0);
    stats.constraint_tolerance_max_m = constrained
        .iter()
        .map(|c| f64::from(c.2))
        .fold(0.0, f64::max);
    stats.constraint_relief_m = hi - lo;
}

/// The exemplar figures of `stats`: the slope distances of the output and the input
/// (`out_hist`, `in_hist`) to the exemplars pooled by the cells each gave the output (`owner`,
/// indices into `placed`) and pooled by size, the cells each gave, and their pit density.
fn exemplar_figures(
    stats: &mut RefineStats,
    exemplars: &[PreparedExemplar],
    (owner, placed): (&[u32], &[Placed]),
    (out_hist, in_hist): (&[f64], &[f64]),
    cell: f64,
) {
    // Reference slope distributions: the exemplars pooled by the cells each gave the output
    // (the exemplars used), and all exemplars pooled by their size.
    let mut used = vec![0usize; exemplars.len()];
    for &o in owner {
        if o != NO_OWNER {
            used[placed[o as usize].ex] += 1;
        }
    }
    let pool = |weights: &[f64]| -> Vec<f64> {
        let total: f64 = weights.iter().sum::<f64>().max(1e-300);
        let mut out = vec![0.0f64; crate::metrics::SLOPE_BINS];
        for (e, w) in exemplars.iter().zip(weights) {
            for (o, v) in out.iter_mut().zip(&e.slope_histogram) {
                *o += v * w / total;
            }
        }
        out
    };
    let sizes: Vec<f64> = exemplars
        .iter()
        .map(|e| (e.heights.w * e.heights.h) as f64)
        .collect();
    let used_w: Vec<f64> = used.iter().map(|&u| u as f64).collect();
    let (pooled_used, pooled_all) = (pool(&used_w), pool(&sizes));
    let total_cells: f64 = sizes.iter().sum();
    let ex_pits: usize = exemplars.iter().map(|e| e.pits_deep).sum();
    stats.exemplar_pits_per_100km2 = ex_pits as f64 * 100.0 / (total_cells * cell * cell / 1e6);
    let w1 = crate::metrics::wasserstein_binned;
    stats.slope_w1_to_exemplars = w1(out_hist, &pooled_used);
    stats.slope_w1_input_to_exemplars = w1(in_hist, &pooled_used);
    stats.slope_w1_to_all_exemplars = w1(out_hist, &pooled_all);
    stats.slope_w1_input_to_all_exemplars = w1(in_hist, &pooled_all);
    stats.exemplar_cells_used = exemplars
        .iter()
        .zip(&used)
        .map(|(e, &u)| (e.name.clone(), u))
        .collect();
}

/// 99th percentile of |Laplacian| over seam cells (a 4-neighbour has another owner) divided by
/// the 99th percentile over all interior cells; 0 if there is no seam.
pub fn seam_ratio(h: &[f32], owner: &[u32], n: usize) -> f64 {
    let mut all = Vec::with_capacity(n * n);
    let mut seam = Vec::new();
    for y in 1..n.saturating_sub(1) {
        for x in 1..n - 1 {
            let i = y * n + x;
            let lap = (h[i - 1] + h[i + 1] + h[i - n] + h[i + n] - 4.0 * h[i]).abs();
            all.push(lap);
            let o = owner[i];
            if [i - 1, i + 1, i - n, i + n].iter().any(|&j| owner[j] != o) {
                seam.push(lap);
            }
        }
    }
    let p99 = |v: &mut Vec<f32>| -> f64 {
        if v.is_empty() {
            return 0.0;
        }
        let k = ((v.len() as f64 * 0.99) as usize).min(v.len() - 1);
        f64::from(*v.select_nth_unstable_by(k, f32::total_cmp).1)
    };
    let (s, a) = (p99(&mut seam), p99(&mut all));
    if a > 0.0 { s / a } else { 0.0 }
}

/// Cells averaged on each side of an edge by [`seam_gradient_jump_ratio`].
pub const SEAM_JUMP_SPAN: usize = 4;

/// How visible seams are in a hillshade: for every edge between two 4-neighbours, the gradient
/// across it (perpendicular to a seam running along it) is averaged over [`SEAM_JUMP_SPAN`]
/// cells on each side and the jump `|g_after - g_before|` taken. Returns the mean jump over
/// seam edges (the two cells have different owners) divided by the mean over all edges; 0 if
/// there is no seam. A seam where the slope turns abruptly (a crease that a hillshade shows as
/// a line) scores above 1 even when the Laplacian's tail, dominated by rough texture, does not.
pub fn seam_gradient_jump_ratio(h: &[f32], owner: &[u32], n: usize) -> f64 {
    let k = SEAM_JUMP_SPAN;
    if n < 2 * k + 2 {
        return 0.0;
    }
    // Rows in parallel, sums per row (f64), reduced in order.
    let rows: Vec<[f64; 4]> = (0..n)
        .into_par_iter()
        .map(|y| {
            let mut acc = [0.0f64; 4]; // seam sum, seam count, all sum, all count
            let mut add = |jump: f32, seam: bool| {
                let j = f64::from(jump);
                acc[2] += j;
                acc[3] += 1.0;
                if seam {
                    acc[0] += j;
                    acc[1] += 1.0;
                }
            };
            let kf = k as f32;
            // East edges: between x and x + 1.
            for x in k..n - k - 1 {
                let i = y * n + x;
                let before = (h[i] - h[i - k]) / kf;
                let after = (h[i + 1 + k] - h[i + 1]) / kf;
                add((after - before).abs(), owner[i] != owner[i + 1]);
            }
            // South edges: between y and y + 1.
            if y >= k && y + k + 1 < n {
                for x in 0..n {
                    let i = y * n + x;
                    let before = (h[i] - h[i - k * n]) / kf;
                    let after = (h[i + (k + 1) * n] - h[i + n]) / kf;
                    add((after - before).abs(), owner[i] != owner[i + n]);
                }
            }
            acc
        })
        .collect();
    let mut t = [0.0f64; 4];
    for r in &rows {
        for (a, b) in t.iter_mut().zip(r) {
            *a += b;
        }
    }
    if t[1] == 0.0 || t[2] == 0.0 {
        return 0.0;
    }
    (t[0] / t[1]) / (t[2] / t[3])
}
