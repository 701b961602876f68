//! Rasterising a sketch's strokes into the solver's constraint maps, by groups of rows in
//! parallel, straight into the level-1 gradient and level-2 roughness problems.

use std::ops::Range;
use std::time::Instant;

use rayon::prelude::*;
use terrasketch_sketch::Sketch;

use super::CpuSolver;
use crate::constraints::{PreparedSketch, RowScratch};
use crate::fields;
use crate::grid::Grid;

impl CpuSolver {
    /// Rasterises level-0 rows `rows`, all columns (see `rasterize_spans`).
    pub(super) fn rasterize(&mut self, sketch: &Sketch, rows: Range<usize>, track: bool) {
        let n = self.grid.n;
        let spans: Vec<(usize, Range<usize>)> = rows.map(|j| (j, 0..n)).collect();
        self.rasterize_spans(sketch, &spans, track);
    }

    /// Rasterises the texels `spans` (row, columns), widened to whole level-2 cells (rows and
    /// columns in multiples of 4) and, per group of `RASTER_ROWS` rows, to one column window (the
    /// union of the group's spans); texels outside come out as they were. Groups run in parallel,
    /// each straight into its rows: the elevation and band maps into `maps`, the gradient and
    /// roughness maps into their level-1 and level-2 downsampled forms, so that no level-0
    /// gradient or roughness map is ever whole. With `track`, the cells whose elevation constraint
    /// changed are appended to `changed` (ascending).
    pub(super) fn rasterize_spans(
        &mut self,
        sketch: &Sketch,
        spans: &[(usize, Range<usize>)],
        track: bool,
    ) {
        let t = Instant::now();
        crate::cpu::par::on_worker(|| self.rasterize_spans_inner(sketch, spans, track));
        self.phase_ms.rasterize += t.elapsed().as_secs_f64() * 1e3;
    }

    fn rasterize_spans_inner(
        &mut self,
        sketch: &Sketch,
        spans: &[(usize, Range<usize>)],
        track: bool,
    ) {
        let n = self.grid.n;
        // Column window per group.
        let mut window = vec![(n, 0usize); n / RASTER_ROWS];
        for (j, c) in spans {
            let (j, a, b) = (*j, c.start, c.end.min(n));
            if j >= n || a >= b {
                continue;
            }
            let w = &mut window[j / RASTER_ROWS];
            *w = (w.0.min(a / 4 * 4), w.1.max(b.div_ceil(4) * 4).min(n));
        }
        for (all, w) in self.raster_windows.iter_mut().zip(&window) {
            if w.0 < w.1 {
                *all = (all.0.min(w.0), all.1.max(w.1));
            }
        }
        let sketch = PreparedSketch::new(sketch, &self.grid);
        let (rows0, rows1, rows2) = (RASTER_ROWS * n, RASTER_ROWS / 2 * n / 2, n / 4);
        let changed: Vec<Vec<u32>> = self
            .maps
            .elev_weight
            .par_chunks_mut(rows0)
            .zip(self.heights.values_mut().par_chunks_mut(rows0))
            .zip(self.maps.band_weight.par_chunks_mut(rows0))
            .zip(self.grad_w.par_chunks_mut(rows1))
            .zip(self.grad.values_mut().par_chunks_mut(rows1))
            .zip(self.grad_rhs_y.values_mut().par_chunks_mut(rows1))
            .zip(self.rough_w.par_chunks_mut(rows2))
            .zip(self.rough_v.par_chunks_mut(rows2))
            .zip(window.par_iter())
            .enumerate()
            .filter(|(_, (_, w))| w.0 < w.1)
            .map_init(
                RasterScratch::default,
                |scratch, (g, ((((((((ew, ev), bw), gw), gx), gy), rw), rv), w))| {
                    let level0 = [ew, ev, bw];
                    let level1 = [gw, gx, gy];
                    let level2 = [rw, rv];
                    rasterize_group(
                        &sketch, &self.grid, g, *w, track, scratch, level0, level1, level2,
                    )
                },
            )
            .collect();
        for c in changed {
            self.changed.extend(c);
        }
    }
}

/// Rows per rasterisation group (the side of a level-2 cell): an edit re-rasterises one column
/// window per group.
pub(super) const RASTER_ROWS: usize = 4;

/// One group's level-0 maps, rasterised aside (all seven) or the gradient and roughness ones only
/// (cold, whole rows), and their downsampled rows (per worker thread).
#[derive(Default)]
struct RasterScratch {
    maps: [Vec<f32>; 7],
    down: [Vec<f32>; 3],
    row: RowScratch,
}

/// Rasterises group `g` (level-0 rows `RASTER_ROWS g ..`) in columns `c0..c1` into its rows of
/// the elevation weight, elevation value and band weight maps (`level0`), of the gradient
/// problem's level-1 weight and x / y values (`level1`) and of the roughness problem's level-2
/// weight and value (`level2`). Returns the level-0 cells whose elevation constraint changed
/// (ascending) if `track`. Without `track` and with whole rows, the level-0 maps are written in
/// place; otherwise the window is rasterised aside and copied in.
#[allow(clippy::too_many_arguments)]
fn rasterize_group<'a>(
    sketch: &PreparedSketch,
    grid: &Grid,
    g: usize,
    (c0, c1): (usize, usize),
    track: bool,
    scratch: &mut RasterScratch,
    level0: [&'a mut [f32]; 3],
    mut level1: [&'a mut [f32]; 3],
    mut level2: [&'a mut [f32]; 2],
) -> Vec<u32> {
    let n = grid.n;
    let w = c1 - c0;
    let a = g * RASTER_ROWS;
    let RasterScratch { maps, down, row } = scratch;
    for v in maps.iter_mut() {
        v.resize(RASTER_ROWS * w, 0.0);
    }
    let direct = !track && w == n;
    let [ew, ev, bw] = level0;
    let [m0, m1, m2, m3, m4, m5, m6] = maps;
    for r in 0..RASTER_ROWS {
        let k = r * w..(r + 1) * w;
        let first: [&mut [f32]; 3] = if direct {
            [&mut ew[k.clone()], &mut ev[k.clone()], &mut bw[k.clone()]]
        } else {
            [&mut m0[k.clone()], &mut m1[k.clone()], &mut m2[k.clone()]]
        };
        let [x0, x1, x2] = first;
        sketch.row(
            a + r,
            c0..c1,
            [
                x0,
                x1,
                x2,
                &mut m3[k.clone()],
                &mut m4[k.clone()],
                &mut m5[k.clone()],
                &mut m6[k],
            ],
            row,
        );
    }
    let mut changed = Vec::new();
    if !direct {
        // The window's rows into the maps, noting the changed elevation cells.
        for r in 0..RASTER_ROWS {
            let (new_w, new_v, new_b) = (
                &m0[r * w..(r + 1) * w],
                &m1[r * w..(r + 1) * w],
                &m2[r * w..(r + 1) * w],
            );
            let o = r * n + c0..r * n + c1;
            let (ow, ov, ob) = (&mut ew[o.clone()], &mut ev[o.clone()], &mut bw[o]);
            if track {
                let start = (a + r) * n + c0;
                for k in 0..w {
                    if ow[k] != new_w[k] || (new_w[k] > 0.0 && ov[k] != new_v[k]) {
                        changed.push((start + k) as u32);
                    }
                }
            }
            ow.copy_from_slice(new_w);
            ov.copy_from_slice(new_v);
            ob.copy_from_slice(new_b);
        }
    }
    // The window's part of the level-1 gradient problem and the level-2 roughness problem.
    let band: &[f32] = if direct { bw } else { m2 };
    let [d0, d1, d2] = down;
    for (f, weight, values, outs) in [
        (2usize, band, [&m3[..], &m4[..]], &mut level1[..]),
        (4, &m5[..], [&m6[..], &[][..]], &mut level2[..]),
    ] {
        let (nf, wc, rows_c) = (n / f, w / f, RASTER_ROWS / f);
        for v in [&mut *d0, &mut *d1, &mut *d2] {
            v.resize(wc * rows_c, 0.0);
        }
        let count = if f == 2 { 2 } else { 1 };
        fields::downsample_weighted_into(
            w,
            f,
            weight,
            &values[..count],
            (&mut d0[..], &mut d1[..], &mut d2[..]),
        );
        for (o, d) in outs.iter_mut().zip([&*d0, &*d1, &*d2]) {
            for rc in 0..rows_c {
                let start = rc * nf + c0 / f;
                o[start..start + wc].copy_from_slice(&d[rc * wc..(rc + 1) * wc]);
            }
        }
    }
    changed
}
