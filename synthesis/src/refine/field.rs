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

/// Smooth low-pass at scale `f` cells: block average, binomial smoothing, bilinear upsampling.
pub fn lowpass(src: &Field, f: usize) -> Field {
    if f <= 1 {
        return src.clone();
    }
    upsample(&smooth3(&downsample(src, f)), f, src.w, src.h)
}

/// Number of patch transforms: 8 rotations by 45 degrees, each optionally mirrored.
pub const TRANSFORMS: usize = 16;

/// Maps an offset in the target's frame to the exemplar's frame under transform `k`:
/// mirror `x` if `k >= 8`, then rotate by `(k % 8) * 45` degrees.
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

const H: f32 = std::f32::consts::FRAC_1_SQRT_2;
/// `(sin, cos)` of the 8 rotations.
const ROT: [(f32, f32); 8] = [
    (0.0, 1.0),
    (H, H),
    (1.0, 0.0),
    (H, -H),
    (0.0, -1.0),
    (-H, -H),
    (-1.0, 0.0),
    (-H, H),
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
        for y in 16..32 {
            for x in 16..48 {
                let d = l.v[y * w + x] - f.v[y * w + x];
                assert!(d.abs() < 1e-3, "{x} {y} {d}");
            }
        }
    }
}
