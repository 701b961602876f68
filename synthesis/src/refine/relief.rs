//! Window statistics by integral images: energies of detail levels and the relief of a
//! low-pass (the local character a patch must match).

use rayon::prelude::*;

use super::field::Field;

/// Mean of squares over every `p x p` window, by an integral image (f64), at window centres
/// `(x, y)` given as the window's top-left `x - p/2`.
pub(super) struct WindowEnergy {
    w: usize,
    sums: Vec<f64>,
}

impl WindowEnergy {
    pub(super) fn new(f: &Field) -> WindowEnergy {
        let w = f.w + 1;
        let mut sums = vec![0.0f64; w * (f.h + 1)];
        for y in 0..f.h {
            let mut row = 0.0;
            for x in 0..f.w {
                let v = f64::from(f.v[y * f.w + x]);
                row += v * v;
                sums[(y + 1) * w + x + 1] = sums[y * w + x + 1] + row;
            }
        }
        WindowEnergy { w, sums }
    }
    pub(super) fn mean(&self, x0: usize, y0: usize, x1: usize, y1: usize) -> f64 {
        let s = &self.sums;
        let w = self.w;
        let total = s[y1 * w + x1] - s[y0 * w + x1] - s[y1 * w + x0] + s[y0 * w + x0];
        total / ((x1 - x0) * (y1 - y0)).max(1) as f64
    }
}

/// The relief of a low-pass surface per patch window: `ln` of its RMS slope (central
/// differences, metres per cell) over the `p x p` window around a centre, floored at 0.005 (a
/// quarter degree) so flat ground of any flatness compares alike. Flat targets then take flat
/// land and steep ones rugged land, whatever the roughness map says.
pub struct Relief {
    gx: WindowEnergy,
    gy: WindowEnergy,
    p: usize,
    w: usize,
    h: usize,
}

impl Relief {
    /// Integral images of the slope components of `low` for `p`-cell windows.
    pub fn new(low: &Field, p: usize) -> Relief {
        let grad = |dx: isize, dy: isize| {
            let v = (0..low.w * low.h)
                .into_par_iter()
                .map(|i| {
                    let (x, y) = ((i % low.w) as isize, (i / low.w) as isize);
                    0.5 * (low.at(x + dx, y + dy) - low.at(x - dx, y - dy))
                })
                .collect();
            WindowEnergy::new(&Field::new(low.w, low.h, v))
        };
        let (gx, gy) = rayon::join(|| grad(1, 0), || grad(0, 1));
        Relief {
            gx,
            gy,
            p,
            w: low.w,
            h: low.h,
        }
    }

    /// The relief of the window centred at `c` (clipped to the grid).
    pub fn at(&self, c: [f32; 2]) -> f32 {
        let (cx, cy) = (
            c[0].round().max(0.0) as usize,
            c[1].round().max(0.0) as usize,
        );
        let (x0, y0) = (cx.saturating_sub(self.p / 2), cy.saturating_sub(self.p / 2));
        let (x1, y1) = ((x0 + self.p).min(self.w), (y0 + self.p).min(self.h));
        if x1 <= x0 || y1 <= y0 {
            return 0.005f32.ln();
        }
        let ms = self.gx.mean(x0, y0, x1, y1) + self.gy.mean(x0, y0, x1, y1);
        (ms.sqrt().max(0.005) as f32).ln()
    }
}

/// Range of [`detail_gain`]: detail is damped at most 4x and amplified at most 2x.
pub const DETAIL_GAIN_RANGE: [f32; 2] = [0.25, 2.0];

/// Factor on a patch's detail from the relief (as [`Relief::at`]) of the target where it lands
/// and of the land it came from: their ratio, clamped to [`DETAIL_GAIN_RANGE`]. When no
/// candidate is as flat (a lake, a valley floor) or as steep (canyon walls) as the target, the
/// best one's detail is scaled towards the target's character instead of copied as it is.
pub fn detail_gain(target: f32, site: f32) -> f32 {
    let [lo, hi] = DETAIL_GAIN_RANGE;
    (target - site).exp().clamp(lo, hi)
}
