//! Gradient-domain merging and the Poisson solves (through the multigrid crate's public API).

use rayon::prelude::*;
use terrasketch_multigrid::cpu::Hierarchy;
use terrasketch_multigrid::{FieldProblem, SolverParams};

use super::field::{Field, to_exemplar};
use super::synth::{ExFields, NO_OWNER, Placed};

/// Half-width in cells of the band over which the gradients of two patches are blended across
/// a seam.
pub const BLEND_RADIUS: i32 = 8;

/// Edge differences of the merged output, `(d_east, d_north)` (row index as the solver's `j`).
///
/// Far from seams an edge takes its patch's own detail difference. Near a seam (another owner
/// within [`BLEND_RADIUS`]) the differences of every patch that owns a cell of the
/// `(2r+1)^2` window around the edge and covers both its cells are averaged, weighted by how
/// many window cells each owns: the gradient moves smoothly from one patch to the other over
/// about `2r` cells instead of jumping, so the Poisson reconstruction has no curvature spike on
/// the seam (Tasse 2011 interpolates seam gradient differences with Shepard weights for the
/// same reason). The low-pass target's differences are added everywhere.
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
        Some(pl.gain * fields[pl.ex].band.sample(pl.c[0] + a, pl.c[1] + b))
    };
    let ni = n as i32;
    let r = BLEND_RADIUS;
    let near = near_seam(n, owner, r as usize);
    // Smooth radial weights over the window (a square box of counts would blend along
    // axis-aligned ramps with kinks, which show as straight lines in a hillshade).
    let side = (2 * r + 1) as usize;
    let kernel: Vec<f32> = (0..side * side)
        .map(|i| {
            let (dx, dy) = ((i % side) as i32 - r, (i / side) as i32 - r);
            let t = (dx * dx + dy * dy) as f32 / ((r + 1) * (r + 1)) as f32;
            if t < 1.0 { (1.0 - t) * (1.0 - t) } else { 0.0 }
        })
        .collect();
    // Both edges leaving cell p (east and north in the solver's terms) share p's window.
    let cell = |p: (i32, i32)| -> [f32; 2] {
        let i = p.1 as usize * n + p.0 as usize;
        let own = owner[i];
        let qs = [(p.0 + 1, p.1), (p.0, p.1 + 1)];
        let plain = |q: (i32, i32)| -> f32 {
            if q.0 >= ni || q.1 >= ni {
                return 0.0;
            }
            let j = q.1 as usize * n + q.0 as usize;
            let d = if own == NO_OWNER || owner[j] != own {
                0.0
            } else {
                dout[j] - dout[i]
            };
            d + low.v[j] - low.v[i]
        };
        if !near[i] {
            return [plain(qs[0]), plain(qs[1])];
        }
        // Owners in the window, with counts (few distinct ones).
        let mut counts: [(u32, f32); 8] = [(NO_OWNER, 0.0); 8];
        let mut distinct = 0usize;
        let mut mixed = false;
        for y in (p.1 - r).max(0)..=(p.1 + r).min(ni - 1) {
            let row = &owner[y as usize * n..(y as usize + 1) * n];
            let x_lo = (p.0 - r).max(0);
            let wy = &kernel[(y - p.1 + r) as usize * side..];
            for (x, &o) in (x_lo..).zip(&row[x_lo as usize..=(p.0 + r).min(ni - 1) as usize]) {
                let k = wy[(x - p.0 + r) as usize];
                if k <= 0.0 {
                    continue;
                }
                mixed |= o != own;
                if o == NO_OWNER {
                    continue;
                }
                if let Some(c) = counts[..distinct].iter_mut().find(|c| c.0 == o) {
                    c.1 += k;
                } else if distinct < counts.len() {
                    counts[distinct] = (o, k);
                    distinct += 1;
                }
            }
        }
        if !mixed {
            return [plain(qs[0]), plain(qs[1])];
        }
        let here: Vec<Option<f32>> = counts[..distinct]
            .iter()
            .map(|&(o, _)| value(&placed[o as usize], p.0, p.1))
            .collect();
        qs.map(|q| {
            if q.0 >= ni || q.1 >= ni {
                return 0.0;
            }
            let j = q.1 as usize * n + q.0 as usize;
            let (mut sum, mut wsum) = (0.0f32, 0.0f32);
            for (&(o, c), a) in counts[..distinct].iter().zip(&here) {
                if let (Some(a), Some(b)) = (a, value(&placed[o as usize], q.0, q.1)) {
                    sum += c * (b - a);
                    wsum += c;
                }
            }
            if wsum > 0.0 {
                sum / wsum + low.v[j] - low.v[i]
            } else {
                plain(q)
            }
        })
    };
    let mut de = vec![0.0f32; n * n];
    let mut dn = vec![0.0f32; n * n];
    de.par_chunks_mut(n)
        .zip(dn.par_chunks_mut(n))
        .enumerate()
        .for_each(|(y, (re, rn))| {
            for x in 0..ni {
                let [e, no] = cell((x, y as i32));
                re[x as usize] = e;
                rn[x as usize] = no;
            }
        });
    (de, dn)
}

/// Cells within `r` (Chebyshev distance) of a cell that has a 4-neighbour of another owner: the
/// only cells whose blending window can hold two owners.
fn near_seam(n: usize, owner: &[u32], r: usize) -> Vec<bool> {
    let boundary: Vec<bool> = (0..n * n)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % n, i / n);
            (x + 1 < n && owner[i + 1] != owner[i]) || (y + 1 < n && owner[i + n] != owner[i])
        })
        .collect();
    // A boundary flag at i also marks its east / north neighbour, so dilate by r + 1.
    let r = r + 1;
    let mut rows = vec![false; n * n];
    rows.par_chunks_mut(n).enumerate().for_each(|(y, row)| {
        let src = &boundary[y * n..(y + 1) * n];
        for (x, o) in row.iter_mut().enumerate() {
            *o = src[x.saturating_sub(r)..(x + r + 1).min(n)]
                .iter()
                .any(|&b| b);
        }
    });
    let mut out = vec![false; n * n];
    out.par_chunks_mut(n).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            *o = (y.saturating_sub(r)..(y + r + 1).min(n)).any(|yy| rows[yy * n + x]);
        }
    });
    out
}

/// Solves the screened Poisson problem `weight`/`value`/`d_east`/`d_north` on an `n x n` grid
/// with square cells (full multigrid, then FCG to `tolerance`). The multigrid needs a
/// power-of-two side: any other `n` (a tile's region) is solved in the north-west corner of the
/// next power of two, the rest a free membrane (no tie, no edge difference), which acts as a
/// zero-flux border a little way out.
pub fn poisson(
    n: usize,
    weight: Vec<f32>,
    value: Vec<f32>,
    d_east: Vec<f32>,
    d_north: Vec<f32>,
    tolerance: f32,
) -> Vec<f32> {
    if n.is_power_of_two() {
        return poisson_pow2(n, weight, value, d_east, d_north, tolerance);
    }
    let p = n.next_power_of_two();
    let pad = |v: &[f32]| -> Vec<f32> {
        if v.is_empty() {
            return Vec::new();
        }
        let mut out = vec![0.0f32; p * p];
        for (dst, src) in out.chunks_mut(p).zip(v.chunks(n)) {
            dst[..n].copy_from_slice(src);
        }
        out
    };
    let (w, v, mut de, mut dn) = (pad(&weight), pad(&value), pad(&d_east), pad(&d_north));
    // Edges from the region into the membrane want no difference.
    if !de.is_empty() {
        for row in de.chunks_mut(p).take(n) {
            row[n - 1] = 0.0;
        }
    }
    if !dn.is_empty() {
        dn[(n - 1) * p..(n - 1) * p + n].fill(0.0);
    }
    let h = poisson_pow2(p, w, v, de, dn, tolerance);
    h.chunks(p)
        .take(n)
        .flat_map(|r| r[..n].iter().copied())
        .collect()
}

fn poisson_pow2(
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
    // Plain FCG (no stop-test relaxation), as the refinement's target solve.
    let params = SolverParams {
        tolerance,
        max_vcycles: 80,
        stop_relaxation: false,
        ..SolverParams::default()
    };
    hy.solve(&mut st, &params);
    st.h
}
