//! Small raster helpers of the refinement pass: low-pass by block averaging, bilinear sampling,
//! the 16 patch transforms, seeded hashing.

use rayon::prelude::*;

/// A square-cell raster, row-major, row 0 = north.
#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    /// Columns.
    pub w: usize,
    /// Rows.
    pub h: usize,
    /// `w * h` values.
    pub v: Vec<f32>,
}

impl Field {
    /// Wraps `v` (length must be `w * h`).
    pub fn new(w: usize, h: usize, v: Vec<f32>) -> Field {
        debug_assert_eq!(v.len(), w * h);
        Field { w, h, v }
    }

    /// Value at a cell, clamped to the grid.
    #[inline]
    pub fn at(&self, x: isize, y: isize) -> f32 {
        let x = x.clamp(0, self.w as isize - 1) as usize;
        let y = y.clamp(0, self.h as isize - 1) as usize;
        self.v[y * self.w + x]
    }

    /// Bilinear sample at continuous cell coordinates (cell centres at integers), clamped.
    #[inline]
    pub fn sample(&self, x: f32, y: f32) -> f32 {
        // Floor without a libm call (coordinates are far inside the i32 range).
        let (ix, iy) = (
            x as i32 - i32::from(x < (x as i32) as f32),
            y as i32 - i32::from(y < (y as i32) as f32),
        );
        let (tx, ty) = (x - ix as f32, y - iy as f32);
        let (w, h) = (self.w as i32, self.h as i32);
        if ix >= 0 && iy >= 0 && ix + 1 < w && iy + 1 < h {
            let i = iy as usize * self.w + ix as usize;
            let v = &self.v;
            if tx == 0.0 && ty == 0.0 {
                return v[i];
            }
            let a = v[i] + (v[i + 1] - v[i]) * tx;
            let b = v[i + self.w] + (v[i + self.w + 1] - v[i + self.w]) * tx;
            return a + (b - a) * ty;
        }
        let (ix, iy) = (ix as isize, iy as isize);
        let a = self.at(ix, iy) * (1.0 - tx) + self.at(ix + 1, iy) * tx;
        let b = self.at(ix, iy + 1) * (1.0 - tx) + self.at(ix + 1, iy + 1) * tx;
        a * (1.0 - ty) + b * ty
    }

    /// `self - other`, cell by cell.
    pub fn minus(&self, other: &Field) -> Field {
        let v = self
            .v
            .par_iter()
            .zip(&other.v)
            .map(|(a, b)| a - b)
            .collect();
        Field::new(self.w, self.h, v)
    }
}

/// Block average by `f` (a partial last block averages what it has).
pub fn downsample(src: &Field, f: usize) -> Field {
    let f = f.max(1);
    let (cw, ch) = (src.w.div_ceil(f), src.h.div_ceil(f));
    let mut out = vec![0.0f32; cw * ch];
    out.par_chunks_mut(cw).enumerate().for_each(|(cy, row)| {
        let y1 = ((cy + 1) * f).min(src.h);
        for (cx, o) in row.iter_mut().enumerate() {
            let x1 = ((cx + 1) * f).min(src.w);
            let mut s = 0.0f64;
            for y in cy * f..y1 {
                for x in cx * f..x1 {
                    s += f64::from(src.v[y * src.w + x]);
                }
            }
            *o = (s / ((y1 - cy * f) * (x1 - cx * f)) as f64) as f32;
        }
    });
    Field::new(cw, ch, out)
}

/// 3x3 binomial smoothing (edges clamped).
pub fn smooth3(src: &Field) -> Field {
    let mut out = vec![0.0f32; src.v.len()];
    out.par_chunks_mut(src.w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, o) in row.iter_mut().enumerate() {
                let (x, y) = (x as isize, y as isize);
                let mut s = 0.0;
                for (dy, wy) in [(-1, 1.0), (0, 2.0), (1, 1.0)] {
                    for (dx, wx) in [(-1, 1.0), (0, 2.0), (1, 1.0)] {
                        s += wx * wy * src.at(x + dx, y + dy);
                    }
                }
                *o = s / 16.0;
            }
        });
    Field::new(src.w, src.h, out)
}

/// Bilinear upsampling of a block-averaged grid back to `w x h` (coarse cell centres at
/// `(c + 0.5) f - 0.5`).
pub fn upsample(coarse: &Field, f: usize, w: usize, h: usize) -> Field {
    let f = f.max(1) as f32;
    let mut out = vec![0.0f32; w * h];
    out.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            let cy = (y as f32 + 0.5) / f - 0.5;
            for (x, o) in row.iter_mut().enumerate() {
                *o = coarse.sample((x as f32 + 0.5) / f - 0.5, cy);
            }
        });
    Field::new(w, h, out)
}

/// Cubic B-spline weights of the four coarse samples `i0 - 1 ..= i0 + 2` around `t` in `[0, 1)`.
#[inline]
fn bspline_weights(t: f32) -> [f32; 4] {
    let s = 1.0 - t;
    let t2 = t * t;
    [
        s * s * s / 6.0,
        (3.0 * t2 * t - 6.0 * t2 + 4.0) / 6.0,
        (-3.0 * t2 * t + 3.0 * t2 + 3.0 * t + 1.0) / 6.0,
        t2 * t / 6.0,
    ]
}

/// Taps of a cubic B-spline upsampling of `c` coarse samples to `out` fine ones by `f`: the
/// four clamped coarse indices and weights per fine index.
fn bspline_taps(c: usize, f: f32, out: usize) -> Vec<([usize; 4], [f32; 4])> {
    (0..out)
        .map(|x| {
            let cx = (x as f32 + 0.5) / f - 0.5;
            let i0 = cx.floor();
            let w = bspline_weights(cx - i0);
            let i0 = i0 as isize;
            let idx =
                std::array::from_fn(|k| (i0 - 1 + k as isize).clamp(0, c as isize - 1) as usize);
            (idx, w)
        })
        .collect()
}

/// Cubic B-spline upsampling of a block-averaged grid to `w x h` (coarse cell centres at
/// `(c + 0.5) f - 0.5`). Unlike bilinear upsampling, whose gradient jumps on every coarse
/// cell centre line (axis-aligned creases `f` cells apart that a hillshade shows), the result
/// has continuous curvature. It reproduces linear functions away from the clamped borders.
pub fn upsample_smooth(coarse: &Field, f: usize, w: usize, h: usize) -> Field {
    let fs = f.max(1) as f32;
    let tx = bspline_taps(coarse.w, fs, w);
    let ty = bspline_taps(coarse.h, fs, h);
    // Separable: rows first (coarse rows x fine columns), then columns.
    let mut rows = vec![0.0f32; coarse.h * w];
    rows.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(cy, row)| {
            let src = &coarse.v[cy * coarse.w..(cy + 1) * coarse.w];
            for (o, (idx, wt)) in row.iter_mut().zip(&tx) {
                *o = wt[0] * src[idx[0]]
                    + wt[1] * src[idx[1]]
                    + wt[2] * src[idx[2]]
                    + wt[3] * src[idx[3]];
            }
        });
    let mut out = vec![0.0f32; w * h];
    out.par_chunks_mut(w.max(1))
        .zip(&ty)
        .for_each(|(row, (idx, wt))| {
            let r = |k: usize| &rows[idx[k] * w..(idx[k] + 1) * w];
            let (r0, r1, r2, r3) = (r(0), r(1), r(2), r(3));
            for (x, o) in row.iter_mut().enumerate() {
                *o = wt[0] * r0[x] + wt[1] * r1[x] + wt[2] * r2[x] + wt[3] * r3[x];
            }
        });
    Field::new(w, h, out)
}

/// Smooth low-pass at scale `f` cells: block average, then cubic B-spline upsampling (C2, so
/// the layout has no creases on the coarse grid). The B-spline smooths by itself; with the
/// extra 3x3 binomial of the bilinear version the band would be wider and the output's slope
/// distribution and seams measurably worse.
pub fn lowpass(src: &Field, f: usize) -> Field {
    if f <= 1 {
        return src.clone();
    }
    upsample_smooth(&downsample(src, f), f, src.w, src.h)
}

/// The layout's low-pass at scale `f`: `2 L - L L` with `L` = [`lowpass`], i.e. `1 - (1 - L)^2`.
/// It keeps more of the waves just above the patches' band than `L` and passes less of the band
/// itself, so layout and patches (`E - layout(E)`, the complement) meet with a narrower gap
/// (synthesis README, "Layout and detail").
pub fn layout_lowpass(src: &Field, f: usize) -> Field {
    if f <= 1 {
        return src.clone();
    }
    let l = lowpass(src, f);
    let ll = lowpass(&l, f);
    let v = l.v.iter().zip(&ll.v).map(|(a, b)| 2.0 * a - b).collect();
    Field::new(src.w, src.h, v)
}

/// Number of patch transforms: 8 rotations 45 degrees apart, each optionally mirrored.
pub const TRANSFORMS: usize = 16;

/// Maps an offset in the target's frame to the exemplar's frame under transform `k`:
/// mirror `x` if `k >= 8`, then rotate by `22.5 + (k % 8) * 45` degrees. No transform keeps the
/// exemplar's grid parallel to the target's axes or diagonals: an exemplar brought to a finer
/// cell size carries creases along its source grid lines (cubic interpolation is only C1), and
/// axis-aligned patches turned them into straight axis-aligned lines in the output.
#[inline]
pub fn to_exemplar(k: usize, u: f32, v: f32) -> (f32, f32) {
    let u = if k >= 8 { -u } else { u };
    let (s, c) = ROT[k % 8];
    (c * u - s * v, s * u + c * v)
}

/// Maps a direction in the exemplar's frame back to the target's frame (inverse of
/// [`to_exemplar`]).
#[inline]
pub fn to_target(k: usize, u: f32, v: f32) -> (f32, f32) {
    let (s, c) = ROT[k % 8];
    let (x, y) = (c * u + s * v, -s * u + c * v);
    if k >= 8 { (-x, y) } else { (x, y) }
}

/// sin and cos of 22.5 degrees.
const S: f32 = 0.382_683_43;
const C: f32 = 0.923_879_5;
/// `(sin, cos)` of the 8 rotations, `22.5 + 45 k` degrees.
const ROT: [(f32, f32); 8] = [
    (S, C),
    (C, S),
    (C, -S),
    (S, -C),
    (-S, -C),
    (-C, -S),
    (-C, S),
    (-S, C),
];

/// SplitMix64 finaliser: a well-mixed 64-bit hash of `x`.
#[inline]
pub fn mix64(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

/// A uniform number in `[0, 1)` from a seed and two indices (deterministic).
#[inline]
pub fn unit_hash(seed: u64, a: u64, b: u64) -> f32 {
    let h = mix64(seed ^ mix64(a.wrapping_mul(0x1000_0000_01b3) ^ mix64(b)));
    (h >> 40) as f32 / (1u64 << 24) as f32
}

/// Smooth value noise in `[0, 1)`: hashed values on a lattice of `period` cells, blended with
/// a smoothstep (deterministic for a seed).
pub fn value_noise(seed: u64, x: i32, y: i32, period: i32) -> f32 {
    let p = period.max(1);
    let (gx, gy) = (x.div_euclid(p), y.div_euclid(p));
    let (tx, ty) = (
        x.rem_euclid(p) as f32 / p as f32,
        y.rem_euclid(p) as f32 / p as f32,
    );
    let v = |a: i32, b: i32| unit_hash(seed, a as u32 as u64, b as u32 as u64);
    let (sx, sy) = (tx * tx * (3.0 - 2.0 * tx), ty * ty * (3.0 - 2.0 * ty));
    let top = v(gx, gy) + (v(gx + 1, gy) - v(gx, gy)) * sx;
    let bottom = v(gx, gy + 1) + (v(gx + 1, gy + 1) - v(gx, gy + 1)) * sx;
    top + (bottom - top) * sy
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transforms_invert() {
        for k in 0..TRANSFORMS {
            let (a, b) = to_exemplar(k, 0.3, -1.7);
            let (u, v) = to_target(k, a, b);
            assert!((u - 0.3).abs() < 1e-5 && (v + 1.7).abs() < 1e-5, "{k}");
        }
    }

    #[test]
    fn sample_is_bilinear_and_clamped() {
        let f = Field::new(3, 2, vec![0.0, 1.0, 2.0, 10.0, 11.0, 12.0]);
        assert_eq!(f.sample(1.0, 1.0), 11.0);
        assert!((f.sample(0.5, 0.25) - 3.0).abs() < 1e-6);
        assert!((f.sample(-3.0, 0.5) - 5.0).abs() < 1e-6);
        assert!((f.sample(2.0, 7.0) - 12.0).abs() < 1e-6);
        assert!((f.sample(1.75, -0.5) - 1.75).abs() < 1e-6);
    }

    #[test]
    fn lowpass_keeps_a_plane() {
        let (w, h) = (64, 48);
        let v = (0..w * h)
            .map(|i| (i % w) as f32 * 2.0 + (i / w) as f32)
            .collect();
        let f = Field::new(w, h, v);
        let l = lowpass(&f, 8);
        // The B-spline reaches two coarse cells out, so stay clear of the clamped borders.
        for y in 20..28 {
            for x in 20..44 {
                let d = l.v[y * w + x] - f.v[y * w + x];
                assert!(d.abs() < 1e-3, "{x} {y} {d}");
            }
        }
    }

    #[test]
    fn lowpass_has_no_creases() {
        // A rough field: with bilinear upsampling the second difference is zero inside coarse
        // cells and spikes on the coarse centre lines, so its jump between neighbouring cells
        // is as large as itself. A C2 upsampling changes it by O(1/f) per cell.
        let (w, h, f) = (128, 64, 8);
        let v = (0..w * h)
            .map(|i| 100.0 * unit_hash(7, i as u64, 0) + (i % w) as f32)
            .collect();
        let l = lowpass(&Field::new(w, h, v), f);
        let row = &l.v[32 * w..33 * w];
        let d2: Vec<f32> = (1..w - 1)
            .map(|x| row[x - 1] - 2.0 * row[x] + row[x + 1])
            .collect();
        let max_d2 = d2.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        let max_d3 = d2
            .windows(2)
            .fold(0.0f32, |m, p| m.max((p[1] - p[0]).abs()));
        assert!(max_d2 > 1e-3, "{max_d2}");
        assert!(max_d3 < 0.4 * max_d2, "d3 {max_d3} vs d2 {max_d2}");
        // The bilinear upsampling of the same coarse grid fails the same check.
        let c = smooth3(&downsample(&Field::new(w, h, l.v.clone()), f));
        let b = upsample(&c, f, w, h);
        let row = &b.v[32 * w..33 * w];
        let d2: Vec<f32> = (1..w - 1)
            .map(|x| row[x - 1] - 2.0 * row[x] + row[x + 1])
            .collect();
        let max_d2 = d2.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        let max_d3 = d2
            .windows(2)
            .fold(0.0f32, |m, p| m.max((p[1] - p[0]).abs()));
        assert!(
            max_d3 >= 0.9 * max_d2,
            "bilinear d3 {max_d3} vs d2 {max_d2}"
        );
    }
}
