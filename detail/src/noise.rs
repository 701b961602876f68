//! Integer-hashed 2-D gradient noise and its octave sum, in plain f32 arithmetic and 32-bit integer
//! hashing (no sine hash, whose precision varies between devices), so that any twin reproduces it
//! to rounding.

use crate::calibration::{BILLOW_MEAN, HURST, REFERENCE_WAVELENGTH_M, TOP_CELLS};

/// Most octaves ever summed (the display's finest, far below any heightmap cell).
pub const MAX_OCTAVES: usize = 16;

/// Per-octave rotations (golden-angle steps), so that octaves do not share the lattice's axes.
pub const ROTATIONS: [[f32; 2]; MAX_OCTAVES] = [
    [1.0, 0.0],
    [-0.737_368_7, 0.675_490_5],
    [0.087_425_27, -0.996_171_1],
    [0.608_439_4, 0.793_600_3],
    [-0.984_713_6, -0.174_181_05],
    [0.843_754_7, -0.536_729],
    [-0.259_602_97, 0.965_715_4],
    [-0.460_908_45, -0.887_447_7],
    [0.939_321_9, 0.343_036_9],
    [-0.924_344_8, 0.381_558_3],
    [0.423_843_9, -0.905_735_3],
    [0.299_286_3, 0.954_163_4],
    [-0.865_212_6, -0.501_405_2],
    [0.976_675_1, -0.214_722_35],
    [-0.575_126_8, 0.818_064_3],
    [-0.128_514_11, -0.991_707_7],
];

/// The PCG output permutation as a 32-bit hash (Jarzynski and Olano 2020, "Hash Functions for GPU
/// Rendering": the best quality per operation of the integer hashes they test).
#[inline(always)]
pub fn pcg(v: u32) -> u32 {
    let s = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let w = ((s >> ((s >> 28) + 4)) ^ s).wrapping_mul(277_803_737);
    (w >> 22) ^ w
}

/// The 32-bit seed of a sketch seed.
pub fn seed32(seed: u64) -> u32 {
    (seed as u32) ^ ((seed >> 32) as u32)
}

#[inline(always)]
fn fade(t: f32) -> f32 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// Multipliers of a lattice point's coordinates in its hash.
const HASH_X: u32 = 0x27d4_eb2d;
const HASH_Y: u32 = 0x1656_67b1;

/// The hash of the lattice point with `x * HASH_X` = `xa`, `y * HASH_Y` = `yb` for octave seed
/// `s`, whose top two bits choose its gradient: one xor-shift-multiply round, whose top bits depend
/// on every input bit (four operations a corner; the octave seeds themselves come from [`pcg`]).
#[inline(always)]
fn corner_bits(xa: u32, yb: u32, s: u32) -> u32 {
    let h = xa ^ yb ^ s;
    (h ^ (h >> 15)).wrapping_mul(0x2c1b_3c6d)
}

/// The float sign bit.
const SIGN: u32 = 0x8000_0000;

/// The dot product of lattice gradient `h` with `(fx, fy)`: the four diagonal gradients
/// `(+-1, +-1)`, bit 30 of the hash flipping the sign of `fx`, bit 31 that of `fy` (moved onto the
/// sign bit directly: branch-free, vectorisable).
#[inline(always)]
fn dot_gradient(h: u32, fx: f32, fy: f32) -> f32 {
    f32::from_bits(fx.to_bits() ^ ((h << 1) & SIGN)) + f32::from_bits(fy.to_bits() ^ (h & SIGN))
}

/// `1.5 * 2^23`: adding it to an integer-valued float of magnitude under `2^22` puts that integer
/// in the mantissa's low bits.
const INT_MAGIC: f32 = 12_582_912.0;

/// `floor(x)` as a float and as an integer, the integer read from the float's bits (exact for
/// `|x| < 2^22`, which every lattice coordinate here is: a grid's side at most). Unlike `as i32`,
/// whose saturation the compiler does lane by lane, this stays in vector registers.
#[inline(always)]
fn floor_parts(x: f32) -> (f32, i32) {
    let f = x.floor();
    (
        f,
        ((f + INT_MAGIC).to_bits() as i32).wrapping_sub(INT_MAGIC.to_bits() as i32),
    )
}

/// Perlin gradient noise at lattice coordinates `(x, y)` for octave seed `s` (quintic fade), in about
/// [-1, 1], zero at lattice points.
#[inline(always)]
pub fn gradient_noise(x: f32, y: f32, s: u32) -> f32 {
    let ((xf, ix), (yf, iy)) = (floor_parts(x), floor_parts(y));
    let (fx, fy) = (x - xf, y - yf);
    let x0 = (ix as u32).wrapping_mul(HASH_X);
    let y0 = (iy as u32).wrapping_mul(HASH_Y);
    let (x1, y1) = (x0.wrapping_add(HASH_X), y0.wrapping_add(HASH_Y));
    let n00 = dot_gradient(corner_bits(x0, y0, s), fx, fy);
    let n10 = dot_gradient(corner_bits(x1, y0, s), fx - 1.0, fy);
    let n01 = dot_gradient(corner_bits(x0, y1, s), fx, fy - 1.0);
    let n11 = dot_gradient(corner_bits(x1, y1, s), fx - 1.0, fy - 1.0);
    let (u, v) = (fade(fx), fade(fy));
    let south = n00 + u * (n10 - n00);
    let north = n01 + u * (n11 - n01);
    south + v * (north - south)
}

/// How far below a heightmap cell [`fine_octaves`] reach: octaves down to `cell / (FINE_DEPTH / 2)`
/// count fully, none at `cell / FINE_DEPTH`. The law is fitted on 25-90 m cells; further down its
/// extrapolation reads as crumpled paper rather than ground.
pub const FINE_DEPTH: f32 = 8.0;

/// The display-only octaves finer than a heightmap cell, shown as shading when the camera is close
/// (the terrain fragment shader's `fine_detail`; its CPU twin, for tests): octave `o` of the
/// calibrated ladder with weight `2^(-H o)` times what the heights leave of it,
/// `1 - clamp(wl / cell - 1, 0, 1)` (the heights hold octaves of two cells and more, part of those
/// between one and two) times `clamp(FINE_DEPTH wl / cell - 1, 0, 1)`, times its share above the
/// pixel, `clamp(wl / (2 footprint) - 1, 0, 1)` (none under two pixels, all from four: finer
/// octaves would alias).
pub fn fine_octaves(cell_m: f32, footprint_m: f32, seed32: u32) -> Octaves {
    let mut o = Octaves::empty(Shape::CALIBRATED.billow);
    for oct in -COARSE_OCTAVES..MAX_OCTAVES as i32 - COARSE_OCTAVES {
        let wl = octave_wavelength_m(oct);
        let left = (1.0 - (wl / cell_m - 1.0).clamp(0.0, 1.0))
            * (FINE_DEPTH * wl / cell_m - 1.0).clamp(0.0, 1.0);
        let shown = (wl / (2.0 * footprint_m) - 1.0).clamp(0.0, 1.0);
        let c = left * shown;
        if c <= 0.0 {
            continue;
        }
        o.push(oct, seed32, c * octave_weight(oct));
    }
    o
}

/// Octave indices below zero (coarser than [`REFERENCE_WAVELENGTH_M`]) the ladder reaches: the
/// coarsest octave is `2^COARSE_OCTAVES` times the reference.
pub const COARSE_OCTAVES: i32 = 6;

/// Lattice spacing of octave `o`, metres: the reference halved `o` times (`o < 0`: doubled).
pub fn octave_wavelength_m(o: i32) -> f32 {
    REFERENCE_WAVELENGTH_M * (-(o as f32)).exp2()
}

/// Weight of octave `o`: `2^(-H o)`, the self-affine scaling of the calibrated Hurst exponent
/// (one at the reference wavelength, above one for the coarser octaves).
pub fn octave_weight(o: i32) -> f32 {
    (-HURST * o as f32).exp2()
}

/// The octave sum's shape: which octaves and how each is shaped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shape {
    /// Hurst exponent of the octave weights.
    pub hurst: f32,
    /// The band's top, in cells of the sampling: the coarsest octave spacing is the larger of
    /// [`REFERENCE_WAVELENGTH_M`] and this many cells (what the diffusion of strokes that far apart
    /// does not draw).
    pub top_cells: f32,
    /// Billow octaves (`2 (|n| - mean)`: V-shaped creases along the noise's zero lines, rounded
    /// crests between) instead of plain gradient noise.
    pub billow: bool,
}

impl Shape {
    /// The calibrated shape (`calibration.rs`).
    pub const CALIBRATED: Shape = Shape {
        hurst: HURST,
        top_cells: TOP_CELLS,
        billow: true,
    };

    /// The top of the band for a sampling of `min_wavelength_m` (its cell), metres.
    pub fn top_m(&self, min_wavelength_m: f32) -> f32 {
        REFERENCE_WAVELENGTH_M.max(self.top_cells * min_wavelength_m)
    }

    /// How much of octave `o` a surface sampled no finer than `min_wavelength_m` shows: 1 when its
    /// lattice spacing is between twice that and the band's top, fading linearly to 0 at one cell
    /// and at twice the top.
    pub fn coverage(&self, o: i32, min_wavelength_m: f32) -> f32 {
        let wl = octave_wavelength_m(o);
        let fine = (wl / min_wavelength_m - 1.0).clamp(0.0, 1.0);
        let coarse = (2.0 - wl / self.top_m(min_wavelength_m)).clamp(0.0, 1.0);
        fine * coarse
    }

    /// Largest `|value|` of one octave's noise.
    pub fn octave_bound(&self) -> f32 {
        if self.billow {
            2.0 * (1.0 - BILLOW_MEAN).max(BILLOW_MEAN)
        } else {
            1.0
        }
    }
}

/// How much of octave `o` the calibrated shape shows at `min_wavelength_m` ([`Shape::coverage`]).
pub fn octave_coverage(o: i32, min_wavelength_m: f32) -> f32 {
    Shape::CALIBRATED.coverage(o, min_wavelength_m)
}

/// The octaves of one sum, prepared once per call (seeds, offsets, scales, weights): the
/// per-point work is then the noise alone.
#[derive(Debug, Clone, Copy)]
pub struct Octaves {
    count: usize,
    billow: bool,
    inv_wavelength: [f32; MAX_OCTAVES],
    weight: [f32; MAX_OCTAVES],
    seed: [u32; MAX_OCTAVES],
    rot: [[f32; 2]; MAX_OCTAVES],
    offset: [[f32; 2]; MAX_OCTAVES],
}

impl Octaves {
    /// The calibrated octaves from the band's top down to those finer than `min_wavelength_m`
    /// (excluded), for sketch seed `seed32` and Hurst exponent `hurst`.
    pub fn new(min_wavelength_m: f32, seed32: u32, hurst: f32) -> Octaves {
        Octaves::with_shape(
            min_wavelength_m,
            seed32,
            &Shape {
                hurst,
                ..Shape::CALIBRATED
            },
        )
    }

    /// The octaves of `shape` for a sampling of `min_wavelength_m` and seed `seed32`. Octave `o`
    /// keeps its seed, rotation and offset whatever the sampling, so that grids of different sizes
    /// share their common octaves.
    pub fn with_shape(min_wavelength_m: f32, seed32: u32, shape: &Shape) -> Octaves {
        let mut o = Octaves::empty(shape.billow);
        for oct in -COARSE_OCTAVES..MAX_OCTAVES as i32 - COARSE_OCTAVES {
            let c = shape.coverage(oct, min_wavelength_m);
            if c <= 0.0 {
                if o.count > 0 {
                    break;
                }
                continue;
            }
            o.push(oct, seed32, (-shape.hurst * oct as f32).exp2() * c);
        }
        o
    }

    fn empty(billow: bool) -> Octaves {
        Octaves {
            count: 0,
            billow,
            inv_wavelength: [0.0; MAX_OCTAVES],
            weight: [0.0; MAX_OCTAVES],
            seed: [0; MAX_OCTAVES],
            rot: [[0.0; 2]; MAX_OCTAVES],
            offset: [[0.0; 2]; MAX_OCTAVES],
        }
    }

    /// Appends ladder octave `oct` with `weight`: its seed, rotation and offset are the ladder's.
    fn push(&mut self, oct: i32, seed32: u32, weight: f32) {
        let k = self.count;
        let s = pcg(seed32.wrapping_add(oct as u32));
        self.inv_wavelength[k] = 1.0 / octave_wavelength_m(oct);
        self.weight[k] = weight;
        self.seed[k] = s;
        self.rot[k] = ROTATIONS[oct.rem_euclid(MAX_OCTAVES as i32) as usize];
        self.offset[k] = [
            (pcg(s) & 0xffff) as f32 / 65536.0,
            (pcg(s ^ 0x9e37_79b9) & 0xffff) as f32 / 65536.0,
        ];
        self.count = k + 1;
    }

    /// Number of octaves summed.
    pub fn count(&self) -> usize {
        self.count
    }

    /// Lattice spacing of summed octave `k` (`k < count()`), metres.
    pub fn wavelength_m(&self, k: usize) -> f32 {
        1.0 / self.inv_wavelength[k]
    }

    /// The sum at world point `(x_m, y_m)`.
    #[inline]
    #[allow(clippy::needless_range_loop)] // k indexes five per-octave tables
    pub fn eval(&self, x_m: f32, y_m: f32) -> f32 {
        let mut sum = 0.0f32;
        for k in 0..self.count {
            let rot = self.rot[k];
            let (px, py) = (x_m * self.inv_wavelength[k], y_m * self.inv_wavelength[k]);
            let x = rot[0] * px - rot[1] * py + self.offset[k][0];
            let y = rot[1] * px + rot[0] * py + self.offset[k][1];
            sum += self.weight[k] * shaped(gradient_noise(x, y, self.seed[k]), self.billow);
        }
        sum
    }
}

/// Directions of the aligned octaves ([`Octaves::eval_aligned`]): 0, 45, 90 and 135 degrees,
/// as (cos, sin).
pub const ALIGNED_DIRECTIONS: [[f32; 2]; 4] = [
    [1.0, 0.0],
    [
        std::f32::consts::FRAC_1_SQRT_2,
        std::f32::consts::FRAC_1_SQRT_2,
    ],
    [0.0, 1.0],
    [
        -std::f32::consts::FRAC_1_SQRT_2,
        std::f32::consts::FRAC_1_SQRT_2,
    ],
];

impl Octaves {
    /// Octave `k` (`k < count()`) stretched `stretch` times along direction `d` of
    /// [`ALIGNED_DIRECTIONS`] at world point `(x_m, y_m)`, weighted: its creases run along `d`.
    /// Each direction has its own seed, so the four are independent fields.
    #[inline]
    pub fn eval_aligned(&self, k: usize, d: usize, stretch: f32, x_m: f32, y_m: f32) -> f32 {
        let [c, s] = ALIGNED_DIRECTIONS[d];
        // Along `d` (compressed) and across it, then the octave's own scale, rotation, offset.
        let (u, v) = ((c * x_m + s * y_m) / stretch, -s * x_m + c * y_m);
        let rot = self.rot[k];
        let (px, py) = (u * self.inv_wavelength[k], v * self.inv_wavelength[k]);
        let x = rot[0] * px - rot[1] * py + self.offset[k][0];
        let y = rot[1] * px + rot[0] * py + self.offset[k][1];
        let seed = pcg(self.seed[k] ^ (0x9e37_79b9u32.wrapping_mul(d as u32 + 1)));
        self.weight[k] * shaped(gradient_noise(x, y, seed), self.billow)
    }
}

/// One octave's value from its gradient noise `n`.
#[inline(always)]
fn shaped(n: f32, billow: bool) -> f32 {
    if billow {
        2.0 * (n.abs() - BILLOW_MEAN)
    } else {
        n
    }
}

impl Octaves {
    /// Adds `scale[i] * sum(xs_m[i], y_m)` to `out[i]` along a row, with [`Self::eval`]'s
    /// arithmetic (the same results), in blocks the compiler vectorises (AVX2 when the processor
    /// has it). Blocks whose scales are all `<= 0` are skipped.
    pub fn add_row(&self, xs_m: &[f32], y_m: f32, scale: &[f32], out: &mut [f32]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor has AVX2 (checked just above).
            unsafe { self.add_row_avx2(xs_m, y_m, scale, out) };
            return;
        }
        self.add_row_plain(xs_m, y_m, scale, out);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn add_row_avx2(&self, xs_m: &[f32], y_m: f32, scale: &[f32], out: &mut [f32]) {
        self.add_row_plain(xs_m, y_m, scale, out);
    }

    #[inline(always)]
    #[allow(clippy::needless_range_loop)] // index loops over fixed blocks are what vectorises
    fn add_row_plain(&self, xs_m: &[f32], y_m: f32, scale: &[f32], out: &mut [f32]) {
        const B: usize = 16;
        for ((xs, sc), o) in xs_m.chunks(B).zip(scale.chunks(B)).zip(out.chunks_mut(B)) {
            if sc.iter().all(|a| *a <= 0.0) {
                continue;
            }
            let len = xs.len().min(sc.len()).min(o.len());
            let mut xb = [0.0f32; B];
            xb[..len].copy_from_slice(&xs[..len]);
            let mut sum = [0.0f32; B];
            // Stage by stage over the block, so that each loop is one vector operation.
            for k in 0..self.count {
                let rot = self.rot[k];
                let inv = self.inv_wavelength[k];
                let (w, s) = (self.weight[k], self.seed[k]);
                let py = y_m * inv;
                let (sy, cy) = (rot[1] * py, rot[0] * py);
                let [ox, oy] = self.offset[k];
                let (mut fx, mut fy) = ([0.0f32; B], [0.0f32; B]);
                let (mut ix, mut iy) = ([0i32; B], [0i32; B]);
                for i in 0..B {
                    let px = xb[i] * inv;
                    let x = rot[0] * px - sy + ox;
                    let y = rot[1] * px + cy + oy;
                    let ((xf, xi), (yf, yi)) = (floor_parts(x), floor_parts(y));
                    (ix[i], iy[i]) = (xi, yi);
                    fx[i] = x - xf;
                    fy[i] = y - yf;
                }
                let mut h = [[0u32; B]; 4];
                for i in 0..B {
                    let x0 = (ix[i] as u32).wrapping_mul(HASH_X);
                    let y0 = (iy[i] as u32).wrapping_mul(HASH_Y);
                    let (x1, y1) = (x0.wrapping_add(HASH_X), y0.wrapping_add(HASH_Y));
                    h[0][i] = corner_bits(x0, y0, s);
                    h[1][i] = corner_bits(x1, y0, s);
                    h[2][i] = corner_bits(x0, y1, s);
                    h[3][i] = corner_bits(x1, y1, s);
                }
                for i in 0..B {
                    let (x, y) = (fx[i], fy[i]);
                    let n00 = dot_gradient(h[0][i], x, y);
                    let n10 = dot_gradient(h[1][i], x - 1.0, y);
                    let n01 = dot_gradient(h[2][i], x, y - 1.0);
                    let n11 = dot_gradient(h[3][i], x - 1.0, y - 1.0);
                    let (u, v) = (fade(x), fade(y));
                    let south = n00 + u * (n10 - n00);
                    let north = n01 + u * (n11 - n01);
                    sum[i] += w * shaped(south + v * (north - south), self.billow);
                }
            }
            for i in 0..len {
                if sc[i] > 0.0 {
                    o[i] += sc[i] * sum[i];
                }
            }
        }
    }
}

/// The calibrated octave sum at world point `(x_m, y_m)` for a sampling of `min_wavelength_m`.
/// Prepare [`Octaves`] once to evaluate many points.
pub fn fbm(x_m: f32, y_m: f32, min_wavelength_m: f32, seed32: u32) -> f32 {
    Octaves::with_shape(min_wavelength_m, seed32, &Shape::CALIBRATED).eval(x_m, y_m)
}

/// [`fbm`] with another shape (the calibration measures candidates).
pub fn fbm_with(x_m: f32, y_m: f32, min_wavelength_m: f32, seed32: u32, shape: &Shape) -> f32 {
    Octaves::with_shape(min_wavelength_m, seed32, shape).eval(x_m, y_m)
}

/// An upper bound of `|fbm|` for `min_wavelength_m` (each octave within
/// [`Shape::octave_bound`]).
pub fn fbm_bound(min_wavelength_m: f32) -> f32 {
    shape_bound(&Shape::CALIBRATED, min_wavelength_m)
}

/// An upper bound of the octave sum of `shape` at `min_wavelength_m`.
pub fn shape_bound(shape: &Shape, min_wavelength_m: f32) -> f32 {
    (-COARSE_OCTAVES..MAX_OCTAVES as i32 - COARSE_OCTAVES)
        .map(|o| (-shape.hurst * o as f32).exp2() * shape.coverage(o, min_wavelength_m))
        .sum::<f32>()
        * shape.octave_bound()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_parts_is_floor_for_every_lattice_coordinate() {
        for k in -40_000..40_000 {
            let x = k as f32 * 0.37 + 0.001 * (k % 7) as f32;
            let (f, i) = floor_parts(x);
            assert_eq!(f, x.floor(), "{x}");
            assert_eq!(i, x.floor() as i32, "{x}");
        }
        for x in [-4_194_303.0f32, -1.0, -0.0, 0.0, 0.999_999_9, 4_194_303.5] {
            assert_eq!(floor_parts(x).1, x.floor() as i32, "{x}");
        }
        // Lattice points are zeros of the noise on both sides of the origin.
        for (x, y) in [(-3.0, 5.0), (7.0, -2.0), (-1.0, -1.0)] {
            assert_eq!(gradient_noise(x, y, 12345), 0.0);
        }
    }
}
