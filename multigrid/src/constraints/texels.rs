//! The per-texel arithmetic of the rasteriser: for each row, the closest segment of a stroke
//! (`nearer`, a branch-free minimum), then that stroke's weights and values composited into the
//! maps (`composite`). Both are f32 throughout, as the GPU twin `rasterize.wgsl`.

use terrasketch_sketch::StrokeKind;

use super::segments::{Prepared, Seg, candidate_ranges, reach_m};
use crate::cpu::rows::{mask, sel};
use crate::cpu::simd::multiversion;

/// One row of every map, and the per-row compositing scratch.
pub(super) struct RowOut<'a> {
    pub(super) ew: &'a mut [f32],
    pub(super) ev: &'a mut [f32],
    pub(super) bw: &'a mut [f32],
    pub(super) gx: &'a mut [f32],
    pub(super) gy: &'a mut [f32],
    pub(super) rw: &'a mut [f32],
    pub(super) rv: &'a mut [f32],
    /// Distance (m) to the stroke that set the elevation value.
    pub(super) ed: &'a mut [f32],
    /// Distance (m) to the stroke that set the band values.
    pub(super) bd: &'a mut [f32],
}

/// Per-row scratch of the rasteriser (kept per worker thread).
#[derive(Default)]
pub(crate) struct RowScratch {
    pub(super) ed: Vec<f32>,
    pub(super) bd: Vec<f32>,
    pub(super) near: NearestRow,
}

/// Per texel of the current row and stroke, what the closest segment so far says: squared distance,
/// the vector from the closest point to the texel, the height there and the signed slope of the side
/// the texel is on (f32 throughout, as the GPU twin).
#[derive(Default)]
pub(super) struct NearestRow {
    d2: Vec<f32>,
    vx: Vec<f32>,
    vy: Vec<f32>,
    z: Vec<f32>,
    slope: Vec<f32>,
    /// Candidate segments of the current row and stroke: index and texel range.
    cand: Vec<(u32, std::ops::Range<usize>)>,
}

impl NearestRow {
    pub(super) fn resize(&mut self, n: usize) {
        for v in [
            &mut self.d2,
            &mut self.vx,
            &mut self.vy,
            &mut self.z,
            &mut self.slope,
        ] {
            v.resize(n, 0.0);
        }
    }
}

/// The per-stroke constants of the per-texel arithmetic.
#[derive(Clone, Copy)]
struct StrokeConsts {
    /// Squared reach: texels at this squared distance or more are out of reach.
    reach2: f32,
    /// Larger cell side (m).
    cell: f32,
    /// Hard-core radius (plateau width, else 0).
    core: f32,
    width: f32,
    /// Ridges and valleys have a gradient band.
    banded: bool,
    roughness: f32,
    /// `1 / width` and the falloff's coefficients (`Prepared`).
    inv_width: f32,
    falloff: [f32; 3],
}

/// Composites stroke `p` into row `j`.
///
/// Candidate segments are those whose expanded box holds the row, each with a conservative texel
/// range of the points within reach. Every candidate, in segment order, lowers a per-texel minimum
/// of the squared distance (a branch-free loop); a segment replaces the current one only if
/// strictly closer. Segments out of reach never win, so the winner of each texel (the smallest
/// squared distance, the first segment on exact ties) is the one a test of all segments gives. The
/// winner's vector, height and side are kept along with its distance, so compositing needs no
/// second look at the segments (and is branch-free too).
pub(super) fn splat_row(
    p: &Prepared,
    [dx, dy]: [f64; 2],
    cell: f64,
    j: usize,
    cols: std::ops::Range<usize>,
    out: &mut RowOut<'_>,
    near: &mut NearestRow,
) {
    // `out` and `near` hold the texels `cols` of the row: local index = column - c0.
    let (c0, c1) = (cols.start, cols.end);
    let reach = reach_m(p, cell) as f32;
    let NearestRow {
        d2,
        vx,
        vy,
        z,
        slope,
        cand,
    } = near;
    cand.clear();
    let (mut i0, mut i1) = (c1 - c0, 0);
    for (k, range) in candidate_ranges(p, dx, dy, cell, j, c0..c1) {
        let (ia, ib) = (range.start.max(c0), range.end);
        if ia < ib {
            cand.push((k, ia - c0..ib - c0));
            i0 = i0.min(ia - c0);
            i1 = i1.max(ib - c0);
        }
    }
    if i0 >= i1 {
        return;
    }
    let (tl, tr) = if p.kind == StrokeKind::Ridge {
        (-p.tan_left, -p.tan_right)
    } else {
        (p.tan_left, p.tan_right)
    };
    let k = StrokeConsts {
        reach2: reach * reach,
        cell: cell as f32,
        core: if p.kind == StrokeKind::Plateau {
            p.width_m
        } else {
            0.0
        },
        width: p.width_m,
        banded: p.kind != StrokeKind::Plateau,
        roughness: p.roughness,
        inv_width: p.inv_width,
        falloff: p.falloff,
    };
    let y = (j as f32 + 0.5) * dy as f32;
    let dx = dx as f32;
    d2[i0..i1].fill(k.reach2);
    for (s, range) in cand.iter() {
        let s = &p.segs[*s as usize];
        let r = range.clone();
        nearer(
            s,
            (tl, tr),
            y,
            dx,
            c0 + r.start,
            [
                &mut d2[r.clone()],
                &mut vx[r.clone()],
                &mut vy[r.clone()],
                &mut z[r.clone()],
                &mut slope[r],
            ],
        );
    }
    let r = i0..i1;
    composite(
        &k,
        &d2[r.clone()],
        &vx[r.clone()],
        &vy[r.clone()],
        &z[r.clone()],
        &slope[r.clone()],
        &mut out.ew[r.clone()],
        &mut out.ev[r.clone()],
        &mut out.bw[r.clone()],
        &mut out.gx[r.clone()],
        &mut out.gy[r.clone()],
        &mut out.rw[r.clone()],
        &mut out.rv[r.clone()],
        &mut out.ed[r.clone()],
        &mut out.bd[r],
    );
}

multiversion! {
    /// Lowers the squared distances `near[0]` (texels from column `i0`) with segment `s`: a texel takes
    /// the segment (distance, vector, height, signed slope of its side) if strictly closer.
    fn nearer(
        s: &Seg,
        slopes: (f32, f32),
        y: f32,
        dx: f32,
        i0: usize,
        near: [&mut [f32]; 5],
    ) {
        let (slope_left, slope_right) = slopes;
        let [bd, bvx, bvy, bz, bs] = near;
        let n = bd.len();
        let (bvx, bvy, bz, bs) = (&mut bvx[..n], &mut bvy[..n], &mut bz[..n], &mut bs[..n]);
        let (ex, ey, inv) = (s.ex32, s.ey32, s.inv32);
        let py = y - s.ay;
        for o in 0..n {
            // Through i32: converts 8 lanes at once (exact below 2^24, as the column is).
            let x = ((i0 + o) as i32 as f32 + 0.5) * dx;
            let px = x - s.ax;
            let t = ((px * ex + py * ey) * inv).clamp(0.0, 1.0);
            let (vx, vy) = (px - t * ex, py - t * ey);
            let d2 = vx * vx + vy * vy;
            let take = d2 < bd[o];
            let left = ex * vy - ey * vx > 0.0;
            bd[o] = if take { d2 } else { bd[o] };
            bvx[o] = if take { vx } else { bvx[o] };
            bvy[o] = if take { vy } else { bvy[o] };
            bz[o] = if take { s.az + t * s.dz } else { bz[o] };
            let sl = if left { slope_left } else { slope_right };
            bs[o] = if take { sl } else { bs[o] };
        }
    }
}

multiversion! {
    /// Composites one stroke's closest points (`near`: squared distance, vector, height, signed slope)
    /// into a row (`out`: elevation weight and value, band weight, gradient x and y, roughness weight
    /// and value, and the distances of the strokes that set the elevation and band values). Texels at
    /// the squared reach or beyond (no segment within reach) are left alone.
    /// (Every slice is its own argument, so that the compiler knows that they do not overlap.)
    #[allow(clippy::too_many_arguments)]
    fn composite(
        k: &StrokeConsts,
        d2s: &[f32],
        vxs: &[f32],
        vys: &[f32],
        zs: &[f32],
        ss: &[f32],
        ew: &mut [f32],
        ev: &mut [f32],
        bw: &mut [f32],
        gx: &mut [f32],
        gy: &mut [f32],
        rw: &mut [f32],
        rv: &mut [f32],
        ed: &mut [f32],
        bd: &mut [f32],
    ) {
        let n = d2s.len();
        let (vxs, vys, zs, ss) = (&vxs[..n], &vys[..n], &zs[..n], &ss[..n]);
        let (ew, ev, bw, gx, gy) = (&mut ew[..n], &mut ev[..n], &mut bw[..n], &mut gx[..n], &mut gy[..n]);
        let (rw, rv, ed, bd) = (&mut rw[..n], &mut rv[..n], &mut ed[..n], &mut bd[..n]);
        let k = *k;
        // Blocks of 8 texels, then the rest.
        const L: usize = 8;
        macro_rules! lanes {
            ($len:expr, $r:expr) => {{
                let r = $r;
                composite_lanes::<$len>(
                    &k,
                    [&d2s[r.clone()], &vxs[r.clone()], &vys[r.clone()], &zs[r.clone()], &ss[r.clone()]],
                    [
                        &mut ew[r.clone()],
                        &mut ev[r.clone()],
                        &mut bw[r.clone()],
                        &mut gx[r.clone()],
                        &mut gy[r.clone()],
                        &mut rw[r.clone()],
                        &mut rv[r.clone()],
                        &mut ed[r.clone()],
                        &mut bd[r],
                    ],
                )
            }};
        }
        let whole = n / L * L;
        for b in (0..whole).step_by(L) {
            lanes!(L, b..b + L);
        }
        for i in whole..n {
            lanes!(1, i..i + 1);
        }
    }
}

/// `composite` on `L` texels: copied into fixed-size arrays, computed lane by lane with bit-mask
/// selects (every value is finite: no NaN rules), copied back. With bool conditions the compiler kept
/// the lanes scalar; with `mask` / `sel` the AVX2 build computes the 8 lanes as vectors.
#[inline(always)]
fn composite_lanes<const L: usize>(k: &StrokeConsts, near: [&[f32]; 5], out: [&mut [f32]; 9]) {
    let get = |v: &[f32]| -> [f32; L] { std::array::from_fn(|l| v[l]) };
    let [d2s, vxs, vys, zs, ss] = near.map(get);
    let [ew, ev, bw, gx, gy, rw, rv, ed, bd] = out;
    let (mut o_ew, mut o_ev, mut o_bw, mut o_gx, mut o_gy) =
        (get(ew), get(ev), get(bw), get(gx), get(gy));
    let (mut o_rw, mut o_rv, mut o_ed, mut o_bd) = (get(rw), get(rv), get(ed), get(bd));
    let c = k.cell;
    // Bit masks and selects (`cpu::rows::{mask, sel}`), as the solver's kernels use them.
    let max = |a: f32, b: f32| sel(mask(a > b), a, b);
    let unit = |v: f32| v.clamp(0.0, 1.0);
    let banded = mask(k.banded);
    for i in 0..L {
        let d2 = d2s[i];
        let found = mask(d2 < k.reach2);
        let d = d2.sqrt();
        // Elevation.
        let we = sel(found, unit((k.core - d) / c + 1.5), 0.0);
        let set_e = mask(we > 0.0) & mask(d <= o_ed[i]);
        o_ed[i] = sel(set_e, d, o_ed[i]);
        o_ev[i] = sel(set_e, zs[i], o_ev[i]);
        o_ew[i] = max(o_ew[i], we);
        // Gradient band (ridges and valleys), outside the hard core.
        let in_band = found & banded & mask(d > 0.5 * c);
        let wb = sel(in_band, unit((k.width - d) / c + 0.5), 0.0);
        let set_b = mask(wb > 0.0) & mask(d <= o_bd[i]);
        // In the band `d > c / 2`: the direction is well defined. The slope fades with the
        // falloff profile `1 + u^2 (c2 + u (c3 + u c4))` of `u = d / width` (1 for "none").
        let (ux, uy) = (vxs[i] / d, vys[i] / d);
        let u = (d * k.inv_width).min(1.0);
        let [c2, c3, c4] = k.falloff;
        let f = (1.0 + u * u * (c2 + u * (c3 + u * c4))).clamp(0.0, 1.0);
        let slope = ss[i] * f;
        o_bd[i] = sel(set_b, d, o_bd[i]);
        o_gx[i] = sel(set_b, slope * ux, o_gx[i]);
        o_gy[i] = sel(set_b, slope * uy, o_gy[i]);
        o_bw[i] = max(o_bw[i], wb);
        // Roughness over the footprint.
        let foot = sel(found & mask(d <= k.width), 1.0, 0.0);
        let wr = max(max(we, wb), foot);
        let set_r = mask(wr > 0.0) & mask(wr >= o_rw[i]);
        o_rv[i] = sel(set_r, k.roughness, o_rv[i]);
        o_rw[i] = max(o_rw[i], wr);
    }
    for (dst, src) in [ew, ev, bw, gx, gy, rw, rv, ed, bd].into_iter().zip([
        &o_ew, &o_ev, &o_bw, &o_gx, &o_gy, &o_rw, &o_rv, &o_ed, &o_bd,
    ]) {
        dst[..L].copy_from_slice(src);
    }
}
