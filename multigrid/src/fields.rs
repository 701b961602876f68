//! The inputs of the height solve that both backends share: the downsampled gradient-field and
//! roughness problems, and the edge differences taken from the diffused gradient field.

use std::ops::Range;

use rayon::prelude::*;

use crate::constraints::ConstraintMaps;
use crate::cpu::p_weights;
use crate::grid::Grid;
use crate::problem::{FieldProblem, is_hard};

/// The gradient-field problem on level 1 (values = `gx`) and the `gy` values for the same operator.
pub fn gradient_problem(grid: &Grid, maps: &ConstraintMaps) -> (FieldProblem, Vec<f32>) {
    let n = grid.n;
    let [ax, ay] = grid.axis_weights();
    let (w, vx, vy) = downsample_weighted(n, 2, &maps.band_weight, &[&maps.grad_x, &maps.grad_y]);
    (
        FieldProblem {
            n: n / 2,
            ax,
            ay,
            weight: w,
            value: vx,
            ..Default::default()
        },
        vy,
    )
}

/// The roughness problem on level 2.
pub fn roughness_problem(grid: &Grid, maps: &ConstraintMaps) -> FieldProblem {
    let n = grid.n;
    let [ax, ay] = grid.axis_weights();
    let (w, v, _) = downsample_weighted(n, 4, &maps.rough_weight, &[&maps.rough_value]);
    FieldProblem {
        n: n / 4,
        ax,
        ay,
        weight: w,
        value: v,
        ..Default::default()
    }
}

/// Fills `d_east` / `d_north` on level-0 rows `rows` from the level-1 gradient field `(gx, gy)`
/// (ALGORITHM.md, "Three fields").
pub fn edge_differences(
    grid: &Grid,
    maps: &ConstraintMaps,
    (gx, gy): (&[f32], &[f32]),
    rows: Range<usize>,
    (d_east, d_north): (&mut [f32], &mut [f32]),
) {
    let n = grid.n;
    let nc = n / 2;
    let [dx, dy] = grid.cell_size_m();
    let (dx, dy) = (dx as f32, dy as f32);
    let band = &maps.band_weight;
    let ew = &maps.elev_weight;
    // Bilinear weights per column (the same for every row) and the sample at one cell.
    let wxs: Vec<[(usize, f32); 2]> = (0..n).map(|i| p_weights(i, nc)).collect();
    let sample = |g: &[f32], wx: [(usize, f32); 2], wy: [(usize, f32); 2]| -> f32 {
        let mut s = 0.0;
        for (cy, a) in wy {
            for (cx, b) in wx {
                s += a * b * g[cy * nc + cx];
            }
        }
        s
    };
    // Row `j` of a field sampled at every level-0 cell centre.
    let sample_row = |g: &[f32], j: usize, out: &mut Vec<f32>| {
        let wy = p_weights(j, nc);
        out.clear();
        out.extend(wxs.iter().map(|&wx| sample(g, wx, wy)));
    };
    let span = rows.start * n..rows.end * n;
    d_east[span.clone()]
        .par_chunks_mut(n)
        .zip(d_north[span].par_chunks_mut(n))
        .enumerate()
        .for_each_init(
            || (Vec::new(), Vec::new(), Vec::new()),
            |(sx, sy, sy1), (r, (de, dn))| {
                let j = rows.start + r;
                let (mut have_x, mut have_y) = (false, false);
                for i in 0..n {
                    let idx = j * n + i;
                    de[i] = 0.0;
                    dn[i] = 0.0;
                    if i + 1 < n {
                        let beta = band[idx].max(band[idx + 1]);
                        if beta > 0.0 {
                            if !have_x {
                                sample_row(gx, j, sx);
                                have_x = true;
                            }
                            let (a, b) = (sx[i], sx[i + 1]);
                            let g = match (is_hard(ew[idx]), is_hard(ew[idx + 1])) {
                                (true, false) => b,
                                (false, true) => a,
                                _ => 0.5 * (a + b),
                            };
                            de[i] = beta * dx * g;
                        }
                    }
                    if j + 1 < n {
                        let beta = band[idx].max(band[idx + n]);
                        if beta > 0.0 {
                            if !have_y {
                                sample_row(gy, j, sy);
                                sample_row(gy, j + 1, sy1);
                                have_y = true;
                            }
                            let (a, b) = (sy[i], sy1[i]);
                            let g = match (is_hard(ew[idx]), is_hard(ew[idx + n])) {
                                (true, false) => b,
                                (false, true) => a,
                                _ => 0.5 * (a + b),
                            };
                            dn[i] = beta * dy * g;
                        }
                    }
                }
            },
        );
}

/// Averages `weight` over `f x f` blocks and the weighted mean of each of `values`.
/// Returns `(weight, value0, value1)` (value1 empty if only one value array).
pub fn downsample_weighted(
    n: usize,
    f: usize,
    weight: &[f32],
    values: &[&[f32]],
) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
    let nc = n / f;
    let mut w = vec![0.0f32; nc * nc];
    let mut v0 = vec![0.0f32; nc * nc];
    let mut v1 = if values.len() > 1 {
        vec![0.0f32; nc * nc]
    } else {
        Vec::new()
    };
    downsample_weighted_into(n, f, weight, values, (&mut w, &mut v0, &mut v1));
    (w, v0, v1)
}

/// `downsample_weighted` of a band of whole blocks: `weight` and `values` hold `k * f` rows of `n`
/// cells, the outputs `(weight, value0, value1)` receive `k` rows of `n / f` cells (`value1` is
/// not touched with a single value array). Each output cell is computed as `downsample_weighted`
/// computes it, so downsampling a grid band by band gives the same values.
pub fn downsample_weighted_into(
    n: usize,
    f: usize,
    weight: &[f32],
    values: &[&[f32]],
    (w, v0, v1): (&mut [f32], &mut [f32], &mut [f32]),
) {
    let nc = n / f;
    let inv = 1.0 / (f * f) as f32;
    let two = values.len() > 1;
    let k = weight.len() / (n * f);
    let (w, v0) = (&mut w[..k * nc], &mut v0[..k * nc]);
    // Written row by row straight into the outputs (no per-cell tuples).
    let rows = w.par_chunks_mut(nc).zip(v0.par_chunks_mut(nc)).enumerate();
    let cell = |ic: usize, jc: usize| -> (f32, f32, f32) {
        let (mut sw, mut s0, mut s1) = (0.0f32, 0.0f32, 0.0f32);
        for j in jc * f..(jc + 1) * f {
            for i in ic * f..(ic + 1) * f {
                let idx = j * n + i;
                let w = weight[idx];
                sw += w;
                s0 += w * values[0][idx];
                if two {
                    s1 += w * values[1][idx];
                }
            }
        }
        let w = sw * inv;
        // Exactly 1 only when every fine cell is hard.
        let w = if sw >= (f * f) as f32 {
            1.0
        } else {
            w.min(0.999)
        };
        if sw > 0.0 {
            (w, s0 / sw, s1 / sw)
        } else {
            (0.0, 0.0, 0.0)
        }
    };
    if two {
        rows.zip(v1[..k * nc].par_chunks_mut(nc))
            .with_min_len(4)
            .for_each(|((jc, (w, v0)), v1)| {
                for ic in 0..nc {
                    (w[ic], v0[ic], v1[ic]) = cell(ic, jc);
                }
            });
    } else {
        rows.with_min_len(4).for_each(|(jc, (w, v0))| {
            for ic in 0..nc {
                (w[ic], v0[ic], _) = cell(ic, jc);
            }
        });
    }
}
