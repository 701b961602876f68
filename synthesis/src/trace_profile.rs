//! Cross-sections of a traced line and the stroke attributes fitted to them: one width, one slope
//! per side, one falloff per piece, and where a line is cut into pieces.

use terrasketch_sketch::{Falloff, MAX_SLOPE_DEG};

use crate::trace::{MAX_SECTIONS, SPLIT_SLOPE_FACTOR, TraceGrid};

/// Points of the normalised cross-section profile kept per side, at `u = 0.1, 0.2, .. 1.0`.
const SHAPE_POINTS: usize = 10;
/// A side walk stops once the land has fallen back from its best rise by this share of it...
const CREST_FALL_SHARE: f64 = 0.25;
/// ...or by this many metres, whichever is larger; a rise under it is no side at all.
const CREST_TOL_M: f64 = 1.0;
/// Path points on each side of a section used for its tangent.
const TANGENT_REACH: usize = 3;
/// The falloffs `auto` chooses from: the fading ones. A constant slope (`none`) often fits a
/// DEM's cross-section best but leaves a crease at the band edge, and its solved slopes are further
/// from the DEM's (synthesis/README.md, "Trace").
const FITTED: [Falloff; 2] = [Falloff::Foot, Falloff::Sigmoid];
/// A piece's width: this quantile of its sections' crest distances (both sides pooled).
const WIDTH_QUANTILE: f64 = 0.75;

/// One side of a cross-section: the distance to the crest (the trough, for a ridge), the rise
/// there, and the profile normalised by both.
#[derive(Clone, Debug)]
pub(crate) struct Side {
    pub width_m: f64,
    pub rise_m: f64,
    pub shape: [f64; SHAPE_POINTS],
}

/// A cross-section at path point `index`: left and right of the direction of travel.
#[derive(Clone, Debug)]
pub(crate) struct Section {
    pub index: usize,
    pub sides: [Option<Side>; 2],
}

impl Section {
    /// Sections at up to [`MAX_SECTIONS`] evenly spaced points of `path` (sketch metres, the DEM's
    /// heights). `sign` is 1 for a valley (the land rises away), -1 for a ridge.
    pub(crate) fn measure_along(
        grid: &TraceGrid<'_>,
        path: &[[f64; 3]],
        sign: f64,
    ) -> Vec<Section> {
        let n = path.len();
        let stride = n.div_ceil(MAX_SECTIONS).max(1);
        let step = grid.cell_size_m[0].min(grid.cell_size_m[1]);
        let max_steps = (grid.width.max(grid.height) / 2).clamp(8, 512);
        (0..n)
            .step_by(stride)
            .filter_map(|i| {
                let (p, q) = (
                    path[i.saturating_sub(TANGENT_REACH)],
                    path[(i + TANGENT_REACH).min(n - 1)],
                );
                let (tx, ty) = (q[0] - p[0], q[1] - p[1]);
                let len = tx.hypot(ty);
                if len <= 0.0 {
                    return None;
                }
                let left = [-ty / len, tx / len];
                let walk = |dir: f64| {
                    let normal = [dir * left[0], dir * left[1]];
                    walk_side(grid, path[i], normal, sign, step, max_steps)
                };
                Some(Section {
                    index: i,
                    sides: [walk(1.0), walk(-1.0)],
                })
            })
            .collect()
    }

    /// Log of the mean of the sides' mean slopes (`rise / width`), if any side was measured.
    fn log_tangent(&self) -> Option<f64> {
        let t: Vec<f64> = self
            .sides
            .iter()
            .flatten()
            .map(|s| s.rise_m / s.width_m)
            .collect();
        (!t.is_empty()).then(|| (t.iter().sum::<f64>() / t.len() as f64).ln())
    }
}

/// Walks from `p` along `normal` until the land falls back from its best rise (see the constants).
fn walk_side(
    grid: &TraceGrid<'_>,
    p: [f64; 3],
    normal: [f64; 2],
    sign: f64,
    step: f64,
    max_steps: usize,
) -> Option<Side> {
    let mut profile = vec![0.0];
    let (mut best, mut best_j) = (0.0f64, 0usize);
    for j in 1..=max_steps {
        let d = j as f64 * step;
        let Some(h) = grid.sample(p[0] + d * normal[0], p[1] + d * normal[1]) else {
            break;
        };
        let rise = sign * (h - p[2]);
        profile.push(rise);
        if rise > best {
            (best, best_j) = (rise, j);
        }
        if rise < best - (CREST_FALL_SHARE * best).max(CREST_TOL_M) {
            break;
        }
    }
    if best <= CREST_TOL_M || best_j == 0 {
        return None;
    }
    let mut shape = [0.0; SHAPE_POINTS];
    for (k, s) in shape.iter_mut().enumerate() {
        let at = (k + 1) as f64 / SHAPE_POINTS as f64 * best_j as f64;
        let (j0, f) = (at.floor() as usize, at.fract());
        let j1 = (j0 + 1).min(best_j);
        *s = (profile[j0] * (1.0 - f) + profile[j1] * f) / best;
    }
    Some(Side {
        width_m: best_j as f64 * step,
        rise_m: best,
        shape,
    })
}

/// Where `path` is cut: inclusive point ranges sharing their cut points, so the pieces join.
/// Binary segmentation on the sections' log mean slope: a cut is kept where the two parts' means
/// differ by more than [`SPLIT_SLOPE_FACTOR`] and both parts are at least `min_length_m` long.
pub(crate) fn split(
    path: &[[f64; 3]],
    sections: &[Section],
    min_length_m: f64,
) -> Vec<(usize, usize)> {
    let mut cum = vec![0.0; path.len()];
    for i in 1..path.len() {
        cum[i] = cum[i - 1] + (path[i][0] - path[i - 1][0]).hypot(path[i][1] - path[i - 1][1]);
    }
    let values: Vec<(usize, f64)> = sections
        .iter()
        .filter_map(|s| s.log_tangent().map(|v| (s.index, v)))
        .collect();
    let mut out = Vec::new();
    let mut todo = vec![(0, path.len().saturating_sub(1))];
    while let Some((a, b)) = todo.pop() {
        match best_cut(&values, &cum, a, b, min_length_m) {
            Some(c) => todo.extend([(a, c), (c, b)]),
            None => out.push((a, b)),
        }
    }
    out.sort_unstable();
    out
}

/// The cut of `[a, b]` with the largest two-sample statistic, if its means differ enough.
fn best_cut(
    values: &[(usize, f64)],
    cum: &[f64],
    a: usize,
    b: usize,
    min_len: f64,
) -> Option<usize> {
    let v: Vec<(usize, f64)> = values
        .iter()
        .copied()
        .filter(|&(i, _)| i > a && i < b)
        .collect();
    let n = v.len();
    if n < 8 {
        return None;
    }
    let total: f64 = v.iter().map(|p| p.1).sum();
    let mut left = 0.0;
    let mut best: Option<(f64, usize)> = None;
    for k in 1..n {
        left += v[k - 1].1;
        let cut = v[k].0;
        if k < 3 || n - k < 3 || cum[cut] - cum[a] < min_len || cum[b] - cum[cut] < min_len {
            continue;
        }
        let (ml, mr) = (left / k as f64, (total - left) / (n - k) as f64);
        if (ml - mr).abs() <= SPLIT_SLOPE_FACTOR.ln() {
            continue;
        }
        let score = (ml - mr).abs() * ((k * (n - k)) as f64 / n as f64).sqrt();
        if best.is_none_or(|(s, _)| score > s) {
            best = Some((score, cut));
        }
    }
    best.map(|(_, cut)| cut)
}

/// A piece's stroke attributes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Fit {
    pub width_m: f64,
    /// Left, right (of the direction of travel).
    pub slope_deg: [f64; 2],
    pub falloff: Falloff,
}

/// The attributes of the piece `[a, b]` from its sections (module documentation of `trace`);
/// `None` if no side was measured (the land never rises away from the line).
pub(crate) fn fit_line(
    sections: &[Section],
    a: usize,
    b: usize,
    forced: Option<Falloff>,
) -> Option<Fit> {
    let inside: Vec<&Section> = sections
        .iter()
        .filter(|s| s.index >= a && s.index <= b)
        .collect();
    let pooled: Vec<&Side> = inside
        .iter()
        .flat_map(|s| s.sides.iter().flatten())
        .collect();
    let width_m = quantile(pooled.iter().map(|s| s.width_m).collect(), WIDTH_QUANTILE)?;
    let falloff = forced.unwrap_or_else(|| {
        let measured: Vec<f64> = (0..SHAPE_POINTS)
            .map(|k| median(pooled.iter().map(|s| s.shape[k]).collect()).unwrap_or(0.0))
            .collect();
        let misfit = |f: Falloff| -> f64 {
            (0..SHAPE_POINTS)
                .map(|k| {
                    (measured[k] - cumulative(f, (k + 1) as f64 / SHAPE_POINTS as f64)).powi(2)
                })
                .sum()
        };
        FITTED
            .into_iter()
            .min_by(|x, y| misfit(*x).total_cmp(&misfit(*y)))
            .unwrap_or_default()
    });
    let mean_profile = cumulative_raw(falloff, 1.0);
    let slope = |side: usize| {
        let t = median(
            inside
                .iter()
                .filter_map(|s| s.sides[side].as_ref())
                .map(|s| s.rise_m / s.width_m)
                .collect(),
        )
        .unwrap_or(0.0);
        (t / mean_profile)
            .atan()
            .to_degrees()
            .clamp(0.0, MAX_SLOPE_DEG)
    };
    Some(Fit {
        width_m,
        slope_deg: [slope(0), slope(1)],
        falloff,
    })
}

/// `∫_0^u profile`, by Simpson's rule on 64 intervals.
pub(crate) fn cumulative_raw(f: Falloff, u: f64) -> f64 {
    let n = 64;
    let h = u / n as f64;
    let sum: f64 = (0..=n)
        .map(|i| {
            let w = if i == 0 || i == n {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            w * f.profile(i as f64 * h)
        })
        .sum();
    sum * h / 3.0
}

/// The rise of a band with falloff `f` at `u` as a share of its total rise.
pub(crate) fn cumulative(f: Falloff, u: f64) -> f64 {
    cumulative_raw(f, u) / cumulative_raw(f, 1.0)
}

/// Median (mean of the middle two for an even count); `None` when empty.
fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_unstable_by(f64::total_cmp);
    let m = v.len() / 2;
    Some(if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    })
}

/// The `q` quantile (linear between order statistics); `None` when empty.
fn quantile(mut v: Vec<f64>, q: f64) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_unstable_by(f64::total_cmp);
    let at = q.clamp(0.0, 1.0) * (v.len() - 1) as f64;
    let (i, f) = (at.floor() as usize, at.fract());
    Some(v[i] * (1.0 - f) + v[(i + 1).min(v.len() - 1)] * f)
}
