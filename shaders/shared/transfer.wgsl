// Shared include `#import transfer`: the cell-centred bilinear prolongation weights and the Galerkin scatter.
// Must be kept in sync with `p_weights` and `scatter` in multigrid/src/cpu/coarse.rs (same formulas, same order).

// The two 1D factors of a fine index: parent (0.75) and side neighbour (0.25), or the parent alone (1.0)
// when the side neighbour is outside the coarse domain.
struct PWeights {
    idx: vec2<u32>,
    w: vec2<f32>,
}

// The side neighbour of fine index `x`'s parent: the next coarse cell toward `x`, clamped to the domain
// (the parent itself at the border).
fn p_side(x: u32, nc: u32) -> u32 {
    let parent = x / 2u;
    if (x & 1u) == 1u {
        return min(parent + 1u, nc - 1u);
    } else if parent > 0u {
        return parent - 1u;
    }
    return parent;
}

fn p_weights(x: u32, nc: u32) -> PWeights {
    let parent = x / 2u;
    let side = p_side(x, nc);
    if side == parent {
        return PWeights(vec2<u32>(parent, parent), vec2<f32>(1.0, 0.0));
    }
    return PWeights(vec2<u32>(parent, side), vec2<f32>(0.75, 0.25));
}

// acc += coeff * P(fine (fx, fy), .) expressed as offsets around coarse cell (ic, jc).
fn scatter(acc: ptr<function, array<f32, 9>>, coeff: f32, fx: u32, fy: u32, nc: u32, ic: u32, jc: u32) {
    let wx = p_weights(fx, nc);
    let wy = p_weights(fy, nc);
    for (var a = 0u; a < 2u; a++) {
        let wyv = wy.w[a];
        if wyv == 0.0 {
            continue;
        }
        let oy = wy.idx[a] + 1u - jc;
        for (var b = 0u; b < 2u; b++) {
            let wxv = wx.w[b];
            if wxv == 0.0 {
                continue;
            }
            let ox = wx.idx[b] + 1u - ic;
            (*acc)[oy * 3u + ox] += coeff * wxv * wyv;
        }
    }
}
