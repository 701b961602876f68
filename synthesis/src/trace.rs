//! `trace`: a DEM's main valleys and ridges as editable sketch strokes.
//!
//! 1. **Networks.** D8 flow on a breached copy of the DEM gives the drainage network (valleys); the
//!    same on the negated DEM gives the divides (ridges) (`trace_flow.rs`). Cells draining at least
//!    [`TraceParams::channel_cells`] cells are channels; the channel tree is cut into main-stem
//!    streams (the larger donor continues at a confluence), ranked by the area they drain at their
//!    lowest own cell, so a tributary always ranks below the stream it joins.
//! 2. **Lines.** Streams shorter than the minimum length are dropped; the best ones (half of the
//!    stroke budget each for valleys and ridges) become lines: cell centres in sketch metres with
//!    the DEM's own heights on the thalweg or crest, plan position smoothed (three [1/4 1/2 1/4]
//!    passes, ends fixed so tributaries still touch their parent).
//! 3. **Cross-sections** (`trace_profile.rs`): at up to [`MAX_SECTIONS`] points along a line, each
//!    side is walked along the normal until the land has fallen back from its highest rise (lowest,
//!    for ridges) by a quarter of it: the distance to that crest `W_i` and the rise `R_i`.
//! 4. **One value per side.** A stroke has one width and one slope per side while real valleys
//!    change along their course. Lines are cut where the mean slope (log of `R_i / W_i`) of one
//!    part differs from the other's by more than a factor 2 (binary segmentation, pieces at least
//!    the minimum length); then each piece takes robust medians: `width_m` = median `W_i` over
//!    both sides, and per side the median mean slope `R_i / W_i`, divided by the falloff's mean
//!    profile so that the band's total rise matches the DEM's. The falloff is the one whose
//!    normalised cumulative profile is closest to the median measured profile (unless forced).
//! 5. **Control points**: Douglas-Peucker ([`terrasketch_sketch::simplify`]) within one cell in
//!    plan and `max(1 m, relief / 500)` in height; the smooth curve passes through them.
//! 6. **Roughness** (`trace_rough.rs`): the roughness under which the live detail's law gives the
//!    land within `width_m` of the piece its high-pass residual.

use rayon::prelude::*;
use terrasketch_sketch::{
    Falloff, MAX_EXTENT_M, Sketch, SketchError, Stroke, StrokeKind, simplify, validate,
};

use crate::trace_flow::{Stream, d8_flow, streams};
use crate::trace_profile::{Section, fit_line};

/// Smallest DEM side `trace` accepts, in cells.
pub const MIN_TRACE_SIDE: usize = 16;
/// Most cells `trace` accepts (2^26, 8192^2): its working arrays take about 40 bytes a cell.
pub const MAX_TRACE_CELLS: usize = 1 << 26;
/// Most strokes `trace` writes.
pub const MAX_TRACE_STROKES: usize = 10_000;
/// Most cross-sections measured along one line.
pub const MAX_SECTIONS: usize = 256;
/// Smoothing passes of a line's plan position (about a Gaussian of `sqrt(passes / 2)` cells)...
const SMOOTH_PASSES: usize = 24;
/// ...and of its heights.
const SMOOTH_PASSES_Z: usize = 8;
/// Control points: Douglas-Peucker tolerance in plan, in cells...
const SIMPLIFY_CELLS: f64 = 2.0;
/// ...and in height, as a share of the DEM's relief (at least 1 m).
const SIMPLIFY_RELIEF: f64 = 1.0 / 300.0;
/// Lines are cut where the mean slope of one part is more than this factor from the other's.
pub const SPLIT_SLOPE_FACTOR: f64 = 2.0;

/// Options of [`trace`].
#[derive(Clone, Debug, PartialEq)]
pub struct TraceParams {
    /// Most strokes written: half valleys (rounded up), half ridges.
    pub max_strokes: usize,
    /// Shortest stroke in metres; `None`: 1/32 of the DEM's larger side (at least 8 cells).
    pub min_length_m: Option<f64>,
    /// Cells a channel drains at least; `None`: 1/1000 of the DEM's cells (at least 8).
    pub channel_cells: Option<u32>,
    /// Every stroke's falloff; `None`: fitted per stroke to the DEM's cross-sections.
    pub falloff: Option<Falloff>,
}

impl Default for TraceParams {
    fn default() -> Self {
        Self {
            max_strokes: 200,
            min_length_m: None,
            channel_cells: None,
            falloff: None,
        }
    }
}

/// What [`trace`] found.
#[derive(Clone, Debug)]
pub struct Traced {
    /// The sketch: the DEM's extent, its mean height as base elevation, ridges then valleys.
    pub sketch: Sketch,
    /// Valley strokes written.
    pub valleys: usize,
    /// Ridge strokes written.
    pub ridges: usize,
    /// Lines cut into pieces where their slope changes (each piece is one stroke).
    pub lines_split: usize,
    /// Why the sketch has fewer strokes than asked (a flat DEM, short networks).
    pub warnings: Vec<String>,
}

/// Why [`trace`] refused.
#[derive(Debug, thiserror::Error)]
pub enum TraceError {
    /// The grid is too small to hold a network.
    #[error("{width}x{height} cells is too small to trace (at least {MIN_TRACE_SIDE} a side)")]
    TooSmall {
        /// Columns.
        width: usize,
        /// Rows.
        height: usize,
    },
    /// The grid is over [`MAX_TRACE_CELLS`].
    #[error("{width}x{height} cells is over trace's limit of {MAX_TRACE_CELLS} cells: crop it")]
    TooLarge {
        /// Columns.
        width: usize,
        /// Rows.
        height: usize,
    },
    /// An option or the grid is inconsistent.
    #[error("{0}")]
    BadInput(String),
    /// The traced sketch breaks a rule of the format (e.g. an extent or height out of range).
    #[error("the traced sketch is not valid: {0}")]
    Sketch(#[from] SketchError),
}

/// A grid to trace: heights in metres, row 0 = north, `cell_size_m` = `[east-west, north-south]`.
#[derive(Clone, Copy, Debug)]
pub struct TraceGrid<'a> {
    /// `width * height` finite heights, row-major.
    pub heights: &'a [f32],
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Cell size in metres.
    pub cell_size_m: [f64; 2],
}

impl TraceGrid<'_> {
    /// Sketch metres `[x east, y north]` of the centre of cell `i`.
    pub(crate) fn centre_m(&self, i: usize) -> [f64; 2] {
        let (col, row) = (i % self.width, i / self.width);
        [
            (col as f64 + 0.5) * self.cell_size_m[0],
            (self.height as f64 - row as f64 - 0.5) * self.cell_size_m[1],
        ]
    }

    /// Bilinear height at sketch metres `(x, y)`; `None` outside the cell centres' hull.
    pub(crate) fn sample(&self, x: f64, y: f64) -> Option<f64> {
        let col = x / self.cell_size_m[0] - 0.5;
        let row = self.height as f64 - y / self.cell_size_m[1] - 0.5;
        let (wmax, hmax) = ((self.width - 1) as f64, (self.height - 1) as f64);
        if !(col >= 0.0 && row >= 0.0 && col <= wmax && row <= hmax) {
            return None;
        }
        let (c0, r0) = (
            (col as usize).min(self.width - 2),
            (row as usize).min(self.height - 2),
        );
        let (fc, fr) = (col - c0 as f64, row - r0 as f64);
        let h = |c: usize, r: usize| f64::from(self.heights[r * self.width + c]);
        let top = h(c0, r0) * (1.0 - fc) + h(c0 + 1, r0) * fc;
        let bottom = h(c0, r0 + 1) * (1.0 - fc) + h(c0 + 1, r0 + 1) * fc;
        Some(top * (1.0 - fr) + bottom * fr)
    }

    /// The larger cell side in metres.
    pub(crate) fn cell_max(&self) -> f64 {
        self.cell_size_m[0].max(self.cell_size_m[1])
    }
}

/// Traces the main valleys and ridges of `grid` into a sketch (see the module documentation).
pub fn trace(grid: &TraceGrid<'_>, params: &TraceParams) -> Result<Traced, TraceError> {
    check(grid, params)?;
    let [cx, cy] = grid.cell_size_m;
    let extent_m = [grid.width as f64 * cx, grid.height as f64 * cy];
    let (lo, hi) = grid
        .heights
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &h| {
            (lo.min(h), hi.max(h))
        });
    let mean = grid.heights.iter().map(|&h| f64::from(h)).sum::<f64>() / grid.heights.len() as f64;
    let relief = f64::from(hi) - f64::from(lo);
    let mut traced = Traced {
        sketch: Sketch::empty(extent_m, mean),
        valleys: 0,
        ridges: 0,
        lines_split: 0,
        warnings: Vec::new(),
    };
    if relief <= 1e-3 + 1e-5 * extent_m[0].hypot(extent_m[1]) {
        traced.warnings.push(format!(
            "the DEM is flat (relief {relief:.3} m): no valleys or ridges, the sketch is empty"
        ));
        validate(&traced.sketch)?;
        return Ok(traced);
    }
    let min_length_m = params
        .min_length_m
        .unwrap_or_else(|| (extent_m[0].max(extent_m[1]) / 32.0).max(8.0 * grid.cell_max()));
    let channel = params
        .channel_cells
        .unwrap_or_else(|| (grid.heights.len() / 1000).max(8) as u32);
    let budget_valleys = params.max_strokes.div_ceil(2);
    let opts = LineOptions {
        min_length_m,
        tol_z_m: (relief * SIMPLIFY_RELIEF).max(1.0),
        falloff: params.falloff,
        rough: crate::trace_rough::RoughnessMaps::new(grid),
    };
    let kinds = [
        (StrokeKind::Ridge, params.max_strokes - budget_valleys),
        (StrokeKind::Valley, budget_valleys),
    ];
    // Valleys and ridges are independent: traced side by side.
    let network = |(kind, budget): (StrokeKind, usize)| {
        if budget == 0 {
            return (Vec::new(), 0);
        }
        let sign = if kind == StrokeKind::Valley {
            1.0
        } else {
            -1.0
        };
        let flow = d8_flow(
            grid.heights,
            grid.width,
            grid.height,
            grid.cell_size_m,
            sign,
        );
        let mut candidates = streams(&flow, channel);
        drop(flow);
        candidates.sort_by(|a, b| {
            b.outlet_acc
                .cmp(&a.outlet_acc)
                .then(a.cells[0].cmp(&b.cells[0]))
        });
        select(grid, kind, &candidates, budget, &opts)
    };
    let (ridges, valleys) = rayon::join(|| network(kinds[0]), || network(kinds[1]));
    for ((kind, budget), (strokes, split)) in kinds.into_iter().zip([ridges, valleys]) {
        let name = kind.as_str();
        if strokes.len() < budget {
            traced.warnings.push(format!(
                "{} {name} strokes of the {budget} asked for: the DEM has no more {name} lines of at least {min_length_m:.0} m draining {channel} cells",
                strokes.len()
            ));
        }
        match kind {
            StrokeKind::Valley => traced.valleys = strokes.len(),
            _ => traced.ridges = strokes.len(),
        }
        traced.lines_split += split;
        traced.sketch.strokes.extend(strokes);
    }
    validate(&traced.sketch)?;
    Ok(traced)
}

fn check(grid: &TraceGrid<'_>, params: &TraceParams) -> Result<(), TraceError> {
    let (width, height) = (grid.width, grid.height);
    if width.checked_mul(height) != Some(grid.heights.len()) {
        return Err(TraceError::BadInput(format!(
            "{} heights for a {width}x{height} grid",
            grid.heights.len()
        )));
    }
    if width < MIN_TRACE_SIDE || height < MIN_TRACE_SIDE {
        return Err(TraceError::TooSmall { width, height });
    }
    if grid.heights.len() > MAX_TRACE_CELLS {
        return Err(TraceError::TooLarge { width, height });
    }
    if !grid.cell_size_m.iter().all(|c| c.is_finite() && *c > 0.0) {
        return Err(TraceError::BadInput(format!(
            "invalid cell size {:?} m",
            grid.cell_size_m
        )));
    }
    if grid.heights.iter().any(|h| !h.is_finite()) {
        return Err(TraceError::BadInput(
            "the grid has non-finite heights".into(),
        ));
    }
    if !(1..=MAX_TRACE_STROKES).contains(&params.max_strokes) {
        return Err(TraceError::BadInput(format!(
            "the number of strokes must be 1 to {MAX_TRACE_STROKES}, got {}",
            params.max_strokes
        )));
    }
    if let Some(m) = params.min_length_m
        && !(0.0..=MAX_EXTENT_M).contains(&m)
    {
        return Err(TraceError::BadInput(format!(
            "the minimum length must be 0 to {MAX_EXTENT_M} m, got {m}"
        )));
    }
    if params.channel_cells == Some(0) {
        return Err(TraceError::BadInput(
            "a channel drains at least 1 cell".into(),
        ));
    }
    Ok(())
}

/// Per-line settings of [`select`].
pub(crate) struct LineOptions {
    pub min_length_m: f64,
    pub tol_z_m: f64,
    pub falloff: Option<Falloff>,
    /// The DEM's high-pass residual and law maps each stroke's roughness is measured on.
    pub rough: crate::trace_rough::RoughnessMaps,
}

/// The best `budget` strokes of the ranked `candidates`: lines measured in parallel batches, each
/// cut where its slope changes, pieces taken in rank order. Returns the strokes and how many lines
/// were cut.
fn select(
    grid: &TraceGrid<'_>,
    kind: StrokeKind,
    candidates: &[Stream],
    budget: usize,
    opts: &LineOptions,
) -> (Vec<Stroke>, usize) {
    let mut out = Vec::new();
    let mut split = 0;
    let batch = rayon::current_num_threads().max(1) * 4;
    let mut rest = candidates;
    while out.len() < budget && !rest.is_empty() {
        let take = batch.min(rest.len());
        let lines: Vec<Vec<Stroke>> = rest[..take]
            .par_iter()
            .map(|s| line_strokes(grid, kind, s, opts))
            .collect();
        rest = &rest[take..];
        for pieces in lines {
            split += usize::from(pieces.len() > 1);
            // Downstream pieces first: they drain more, as the ranking does.
            for p in pieces.into_iter().rev() {
                if out.len() < budget {
                    out.push(p);
                }
            }
        }
    }
    (out, split)
}

/// A stream as strokes: its path in metres, smoothed, measured, cut where its slope changes.
fn line_strokes(
    grid: &TraceGrid<'_>,
    kind: StrokeKind,
    stream: &Stream,
    opts: &LineOptions,
) -> Vec<Stroke> {
    let path = smooth_path(grid, &stream.cells);
    let length: f64 = path
        .windows(2)
        .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
        .sum();
    if length < opts.min_length_m || path.len() < 2 {
        return Vec::new();
    }
    let sign = if kind == StrokeKind::Valley {
        1.0
    } else {
        -1.0
    };
    let sections = Section::measure_along(grid, &path, sign);
    let pieces = crate::trace_profile::split(&path, &sections, opts.min_length_m);
    pieces
        .into_iter()
        .filter_map(|(a, b)| {
            // A piece whose land never rises away on either side is no valley (ridge): a flow path
            // across a lake or a plain.
            let fit = fit_line(&sections, a, b, opts.falloff)?;
            let points = simplify(&path[a..=b], SIMPLIFY_CELLS * grid.cell_max(), opts.tol_z_m);
            (points.len() >= 2).then(|| Stroke {
                slope_left_deg: fit.slope_deg[0],
                slope_right_deg: fit.slope_deg[1],
                width_m: fit.width_m,
                falloff: fit.falloff,
                roughness: opts.rough.stroke(grid, &path[a..=b], fit.width_m),
                ..Stroke::new(kind, points)
            })
        })
        .collect()
}

/// Cell centres in sketch metres with the DEM's heights; plan position and heights smoothed
/// (binomial passes of [1/4 1/2 1/4], ends fixed): a D8 path zigzags across the thalweg or crest by a
/// cell, and its heights with it.
fn smooth_path(grid: &TraceGrid<'_>, cells: &[u32]) -> Vec<[f64; 3]> {
    let mut path: Vec<[f64; 3]> = cells
        .iter()
        .map(|&c| {
            let [x, y] = grid.centre_m(c as usize);
            [x, y, f64::from(grid.heights[c as usize])]
        })
        .collect();
    for pass in 0..SMOOTH_PASSES {
        let prev = path.clone();
        let dims = if pass < SMOOTH_PASSES_Z { 3 } else { 2 };
        for i in 1..path.len().saturating_sub(1) {
            for k in 0..dims {
                path[i][k] = 0.25 * prev[i - 1][k] + 0.5 * prev[i][k] + 0.25 * prev[i + 1][k];
            }
        }
    }
    path
}
