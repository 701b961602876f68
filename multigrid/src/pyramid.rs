//! Display mip chain and the min/max height pyramid, computed on the CPU (also the GPU's oracle).
//!
//! See `ALGORITHM.md`, "Mip chain and min/max pyramid".

use rayon::prelude::*;

use crate::cpu::rows::{mask, sel};
use crate::cpu::simd::multiversion;

/// Side of the finest min/max pyramid level the CPU keeps (64 x 64 cells, 32 KB).
pub const MINMAX_MAX_SIDE: usize = 64;

/// Per coarse level, the hard level-0 cells under each cell: the sum of their constrained values
/// and their count (the display shows the mean `sum / count` where the count is not 0).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct HardSummary {
    /// `levels[k - 1]`: level k, `(sum of the hard values, count of hard cells)` per cell.
    pub levels: Vec<Vec<(f32, f32)>>,
}

/// Sum and count of the hard values among the level-0 cells under level-1 cell `(ic, jc)` (side
/// `n` of level 0). Branch-free (`sel`), so that the row loops vectorise; the same order of sums
/// wherever it is called from.
#[inline(always)]
fn level1_cell(n: usize, weight: &[f32], value: &[f32], ic: usize, jc: usize) -> (f32, f32) {
    let b = 2 * jc * n + 2 * ic;
    let mut s = (0.0, 0.0);
    for o in [b, b + 1, b + n, b + n + 1] {
        let m = mask(weight[o] >= 1.0);
        s.0 += sel(m, value[o], 0.0);
        s.1 += sel(m, 1.0, 0.0);
    }
    s
}

/// The sums of the 4 children of cell `(ic, jc)` on the level above (`prev`, side `side`).
#[inline(always)]
fn coarser_cell(prev: &[(f32, f32)], side: usize, ic: usize, jc: usize) -> (f32, f32) {
    let b = 2 * jc * side + 2 * ic;
    let mut s = (0.0, 0.0);
    for o in [b, b + 1, b + side, b + side + 1] {
        s.0 += prev[o].0;
        s.1 += prev[o].1;
    }
    s
}

impl HardSummary {
    /// True if the levels exist for a level 0 of side `n`.
    fn sized(&self, n: usize) -> bool {
        self.levels.first().map(Vec::len) == Some(n * n / 4)
            && self.levels.last().map(Vec::len) == Some(1)
    }

    /// Builds the summary of level-0 hard cells (`weight >= 1`) for every level down to 1x1.
    pub fn new(n: usize, weight: &[f32], value: &[f32]) -> HardSummary {
        let mut s = HardSummary::default();
        s.rebuild(n, weight, value);
        s
    }

    /// `new` into the existing storage (no allocation once the levels exist).
    pub fn rebuild(&mut self, n: usize, weight: &[f32], value: &[f32]) {
        let mut sides = Vec::new();
        let mut side = n / 2;
        while side >= 1 && n >= 2 {
            sides.push(side);
            side /= 2;
        }
        self.levels.resize(sides.len(), Vec::new());
        for (l, &side) in self.levels.iter_mut().zip(&sides) {
            l.resize(side * side, (0.0, 0.0));
        }
        self.rebuild_rows(n, weight, value, 0..n);
    }

    /// Updates the cells over level-0 rows `rows` after the constraints of those rows changed
    /// (the levels must exist for `n`: `new` or `rebuild` first; otherwise everything is rebuilt).
    ///
    /// Level 1 is summed straight from level 0 and every coarser level from the sums of the level
    /// above (pairs summed in the same order whatever the rows), so the result is the same, bit
    /// for bit, as a whole rebuild.
    pub fn rebuild_rows(
        &mut self,
        n: usize,
        weight: &[f32],
        value: &[f32],
        rows: std::ops::Range<usize>,
    ) {
        if !self.sized(n) {
            return self.rebuild(n, weight, value);
        }
        let (lo, hi) = (rows.start.min(n), rows.end.min(n));
        if lo >= hi {
            return;
        }
        let n1 = n / 2;
        let (mut lo, mut hi) = (lo / 2, hi.div_ceil(2));
        self.levels[0][lo * n1..hi * n1]
            .par_chunks_mut(n1)
            .enumerate()
            .with_min_len(8)
            .for_each(|(r, row)| {
                for (ic, out) in row.iter_mut().enumerate() {
                    *out = level1_cell(n, weight, value, ic, lo + r);
                }
            });
        for k in 1..self.levels.len() {
            let (fine, coarse) = self.levels.split_at_mut(k);
            let prev = &fine[k - 1];
            let side = n >> k;
            let nc = side / 2;
            (lo, hi) = (lo / 2, hi.div_ceil(2));
            coarse[0][lo * nc..hi * nc]
                .par_chunks_mut(nc)
                .enumerate()
                .with_min_len(8)
                .for_each(|(r, row)| {
                    for (ic, out) in row.iter_mut().enumerate() {
                        *out = coarser_cell(prev, side, ic, lo + r);
                    }
                });
        }
    }

    /// Updates the cells over the level-0 cells `cells` (indices `j * n + i`, any order, repeats
    /// allowed) after the constraints of exactly those cells changed: each level's cells above
    /// them are summed again from their children, in the same order as a whole rebuild (so the
    /// result is the same bit for bit). The levels must exist for `n`; otherwise everything is
    /// rebuilt.
    pub fn update_cells(&mut self, n: usize, weight: &[f32], value: &[f32], cells: &[u32]) {
        if !self.sized(n) {
            return self.rebuild(n, weight, value);
        }
        let parents = |cells: &mut Vec<u32>, side: usize| {
            for c in cells.iter_mut() {
                let (i, j) = (*c as usize % side, *c as usize / side);
                *c = ((j / 2) * (side / 2) + i / 2) as u32;
            }
            cells.sort_unstable();
            cells.dedup();
        };
        let mut dirty: Vec<u32> = cells
            .iter()
            .filter(|c| (**c as usize) < n * n)
            .copied()
            .collect();
        parents(&mut dirty, n);
        for &c in &dirty {
            let (ic, jc) = (c as usize % (n / 2), c as usize / (n / 2));
            self.levels[0][c as usize] = level1_cell(n, weight, value, ic, jc);
        }
        for k in 1..self.levels.len() {
            let side = n >> k;
            parents(&mut dirty, side);
            let (fine, coarse) = self.levels.split_at_mut(k);
            for &c in &dirty {
                let (ic, jc) = (c as usize % (side / 2), c as usize / (side / 2));
                coarse[0][c as usize] = coarser_cell(&fine[k - 1], side, ic, jc);
            }
        }
    }
}

/// Display value of a coarse cell: the mean of the constrained values where the footprint holds a
/// hard cell (`summary` = (sum, count), see `HardSummary`), else `v`.
#[inline(always)]
pub fn display_value(summary: (f32, f32), v: f32) -> f32 {
    sel(mask(summary.1 > 0.0), summary.0 / summary.1, v)
}

/// Display downsample of `fine` (side `2 nc`) onto level `k` (side `nc`).
pub fn display_downsample(fine: &[f32], summary: &[(f32, f32)]) -> Vec<f32> {
    let mut out = vec![0.0; summary.len()];
    display_downsample_into(fine, summary, &mut out);
    out
}

/// [`display_downsample`] into an existing buffer of `summary.len()` cells.
pub fn display_downsample_into(fine: &[f32], summary: &[(f32, f32)], out: &mut [f32]) {
    let nc = (summary.len() as f64).sqrt() as usize;
    let nf = 2 * nc;
    out.par_chunks_mut(nc.max(1))
        .enumerate()
        .with_min_len(8)
        .for_each(|(jc, row)| {
            let f = &fine[2 * jc * nf..(2 * jc + 2) * nf];
            display_downsample_row(f, &summary[jc * nc..(jc + 1) * nc], row);
        });
}

multiversion! {
    /// One row of [`display_downsample_into`]: `fine` holds the two fine rows, `summary` and `out`
    /// the coarse row (an AVX2 build where available; the same arithmetic, the same bits).
    fn display_downsample_row(fine: &[f32], summary: &[(f32, f32)], out: &mut [f32]) {
        let nc = out.len();
        let nf = 2 * nc;
        let (f0, f1, summary) = (&fine[..nf], &fine[nf..2 * nf], &summary[..nc]);
        for ic in 0..nc {
            let b = 2 * ic;
            let avg = 0.25 * (f0[b] + f0[b + 1] + f1[b] + f1[b + 1]);
            out[ic] = display_value(summary[ic], avg);
        }
    }
}

/// One level of the min/max pyramid: `side x side` cells of `[min, max]`, row 0 = south.
#[derive(Debug, Clone, PartialEq)]
pub struct MinMaxLevel {
    /// Cells per side.
    pub side: usize,
    /// `[min, max]` per cell.
    pub cells: Vec<[f32; 2]>,
}

/// Exact min/max of the level-0 heights over each cell's footprint, for the levels of side at most
/// `MINMAX_MAX_SIDE`, finest first, down to 1x1.
pub fn minmax_pyramid(n: usize, heights: &[f32]) -> Vec<MinMaxLevel> {
    let side = n.min(MINMAX_MAX_SIDE);
    let block = n / side;
    // Per band of `block` rows: the column-wise min and max over the band (plain compares, which
    // vectorise; they ignore NaN as `f32::min` / `max` do), then per cell over its `block` columns.
    let first: Vec<[f32; 2]> = (0..side)
        .into_par_iter()
        .flat_map_iter(|jc| {
            let (mut lo, mut hi) = (vec![f32::INFINITY; n], vec![f32::NEG_INFINITY; n]);
            for j in jc * block..(jc + 1) * block {
                let row = &heights[j * n..(j + 1) * n];
                for ((l, h), &v) in lo.iter_mut().zip(hi.iter_mut()).zip(row) {
                    *l = if v < *l { v } else { *l };
                    *h = if v > *h { v } else { *h };
                }
            }
            (0..side).map(move |ic| {
                let cols = ic * block..(ic + 1) * block;
                [
                    lo[cols.clone()]
                        .iter()
                        .fold(f32::INFINITY, |m, &v| m.min(v)),
                    hi[cols].iter().fold(f32::NEG_INFINITY, |m, &v| m.max(v)),
                ]
            })
        })
        .collect();
    let mut levels = vec![MinMaxLevel { side, cells: first }];
    while let Some(last) = levels.last().filter(|l| l.side > 1) {
        let nc = last.side / 2;
        let nf = last.side;
        let cells = (0..nc * nc)
            .map(|c| {
                let (ic, jc) = (c % nc, c / nc);
                let b = 2 * jc * nf + 2 * ic;
                let mut mm = [f32::INFINITY, f32::NEG_INFINITY];
                for o in [b, b + 1, b + nf, b + nf + 1] {
                    mm[0] = mm[0].min(last.cells[o][0]);
                    mm[1] = mm[1].max(last.cells[o][1]);
                }
                mm
            })
            .collect();
        levels.push(MinMaxLevel { side: nc, cells });
    }
    levels
}

/// Bytes of a min/max pyramid (what the GPU backend reads back).
pub fn minmax_bytes(levels: &[MinMaxLevel]) -> usize {
    levels.iter().map(|l| l.cells.len() * 8).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn minmax_is_exact() {
        let n = 128;
        let h: Vec<f32> = (0..n * n)
            .map(|k| ((k * 7919) % 1000) as f32 - 300.0)
            .collect();
        let p = minmax_pyramid(n, &h);
        assert_eq!(p[0].side, 64);
        assert_eq!(p.last().map(|l| l.side), Some(1));
        let top = p.last().unwrap().cells[0];
        assert_eq!(
            top,
            [
                h.iter().cloned().fold(f32::INFINITY, f32::min),
                h.iter().cloned().fold(f32::NEG_INFINITY, f32::max)
            ]
        );
        // Every cell of every level against its footprint (cell (ic, jc) of a level of side s
        // covers texels ic * n / s .. (ic + 1) * n / s, likewise in j), at 128^2 and 256^2 (blocks
        // of 2 and 4 texels).
        for n in [128usize, 256] {
            let h: Vec<f32> = (0..n * n)
                .map(|k| ((k * 7919) % 1000) as f32 - 300.0)
                .collect();
            for level in minmax_pyramid(n, &h) {
                let (s, b) = (level.side, n / level.side);
                for (c, got) in level.cells.iter().enumerate() {
                    let (ic, jc) = (c % s, c / s);
                    let mut mm = [f32::INFINITY, f32::NEG_INFINITY];
                    for j in jc * b..(jc + 1) * b {
                        for i in ic * b..(ic + 1) * b {
                            mm[0] = mm[0].min(h[j * n + i]);
                            mm[1] = mm[1].max(h[j * n + i]);
                        }
                    }
                    assert_eq!(*got, mm, "{n}^2, side {s}, cell ({ic}, {jc})");
                }
            }
        }
    }

    #[test]
    fn summary_rows_update_equals_a_whole_rebuild() {
        let n = 128;
        let cell = |k: usize, salt: usize| -> (f32, f32) {
            let x = (k * 7919 + salt * 104_729) % 1000;
            let w = if x < 300 {
                1.0
            } else if x < 400 {
                0.5
            } else {
                0.0
            };
            (w, x as f32 * 1.37 - 200.0)
        };
        let (w0, v0): (Vec<f32>, Vec<f32>) = (0..n * n).map(|k| cell(k, 0)).unzip();
        let mut s = HardSummary::new(n, &w0, &v0);
        // New constraints on rows 37..70 only; an update of rows 35..71 must give the whole rebuild.
        let (mut w1, mut v1) = (w0.clone(), v0.clone());
        for k in 37 * n..70 * n {
            (w1[k], v1[k]) = cell(k, 1);
        }
        s.rebuild_rows(n, &w1, &v1, 35..71);
        let whole = HardSummary::new(n, &w1, &v1);
        assert_eq!(s, whole);
        assert_ne!(whole, HardSummary::new(n, &w0, &v0));
        // The same from the list of changed cells (in any order, with repeats).
        let mut changed: Vec<u32> = (0..(n * n) as u32)
            .filter(|&k| (w0[k as usize], v0[k as usize]) != (w1[k as usize], v1[k as usize]))
            .rev()
            .collect();
        changed.extend_from_slice(&changed.clone()[..10]);
        let mut by_cells = HardSummary::new(n, &w0, &v0);
        by_cells.update_cells(n, &w1, &v1, &changed);
        assert_eq!(by_cells, whole);
        let mut partial = HardSummary::new(n, &w0, &v0);
        partial.update_cells(n, &w1, &v1, &changed[changed.len() / 2..]);
        assert_ne!(partial, whole);
        // Missing the rows that changed leaves the old sums (the test above can fail).
        let mut stale = HardSummary::new(n, &w0, &v0);
        stale.rebuild_rows(n, &w1, &v1, 50..71);
        assert_ne!(stale, whole);
    }

    /// The row kernel gives every coarse cell its definition: the mean of its four fine cells,
    /// or the mean of its hard values where it has some (bit for bit, odd sides included).
    #[test]
    fn display_downsample_equals_the_cell_definition() {
        for nc in [1usize, 3, 8, 37, 64] {
            let nf = 2 * nc;
            let mut x = 12345u32;
            let mut next = move || {
                x = x.wrapping_mul(1664525).wrapping_add(1013904223);
                (x >> 8) as f32 / 65536.0 - 128.0
            };
            let fine: Vec<f32> = (0..nf * nf).map(|_| next()).collect();
            let summary: Vec<(f32, f32)> = (0..nc * nc)
                .map(|k| {
                    if k % 3 == 0 {
                        (next(), (k % 4 + 1) as f32)
                    } else {
                        (0.0, 0.0)
                    }
                })
                .collect();
            let got = display_downsample(&fine, &summary);
            for jc in 0..nc {
                for ic in 0..nc {
                    let b = 2 * jc * nf + 2 * ic;
                    let avg = 0.25 * (fine[b] + fine[b + 1] + fine[b + nf] + fine[b + nf + 1]);
                    let (sum, count) = summary[jc * nc + ic];
                    let want = if count > 0.0 { sum / count } else { avg };
                    assert_eq!(
                        got[jc * nc + ic].to_bits(),
                        want.to_bits(),
                        "{nc}: ({ic}, {jc})"
                    );
                }
            }
        }
    }

    #[test]
    fn thin_curve_survives_display_downsampling() {
        let n = 64;
        let mut w = vec![0.0f32; n * n];
        let mut v = vec![0.0f32; n * n];
        let mut h = vec![0.0f32; n * n];
        for i in 0..n {
            w[20 * n + i] = 1.0;
            v[20 * n + i] = 900.0;
            h[20 * n + i] = 900.0;
        }
        let s = HardSummary::new(n, &w, &v);
        let mut m = h.clone();
        for lvl in &s.levels {
            m = display_downsample(&m, lvl);
        }
        assert_eq!(m.len(), 1);
        assert_eq!(m[0], 900.0);
        let l1 = display_downsample(&h, &s.levels[0]);
        assert_eq!(l1[10 * 32 + 5], 900.0);
        assert_eq!(l1[11 * 32 + 5], 0.0);
    }
}
