//! The linear map between metres and the 16-bit codes of PNG and R16 files.

/// How 16-bit codes map to metres: code 0 is `min_m`, code 65535 is `max_m`, linear between.
///
/// Written files use the data's own range, so the quantisation step is
/// `(max_m - min_m) / 65535` and the round-trip error at most half of it (plus `f32` rounding).
/// For constant data `min_m == max_m` and every code is 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stretch {
    /// Height in metres of code 0.
    pub min_m: f32,
    /// Height in metres of code 65535.
    pub max_m: f32,
}

impl Stretch {
    /// The stretch over `[min, max]` of `heights_m`, which must be finite and non-empty
    /// (the encoders check both before calling this).
    pub(crate) fn covering(heights_m: &[f32]) -> Stretch {
        let (min_m, max_m) = heights_m.iter().fold(
            (f32::INFINITY, f32::NEG_INFINITY),
            |(min_m, max_m), &height_m| (min_m.min(height_m), max_m.max(height_m)),
        );
        Stretch { min_m, max_m }
    }

    /// The code nearest to `height_m`, clamped to `0..=65535`. Computed in `f64`, so ranges
    /// near the `f32` limits do not overflow.
    pub fn code_from_metres(self, height_m: f32) -> u16 {
        let range_m = f64::from(self.max_m) - f64::from(self.min_m);
        if range_m <= 0.0 || range_m.is_nan() {
            return 0;
        }
        let fraction = (f64::from(height_m) - f64::from(self.min_m)) / range_m;
        // The clamp makes the cast exact; NaN (impossible for finite input) would become 0.
        (fraction * 65535.0).round().clamp(0.0, 65535.0) as u16
    }

    /// The height in metres that `code` stands for.
    pub fn metres_from_code(self, code: u16) -> f32 {
        let range_m = f64::from(self.max_m) - f64::from(self.min_m);
        (f64::from(self.min_m) + f64::from(code) * range_m / 65535.0) as f32
    }

    /// Whether the stretch can be applied: both ends finite and `min_m <= max_m`.
    pub(crate) fn is_valid(self) -> bool {
        self.min_m.is_finite() && self.max_m.is_finite() && self.min_m <= self.max_m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ends_map_to_the_extreme_codes() {
        let stretch = Stretch {
            min_m: -12.5,
            max_m: 1830.0,
        };
        assert_eq!(stretch.code_from_metres(-12.5), 0);
        assert_eq!(stretch.code_from_metres(1830.0), 65535);
        assert_eq!(stretch.metres_from_code(0), -12.5);
        assert_eq!(stretch.metres_from_code(65535), 1830.0);
        assert_eq!(stretch.code_from_metres(-1000.0), 0, "below min clamps");
        assert_eq!(stretch.code_from_metres(9000.0), 65535, "above max clamps");
    }

    #[test]
    fn constant_range_gives_code_zero_and_back() {
        let stretch = Stretch::covering(&[4.25; 9]);
        assert_eq!(
            stretch,
            Stretch {
                min_m: 4.25,
                max_m: 4.25
            }
        );
        assert_eq!(stretch.code_from_metres(4.25), 0);
        assert_eq!(stretch.metres_from_code(0), 4.25);
    }

    #[test]
    fn extreme_f32_range_does_not_overflow() {
        let stretch = Stretch::covering(&[-f32::MAX, 0.0, f32::MAX]);
        assert_eq!(stretch.code_from_metres(-f32::MAX), 0);
        assert_eq!(stretch.code_from_metres(f32::MAX), 65535);
        assert!(stretch.metres_from_code(32768).is_finite());
    }

    #[test]
    fn round_trip_error_is_within_half_a_step() {
        let stretch = Stretch {
            min_m: -3.0,
            max_m: 7.0,
        };
        let half_step_m = (7.0 - -3.0) / 65535.0 / 2.0;
        for i in 0..=1000 {
            let height_m = -3.0 + 10.0 * i as f32 / 1000.0;
            let back_m = stretch.metres_from_code(stretch.code_from_metres(height_m));
            let error_m = (back_m - height_m).abs();
            assert!(
                error_m <= half_step_m + 8.0 * f32::EPSILON,
                "{height_m}: {error_m}"
            );
        }
    }
}
