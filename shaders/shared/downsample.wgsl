// Shared include `#import downsample`: one downsampled cell of a weighted field problem from the sums
// over its f x f block of the weights (sw) and of weight times value (s), as `finish_cell` in
// multigrid/src/fields.rs (keep in sync: same formulas, same f32 operations).

// The mean weight, exactly 1 only when every fine cell is hard (sw >= f^2), else at most 0.999;
// 0 without weight.
fn ds_weight(sw: f32, f: u32) -> f32 {
    if sw <= 0.0 {
        return 0.0;
    }
    if sw >= f32(f * f) {
        return 1.0;
    }
    return min(sw * (1.0 / f32(f * f)), 0.999);
}

// The weighted mean value (0 without weight).
fn ds_value(s: f32, sw: f32) -> f32 {
    if sw > 0.0 {
        return s / sw;
    }
    return 0.0;
}
