//! Rasterisation of strokes into level-0 constraint maps.
//!
//! Every stroke is first turned into its curve's fine polyline (`terrasketch_sketch::stroke_curve`,
//! shared with the GPU twin and the editor). Per texel and per stroke, the closest point on that
//! polyline (in metres, seen from above) decides everything: its distance `d`, its height `z`, the side (left/right of the direction of
//! travel) and the direction `n` from the curve to the texel. With `c` the larger cell side:
//! - elevation weight `clamp(1.5 - d / c, 0, 1)`: hard (1) within half a cell of the curve, so a curve is
//!   never thinner than one texel (at least 8-connected), anti-aliased over the next cell; plateaus extend
//!   the hard core to `width_m`;
//! - band weight `clamp((width_m - d) / c + 0.5, 0, 1)` for ridges and valleys, with the gradient
//!   `-tan(slope) f(d / width_m) n` (ridge: falls away) or `+tan(slope) f(d / width_m) n` (valley:
//!   rises away), `f` the stroke's falloff profile (`Falloff`: 1 at the curve, fading to 0 at the
//!   band edge so the slope eases into the land instead of stopping dead);
//! - roughness over the whole footprint.
//!
//! Where strokes overlap, the closest stroke gives the values and the weights are the maxima, so the
//! result does not depend on drawing order except for exact ties (later wins).
//!
//! The module is split by concern: `segments` turns a stroke into segments with their boxes and
//! finds each row's candidates, `texels` runs the per-texel arithmetic (closest point, then the
//! maps' values), and this file drives rows and blocks over the maps.

use rayon::prelude::*;
use terrasketch_sketch::Sketch;

use crate::grid::Grid;

mod segments;
#[cfg(test)]
mod tests;
mod texels;

use segments::{Prepared, candidate_ranges, prepare, prepare_one};
pub(crate) use texels::RowScratch;
use texels::{RowOut, splat_row};

/// Level-0 constraint maps. All arrays are `n * n`, row 0 = south, index `j * n + i`.
#[derive(Debug, Clone, PartialEq)]
pub struct ConstraintMaps {
    /// Cells per side.
    pub n: usize,
    /// Elevation constraint weight in [0, 1] (1 = hard).
    pub elev_weight: Vec<f32>,
    /// Constrained elevation, metres.
    pub elev_value: Vec<f32>,
    /// Gradient band coverage in [0, 1] (ridges and valleys).
    pub band_weight: Vec<f32>,
    /// Prescribed gradient, x component (dz/dx, unitless).
    pub grad_x: Vec<f32>,
    /// Prescribed gradient, y component (dz/dy, unitless).
    pub grad_y: Vec<f32>,
    /// Roughness constraint weight (stroke footprint coverage).
    pub rough_weight: Vec<f32>,
    /// Constrained roughness in [0, 1].
    pub rough_value: Vec<f32>,
}

impl ConstraintMaps {
    /// Empty maps (no constraint anywhere) for an `n x n` grid.
    pub fn new(n: usize) -> ConstraintMaps {
        let z = || vec![0.0f32; n * n];
        ConstraintMaps {
            n,
            elev_weight: z(),
            elev_value: z(),
            band_weight: z(),
            grad_x: z(),
            grad_y: z(),
            rough_weight: z(),
            rough_value: z(),
        }
    }

    /// The seven maps in the rasteriser's order: elevation weight and value, band weight, gradient x
    /// and y, roughness weight and value.
    fn arrays_mut(&mut self) -> [&mut Vec<f32>; 7] {
        [
            &mut self.elev_weight,
            &mut self.elev_value,
            &mut self.band_weight,
            &mut self.grad_x,
            &mut self.grad_y,
            &mut self.rough_weight,
            &mut self.rough_value,
        ]
    }

    /// Rasterises the whole sketch.
    pub fn rasterize(sketch: &Sketch, grid: &Grid) -> ConstraintMaps {
        let mut maps = ConstraintMaps::new(grid.n);
        maps.rasterize_rows(sketch, grid, 0..grid.n);
        maps
    }

    /// Clears rows `rows` and rasterises every stroke into them (incremental update after an edit).
    ///
    /// Rows are independent: each row is cleared and composited stroke by stroke (in sketch order),
    /// in parallel over rows, with per-row scratch only.
    pub fn rasterize_rows(&mut self, sketch: &Sketch, grid: &Grid, rows: std::ops::Range<usize>) {
        let n = self.n;
        let rows = rows.start.min(n)..rows.end.min(n);
        if rows.is_empty() {
            return;
        }
        let span = rows.start * n..rows.end * n;
        let out = self.arrays_mut().map(|v| &mut v[span.clone()]);
        rasterize_block(sketch, grid, rows, 0..n, out, false);
    }

    /// Rasterises rows `rows` of an `n x n` grid into `band`, a band of maps holding just those
    /// rows (every array `rows.len() * n` cells, row `rows.start` first; `band.n` is ignored). The
    /// values are those `rasterize_rows` writes into the same rows of full maps.
    pub fn rasterize_band(
        band: &mut ConstraintMaps,
        sketch: &Sketch,
        grid: &Grid,
        rows: std::ops::Range<usize>,
    ) {
        ConstraintMaps::rasterize_band_cols(band, sketch, grid, rows, 0..grid.n);
    }

    /// Like `rasterize_band`, but only the columns `cols`: every array holds `rows.len() *
    /// cols.len()` cells, row-major, with the values a full rasterisation gives those texels
    /// (bit for bit: a texel's closest segment is chosen among the same candidates).
    pub fn rasterize_band_cols(
        band: &mut ConstraintMaps,
        sketch: &Sketch,
        grid: &Grid,
        rows: std::ops::Range<usize>,
        cols: std::ops::Range<usize>,
    ) {
        let n = grid.n;
        let rows = rows.start.min(n)..rows.end.min(n);
        let cols = cols.start.min(n)..cols.end.min(n);
        let len = rows.len() * cols.len();
        let out = band.arrays_mut().map(|v| {
            v.resize(len, 0.0);
            &mut v[..]
        });
        if len > 0 {
            rasterize_block(sketch, grid, rows, cols, out, false);
        }
    }

    /// Per texel row that stroke `stroke` of `sketch` can touch, the columns of the texels within
    /// its reach (the texels whose values can change when the stroke is added, removed or moved),
    /// rows ascending, rows without such texels left out. Pass the spans of an edited stroke before
    /// and after the edit to `CpuSolver::update_sketch_spans`.
    pub fn stroke_spans(
        sketch: &Sketch,
        stroke: usize,
        grid: &Grid,
    ) -> Vec<(usize, std::ops::Range<usize>)> {
        let [dx, dy] = grid.cell_size_m();
        let cell = dx.max(dy);
        let Some(p) = prepare_one(sketch, stroke, grid, cell) else {
            return Vec::new();
        };
        p.rows
            .clone()
            .into_par_iter()
            .filter_map(|j| {
                let (a, b) = candidate_ranges(&p, dx, dy, cell, j, 0..grid.n)
                    .fold((usize::MAX, 0), |(a, b), (_, r)| {
                        (a.min(r.start), b.max(r.end))
                    });
                (a < b).then_some((j, a..b))
            })
            .collect()
    }

    /// Rows of the grid that stroke `stroke` of `sketch` can touch (for dirty tracking).
    pub fn stroke_rows(sketch: &Sketch, stroke: usize, grid: &Grid) -> std::ops::Range<usize> {
        let [dx, dy] = grid.cell_size_m();
        prepare_one(sketch, stroke, grid, dx.max(dy))
            .map(|p| p.rows)
            .unwrap_or(0..0)
    }
}

/// Rasterises rows `rows` x columns `cols` of an `n x n` grid into `out` (elevation weight and value,
/// band weight, gradient x and y, roughness weight and value), each holding `rows.len() * cols.len()`
/// cells, row-major.
fn rasterize_block(
    sketch: &Sketch,
    grid: &Grid,
    rows: std::ops::Range<usize>,
    cols: std::ops::Range<usize>,
    out: [&mut [f32]; 7],
    exhaustive: bool,
) {
    let n = cols.len();
    let prepared = PreparedSketch::new_for_rows(sketch, grid, rows.clone(), exhaustive);
    let [ew, ev, bw, gx, gy, rw, rv] = out;
    ew.par_chunks_mut(n)
        .zip(ev.par_chunks_mut(n))
        .zip(bw.par_chunks_mut(n))
        .zip(gx.par_chunks_mut(n))
        .zip(gy.par_chunks_mut(n))
        .zip(rw.par_chunks_mut(n))
        .zip(rv.par_chunks_mut(n))
        .enumerate()
        .with_min_len(4)
        .for_each_init(
            RowScratch::default,
            |scratch, (r, ((((((ew, ev), bw), gx), gy), rw), rv))| {
                prepared.row(
                    rows.start + r,
                    cols.clone(),
                    [ew, ev, bw, gx, gy, rw, rv],
                    scratch,
                );
            },
        );
}

/// The strokes of a sketch prepared for rasterisation (segments with their boxes, per-kind
/// constants), for callers that rasterise many small blocks: prepared once, not per block.
pub(crate) struct PreparedSketch {
    pub(crate) strokes: Vec<Prepared>,
    dx: f64,
    dy: f64,
    cell: f64,
}

impl PreparedSketch {
    /// Every stroke of `sketch` (those without finite points left out).
    pub(crate) fn new(sketch: &Sketch, grid: &Grid) -> PreparedSketch {
        PreparedSketch::new_for_rows(sketch, grid, 0..grid.n, false)
    }

    /// The strokes that can touch rows `rows`.
    fn new_for_rows(
        sketch: &Sketch,
        grid: &Grid,
        rows: std::ops::Range<usize>,
        exhaustive: bool,
    ) -> PreparedSketch {
        let [dx, dy] = grid.cell_size_m();
        let cell = dx.max(dy);
        let curves = terrasketch_sketch::stroke_curves(sketch, cell);
        let strokes = sketch
            .strokes
            .iter()
            .zip(curves)
            .filter_map(|(s, c)| prepare(s, c, grid, cell))
            .filter(|p| p.rows.start < rows.end && p.rows.end > rows.start)
            .map(|p| Prepared { exhaustive, ..p })
            .collect();
        PreparedSketch {
            strokes,
            dx,
            dy,
            cell,
        }
    }

    /// Rasterises row `j`, columns `cols`, into `out` (the seven maps' cells of those columns, in
    /// the order of `rasterize_block`), on the calling thread: the values `rasterize_block` gives
    /// them, bit for bit.
    pub(crate) fn row(
        &self,
        j: usize,
        cols: std::ops::Range<usize>,
        out: [&mut [f32]; 7],
        scratch: &mut RowScratch,
    ) {
        let n = cols.len();
        let [ew, ev, bw, gx, gy, rw, rv] = out;
        for v in [
            &mut *ew, &mut *ev, &mut *bw, &mut *gx, &mut *gy, &mut *rw, &mut *rv,
        ] {
            v[..n].fill(0.0);
        }
        scratch.ed.clear();
        scratch.ed.resize(n, f32::INFINITY);
        scratch.bd.clear();
        scratch.bd.resize(n, f32::INFINITY);
        scratch.near.resize(n);
        let RowScratch { ed, bd, near } = scratch;
        let mut out = RowOut {
            ew,
            ev,
            bw,
            gx,
            gy,
            rw,
            rv,
            ed,
            bd,
        };
        for p in &self.strokes {
            if p.rows.contains(&j) {
                splat_row(
                    p,
                    [self.dx, self.dy],
                    self.cell,
                    j,
                    cols.clone(),
                    &mut out,
                    near,
                );
            }
        }
    }
}
