//! Galerkin assembly `A_k = R A_{k-1} P` of the coarse levels.
//!
//! A coarse cell is *standard* when everything its stencil depends on is the same as for an
//! unconstrained interior cell: it is not on the border (so no prolongation weight is clamped),
//! its 4 children are standard (level 1: free, no soft weight, full interior diagonal) and the 12
//! cells around them are active (level 1: the 8 outer 4-neighbours are free). Its stencil is then
//! bit-for-bit the level's standard stencil, computed once by the same code on a virtual
//! unconstrained neighbourhood, and is copied instead of recomputed.

use rayon::prelude::*;

use super::coarse::{CoarseOp, GENERAL, GenCell, INACTIVE, INACTIVE_REL, STANDARD, p_weights};
use super::level0::Level0;
use super::par::PARALLEL_MIN_CELLS;

/// Accumulates `sum_{fine j} coeff * P(j, .)` into the stencil `acc` of coarse cell `(ic, jc)`.
#[inline(always)]
fn scatter(acc: &mut [f32; 9], coeff: f32, fx: usize, fy: usize, nc: usize, ic: usize, jc: usize) {
    let wx = p_weights(fx, nc);
    let wy = p_weights(fy, nc);
    for (cy, wyv) in wy {
        if wyv == 0.0 {
            continue;
        }
        let oy = cy + 1 - jc; // in 0..=2 by construction
        for (cx, wxv) in wx {
            if wxv == 0.0 {
                continue;
            }
            let ox = cx + 1 - ic;
            acc[oy * 3 + ox] += coeff * wxv * wyv;
        }
    }
}

/// Stencil of coarse cell `(ic, jc)` (side `nc`) from a level-0 operator of side `nf` given by its
/// diagonal `diag(i, j)` (0 = hard) and edge weights.
#[inline(always)]
fn cell_from_level0(
    diag: impl Fn(usize, usize) -> f32,
    nf: usize,
    ax: f32,
    ay: f32,
    nc: usize,
    ic: usize,
    jc: usize,
) -> [f32; 9] {
    let mut acc = [0.0f32; 9];
    for cy in 0..2 {
        for cx in 0..2 {
            let (i, j) = (2 * ic + cx, 2 * jc + cy);
            let d = diag(i, j);
            if d == 0.0 {
                continue; // hard row: not part of A_ff
            }
            scatter(&mut acc, d, i, j, nc, ic, jc);
            if i > 0 && diag(i - 1, j) != 0.0 {
                scatter(&mut acc, -ax, i - 1, j, nc, ic, jc);
            }
            if i + 1 < nf && diag(i + 1, j) != 0.0 {
                scatter(&mut acc, -ax, i + 1, j, nc, ic, jc);
            }
            if j > 0 && diag(i, j - 1) != 0.0 {
                scatter(&mut acc, -ay, i, j - 1, nc, ic, jc);
            }
            if j + 1 < nf && diag(i, j + 1) != 0.0 {
                scatter(&mut acc, -ay, i, j + 1, nc, ic, jc);
            }
        }
    }
    acc
}

/// Stencil of coarse cell `(ic, jc)` (side `nc`) from a 9-point level of side `nf` given by its
/// stencils `st(i, j)` (centre 0 = inactive).
#[inline(always)]
fn cell_from_coarse<'a>(
    st: impl Fn(usize, usize) -> &'a [f32; 9],
    nf: usize,
    nc: usize,
    ic: usize,
    jc: usize,
) -> [f32; 9] {
    let mut acc = [0.0f32; 9];
    for cy in 0..2 {
        for cx in 0..2 {
            let (i, j) = (2 * ic + cx, 2 * jc + cy);
            let row = st(i, j);
            if row[4] == 0.0 {
                continue;
            }
            for oy in 0..3 {
                let y = j + oy;
                if y < 1 || y > nf {
                    continue;
                }
                let y = y - 1;
                for ox in 0..3 {
                    let c = row[oy * 3 + ox];
                    if c == 0.0 {
                        continue;
                    }
                    let x = i + ox;
                    if x < 1 || x > nf {
                        continue;
                    }
                    let x = x - 1;
                    if st(x, y)[4] == 0.0 {
                        continue; // inactive fine cell: P row is zero
                    }
                    scatter(&mut acc, c, x, y, nc, ic, jc);
                }
            }
        }
    }
    acc
}

/// The standard stencils of levels 1, 2, ... (`count` of them) for edge weights `ax`, `ay`, each
/// with a flag saying whether it is active.
pub(crate) fn standard_stencils(
    ax: f32,
    ay: f32,
    full_diag: f32,
    count: usize,
) -> Vec<([f32; 9], bool)> {
    let threshold = INACTIVE_REL * (2.0 * ax + 2.0 * ay);
    let mut out = Vec::with_capacity(count);
    // Coarse cell (1, 1) of a 4x4 level over an 8x8 virtual fine level: interior, nothing clamped.
    let mut s = cell_from_level0(|_, _| full_diag, 8, ax, ay, 4, 1, 1);
    for _ in 0..count {
        let active = s[4] > threshold && out.last().is_none_or(|l: &([f32; 9], bool)| l.1);
        out.push((s, active));
        let prev = s;
        s = cell_from_coarse(|_, _| &prev, 8, 4, 1, 1);
    }
    out
}

impl CoarseOp {
    /// Runs `build(jc, columns, stencils, kinds)` over rows `rows` (in parallel on large levels),
    /// `cols[r]` being the columns of row `rows.start + r` to rebuild, then updates the per-row lists.
    fn build_rows(
        &mut self,
        fine_cells: usize,
        rows: std::ops::Range<usize>,
        cols: &[Vec<std::ops::Range<usize>>],
        build: impl Fn(usize, std::ops::Range<usize>, &mut [[f32; 9]], &mut [u8]) + Sync,
    ) {
        let nc = self.n;
        let span = rows.start * nc..rows.end * nc;
        let kind = self.kind[span].par_chunks_mut(nc);
        let general = self.general[rows.clone()].par_iter_mut();
        let counts = self.std_count[rows.clone()].par_iter_mut();
        let work = kind.zip(general).zip(counts).enumerate();
        let min_len = if fine_cells >= PARALLEL_MIN_CELLS {
            4
        } else {
            usize::MAX
        };
        // The rebuilt cells' stencils go to a scratch row (indexed by column; only `cols[r]` is
        // written), then replace the row's list entries in those columns (the list stays in column
        // order) and the row's standard count is corrected: the rest of the row is not touched.
        work.with_min_len(min_len).for_each_init(
            Vec::new,
            |st: &mut Vec<[f32; 9]>, (r, ((kind, general), count))| {
                for c in &cols[r] {
                    let c = c.start.min(nc)..c.end.min(nc);
                    if c.is_empty() {
                        continue;
                    }
                    if st.len() < nc {
                        st.resize(nc, [0.0; 9]);
                    }
                    let standard =
                        |kind: &[u8]| kind.iter().filter(|k| **k == STANDARD).count() as u32;
                    let before = standard(&kind[c.clone()]);
                    build(rows.start + r, c.clone(), st, kind);
                    *count = *count - before + standard(&kind[c.clone()]);
                    let a = general.partition_point(|g| (g.i as usize) < c.start);
                    let b = general.partition_point(|g| (g.i as usize) < c.end);
                    let kind = &*kind;
                    general.splice(
                        a..b,
                        c.filter(|&i| kind[i] != STANDARD).map(|i| GenCell {
                            i: i as u32,
                            st: st[i],
                        }),
                    );
                }
            },
        );
        if !self.st.is_empty() {
            for j in rows {
                for i in 0..nc {
                    self.st[j * nc + i] = *self.stencil(i, j);
                }
            }
        }
    }

    /// Builds the cells `cols[r]` of rows `rows` of `R A_0 P` from level 0.
    pub fn galerkin_from_level0_rows(
        &mut self,
        fine: &Level0,
        rows: std::ops::Range<usize>,
        cols: &[Vec<std::ops::Range<usize>>],
    ) {
        let nc = self.n;
        let nf = fine.n;
        let (ax, ay) = (fine.ax, fine.ay);
        let threshold = INACTIVE_REL * (2.0 * ax + 2.0 * ay);
        let full = fine.full_diag();
        let (std_st, has_std) = (self.std_st, self.has_std);
        let d = &fine.diag[..];
        let build = |jc: usize,
                     cols: std::ops::Range<usize>,
                     st: &mut [[f32; 9]],
                     kind: &mut [u8]| {
            // Standard flags first, branch-free (vectorisable), then one pass over the cells.
            kind[cols.clone()].fill(INACTIVE);
            if has_std && jc > 0 && jc + 1 < nc {
                let (j0, j1) = (2 * jc, 2 * jc + 1);
                let (rm, r0, r1, rp) = (
                    &d[(j0 - 1) * nf..][..nf],
                    &d[j0 * nf..][..nf],
                    &d[j1 * nf..][..nf],
                    &d[(j1 + 1) * nf..][..nf],
                );
                // Reads four neighbouring rows at 2ic-1 ..= 2ic+2.
                #[allow(clippy::needless_range_loop)]
                for ic in cols.start.max(1)..cols.end.min(nc - 1) {
                    let (i0, i1) = (2 * ic, 2 * ic + 1);
                    let children =
                        (r0[i0] == full) & (r0[i1] == full) & (r1[i0] == full) & (r1[i1] == full);
                    let sides = (r0[i0 - 1] != 0.0)
                        & (r1[i0 - 1] != 0.0)
                        & (r0[i1 + 1] != 0.0)
                        & (r1[i1 + 1] != 0.0);
                    let ends =
                        (rm[i0] != 0.0) & (rm[i1] != 0.0) & (rp[i0] != 0.0) & (rp[i1] != 0.0);
                    kind[ic] = (children & sides & ends) as u8 * STANDARD;
                }
            }
            for ic in cols {
                if kind[ic] == STANDARD {
                    st[ic] = std_st;
                    continue;
                }
                let acc = cell_from_level0(|i, j| d[j * nf + i], nf, ax, ay, nc, ic, jc);
                (st[ic], kind[ic]) = if acc[4] > threshold {
                    (acc, GENERAL)
                } else {
                    ([0.0; 9], INACTIVE)
                };
            }
        };
        self.build_rows(nf * nf, rows, cols, build);
    }

    /// Builds the cells `cols[r]` of rows `rows` of `R A_f P` from the finer coarse level `fine`.
    pub fn galerkin_from_coarse_rows(
        &mut self,
        fine: &CoarseOp,
        threshold: f32,
        rows: std::ops::Range<usize>,
        cols: &[Vec<std::ops::Range<usize>>],
    ) {
        let nc = self.n;
        let nf = fine.n;
        let (std_st, has_std) = (self.std_st, self.has_std);
        let fk = &fine.kind[..];
        let build =
            |jc: usize, cols: std::ops::Range<usize>, st: &mut [[f32; 9]], kind: &mut [u8]| {
                kind[cols.clone()].fill(INACTIVE);
                if has_std && jc > 0 && jc + 1 < nc {
                    // Rows 2jc-1 ..= 2jc+2 of the fine kinds: children standard, the 12 around active.
                    let r: [&[u8]; 4] = std::array::from_fn(|y| &fk[(2 * jc - 1 + y) * nf..][..nf]);
                    // Reads four neighbouring rows at 2ic-1 ..= 2ic+2.
                    #[allow(clippy::needless_range_loop)]
                    for ic in cols.start.max(1)..cols.end.min(nc - 1) {
                        let (a, b, c, e) = (2 * ic - 1, 2 * ic, 2 * ic + 1, 2 * ic + 2);
                        let children = (r[1][b] == STANDARD)
                            & (r[1][c] == STANDARD)
                            & (r[2][b] == STANDARD)
                            & (r[2][c] == STANDARD);
                        let mut ring = (r[1][a] != INACTIVE)
                            & (r[1][e] != INACTIVE)
                            & (r[2][a] != INACTIVE)
                            & (r[2][e] != INACTIVE);
                        for y in [0, 3] {
                            ring &= (r[y][a] != INACTIVE)
                                & (r[y][b] != INACTIVE)
                                & (r[y][c] != INACTIVE)
                                & (r[y][e] != INACTIVE);
                        }
                        kind[ic] = (children & ring) as u8 * STANDARD;
                    }
                }
                for ic in cols {
                    if kind[ic] == STANDARD {
                        st[ic] = std_st;
                        continue;
                    }
                    let acc = cell_from_coarse(|i, j| fine.stencil(i, j), nf, nc, ic, jc);
                    (st[ic], kind[ic]) = if acc[4] > threshold {
                        (acc, GENERAL)
                    } else {
                        ([0.0; 9], INACTIVE)
                    };
                }
            };
        self.build_rows(nf * nf, rows, cols, build);
    }

    /// Sets this level's standard stencil.
    pub fn set_standard(&mut self, st: [f32; 9], active: bool) {
        self.std_st = st;
        self.has_std = active;
        self.std_inv = if active { 1.0 / st[4] } else { 0.0 };
        let eq = |a: usize, b: usize| st[a].to_bits() == st[b].to_bits();
        self.std_sym = eq(0, 2) && eq(0, 6) && eq(0, 8) && eq(1, 7) && eq(3, 5);
    }
}
