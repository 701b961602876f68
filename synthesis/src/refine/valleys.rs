//! Breaching with a valley-like cross-section: the priority-flood breach cuts one-cell channels
//! (a straight trench in a hillshade, often to the map border); here every cell the breach
//! lowered also lowers its surroundings (never below its own floor) to a smooth, round-bottomed
//! profile whose width grows with the cut's depth, so the channel reads as a small valley.

use rayon::prelude::*;

use crate::pits::{self, PitMode};

/// Bank slope of the carved valleys, degrees: its width is the depth over `tan` of this.
pub const BANK_SLOPE_DEG: f32 = 12.0;
/// Narrowest and widest valley half-width, in cells.
pub const VALLEY_RADIUS_CELLS: [f32; 2] = [2.0, 24.0];
/// Cuts up to this deep (metres) are left as they are: they cannot make a trench, and widening
/// the many shallow cuts along a valley floor dimpled its banks at every step of the channel.
const MIN_CUT_M: f32 = 2.0;

/// Removes the depressions of an `n x n` grid with `mode`; with [`PitMode::Breach`] the channels
/// are widened into valleys ([`carve_valleys`]) and the few cells the widening leaves undrained are
/// breached again (shallow cuts). Marked `sinks` are never lowered. The depressions are not
/// counted first (one flood fewer per pass: nothing here reads the count).
pub fn remove_pits_as_valleys(
    h: &mut [f32],
    n: usize,
    sinks: Option<&[bool]>,
    mode: PitMode,
    cell_m: f64,
) {
    let before = h.to_vec();
    pits::remove_pits_uncounted(h, n, n, sinks, mode);
    if mode != PitMode::Breach {
        return;
    }
    let carved = carve_valleys(&before, h, n, cell_m);
    for (i, v) in h.iter_mut().enumerate() {
        if sinks.is_none_or(|s| !s[i]) {
            *v = v.min(carved[i]);
        }
    }
    pits::remove_pits_uncounted(h, n, n, sinks, mode);
}

/// Valleys around the cells a breach lowered: `before` and `after` the breach (`n x n`). A
/// cell lowered by `d` to the floor `f` bounds every cell within `r = d / (cell tan(bank))`
/// cells (clamped to [`VALLEY_RADIUS_CELLS`]) from above by `f + d (1 - (1 - (dist / r)^2)^2)`:
/// a round-bottomed cross-section that meets the land tangentially at the rim. Returns the
/// lowest bound per cell (`after` where no valley reaches), so no cell goes below a floor.
pub fn carve_valleys(before: &[f32], after: &[f32], n: usize, cell_m: f64) -> Vec<f32> {
    let tan = BANK_SLOPE_DEG.to_radians().tan();
    let [r_min, r_max] = VALLEY_RADIUS_CELLS;
    let cells: Vec<(usize, f32, f32, f32)> = before
        .iter()
        .zip(after)
        .enumerate()
        .filter(|&(_, (b, a))| b - a > MIN_CUT_M)
        .map(|(i, (b, a))| {
            let d = b - a;
            (i, *a, d, (d / (cell_m as f32 * tan)).clamp(r_min, r_max))
        })
        .collect();
    let mut out = after.to_vec();
    if cells.is_empty() {
        return out;
    }
    // Rows in parallel: each row takes the lowest bound of the cut cells whose disc reaches it
    // (cells are in row order, so a row scans a contiguous range).
    let r_reach = r_max.ceil() as usize;
    out.par_chunks_mut(n).enumerate().for_each(|(y, row)| {
        let lo = cells.partition_point(|c| c.0 / n + r_reach < y);
        for &(i, floor, d, r) in &cells[lo..] {
            let (cx, cy) = (i % n, i / n);
            if cy > y + r_reach {
                break;
            }
            let dy = cy.abs_diff(y) as f32;
            if dy >= r {
                continue;
            }
            let half = (r * r - dy * dy).sqrt() as usize;
            for (x, o) in row
                .iter_mut()
                .enumerate()
                .take((cx + half + 1).min(n))
                .skip(cx.saturating_sub(half))
            {
                let dx = cx.abs_diff(x) as f32;
                let t = (dx * dx + dy * dy) / (r * r);
                if t < 1.0 {
                    let bound = floor + d * (1.0 - (1.0 - t) * (1.0 - t));
                    if bound < *o {
                        *o = bound;
                    }
                }
            }
        }
    });
    out
}
