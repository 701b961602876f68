//! The inputs of the height solve that both backends share: the downsampled gradient-field and
//! roughness problems, and the edge differences taken from the diffused gradient field.

use std::ops::Range;

use rayon::prelude::*;

use crate::constraints::ConstraintMaps;
use crate::cpu::EDGE_SCRATCH_PER_N;
use crate::cpu::par::{SharedMut, with_scratch};
use crate::cpu::rows::{mask, prolong_row_cols, sel};
use crate::cpu::simd::multiversion;
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
    let [dx, dy] = grid.cell_size_m();
    let (dx, dy) = (dx as f32, dy as f32);
    let rows = rows.start.min(n)..rows.end.min(n);
    let span = rows.start * n..rows.end * n;
    d_east[span.clone()]
        .par_chunks_mut(n)
        .zip(d_north[span].par_chunks_mut(n))
        .enumerate()
        .for_each(|(r, (de, dn))| {
            with_scratch(EDGE_SCRATCH_PER_N * n + 2, |s| {
                edge_row(
                    [&maps.band_weight, &maps.elev_weight],
                    (gx, gy),
                    [dx, dy],
                    rows.start + r,
                    (0, n),
                    de,
                    dn,
                    s,
                )
            });
        });
}

/// Columns `cols` of row `j` of `edge_differences` into `d_east_row` / `d_north_row` (`n` each, the
/// other columns left as they were), with `scratch` of `EDGE_SCRATCH_PER_N * n + 2` floats: the
/// form `Hierarchy::assemble_rows_with` takes. `band_weight` and `elev_weight` are the level-0
/// maps of `ConstraintMaps`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn edge_differences_row(
    grid: &Grid,
    [band_weight, elev_weight]: [&[f32]; 2],
    (gx, gy): (&[f32], &[f32]),
    j: usize,
    cols: (usize, usize),
    d_east_row: &mut [f32],
    d_north_row: &mut [f32],
    scratch: &mut [f32],
) {
    let [dx, dy] = grid.cell_size_m();
    edge_row(
        [band_weight, elev_weight],
        (gx, gy),
        [dx as f32, dy as f32],
        j,
        cols,
        d_east_row,
        d_north_row,
        scratch,
    );
}

multiversion! {
    /// Columns `a..b` of row `j` of `edge_differences` (`cols = (a, b)`; the rest of `de` and `dn`
    /// is left as it was): the field rows are the bilinear prolongation (`prolong_row_cols`, the
    /// weights of `cpu::coarse::p_weights`) of `gx` at row `j` and of `gy` at rows `j` and
    /// `j + 1`, sampled only if the columns have a band edge. Each value is the same whatever
    /// `cols`.
    #[allow(clippy::too_many_arguments)]
    fn edge_row(maps: [&[f32]; 2], g: (&[f32], &[f32]), cell: [f32; 2], j: usize, cols: (usize, usize), de: &mut [f32], dn: &mut [f32], scratch: &mut [f32]) {
        let [dx, dy] = cell;
        let n = de.len();
        let nc = n / 2;
        let (a, b) = (cols.0.min(n), cols.1.min(n));
        if a >= b {
            return;
        }
        let [band, ew] = maps;
        let (gx, gy) = g;
        let row = j * n..(j + 1) * n;
        let (b0, e0) = (&band[row.clone()], &ew[row]);
        let north = j + 1 < n;
        let (b1, e1) = if north {
            (&band[(j + 1) * n..(j + 2) * n], &ew[(j + 1) * n..(j + 2) * n])
        } else {
            (b0, e0)
        };
        // The east edges of columns a..b reach column b.
        let any_east = b0[a..(b + 1).min(n)].iter().any(|b| *b > 0.0);
        let any_north = north && (any_east || b1[a..b].iter().any(|b| *b > 0.0));
        de[a..b].fill(0.0);
        dn[a..b].fill(0.0);
        if !any_east && !any_north {
            return;
        }
        // Sampled fields: gx at row j, gy at rows j and j + 1 (3 n), scratch of the prolongation.
        {
            let s = &mut scratch[..3 * n + nc + 2];
            let (sx, s) = s.split_at_mut(n);
            let (sy, s) = s.split_at_mut(n);
            let (sy1, v) = s.split_at_mut(n);
            // The wanted difference across an edge from the field at its two ends: where exactly one
            // end is hard, the other end's value alone.
            let pick = |a: f32, b: f32, ha: f32, hb: f32| -> f32 {
                let (ha, hb) = (is_hard(ha), is_hard(hb));
                sel(mask(ha && !hb), b, sel(mask(hb && !ha), a, 0.5 * (a + b)))
            };
            if any_east {
                prolong_row_cols(gx, nc, j, v, sx, (a, (b + 1).min(n)));
                for i in a..b.min(n - 1) {
                    let beta = b0[i].max(b0[i + 1]);
                    let g = pick(sx[i], sx[i + 1], e0[i], e0[i + 1]);
                    de[i] = sel(mask(beta > 0.0), beta * dx * g, 0.0);
                }
            }
            if any_north {
                prolong_row_cols(gy, nc, j, v, sy, (a, b));
                prolong_row_cols(gy, nc, j + 1, v, sy1, (a, b));
                for i in a..b {
                    let beta = b0[i].max(b1[i]);
                    let g = pick(sy[i], sy1[i], e0[i], e1[i]);
                    dn[i] = sel(mask(beta > 0.0), beta * dy * g, 0.0);
                }
            }
        }
    }
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
    let k = weight.len() / (n * f);
    let two = values.len() > 1;
    let (w, v0) = (&mut w[..k * nc], &mut v0[..k * nc]);
    let v1: &mut [f32] = if two { &mut v1[..k * nc] } else { &mut [] };
    let out = (
        SharedMut(w.as_mut_ptr()),
        SharedMut(v0.as_mut_ptr()),
        SharedMut(v1.as_mut_ptr()),
    );
    (0..k).into_par_iter().with_min_len(4).for_each(|jc| {
        with_scratch(3 * nc, |s| {
            let fine = jc * f * n..(jc + 1) * f * n;
            let b: &[f32] = if two { &values[1][fine.clone()] } else { &[] };
            downsample_row(n, f, &weight[fine.clone()], &values[0][fine], b, s);
            let (sw, s) = s.split_at(nc);
            let (s0, s1) = s.split_at(nc);
            // SAFETY: output row jc is written by this task only.
            unsafe {
                out.0.slice_mut(jc * nc, nc).copy_from_slice(sw);
                out.1.slice_mut(jc * nc, nc).copy_from_slice(s0);
                if two {
                    out.2.slice_mut(jc * nc, nc).copy_from_slice(s1);
                }
            }
        })
    });
}

multiversion! {
    /// One output row of `downsample_weighted_into` from its `f` fine rows (`weight`, `a`, and `b`
    /// unless empty), into `out` = (weight, value a, value b), `n / f` cells each. Per output cell
    /// the fine cells are summed in row-major order (the order of the original per-cell loop).
    fn downsample_row(n: usize, f: usize, weight: &[f32], a: &[f32], b: &[f32], out: &mut [f32]) {
        match f {
            2 => downsample_block::<2>(n, weight, a, b, out),
            4 => downsample_block::<4>(n, weight, a, b, out),
            _ => downsample_block_any(n, f, weight, a, b, out),
        }
    }
}

/// `downsample_row` for a block side `F` known at compile time: one pass over the output cells, each
/// summing its `F x F` block row by row (the same order as `downsample_block_any`, so the same
/// values), which the compiler unrolls and vectorises across output cells.
#[inline(always)]
fn downsample_block<const F: usize>(
    n: usize,
    weight: &[f32],
    a: &[f32],
    b: &[f32],
    out: &mut [f32],
) {
    let nc = n / F;
    let two = !b.is_empty();
    let (sw, s) = out[..3 * nc].split_at_mut(nc);
    let (s0, s1) = s.split_at_mut(nc);
    fn rows<const F: usize>(v: &[f32], n: usize, nc: usize) -> [&[f32]; F] {
        std::array::from_fn(|j| &v[j * n..j * n + nc * F])
    }
    let (wr, ar) = (rows::<F>(weight, n, nc), rows::<F>(a, n, nc));
    let br = if two {
        rows::<F>(b, n, nc)
    } else {
        [&[][..]; F]
    };
    for ic in 0..nc {
        let (mut tw, mut t0, mut t1) = (0.0f32, 0.0f32, 0.0f32);
        for j in 0..F {
            for di in 0..F {
                let x = ic * F + di;
                tw += wr[j][x];
                t0 += wr[j][x] * ar[j][x];
                if two {
                    t1 += wr[j][x] * br[j][x];
                }
            }
        }
        let (wv, v0, v1) = finish_cell(tw, t0, t1, F);
        sw[ic] = wv;
        s0[ic] = v0;
        if two {
            s1[ic] = v1;
        }
    }
}

/// `downsample_row` for any block side.
fn downsample_block_any(n: usize, f: usize, weight: &[f32], a: &[f32], b: &[f32], out: &mut [f32]) {
    let nc = n / f;
    let two = !b.is_empty();
    let (sw, s) = out[..3 * nc].split_at_mut(nc);
    let (s0, s1) = s.split_at_mut(nc);
    for ic in 0..nc {
        let (mut tw, mut t0, mut t1) = (0.0f32, 0.0f32, 0.0f32);
        for j in 0..f {
            for di in 0..f {
                let x = j * n + ic * f + di;
                tw += weight[x];
                t0 += weight[x] * a[x];
                if two {
                    t1 += weight[x] * b[x];
                }
            }
        }
        let (wv, v0, v1) = finish_cell(tw, t0, t1, f);
        sw[ic] = wv;
        s0[ic] = v0;
        if two {
            s1[ic] = v1;
        }
    }
}

/// One downsampled cell from its block sums (weight, weight * a, weight * b): the weight averaged and
/// exactly 1 only when every fine cell is hard, the values weight-averaged (0 without weight).
#[inline(always)]
fn finish_cell(tw: f32, t0: f32, t1: f32, f: usize) -> (f32, f32, f32) {
    let inv = 1.0 / (f * f) as f32;
    let full = (f * f) as f32;
    let wv = sel(mask(tw >= full), 1.0, (tw * inv).min(0.999));
    let pos = mask(tw > 0.0);
    (
        sel(pos, wv, 0.0),
        sel(pos, t0 / tw, 0.0),
        sel(pos, t1 / tw, 0.0),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::Hierarchy;

    /// The height problem assembled with its edge differences computed row by row inside the
    /// assembly (the solver's way) equals, bit for bit, the assembly from whole edge-difference
    /// arrays, on whole assemblies and on row ranges (block starts, the first and last rows).
    #[test]
    fn assembly_with_edge_rows_equals_assembly_from_edge_arrays() {
        let sketch = terrasketch_sketch::benchmark_sketch();
        let n = 128;
        let grid = Grid::new(n, sketch.extent_m).expect("grid");
        let maps = ConstraintMaps::rasterize(&sketch, &grid);
        let [ax, ay] = grid.axis_weights();
        // Any smooth-ish level-1 field with both signs.
        let nc = n / 2;
        let gx: Vec<f32> = (0..nc * nc)
            .map(|k| ((k % nc) as f32 * 0.37).sin() * 0.4 + ((k / nc) as f32 * 0.11).cos() * 0.2)
            .collect();
        let gy: Vec<f32> = (0..nc * nc)
            .map(|k| ((k / nc) as f32 * 0.23).cos() * 0.5 - 0.1)
            .collect();
        let (mut de, mut dn) = (vec![0.0; n * n], vec![0.0; n * n]);
        edge_differences(&grid, &maps, (&gx, &gy), 0..n, (&mut de, &mut dn));
        assert!(de.iter().any(|d| *d != 0.0) && dn.iter().any(|d| *d != 0.0));
        let with_arrays = FieldProblem {
            n,
            ax,
            ay,
            weight: maps.elev_weight.clone(),
            value: maps.elev_value.clone(),
            d_east: de,
            d_north: dn,
        };
        let bare = FieldProblem {
            d_east: Vec::new(),
            d_north: Vec::new(),
            ..with_arrays.clone()
        };
        let (band, ew) = (&maps.band_weight, &maps.elev_weight);
        let edges = |j: usize, c: (usize, usize), de: &mut [f32], dn: &mut [f32], s: &mut [f32]| {
            edge_differences_row(&grid, [band, ew], (&gx, &gy), j, c, de, dn, s)
        };
        let mut a = Hierarchy::new(n, ax, ay);
        let mut b = Hierarchy::new(n, ax, ay);
        a.assemble_rows(&with_arrays, 0..n);
        b.assemble_rows_with(&bare, 0..n, Some(&edges), None);
        assert!(a.level0_diag_rhs() == b.level0_diag_rhs());
        // Row ranges: a fresh hierarchy assembled in three parts, two of them values only.
        let mut c = Hierarchy::new(n, ax, ay);
        c.assemble_rows(&with_arrays, 0..n);
        let mut d = Hierarchy::new(n, ax, ay);
        d.assemble_rows(&with_arrays, 0..n);
        c.assemble_values_rows(&bare, 0..n);
        assert!(
            c.level0_diag_rhs() != a.level0_diag_rhs(),
            "the edge terms matter"
        );
        d.assemble_values_rows_with(&bare, 0..n, Some(&edges));
        assert!(d.level0_diag_rhs() == a.level0_diag_rhs());
        for rows in [0..1, 1..37, 37..127, 127..128] {
            c.assemble_values_rows_with(&bare, rows, Some(&edges));
        }
        assert!(c.level0_diag_rhs() == a.level0_diag_rhs());
    }

    /// The per-cell definition: weights summed over the block, weighted means, the weight averaged
    /// and exactly 1 only when every fine cell is hard.
    fn reference(n: usize, f: usize, w: &[f32], a: &[f32], b: &[f32]) -> Vec<(f32, f32, f32)> {
        let nc = n / f;
        let mut out = Vec::new();
        for jc in 0..nc {
            for ic in 0..nc {
                let (mut sw, mut s0, mut s1) = (0.0f32, 0.0f32, 0.0f32);
                for j in jc * f..(jc + 1) * f {
                    for i in ic * f..(ic + 1) * f {
                        let k = j * n + i;
                        sw += w[k];
                        s0 += w[k] * a[k];
                        s1 += w[k] * b[k];
                    }
                }
                let wv = if sw >= (f * f) as f32 {
                    1.0
                } else {
                    (sw / (f * f) as f32).min(0.999)
                };
                out.push(if sw > 0.0 {
                    (wv, s0 / sw, s1 / sw)
                } else {
                    (0.0, 0.0, 0.0)
                });
            }
        }
        out
    }

    #[test]
    fn downsampling_matches_the_per_cell_definition_bit_for_bit() {
        let n = 64;
        // Deterministic pseudo-random weights (some exactly 0 and 1) and values.
        let mut x = 12345u32;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            (x % 1000) as f32 / 999.0
        };
        let w: Vec<f32> = (0..n * n)
            .map(|_| match next() {
                v if v < 0.3 => 0.0,
                v if v > 0.7 => 1.0,
                v => v,
            })
            .collect();
        let a: Vec<f32> = (0..n * n).map(|_| 100.0 * next() - 50.0).collect();
        let b: Vec<f32> = (0..n * n).map(|_| next()).collect();
        // 2 and 4 (the gradient field and roughness) have their own unrolled paths; 8 takes the
        // general one.
        for f in [2, 4, 8] {
            let (dw, da, db) = downsample_weighted(n, f, &w, &[&a, &b]);
            let (ew, ea, _) = downsample_weighted(n, f, &w, &[&a]);
            for (k, r) in reference(n, f, &w, &a, &b).into_iter().enumerate() {
                assert_eq!((dw[k], da[k], db[k]), r, "f = {f}, cell {k}");
                assert_eq!((ew[k], ea[k]), (r.0, r.1), "one value, f = {f}, cell {k}");
            }
        }
    }
}
