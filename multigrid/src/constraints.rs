//! Rasterisation of strokes into level-0 constraint maps.
//!
//! Per texel and per stroke, the closest point on the stroke's polyline (in metres, seen from above)
//! decides everything: its distance `d`, its height `z`, the side (left/right of the direction of
//! travel) and the direction `n` from the curve to the texel. With `c` the larger cell side:
//! - elevation weight `clamp(1.5 - d / c, 0, 1)`: hard (1) within half a cell of the curve, so a curve is
//!   never thinner than one texel (at least 8-connected), anti-aliased over the next cell; plateaus extend
//!   the hard core to `width_m`;
//! - band weight `clamp((width_m - d) / c + 0.5, 0, 1)` for ridges and valleys, with the gradient
//!   `-tan(slope) n` (ridge: falls away) or `+tan(slope) n` (valley: rises away);
//! - roughness over the whole footprint.
//!
//! Where strokes overlap, the closest stroke gives the values and the weights are the maxima, so the
//! result does not depend on drawing order except for exact ties (later wins).

use rayon::prelude::*;
use terrasketch_sketch::{Sketch, StrokeKind};

use crate::cpu::simd::multiversion;
use crate::grid::Grid;

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

/// A stroke prepared for rasterisation: segments and per-kind parameters.
struct Prepared {
    kind: StrokeKind,
    segs: Vec<Seg>,
    tan_left: f32,
    tan_right: f32,
    width_m: f32,
    roughness: f32,
    /// Texel-row range this stroke can touch.
    rows: std::ops::Range<usize>,
}

#[derive(Clone, Copy)]
struct Seg {
    a: [f64; 3],
    b: [f64; 3],
    /// `b - a` in x and y, and `1 / |b - a|^2` (0 for a single point).
    e: [f64; 2],
    inv_len2: f64,
    /// Expanded bounding box in metres: x0, x1, y0, y1.
    bbox: [f64; 4],
}

impl Seg {
    fn new(a: [f64; 3], b: [f64; 3], bbox: [f64; 4]) -> Seg {
        let e = [b[0] - a[0], b[1] - a[1]];
        let len2 = e[0] * e[0] + e[1] * e[1];
        Seg {
            a,
            b,
            e,
            inv_len2: if len2 > 0.0 { 1.0 / len2 } else { 0.0 },
            bbox,
        }
    }

    /// A superset of the x-interval (metres) of the points of the line `y` within `r` of the
    /// segment: the part of the segment within `r` of the line, widened by `r`. `None` if empty.
    fn row_interval(&self, y: f64, r: f64) -> Option<(f64, f64)> {
        let [ex, ey] = self.e;
        let (t0, t1) = if ey == 0.0 {
            if (self.a[1] - y).abs() > r {
                return None;
            }
            (0.0, 1.0)
        } else {
            let u = (y - r - self.a[1]) / ey;
            let v = (y + r - self.a[1]) / ey;
            (u.min(v).max(0.0), u.max(v).min(1.0))
        };
        if t0 > t1 {
            return None;
        }
        let (x0, x1) = (self.a[0] + t0 * ex, self.a[0] + t1 * ex);
        Some((x0.min(x1) - r, x0.max(x1) + r))
    }
}

/// What the closest point of one stroke says about one texel.
#[derive(Clone, Copy)]
struct Hit {
    d: f64,
    z: f64,
    /// Unit vector from the curve to the texel (0 if on the curve).
    dir: [f64; 2],
    left: bool,
}

/// One row of every map, and the per-row compositing scratch.
struct RowOut<'a> {
    ew: &'a mut [f32],
    ev: &'a mut [f32],
    bw: &'a mut [f32],
    gx: &'a mut [f32],
    gy: &'a mut [f32],
    rw: &'a mut [f32],
    rv: &'a mut [f32],
    /// Distance (m) to the stroke that set the elevation value.
    ed: &'a mut [f32],
    /// Distance (m) to the stroke that set the band values.
    bd: &'a mut [f32],
}

/// Per-row scratch of the rasteriser (kept per worker thread).
#[derive(Default)]
struct RowScratch {
    ed: Vec<f32>,
    bd: Vec<f32>,
    /// Per texel of the current row and stroke: smallest squared distance so far and the index of
    /// its segment (`NO_SEG`: none within reach).
    best_d2: Vec<f64>,
    best_seg: Vec<u32>,
    /// Candidate segments of the current row and stroke: index and texel range.
    cand: Vec<(u32, std::ops::Range<usize>)>,
}

/// `best_seg` value of a texel that no segment reaches.
const NO_SEG: u32 = u32::MAX;

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
        let out = [
            &mut self.elev_weight[span.clone()],
            &mut self.elev_value[span.clone()],
            &mut self.band_weight[span.clone()],
            &mut self.grad_x[span.clone()],
            &mut self.grad_y[span.clone()],
            &mut self.rough_weight[span.clone()],
            &mut self.rough_value[span],
        ];
        rasterize_block(sketch, grid, rows, 0..n, out);
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
        let out = [
            &mut band.elev_weight,
            &mut band.elev_value,
            &mut band.band_weight,
            &mut band.grad_x,
            &mut band.grad_y,
            &mut band.rough_weight,
            &mut band.rough_value,
        ]
        .map(|v| {
            v.resize(len, 0.0);
            &mut v[..]
        });
        if len > 0 {
            rasterize_block(sketch, grid, rows, cols, out);
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
        let Some(p) = sketch
            .strokes
            .get(stroke)
            .and_then(|s| prepare(s, grid, cell))
        else {
            return Vec::new();
        };
        p.rows
            .clone()
            .filter_map(|j| {
                let (a, b) = candidate_ranges(&p, dx, dy, cell, j, grid.n)
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
        sketch
            .strokes
            .get(stroke)
            .and_then(|s| prepare(s, grid, dx.max(dy)))
            .map(|p| p.rows)
            .unwrap_or(0..0)
    }
}

/// The nearest-segment scratch of one row.
struct Nearest<'a> {
    best_d2: &'a mut [f64],
    best_seg: &'a mut [u32],
    cand: &'a mut Vec<(u32, std::ops::Range<usize>)>,
}

/// Composites stroke `p` into row `j`.
///
/// Candidate segments are those whose expanded box holds the row, each with a conservative texel
/// range of the points within reach. Every candidate, in segment order, lowers a per-texel minimum
/// of the squared distance (a branch-free loop); a segment replaces the current one only if
/// strictly closer. Segments out of reach never win, so the winner of each texel (the smallest
/// squared distance, the first segment on exact ties) is the one a test of all segments gives.
fn splat_row(
    p: &Prepared,
    [dx, dy]: [f64; 2],
    cell: f64,
    j: usize,
    cols: std::ops::Range<usize>,
    out: &mut RowOut<'_>,
    near: &mut Nearest<'_>,
) {
    // `out` and `near` hold the texels `cols` of the row: local index = column - c0.
    let (c0, c1) = (cols.start, cols.end);
    let y = (j as f64 + 0.5) * dy;
    let reach = reach_m(p, cell);
    near.cand.clear();
    let (mut i0, mut i1) = (c1 - c0, 0);
    for (k, range) in candidate_ranges(p, dx, dy, cell, j, c1) {
        let (ia, ib) = (range.start.max(c0), range.end);
        if ia < ib {
            near.cand.push((k, ia - c0..ib - c0));
            i0 = i0.min(ia - c0);
            i1 = i1.max(ib - c0);
        }
    }
    if i0 >= i1 {
        return;
    }
    let reach2 = reach * reach;
    near.best_d2[i0..i1].fill(reach2);
    near.best_seg[i0..i1].fill(NO_SEG);
    for (k, range) in near.cand.iter() {
        let s = &p.segs[*k as usize];
        nearer(
            s,
            y,
            dx,
            c0 + range.start,
            &mut near.best_d2[range.clone()],
            &mut near.best_seg[range.clone()],
            *k,
        );
    }
    let core = if p.kind == StrokeKind::Plateau {
        p.width_m as f64
    } else {
        0.0
    };
    for i in i0..i1 {
        let k = near.best_seg[i];
        if k == NO_SEG {
            continue;
        }
        let x = ((c0 + i) as f64 + 0.5) * dx;
        let hit = hit_of(&p.segs[k as usize], x, y, near.best_d2[i]);
        let d = hit.d;
        let d32 = d as f32;
        // Elevation.
        let we = ((core - d) / cell + 1.5).clamp(0.0, 1.0) as f32;
        if we > 0.0 {
            if d32 <= out.ed[i] {
                out.ed[i] = d32;
                out.ev[i] = hit.z as f32;
            }
            out.ew[i] = out.ew[i].max(we);
        }
        // Gradient band (ridges and valleys), outside the hard core.
        let mut wb = 0.0f32;
        if p.kind != StrokeKind::Plateau && d > 0.5 * cell {
            wb = ((p.width_m as f64 - d) / cell + 0.5).clamp(0.0, 1.0) as f32;
            if wb > 0.0 {
                if d32 <= out.bd[i] {
                    out.bd[i] = d32;
                    let t = if hit.left { p.tan_left } else { p.tan_right };
                    let s = if p.kind == StrokeKind::Ridge { -t } else { t };
                    out.gx[i] = s * hit.dir[0] as f32;
                    out.gy[i] = s * hit.dir[1] as f32;
                }
                out.bw[i] = out.bw[i].max(wb);
            }
        }
        // Roughness over the footprint.
        let wr = we
            .max(wb)
            .max(if d <= p.width_m as f64 { 1.0 } else { 0.0 });
        if wr > 0.0 {
            if wr >= out.rw[i] {
                out.rv[i] = p.roughness;
            }
            out.rw[i] = out.rw[i].max(wr);
        }
    }
}

/// The candidate segments of stroke `p` on row `j` with their texel ranges (clipped to `0..n`): a
/// conservative range of the texels within reach of each segment (the part of the segment within
/// `reach + c/2` of the row, widened by that much). Empty ranges are left out.
fn candidate_ranges(
    p: &Prepared,
    dx: f64,
    dy: f64,
    cell: f64,
    j: usize,
    n: usize,
) -> impl Iterator<Item = (u32, std::ops::Range<usize>)> + '_ {
    let y = (j as f64 + 0.5) * dy;
    // Margin so that the ranges are strict supersets despite rounding.
    let r = reach_m(p, cell) + 0.5 * cell;
    p.segs.iter().enumerate().filter_map(move |(k, s)| {
        if y >= s.bbox[2] && y <= s.bbox[3] {
            let (a, b) = s.row_interval(y, r)?;
            let ia = ((a / dx - 0.5).floor().max(0.0) as usize).min(n);
            let ib = ((b / dx + 0.5).ceil().max(0.0) as usize).min(n);
            (ia < ib).then_some((k as u32, ia..ib))
        } else {
            None
        }
    })
}

/// How far (metres) a stroke's influence reaches from its curve.
fn reach_m(p: &Prepared, cell: f64) -> f64 {
    p.width_m as f64 + 1.5 * cell
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
) {
    let n = cols.len();
    let [dx, dy] = grid.cell_size_m();
    let cell = dx.max(dy);
    let prepared: Vec<Prepared> = sketch
        .strokes
        .iter()
        .filter_map(|s| prepare(s, grid, cell))
        .filter(|p| p.rows.start < rows.end && p.rows.end > rows.start)
        .collect();
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
                let j = rows.start + r;
                for v in [
                    &mut *ew, &mut *ev, &mut *bw, &mut *gx, &mut *gy, &mut *rw, &mut *rv,
                ] {
                    v.fill(0.0);
                }
                scratch.ed.clear();
                scratch.ed.resize(n, f32::INFINITY);
                scratch.bd.clear();
                scratch.bd.resize(n, f32::INFINITY);
                scratch.best_d2.resize(n, 0.0);
                scratch.best_seg.resize(n, NO_SEG);
                let RowScratch {
                    ed,
                    bd,
                    best_d2,
                    best_seg,
                    cand,
                } = scratch;
                let mut near = Nearest {
                    best_d2,
                    best_seg,
                    cand,
                };
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
                for p in &prepared {
                    if p.rows.contains(&j) {
                        splat_row(p, [dx, dy], cell, j, cols.clone(), &mut out, &mut near);
                    }
                }
            },
        );
}

fn prepare(stroke: &terrasketch_sketch::Stroke, grid: &Grid, cell: f64) -> Option<Prepared> {
    let mut segs = Vec::new();
    let width_m = stroke.width_m.max(0.0);
    let reach = width_m + 1.5 * cell;
    for w in stroke.points.windows(2) {
        let (a, b) = (w[0], w[1]);
        if !(a.iter().chain(b.iter()).all(|v| v.is_finite())) {
            return None;
        }
        if a[0] == b[0] && a[1] == b[1] {
            continue;
        }
        let bbox = [
            a[0].min(b[0]) - reach,
            a[0].max(b[0]) + reach,
            a[1].min(b[1]) - reach,
            a[1].max(b[1]) + reach,
        ];
        segs.push(Seg::new(a, b, bbox));
    }
    if segs.is_empty() {
        // A stroke whose points all coincide (seen from above) is a single point: keep it as a dot.
        let a = *stroke.points.first()?;
        let bbox = [a[0] - reach, a[0] + reach, a[1] - reach, a[1] + reach];
        segs.push(Seg::new(a, a, bbox));
    }
    let dy = grid.cell_size_m()[1];
    let y0 = segs.iter().map(|s| s.bbox[2]).fold(f64::INFINITY, f64::min);
    let y1 = segs
        .iter()
        .map(|s| s.bbox[3])
        .fold(f64::NEG_INFINITY, f64::max);
    let j0 = (y0 / dy - 0.5).floor().clamp(0.0, grid.n as f64) as usize;
    let j1 = (y1 / dy + 0.5).ceil().clamp(0.0, grid.n as f64) as usize;
    let tan = |deg: f64| deg.clamp(0.0, 89.0).to_radians().tan() as f32;
    Some(Prepared {
        kind: stroke.kind,
        segs,
        tan_left: tan(stroke.slope_left_deg),
        tan_right: tan(stroke.slope_right_deg),
        width_m: width_m as f32,
        roughness: stroke.roughness.clamp(0.0, 1.0) as f32,
        rows: j0..j1,
    })
}

multiversion! {
    /// Lowers `best_d2` / `best_seg` (texels `i0..`) with segment `s` (index `k`): a texel takes the
    /// segment if its squared distance is strictly smaller, or equal to the initial bound with no
    /// segment yet.
    fn nearer(
        s: &Seg,
        y: f64,
        dx: f64,
        i0: usize,
        best_d2: &mut [f64],
        best_seg: &mut [u32],
        k: u32,
    ) {
        let [ex, ey] = s.e;
        let (ax, inv) = (s.a[0], s.inv_len2);
        let py = y - s.a[1];
        let i0 = i0 as i32;
        for (o, (bd, bs)) in best_d2.iter_mut().zip(best_seg.iter_mut()).enumerate() {
            let x = ((i0 + o as i32) as f64 + 0.5) * dx;
            let px = x - ax;
            let t = ((px * ex + py * ey) * inv).clamp(0.0, 1.0);
            let (vx, vy) = (px - t * ex, py - t * ey);
            let d2 = vx * vx + vy * vy;
            let take = d2 < *bd || (d2 == *bd && *bs == NO_SEG);
            *bd = if take { d2 } else { *bd };
            *bs = if take { k } else { *bs };
        }
    }
}

/// What segment `s`, at squared distance `d2` from `(x, y)`, says about that texel (the same
/// arithmetic as `nearer`).
fn hit_of(s: &Seg, x: f64, y: f64, d2: f64) -> Hit {
    let [ex, ey] = s.e;
    let (px, py) = (x - s.a[0], y - s.a[1]);
    let t = ((px * ex + py * ey) * s.inv_len2).clamp(0.0, 1.0);
    let (vx, vy) = (px - t * ex, py - t * ey);
    let d = d2.sqrt();
    let z = s.a[2] + t * (s.b[2] - s.a[2]);
    let dir = if d > 1e-9 {
        [vx / d, vy / d]
    } else {
        [0.0, 0.0]
    };
    let left = ex * vy - ey * vx > 0.0;
    Hit { d, z, dir, left }
}

#[cfg(test)]
mod tests {
    use super::*;
    use terrasketch_sketch::Stroke;

    fn grid(n: usize) -> Grid {
        Grid::new(n, [6400.0, 6400.0]).unwrap()
    }

    #[test]
    fn curve_is_never_thinner_than_one_texel() {
        // A diagonal stroke at an awkward angle: every column it crosses has a hard texel.
        let g = grid(64);
        let s = Sketch {
            extent_m: g.extent_m,
            base_elevation_m: 0.0,
            strokes: vec![Stroke::new(
                StrokeKind::Ridge,
                vec![[130.0, 710.0, 500.0], [6100.0, 4333.0, 700.0]],
            )],
        };
        let m = ConstraintMaps::rasterize(&s, &g);
        let n = g.n;
        for i in 2..60 {
            let hard = (0..n).filter(|&j| m.elev_weight[j * n + i] >= 1.0).count();
            assert!(hard >= 1, "column {i} has no hard texel");
        }
        // Heights along the curve interpolate between 500 and 700.
        let vals: Vec<f32> = (0..n * n)
            .filter(|&k| m.elev_weight[k] >= 1.0)
            .map(|k| m.elev_value[k])
            .collect();
        assert!(vals.iter().all(|v| (499.0..=701.0).contains(v)));
    }

    #[test]
    fn ridge_band_gradients_point_down_and_away() {
        let g = grid(64);
        let mut st = Stroke::new(
            StrokeKind::Ridge,
            vec![[0.0, 3200.0, 800.0], [6400.0, 3200.0, 800.0]],
        );
        st.slope_left_deg = 30.0;
        st.slope_right_deg = 10.0;
        st.width_m = 1000.0;
        let s = Sketch {
            extent_m: g.extent_m,
            base_elevation_m: 0.0,
            strokes: vec![st],
        };
        let m = ConstraintMaps::rasterize(&s, &g);
        let n = g.n;
        // Travel is eastward: left = north. North of the ridge heights fall northward: gy = -tan 30.
        let north = 40 * n + 32; // y = 4050 m, 850 m north of the curve
        assert!((m.grad_y[north] + 30f32.to_radians().tan()).abs() < 1e-5);
        assert!(m.band_weight[north] == 1.0);
        let south = 26 * n + 32; // y = 2650 m, 550 m south
        assert!((m.grad_y[south] - 10f32.to_radians().tan()).abs() < 1e-5);
        // Outside the band: nothing.
        let far = 60 * n + 32;
        assert_eq!(m.band_weight[far], 0.0);
        assert_eq!(m.elev_weight[far], 0.0);
    }

    #[test]
    fn incremental_rows_match_full_rasterisation() {
        let g = grid(128);
        let s = terrasketch_sketch::benchmark_sketch();
        let g = Grid::new(g.n, s.extent_m).unwrap();
        let full = ConstraintMaps::rasterize(&s, &g);
        let mut part = ConstraintMaps::rasterize(
            &Sketch {
                strokes: vec![],
                ..s.clone()
            },
            &g,
        );
        part.rasterize_rows(&s, &g, 0..50);
        part.rasterize_rows(&s, &g, 50..128);
        assert_eq!(full, part);
    }

    #[test]
    fn column_windows_match_full_rasterisation_bit_for_bit() {
        for (s, n) in [
            (terrasketch_sketch::benchmark_sketch(), 128),
            (terrasketch_sketch::example_sketch(), 256),
        ] {
            let g = Grid::new(n, s.extent_m).unwrap();
            let full = ConstraintMaps::rasterize(&s, &g);
            let mut band = ConstraintMaps::new(0);
            // Windows of every shape: edges, one column, odd offsets, the whole grid.
            let mut seed = 7usize;
            let mut windows = vec![(0..n, 0..n), (0..1, n - 1..n), (n - 3..n, 0..1)];
            for _ in 0..20 {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let (a, b) = ((seed >> 20) % n, (seed >> 40) % n);
                let (c, d) = ((seed >> 8) % n, (seed >> 50) % n);
                windows.push((a.min(b)..a.max(b) + 1, c.min(d)..c.max(d) + 1));
            }
            for (rows, cols) in windows {
                ConstraintMaps::rasterize_band_cols(&mut band, &s, &g, rows.clone(), cols.clone());
                let w = cols.len();
                for (r, j) in rows.clone().enumerate() {
                    for (c, i) in cols.clone().enumerate() {
                        let (k, l) = (r * w + c, j * n + i);
                        let pairs = [
                            (band.elev_weight[k], full.elev_weight[l]),
                            (band.elev_value[k], full.elev_value[l]),
                            (band.band_weight[k], full.band_weight[l]),
                            (band.grad_x[k], full.grad_x[l]),
                            (band.grad_y[k], full.grad_y[l]),
                            (band.rough_weight[k], full.rough_weight[l]),
                            (band.rough_value[k], full.rough_value[l]),
                        ];
                        for (m, (a, b)) in pairs.iter().enumerate() {
                            assert_eq!(
                                a.to_bits(),
                                b.to_bits(),
                                "map {m} at ({i},{j}), window {rows:?} x {cols:?}"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn stroke_spans_cover_every_texel_the_stroke_changes() {
        let s = terrasketch_sketch::benchmark_sketch();
        let n = 128;
        let g = Grid::new(n, s.extent_m).unwrap();
        let full = ConstraintMaps::rasterize(&s, &g);
        for stroke in 0..s.strokes.len() {
            let mut without = s.clone();
            without.strokes.remove(stroke);
            let other = ConstraintMaps::rasterize(&without, &g);
            let spans = ConstraintMaps::stroke_spans(&s, stroke, &g);
            let covered = |i: usize, j: usize| spans.iter().any(|(r, c)| *r == j && c.contains(&i));
            let mut changed = 0;
            for j in 0..n {
                for i in 0..n {
                    let l = j * n + i;
                    let differs = [
                        (&full.elev_weight, &other.elev_weight),
                        (&full.elev_value, &other.elev_value),
                        (&full.band_weight, &other.band_weight),
                        (&full.grad_x, &other.grad_x),
                        (&full.grad_y, &other.grad_y),
                        (&full.rough_weight, &other.rough_weight),
                        (&full.rough_value, &other.rough_value),
                    ]
                    .iter()
                    .any(|(a, b)| a[l].to_bits() != b[l].to_bits());
                    if differs {
                        changed += 1;
                        assert!(
                            covered(i, j),
                            "stroke {stroke} changes ({i},{j}) outside its spans"
                        );
                    }
                }
            }
            assert!(changed > 0, "stroke {stroke} changes nothing");
            // Spans are narrower than whole rows (they are worth having).
            let cells: usize = spans.iter().map(|(_, c)| c.len()).sum();
            assert!(cells < n * n, "stroke {stroke}: spans cover the whole grid");
        }
    }
}
