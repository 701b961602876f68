//! Level 0 fast paths: the preconditioner's level-0 work and the FCG vector updates as fused row
//! pipelines (each pass streams its inputs once; rows beside a block are recomputed, not shared).
//!
//! Pipelines keep a few recent rows in ring buffers of padded rows (cell `i` at `i + 1`, zeros at both
//! ends and for rows outside the domain, so Neumann borders need no branches).

use super::level0::Level0;
use super::par::{Halo, SharedMut, ZEROS, block_count, for_blocks, map_blocks, with_scratch};
use super::rows::{
    ALT, dot_row, dot2_row, mask, max_abs_row, max_gt, prolong_row, recip, restrict_pair, sel,
};
use super::simd::multiversion;

/// Ring slot offset of row `j` (rows from -2 up) in a ring of 4 padded rows of width `w`.
#[inline(always)]
fn slot(j: isize, w: usize) -> usize {
    ((j + 4) & 3) as usize * w
}

/// The three padded ring rows around row `j`.
#[inline(always)]
fn ring3(ring: &[f32], j: isize, w: usize) -> (&[f32], &[f32], &[f32]) {
    (
        &ring[slot(j - 1, w)..][..w],
        &ring[slot(j, w)..][..w],
        &ring[slot(j + 1, w)..][..w],
    )
}

/// True if row `j` is inside a domain of `n` rows.
#[inline(always)]
fn inside(j: isize, n: usize) -> bool {
    j >= 0 && (j as usize) < n
}

/// Sets a padded row to zero padding and returns its `n` inner cells.
#[inline(always)]
fn inner(out: &mut [f32], n: usize) -> &mut [f32] {
    out[0] = 0.0;
    out[n + 1] = 0.0;
    &mut out[1..n + 1]
}

/// One colour of a Gauss-Seidel update of a row from its padded ring rows `(below, row, above)`:
/// cells of `colour` take `(r + neighbours) / d` (`(r, d)`: the row's residual and diagonal), the
/// others keep `row`'s value.
#[inline(always)]
fn colour_update(
    o: &mut [f32],
    (zm, z0, zp): (&[f32], &[f32], &[f32]),
    (r, d): (&[f32], &[f32]),
    colour: &[u32],
    [ax, ay]: [f32; 2],
) {
    for i in 0..o.len() {
        let nb = ax * (z0[i] + z0[i + 2]) + ay * (zm[i + 1] + zp[i + 1]);
        o[i] = sel(colour[i], (r[i] + nb) * recip(d[i]), z0[i + 1]);
    }
}

/// Writes row `A p` into `o` (0 on hard cells, `d`: the row's diagonal) from the padded ring rows
/// of `p` around it, and returns `p.Ap` over the row.
#[inline(always)]
fn apply_row(
    o: &mut [f32],
    (pm, p0, pn): (&[f32], &[f32], &[f32]),
    d: &[f32],
    [ax, ay]: [f32; 2],
) -> f64 {
    let n = o.len();
    for i in 0..n {
        let nb = ax * (p0[i] + p0[i + 2]) + ay * (pm[i + 1] + pn[i + 1]);
        o[i] = sel(mask(d[i] != 0.0), d[i] * p0[i + 1] - nb, 0.0);
    }
    dot_row(&p0[1..n + 1], o)
}

/// Padded row `j` of `t = r / d` (the red update from zero); zeros outside the domain.
#[inline(always)]
fn fill_t(l0: &Level0, r: &[f32], j: isize, out: &mut [f32]) {
    let n = l0.n;
    let o = inner(out, n);
    if inside(j, n) {
        let s = j as usize * n..(j as usize + 1) * n;
        let (r, d) = (&r[s.clone()], &l0.diag[s]);
        for i in 0..n {
            o[i] = r[i] * recip(d[i]);
        }
    } else {
        o.fill(0.0);
    }
}

/// Row `j` of `S r`, the red-black pre-sweep of `A z = r` from `z = 0`, from the `t` rows around
/// it (ring `tr`), into `o` (`n` cells): `t` on red cells, `(r + sum a t) / d` on black ones; plus
/// `e` on free cells if given (the coarse-grid correction).
#[inline(always)]
fn smooth_from_zero(
    l0: &Level0,
    r: &[f32],
    j: isize,
    tr: &[f32],
    e: Option<&[f32]>,
    o: &mut [f32],
) {
    let n = l0.n;
    let w = n + 2;
    let (ax, ay) = (l0.ax, l0.ay);
    let (tm, t0, tp) = ring3(tr, j, w);
    let s = j as usize * n..(j as usize + 1) * n;
    let (rr, dd) = (&r[s.clone()], &l0.diag[s]);
    let red = &ALT[(j & 1) as usize..][..n];
    let o = &mut o[..n];
    match e {
        None => {
            for i in 0..n {
                let nb = ax * (t0[i] + t0[i + 2]) + ay * (tm[i + 1] + tp[i + 1]);
                o[i] = sel(red[i], t0[i + 1], (rr[i] + nb) * recip(dd[i]));
            }
        }
        Some(e) => {
            let e = &e[..n];
            for i in 0..n {
                let nb = ax * (t0[i] + t0[i + 2]) + ay * (tm[i + 1] + tp[i + 1]);
                let z = sel(red[i], t0[i + 1], (rr[i] + nb) * recip(dd[i]));
                o[i] = z + sel(mask(dd[i] != 0.0), e[i], 0.0);
            }
        }
    }
}

multiversion! {
    /// The first half of `z = M r` with one pre-sweep, from `z = 0`: red sweep (`z = r / d` on red
    /// cells), black sweep, residual and its restriction into `f1` (side n/2). The smoothed `z`
    /// itself is not stored: `post_phase` recomputes it from `r` (cheaper than the memory traffic).
    ///
    /// After a red-black sweep the residual vanishes on black cells and is `sum_j a_ij z_j` on free
    /// red cells (exact arithmetic), so only that is computed: the result equals the general kernels
    /// up to round-off. Pure function of `r`: blocks need no synchronisation.
    pub(crate) fn pre_phase(l0: &Level0, r: &[f32], f1: &mut [f32]) {
        let n = l0.n;
        let nc = n / 2;
        let w = n + 2;
        let (ax, ay) = (l0.ax, l0.ay);
        let diag = &l0.diag[..];
        let fo = SharedMut(f1.as_mut_ptr());
        let fill_z = |j: isize, tr: &[f32], out: &mut [f32]| {
            let o = inner(out, n);
            if inside(j, n) {
                smooth_from_zero(l0, r, j, tr, None, o);
            } else {
                o.fill(0.0);
            }
        };
        // Residual of row j after the sweep: sum a z over neighbours on free red cells, else 0.
        let res = |j: isize, zr: &[f32], out: &mut [f32]| {
            let (zm, z0, zp) = ring3(zr, j, w);
            let dd = &diag[j as usize * n..(j as usize + 1) * n];
            let red = &ALT[(j & 1) as usize..][..n];
            for i in 0..n {
                let nb = ax * (z0[i] + z0[i + 2]) + ay * (zm[i + 1] + zp[i + 1]);
                out[i] = sel(red[i] & mask(dd[i] != 0.0), nb, 0.0);
            }
        };
        for_blocks(nc, block_count(n, n), 1, |_, crows| {
            with_scratch(8 * w + 2 * n, |s| {
                let (tr, s) = s.split_at_mut(4 * w);
                let (zr, s) = s.split_at_mut(4 * w);
                let (r0, r1) = s.split_at_mut(n);
                let j0 = 2 * crows.start as isize;
                for j in j0 - 2..j0 + 2 {
                    fill_t(l0, r, j, &mut tr[slot(j, w)..][..w]);
                }
                for j in j0 - 1..j0 + 1 {
                    fill_z(j, tr, &mut zr[slot(j, w)..][..w]);
                }
                for jc in crows {
                    let j = 2 * jc as isize;
                    for k in 1..3 {
                        fill_t(l0, r, j + k + 1, &mut tr[slot(j + k + 1, w)..][..w]);
                        fill_z(j + k, tr, &mut zr[slot(j + k, w)..][..w]);
                    }
                    res(j, zr, r0);
                    res(j + 1, zr, r1);
                    // SAFETY: coarse row jc belongs to this block only.
                    restrict_pair(r0, r1, unsafe { fo.slice_mut(jc * nc, nc) });
                }
            })
        });
    }
}

multiversion! {
    /// The second half of `z = M r` with one post-sweep: `z = S r + P u1` on free cells (`S r`, the
    /// pre-sweep result, recomputed from `r`), then a black and a red Gauss-Seidel update. Writes
    /// `z` and returns `(r.z, z.q, z.Az)` of the result (`z.q` 0 without `q`). With `aq`, also
    /// writes `A z` there (0 on hard cells) and returns `z.Az`, with the arithmetic and the row
    /// order of `direction`'s `q = A p` and `p.q` for `p = z` (the same bits), else 0: FCG's first
    /// iteration then needs no pass of its own to compute them. Pure function of `r` and `u1`:
    /// blocks need no synchronisation (a block recomputes the final rows beside it that `A z`
    /// needs).
    pub(crate) fn post_phase(
        l0: &Level0,
        z: &mut [f32],
        u1: &[f32],
        r: &[f32],
        q: Option<&[f32]>,
        aq: Option<&mut [f32]>,
    ) -> (f64, f64, f64) {
        let n = l0.n;
        let nc = n / 2;
        let w = n + 2;
        let (ax, ay) = (l0.ax, l0.ay);
        let diag = &l0.diag[..];
        let zptr = SharedMut(z.as_mut_ptr());
        let with_aq = aq.is_some();
        let aptr = aq.map(|a| SharedMut(a.as_mut_ptr()));
        // With `A z`, the pipeline runs one row further on each side (rows outside the block are
        // computed into the final ring only).
        let ext = with_aq as isize;
        let per_block = |_, rows: std::ops::Range<usize>| -> (f64, f64, f64) {
            with_scratch(16 * w + n + nc + 2, |s| {
                let (tr, s) = s.split_at_mut(4 * w);
                let (zr, s) = s.split_at_mut(4 * w);
                let (wr, s) = s.split_at_mut(4 * w);
                let (fr, s) = s.split_at_mut(4 * w);
                let (e, v) = s.split_at_mut(n);
                let (a, end) = (rows.start as isize, rows.end as isize);
                // S r + P u1 on free cells, padded.
                let mut fill_zp = |j: isize, tr: &[f32], out: &mut [f32]| {
                    let o = inner(out, n);
                    if !inside(j, n) {
                        o.fill(0.0);
                        return;
                    }
                    let ju = j as usize;
                    smooth_from_zero(l0, r, j, tr, None, o);
                    prolong_row(u1, nc, ju, v, e);
                    let dd = &diag[ju * n..(ju + 1) * n];
                    for i in 0..n {
                        o[i] = sel(mask(dd[i] != 0.0), o[i] + e[i], o[i]);
                    }
                };
                // Rows after the black update, padded.
                let fill_w = |j: isize, zr: &[f32], out: &mut [f32]| {
                    let o = inner(out, n);
                    if !inside(j, n) {
                        o.fill(0.0);
                        return;
                    }
                    let s = j as usize * n..(j as usize + 1) * n;
                    let black = &ALT[((j + 1) & 1) as usize..][..n];
                    colour_update(o, ring3(zr, j, w), (&r[s.clone()], &diag[s]), black, [ax, ay]);
                };
                let a0 = a - ext;
                fill_t(l0, r, a0 - 3, &mut tr[slot(a0 - 3, w)..][..w]);
                fill_t(l0, r, a0 - 2, &mut tr[slot(a0 - 2, w)..][..w]);
                for k in a0 - 2..a0 + 2 {
                    fill_t(l0, r, k + 1, &mut tr[slot(k + 1, w)..][..w]);
                    fill_zp(k, tr, &mut zr[slot(k, w)..][..w]);
                }
                for j in a0 - 1..a0 + 1 {
                    fill_w(j, zr, &mut wr[slot(j, w)..][..w]);
                }
                let (mut rz, mut zq, mut zaz) = (0.0f64, 0.0f64, 0.0f64);
                for j in a0..end + ext {
                    fill_t(l0, r, j + 3, &mut tr[slot(j + 3, w)..][..w]);
                    fill_zp(j + 2, tr, &mut zr[slot(j + 2, w)..][..w]);
                    fill_w(j + 1, zr, &mut wr[slot(j + 1, w)..][..w]);
                    if j < a || j >= end {
                        // Outside the block (with `A z` only): into the final ring.
                        let o = inner(&mut fr[slot(j, w)..][..w], n);
                        if inside(j, n) {
                            let s = j as usize * n..(j as usize + 1) * n;
                            let red = &ALT[(j & 1) as usize..][..n];
                            colour_update(o, ring3(wr, j, w), (&r[s.clone()], &diag[s]), red, [ax, ay]);
                        } else {
                            o.fill(0.0);
                        }
                    } else {
                        let ju = j as usize;
                        let s = ju * n..(ju + 1) * n;
                        let (rr, dd) = (&r[s.clone()], &diag[s.clone()]);
                        let red = &ALT[(j & 1) as usize..][..n];
                        // SAFETY: row j belongs to this block.
                        let fin = unsafe { zptr.slice_mut(ju * n, n) };
                        colour_update(fin, ring3(wr, j, w), (rr, dd), red, [ax, ay]);
                        match q {
                            Some(q) => {
                                let (a, b) = dot2_row(rr, fin, &q[s]);
                                rz += a;
                                zq += b;
                            }
                            None => rz += dot_row(rr, fin),
                        }
                        if with_aq {
                            inner(&mut fr[slot(j, w)..][..w], n).copy_from_slice(fin);
                        }
                    }
                    // `A z` on row j - 1, whose neighbours are final now.
                    let k = j - 1;
                    if let Some(ap) = aptr
                        && k >= a
                        && k < end
                    {
                            let ku = k as usize;
                            // SAFETY: row k belongs to this block.
                            let qo = unsafe { ap.slice_mut(ku * n, n) };
                            zaz += apply_row(qo, ring3(fr, k, w), &diag[ku * n..(ku + 1) * n], [ax, ay]);
                    }
                }
                (rz, zq, zaz)
            })
        };
        map_blocks(n, block_count(n, n), 1, per_block, (0.0, 0.0, 0.0), |x, y| {
            (x.0 + y.0, x.1 + y.1, x.2 + y.2)
        })
    }
}

multiversion! {
    /// FCG start: `r = f - A h` on free cells, 0 on hard cells. Returns `max |r|`.
    pub(crate) fn initial_residual(l0: &Level0, h: &[f32], r: &mut [f32]) -> f32 {
        let n = l0.n;
        let (ax, ay) = (l0.ax, l0.ay);
        let rp = SharedMut(r.as_mut_ptr());
        let per_block = |_, rows: std::ops::Range<usize>| {
            let mut m = 0.0f32;
            for j in rows {
                let s = if j > 0 { &h[(j - 1) * n..j * n] } else { &ZEROS[..n] };
                let t = if j + 1 < n { &h[(j + 1) * n..(j + 2) * n] } else { &ZEROS[..n] };
                let c = &h[j * n..(j + 1) * n];
                let span = j * n..(j + 1) * n;
                let (d, f) = (&l0.diag[span.clone()], &l0.f[span]);
                // SAFETY: row j belongs to this block.
                let o = unsafe { rp.slice_mut(j * n, n) };
                let nb0 = ax * c[1] + ay * (s[0] + t[0]);
                o[0] = sel(mask(d[0] != 0.0), f[0] - (d[0] * c[0] - nb0), 0.0);
                for i in 1..n - 1 {
                    let nb = ax * (c[i - 1] + c[i + 1]) + ay * (s[i] + t[i]);
                    o[i] = sel(mask(d[i] != 0.0), f[i] - (d[i] * c[i] - nb), 0.0);
                }
                let k = n - 1;
                let nbk = ax * c[k - 1] + ay * (s[k] + t[k]);
                o[k] = sel(mask(d[k] != 0.0), f[k] - (d[k] * c[k] - nbk), 0.0);
                m = m.max(max_abs_row(o));
            }
            m
        };
        map_blocks(n, block_count(n, n), 1, per_block, 0.0, f32::max)
    }
}

multiversion! {
    /// FCG direction: `p = a z + b p` for `coef = Some((a, b))`, `p = z` for `None`; then `q = A p`.
    /// Returns `p.q`.
    pub(crate) fn direction(l0: &Level0, z: &[f32], p: &mut [f32], q: &mut [f32], coef: Option<(f32, f32)>) -> f64 {
        let n = l0.n;
        let w = n + 2;
        let (ax, ay) = (l0.ax, l0.ay);
        let count = block_count(n, n);
        let halo = Halo::take(p, n, n, count, 1, 1);
        let pp = SharedMut(p.as_mut_ptr());
        let qp = SharedMut(q.as_mut_ptr());
        let per_block = |b: usize, rows: std::ops::Range<usize>| -> f64 {
            with_scratch(4 * w, |ring| {
                let (a, end) = (rows.start as isize, rows.end as isize);
                let fill = |j: isize, out: &mut [f32]| {
                    let o = inner(out, n);
                    if !inside(j, n) {
                        o.fill(0.0);
                        return;
                    }
                    let ju = j as usize;
                    let zz = &z[ju * n..(ju + 1) * n];
                    match coef {
                        None => o.copy_from_slice(zz),
                        Some((ca, cb)) => {
                            let old = if j >= a && j < end {
                                // SAFETY: rows of this block are read one row ahead of their writes.
                                unsafe { pp.slice(ju * n, n) }
                            } else {
                                halo.row(b, ju)
                            };
                            for i in 0..n {
                                o[i] = ca * zz[i] + cb * old[i];
                            }
                        }
                    }
                };
                fill(a - 1, &mut ring[slot(a - 1, w)..][..w]);
                fill(a, &mut ring[slot(a, w)..][..w]);
                let mut pq = 0.0f64;
                for j in a..end {
                    fill(j + 1, &mut ring[slot(j + 1, w)..][..w]);
                    let (pm, p0, pn) = ring3(ring, j, w);
                    let ju = j as usize;
                    let d = &l0.diag[ju * n..(ju + 1) * n];
                    // SAFETY: row j belongs to this block; its old value was consumed by `fill(j)`.
                    let (po, qo) = unsafe { (pp.slice_mut(ju * n, n), qp.slice_mut(ju * n, n)) };
                    po.copy_from_slice(&p0[1..n + 1]);
                    for i in 0..n {
                        let nb = ax * (p0[i] + p0[i + 2]) + ay * (pm[i + 1] + pn[i + 1]);
                        qo[i] = sel(mask(d[i] != 0.0), d[i] * p0[i + 1] - nb, 0.0);
                    }
                    pq += dot_row(po, qo);
                }
                pq
            })
        };
        map_blocks(n, count, 1, per_block, 0.0, |x, y| x + y)
    }
}

multiversion! {
    /// FCG update: `h += alpha p`, `r -= alpha q`. Returns `max |r|`.
    pub(crate) fn update(n: usize, h: &mut [f32], p: &[f32], r: &mut [f32], q: &[f32], alpha: f32) -> f32 {
        let hp = SharedMut(h.as_mut_ptr());
        let rp = SharedMut(r.as_mut_ptr());
        let per_block = |_, rows: std::ops::Range<usize>| {
            let span = rows.start * n..rows.end * n;
            // SAFETY: these rows belong to this block.
            let (h, r) = unsafe { (hp.slice_mut(span.start, span.len()), rp.slice_mut(span.start, span.len())) };
            let (p, q) = (&p[span.clone()], &q[span]);
            for i in 0..h.len() {
                h[i] += alpha * p[i];
            }
            let mut m = 0.0f32;
            for (rc, qc) in r.chunks_mut(n).zip(q.chunks(n)) {
                for i in 0..n {
                    rc[i] -= alpha * qc[i];
                }
                m = max_gt(m, max_abs_row(rc));
            }
            m
        };
        map_blocks(n, block_count(n, n), 1, per_block, 0.0, f32::max)
    }
}

/// Recomputes `r = f - A h` (as `initial_residual` computes it, bit for bit) at the cells within
/// one cell (4-neighbours included) of the row spans `changed` `(row, first column, end column)`:
/// where `r` is stale after `h` changed in `changed` only. Each such cell once (the spans widened
/// by one cell, merged per row), rows in parallel. Returns nothing: `max_abs` gives the new
/// maximum.
pub(crate) fn residual_near(l0: &Level0, h: &[f32], r: &mut [f32], changed: &[(u32, u32, u32)]) {
    let n = l0.n;
    let (ax, ay) = (l0.ax, l0.ay);
    let spans = widened_row_spans(n, changed);
    let rp = SharedMut(r.as_mut_ptr());
    let per_span = |&(y, a, b): &(usize, usize, usize)| {
        // The border columns one by one, the rest as `initial_residual`'s row loop.
        let cell = |i: usize| {
            let k = y * n + i;
            let s = if y > 0 { h[k - n] } else { 0.0 };
            let t = if y + 1 < n { h[k + n] } else { 0.0 };
            let nb = if i == 0 {
                ax * h[k + 1] + ay * (s + t)
            } else if i == n - 1 {
                ax * h[k - 1] + ay * (s + t)
            } else {
                ax * (h[k - 1] + h[k + 1]) + ay * (s + t)
            };
            let d = l0.diag[k];
            let v = if d != 0.0 {
                l0.f[k] - (d * h[k] - nb)
            } else {
                0.0
            };
            // SAFETY: the spans are disjoint, so each cell is written by one task; `r` is not
            // read here.
            unsafe { rp.set(k, v) };
        };
        let (ia, ib) = (a.max(1), b.min(n - 1));
        if ia >= ib {
            (a..b).for_each(cell);
            return;
        }
        if a == 0 {
            cell(0);
        }
        if b == n {
            cell(n - 1);
        }
        let row = y * n;
        let sr = if y > 0 {
            &h[row - n + ia..row - n + ib]
        } else {
            &ZEROS[..ib - ia]
        };
        let tr = if y + 1 < n {
            &h[row + n + ia..row + n + ib]
        } else {
            &ZEROS[..ib - ia]
        };
        let span = row + ia..row + ib;
        // SAFETY: as above (this span's cells only).
        let o = unsafe { rp.slice_mut(span.start, span.len()) };
        residual_cols(
            (ax, ay),
            &h[span.start - 1..span.end + 1],
            (sr, tr),
            (&l0.diag[span.clone()], &l0.f[span]),
            o,
        );
    };
    if spans.len() < 64 {
        spans.iter().for_each(per_span);
    } else {
        use rayon::prelude::*;
        spans.par_iter().with_min_len(32).for_each(per_span);
    }
}

/// The spans `changed` `(row, first column, end column)` widened by one cell on every side (rows
/// `j - 1 ..= j + 1`, columns `a - 1 .. b + 1`, clipped to the `n x n` level), per row sorted by
/// column with overlapping or touching spans merged: `(row, first column, end column)` in row
/// order. The spans are grouped by row with a counting sort (the edits of a drag give thousands
/// of spans over a few hundred rows; each row then sorts its few).
pub(crate) fn widened_row_spans(
    n: usize,
    changed: &[(u32, u32, u32)],
) -> Vec<(usize, usize, usize)> {
    let rows_of = |j: u32| (j as usize).saturating_sub(1)..(j as usize + 2).min(n);
    // Start of each row's spans in `cols`.
    let mut start = vec![0usize; n + 1];
    for &(j, _, _) in changed {
        for y in rows_of(j) {
            start[y + 1] += 1;
        }
    }
    for y in 0..n {
        start[y + 1] += start[y];
    }
    let mut next = start.clone();
    let mut cols = vec![(0usize, 0usize); start[n]];
    for &(j, a, b) in changed {
        let span = ((a as usize).saturating_sub(1), (b as usize + 1).min(n));
        for y in rows_of(j) {
            cols[next[y]] = span;
            next[y] += 1;
        }
    }
    let mut spans: Vec<(usize, usize, usize)> = Vec::with_capacity(cols.len());
    for y in 0..n {
        let row = &mut cols[start[y]..start[y + 1]];
        row.sort_unstable();
        let mut run: Option<(usize, usize)> = None;
        for &(a, b) in row.iter() {
            run = match run {
                Some((ra, rb)) if a <= rb => Some((ra, rb.max(b))),
                Some((ra, rb)) => {
                    spans.push((y, ra, rb));
                    Some((a, b))
                }
                None => Some((a, b)),
            };
        }
        if let Some((a, b)) = run {
            spans.push((y, a, b));
        }
    }
    spans
}

multiversion! {
    /// `r = f - A h` on consecutive interior cells of a row, with `initial_residual`'s
    /// arithmetic: `c` holds the row's cells from one before to one after them, `s` / `t` the
    /// rows below and above, `d` / `f` the diagonal and right-hand side, `o` the output.
    fn residual_cols(
        axy: (f32, f32),
        c: &[f32],
        st: (&[f32], &[f32]),
        df: (&[f32], &[f32]),
        o: &mut [f32],
    ) {
        let ((ax, ay), (s, t), (d, f)) = (axy, st, df);
        let m = o.len();
        let (c, s, t, d, f) = (&c[..m + 2], &s[..m], &t[..m], &d[..m], &f[..m]);
        for i in 0..m {
            let nb = ax * (c[i] + c[i + 2]) + ay * (s[i] + t[i]);
            o[i] = sel(mask(d[i] != 0.0), f[i] - (d[i] * c[i + 1] - nb), 0.0);
        }
    }
}

/// `max |r|` over a whole level (`n x n`), in parallel.
pub(crate) fn max_abs(n: usize, r: &[f32]) -> f32 {
    let per_block = |_, rows: std::ops::Range<usize>| max_abs_row(&r[rows.start * n..rows.end * n]);
    map_blocks(n, block_count(n, n), 1, per_block, 0.0, f32::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::testutil::{Lcg, random_hierarchy, sort_and_merge};

    /// The counting sort groups, orders and merges the widened spans as sorting all of them does
    /// (random spans, many per row, overlapping, touching, at the borders).
    #[test]
    fn widened_row_spans_equal_a_sort_and_merge() {
        let n = 64;
        let mut rng = Lcg(11);
        for round in 0..50 {
            let changed: Vec<(u32, u32, u32)> = (0..(round * 7 % 300))
                .map(|_| {
                    let j = rng.below(n as u32) as u32;
                    let a = rng.below(n as u32) as u32;
                    let len = rng.below(6) as u32;
                    (j, a, (a + len).min(n as u32))
                })
                .collect();
            let mut all: Vec<(usize, usize, usize)> = Vec::new();
            for &(j, a, b) in &changed {
                let (j, a, b) = (j as usize, a as usize, b as usize);
                for y in j.saturating_sub(1)..(j + 2).min(n) {
                    all.push((y, a.saturating_sub(1), (b + 1).min(n)));
                }
            }
            assert_eq!(
                widened_row_spans(n, &changed),
                sort_and_merge(all),
                "round {round}"
            );
        }
    }

    /// `post_phase` with `A z` gives the `z` it gives without, and the `q = A z` and `z.Az` that
    /// `direction` computes for `p = z`, bit for bit, on a level split into several blocks (the
    /// rows beside each block are recomputed, not read).
    #[test]
    fn post_phase_with_az_equals_the_direction_pass() {
        let n = 256;
        let mut rng = Lcg(5);
        let weights = [1.0, 0.4, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        let hy = random_hierarchy(n, &weights, &mut rng);
        let l0 = &hy.level0;
        let r: Vec<f32> = (0..n * n)
            .map(|k| {
                if l0.diag[k] == 0.0 {
                    0.0
                } else {
                    rng.below(1000) - 500.0
                }
            })
            .collect();
        let u1: Vec<f32> = (0..n * n / 4).map(|_| rng.below(1000) - 500.0).collect();
        assert!(
            block_count(n, n) > 1,
            "one block: the boundaries are not tested"
        );
        let mut z0 = vec![0.0f32; n * n];
        let (rz0, _, _) = post_phase(l0, &mut z0, &u1, &r, None, None);
        let mut z = vec![0.0f32; n * n];
        let mut aq = vec![0.0f32; n * n];
        let (rz, _, zaz) = post_phase(l0, &mut z, &u1, &r, None, Some(&mut aq));
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert!(bits(&z) == bits(&z0), "z");
        assert_eq!(rz.to_bits(), rz0.to_bits());
        let (mut pp, mut q) = (vec![0.0f32; n * n], vec![0.0f32; n * n]);
        let pq = direction(l0, &z, &mut pp, &mut q, None);
        assert!(bits(&aq) == bits(&q), "A z");
        assert_eq!(zaz.to_bits(), pq.to_bits(), "z.Az");
    }
}
