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
    /// Distance (m) to the stroke that set the elevation value (scratch for compositing).
    elev_dist: Vec<f32>,
    /// Distance (m) to the stroke that set the band values (scratch for compositing).
    band_dist: Vec<f32>,
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
            elev_dist: vec![f32::INFINITY; n * n],
            band_dist: vec![f32::INFINITY; n * n],
        }
    }

    /// Rasterises the whole sketch.
    pub fn rasterize(sketch: &Sketch, grid: &Grid) -> ConstraintMaps {
        let mut maps = ConstraintMaps::new(grid.n);
        maps.rasterize_rows(sketch, grid, 0..grid.n);
        maps
    }

    /// Clears rows `rows` and rasterises every stroke into them (incremental update after an edit).
    pub fn rasterize_rows(&mut self, sketch: &Sketch, grid: &Grid, rows: std::ops::Range<usize>) {
        let n = self.n;
        let rows = rows.start.min(n)..rows.end.min(n);
        let span = rows.start * n..rows.end * n;
        for v in [
            &mut self.elev_weight,
            &mut self.elev_value,
            &mut self.band_weight,
            &mut self.grad_x,
            &mut self.grad_y,
            &mut self.rough_weight,
            &mut self.rough_value,
        ] {
            v[span.clone()].iter_mut().for_each(|x| *x = 0.0);
        }
        self.elev_dist[span.clone()]
            .iter_mut()
            .for_each(|x| *x = f32::INFINITY);
        self.band_dist[span]
            .iter_mut()
            .for_each(|x| *x = f32::INFINITY);
        let [dx, dy] = grid.cell_size_m();
        let cell = dx.max(dy);
        for stroke in &sketch.strokes {
            let Some(p) = prepare(stroke, grid, cell) else {
                continue;
            };
            let lo = p.rows.start.max(rows.start);
            let hi = p.rows.end.min(rows.end);
            if lo >= hi {
                continue;
            }
            self.splat(&p, grid, cell, lo..hi);
        }
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

    fn splat(&mut self, p: &Prepared, grid: &Grid, cell: f64, rows: std::ops::Range<usize>) {
        let n = self.n;
        let [dx, dy] = grid.cell_size_m();
        let span = rows.start * n..rows.end * n;
        let reach = reach_m(p, cell);
        let elev_w = &mut self.elev_weight[span.clone()];
        let elev_v = &mut self.elev_value[span.clone()];
        let band_w = &mut self.band_weight[span.clone()];
        let gx = &mut self.grad_x[span.clone()];
        let gy = &mut self.grad_y[span.clone()];
        let rough_w = &mut self.rough_weight[span.clone()];
        let rough_v = &mut self.rough_value[span.clone()];
        let elev_d = &mut self.elev_dist[span.clone()];
        let band_d = &mut self.band_dist[span];
        elev_w
            .par_chunks_mut(n)
            .zip(elev_v.par_chunks_mut(n))
            .zip(band_w.par_chunks_mut(n))
            .zip(gx.par_chunks_mut(n))
            .zip(gy.par_chunks_mut(n))
            .zip(rough_w.par_chunks_mut(n))
            .zip(rough_v.par_chunks_mut(n))
            .zip(elev_d.par_chunks_mut(n))
            .zip(band_d.par_chunks_mut(n))
            .enumerate()
            .for_each(|(r, ((((((((ew, ev), bw), gx), gy), rw), rv), ed), bd))| {
                let j = rows.start + r;
                let y = (j as f64 + 0.5) * dy;
                let segs: Vec<&Seg> = p
                    .segs
                    .iter()
                    .filter(|s| y >= s.bbox[2] && y <= s.bbox[3])
                    .collect();
                if segs.is_empty() {
                    return;
                }
                let x0 = segs.iter().map(|s| s.bbox[0]).fold(f64::INFINITY, f64::min);
                let x1 = segs
                    .iter()
                    .map(|s| s.bbox[1])
                    .fold(f64::NEG_INFINITY, f64::max);
                let i0 = ((x0 / dx - 0.5).floor().max(0.0)) as usize;
                let i1 = ((x1 / dx + 0.5).ceil().max(0.0) as usize).min(n);
                for i in i0..i1 {
                    let x = (i as f64 + 0.5) * dx;
                    let Some(hit) = closest(&segs, x, y, reach) else {
                        continue;
                    };
                    let d = hit.d;
                    let d32 = d as f32;
                    // Elevation.
                    let core = if p.kind == StrokeKind::Plateau {
                        p.width_m as f64
                    } else {
                        0.0
                    };
                    let we = ((core - d) / cell + 1.5).clamp(0.0, 1.0) as f32;
                    if we > 0.0 {
                        if d32 <= ed[i] {
                            ed[i] = d32;
                            ev[i] = hit.z as f32;
                        }
                        ew[i] = ew[i].max(we);
                    }
                    // Gradient band (ridges and valleys), outside the hard core.
                    let mut wb = 0.0f32;
                    if p.kind != StrokeKind::Plateau && d > 0.5 * cell {
                        wb = ((p.width_m as f64 - d) / cell + 0.5).clamp(0.0, 1.0) as f32;
                        if wb > 0.0 {
                            if d32 <= bd[i] {
                                bd[i] = d32;
                                let t = if hit.left { p.tan_left } else { p.tan_right };
                                let s = if p.kind == StrokeKind::Ridge { -t } else { t };
                                gx[i] = s * hit.dir[0] as f32;
                                gy[i] = s * hit.dir[1] as f32;
                            }
                            bw[i] = bw[i].max(wb);
                        }
                    }
                    // Roughness over the footprint.
                    let wr = we
                        .max(wb)
                        .max(if d <= p.width_m as f64 { 1.0 } else { 0.0 });
                    if wr > 0.0 {
                        if wr >= rw[i] {
                            rv[i] = p.roughness;
                        }
                        rw[i] = rw[i].max(wr);
                    }
                }
            });
    }
}

/// How far (metres) a stroke's influence reaches from its curve.
fn reach_m(p: &Prepared, cell: f64) -> f64 {
    p.width_m as f64 + 1.5 * cell
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

/// Closest point of the candidate segments to `(x, y)` within `reach` metres.
///
/// Squared distances decide; the square root, height, direction and side are computed once, for the
/// winner (this loop runs for every texel of every stroke's band).
fn closest(segs: &[&Seg], x: f64, y: f64, reach: f64) -> Option<Hit> {
    let mut best_d2 = reach * reach;
    let mut best: Option<(&Seg, f64, f64, f64)> = None;
    for s in segs {
        if x < s.bbox[0] || x > s.bbox[1] {
            continue;
        }
        let [ex, ey] = s.e;
        let (px, py) = (x - s.a[0], y - s.a[1]);
        let t = ((px * ex + py * ey) * s.inv_len2).clamp(0.0, 1.0);
        let (vx, vy) = (px - t * ex, py - t * ey);
        let d2 = vx * vx + vy * vy;
        if d2 < best_d2 || (d2 == best_d2 && best.is_none()) {
            best_d2 = d2;
            best = Some((s, t, vx, vy));
        }
    }
    let (s, t, vx, vy) = best?;
    let d = best_d2.sqrt();
    let [ex, ey] = s.e;
    let z = s.a[2] + t * (s.b[2] - s.a[2]);
    let dir = if d > 1e-9 {
        [vx / d, vy / d]
    } else {
        [0.0, 0.0]
    };
    let left = ex * vy - ey * vx > 0.0;
    Some(Hit { d, z, dir, left })
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
}
