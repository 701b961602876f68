//! No-data filling by multi-resolution pull-push.
//!
//! Pull: build a pyramid where each coarse cell is the weighted mean of its (up to) 2x2 finer
//! cells, with weight `min(1, sum of child weights)`; valid input cells have weight 1, holes 0.
//! Push: from the 1x1 top down, each level's cells become `w * own + (1 - w) * up`, where `up` is
//! the coarser level bilinearly interpolated at the cell's centre. At level 0 valid cells keep
//! their value (w = 1) and holes take the smooth interpolated value.

/// Turns the no-data value and non-finite values into NaN.
pub(crate) fn mark_holes(heights: &mut [f32], nodata: Option<f64>) {
    let nodata = nodata.filter(|v| v.is_finite()).map(|v| v as f32);
    for h in heights {
        if !h.is_finite() || Some(*h) == nodata {
            *h = f32::NAN;
        }
    }
}

/// One pyramid level: values and weights in [0, 1].
struct Level {
    width: usize,
    height: usize,
    value: Vec<f32>,
    weight: Vec<f32>,
}

/// Replaces every non-finite value in `heights` (a `width * height` grid; callers turn no-data
/// values into NaN first) by a smooth fill. Returns the number of cells filled, or `None` if
/// every cell is a hole.
pub(crate) fn fill_holes(width: usize, height: usize, heights: &mut [f32]) -> Option<usize> {
    debug_assert_eq!(heights.len(), width * height);
    let holes = heights.iter().filter(|h| !h.is_finite()).count();
    if holes == 0 {
        return Some(0);
    }
    if holes == heights.len() {
        return None;
    }
    let weight = heights
        .iter()
        .map(|h| if h.is_finite() { 1.0 } else { 0.0 })
        .collect();
    let value = heights
        .iter()
        .map(|&h| if h.is_finite() { h } else { 0.0 })
        .collect();
    let mut levels = vec![Level {
        width,
        height,
        value,
        weight,
    }];
    while let Some(fine) = levels.last().filter(|l| l.width > 1 || l.height > 1) {
        let coarse = pull(fine);
        levels.push(coarse);
    }
    for i in (0..levels.len() - 1).rev() {
        let (fine_levels, coarse_levels) = levels.split_at_mut(i + 1);
        push(&coarse_levels[0], &mut fine_levels[i]);
    }
    for (h, &v) in heights.iter_mut().zip(&levels[0].value) {
        if !h.is_finite() {
            *h = v;
        }
    }
    Some(holes)
}

fn pull(fine: &Level) -> Level {
    let width = fine.width.div_ceil(2);
    let height = fine.height.div_ceil(2);
    let mut value = vec![0.0; width * height];
    let mut weight = vec![0.0; width * height];
    for y in 0..height {
        for x in 0..width {
            let (mut sum_wv, mut sum_w) = (0.0f64, 0.0f64);
            for fy in (2 * y)..(2 * y + 2).min(fine.height) {
                for fx in (2 * x)..(2 * x + 2).min(fine.width) {
                    let i = fy * fine.width + fx;
                    sum_wv += f64::from(fine.weight[i]) * f64::from(fine.value[i]);
                    sum_w += f64::from(fine.weight[i]);
                }
            }
            if sum_w > 0.0 {
                value[y * width + x] = (sum_wv / sum_w) as f32;
                weight[y * width + x] = sum_w.min(1.0) as f32;
            }
        }
    }
    Level {
        width,
        height,
        value,
        weight,
    }
}

fn push(coarse: &Level, fine: &mut Level) {
    for y in 0..fine.height {
        // Centre of fine cell y in coarse cell coordinates (cell centres at integer + 0.5).
        let (y0, y1, ty) = taps(y, coarse.height);
        for x in 0..fine.width {
            let (x0, x1, tx) = taps(x, coarse.width);
            let at = |cx: usize, cy: usize| coarse.value[cy * coarse.width + cx];
            let top = at(x0, y0) * (1.0 - tx) + at(x1, y0) * tx;
            let bottom = at(x0, y1) * (1.0 - tx) + at(x1, y1) * tx;
            let up = top * (1.0 - ty) + bottom * ty;
            let i = y * fine.width + x;
            let w = fine.weight[i];
            fine.value[i] = w * fine.value[i] + (1.0 - w) * up;
        }
    }
}

/// Bilinear taps on the coarse axis for fine index `i`: two indices and the blend factor.
fn taps(i: usize, coarse_len: usize) -> (usize, usize, f32) {
    let pos = ((i as f32 + 0.5) * 0.5 - 0.5).clamp(0.0, (coarse_len - 1) as f32);
    let i0 = pos.floor() as usize;
    let i1 = (i0 + 1).min(coarse_len - 1);
    (i0, i1, pos - i0 as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fills_a_hole_in_a_plane_with_plane_values() {
        let (w, h) = (33, 17);
        let plane = |x: usize, y: usize| 100.0 + 2.0 * x as f32 - 3.0 * y as f32;
        let mut grid: Vec<f32> = (0..w * h).map(|i| plane(i % w, i / w)).collect();
        for y in 6..10 {
            for x in 12..16 {
                grid[y * w + x] = f32::NAN;
            }
        }
        assert_eq!(fill_holes(w, h, &mut grid), Some(16));
        for y in 6..10 {
            for x in 12..16 {
                let got = grid[y * w + x];
                // Pull-push is smooth, not exact on a slope; it stays within the rim's range.
                assert!(
                    (got - plane(x, y)).abs() < 8.0,
                    "({x},{y}) {got} vs {}",
                    plane(x, y)
                );
            }
        }
        assert!(grid.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn all_holes_is_none_and_no_holes_is_zero() {
        let mut all = vec![f32::NAN; 12];
        assert_eq!(fill_holes(4, 3, &mut all), None);
        let mut none = vec![1.0; 12];
        assert_eq!(fill_holes(4, 3, &mut none), Some(0));
    }

    #[test]
    fn single_valid_cell_floods_the_grid() {
        let mut grid = vec![f32::NAN; 7 * 5];
        grid[3] = 42.0;
        assert_eq!(fill_holes(7, 5, &mut grid), Some(34));
        assert!(grid.iter().all(|&v| (v - 42.0).abs() < 1e-4));
    }
}
