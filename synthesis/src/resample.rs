//! Resampling a [`Dem`] to a square cell size.
//!
//! Separable: columns first, then rows. Along an axis whose cells grow (downsampling) each output
//! cell is the area-weighted mean of the input cells it covers, so the mean height is kept and no
//! aliasing is introduced; along an axis whose cells shrink (or stay) the output samples a
//! Catmull-Rom bicubic interpolant at its cell centre. The output grid is centred on the input's
//! extent; its cell size is exactly the requested one.

use rayon::prelude::*;

use crate::{Dem, DemError, MAX_CELLS, MAX_SIDE};

/// One output sample along an axis: input indices and their weights (summing to 1).
type Taps = Vec<(usize, f32)>;

/// Resamples `dem` to square cells of `cell_size_m` metres. The result covers the same extent
/// (rounded to whole cells, centred), keeps the name, source and fill count, and is refused with
/// [`DemError::TooLarge`] when it would exceed [`MAX_SIDE`] or [`MAX_CELLS`].
pub fn resample_to_cell_size(dem: &Dem, cell_size_m: f64) -> Result<Dem, DemError> {
    if !(cell_size_m.is_finite() && cell_size_m > 0.0) {
        return Err(DemError::InvalidCellSize {
            cell_size_m: [cell_size_m; 2],
        });
    }
    // Input cells per output cell, along x and y.
    let ratio = [
        cell_size_m / dem.cell_size_m[0],
        cell_size_m / dem.cell_size_m[1],
    ];
    let out_len = |n: usize, r: f64| (n as f64 / r).round().max(1.0);
    let (width, height) = (out_len(dem.width, ratio[0]), out_len(dem.height, ratio[1]));
    if width > MAX_SIDE as f64 || height > MAX_SIDE as f64 || width * height > MAX_CELLS as f64 {
        return Err(DemError::TooLarge {
            width: width as usize,
            height: height as usize,
            read_as: None,
        });
    }
    let (width, height) = (width as usize, height as usize);

    let taps_x = axis_taps(dem.width, width, ratio[0]);
    let taps_y = axis_taps(dem.height, height, ratio[1]);
    // Pass 1: resample each input row along x -> dem.height rows of `width`.
    let mut rows_x = vec![0.0f32; width * dem.height];
    rows_x
        .par_chunks_mut(width)
        .enumerate()
        .for_each(|(y, out)| {
            let row = &dem.heights_m[y * dem.width..(y + 1) * dem.width];
            for (o, taps) in out.iter_mut().zip(&taps_x) {
                *o = taps.iter().map(|&(i, w)| w * row[i]).sum();
            }
        });
    // Pass 2: combine rows along y.
    let mut heights_m = vec![0.0f32; width * height];
    heights_m
        .par_chunks_mut(width)
        .zip(&taps_y)
        .for_each(|(out, taps)| {
            for &(i, w) in taps {
                let row = &rows_x[i * width..(i + 1) * width];
                for (o, &v) in out.iter_mut().zip(row) {
                    *o += w * v;
                }
            }
        });
    Ok(Dem {
        width,
        height,
        heights_m,
        cell_size_m: [cell_size_m; 2],
        name: dem.name.clone(),
        source: dem.source.clone(),
        filled_nodata: dem.filled_nodata,
    })
}

/// Taps for resampling an axis of `n` input cells to `m` output cells, `ratio` input cells per
/// output cell, output centred on the input.
fn axis_taps(n: usize, m: usize, ratio: f64) -> Vec<Taps> {
    let offset = (n as f64 - m as f64 * ratio) / 2.0;
    (0..m)
        .map(|j| {
            let start = offset + j as f64 * ratio;
            if ratio > 1.0 {
                area_taps(n, start, start + ratio)
            } else {
                cubic_taps(n, start + ratio / 2.0 - 0.5)
            }
        })
        .collect()
}

/// Area-weighted mean of input cells overlapping `[start, end)` (clipped to the grid).
fn area_taps(n: usize, start: f64, end: f64) -> Taps {
    let (start, end) = (start.max(0.0), end.min(n as f64));
    if end <= start {
        // Entirely outside (only possible for a rounded-up edge cell): take the nearest cell.
        let i = if start >= n as f64 { n - 1 } else { 0 };
        return vec![(i, 1.0)];
    }
    let first = start.floor() as usize;
    let last = (end.ceil() as usize).min(n);
    let taps: Vec<(usize, f64)> = (first..last)
        .map(|i| (i, (end.min(i as f64 + 1.0) - start.max(i as f64)).max(0.0)))
        .filter(|&(_, w)| w > 0.0)
        .collect();
    let total: f64 = taps.iter().map(|&(_, w)| w).sum();
    taps.into_iter()
        .map(|(i, w)| (i, (w / total) as f32))
        .collect()
}

/// Catmull-Rom taps at input coordinate `x` (cell centres at integers), edges clamped.
fn cubic_taps(n: usize, x: f64) -> Taps {
    let base = x.floor();
    let t = x - base;
    let (t2, t3) = (t * t, t * t * t);
    let weights = [
        (-t3 + 2.0 * t2 - t) / 2.0,
        (3.0 * t3 - 5.0 * t2 + 2.0) / 2.0,
        (-3.0 * t3 + 4.0 * t2 + t) / 2.0,
        (t3 - t2) / 2.0,
    ];
    let mut taps: Taps = Vec::with_capacity(4);
    for (k, w) in weights.into_iter().enumerate() {
        let i = (base as i64 + k as i64 - 1).clamp(0, n as i64 - 1) as usize;
        match taps.iter_mut().find(|(j, _)| *j == i) {
            Some(tap) => tap.1 += w as f32,
            None => taps.push((i, w as f32)),
        }
    }
    taps.retain(|&(_, w)| w != 0.0);
    taps
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sum(taps: &Taps) -> f32 {
        taps.iter().map(|&(_, w)| w).sum()
    }

    #[test]
    fn taps_are_normalised_and_in_range() {
        for (n, m, r) in [
            (10, 5, 2.0),
            (10, 4, 2.5),
            (7, 21, 1.0 / 3.0),
            (5, 5, 1.0),
            (3, 1, 3.2),
        ] {
            for taps in axis_taps(n, m, r) {
                assert!((sum(&taps) - 1.0).abs() < 1e-5, "{n} {m} {r}: {taps:?}");
                assert!(taps.iter().all(|&(i, _)| i < n));
            }
        }
    }

    #[test]
    fn same_cell_size_is_identity() {
        for (j, taps) in axis_taps(6, 6, 1.0).iter().enumerate() {
            assert_eq!(taps, &vec![(j, 1.0)]);
        }
    }

    #[test]
    fn cubic_reproduces_a_line() {
        let line: Vec<f32> = (0..20).map(|i| 3.0 * i as f32 + 1.0).collect();
        for (j, taps) in axis_taps(20, 60, 1.0 / 3.0)
            .iter()
            .enumerate()
            .skip(6)
            .take(40)
        {
            let x = (j as f64 + 0.5) / 3.0 - 0.5;
            let got: f32 = taps.iter().map(|&(i, w)| w * line[i]).sum();
            assert!(
                (f64::from(got) - (3.0 * x + 1.0)).abs() < 1e-3,
                "{j}: {got}"
            );
        }
    }
}
