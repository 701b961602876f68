//! Local relaxation on level 0: red-black Gauss-Seidel sweeps over the cells near a few seed cells.
//!
//! Used where the error is concentrated in a few small places that global cycles reduce only at
//! their steady rate: after FMG, at the handful of spots where the coarse levels cannot represent
//! the solution (steep stroke crossings, plateau corners: the largest residuals), and on a warm
//! start, around the cells whose elevation constraint changed. A few sweeps there cost a few hundred
//! cells each (the classic local relaxation near singularities of Brandt's multigrid guide).

use rayon::prelude::*;

use super::Hierarchy;
use super::fast;
use super::level0::{Level0, neighbour_sum};
use super::par::SharedMut;
use super::rows::max_abs_row;
use crate::cycle::RADIUS;

/// The cells within `RADIUS` of any seed, as row spans `(row, first column, end column)`, sorted by
/// row then column, disjoint and not touching (adjacent spans are merged).
pub(crate) struct Windows {
    spans: Vec<(u32, u32, u32)>,
    cells: usize,
}

impl Windows {
    pub(crate) fn new(n: usize, seeds: &[u32]) -> Windows {
        let sorted;
        let seeds = if seeds.is_sorted() {
            seeds
        } else {
            sorted = {
                let mut v = seeds.to_vec();
                v.sort_unstable();
                v
            };
            &sorted
        };
        // The seeds' rows, each with its merged column windows (sorted by row, then column).
        let mut seed_rows: Vec<(u32, u32, u32)> = Vec::new();
        for &c in seeds {
            let (i, j) = (c as usize % n, (c as usize / n) as u32);
            let (a, b) = (
                i.saturating_sub(RADIUS) as u32,
                (i + RADIUS + 1).min(n) as u32,
            );
            match seed_rows.last_mut() {
                Some((lj, _, lb)) if *lj == j && a <= *lb => *lb = (*lb).max(b),
                _ => seed_rows.push((j, a, b)),
            }
        }
        // Row y holds the union of the windows of the seed rows within RADIUS of it: a sliding
        // range of `seed_rows`, merged per row.
        let mut spans: Vec<(u32, u32, u32)> = Vec::new();
        let mut row: Vec<(u32, u32)> = Vec::new();
        let (mut lo, mut hi) = (0, 0);
        let r = RADIUS as u32;
        let mut y = seed_rows.first().map_or(0, |s| s.0.saturating_sub(r));
        let end = seed_rows.last().map_or(0, |s| (s.0 + r + 1).min(n as u32));
        while y < end {
            while hi < seed_rows.len() && seed_rows[hi].0 <= y + r {
                hi += 1;
            }
            while lo < hi && seed_rows[lo].0 + r < y {
                lo += 1;
            }
            if lo == hi {
                // No seed row within reach: jump to the next one's first row.
                match seed_rows.get(hi) {
                    Some(s) => y = s.0 - r,
                    None => break,
                }
                continue;
            }
            row.clear();
            row.extend(seed_rows[lo..hi].iter().map(|s| (s.1, s.2)));
            row.sort_unstable();
            for &(a, b) in &row {
                match spans.last_mut() {
                    Some((ly, _, lb)) if *ly == y && a <= *lb => *lb = (*lb).max(b),
                    _ => spans.push((y, a, b)),
                }
            }
            y += 1;
        }
        let cells = spans.iter().map(|(_, a, b)| (b - a) as usize).sum();
        Windows { spans, cells }
    }

    /// Number of cells covered.
    pub(crate) fn cells(&self) -> usize {
        self.cells
    }

    /// The spans in at most `count` consecutive chunks of about equal cells.
    fn chunks(&self, count: usize) -> Vec<&[(u32, u32, u32)]> {
        let per = self.cells.div_ceil(count.max(1)).max(1);
        let mut out = Vec::with_capacity(count);
        let (mut first, mut acc) = (0, 0);
        for (k, &(_, a, b)) in self.spans.iter().enumerate() {
            acc += (b - a) as usize;
            if acc >= per {
                out.push(&self.spans[first..=k]);
                (first, acc) = (k + 1, 0);
            }
        }
        if first < self.spans.len() || out.is_empty() {
            out.push(&self.spans[first..]);
        }
        out
    }
}

/// Windows of fewer cells are relaxed on the calling thread.
const PARALLEL_MIN_WINDOW_CELLS: usize = 4096;

/// One Gauss-Seidel update of the free cells of `colour` (`(i + j) & 1`) in `spans`.
///
/// # Safety
/// `h` points to the level's `n x n` values; while this runs, no other thread writes a cell of
/// the other colour, nor a cell of `spans`, nor reads a cell of `colour` in `spans`.
unsafe fn relax_spans(
    l0: &Level0,
    f: &[f32],
    h: SharedMut,
    spans: &[(u32, u32, u32)],
    colour: usize,
) {
    let n = l0.n;
    let (ax, ay) = (l0.ax, l0.ay);
    for &(j, a, b) in spans {
        let (j, a, b) = (j as usize, a as usize, b as usize);
        // First column of this colour in the span.
        let start = a + ((a + j + colour) & 1);
        let row = j * n;
        if j > 0 && j + 1 < n && a > 0 && b < n {
            // Interior span: no border tests (the same arithmetic in the same order).
            let (diag, f) = (&l0.diag[row..row + n], &f[row..row + n]);
            for i in (start..b).step_by(2) {
                let k = row + i;
                let d = diag[i];
                // SAFETY: in bounds (interior); the neighbours are of the other colour.
                unsafe {
                    let s = ax * h.get(k - 1)
                        + ax * h.get(k + 1)
                        + ay * h.get(k - n)
                        + ay * h.get(k + n);
                    if d != 0.0 {
                        h.set(k, (f[i] + s) / d);
                    }
                }
            }
            continue;
        }
        for i in (start..b).step_by(2) {
            let k = row + i;
            let d = l0.diag[k];
            if d == 0.0 {
                continue;
            }
            // SAFETY: the neighbours are of the other colour, the cell is in `spans`.
            unsafe {
                let s = neighbour_sum(h, n, (ax, ay), i, j);
                h.set(k, (f[k] + s) / d);
            }
        }
    }
}

impl Hierarchy {
    /// Local relaxation of `h` around `seeds` (level-0 indices): `sweeps` sweeps (`SWEEPS`,
    /// or `FIELD_WARM_SWEEPS`) over the windows of radius `RADIUS` around them, unless they
    /// cover more than a quarter of the level (then not local: the cycles do it better). Returns
    /// work units and the cells it may have changed as row spans `(row, first column, end
    /// column)` (empty if it did not relax).
    pub(crate) fn relax_around_spans(
        &self,
        h: &mut [f32],
        seeds: &[u32],
        sweeps: usize,
    ) -> (f64, Vec<(u32, u32, u32)>) {
        let n = self.n();
        if seeds.is_empty() || seeds.len() * 4 > n * n {
            return (0.0, Vec::new());
        }
        let windows = Windows::new(n, seeds);
        if windows.cells() * 4 > n * n {
            return (0.0, Vec::new());
        }
        let wu = self.relax_windows(h, &windows, sweeps);
        (wu, windows.spans)
    }

    /// `sweeps` red-black Gauss-Seidel sweeps of `h` over the windows (hard cells are skipped).
    /// Returns work units (cells swept / level-0 cells).
    ///
    /// Each colour's cells read only cells of the other colour, so the spans of one colour pass
    /// are split into chunks of about equal cells updated in parallel: the same values, bit for
    /// bit, as a sequential sweep.
    pub(crate) fn relax_windows(&self, h: &mut [f32], windows: &Windows, sweeps: usize) -> f64 {
        self.relax_windows_of(h, &self.level0.f, windows, sweeps)
    }

    /// [`Self::relax_windows`] of `A h = f`.
    fn relax_windows_of(&self, h: &mut [f32], f: &[f32], windows: &Windows, sweeps: usize) -> f64 {
        let count = if windows.cells() >= PARALLEL_MIN_WINDOW_CELLS {
            2 * rayon::current_num_threads()
        } else {
            1
        };
        self.relax_windows_in(h, f, windows, sweeps, count)
    }

    /// FCG's stop-test relaxation in correction form (`cpu/fcg.rs`, `relax_spikes`): over the
    /// windows around `seeds` (unless they cover more than `max_cells` cells), `sweeps` sweeps of
    /// `A d = r` from `d = 0` (`d`: scratch of the level's size), then `h += d` there and
    /// `r -= A d` (with `shaders/shared/apply_p.wgsl`'s arithmetic) where it changes. Needs no
    /// right-hand side `f` (`GpuSolver`'s heights keep theirs in `p` while FCG runs). Returns the
    /// work units, `None` when it did not relax.
    pub(crate) fn relax_correction(
        &self,
        h: &mut [f32],
        r: &mut [f32],
        d: &mut [f32],
        seeds: &[u32],
        sweeps: usize,
        max_cells: usize,
    ) -> Option<f64> {
        let l0 = &self.level0;
        let n = l0.n;
        if seeds.is_empty() || seeds.len() > max_cells {
            return None;
        }
        let windows = Windows::new(n, seeds);
        if windows.cells() > max_cells {
            return None;
        }
        // `d` is 0 outside the windows: on the cells `r -= A d` changes and their neighbours.
        let near = fast::widened_row_spans(n, &windows.spans);
        let near_u32: Vec<(u32, u32, u32)> = near
            .iter()
            .map(|&(y, a, b)| (y as u32, a as u32, b as u32))
            .collect();
        for (y, a, b) in fast::widened_row_spans(n, &near_u32) {
            d[y * n + a..y * n + b].fill(0.0);
        }
        let wu = self.relax_windows_of(d, r, &windows, sweeps);
        for &(y, a, b) in &windows.spans {
            for k in y as usize * n + a as usize..y as usize * n + b as usize {
                if l0.diag[k] != 0.0 {
                    h[k] += d[k];
                }
            }
        }
        let (ax, ay) = (l0.ax, l0.ay);
        for &(y, a, b) in &near {
            for i in a..b {
                let k = y * n + i;
                let dk = l0.diag[k];
                if dk == 0.0 {
                    continue;
                }
                let mut s = 0.0;
                if i > 0 {
                    s += ax * d[k - 1];
                }
                if i + 1 < n {
                    s += ax * d[k + 1];
                }
                if y > 0 {
                    s += ay * d[k - n];
                }
                if y + 1 < n {
                    s += ay * d[k + n];
                }
                r[k] -= dk * d[k] - s;
            }
        }
        Some(wu)
    }

    /// `relax_windows` with the spans of each colour pass in `count` chunks.
    fn relax_windows_in(
        &self,
        h: &mut [f32],
        f: &[f32],
        windows: &Windows,
        sweeps: usize,
        count: usize,
    ) -> f64 {
        let l0 = &self.level0;
        let n = l0.n;
        let chunks = windows.chunks(count);
        let hp = SharedMut(h.as_mut_ptr());
        for _ in 0..sweeps {
            for colour in 0..2 {
                let pass = |spans: &[(u32, u32, u32)]| {
                    // SAFETY: a colour pass writes only cells of `colour` and reads only cells of
                    // the other colour (and the cell itself): no cell is read by one task while
                    // another writes it, and each cell is written by the one task whose span
                    // holds it (spans are disjoint).
                    unsafe { relax_spans(l0, f, hp, spans, colour) }
                };
                if chunks.len() == 1 {
                    pass(chunks[0]);
                } else {
                    chunks.par_iter().for_each(|c| pass(c));
                }
            }
        }
        (windows.cells() * sweeps) as f64 / (n * n) as f64
    }

    /// Level-0 cells whose normalised residual exceeds `threshold` (ascending), with the residual
    /// left in `r` (at least the level's cells long).
    pub(crate) fn large_residual_cells(
        &self,
        h: &[f32],
        r: &mut [f32],
        threshold: f32,
    ) -> Vec<u32> {
        let n = self.n();
        fast::initial_residual(&self.level0, h, &mut r[..n * n]);
        self.cells_above(r, threshold)
    }

    /// Level-0 cells whose normalised residual in `r` (at least the level's cells long) exceeds
    /// `threshold`, ascending.
    pub(crate) fn cells_above(&self, r: &[f32], threshold: f32) -> Vec<u32> {
        let n = self.n();
        let r = &r[..n * n];
        let limit = threshold / self.residual_scale();
        // Most rows hold no such cell: a vectorised maximum rules them out before the cell scan
        // (the same cells: both ignore NaN).
        r.par_chunks(n)
            .enumerate()
            .with_min_len(16)
            .flat_map_iter(|(j, row)| {
                let scan = (max_abs_row(row) > limit).then_some(row);
                scan.into_iter().flat_map(move |row| {
                    row.iter()
                        .enumerate()
                        .filter(move |(_, v)| v.abs() > limit)
                        .map(move |(i, _)| (j * n + i) as u32)
                })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::testutil::{Lcg, random_hierarchy, sort_and_merge};
    use crate::cycle::SWEEPS;

    /// Windows the plain way: every seed's square, merged.
    fn brute(n: usize, seeds: &[u32]) -> Vec<(u32, u32, u32)> {
        let mut raw = Vec::new();
        for &c in seeds {
            let (i, j) = (c as usize % n, c as usize / n);
            let (a, b) = (i.saturating_sub(RADIUS), (i + RADIUS + 1).min(n));
            for y in j.saturating_sub(RADIUS)..(j + RADIUS + 1).min(n) {
                raw.push((y as u32, a as u32, b as u32));
            }
        }
        sort_and_merge(raw)
    }

    #[test]
    fn windows_equal_the_merged_squares_of_the_seeds() {
        let n = 128;
        let mut seed = 11u64;
        for count in [0usize, 1, 2, 7, 40, 300, 3000] {
            let mut seeds: Vec<u32> = (0..count)
                .map(|_| {
                    seed = seed
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    // Clustered rows (gaps longer than the radius too), any column.
                    let j = ((seed >> 33) % 40) as usize * 3 % n;
                    let i = ((seed >> 13) % n as u64) as usize;
                    (j * n + i) as u32
                })
                .collect();
            // Unsorted input and edge cells.
            seeds.extend([0, (n * n - 1) as u32, (n - 1) as u32]);
            let w = Windows::new(n, &seeds);
            assert_eq!(w.spans, brute(n, &seeds), "{count} seeds");
            assert_eq!(
                w.cells,
                w.spans.iter().map(|s| (s.2 - s.1) as usize).sum::<usize>()
            );
        }
    }

    /// The stop-test relaxation's correction form is the local relaxation of `h` itself: from
    /// `d = 0` on `A d = f - A h`, `h + d` equals `h` relaxed directly (up to rounding), `r -= A d`
    /// leaves the residual of the new `h` everywhere (a few cells next to a border seed, hard
    /// cells, garbage in `d` outside the windows), and windows over the limit change nothing.
    #[test]
    fn the_correction_form_relaxes_h_and_keeps_the_residual() {
        let n = 128;
        let mut rng = Lcg(5);
        let hy = random_hierarchy(
            n,
            &[1.0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            &mut rng,
        );
        let h0: Vec<f32> = (0..n * n).map(|_| rng.below(500)).collect();
        let mut seeds: Vec<u32> = (0..12).map(|_| rng.next() % (n * n) as u32).collect();
        seeds.extend([0, (n - 1) as u32]);
        seeds.sort_unstable();
        let windows = Windows::new(n, &seeds);
        let mut direct = h0.clone();
        hy.relax_windows(&mut direct, &windows, 5);
        let mut h = h0.clone();
        let mut r = vec![0.0f32; n * n];
        fast::initial_residual(&hy.level0, &h, &mut r);
        let mut d: Vec<f32> = (0..n * n).map(|_| rng.below(1000) - 500.0).collect();
        let wu = hy.relax_correction(&mut h, &mut r, &mut d, &seeds, 5, n * n);
        assert_eq!(wu, Some((windows.cells() * 5) as f64 / (n * n) as f64));
        let scale = h0.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        let off = h
            .iter()
            .zip(&direct)
            .fold(0.0f32, |m, (a, b)| m.max((a - b).abs()));
        assert!(
            off <= 1e-4 * scale,
            "h + d is {off} off the direct relaxation"
        );
        assert!(h != h0);
        let mut fresh = vec![0.0f32; n * n];
        fast::initial_residual(&hy.level0, &h, &mut fresh);
        let rscale = fresh.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        let off = r
            .iter()
            .zip(&fresh)
            .fold(0.0f32, |m, (a, b)| m.max((a - b).abs()));
        assert!(
            off <= 1e-4 * rscale,
            "r is {off} off f - A h (max {rscale})"
        );
        // Over the limit: nothing relaxed, nothing changed.
        let (h1, r1) = (h.clone(), r.clone());
        let over = hy.relax_correction(&mut h, &mut r, &mut d, &seeds, 5, windows.cells() - 1);
        assert_eq!(over, None);
        assert!(h == h1 && r == r1);
    }

    /// The colour passes split into chunks run in parallel give the sequential sweep's values,
    /// bit for bit (a random problem with hard and soft cells, windows touching every border).
    #[test]
    fn parallel_relaxation_equals_the_sequential_one() {
        let n = 128;
        let mut rng = Lcg(7);
        let hy = random_hierarchy(
            n,
            &[1.0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            &mut rng,
        );
        let h0: Vec<f32> = (0..n * n).map(|_| rng.below(500)).collect();
        let mut seeds: Vec<u32> = (0..300).map(|_| rng.next() % (n * n) as u32).collect();
        seeds.extend([0, (n * n - 1) as u32, (n - 1) as u32, ((n - 1) * n) as u32]);
        let windows = Windows::new(n, &seeds);
        let mut one = h0.clone();
        hy.relax_windows_in(&mut one, &hy.level0.f, &windows, SWEEPS, 1);
        assert!(one != h0, "the relaxation changed nothing");
        for count in [2, 3, 8, 1000] {
            let mut many = h0.clone();
            hy.relax_windows_in(&mut many, &hy.level0.f, &windows, SWEEPS, count);
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert!(bits(&one) == bits(&many), "{count} chunks");
        }
    }

    /// The cells above the threshold are those a plain scan of the residual finds (rows ruled
    /// out by their maximum hold none), with a NaN and the borders in play.
    #[test]
    fn large_residual_cells_equal_a_plain_scan() {
        let n = 160;
        let mut rng = Lcg(9);
        let hy = random_hierarchy(n, &[1.0, 0.3, 0.0, 0.0, 0.0, 0.0], &mut rng);
        let mut h: Vec<f32> = (0..n * n).map(|_| rng.below(500) * 0.01).collect();
        for _ in 0..40 {
            let c = (rng.next() % (n * n) as u32) as usize;
            h[c] += 300.0;
        }
        h[0] += 300.0;
        h[n * n - 1] += 300.0;
        let mut r = vec![0.0f32; n * n];
        fast::initial_residual(&hy.level0, &h, &mut r);
        let scale = hy.residual_scale();
        let mut sorted: Vec<f32> = r.iter().map(|v| v.abs()).collect();
        sorted.sort_by(f32::total_cmp);
        // A threshold that some cells exceed and most do not.
        let threshold = sorted[n * n - 150] * scale;
        // A NaN in a row with a large residual and in a row without.
        h[7 * n + 3] = f32::NAN;
        let cells = hy.large_residual_cells(&h, &mut r, threshold);
        let limit = threshold / scale;
        let want: Vec<u32> = (0..n * n)
            .filter(|&k| r[k].abs() > limit)
            .map(|k| k as u32)
            .collect();
        assert!(want.len() > 50 && want.len() < 400, "{} cells", want.len());
        assert!(r.iter().any(|v| v.is_nan()));
        assert_eq!(cells, want);
    }

    /// The residual recomputed near changed spans (`fast::residual_near`, overlapping and
    /// unsorted spans, at every border) equals a whole recomputation bit for bit.
    #[test]
    fn residual_near_changed_spans_equals_a_whole_residual() {
        let n = 96;
        let mut rng = Lcg(3);
        let hy = random_hierarchy(n, &[1.0, 0.3, 0.0, 0.0], &mut rng);
        let mut h: Vec<f32> = (0..n * n).map(|_| rng.below(500)).collect();
        let mut r = vec![0.0f32; n * n];
        fast::initial_residual(&hy.level0, &h, &mut r);
        let n32 = n as u32;
        let mut spans = vec![
            (0, 0, n32),
            (n32 - 1, n32 - 5, n32),
            (40, 10, 20),
            (40, 15, 30),
        ];
        for _ in 0..200 {
            let (j, a) = (rng.next() % n32, rng.next() % n32);
            spans.push((j, a, (a + 1 + rng.next() % 9).min(n32)));
        }
        for &(j, a, b) in &spans {
            for i in a..b {
                h[(j * n32 + i) as usize] += 17.0;
            }
        }
        fast::residual_near(&hy.level0, &h, &mut r, &spans);
        let mut whole = vec![0.0f32; n * n];
        fast::initial_residual(&hy.level0, &h, &mut whole);
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert!(bits(&r) == bits(&whole));
    }

    #[test]
    fn windows_merge_into_disjoint_row_spans() {
        let n = 64;
        // Two seeds 5 columns apart on one row (their windows overlap), one in a corner.
        let w = Windows::new(n, &[20 * n as u32 + 10, 20 * n as u32 + 15, 0]);
        let side = 2 * RADIUS + 1;
        // Rows 14..=26 hold one merged span 4..22; rows 0..=6 one span 0..7.
        assert_eq!(w.cells(), side * (22 - 4) + (RADIUS + 1) * (RADIUS + 1));
        for pair in w.spans.windows(2) {
            let ((ya, _, ba), (yb, ab, _)) = (pair[0], pair[1]);
            assert!(ya < yb || ba < ab, "spans overlap or touch: {pair:?}");
        }
    }
}
