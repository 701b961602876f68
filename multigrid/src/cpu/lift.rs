//! The FMG lift: a smooth extension `g` of the level-0 constrained values, by push-pull.
//!
//! FMG solves for `v = h - g`, which is 0 on hard cells like every coarse-grid correction, and ends
//! with `h = g + P u_1`. Without the lift (`g = 0` off the hard cells, the hard values moved to the
//! right-hand side) the function FMG must interpolate jumps by the full constrained height at every
//! hard curve and region, which the bilinear prolongation cannot represent: measured on the
//! benchmark sketch, FMG then leaves errors of 24-29% of the relief (8-30% of the cells off by more
//! than 1%) around the plateau and the curve crossings; with the lift 9-14%, concentrated at the
//! crossings (0.1% of the cells off by more than 1%), and one level-0 iteration fewer
//! (ALGORITHM.md, "FMG lift").
//!
//! Levels `k = 1 ..= L` (`n = 2^L`, level `k` has side `n >> k`, down to one cell) are stored packed
//! in one vector, level `k` at `offset(n, k)`.
//! - Level-0 weight `a_0`: 1 on hard cells; on free cells `s / (1 + s)` with
//!   `s = (diag - deg) / (2 ax + 2 ay)`, `deg` the cell's sum of edge weights (the rasterised soft
//!   weight; 0 where unconstrained).
//! - Push: `W_1` = sum of the 4 children's `a_0`, `V_1` their `a_0`-weighted mean of `E`; for `k >= 1`,
//!   with `a_k = min(1, W_k)`: `W_{k+1}` = sum of the children's `a_k`, `V_{k+1}` their `a_k`-weighted
//!   mean of `V_k`. A cell whose weight sum is 0 gets `V = 0`.
//! - Pull: `g_L = V_L`; `g_k = a_k V_k + (1 - a_k) (P g_{k+1})` for `k = L-1 .. 1`, `P` the bilinear
//!   prolongation of `ALGORITHM.md` (clamped at the border, no cell inactive);
//!   `g_0 = a_0 E + (1 - a_0) (P g_1)` (so `g_0 = E` on hard cells).

use super::Level0;
use super::par::{SharedMut, block_count, for_blocks, with_scratch};
use super::rows::{mask, prolong_row, sel};
use super::simd::multiversion;

/// Offset of level `k >= 1` in the packed storage of a lift of level-0 side `n`.
pub(crate) fn offset(n: usize, k: usize) -> usize {
    (1..k).map(|l| (n >> l) * (n >> l)).sum()
}

/// Length of the packed storage (levels 1 ..= log2 n).
pub(crate) fn packed_len(n: usize) -> usize {
    offset(n, n.trailing_zeros() as usize + 1)
}

multiversion! {
    /// Level-0 push-pull weights `a_0` of row `j` into `out` (see the module documentation). The
    /// degree is summed east, west, north, south with 0 for a missing neighbour (adding 0 is exact,
    /// so this equals the conditional sum of `Level0::assemble_cell`).
    fn weight0_row(l0: &Level0, j: usize, out: &mut [f32]) {
        let n = l0.n;
        let (ax, ay) = (l0.ax, l0.ay);
        let (yn, ys) = (if j + 1 < n { ay } else { 0.0 }, if j > 0 { ay } else { 0.0 });
        let full = 2.0 * ax + 2.0 * ay;
        let d = &l0.diag[j * n..(j + 1) * n];
        let out = &mut out[..n];
        for i in 0..n {
            let xe = sel(mask(i + 1 < n), ax, 0.0);
            let xw = sel(mask(i > 0), ax, 0.0);
            let deg = ((xe + xw) + yn) + ys;
            let s = ((d[i] - deg) / full).max(0.0);
            out[i] = sel(mask(d[i] == 0.0), 1.0, s / (1.0 + s));
        }
    }
}

multiversion! {
    /// Push of coarse row `jc` of level 1 from level-0 rows `2 jc`, `2 jc + 1` (weights `wa`, `wb`).
    fn push_row0(l0: &Level0, jc: usize, wa: &[f32], wb: &[f32], w_out: &mut [f32], v_out: &mut [f32]) {
        let n = l0.n;
        let nc = n / 2;
        let (ea, eb) = (&l0.value[2 * jc * n..][..n], &l0.value[(2 * jc + 1) * n..][..n]);
        let (wa, wb) = (&wa[..n], &wb[..n]);
        for ic in 0..nc {
            let (i0, i1) = (2 * ic, 2 * ic + 1);
            let sw = ((wa[i0] + wa[i1]) + wb[i0]) + wb[i1];
            let sv = ((wa[i0] * ea[i0] + wa[i1] * ea[i1]) + wb[i0] * eb[i0]) + wb[i1] * eb[i1];
            w_out[ic] = sw;
            v_out[ic] = sel(mask(sw > 0.0), sv / sw, 0.0);
        }
    }
}

multiversion! {
    /// Push of one coarse row from fine rows `fa`, `fb` (weights `wa`, `wb`, side `2 nc`).
    fn push_row(wa: &[f32], wb: &[f32], fa: &[f32], fb: &[f32], w_out: &mut [f32], v_out: &mut [f32]) {
        let nc = w_out.len();
        for ic in 0..nc {
            let (i0, i1) = (2 * ic, 2 * ic + 1);
            let (a0, a1, b0, b1) = (wa[i0].min(1.0), wa[i1].min(1.0), wb[i0].min(1.0), wb[i1].min(1.0));
            let sw = ((a0 + a1) + b0) + b1;
            let sv = ((a0 * fa[i0] + a1 * fa[i1]) + b0 * fb[i0]) + b1 * fb[i1];
            w_out[ic] = sw;
            v_out[ic] = sel(mask(sw > 0.0), sv / sw, 0.0);
        }
    }
}

multiversion! {
    /// `o = a V + (1 - a) e` with `a = min(1, w)` (the pull of one row; `o` holds `V` on entry).
    fn blend_row(o: &mut [f32], w: &[f32], e: &[f32]) {
        let n = o.len();
        let (w, e) = (&w[..n], &e[..n]);
        for i in 0..n {
            let a = w[i].min(1.0);
            o[i] = a * o[i] + (1.0 - a) * e[i];
        }
    }
}

/// Computes the lift of `l0`'s constraints: level 0 into `g0`, levels 1 ..= log2 n packed into
/// `lift` (grown if shorter: a longer vector keeps its length, so that FCG's vectors, lent for
/// it, are not shrunk and zero-filled again). `w` is scratch (likewise; the push weights).
pub(crate) fn push_pull(l0: &Level0, g0: &mut [f32], lift: &mut Vec<f32>, w: &mut Vec<f32>) {
    let n = l0.n;
    let levels = n.trailing_zeros() as usize;
    let len = packed_len(n);
    for v in [&mut *lift, &mut *w] {
        if v.len() < len {
            v.resize(len, 0.0);
        }
    }
    // Push level 1 from level 0.
    {
        let nc = n / 2;
        let (wp, vp) = (SharedMut(w.as_mut_ptr()), SharedMut(lift.as_mut_ptr()));
        for_blocks(nc, block_count(n, n), 1, |_, rows| {
            with_scratch(2 * n, |s| {
                let (wa, wb) = s.split_at_mut(n);
                for jc in rows {
                    weight0_row(l0, 2 * jc, wa);
                    weight0_row(l0, 2 * jc + 1, wb);
                    // SAFETY: coarse row jc (level 1 is at offset 0) belongs to this block.
                    let (wo, vo) =
                        unsafe { (wp.slice_mut(jc * nc, nc), vp.slice_mut(jc * nc, nc)) };
                    push_row0(l0, jc, wa, wb, wo, vo);
                }
            })
        });
    }
    // Push the coarser levels.
    for k in 1..levels {
        let (nf, nc) = (n >> k, n >> (k + 1));
        let (of, oc) = (offset(n, k), offset(n, k + 1));
        let (wf, wc) = w.split_at_mut(oc);
        let (vf, vc) = lift.split_at_mut(oc);
        let (wf, vf) = (&wf[of..], &vf[of..]);
        let (wp, vp) = (SharedMut(wc.as_mut_ptr()), SharedMut(vc.as_mut_ptr()));
        for_blocks(nc, block_count(nf, nf), 1, |_, rows| {
            for jc in rows {
                let (ra, rb) = (
                    2 * jc * nf..(2 * jc + 1) * nf,
                    (2 * jc + 1) * nf..(2 * jc + 2) * nf,
                );
                // SAFETY: coarse row jc belongs to this block.
                let (wo, vo) = unsafe { (wp.slice_mut(jc * nc, nc), vp.slice_mut(jc * nc, nc)) };
                push_row(&wf[ra.clone()], &wf[rb.clone()], &vf[ra], &vf[rb], wo, vo);
            }
        });
    }
    // Pull the coarse levels: level k's values become g_k.
    for k in (1..levels).rev() {
        let (nf, nc) = (n >> k, n >> (k + 1));
        let (of, oc) = (offset(n, k), offset(n, k + 1));
        let (gf, gc) = lift.split_at_mut(oc);
        let (gf, gc, wf) = (&mut gf[of..], &gc[..nc * nc], &w[of..oc]);
        let gp = SharedMut(gf.as_mut_ptr());
        for_blocks(nf, block_count(nf, nf), 1, |_, rows| {
            with_scratch(nf + nc + 2, |s| {
                let (e, v) = s.split_at_mut(nf);
                for j in rows {
                    prolong_row(gc, nc, j, v, e);
                    // SAFETY: row j belongs to this block.
                    let o = unsafe { gp.slice_mut(j * nf, nf) };
                    blend_row(o, &wf[j * nf..(j + 1) * nf], e);
                }
            })
        });
    }
    // Level 0.
    let nc = n / 2;
    let g1 = &lift[..nc * nc];
    let gp = SharedMut(g0.as_mut_ptr());
    for_blocks(n, block_count(n, n), 1, |_, rows| {
        with_scratch(2 * n + nc + 2, |s| {
            let (e, s) = s.split_at_mut(n);
            let (a, v) = s.split_at_mut(n);
            for j in rows {
                prolong_row(g1, nc, j, v, e);
                weight0_row(l0, j, a);
                // SAFETY: row j belongs to this block.
                let o = unsafe { gp.slice_mut(j * n, n) };
                o.copy_from_slice(&l0.value[j * n..(j + 1) * n]);
                // `o = a E + (1 - a) e` (a <= 1 here, so `min(1, a)` changes nothing).
                blend_row(o, a, e);
            }
        })
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problem::FieldProblem;

    /// An isotropic `n x n` problem without constraints.
    fn unconstrained(n: usize) -> FieldProblem {
        FieldProblem {
            n,
            ax: 1.0,
            ay: 1.0,
            weight: vec![0.0; n * n],
            value: vec![0.0; n * n],
            ..Default::default()
        }
    }

    /// The lift of `p`: level 0 and the packed coarse levels.
    fn lift_of(p: &FieldProblem) -> (Vec<f32>, Vec<f32>) {
        let mut l0 = Level0::new(p.n, p.ax, p.ay);
        l0.assemble_rows(p, 0..p.n, None, None);
        let (mut g, mut lift, mut w) = (vec![0.0; p.n * p.n], Vec::new(), Vec::new());
        push_pull(&l0, &mut g, &mut lift, &mut w);
        (g, lift)
    }

    #[test]
    fn packed_offsets() {
        assert_eq!(offset(8, 1), 0);
        assert_eq!(offset(8, 2), 16);
        assert_eq!(offset(8, 3), 20);
        assert_eq!(packed_len(8), 21);
    }

    #[test]
    fn hard_cells_keep_their_values_and_one_value_extends_everywhere() {
        let n = 32;
        let mut p = unconstrained(n);
        // A hard diagonal line at 7 m: the lift is 7 m everywhere.
        for i in 0..n {
            p.weight[i * n + i] = 1.0;
            p.value[i * n + i] = 7.0;
        }
        let (g, lift) = lift_of(&p);
        assert!(g.iter().all(|v| (v - 7.0).abs() < 1e-5), "{g:?}");
        assert!(lift.iter().all(|v| (v - 7.0).abs() < 1e-5));
    }

    #[test]
    fn lift_is_continuous_between_two_hard_regions() {
        // Two hard columns at 0 m (west) and 100 m (east): the lift lies between them, equals them
        // on them, and rises west to east without jumps larger than a quarter of the difference.
        let n = 64;
        let mut p = unconstrained(n);
        for j in 0..n {
            p.weight[j * n + 4] = 1.0;
            p.weight[j * n + 59] = 1.0;
            p.value[j * n + 59] = 100.0;
        }
        let (g, _) = lift_of(&p);
        for j in 0..n {
            let row = &g[j * n..(j + 1) * n];
            assert_eq!(row[4], 0.0);
            assert_eq!(row[59], 100.0);
            for (i, v) in row.iter().enumerate() {
                assert!((-1e-3..=100.001).contains(v), "g({i},{j}) = {v}");
            }
            for i in 4..59 {
                assert!(row[i + 1] - row[i] > -1e-3, "not monotone at ({i},{j})");
                assert!(row[i + 1] - row[i] < 25.0, "jump at ({i},{j})");
            }
        }
    }
}
