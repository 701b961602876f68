//! The detail amplitude on level [`AMPLITUDE_LEVEL`] (half the heightmap's side): calibrated RMS
//! for the local slope, scaled by the diffused roughness, faded out around hard elevation
//! constraints. The CPU twin of `shaders/render/detail_amplitude.wgsl`.

use rayon::prelude::*;

use crate::calibration::{
    AMPLITUDE_GAIN, FBM_RESIDUAL_RMS, RMS_FLAT_M, RMS_PER_SLOPE_M, ROUGHNESS_REFERENCE,
    SLOPE_TAN_MAX,
};

/// The amplitude map's mip level: side `n >> AMPLITUDE_LEVEL`, one value per block of 2 x 2
/// level-0 cells, fine enough that the fade around a stroke is a few cells wide.
pub const AMPLITUDE_LEVEL: u32 = 1;

/// Side of the amplitude map of an `n x n` heightmap.
pub fn amplitude_side(n: usize) -> usize {
    n >> AMPLITUDE_LEVEL
}

/// Amplitude-map cells (Chebyshev distance) around a block holding a hard level-0 cell where the
/// detail is zero; it reaches full strength `FADE_CELLS` further out (smoothstep). As the texels
/// sample the map (bilinearly): zero within 1-2 level-0 cells of a hard cell, full from 6-7. A hard
/// texel's taps read only its own block and its neighbours, so hard texels get exactly no detail.
pub const ZERO_CELLS: i32 = 1;
/// See [`ZERO_CELLS`].
pub const FADE_CELLS: i32 = 2;
/// Distance search radius (level-2 cells): beyond it the fade is 1.
const REACH: i32 = ZERO_CELLS + FADE_CELLS;

/// Fade factor at Chebyshev distance `d` (amplitude-map cells) from the nearest block with a hard
/// cell.
pub fn fade(d: i32) -> f32 {
    let t = ((d - ZERO_CELLS) as f32 / FADE_CELLS as f32).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// The calibrated amplitude (fbm units) for slope tangent `slope_tan` and diffused roughness `r`.
pub fn amplitude_law(slope_tan: f32, r: f32) -> f32 {
    let rms = RMS_FLAT_M + RMS_PER_SLOPE_M * slope_tan.min(SLOPE_TAN_MAX);
    rms * r.clamp(0.0, 1.0) * law_gain()
}

/// The law's factor from metres of residual RMS times roughness to amplitude (fbm units): the
/// shaders' `gain`.
pub fn law_gain() -> f32 {
    AMPLITUDE_GAIN / (ROUGHNESS_REFERENCE * FBM_RESIDUAL_RMS)
}

/// Counts per block of level-0 cells (one amplitude-map cell) whose elevation weight is hard
/// (`>= 1`): the occupancy the fade is measured from. `elev_weight` is `n x n`, row 0 = south.
pub fn hard_counts(n: usize, elev_weight: &[f32]) -> Vec<u32> {
    let m = amplitude_side(n);
    let b = 1usize << AMPLITUDE_LEVEL;
    let mut out = vec![0u32; m * m];
    if elev_weight.len() != n * n || m == 0 {
        return out;
    }
    out.par_chunks_mut(m).enumerate().for_each(|(j, row)| {
        for dj in 0..b {
            let src = &elev_weight[(b * j + dj) * n..(b * j + dj + 1) * n];
            for (c, block) in row.iter_mut().zip(src.chunks_exact(b)) {
                *c += block.iter().map(|w| u32::from(*w >= 1.0)).sum::<u32>();
            }
        }
    });
    out
}

/// Chebyshev distance along each row (map cells, capped at `REACH + 1`) from each block to the
/// nearest block of that row with `counts > 0`, as bytes (each shift of the occupancy row is one
/// pass over a contiguous slice, which vectorises).
fn row_distance(m: usize, hard: HardCells) -> Vec<u8> {
    let cap = (REACH + 1) as u8;
    let mut hd = vec![cap; m * m];
    hd.par_chunks_mut(m)
        .enumerate()
        .for_each_init(Vec::new, |occupied, (j, row)| {
            hard.occupied(j * m..(j + 1) * m, occupied);
            for di in 0..=(REACH as usize).min(m.saturating_sub(1)) {
                let d = di as u8;
                for (o, c) in row[di..].iter_mut().zip(&occupied[..m - di]) {
                    *o = if *c { (*o).min(d) } else { *o };
                }
                for (o, c) in row[..m - di].iter_mut().zip(&occupied[di..]) {
                    *o = if *c { (*o).min(d) } else { *o };
                }
            }
        });
    hd
}

/// Row `j` of the Chebyshev distance (capped at `REACH + 1`) from the row distances `hd`: the
/// minimum over the rows within reach of `max(|dy|, hd)`.
fn distance_row(m: usize, hd: &[u8], j: usize, out: &mut [u8]) {
    out.fill((REACH + 1) as u8);
    let lo = j.saturating_sub(REACH as usize);
    let hi = (j + REACH as usize).min(m - 1);
    for y in lo..=hi {
        let dj = y.abs_diff(j) as u8;
        for (o, h) in out.iter_mut().zip(&hd[y * m..(y + 1) * m]) {
            *o = (*o).min(dj.max(*h));
        }
    }
}

/// Chebyshev distance (map cells, capped at `REACH + 1`) from each block to the nearest block
/// with `counts > 0`; separable (rows, then columns), equal to the shader's window search.
#[cfg(test)]
fn block_distance(m: usize, counts: &[u32]) -> Vec<i32> {
    let hd = row_distance(m, HardCells::Counts(counts));
    let mut row = vec![0u8; m];
    let mut d = Vec::with_capacity(m * m);
    for j in 0..m {
        distance_row(m, &hd, j, &mut row);
        d.extend(row.iter().map(|v| i32::from(*v)));
    }
    d
}

/// Inputs of the amplitude map (side `m`, row 0 = south).
pub struct AmplitudeInputs<'a> {
    /// Side of the map ([`amplitude_side`] for the live detail).
    pub m: usize,
    /// The map's cell size `[x, y]`, metres.
    pub cell_m: [f32; 2],
    /// Heights at the map's cells (the mip of its level), metres.
    pub heights: &'a [f32],
    /// The diffused roughness, `roughness_side` a side (at most `m`, dividing it), read at the
    /// cell covering each map cell (the roughness is smooth: its solve's grid is level 2).
    pub roughness: &'a [f32],
    /// See [`Self::roughness`].
    pub roughness_side: usize,
    /// The hard level-0 cells per map cell.
    pub hard: HardCells<'a>,
}

/// The hard level-0 cells under each amplitude-map cell (`m x m`); only whether there are any
/// matters.
#[derive(Clone, Copy)]
pub enum HardCells<'a> {
    /// Counts ([`hard_counts`], or the GPU's constraint pyramid).
    Counts(&'a [u32]),
    /// `(sum of the hard values, count)` per cell: the CPU solver's constraint summary of the
    /// map's level, read in place.
    Summary(&'a [(f32, f32)]),
}

impl HardCells<'_> {
    fn len(&self) -> usize {
        match self {
            HardCells::Counts(c) => c.len(),
            HardCells::Summary(s) => s.len(),
        }
    }

    /// Whether each cell of `range` holds a hard cell, into `out`.
    fn occupied(&self, range: std::ops::Range<usize>, out: &mut Vec<bool>) {
        out.clear();
        match self {
            HardCells::Counts(c) => out.extend(c[range].iter().map(|c| *c > 0)),
            HardCells::Summary(s) => out.extend(s[range].iter().map(|c| c.1 > 0.0)),
        }
    }
}

/// The amplitude map (fbm units, `m x m`): [`amplitude_law`] of the heights' slope (central
/// differences, one-sided at the borders) and the roughness, times [`fade`]. Empty if the inputs'
/// sizes do not match `m`.
pub fn amplitude_map(inp: &AmplitudeInputs) -> Vec<f32> {
    let m = inp.m;
    let cells = m * m;
    let rs = inp.roughness_side;
    if m < 2
        || inp.heights.len() != cells
        || rs == 0
        || rs > m
        || !m.is_multiple_of(rs)
        || inp.roughness.len() != rs * rs
        || inp.hard.len() != cells
    {
        return Vec::new();
    }
    let hd = row_distance(m, inp.hard);
    // `fade` and `amplitude_law` with their per-cell constants hoisted, a row at a time, the
    // interior as plain slices so that it vectorises; the borders' one-sided differences after.
    let [cx, cy] = inp.cell_m;
    let inv_2cx = 1.0 / (2.0 * cx);
    let h = inp.heights;
    let mut out = vec![0.0f32; cells];
    out.par_chunks_mut(m).enumerate().for_each(|(j, row)| {
        let (jm, jp) = (j.saturating_sub(1), (j + 1).min(m - 1));
        let inv_dy = 1.0 / ((jp - jm) as f32 * cy);
        let (south, here, north) = (&h[jm * m..][..m], &h[j * m..][..m], &h[jp * m..][..m]);
        // The roughness of the cell covering each map cell, and the fade, as rows of `m`.
        let rough_row = &inp.roughness[(j * rs / m) * rs..][..rs];
        let rough: Vec<f32> = (0..m).map(|i| rough_row[i * rs / m]).collect();
        let mut d = vec![0u8; m];
        distance_row(m, &hd, j, &mut d);
        // Zero where the fade is (`r` is clamped to [0, 1], so the product is never -0).
        let value = |gx: f32, gy: f32, r: f32, d: u8| {
            fade(i32::from(d)) * amplitude_law((gx * gx + gy * gy).sqrt(), r)
        };
        let k = m - 2;
        let (o, e, w) = (&mut row[1..m - 1], &here[2..], &here[..k]);
        let (n, s, r, f) = (
            &north[1..][..k],
            &south[1..][..k],
            &rough[1..][..k],
            &d[1..][..k],
        );
        for i in 0..k {
            o[i] = value((e[i] - w[i]) * inv_2cx, (n[i] - s[i]) * inv_dy, r[i], f[i]);
        }
        for i in [0, m - 1] {
            let (im, ip) = (i.saturating_sub(1), (i + 1).min(m - 1));
            let gx = (here[ip] - here[im]) / ((ip - im) as f32 * cx);
            row[i] = value(gx, (north[i] - south[i]) * inv_dy, rough[i], d[i]);
        }
    });
    out
}

/// The gradient of an `m x m` map of `cell_m` cells at cell `(i, j)`: central differences,
/// one-sided at the borders (the slope [`amplitude_map`] reads).
#[inline]
pub fn gradient_at(h: &[f32], m: usize, cell_m: [f32; 2], i: usize, j: usize) -> [f32; 2] {
    let (im, ip) = (i.saturating_sub(1), (i + 1).min(m - 1));
    let (jm, jp) = (j.saturating_sub(1), (j + 1).min(m - 1));
    [
        (h[j * m + ip] - h[j * m + im]) / ((ip - im) as f32 * cell_m[0]),
        (h[jp * m + i] - h[jm * m + i]) / ((jp - jm) as f32 * cell_m[1]),
    ]
}

/// Bilinear sample of an `m x m` map at `(u, v)` (texel centres at `(c + 0.5) / m`, clamped): the
/// shaders' `sample_height` / `sample_amplitude`.
#[inline]
pub fn sample_bilinear(data: &[f32], m: usize, u: f32, v: f32) -> f32 {
    let s = m as f32;
    let px = (u * s - 0.5).clamp(0.0, s - 1.0);
    let py = (v * s - 0.5).clamp(0.0, s - 1.0);
    let (x0, y0) = (px.floor(), py.floor());
    let (fx, fy) = (px - x0, py - y0);
    let (i0, j0) = (x0 as usize, y0 as usize);
    let (i1, j1) = ((i0 + 1).min(m - 1), (j0 + 1).min(m - 1));
    let south = data[j0 * m + i0] * (1.0 - fx) + data[j0 * m + i1] * fx;
    let north = data[j1 * m + i0] * (1.0 - fx) + data[j1 * m + i1] * fx;
    south * (1.0 - fy) + north * fy
}

/// Per level of a min/max pyramid (sides `sides`, each a power of two), the largest amplitude any
/// point of each cell can sample (the map dilated by one texel for the bilinear taps, then the
/// maximum over the cell's footprint).
pub fn max_pyramid(m: usize, amp: &[f32], sides: &[usize]) -> Vec<Vec<f32>> {
    if amp.len() != m * m || m == 0 {
        return sides.iter().map(|s| vec![0.0; s * s]).collect();
    }
    let dil = dilate(m, amp);
    // Finest first, so that each side is reduced from the finest one already made that it
    // divides (a maximum of maxima), or from the dilated map.
    let mut order: Vec<usize> = (0..sides.len()).collect();
    order.sort_by_key(|&k| std::cmp::Reverse(sides[k]));
    let mut out: Vec<Option<Vec<f32>>> = vec![None; sides.len()];
    for &k in &order {
        let s = sides[k];
        let finer = order
            .iter()
            .filter_map(|&f| out[f].as_ref().map(|v| (sides[f], v)))
            .filter(|(fs, _)| *fs >= s && s > 0 && fs.is_multiple_of(s))
            .min_by_key(|(fs, _)| *fs);
        out[k] = Some(match finer {
            Some((fs, v)) => block_max(fs, v, s),
            None if s > 0 && s <= m && m.is_multiple_of(s) => block_max(m, &dil, s),
            None => cover_max(m, &dil, s),
        });
    }
    out.into_iter().map(Option::unwrap_or_default).collect()
}

/// The `m x m` map dilated by one texel (3 x 3 maximum, clamped at the borders), as a row pass
/// and a column pass.
fn dilate(m: usize, amp: &[f32]) -> Vec<f32> {
    let mut rows = vec![0.0f32; m * m];
    for (o, a) in rows.chunks_exact_mut(m).zip(amp.chunks_exact(m)) {
        for i in 0..m {
            o[i] = a[i.saturating_sub(1)].max(a[i]).max(a[(i + 1).min(m - 1)]);
        }
    }
    let mut dil = vec![0.0f32; m * m];
    for (j, o) in dil.chunks_exact_mut(m).enumerate() {
        let (s, h, n) = (
            &rows[j.saturating_sub(1) * m..][..m],
            &rows[j * m..][..m],
            &rows[(j + 1).min(m - 1) * m..][..m],
        );
        for i in 0..m {
            o[i] = s[i].max(h[i]).max(n[i]);
        }
    }
    dil
}

/// The maximum over each `b x b` block of an `ms x ms` map, `s = ms / b` a side.
fn block_max(ms: usize, src: &[f32], s: usize) -> Vec<f32> {
    let b = ms / s;
    let mut out = vec![0.0f32; s * s];
    for (j, row) in src.chunks_exact(ms).enumerate() {
        let o = &mut out[(j / b) * s..][..s];
        for (c, block) in o.iter_mut().zip(row.chunks_exact(b)) {
            *c = block.iter().fold(*c, |a, v| a.max(*v));
        }
    }
    out
}

/// The maximum over the cells of side `s` each texel of the `m x m` map overlaps, for sides that
/// do not divide `m` (each texel's value goes to every cell it touches).
fn cover_max(m: usize, dil: &[f32], s: usize) -> Vec<f32> {
    let mut out = vec![0.0f32; s * s];
    for j in 0..m {
        for i in 0..m {
            let (x0, x1) = (i * s / m, ((i + 1) * s).div_ceil(m).max(i * s / m + 1));
            let (y0, y1) = (j * s / m, ((j + 1) * s).div_ceil(m).max(j * s / m + 1));
            for y in y0..y1.min(s) {
                for x in x0..x1.min(s) {
                    let o = &mut out[y * s + x];
                    *o = o.max(dil[j * m + i]);
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reduced pyramid equals each texel's value spread over every cell it touches, for sides
    /// finer and coarser than the map, dividing it or not, in any order.
    #[test]
    fn max_pyramid_equals_the_direct_cover() {
        let m = 64;
        let amp: Vec<f32> = (0..m * m).map(|k| ((k * 7919) % 1013) as f32).collect();
        let sides = [1usize, 64, 8, 128, 48, 16, 2, 32, 4];
        let dil = dilate(m, &amp);
        for (s, got) in sides.iter().zip(max_pyramid(m, &amp, &sides)) {
            assert_eq!(got, cover_max(m, &dil, *s), "side {s}");
        }
        // The dilation is the 3 x 3 maximum.
        for j in 0..m {
            for i in 0..m {
                let mut v = 0.0f32;
                for y in j.saturating_sub(1)..=(j + 1).min(m - 1) {
                    for x in i.saturating_sub(1)..=(i + 1).min(m - 1) {
                        v = v.max(amp[y * m + x]);
                    }
                }
                assert_eq!(dil[j * m + i], v);
            }
        }
    }

    /// The separable distance equals a direct Chebyshev search, capped past the reach.
    #[test]
    fn block_distance_is_the_capped_chebyshev_distance() {
        for (m, every) in [(1usize, 1u32), (5, 3), (37, 11), (64, 97)] {
            let counts: Vec<u32> = (0..m * m)
                .map(|k| u32::from((k as u32).wrapping_mul(2_654_435_761).is_multiple_of(every)))
                .collect();
            let d = block_distance(m, &counts);
            for j in 0..m {
                for i in 0..m {
                    let mut want = REACH + 1;
                    for y in 0..m {
                        for x in 0..m {
                            if counts[y * m + x] > 0 {
                                let c = x.abs_diff(i).max(y.abs_diff(j)) as i32;
                                want = want.min(c);
                            }
                        }
                    }
                    assert_eq!(d[j * m + i], want, "m {m}, ({i}, {j})");
                }
            }
        }
    }
}
