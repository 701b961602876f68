// Shared include `#import prolong`: the bilinear interpolation of coarse level k+1 at a cell of
// level k, the correction `prolong_coarse.wgsl` and `prolong_coarse_alt.wgsl` add or set.
// The importing pass must import `transfer` and declare `uc` (level k+1, n/2 x n/2).

// (P uc)(i, j) on a level of side n.
fn prolong_e(i: u32, j: u32, n: u32) -> f32 {
    let nc = n / 2u;
    let wy = p_weights(j, nc);
    let wx = p_weights(i, nc);
    var e = 0.0;
    for (var a = 0u; a < 2u; a++) {
        for (var b = 0u; b < 2u; b++) {
            e += wx.w[b] * wy.w[a] * uc[wy.idx[a] * nc + wx.idx[b]];
        }
    }
    return e;
}
