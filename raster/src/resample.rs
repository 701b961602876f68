//! Sampling conventions of exported rasters and bilinear resampling between them.
//!
//! A side of `n` samples covers an extent `E` in one of two ways:
//! - [`Sampling::Cells`]: sample `i` is the centre of cell `i` of `n` equal cells, at
//!   `(i + 0.5) * E / n` (the solver's own grid; spacing `E / n`).
//! - [`Sampling::Corners`]: sample `i` is at `i * E / (n - 1)`, the first and last on the
//!   extent's edges (spacing `E / (n - 1)`), so neighbouring tiles share their edge samples.

use crate::{Heightmap, RasterError};

/// Where the samples of a raster sit in its extent (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Sampling {
    /// Cell centres: `n` samples at `(i + 0.5) * E / n` (the default).
    #[default]
    Cells,
    /// Cell corners: `n` samples at `i * E / (n - 1)`, edges included.
    Corners,
}

impl Sampling {
    /// The convention of an export of `n` samples per side: a power of two stays cell-centred
    /// (the solver's grid), every other size samples corners (2^k + 1 for Unity, 1009 / 2017 /
    /// 4033 / 8129 for Unreal, whose landscapes are vertex grids).
    pub fn for_size(n: usize) -> Sampling {
        if n.is_power_of_two() {
            Sampling::Cells
        } else {
            Sampling::Corners
        }
    }

    /// Name used in manifests and reports: `"cells"` or `"corners"`.
    pub fn name(self) -> &'static str {
        match self {
            Sampling::Cells => "cells",
            Sampling::Corners => "corners",
        }
    }

    /// Spacing of `n` samples over `extent_m` (`n >= 2` for corners).
    pub fn spacing_m(self, extent_m: f64, n: usize) -> f64 {
        match self {
            Sampling::Cells => extent_m / n.max(1) as f64,
            Sampling::Corners => extent_m / n.saturating_sub(1).max(1) as f64,
        }
    }
}

/// For each of `n_out` output samples, the two source samples around it and the weight of the
/// second, when `n_src` cell-centred samples are read at the `sampling` positions.
fn taps(n_src: usize, n_out: usize, sampling: Sampling) -> Vec<(usize, usize, f32)> {
    let last = n_src - 1;
    (0..n_out)
        .map(|i| {
            // Position in source cell units, from integer products so that exact cases (a
            // corner of the source grid) are exact.
            let s = match sampling {
                Sampling::Cells => ((2 * i + 1) * n_src) as f64 / (2 * n_out) as f64 - 0.5,
                Sampling::Corners => (i * n_src) as f64 / (n_out - 1).max(1) as f64 - 0.5,
            };
            // Outside the outermost centres the edge value holds (the solver's Neumann border).
            let s = s.clamp(0.0, last as f64);
            let k0 = (s.floor() as usize).min(last);
            let k1 = (k0 + 1).min(last);
            (k0, k1, (s - k0 as f64) as f32)
        })
        .collect()
}

/// Resamples `src`, a cell-centred raster over some extent, to `width x height` samples of the
/// same extent placed by `sampling`, bilinearly; near the border, where a sample lies outside
/// the outermost cell centres, the edge cells' values hold (clamp). A corner-sampled output
/// from a `2^k` source at `2^k + 1` is exactly the mean of the four cells around each interior
/// corner. The result's cell size is the new spacing.
pub fn resample_cells(
    src: &Heightmap,
    width: usize,
    height: usize,
    sampling: Sampling,
) -> Result<Heightmap, RasterError> {
    crate::checks::check_size(width as u64, height as u64)?;
    if src.width == 0 || src.height == 0 || src.data.len() != src.width * src.height {
        return Err(RasterError::BadShape {
            width: src.width,
            height: src.height,
            len: src.data.len(),
        });
    }
    if width < 2 || height < 2 {
        return Err(RasterError::encode(format!(
            "cannot resample to {width} x {height}: at least 2 x 2 samples"
        )));
    }
    let extent_m = [
        src.cell_size_m[0] * src.width as f64,
        src.cell_size_m[1] * src.height as f64,
    ];
    let xs = taps(src.width, width, sampling);
    let ys = taps(src.height, height, sampling);
    // Columns first, per source row that any output row needs; then rows.
    let mut data = Vec::with_capacity(width * height);
    let mut row0 = vec![0.0f32; width];
    let mut row1 = vec![0.0f32; width];
    let horizontal = |row: usize, out: &mut [f32]| {
        let line = &src.data[row * src.width..(row + 1) * src.width];
        for (o, &(k0, k1, t)) in out.iter_mut().zip(&xs) {
            *o = lerp(line[k0], line[k1], t);
        }
    };
    let mut loaded = (usize::MAX, usize::MAX);
    for &(j0, j1, t) in &ys {
        if loaded != (j0, j1) {
            horizontal(j0, &mut row0);
            horizontal(j1, &mut row1);
            loaded = (j0, j1);
        }
        data.extend(row0.iter().zip(&row1).map(|(&a, &b)| lerp(a, b, t)));
    }
    Ok(Heightmap {
        width,
        height,
        data,
        cell_size_m: [
            sampling.spacing_m(extent_m[0], width),
            sampling.spacing_m(extent_m[1], height),
        ],
    })
}

/// `a + t (b - a)`, exactly `a` at `t = 0` and the mean `(a + b) / 2` at `t = 0.5`.
fn lerp(a: f32, b: f32, t: f32) -> f32 {
    if t == 0.0 {
        a
    } else if t == 0.5 {
        0.5 * (a + b)
    } else {
        a + t * (b - a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cell-centred plane `h = 3 x - 2 y + 7` over a `w x h` grid of 10 m cells, north-up.
    fn plane(w: usize, h: usize) -> Heightmap {
        let mut data = Vec::new();
        for row in 0..h {
            let y = (h - 1 - row) as f64 * 10.0 + 5.0;
            for col in 0..w {
                let x = col as f64 * 10.0 + 5.0;
                data.push((3.0 * x - 2.0 * y + 7.0) as f32);
            }
        }
        Heightmap {
            width: w,
            height: h,
            data,
            cell_size_m: [10.0, 10.0],
        }
    }

    #[test]
    fn corners_of_a_power_of_two_are_means_of_four_cells() {
        let src = plane(8, 8);
        let out = resample_cells(&src, 9, 9, Sampling::Corners).unwrap();
        assert_eq!(out.cell_size_m, [10.0, 10.0]);
        for r in 1..8 {
            for c in 1..8 {
                let mean = 0.5
                    * (0.5 * (src.data[(r - 1) * 8 + c - 1] + src.data[(r - 1) * 8 + c])
                        + 0.5 * (src.data[r * 8 + c - 1] + src.data[r * 8 + c]));
                assert_eq!(out.data[r * 9 + c], mean, "({r}, {c})");
                // A plane is reproduced at its corners: x = 10 c, y = 80 - 10 r.
                let exact = 3.0 * 10.0 * c as f64 - 2.0 * (80.0 - 10.0 * r as f64) + 7.0;
                assert!((f64::from(out.data[r * 9 + c]) - exact).abs() < 1e-3);
            }
        }
        // On the border the edge cells hold: corner (0, 0) is the north-west cell.
        assert_eq!(out.data[0], src.data[0]);
        assert_eq!(out.data[9 * 9 - 1], src.data[63]);
    }

    #[test]
    fn same_size_cells_is_the_identity_and_other_sizes_follow_a_plane() {
        let src = plane(16, 12);
        assert_eq!(resample_cells(&src, 16, 12, Sampling::Cells).unwrap(), src);
        // 13 x 11 corner samples of a 160 m x 120 m extent: inside the outermost centres the
        // plane is exact.
        let out = resample_cells(&src, 13, 11, Sampling::Corners).unwrap();
        assert_eq!(out.cell_size_m, [160.0 / 12.0, 12.0]);
        for r in 1..10 {
            for c in 1..12 {
                let (x, y) = (c as f64 * 160.0 / 12.0, 120.0 - r as f64 * 12.0);
                let exact = 3.0 * x - 2.0 * y + 7.0;
                let got = f64::from(out.data[r * 13 + c]);
                assert!((got - exact).abs() < 1e-3, "({r}, {c}): {got} vs {exact}");
            }
        }
    }

    #[test]
    fn degenerate_requests_are_errors() {
        let src = plane(4, 4);
        assert!(resample_cells(&src, 1, 4, Sampling::Corners).is_err());
        assert!(resample_cells(&src, 100_000, 4, Sampling::Corners).is_err());
        let bad = Heightmap {
            data: vec![0.0; 3],
            ..src
        };
        assert!(resample_cells(&bad, 4, 4, Sampling::Cells).is_err());
    }

    #[test]
    fn sizes_pick_their_convention() {
        for n in [64, 1024, 16384] {
            assert_eq!(Sampling::for_size(n), Sampling::Cells);
        }
        for n in [65, 1009, 1025, 2017, 4033, 8129, 16385] {
            assert_eq!(Sampling::for_size(n), Sampling::Corners);
        }
    }
}
