//! A traced stroke's roughness measured from the DEM: the value under which the live detail's
//! calibrated law, at the DEM's own low-pass slope, gives the land around the stroke its high-pass
//! residual (`terrasketch_detail::calibration`: the same Gaussian low-pass and law the law was
//! fitted with).

use rayon::prelude::*;
use terrasketch_detail::calibration::{
    HIGH_PASS_SIGMA_M, RMS_FLAT_M, RMS_PER_SLOPE_M, ROUGHNESS_REFERENCE, SLOPE_TAN_MAX,
    gaussian_blur,
};

use crate::trace::TraceGrid;

/// Per cell, the squared high-pass residual and the squared law RMS at the low-pass slope.
pub(crate) struct RoughnessMaps {
    res2: Vec<f32>,
    law2: Vec<f32>,
}

impl RoughnessMaps {
    pub(crate) fn new(grid: &TraceGrid<'_>) -> RoughnessMaps {
        let (w, ht) = (grid.width, grid.height);
        let [cx, cy] = grid.cell_size_m;
        let sigma = [HIGH_PASS_SIGMA_M / cx, HIGH_PASS_SIGMA_M / cy];
        let low = gaussian_blur(grid.heights, w, ht, sigma);
        let mut res2 = vec![0.0f32; w * ht];
        let mut law2 = vec![0.0f32; w * ht];
        res2.par_chunks_mut(w)
            .zip(law2.par_chunks_mut(w))
            .enumerate()
            .for_each(|(y, (res_row, law_row))| {
                let (ym, yp) = (y.saturating_sub(1), (y + 1).min(ht - 1));
                for x in 0..w {
                    let i = y * w + x;
                    let (xm, xp) = (x.saturating_sub(1), (x + 1).min(w - 1));
                    let dx = ((xp - xm).max(1) as f64 * cx) as f32;
                    let dy = ((yp - ym).max(1) as f64 * cy) as f32;
                    let gx = (low[y * w + xp] - low[y * w + xm]) / dx;
                    let gy = (low[yp * w + x] - low[ym * w + x]) / dy;
                    let tan = (gx * gx + gy * gy).sqrt().min(SLOPE_TAN_MAX);
                    let law = RMS_FLAT_M + RMS_PER_SLOPE_M * tan;
                    let r = grid.heights[i] - low[i];
                    res_row[x] = r * r;
                    law_row[x] = law * law;
                }
            });
        RoughnessMaps { res2, law2 }
    }

    /// The roughness (0..=1) of the land within `width_m` of `path` (sketch metres): the reference
    /// roughness times the residual RMS over the law's RMS, both over the squares of `width_m`
    /// around the path's cells (one every quarter of the square's side).
    pub(crate) fn stroke(&self, grid: &TraceGrid<'_>, path: &[[f64; 3]], width_m: f64) -> f64 {
        let (w, ht) = (grid.width as isize, grid.height as isize);
        let [cx, cy] = grid.cell_size_m;
        let (rx, ry) = (
            (width_m / cx).ceil() as isize,
            (width_m / cy).ceil() as isize,
        );
        let (mut res, mut law) = (0.0f64, 0.0f64);
        // Windows a quarter of their width apart: they overlap anyway, and the cost stays linear
        // in the width.
        let stride = (rx.min(ry) / 2).max(1) as usize;
        for p in path.iter().step_by(stride) {
            let col = (p[0] / cx - 0.5).round() as isize;
            let row = (grid.height as f64 - p[1] / cy - 0.5).round() as isize;
            for y in (row - ry).max(0)..=(row + ry).min(ht - 1) {
                for x in (col - rx).max(0)..=(col + rx).min(w - 1) {
                    let i = (y * w + x) as usize;
                    res += f64::from(self.res2[i]);
                    law += f64::from(self.law2[i]);
                }
            }
        }
        if law <= 0.0 {
            return f64::from(ROUGHNESS_REFERENCE);
        }
        (f64::from(ROUGHNESS_REFERENCE) * (res / law).sqrt()).clamp(0.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A plane of slope 0.2 (25 m cells) with a checkerboard of `amp` metres on it.
    fn plane(amp: f32) -> Vec<f32> {
        let n = 64;
        (0..n * n)
            .map(|i| {
                let (x, y) = (i % n, i / n);
                let sign = if (x + y) % 2 == 0 { 1.0 } else { -1.0 };
                0.2 * 25.0 * x as f32 + sign * amp
            })
            .collect()
    }

    fn measured(amp: f32) -> f64 {
        let h = plane(amp);
        let grid = TraceGrid {
            heights: &h,
            width: 64,
            height: 64,
            cell_size_m: [25.0, 25.0],
        };
        let maps = RoughnessMaps::new(&grid);
        let path: Vec<[f64; 3]> = (20..44)
            .map(|y| [800.0, y as f64 * 25.0 + 12.5, 0.0])
            .collect();
        maps.stroke(&grid, &path, 100.0)
    }

    #[test]
    fn roughness_is_the_residual_over_the_law_at_the_land_slope() {
        // The law at slope 0.2: 1.75 + 63 * 0.2 = 14.35 m of residual for the reference roughness.
        let law = RMS_FLAT_M + RMS_PER_SLOPE_M * 0.2;
        let r = measured(law);
        assert!(
            (r - 0.5).abs() < 0.03,
            "roughness {r} for the law's own residual"
        );
        let half = measured(law / 2.0);
        assert!(
            (half - 0.25).abs() < 0.02,
            "roughness {half} for half of it"
        );
        assert!(measured(0.0) < 0.01, "a smooth plane is smooth");
        assert_eq!(measured(10.0 * law), 1.0, "clamped at 1");
    }
}
