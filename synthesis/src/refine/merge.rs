//! Gradient-domain merging and the Poisson solves (through the multigrid crate's public API).

use rayon::prelude::*;
use terrasketch_multigrid::cpu::Hierarchy;
use terrasketch_multigrid::{FieldProblem, SolverParams};

use super::field::{Field, to_exemplar};
use super::synth::{ExFields, NO_OWNER, Placed};

/// Edge differences of the merged output: inside one patch its own detail differences; across
/// a seam (cells owned by different patches) the mean of both patches' differences over that
/// edge (where each covers both cells), so neither side's slope is cut off; plus the low-pass
/// target's differences. Returns `(d_east, d_north)` with row index as the solver's `j`.
pub fn assemble_gradients(
    n: usize,
    half: i32,
    owner: &[u32],
    dout: &[f32],
    placed: &[Placed],
    fields: &[ExFields],
    low: &Field,
) -> (Vec<f32>, Vec<f32>) {
    let value = |pl: &Placed, x: i32, y: i32| -> Option<f32> {
        let (u, v) = (x - pl.p[0], y - pl.p[1]);
        if u < -half || v < -half || u >= half || v >= half {
            return None;
        }
        let (a, b) = to_exemplar(pl.k, u as f32, v as f32);
        Some(fields[pl.ex].band.sample(pl.c[0] + a, pl.c[1] + b))
    };
    let diff = |pl: &Placed, p: (i32, i32), q: (i32, i32)| -> Option<f32> {
        Some(value(pl, q.0, q.1)? - value(pl, p.0, p.1)?)
    };
    let edge = |p: (i32, i32), q: (i32, i32)| -> f32 {
        let (i, j) = (
            p.1 as usize * n + p.0 as usize,
            q.1 as usize * n + q.0 as usize,
        );
        let (a, b) = (owner[i], owner[j]);
        let detail = if a == b {
            if a == NO_OWNER {
                0.0
            } else {
                dout[j] - dout[i]
            }
        } else {
            let mut s = 0.0;
            let mut c = 0.0;
            for o in [a, b] {
                if o != NO_OWNER
                    && let Some(d) = diff(&placed[o as usize], p, q)
                {
                    s += d;
                    c += 1.0;
                }
            }
            if c > 0.0 { s / c } else { 0.0 }
        };
        detail + low.v[j] - low.v[i]
    };
    let mut de = vec![0.0f32; n * n];
    let mut dn = vec![0.0f32; n * n];
    de.par_chunks_mut(n)
        .zip(dn.par_chunks_mut(n))
        .enumerate()
        .for_each(|(y, (re, rn))| {
            let y = y as i32;
            for x in 0..n as i32 {
                if x + 1 < n as i32 {
                    re[x as usize] = edge((x, y), (x + 1, y));
                }
                if y + 1 < n as i32 {
                    rn[x as usize] = edge((x, y), (x, y + 1));
                }
            }
        });
    (de, dn)
}

/// Solves the screened Poisson problem `weight`/`value`/`d_east`/`d_north` on an `n x n` grid
/// with square cells (full multigrid, then FCG to `tolerance`).
pub fn poisson(
    n: usize,
    weight: Vec<f32>,
    value: Vec<f32>,
    d_east: Vec<f32>,
    d_north: Vec<f32>,
    tolerance: f32,
) -> Vec<f32> {
    let problem = FieldProblem {
        n,
        ax: 1.0,
        ay: 1.0,
        weight,
        value,
        d_east,
        d_north,
    };
    let mut hy = Hierarchy::new(n, 1.0, 1.0);
    hy.assemble(&problem);
    let mut st = hy.new_state();
    let params = SolverParams {
        tolerance,
        max_vcycles: 80,
        ..SolverParams::default()
    };
    hy.solve(&mut st, &params);
    st.h
}
